:- begin_tests(robust).
:- use_module(robust).

robust(Options) :-
    robust:robust_options(Options, _, _).

test(indifference_below_zero, error(domain_error(indifference, -0.1))) :-
    robust([indifference(-0.1)]).
test(indifference_of_one, error(domain_error(indifference, 1))) :-
    robust([indifference(1)]).
test(confidence_of_one, error(domain_error(confidence, 1.0))) :-
    robust([confidence(1.0)]).
test(risk_of_zero, error(domain_error(risk, 0))) :-
    robust([risk(0)]).
test(certify_zero, error(domain_error(positive_integer, 0))) :-
    robust([certify(0)]).
test(samples_zero, error(domain_error(positive_integer, 0))) :-
    robust([certify(5), samples(0)]).
test(samples_reaching_the_certifying_worlds,
     error(domain_error(choosing_worlds(at_most(1000000)), samples(1000001)))) :-
    robust([certify(5), samples(1000001)]).
test(unknown_option, error(domain_error(robust_option, colour(red)))) :-
    robust([certify(5), colour(red)]).
test(passed_on, Pass =@= [timeout(30), physics(_{rate_hz: 480})]) :-
    robust:robust_options([certify(5), timeout(30), physics(_{rate_hz: 480}), seed(3)],
                          opts(_, _, _, 5, 30, workers, 3, margin), Pass).
test(prefer_gentlest, Rule-Sign == prefer-(-1)) :-
    robust:prefer_rule(-max_load(egg1), Rule, _, Sign).
test(prefer_near, Rule-Near == near-[5, 0.0]) :-
    robust:prefer_rule(near([5, 0.0]), Rule, Near, _).
test(cells, Cells == [[1, a], [1, b], [2, a], [2, b]]) :-
    robust:cells([(_, f, [1, 2]), (_, p, [a, b])], _, _, Cells).

test(near_values_one_per_parameter, error(domain_error(near_values(2), near([5])))) :-
    robust:near_values(near, [5], [force, position]).
test(near_values_of_every_parameter) :-
    robust:near_values(near, [5, 0.0], [force, position]).

:- end_tests(robust).
