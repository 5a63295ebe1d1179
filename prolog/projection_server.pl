:- module(projection_server,
          [ projection_server_init/1    % +Options:dict
          ]).
:- use_module(query_service).
:- use_module(knowledge_base, [knowledge_base_load/0]).
:- use_module(scenario).
:- use_module(timeline).
:- use_module(projection).

/** <module> projection_server: the Prolog side of the ROS query service

Loading this file loads every module of the server and does nothing else.
projection_server_init/1 does the work that needs configuration: it loads the
knowledge base and makes the query language visible to queries, which run in
module `user`:

  - scenarios (scenario.pl): create_scenario/1, add_to_scenario/2, ...
  - projection (projection.pl): make_projection/4,5, simulate/5, translate/2
  - timelines (timeline.pl, temporal.pl): holds/2,3, occurs/2,3, Allen's relations
*/

%!  projection_server_init(+Options:dict) is det.
%
%   Initialise the server's Prolog side. Called once by the node after
%   loading, with the node's parameters.

projection_server_init(_Options) :-
    knowledge_base_load,
    forall(( api_module(M), module_property(M, file(File)) ),
           user:use_module(File)).

api_module(scenario).
api_module(timeline).
api_module(projection).

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
sandbox:safe_primitive(projection:simulate(_, _, _, _, _)).
sandbox:safe_primitive(projection:translate(_, _)).
sandbox:safe_primitive(projection:projection_program(_, _)).
sandbox:safe_primitive(projection:projection_physics_setting(_, _, _)).
sandbox:safe_primitive(timeline:timeline_create(_, _)).
sandbox:safe_primitive(timeline:timeline_remove(_)).
