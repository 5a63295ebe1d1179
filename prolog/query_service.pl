:- module(query_service,
          [ query_check/3,              % +Text, +Options, -Result
            query_solution/3,           % +Text, +Options, -Result
            error_report/2              % +Error, -Report
          ]).
% Loaded eagerly, not autoloaded: an abort that lands while a library is being
% autoloaded leaves it half loaded for every later query.
:- use_module(library(error), [must_be/2]).
:- use_module(library(sandbox), [safe_goal/1]).
:- use_module(library(time), [alarm/4, install_alarm/2, uninstall_alarm/1, remove_alarm/1]).
:- use_module(library(modules), [in_temporary_module/3]).
:- use_module(json_bindings, [bindings_json/2, term_json/3, json_text/2]).
:- use_module(projection, [with_query_context/2]).

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

Each query runs in its own temporary module, created for it and deleted when
the query is closed. What a query asserts, the operators and flags it sets
for its module, stay there: one client's query cannot change what another
client's query means. Module-qualified asserts (e.g. of hooks in `user`) are
refused by the sandbox. In the query's module sleep/1 sleeps in short slices,
so that a time limit or a cancellation stops it within a tenth of a second.
*/

%!  query_check(+Text:text, +Options:dict, -Result:dict) is det.
%
%   Parse Text and check that it may be run, without running it. Result
%   is `_{status: "ok"}` or an error result as for query_solution/3.

query_check(Text, Options, Result) :-
    catch(in_temporary_module(M, query_module(M),
                              ( prepare(M, Text, Options, _, _), Result = _{status: "ok"} )),
          E, error_report(E, Result)).

%!  query_solution(+Text:text, +Options:dict, -Result:dict) is nondet.
%
%   Result is a solution of the goal in Text, or the error that ended it.
%   Options:
%     - timeout: seconds each solution may take (0 or less: no limit)
%     - sandbox: `true` refuses goals that library(sandbox) cannot prove
%       safe; `false` (or janus' `@false`) runs any goal
%     - stack_limit: bytes of Prolog stacks this engine may use
%     - max_answer: most cells (roughly 8 bytes each) an answer may have
%     - query: `_{id: Id, owner: Owner}`, the query as the service knows it:
%       the projections the goal makes are owned by Owner and report their
%       progress to Id (projection:with_query_context/2)
%
%   The query runs in a temporary module that is deleted when the query is
%   closed.

query_solution(Text, Options, Result) :-
    engine_limits(Options),
    in_temporary_module(M, query_module(M), query_solution(M, Text, Options, Result)).

query_solution(M, Text, Options, Result) :-
    catch(solve(M, Text, Options, Json), E, true),
    (   var(E)
    ->  Result = _{status: "solution", bindings: Json}
    ;   error_report(E, Result)
    ).

engine_limits(Options) :-
    (   get_dict(stack_limit, Options, Limit), integer(Limit), Limit > 0
    ->  set_prolog_flag(stack_limit, Limit)         % per thread
    ;   true
    ).

% The query's module: inherits from user, has its own sleep/1 and parsers.
query_module(M) :-
    forall(bounded(Head, Body), bounded_in(M, Head, Body)).

bounded_in(M, Head, Body) :-
    functor(Head, Name, Arity),
    redefine_system_predicate(M:Head),
    assertz(M:(Head :- Body)),
    compile_predicates([M:Name/Arity]).

bounded(sleep(S), query_service:bounded_sleep(S)).
bounded(term_to_atom(T, A), query_service:bounded_term_to_atom(T, A)).
bounded(term_string(T, S), query_service:bounded_term_string(T, S)).
bounded(term_string(T, S, O), query_service:bounded_term_string(T, S, O)).
bounded(atom_to_term(A, T, B), query_service:bounded_atom_to_term(A, T, B)).
bounded(read_term_from_atom(A, T, O), query_service:bounded_read_term_from_atom(A, T, O)).
bounded(open_string(S, In), query_service:bounded_open_string(S, In)).

% Text a query builds and parses: Prolog's parser recurses on the C stack
% once per level of nesting, so the text it may parse is bounded in length.
max_parse_length(1000000).

parsable(Text) :-
    (   var(Text)
    ->  true
    ;   catch(atom_length(Text, Length), _, fail),
        max_parse_length(Max),
        Length > Max
    ->  throw(error(resource_error(parse_length), context(_, max_parse_length(Max))))
    ;   true
    ).

bounded_term_to_atom(T, A) :- parsable(A), system:term_to_atom(T, A).
bounded_term_string(T, S) :- parsable(S), system:term_string(T, S).
bounded_term_string(T, S, O) :- parsable(S), system:term_string(T, S, O).
bounded_atom_to_term(A, T, B) :- parsable(A), system:atom_to_term(A, T, B).
bounded_read_term_from_atom(A, T, O) :- parsable(A), system:read_term_from_atom(A, T, O).
bounded_open_string(S, In) :- parsable(S), system:open_string(S, In).

solve(M, Text, Options, Json) :-
    prepare(M, Text, Options, Goal, Bindings),
    Run = ( M:Goal, encode(Bindings, Options, Json) ),
    (   get_dict(query, Options, Query)
    ->  Solve = with_query_context(Query, Run)
    ;   Solve = Run
    ),
    (   get_dict(timeout, Options, Limit), number(Limit), Limit > 0
    ->  limited_call(Solve, Limit)
    ;   call(Solve)
    ).

encode(Bindings, Options, Json) :-
    (   get_dict(max_answer, Options, Max), integer(Max), Max > 0,
        \+ '$term_size'(Bindings, Max, _)
    ->  throw(error(resource_error(answer_size), context(_, max_answer(Max))))
    ;   bindings_json(Bindings, Json)
    ).

prepare(M, Text0, Options, Goal, Bindings) :-
    must_be(text, Text0),
    text_to_string(Text0, Text),
    term_string(Goal0, Text, [ variable_names(Bindings),
                               syntax_errors(error),
                               module(M)
                             ]),
    (   Goal0 == end_of_file
    ->  throw(error(syntax_error(empty_query), string(Text, 0)))
    ;   true
    ),
    no_trailing_text(Text),
    must_be(callable, Goal0),
    % As the toplevel does: dicts' functional notation (P.low) becomes calls.
    % The sandbox checks what is called, the expanded goal.
    @(expand_goal(Goal0, Goal), M),
    (   sandboxed(Options)
    ->  safe_goal(M:Goal),
        (   sub_term(Q, Goal), nonvar(Q), Q = _:S, callable(S),
            functor(S, Name, Arity), functor(H, Name, Arity), bounded(H, _)
        ->  throw(error(permission_error(call, qualified_builtin, Q), sandbox(Q, [])))
        ;   true
        )
    ;   true
    ).

% janus passes Python False as @false.
sandboxed(Options) :-
    \+ ( get_dict(sandbox, Options, Off), ( Off == false ; Off == @(false) ) ).

% One goal per query: text after the first clause's full stop (other than
% layout and comments) is an error, not silently dropped.
no_trailing_text(Text) :-
    setup_call_cleanup(open_string(Text, In),
                       trailing(In, Rest),
                       close(In)),
    (   Rest == none
    ->  true
    ;   throw(error(syntax_error(trailing_text), string(Text, Rest)))
    ).

trailing(In, Rest) :-
    (   catch(read_term(In, _, [syntax_errors(quiet)]), _, fail)
    ->  character_count(In, Pos),
        (   catch(read_term(In, T, [syntax_errors(quiet)]), _, fail), T == end_of_file
        ->  Rest = none
        ;   Rest = Pos
        )
    ;   Rest = none                     % no full stop: term_string/3 read it all
    ).

%!  bounded_sleep(+Seconds) is det.
%
%   sleep/1 of the query modules: sleeps in slices of at most 0.1 s, so
%   that signals (time limits, cancellation) are handled between slices.
%   The embedded Prolog runs without signal handlers, which would let a
%   signal interrupt system:sleep/1.

bounded_sleep(Seconds) :-
    must_be(number, Seconds),
    get_time(Now),
    End is Now + Seconds,
    sleep_until(End).

sleep_until(End) :-
    get_time(Now),
    Left is End - Now,
    (   Left =< 0
    ->  true
    ;   Slice is min(Left, 0.1),
        system:sleep(Slice),
        sleep_until(End)
    ).

:- multifile sandbox:safe_primitive/1.

sandbox:safe_primitive(query_service:bounded_sleep(_)).
sandbox:safe_primitive(query_service:bounded_term_to_atom(_, _)).
sandbox:safe_primitive(query_service:bounded_term_string(_, _)).
sandbox:safe_primitive(query_service:bounded_term_string(_, _, _)).
sandbox:safe_primitive(query_service:bounded_atom_to_term(_, _, _)).
sandbox:safe_primitive(query_service:bounded_read_term_from_atom(_, _, _)).
sandbox:safe_primitive(query_service:bounded_open_string(_, _)).

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
    (   '$term_size'(E, 10000, _)
    ->  error_message(E, Message),
        (   catch(term_json(E, [], JsonTerm), _, fail),
            catch(json_text(JsonTerm, Json), _, fail)
        ->  true
        ;   Json = ""
        )
    ;   % A culprit too large to report: its outline only.
        format(string(Outline), '~W', [E, [max_depth(8), quoted(true), portray(false)]]),
        format(string(Message), 'Error term too large to report in full: ~s', [Outline]),
        Json = ""
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
prolog:message(error(syntax_error(trailing_text), string(_, Pos))) -->
    [ 'Syntax error: text after the end of the query at character ~w '-[Pos],
      '(one goal per query; join goals with a comma)' ].
prolog:message(error(resource_error(answer_size), context(_, max_answer(Max)))) -->
    [ 'Resource error: the answer has more than ~D cells (max_answer)'-[Max] ].
prolog:message(error(resource_error(parse_length), context(_, max_parse_length(Max)))) -->
    [ 'Resource error: a query may parse text of at most ~D characters'-[Max] ].
prolog:message(error(permission_error(call, qualified_builtin, _:G), _)) -->
    { functor(G, Name, Arity) },
    [ 'No permission to call ~w/~w module-qualified: call it unqualified'-[Name, Arity] ].
