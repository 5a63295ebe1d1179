:- module(robust,
          [ robust_parametrization/7,   % +Scenario, +Program, +Params, +Options, ?TL,
                                        % :Condition, -Best
            below_certifying_worlds/1   % +N
          ]).
:- autoload(library(apply), [maplist/2, maplist/3, maplist/4, foldl/4, foldl/6]).
:- autoload(library(yall), [(>>)/3, (>>)/4, (>>)/5]).
:- autoload(library(error), [must_be/2, domain_error/2, existence_error/2]).
:- autoload(library(lists), [append/3, member/2, nth0/3, sum_list/2]).
:- autoload(library(option), [select_option/3]).
:- autoload(library(aggregate), [aggregate_all/3]).
:- autoload(library(pairs), [pairs_keys_values/3]).
:- use_module(library(janus), [py_call/2]).
:- use_module(projection, [make_projection/5, parameter_values/2,
                            projection_check_condition/4, projection_check_quantity/3]).
:- use_module(scenario, [scenario_description/2]).
:- use_module(timeline, [quantity/3]).
:- meta_predicate robust_parametrization(+, +, +, +, ?, 0, -).

/** <module> A choice under a belief that holds up on worlds it never saw

outcome_probability/7 says how probable an outcome is for each
parametrization.  robust_parametrization/7 chooses the parametrization whose
Condition is most probable over the scenario's belief, projecting as few
worlds as it can, and then certifies the choice on fresh worlds:

```
?- copy_scenario(grasping, S),
   scenario_set_property(S, egg1, friction, uniform(0.2, 0.4)),
   scenario_set_property(S, egg1, breaking_force, normal(10, 1.5)),
   robust_parametrization(S, grasp_object,
                          [(F, force, range(1, 11, 1)), (P, position, [-0.02, 0.0, 0.02])],
                          [seed(1)], TL,
                          ( \+ occurs(break, _, TL), \+ occurs(slip, _, TL) ), Best).
F = 4, P = 0.0,
Best = _{params: _{force: 4, position: 0.0}, p: 1.0, low: 0.9505, high: 1.0, n: 59,
         certified: true, projections: 187, equals: [...], worlds: 14}.
```

Choosing (projection_server/selection.py has the statistics): every cell
(parametrization) is projected in the same worlds of the seed (world i is the
same for every cell), round by round; after each round a cell is eliminated
when another did better in the worlds where the two differ (an exact sign
test), or when it could not be certified at the risk while another could,
each at the confidence with Bonferroni's correction over the cells.  When one
cell is left, at samples(N) worlds, or when the leading cells have agreed in
every world for as long as the test needs to part two cells and every other
survivor is observed to be worse by more than the indifference zone, choosing
stops; under a `prefer` or `near` rule, which takes an edge of the equals, the
leaders must have agreed in as many worlds as the certificate has, and only
the two the rule ranks first go on to them (the others keep the worlds they
have, to be taken only if both fail).  The survivors whose observed probability is within the indifference
zone of the best's are equals; a rule picks one of them.

Certifying: the chosen cell is projected in certify(M) fresh worlds, worlds
1000000 to 1000000 + M - 1 of the seed, which choosing never uses.  `p`,
`low`, `high` and `certified` come from these worlds only (choosing the best
of many cells on the worlds that then report its probability would overstate
it).
*/

%!  robust_parametrization(+Scenario, +Program, +Params, +Options, ?TL,
%!                         :Condition, -Best) is det.
%
%   Best is the parametrization of Params (as make_projection/5 takes them:
%   lists and stepped ranges) whose Condition, a goal on the projection's
%   timeline TL, is most probable over Scenario's belief, certified on fresh
%   worlds; the parameter variables are bound to its values.  Best is
%   `_{params: Dict, p: P, low: L, high: H, n: M, certified: Bool,
%   projections: K, worlds: W, equals: Equals}`: the fraction of the M
%   certifying worlds in which Condition held, its one-sided Clopper-Pearson
%   bounds at the confidence, whether `low` proves P >= 1 - risk, the
%   projections made in all, the choosing worlds per survivor, and the
%   parameter dicts of the equals.  TL is left unbound.  Options:
%
%     - indifference(+D): cells within D of the best's probability are
%       equals (default 0.05; 0 =< D < 1);
%     - confidence(+C): of the eliminations and the certificate (default
%       0.95; 0 < C < 1);
%     - risk(+A): the certificate proves P(Condition) >= 1 - A (default
%       0.05; 0 < A < 1);
%     - certify(+M): the fresh worlds (default: the fewest that could prove
%       the risk, 59 at the defaults);
%     - samples(+N): at most N choosing worlds per cell (default 30);
%     - batch(+B): worlds per round (default: as few as give the workers
%       twice their number of projections, one world when the cells are
%       many; give it to get the same choice on nodes with other workers);
%     - prefer(+Rule): which of the equals: `margin` (the default: the one
%       farthest from any cell that failed in some world, in the parameters'
%       space scaled by their spans), `near(Values)` (nearest the values, in
%       Params' order: e.g. the program's defaults, to keep them when they are
%       equals), Quantity or -Quantity (the greatest or least mean of a
%       quantity of the timeline over the choosing worlds, e.g.
%       `-max_load(egg1)`: the gentlest grip); ties go to margin, then to the
%       equal nearest the equals' centre: never to the grid's order;
%     - seed(+K) (default 0), timeout(+S), physics(+Dict): as for
%       make_projection/5.
%
%   @error domain_error(indifference, D), domain_error(confidence, C),
%          domain_error(risk, A) for a value outside its range
%   @error domain_error(positive_integer, N) for certify(N), samples(N) or
%          batch(N) with N < 1
%   @error domain_error(choosing_worlds(at_most(Offset)), samples(N)) for more
%          choosing worlds than lie below the certifying ones (Offset = 1000000)
%   @error domain_error(scenario_with_beliefs, Scenario) for a scenario whose
%          properties are all numbers: a certified choice needs a belief
%   @error domain_error(robust_option, O) for an unknown option
%   @error domain_error(near_values(N), near(Values)) for a prefer(near(Values))
%          whose Values are not N, one per parameter
%   @error existence_error(Kind, Term) for a fluent, event, quantity, type or
%          object (Kind `entity`) that Condition names on TL, or a prefer(Q)
%          quantity, that no timeline of Scenario can have, before anything
%          is projected (projection_check_condition/4): a misspelled name
%          would certify any cell
%   @error existence_error(quantity, Q) for a prefer(Q) that a timeline lacks
%   @error make_projection/5's errors

robust_parametrization(Scenario, Program, Params, Options, TL, Condition, Best) :-
    must_be(atom, Scenario),
    must_be(list, Params),
    must_be(list, Options),
    robust_options(Options, Opts, Pass),
    Opts = opts(D, C, A, M, N, Batch0, Seed, Prefer),
    prefer_rule(Prefer, Rule, Near, Sign),
    must_have_beliefs(Scenario),
    cells(Params, Vars, Names, Cells),
    projection_check_condition(Scenario, TL, Condition, robust_parametrization/7),
    prefer_known(Rule, Prefer, Scenario),
    near_values(Rule, Near, Names),
    length(Cells, K),
    (   Batch0 == workers
    ->  py_call('projection_server.projection':workers(), W),
        Batch = per_worker(W)
    ;   Batch = Batch0
    ),
    round_size(Batch, K, Size0),
    py_call('projection_server.selection':first_round(K, C, A, Size0), First),
    Run = run(Scenario, Program, Params, Vars, [seed(Seed)|Pass], TL, Condition, Prefer),
    maplist([_, cell([], [])]>>true, Cells, States0),
    % An edge rule's settled stop waits for as many worlds as the certificate.
    (   Rule == margin -> Settle = 0 ; Settle = M ),
    Choose = choose(Cells, D, Rule, Near, Sign),
    choose_rounds(Run, Cells, s(C, A, D, N, Batch, Settle, Choose), 0, First, States0,
                  States, 0, Spent0),
    maplist(state_all_outcomes, States, Outcomes),
    maplist(state_mean, States, Means),
    py_call('projection_server.selection':choose(Outcomes, Cells, D, Rule, near=Near,
                                                 quantities=Means, sign=Sign), Choice),
    get_dict(cell, Choice, Chosen),
    get_dict(equals, Choice, EqualIndices),
    nth0(Chosen, Cells, Values),
    nth0(Chosen, Outcomes, ChosenOutcomes),
    length(ChosenOutcomes, Worlds),
    certify(Run, Values, M, Successes),
    Spent is Spent0 + M,
    py_call('projection_server.selection':certificate(Successes, M, C, A),
            py{p: P, low: Low, high: High, n: M, certified: Certified0}),
    (   Certified0 == @(true) -> Certified = true ; Certified = false ),
    maplist(params_dict(Names), Cells, Dicts),
    findall(E, ( member(I, EqualIndices), nth0(I, Dicts, E) ), Equals),
    nth0(Chosen, Dicts, ParamsDict),
    Vars = Values,
    Best = _{params: ParamsDict, p: P, low: Low, high: High, n: M, certified: Certified,
             projections: Spent, worlds: Worlds, equals: Equals}.

% prefer_rule(+Prefer, -Rule, -Near, -Sign): selection:choose/5's arguments.
prefer_rule(margin, margin, @(none), 1) :- !.
prefer_rule(near(Values), near, Values, 1) :- !,
    must_be(list(number), Values).
prefer_rule(-Quantity, prefer, @(none), -1) :- !,
    must_be(callable, Quantity).
prefer_rule(Quantity, prefer, @(none), 1) :-
    must_be(callable, Quantity).

% near_values(+Rule, +Near, +Names): near(Values) gives a value per parameter (fewer
% would be matched against the first parameters only).
near_values(near, Near, Names) :-
    length(Near, N),
    length(Names, M),
    N =\= M, !,
    domain_error(near_values(M), near(Near)).
near_values(_, _, _).

% prefer_known(+Rule, +Prefer, +Scenario): a prefer(Quantity) names a quantity the
% scenario's timelines can have.
prefer_known(prefer, Prefer, Scenario) :- !,
    (   Prefer = -Quantity -> true ; Quantity = Prefer ),
    projection_check_quantity(Scenario, Quantity, robust_parametrization/7).
prefer_known(_, _, _).

% robust_options(+Options, -Opts, -Pass): this predicate's options and those
% passed to make_projection/5, all checked before anything is projected.
robust_options(Options, opts(D, C, A, M, N, Batch, Seed, Prefer), Pass) :-
    option_or(indifference(D), Options, 0.05, O1),
    option_or(confidence(C), O1, 0.95, O2),
    option_or(risk(A), O2, 0.05, O3),
    option_or(certify(M0), O3, default, O4),
    option_or(samples(N), O4, 30, O5),
    option_or(batch(Batch), O5, workers, O6),
    option_or(seed(Seed), O6, 0, O7),
    option_or(prefer(Prefer), O7, margin, Pass),
    must_be(number, D),
    (   D >= 0, D < 1 -> true ; domain_error(indifference, D) ),
    must_be(number, C),
    (   C > 0, C < 1 -> true ; domain_error(confidence, C) ),
    must_be(number, A),
    (   A > 0, A < 1 -> true ; domain_error(risk, A) ),
    (   M0 == default
    ->  py_call('projection_server.selection':certify_count(A, C), M)
    ;   M = M0,
        positive_integer(M)
    ),
    positive_integer(N),
    below_certifying_worlds(N),
    (   Batch == workers -> true ; positive_integer(Batch) ),
    must_be(integer, Seed),
    must_be(nonvar, Prefer),
    forall(member(O, Pass),
           (   ( O = timeout(_) ; O = physics(_) ; number(O) )
           ->  true
           ;   domain_error(robust_option, O)
           )).

option_or(Option, Options, Default, Rest) :-
    (   select_option(Option, Options, Rest)
    ->  true
    ;   arg(1, Option, Default),
        Rest = Options
    ).

%!  below_certifying_worlds(+N) is semidet.
%
%   True when the N choosing worlds of a seed (0..N-1) stay clear of its
%   certifying worlds, which start at selection.CERTIFY_OFFSET.
below_certifying_worlds(N) :-
    py_call('projection_server.selection':'CERTIFY_OFFSET', Offset),
    (   N =< Offset -> true ; domain_error(choosing_worlds(at_most(Offset)), samples(N)) ).

positive_integer(N) :-
    must_be(integer, N),
    (   N >= 1 -> true ; domain_error(positive_integer, N) ).

must_have_beliefs(Scenario) :-
    scenario_description(Scenario, Description),
    py_call('projection_server.beliefs':has_beliefs(Description), Has),
    (   Has == @(true)
    ->  true
    ;   domain_error(scenario_with_beliefs, Scenario)
    ).

% cells(+Params, -Vars, -Names, -Cells): the parameter variables and names,
% and every combination of their values (the first parameter slowest).
cells(Params, Vars, Names, Cells) :-
    maplist(param_parts, Params, Vars, Names, Ranges),
    maplist(parameter_values, Ranges, ValueLists),
    findall(Values, maplist(member, Values, ValueLists), Cells).

param_parts(Param, Var, Name, Range) :-
    (   Param = (Var, Name, Range)
    ->  must_be(atom, Name)
    ;   must_be(oneof([(_, _, _)]), Param)
    ).

% choose_rounds(+Run, +Cells, +S, +From, +Size, +States0, -States, +Spent0,
% -Spent): project the surviving cells in worlds From to From + Size - 1,
% eliminate, and go on until selection:step/4 stops.  A cell's state is
% cell(Hits, Quantities), one of each per world, or `none` once eliminated.
choose_rounds(Run, Cells, S, From, Size, States0, States, Spent0, Spent) :-
    S = s(C, A, D, N, Batch, Settle, Choose),
    To is min(N, From + Size),
    findall(Values, ( nth0(I, Cells, Values), nth0(I, States0, cell(_, _)) ), Alive),
    round(Run, Alive, From, To, Results),
    maplist(add_round(Results), Cells, States0, States1),
    length(Results, Made),
    Spent1 is Spent0 + Made,
    maplist(state_outcomes, States1, Outcomes),
    ranked(Settle, Choose, States1, Ranked),
    py_call('projection_server.selection':step(Outcomes, C, A, D, N, Settle, Ranked), Step),
    get_dict(eliminate, Step, Eliminate),
    get_dict(park, Step, Park),
    foldl(eliminate_cell, Eliminate, States1, States1a),
    foldl(park_cell, Park, States1a, States2),
    (   get_dict(stop, Step, @(true))
    ->  States = States2, Spent = Spent1
    ;   aggregate_all(count, member(cell(_, _), States2), Left),
        round_size(Batch, Left, Next),
        choose_rounds(Run, Cells, S, To, Next, States2, States, Spent1, Spent)
    ).

% ranked(+Settle, +Choose, +States, -Ranked): the equals in the rule's order,
% which step/7 parks by; none for the margin rule (Settle 0), which parks none.
ranked(0, _, _, []) :- !.
ranked(_, choose(Cells, D, Rule, Near, Sign), States, Ranked) :-
    maplist(state_all_outcomes, States, Outcomes),
    maplist(state_mean, States, Means),
    py_call('projection_server.selection':choose(Outcomes, Cells, D, Rule, near=Near,
                                                 quantities=Means, sign=Sign), Choice),
    get_dict(ranked, Choice, Ranked).

% round_size(+Batch, +Alive, -Worlds): a round's worlds: the given batch, or by
% default as few as keep every worker busy, twice the workers' projections.
round_size(per_worker(W), Alive, Worlds) :- !,
    Worlds is max(1, ceiling(2 * W / Alive)).
round_size(Batch, _, Batch).

% round(+Run, +Alive, +From, +To, -Results): the cells Alive in worlds From to
% To - 1, one make_projection/5 enumeration (its projections on all workers):
% Values-(Hit-Quantity) for each, cell by cell, world by world.
round(Run, Alive, From, To, Results) :-
    Run = run(Scenario, Program, Params, Vars, Options, TL, Condition, Prefer),
    findall(Vars-(Hit-Q),
            ( make_projection(Scenario, Program, Params,
                              [only(Alive), worlds(From, To)|Options], TL),
              (   \+ \+ call(Condition)
              ->  Hit = 1
              ;   Hit = 0
              ),
              prefer_value(Prefer, TL, Q) ),
            Results).

add_round(_, _, none, none) :- !.
add_round(_, _, parked(Hits, Qs), parked(Hits, Qs)) :- !.
add_round(Results, Values, cell(Hits0, Qs0), cell(Hits, Qs)) :-
    findall(H-Q, member(Values-(H-Q), Results), Pairs),
    pairs_keys_values(Pairs, NewHits, NewQs),
    append(Hits0, NewHits, Hits),
    append(Qs0, NewQs, Qs).

% projection_in(+Run, +Values, +Worlds, -Hit): on backtracking, the cell
% Values projected in each of the Worlds; Hit is 1 if Condition holds.
projection_in(Run, Values, Worlds, Hit) :-
    Run = run(Scenario, Program, Params, Vars, Options, TL, Condition, _),
    Vars = Values,
    maplist([(V, Name, _), X, (V, Name, [X])]>>true, Params, Values, Fixed),
    make_projection(Scenario, Program, Fixed, [Worlds|Options], TL),
    (   \+ \+ call(Condition)
    ->  Hit = 1
    ;   Hit = 0
    ).

prefer_value(Prefer, _, 0) :-
    ( Prefer == margin ; Prefer = near(_) ), !.
prefer_value(-Quantity, TL, V) :- !,
    prefer_value(Quantity, TL, V).
prefer_value(Quantity, TL, V) :-
    (   quantity(Quantity, V, TL), number(V)
    ->  true
    ;   existence_error(quantity, Quantity)
    ).

eliminate_cell(I, States0, States) :-
    length(Before, I),
    append(Before, [_|After], States0),
    append(Before, [none|After], States).

park_cell(I, States0, States) :-
    nth0(I, States0, cell(Hits, Qs)),
    length(Before, I),
    append(Before, [_|After], States0),
    append(Before, [parked(Hits, Qs)|After], States).

% state_outcomes(+State, -Outcomes): a cell's outcomes while it is in the race;
% state_all_outcomes/2 a parked cell's too, with the worlds it has.
state_outcomes(cell(Hits, _), Hits) :- !.
state_outcomes(_, @(none)).

state_all_outcomes(parked(Hits, _), Hits) :- !.
state_all_outcomes(State, Outcomes) :-
    state_outcomes(State, Outcomes).

state_mean(none, @(none)).
state_mean(parked(_, Qs), Mean) :- !,
    state_mean(cell(_, Qs), Mean).
state_mean(cell(_, Qs), Mean) :-
    sum_list(Qs, Sum),
    length(Qs, L),
    Mean is Sum / max(1, L).

% certify(+Run, +Values, +M, -Successes): the cell Values in M fresh worlds,
% from selection.CERTIFY_OFFSET on, which choosing never reaches.
certify(Run, Values, M, Successes) :-
    py_call('projection_server.selection':'CERTIFY_OFFSET', From),
    To is From + M,
    findall(Hit, projection_in(Run, Values, worlds(From, To), Hit), Hits),
    sum_list(Hits, Successes).

params_dict(Names, Values, Dict) :-
    pairs_keys_values(Pairs, Names, Values),
    dict_pairs(Dict, _, Pairs).

:- multifile prolog:message//1.

prolog:message(error(domain_error(scenario_with_beliefs, Scenario), _)) -->
    [ 'Scenario ~w has no belief: a certified choice needs one; give a property a '-[Scenario],
      'distribution with scenario_set_property/4 (e.g. uniform(0.2, 0.4))' ].
prolog:message(error(domain_error(near_values(N), near(Values)), _)) -->
    [ 'prefer(near(~w)): give ~w values, one per parameter in Params\' order'-[Values, N] ].
prolog:message(error(domain_error(robust_option, Option), _)) -->
    [ 'robust_parametrization/7 has no option ~q (see its documentation)'-[Option] ].
