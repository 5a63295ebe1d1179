:- begin_tests(json_bindings).
:- use_module(json_bindings).

enc(Term, Json) :- bindings_json(['X'=Term], Text), sub_string(Text, 5, _, 1, Json).

test(atom, J == "\"a\"") :- enc(a, J).
test(string, J == "{\"string\":\"s\"}") :- enc("s", J).
test(atom_true_is_not_boolean, J == "\"true\"") :- enc(true, J).
test(big_integer, J == "123456789012345678901234567890") :-
    enc(123456789012345678901234567890, J).
test(negative_integer, J == "-7") :- enc(-7, J).
test(float_shortest, J == "0.30000000000000004") :- X is 0.1+0.2, enc(X, J).
test(float_whole_keeps_point, J == "1.0") :- enc(1.0, J).
test(float_inf, J == "{\"float\":\"inf\"}") :- X is inf, enc(X, J).
test(float_nan, J == "{\"float\":\"nan\"}") :- X is nan, enc(X, J).
test(empty_list, J == "[]") :- enc([], J).
test(atom_empty_list_brackets, J == "\"[]\"") :- enc('[]', J).
test(list, J == "[1,\"a\",{\"string\":\"b\"}]") :- enc([1,a,"b"], J).
test(compound, J == "{\"functor\":\"f\",\"args\":[\"a\",1]}") :- enc(f(a,1), J).
test(compound_zero_arity, J == "{\"functor\":\"f\",\"args\":[]}") :-
    compound_name_arguments(T, f, []), enc(T, J).
test(partial_list, J == "{\"functor\":\"[|]\",\"args\":[\"a\",{\"var\":\"_G1\"}]}") :-
    enc([a|_], J).
test(unbound_query_var_named) :-
    bindings_json(['X'=f(Y), 'Y'=Y], J),
    J == "{\"X\":{\"functor\":\"f\",\"args\":[{\"var\":\"Y\"}]},\"Y\":{\"var\":\"Y\"}}".
test(aliased_vars_share_name) :-
    bindings_json(['X'=V, 'Y'=V], J),
    J == "{\"X\":{\"var\":\"X\"},\"Y\":{\"var\":\"X\"}}".
test(fresh_vars_numbered, J == "{\"functor\":\"g\",\"args\":[{\"var\":\"_G1\"},{\"var\":\"_G2\"},{\"var\":\"_G1\"}]}") :-
    enc(g(A,_,A), J).
test(cyclic, error(representation_error(acyclic_term))) :-
    X = f(X), enc(X, _).
test(dict, J == "{\"dict\":[[\"k\",1]],\"tag\":\"t\"}") :- enc(t{k:1}, J).
test(rational, J == "{\"rational\":\"1r3\"}") :- X is 1r3, enc(X, J).
test(no_bindings, J == "{}") :- bindings_json([], J).

:- end_tests(json_bindings).
