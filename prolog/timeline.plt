:- begin_tests(timeline, [cleanup(remove_all)]).
:- use_module(timeline).
:- use_module(temporal).

% The paper's egg scenario (section II): egg1 is grasped, dropped at 2.0
% and lies broken on the floor from 2.1 to 5.0.  Strings stand for the
% values that janus passes from Python.
egg_data(_{ fluents: [ ["contact", ["egg1", "gripper"], 0.5, 2.0],
                       [on, [egg1, table1], 0.0, 0.5],
                       ["on", ["egg1", "floor"], 2.1, 5.0],
                       [broken, [egg1], 2.1, 5.0],
                       [on, [cup1, table1], 0.0, 5.0],
                       [upside_down, [], 3.0, 4.0] ],
            events:  [ [grasp, [egg1], 0.5, 0.5],
                       ["drop", ["egg1"], 2.0, 2.0],
                       [break, [egg1], 2.1, 2.1],
                       [lift, [egg1, 0.3], 0.6, 1.8] ],
            quantities: [ [max_force, [egg1], 31.5], ["particles", [], 12] ],
            meta: _{program: "grasp_object", force: 11} }).

with_egg(TL) :-
    egg_data(D),
    timeline_create(D, TL).

remove_all :-
    forall(timeline_exists(TL), timeline_remove(TL)).

% the paper's query, literally, on the current timeline
test(paper_query, Fs == [broken(egg1), on(egg1, floor)]) :-
    with_egg(_),
    findall(F, ( occurs(Evt, T1), typeOf(Evt, dropping), objOf(Evt, egg1),
                 after(T2, T1), holds(F, T2), objOf(F, egg1) ),
            Fs0),
    msort(Fs0, Fs).
test(paper_query_binds_times, [T1-T2 == 2.0-interval(2.1, 5.0), nondet]) :-
    with_egg(_),
    occurs(Evt, T1), typeOf(Evt, dropping), objOf(Evt, egg1),
    after(T2, T1), holds(F, T2), objOf(F, egg1).
test(paper_grasping_query_break, nondet) :-
    with_egg(TL),
    occurs(break, _, TL),
    \+ occurs(slip, _, TL).
test(paper_turning_query, [T == interval(3.0, 4.0), nondet]) :-
    with_egg(TL),
    holds(upside_down, T, TL).

% creation and normalisation
test(create_fresh_ids, true(TL1 \== TL2)) :-
    with_egg(TL1), with_egg(TL2).
test(id_is_atom, true(atom(TL))) :- with_egg(TL).
test(strings_become_atoms, [F == contact(egg1, gripper), nondet]) :-
    with_egg(TL), holds(F, interval(0.5, 2.0), TL), F = contact(_, _).
test(zero_args_is_atom, true) :-
    with_egg(TL), holds(upside_down, 3.5, TL).
test(number_args_kept, [T == interval(0.6, 1.8)]) :-
    with_egg(TL), occurs(lift(egg1, 0.3), T, TL).
test(optional_keys, Props-Meta == [fluents(0), events(0), quantities(0)]-[]) :-
    timeline_create(_{fluents: [], events: []}, TL),
    findall(P, ( timeline_property(TL, P), P \= meta(_) ), Props),
    timeline_property(TL, meta(M)), dict_pairs(M, _, Meta).
test(properties, [M-NF-NE-NQ == "grasp_object"-6-4-2]) :-
    with_egg(TL),
    timeline_property(TL, meta(Meta)), get_dict(program, Meta, M),
    timeline_property(TL, fluents(NF)),
    timeline_property(TL, events(NE)),
    timeline_property(TL, quantities(NQ)).
test(duplicate_records_stored_once, N == 1) :-
    timeline_create(_{fluents: [[a, [], 0, 1], [a, [], 0, 1]], events: []}, TL),
    timeline_property(TL, fluents(N)).
test(open_end_inf, true) :-
    timeline_create(_{fluents: [[a, [], 0, inf]], events: []}, TL),
    holds(a, 1.0e9, TL).
test(missing_events, error(existence_error(key, events))) :-
    timeline_create(_{fluents: []}, _).
test(data_not_dict, error(type_error(dict, [])))  :-
    timeline_create([], _).
test(bad_record, error(type_error(fluent_record, [a, [], 1]))) :-
    timeline_create(_{fluents: [[a, [], 1]], events: []}, _).
test(bad_argument, error(type_error(atomic, f(x)))) :-
    timeline_create(_{fluents: [], events: [[a, [f(x)], 1, 1]]}, _).
test(reversed_times, error(domain_error(time, interval(2, 1)))) :-
    timeline_create(_{fluents: [[a, [], 2, 1]], events: []}, _).
test(failed_create_leaves_nothing, Before == After) :-
    findall(TL, timeline_exists(TL), Before),
    catch(timeline_create(_{fluents: [[a, [], 0, 1]], events: [x]}, _), _, true),
    findall(TL, timeline_exists(TL), After).

% removal and existence
test(remove) :-
    with_egg(TL), timeline_remove(TL), \+ timeline_exists(TL).
test(remove_unknown, error(existence_error(timeline, no_such))) :-
    timeline_remove(no_such).
test(exists_enumerates_in_creation_order, [L == [TL1, TL2]]) :-
    remove_all, with_egg(TL1), with_egg(TL2),
    findall(TL, timeline_exists(TL), L).
test(removed_facts_gone, fail) :-
    with_egg(TL), timeline_remove(TL), timeline:tl_fluent(TL, _, _).

% holds/3
test(holds_enumerates_intervals, L == [on(egg1, table1)-interval(0.0, 0.5),
                                       on(egg1, floor)-interval(2.1, 5.0)]) :-
    with_egg(TL), findall(F-T, (F = on(egg1, _), holds(F, T, TL)), L).
test(holds_at_point, Fs == [broken(egg1), on(cup1, table1), on(egg1, floor)]) :-
    with_egg(TL), findall(F, holds(F, 2.5, TL), Fs0), msort(Fs0, Fs).
test(holds_at_interval_end) :-
    with_egg(TL), holds(broken(egg1), 5.0, TL).
test(holds_not_after_end, fail) :-
    with_egg(TL), holds(broken(egg1), 5.1, TL).
test(holds_throughout, Fs == [broken(egg1), on(cup1, table1), on(egg1, floor)]) :-
    with_egg(TL), findall(F, holds(F, interval(2.5, 5.0), TL), Fs0), msort(Fs0, Fs).
test(holds_not_throughout, fail) :-
    with_egg(TL), holds(broken(egg1), interval(2.0, 3.0), TL).
test(holds_pattern_atom) :-
    with_egg(TL), holds(broken, 3, TL).
test(holds_partial_interval, [S-E == 2.1-5.0, nondet]) :-
    with_egg(TL), holds(broken(egg1), interval(S, E), TL).
test(holds_unknown_timeline, error(existence_error(timeline, nope))) :-
    holds(_, _, nope).
test(holds_unbound_timeline, error(instantiation_error)) :-
    holds(_, _, _).
test(holds_non_callable, error(type_error(callable, 42))) :-
    with_egg(TL), holds(42, _, TL).
test(holds_string_fluent, error(type_error(callable, "broken"))) :-
    with_egg(TL), holds("broken", _, TL).
test(holds_bad_time, error(type_error(time, soon))) :-
    with_egg(TL), holds(_, soon, TL).
test(fluent_intervals, L == [interval(0, 1), interval(2, 3)]) :-
    timeline_create(_{fluents: [[a, [], 2, 3], [a, [], 0, 1]], events: []}, TL),
    timeline_fluent_intervals(a, L, TL).

% occurs/3
test(occurs_point_time, [T == 2.0, nondet]) :-
    with_egg(TL), occurs(drop(egg1), T, TL).
test(occurs_at_point) :-
    with_egg(TL), occurs(drop(egg1), 2.0, TL).
test(occurs_during_own_interval) :-
    with_egg(TL), occurs(lift(egg1, _), 1.0, TL).
test(occurs_within_interval, Es == [break(egg1), drop(egg1)]) :-
    with_egg(TL), findall(E, occurs(E, interval(1.9, 3.0), TL), Es0), msort(Es0, Es).
test(occurs_not_at, fail) :-
    with_egg(TL), occurs(drop(egg1), 2.05, TL).
test(occurs_unknown_timeline, error(existence_error(timeline, nope))) :-
    occurs(_, _, nope).
test(occurs_non_callable, error(type_error(callable, 1.5))) :-
    with_egg(TL), occurs(1.5, _, TL).

% holds/3 and occurs/3 share their code; each sees only its own records
test(holds_not_events, fail) :-
    with_egg(TL), holds(drop, _, TL).
test(occurs_not_fluents, fail) :-
    with_egg(TL), occurs(upside_down, _, TL).
test(occurs_not_fluents_at_point, fail) :-
    with_egg(TL), occurs(broken(_), 3.0, TL).

% quantities
test(quantity, [V =:= 31.5, nondet]) :-
    with_egg(TL), quantity(max_force(egg1), V, TL).
test(quantity_zero_args, V == 12) :-
    with_egg(TL), quantity(particles, V, TL).
test(quantity_current, [V =:= 31.5, nondet]) :-
    with_egg(_), quantity(max_force(egg1), V).

% typeOf/objOf
test(type_of_gerund) :- typeOf(drop(egg1), dropping).
test(type_of_functor) :- typeOf(drop(egg1), drop).
test(type_of_enumerates, all(T == [drop, dropping])) :- typeOf(drop(egg1), T).
test(type_of_fluent, [T == broken, nondet]) :- typeOf(broken(egg1), T).
test(type_of_wrong, fail) :- typeOf(drop(egg1), slipping).
test(type_of_generates, all(E == [drop(egg1)])) :-
    with_egg(_), typeOf(E, dropping).
test(obj_of_any_argument, all(O == [egg1, gripper])) :-
    objOf(contact(egg1, gripper), O).
test(obj_of_second_argument) :- objOf(contact(gripper, egg1), egg1).
test(obj_of_skips_numbers, all(O == [egg1])) :- objOf(lift(egg1, 0.3), O).
test(obj_of_once, all(O == [a])) :- objOf(f(a, a), O).
test(obj_of_atom_term, fail) :- objOf(upside_down, _).
test(obj_of_non_callable, error(type_error(callable, 3))) :- objOf(3, _).

% the current timeline
test(current_is_latest, TL == TL2) :-
    with_egg(_), with_egg(TL2), current_timeline(TL).
test(current_after_remove, TL == TL1) :-
    with_egg(TL1), with_egg(TL2), timeline_remove(TL2), current_timeline(TL).
test(no_current_timeline, error(existence_error(timeline, current))) :-
    remove_all, holds(_, _).
test(with_timeline_selects, [N == 0]) :-
    with_egg(TL1),
    timeline_create(_{fluents: [], events: []}, _),
    with_timeline(TL1, aggregate_all(count, holds(_, _), N0)),
    aggregate_all(count, holds(_, _), N),
    N0 == 6.
test(with_timeline_current, [TL == TL1, nondet]) :-
    with_egg(TL1), with_egg(_),
    with_timeline(TL1, current_timeline(TL)).
test(with_timeline_ends_after_exit, [TL == TL2, nondet]) :-
    with_egg(TL1), with_egg(TL2),
    with_timeline(TL1, member(_, [a, b])),
    current_timeline(TL).
test(with_timeline_kept_on_backtracking, L == [TL1-TL1, TL1-TL1]) :-
    with_egg(TL1), with_egg(_),
    findall(A-B, with_timeline(TL1, ( current_timeline(A), member(_, [x, y]),
                                       current_timeline(B) )),
            L).
test(with_timeline_nested, [L == [TL2, TL1], nondet]) :-
    with_egg(TL1), with_egg(TL2),
    with_timeline(TL1, ( with_timeline(TL2, current_timeline(A)),
                         current_timeline(B) )),
    L = [A, B].
test(with_timeline_after_error, TL == TL2) :-
    with_egg(TL1), with_egg(TL2),
    catch(with_timeline(TL1, throw(oops)), oops, true),
    current_timeline(TL).
test(with_timeline_unknown, error(existence_error(timeline, nope))) :-
    with_timeline(nope, true).
test(with_timeline_per_thread, [TL == TL2, nondet]) :-
    with_egg(TL1), with_egg(TL2),
    message_queue_create(Q),
    with_timeline(TL1,
                  ( thread_create(( current_timeline(X),
                                    thread_send_message(Q, X) ), Id, []),
                    thread_join(Id, true) )),
    thread_get_message(Q, TL),
    message_queue_destroy(Q).

% the query service's sandbox accepts the query form
test(sandbox_accepts_paper_query) :-
    safe_goal(( occurs(Evt, T1), typeOf(Evt, dropping), objOf(Evt, egg1),
                after(T2, T1), holds(F, T2), objOf(F, egg1) )).
test(sandbox_accepts_with_timeline) :-
    safe_goal(with_timeline(timeline_1, holds(_, _))).
% the readers are sandbox primitives; the goal of with_timeline/2 is still checked
test(sandbox_readers_are_primitives) :-
    forall(member(H, [holds(_, _, _), occurs(_, _, _), quantity(_, _), typeOf(_, _),
                      timeline_fluent_intervals(_, _, _), current_timeline(_)]),
           sandbox:safe_primitive(timeline:H)).
test(sandbox_store_writers_not_readers, fail) :-
    sandbox:safe_primitive(timeline:with_timeline(_, _)).
test(sandbox_refuses_unsafe_goal_in_with_timeline, error(permission_error(_, _, _))) :-
    safe_goal(with_timeline(timeline_1, shell(ls))).

:- use_module(library(sandbox), [safe_goal/1]).

% messages
test(message_unknown_timeline, true(sub_string(Msg, 0, _, _, "Unknown timeline: nope"))) :-
    catch(holds(_, _, nope), E, true),
    message_string(E, Msg).
test(message_no_timeline, true(sub_string(Msg, 0, _, _, "No timeline exists"))) :-
    remove_all,
    catch(occurs(_, _), E, true),
    message_string(E, Msg).

message_string(E, Msg) :-
    message_to_codes(E, Codes),
    string_codes(Msg, Codes).

message_to_codes(E, Codes) :-
    '$messages':translate_message(E, Lines, []),
    with_output_to(codes(Codes), print_message_lines(current_output, '', Lines)).


% vocabulary: what a projection's timeline can name (timeline/vocabulary.py's form)
grasp_vocabulary(_{ fluents: [["in_gripper", ["object"]], [contact, [object, object]],
                              [upside_down, [object]]],
                    events: [[break, [object]], [slip, [object]], [drop, [object]]],
                    quantities: [[max_load, [object]], [sampled, [object, property]]],
                    objects: ["egg1", table1, pr2_robot, pancake1] }).

with_vocabulary(TL) :-
    grasp_vocabulary(V),
    timeline_create(_{ fluents: [[in_gripper, [egg1], 1.0, 2.0],
                                 [contact, [egg1, pr2_robot], 1.0, 2.0]],
                       events: [[break, [egg1], 1.5, 1.5]],
                       quantities: [[max_load, [egg1], 12.0]],
                       vocabulary: V, meta: _{scenario: "grasping"} }, TL).

test(an_unknown_event_is_an_existence_error, error(existence_error(event, brake), _)) :-
    with_vocabulary(TL), \+ occurs(brake, _, TL).
test(an_unknown_fluent_is_an_existence_error,
     error(existence_error(fluent, in_griper(egg1)), _)) :-
    with_vocabulary(TL), holds(in_griper(egg1), _, TL).
test(an_unknown_quantity_is_an_existence_error,
     error(existence_error(quantity, max_lod(egg1)), _)) :-
    with_vocabulary(TL), quantity(max_lod(egg1), _, TL).
test(an_object_not_in_the_scenario_is_an_existence_error,
     error(existence_error(entity, egg2), _)) :-
    with_vocabulary(TL), occurs(break(egg2), _, TL).
test(an_object_in_a_later_argument_is_checked, error(existence_error(entity, gripper), _)) :-
    with_vocabulary(TL), holds(contact(egg1, gripper), _, TL).
test(a_known_name_with_another_arity_is_an_existence_error,
     error(existence_error(event, slip(egg1, fast)), _)) :-
    with_vocabulary(TL), occurs(slip(egg1, fast), _, TL).
test(a_known_event_that_did_not_happen_fails, fail) :-
    with_vocabulary(TL), occurs(slip, _, TL).
test(a_known_object_that_did_not_break_fails, fail) :-
    with_vocabulary(TL), occurs(break(pancake1), _, TL).
test(a_known_quantity_absent_from_the_timeline_fails, fail) :-
    with_vocabulary(TL), quantity(sampled(egg1, friction), _, TL).
test(a_property_argument_is_not_an_object, fail) :-
    with_vocabulary(TL), quantity(sampled(egg1, no_such_property), _, TL).
test(variables_range_freely, Es == [break(egg1)]) :-
    with_vocabulary(TL), findall(E, occurs(E, _, TL), Es).
test(a_partly_bound_term_ranges_freely, Os == [egg1]) :-
    with_vocabulary(TL), findall(O, holds(in_gripper(O), _, TL), Os).
test(an_atom_pattern_of_a_known_name_matches, [T == 1.5]) :-
    with_vocabulary(TL), occurs(break, T, TL).
test(an_alias_of_a_known_name_is_known, fail) :-
    with_vocabulary(TL), holds(upsidedown, _, TL).
test(the_query_form_checks_the_current_timeline, error(existence_error(event, brake), _)) :-
    with_vocabulary(_), occurs(brake, _).
test(fluent_intervals_check_the_fluent, error(existence_error(fluent, in_griper), _)) :-
    with_vocabulary(TL), timeline_fluent_intervals(in_griper, _, TL).
test(an_unknown_type_is_an_existence_error, error(existence_error(type, droping), _)) :-
    with_vocabulary(_), typeOf(_, droping).
test(a_known_gerund_is_a_type, [Es == [break(egg1)]]) :-
    with_vocabulary(_), findall(E, typeOf(E, breaking), Es).
test(objof_an_unknown_object_is_an_existence_error, error(existence_error(entity, eg1), _)) :-
    with_vocabulary(_), objOf(_, eg1).
test(a_timeline_without_vocabulary_takes_any_name, fail) :-
    with_egg(TL), occurs(brake, _, TL).
test(one_scenarios_timelines_share_their_vocabulary, V1 == V2) :-
    grasp_vocabulary(D),
    timeline_vocabulary_create(D, V1),
    put_dict(objects, D, [pancake1, egg1, table1, pr2_robot], D2),
    timeline_vocabulary_create(D2, V2).
test(a_malformed_vocabulary_is_a_type_error, error(type_error(vocabulary, _))) :-
    timeline_create(_{fluents: [], events: [], vocabulary: _{fluents: []}}, _).
test(the_vocabulary_is_a_property, Es == [break/1, drop/1, slip/1]) :-
    with_vocabulary(TL), timeline_property(TL, vocabulary(V)), get_dict(events, V, Es).
test(the_message_names_the_term_and_the_known_ones) :-
    with_vocabulary(TL),
    catch(occurs(brake, _, TL), E, true),
    message_string(E, Msg),
    assertion(sub_string(Msg, _, _, _, "brake")),
    assertion(sub_string(Msg, _, _, _, "scenario grasping")),
    assertion(sub_string(Msg, _, _, _, "break/1, drop/1, slip/1")).
test(the_object_message_lists_the_objects) :-
    with_vocabulary(TL),
    catch(holds(in_gripper(egg2), _, TL), E, true),
    message_string(E, Msg),
    assertion(sub_string(Msg, _, _, _, "egg2 is no object of scenario grasping")),
    assertion(sub_string(Msg, _, _, _, "egg1, pancake1, pr2_robot, table1")).

% the terms a condition names on its timeline, before any timeline exists
test(a_condition_names_its_terms_through_negation_and_all_solutions,
     Terms =@= [event-brake, fluent-in_griper(_), quantity-max_lod(egg1), event-slip(egg1),
                fluent-on(egg1, _), type-dropping, entity-egg1]) :-
    timeline_condition_terms(
        user:( \+ occurs(brake, _, TL),
               findall(X, holds(in_griper(X), _, TL), _),
               forall(quantity(max_lod(egg1), V, TL), V > 1),
               (   aggregate_all(count, occurs(slip(egg1), _, TL), 0)
               ->  true
               ;   not(holds(on(egg1, _), _))
               ),
               occurs(E, _, TL), typeOf(E, dropping), objOf(E, egg1) ),
        TL, Terms).
test(a_condition_on_another_timeline_is_not_this_ones, Terms == []) :-
    timeline_condition_terms(( occurs(brake, _, Other), Other \== TL ), TL, Terms).
test(unbound_terms_are_left_out, Terms == []) :-
    timeline_condition_terms(( occurs(E, _, TL), holds(F, _, TL), E \== F ), TL, Terms).
test(a_checked_condition_term_outside_the_vocabulary_is_an_error,
     error(existence_error(event, brake), context(outcome_probability/7, _))) :-
    grasp_vocabulary(D),
    timeline_vocabulary_create(D, V),
    timeline_condition_terms(\+ occurs(brake, _, TL), TL, [Term]),
    timeline_check_term(V, context(outcome_probability/7, grasping), Term).
test(no_vocabulary_checks_nothing) :-
    timeline_check_term(none, context(outcome_probability/7, grasping), event-brake).

test(paper_spelling_upsidedown, T == interval(1.0, 2.0)) :-
    timeline_create(_{fluents: [[upside_down, [pancake1], 1.0, 2.0]], events: []}, TL),
    holds(upsidedown, T, TL),
    timeline_remove(TL).

:- end_tests(timeline).
