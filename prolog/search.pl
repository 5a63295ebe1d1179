:- module(search,
          [ outcome_boundary/7,         % +Scenario, +Program, +Params, +Options, -Timeline,
                                        % :Condition, -Boundary
            best_parametrization/8      % +Scenario, +Program, +Params, +Options, -Timeline,
                                        % :Constraint, +Objective, -Best
          ]).
:- autoload(library(apply),
            [maplist/2, maplist/3, maplist/4, foldl/4, partition/4, exclude/3]).
:- autoload(library(aggregate), [aggregate_all/3]).
:- autoload(library(pairs), [pairs_keys_values/3]).
:- autoload(library(error),
            [ must_be/2, domain_error/2, existence_error/2, type_error/2,
              instantiation_error/1, uninstantiation_error/1 ]).
:- autoload(library(lists), [append/3, member/2, numlist/3, sum_list/2]).
:- use_module(library(janus), [py_call/2]).
:- autoload(library(thread), [concurrent/3]).
:- use_module(projection,
              [make_projection/5, projection_program/2, with_query_context/2,
               current_query_context/1, parameter_values/2,
               projection_check_condition/4, projection_check_quantity/3]).
:- use_module(timeline, [quantity/3, timeline_exists/1]).
:- use_module(robust, [below_certifying_worlds/1]).
:- use_module(uncertainty, [wilson_interval/4]).

:- meta_predicate
    outcome_boundary(+, +, +, +, -, 0, -),
    best_parametrization(+, +, +, +, -, 0, +, -).

/** <module> Adaptive search over a projection's parameters

make_projection/5 projects every combination of its parameters' values, a
grid.  The two predicates here project only where it tells something, over a
parameter given as `range(Low, High)` (no step): every projection is one
make_projection/5 call's, so it runs on the simulation workers, reuses an
identical projection's bag, and reports its progress to the `~/project`
action.  Where the grid of Table I over 0.5-20 N at 0.25 N needs 79 grasps,
outcome_boundary/7 finds its two force boundaries to 0.25 N with 15:

```
?- outcome_boundary(grasping, grasp_object,
                    [(F, force, range(0.5, 20)), (P, position, [0.0])],
                    [tolerance(0.25)], TL,
                    ( \+ occurs(slip, _, TL), \+ occurs(break, _, TL) ), B).
B = _{from:false, high:1.3125, low:1.109375, projections:11, to:true} ;
B = _{from:true, high:10.046875, low:9.84375, projections:4, to:false}.
```

best_parametrization/8 maximises a quantity of the timeline where a
constraint holds, with Optuna's TPE sampler asked for trials in batches that
run on all workers at once (projection_server/search.py):

```
?- best_parametrization(pouring, pour,
                        [(A, angle, range(1.8, 2.2)), (T, time, [1.0]), (P, position, [0.0])],
                        [max_projections(16), seed(1)], TL,
                        \+ occurs(spill(_), _, TL), particles_on(pancake_maker1), Best).
```

In both, Params is make_projection/5's list of `(Var, Name, Range)`: the
parameters whose Range is `range(Low, High)` are searched (Low < High, any
number between them); the others (a list of values, or `range(Low, High,
Step)`) are enumerated as make_projection/5 does, one search per combination
of their values, on backtracking, with their variables bound to it.  The
Condition or Constraint is a goal on the variable Timeline: it runs once per
projection, with Timeline bound to that projection's timeline, and its
bindings are undone.  It may also use the parameters' variables.
*/

%!  outcome_boundary(+Scenario, +Program, +Params, +Options, -Timeline,
%!                   :Condition, -Boundary) is nondet.
%
%   Boundary is a change of Condition along the one parameter of Params
%   given as `range(Low, High)`: the interval between two values of it where
%   Condition (a goal on Timeline, see the module doc) holds at one end and
%   not at the other:
%
%   ```
%   _{low: L, high: H, from: From, to: To, projections: N}
%   ```
%
%   From and To are `true` or `false`, Condition's truth at L and at H.  One
%   solution per change, in the order of the range; none if Condition is the
%   same all along the coarse pass.  The search projects a coarse pass of
%   evenly spaced values, Low and High included, then bisects every interval
%   between two of them where Condition changes until it is at most the
%   tolerance wide.  The projections of a round (the coarse pass; the
%   midpoints of all intervals still too wide) are one make_projection/5
%   call, so they run on all workers at once.  N counts the projections of
%   the change: its midpoints, and for the first change also the coarse
%   pass, so the counts of the solutions add up to the search's.  A
%   projection identical to an earlier one (in this search or before) counts,
%   and reuses its bag.  Two changes closer together than the coarse pass's
%   spacing may hide each other.
%
%   Params other than the searched one are enumerated: one search per
%   combination of their values, on backtracking.  Timeline and the searched
%   parameter's variable are left unbound.  Options:
%
%     - tolerance(+Width): the widest interval answered (default: a
%       hundredth of High - Low);
%     - max_projections(+N): the most projections one search makes
%       (default 64), at least the coarse pass's.  When they are spent,
%       the intervals found so far are answered as they are, wider than
%       Width;
%     - coarse(+K): the values of the coarse pass (default 7, at least 2;
%       fewer when the tolerance needs fewer: ceiling((High - Low) / Width)
%       + 1);
%     - the options of make_projection/5 (timeout(Seconds), physics(Dict),
%       ...), passed on to each of its calls.  A number is the timeout.
%
%   A search past the query's time limit is stopped as any query is
%   (error kind `timeout`).
%
%   @error domain_error(one_range_parameter, Names) unless exactly one
%          parameter of Params is `range(Low, High)`; Names are those that are
%   @error domain_error(search_range, range(Low, High)) unless Low < High
%   @error domain_error(search_option, Option) for best_parametrization/8's
%          options; domain_error(tolerance, tolerance(T)),
%          domain_error(coarse, coarse(K)) for values out of their domain,
%          domain_error(max_projections(at_least(K)), max_projections(N)) for a
%          budget smaller than the coarse pass;
%          make_projection/5's domain_error(projection_option, O) for any
%          other unknown option
%   @error uninstantiation_error(X) for a bound Timeline or searched variable
%   @error existence_error(Kind, Term) for a fluent, event, quantity, type or
%          object (Kind `entity`) that Condition names on Timeline and no
%          timeline of Scenario can have (projection_check_condition/4),
%          before anything is projected
%   @error make_projection/5's errors, such as domain_error(parameter_value,
%          Name=Value) for a range beyond the program's parameter

outcome_boundary(Scenario, Program, Params, Options, Timeline, Condition, Boundary) :-
    must_be(atom, Scenario),
    must_be(list, Params),
    must_be_unbound(Timeline),
    boundary_options(Options, Own, Pass),
    search_params(Params, Searched, Fixed),
    (   Searched = [searched(Var, Name, Low, High)]
    ->  true
    ;   maplist([searched(_, N, _, _), N]>>true, Searched, Names),
        domain_error(one_range_parameter, Names)
    ),
    boundary_settings(Own, Low, High, Tolerance, Max, K),
    check_ends(Program, [searched(Var, Name, Low, High)]),
    projection_check_condition(Scenario, Timeline, Condition, outcome_boundary/7),
    fixed_combination(Fixed, FixedParams),
    Probe = probe(Scenario, Program, Var, Name, FixedParams, Pass, Timeline, Condition),
    boundaries(Probe, Low, High, Tolerance, Max, K, Boundaries),
    member(Boundary, Boundaries).

% boundary_settings(+Own, +Low, +High, -Tolerance, -Max, -K): the search's options,
% K the values of its coarse pass: coarse(K), or fewer when the tolerance needs fewer.
boundary_settings(Own, Low, High, Tolerance, Max, K) :-
    DefaultTolerance is (High - Low) / 100,
    option_value(tolerance, Own, DefaultTolerance, Tolerance),
    option_value(max_projections, Own, 64, Max),
    option_value(coarse, Own, 7, Coarse),
    check_number(tolerance, Tolerance, 0, exclusive),
    check_integer(max_projections, Max, 2),
    check_integer(coarse, Coarse, 2),
    K is max(2, min(Coarse, ceiling((High - Low) / Tolerance - 1.0e-9) + 1)),
    (   Max >= K
    ->  true
    ;   domain_error(max_projections(at_least(K)), max_projections(Max))
    ).

% boundaries(+Probe, +Low, +High, +Tolerance, +Max, +K, -Boundaries)
boundaries(Probe, Low, High, Tolerance, Max, K, Boundaries) :-
    coarse_points(Low, High, K, Points),
    probe(Probe, Points, Outcomes),
    changes(Outcomes, Intervals0),
    bisect(Probe, Intervals0, Tolerance, Max, K, Intervals),
    boundary_dicts(Intervals, K, Boundaries).

coarse_points(Low, High, K, Points) :-
    Last is K - 1,
    numlist(0, Last, Is),
    maplist([I, V]>>( I =:= Last -> V = High ; rounded(Low + I * (High - Low) / Last, V) ),
            Is, Points).

% changes(+Outcomes, -Intervals): the neighbours in the coarse pass whose outcomes
% differ, as change(Low, High, From, To, Projections).
changes([V1-H1, V2-H2|T], Intervals) :- !,
    (   H1 == H2
    ->  Intervals = Intervals1
    ;   Intervals = [change(V1, V2, H1, H2, 0)|Intervals1]
    ),
    changes([V2-H2|T], Intervals1).
changes(_, []).

% bisect(+Probe, +Intervals0, +Tolerance, +Max, +Spent, -Intervals): halve the intervals
% wider than Tolerance, all of one round in one make_projection call, until none is or
% Max projections are spent.
bisect(Probe, Intervals0, Tolerance, Max, Spent, Intervals) :-
    Left is Max - Spent,
    findall(M, ( member(change(L, H, _, _, _), Intervals0),
                 splittable(L, H, Tolerance, M) ), Mids0),
    take(Left, Mids0, Mids),
    (   Mids == []
    ->  Intervals = Intervals0
    ;   probe(Probe, Mids, Outcomes),
        maplist(narrow(Outcomes), Intervals0, Intervals1),
        length(Mids, N),
        Spent1 is Spent + N,
        bisect(Probe, Intervals1, Tolerance, Max, Spent1, Intervals)
    ).

% splittable(+Low, +High, +Tolerance, -Mid): the interval is wider than Tolerance and
% its (rounded) midpoint lies strictly inside it.
splittable(L, H, Tolerance, M) :-
    H - L > Tolerance,
    rounded((L + H) / 2, M),
    M > L, M < H.

narrow(Outcomes, change(L, H, From, To, N), Interval) :-
    (   rounded((L + H) / 2, M),
        memberchk(M-Holds, Outcomes)
    ->  N1 is N + 1,
        (   Holds == From
        ->  Interval = change(M, H, From, To, N1)
        ;   Interval = change(L, M, From, To, N1)
        )
    ;   Interval = change(L, H, From, To, N)
    ).

boundary_dicts([], _, []).
boundary_dicts([change(L, H, From, To, N0)|T], Coarse, [B|Bs]) :-
    N is N0 + Coarse,
    B = _{low: L, high: H, from: From, to: To, projections: N},
    boundary_dicts(T, 0, Bs).

% probe(+Probe, +Values, -Outcomes): Outcomes are Value-Holds, Holds `true` or `false`
% whether the condition holds at Value: for probe(...), projections of Values of the
% searched parameter in one make_projection call; for goal(G), call(G, Values, Outcomes)
% (the search without simulations, for its tests).
probe(goal(G), Values, Outcomes) :- !,
    call(G, Values, Outcomes).
probe(probe(Scenario, Program, Var, Name, FixedParams, Options, Timeline, Condition),
      Values, Outcomes) :-
    findall(V-Holds,
            ( make_projection(Scenario, Program, [(Var, Name, Values)|FixedParams], Options,
                              TL),
              V = Var,
              truth(Timeline, TL, Condition, Holds) ),
            Outcomes).

% truth(?Timeline, +TL, :Goal, -Holds): Holds is whether Goal holds with Timeline = TL.
truth(Timeline, TL, Goal, Holds) :-
    (   \+ \+ ( Timeline = TL, call(Goal) )
    ->  Holds = true
    ;   Holds = false
    ).

%!  best_parametrization(+Scenario, +Program, +Params, +Options, -Timeline,
%!                       :Constraint, +Objective, -Best) is nondet.
%
%   Best is the projection, among those the search makes, with the largest
%   value of the quantity Objective (quantity/3, e.g.
%   `particles_on(pancake_maker1)`; its first value) where Constraint (a goal
%   on Timeline, see the module doc) holds:
%
%   ```
%   _{params: Params, value: V, projections: N}
%   ```
%
%   Params is a dict of every parameter's value (Name: Value), V the
%   Objective's and N the number of projections the search made.  The
%   parameters given as `range(Low, High)` are searched by Optuna's TPE
%   sampler, seeded, driven through ask and tell (projection_server/search.py):
%   the trials come in batches of as many as there are simulation workers,
%   and a batch's projections run on all workers at once: with one searched
%   parameter the batch is one make_projection/5 call over its values; with
%   several (make_projection/5 would project the product of their values)
%   each trial is a make_projection/5 call in a thread of its own.  A trial whose Constraint fails is told to the
%   sampler as infeasible (Optuna's trial constraint, with its objective
%   value), one without an Objective value as failed; neither is a candidate.
%   The searched variables are bound to Best's values and Timeline to its
%   timeline.  No feasible projection with an Objective value: no solution.
%
%   The same seed, batch size, parameters and options give the same trials
%   and Best.
%   Params other than the searched ones are enumerated: one search per
%   combination of their values, on backtracking.  Options:
%
%     - max_projections(+N): the projections one search makes (default
%       32, at least 1);
%     - seed(+K): the sampler's seed, an integer (default 0);
%     - batch(+B): the trials asked for before any is told (default: the
%       number of simulation workers; give it to get the same trials on
%       a node with another number of workers);
%     - the options of make_projection/5, passed on to each of its calls.
%
%   Over a belief (the scenario's properties that are distributions), with
%
%     - samples(+N) and chance(+P): each trial is projected in the worlds
%       0..N-1 of the seed (the same for every trial); its value is the
%       mean of Objective over them, and it is feasible when the Wilson
%       lower bound (95 %) of the fraction of them in which Constraint
%       holds is at least P (0 < P < 1).  The sampler is told the gap P -
%       low as the trial's constraint.  A trial costs N projections; one
%       whose Wilson upper bound falls below P stops there (rounds of twice
%       the workers' worlds), so a clearly infeasible trial costs few.
%       max_projections defaults to 8 N.  Proving a chance of 0.95 takes 73
%       worlds without a failure, 0.9 takes 35, 0.8 takes 16;
%     - certify(+M): the best trial is then projected in M fresh worlds
%       (default: the fewest that could prove P, 59 for 0.95), those of
%       robust_parametrization/7's certificate, and Best gains `p`, `low`,
%       `high` (one-sided Clopper-Pearson bounds at 95 %), `n` and
%       `certified` (`low` >= P), all from the fresh worlds only.
%
%   Timeline is then the best parametrization's projection in the nominal
%   world.
%
%   @error domain_error(range_parameters, Params) if no parameter of Params
%          is `range(Low, High)`
%   @error domain_error(samples_with_chance, O) for samples(N) without
%          chance(P) or chance(P) without samples(N); domain_error(chance, P)
%          for P outside (0, 1); domain_error(choosing_worlds(at_most(1000000)),
%          samples(N)) for more worlds than lie below the certifying ones
%   @error domain_error(search_range, range(Low, High)) unless Low < High
%   @error domain_error(max_projections(at_least(N)), max_projections(M)) for a
%          budget M below one trial over a belief, its samples(N) worlds
%   @error domain_error(search_option, Option) for outcome_boundary/7's
%          options; domain_error(max_projections, max_projections(N)),
%          domain_error(batch, batch(B)) or type_error(integer, K) for
%          values out of their domain; make_projection/5's
%          domain_error(projection_option, O) for any other unknown option
%   @error type_error(number, Value) for an Objective whose value is no number
%   @error uninstantiation_error(X) for a bound Timeline or searched variable
%   @error existence_error(Kind, Term) for a fluent, event, quantity, type or
%          object (Kind `entity`) that Constraint names on Timeline, or an
%          Objective quantity, that no timeline of Scenario can have
%          (projection_check_condition/4), before anything is projected: a
%          misspelled Objective would leave every trial without a value
%   @error make_projection/5's errors

best_parametrization(Scenario, Program, Params, Options, Timeline, Constraint, Objective,
                     Best) :-
    must_be(atom, Scenario),
    must_be(list, Params),
    must_be_unbound(Timeline),
    must_be(callable, Objective),
    must_be(ground, Objective),
    best_options(Options, Own, Pass),
    search_params(Params, Searched, Fixed),
    (   Searched == []
    ->  domain_error(range_parameters, Params)
    ;   true
    ),
    belief_search(Own, Belief),
    (   Belief = belief(Samples, _, _)
    ->  DefaultMax is 8 * Samples
    ;   DefaultMax = 32
    ),
    option_value(max_projections, Own, DefaultMax, Max),
    option_value(seed, Own, 0, Seed),
    option_value(batch, Own, workers, Batch),
    check_integer(max_projections, Max, 1),
    trial_budget(Belief, Max),
    must_be(integer, Seed),
    (   Batch == workers
    ->  py_call('projection_server.projection':workers(), Workers)
    ;   check_integer(batch, Batch, 1),
        Workers = Batch
    ),
    check_ends(Program, Searched),
    projection_check_condition(Scenario, Timeline, Constraint, best_parametrization/8),
    projection_check_quantity(Scenario, Objective, best_parametrization/8),
    fixed_combination(Fixed, FixedParams),
    maplist([searched(_, N, L, H), [N, L, H]]>>true, Searched, Space),
    (   Belief = belief(_, _, _)
    ->  Pass1 = [seed(Seed)|Pass]
    ;   Pass1 = Pass
    ),
    Run = run(Scenario, Program, Searched, FixedParams, Pass1, Timeline, Constraint,
              Objective),
    setup_call_cleanup(
        py_call('projection_server.search':create(Space, Seed, Max), Study),
        (   Belief == none
        ->  optimise(Run, Study, Workers, Max, 0, Spent0, none, Found)
        ;   py_call('projection_server.projection':workers(), Workers0),
            optimise_belief(Run, Study, Belief, Workers, Workers0, Max, 0, Spent0, none,
                            Found)
        ),
        py_call('projection_server.search':release(Study))),
    Found = best(Values, Value, _, TL),
    maplist(bind_searched(Values), Searched),
    foldl([(_, N, [V]), D0, D]>>put_dict(N, D0, V, D), FixedParams, Values, AllValues),
    (   Belief = belief(_, Chance, Certify)
    ->  certify_best(Run, Values, Certify, Successes),
        Spent is Spent0 + Certify,
        Risk is 1 - Chance,
        py_call('projection_server.selection':certificate(Successes, Certify, 0.95, Risk),
                py{p: P, low: Low, high: High, n: Certify, certified: Certified0}),
        (   Certified0 == @(true) -> Certified = true ; Certified = false ),
        Best = _{params: AllValues, value: Value, projections: Spent, p: P, low: Low,
                 high: High, n: Certify, certified: Certified}
    ;   Spent = Spent0,
        Best = _{params: AllValues, value: Value, projections: Spent}
    ),
    best_timeline(Run, Values, TL, Timeline).

% trial_budget(+Belief, +Max): over a belief a trial costs its N worlds; a budget
% below one trial would answer no solution without projecting anything.
trial_budget(belief(N, _, _), Max) :-
    Max < N, !,
    throw(error(domain_error(max_projections(at_least(N)), max_projections(Max)),
                context(best_parametrization/8, trial_worlds(N)))).
trial_budget(_, _).

% belief_search(+Own, -Belief): `none`, or belief(N, P, M): samples(N) worlds a trial,
% chance(P) the probability its Constraint must have, certify(M) fresh worlds.
belief_search(Own, Belief) :-
    option_value(samples, Own, none, N),
    option_value(chance, Own, none, P),
    option_value(certify, Own, default, M0),
    (   N == none, P == none
    ->  (   M0 == default -> Belief = none ; domain_error(search_option, certify(M0)) )
    ;   P == none
    ->  domain_error(samples_with_chance, samples(N))
    ;   N == none
    ->  domain_error(samples_with_chance, chance(P))
    ;   check_integer(samples, N, 1),
        below_certifying_worlds(N),
        must_be(number, P),
        (   P > 0, P < 1 -> true ; domain_error(chance, P) ),
        (   M0 == default
        ->  Risk is 1 - P,
            py_call('projection_server.selection':certify_count(Risk, 0.95), M)
        ;   check_integer(certify, M0, 1),
            M = M0
        ),
        Belief = belief(N, P, M)
    ).

% optimise_belief(+Run, +Study, +Belief, +Batch, +Workers, +Max, +Spent0, -Spent,
% +Best0, -Best): as optimise/8, each trial projected in the worlds of the belief, one
% trial after another (its worlds run on all workers at once).  A trial's value is the
% mean of the Objective over its worlds; it is feasible when the Wilson lower bound (95 %)
% of the fraction of its worlds in which Constraint holds is at least the chance P, and
% is told the gap P - low as its constraint (Optuna: <= 0 is feasible).
optimise_belief(Run, Study, Belief, Batch, Workers, Max, Spent0, Spent, Best0, Best) :-
    Belief = belief(N, _, _),
    Left is Max - Spent0,
    (   Left < N
    ->  Spent = Spent0,
        Best = Best0
    ;   Count is max(1, min(Batch, Left // N)),
        py_call('projection_server.search':ask(Study, Count), Trials),
        foldl(belief_trial(Run, Study, Belief, Workers), Trials, Best0-Spent0, Best1-Spent1),
        optimise_belief(Run, Study, Belief, Batch, Workers, Max, Spent1, Spent, Best1, Best)
    ).

belief_trial(Run, Study, belief(N, Chance, _), Workers, Trial, Best0-Spent0, Best-Spent) :-
    trial_params(Trial, Number, Values),
    dict_pairs(Values, _, Pairs0),
    maplist([K-V, K-[V]]>>true, Pairs0, Lists),
    Round is max(2, 2 * Workers),
    belief_rounds(Run, Lists, N, Chance, Round, 0, 0, [], Successes, Made, ObjValues),
    Spent is Spent0 + Made,
    wilson_interval(Successes, Made, Low, _),
    Gap is Chance - Low,
    (   ObjValues == []
    ->  Value = none
    ;   sum_list(ObjValues, Sum),
        length(ObjValues, L),
        Value is Sum / L
    ),
    (   Value == none
    ->  py_call('projection_server.search':tell(Study, Number, @(none), @(false)))
    ;   py_call('projection_server.search':tell(Study, Number, Value, @(false),
                                                constraint=Gap))
    ),
    (   Gap =< 0 -> Feasible = true ; Feasible = false ),
    keep_best(Feasible, best(Values, Value, Number, none), Best0, Best).

% belief_rounds(..., +From, +K0, +Vs0, -K, -Made, -Vs): the trial's worlds From on, in
% rounds, until N worlds, or until its Wilson upper bound is below the chance (it
% cannot be feasible): K of them with Constraint, Vs the Objective's values.
belief_rounds(Run, Lists, N, Chance, Round, From, K0, Vs0, K, Made, Vs) :-
    Run = run(Scenario, Program, Searched, FixedParams, Options, Timeline, Constraint,
              Objective),
    To is min(N, From + Round),
    maplist(searched_param(Lists), Searched, Params, _),
    append(Params, FixedParams, AllParams),
    findall(Hit-V, ( make_projection(Scenario, Program, AllParams,
                                     [worlds(From, To)|Options], TL),
                     truth(Timeline, TL, Constraint, Holds),
                     ( Holds == true -> Hit = 1 ; Hit = 0 ),
                     objective_value(Objective, TL, V) ),
            Outcomes),
    pairs_keys_values(Outcomes, Hits, Vs1),
    sum_list(Hits, Sum),
    K1 is K0 + Sum,
    exclude(==(none), Vs1, Numbers),
    append(Vs0, Numbers, Vs2),
    wilson_interval(K1, To, _, High),
    (   ( To >= N ; High < Chance )
    ->  K = K1, Made = To, Vs = Vs2
    ;   belief_rounds(Run, Lists, N, Chance, Round, To, K1, Vs2, K, Made, Vs)
    ).

% certify_best(+Run, +Values, +M, -Successes): the best trial in M fresh worlds (those
% of robust_parametrization/7's certificate).
certify_best(Run, Values, M, Successes) :-
    Run = run(Scenario, Program, Searched, FixedParams, Options, Timeline, Constraint, _),
    maplist([searched(Var, Name, _, _), (Var, Name, [V])]>>get_dict(Name, Values, V),
            Searched, Params),
    append(Params, FixedParams, AllParams),
    py_call('projection_server.selection':'CERTIFY_OFFSET', From),
    To is From + M,
    aggregate_all(count, ( make_projection(Scenario, Program, AllParams,
                                           [worlds(From, To)|Options], TL),
                           truth(Timeline, TL, Constraint, true) ),
                  Successes).

% optimise(+Run, +Study, +Workers, +Max, +Spent0, -Spent, +Best0, -Best): ask, project
% and tell batches of trials until Max projections are spent.  Best is best(Values,
% Value, Trial, TL), Values the searched parameters' dict, or `none`.
optimise(Run, Study, Workers, Max, Spent0, Spent, Best0, Best) :-
    Left is Max - Spent0,
    (   Left =< 0
    ->  Spent = Spent0,
        Best = Best0
    ;   Count is min(Workers, Left),
        py_call('projection_server.search':ask(Study, Count), Trials),
        run_trials(Run, Trials, Results),
        foldl(tell_trial(Study), Results, Best0, Best1),
        Spent1 is Spent0 + Count,
        optimise(Run, Study, Workers, Max, Spent1, Spent, Best1, Best)
    ).

% run_trials(+Run, +Trials, -Results): Results are result(Trial, Values, Feasible,
% Value, TL) in the order of Trials.
run_trials(Run, Trials, Results) :-
    Run = run(_, _, [searched(_, Name, _, _)], _, _, _, _, _), !,
    findall(V, ( member(T, Trials), get_dict(params, T, P), get_dict(Name, P, V) ), Vs0),
    sort(Vs0, Vs),
    findall(V-Outcome, trial(Run, [Name-Vs], V, Outcome), Outcomes),
    maplist(trial_result(Name, Outcomes), Trials, Results).
run_trials(Run, Trials, Results) :-
    maplist(trial_alone(Run), Trials, Results, Goals0),
    (   current_query_context(Context)
    ->  maplist([G, with_query_context(Context, G)]>>true, Goals0, Goals)
    ;   Goals = Goals0
    ),
    length(Goals, N),
    concurrent(N, Goals, []).

% trial_alone(+Run, +Trial, -Result, -Goal): Goal, run in a thread of its own, makes
% Trial's projection with its values and binds Result, and only Result (the search's
% variables stay unbound: concurrent/3 unifies each goal's variables back).
trial_alone(Run, Trial, Result, findall(R, trial_alone(Run, Trial, R), [Result])).

trial_result(Name, Outcomes, Trial, result(Number, Values, Feasible, Value, TL)) :-
    trial_params(Trial, Number, Values),
    get_dict(Name, Values, V),
    memberchk(V-outcome(Feasible, Value, TL), Outcomes).

trial_alone(Run, Trial, result(Number, Values, Feasible, Value, TL)) :-
    trial_params(Trial, Number, Values),
    dict_pairs(Values, _, Pairs0),
    maplist([N-V, N-[V]]>>true, Pairs0, Pairs),
    once(trial(Run, Pairs, _, outcome(Feasible, Value, TL))).

% trial_params(+Trial, -Number, -Values): a trial the sampler asks for, its values a
% dict without the tag janus gives it.
trial_params(Trial, Number, Values) :-
    get_dict(trial, Trial, Number),
    get_dict(params, Trial, Values0),
    dict_pairs(Values0, _, Pairs),
    dict_pairs(Values, _, Pairs).

% trial(+Run, +Lists, -V, -Outcome): a projection of the searched parameters with the
% values Lists (Name-Values), the first searched one's value V and its outcome.
trial(run(Scenario, Program, Searched, FixedParams, Options, Timeline, Constraint,
          Objective), Lists, V, outcome(Feasible, Value, TL)) :-
    maplist(searched_param(Lists), Searched, Params, Vars),
    append(Params, FixedParams, AllParams),
    make_projection(Scenario, Program, AllParams, Options, TL),
    Vars = [V|_],
    truth(Timeline, TL, Constraint, Feasible),
    objective_value(Objective, TL, Value).

searched_param(Lists, searched(Var, Name, _, _), (Var, Name, Values), Var) :-
    memberchk(Name-Values, Lists).

objective_value(Objective, TL, Value) :-
    (   quantity(Objective, V, TL)
    ->  (   number(V)
        ->  Value = V
        ;   type_error(number, V)
        )
    ;   Value = none
    ).

% tell_trial(+Study, +Result, +Best0, -Best): tell the sampler a trial's outcome; keep the
% best feasible one (the first of equals).
tell_trial(Study, result(Number, Values, Feasible, Value, TL), Best0, Best) :-
    (   Value == none
    ->  PyValue = @(none)
    ;   PyValue = Value
    ),
    (   Feasible == true -> PyFeasible = @(true) ; PyFeasible = @(false) ),
    py_call('projection_server.search':tell(Study, Number, PyValue, PyFeasible)),
    keep_best(Feasible, best(Values, Value, Number, TL), Best0, Best).

% keep_best(+Feasible, +Candidate, +Best0, -Best): Candidate, best(Values, Value,
% Trial, TL), if it is feasible, has a value and a larger one than Best0 (the first of
% equals stays).
keep_best(Feasible, Candidate, Best0, Best) :-
    Candidate = best(_, Value, _, _),
    (   Feasible == true,
        Value \== none,
        (   Best0 = best(_, Value0, _, _)
        ->  Value > Value0
        ;   true
        )
    ->  Best = Candidate
    ;   Best = Best0
    ).

bind_searched(Values, searched(Var, Name, _, _)) :-
    get_dict(Name, Values, Var).

% best_timeline(+Run, +Values, +TL, -Timeline): Best's timeline, made again from its
% bag if it was removed since (translate/2 keeps the most recent ones).
best_timeline(_, _, TL, Timeline) :-
    TL \== none,
    timeline_exists(TL), !,
    Timeline = TL.
best_timeline(Run, Values, _, Timeline) :-
    Run = run(Scenario, Program, Searched, FixedParams, Options, _, _, _),
    maplist([searched(Var, Name, _, _), (Var, Name, [V])]>>get_dict(Name, Values, V),
            Searched, Params),
    append(Params, FixedParams, AllParams),
    once(make_projection(Scenario, Program, AllParams, Options, Timeline)).


                 /*******************************
                 *       PARAMS AND OPTIONS     *
                 *******************************/

% search_params(+Params, -Searched, -Fixed): the parameters given as range(Low, High),
% as searched(Var, Name, Low, High), and the others as fixed(Var, Name, Values).
search_params([], [], []).
search_params([Param|Params], Searched, Fixed) :-
    (   Param = (Var, Name, Range)
    ->  true
    ;   type_error(projection_parameter, Param)
    ),
    must_be(atom, Name),
    (   var(Range)
    ->  instantiation_error(Range)
    ;   Range = range(Low, High)
    ->  must_be(number, Low),
        must_be(number, High),
        (   Low < High
        ->  true
        ;   domain_error(search_range, range(Low, High))
        ),
        must_be_unbound(Var),
        Searched = [searched(Var, Name, Low, High)|Searched1],
        Fixed = Fixed1
    ;   parameter_values(Range, Values),
        Fixed = [fixed(Var, Name, Values)|Fixed1],
        Searched = Searched1
    ),
    search_params(Params, Searched1, Fixed1).

% check_ends(+Program, +Searched): the ends of the searched ranges are values of the
% registered Program's parameters (a plan's parameters take any number).
check_ends(Program, Searched) :-
    atom(Program),
    projection_program(Program, Formal), !,
    forall(member(searched(_, Name, Low, High), Searched),
           (   member(F, Formal), get_dict(name, F, Name0), atom_string(Name, Name0)
           ->  get_dict(min, F, Min), get_dict(max, F, Max),
               forall(member(End, [Low, High]),
                      (   End >= Min, End =< Max
                      ->  true
                      ;   domain_error(parameter_value, Name=End)
                      ))
           ;   existence_error(program_parameter, Program:Name)
           )).
check_ends(_, _).

% fixed_combination(+Fixed, -Params): on backtracking, each combination of the fixed
% parameters' values, the first changing slowest, as make_projection/5 parameters of
% one value each (their variables bound to it).
fixed_combination([], []).
fixed_combination([fixed(Var, Name, Values)|T], [(Var, Name, [Var])|Params]) :-
    member(Var, Values),
    fixed_combination(T, Params).

% The options of each search; boundary_options/3 and best_options/3 split Options into
% the search's own and those passed on to make_projection/5.
search_option(boundary, tolerance(_)).
search_option(boundary, max_projections(_)).
search_option(boundary, coarse(_)).
search_option(best, max_projections(_)).
search_option(best, seed(_)).
search_option(best, batch(_)).
search_option(best, samples(_)).
search_option(best, chance(_)).
search_option(best, certify(_)).

% Worlds drawn from a belief: a search's condition is of one projection.
belief_option(samples(_)).
belief_option(worlds(_, _)).

boundary_options(Options, Own, Pass) :-
    split_options(boundary, Options, Own, Pass).

best_options(Options, Own, Pass) :-
    split_options(best, Options, Own, Pass).

split_options(_, Timeout, [], Timeout) :-
    number(Timeout), !.
split_options(Search, Options, Own, Pass) :-
    must_be(list, Options),
    partition(own_option(Search), Options, Own, Pass).

own_option(_, Option) :-
    var(Option), !,
    instantiation_error(Option).
own_option(Search, Option) :-
    search_option(Search, Option), !.
own_option(_, Option) :-
    belief_option(Option), !,
    domain_error(search_option, Option).
own_option(_, Option) :-
    search_option(_, Option), !,
    domain_error(search_option, Option).

option_value(Name, Options, Default, Value) :-
    functor(Option, Name, 1),
    (   memberchk(Option, Options)
    ->  arg(1, Option, Value)
    ;   Value = Default
    ).

check_number(Name, Value, Min, exclusive) :-
    must_be(number, Value),
    (   Value > Min
    ->  true
    ;   Culprit =.. [Name, Value],
        domain_error(Name, Culprit)
    ).

check_integer(Name, Value, Min) :-
    must_be(integer, Value),
    (   Value >= Min
    ->  true
    ;   Culprit =.. [Name, Value],
        domain_error(Name, Culprit)
    ).

must_be_unbound(X) :-
    (   var(X)
    ->  true
    ;   uninstantiation_error(X)
    ).

rounded(Expr, V) :-
    V is round(Expr * 1.0e9) / 1.0e9.

take(N, List, Prefix) :-
    length(List, Len),
    (   Len =< N
    ->  Prefix = List
    ;   length(Prefix, N),
        append(Prefix, _, List)
    ).


                 /*******************************
                 *           MESSAGES           *
                 *******************************/

:- multifile prolog:message//1.

prolog:message(error(domain_error(one_range_parameter, Names), _)) -->
    { length(Names, N) },
    [ 'outcome_boundary/7 searches exactly one parameter given as range(Low, High); ',
      'the parameters give ~D: ~w'-[N, Names] ].
prolog:message(error(domain_error(range_parameters, _), _)) -->
    [ 'best_parametrization/8 searches the parameters given as range(Low, High); ',
      'the parameters give none' ].
prolog:message(error(domain_error(search_range, range(Low, High)), _)) -->
    [ 'A searched range(Low, High) needs Low < High; found range(~w, ~w)'-[Low, High] ].
prolog:message(error(domain_error(max_projections(at_least(K)), max_projections(N)),
                     Context)) -->
    { nonvar(Context), Context = context(_, Worlds), Worlds == trial_worlds(K) }, !,
    [ 'max_projections(~w) cannot afford one trial: a trial over the belief is '-[N],
      'projected in its samples(~w) worlds; give max_projections(~w) or more, '-[K, K],
      'or fewer samples' ].
prolog:message(error(domain_error(max_projections(at_least(K)), max_projections(N)), _)) -->
    [ 'max_projections(~w) is smaller than the coarse pass, ~w projections: '-[N, K],
      'give a larger budget or a smaller coarse(K)' ].
prolog:message(error(domain_error(samples_with_chance, samples(N)), _)) --> !,
    [ 'samples(~w): a search over a belief needs chance(P), the probability its '-[N],
      'Constraint must have' ].
prolog:message(error(domain_error(samples_with_chance, chance(P)), _)) --> !,
    [ 'chance(~w) needs samples(N): the worlds of the belief each trial is '-[P],
      'projected in' ].
prolog:message(error(domain_error(chance, P), _)) -->
    [ 'chance(~w): a probability strictly between 0 and 1'-[P] ].
prolog:message(error(domain_error(search_option, Option), _)) -->
    { belief_option(Option) }, !,
    [ '~q: a search projects the nominal world, one projection per value; '-[Option],
      'outcome_probability/7 answers over the worlds of a belief' ].
prolog:message(error(domain_error(search_option, Option), _)) -->
    [ '~q is not an option of this search (outcome_boundary/7: tolerance, '-[Option],
      'max_projections, coarse; best_parametrization/8: max_projections, seed, batch)' ].
