:- module(object_factory,
          [ object_type/1,              % ?Type
            object_model/3,             % +Type, +Options:dict, -Entity:dict
            pancake_joint_graph/4       % +Points, +Radius, -Seed, -Edges
          ]).
:- autoload(library(apply), [foldl/4, maplist/3, partition/4]).
:- autoload(library(error),
            [ must_be/2, domain_error/2, existence_error/2, type_error/2 ]).
:- autoload(library(lists), [append/3, nth0/3]).
:- use_module(knowledge_base,
              [ kb_class_defaults/2, kb_class_pose/2, kb_simulator_class/2,
                kb_check_property/4, kb_check_pose/2 ]).

/** <module> The object model factory

The paper's object model factory (Fig. 2): it generates parametrised models
for object types that have no fixed individual in the knowledge base.  A
model is an entity description as in docs/contracts.md; unspecified
properties take the defaults of the type's class in the ontology.

  - `pancake`: the generic circular deformable model (centre disc and
    `ring_count` rings of `segment_count` segments, `model: "rings"`), or,
    given `particles` (world positions `[X,Y,Z]`, e.g. the poured particles
    that ended up on the pancake maker), a model with one segment per
    particle joined as in the paper's Fig. 7 (`model: "particles"`): starting
    at the particle nearest the centroid, each seed is joined to the
    not yet joined particles within `joint_radius`, which then become seeds.
    The joined particles are laid into one flat layer (the batter sets into
    a pancake; a heap of particles would otherwise make a lumpy one).
    The resulting `joints` form a tree (what a Bullet multibody needs);
    particles it does not reach (spilled ones) are left out.
  - `pancake_mix`, `particle_fluid`: a fluid of `particle_count` spheres;
    given `positions` (world `[X,Y,Z]` of each particle, e.g. a projection's
    `particle_positions(F)`), that many placed there, optionally with their
    `temperatures` (degrees Celsius, one each) and `bonds` (`[I, J]` index
    pairs of bonded particles): the state in which one projection left a
    batter, handed on to the next (a cooked batter turned).

```
?- object_model(pancake, _{name: p1, radius: 0.06}, E).
E = _{class:pancake, name:p1, parts:[], pose:_{...},
      properties:_{model:"rings", radius:0.06, thickness:0.008, ...}}.
?- pancake_joint_graph([[0,0,0],[0.01,0,0],[0.02,0,0],[0.1,0,0]], 0.015, S, E).
S = 2, E = [[2,1],[1,0]].          % centroid x = 0.0325; [0.1,0,0] is not reached
```
*/

%!  object_type(?Type) is nondet.
%
%   Type is an object type the factory can generate.

object_type(pancake).
object_type(pancake_mix).
object_type(particle_fluid).

% type_class(?Type, ?Class): the KB class whose defaults a type takes.
type_class(pancake, pancake).
type_class(pancake_mix, pancake_mix).
type_class(particle_fluid, particle_fluid).

% factory_option(?Type, ?Key): options beyond the class's physical
% properties, `name` and `pose`.
factory_option(pancake, particles).
factory_option(pancake, particle_radius).
factory_option(Fluid, State) :-
    fluid_type(Fluid),
    memberchk(State, [positions, temperatures, bonds]).

fluid_type(pancake_mix).
fluid_type(particle_fluid).

%!  object_model(+Type, +Options:dict, -Entity:dict) is det.
%
%   Entity is a generated model of Type.  Options are:
%
%     - name: the entity's name (default: Type)
%     - pose: `_{xyz: [X,Y,Z], rpy: [R,P,Y]}` (default: the class's)
%     - any physical property of the type's class (radius, mass, ...)
%     - for `pancake` only: `particles`, a non-empty list of `[X,Y,Z]`
%       world positions, and `particle_radius` (m; default from the
%       `particle_fluid` class), used to compute the radius.
%     - for `pancake_mix` and `particle_fluid` only: `positions`, a
%       non-empty list of `[X,Y,Z]` (it sets `particle_count` and drops a
%       `container`), and with it `temperatures` (degrees Celsius, one per
%       position) and `bonds` (`[I, J]` pairs of 0-based indices).
%
%   A pancake built from particles has `model: "particles"`, its pose at
%   the centroid of the joined particles (rpy 0) with its bottom at the
%   lowest particle's bottom, `particles` as horizontal offsets from that
%   centroid (z 0; index 0 is the seed), `joints` as `[Parent, Child]`
%   index pairs (Parent < Child), no ring_count/segment_count, and, unless
%   given, `radius` = the largest
%   horizontal distance of a particle from the centroid + particle_radius.
%
%   @error existence_error(object_type, Type) for an unknown type.
%   @error type_error(dict, Options) if Options is not a dict.
%   @error domain_error(entity_property, Key) for an unknown option.
%   @error domain_error(object_option, pose) if both particles and pose
%          are given (the particles place the pancake);
%          domain_error(object_option, Key) for temperatures or bonds
%          without positions.
%   @error domain_error(bond_of(Count), Bond) for a bond that is not two
%          distinct indices of the Count positions.
%   @error type_error(_, _), domain_error(_, _) for bad option values
%          (see kb_check_property/4, kb_check_pose/2).

object_model(Type, Options, Entity) :-
    must_be(atom, Type),
    (   object_type(Type) -> true ; existence_error(object_type, Type) ),
    (   is_dict(Options) -> true ; type_error(dict, Options) ),
    type_class(Type, Class),
    kb_simulator_class(Class, SimClass),
    (   get_dict(name, Options, Name)
    ->  must_be(atom, Name)
    ;   Name = Type
    ),
    dict_pairs(Options, _, Pairs),
    partition(property_option(Type), Pairs, PropPairs, _),
    foldl(check_option(Class), PropPairs, [], Checked),
    kb_class_defaults(Class, Defaults),
    dict_pairs(Given, _, Checked),
    Properties0 = Defaults.put(Given),
    (   get_dict(pose, Options, Pose0)
    ->  kb_check_pose(Pose0, Pose1)
    ;   kb_class_pose(Class, Pose1)
    ),
    build(Type, Options, Properties0, Pose1, Properties, Pose),
    Entity = _{name: Name, class: SimClass, pose: Pose,
               properties: Properties, parts: []}.

property_option(Type, Key-_) :-
    \+ memberchk(Key, [name, pose]),
    \+ factory_option(Type, Key).

check_option(Class, Key-Value0, Acc, [Key-Value|Acc]) :-
    kb_check_property(Class, Key, Value0, Value).

% build(+Type, +Options, +Properties0, +Pose0, -Properties, -Pose)
build(pancake, Options, Props0, _ClassPose, Props, Pose) :-
    get_dict(particles, Options, Points),
    !,
    (   get_dict(pose, Options, _)
    ->  domain_error(object_option, pose)
    ;   true
    ),
    check_points(Points),
    (   get_dict(particle_radius, Options, PR0)
    ->  kb_check_property(particle_fluid, particle_radius, PR0, PR)
    ;   kb_class_defaults(particle_fluid, FluidDefaults),
        PR = FluidDefaults.particle_radius
    ),
    JointRadius = Props0.joint_radius,
    particle_pancake(Points, JointRadius, [X,Y,_], Lowest, Offsets, Joints),
    Z is Lowest - PR + Props0.thickness/2,    % its bottom at the lowest particle's
    Centroid = [X,Y,Z],
    (   get_dict(radius, Options, _)
    ->  Radius = Props0.radius
    ;   foldl(max_horizontal, Offsets, 0.0, Reach),
        Radius is Reach + PR
    ),
    del_dict(ring_count, Props0, _, Props1),
    del_dict(segment_count, Props1, _, Props2),
    Props = Props2.put(_{model: "particles", particles: Offsets,
                         joints: Joints, radius: Radius}),
    Pose = _{xyz: Centroid, rpy: [0.0, 0.0, 0.0]}.
build(pancake, Options, Props0, Pose, Props, Pose) :-
    !,
    (   get_dict(particle_radius, Options, _)
    ->  domain_error(object_option, particle_radius)
    ;   true
    ),
    Props = Props0.put(model, "rings").
build(Type, Options, Props0, Pose, Props, Pose) :-
    fluid_type(Type),
    get_dict(positions, Options, Points),
    !,
    check_points(Points),
    maplist(maplist(to_float), Points, Positions),
    length(Points, Count),
    (   get_dict(temperatures, Options, Ts0)
    ->  must_be(list(number), Ts0),
        (   length(Ts0, Count) -> true ; domain_error(list_of_length(Count), Ts0) ),
        maplist(kb_check_property(Type, temperature), Ts0, Ts),
        Props1 = Props0.put(temperatures, Ts)
    ;   Props1 = Props0
    ),
    (   get_dict(bonds, Options, Bonds)
    ->  must_be(list, Bonds),
        maplist(check_bond(Count), Bonds),
        Props2 = Props1.put(bonds, Bonds)
    ;   Props2 = Props1
    ),
    (   del_dict(container, Props2, _, Props3) -> true ; Props3 = Props2 ),
    Props = Props3.put(_{positions: Positions, particle_count: Count}).
build(Type, Options, _, _, _, _) :-
    fluid_type(Type),
    member(Key, [temperatures, bonds]),
    get_dict(Key, Options, _),
    !,
    domain_error(object_option, Key).
build(_, _, Props, Pose, Props, Pose).

check_bond(Count, Bond) :-
    must_be(list(integer), Bond),
    (   Bond = [I, J], I \== J, between(0, Count, I), I < Count,
        between(0, Count, J), J < Count
    ->  true
    ;   domain_error(bond_of(Count), Bond)
    ).

max_horizontal([X,Y,_], M0, M) :-
    M is max(M0, sqrt(X*X + Y*Y)).

check_points(Points) :-
    must_be(list, Points),
    (   Points == [] -> domain_error(non_empty_list, Points) ; true ),
    maplist(check_point, Points).

check_point(P) :-
    must_be(list(number), P),
    (   P = [_,_,_] -> true ; domain_error(list_of_length(3), P) ).

% particle_pancake(+Points, +Radius, -Centroid, -Lowest, -Offsets, -Joints)
% Offsets are the joined points in joining order, relative to their
% centroid and flattened into its horizontal plane (the batter sets into
% one layer: a heap of particles becomes a flat pancake); Lowest is the
% lowest z of a joined point; Joints are the tree's edges in those indices.
particle_pancake(Points, Radius, Centroid, Lowest, Offsets, Joints) :-
    pancake_joint_graph(Points, Radius, Seed, Edges),
    maplist(edge_child, Edges, Children),
    Order = [Seed|Children],
    maplist(point_at(Points), Order, Joined),
    centroid(Joined, Centroid),
    maplist(flat_offset(Centroid), Joined, Offsets),
    foldl(lowest, Joined, inf, Lowest),
    numbered(Order, 0, Index),
    maplist(reindex(Index), Edges, Joints).

lowest([_,_,Z], Z0, Z1) :-
    Z1 is min(Z0, Z).

edge_child([_, C], C).

point_at(Points, I, P) :-
    nth0(I, Points, P0),
    maplist(to_float, P0, P).

to_float(X0, X) :- X is float(X0).

flat_offset([CX,CY,_], [X,Y,_], [DX,DY,0.0]) :-
    DX is X-CX, DY is Y-CY.

numbered([], _, []).
numbered([H|T], N, [H-N|R]) :-
    N1 is N+1,
    numbered(T, N1, R).

reindex(Index, [P0, C0], [P, C]) :-
    memberchk(P0-P, Index),
    memberchk(C0-C, Index).

%!  pancake_joint_graph(+Points:list, +Radius:number, -Seed:integer,
%!                      -Edges:list) is det.
%
%   Build the joint structure of a pancake from particle positions
%   (paper, Fig. 7).  Points is a non-empty list of `[X,Y,Z]`; indices are
%   0-based positions in Points.  Seed is the index of the point nearest
%   the centroid of all points (the lowest index on a tie).  Starting
%   from Seed, each seed is joined to every point not yet joined within
%   Radius of it (Euclidean, inclusive), in index order, and these points
%   become seeds in turn (breadth first).  Edges are `[Seed, Point]`
%   pairs in joining order; they form a tree over the points reachable
%   from Seed.
%
%   @error type_error(_, _), domain_error(_, _) for malformed Points.
%   @error domain_error(not_less_than_zero, Radius) for a negative Radius.

pancake_joint_graph(Points, Radius, Seed, Edges) :-
    check_points(Points),
    must_be(number, Radius),
    (   Radius >= 0 -> true ; domain_error(not_less_than_zero, Radius) ),
    numbered_points(Points, 0, Indexed),
    centroid(Points, C),
    maplist(distance_key(C), Indexed, Keyed),
    keysort(Keyed, [_-(Seed-SeedPoint)|_]),   % keysort is stable: lowest index wins
    exclude_index(Seed, Indexed, Rest),
    R2 is Radius*Radius,
    grow([Seed-SeedPoint], Rest, R2, Edges).

numbered_points([], _, []).
numbered_points([P|T], I, [I-P|R]) :-
    I1 is I+1,
    numbered_points(T, I1, R).

distance_key(C, I-P, D-(I-P)) :-
    squared_distance(C, P, D).

exclude_index(_, [], []).
exclude_index(I, [J-P|T], R) :-
    (   I == J -> R = T ; R = [J-P|R1], exclude_index(I, T, R1) ).

% grow(+Queue, +Free, +R2, -Edges): breadth-first from the seeds in Queue.
grow([], _, _, []).
grow([S-SP|Queue], Free, R2, Edges) :-
    partition(within(SP, R2), Free, Near, Far),
    maplist(edge_from(S), Near, New),
    append(New, Edges1, Edges),
    append(Queue, Near, Queue1),
    grow(Queue1, Far, R2, Edges1).

edge_from(S, J-_, [S, J]).

within(SP, R2, _-P) :-
    squared_distance(SP, P, D),
    D =< R2.

squared_distance([X1,Y1,Z1], [X2,Y2,Z2], D) :-
    DX is X1-X2, DY is Y1-Y2, DZ is Z1-Z2,
    D is DX*DX + DY*DY + DZ*DZ.

centroid(Points, [CX, CY, CZ]) :-
    length(Points, N),
    foldl(add_point, Points, [0.0,0.0,0.0], [SX,SY,SZ]),
    CX is SX/N, CY is SY/N, CZ is SZ/N.

add_point([X,Y,Z], [SX0,SY0,SZ0], [SX,SY,SZ]) :-
    SX is SX0+X, SY is SY0+Y, SZ is SZ0+Z.

:- multifile prolog:message//1.

prolog:message(error(existence_error(object_type, Type), _)) -->
    { findall(T, object_type(T), Ts) },
    [ 'The object model factory cannot generate ~q (it knows ~w)'-[Type, Ts] ].
prolog:message(error(domain_error(object_option, Key), _)) -->
    [ 'Object option ~q cannot be combined with the other options given'-[Key] ].
