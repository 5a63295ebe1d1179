:- module(timeline,
          [ timeline_create/2,          % +Data:dict, -Timeline
            timeline_remove/1,          % +Timeline
            timeline_exists/1,          % ?Timeline
            timeline_property/2,        % ?Timeline, ?Property
            timeline_fluent_intervals/3, % ?Fluent, -Intervals, +Timeline
            holds/3,                    % ?Fluent, ?Time, +Timeline
            occurs/3,                   % ?Event, ?Time, +Timeline
            quantity/3,                 % ?Quantity, ?Value, +Timeline
            current_timeline/1,         % -Timeline
            with_timeline/2,            % +Timeline, :Goal
            holds/2,                    % ?Fluent, ?Time
            occurs/2,                   % ?Event, ?Time
            quantity/2,                 % ?Quantity, ?Value
            typeOf/2,                   % ?Term, ?Type
            objOf/2,                    % ?Term, ?Object
            timeline_vocabulary_create/2, % +Data:dict, -Vocabulary
            timeline_vocabulary_dict/2, % +Vocabulary, -Dict
            timeline_condition_terms/3, % @Goal, ?Timeline, -Terms:list
            timeline_check_term/3       % +Vocabulary, +Context, +Term
          ]).
:- reexport(temporal).
:- autoload(library(apply), [maplist/3]).
:- autoload(library(aggregate), [aggregate_all/3]).
:- autoload(library(error),
            [ must_be/2, type_error/2, existence_error/2 ]).
:- autoload(library(lists), [list_to_set/2, member/2]).
:- autoload(library(pairs), [pairs_values/2]).
:- autoload(library(solution_sequences), [distinct/2, limit/2]).

/** <module> Timelines: fluents and events of one projection

A _timeline_ is what one simulation-based projection produced, translated
into first-order terms (section II of Kunze, Dolha & Beetz, IROS 2011):

  - _fluents_, terms such as `contact(egg1, gripper)` or `broken(egg1)`,
    that hold over maximal intervals `interval(Start, End)`;
  - _events_, terms such as `drop(egg1)`, that happen at a point `T` (when
    they start and end at the same time) or over an `interval(Start, End)`;
  - _quantities_, terms such as `max_force(egg1)`, with a value.

Times are seconds from the start of the projection and follow
library(temporal), which this module re-exports so that queries can relate
times (before/2, after/2, Allen's relations, ...).

timeline_create/2 stores the translated log under a new timeline id and
holds/3, occurs/3 and quantity/3 query a given timeline:

```
?- timeline_create(_{fluents: [[broken, [egg1], 2.1, 5.0]],
                     events:  [[drop, [egg1], 2.0, 2.0]]}, TL),
   occurs(drop(Egg), T1, TL), holds(broken(Egg), T2, TL).
TL = timeline_1, Egg = egg1, T1 = 2.0, T2 = interval(2.1, 5.0).
```

*Patterns*: an atom Name given as the fluent, event or quantity stands for
any term named Name, whatever its arguments, as the paper writes
`\+ occurs(break, _, Timeline)` for "no break(_) event".  The atom stays
unbound to the stored term.  Other terms are unified with the stored terms.

*Vocabulary*: a timeline made by a projection knows what any timeline of
its scenario can name: the fluents, events and quantities the translation
makes (each a name and an arity) and the scenario's objects (its entities,
parts, robots and grippers included).  A fluent, event or quantity given to
holds/3, occurs/3, quantity/3 (and their query forms, typeOf/2 and objOf/2)
that no timeline of the scenario can have is an existence_error, not a
silent failure: `\+ occurs(brake, _, TL)` would otherwise be true of every
timeline.  A known term that did not happen fails as before; variables and
partly bound terms range freely.  The predicates that take a condition
(outcome_probability/7, robust_parametrization/7, outcome_boundary/7,
best_parametrization/8) check its terms the same way before they project
(timeline_condition_terms/3):

```
?- make_projection(grasping, grasp_object, [(_, force, [5])], TL),
   \+ occurs(brake, _, TL).
ERROR: occurs/3: no timeline of scenario grasping has an event brake; its
ERROR: events are break/1, collision/2, drop/1, ...
```

A timeline created from data without a `vocabulary` (timeline_create/2)
takes any term.

*Query form*: holds/2, occurs/2, quantity/2, typeOf/2 and objOf/2 evaluate
on the _current timeline_, so that the paper's query runs as written:

```
?- occurs(Evt, T1), typeOf(Evt, dropping), objOf(Evt, egg1),
   after(T2, T1), holds(F, T2), objOf(F, egg1).
```

The current timeline is the one selected with with_timeline/2 for the
duration of its goal, else the most recently created timeline that still
exists.  The selection is a backtrackable global variable (b_setval/2),
which is private to each thread and engine, so concurrent queries do not
see each other's selection; but "most recently created" is shared by all
threads, so a client that runs queries concurrently with projections
should select its timeline with with_timeline/2 or use the 3-argument
forms.

In the query above after/2 is called with T2 unbound: library(temporal)
then delays the test until T2 is bound, holds/2 binds T2 to each maximal
interval of each fluent, and the test keeps those intervals that lie
strictly after T1.  So F ranges over the fluents that began after the drop;
a fluent that began before the event and still holds after it is not an
answer.
*/

:- dynamic
    tl_registered/2,                    % Timeline, Sequence number
    tl_fluent/3,                        % Timeline, Term, interval(S, E)
    tl_event/3,                         % Timeline, Term, Time
    tl_quantity/3,                      % Timeline, Term, Value
    tl_meta/2,                          % Timeline, Dict
    tl_vocabulary/2,                    % Timeline, Vocabulary key
    vocab_registered/2,                 % Key, Sequence number
    vocab_term/5,                       % Key, Kind, Name, Arity, ArgKinds
    vocab_object/2.                     % Key, Object

                 /*******************************
                 *         THE STORE            *
                 *******************************/

%!  timeline_create(+Data:dict, -Timeline:atom) is det.
%
%   Store the translated log Data as a new timeline with the fresh id
%   Timeline (`timeline_1`, `timeline_2`, ...).  Data is the dict
%   `_{fluents: Fs, events: Es, quantities: Qs, meta: M}` of the contract
%   (docs/contracts.md); `quantities` and `meta` may be left out:
%
%     - Fs and Es are lists of `[Name, Args, Start, End]`, Qs a list of
%       `[Name, Args, Value]`.  Names and entity arguments may be atoms or
%       strings; they become atoms.  Numeric arguments stay numbers.  The
%       stored term is `Name(Args...)`, or the atom Name if Args is `[]`.
%     - Start and End are numbers with Start =< End; End may be `inf`.
%       An event whose Start and End are equal (within time_epsilon/1)
%       happens at the point Start.
%     - M is a dict, kept as the timeline property meta(M).
%     - The optional `vocabulary` is what any timeline of the projection's
%       scenario can name (timeline_vocabulary_create/2); with it, holds/3,
%       occurs/3 and quantity/3 raise an existence_error for a term outside
%       it (see the module doc).  Without it, any term is taken.
%
%   The new timeline becomes the current timeline (see the module doc).
%   Records that occur twice are stored once.
%
%   @error existence_error(key, fluents) or existence_error(key, events) if
%          Data lacks that key.
%   @error type_error(fluent_record, R), type_error(event_record, R) or
%          type_error(quantity_record, R) if a record R has the wrong shape.
%   @error type_error(atomic, A) if an argument is not an atom, string or
%          number; type_error(time, _) or domain_error(time, _) for bad
%          times (see temporal:must_be_time/1).
%   @error type_error(vocabulary, V) for a malformed vocabulary.

timeline_create(Data, TL) :-
    must_be(dict, Data),
    required_key(fluents, Data, Fs0),
    required_key(events, Data, Es0),
    optional_key(quantities, Data, [], Qs0),
    optional_key(meta, Data, _{}, Meta),
    must_be(list, Fs0),
    must_be(list, Es0),
    must_be(list, Qs0),
    must_be(dict, Meta),
    (   get_dict(vocabulary, Data, VData)
    ->  timeline_vocabulary_create(VData, Vocabulary)
    ;   Vocabulary = none
    ),
    maplist(interval_record(fluent_record), Fs0, Fs1),
    maplist(interval_record(event_record), Es0, Es1),
    maplist(quantity_record, Qs0, Qs1),
    list_to_set(Fs1, Fs),
    list_to_set(Es1, Es2),
    maplist(event_time, Es2, Es),
    list_to_set(Qs1, Qs),
    with_mutex(timeline_store, flag(timeline_seq, N0, N0+1)),
    N is N0+1,
    format(atom(TL), 'timeline_~d', [N]),
    catch(store(TL, N, Fs, Es, Qs, Meta, Vocabulary), E,
          ( remove_facts(TL), throw(E) )).

required_key(Key, Dict, Value) :-
    (   get_dict(Key, Dict, Value)
    ->  true
    ;   existence_error(key, Key)
    ).

optional_key(Key, Dict, Default, Value) :-
    (   get_dict(Key, Dict, Value0) -> Value = Value0 ; Value = Default ).

% The registration is asserted last, so other threads never see a
% timeline whose facts are still being added.
store(TL, N, Fs, Es, Qs, Meta, Vocabulary) :-
    forall(member(T-I, Fs), assertz(tl_fluent(TL, T, I))),
    forall(member(T-Time, Es), assertz(tl_event(TL, T, Time))),
    forall(member(T-V, Qs), assertz(tl_quantity(TL, T, V))),
    assertz(tl_meta(TL, Meta)),
    (   Vocabulary = vocabulary(Key)
    ->  assertz(tl_vocabulary(TL, Key))
    ;   true
    ),
    assertz(tl_registered(TL, N)).

interval_record(Type, Record, Term-interval(S, E)) :-
    (   is_list(Record), Record = [Name, Args, S, E0]
    ->  must_be(list, Args),
        record_term(Name, Args, Term),
        open_end(E0, E),
        must_be_time(interval(S, E))
    ;   type_error(Type, Record)
    ).

quantity_record(Record, Term-Value) :-
    (   is_list(Record), Record = [Name, Args, Value]
    ->  must_be(list, Args),
        record_term(Name, Args, Term),
        must_be(ground, Value)
    ;   type_error(quantity_record, Record)
    ).

record_term(Name0, Args0, Term) :-
    must_be(text, Name0),
    atom_string(Name, Name0),
    maplist(record_arg, Args0, Args),
    Term =.. [Name|Args].

record_arg(X, X) :- number(X), !.
record_arg(X, A) :- atom(X), !, A = X.
record_arg(X, A) :- string(X), !, atom_string(A, X).
record_arg(X, _) :- type_error(atomic, X).

open_end(E, inf) :- float(E), E =:= inf, !.
open_end(E, E).

event_time(T-interval(S, E), T-Time) :-
    (   E \== inf, equals(S, E) -> Time = S ; Time = interval(S, E) ).

%!  timeline_remove(+Timeline) is det.
%
%   Remove Timeline and all its facts.  If it was the current timeline, the
%   most recent one left becomes current.
%
%   @error existence_error(timeline, Timeline) if there is no such timeline.

timeline_remove(TL) :-
    must_be_timeline(TL),
    retractall(tl_registered(TL, _)),
    remove_facts(TL).

remove_facts(TL) :-
    retractall(tl_fluent(TL, _, _)),
    retractall(tl_event(TL, _, _)),
    retractall(tl_quantity(TL, _, _)),
    retractall(tl_meta(TL, _)),
    retractall(tl_vocabulary(TL, _)).

%!  timeline_exists(?Timeline) is nondet.
%
%   True if Timeline is a stored timeline.  Enumerates them in the order of
%   creation if Timeline is unbound.
%
%   @error type_error(atom, Timeline) if Timeline is bound to a non-atom.

timeline_exists(TL) :-
    (   var(TL)
    ->  tl_registered(TL, _)
    ;   must_be(atom, TL),
        tl_registered(TL, _),
        !
    ).

%!  timeline_property(?Timeline, ?Property) is nondet.
%
%   Property is a property of the stored Timeline:
%     - meta(Dict): the `meta` dict it was created with (`_{}` if none)
%     - fluents(Count), events(Count), quantities(Count): number of
%       fluent intervals, events and quantities stored.
%     - vocabulary(Dict): what any timeline of its scenario can name,
%       `_{fluents: [Name/Arity, ...], events: ..., quantities: ...,
%       objects: [Object, ...]}` (a timeline created with a vocabulary).

timeline_property(TL, Prop) :-
    timeline_exists(TL),
    property(Prop, TL).

property(meta(M), TL) :- tl_meta(TL, M).
property(fluents(N), TL) :- aggregate_all(count, tl_fluent(TL, _, _), N).
property(events(N), TL) :- aggregate_all(count, tl_event(TL, _, _), N).
property(quantities(N), TL) :- aggregate_all(count, tl_quantity(TL, _, _), N).
property(vocabulary(V), TL) :-
    tl_vocabulary(TL, Key),
    timeline_vocabulary_dict(vocabulary(Key), V).

%!  timeline_fluent_intervals(?Fluent, -Intervals:list, +Timeline) is nondet.
%
%   Intervals are the maximal intervals over which Fluent holds in Timeline,
%   sorted by start time.  Enumerates the distinct fluents that unify with
%   Fluent (no pattern reading of atoms here: Fluent is bound to the term).
%
%   @error existence_error(timeline, Timeline) if there is no such timeline.
%   @error type_error(callable, Fluent) if Fluent is not a term.
%   @error existence_error(fluent, Fluent) or existence_error(entity, Object)
%          for a fluent or object that no timeline of Timeline's scenario can
%          have (see the module doc).

timeline_fluent_intervals(F, Intervals, TL) :-
    must_be_timeline(TL),
    must_be_pattern(F),
    known_on(TL, fluent, F, timeline_fluent_intervals/3),
    (   ground(F)
    ->  once(tl_fluent(TL, F, _))
    ;   distinct(F, tl_fluent(TL, F, _))
    ),
    findall(S-I, ( tl_fluent(TL, F, I), I = interval(S, _) ), Pairs),
    keysort(Pairs, Sorted),
    pairs_values(Sorted, Intervals).

                 /*******************************
                 *       HOLDS AND OCCURS       *
                 *******************************/

%!  holds(?Fluent, ?Time, +Timeline) is nondet.
%
%   Fluent holds at Time in Timeline.
%
%     - Time not ground: enumerate the fluents matching Fluent with each of
%       their maximal intervals `interval(Start, End)`, unified with Time.
%     - Time a point: the fluents that hold at that point (interval ends
%       included), each once.
%     - Time an interval: the fluents that hold throughout it, each once.
%
%   Fluent may be an atom pattern (see the module doc).  With Fluent and
%   Time ground this is a test (semidet).
%
%   @error instantiation_error if Timeline is unbound.
%   @error existence_error(timeline, Timeline) if there is no such timeline.
%   @error type_error(callable, Fluent) if Fluent is bound to a non-term
%          (a number or string).
%   @error type_error(time, Time) if Time is ground but not a time.
%   @error existence_error(fluent, Fluent) for a fluent that no timeline of
%          Timeline's scenario can have (its name, or its name with its
%          arity); existence_error(entity, Object) for an argument that is
%          no object of that scenario.  The message lists the known ones.
%          Only timelines with a vocabulary (those of projections) check.

holds(F, T, TL) :-
    record_at(fluent, F, T, TL).

%!  occurs(?Event, ?Time, +Timeline) is nondet.
%
%   Event happens at Time in Timeline.  The time of an event is a point
%   `T` if it starts and ends at the same time, else `interval(S, E)`.
%
%     - Time not ground: enumerate the events matching Event with their
%       times, unified with Time.
%     - Time a point: the events happening at that point (an event with an
%       interval happens at every point of it), each once.
%     - Time an interval: the events whose time lies within it, each once.
%
%   Event may be an atom pattern (see the module doc):
%   `occurs(break, _, TL)` is true if a break(_) event happened.
%
%   @error as for holds/3, with type_error(callable, Event) and
%          existence_error(event, Event): `occurs(brake, _, TL)` is an error
%          where a timeline's scenario has break(_) events and no brake.

occurs(Ev, T, TL) :-
    record_at(event, Ev, T, TL).

% record_at(+Kind, ?Pattern, ?Time, +Timeline): a record of Kind (fluent
% or event) matching Pattern is at or over Time in Timeline; holds/3 and
% occurs/3 as documented there.
record_at(Kind, P, T, TL) :-
    must_be_timeline(TL),
    must_be_pattern(P),
    known_on(TL, Kind, P, Kind),   % the context is the kind's predicate
    (   ground(T)
    ->  must_be_time(T),
        (   ground(P)
        ->  once(record_at_time(Kind, P, T, TL))
        ;   distinct(P, record_at_time(Kind, P, T, TL))
        )
    ;   stored(Kind, TL, Term, Time),
        matches(P, Term),
        T = Time
    ).

record_at_time(Kind, P, T, TL) :-
    stored(Kind, TL, Term, Time),
    matches(P, Term),
    at_time(Kind, T, Time).

% stored(+Kind, ?Timeline, ?Term, ?Time).  Clauses rather than call/N,
% so that library(sandbox) can still verify holds/3 and occurs/3.
stored(fluent, TL, Term, I) :- tl_fluent(TL, Term, I).
stored(event, TL, Term, T) :- tl_event(TL, Term, T).

% at_time(+Kind, +T, +Time): the stored Time fits the query time T.  A
% fluent must hold throughout T; an event must happen at a point T, or
% lie within an interval T.
at_time(fluent, T, I) :-
    time_inside(T, I).
at_time(event, T, Time) :-
    (   number(T)
    ->  time_inside(T, Time)
    ;   time_inside(Time, T)
    ).

%!  quantity(?Quantity, ?Value, +Timeline) is nondet.
%
%   Quantity, a term such as `max_force(egg1)` built like fluents, has
%   Value in Timeline.  Quantity may be an atom pattern (see the module
%   doc).
%
%   @error as for holds/3, with type_error(callable, Quantity) and
%          existence_error(quantity, Quantity).

quantity(Q, V, TL) :-
    must_be_timeline(TL),
    must_be_pattern(Q),
    known_on(TL, quantity, Q, quantity/3),
    tl_quantity(TL, Term, V),
    matches(Q, Term).

% Time1 lies within Time2, end points included.
time_inside(T1, T2) :-
    allen_relation(R, T1, T2),
    inside(R),
    !.

inside(equals).
inside(starts).
inside(during).
inside(finishes).

% matches(?Pattern, +Term): an atom matches every term of that name, or of
% the name it is an alias of (name_alias/2).
matches(P, Term) :-
    (   atom(P)
    ->  (   P == Term
        ->  true
        ;   compound(Term),
            compound_name_arity(Term, Name, _),
            (   Name == P
            ->  true
            ;   name_alias(P, Name)
            )
        )
    ;   P = Term
    ).

%!  name_alias(?Alias, ?Name) is nondet.
%
%   Alias, used as an atom pattern, matches fluents, events and quantities
%   named Name.  The paper writes `holds(upsidedown, _, Timeline)` for the
%   fluent upside_down(Pancake).  Multifile: add spellings here.

:- multifile name_alias/2.

name_alias(upsidedown, upside_down).

must_be_pattern(P) :-
    (   var(P) -> true
    ;   callable(P) -> true
    ;   type_error(callable, P)
    ).

must_be_timeline(TL) :-
    must_be(atom, TL),
    (   tl_registered(TL, _) -> true ; existence_error(timeline, TL) ).

                 /*******************************
                 *          VOCABULARY          *
                 *******************************/

%!  timeline_vocabulary_create(+Data:dict, -Vocabulary) is det.
%
%   Vocabulary is the stored vocabulary Data, the `vocabulary` of a
%   projection's timeline (projection_server/timeline/vocabulary.py):
%   `_{fluents: Fs, events: Es, quantities: Qs, objects: Os}`, with Fs, Es
%   and Qs lists of `[Name, ArgKinds]` (ArgKinds a list of `object` or
%   `property`, one per argument) and Os the scenario's objects.  Names may
%   be atoms or strings.  The same Data gives the same Vocabulary: the
%   timelines of one scenario share theirs.
%
%   @error type_error(vocabulary, Data) if Data is not of that form.

timeline_vocabulary_create(Data, vocabulary(Key)) :-
    (   vocabulary_term(Data, Term)
    ->  true
    ;   type_error(vocabulary, Data)
    ),
    variant_sha1(Term, Key),
    (   vocab_registered(Key, _)
    ->  true
    ;   with_mutex(timeline_vocabulary, register_vocabulary(Key, Term))
    ).

vocabulary_term(Data, v(Fs, Es, Qs, Os)) :-
    is_dict(Data),
    get_dict(fluents, Data, Fs0), vocabulary_names(Fs0, Fs),
    get_dict(events, Data, Es0), vocabulary_names(Es0, Es),
    get_dict(quantities, Data, Qs0), vocabulary_names(Qs0, Qs),
    get_dict(objects, Data, Os0), is_list(Os0),
    maplist(text_atom, Os0, Os1),
    sort(Os1, Os).

vocabulary_names(L0, L) :-
    is_list(L0),
    maplist(vocabulary_name, L0, L1),
    sort(L1, L).

vocabulary_name([Name0, Kinds0], Name-Kinds) :-
    text_atom(Name0, Name),
    is_list(Kinds0),
    maplist(text_atom, Kinds0, Kinds),
    forall(member(K, Kinds), memberchk(K, [object, property])).

%!  timeline_vocabulary_dict(+Vocabulary, -Dict) is det.
%
%   Dict is Vocabulary as `_{fluents: [Name/Arity, ...], events: ...,
%   quantities: ..., objects: [Object, ...]}`, each list sorted.

timeline_vocabulary_dict(vocabulary(Key), V) :-
    known(Key, fluent, Fs), known(Key, event, Es), known(Key, quantity, Qs),
    known(Key, entity, Os),
    V = _{fluents: Fs, events: Es, quantities: Qs, objects: Os}.

text_atom(T, A) :-
    (   atom(T) -> A = T ; string(T), atom_string(A, T) ).

% register_vocabulary(+Key, +Term): store it, and forget the oldest
% vocabularies no timeline has beyond the flag timeline_max_vocabularies, so
% that a stream of scenarios with new objects runs in bounded memory.
:- create_prolog_flag(timeline_max_vocabularies, 64, [type(integer), keep(true)]).

register_vocabulary(Key, _) :-
    vocab_registered(Key, _), !.
register_vocabulary(Key, v(Fs, Es, Qs, Os)) :-
    forall(( member(Kind-L, [fluent-Fs, event-Es, quantity-Qs]),
             member(Name-Kinds, L) ),
           ( length(Kinds, Arity),
             assertz(vocab_term(Key, Kind, Name, Arity, Kinds)) )),
    forall(member(O, Os), assertz(vocab_object(Key, O))),
    flag(timeline_vocabulary_seq, N, N+1),
    assertz(vocab_registered(Key, N)),
    current_prolog_flag(timeline_max_vocabularies, Max),
    aggregate_all(count, vocab_registered(_, _), Count),
    Excess is Count - Max,
    forall(limit(Excess, ( vocab_registered(Old, _), Old \== Key,
                           \+ tl_vocabulary(_, Old) )),
           forget_vocabulary(Old)).

forget_vocabulary(Key) :-
    retractall(vocab_registered(Key, _)),
    retractall(vocab_term(Key, _, _, _, _)),
    retractall(vocab_object(Key, _)).

%!  timeline_condition_terms(@Goal, ?Timeline, -Terms:list) is det.
%
%   Terms are the fluents, events, quantities, types and objects that the
%   condition Goal names on the timeline Timeline (a variable, bound to each
%   projection's timeline later), as `Kind-Term` with Kind `fluent`,
%   `event`, `quantity`, `type` or `entity`: the first arguments of its
%   holds/3, occurs/3, quantity/3 and timeline_fluent_intervals/3 calls on
%   Timeline, of its holds/2, occurs/2 and quantity/2 calls (on the current
%   timeline, which is Timeline's while the condition runs), and the bound
%   second arguments of typeOf/2 and objOf/2.  Goal is walked through the
%   control constructs and the all-solutions and aggregation predicates
%   (`,`, `;`, `->`, `*->`, `\+`, not/1, call/1, once/1, ignore/1, forall/2,
%   findall/3,4, aggregate_all/3,4, bagof/3, setof/3, ...); what it calls
%   otherwise is not looked into.  Unbound terms are left out.

timeline_condition_terms(Goal, TL, Terms) :-
    phrase(condition_terms(Goal, TL), Terms).

condition_terms(G, _) --> { var(G) }, !.
condition_terms(_:G, TL) --> !, condition_terms(G, TL).
condition_terms(G, TL) --> { inner_goals(G, TL, Gs) }, !, inner_terms(Gs, TL).
condition_terms(G, TL) --> { named_term(G, TL, Kind, Term) }, !,
    (   { var(Term) } -> [] ; [Kind-Term] ).
condition_terms(_, _) --> [].

inner_terms([], _) --> [].
inner_terms([G|Gs], TL) --> condition_terms(G, TL), inner_terms(Gs, TL).

% inner_goals(+Goal, +TL, -Goals): the goals that Goal calls.
inner_goals((A, B), _, [A, B]).
inner_goals((A ; B), _, [A, B]).
inner_goals((A -> B), _, [A, B]).
inner_goals((A *-> B), _, [A, B]).
inner_goals(\+ A, _, [A]).
inner_goals(not(A), _, [A]).
inner_goals(call(A), _, [A]).
inner_goals(once(A), _, [A]).
inner_goals(ignore(A), _, [A]).
inner_goals(forall(A, B), _, [A, B]).
inner_goals(findall(_, A, _), _, [A]).
inner_goals(findall(_, A, _, _), _, [A]).
inner_goals(aggregate_all(_, A, _), _, [A]).
inner_goals(aggregate_all(_, _, A, _), _, [A]).
inner_goals(bagof(_, A, _), _, [B]) :- strip_carets(A, B).
inner_goals(setof(_, A, _), _, [B]) :- strip_carets(A, B).
inner_goals(aggregate(_, A, _), _, [B]) :- strip_carets(A, B).
inner_goals(_^A, _, [A]).
inner_goals(limit(_, A), _, [A]).
inner_goals(offset(_, A), _, [A]).
inner_goals(order_by(_, A), _, [A]).
inner_goals(distinct(A), _, [A]).
inner_goals(distinct(_, A), _, [A]).
inner_goals(call_nth(A, _), _, [A]).
inner_goals(catch(A, _, B), _, [A, B]).
inner_goals(with_timeline(T, A), TL, Gs) :-
    (   T == TL -> Gs = [A] ; Gs = [] ).  % another timeline's terms: not known here

strip_carets(G, G) :- var(G), !.
strip_carets(_^G0, G) :- !, strip_carets(G0, G).
strip_carets(G, G).

% named_term(+Goal, +TL, -Kind, -Term): Goal names Term of Kind on TL.
named_term(holds(F, _, T), TL, fluent, F) :- T == TL.
named_term(occurs(E, _, T), TL, event, E) :- T == TL.
named_term(quantity(Q, _, T), TL, quantity, Q) :- T == TL.
named_term(timeline_fluent_intervals(F, _, T), TL, fluent, F) :- T == TL.
named_term(holds(F, _), _, fluent, F).
named_term(occurs(E, _), _, event, E).
named_term(quantity(Q, _), _, quantity, Q).
named_term(typeOf(_, Type), _, type, Type).
named_term(objOf(_, Object), _, entity, Object).

%!  timeline_check_term(+Vocabulary, +Context, +Term) is det.
%
%   Term, `Kind-Term` as timeline_condition_terms/3 gives it, is one that a
%   timeline of Vocabulary can have (see the module doc).  Context is
%   `context(Predicate, Scenario)`, for the message.  Vocabulary `none`
%   takes any term.
%
%   @error existence_error(Kind, Term) if it is not; for an argument that is
%          no object, existence_error(entity, Object).

timeline_check_term(none, _, _) :- !.
timeline_check_term(vocabulary(Key), Context, Kind-Term) :-
    known_term(Kind, Key, Term, Context).

% known_on(+TL, +Kind, +Pattern, +Pred): Pattern is one that TL's vocabulary
% has, if TL has a vocabulary.
known_on(_, _, P, _) :-
    var(P), !.
known_on(TL, Kind, P, Pred) :-
    (   tl_vocabulary(TL, Key)
    ->  kind_predicate(Kind, Pred, Pred1),
        known_term(Kind, Key, P, context(Pred1, timeline(TL)))
    ;   true
    ).

kind_predicate(fluent, fluent, holds/3) :- !.
kind_predicate(event, event, occurs/3) :- !.
kind_predicate(_, Pred, Pred).

% known_term(+Kind, +Key, +Term, +Context)
known_term(_, _, Term, _) :-
    var(Term), !.
known_term(entity, Key, Object, Context) :- !,
    known_object(Key, Object, Context).
known_term(type, Key, Type, Context) :- !,
    (   ( Kind = event ; Kind = fluent ),
        (   vocab_term(Key, Kind, Type, _, _)
        ;   type_alias(Type, Name), vocab_term(Key, Kind, Name, _, _)
        )
    ->  true
    ;   unknown(type, Type, Key, Context)
    ).
known_term(Kind, Key, Term, Context) :-
    atom(Term), !,
    (   vocab_term(Key, Kind, Term, _, _)
    ->  true
    ;   name_alias(Term, Name),
        vocab_term(Key, Kind, Name, _, _)
    ->  true
    ;   unknown(Kind, Term, Key, Context)
    ).
known_term(Kind, Key, Term, Context) :-
    compound(Term), !,
    compound_name_arity(Term, Name, Arity),
    (   vocab_term(Key, Kind, Name, Arity, Kinds)
    ->  known_arguments(Kinds, 1, Term, Key, Context)
    ;   unknown(Kind, Term, Key, Context)
    ).
known_term(_, _, _, _).         % not a term: its type error comes later

known_arguments([], _, _, _, _).
known_arguments([K|Ks], I, Term, Key, Context) :-
    (   K == object
    ->  arg(I, Term, A),
        known_object(Key, A, Context)
    ;   true
    ),
    I1 is I + 1,
    known_arguments(Ks, I1, Term, Key, Context).

known_object(Key, A, Context) :-
    (   var(A)
    ->  true
    ;   atom(A), vocab_object(Key, A)
    ->  true
    ;   unknown(entity, A, Key, Context)
    ).

% unknown(+Kind, +Term, +Key, +Context): the existence error of Term, its
% context naming the predicate, the scenario and the known terms of Kind.
unknown(Kind, Term, Key, context(Pred, Source)) :-
    known(Key, Kind, Known),
    source_scenario(Source, Scenario),
    throw(error(existence_error(Kind, Term),
                context(Pred, vocabulary(Scenario, Known)))).

known(Key, entity, Known) :- !,
    findall(O, vocab_object(Key, O), Known).
known(Key, type, Known) :- !,
    findall(T, ( member(K, [event, fluent]), vocab_term(Key, K, N, _, _),
                 type_name(N, T) ), Known0),
    sort(Known0, Known).
known(Key, Kind, Known) :-
    findall(N/A, vocab_term(Key, Kind, N, A, _), Known).

source_scenario(timeline(TL), Scenario) :- !,
    (   tl_meta(TL, Meta), get_dict(scenario, Meta, S0), text_atom(S0, S)
    ->  Scenario = S
    ;   Scenario = timeline(TL)
    ).
source_scenario(Scenario, Scenario).


                 /*******************************
                 *          QUERY FORM          *
                 *******************************/

%!  current_timeline(-Timeline) is semidet.
%
%   Timeline is the current timeline: the one selected by the innermost
%   with_timeline/2 of this thread, else the most recently created one.
%   Fails if there is none.

current_timeline(TL) :-
    (   nb_current('$timeline_selected', TL0), TL0 \== []
    ->  TL = TL0
    ;   aggregate_all(max(N, TL0), tl_registered(TL0, N), max(_, TL0)),
        TL = TL0
    ).

the_current_timeline(TL) :-
    (   current_timeline(TL0)
    ->  TL = TL0
    ;   existence_error(timeline, current)
    ).

%!  with_timeline(+Timeline, :Goal) is nondet.
%
%   Call Goal with Timeline as the current timeline.  The selection holds
%   while Goal runs, also when backtracking into it, and ends when Goal
%   exits, fails or throws.
%
%   @error existence_error(timeline, Timeline) if there is no such timeline.

:- meta_predicate with_timeline(+, 0).

with_timeline(TL, Goal) :-
    must_be_timeline(TL),
    (   nb_current('$timeline_selected', Old) -> true ; Old = [] ),
    b_setval('$timeline_selected', TL),
    call(Goal),
    b_setval('$timeline_selected', Old).

%!  holds(?Fluent, ?Time) is nondet.
%!  occurs(?Event, ?Time) is nondet.
%!  quantity(?Quantity, ?Value) is nondet.
%
%   holds/3, occurs/3 and quantity/3 on the current timeline.
%
%   @error existence_error(timeline, current) if there is no timeline.

holds(F, T) :-
    the_current_timeline(TL),
    holds(F, T, TL).

occurs(Ev, T) :-
    the_current_timeline(TL),
    occurs(Ev, T, TL).

quantity(Q, V) :-
    the_current_timeline(TL),
    quantity(Q, V, TL).

%!  typeOf(?Term, ?Type) is nondet.
%
%   Type is the type of the event or fluent Term: the name of Term, or its
%   gerund as the paper writes event types (`dropping` for drop(egg1)).
%   The gerunds known are: dropping-drop, slipping-slip, shifting-shift,
%   breaking-break,
%   grasping-grasp, lifting-lift, spilling-spill, flipping-flip,
%   pouring-pour, turning-turn, falling-fall.  Add others with clauses of
%   the multifile timeline:type_alias(Gerund, Name).  If Term is
%   unbound, it ranges over the events and fluents of the current
%   timeline.
%
%   @error type_error(callable, Term) if Term is bound to a non-term.
%   @error existence_error(timeline, current) if Term is unbound and there
%          is no timeline.
%   @error existence_error(type, Type) for a Type that names no event or
%          fluent a timeline of the current timeline's scenario can have
%          (`droping`), if that timeline has a vocabulary (see the module
%          doc).

typeOf(Term, Type) :-
    known_on_current(type, Type, typeOf/2),
    timeline_term(Term),
    functor(Term, Name, _),
    (   nonvar(Type)
    ->  once(type_name(Name, Type))
    ;   type_name(Name, Type)
    ).

type_name(Name, Name).
type_name(Name, Alias) :-
    type_alias(Alias, Name).

:- multifile type_alias/2.

type_alias(dropping, drop).
type_alias(slipping, slip).
type_alias(shifting, shift).
type_alias(breaking, break).
type_alias(grasping, grasp).
type_alias(lifting, lift).
type_alias(spilling, spill).
type_alias(flipping, flip).
type_alias(pouring, pour).
type_alias(turning, turn).
type_alias(falling, fall).

%!  objOf(?Term, ?Object) is nondet.
%
%   Object is an object that the event or fluent Term is about: any
%   argument of Term that is an atom (an entity name), not only the first,
%   so that `contact(gripper, egg1)` is about egg1 too.  Numeric arguments
%   are not objects.  Each object is given once.  If Term is unbound, it
%   ranges over the events and fluents of the current timeline.
%
%   @error as for typeOf/2, and existence_error(entity, Object) for an
%          Object that is none of the current timeline's scenario.

objOf(Term, Obj) :-
    known_on_current(entity, Obj, objOf/2),
    timeline_term(Term),
    compound(Term),
    Term =.. [_|Args],
    (   nonvar(Obj)
    ->  atom(Obj),
        memberchk(Obj, Args)
    ;   include_atoms(Args, Objs0),
        list_to_set(Objs0, Objs),
        member(Obj, Objs)
    ).

include_atoms([], []).
include_atoms([H|T0], L) :-
    (   atom(H) -> L = [H|T] ; L = T ),
    include_atoms(T0, T).

% known_on_current(+Kind, ?Term, +Pred): Term is known to the current
% timeline's vocabulary, if there is one.
known_on_current(_, Term, _) :-
    var(Term), !.
known_on_current(Kind, Term, Pred) :-
    (   current_timeline(TL),
        tl_vocabulary(TL, Key)
    ->  known_term(Kind, Key, Term, context(Pred, timeline(TL)))
    ;   true
    ).

% timeline_term(?Term): Term is checked if bound, else enumerated from the
% distinct event and fluent terms of the current timeline.
timeline_term(Term) :-
    (   var(Term)
    ->  the_current_timeline(TL),
        distinct(Term, ( tl_event(TL, Term, _) ; tl_fluent(TL, Term, _) ))
    ;   must_be(callable, Term)
    ).

                 /*******************************
                 *           SANDBOX            *
                 *******************************/

% The query service runs goals under library(sandbox): with_timeline/2
% calls its goal, and the selection uses a global variable.  The readers
% below only read the timeline store and call none of their arguments, so
% they are primitives: proving their bodies safe again for every query cost
% 5-10 ms each (most of a cached Table I query).

:- multifile sandbox:safe_meta/2, sandbox:safe_global_variable/1,
             sandbox:safe_primitive/1.

sandbox:safe_meta(timeline:with_timeline(_, Goal), [Goal]).
sandbox:safe_global_variable('$timeline_selected').

sandbox:safe_primitive(timeline:holds(_, _, _)).
sandbox:safe_primitive(timeline:occurs(_, _, _)).
sandbox:safe_primitive(timeline:quantity(_, _, _)).
sandbox:safe_primitive(timeline:holds(_, _)).
sandbox:safe_primitive(timeline:occurs(_, _)).
sandbox:safe_primitive(timeline:quantity(_, _)).
sandbox:safe_primitive(timeline:typeOf(_, _)).
sandbox:safe_primitive(timeline:objOf(_, _)).
sandbox:safe_primitive(timeline:timeline_exists(_)).
sandbox:safe_primitive(timeline:timeline_property(_, _)).
sandbox:safe_primitive(timeline:timeline_fluent_intervals(_, _, _)).
sandbox:safe_primitive(timeline:current_timeline(_)).

                 /*******************************
                 *           MESSAGES           *
                 *******************************/

:- multifile prolog:message//1.

prolog:message(error(existence_error(timeline, current), _)) -->
    [ 'No timeline exists: holds/2, occurs/2 and the other query forms ',
      'use the most recently created timeline' ].
prolog:message(error(existence_error(Kind, Term), Context)) -->
    { nonvar(Context), Context = context(Pred, Known0),
      nonvar(Known0), Known0 = vocabulary(S, Known)
    }, !,
    vocabulary_message(Kind, Term, Pred, S, Known).
prolog:message(error(existence_error(timeline, TL), _)) -->
    [ 'Unknown timeline: ~p (created timelines are listed by timeline_exists/1)'-[TL] ].

vocabulary_message(entity, Object, Pred, S, Known) --> !,
    { atomic_list_concat(Known, ', ', List) },
    [ '~w: ~q is no object of '-[Pred, Object] ], scenario(S),
    [ ': its objects are ~w'-[List] ].
vocabulary_message(type, Type, Pred, S, Known) --> !,
    { atomic_list_concat(Known, ', ', List) },
    [ '~w: no timeline of '-[Pred] ], scenario(S),
    [ ' has an event or fluent of type ~q; the types are ~w'-[Type, List] ].
vocabulary_message(Kind, Term, Pred, S, Known) -->
    { maplist(indicator_atom, Known, Ts),
      atomic_list_concat(Ts, ', ', List),
      kind_words(Kind, Article, Plural),
      (   Known = [Name/_|_] -> true ; Name = break )
    },
    [ '~w: no timeline of '-[Pred] ], scenario(S),
    [ ' has ~w ~w ~q; its ~w are ~w (an atom such as ~w stands for '-
      [Article, Kind, Term, Plural, List, Name],
      'any term of that name)' ].

indicator_atom(N/A, T) :-
    format(atom(T), '~w/~w', [N, A]).

kind_words(event, an, events) :- !.
kind_words(quantity, a, quantities) :- !.
kind_words(Kind, a, Plural) :-
    atom_concat(Kind, s, Plural).

scenario(timeline(TL)) --> !, [ 'the scenario of ~w'-[TL] ].
scenario(S) --> [ 'scenario ~w'-[S] ].
