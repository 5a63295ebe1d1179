:- begin_tests(query_service).
:- use_module(query_service).

sols(Text, Rs) :- findall(R, query_solution(Text, _{timeout: 5}, R), Rs).

test(solutions_in_order, Bs == ["{\"X\":\"a\"}", "{\"X\":1}"]) :-
    sols("member(X, [a, 1])", Rs),
    findall(B, member(_{status: "solution", bindings: B}, Rs), Bs).
test(trailing_full_stop_allowed, S == "solution") :-
    sols("X = 1.", [R]), get_dict(status, R, S).
test(dict_functional_notation) :-
    sols("P = _{a: 1, b: 2}, X = P.a, Y is P.b * 1", [R]),
    get_dict(bindings, R, B),
    once(sub_string(B, _, _, _, "\"X\":1")),
    once(sub_string(B, _, _, _, "\"Y\":2")).
test(dict_expansion_is_checked, K == "permission_error") :-
    sols("P = _{a: 'true'}, shell(P.a)", [R]), get_dict(kind, R, K).
test(no_solution, Rs == []) :-
    sols("fail", Rs).
test(syntax_error_has_position) :-
    sols("foo(", [R]),
    get_dict(kind, R, "syntax_error"),
    get_dict(error, R, J),
    once(sub_string(J, _, _, _, "{\"functor\":\"string\",\"args\":[{\"string\":\"foo( . \"},4]}")).
test(empty_query_is_syntax_error, K == "syntax_error") :-
    sols("   ", [R]), get_dict(kind, R, K).
test(unknown_predicate, K == "existence_error") :-
    sols("no_such_predicate(1)", [R]), get_dict(kind, R, K).
test(dangerous_goal_refused, K == "permission_error") :-
    sols("shell('true')", [R]), get_dict(kind, R, K).
test(halt_refused, K == "permission_error") :-
    sols("halt", [R]), get_dict(kind, R, K).
test(unverifiable_dynamic_call_refused, K == "permission_error") :-
    sols("G = halt, call(G)", [R]), get_dict(kind, R, K).
test(type_error, K == "type_error") :-
    sols("atom_length(f(x), L)", [R]), get_dict(kind, R, K).
test(evaluation_error, K == "evaluation_error") :-
    sols("X is 1/0", [R]), get_dict(kind, R, K).
test(instantiation_error, K == "instantiation_error") :-
    sols("X is Y + 1", [R]), get_dict(kind, R, K).
test(user_exception, K == "exception") :-
    sols("throw(my_ball)", [R]), get_dict(kind, R, K).
test(endless_query_times_out, K == "timeout") :-
    findall(R, query_solution("repeat, fail", _{timeout: 0.3}, R), [R0]),
    get_dict(kind, R0, K).
test(time_limit_is_per_solution, N == 3) :-
    % each solution takes ~0.2 s; three of them exceed 0.5 s in total
    findall(x, query_solution("member(X, [1,2,3]), sleep(0.2)", _{timeout: 0.5, sandbox: false}, _{status: "solution", bindings: _}), L),
    length(L, N).
test(check_does_not_run, S == "ok") :-
    query_check("throw(never)", _{}, R), get_dict(status, R, S).
test(check_reports_syntax, K == "syntax_error") :-
    query_check("a(", _{}, R), get_dict(kind, R, K).
test(sandbox_off_allows, S == "solution") :-
    once(query_solution("shell(true)", _{sandbox: false}, R)), get_dict(status, R, S).

test(sandbox_off_as_janus_passes_it, S == "solution") :-
    once(query_solution("shell(true)", _{sandbox: @(false)}, R)), get_dict(status, R, S).
test(trailing_text_is_a_syntax_error, K == "syntax_error") :-
    sols("X = 1. garbage ((((", [R]), get_dict(kind, R, K).
test(a_second_goal_is_a_syntax_error, K == "syntax_error") :-
    sols("X = 1. Y = 2", [R]), get_dict(kind, R, K).
test(a_trailing_comment_is_allowed, S == "solution") :-
    sols("X = 1. % a comment", [R]), get_dict(status, R, S).
test(asserts_stay_in_the_query_module, Rs == []) :-
    sols("assertz(exception(undefined_predicate, _, fail))", [_]),
    sols("assertz(portray(_))", [_]),
    sols("assertz(poisoned(1))", [_]),
    findall(x, ( catch(user:portray(_), _, fail)
               ; catch(user:exception(undefined_predicate, _, _), _, fail)
               ; current_predicate(user:poisoned/1) ), Rs).
test(qualified_asserts_are_refused, K == "permission_error") :-
    sols("assertz(user:portray(_))", [R]), get_dict(kind, R, K).
test(sleep_is_cut_by_the_time_limit, [K-Fast == "timeout"-true]) :-
    get_time(T0),
    sols_t("sleep(5)", 0.3, [R]), get_dict(kind, R, K),
    get_time(T1), ( T1 - T0 < 1.5 -> Fast = true ; Fast = T1-T0 ).
test(qualified_sleep_refused, K == "permission_error") :-
    sols("system:sleep(5)", [R]), get_dict(kind, R, K).
test(answers_above_max_answer_are_refused, K == "resource_error") :-
    findall(R, query_solution("numlist(1, 1000, L)", _{max_answer: 100}, R), [R]),
    get_dict(kind, R, K).
test(deep_answers_encode_in_linear_time, S == "solution") :-
    sols("numlist(1, 30000, L), foldl([_,A,f(A)]>>true, L, a, T)", [R]),
    get_dict(status, R, S).
test(huge_error_terms_are_outlined, K == "type_error") :-
    sols("numlist(1, 100000, L), atom_length(f(L), _)", [R]),
    get_dict(kind, R, K), get_dict(message, R, M), string_length(M, N), N < 2000.

sols_t(Text, T, Rs) :- findall(R, query_solution(Text, _{timeout: T}, R), Rs).

test(parsing_long_built_text_is_refused, K == "resource_error") :-
    sols("format(atom(A), '~*c', [2000000, 0'(]), term_to_atom(_, A)", [R]),
    get_dict(kind, R, K).
test(parsing_built_text_still_works, S == "solution") :-
    sols("term_to_atom(T, 'f(X, \"s\")'), term_string(U, \"g(1)\")", [R]),
    get_dict(status, R, S).
test(qualified_parser_refused, K == "permission_error") :-
    sols("system:term_to_atom(_, 'a')", [R]), get_dict(kind, R, K).

:- end_tests(query_service).
