:- module(uncertainty,
          [ outcome_probability/7,      % +S, +Program, +Params, +Options, ?TL, :Condition, -P
            wilson_interval/4           % +Successes, +N, -Low, -High
          ]).
:- autoload(library(error), [must_be/2, domain_error/2]).
:- autoload(library(lists), [member/2, select/3, sum_list/2]).
:- autoload(library(option), [option/2, option/3]).
:- use_module(library(janus), [py_call/2]).
:- use_module(projection, [make_projection/5, parameter_values/2,
                            projection_check_condition/4]).
:- meta_predicate outcome_probability(+, +, +, +, ?, 0, -).

/** <module> How probable an outcome is, over what the robot does not know

A scenario whose properties are distributions (scenario_set_property/4 with
`uniform(Low, High)`, `normal(Mean, SD)` or `choice(Values)`) describes what a
robot believes, not one world.  outcome_probability/7 projects each
parametrization in worlds drawn from that belief and answers how probable an
outcome is, with its uncertainty:

```
?- copy_scenario(grasping, S),
   scenario_set_property(S, egg1, friction, uniform(0.2, 0.4)),
   outcome_probability(S, grasp_object, [(F, force, [1, 3, 5, 7, 9, 11])],
                       [samples(30), seed(1)], TL,
                       ( \+ occurs(break, _, TL), \+ occurs(slip, _, TL) ), P).
F = 5, P = _{p: 0.93, low: 0.79, high: 0.98, n: 30} ;
...
```
*/

%!  outcome_probability(+Scenario, +Program, +Params, +Options, ?TL, :Condition,
%!                      -P) is nondet.
%
%   One solution per parametrization of Params (as make_projection/5 takes
%   them; the parameter variables are bound): P is `_{p: Fraction, low: Low,
%   high: High, n: N}`, the fraction of the N worlds drawn from Scenario's
%   beliefs in which Condition holds of the projection's timeline TL, and
%   its Wilson score interval (95 %, two-sided: wilson_interval/4).
%   Options are make_projection/5's (`seed(K)`, `timeout(S)`, `physics(D)`)
%   and
%
%     - samples(+N): at most N worlds per parametrization (default 30);
%     - decide(+T): stop sampling a parametrization as soon as its interval
%       lies wholly above or below T (0 < T < 1), so that clearly bad or
%       clearly good parameters cost few projections; without it, N worlds.
%
%   A parametrization's worlds are those of the same seed as every other's:
%   differences between parametrizations are not differences of their
%   worlds.  The worlds of a round are projected at once on all workers.
%
%   @error domain_error(positive_integer, N) for samples(N) with N < 1
%   @error domain_error(probability_threshold, T) for decide(T) outside (0, 1)
%   @error existence_error(Kind, Term) for a fluent, event, quantity, type or
%          object (Kind `entity`) that Condition names on TL and no timeline
%          of Scenario can have (projection_check_condition/4), before
%          anything is projected: `\+ occurs(brake, _, TL)` would be true in
%          every world
%   @error the errors of make_projection/5

outcome_probability(Scenario, Program, Params, Options0, TL, Condition, P) :-
    must_be(list, Options0),
    must_be(list, Params),
    probability_options(Options0, N, Decide, Options),
    projection_check_condition(Scenario, TL, Condition, outcome_probability/7),
    py_call('projection_server.projection':workers(), Workers),
    fixed_parametrization(Params, Fixed),
    sample(Scenario, Program, Fixed, Options, TL, Condition,
           rounds(N, Decide, Workers), 0, 0, Successes, Total),
    wilson_interval(Successes, Total, Low, High),
    Fraction is Successes / Total * 1.0,
    P = _{p: Fraction, low: Low, high: High, n: Total}.

probability_options(Options0, N, Decide, Options) :-
    (   select(samples(N), Options0, Options1)
    ->  must_be(integer, N),
        (   N >= 1 -> true ; domain_error(positive_integer, N) )
    ;   N = 30, Options1 = Options0
    ),
    (   select(decide(T), Options1, Options)
    ->  must_be(number, T),
        (   T > 0, T < 1 -> Decide = decide(T) ; domain_error(probability_threshold, T) )
    ;   Decide = none, Options = Options1
    ),
    (   option(worlds(_, _), Options)
    ->  domain_error(probability_option, worlds)
    ;   true
    ).

% fixed_parametrization(+Params, -Fixed): on backtracking, each combination
% of Params' values, the parameter variables bound, as single-valued Params.
fixed_parametrization([], []).
fixed_parametrization([Param|Params], [(Var, Name, [Value])|Fixed]) :-
    (   Param = (Var, Name, Range)
    ->  true
    ;   must_be(oneof([(_, _, _)]), Param)
    ),
    parameter_values(Range, Values),
    member(Value, Values),
    Var = Value,
    fixed_parametrization(Params, Fixed).

% sample(..., +Rounds, +K0, +N0, -K, -N): project rounds of worlds from N0
% on, counting those in which Condition holds, until N worlds or decided.
sample(Scenario, Program, Fixed, Options, TL, Condition, Rounds, K0, N0, K, N) :-
    Rounds = rounds(Max, Decide, Workers),
    (   N0 >= Max
    ->  K = K0, N = N0
    ;   decided(Decide, K0, N0)
    ->  K = K0, N = N0
    ;   round_size(Decide, Workers, K0, N0, Max, Size),
        To is min(Max, N0 + Size),
        findall(Hit, ( make_projection(Scenario, Program, Fixed,
                                       [worlds(N0, To)|Options], TL),
                       ( \+ \+ call(Condition) -> Hit = 1 ; Hit = 0 ) ),
                Hits),
        sum_list(Hits, Sum),
        K1 is K0 + Sum,
        sample(Scenario, Program, Fixed, Options, TL, Condition, Rounds, K1, To, K, N)
    ).

% Without a threshold every world runs in one round.  With one, a round is
% two worlds per worker, or, if more, the fewest worlds that could decide the
% way the parametrization leans: one of 4 worlds without a failure needs 31
% more to prove 0.9, and fewer cannot stop it unless it fails.
round_size(none, _, _, _, Max, Max) :- !.
round_size(decide(T), Workers, K, N, Max, Size) :-
    Left is Max - N,
    (   N > 0, K / N >= T
    ->  Lean = up
    ;   Lean = down
    ),
    least_to_decide(Lean, T, K, N, 1, Left, Least),
    Size is max(2 * Workers, Least).

% least_to_decide(+Lean, +T, +K, +N, +M, +Left, -Least): the fewest more
% worlds M (at most Left) after which K/N is decided if all of them succeed
% (Lean = up) or all fail (down).
least_to_decide(Lean, T, K, N, M, Left, Least) :-
    N1 is N + M,
    (   Lean == up -> K1 is K + M ; K1 = K ),
    (   M >= Left
    ->  Least = Left
    ;   decided(decide(T), K1, N1)
    ->  Least = M
    ;   M1 is M + 1,
        least_to_decide(Lean, T, K, N, M1, Left, Least)
    ).

decided(decide(T), K, N) :-
    N > 0,
    wilson_interval(K, N, Low, High),
    (   Low > T
    ;   High < T
    ),
    !.

%!  wilson_interval(+Successes, +N, -Low, -High) is det.
%
%   The Wilson score interval of a proportion, 95 %, two-sided (z = 1.96):
%   sound at small N and at proportions of 0 and 1, where the normal
%   approximation's is not.

wilson_interval(K, N, Low, High) :-
    must_be(nonneg, K),
    must_be(positive_integer, N),
    Z = 1.959963984540054,
    P is K / N,
    Z2 is Z * Z,
    Denominator is 1 + Z2 / N,
    Centre is (P + Z2 / (2 * N)) / Denominator,
    Half is Z * sqrt(P * (1 - P) / N + Z2 / (4 * N * N)) / Denominator,
    % At 0 and N the bound is exactly 0 or 1, not what rounding leaves of it.
    (   K =:= 0 -> Low = 0.0 ; Low is max(0.0, Centre - Half) ),
    (   K =:= N -> High = 1.0 ; High is min(1.0, Centre + Half) ).

:- multifile prolog:message//1.

prolog:message(error(domain_error(probability_threshold, T), _)) -->
    [ 'decide(~w): a threshold is a probability strictly between 0 and 1'-[T] ].
