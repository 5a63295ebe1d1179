:- begin_tests(query_service).
:- use_module(query_service).

sols(Text, Rs) :- findall(R, query_solution(Text, _{timeout: 5}, R), Rs).

test(solutions_in_order, Bs == ["{\"X\":\"a\"}", "{\"X\":1}"]) :-
    sols("member(X, [a, 1])", Rs),
    findall(B, member(_{status: "solution", bindings: B}, Rs), Bs).
test(trailing_full_stop_allowed, S == "solution") :-
    sols("X = 1.", [R]), get_dict(status, R, S).
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

:- end_tests(query_service).
