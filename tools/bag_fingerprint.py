"""Fingerprints of the bags and timelines of a grasp, a pour tree and a pancake turn.

    tools/with_env.sh python tools/bag_fingerprint.py [--out FILE]

For checking that a change of the code's structure leaves what a projection logs as it
was: every message of each bag (raw CDR bytes, in order, with topic and time) goes into one
digest per bag, and each timeline into another. The two fields of ``/projection/info`` that
name the code itself (``job_key``, ``code_version``) are left out, and so are the bag's
path and key in the timeline's meta: everything else must be the same byte for byte. Run it
before and after a change and compare the printed digests (``--out`` writes them as JSON).
"""

from __future__ import annotations

import argparse
import hashlib
import json
from pathlib import Path
import sys
import tempfile

from rosbags.highlevel import AnyReader

CODE_FIELDS = ('job_key', 'code_version')
META_FIELDS = ('bag', 'job_key', 'code_version')
GRASP = ('grasping', 'grasp_object', {'force': 5.0, 'position': 0.02})
# MuJoCo's grasps: held, slipped, broken (each outcome's code runs)
MUJOCO_GRASPS = {f'mujoco_{label}': ('grasping', 'grasp_object', params, {'engine': 'mujoco'})
                 for label, params in (('held', {'force': 5.0, 'position': 0.0}),
                                       ('slip', {'force': 1.0, 'position': 0.02}),
                                       ('break', {'force': 11.0, 'position': -0.02}))}
TURN = ('turning', 'turn_pancake', {'angle': 0.5})
POUR_TREE = ('pouring', 'pour', [{'angle': a, 'time': 0.5, 'position': 0.0}
                                 for a in (1.84, 2.14)])


def scenario(name: str) -> dict:
    """The knowledge base's scenario description, as simulate/5 passes it to Python."""
    import janus_swi as janus

    return janus.query_once('scenario:scenario_description(S, D)', {'S': name})['D']


def bag_digest(path: Path) -> str:
    """One digest of every message of the bag at ``path``, the code's own fields left out
    of ``/projection/info``."""
    digest = hashlib.sha256()
    with AnyReader([path]) as reader:
        for connection, t_ns, raw in reader.messages():
            digest.update(f'{connection.topic}@{t_ns}:'.encode())
            if connection.topic == '/projection/info':
                message = reader.deserialize(raw, connection.msgtype)
                fields = {k: getattr(message, k) for k in message.__dataclass_fields__
                          if k not in CODE_FIELDS and k != 'header'}
                digest.update(json.dumps(fields, sort_keys=True, default=str).encode())
            else:
                digest.update(raw)
    return digest.hexdigest()


def timeline_digest(timeline: dict) -> str:
    meta = {k: v for k, v in timeline['meta'].items() if k not in META_FIELDS}
    text = json.dumps({**timeline, 'meta': meta}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--out', type=Path, help='write the digests as JSON here too')
    args = parser.parse_args()

    import janus_swi as janus

    from projection_server.service import prolog_bridge
    from projection_server.simulation import Job, load_settings
    from projection_server.simulation.branching import run_tree
    from projection_server.simulation.runner import Simulator
    from projection_server.workers.run import project, translate_bag

    prolog_bridge.load()
    janus.query_once('knowledge_base:knowledge_base_load')
    settings = load_settings()
    digests: dict[str, dict[str, str]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        simulator = Simulator()
        try:
            singles = {'grasp': (*GRASP, None), 'turn': (*TURN, None), **MUJOCO_GRASPS}
            for label, (name, program, params, physics) in singles.items():
                bag = Path(tmp) / label
                timeline = project(simulator, Job.checked(scenario(name), program, params,
                                                          physics), settings, bag)
                if label.startswith('mujoco_'):
                    events = sorted({e[0] if isinstance(e, list) else str(e)
                                     for e in timeline.get('events', [])})
                    print(f'{label}: events {events}', file=sys.stderr)
                digests[label] = {'bag': bag_digest(bag), 'timeline': timeline_digest(timeline)}
            name, program, family = POUR_TREE
            leaves = [(Job.checked(scenario(name), program, p), Path(tmp) / f'pour{i}')
                      for i, p in enumerate(family)]
            if not run_tree(simulator.client, leaves, settings, lambda *_: None):
                print('the pour tree did not complete', file=sys.stderr)
                return 1
            for i, (_, bag) in enumerate(leaves):
                digests[f'pour_tree_{i}'] = {'bag': bag_digest(bag),
                                             'timeline': timeline_digest(translate_bag(bag))}
        finally:
            simulator.close()
    for label, values in digests.items():
        print(f'{label:12} bag {values["bag"][:16]}  timeline {values["timeline"][:16]}')
    if args.out is not None:
        args.out.write_text(json.dumps(digests, indent=1, sort_keys=True) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
