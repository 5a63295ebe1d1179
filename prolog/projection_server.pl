:- module(projection_server,
          [ projection_server_init/1    % +Options:dict
          ]).
:- use_module(query_service).

/** <module> projection_server: the Prolog side of the ROS query service

Loading this file loads every module of the server and does nothing else.
projection_server_init/1 does the work that needs configuration.
*/

%!  projection_server_init(+Options:dict) is det.
%
%   Initialise the server's Prolog side. Called once by the node after
%   loading, with the node's parameters.

projection_server_init(_Options).
