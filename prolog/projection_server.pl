:- module(projection_server,
          [ projection_server_init/1    % +Options:dict
          ]).
:- use_module(query_service).
:- use_module(knowledge_base, [knowledge_base_load/0, knowledge_base_add/1]).
:- use_module(model_files, [set_model_directories/1]).
:- use_module(scenario).
:- use_module(timeline).
:- use_module(projection).
:- use_module(uncertainty).
:- use_module(robust).
:- use_module(search).
:- use_module(robot_world).
:- autoload(library(error), [must_be/2]).
:- autoload(library(lists), [member/2]).

/** <module> projection_server: the Prolog side of the ROS query service

Loading this file loads every module of the server and does nothing else.
projection_server_init/1 does the work that needs configuration: it loads the
knowledge base and makes the query language visible to queries, which run in
module `user`:

  - scenarios (scenario.pl): create_scenario/1, add_to_scenario/2, ...
  - projection (projection.pl): make_projection/4,5, simulate/5, translate/2
  - timelines (timeline.pl, temporal.pl): holds/2,3, occurs/2,3, Allen's relations
  - uncertainty (uncertainty.pl): outcome_probability/7
  - robust (robust.pl): robust_parametrization/7
  - search (search.pl): outcome_boundary/7, best_parametrization/8
  - the robot's world (robot_world.pl): robot_world/2, bag_scenario/2
*/

%!  projection_server_init(+Options:dict) is det.
%
%   Initialise the server's Prolog side. Called once by the node after
%   loading, with the node's parameters.  Options used (both lists of
%   file names, default `[]`):
%
%     - asset_paths: directories where model files resolve, after the
%       package's own and before `pybullet_data`'s (model_files.pl);
%     - kb_files: Turtle files added to the knowledge base
%       (knowledge_base_add/1).
%
%   @error existence_error(directory, Dir) for an asset path that is no
%          directory; existence_error(file, File) or syntax_error(_) for a
%          KB file that is missing or not valid Turtle.

projection_server_init(Options) :-
    init_option(Options, asset_paths, AssetPaths),
    init_option(Options, kb_files, KbFiles),
    set_model_directories(AssetPaths),
    knowledge_base_load,
    forall(member(KbFile, KbFiles), ( atom_string(A, KbFile), knowledge_base_add(A) )),
    forall(( api_module(M), module_property(M, file(File)) ),
           user:use_module(File)).

init_option(Options, Key, Value) :-
    (   is_dict(Options), get_dict(Key, Options, Value0)
    ->  must_be(list(text), Value0),
        Value = Value0
    ;   Value = []
    ).

api_module(scenario).
api_module(timeline).
api_module(projection).
api_module(uncertainty).
api_module(robust).
api_module(search).
api_module(robot_world).

% The query language is safe to call from sandboxed queries: it only changes
% the server's own scenario and timeline stores and runs simulations.
:- multifile sandbox:safe_primitive/1.

sandbox:safe_primitive(scenario:create_scenario(_)).
sandbox:safe_primitive(scenario:add_to_scenario(_, _)).
sandbox:safe_primitive(scenario:scenario_description(_, _)).
sandbox:safe_primitive(scenario:scenario_entities(_, _)).
sandbox:safe_primitive(scenario:scenario_entity(_, _, _)).
sandbox:safe_primitive(scenario:scenario_set_property(_, _, _, _)).
sandbox:safe_primitive(scenario:remove_from_scenario(_, _)).
sandbox:safe_primitive(scenario:copy_scenario(_, _)).
sandbox:safe_primitive(scenario:delete_scenario(_)).
sandbox:safe_primitive(scenario:current_scenario(_)).
sandbox:safe_primitive(projection:make_projection(_, _, _, _)).
sandbox:safe_primitive(projection:make_projection(_, _, _, _, _)).
sandbox:safe_primitive(uncertainty:wilson_interval(_, _, _, _)).
sandbox:safe_primitive(projection:simulate(_, _, _, _, _)).
sandbox:safe_primitive(projection:translate(_, _)).
sandbox:safe_primitive(projection:projection_program(_, _)).
sandbox:safe_primitive(projection:projection_physics_setting(_, _, _)).
sandbox:safe_primitive(projection:projection_physics_setting(_, _, _, _)).
sandbox:safe_primitive(timeline:timeline_create(_, _)).
sandbox:safe_primitive(timeline:timeline_remove(_)).
sandbox:safe_primitive(scenario:scenario_snapshot(_, _)).
% Reads what the node's subscriptions received; writes a scenario and a robot description
% (a model file under its content hash), nothing else.
sandbox:safe_primitive(robot_world:robot_world(_, _)).
sandbox:safe_primitive(robot_world:bag_scenario(_, _)).

% A probability's condition and the searches' Condition/Constraint are the query's own
% goals: safe when they are (library(sandbox) checks the meta arguments).
sandbox:safe_meta_predicate(uncertainty:outcome_probability/7).
sandbox:safe_meta_predicate(robust:robust_parametrization/7).
sandbox:safe_meta_predicate(search:outcome_boundary/7).
sandbox:safe_meta_predicate(search:best_parametrization/8).
