"""The robot in the loop, for real over ROS 2: a robot program reads the stand-in robot's
world, chooses a grip by projecting, executes it on the stand-in and records what happened.

    tools/with_env.sh python bench/robot_loop.py [--eggs 100] [--seed 1] [--options OPTS]
        [--physics DICT] [--trials PATH] [--report TRIALS_JSON ...]

Two processes stand for the robot and its brain: ``projection_standin_robot`` (the world:
a Panda and an egg in a PyBullet world of its own at 4x the projection's rate and solver
iterations, the egg's true friction and breaking force drawn at each reset and published on
no topic) and ``projection_server``; this program talks to both over ROS 2 only. For egg i
(the stand-in's reset with seed ``--seed`` + i):

1. sense: ``robot_world/2`` reads the stand-in's ``/robot_description``, ``/joint_states``
   and ``/tf`` (the arm where it stands, the egg where perception put it) into a scenario
   whose egg has the program's *belief*: friction uniform(0.2, 0.4) and breaking force
   normal(10, 1.5), the README's, and mass uniform(0.05, 0.07) kg (an egg's size class);
2. decide, on that snapshot, the gentlest grip force of ``--forces`` (1-5 N in 0.5 N) that
   lifts the egg whole (no slip, no break) in a top grasp and lift: an egg program squeezes
   no harder than it must. (b) nominal: the least force that does so in the belief's
   nominal world (friction 0.3, breaking force 10 N, 60 g); (c) belief:
   ``robust_parametrization/7`` over the same forces with ``prefer(-max_load(egg1))`` (the
   gentlest of the forces as probable as the best; its other defaults, seed i). Both
   decide on the node's default engine, or on ``--physics`` (e.g. ``'_{engine: mujoco}'``:
   the decisions on MuJoCo, the truth on the stand-in's PyBullet);
3. act: each choice executed on the same egg (the stand-in reset with seed i before each),
   through its ``~/execute_plan`` action;
4. record: an undesired outcome is a ``slip(egg1)`` or ``break(egg1)`` the stand-in saw.

The stand-in's truth is wider than the belief (``--friction``, ``--breaking-force``; by
default friction uniform(0.15, 0.45) against the belief's (0.2, 0.4), breaking force
uniform(7, 13), mass uniform(0.05, 0.07) kg, the stand-in's; none of it is told to the
program). Why the
choices part: the pads hold the egg through the lift iff 2 mu F >= m (g + a), so the least
force that holds the nominal egg slips every egg of less friction, while the belief's
choice holds down to about its lowest friction. Reported: the undesired
outcomes per policy with their Wilson 95 % interval; the exact McNemar test of (c) against
(b) on the paired eggs; per trial the seconds to sense (``robot_world/2`` inside its
query), to decide (the query's wall time less sensing) and to act (the action's).

The trials of the run in bench/RESULTS.md are in ``bench/data/robot_loop_trials.json``:
``--report bench/data/robot_loop_trials.json`` prints its figures again.
"""

from __future__ import annotations

import json
from pathlib import Path
import statistics
import tempfile
import time
from typing import Any

import harness
from closed_loop import mcnemar, wilson

BELIEF = ('friction: uniform(0.2, 0.4), breaking_force: normal(10, 1.5), '
          'mass: uniform(0.05, 0.07)')
SENSE = ('get_time(T0), robot_world(S, [entities([kitchen_env, entity(egg1, egg, '
         f'_{{frame: egg_1, {BELIEF}}})])]), get_time(T1), Sense is T1 - T0')
PLAN = ('[move_to(egg1, [0, 0, 0.10], [orientation(top), speed(0.5)]), '
        'move_to(egg1, [0, 0, 0], [speed(0.1)]), close_gripper({force}), wait(0.3), '
        'move_by([0, 0, 0.1]), wait(0.5)]')
OK = r'( \+ occurs(break(egg1), _, TL), \+ occurs(slip(egg1), _, TL) )'
STANDIN = '/standin_robot'
# Both policies want the gentlest grip that lifts the egg whole.
PREFER = 'prefer(-max_load(egg1))'


class StandIn:
    """A client of the stand-in robot's action and reset service."""

    def __init__(self, node: Any):
        from projection_interfaces.action import ExecutePlan
        from projection_interfaces.srv import ResetWorld
        from rclpy.action import ActionClient

        self._node, self._goal = node, ExecutePlan.Goal
        self._reset = node.create_client(ResetWorld, f'{STANDIN}/reset_world')
        self._request = ResetWorld.Request
        self._execute = ActionClient(node, ExecutePlan, f'{STANDIN}/execute_plan')
        if not (self._reset.wait_for_service(timeout_sec=60.0)
                and self._execute.wait_for_server(timeout_sec=60.0)):
            raise RuntimeError('the stand-in robot did not come up')

    def _wait(self, future: Any, timeout: float) -> Any:
        import rclpy

        rclpy.spin_until_future_complete(self._node, future, timeout_sec=timeout)
        if not future.done():
            raise RuntimeError('no answer from the stand-in robot')
        return future.result()

    def reset(self, seed: int) -> dict[str, Any]:
        answer = self._wait(self._reset.call_async(self._request(seed=seed)), 60.0)
        if not answer.ok:
            raise RuntimeError(f'reset {seed}: {answer.error}')
        return json.loads(answer.world_json)

    def execute(self, plan: str) -> tuple[list[str], float]:
        """The events the stand-in saw, and the seconds the action took."""
        handle = self._wait(self._execute.send_goal_async(self._goal(plan=plan)), 60.0)
        if not handle.accepted:
            raise RuntimeError('the stand-in refused the plan')
        result = self._wait(handle.get_result_async(), 300.0).result
        if not result.ok:
            raise RuntimeError(f'the plan failed on the stand-in: {result.error}')
        return list(result.events), result.duration


def nominal(c: Any, forces: list[float], physics: str = '') -> tuple[float, float, float]:
    """(b): the gentlest force that lifts the egg whole in the belief's nominal world, on a
    fresh snapshot; (force, sense s, decide s)."""
    start = time.perf_counter()
    solutions = c.all(f'{SENSE}, make_projection(S, plan({PLAN.format(force="F")}), '
                      f'[(F, force, {forces})], [{physics}], TL), ( {OK} -> Ok = 1 ; Ok = 0 )',
                      timeout=600.0, max_solutions=1000)
    wall = time.perf_counter() - start
    ok = [float(s['F']) for s in solutions if int(s['Ok'])]
    if not ok:
        raise RuntimeError('no force ok in the nominal world')
    sense = float(solutions[0]['Sense'])
    return min(ok), sense, wall - sense


def robust(c: Any, forces: list[float], seed: int, options: str = ''
           ) -> tuple[float, float, float, str]:
    """(c): robust_parametrization/7 on a fresh snapshot, the gentlest of the equals
    (``prefer(-max_load(egg1))``); (force, sense s, decide s, how)."""
    start = time.perf_counter()
    s = c.once(f'{SENSE}, robust_parametrization(S, plan({PLAN.format(force="F")}), '
               f'[(F, force, {forces})], [seed({seed}), {PREFER}{options}], TL, {OK}, Best), '
               'get_dict(p, Best, P), get_dict(low, Best, Low), get_dict(n, Best, N), '
               'get_dict(certified, Best, Cert), get_dict(projections, Best, Proj)',
               timeout=900.0)
    wall = time.perf_counter() - start
    sense = float(s['Sense'])
    how = (f'p {float(s["P"]):.3f} low {float(s["Low"]):.3f} of {s["N"]}, certified '
           f'{s["Cert"]}, {s["Proj"]} projections')
    return float(s['F']), sense, wall - sense, how


def undesired(events: list[str]) -> bool:
    return any(e.startswith(('slip(egg1)', 'break(egg1)')) for e in events)


def main() -> None:
    parser = harness.arguments(__doc__, seed=1)
    parser.add_argument('--eggs', type=int, default=100)
    parser.add_argument('--forces', default='1,1.5,2,2.5,3,3.5,4,4.5,5',
                        help='grip forces [N] the policies choose among')
    parser.add_argument('--friction', default='0.15,0.45', help="the truth's range")
    parser.add_argument('--breaking-force', default='7,13', help="the truth's range")
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--options', default='',
                        help="more options of (c)'s robust_parametrization/7, e.g. 'risk(0.1)'")
    parser.add_argument('--physics', default='',
                        help="the decisions' physics(Dict), e.g. '_{engine: mujoco}' (the "
                             "stand-in's world stays PyBullet's)")
    parser.add_argument('--trials', type=Path,
                        help="where to keep the trials as they are made (default: the run's "
                             "temporary directory's trials.json)")
    parser.add_argument('--report', metavar='TRIALS_JSON', nargs='+',
                        help="only report the trials of earlier runs' trials.json, together "
                             "(runs of disjoint seeds, e.g. two halves run side by side)")
    args = parser.parse_args()
    if args.report:
        report([t for f in args.report for t in json.loads(Path(f).read_text())])
        return
    forces = [float(f) for f in args.forces.split(',')]
    harness.ros_domain(200)
    import rclpy
    from projection_server.client.launcher import NodeProcess
    rclpy.init()
    tmp = Path(tempfile.mkdtemp(prefix='bench_robot_loop_'))
    kept = args.trials or tmp / 'trials.json'
    print(f'settings: {args.eggs} eggs from seed {args.seed}; belief {BELIEF}; truth '
          f'friction U({args.friction}), breaking force U({args.breaking_force}); forces '
          f'{forces}; (c) options {args.options or "the defaults"}; decisions\' physics '
          f'{args.physics or "the defaults"}; {args.workers} workers; '
          f'{harness.machine()}', flush=True)
    standin_cmd = ['projection_standin_robot', '--ros-args',
                   '-p', f'friction_range:=[{args.friction}]',
                   '-p', f'breaking_force_range:=[{args.breaking_force}]']
    node = rclpy.create_node('bench_robot_loop')
    trials: list[dict[str, Any]] = []
    try:
        with NodeProcess(standin_cmd, tmp / 'standin.log') as _, \
                harness.start_node({'bag_dir': str(tmp / 'bags'),
                                    'projection_workers': args.workers},
                                   tmp / 'node.log') as _, harness.client() as c:
            robot = StandIn(node)
            print(f'\n{"egg":>4} {"friction":>8} {"break N":>7} | {"(b) N":>5} {"out":>4} '
                  f'{"sense":>6} {"decide":>7} {"act":>5} | {"(c) N":>5} {"out":>4} '
                  f'{"sense":>6} {"decide":>7} {"act":>5} | (c)', flush=True)
            for i in range(args.eggs):
                seed = args.seed + i
                truth = robot.reset(seed)['object']['properties']
                physics = f'physics({args.physics})' if args.physics else ''
                fb, sense_b, decide_b = nominal(c, forces, physics)
                options = ''.join(f', {o}' for o in (args.options, physics) if o)
                fc, sense_c, decide_c, how = robust(c, forces, seed, options)
                row = {'seed': seed, 'truth': truth}
                for name, force, sense, decide in (('b', fb, sense_b, decide_b),
                                                   ('c', fc, sense_c, decide_c)):
                    robot.reset(seed)   # the same egg for both, where it was
                    events, act = robot.execute(PLAN.format(force=force))
                    row[name] = {'force': force, 'undesired': undesired(events),
                                 'events': events, 'sense': sense, 'decide': decide,
                                 'act': act}
                row['c']['choice'] = how
                trials.append(row)
                # Kept as it goes: a run stopped early still has every trial made.
                kept.write_text(json.dumps(trials, indent=1))
                b, cc = row['b'], row['c']
                print(f'{seed:4d} {truth["friction"]:8.3f} {truth["breaking_force"]:7.2f} | '
                      f'{b["force"]:5.1f} {"BAD" if b["undesired"] else "ok":>4} '
                      f'{b["sense"]:6.3f} {b["decide"]:7.2f} {b["act"]:5.2f} | '
                      f'{cc["force"]:5.1f} {"BAD" if cc["undesired"] else "ok":>4} '
                      f'{cc["sense"]:6.3f} {cc["decide"]:7.2f} {cc["act"]:5.2f} | {how}',
                      flush=True)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    report(trials)
    print(f'\ntrials: {kept}')


def report(trials: list[dict[str, Any]]) -> None:
    n = len(trials)
    if not n:
        return
    print(f'\n{"policy":<12} {"undesired":>9} {"Wilson 95 %":>16}   sense s  decide s  act s '
          '(medians)')
    for name, label in (('b', '(b) nominal'), ('c', '(c) belief')):
        k = sum(t[name]['undesired'] for t in trials)
        low, high = wilson(k, n)
        med = {key: statistics.median(t[name][key] for t in trials)
               for key in ('sense', 'decide', 'act')}
        print(f'{label:<12} {k:4d}/{n:<4d} [{low:.3f}, {high:.3f}]   {med["sense"]:7.3f} '
              f'{med["decide"]:9.2f} {med["act"]:6.2f}')
    only_b = sum(t['b']['undesired'] and not t['c']['undesired'] for t in trials)
    only_c = sum(t['c']['undesired'] and not t['b']['undesired'] for t in trials)
    print(f'\nexact McNemar, (c) against (b): {only_b} eggs lost by (b) alone, {only_c} by '
          f'(c) alone, p = {mcnemar(only_b, only_c):.2g}')


if __name__ == '__main__':
    main()
