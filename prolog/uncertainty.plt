:- begin_tests(uncertainty).
:- use_module(uncertainty).

close_to(X, Y) :- abs(X - Y) < 1.0e-4.

test(wilson_none_of_ten) :-
    wilson_interval(0, 10, Low, High),
    Low == 0.0, close_to(High, 0.2775).
test(wilson_half_of_ten) :-
    wilson_interval(5, 10, Low, High),
    close_to(Low, 0.2366), close_to(High, 0.7634).
test(wilson_all_of_thirty) :-
    wilson_interval(30, 30, Low, High),
    close_to(Low, 0.8865), High == 1.0.
test(wilson_narrows_with_n) :-
    wilson_interval(9, 10, L1, H1),
    wilson_interval(90, 100, L2, H2),
    H2 - L2 < (H1 - L1) / 2.
test(wilson_no_worlds, error(type_error(positive_integer, 0))) :-
    wilson_interval(0, 0, _, _).
test(wilson_negative, error(type_error(nonneg, -1))) :-
    wilson_interval(-1, 10, _, _).
test(samples_must_be_positive, error(domain_error(positive_integer, 0))) :-
    outcome_probability(grasping, grasp_object, [], [samples(0)], _, true, _).
test(samples_must_be_integer, error(type_error(integer, a))) :-
    outcome_probability(grasping, grasp_object, [], [samples(a)], _, true, _).
test(threshold_is_a_probability, error(domain_error(probability_threshold, 1))) :-
    outcome_probability(grasping, grasp_object, [], [decide(1)], _, true, _).
test(worlds_are_its_own, error(domain_error(probability_option, worlds))) :-
    outcome_probability(grasping, grasp_object, [], [worlds(0, 3)], _, true, _).

test(a_clean_start_needs_31_more_to_prove_0_9, M == 31) :-
    uncertainty:least_to_decide(up, 0.9, 4, 4, 1, 100, M).
test(one_failure_decides_below_at_once, M == 1) :-
    uncertainty:least_to_decide(down, 0.9, 0, 0, 1, 100, M).
test(rounds_are_capped_by_what_is_left, M == 5) :-
    uncertainty:least_to_decide(up, 0.9, 4, 4, 1, 5, M).
test(round_of_the_workers_at_least, S == 4) :-
    uncertainty:round_size(decide(0.9), 2, 0, 0, 35, S).
test(round_of_what_can_decide, S == 31) :-
    uncertainty:round_size(decide(0.9), 2, 4, 4, 35, S).
test(round_of_a_failing_one_is_the_workers, S == 4) :-
    uncertainty:round_size(decide(0.9), 2, 3, 4, 35, S).

:- end_tests(uncertainty).
