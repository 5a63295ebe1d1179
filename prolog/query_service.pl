:- module(query_service,
          [ query_check/3,              % +Text, +Options, -Result
            query_solution/3,           % +Text, +Options, -Result
            error_report/2              % +Error, -Report
          ]).
:- autoload(library(error), [must_be/2]).
:- autoload(library(sandbox), [safe_goal/1]).
:- autoload(library(time), [alarm/4, install_alarm/2, uninstall_alarm/1, remove_alarm/1]).
:- use_module(json_bindings, [bindings_json/2, term_json/3, json_text/2]).

/** <module> Running query text for the ROS query service

The query service receives goals as text. This module parses them, refuses
goals that are not safe to run (library(sandbox)), runs them with a time limit
per solution, and turns solutions and errors into plain data (dicts of strings
and numbers) for the Python side:

```
?- query_solution("member(X, [a, 1])", _{timeout: 5, sandbox: true}, R).
R = _{status: "solution", bindings: "{\"X\":\"a\"}"} ;
R = _{status: "solution", bindings: "{\"X\":1}"}.
```

An error ends the query: its last result is `_{status: "error", kind: K,
message: M, error: J}` where K is the error kind (syntax_error,
existence_error, ..., timeout) and J the error term in the binding encoding.
*/

%!  query_check(+Text:text, +Options:dict, -Result:dict) is det.
%
%   Parse Text and check that it may be run, without running it. Result
%   is `_{status: "ok"}` or an error result as for query_solution/3.

query_check(Text, Options, Result) :-
    catch(( prepare(Text, Options, _, _), Result = _{status: "ok"} ),
          E, error_report(E, Result)).

%!  query_solution(+Text:text, +Options:dict, -Result:dict) is nondet.
%
%   Result is a solution of the goal in Text, or the error that ended it.
%   Options:
%     - timeout: seconds each solution may take (0 or less: no limit)
%     - sandbox: `true` refuses goals that library(sandbox) cannot prove safe

query_solution(Text, Options, Result) :-
    catch(solve(Text, Options, Json), E, true),
    (   var(E)
    ->  Result = _{status: "solution", bindings: Json}
    ;   error_report(E, Result)
    ).

solve(Text, Options, Json) :-
    prepare(Text, Options, Goal, Bindings),
    (   get_dict(timeout, Options, Limit), number(Limit), Limit > 0
    ->  limited_call(user:Goal, Limit)
    ;   call(user:Goal)
    ),
    bindings_json(Bindings, Json).

prepare(Text0, Options, Goal, Bindings) :-
    must_be(text, Text0),
    text_to_string(Text0, Text),
    term_string(Goal, Text, [ variable_names(Bindings),
                              syntax_errors(error),
                              module(user)
                            ]),
    (   Goal == end_of_file
    ->  throw(error(syntax_error(empty_query), string(Text, 0)))
    ;   true
    ),
    must_be(callable, Goal),
    (   get_dict(sandbox, Options, false)
    ->  true
    ;   safe_goal(user:Goal)
    ).

%!  limited_call(:Goal, +Seconds) is nondet.
%
%   Call Goal like call/1, but throw `time_limit_exceeded(Seconds)` if
%   finding any single solution takes longer than Seconds.  Unlike
%   call_with_time_limit/2 this keeps Goal's choice points: the alarm is
%   armed while Goal runs and disarmed while the caller holds a solution.

limited_call(Goal, Seconds) :-
    alarm(Seconds, throw(time_limit_exceeded(Seconds)), Id, [install(false)]),
    setup_call_cleanup(true,
                       limited_call_(Goal, Id, Seconds),
                       remove_alarm(Id)).

limited_call_(Goal, Id, Seconds) :-
    install_alarm(Id, Seconds),
    call(Goal),
    (   uninstall_alarm(Id)
    ;   install_alarm(Id, Seconds),     % re-arm before backtracking into Goal
        fail
    ).

%!  error_report(+Error, -Report:dict) is det.
%
%   Report is `_{status: "error", kind: Kind, message: Message, error: Json}`
%   describing Error, a caught exception.

error_report(E, _{status: "error", kind: Kind, message: Message, error: Json}) :-
    error_kind(E, Kind),
    error_message(E, Message),
    (   catch(term_json(E, [], JsonTerm), _, fail), catch(json_text(JsonTerm, Json), _, fail)
    ->  true
    ;   Json = ""
    ).

error_kind(time_limit_exceeded(_), "timeout") :- !.
error_kind(time_limit_exceeded, "timeout") :- !.
error_kind(error(Formal, Context), Kind) :-
    nonvar(Formal), nonvar(Context), Context = sandbox(_, _),
    \+ Formal = existence_error(_, _), !,
    Kind = "permission_error".
error_kind(error(Formal, _), Kind) :-
    callable(Formal), !,
    functor(Formal, Name, _),
    (   known_kind(Name) -> atom_string(Name, Kind) ; Kind = "system_error" ).
error_kind('$aborted', "aborted") :- !.
error_kind(unwind(_), "aborted") :- !.
error_kind(_, "exception").

known_kind(syntax_error).
known_kind(existence_error).
known_kind(type_error).
known_kind(domain_error).
known_kind(instantiation_error).
known_kind(uninstantiation_error).
known_kind(permission_error).
known_kind(representation_error).
known_kind(evaluation_error).
known_kind(resource_error).
known_kind(projection_error).
known_kind(timeout_error).

error_message(E, Message) :-
    (   catch(message_to_codes(E, Codes), _, fail)
    ->  string_codes(Message0, Codes),
        normalize_space(string(Message), Message0)
    ;   format(string(Message), '~q', [E])
    ).

message_to_codes(E, Codes) :-
    '$messages':translate_message(E, Lines, []),
    with_output_to(codes(Codes), print_message_lines(current_output, '', Lines)).

:- multifile prolog:message//1.

prolog:message(time_limit_exceeded(Seconds)) -->
    [ 'Time limit exceeded: no solution within ~w seconds'-[Seconds] ].
prolog:message(error(syntax_error(empty_query), _)) -->
    [ 'Syntax error: the query is empty' ].
