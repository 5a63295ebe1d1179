:- module(json_bindings,
          [ bindings_json/2,            % +Bindings, -JsonText
            term_json/3,                % +Term, +VarNames, -JsonTerm
            json_text/2                 % +JsonTerm, -JsonText
          ]).
:- use_module(library(apply), [foldl/4, maplist/3]).
:- use_module(library(error), [must_be/2, domain_error/2]).
:- use_module(library(lists), [reverse/2]).
:- use_module(library(http/json), [json_write/3]).

/** <module> Lossless JSON encoding of query bindings

Encodes the bindings of one solution as a JSON object that maps each variable
name of the query to the encoded value. Every Prolog term kind has its own JSON
shape, so a client can tell them apart and read them back without loss:

  | Prolog                  | JSON                                              |
  |-------------------------|---------------------------------------------------|
  | atom `a`                | `"a"`                                             |
  | string `"s"`            | `{"string": "s"}`                                 |
  | integer (any size)      | number written with its exact digits: `12345678901234567890` |
  | float                   | number with `.` or `e`, shortest exact form: `0.1`, `1.0e300` |
  | inf, -inf, nan          | `{"float": "inf"}`, `{"float": "-inf"}`, `{"float": "nan"}` |
  | rational `1r3`          | `{"rational": "1r3"}`                             |
  | proper list             | array: `[1, "a"]`; `[]` is `[]`                   |
  | compound `f(a, 1)`      | `{"functor": "f", "args": ["a", 1]}`              |
  | partial list `[a|T]`    | `{"functor": "[|]", "args": ["a", {"var": "T"}]}` |
  | unbound variable        | `{"var": "Y"}`: the query's name, or `_G1`, `_G2` ... |
  | dict `t{k: v}`          | `{"dict": [["k", "v"]], "tag": "t"}`              |
  | other blobs (streams..) | `{"blob": "<stream>(0x..)", "type": "stream"}`    |

Variables that stay unbound are reported, never dropped. Two query variables
bound to the same unbound variable are reported under the same name.

```
?- bindings_json(['X'=f(Y, "s"), 'Y'=Y], J).
J = "{\"X\":{\"functor\":\"f\",\"args\":[{\"var\":\"Y\"},{\"string\":\"s\"}]},\"Y\":{\"var\":\"Y\"}}".
```
*/

%!  bindings_json(+Bindings:list, -JsonText:string) is det.
%
%   JsonText is the JSON object for Bindings, a list of `Name=Value` as
%   produced by read_term/2's variable_names option.
%
%   @error representation_error(acyclic_term) if a value is cyclic.

bindings_json(Bindings, JsonText) :-
    must_be(list, Bindings),
    var_names(Bindings, VarNames),
    foldl(binding_pair(VarNames), Bindings, Pairs, []),
    json_text(json(Pairs), JsonText).

binding_pair(VarNames, Name=Value, [Key-Json|T], T) :-
    atom_string(Name, Key),
    term_json(Value, VarNames, Json).

% Query variables that are still unbound keep their own name; other
% variables get fresh names _G1, _G2, ... in order of appearance.
var_names(Bindings, VarNames) :-
    foldl(query_var_name, Bindings, [], Named0),
    reverse(Named0, Named),
    maplist(binding_value, Bindings, Values),
    term_variables(Values, Vars),
    foldl(fresh_var_name, Vars, Named-1, VarNames-_).

binding_value(_=Value, Value).

query_var_name(_=Value, Named, Named) :-
    (   nonvar(Value) ; known_var(Value, Named, _) ), !.
query_var_name(Name=Value, Named, [Value-Name|Named]).

fresh_var_name(V, Named-N, Named-N) :-
    known_var(V, Named, _), !.
fresh_var_name(V, Named-N, [V-Name|Named]-N1) :-
    format(atom(Name), '_G~d', [N]),
    N1 is N+1.

known_var(V, [V0-Name0|T], Name) :-
    (   V == V0 -> Name = Name0 ; known_var(V, T, Name) ).

%!  term_json(+Term, +VarNames, -Json) is det.
%
%   Json is the JSON term (see json_text/2) for Term.
%   VarNames is a list `Var-Name` naming the variables of Term.

term_json(Term, VarNames, Json) :-
    (   cyclic_term(Term)               % once for the whole term: it walks all of it
    ->  throw(error(representation_error(acyclic_term), _))
    ;   json_(Term, VarNames, Json)
    ).

json_(Var, VarNames, json([var-Name])) :-
    var(Var), !,
    (   known_var(Var, VarNames, Name0) -> atom_string(Name0, Name) ; Name = "_" ).
json_(Int, _, Int) :-
    integer(Int), !.
json_(Float, _, Json) :-
    float(Float), !,
    float_json(Float, Json).
json_(Rat, _, json([rational-S])) :-
    rational(Rat), !,
    format(string(S), '~w', [Rat]).
json_(String, _, json([string-String])) :-
    string(String), !.
json_([], _, []) :- !.
json_(Atom, _, String) :-
    atom(Atom), !,
    atom_string(Atom, String).
json_(List, VarNames, Json) :-
    is_list(List), !,
    maplist(term_json_(VarNames), List, Json).
json_(Dict, VarNames, json([dict-Pairs, tag-TagJson])) :-
    is_dict(Dict, Tag), !,
    dict_pairs(Dict, _, KVs),
    json_(Tag, VarNames, TagJson),
    maplist(pair_json(VarNames), KVs, Pairs).
json_(Compound, VarNames, json([functor-Name, args-Args])) :-
    compound(Compound), !,
    compound_name_arguments(Compound, Name0, Args0),
    atom_string(Name0, Name),
    maplist(term_json_(VarNames), Args0, Args).
json_(Blob, _, json([blob-Text, type-Type])) :-
    blob(Blob, Type0),
    format(string(Text), '~p', [Blob]),
    atom_string(Type0, Type).

term_json_(VarNames, Term, Json) :-
    json_(Term, VarNames, Json).

pair_json(VarNames, K-V, [KJ, VJ]) :-
    json_(K, VarNames, KJ),
    json_(V, VarNames, VJ).

float_json(F, Json) :-
    (   F =:= inf -> Json = json([float-"inf"])
    ;   F =:= -inf -> Json = json([float-"-inf"])
    ;   F =\= F -> Json = json([float-"nan"])
    ;   Json = F
    ).

%!  json_text(+Json, -Text:string) is det.
%
%   Text is Json written compactly on one line.  Json is a string, a
%   number, a list of Json, or json(Pairs) with `Key-Json` pairs (Key an
%   atom or string) whose
%   order is kept.  Floats are written in their shortest form that reads
%   back to the same float.

json_text(Json, Text) :-
    with_output_to(string(Text), write_json(Json)).

write_json(json(Pairs)) :- !,
    write('{'), write_members(Pairs), write('}').
write_json(List) :-
    is_list(List), !,
    write('['), write_elements(List), write(']').
write_json(String) :-
    string(String), !,
    json_write(current_output, String, [width(0)]).
write_json(Number) :-
    number(Number), !,
    write(Number).

write_members([]).
write_members([K-V|T]) :-
    atom_string(K, Key),
    write_json(Key), write(':'), write_json(V),
    (   T == [] -> true ; write(','), write_members(T) ).

write_elements([]).
write_elements([H|T]) :-
    write_json(H),
    (   T == [] -> true ; write(','), write_elements(T) ).
