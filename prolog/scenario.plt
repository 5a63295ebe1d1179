:- begin_tests(scenario).
:- use_module(scenario).
:- use_module(knowledge_base, [kb_entity_properties/2, kb_class_defaults/2]).

fresh(S) :- create_scenario(S).
gone(S) :- ( current_scenario(S) -> delete_scenario(S) ; true ).

names(S, Names) :-
    scenario_description(S, D),
    maplist(get_dict(name), D.entities, Names).

prop(S, Entity, Key, Value) :-
    scenario_entity(S, Entity, E),
    get_dict(Key, E.properties, Value).

% Every entity has exactly the keys of docs/contracts.md, its parts too.
contract_entity(E) :-
    dict_keys(E, Keys),
    Keys == [class, name, parts, pose, properties],
    atom(E.name), atom(E.class),
    is_dict(E.properties),
    E.pose = _{xyz: [_,_,_], rpy: [_,_,_]},
    maplist(contract_entity, E.parts).

dict_keys(D, Keys) :- dict_pairs(D, _, Pairs), pairs_keys(Pairs, Keys).

% --- creating

test(create_gives_new_atoms) :-
    create_scenario(A), create_scenario(B),
    atom(A), atom(B), A \== B,
    scenario_entities(A, []),
    delete_scenario(A), delete_scenario(B).
test(create_bound, error(uninstantiation_error(s))) :-
    create_scenario(s).
test(oldest_created_are_forgotten_beyond_the_cap,
     [ setup(set_prolog_flag(scenario_max_created, 2)),
       cleanup(set_prolog_flag(scenario_max_created, 1000)),
       Alive == [false, true, true] ]) :-
    create_scenario(A), add_to_scenario(A, egg1),
    copy_scenario(A, B), create_scenario(C),
    maplist([S, T]>>(current_scenario(S) -> T = true ; T = false), [A, B, C], Alive),
    catch(scenario_entity(A, egg1, _), error(existence_error(scenario, A), _), Gone = true),
    Gone == true,
    scenario_entity(B, egg1, _),
    delete_scenario(B), delete_scenario(C).

% --- the KB's scenarios

test(grasping_description) :-
    scenario_description(grasping, D),
    D.name == grasping,
    maplist(get_dict(name), D.entities, [kitchen_env, pr2_robot, egg1]),
    maplist(get_dict(class), D.entities, [environment, robot, egg]),
    maplist(contract_entity, D.entities).
test(grasping_egg_as_in_contract) :-
    scenario_entity(grasping, egg1, E),
    P = E.properties,
    P.shape == "ellipsoid", P.length == 0.058, P.diameter == 0.044,
    P.mass == 0.06, P.friction == 0.22, P.restitution == 0.05,
    P.breaking_force == 10.0.
test(grasping_environment_has_table_and_floor, Parts == [floor1, table1]) :-
    scenario_entity(grasping, kitchen_env, E),
    maplist(get_dict(name), E.parts, Parts).
test(grasping_robot_has_gripper) :-
    scenario_entity(grasping, pr2_robot, R),
    R.properties.gripper == pr2_gripper,
    scenario_entity(grasping, pr2_gripper, G),
    G.class == gripper.
test(pouring_description) :-
    scenario_description(pouring, D),
    maplist(get_dict(name), D.entities, [kitchen_env, pr2_robot, cup1, pancake_maker1]),
    maplist(contract_entity, D.entities),
    scenario_entity(pouring, pancake_mix1, Mix),
    Mix.class == particle_fluid,
    Mix.properties.container == cup1,
    Mix.properties.particle_count == 300.
test(turning_description) :-
    scenario_description(turning, D),
    maplist(get_dict(name), D.entities,
            [kitchen_env, pr2_robot, pancake1, pancake_maker1, spatula1]),
    maplist(contract_entity, D.entities),
    scenario_entity(turning, pancake1, P),
    P.class == pancake,
    P.properties.model == "rings".
test(kb_scenarios_exist, all(S == [grasping, pouring, turning])) :-
    current_scenario(S),
    memberchk(S, [grasping, pouring, turning]).
test(kb_scenario_read_only, error(permission_error(modify, scenario, grasping))) :-
    add_to_scenario(grasping, cup1).
test(kb_scenario_set_read_only, error(permission_error(modify, scenario, grasping))) :-
    scenario_set_property(grasping, egg1, friction, 0.1).
test(kb_scenario_remove_read_only, error(permission_error(modify, scenario, turning))) :-
    remove_from_scenario(turning, pancake1).
test(kb_scenario_delete_read_only, error(permission_error(modify, scenario, pouring))) :-
    delete_scenario(pouring).

% --- adding: the three ways of the paper and lists

test(add_kb_names, [setup(fresh(S)), cleanup(gone(S)),
                    Names == [kitchen_env, pr2_robot, egg1]]) :-
    add_to_scenario(S, kitchen_env),
    add_to_scenario(S, pr2_robot),
    add_to_scenario(S, egg1),
    scenario_entities(S, Names).
test(add_kb_name_is_its_kb_description, [setup(fresh(S)), cleanup(gone(S))]) :-
    add_to_scenario(S, egg1),
    scenario_description(S, D),
    scenario_description(grasping, G),
    D.entities = [E],
    G.entities = [_, _, E0],
    E =@= E0.
test(add_explicit_entity, [setup(fresh(S)), cleanup(gone(S))]) :-
    add_to_scenario(S, entity(egg2, egg,
                              _{mass: 0.07, length: 0.06, diameter: 0.045,
                                friction: 0.35, restitution: 0.05, breaking_force: 30,
                                pose: _{xyz: [0, 0, 0.75], rpy: [0, 0, 0]}})),
    scenario_entity(S, egg2, E),
    E.class == egg,
    E.properties.mass == 0.07,
    E.properties.breaking_force == 30.0,
    E.properties.shape == "ellipsoid",               % a class default
    E.pose =@= _{xyz: [0.0, 0.0, 0.75], rpy: [0.0, 0.0, 0.0]},
    contract_entity(E).
test(add_explicit_defaults_from_class, [setup(fresh(S)), cleanup(gone(S))]) :-
    add_to_scenario(S, entity(egg3, egg, _{})),
    scenario_entity(S, egg3, E),
    kb_class_defaults(egg, D),
    E.properties =@= D,
    E.pose.xyz == [-0.3, 0.0, 0.742].
test(add_explicit_subclass_uses_simulator_class, [setup(fresh(S)), cleanup(gone(S)),
                                                 C == particle_fluid]) :-
    add_to_scenario(S, entity(batter, pancake_mix, _{particle_count: 20})),
    scenario_entity(S, batter, E),
    C = E.class.
test(add_factory_object, [setup(fresh(S)), cleanup(gone(S))]) :-
    add_to_scenario(S, object(pancake)),
    scenario_entity(S, pancake_1, E),
    E.class == pancake,
    E.properties.model == "rings".
test(add_factory_object_with_options, [setup(fresh(S)), cleanup(gone(S))]) :-
    add_to_scenario(S, object(pancake, _{name: small, radius: 0.05})),
    scenario_entity(S, small, E),
    E.properties.radius == 0.05.
test(add_factory_type_name, [setup(fresh(S)), cleanup(gone(S)),
                             Names == [pancake_1, pancake_2, pancake_mix_1]]) :-
    add_to_scenario(S, [pancake, object(pancake), pancake_mix]),
    scenario_entities(S, Names).
test(add_factory_pancake_from_particles, [setup(fresh(S)), cleanup(gone(S))]) :-
    Ps = [[0,0,0.75],[0.01,0,0.75],[0.02,0,0.75]],
    add_to_scenario(S, object(pancake, _{name: poured, particles: Ps})),
    scenario_entity(S, poured, E),
    E.properties.model == "particles",
    E.properties.joints == [[0,1],[0,2]].
test(add_list, [setup(fresh(S)), cleanup(gone(S)),
                Names == [kitchen_env, pr2_robot, pancake_maker1, spatula1, pancake_1]]) :-
    add_to_scenario(S, [kitchen_env, pr2_robot]),
    add_to_scenario(S, [pancake_maker1, [spatula1], object(pancake)]),
    scenario_entities(S, Names).
test(add_empty_list, [setup(fresh(S)), cleanup(gone(S)), Names == []]) :-
    add_to_scenario(S, []),
    scenario_entities(S, Names).
test(rebuild_grasping_as_in_paper, [setup(fresh(S)), cleanup(gone(S))]) :-
    add_to_scenario(S, kitchen_env),
    add_to_scenario(S, pr2_robot),
    add_to_scenario(S, egg1),
    scenario_description(S, D),
    scenario_description(grasping, G),
    D.entities =@= G.entities.

% --- adding: errors

test(add_unknown_name, [setup(fresh(S)), cleanup(gone(S)),
                        error(existence_error(entity, dragon))]) :-
    add_to_scenario(S, dragon).
test(add_to_unknown_scenario, error(existence_error(scenario, nowhere))) :-
    add_to_scenario(nowhere, egg1).
test(add_to_non_atom_scenario, error(type_error(atom, 7))) :-
    add_to_scenario(7, egg1).
test(add_unbound_entity, [setup(fresh(S)), cleanup(gone(S)), error(instantiation_error)]) :-
    add_to_scenario(S, _).
test(add_bad_term, [setup(fresh(S)), cleanup(gone(S)), error(type_error(entity, 42))]) :-
    add_to_scenario(S, 42).
test(add_twice, [setup(fresh(S)), cleanup(gone(S)),
                 error(permission_error(create, entity, egg1))]) :-
    add_to_scenario(S, egg1),
    add_to_scenario(S, egg1).
test(add_part_twice, [setup(fresh(S)), cleanup(gone(S)),
                      error(permission_error(create, entity, table1))]) :-
    add_to_scenario(S, kitchen_env),
    add_to_scenario(S, table1).
test(add_explicit_name_clash, [setup(fresh(S)), cleanup(gone(S)),
                               error(permission_error(create, entity, egg1))]) :-
    add_to_scenario(S, egg1),
    add_to_scenario(S, entity(egg1, egg, _{})).
test(add_list_is_all_or_nothing, [setup(fresh(S)), cleanup(gone(S)), Names == [egg1]]) :-
    add_to_scenario(S, egg1),
    catch(add_to_scenario(S, [kitchen_env, cup1, dragon]), error(existence_error(_,_), _), true),
    catch(add_to_scenario(S, [kitchen_env, cup1, egg1]), error(permission_error(_,_,_), _), true),
    scenario_entities(S, Names).
test(add_list_duplicate_inside, [setup(fresh(S)), cleanup(gone(S)),
                                 error(permission_error(create, entity, cup1))]) :-
    add_to_scenario(S, [cup1, cup1]).
test(add_explicit_unknown_class, [setup(fresh(S)), cleanup(gone(S)),
                                  error(existence_error(class, dragon))]) :-
    add_to_scenario(S, entity(d1, dragon, _{})).
test(add_explicit_abstract_class, [setup(fresh(S)), cleanup(gone(S)),
                                   error(domain_error(simulated_class, physical_object))]) :-
    add_to_scenario(S, entity(thing, physical_object, _{})).
test(add_explicit_unknown_property, [setup(fresh(S)), cleanup(gone(S)),
                                     error(domain_error(entity_property, colour))]) :-
    add_to_scenario(S, entity(egg2, egg, _{colour: brown})).
test(add_explicit_inapplicable_property, [setup(fresh(S)), cleanup(gone(S)),
                                          error(domain_error(entity_property, breaking_force))]) :-
    add_to_scenario(S, entity(t2, table, _{breaking_force: 100})).
test(add_explicit_wrong_type, [setup(fresh(S)), cleanup(gone(S)),
                               error(type_error(number, heavy))]) :-
    add_to_scenario(S, entity(egg2, egg, _{mass: heavy})).
test(add_explicit_negative, [setup(fresh(S)), cleanup(gone(S)),
                             error(domain_error(not_less_than_zero, -0.1))]) :-
    add_to_scenario(S, entity(egg2, egg, _{friction: -0.1})).
test(add_explicit_bad_pose, [setup(fresh(S)), cleanup(gone(S)),
                             error(domain_error(list_of_length(3), [0,0]))]) :-
    add_to_scenario(S, entity(egg2, egg, _{pose: _{xyz: [0,0]}})).
test(add_explicit_props_not_dict, [setup(fresh(S)), cleanup(gone(S)),
                                   error(type_error(dict, [mass=1]))]) :-
    add_to_scenario(S, entity(egg2, egg, [mass=1])).
test(add_explicit_name_not_atom, [setup(fresh(S)), cleanup(gone(S)),
                                  error(type_error(atom, "egg2"))]) :-
    add_to_scenario(S, entity("egg2", egg, _{})).
test(add_unknown_object_type, [setup(fresh(S)), cleanup(gone(S)),
                               error(existence_error(object_type, cake))]) :-
    add_to_scenario(S, object(cake)).
test(add_object_options_not_dict, [setup(fresh(S)), cleanup(gone(S)),
                                   error(type_error(dict, radius))]) :-
    add_to_scenario(S, object(pancake, radius)).
test(add_object_bad_option, [setup(fresh(S)), cleanup(gone(S)),
                             error(domain_error(entity_property, flavour))]) :-
    add_to_scenario(S, object(pancake, _{flavour: sweet})).

% --- changing properties for counterfactual projections

test(set_property, [setup(fresh(S)), cleanup(gone(S)), F == 0.2]) :-
    add_to_scenario(S, [kitchen_env, pr2_robot, egg1]),
    scenario_set_property(S, egg1, friction, 0.2),
    prop(S, egg1, friction, F).
test(set_property_leaves_kb_alone, [setup(fresh(S)), cleanup(gone(S)), F == 0.22]) :-
    add_to_scenario(S, egg1),
    scenario_set_property(S, egg1, friction, 0.2),
    kb_entity_properties(egg1, P),
    F = P.friction.
test(set_property_the_simulator_does_not_build,
     [setup(fresh(S)), cleanup(gone(S)),
      error(domain_error(entity_property, rolling_friction))]) :-
    add_to_scenario(S, kitchen_env),
    scenario_set_property(S, floor1, rolling_friction, 0.01).
test(set_property_error_names_entity_and_accepted_keys,
     [setup(fresh(S)), cleanup(gone(S))]) :-
    add_to_scenario(S, kitchen_env),
    catch(scenario_set_property(S, floor1, rolling_friction, 0.01),
          error(domain_error(entity_property, rolling_friction), context(_, Msg)), true),
    sub_atom(Msg, 0, _, _, 'floor1 (floor)'),
    sub_atom(Msg, _, _, 0, 'friction, mass, restitution, shape').
test(set_property_of_gripper, [setup(fresh(S)), cleanup(gone(S)), F == 3.0]) :-
    add_to_scenario(S, pr2_robot),
    scenario_set_property(S, pr2_gripper, max_force, 3),
    prop(S, pr2_gripper, max_force, F).
test(set_property_of_part, [setup(fresh(S)), cleanup(gone(S)), F == 0.9]) :-
    add_to_scenario(S, kitchen_env),
    scenario_set_property(S, table1, friction, 0.9),
    prop(S, table1, friction, F).
test(set_property_keeps_order, [setup(fresh(S)), cleanup(gone(S)),
                                Names == [kitchen_env, egg1, cup1]]) :-
    add_to_scenario(S, [kitchen_env, egg1, cup1]),
    scenario_set_property(S, egg1, mass, 0.05),
    scenario_set_property(S, table1, mass, 0),
    scenario_entities(S, Names).
test(set_pose, [setup(fresh(S)), cleanup(gone(S)), Xyz == [0.1, 0.2, 0.742]]) :-
    add_to_scenario(S, egg1),
    scenario_set_property(S, egg1, pose, _{xyz: [0.1, 0.2, 0.742]}),
    scenario_entity(S, egg1, E),
    Xyz = E.pose.xyz.
test(set_on_copy_of_kb_scenario, [cleanup(gone(C)), F == 0.1]) :-
    copy_scenario(grasping, C),
    scenario_set_property(C, egg1, friction, 0.1),
    prop(C, egg1, friction, F),
    prop(grasping, egg1, friction, 0.22).
test(set_unknown_entity, [setup(fresh(S)), cleanup(gone(S)),
                          error(existence_error(entity, egg9))]) :-
    add_to_scenario(S, egg1),
    scenario_set_property(S, egg9, friction, 0.2).
test(set_unknown_property, [setup(fresh(S)), cleanup(gone(S)),
                            error(domain_error(entity_property, colour))]) :-
    add_to_scenario(S, egg1),
    scenario_set_property(S, egg1, colour, white).
test(set_inapplicable_property, [setup(fresh(S)), cleanup(gone(S)),
                                 error(domain_error(entity_property, breaking_force))]) :-
    add_to_scenario(S, kitchen_env),
    scenario_set_property(S, table1, breaking_force, 5).
test(set_wrong_type, [setup(fresh(S)), cleanup(gone(S)), error(type_error(number, slippery))]) :-
    add_to_scenario(S, egg1),
    scenario_set_property(S, egg1, friction, slippery).
test(set_bad_pose, [setup(fresh(S)), cleanup(gone(S)), error(type_error(dict, [0,0,1]))]) :-
    add_to_scenario(S, egg1),
    scenario_set_property(S, egg1, pose, [0,0,1]).
test(set_unknown_scenario, error(existence_error(scenario, nowhere))) :-
    scenario_set_property(nowhere, egg1, friction, 0.2).
test(set_failed_changes_nothing, [setup(fresh(S)), cleanup(gone(S)), F == 0.22]) :-
    add_to_scenario(S, egg1),
    catch(scenario_set_property(S, egg1, friction, -1), _, true),
    prop(S, egg1, friction, F).

% --- removing, copying, deleting, listing

test(remove, [setup(fresh(S)), cleanup(gone(S)), Names == [egg1]]) :-
    add_to_scenario(S, [kitchen_env, egg1]),
    remove_from_scenario(S, kitchen_env),
    scenario_entities(S, Names),
    \+ scenario_entity(S, table1, _).
test(remove_then_add_again, [setup(fresh(S)), cleanup(gone(S)), Names == [egg1]]) :-
    add_to_scenario(S, egg1),
    remove_from_scenario(S, egg1),
    add_to_scenario(S, egg1),
    scenario_entities(S, Names).
test(remove_part_refused, [setup(fresh(S)), cleanup(gone(S)),
                           error(existence_error(entity, table1))]) :-
    add_to_scenario(S, kitchen_env),
    remove_from_scenario(S, table1).
test(remove_unknown, [setup(fresh(S)), cleanup(gone(S)),
                      error(existence_error(entity, egg1))]) :-
    remove_from_scenario(S, egg1).
test(copy_created, [setup(fresh(S)), cleanup((gone(S), gone(C)))]) :-
    add_to_scenario(S, [egg1, object(pancake)]),
    copy_scenario(S, C),
    C \== S,
    scenario_description(S, DS),
    scenario_description(C, DC),
    DS.entities =@= DC.entities,
    scenario_set_property(C, egg1, mass, 0.08),
    prop(S, egg1, mass, 0.06).
test(copy_unknown, error(existence_error(scenario, nowhere))) :-
    copy_scenario(nowhere, _).
test(copy_bound, error(uninstantiation_error(c))) :-
    copy_scenario(grasping, c).
test(delete) :-
    create_scenario(S),
    add_to_scenario(S, egg1),
    delete_scenario(S),
    \+ current_scenario(S),
    catch(scenario_entities(S, _), error(existence_error(scenario, S), _), true).
test(delete_unknown, error(existence_error(scenario, nowhere))) :-
    delete_scenario(nowhere).
test(describe_unknown, error(existence_error(scenario, nowhere))) :-
    scenario_description(nowhere, _).
test(entities_unknown, error(existence_error(scenario, nowhere))) :-
    scenario_entities(nowhere, _).
test(current_lists_created, [setup(fresh(S)), cleanup(gone(S))]) :-
    findall(X, current_scenario(X), Xs),
    append([grasping, pouring, turning], _, Xs),
    memberchk(S, Xs).
test(current_unknown, fail) :-
    current_scenario(nowhere).
test(current_non_atom, error(type_error(atom, 3))) :-
    current_scenario(3).
test(entity_lookup_enumerates_parts,
     all(N == [kitchen_env, floor1, table1, pr2_robot, pr2_gripper, egg1])) :-
    scenario_entity(grasping, N, _).

% --- model files: resolved when added or set (model_files.pl)

test(explicit_mesh_gets_its_absolute_path, [setup(fresh(S)), cleanup(gone(S))]) :-
    add_to_scenario(S, entity(g2, rigid_object, _{shape: mesh, file: "glass.obj",
                                                  mass: 0.2})),
    prop(S, g2, file, File),
    string(File),
    is_absolute_file_name(File),
    sub_string(File, _, _, 0, "/glass.obj"),
    prop(S, g2, friction, 0.5).                 % the class's default
test(kb_glass_gets_its_absolute_path, [setup(fresh(S)), cleanup(gone(S))]) :-
    add_to_scenario(S, glass1),
    prop(S, glass1, file, File),
    is_absolute_file_name(File),
    prop(S, glass1, breaking_force, 40.0).
test(a_file_outside_is_refused, [setup(fresh(S)), cleanup(gone(S)),
                                  error(permission_error(access, model_file, "../x.obj"))]) :-
    add_to_scenario(S, entity(g2, rigid_object, _{shape: mesh, file: "../x.obj",
                                                  mass: 0.2})).
test(a_refused_file_adds_nothing, [setup(fresh(S)), cleanup(gone(S)), Names == [egg1]]) :-
    catch(add_to_scenario(S, [egg1, entity(g2, rigid_object,
                                           _{shape: mesh, file: "none.obj", mass: 0.2})]),
          error(existence_error(model_file, "none.obj"), _), true),
    add_to_scenario(S, egg1),
    scenario_entities(S, Names).
test(set_a_file_resolves_it, [setup(fresh(S)), cleanup(gone(S))]) :-
    add_to_scenario(S, entity(g2, rigid_object, _{shape: box, size_x: 0.1, size_y: 0.1,
                                                  size_z: 0.1, mass: 0.2})),
    scenario_set_property(S, g2, file, 'glass.obj'),
    prop(S, g2, file, File),
    is_absolute_file_name(File).
test(set_a_missing_file, [setup(fresh(S)), cleanup(gone(S)),
                          error(existence_error(model_file, "none.obj"))]) :-
    add_to_scenario(S, glass1),
    scenario_set_property(S, glass1, file, "none.obj").
test(set_a_file_refused_changes_nothing, [setup(fresh(S)), cleanup(gone(S))]) :-
    add_to_scenario(S, glass1),
    prop(S, glass1, file, Before),
    catch(scenario_set_property(S, glass1, file, "/etc/passwd"),
          error(permission_error(access, model_file, _), _), true),
    prop(S, glass1, file, Before).

% --- threads

% Each thread builds and changes its own scenario; none sees another's.
test(threads_use_their_own_scenarios) :-
    findall(thread_work(r(I, _)), between(1, 8, I), Goals),
    concurrent(4, Goals, []),
    findall(R, member(thread_work(R), Goals), Results),
    forall(member(r(I, F), Results),
           F =:= I/100).

thread_work(r(I, F)) :-
    create_scenario(S),
    add_to_scenario(S, [kitchen_env, pr2_robot, egg1, object(pancake)]),
    Fr is I/100,
    scenario_set_property(S, egg1, friction, Fr),
    scenario_description(S, D),
    length(D.entities, 4),
    prop(S, egg1, friction, F),
    delete_scenario(S).

% Threads adding the same name to one scenario: exactly one wins.
test(threads_race_for_a_name, [setup(fresh(S)), cleanup(gone(S)), Names == [egg1]]) :-
    findall(try_add(S), between(1, 8, _), Goals),
    concurrent(4, Goals, []),
    scenario_entities(S, Names).

try_add(S) :-
    catch(add_to_scenario(S, egg1), error(permission_error(create, entity, egg1), _), true).

% Threads adding different entities to one scenario: all arrive, names unique.
test(threads_share_a_scenario, [setup(fresh(S)), cleanup(gone(S)), N == 16]) :-
    findall(add_to_scenario(S, object(pancake)), between(1, 16, _), Goals),
    concurrent(4, Goals, []),
    scenario_entities(S, Names),
    sort(Names, Unique),
    length(Unique, N).

test(error_message_for_read_only) :-
    catch(add_to_scenario(grasping, cup1), E, true),
    '$messages':translate_message(E, Lines, []),
    with_output_to(string(Msg), print_message_lines(current_output, '', Lines)),
    once(sub_string(Msg, _, _, _, "copy_scenario")).

:- end_tests(scenario).
