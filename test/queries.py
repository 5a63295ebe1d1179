"""Query texts that more than one test module asks of the service, and their parts.

Each is a template for ``str.format`` (its literal braces doubled); the parts are put
together with f-strings, which leave the parts' braces as they are.
"""

from __future__ import annotations

# A box on the table, its centre 0.15 m from the edge: scenario S.
BOX_ON_THE_TABLE = '''create_scenario(S), add_to_scenario(S, [kitchen_env, pr2_robot,
        entity(box1, rigid_object, _{{shape: box, size_x: 0.05, size_y: 0.05, size_z: 0.05,
                                      mass: 0.2, friction: 0.4,
                                      pose: _{{xyz: [0.45, 0.0, 0.745]}}}})])'''
# The plan that pushes it along x by D with the PR2's closed fingers (they touch it after
# 0.04 m).
PUSH_BY_D = '''plan([close_gripper(10),
                             move_to(box1, [-0.09, 0, 0], [orientation(side(0)), speed(1.0)]),
                             move_by([D, 0, 0], [speed(0.1)]), move_by([-0.1, 0, 0])])'''
# That push by each of ``{distances}``, with make_projection's ``{options}``; Fell is yes
# once the box dropped.
PUSH_OFF_THE_EDGE = f'''{BOX_ON_THE_TABLE},
    make_projection(S, {PUSH_BY_D},
                    [(D, distance, {{distances}})], {{options}}, TL),
    ( occurs(drop(box1), _, TL) -> Fell = yes ; Fell = no )'''
