:- module(temporal,
          [ before/2,                   % ?Time1, ?Time2
            after/2,                    % ?Time1, ?Time2
            meets/2,                    % ?Time1, ?Time2
            met_by/2,                   % ?Time1, ?Time2
            overlaps/2,                 % ?Time1, ?Time2
            overlapped_by/2,            % ?Time1, ?Time2
            starts/2,                   % ?Time1, ?Time2
            started_by/2,               % ?Time1, ?Time2
            during/2,                   % ?Time1, ?Time2
            contains/2,                 % ?Time1, ?Time2
            finishes/2,                 % ?Time1, ?Time2
            finished_by/2,              % ?Time1, ?Time2
            equals/2,                   % ?Time1, ?Time2
            allen_relation/3,           % ?Relation, +Time1, +Time2
            time_within/2,              % +Point, +Interval
            time_start/2,               % +Time, -Start
            time_end/2,                 % +Time, -End
            duration/2,                 % +Time, -Seconds
            is_time/1,                  % @Term
            must_be_time/1,             % @Term
            time_epsilon/1              % -Seconds
          ]).
:- autoload(library(error),
            [ type_error/2, domain_error/2, instantiation_error/1, must_be/2 ]).

/** <module> Time points, intervals and Allen's interval relations

A _time_ is either

  - a _point_: a finite number, seconds from the start of a projection, or
  - an _interval_ `interval(Start, End)`: Start a finite number, End a
    finite number with `Start =< End`, or the atom `inf` for an interval
    that is still open (a fluent that holds until the end of time).  A float
    infinity is accepted for `inf`.  `interval(S, S)` is allowed and behaves
    like the point S.

Floats are compared with the tolerance time_epsilon/1 (1.0e-9 s): two time
values whose difference is at most that are equal, and `A < B` only holds if
B exceeds A by more than the tolerance.  Simulation times are sums of fixed
steps, so exact float comparison would split instants that are the same.

Allen's 13 relations are defined on the end points, with a point P read as
the interval `interval(P, P)`.  Exactly one relation holds between any two
times, also for points: equalities of end points are decided first
(equals, starts, started_by, finishes, finished_by, then meets, met_by), then
the strict orders.  So a point and an interval relate by one of before,
starts, during, finishes or after, and two points by before, equals or after:

```
?- allen_relation(R, interval(1, 3), interval(3, 5)).
R = meets.
?- allen_relation(R, 3, interval(3, 5)).
R = starts.
?- before(interval(1, 2), 2.5).
true.
```

before/2 is strict: Time1 ends more than the tolerance before Time2 starts.

*Unbound times*: the relation predicates (before/2 ... equals/2) are tests
on two times.  When an argument is not yet ground, the test is delayed
(with freeze/2) until both are ground, and then run.  This lets a query
name a time before the goal that binds it, as in the paper's query
`after(T2, T1), holds(F, T2)`: holds/2 binds T2 to each interval of a
fluent and the delayed `after` test keeps the intervals that lie after T1.
A relation whose times never get bound succeeds with a residual goal.
allen_relation/3 and the other predicates need bound times.
*/

%!  time_epsilon(-Seconds:float) is det.
%
%   The tolerance with which time values are compared: 1.0e-9 s.

time_epsilon(1.0e-9).

                 /*******************************
                 *      ALLEN'S RELATIONS       *
                 *******************************/

%!  before(?Time1, ?Time2) is semidet.
%!  after(?Time1, ?Time2) is semidet.
%!  meets(?Time1, ?Time2) is semidet.
%!  met_by(?Time1, ?Time2) is semidet.
%!  overlaps(?Time1, ?Time2) is semidet.
%!  overlapped_by(?Time1, ?Time2) is semidet.
%!  starts(?Time1, ?Time2) is semidet.
%!  started_by(?Time1, ?Time2) is semidet.
%!  during(?Time1, ?Time2) is semidet.
%!  contains(?Time1, ?Time2) is semidet.
%!  finishes(?Time1, ?Time2) is semidet.
%!  finished_by(?Time1, ?Time2) is semidet.
%!  equals(?Time1, ?Time2) is semidet.
%
%   Allen's interval relations between two times, named as Time1 Relation
%   Time2: before(interval(1,2), 3) reads "1..2 is before 3".  See the
%   module documentation for points and for unbound arguments.
%
%   @error type_error(time, T) if a bound argument is not a time.
%   @error domain_error(time, T) if it is an interval that ends before it
%          starts, or a point that is not finite.

before(T1, T2)        :- relation(before, T1, T2).
after(T1, T2)         :- relation(after, T1, T2).
meets(T1, T2)         :- relation(meets, T1, T2).
met_by(T1, T2)        :- relation(met_by, T1, T2).
overlaps(T1, T2)      :- relation(overlaps, T1, T2).
overlapped_by(T1, T2) :- relation(overlapped_by, T1, T2).
starts(T1, T2)        :- relation(starts, T1, T2).
started_by(T1, T2)    :- relation(started_by, T1, T2).
during(T1, T2)        :- relation(during, T1, T2).
contains(T1, T2)      :- relation(contains, T1, T2).
finishes(T1, T2)      :- relation(finishes, T1, T2).
finished_by(T1, T2)   :- relation(finished_by, T1, T2).
equals(T1, T2)        :- relation(equals, T1, T2).

% Ground arguments are checked at once, so a wrong type is reported where
% it is written even if the other argument is still unbound.
relation(Rel, T1, T2) :-
    check_if_ground(T1),
    check_if_ground(T2),
    term_variables(T1-T2, Vars),
    (   Vars = [V|_]
    ->  freeze(V, relation(Rel, T1, T2))
    ;   endpoints(T1, S1, E1),
        endpoints(T2, S2, E2),
        classify(S1, E1, S2, E2, Rel0),
        Rel0 == Rel
    ).

check_if_ground(T) :-
    (   ground(T) -> must_be_time(T) ; true ).

%!  allen_relation(?Relation, +Time1, +Time2) is semidet.
%
%   Relation is the one Allen relation (an atom such as `before`, `meets`,
%   `during`, ...) that holds between Time1 and Time2.
%
%   @error instantiation_error if Time1 or Time2 is not ground.
%   @error type_error(time, T), domain_error(time, T) as for before/2.
%   @error domain_error(allen_relation, Relation) if Relation is bound
%          to something else than the name of a relation.

allen_relation(Rel, T1, T2) :-
    must_be_time(T1),
    must_be_time(T2),
    (   var(Rel)
    ->  true
    ;   must_be(atom, Rel),
        (   relation_name(Rel) -> true ; domain_error(allen_relation, Rel) )
    ),
    endpoints(T1, S1, E1),
    endpoints(T2, S2, E2),
    classify(S1, E1, S2, E2, Rel0),
    Rel = Rel0.

relation_name(before).
relation_name(after).
relation_name(meets).
relation_name(met_by).
relation_name(overlaps).
relation_name(overlapped_by).
relation_name(starts).
relation_name(started_by).
relation_name(during).
relation_name(contains).
relation_name(finishes).
relation_name(finished_by).
relation_name(equals).

% classify(+S1, +E1, +S2, +E2, -Relation): the clauses are tried in order;
% deciding the equalities first makes the relation unique for points too.
classify(S1, E1, S2, E2, Rel) :-
    (   eq(S1, S2), eq(E1, E2) -> Rel = equals
    ;   eq(S1, S2) -> ( lt(E1, E2) -> Rel = starts ; Rel = started_by )
    ;   eq(E1, E2) -> ( lt(S2, S1) -> Rel = finishes ; Rel = finished_by )
    ;   eq(E1, S2) -> Rel = meets
    ;   eq(S1, E2) -> Rel = met_by
    ;   lt(E1, S2) -> Rel = before
    ;   lt(E2, S1) -> Rel = after
    ;   lt(S1, S2) -> ( lt(E1, E2) -> Rel = overlaps ; Rel = contains )
    ;   lt(E1, E2) -> Rel = during
    ;   Rel = overlapped_by
    ).

                 /*******************************
                 *       POINTS, INTERVALS      *
                 *******************************/

%!  time_within(+Point, +Time) is semidet.
%
%   True if Point lies in Time, end points included (within the
%   tolerance).  Time is an interval or a point (then Point must equal it).
%
%   @error type_error(number, Point) if Point is not a number.
%   @error type_error(time, T), domain_error(time, T) as for before/2.

time_within(P, T) :-
    must_be_time(P),
    (   number(P) -> true ; type_error(number, P) ),
    must_be_time(T),
    endpoints(T, S, E),
    \+ lt(P, S),
    \+ lt(E, P).

%!  time_start(+Time, -Start:number) is det.
%!  time_end(+Time, -End) is det.
%
%   Start and end of Time; both are Time itself for a point.  End is the
%   atom `inf` for an open interval.
%
%   @error type_error(time, T), domain_error(time, T) as for before/2.

time_start(T, S) :-
    must_be_time(T),
    endpoints(T, S, _).

time_end(T, E) :-
    must_be_time(T),
    endpoints(T, _, E).

%!  duration(+Time, -Seconds) is det.
%
%   Seconds is the length of Time: 0 for a point, `End - Start` for an
%   interval and the atom `inf` for an open interval.
%
%   @error type_error(time, T), domain_error(time, T) as for before/2.

duration(T, D) :-
    must_be_time(T),
    endpoints(T, S, E),
    (   E == inf -> D = inf
    ;   D is E - S
    ).

%!  is_time(@Term) is semidet.
%
%   True if Term is a time: a finite number or a proper interval.

is_time(T) :-
    catch(must_be_time(T), error(_, _), fail).

%!  must_be_time(@Term) is det.
%
%   Succeed if Term is a time, otherwise throw the error below.
%
%   @error instantiation_error if Term is not ground.
%   @error type_error(time, Term) if Term is neither a number nor an
%          interval of numbers.
%   @error domain_error(time, Term) if Term is a point that is not finite,
%          or an interval whose start is not finite or is after its end.

must_be_time(T) :-
    var(T), !,
    instantiation_error(T).
must_be_time(T) :-
    number(T), !,
    (   finite(T) -> true ; domain_error(time, T) ).
must_be_time(T) :-
    T = interval(S, E), !,
    (   var(S) -> instantiation_error(S)
    ;   var(E) -> instantiation_error(E)
    ;   number(S), ( number(E) ; E == inf )
    ->  norm_end(E, E1),
        (   finite(S), ( E1 == inf ; finite(E1) ), \+ lt(E1, S)
        ->  true
        ;   domain_error(time, T)
        )
    ;   type_error(time, T)
    ).
must_be_time(T) :-
    type_error(time, T).

finite(X) :-
    X =:= X,                            % not NaN
    abs(X) < inf.

norm_end(E, inf) :- E == inf, !.
norm_end(E, inf) :- float(E), E =:= inf, !.
norm_end(E, E).

% endpoints(+Time, -Start, -End): Time checked; End is a number or `inf`.
endpoints(interval(S, E0), S, E) :- !,
    norm_end(E0, E).
endpoints(P, P, P).

% Comparison with tolerance; `inf` is only equal to itself.
eq(A, B) :-
    (   ( A == inf ; B == inf )
    ->  A == B
    ;   time_epsilon(Eps),
        abs(A - B) =< Eps
    ).

lt(A, B) :-
    (   A == inf -> fail
    ;   B == inf -> true
    ;   time_epsilon(Eps),
        B - A > Eps
    ).
