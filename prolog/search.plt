:- begin_tests(search).
:- use_module(search).

% The search's bisection over a condition given as a function of the value, without
% simulations: Condition holds within (Low, High), the changes are at Low and High.
inside(Low, High, Values, Outcomes) :-
    maplist([V, V-H]>>( V > Low, V =< High -> H = true ; H = false ), Values, Outcomes).

% A probe that also counts its values.
counted(Low, High, Values, Outcomes) :-
    length(Values, N),
    flag(search_test_probes, C, C + N),
    inside(Low, High, Values, Outcomes).

boundaries(Low, High, Options, Bs) :-
    search:boundary_settings(Options, 0.0, 10.0, Tolerance, Max, K),
    search:boundaries(goal(plunit_search:inside(Low, High)), 0.0, 10.0, Tolerance, Max, K,
                      Bs).

test(bisection_finds_both_changes_to_the_tolerance,
     [ [F1-T1, F2-T2] == [false-true, true-false] ]) :-
    boundaries(2.3, 7.7, [tolerance(0.1)], [B1, B2]),
    _{low: L1, high: H1, from: F1, to: T1} :< B1,
    _{low: L2, high: H2, from: F2, to: T2} :< B2,
    assertion((L1 < 2.3, 2.3 =< H1, H1 - L1 =< 0.1)),
    assertion((L2 < 7.7, 7.7 =< H2, H2 - L2 =< 0.1)).

test(the_counts_add_up_to_the_projections_made, Sum == Made) :-
    flag(search_test_probes, _, 0),
    search:boundaries(goal(plunit_search:counted(2.3, 7.7)), 0.0, 10.0, 0.1, 64, 7, Bs),
    flag(search_test_probes, Made, Made),
    aggregate_all(sum(N), ( member(B, Bs), get_dict(projections, B, N) ), Sum).

test(bisection_costs_the_coarse_pass_and_a_halving_per_round, Ns == [7-5, 5]) :-
    % 10 / 6 wide coarse intervals halved 5 times: 0.052 =< 0.1.
    boundaries(2.3, 7.7, [tolerance(0.1)], Bs),
    maplist([B, N]>>get_dict(projections, B, N), Bs, [N1, N2]),
    Mids is N1 - 7,
    Ns = [7-Mids, N2].

test(no_change_no_boundary, fail) :-
    boundaries(20.0, 30.0, [], [_|_]).

test(a_spent_budget_answers_the_intervals_found, Widths == [true, true]) :-
    flag(search_test_probes, _, 0),
    search:boundaries(goal(plunit_search:counted(2.3, 7.7)), 0.0, 10.0, 0.1, 9, 7, Bs),
    flag(search_test_probes, Made, Made),
    assertion(Made =:= 9),
    maplist([B, W]>>( get_dict(low, B, L), get_dict(high, B, H),
                      ( H - L > 0.1, H - L < 10 / 6 -> W = true ; W = false ) ), Bs, Widths).

test(a_budget_below_the_coarse_pass_is_an_error,
     error(domain_error(max_projections(at_least(7)), max_projections(3)))) :-
    outcome_boundary(grasping, grasp_object, [(_, force, range(1, 9))],
                     [max_projections(3)], _, true, _).

test(a_budget_below_one_trial_over_a_belief_is_an_error,
     error(domain_error(max_projections(at_least(73)), max_projections(20)), _)) :-
    best_parametrization(grasping, grasp_object, [(_, force, range(1, 11))],
                         [samples(73), chance(0.95), max_projections(20)], _, true,
                         max_load(egg1), _).

test(the_trial_budget_message_says_one_trial, true(sub_string(Msg, _, _, _, "one trial"))) :-
    catch(search:trial_budget(belief(73, 0.95, 59), 20), E, true),
    once(message_to_codes(E, Codes)), string_codes(Msg, Codes).

% Its formal term is the coarse pass's, which has no context.
test(the_coarse_pass_message_says_coarse, true(sub_string(Msg, _, _, _, "coarse pass"))) :-
    catch(search:boundary_settings([max_projections(3)], 1, 9, _, _, _), E, true),
    once(message_to_codes(E, Codes)), string_codes(Msg, Codes).

test(a_budget_of_one_trial_over_a_belief_is_enough) :-
    search:trial_budget(belief(73, 0.95, 59), 73).

test(a_smaller_coarse_pass_fits_a_small_budget, K == 3) :-
    search:boundary_settings([max_projections(3), coarse(3)], 1, 9, _, _, K).

test(a_coarse_tolerance_makes_the_coarse_pass_smaller, K == 5) :-
    search:boundary_settings([tolerance(2.5)], 0, 10, _, _, K).

test(a_coarse_tolerance_needs_no_bisection, Points == [0.0, 2.5, 5.0, 7.5, 10.0]) :-
    K is ceiling(10.0 / 2.5) + 1,
    search:coarse_points(0.0, 10.0, K, Points).

test(a_change_next_to_an_end_is_found, From-L == true-0.0) :-
    boundaries(-1.0, 0.0, [tolerance(0.1)], [B]),
    _{low: L, high: H, from: From} :< B,
    assertion(H =< 0.1).

test(equal_ends_are_an_error, error(domain_error(search_range, range(5, 5)))) :-
    outcome_boundary(grasping, grasp_object, [(_, force, range(5, 5))], [], _, true, _).

test(reversed_ends_are_an_error, error(domain_error(search_range, range(9, 5)))) :-
    best_parametrization(grasping, grasp_object, [(_, force, range(9, 5))], [], _, true,
                         max_load(egg1), _).

test(two_range_parameters_are_an_error_for_a_boundary,
     error(domain_error(one_range_parameter, [force, position]))) :-
    outcome_boundary(grasping, grasp_object,
                     [(_, force, range(1, 9)), (_, position, range(-0.02, 0.02))], [], _,
                     true, _).

test(a_boundary_without_a_range_parameter_is_an_error,
     error(domain_error(one_range_parameter, []))) :-
    outcome_boundary(grasping, grasp_object, [(_, force, [1, 3])], [], _, true, _).

test(a_best_parametrization_without_a_range_parameter_is_an_error,
     error(domain_error(range_parameters, _))) :-
    best_parametrization(grasping, grasp_object, [(_, force, [1, 3])], [], _, true,
                         max_load(egg1), _).

test(another_searchs_option_is_an_error, error(domain_error(search_option, seed(1)))) :-
    outcome_boundary(grasping, grasp_object, [(_, force, range(1, 9))], [seed(1)], _,
                     true, _).

test(a_tolerance_must_be_positive, error(domain_error(tolerance, tolerance(0)))) :-
    outcome_boundary(grasping, grasp_object, [(_, force, range(1, 9))], [tolerance(0)], _,
                     true, _).

test(a_boundary_budget_needs_both_ends, error(domain_error(max_projections, _))) :-
    outcome_boundary(grasping, grasp_object, [(_, force, range(1, 9))],
                     [max_projections(1)], _, true, _).

test(a_seed_is_an_integer, error(type_error(integer, a))) :-
    best_parametrization(grasping, grasp_object, [(_, force, range(1, 9))], [seed(a)], _,
                         true, max_load(egg1), _).

test(a_batch_is_at_least_one_trial, error(domain_error(batch, batch(0)))) :-
    best_parametrization(grasping, grasp_object, [(_, force, range(1, 9))], [batch(0)], _,
                         true, max_load(egg1), _).

test(a_bound_timeline_is_an_error, error(uninstantiation_error(tl))) :-
    outcome_boundary(grasping, grasp_object, [(_, force, range(1, 9))], [], tl, true, _).

test(options_not_of_the_search_are_passed_on, Own-Pass == [tolerance(1)]-[timeout(5)]) :-
    search:boundary_options([tolerance(1), timeout(5)], Own, Pass).

test(the_other_parameters_are_enumerated, Combinations == [1-a, 1-b, 3-a, 3-b]) :-
    search:search_params([(X, force, [1, 3]), (_, position, range(0, 1)), (Y, p, [a, b])],
                         [searched(_, position, 0, 1)], Fixed),
    findall(X-Y, search:fixed_combination(Fixed, _), Combinations).

test(a_stepped_range_is_enumerated_as_make_projection_does, Values == [0.1, 0.2, 0.3]) :-
    search:search_params([(_, force, range(0.1, 0.3, 0.1)), (_, position, range(0, 1))],
                         _, [fixed(_, force, Values)]).

test(samples_are_not_a_search_option, error(domain_error(search_option, samples(5)))) :-
    search:boundary_options([samples(5), tolerance(0.1)], _, _).
test(chance_needs_samples, error(domain_error(samples_with_chance, chance(0.9)))) :-
    search:belief_search([chance(0.9)], _).
test(samples_need_a_chance, error(domain_error(samples_with_chance, samples(5)))) :-
    search:belief_search([samples(5)], _).
test(chance_is_a_probability, error(domain_error(chance, 1.5))) :-
    search:belief_search([samples(5), chance(1.5)], _).
test(certify_at_least_one, error(domain_error(certify, certify(0)))) :-
    search:belief_search([samples(5), chance(0.9), certify(0)], _).
test(samples_reaching_the_certifying_worlds,
     error(domain_error(choosing_worlds(at_most(1000000)), samples(1000001)))) :-
    search:belief_search([samples(1000001), chance(0.9)], _).
test(a_belief_search, B == belief(16, 0.8, 5)) :-
    search:best_options([samples(16), chance(0.8), certify(5), timeout(9)], Own, Pass),
    Pass == [timeout(9)],
    search:belief_search(Own, B).
test(no_belief, B == none) :-
    search:belief_search([max_projections(4)], B).
test(worlds_are_not_a_search_option, error(domain_error(search_option, worlds(0, 2)))) :-
    search:best_options([worlds(0, 2)], _, _).

test(errors_have_messages) :-
    forall(member(E, [ domain_error(one_range_parameter, [a, b]),
                       domain_error(range_parameters, []),
                       domain_error(search_range, range(1, 1)),
                       domain_error(search_option, seed(1)),
                       domain_error(max_projections(at_least(7)), max_projections(3)) ]),
           ( message_to_codes(error(E, _), Codes), assertion(Codes \== []) )).

message_to_codes(Term, Codes) :-
    '$messages':translate_message(Term, Lines, []),
    with_output_to(codes(Codes), print_message_lines(current_output, '', Lines)).

:- end_tests(search).
