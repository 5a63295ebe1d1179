:- module(knowledge_base,
          [ knowledge_base_load/0,
            knowledge_base_load/1,      % +File
            knowledge_base_add/1,       % +File
            kb_entity/1,                % ?Name
            kb_entity_class/2,          % +Name, -Class
            kb_entity_properties/2,     % +Name, -Properties:dict
            kb_entity_pose/2,           % +Name, -Pose:dict
            kb_entity_parts/2,          % +Name, -Parts:list
            kb_entity_description/2,    % +Name, -Entity:dict
            kb_urdf_robot/2,            % ?RobotName, ?Name
            kb_entity_frame/2,          % +Name, -Frame
            kb_scenario/2,              % ?Name, -Members:list
            kb_class/1,                 % ?Class
            kb_simulator_class/2,       % +Class, -SimulatorClass
            kb_class_defaults/2,        % +Class, -Properties:dict
            kb_class_pose/2,            % +Class, -Pose:dict
            kb_property_unit/2,         % ?Key, ?Unit
            kb_property_kind/2,         % +Key, -Kind
            kb_check_property/4,        % +Class, +Key, +Value0, -Value
            kb_class_properties/2,      % +Class, -Keys:list(atom)
            kb_check_pose/2,            % +Pose0, -Pose:dict
            kb_belief/1                 % ?Term
          ]).
:- use_module(library(semweb/rdf11)).
:- use_module(library(semweb/turtle), []).     % the Turtle parser for rdf_load/2
:- autoload(library(apply), [foldl/4, maplist/3, include/3, exclude/3]).
:- autoload(library(error),
            [ must_be/2, domain_error/2, existence_error/2, type_error/2 ]).
:- autoload(library(lists), [member/2, reverse/2, list_to_set/2]).
:- autoload(library(pairs), [pairs_values/2]).
:- autoload(library(uri), [uri_file_name/2]).

/** <module> The kitchen knowledge base (OWL in Turtle, read with semweb)

The knowledge base of the paper's Fig. 2: the environment, the robot and the
task objects with the physical properties the simulator needs, their poses,
and the named scenarios of section IV.  All of it lives in the ontology
`kb/kitchen.ttl` beside this file (its header comment explains the modelling
conventions); nothing here is a Prolog fact about the kitchen.

Entities and classes are named by plain atoms: an entity by the local name of
its individual (`egg1`), a class by the snake_case form of its OWL class
(`pancake_maker` for `kitchen:PancakeMaker`).  Every quantity is SI.

The ontology is loaded by knowledge_base_load/0, or on first use by any
query predicate of this module.  knowledge_base_add/1 adds a Turtle file of
one's own (classes, individuals, scenarios in the same vocabulary); the node
adds those of its parameter `kb_files` at start.

```
?- knowledge_base_load.
?- kb_entity_properties(egg1, P).
P = _{breaking_force:10.0, diameter:0.044, friction:0.22, length:0.058,
      mass:0.06, restitution:0.05, rolling_friction:0.001, shape:"ellipsoid",
      spinning_friction:0.001}.
?- kb_scenario(grasping, M).
M = [kitchen_env, pr2_robot, egg1].
```
*/

:- rdf_register_prefix(kitchen, 'http://projection-server.org/ontology/kitchen#').

kb_graph(kitchen).

%!  knowledge_base_load is det.
%
%   Load (or, if it changed on disk, reload) the ontology `kb/kitchen.ttl`
%   found beside this module's source file.
%
%   @error existence_error(file, File) if the ontology is missing.
%   @error syntax_error(_) if it is not valid Turtle.

knowledge_base_load :-
    module_property(knowledge_base, file(Source)),
    file_directory_name(Source, Dir),
    directory_file_path(Dir, 'kb/kitchen.ttl', File),
    knowledge_base_load(File).

%!  knowledge_base_load(+File) is det.
%
%   Load the ontology in the Turtle file File into the graph `kitchen`,
%   replacing what the graph held.  Loading the same unchanged file again
%   does nothing; a changed file is reloaded.
%
%   @error existence_error(file, File) if File does not exist.
%   @error syntax_error(_) if File is not valid Turtle; the graph is then
%          left empty.

knowledge_base_load(File0) :-
    existing_file(File0, File),
    kb_graph(G),
    with_mutex(knowledge_base, load_graph(G, File)).

%!  knowledge_base_add(+File) is det.
%
%   Add the Turtle file File to the knowledge base, beside the ontology
%   `kb/kitchen.ttl` (loaded first if it is not): its classes, individuals
%   and scenarios are the knowledge base's from then on.  Each file is a
%   graph of its own (its URL), so adding it again reloads it if it
%   changed and does nothing otherwise.
%
%   @error existence_error(file, File) if File does not exist.
%   @error syntax_error(_) if File is not valid Turtle; nothing of it is
%          then added.

knowledge_base_add(File0) :-
    existing_file(File0, File),
    ensure_loaded_kb,
    uri_file_name(URL, File),
    load_options(URL, Options),
    with_mutex(knowledge_base,
               catch(rdf_load(File, Options),
                     E,
                     ( rdf_unload_graph(URL), throw(E) ))).

% existing_file(+File0, -File): File0's absolute path, a file that exists.
existing_file(File0, File) :-
    must_be(atom, File0),
    absolute_file_name(File0, File),
    (   exists_file(File)
    ->  true
    ;   existence_error(file, File0)
    ).

% Whether the ontology is loaded is kept in a flag, not in a dynamic
% predicate: the first query may come from inside a transaction/1 (see
% scenario.pl), whose rollback must not forget a load that rdf_db keeps.
load_graph(G, File) :-
    uri_file_name(URL, File),
    (   rdf_graph_property(G, source(Old)), Old \== URL
    ->  rdf_unload_graph(G)
    ;   true
    ),
    flag(knowledge_base_loaded, _, false),
    load_options(G, Options),
    catch(rdf_load(File, Options),
          E,
          ( rdf_unload_graph(G), throw(E) )),
    flag(knowledge_base_loaded, _, true).

% on_error(error) goes through rdf_load/2 to the Turtle parser, which
% otherwise prints syntax errors and loads the rest.  (It is not among
% rdf_load/2's declared options, so it is kept out of the call for check/0.)
load_options(G, [graph(G), format(turtle), silent(true), on_error(error)]).

% Query predicates load the ontology on first use.
ensure_loaded_kb :-
    (   kb_loaded
    ->  true
    ;   with_mutex(knowledge_base,
                   (   kb_loaded
                   ->  true
                   ;   knowledge_base_load
                   ))
    ).

kb_loaded :-
    flag(knowledge_base_loaded, Loaded, Loaded),
    Loaded == true.


                 /*******************************
                 *           ENTITIES           *
                 *******************************/

%!  kb_entity(?Name) is nondet.
%
%   Name is an individual of the knowledge base that can be added to a
%   scenario (an instance of a subclass of `kitchen:Entity`; class
%   prototypes are not).  Enumerates in alphabetical order.

kb_entity(Name) :-
    ensure_loaded_kb,
    (   atom(Name)
    ->  entity_iri(Name, _)
    ;   var(Name)
    ->  findall(N, entity_iri(N, _), Names0),
        sort(Names0, Names),
        member(Name, Names)
    ;   fail
    ).

% entity_iri(?Name, ?IRI): IRI is the kitchen individual Name, an entity.
entity_iri(Name, IRI) :-
    (   atom(Name)
    ->  rdf_global_id(kitchen:Name, IRI),
        once(( rdf(IRI, rdf:type, C), entity_class_iri(C) ))
    ;   rdf(IRI, rdf:type, C),
        entity_class_iri(C),
        rdf_global_id(kitchen:Name, IRI)
    ),
    \+ rdf(IRI, rdf:type, kitchen:'Prototype').

entity_class_iri(C) :-
    rdf_reachable(C, rdfs:subClassOf, kitchen:'Entity').

known_entity(Name, IRI) :-
    must_be(atom, Name),
    ensure_loaded_kb,
    (   entity_iri(Name, IRI)
    ->  true
    ;   existence_error(entity, Name)
    ).

%!  kb_entity_class(+Name, -Class) is det.
%
%   Class is the most specific class of the entity Name, e.g.
%   `pancake_mix` for `pancake_mix1`.  kb_simulator_class/2 maps it to
%   the class the simulator knows.
%
%   @error existence_error(entity, Name) if Name is not a KB entity.

kb_entity_class(Name, Class) :-
    known_entity(Name, IRI),
    findall(C, ( rdf(IRI, rdf:type, C), entity_class_iri(C) ), Cs),
    member(C, Cs),
    \+ ( member(C2, Cs), C2 \== C, rdf_reachable(C2, rdfs:subClassOf, C) ),
    !,
    class_iri_name(C, Class).

%!  kb_entity_properties(+Name, -Properties:dict) is det.
%
%   Properties is the dict of the physical properties the ontology
%   states for Name (no class defaults), keyed by property local name,
%   SI values: numbers for quantities, strings for shape/model/urdf,
%   entity names (atoms) for references such as a robot's `gripper`.
%
%   @error existence_error(entity, Name) if Name is not a KB entity.

kb_entity_properties(Name, Properties) :-
    known_entity(Name, IRI),
    own_properties(IRI, Properties).

own_properties(IRI, Properties) :-
    findall(Key-Value, own_property(IRI, Key, Value), Pairs),
    dict_pairs(Properties, _, Pairs).

own_property(IRI, Key, Value) :-
    rdf(IRI, P, O),
    property_kind(P, Kind),
    rdf_global_id(kitchen:Key, P),
    literal_value(Kind, Key, O, Value).

% property_kind(+P, -Kind): P is a key of the property dict.
property_kind(P, data(Range)) :-
    \+ rdf_equal(P, kitchen:physicalProperty),
    rdf_reachable(P, rdfs:subPropertyOf, kitchen:physicalProperty),
    !,
    (   rdf(P, rdfs:range, Range) -> true ; Range = xsd:string ).
property_kind(P, reference) :-
    \+ rdf_equal(P, kitchen:entityReference),
    rdf_reachable(P, rdfs:subPropertyOf, kitchen:entityReference),
    !.

literal_value(reference, _Key, IRI, Name) :-
    !,
    (   atom(IRI), rdf_global_id(kitchen:Name, IRI)
    ->  true
    ;   type_error(entity_reference, IRI)
    ).
literal_value(data(_), Key, Text^^Type, Value) :-
    rdf_equal(Type, kitchen:'Distribution'),
    !,
    (   catch(term_string(Term, Text), _, fail), belief_term(Term)
    ->  check_value(quantity, Key, Term, Value)
    ;   domain_error(belief, Text)
    ).
literal_value(data(Range), Key, Literal, Value) :-
    (   Literal = V0^^_ -> true
    ;   Literal = V0@_ -> true
    ;   V0 = Literal
    ),
    range_kind(Range, Kind),
    lexical_value(Kind, V0, V),
    check_value(Kind, Key, V, Value).

% lexical_value(+Kind, +Lexical, -Value): a list-valued literal's text is
% its elements separated by white space (see kb/kitchen.ttl's header).
lexical_value(Kind, Text, List) :-
    list_kind(Kind),
    !,
    (   string(Text)
    ->  split_string(Text, " \t\n\r", " \t\n\r", Parts0),
        exclude(==(""), Parts0, Parts),
        (   Kind == names
        ->  List = Parts
        ;   maplist(lexical_number(Text), Parts, List)
        )
    ;   type_error(Kind, Text)
    ).
lexical_value(_, Value, Value).

lexical_number(Text, Part, Number) :-
    (   catch(number_string(Number, Part), _, fail)
    ->  true
    ;   type_error(list_of_numbers, Text)
    ).

list_kind(vector).
list_kind(numbers).
list_kind(names).

%!  kb_entity_pose(+Name, -Pose:dict) is det.
%
%   Pose is `_{xyz: [X,Y,Z], rpy: [Roll,Pitch,Yaw]}` (m, rad, world
%   frame) of the centre of Name's shape.  Missing components are 0.0.
%
%   @error existence_error(entity, Name) if Name is not a KB entity.

kb_entity_pose(Name, Pose) :-
    known_entity(Name, IRI),
    own_pose(IRI, Partial),
    complete_pose(Partial, Pose).

own_pose(IRI, Partial) :-
    findall(K-V,
            ( pose_component(K),
              rdf_global_id(kitchen:K, P),
              rdf(IRI, P, V0^^_),
              V is float(V0)
            ),
            Pairs),
    dict_pairs(Partial, _, Pairs).

pose_component(x).
pose_component(y).
pose_component(z).
pose_component(roll).
pose_component(pitch).
pose_component(yaw).

complete_pose(Partial, _{xyz: [X,Y,Z], rpy: [R,P,W]}) :-
    maplist(component(Partial), [x,y,z,roll,pitch,yaw], [X,Y,Z,R,P,W]).

component(Partial, K, V) :-
    (   get_dict(K, Partial, V) -> true ; V = 0.0 ).

%!  kb_entity_parts(+Name, -Parts:list(atom)) is det.
%
%   Parts are the entities that come with Name when it is added to a
%   scenario, sorted by name: its parts (`kitchen:hasPart`, e.g. the
%   table and floor of `kitchen_env`) and its contents
%   (`kitchen:contains`, e.g. the pancake mix in `cup1`).  `[]` if none.
%
%   @error existence_error(entity, Name) if Name is not a KB entity.

kb_entity_parts(Name, Parts) :-
    known_entity(Name, IRI),
    findall(Part,
            ( ( rdf(IRI, kitchen:hasPart, P) ; rdf(IRI, kitchen:contains, P) ),
              entity_iri(Part, P)
            ),
            Parts0),
    sort(Parts0, Parts).

%!  kb_entity_description(+Name, -Entity:dict) is det.
%
%   Entity describes Name for the simulator as in docs/contracts.md:
%   `_{name: Name, class: SimulatorClass, pose: Pose, properties: Dict,
%   parts: [Entity, ...]}`.
%
%   @error existence_error(entity, Name) if Name is not a KB entity.

kb_entity_description(Name, _{name: Name, class: SimClass, pose: Pose,
                              properties: Properties, parts: PartEntities}) :-
    kb_entity_class(Name, Class),
    kb_simulator_class(Class, SimClass),
    kb_entity_pose(Name, Pose),
    kb_entity_properties(Name, Properties),
    kb_entity_parts(Name, Parts),
    maplist(kb_entity_description, Parts, PartEntities).

%!  kb_urdf_robot(?RobotName:atom, ?Name:atom) is nondet.
%
%   The robot entity Name of the knowledge base gives the facts (tool link,
%   fingers, force limit) of a URDF whose `<robot name>` is RobotName: the
%   annotation `kitchen:urdfRobot` of the individual.  robot_world/2 takes
%   them for a robot description received over ROS.
%
%   ```
%   ?- kb_urdf_robot(panda, R).
%   R = panda_robot.
%   ```

kb_urdf_robot(RobotName, Name) :-
    ensure_loaded_kb,
    (   atom(RobotName) -> atom_string(RobotName, S) ; true ),
    rdf(IRI, kitchen:urdfRobot, S^^xsd:string),
    entity_iri(Name, IRI),
    atom_string(RobotName, S).

%!  kb_entity_frame(+Name:atom, -Frame:atom) is semidet.
%
%   The entity Name is where TF frame Frame is (its individual's annotation
%   `kitchen:tfFrame`): robot_world/2 places it at that frame's pose.

kb_entity_frame(Name, Frame) :-
    ensure_loaded_kb,
    entity_iri(Name, IRI),
    rdf(IRI, kitchen:tfFrame, S^^xsd:string),
    !,
    atom_string(Frame, S).


                 /*******************************
                 *          SCENARIOS           *
                 *******************************/

%!  kb_scenario(?Name, -Members:list(atom)) is nondet.
%
%   Name is a scenario the ontology defines (grasping, pouring, turning)
%   and Members are its entities: the environment first, then robots,
%   then the others by name.  Fails if Name is not such a scenario.

kb_scenario(Name, Members) :-
    ensure_loaded_kb,
    (   atom(Name)
    ->  rdf_global_id(kitchen:Name, IRI),
        rdf(IRI, rdf:type, kitchen:'Scenario')
    ;   var(Name)
    ->  findall(N-I, ( rdf(I, rdf:type, kitchen:'Scenario'),
                       rdf_global_id(kitchen:N, I) ), Pairs0),
        sort(Pairs0, Pairs),
        member(Name-IRI, Pairs)
    ),
    findall(Rank-M,
            ( rdf(IRI, kitchen:hasMember, MI),
              entity_iri(M, MI),
              member_rank(M, Rank)
            ),
            Ranked0),
    sort(Ranked0, Ranked),
    pairs_values(Ranked, Members).

member_rank(M, Rank-M) :-
    kb_entity_class(M, Class),
    kb_simulator_class(Class, Sim),
    (   Sim == environment -> Rank = 0
    ;   Sim == robot -> Rank = 1
    ;   Rank = 2
    ).


                 /*******************************
                 *           CLASSES            *
                 *******************************/

%!  kb_class(?Class) is nondet.
%
%   Class names a subclass of `kitchen:Entity` (including it).  Enumerates
%   in alphabetical order.

kb_class(Class) :-
    ensure_loaded_kb,
    (   atom(Class)
    ->  class_iri(Class, _)
    ;   var(Class)
    ->  findall(N, ( rdf(C, rdf:type, owl:'Class'),
                     entity_class_iri(C),
                     class_iri_name(C, N) ), Ns0),
        sort(Ns0, Ns),
        member(Class, Ns)
    ;   fail
    ).

class_iri(Class, IRI) :-
    atomic_list_concat(Parts, '_', Class),
    maplist(capitalise, Parts, Caps),
    atomic_list_concat(Caps, Local),
    rdf_global_id(kitchen:Local, IRI),
    rdf(IRI, rdf:type, owl:'Class'),
    entity_class_iri(IRI),
    class_iri_name(IRI, Class).            % round trip: reject 'Egg', 'egg__x'

capitalise(Part, Cap) :-
    Part \== '',
    sub_atom(Part, 0, 1, _, First),
    sub_atom(Part, 1, _, 0, Rest),
    upcase_atom(First, Up),
    atom_concat(Up, Rest, Cap).

class_iri_name(IRI, Name) :-
    rdf_global_id(kitchen:Local, IRI),
    atom_codes(Local, Codes),
    snake_codes(Codes, true, Snake),
    atom_codes(Name, Snake).

snake_codes([], _, []).
snake_codes([C|T], First, Out) :-
    (   code_type(C, upper(L))
    ->  (   First == true -> Out = [L|Rest] ; Out = [0'_, L|Rest] )
    ;   Out = [C|Rest]
    ),
    snake_codes(T, false, Rest).

known_class(Class, IRI) :-
    must_be(atom, Class),
    ensure_loaded_kb,
    (   class_iri(Class, IRI)
    ->  true
    ;   existence_error(class, Class)
    ).

%!  kb_simulator_class(+Class, -SimulatorClass) is det.
%
%   SimulatorClass is the class under which the simulator's world builder
%   knows entities of Class (the `class` of an entity description): the
%   `kitchen:simulatorClass` of Class or of its nearest superclass that
%   has one.  E.g. `pancake_mix` -> `particle_fluid`.
%
%   @error existence_error(class, Class) if Class is not a KB class.
%   @error domain_error(simulated_class, Class) if Class is abstract
%          (no simulator class, e.g. `physical_object`).

kb_simulator_class(Class, SimClass) :-
    known_class(Class, IRI),
    (   ancestors(IRI, Ancestors),
        member(A, Ancestors),
        rdf(A, kitchen:simulatorClass, Lit),
        !,
        literal_atom(Lit, SimClass)
    ->  true
    ;   domain_error(simulated_class, Class)
    ).

literal_atom(V^^_, A) :- !, atom_string(A, V).
literal_atom(V@_, A) :- !, atom_string(A, V).
literal_atom(V, A) :- atom_string(A, V).

% ancestors(+ClassIRI, -Classes): ClassIRI and its superclasses, nearest first.
ancestors(IRI, Ancestors) :-
    findall(D-A, ( rdf_reachable(IRI, rdfs:subClassOf, A, 100, D) ), Pairs0),
    sort(Pairs0, Pairs),
    pairs_values(Pairs, Ancestors0),
    list_to_set(Ancestors0, Ancestors).

%!  kb_class_defaults(+Class, -Properties:dict) is det.
%
%   Properties are the default physical properties of entities of
%   Class: the values of the prototypes (`kitchen:prototype`) of Class
%   and its superclasses, a nearer class overriding a farther one, of the
%   properties that apply to Class (kb_class_properties/2).
%
%   @error existence_error(class, Class) if Class is not a KB class.

kb_class_defaults(Class, Properties) :-
    known_class(Class, IRI),
    prototypes_far_first(IRI, Protos),
    foldl(add_prototype_properties, Protos, _{}, Properties0),
    kb_class_properties(Class, Keys),
    dict_pairs(Properties0, Tag, Pairs0),
    include(applicable_pair(Keys), Pairs0, Pairs),
    dict_pairs(Properties, Tag, Pairs).

add_prototype_properties(Proto, D0, D) :-
    own_properties(Proto, P),
    D = D0.put(P).

% A superclass's prototype may give values that do not apply to a subclass
% (a physical object's friction, not a robot's).
applicable_pair(Keys, Key-_) :-
    memberchk(Key, Keys).

prototypes_far_first(IRI, Protos) :-
    ancestors(IRI, Near),
    reverse(Near, Far),
    findall(P, ( member(C, Far), rdf(C, kitchen:prototype, P) ), Protos).

%!  kb_class_pose(+Class, -Pose:dict) is det.
%
%   Pose is the default pose of entities of Class from its prototypes
%   (e.g. an egg lies on the table); components no prototype gives are
%   0.0.
%
%   @error existence_error(class, Class) if Class is not a KB class.

kb_class_pose(Class, Pose) :-
    known_class(Class, IRI),
    prototypes_far_first(IRI, Protos),
    foldl(add_prototype_pose, Protos, _{}, Partial),
    complete_pose(Partial, Pose).

add_prototype_pose(Proto, D0, D) :-
    own_pose(Proto, P),
    D = D0.put(P).


                 /*******************************
                 *     PROPERTIES AND UNITS     *
                 *******************************/

%!  kb_property_unit(?Key, ?Unit) is nondet.
%
%   The values of property Key are in Unit, the local name of a QUDT
%   unit (`'M'`, `'KiloGM'`, `'N'`, `'UNITLESS'`, `'NUM'`, ...).  Holds
%   for the quantity properties and the pose components.

kb_property_unit(Key, Unit) :-
    ensure_loaded_kb,
    (   atom(Key)
    ->  property_unit(Key, Unit0),
        !,
        Unit = Unit0
    ;   findall(K-U, property_unit(K, U), Pairs0),
        sort(Pairs0, Pairs),
        member(Key-Unit, Pairs)
    ).

property_unit(Key, Unit) :-
    (   atom(Key) -> rdf_global_id(kitchen:Key, P) ; true ),
    rdf(P, kitchen:unit, UI),
    rdf_global_id(kitchen:Key, P),
    atom_concat('http://qudt.org/vocab/unit/', Unit, UI).

%!  kb_check_property(+Class, +Key, +Value0, -Value) is det.
%
%   Value is Value0 checked and normalised as a value of the physical
%   property Key for an entity of Class, by its kind (kb_property_kind/2):
%   floats for quantities (non-negative), non-negative integers for
%   counts, strings for text and model files (an atom is accepted), a
%   list of three floats for a vector and a list of floats for a list of
%   numbers (of any sign), a non-empty list of strings for a list of names,
%   an atom for references.  A model file is not resolved here (see
%   model_files.pl).
%
%   @error existence_error(class, Class) if Class is not a KB class.
%   @error domain_error(entity_property, Key) if Key is no physical
%          property, or one that does not apply to Class.
%   @error type_error(Type, Value0) if Value0 has the wrong type.
%   @error domain_error(not_less_than_zero, Value0) for a negative
%          quantity (the context's message names Key).
%   @error domain_error(not_below_absolute_zero(Key), Value0) for a
%          temperature below -273.15 degrees Celsius.
%   @error domain_error(list_of_length(3), Value0) for a vector of
%          another length; domain_error(non_empty_list, []) for an empty
%          list of names.

kb_check_property(Class, Key, Value0, Value) :-
    known_class(Class, ClassIRI),
    must_be(atom, Key),
    (   rdf_global_id(kitchen:Key, P),
        property_kind(P, Kind)
    ->  true
    ;   throw(error(domain_error(entity_property, Key), _))
    ),
    (   applies_to(P, ClassIRI)
    ->  true
    ;   kb_class_properties(Class, Keys),
        atomic_list_concat(Keys, ', ', Accepted),
        format(atom(Msg), 'not a property of class ~w (its properties: ~w)',
               [Class, Accepted]),
        throw(error(domain_error(entity_property, Key), context(_, Msg)))
    ),
    (   Kind = data(Range)
    ->  range_kind(Range, ValueKind),
        check_value(ValueKind, Key, Value0, Value)
    ;   must_be(atom, Value0),
        Value = Value0
    ).

%!  kb_class_properties(+Class, -Keys:list(atom)) is det.
%
%   Keys are the properties entities of Class may have, sorted: those
%   that apply to it (kitchen:appliesTo one of its classes, or no
%   appliesTo at all).  They are the properties the simulator builds
%   an entity of Class from.
%
%   @error existence_error(class, Class) if Class is not a KB class.

kb_class_properties(Class, Keys) :-
    known_class(Class, ClassIRI),
    findall(Key, ( rdf(P, rdf:type, _),
                   property_kind(P, _),
                   applies_to(P, ClassIRI),
                   rdf_global_id(kitchen:Key, P) ), Keys0),
    sort(Keys0, Keys).

% applies_to(+P, +ClassIRI): P has no kitchen:appliesTo, or one of its
% kitchen:appliesTo classes is ClassIRI or a superclass of it.
applies_to(P, ClassIRI) :-
    (   rdf(P, kitchen:appliesTo, _)
    ->  once(( rdf(P, kitchen:appliesTo, D),
               rdf_reachable(ClassIRI, rdfs:subClassOf, D) ))
    ;   true
    ).

%!  kb_property_kind(+Key, -Kind) is semidet.
%
%   Kind is what the values of the physical property Key are: `quantity`
%   (a non-negative float, rdfs:range xsd:double), `temperature` (a float
%   in degrees Celsius not below absolute zero, -273.15, kitchen:Temperature),
%   `count` (a non-negative
%   integer, xsd:nonNegativeInteger), `text` (xsd:string), `vector` (three
%   floats, kitchen:Vector), `numbers` (floats, kitchen:NumberList),
%   `names` (strings, kitchen:NameList), `file` (a model file's path,
%   kitchen:ModelFile) or `reference` (an entity's name).  Fails if Key is
%   no physical property.

kb_property_kind(Key, Kind) :-
    must_be(atom, Key),
    ensure_loaded_kb,
    rdf_global_id(kitchen:Key, P),
    property_kind(P, Kind0),
    !,
    (   Kind0 = data(Range)
    ->  range_kind(Range, Kind)
    ;   Kind = Kind0
    ).

% range_kind(+RangeIRI, -Kind)
range_kind(Range, Kind) :-
    range_kind_(Local, Kind0),
    rdf_global_id(Local, Range),
    !,
    Kind = Kind0.
range_kind(_, text).

range_kind_(xsd:double, quantity).
range_kind_(kitchen:'Temperature', temperature).
range_kind_(xsd:nonNegativeInteger, count).
range_kind_(kitchen:'Vector', vector).
range_kind_(kitchen:'NumberList', numbers).
range_kind_(kitchen:'NameList', names).
range_kind_(kitchen:'ModelFile', file).

% check_value(+Kind, +Key, +Value0, -Value)
check_value(quantity, _Key, V0, V) :-
    belief_term(V0),
    !,
    belief(V0, V).
check_value(quantity, Key, V0, V) :-
    !,
    must_be(number, V0),
    (   V0 >= 0
    ->  V is float(V0)
    ;   format(atom(Msg), '~w must not be negative', [Key]),
        throw(error(domain_error(not_less_than_zero, V0), context(_, Msg)))
    ).
check_value(temperature, Key, V0, V) :-
    !,
    must_be(number, V0),
    (   V0 >= -273.15
    ->  V is float(V0)
    ;   format(atom(Msg), '~w is a temperature in degrees Celsius', [Key]),
        throw(error(domain_error(not_below_absolute_zero(Key), V0), context(_, Msg)))
    ).
check_value(count, _Key, V0, V) :-
    !,
    must_be(integer, V0),
    (   V0 >= 0 -> V = V0 ; domain_error(not_less_than_zero, V0) ).
check_value(vector, _Key, V0, V) :-
    !,
    must_be(list(number), V0),
    (   V0 = [_,_,_] -> true ; domain_error(list_of_length(3), V0) ),
    maplist(to_float, V0, V).
check_value(numbers, _Key, V0, V) :-
    !,
    must_be(list(number), V0),
    maplist(to_float, V0, V).
check_value(names, _Key, V0, V) :-
    !,
    must_be(list(text), V0),
    (   V0 == [] -> domain_error(non_empty_list, V0) ; true ),
    maplist(name_string, V0, V).
check_value(_Kind, _Key, V0, V) :-        % text, file
    (   ( atom(V0) ; string(V0) )
    ->  atom_string(V0, V)
    ;   type_error(text, V0)
    ).

%!  kb_belief(?Term) is semidet.
%
%   Term is a distribution a quantity property may have instead of a
%   number: `uniform(Low, High)`, `normal(Mean, SD)` or `choice(Values)`.

kb_belief(Term) :-
    belief_term(Term).

belief_term(Term) :-
    compound(Term),
    compound_name_arity(Term, Name, Arity),
    memberchk(Name/Arity, [uniform/2, normal/2, choice/1]).

% belief(+Term, -Dict): a distribution as the simulator takes it (its range
% and the property's are checked there: projection_server/beliefs.py).
belief(uniform(L, H), belief{distribution: uniform, low: Low, high: High}) :-
    must_be(number, L), must_be(number, H),
    Low is float(L), High is float(H).
belief(normal(M, SD), belief{distribution: normal, mean: Mean, sd: S}) :-
    must_be(number, M), must_be(number, SD),
    Mean is float(M), S is float(SD).
belief(choice(Vs), belief{distribution: choice, values: Values}) :-
    must_be(list(number), Vs),
    (   Vs == [] -> domain_error(non_empty_list, Vs) ; true ),
    maplist(to_float, Vs, Values).

name_string(Name, String) :-
    text_to_string(Name, String),
    (   String == "" -> domain_error(name, Name) ; true ).

%!  kb_check_pose(+Pose0, -Pose:dict) is det.
%
%   Pose is Pose0, a dict with the optional keys `xyz` and `rpy` (lists
%   of three numbers, m and rad), made complete (a missing key is
%   `[0.0,0.0,0.0]`) with float components.
%
%   @error type_error(dict, Pose0) if Pose0 is not a dict.
%   @error domain_error(pose_key, Key) for another key.
%   @error type_error(list, L), type_error(number, X) or
%          domain_error(list_of_length(3), L) for a bad vector.

kb_check_pose(Pose0, _{xyz: XYZ, rpy: RPY}) :-
    (   is_dict(Pose0) -> true ; type_error(dict, Pose0) ),
    dict_pairs(Pose0, _, Pairs),
    forall(member(K-_, Pairs),
           (   memberchk(K, [xyz, rpy]) -> true ; domain_error(pose_key, K) )),
    pose_vector(Pose0, xyz, XYZ),
    pose_vector(Pose0, rpy, RPY).

pose_vector(Pose, Key, V) :-
    (   get_dict(Key, Pose, V0)
    ->  must_be(list(number), V0),
        (   V0 = [_,_,_] -> true ; domain_error(list_of_length(3), V0) ),
        maplist(to_float, V0, V)
    ;   V = [0.0, 0.0, 0.0]
    ).

to_float(X0, X) :- X is float(X0).

:- multifile prolog:message//1.

prolog:message(error(domain_error(not_below_absolute_zero(Key), Value), _)) -->
    [ '~w = ~w: a temperature (degrees Celsius) cannot be below absolute zero, -273.15'-
      [Key, Value] ].

prolog:message(error(domain_error(entity_property, Key), context(_, Msg))) -->
    { atom(Msg) }, !,
    [ 'Unknown entity property ~q: ~w'-[Key, Msg] ].
prolog:message(error(domain_error(entity_property, Key), _)) -->
    [ 'Unknown entity property ~q (see the physical properties in kb/kitchen.ttl)'-[Key] ].
prolog:message(error(domain_error(simulated_class, Class), _)) -->
    [ 'Class ~q is abstract: the simulator has no model for it'-[Class] ].
