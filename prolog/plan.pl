:- module(plan,
          [ plan_template/3,            % +Plan, +Params, -Template:list(dict)
            plan_primitive/2            % ?Name, ?Arities:list
          ]).
:- autoload(library(apply), [maplist/3]).
:- autoload(library(error),
            [ must_be/2, domain_error/2, type_error/2, instantiation_error/1 ]).
:- autoload(library(lists), [member/2, memberchk/2]).

/** <module> Plans: control programs written in the query

A plan is a list of motion primitives of the scenario's robot, the control
program of a projection written in the query itself:

```
?- make_projection(S, plan([move_to(egg1, [0, 0, 0.10], [orientation(top)]),
                            open_gripper,
                            move_to(egg1, [P, 0, 0]),
                            close_gripper(F),
                            move_by([0, 0, 0.10]),
                            wait(1.0)]),
                   [(F, force, [1, 3, 5]), (P, position, [-0.02, 0.0, 0.02])], TL).
```

The primitives (Options a list; numbers may be arithmetic of numbers and
parameters, e.g. `P + 0.09`):

  - move_to(+Object, +[DX, DY, DZ]), move_to(+Object, +Offset, +Options):
    the tool point to Object's position (when the step starts) plus the
    offset, in world axes;
  - move_to(pose([X, Y, Z], [QX, QY, QZ, QW])), move_to(pose(...), +Options):
    the tool point and frame to a pose (quaternion in ROS order);
  - move_by(+[DX, DY, DZ]), move_by(+Offset, +Options);
  - rotate_by(+Axis, +Angle), rotate_by(+Axis, +Angle, +Options): the tool
    frame about Axis (`x`, `y`, `z` or `[X, Y, Z]`, world axes) through the
    tool point by Angle (rad);
  - open_gripper, close_gripper(+Force) (N), wait(+Seconds).

Options: speed(MetresPerSecond), angular_speed(RadiansPerSecond),
orientation(top), orientation(top(Yaw)), orientation(side(Yaw)) (not for a
pose). The conventions (tool frame, defaults, bounds) are those of the
interpreter, projection_server/simulation/programs/plan.py.

plan_template/3 checks a plan's form and turns it into the data the
simulation takes, each parameter variable a reference `_{param: Name}`:
the plan knows where each parameter first acts. Its values and its bounds
(steps, simulated time) are checked when it is grounded, before anything
runs.
*/

%!  plan_primitive(?Name, ?Arities:list) is nondet.
%
%   Name is a motion primitive with the arities it may be written with.

plan_primitive(move_to, [1, 2, 3]).
plan_primitive(move_by, [1, 2]).
plan_primitive(rotate_by, [2, 3]).
plan_primitive(open_gripper, [0]).
plan_primitive(close_gripper, [1]).
plan_primitive(wait, [1]).

%!  plan_template(+Plan:list, +Params:list, -Template:list(dict)) is det.
%
%   Template is the data form of Plan, whose variables are those of Params
%   (`Name-Var` pairs): a list of dicts with an `action` and its arguments,
%   each parameter a `_{param: Name}`, each arithmetic expression over
%   parameters an `_{expr: [Op, A, B]}`.
%
%   @error instantiation_error if Plan or a step is unbound, or holds a
%          variable that is no parameter
%   @error type_error(list, Plan) for a plan that is not a list
%   @error domain_error(plan_step, Step) for an unknown primitive, a wrong
%          arity, an argument or option of the wrong form
%   @error domain_error(plan_length(1, Max), N) for an empty plan or one of
%          more than Max steps

plan_template(Plan, Params, Template) :-
    must_be(list, Plan),
    length(Plan, N),
    max_steps(Max),
    (   N >= 1, N =< Max
    ->  true
    ;   domain_error(plan_length(1, Max), N)
    ),
    maplist(step_template(Params), Plan, Template).

% The interpreter's bound, which Python checks again.
max_steps(100).

step_template(_, Step, _) :-
    var(Step), !,
    instantiation_error(Step).
step_template(Params, Step, Dict) :-
    (   catch(step_(Step, Params, Pairs), error(domain_error(plan_argument, _), _), fail)
    ->  dict_pairs(Dict, step, Pairs)
    ;   domain_error(plan_step, Step)
    ).

step_(Step, Params, [action-Name|Args]) :-
    compound(Step),
    compound_name_arity(Step, Name, Arity),
    plan_primitive(Name, Arities),
    memberchk(Arity, Arities),
    Step =.. [Name|Args0],
    primitive_args(Name, Args0, Params, Args).
step_(Step, _, [action-Step]) :-
    atom(Step),
    plan_primitive(Step, Arities),
    memberchk(0, Arities).

primitive_args(move_to, [pose(P, Q)|Rest], Params,
               [pose-pose{position: PT, orientation: QT}|Opts]) :- !,
    options_of(Rest, Options),
    vector(P, 3, Params, PT),
    vector(Q, 4, Params, QT),
    options(Options, [speed, angular_speed], Params, Opts).
primitive_args(move_to, [Object|Rest], Params, [object-Object, offset-OT|Opts]) :-
    atom(Object),
    (   Rest == [] -> Offset = [0, 0, 0], Options = [] ; Rest = [Offset|More] ),
    (   var(Options) -> options_of(More, Options) ; true ),
    vector(Offset, 3, Params, OT),
    options(Options, [speed, angular_speed, orientation], Params, Opts).
primitive_args(move_by, [Offset|Rest], Params, [offset-OT|Opts]) :-
    options_of(Rest, Options),
    vector(Offset, 3, Params, OT),
    options(Options, [speed, angular_speed, orientation], Params, Opts).
primitive_args(rotate_by, [Axis, Angle|Rest], Params, [axis-AT, angle-A|Opts]) :-
    options_of(Rest, Options),
    (   memberchk(Axis, [x, y, z]) -> AT = Axis ; vector(Axis, 3, Params, AT) ),
    number_(Angle, Params, A),
    options(Options, [angular_speed], Params, Opts).
primitive_args(close_gripper, [Force], Params, [force-F]) :-
    number_(Force, Params, F).
primitive_args(wait, [Seconds], Params, [seconds-S]) :-
    number_(Seconds, Params, S).

% options_of(+Rest, -Options): a primitive's optional last argument, its
% options list.
options_of([], []).
options_of([Options], Options).

options([], _, _, []) :- !.
options(Options, Allowed, Params, Pairs) :-
    is_list(Options),
    maplist(option(Allowed, Params), Options, Pairs),
    \+ ( member(K-_, Pairs), aggregate_count(K, Pairs, C), C > 1 ).

aggregate_count(K, Pairs, C) :-
    findall(x, member(K-_, Pairs), Xs),
    length(Xs, C).

option(Allowed, Params, Option, Key-Value) :-
    nonvar(Option),
    Option =.. [Key, Arg],
    memberchk(Key, Allowed),
    option_value(Key, Arg, Params, Value).

option_value(orientation, top, _, top) :- !.
option_value(orientation, top(Yaw), Params, [top, Y]) :- !,
    number_(Yaw, Params, Y).
option_value(orientation, side(Yaw), Params, [side, Y]) :- !,
    number_(Yaw, Params, Y).
option_value(Key, Arg, Params, V) :-
    memberchk(Key, [speed, angular_speed]),
    number_(Arg, Params, V).

vector(List, N, Params, Template) :-
    is_list(List),
    length(List, N),
    numbers(List, Params, Template).

% (Not maplist/3 with a lambda: yall copies the lambda's free variables,
% the parameter variables among them.)
numbers([], _, []).
numbers([X|Xs], Params, [T|Ts]) :-
    number_(X, Params, T),
    numbers(Xs, Params, Ts).

% number_(+Term, +Params, -Template): a number, a parameter, or arithmetic
% of them (evaluated where it names no parameter).
number_(X, Params, T) :-
    var(X), !,
    (   member(Name-V, Params), V == X
    ->  T = ref{param: Name}
    ;   instantiation_error(X)
    ).
number_(X, _, X) :-
    number(X), !.
number_(X, _, V) :-
    ground(X),
    catch(V0 is X, _, fail),
    !,
    V is float(V0).
number_(X, Params, ref{expr: [Op|Ts]}) :-
    compound(X),
    X =.. [Op|Args],
    memberchk(Op-Arity, ['+'-2, '-'-2, '*'-2, '/'-2, '-'-1]),
    length(Args, Arity),
    !,
    numbers(Args, Params, Ts).
number_(X, _, _) :-
    throw(error(domain_error(plan_argument, X), _)).

:- multifile prolog:message//1.

prolog:message(error(domain_error(plan_step, Step), _)) -->
    [ 'Unknown or malformed plan step ~q: a step is one of move_to/1,2,3, '-[Step],
      'move_by/1,2, rotate_by/2,3, open_gripper, close_gripper/1, wait/1 with its ',
      'arguments and options (speed/1, angular_speed/1, orientation/1)' ].
prolog:message(error(domain_error(plan_length(Min, Max), N), _)) -->
    [ 'A plan has ~w to ~w steps, this one ~w'-[Min, Max, N] ].
