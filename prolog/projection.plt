:- begin_tests(projection, [ setup(set_prolog_flag(projection_max_timelines, 2)),
                             cleanup(forget_all) ]).
:- use_module(projection).
:- use_module(timeline).

forget_all :-
    retractall(projection:log_timeline(_, _)),
    forall(timeline_exists(TL), timeline_remove(TL)),
    set_prolog_flag(projection_max_timelines, 256).

translated(Log, TL) :-
    timeline_create(_{fluents: [[on, [egg1, table1], 0.0, 1.0]], events: []}, TL),
    projection:remember_timeline(Log, TL).

test(only_the_most_recent_translations_are_kept, Kept == [b-T2, c-T3]) :-
    translated(a, T1), translated(b, T2), translated(c, T3),
    findall(L-T, projection:log_timeline(L, T), Kept),
    assertion(\+ timeline_exists(T1)),
    assertion(timeline_exists(T3)).

test(translating_a_bag_again_replaces_its_timeline, Kept == [d-T5]) :-
    forget_all, set_prolog_flag(projection_max_timelines, 2),
    translated(d, _), translated(d, T5),
    findall(L-T, projection:log_timeline(L, T), Kept).

test(a_stepped_range_without_values_is_an_error,
     error(domain_error(parameter_range, range(5, 1, 1)))) :-
    parameter_values(range(5, 1, 1), _).
test(a_stepped_range_of_one_value, Vs == [5.0]) :-
    parameter_values(range(5, 5, 1), Vs).
test(an_only_combination_outside_the_parameters_is_an_error,
     error(domain_error(params_combination, [3]))) :-
    projection:only_combinations([only([[5], [3]])], [choice(_, force, [1, 5])],
                                 [params{force: 1}, params{force: 5}], _).
test(only_keeps_the_combinations_given, All == [params{force: 5}]) :-
    projection:only_combinations([only([[5]])], [choice(_, force, [1, 5])],
                                 [params{force: 1}, params{force: 5}], All).

:- end_tests(projection).
