:- begin_tests(model_files, [ setup(make_assets),
                              cleanup(remove_assets) ]).
:- use_module(model_files).

% A directory of assets of one's own, and beside it a file no query may reach.
:- dynamic assets/2.                    % assets(Dir, Outside)

make_assets :-
    tmp_file(assets, Root),
    make_directory(Root),
    directory_file_path(Root, models, Dir),
    make_directory(Dir),
    directory_file_path(Root, 'secret.obj', Outside),
    write_file(Outside, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
    file_in(Dir, 'cube.obj', Cube),
    write_file(Cube, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"),
    file_in(Dir, 'thing.urdf', Urdf),
    link_with_mesh("cube.obj", Thing),
    write_file(Urdf, Thing),
    file_in(Dir, 'holes.obj', Holes),
    write_file(Holes, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n"),
    file_in(Dir, 'nolink.urdf', NoLink),
    write_file(NoLink, "<robot name=\"x\"></robot>"),
    file_in(Dir, 'escape.urdf', Escape),
    link_with_mesh("../secret.obj", Leak),
    write_file(Escape, Leak),
    file_in(Dir, 'thing.sdf', Sdf),
    write_file(Sdf, "<sdf version=\"1.6\"><model name=\"x\"/></sdf>"),
    file_in(Dir, 'notes.txt', Notes),
    write_file(Notes, "hello\n"),
    file_in(Dir, 'link.obj', Link),
    link_file(Outside, Link, symbolic),
    assertz(assets(Dir, Outside)),
    set_model_directories([Dir]).

% A URDF of one link whose collision is the mesh File.
link_with_mesh(File, Text) :-
    format(string(Text), "~w~w~w",
           [ "<robot name=\"thing\"><link name=\"base\"><collision><geometry><mesh filename=\"",
             File,
             "\"/></geometry></collision></link></robot>" ]).

remove_assets :-
    forall(retract(assets(Dir, _)),
           ( file_directory_name(Dir, Root),
             delete_directory_and_contents(Root) )),
    retractall(model_files:directories(_)).

file_in(Dir, Name, Path) :-
    directory_file_path(Dir, Name, Path).

write_file(Path, Text) :-
    setup_call_cleanup(open(Path, write, S), write(S, Text), close(S)).

in_assets(Name, Path) :-
    assets(Dir, _),
    file_in(Dir, Name, Path0),
    atom_string(Path0, Path).

test(directories_put_ones_own_after_the_packages, [Dir] == Mine) :-
    assets(Dir0, _),
    atom_string(Dir0, Dir),
    model_directories([_Package, Dir1|_]),
    Mine = [Dir1].
test(relative_path, P == Expected) :-
    in_assets('cube.obj', Expected),
    model_file("cube.obj", P).
test(absolute_path_inside, P == Expected) :-
    in_assets('thing.urdf', Expected),
    model_file(Expected, P).
test(absolute_path_with_dots_inside, P == Expected) :-
    in_assets('cube.obj', Expected),
    assets(Dir, _),
    format(string(Dotted), "~w/../models/cube.obj", [Dir]),
    model_file(Dotted, P).
test(atom_path, P == Expected) :-
    in_assets('cube.obj', Expected),
    model_file('cube.obj', P).
test(the_packages_own_glass, true) :-
    model_file("glass.obj", P),
    sub_string(P, _, _, 0, "/glass.obj").
test(outside_by_dots, error(permission_error(access, model_file, "../secret.obj"))) :-
    model_file("../secret.obj", _).
test(outside_by_absolute_path, error(permission_error(access, model_file, Outside))) :-
    assets(_, Outside0),
    atom_string(Outside0, Outside),
    model_file(Outside, _).
test(outside_by_symbolic_link, error(permission_error(access, model_file, "link.obj"))) :-
    model_file("link.obj", _).
test(outside_and_missing, error(permission_error(access, model_file, "/etc/none.obj"))) :-
    model_file("/etc/none.obj", _).
test(missing, error(existence_error(model_file, "none.obj"))) :-
    model_file("none.obj", _).
test(a_directory_is_no_file, error(existence_error(model_file, "."))) :-
    model_file(".", _).
test(malformed_obj, error(domain_error(model_file(obj), "holes.obj"))) :-
    model_file("holes.obj", _).
test(malformed_urdf, error(domain_error(model_file(urdf), "nolink.urdf"))) :-
    model_file("nolink.urdf", _).
test(urdf_naming_a_mesh_outside, error(domain_error(model_file(urdf), "escape.urdf"))) :-
    model_file("escape.urdf", _).
test(malformed_sdf, error(domain_error(model_file(sdf), "thing.sdf"))) :-
    model_file("thing.sdf", _).
test(other_file_type, error(domain_error(model_file, "notes.txt"))) :-
    model_file("notes.txt", _).
test(not_text, error(type_error(text, 42))) :-
    model_file(42, _).
test(messages_say_what_is_wrong) :-
    catch(model_file("holes.obj", _), E1, true),
    message_to_codes(E1, S1),
    once(sub_string(S1, _, _, _, "names a vertex that does not exist")),
    catch(model_file("../secret.obj", _), E2, true),
    message_to_codes(E2, S2),
    once(sub_string(S2, _, _, _, "outside the asset directories")).
test(a_missing_directory_is_refused,
     [ error(existence_error(directory, '/nonexistent/models')),
       cleanup(( assets(Dir, _), set_model_directories([Dir]) )) ]) :-
    set_model_directories(['/nonexistent/models']).

message_to_codes(E, S) :-
    '$messages':translate_message(E, Lines, []),
    with_output_to(string(S), print_message_lines(current_output, '', Lines)).

:- end_tests(model_files).
