"""``python -m projection_server.reproduce [--out DIR] [--quick] [--server NAME]``.

Runs the paper's experiments through the query service at ``--server``; if no node answers
there, starts one (bags in ``DIR/bags``) and stops it at the end. Prints each table beside
the paper's and writes ``DIR/report.md``.
"""

from __future__ import annotations

import argparse
import contextlib
from pathlib import Path
import shutil
import sys
from typing import Iterator, TYPE_CHECKING

from projection_server.client.launcher import LaunchError, node_command, NodeProcess

if TYPE_CHECKING:
    from collections.abc import Sequence

__all__ = ['main', 'ReproduceError']


class ReproduceError(Exception):
    """The reproduction could not be set up (no node, no projection_server command)."""


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog='python -m projection_server.reproduce',
        description="Reproduce the paper's experiments (section IV) through the live service "
                    'and write a report.')
    parser.add_argument('--out', type=Path, default=Path('reproduction'),
                        help='directory for report.md, PNG files and (own node) bags')
    parser.add_argument('--quick', action='store_true',
                        help='a reduced grid (e.g. forces 1, 5, 11 x positions 0.0, 0.02)')
    parser.add_argument('--server', default='/projection_server',
                        help='the node whose services to use (default: %(default)s)')
    parser.add_argument('--only', action='append', metavar='TABLE',
                        help='run only these experiments, repeated or comma-separated (table1, '
                             'table2, table3, table3_poured, table3_cooked)')
    parser.add_argument('--timeout', type=float, default=900.0,
                        help='seconds one solution (projection) may take')
    parser.add_argument('--no-frames', action='store_true', help='skip rendering key frames')
    parser.add_argument('--sequential', action='store_true',
                        help="send one experiment's query at a time (default: all at once, "
                             'their tables printed in order)')
    parser.add_argument('--reference', action='store_true',
                        help='run each experiment again at a 4x finer time step (4x the '
                             'solver iterations) and report the agreement with it')
    args = parser.parse_args(argv)

    import rclpy

    from projection_server.client import PrologClient, PrologClientError
    from projection_server.reproduce.experiments import EXPERIMENTS
    from projection_server.reproduce.run import reproduce

    only = {key for item in args.only or () for key in item.split(',') if key}
    unknown = only - {e.key for e in EXPERIMENTS}
    if unknown:
        parser.error(f'--only: no experiment {", ".join(sorted(unknown))} (there are '
                     f'{", ".join(e.key for e in EXPERIMENTS)})')
    experiments = [e for e in EXPERIMENTS if not only or e.key in only]
    args.out.mkdir(parents=True, exist_ok=True)
    rclpy.init()
    try:
        client = PrologClient(args.server)
        own = False
        try:
            with _server(client, args.server, args.out / 'bags', args.timeout) as own:
                reproduce(client, args.out, quick=args.quick, experiments=experiments,
                          timeout=args.timeout, frames=not args.no_frames,
                          reference=args.reference, concurrent=not args.sequential,
                          say=_say)
        finally:
            # Our own node has finished our queries and is gone: asking it again would
            # wait out the client's service timeout (10 s) for nothing.
            client.close(finish=not own)
    except (ReproduceError, LaunchError, PrologClientError) as exc:
        print(f'reproduce: {exc}', file=sys.stderr)
        return 1
    finally:
        rclpy.try_shutdown()
    return 0


def _say(line: str) -> None:
    print(line, flush=True)


@contextlib.contextmanager
def _server(client, server: str, bag_dir: Path, timeout: float) -> Iterator[bool]:
    """Use the node at ``server`` if it answers, else run our own for the block's duration
    (the block gets True: the node is ours, and gone after the block)."""
    from projection_server.client import PrologClientError

    if client.wait_for_server(3.0):
        _say(f'using the running node {server}')
        yield False
        return
    command = shutil.which('projection_server')
    if command is None:
        message = (f'no node answers at {server} and there is no projection_server command '
                   'to start one (run inside tools/with_env.sh)')
        raise ReproduceError(message)
    bag_dir.mkdir(parents=True, exist_ok=True)
    log_path = bag_dir.parent / 'node.log'
    cmd = node_command(server, {'bag_dir': bag_dir, 'projection_workers': 2,
                                'default_timeout': timeout}, executable=command)
    _say(f'starting a node at {server} (log: {log_path})')
    with NodeProcess(cmd, log_path, stop_timeout=20.0) as proc:
        proc.wait_for_service(f'{server}/query')
        try:
            yield True
        finally:
            if proc.running:
                # Release our queries before the node shuts down.
                with contextlib.suppress(PrologClientError):
                    client.finish_all()


if __name__ == '__main__':
    sys.exit(main())
