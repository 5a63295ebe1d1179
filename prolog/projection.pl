:- module(projection,
          [ make_projection/4,          % +Scenario, +Program, +Params, -Timeline
            make_projection/5,          % +Scenario, +Program, +Params, +Options, -Timeline
            simulate/5,                 % +Scenario, +Program, +Params, +Options, -Log
            translate/2,                % +Log, -Timeline
            projection_program/2,       % ?Program, -FormalParams:list(dict)
            projection_physics_setting/3, % ?Program, ?Name, -Setting:dict
            projection_physics_setting/4, % ?Program, ?Engine, ?Name, -Setting:dict
            projection_default_timeout/1, % -Seconds
            with_query_context/2,       % +Context:dict, :Goal
            current_query_context/1,    % -Context:dict
            parameter_values/2,         % +Range, -Values:list(number)
            projection_vocabulary/2,    % +Scenario, -Vocabulary:dict
            projection_check_condition/4, % +Scenario, ?Timeline, :Condition, +Pred
            projection_check_quantity/3 % +Scenario, +Quantity, +Pred
          ]).
:- autoload(library(apply), [maplist/3, foldl/4, include/3]).
:- autoload(library(error),
            [ must_be/2, domain_error/2, existence_error/2, type_error/2,
              instantiation_error/1 ]).
:- autoload(library(lists), [list_to_set/2, member/2, nth0/3, numlist/3]).
:- autoload(library(option), [option/2, option/3]).
:- autoload(library(pairs), [pairs_keys/2, pairs_keys_values/3]).
:- autoload(library(aggregate), [aggregate_all/3]).
:- autoload(library(solution_sequences), [limit/2]).
:- use_module(library(janus), [py_call/2]).
:- meta_predicate
    with_query_context(+, 0),
    projection_check_condition(+, ?, 0, +).
:- use_module(scenario, [scenario_description/2, scenario_entity/3]).
:- use_module(plan, [plan_template/3]).
:- use_module(timeline, [timeline_create/2, timeline_exists/1, timeline_remove/1,
                         occurs/3, timeline_vocabulary_create/2,
                         timeline_condition_terms/3, timeline_check_term/3,
                         timeline_vocabulary_dict/2]).

/** <module> Simulation-based temporal projection (the paper's section III-B)

make_projection/4,5 runs a robot control program in a physics simulation of a
scenario, once for every combination of parameter values, on backtracking,
and gives the timeline of each run:

```
?- make_projection(grasping, grasp_object,
                   [(F, force, [1, 3, 5]), (P, position, [-0.02, 0.0])],
                   Timeline),
   \+ occurs(break, _, Timeline),
   \+ occurs(slip, _, Timeline).
```

Params is a list of `(Var, Name, Range)`. Range is a list of values or
`range(Low, High, Step)` (inclusive, numeric). Combinations are enumerated in
lexicographic order of the list: the first parameter changes slowest, as in
nested loops. Parameters the list leaves out take the program's default.
While Prolog evaluates one combination, the next ones (as many as there are
simulation workers) are already being simulated.

make_projection/5 is simulate/5 followed by translate/2. simulate/5 runs the
projection in a PyBullet worker (projection_server.projection), which writes one
ROS bag per projection and makes its timeline from the samples in memory;
translate/2 stores that timeline (timeline.pl) in one call, or reads an older
bag into one.
An identical projection (same scenario description, program, parameters and
physics settings) reuses the bag and the timeline made before.

The physics settings come from config/physics.yaml (with settings per
program there); a query may choose its own, within the ranges that
projection_physics_setting/3 lists, e.g. to check a prediction against a 4x
finer time step:

```
?- make_projection(grasping, grasp_object, [(_, force, [5])],
                   [physics(_{rate_hz: 960, solver_iterations: 400})], TL).
```

After make_projection/4,5 (or translate/2), the paper's section II form runs
on that projection's timeline:

```
?- create_scenario(S), add_to_scenario(S, [kitchen_env, pr2_robot, egg1]),
   scenario_set_property(S, egg1, mass, 0.1),
   make_projection(S, grasp_object, [(F, force, [1.5])], _),
   occurs(Evt, T1), typeOf(Evt, dropping), objOf(Evt, egg1),
   after(T2, T1), holds(Fl, T2), objOf(Fl, egg1).
```
*/

%!  make_projection(+Scenario, +Program, +Params, -Timeline) is nondet.
%!  make_projection(+Scenario, +Program, +Params, +Options, -Timeline) is nondet.
%
%   Project Program in Scenario for each instantiation of Params (see the
%   module doc), binding the parameter variables and Timeline, the id of the
%   projection's timeline.  Program is a registered program (the named
%   programs, projection_program/2) or `plan(Steps)`, a plan written in the
%   query (plan.pl), whose variables are parameters of Params with any name
%   and any numbers as values.  Options is a list of
%
%     - timeout(+Seconds): the wall-clock limit of one simulation
%       (default: projection_default_timeout/1, times the factors by which
%       physics(D) raises the program's rate_hz and solver_iterations);
%     - physics(+Dict): engine settings of these projections instead of the
%       program's (projection_physics_setting/3), e.g.
%       `_{rate_hz: 960, solver_iterations: 400}`, or `_{engine: mujoco}`
%       (the engines: `pybullet`, the default, and `mujoco`);
%     - samples(+N): project each parametrization in N worlds drawn from the
%       scenario's beliefs (properties given as distributions, see
%       scenario_set_property/4), the worlds enumerated for each
%       parametrization in turn; each world's draws are the quantities
%       `sampled(Entity, Property)` of its timeline.  Without it, the
%       scenario's nominal world (each distribution's middle or mean);
%     - seed(+K): the sequence the worlds are drawn from (default 0): the
%       same seed draws the same worlds, whichever the parametrization;
%     - worlds(+From, +To): the worlds From..To-1 of the sequence (samples(N)
%       is worlds(0, N));
%     - only(+Combinations): of Params' combinations only these, each a list
%       of values in Params' order (e.g. the cells still in the running of a
%       choice: their projections run on all workers as one enumeration).
%
%   A number as Options is the timeout.
%
%   @error existence_error(scenario, S), existence_error(program, P),
%          existence_error(program_parameter, Program:Name),
%          existence_error(physics_setting, Name)
%   @error type_error(projection_parameter, E) for a malformed Params element
%   @error domain_error(parameter_value, Name=Value) for a value out of range
%   @error domain_error(projection_option, O) for an unknown option
%   @error domain_error(positive_integer, N) for samples(N) with N < 1
%   @error domain_error(params_combination, C) for a combination C of
%          only(Combinations) that is none of Params'
%   @error domain_error(parameter_range, range(Low, High, Step)) for a range
%          without values (High < Low)
%   @error domain_error(physics_setting(Name, Range), Value) for a physics
%          setting out of Range (`between(Min, Max)`, `multiple_of(N)`, or
%          `oneof(Engines)` for an unknown engine)
%   @error domain_error(plan_step, Step), domain_error(plan_length(1, Max), N)
%          for a malformed plan (plan_template/3)
%   @error domain_error(plan_value, Values) for a plan whose grounded values
%          are out of their ranges, resource_error(plan_duration) for one that
%          cannot finish within the interpreter's 120 s of simulated time (its
%          moves by offsets, turns and waits alone take longer) or that ran past
%          them (the message names the step)
%   @error existence_error(entity, Object) for a plan moving to an object
%          that is not in the scenario
%   @error projection_error(Kind, Message) when a simulation fails or times out
%          (kind `unreachable`: the robot cannot reach a pose the plan asks)

make_projection(Scenario, Program, Params, Timeline) :-
    projection_default_timeout(Timeout),
    make_projection(Scenario, Program, Params, Timeout, Timeline).

make_projection(Scenario, Program, Params, Options, Timeline) :-
    simulate(Scenario, Program, Params, Options, Log, Step),
    translate(Log, Timeline),
    report_progress(Step, Log, Timeline).

% The running query's progress listener (feedback of the ~/project action) hears of
% each finished projection: its place in the enumeration, parameters, events and bag.
report_progress(step(I, Total, Program, Values), Log, Timeline) :-
    findall(Name, ( occurs(Event, _, Timeline), functor(Event, Name, _) ), Names0),
    list_to_set(Names0, Names),
    Index is I + 1,
    query_context(Query),
    py_call('projection_server.service.progress':projection_done(Query, Index, Total,
                                                                 Program, Values, Log,
                                                                 Names)).

%!  with_query_context(+Context:dict, :Goal) is nondet.
%
%   Run Goal as the query the service knows by Context, `_{id: Id, owner:
%   Owner}`: the projections Goal makes are owned by Owner (the service
%   cancels them with the query) and report their progress to the query Id.
%   The query service runs each query's goal this way (query_service.pl);
%   outside it, projections have no owner.

%!  current_query_context(-Context:dict) is semidet.
%
%   Context is the context of the query this thread runs, if it runs one (to
%   run a query's goals in threads of their own as that query).

:- thread_local current_query_context/1.

with_query_context(Context, Goal) :-
    must_be(dict, Context),
    setup_call_cleanup(asserta(current_query_context(Context), Ref),
                       Goal,
                       erase(Ref)).

% query_context(-Query): the context of the query this thread runs, for Python
% (a dict, or None).
query_context(Query) :-
    (   current_query_context(Context)
    ->  Query = Context
    ;   Query = @(none)
    ).

query_owner(Owner) :-
    (   current_query_context(Context)
    ->  get_dict(owner, Context, Owner)
    ;   Owner = @(none)
    ).

%!  simulate(+Scenario, +Program, +Params, +Options, -Log) is nondet.
%
%   Set up and run one simulation per instantiation of Params; Log is the
%   path of its bag.  Options and errors as for make_projection/5.

simulate(Scenario, Program, Params, Options, Log) :-
    simulate(Scenario, Program, Params, Options, Log, _Step).

% simulate(..., -Step): Step is step(I, Total, Program, Values), the 0-based place
% of the projection in the enumeration, for make_projection's progress report.
simulate(Scenario, Program0, Params, Options, Log, step(I, Total, Program, Shown)) :-
    must_be(atom, Scenario),
    must_be(list, Params),
    program(Program0, Program, Formal),
    projection_options(Program, Options, Timeout, Physics, Worlds),
    maplist(parse_param(Program, Formal), Params, Choices),
    check_unique(Choices),
    plan_of(Program0, Choices, Plan),
    scenario_description(Scenario, Description0),
    plan_objects_exist(Plan, Scenario),
    % Made a Python dict once: every projection and prefetch of the query passes it on.
    py_call(dict(Description0), Description, [py_object(true)]),
    findall(Values, ( instantiate(Choices, Pairs),
                      dict_pairs(Values, params, Pairs) ), All0),
    only_combinations(Options, Choices, All0, All),
    check_plan(Plan, All),
    % The units of the enumeration: each parametrization, in each world.
    findall(Values-World, ( member(Values, All), world(Worlds, World) ), Units),
    pairs_keys(Units, UnitValues),
    py_call('projection_server.projection':workers(), Depth),
    py_call('projection_server.projection':prefetch_plan(Program, UnitValues, Depth,
                                                         physics=Physics), Ahead),
    Table =.. [units|Units],
    pairs_keys_values(Steps, Units, Ahead),
    length(Units, Total),
    query_owner(Owner),
    Run = run(Description, Program, Timeout, Physics, Owner, Plan),
    nth0(I, Steps, (Values-World)-Next),
    prefetch(Run, Table, Next),
    maplist(bind_choice(Values), Choices),
    shown(Values, World, Shown),
    run_simulation(Run, Values, World, Log).

% only_combinations(+Options, +Choices, +All0, -All): All0 without the
% combinations that option only(Combinations) leaves out.
only_combinations(Options, Choices, All0, All) :-
    is_list(Options),
    memberchk(only(Combinations), Options), !,
    include(in_combinations(Choices, Combinations), All0, All),
    % A combination that is none of Params' would silently not be projected.
    findall(Vs, ( member(Values, All),
                  maplist([choice(_, Name, _), V]>>get_dict(Name, Values, V), Choices, Vs) ),
            Grid),
    forall(member(C, Combinations),
           (   memberchk(C, Grid)
           ->  true
           ;   domain_error(params_combination, C)
           )).
only_combinations(_, _, All, All).

in_combinations(Choices, Combinations, Values) :-
    maplist([choice(_, Name, _), V]>>get_dict(Name, Values, V), Choices, Vs),
    memberchk(Vs, Combinations).

% world(+Worlds, -World): each world of the projection: @none for the
% nominal one, else [Seed, Index].
world(nominal, @(none)).
world(worlds(Seed, From, To), [Seed, J]) :-
    End is To - 1,
    between(From, End, J).

% shown(+Values, +World, -Shown): the parametrization as progress reports it,
% with the world's index when it is one of several.
shown(Values, @(none), Values) :- !.
shown(Values, [_, J], Values.put(world, J)).

% program(+Program0, -Name, -Formal): a registered program and its formal
% parameters, or a plan (Name `plan`, any parameters).
program(Program, _, _) :-
    var(Program), !,
    instantiation_error(Program).
program(plan(_), plan, any) :- !.
program(Program, Program, Formal) :-
    must_be(atom, Program),
    (   projection_program(Program, Formal)
    ->  true
    ;   existence_error(program, Program)
    ).

% plan_of(+Program0, +Choices, -Plan): the plan's template (@none for a
% registered program), its parameters referenced by name.
plan_of(plan(Steps), Choices, Plan) :- !,
    maplist([choice(Var, Name, _), Name-Var]>>true, Choices, Pairs),   % (not findall: it copies)
    plan_template(Steps, Pairs, Plan).
plan_of(_, _, @(none)).

% plan_objects_exist(+Plan, +Scenario): the objects the plan moves to are
% entities of Scenario.
plan_objects_exist(@(none), _) :- !.
plan_objects_exist(Plan, Scenario) :-
    forall(( member(Step, Plan), get_dict(object, Step, Object) ),
           (   scenario_entity(Scenario, Object, _)
           ->  true
           ;   format(atom(Msg), 'the plan moves to ~w, which is not in scenario ~w',
                      [Object, Scenario]),
               throw(error(existence_error(entity, Object), context(_, Msg)))
           )).

% check_plan(+Plan, +All): every parametrization grounds Plan to a plan the
% interpreter runs: its values in their ranges, its simulated time bounded.
check_plan(@(none), _) :- !.
check_plan(Plan, All) :-
    forall(member(Values, All),
           (   py_call('projection_server.projection':plan_problem(Plan, Values), Problem),
               (   Problem == @(none)
               ->  true
               ;   plan_error(Problem, Values)
               )
           )).

plan_error([duration, Message], _) :- !,
    atom_string(Msg, Message),
    throw(error(resource_error(plan_duration), context(_, Msg))).
plan_error([_, Message], Values) :-
    atom_string(Msg, Message),
    throw(error(domain_error(plan_value, Values), context(_, Msg))).

bind_choice(Values, choice(Var, Name, _)) :-
    get_dict(Name, Values, Var).

% While the workers simulate parametrization I, the ones the plan names for I
% are queued (the plan is projection:prefetch_plan/3's), so a query that
% backtracks finds them done or under way: the next Depth ones, or, for a
% program whose parametrizations share their first steps, the next Depth+1
% families of them, each family at once.  Each is queued once: queueing it
% again would cost a check and a key (a third of a cached query).
prefetch(_, _, []) :- !.
prefetch(run(Description, Program, Timeout, Physics, Owner, Plan), Table, Ahead) :-
    findall(V-W, ( member(J, Ahead), A is J + 1, arg(A, Table, V-W) ), Next),
    pairs_keys_values(Next, Values, Worlds),
    py_call('projection_server.projection':prefetch(Description, Program, Values,
                                                    Timeout, physics=Physics,
                                                    owner=Owner, plan=Plan,
                                                    worlds=Worlds), _).

projection_options(_, Timeout, Timeout, _{}, nominal) :-
    number(Timeout), !,
    must_be_positive(Timeout).
projection_options(Program, Options, Timeout, Physics, Worlds) :-
    must_be(list, Options),
    maplist(check_option, Options),
    worlds_option(Options, Worlds),
    option(physics(Physics), Options, _{}),
    (   is_dict(Physics)
    ->  true
    ;   type_error(dict, Physics)
    ),
    dict_pairs(Physics, _, Pairs),
    maplist(check_physics_setting(Program), Pairs),
    (   option(timeout(Timeout), Options)
    ->  true
    ;   default_timeout(Program, Pairs, Timeout)
    ),
    must_be_positive(Timeout).

% default_timeout(+Program, +Physics, -Seconds): projection_default_timeout/1,
% times as many more steps and solver iterations as Physics asks of the
% program's own: a 4x finer pour takes about 16x as long as the pour.
default_timeout(Program, Physics, Timeout) :-
    projection_default_timeout(Default),
    (   memberchk(engine-Engine, Physics) -> true ; Engine = @(none) ),
    py_call('projection_server.projection':physics_settings(Program, Engine), Settings),
    foldl(cost_factor(Settings), Physics, 1, Factor),
    Timeout is Default * Factor.

% cost_factor(+Settings, +Name-Value, +F0, -F): F0 times as many more steps or
% solver iterations as Value is of the default (of the projection's engine).
cost_factor(Settings, Name-Value, F0, F) :-
    (   memberchk(Name, [rate_hz, solver_iterations]),
        member(Setting, Settings),
        get_dict(name, Setting, Name), !,
        get_dict(default, Setting, Own), Own > 0
    ->  F is F0 * max(1, Value / Own)
    ;   F = F0
    ).

check_option(Option) :-
    var(Option), !,
    instantiation_error(Option).
check_option(timeout(_)) :- !.
check_option(physics(_)) :- !.
check_option(samples(N)) :- !,
    must_be(integer, N),
    (   N >= 1 -> true ; domain_error(positive_integer, N) ).
check_option(seed(K)) :- !,
    must_be(integer, K),
    (   K >= 0 -> true ; domain_error(nonneg, K) ).
check_option(worlds(From, To)) :- !,
    must_be(nonneg, From), must_be(integer, To),
    (   To > From -> true ; domain_error(worlds_range, worlds(From, To)) ).
check_option(only(Combinations)) :- !,
    must_be(list(list), Combinations).
check_option(Option) :-
    domain_error(projection_option, Option).

% worlds_option(+Options, -Worlds): `nominal`, or worlds(Seed, From, To), the
% worlds From..To-1 of the sequence Seed drawn from the scenario's beliefs.
worlds_option(Options, Worlds) :-
    option(seed(Seed), Options, 0),
    (   option(worlds(From, To), Options)
    ->  (   option(samples(_), Options)
        ->  domain_error(projection_option, samples_and_worlds)
        ;   Worlds = worlds(Seed, From, To)
        )
    ;   option(samples(N), Options)
    ->  Worlds = worlds(Seed, 0, N)
    ;   Worlds = nominal
    ).

check_physics_setting(Program, Name-Value) :-
    (   projection_physics_setting(Program, Name, Setting)
    ->  true
    ;   existence_error(physics_setting, Name)
    ),
    (   get_dict(values, Setting, Names)    % a choice of names: the engine
    ->  maplist(string_atom, Names, Atoms),
        (   atom(Value), memberchk(Value, Atoms)
        ->  true
        ;   domain_error(physics_setting(Name, oneof(Atoms)), Value)
        )
    ;   check_physics_number(Name, Value, Setting)
    ).

string_atom(String, Atom) :- atom_string(Atom, String).

check_physics_number(Name, Value, Setting) :-
    (   get_dict(integer, Setting, @(true))
    ->  must_be(integer, Value)
    ;   must_be(number, Value)
    ),
    get_dict(min, Setting, Min), get_dict(max, Setting, Max),
    (   Value >= Min, Value =< Max
    ->  true
    ;   domain_error(physics_setting(Name, between(Min, Max)), Value)
    ),
    (   get_dict(multiple_of, Setting, N), Value mod N =\= 0
    ->  domain_error(physics_setting(Name, multiple_of(N)), Value)
    ;   true
    ).

parse_param(Program, Formal, Param, choice(Var, Name, Values)) :-
    (   Param = (Var, Name, Range)
    ->  true
    ;   type_error(projection_parameter, Param)
    ),
    must_be(atom, Name),
    range_values(Range, Values),
    (   Formal == any                   % a plan's parameter: any name, any number
    ->  must_be(list(number), Values)
    ;   member(F, Formal), get_dict(name, F, Name0), atom_string(Name, Name0)
    ->  maplist(check_value(F, Name), Values)
    ;   existence_error(program_parameter, Program:Name)
    ).

%!  parameter_values(+Range, -Values:list(number)) is det.
%
%   Values are the values of a parameter's Range as make_projection/5 takes
%   it: a non-empty list, or `range(Low, High, Step)`.
%
%   @error type_error(parameter_range, Range) for another term
%   @error domain_error(parameter_range, range(Low, High, Step)) for High < Low
%          (no values)

parameter_values(Range, Values) :-
    range_values(Range, Values).

range_values(range(Low, High, Step), Values) :- !,
    must_be(number, Low), must_be(number, High), must_be_positive(Step),
    (   High >= Low
    ->  true
    ;   domain_error(parameter_range, range(Low, High, Step))
    ),
    N is floor((High - Low) / Step + 1.0e-9),
    numlist(0, N, Is),
    maplist([I, V]>>(V0 is Low + I * Step, V is round(V0 * 1.0e9) / 1.0e9), Is, Values).
range_values(Values, Values) :-
    is_list(Values), Values \== [], !.
range_values(Range, _) :-
    type_error(parameter_range, Range).

check_value(Formal, Name, Value) :-
    (   number(Value)
    ->  true
    ;   type_error(number, Value)
    ),
    get_dict(min, Formal, Min), get_dict(max, Formal, Max),
    (   Value >= Min, Value =< Max
    ->  true
    ;   domain_error(parameter_value, Name=Value)
    ).

check_unique(Choices) :-
    findall(N, member(choice(_, N, _), Choices), Names),
    sort(Names, Unique),
    length(Names, L), length(Unique, L), !.
check_unique(Choices) :-
    domain_error(distinct_parameters, Choices).

must_be_positive(X) :-
    must_be(number, X),
    (   X > 0 -> true ; domain_error(positive_number, X) ).

instantiate([], []).
instantiate([choice(_, Name, Values)|T], [Name-Value|Pairs]) :-
    member(Value, Values),
    instantiate(T, Pairs).

run_simulation(run(Description, Program, Timeout, Physics, Owner, Plan), Values, World,
               Log) :-
    catch(py_call('projection_server.projection':simulate(Description, Program,
                                                          Values, Timeout,
                                                          physics=Physics,
                                                          owner=Owner, plan=Plan,
                                                          world=World), Log0),
          error(python_error(Class, Value), _),
          projection_error(Class, Value)),
    atom_string(Log, Log0).

projection_error(Class, Value) :-
    (   catch(py_call(Value:kind, Kind0), _, fail)
    ->  atom_string(Kind, Kind0)
    ;   Kind = Class
    ),
    (   catch(py_call(str(Value), Message0), _, fail)
    ->  atom_string(Message, Message0)
    ;   Message = Class
    ),
    (   Kind == plan_duration   % as check_plan/2 says it before running
    ->  throw(error(resource_error(plan_duration), context(_, Message)))
    ;   throw(error(projection_error(Kind, Message), _))
    ).

%!  translate(+Log, -Timeline) is det.
%
%   Timeline is the timeline of the bag Log: the one the simulation worker
%   made from its samples when this process just made the bag, else read
%   from the bag (the same timeline).  Translating the same bag again
%   gives the same timeline, as long as it was not removed.  Timeline becomes
%   the query's current timeline: holds/2, occurs/2, typeOf/2 and objOf/2
%   (the paper's section II form) evaluate on it until the next translation
%   or a with_timeline/2.
%
%   @error existence_error(file, Log) if there is no such bag

:- dynamic log_timeline/2.

translate(Log, Timeline) :-
    translate_(Log, Timeline),
    % The paper's two-argument forms (holds/2, occurs/2) then evaluate on this
    % timeline for the rest of the query (see timeline:current_timeline/1).
    b_setval('$timeline_selected', Timeline).

translate_(Log0, Timeline) :-
    must_be(text, Log0),
    atom_string(Log, Log0),
    (   log_timeline(Log, Timeline0), timeline_exists(Timeline0)
    ->  Timeline = Timeline0
    ;   exists_directory(Log)
    ->  catch(py_call('projection_server.projection':timeline(Log), Data),
              error(python_error(Class, Value), _),
              projection_error(Class, Value)),
        with_mutex(projection_translate,
                   (   log_timeline(Log, Timeline0), timeline_exists(Timeline0)
                   ->  Timeline = Timeline0
                   ;   timeline_create(Data, Timeline),
                       remember_timeline(Log, Timeline)
                   ))
    ;   existence_error(file, Log)
    ).

% translate/2 keeps the timelines of the most recently translated bags, as
% many as the flag projection_max_timelines says (default 256); older ones
% are removed, so that a query over thousands of parametrizations runs in
% bounded memory.  Translating such a bag again makes its timeline anew.
:- create_prolog_flag(projection_max_timelines, 256, [type(integer), keep(true)]).

remember_timeline(Log, Timeline) :-
    retractall(log_timeline(Log, _)),
    assertz(log_timeline(Log, Timeline)),
    current_prolog_flag(projection_max_timelines, Max),
    aggregate_all(count, log_timeline(_, _), N),
    (   N > Max
    ->  Excess is N - Max,
        forall(limit(Excess, retract(log_timeline(_, Old))),
               (   timeline_exists(Old) -> timeline_remove(Old) ; true ))
    ;   true
    ).

%!  projection_program(?Program, -FormalParams:list) is nondet.
%
%   Program is a registered robot control program; FormalParams are dicts
%   with its parameters' name, unit, min, max and default.

projection_program(Program, Formal) :-
    py_call('projection_server.projection':programs(), Programs),
    member(P, Programs),
    get_dict(program, P, Name),
    atom_string(Program, Name),
    get_dict(params, P, Formal).

%!  projection_physics_setting(?Program, ?Name, -Setting:dict) is nondet.
%
%   Name is a physics setting that a query may choose for projections of
%   Program (make_projection/5's physics(Dict) option); `plan` for plans.  Setting is a dict
%   with its name, unit, min, max, integer (`@true` or `@false`), doc and
%   default (the program's on the node's engine, from config/physics.yaml:
%   MuJoCo's rate is its own); that of `rate_hz` has
%   multiple_of: the step rate must be a multiple of the control and logging
%   rates.
%
%   @error existence_error(program, Program) for a Program that is bound to
%          no registered program (nor `plan`).

projection_physics_setting(Program, Name, Setting) :-
    (   Program == plan                 % a plan: the settings file's defaults
    ->  true
    ;   atom(Program)
    ->  (   projection_program(Program, _)
        ->  true
        ;   existence_error(program, Program)
        )
    ;   projection_program(Program, _)
    ),
    py_call('projection_server.projection':physics_settings(Program), Settings),
    member(Setting, Settings),
    get_dict(name, Setting, Name0),
    atom_string(Name, Name0).

%!  projection_physics_setting(?Program, ?Engine, ?Name, -Setting:dict) is nondet.
%
%   As projection_physics_setting/3, with Setting's default that of Program on
%   Engine (`pybullet` or `mujoco`): e.g. MuJoCo's own `rate_hz`, 120.
%
%   @error domain_error(physics_setting(engine, oneof(Engines)), Engine) for
%          an Engine that is none of Engines.
%   @error existence_error(program, Program) as projection_physics_setting/3.

projection_physics_setting(Program, Engine, Name, Setting) :-
    projection_physics_setting(Program, engine, EngineSetting),
    get_dict(values, EngineSetting, Names),
    maplist(string_atom, Names, Engines),
    (   var(Engine)
    ->  member(Engine, Engines)
    ;   atom(Engine), memberchk(Engine, Engines)
    ->  true
    ;   domain_error(physics_setting(engine, oneof(Engines)), Engine)
    ),
    py_call('projection_server.projection':physics_settings(Program, Engine), Settings),
    member(Setting, Settings),
    get_dict(name, Setting, Name0),
    atom_string(Name, Name0).

%!  projection_vocabulary(+Scenario, -Vocabulary:dict) is det.
%
%   Vocabulary is what any timeline of a projection of Scenario can name:
%   `_{fluents: [Name/Arity, ...], events: ..., quantities: ..., objects:
%   [Object, ...]}`, the fluents, events and quantities the translation
%   makes of its entities (those of a particle fluid only if it has one)
%   and its objects (its entities, parts included).  The translation's
%   rules are the same for every program, so the vocabulary is the
%   scenario's.  A name or object outside it is an existence_error in
%   holds/3, occurs/3, quantity/3 and in the conditions of the predicates
%   that take one (see timeline.pl).
%
%   @error existence_error(scenario, Scenario) for an unknown scenario.
%   @error projection_error(invalid_scenario, Message) for a scenario the
%          simulator refuses.

projection_vocabulary(Scenario, Dict) :-
    scenario_vocabulary_data(Scenario, Data),
    (   Data = error(Class, Value)
    ->  projection_error(Class, Value)
    ;   timeline_vocabulary_create(Data, Vocabulary),
        timeline_vocabulary_dict(Vocabulary, Dict)
    ).

% vocabulary_of(+Scenario, -Vocabulary): the stored vocabulary of Scenario's timelines,
% `none` for a scenario the simulator refuses (projecting it says why).
vocabulary_of(Scenario, Vocabulary) :-
    scenario_vocabulary_data(Scenario, Data),
    (   Data = error(_, _)
    ->  Vocabulary = none
    ;   timeline_vocabulary_create(Data, Vocabulary)
    ).

% scenario_vocabulary_data(+Scenario, -Data): the simulator's vocabulary of Scenario's
% description, or error(Class, Value); kept per description, so that a changed scenario
% gets its own, and for the most recent ones only (bounded memory).
:- dynamic scenario_vocabulary/3.       % Hash, Sequence number, Data

scenario_vocabulary_data(Scenario, Data) :-
    scenario_description(Scenario, Description),
    variant_sha1(Description, Hash),
    (   scenario_vocabulary(Hash, _, Data0)
    ->  Data = Data0
    ;   % A scenario the simulator refuses has no vocabulary; any other error is a bug
        % and must not pass for "check nothing".
        catch(py_call('projection_server.projection':vocabulary(Description), Data),
              error(python_error('ProjectionError', Value), _),
              Data = error('ProjectionError', Value)),
        flag(projection_vocabulary_seq, N, N+1),
        assertz(scenario_vocabulary(Hash, N, Data)),
        aggregate_all(count, scenario_vocabulary(_, _, _), Count),
        Excess is Count - 64,
        forall(limit(Excess, retract(scenario_vocabulary(_, _, _))), true)
    ).

%!  projection_check_condition(+Scenario, ?Timeline, :Condition, +Pred) is det.
%
%   The fluents, events, quantities, types and objects that Condition, a
%   goal on the projection's timeline Timeline, names
%   (timeline_condition_terms/3) are ones a timeline of Scenario can have;
%   called before projecting by the predicates that take a condition, Pred
%   (e.g. outcome_probability/7), so that a misspelled name is an error
%   instead of a condition that is never, or always, true.
%
%   @error existence_error(Kind, Term) for the first term that is not (Kind
%          `fluent`, `event`, `quantity`, `type` or `entity`); the message
%          names Pred and Scenario and lists the known ones.

projection_check_condition(Scenario, Timeline, Condition, Pred) :-
    timeline_condition_terms(Condition, Timeline, Terms),
    (   Terms == []
    ->  true
    ;   vocabulary_of(Scenario, Vocabulary),
        maplist(timeline_check_term(Vocabulary, context(Pred, Scenario)), Terms)
    ).

%!  projection_check_quantity(+Scenario, +Quantity, +Pred) is det.
%
%   Quantity (a term or an atom pattern, as quantity/3 takes it) is one a
%   timeline of Scenario can have; Pred takes it (e.g. the objective of
%   best_parametrization/8).
%
%   @error existence_error(quantity, Quantity) or existence_error(entity,
%          Object) if it is not.

projection_check_quantity(Scenario, Quantity, Pred) :-
    vocabulary_of(Scenario, Vocabulary),
    timeline_check_term(Vocabulary, context(Pred, Scenario), quantity-Quantity).

%!  projection_default_timeout(-Seconds) is det.
%
%   Wall-clock limit of one simulation for make_projection/4: 300 s. A pour
%   takes about 30 s on a quiet core, and a machine shared with other work may
%   take several times as long; the query's own time limit bounds the whole.

projection_default_timeout(300).

:- multifile sandbox:safe_primitive/1.

% It reads the scenario store and asks the simulator's vocabulary of it, nothing else.
sandbox:safe_primitive(projection:projection_vocabulary(_, _)).

:- multifile prolog:error_message//1.

prolog:error_message(projection_error(Kind, Message)) -->
    [ 'Projection failed (~w): ~w'-[Kind, Message] ].
