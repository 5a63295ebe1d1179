:- module(robot_world,
          [ robot_world/2,              % -Scenario, +Options
            bag_scenario/2              % +Bag, -Scenario
          ]).
:- autoload(library(apply), [maplist/3, partition/4]).
:- autoload(library(error), [must_be/2, domain_error/2, existence_error/2]).
:- autoload(library(lists), [member/2]).
:- autoload(library(option), [option/2, option/3]).
:- autoload(library(pairs), [pairs_keys/2]).
:- use_module(library(janus), [py_call/3]).
:- use_module(scenario, [create_scenario/1, add_to_scenario/2, scenario_set_property/4,
                         scenario_set_snapshot/2, delete_scenario/1,
                         create_scenario_from/2]).
:- use_module(knowledge_base, [kb_urdf_robot/2, kb_entity_properties/2, kb_entity_frame/2]).

/** <module> Scenarios from the world the robot is in

robot_world/2 makes a scenario of what the robot's ROS graph publishes now:
the robot from `/robot_description` at the joint positions of `/joint_states`,
its base where TF puts its root link in the world frame, and each object at
the pose of its TF frame.

```
?- robot_world(S, [entities([kitchen_env,
                             entity(egg1, egg, _{frame: egg_1})])]),
   make_projection(S, plan([move_to(egg1, [0, 0, 0.1], [orientation(top)]),
                            move_to(egg1, [0, 0, 0]), close_gripper(5),
                            wait(0.2), move_by([0, 0, 0.1]), wait(0.3)]), [], TL).
```

The scenario is an ordinary created scenario (same lifetime, copy_scenario/2,
scenario_set_property/4, beliefs) that also holds its *snapshot*: the joint
positions, the frames' poses in the world frame with their stamps and ages,
and the robot description's SHA-256.  The snapshot is in every projection's
`/projection/info`, so a projection from the live world can be run again and
drawn without the robot.  Nothing is written back into the live world.

What a URDF does not say (which link carries the tool, which joints are the
fingers, the grip force limit) comes from the knowledge base's robot whose
`kitchen:urdfRobot` is the URDF's robot name (the Panda's ship: `panda`), over
which the option robot(Facts) goes.
*/

%!  robot_world(-Scenario, +Options:list) is det.
%
%   Scenario is a new scenario of the robot's world as its ROS graph has it
%   now.  Options:
%
%     - entities(+List): what to add besides the robot, in the forms of
%       add_to_scenario/2 (default `[]`).  An `entity(Name, Class, Props)`
%       whose Props have `frame: F`, or a knowledge-base entity whose
%       individual has a `kitchen:tfFrame`, is placed at the pose of TF frame F
%       (its other properties, a belief too, as add_to_scenario/2 takes them).
%     - robot(+Facts:dict): the robot's facts over the knowledge base's
%       (`tool_link`, `tool_offset`, `finger_joints`, `max_force`, `pad_links`,
%       `tool_rpy`, ...: those of a `urdf` robot, add_to_scenario/2).
%     - robot_name(+Name): the robot entity's name (default: the URDF's robot
%       name, `panda` for the Panda).
%     - world_frame(+Frame): the frame poses are in (default `map`).
%     - max_age(+Seconds): the oldest a frame or joint state may be (default
%       1.0; static frames never age).
%     - wait(+Seconds): how long to wait for a robot description, a frame or a
%       joint state that has not arrived (default 2.0).
%
%   @error existence_error(robot_description, Topic) if none arrives within
%          the wait.
%   @error domain_error(urdf, Topic) for a description that does not parse
%          (the message names the line and column).
%   @error existence_error(mesh, URI) for a mesh URI that is not found;
%          permission_error(mesh, URI, _) for one outside the asset and
%          package share directories.
%   @error existence_error(frame, Frame) for a frame TF does not know within
%          the wait; existence_error(transform, Text) for one not connected
%          to the world frame.
%   @error domain_error(fresh_frame, Frame) for a frame older than max_age
%          (the message gives its age).
%   @error existence_error(joint_state, Joint) for a moving joint of the URDF
%          with no state within the wait; domain_error(fresh_joint_state,
%          Joint) for one older than max_age.
%   @error domain_error(joint_limits, Joint) for a joint state outside the
%          joint's limits.
%   @error existence_error(urdf_robot_facts, Name) for a robot the knowledge
%          base has no facts of and whose robot(Facts) lacks them.
%   @error domain_error(robot_world_option, Option) for an unknown option.
%   Errors of add_to_scenario/2 for the entities.

robot_world(Scenario, Options) :-
    must_be(var, Scenario),
    must_be(list, Options),
    maplist(check_option, Options),
    option(entities(Entities), Options, []),
    must_be(list, Entities),
    option(world_frame(World), Options, map),
    option(max_age(MaxAge), Options, 1.0),
    option(wait(Wait), Options, 2.0),
    must_be(atomic, World),
    seconds(max_age, MaxAge),
    seconds(wait, Wait),
    maplist(framed, Entities, Placed, Framed0),
    exclude_none(Framed0, Framed),
    pairs_keys_values_(Framed, _, Frames),
    get_time(Now),
    Deadline is Now + Wait,
    py_options(World, Frames, MaxAge, PyOptions),
    take(PyOptions, Deadline, Snapshot),
    robot_entity(Snapshot.robot, Options, Robot),
    create_scenario(Scenario),
    catch(fill(Scenario, Robot, Placed, Framed, Snapshot),
          Error,
          ( delete_scenario(Scenario), throw(Error) )).

seconds(Name, Value) :-
    must_be(number, Value),
    (   Value >= 0
    ->  true
    ;   Option =.. [Name, Value],
        domain_error(robot_world_option, Option)
    ).

check_option(Option) :-
    (   var(Option)
    ->  domain_error(robot_world_option, Option)
    ;   functor(Option, Name, 1),
        memberchk(Name, [entities, robot, robot_name, world_frame, max_age, wait])
    ->  true
    ;   domain_error(robot_world_option, Option)
    ).

% framed(+Spec, -Spec1, -NameFrame): Spec1 is Spec without its frame, and
% NameFrame the entity's name and frame (none: it has none).
framed(entity(Name, Class, Props), entity(Name, Class, Props1), Name-Frame) :-
    is_dict(Props),
    del_dict(frame, Props, Frame0, Props1),
    !,
    must_be(atomic, Frame0),
    atom_string(Frame, Frame0).
framed(Name, Name, Name-Frame) :-
    atom(Name),
    kb_entity_frame(Name, Frame),
    !.
framed(Spec, Spec, none).

exclude_none(Pairs0, Pairs) :-
    partition(==(none), Pairs0, _, Pairs).

pairs_keys_values_(Pairs, Keys, Values) :-
    pairs_keys(Pairs, Keys),
    maplist([_-V, V]>>true, Pairs, Values).

py_options(World, Frames, MaxAge, _{world_frame: WorldS, frames: FrameStrings, max_age: A}) :-
    atom_string(World, WorldS),
    maplist([F, S]>>atom_string(F, S), Frames, FrameStrings),
    A is float(MaxAge).

% take(+Options, +Deadline, -Snapshot): try, waiting in slices of at most
% 0.1 s (projection_server.world.WAIT_SLICE) so that a query's time limit or
% cancel stops the wait.
take(Options, Deadline, Snapshot) :-
    py_call('projection_server.world':try_snapshot(Options, Deadline), Answer,
            [py_string_as(string)]),
    get_dict(status, Answer, Status),
    (   Status == "ok"
    ->  Snapshot = Answer.snapshot
    ;   Status == "waiting"
    ->  take(Options, Deadline, Snapshot)
    ;   world_error(Answer.error)
    ).

world_error(E) :-
    atom_string(Formal, E.formal),
    atom_string(Type, E.type),
    culprit(E.culprit, Culprit),
    (   Formal == permission_error
    ->  Term = permission_error(read, Type, Culprit)
    ;   Term =.. [Formal, Type, Culprit]
    ),
    throw(error(Term, context(robot_world/2, E.message))).

culprit(C0, C) :-
    (   string(C0) -> atom_string(C, C0) ; C = C0 ).

% robot_entity(+Robot, +Options, -Entity): the robot entity of a snapshot,
% with the facts of the knowledge base's robot for its URDF and robot(Facts).
robot_entity(Robot, Options, entity(Name, robot, Props)) :-
    atom_string(UrdfName, Robot.name),
    option(robot_name(Name), Options, UrdfName),
    must_be(atom, Name),
    option(robot(Given), Options, _{}),
    (   is_dict(Given) -> true ; must_be(dict, Given) ),
    (   kb_urdf_robot(UrdfName, Individual)
    ->  kb_entity_properties(Individual, Kb0),
        del_keys([file, home, shape], Kb0, Kb)
    ;   Kb = _{}
    ),
    Facts = Kb.put(Given),
    (   get_dict(tool_link, Facts, _)
    ->  true
    ;   format(atom(Msg), 'the knowledge base has no facts of the URDF robot ~w \c
                           (a robot individual with kitchen:urdfRobot "~w"): give \c
                           robot(_{tool_link: ..., tool_offset: ..., finger_joints: ..., \c
                           max_force: ...})', [UrdfName, UrdfName]),
        throw(error(existence_error(urdf_robot_facts, UrdfName), context(robot_world/2, Msg)))
    ),
    maplist([S, A]>>atom_string(A, S), Robot.joint_names, Joints),
    Props = Facts.put(_{model: "urdf", file: Robot.file, joint_names: Joints,
                        joint_positions: Robot.joint_positions, pose: Robot.pose}).

del_keys([], D, D).
del_keys([K|Ks], D0, D) :-
    (   del_dict(K, D0, _, D1) -> true ; D1 = D0 ),
    del_keys(Ks, D1, D).

fill(Scenario, Robot, Placed, Framed, Snapshot) :-
    add_to_scenario(Scenario, [Robot|Placed]),
    forall(member(Name-Frame, Framed),
           ( get_dict(Frame, Snapshot.frames, Pose0),
             frame_pose(Pose0, Pose),
             scenario_set_property(Scenario, Name, pose, Pose) )),
    scenario_set_snapshot(Scenario, Snapshot.snapshot).

frame_pose(Pose0, _{xyz: Pose0.xyz, rpy: Pose0.rpy}).

%!  bag_scenario(+Bag, -Scenario) is det.
%
%   Scenario is a new scenario of the world the projection logged in Bag was
%   made in (its `/projection/info`), snapshot included: a projection made
%   from the live world, made again later without the robot.  The bag's
%   program and parameters are in its timeline's meta
%   (timeline_property/2).
%
%   ```
%   ?- bag_scenario("/home/me/.cache/projection_server/bags/3f2a...", S),
%      make_projection(S, plan([...]), [], TL).
%   ```
%
%   @error existence_error(file, Bag) if there is no such bag.
%   @error projection_error(bag_error, Message) for a bag that is no
%          projection's.

bag_scenario(Bag, Scenario) :-
    must_be(text, Bag),
    text_to_string(Bag, Path),
    (   exists_directory(Path) -> true ; exists_file(Path) -> true
    ;   existence_error(file, Bag)
    ),
    catch(py_call('projection_server.world':bag_scenario(Path), Description,
                  [py_string_as(string)]),
          error(python_error(_, Ex), _),
          ( py_call(str(Ex), Msg),
            throw(error(projection_error(bag_error, Msg), context(bag_scenario/2, _))) )),
    create_scenario_from(Description, Scenario).

:- multifile prolog:message//1.

prolog:message(error(Formal, context(robot_world/2, Msg))) -->
    { string(Msg), Formal \= type_error(_, _) },
    [ '~w'-[Msg] ].
