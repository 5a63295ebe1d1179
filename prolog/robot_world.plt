:- begin_tests(robot_world).
:- use_module(robot_world).
:- use_module(scenario).
:- use_module(knowledge_base, [kb_urdf_robot/2, kb_entity_frame/2]).

% Outside the node no subscriptions feed a robot world: a named error, not a wait.
test(no_world_outside_the_node, error(existence_error(robot_world, ros_graph), _)) :-
    robot_world(_, [wait(0)]).

test(an_unknown_option, error(domain_error(robot_world_option, colour(red)), _)) :-
    robot_world(_, [colour(red)]).

test(a_negative_wait, error(domain_error(robot_world_option, wait(-1)), _)) :-
    robot_world(_, [wait(-1)]).

test(a_bound_scenario, error(uninstantiation_error(s), _)) :-
    robot_world(s, []).

test(a_bag_that_is_not_there, error(existence_error(file, "/no/such/bag"), _)) :-
    bag_scenario("/no/such/bag", _).

% A scenario made again from its description has its entities and snapshot.
test(a_description_makes_the_scenario_again) :-
    create_scenario(S),
    add_to_scenario(S, [kitchen_env, egg1]),
    scenario_set_snapshot(S, _{stamp: 1, world_frame: "map"}),
    scenario_description(S, D),
    create_scenario_from(D, S2),
    scenario_description(S2, D2),
    D2.entities =@= D.entities,
    scenario_snapshot(S2, Snap),
    Snap.world_frame == "map",
    copy_scenario(S2, S3),
    scenario_snapshot(S3, _),
    delete_scenario(S2),
    \+ scenario_snapshot(S2, _),
    maplist(delete_scenario, [S, S3]).

test(a_description_without_entities, error(type_error(scenario_description, _), _)) :-
    create_scenario_from(_{name: x}, _).

% The Panda's facts ship, keyed by its URDF's robot name.
test(the_pandas_facts_are_keyed_by_its_urdf_name, R == panda_robot) :-
    kb_urdf_robot(panda, R).

test(no_facts_of_an_unknown_urdf_robot, fail) :-
    kb_urdf_robot(no_such_robot, _).

test(no_entity_of_the_kitchen_has_a_frame_of_its_own, fail) :-
    kb_entity_frame(egg1, _).

:- end_tests(robot_world).
