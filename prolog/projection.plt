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

:- end_tests(projection).
