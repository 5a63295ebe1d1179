:- begin_tests(object_factory).
:- use_module(object_factory).
:- use_module(knowledge_base, [kb_class_defaults/2]).

close_to(X, Y) :- abs(X-Y) < 1.0e-9.
close_points(Ps, Qs) :- maplist(maplist(close_to), Ps, Qs).

test(types, all(T == [pancake, pancake_mix, particle_fluid])) :-
    object_type(T).

test(generic_pancake_takes_class_defaults) :-
    object_model(pancake, _{}, E),
    kb_class_defaults(pancake, D),
    E.name == pancake,
    E.class == pancake,
    E.parts == [],
    E.properties =@= D,
    E.properties.model == "rings".
test(generic_pancake_default_pose_on_the_pancake_maker, Z == 0.754) :-
    object_model(pancake, _{}, E),
    E.pose.xyz = [_, _, Z].
test(generic_pancake_options_override) :-
    object_model(pancake, _{name: p1, radius: 0.05, mass: 0.04, ring_count: 2,
                            pose: _{xyz: [0.01, 0, 0.754]}}, E),
    E.name == p1,
    E.properties.radius == 0.05,
    E.properties.mass == 0.04,
    E.properties.ring_count == 2,
    E.properties.thickness == 0.008,
    E.pose =@= _{xyz: [0.01, 0.0, 0.754], rpy: [0.0, 0.0, 0.0]}.
test(pancake_mix_is_a_particle_fluid) :-
    object_model(pancake_mix, _{name: mix2, container: cup1, particle_count: 50}, E),
    E.class == particle_fluid,
    E.properties.container == cup1,
    E.properties.particle_count == 50,
    E.properties.particle_radius == 0.0048.

test(unknown_type, error(existence_error(object_type, cake))) :-
    object_model(cake, _{}, _).
test(options_not_dict, error(type_error(dict, [radius=0.1]))) :-
    object_model(pancake, [radius=0.1], _).
test(unknown_option, error(domain_error(entity_property, colour))) :-
    object_model(pancake, _{colour: golden}, _).
test(inapplicable_option, error(domain_error(entity_property, breaking_force))) :-
    object_model(pancake, _{breaking_force: 3}, _).
test(wrong_option_type, error(type_error(number, big))) :-
    object_model(pancake, _{radius: big}, _).
test(name_not_atom, error(type_error(atom, "p"))) :-
    object_model(pancake, _{name: "p"}, _).
test(particles_only_for_pancakes, error(domain_error(entity_property, particles))) :-
    object_model(pancake_mix, _{particles: [[0,0,0]]}, _).
test(particle_radius_needs_particles, error(domain_error(object_option, particle_radius))) :-
    object_model(pancake, _{particle_radius: 0.004}, _).
test(reference_must_be_atom, error(type_error(atom, 3))) :-
    object_model(particle_fluid, _{container: 3}, _).

% The joint graph (paper, Fig. 7) on small hand-made point sets.

cross([[0,0,0], [0.01,0,0], [-0.01,0,0], [0,0.01,0], [0,-0.01,0],
       [0.02,0,0], [-0.02,0,0]]).

test(graph_cross, [Seed, Edges] == [0, [[0,1],[0,2],[0,3],[0,4],[1,5],[2,6]]]) :-
    cross(Ps),
    pancake_joint_graph(Ps, 0.012, Seed, Edges).
test(graph_leaves_out_unreachable_points,
     [Seed, Edges] == [0, [[0,1],[0,2],[0,3],[0,4],[1,5],[2,6]]]) :-
    cross(Ps0),
    append(Ps0, [[0.3,0,0], [-0.3,0,0]], Ps),      % centroid stays at the origin
    pancake_joint_graph(Ps, 0.012, Seed, Edges).
test(graph_chain_is_breadth_first, [Seed, Edges] == [2, [[2,1],[2,3],[1,0],[3,4]]]) :-
    pancake_joint_graph([[0,0,0],[0.01,0,0],[0.02,0,0],[0.03,0,0],[0.04,0,0]],
                        0.015, Seed, Edges).
test(graph_seed_tie_lowest_index, [Seed, Edges] == [0, []]) :-
    pancake_joint_graph([[0,0,0],[0.02,0,0]], 0.015, Seed, Edges).
test(graph_radius_inclusive, Edges == [[0,1]]) :-
    pancake_joint_graph([[0,0,0],[0.02,0,0]], 0.02, _, Edges).
test(graph_in_3d, Edges == [[0,1]]) :-
    pancake_joint_graph([[0,0,0],[0,0,0.01],[0,0,-0.5]], 0.012, _, Edges).
test(graph_single_point, [Seed, Edges] == [0, []]) :-
    pancake_joint_graph([[1,2,3]], 0.1, Seed, Edges).
test(graph_is_a_tree) :-
    findall([X,Y,0.75], ( between(0, 9, I), between(0, 9, J),
                          X is I*0.008 + (J mod 3)*0.001,
                          Y is J*0.008 ), Ps),
    pancake_joint_graph(Ps, 0.01, Seed, Edges),
    length(Ps, N),
    length(Edges, M),
    M =:= N-1,                                       % all reached on this grid
    findall(C, member([_,C], Edges), Cs),
    sort([Seed|Cs], All),
    length(All, N).                                  % each point joined once
test(graph_empty, error(domain_error(non_empty_list, []))) :-
    pancake_joint_graph([], 0.01, _, _).
test(graph_bad_point, error(domain_error(list_of_length(3), [1,2]))) :-
    pancake_joint_graph([[1,2]], 0.01, _, _).
test(graph_bad_coordinate, error(type_error(number, a))) :-
    pancake_joint_graph([[a,0,0]], 0.01, _, _).
test(graph_negative_radius, error(domain_error(not_less_than_zero, -1))) :-
    pancake_joint_graph([[0,0,0]], -1, _, _).

% A pancake from particles: joined ones only, in joining order, around
% their centroid.
test(pancake_from_particles) :-
    Ps = [[0,0,0.75],[0.01,0,0.75],[0.02,0,0.75],[0.03,0,0.75],[0.04,0,0.75]],
    object_model(pancake, _{name: p2, particles: Ps, joint_radius: 0.015}, E),
    E.properties.model == "particles",
    E.properties.joints == [[0,1],[0,2],[1,3],[2,4]],
    close_points(E.properties.particles,
                 [[0,0,0],[-0.01,0,0],[0.01,0,0],[-0.02,0,0],[0.02,0,0]]),
    % bottom at the particles' bottom: 0.75 - particle radius 0.005 + thickness/2
    close_points([E.pose.xyz], [[0.02,0,0.749]]),
    E.pose.rpy == [0.0, 0.0, 0.0],
    close_to(E.properties.radius, 0.025),            % 0.02 + particle radius 0.005
    \+ get_dict(ring_count, E.properties, _).
test(pancake_from_particles_is_one_flat_layer) :-
    Ps = [[0,0,0.75],[0.01,0,0.75],[0.005,0,0.76],[0.0,0.01,0.76]],
    object_model(pancake, _{particles: Ps, thickness: 0.01}, E),
    forall(member([_,_,Z], E.properties.particles), Z =:= 0),
    close_points([E.pose.xyz], [[0.00375,0.0025,0.75]]).   % 0.75 - 0.005 + 0.005
test(pancake_from_particles_drops_spilled) :-
    Ps = [[0,0,0.75],[0.01,0,0.75],[-0.01,0,0.75],[0.5,0,0.72],[-0.5,0,0.72]],
    object_model(pancake, _{particles: Ps, particle_radius: 0.004}, E),
    length(E.properties.particles, 3),
    E.properties.joints == [[0,1],[0,2]],
    close_to(E.properties.radius, 0.014),
    close_points([E.pose.xyz], [[0,0,0.75]]).      % not the spilled ones' height
test(pancake_from_particles_keeps_given_radius, R == 0.09) :-
    object_model(pancake, _{particles: [[0,0,0.75]], radius: 0.09}, E),
    R = E.properties.radius.
test(pancake_particles_and_pose_exclusive, error(domain_error(object_option, pose))) :-
    object_model(pancake, _{particles: [[0,0,0.75]], pose: _{xyz: [0,0,1]}}, _).

% A batter's state handed on from one projection to the next.
test(batter_placed_by_positions) :-
    object_model(pancake_mix, _{name: b, positions: [[0, 0, 0.755], [0.0096, 0, 0.755]],
                                temperatures: [80, 65.5], bonds: [[0, 1]]}, E),
    E.class == particle_fluid,
    E.properties.particle_count == 2,
    E.properties.positions == [[0.0, 0.0, 0.755], [0.0096, 0.0, 0.755]],
    E.properties.temperatures == [80.0, 65.5],
    E.properties.bonds == [[0, 1]],
    \+ get_dict(container, E.properties, _).
test(batter_state_needs_positions, error(domain_error(object_option, bonds))) :-
    object_model(pancake_mix, _{bonds: [[0, 1]]}, _).
test(batter_temperature_per_position, error(domain_error(list_of_length(1), [20, 20]))) :-
    object_model(pancake_mix, _{positions: [[0, 0, 0]], temperatures: [20, 20]}, _).
test(batter_below_absolute_zero,
     error(domain_error(not_below_absolute_zero(temperature), -300))) :-
    object_model(pancake_mix, _{positions: [[0, 0, 0]], temperatures: [-300]}, _).
test(batter_bond_of_its_particles, error(domain_error(bond_of(2), [0, 2]))) :-
    object_model(pancake_mix, _{positions: [[0, 0, 0], [1, 0, 0]], bonds: [[0, 2]]}, _).

:- end_tests(object_factory).
