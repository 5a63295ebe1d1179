:- begin_tests(knowledge_base_load).
:- use_module(knowledge_base).

test(load_default_ontology) :-
    knowledge_base_load,
    kb_entity(egg1).
test(load_twice_is_harmless, all(E == [egg1])) :-
    knowledge_base_load,
    knowledge_base_load,
    kb_entity(E), E == egg1.
test(load_missing_file, error(existence_error(file, '/nonexistent/kitchen.ttl'))) :-
    knowledge_base_load('/nonexistent/kitchen.ttl').
test(load_non_atom, error(type_error(atom, 42))) :-
    knowledge_base_load(42).
test(load_bad_turtle,
     [ setup(bad_turtle(File)),
       cleanup(( delete_file(File), knowledge_base_load )),
       error(syntax_error(_))
     ]) :-
    knowledge_base_load(File).
test(failed_load_falls_back_to_default_on_use,
     [ setup(bad_turtle(File)),
       cleanup(delete_file(File))
     ]) :-
    catch(knowledge_base_load(File), error(syntax_error(_), _), true),
    kb_entity(egg1).
test(load_other_file_replaces_graph,
     [ setup(tmp_file_stream(text, File, S)),
       cleanup(( delete_file(File), knowledge_base_load ))
     ]) :-
    format(S, '@prefix kitchen: <http://projection-server.org/ontology/kitchen#> .~n', []),
    format(S, 'kitchen:Entity a <http://www.w3.org/2002/07/owl#Class> .~n', []),
    format(S, 'kitchen:thing1 a kitchen:Entity .~n', []),
    close(S),
    knowledge_base_load(File),
    findall(E, kb_entity(E), Es),
    Es == [thing1].

bad_turtle(File) :-
    tmp_file_stream(text, File, S),
    format(S, '@prefix k: <http://x.org/k#> .~nk:a k:b ;; .~n', []),
    close(S).

:- end_tests(knowledge_base_load).

:- begin_tests(knowledge_base).
:- use_module(knowledge_base).

close_to(X, Y) :- abs(X-Y) < 1.0e-9.

test(entities, Es == [cup1, egg1, floor1, glass1, kitchen_env, mug1, pancake1,
                      pancake_maker1, pancake_mix1, panda_robot, pr2_gripper, pr2_robot,
                      spatula1,
                      table1, tray1]) :-
    findall(E, kb_entity(E), Es).
test(prototypes_are_not_entities, fail) :-
    kb_entity(egg_prototype).
test(unknown_entity_is_no_entity, fail) :-
    kb_entity(dragon).

test(entity_class, C == egg) :- kb_entity_class(egg1, C).
test(entity_class_most_specific, C == pancake_mix) :- kb_entity_class(pancake_mix1, C).
test(entity_class_unknown, error(existence_error(entity, dragon))) :-
    kb_entity_class(dragon, _).
test(entity_class_non_atom, error(type_error(atom, 1))) :-
    kb_entity_class(1, _).
test(entity_class_unbound, error(instantiation_error)) :-
    kb_entity_class(_, _).

test(egg_properties,
     P =@= _{shape: "ellipsoid", length: 0.058, diameter: 0.044, mass: 0.06,
            friction: 0.22, restitution: 0.05, rolling_friction: 0.001,
            spinning_friction: 0.001, breaking_force: 10.0}) :-
    kb_entity_properties(egg1, P).
test(table_properties,
     P =@= _{shape: "box", size_x: 1.2, size_y: 0.8, size_z: 0.04, height: 0.72,
            mass: 0.0, friction: 0.6, restitution: 0.1}) :-
    kb_entity_properties(table1, P).
test(robot_refers_to_its_gripper, G == pr2_gripper) :-
    kb_entity_properties(pr2_robot, P),
    G = P.gripper.
test(mix_refers_to_its_cup, C == cup1) :-
    kb_entity_properties(pancake_mix1, P),
    C = P.container.
test(counts_are_integers, N == 300) :-
    kb_entity_properties(pancake_mix1, P),
    N = P.particle_count.
test(properties_unknown, error(existence_error(entity, dragon))) :-
    kb_entity_properties(dragon, _).

% Every body has the dimensions its shape needs, a mass and a friction.
test(shapes_have_their_dimensions, Missing == []) :-
    findall(E-K,
            ( kb_entity(E),
              kb_entity_properties(E, P),
              get_dict(shape, P, Shape),
              shape_keys(Shape, Keys),
              member(K, Keys),
              \+ get_dict(K, P, _)
            ),
            Missing).

shape_keys("plane", [mass, friction]).
shape_keys("box", [size_x, size_y, size_z, mass, friction]).
shape_keys("ellipsoid", [length, diameter, mass, friction]).
shape_keys("cylinder", [radius, height, mass, friction]).
shape_keys("disc", [radius, thickness, mass, friction]).
shape_keys("cup", [radius, height, wall_thickness, mass, friction]).
shape_keys("sphere", [particle_count, particle_radius, particle_mass, friction]).
shape_keys("mesh", [file, mass, friction]).
shape_keys("urdf", [friction]).
shape_keys("none", []).

test(urdf_bodies_name_their_model, Missing == []) :-
    findall(E,
            ( kb_entity(E),
              kb_entity_properties(E, P),
              get_dict(shape, P, "urdf"),
              \+ get_dict(urdf, P, _),
              \+ get_dict(file, P, _)
            ),
            Missing).

test(egg_is_a_hens_egg) :-
    kb_entity_properties(egg1, P),
    P.length >= 0.05, P.length =< 0.065,
    P.diameter >= 0.04, P.diameter =< 0.05,
    P.mass >= 0.05, P.mass =< 0.07,
    P.friction >= 0.2, P.friction =< 0.5.

test(egg_lies_on_the_table) :-
    kb_entity_pose(egg1, _{xyz: [_, _, Z], rpy: _}),
    kb_entity_properties(egg1, E),
    kb_entity_properties(table1, T),
    close_to(Z - E.diameter/2, T.height).
test(table_pose_is_its_top_slab) :-
    kb_entity_pose(table1, _{xyz: [0.0, 0.0, Z], rpy: [0.0, 0.0, 0.0]}),
    kb_entity_properties(table1, T),
    close_to(Z + T.size_z/2, T.height).
test(pancake_maker_stands_on_the_table) :-
    kb_entity_pose(pancake_maker1, _{xyz: [_, _, Z], rpy: _}),
    kb_entity_properties(pancake_maker1, M),
    close_to(Z - M.height/2, 0.72).
test(pancake_lies_on_the_pancake_maker) :-
    kb_entity_pose(pancake1, _{xyz: [X, Y, Z], rpy: _}),
    kb_entity_pose(pancake_maker1, _{xyz: [MX, MY, MZ], rpy: _}),
    kb_entity_properties(pancake1, P),
    kb_entity_properties(pancake_maker1, M),
    close_to(Z - P.thickness/2, MZ + M.height/2),
    sqrt((X-MX)**2 + (Y-MY)**2) + P.radius =< M.radius.
test(cup_is_above_the_pancake_maker) :-
    kb_entity_pose(cup1, _{xyz: [X, Y, Z], rpy: _}),
    kb_entity_pose(pancake_maker1, _{xyz: [MX, MY, MZ], rpy: _}),
    kb_entity_properties(cup1, C),
    kb_entity_properties(pancake_maker1, M),
    sqrt((X-MX)**2 + (Y-MY)**2) < M.radius,
    Z - C.height/2 > MZ + M.height/2.
test(pose_missing_components_are_zero, P =@= _{xyz: [-0.95, 0.0, 0.0], rpy: [0.0, 0.0, 0.0]}) :-
    kb_entity_pose(pr2_robot, P).

test(environment_parts, Ps == [floor1, table1]) :- kb_entity_parts(kitchen_env, Ps).
test(robot_parts, Ps == [pr2_gripper]) :- kb_entity_parts(pr2_robot, Ps).
test(cup_contents_are_parts, Ps == [pancake_mix1]) :- kb_entity_parts(cup1, Ps).
test(simple_entity_has_no_parts, Ps == []) :- kb_entity_parts(egg1, Ps).

test(description_is_nested) :-
    kb_entity_description(kitchen_env, E),
    E.name == kitchen_env,
    E.class == environment,
    maplist(get_dict(name), E.parts, [floor1, table1]),
    maplist(get_dict(class), E.parts, [floor, table]).
test(description_uses_simulator_class, C == particle_fluid) :-
    kb_entity_description(pancake_mix1, E),
    C = E.class.

test(scenario_grasping, M == [kitchen_env, pr2_robot, egg1]) :-
    kb_scenario(grasping, M).
test(scenario_pouring, M == [kitchen_env, pr2_robot, cup1, pancake_maker1]) :-
    kb_scenario(pouring, M).
test(scenario_turning, M == [kitchen_env, pr2_robot, pancake1, pancake_maker1, spatula1]) :-
    kb_scenario(turning, M).
test(scenario_names, all(S == [grasping, pouring, turning])) :-
    kb_scenario(S, _).
test(scenario_unknown, fail) :-
    kb_scenario(cooking, _).

test(classes_include_leaves) :-
    forall(member(C, [egg, table, floor, robot, gripper, cup, pancake_mix,
                      particle_fluid, pancake_maker, spatula, pancake, environment]),
           kb_class(C)).
test(class_name_round_trip_only, fail) :-
    kb_class('PancakeMaker').
test(simulator_class_inherited, S == particle_fluid) :-
    kb_simulator_class(pancake_mix, S).
test(simulator_class_abstract, error(domain_error(simulated_class, physical_object))) :-
    kb_simulator_class(physical_object, _).
test(simulator_class_unknown, error(existence_error(class, dragon))) :-
    kb_simulator_class(dragon, _).

test(class_defaults_pancake) :-
    kb_class_defaults(pancake, D),
    D.radius == 0.07, D.thickness == 0.008, D.mass == 0.06,
    D.model == "rings", D.ring_count == 3.
test(class_defaults_inherited, S == "sphere") :-
    kb_class_defaults(pancake_mix, D),
    S = D.shape.
test(class_defaults_only_applicable, Keys == [model, shape]) :-
    kb_class_defaults(robot, D),            % no physical object's friction
    dict_pairs(D, _, Pairs), pairs_keys(Pairs, Keys).
test(class_defaults_nearer_class_wins, F == 0.22) :-
    kb_class_defaults(egg, D),
    F = D.friction.
test(class_pose_egg_on_table, P =@= _{xyz: [-0.3, 0.0, 0.742], rpy: [0.0, 0.0, 0.0]}) :-
    kb_class_pose(egg, P).
test(class_pose_default_origin, P =@= _{xyz: [0.0, 0.0, 0.0], rpy: [0.0, 0.0, 0.0]}) :-
    kb_class_pose(particle_fluid, P).
test(class_defaults_unknown, error(existence_error(class, dragon))) :-
    kb_class_defaults(dragon, _).

test(unit_mass, U == 'KiloGM') :- kb_property_unit(mass, U).
test(unit_breaking_force, U == 'N') :- kb_property_unit(breaking_force, U).
test(unit_pose, U == 'RAD') :- kb_property_unit(yaw, U).
test(every_numeric_property_has_a_unit, Missing == []) :-
    findall(K, ( kb_entity(E), kb_entity_properties(E, P),
                 get_dict(K, P, V), number(V),
                 \+ kb_property_unit(K, _) ), Ks),
    sort(Ks, Missing).

test(check_integer_to_float, V == 1.0) :- kb_check_property(egg, mass, 1, V).
test(check_atom_to_string, V == "box") :- kb_check_property(table, shape, box, V).
test(check_count, V == 10) :- kb_check_property(pancake_mix, particle_count, 10, V).
test(check_reference, V == cup2) :- kb_check_property(particle_fluid, container, cup2, V).
test(check_wrong_type, error(type_error(number, heavy))) :-
    kb_check_property(egg, mass, heavy, _).
test(check_count_float, error(type_error(integer, 2.5))) :-
    kb_check_property(pancake_mix, particle_count, 2.5, _).
test(check_negative, error(domain_error(not_less_than_zero, -1))) :-
    kb_check_property(egg, mass, -1, _).
test(check_negative_names_the_property, Msg == 'bond_strength must not be negative') :-
    catch(kb_check_property(pancake_mix, bond_strength, -1, _),
          error(domain_error(not_less_than_zero, -1), context(_, Msg)), true).
test(check_temperature_below_zero, V == -18.0) :-
    kb_check_property(pancake_maker, temperature, -18, V).
test(check_below_absolute_zero,
     error(domain_error(not_below_absolute_zero(setting_temperature), -274))) :-
    kb_check_property(pancake_mix, setting_temperature, -274, _).
test(unit_temperature, U == 'DEG_C') :- kb_property_unit(temperature, U).
test(pancake_maker1_heats, [H, T] == [1, 195.0]) :-
    kb_entity_properties(pancake_maker1, P),
    H = P.heating, T = P.temperature.
test(check_unknown_key, error(domain_error(entity_property, colour))) :-
    kb_check_property(egg, colour, red, _).
test(check_pose_is_no_property, error(domain_error(entity_property, x))) :-
    kb_check_property(egg, x, 1, _).
test(class_properties_of_egg, Keys == [breaking_force, diameter, friction, length, mass,
                                        restitution, rolling_friction, shape,
                                        spinning_friction]) :-
    kb_class_properties(egg, Keys).
test(class_properties_of_environment, Keys == [gravity]) :-
    kb_class_properties(environment, Keys).
test(check_property_of_one_of_several_classes, V == 0.01) :-
    kb_check_property(particle_fluid, rolling_friction, 0.01, V).
test(check_property_of_none_of_several_classes,
     error(domain_error(entity_property, rolling_friction))) :-
    kb_check_property(cup, rolling_friction, 0.01, _).
test(check_inapplicable_key, error(domain_error(entity_property, breaking_force))) :-
    kb_check_property(table, breaking_force, 10, _).
test(check_reference_type, error(type_error(atom, 3))) :-
    kb_check_property(particle_fluid, container, 3, _).
test(check_unknown_class, error(existence_error(class, dragon))) :-
    kb_check_property(dragon, mass, 1, _).

test(pose_complete, P =@= _{xyz: [1.0, 2.0, 3.0], rpy: [0.0, 0.0, 0.0]}) :-
    kb_check_pose(_{xyz: [1, 2, 3]}, P).
test(pose_not_dict, error(type_error(dict, [1,2,3]))) :-
    kb_check_pose([1,2,3], _).
test(pose_unknown_key, error(domain_error(pose_key, quaternion))) :-
    kb_check_pose(_{quaternion: [0,0,0,1]}, _).
test(pose_short_vector, error(domain_error(list_of_length(3), [1,2]))) :-
    kb_check_pose(_{xyz: [1,2]}, _).
test(pose_non_numbers, error(type_error(number, a))) :-
    kb_check_pose(_{rpy: [a,b,c]}, _).

% Rigid objects: any shape, their model file as text (resolved by scenario.pl).
test(class_properties_of_rigid_object,
     Keys == [breaking_force, file, friction, height, mass, radius, restitution,
              rolling_friction, scale, shape, size_x, size_y, size_z, spinning_friction]) :-
    kb_class_properties(rigid_object, Keys).
test(everyday_objects_are_rigid_objects, all(S == [rigid_object, rigid_object, rigid_object])) :-
    member(E, [glass1, mug1, tray1]),
    kb_entity_class(E, C),
    kb_simulator_class(C, S).
test(model_files_are_text_in_the_kb, F == "objects/mug.urdf") :-
    kb_entity_properties(mug1, P),
    F = P.file.
test(the_glass_is_breakable_and_stands_on_the_table) :-
    kb_entity_properties(glass1, P),
    P.breaking_force > 0, P.mass > 0,
    kb_entity_pose(glass1, _{xyz: [_, _, Z], rpy: _}),
    close_to(Z, 0.72).
test(check_file, V == "my/cup.obj") :-
    kb_check_property(rigid_object, file, 'my/cup.obj', V).
test(check_file_type, error(type_error(text, 3))) :-
    kb_check_property(rigid_object, file, 3, _).
test(property_kinds, Kinds == [quantity, count, text, file, reference]) :-
    maplist(kb_property_kind, [mass, particle_count, shape, file, container], Kinds).
test(property_kind_of_no_property, fail) :-
    kb_property_kind(colour, _).

test(error_message_is_readable) :-
    catch(kb_check_property(table, breaking_force, 10, _), E, true),
    message_to_codes(E, S),
    once(sub_string(S, _, _, _, "not a property of class table")).

message_to_codes(E, S) :-
    '$messages':translate_message(E, Lines, []),
    with_output_to(string(S), print_message_lines(current_output, '', Lines)).

:- end_tests(knowledge_base).

% Turtle files of one's own, and the list-valued kinds (typed literals).
:- begin_tests(knowledge_base_files, [ setup(add_gadgets(File)),
                                       cleanup(remove_gadgets(File)) ]).
:- use_module(knowledge_base).
:- use_module(library(semweb/rdf11), [rdf_unload_graph/1]).
:- use_module(library(uri), [uri_file_name/2]).

add_gadgets(File) :-
    tmp_file_stream(text, File, S),
    format(S, '~s', [
"@prefix kitchen: <http://projection-server.org/ontology/kitchen#> .
@prefix owl: <http://www.w3.org/2002/07/owl#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
kitchen:Gadget a owl:Class ; rdfs:subClassOf kitchen:PhysicalObject ;
    kitchen:simulatorClass \"gadget\" .
kitchen:direction a owl:DatatypeProperty ; rdfs:subPropertyOf kitchen:physicalProperty ;
    rdfs:range kitchen:Vector ; kitchen:appliesTo kitchen:Gadget .
kitchen:weights a owl:DatatypeProperty ; rdfs:subPropertyOf kitchen:physicalProperty ;
    rdfs:range kitchen:NumberList ; kitchen:appliesTo kitchen:Gadget .
kitchen:joint_names a owl:DatatypeProperty ; rdfs:subPropertyOf kitchen:physicalProperty ;
    rdfs:range kitchen:NameList ; kitchen:appliesTo kitchen:Gadget .
kitchen:gadget1 a kitchen:Gadget ;
    kitchen:direction \"0 -1 0.5\"^^kitchen:Vector ;
    kitchen:weights \" 1  -2.5 \"^^kitchen:NumberList ;
    kitchen:joint_names \"joint_a joint_b\"^^kitchen:NameList .
kitchen:gadget2 a kitchen:Gadget ; kitchen:direction \"0 up 1\"^^kitchen:Vector .
kitchen:gadget3 a kitchen:Gadget ; kitchen:mass \"uniform(0.2, 0.4)\"^^kitchen:Distribution ;
    kitchen:friction \"choice([0.5, 1])\"^^kitchen:Distribution .
kitchen:gadget4 a kitchen:Gadget ; kitchen:mass \"normal(0.2\"^^kitchen:Distribution .
"]),
    close(S),
    knowledge_base_add(File).

remove_gadgets(File) :-
    uri_file_name(URL, File),
    rdf_unload_graph(URL),
    delete_file(File).

test(added_files_add_entities, true) :-
    kb_entity(gadget1),
    kb_entity(egg1).
test(lists_in_turtle,
     P =@= _{direction: [0.0, -1.0, 0.5], weights: [1.0, -2.5],
             joint_names: ["joint_a", "joint_b"]}) :-
    kb_entity_properties(gadget1, P).
test(a_malformed_list_literal, error(type_error(list_of_numbers, "0 up 1"))) :-
    kb_entity_properties(gadget2, _).
test(list_kinds, Kinds == [vector, numbers, names]) :-
    maplist(kb_property_kind, [direction, weights, joint_names], Kinds).
test(check_vector, V == [1.0, -2.0, 0.5]) :-
    kb_check_property(gadget, direction, [1, -2, 0.5], V).
test(check_vector_length, error(domain_error(list_of_length(3), [1, 2]))) :-
    kb_check_property(gadget, direction, [1, 2], _).
test(check_vector_numbers, error(type_error(number, up))) :-
    kb_check_property(gadget, direction, [0, up, 1], _).
test(check_numbers, V == [-1.0, 0.0, 2.5, 7.0]) :-
    kb_check_property(gadget, weights, [-1, 0, 2.5, 7], V).
test(check_numbers_empty, V == []) :-
    kb_check_property(gadget, weights, [], V).
test(check_names, V == ["a", "b"]) :-
    kb_check_property(gadget, joint_names, [a, "b"], V).
test(check_names_empty, error(domain_error(non_empty_list, []))) :-
    kb_check_property(gadget, joint_names, [], _).
test(check_names_not_text, error(type_error(text, 1))) :-
    kb_check_property(gadget, joint_names, [1], _).
test(distributions_in_turtle, [M, F] =@= [belief{distribution: uniform, low: 0.2, high: 0.4},
                                           belief{distribution: choice, values: [0.5, 1.0]}]) :-
    kb_entity_properties(gadget3, P),
    M = P.mass, F = P.friction.
test(a_malformed_distribution_literal, error(domain_error(belief, "normal(0.2"))) :-
    kb_entity_properties(gadget4, _).
test(check_distribution, V == belief{distribution: normal, mean: 10.0, sd: 1.0}) :-
    kb_check_property(egg, mass, normal(10, 1), V).
test(check_distribution_numbers, error(type_error(number, a))) :-
    kb_check_property(egg, mass, uniform(a, 1), _).
test(check_distribution_choice_empty, error(domain_error(non_empty_list, []))) :-
    kb_check_property(egg, mass, choice([]), _).
test(distribution_terms, Bs == [uniform(0, 1), normal(0, 1), choice([])]) :-
    include(kb_belief, [uniform(0, 1), normal(0, 1), choice([]), beta(1, 2), 0.5], Bs).
test(add_missing_file, error(existence_error(file, '/nonexistent/my.ttl'))) :-
    knowledge_base_add('/nonexistent/my.ttl').
test(add_bad_turtle, [ setup(bad_file(Bad)), cleanup(delete_file(Bad)),
                       error(syntax_error(_)) ]) :-
    knowledge_base_add(Bad).

bad_file(File) :-
    tmp_file_stream(text, File, S),
    format(S, '@prefix k: <http://x.org/k#> .~nk:a k:b ;; .~n', []),
    close(S).

:- end_tests(knowledge_base_files).
