"""What a snapshot of the robot's world costs, and a projection from it against the same
projection from a scenario typed into the query, in the same run.

A publisher of this process (a real rclpy node: the Panda's description with package://
meshes, its joints at 50 Hz, its base on /tf_static, an egg's frame on /tf) stands in for
the robot's graph. ``robot_world/2`` is timed inside the query (``get_time/1`` around the
call, the description long received): the cost from the call to the scenario. Then the
same grasps, each a new projection (distinct forces, so nothing comes from the cache), are
made from the snapshot's scenario and from a typed scenario of the same world, in
alternating rounds; the ratio of their medians is the snapshot's share of a projection.

    tools/with_env.sh python bench/robot_world.py [--repeat 5] [--snapshots 50]
"""

from __future__ import annotations

from pathlib import Path
import statistics
import sys
import tempfile
import time

import harness

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test'))   # the tests' robot graph
from world.robot_graph import BASE, JOINTS, RobotGraph  # noqa: E402

EGG = ((-0.32, 0.05, 0.742), (0.0, 0.0, 0.0, 1.0))
ENTITIES = 'entities([kitchen_env, entity(egg1, egg, _{frame: egg_1})])'
GRASP = '''plan([move_to(egg1, [0, 0, 0.10], [orientation(top), speed(0.5)]),
                 move_to(egg1, [0, 0, 0], [speed(0.1)]), close_gripper(F), wait(0.3),
                 move_by([0, 0, 0.1]), wait(0.5)])'''
PANDA = ('entity(panda, robot, _{{model: urdf, file: "franka_panda/panda.urdf", '
         'tool_link: panda_hand, tool_offset: [0, 0, 0.1034], '
         'finger_joints: [panda_finger_joint1, panda_finger_joint2], max_force: 20, '
         'joint_names: {names}, joint_positions: {values}, pose: _{{xyz: {base}}}}})')
TYPED = ('create_scenario(S), add_to_scenario(S, [kitchen_env, {panda}, '
         'entity(egg1, egg, _{{pose: _{{xyz: {egg}}}}})])')


def main() -> None:
    parser = harness.arguments(__doc__, repeat=5)
    parser.add_argument('--snapshots', type=int, default=50, help='snapshots timed')
    parser.add_argument('--grasps', type=int, default=4, help='grasps a round, each side')
    args = parser.parse_args()
    harness.ros_domain(160)
    import rclpy
    rclpy.init()
    tmp = Path(tempfile.mkdtemp(prefix='bench_robot_world_'))
    panda = PANDA.format(names=list(JOINTS), values=list(JOINTS.values()),
                         base=list(BASE[0]))
    typed = TYPED.format(panda=panda, egg=list(EGG[0]))
    print(f'settings: {args.snapshots} snapshots; {args.repeat} rounds of {args.grasps} '
          f'grasps from each scenario; 1 worker; {harness.machine()}')
    graph = RobotGraph(rclpy.create_node('bench_robot_graph'))
    graph.frames['egg_1'] = ('map', *EGG, 0.0)
    try:
        with harness.start_node({'bag_dir': str(tmp / 'bags'), 'projection_workers': 1},
                                tmp / 'node.log') as _, harness.client() as c:
            c.once(f'robot_world(S, [{ENTITIES}])', timeout=30.0)   # description received
            answer = c.once(f'''findall(D, (between(1, {args.snapshots}, _), get_time(T0),
                robot_world(S, [{ENTITIES}]), get_time(T1), delete_scenario(S),
                D is T1 - T0), Ds)''', timeout=120.0)
            seconds = [float(v) for v in answer['Ds']]
            print(f'\nsnapshot (robot_world/2, call to scenario): median '
                  f'{statistics.median(seconds) * 1000:.1f} ms, max '
                  f'{max(seconds) * 1000:.1f} ms, of {len(seconds)}')
            rows: dict[str, list[float]] = {'snapshot': [], 'typed': []}
            force = 4.0
            for _ in range(args.repeat):
                for side in ('snapshot', 'typed'):
                    forces = [round(force + 0.001 * i, 4) for i in range(args.grasps)]
                    force += 0.01
                    setup = (f'robot_world(S, [{ENTITIES}])' if side == 'snapshot'
                             else typed)
                    start = time.perf_counter()
                    c.all(f'{setup}, make_projection(S, {GRASP}, [(F, force, {forces})], '
                          'TL), ( occurs(grasp, _, TL) -> O = grasp ; O = none )',
                          timeout=600.0, max_solutions=100)
                    rows[side].append(time.perf_counter() - start)
            print(f'\n{"scenario":<10} {"median s":>9}   rounds ({args.grasps} grasps each)')
            for side, runs in rows.items():
                print(f'{side:<10} {statistics.median(runs):9.2f}   {harness.listed(runs)}')
            ratio = statistics.median(rows['snapshot']) / statistics.median(rows['typed'])
            print(f'\nprojection from a snapshot / from a typed scenario: {ratio:.3f}x')
    finally:
        graph.close()
        graph.node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
