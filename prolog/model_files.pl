:- module(model_files,
          [ model_directories/1,        % -Dirs:list(string)
            set_model_directories/1,    % +UserDirs:list(text)
            model_file/2                % +Path0:text, -Path:string
          ]).
:- use_module(library(janus), [py_call/3]).
:- autoload(library(apply), [maplist/2, maplist/3]).
:- autoload(library(error), [must_be/2, existence_error/2]).

/** <module> Model files: the meshes and URDFs a scenario's entities are made of

A file-valued property of an entity (the `file` of a `rigid_object`, see
kb/kitchen.ttl; a `urdf` robot's, which may be an SDF) names a model file:
a URDF, an SDF, an OBJ or an STL mesh.  Model
files resolve only inside the *asset directories*: the package's own, the
directories the node is started with (parameter `asset_paths`) and
`pybullet_data`'s, in that order, each with its symbolic links and `..`
resolved.  scenario.pl resolves the files of every entity it adds or
changes with model_file/2, so a scenario description holds absolute paths,
and a bad file is an error of the query that names it, before any worker
runs:

  - a relative path is looked up in each asset directory in turn, the first
    that has it wins; an absolute one must lie inside one of them;
  - a path that leads outside them (by `..`, a symbolic link or an absolute
    path elsewhere) is a `permission_error(access, model_file, Path)`;
  - a file that is in none of them is an `existence_error(model_file, Path)`;
  - a file that is not a well formed URDF, SDF, OBJ or STL is a
    `domain_error(model_file(Format), Path)` whose message says what is
    wrong (a file of another type: `domain_error(model_file, Path)`).

The checks themselves are Python's (`projection_server.assets`, which the
simulation side shares to check every job again).  The asset directories
are set once, by the node (set_model_directories/1, which no sandboxed
query may call).

```
?- model_file("objects/mug.urdf", P).
P = "/.../site-packages/pybullet_data/objects/mug.urdf".
?- catch(model_file("../../etc/passwd", _), error(E, _), true).
E = permission_error(access, model_file, "../../etc/passwd").
```
*/

:- dynamic directories/1.               % directories(Dirs), once set

%!  set_model_directories(+UserDirs:list) is det.
%
%   Make the asset directories the package's own, UserDirs (absolute, or
%   relative to the working directory) and `pybullet_data`'s, in that
%   order, each resolved.  Python's checks of jobs use the same ones.
%
%   @error existence_error(directory, Dir) for a Dir of UserDirs that is
%          not a directory.

set_model_directories(User) :-
    must_be(list(text), User),
    maplist(existing_directory, User),
    maplist(text_to_string, User, Strings),
    py_call('projection_server.assets':configure(Strings), Dirs,
            [py_string_as(string)]),
    with_mutex(model_files,
               ( retractall(directories(_)),
                 assertz(directories(Dirs)) )).

existing_directory(Dir) :-
    (   exists_directory(Dir)
    ->  true
    ;   existence_error(directory, Dir)
    ).

%!  model_directories(-Dirs:list(string)) is det.
%
%   Dirs are the asset directories, in the order a relative path is looked
%   up in: as set_model_directories/1 set them, else the package's own and
%   `pybullet_data`'s.

model_directories(Dirs) :-
    (   directories(Dirs0)
    ->  Dirs = Dirs0
    ;   py_call('projection_server.assets':default_directories(), Dirs,
                [py_string_as(string)])
    ).

%!  model_file(+Path0:text, -Path:string) is det.
%
%   Path is the absolute, resolved path of the well formed model file
%   Path0 names in the asset directories (see the module documentation).
%
%   @error type_error(text, Path0) if Path0 is no text.
%   @error permission_error(access, model_file, Path0) if it resolves
%          outside the asset directories.
%   @error existence_error(model_file, Path0) if no asset directory has it.
%   @error domain_error(model_file(Format), Path0) if its content is not a
%          well formed `urdf`, `sdf`, `obj` or `stl` file (a URDF's or
%          SDF's meshes included); domain_error(model_file, Path0) for another type.

model_file(Path0, Path) :-
    must_be(text, Path0),
    text_to_string(Path0, String),
    model_directories(Dirs),
    py_call('projection_server.assets':resolve(String, Dirs),
            [Status, Value, Message], [py_string_as(string)]),
    resolved(Status, String, Value, Message, Path).

resolved("ok", _, Path, _, Path) :- !.
resolved("outside", Path0, _, Message, _) :-
    !,
    throw(error(permission_error(access, model_file, Path0),
                context(model_file/2, Message))).
resolved("missing", Path0, _, Message, _) :-
    !,
    throw(error(existence_error(model_file, Path0), context(model_file/2, Message))).
resolved("format", Path0, _, Message, _) :-
    !,
    throw(error(domain_error(model_file, Path0), context(model_file/2, Message))).
resolved("malformed", Path0, Format, Message, _) :-
    atom_string(F, Format),
    throw(error(domain_error(model_file(F), Path0), context(model_file/2, Message))).

:- multifile prolog:message//1.

prolog:message(error(permission_error(access, model_file, Path), context(_, Msg))) -->
    { string(Msg) }, !,
    [ 'Model file ~q: ~w'-[Path, Msg] ].
prolog:message(error(existence_error(model_file, Path), context(_, Msg))) -->
    { string(Msg) }, !,
    [ 'Model file ~q: ~w'-[Path, Msg] ].
prolog:message(error(domain_error(model_file, Path), context(_, Msg))) -->
    { string(Msg) }, !,
    [ 'Model file ~q: ~w'-[Path, Msg] ].
prolog:message(error(domain_error(model_file(Format), Path), context(_, Msg))) -->
    { string(Msg) }, !,
    [ 'Model file ~q is not a well formed ~w file: ~w'-[Path, Format, Msg] ].
