:- begin_tests(temporal).
:- use_module(temporal).

i(S, E, interval(S, E)).

% The 13 relations on proper intervals, each with its defining example.
test(before, R == before)               :- allen_relation(R, interval(1, 2), interval(3, 4)).
test(after, R == after)                 :- allen_relation(R, interval(3, 4), interval(1, 2)).
test(meets, R == meets)                 :- allen_relation(R, interval(1, 3), interval(3, 4)).
test(met_by, R == met_by)               :- allen_relation(R, interval(3, 4), interval(1, 3)).
test(overlaps, R == overlaps)           :- allen_relation(R, interval(1, 3), interval(2, 4)).
test(overlapped_by, R == overlapped_by) :- allen_relation(R, interval(2, 4), interval(1, 3)).
test(starts, R == starts)               :- allen_relation(R, interval(1, 2), interval(1, 4)).
test(started_by, R == started_by)       :- allen_relation(R, interval(1, 4), interval(1, 2)).
test(during, R == during)               :- allen_relation(R, interval(2, 3), interval(1, 4)).
test(contains, R == contains)           :- allen_relation(R, interval(1, 4), interval(2, 3)).
test(finishes, R == finishes)           :- allen_relation(R, interval(3, 4), interval(1, 4)).
test(finished_by, R == finished_by)     :- allen_relation(R, interval(1, 4), interval(3, 4)).
test(equals, R == equals)               :- allen_relation(R, interval(1, 4), interval(1, 4)).

test(named_predicates_agree_with_allen_relation,
     Rs == [before, after, meets, met_by, overlaps, overlapped_by, starts,
            started_by, during, contains, finishes, finished_by, equals]) :-
    findall(R,
            ( member(R-A-B,
                     [ before-(1-2)-(3-4), after-(3-4)-(1-2), meets-(1-3)-(3-4),
                       met_by-(3-4)-(1-3), overlaps-(1-3)-(2-4),
                       overlapped_by-(2-4)-(1-3), starts-(1-2)-(1-4),
                       started_by-(1-4)-(1-2), during-(2-3)-(1-4),
                       contains-(1-4)-(2-3), finishes-(3-4)-(1-4),
                       finished_by-(1-4)-(3-4), equals-(1-4)-(1-4) ]),
              A = S1-E1, B = S2-E2, i(S1, E1, I1), i(S2, E2, I2),
              call(R, I1, I2)
            ),
            Rs).

test(exactly_one_relation_holds, Counts == [1]) :-
    Ts = [0, 1, 2, 3, interval(0, 1), interval(1, 2), interval(0, 3),
          interval(1, 1), interval(2, inf), interval(0, inf)],
    Rels = [before, after, meets, met_by, overlaps, overlapped_by, starts,
            started_by, during, contains, finishes, finished_by, equals],
    findall(N,
            ( member(A, Ts), member(B, Ts),
              aggregate_all(count, (member(R, Rels), call(R, A, B)), N)
            ),
            Ns),
    sort(Ns, Counts).

test(relation_name_checked, fail) :- allen_relation(meets, interval(1, 2), interval(5, 6)).
test(unknown_relation_name, error(domain_error(allen_relation, sideways))) :-
    allen_relation(sideways, 1, 2).

% before/after: strict, on points, intervals and mixes
test(before_is_strict, fail) :- before(interval(1, 2), interval(2, 3)).
test(point_before_point) :- before(1, 2).
test(point_not_before_equal_point, fail) :- before(2, 2.0).
test(interval_before_point) :- before(interval(1, 2), 2.5).
test(point_before_interval) :- before(0.5, interval(1, 2)).
test(point_at_interval_start_is_not_before, fail) :- before(1, interval(1, 2)).
test(point_after_interval) :- after(2.1, interval(1, 2)).
test(point_after_point) :- after(2.1, 2.0).
test(interval_after_point) :- after(interval(2.1, 5.0), 2.0).
test(interval_starting_at_point_is_not_after, fail) :- after(interval(2.0, 5.0), 2.0).

% points and intervals relate by before, starts, during, finishes, after
test(point_interval_relations, Rs == [before, starts, during, finishes, after]) :-
    findall(R, ( member(P, [0, 1, 1.5, 2, 3]),
                 allen_relation(R, P, interval(1, 2)) ), Rs).
test(point_equals_point, R == equals) :- allen_relation(R, 2, 2.0).
test(point_equals_degenerate_interval, R == equals) :-
    allen_relation(R, 2, interval(2, 2)).

% tolerance
test(epsilon_value, E =:= 1.0e-9) :- time_epsilon(E).
test(equal_within_epsilon, R == equals) :-
    X is 0.1 + 0.2, allen_relation(R, X, 0.3).
test(meets_within_epsilon, R == meets) :-
    X is 0.1 + 0.2, allen_relation(R, interval(0, X), interval(0.3, 1)).
test(differences_above_epsilon_count, R == before) :-
    allen_relation(R, 1.0, 1.000001).

% open intervals
test(open_interval_contains, R == contains) :- allen_relation(R, interval(0, inf), interval(1, 2)).
test(open_intervals_finish_together, R == finishes) :-
    allen_relation(R, interval(1, inf), interval(0, inf)).
test(float_infinity_is_open_end, R == equals) :-
    X is inf, allen_relation(R, interval(0, X), interval(0, inf)).
test(open_interval_never_before, fail) :- before(interval(0, inf), 1.0e300).

% unbound times: the test waits until the time is bound
test(delayed_until_bound, fail) :- after(T, 2.0), T = interval(1, 3).
test(delayed_until_bound_succeeds, T == interval(2.1, 5.0)) :-
    after(T, 2.0), T = interval(2.1, 5.0).
test(delayed_filters_generator, Ts == [interval(3, 4)]) :-
    after(T, interval(0, 2)),
    findall(T, member(T, [interval(1, 2), interval(3, 4), 2]), Ts).
test(delayed_on_partial_interval, fail) :-
    before(interval(S, E), 3), S = 1, E = 4.
test(delayed_left_unbound_is_residual) :-
    before(T, 3), var(T), frozen(T, G), G \== true.
test(bound_argument_checked_before_delay, error(type_error(time, foo))) :-
    before(_, foo).

% accessors
test(duration_interval, D =:= 1.5) :- duration(interval(1, 2.5), D).
test(duration_point, D =:= 0) :- duration(3.0, D).
test(duration_open, D == inf) :- duration(interval(1, inf), D).
test(start_end_interval, S-E == 1-2) :- time_start(interval(1, 2), S), time_end(interval(1, 2), E).
test(start_end_point, S-E == 3-3) :- time_start(3, S), time_end(3, E).
test(end_open, E == inf) :- time_end(interval(0, inf), E).
test(within) :- time_within(1.5, interval(1, 2)).
test(within_closed_ends) :- time_within(2, interval(1, 2)).
test(within_epsilon) :- X is 2 + 1.0e-10, time_within(X, interval(1, 2)).
test(within_outside, fail) :- time_within(2.1, interval(1, 2)).
test(within_open) :- time_within(1.0e6, interval(1, inf)).
test(within_point) :- time_within(2, 2.0).
test(within_needs_point, error(type_error(number, interval(1, 2)))) :-
    time_within(interval(1, 2), interval(0, 3)).

% type checking
test(is_time_point) :- is_time(1).
test(is_time_interval) :- is_time(interval(1, 2)).
test(is_time_not, fail) :- is_time(foo).
test(atom_not_time, error(type_error(time, foo))) :- before(foo, 1).
test(string_not_time, error(type_error(time, "1"))) :- after(1, "1").
test(bad_interval_arity, error(type_error(time, interval(1)))) :- duration(interval(1), _).
test(non_number_endpoint, error(type_error(time, interval(a, 2)))) :- duration(interval(a, 2), _).
test(reversed_interval, error(domain_error(time, interval(2, 1)))) :- duration(interval(2, 1), _).
test(infinite_point, error(domain_error(time, X))) :- X is inf, duration(X, _).
test(open_start_is_not_a_time, error(type_error(time, interval(inf, inf)))) :-
    must_be_time(interval(inf, inf)).
test(nan_point, error(domain_error(time, _))) :- X is nan, time_start(X, _).
test(unbound_in_allen_relation, error(instantiation_error)) :- allen_relation(_, _, 1).
test(unbound_in_duration, error(instantiation_error)) :- duration(_, _).

:- end_tests(temporal).
