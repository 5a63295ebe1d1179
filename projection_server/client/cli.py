"""prolog_query: send a query to a running projection_server and print the answer.

    prolog_query 'member(X, [a, f(Y), "s", 1.5])'
    prolog_query --mode once --timeout 10 'between(1, 3, X)'
    prolog_query --mode incremental 'between(1, inf, X)'      # prints as solutions come
    prolog_query --progress 'make_projection(grasping, grasp_object, ...)'
"""

from __future__ import annotations

import argparse
import signal
import sys
from typing import Any, TYPE_CHECKING

import rclpy
from rclpy.signals import SignalHandlerOptions

from projection_server.client.bindings import to_prolog_text
from projection_server.client.prolog_client import (PrologClient, PrologClientError,
                                                    PrologDeadlineError, PrologQueryError)

if TYPE_CHECKING:
    from collections.abc import Sequence

__all__ = [
    'EXIT_DEADLINE',
    'EXIT_INTERRUPTED',
    'EXIT_QUERY_ERROR',
    'EXIT_TERMINATED',
    'EXIT_UNAVAILABLE',
    'format_solution',
    'format_table',
    'main',
]

EXIT_QUERY_ERROR = 1   # the server answered with an error (argparse uses 2 for usage)
EXIT_UNAVAILABLE = 3   # no server, or it stopped answering
EXIT_DEADLINE = 4      # --deadline passed; the query was cancelled on the server
EXIT_INTERRUPTED = 130  # Ctrl-C; the query was cancelled on the server
EXIT_TERMINATED = 143   # SIGTERM; likewise

EPILOG = f"""exit status: 0 answered (also with no solution), {EXIT_QUERY_ERROR} query error,
{EXIT_UNAVAILABLE} server not reachable or stopped answering, {EXIT_DEADLINE} --deadline passed,
{EXIT_INTERRUPTED} interrupted (Ctrl-C), {EXIT_TERMINATED} terminated (SIGTERM); in the last
three cases the query is cancelled on the server."""


class Terminated(KeyboardInterrupt):
    """SIGTERM, handled like Ctrl-C: cancel the query on the server, then exit."""


def format_table(solutions: list[dict]) -> str:
    """Solutions as a text table, one row per solution, one column per variable."""
    if not solutions:
        return 'false.'
    names = list(solutions[0])
    if not names:
        return 'true.' if len(solutions) == 1 else f'true ({len(solutions)} times).'
    rows = [[to_prolog_text(s[n]) for n in names] for s in solutions]
    widths = [max(len(n), *(len(r[i]) for r in rows)) for i, n in enumerate(names)]

    def line(cells: list[str]) -> str:
        return ' | '.join(c.ljust(w) for c, w in zip(cells, widths)).rstrip()

    out = [line(names), '-+-'.join('-' * w for w in widths)]
    out += [line(r) for r in rows]
    return '\n'.join(out)


def format_solution(solution: dict) -> str:
    """One solution as the Prolog top level prints it: ``X = a, Y = f(b)``."""
    return ', '.join(f'{n} = {to_prolog_text(v)}' for n, v in solution.items()) or 'true'


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='prolog_query', description=__doc__.splitlines()[0],
                                     epilog=EPILOG)
    parser.add_argument('query', help='Prolog goal, e.g. "member(X, [a, b])"')
    parser.add_argument('--mode', choices=('all', 'once', 'incremental'), default='all')
    parser.add_argument('--timeout', type=float, default=0.0,
                        help='seconds the server may take per solution (0: its default)')
    parser.add_argument('--deadline', type=float, default=None,
                        help='seconds this command waits in all before it cancels the query')
    parser.add_argument('--max-solutions', type=int, default=0,
                        help="cap on solutions (0: the server's max_solutions)")
    parser.add_argument('--progress', action='store_true',
                        help='run through the ~/project action with a progress bar of its '
                             'projections (modes all and once)')
    parser.add_argument('--server', default='/projection_server')
    parser.add_argument('--wait', type=float, default=10.0,
                        help='seconds to wait for the server to appear, and for it to '
                             'answer a ping while a query runs')
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    argv = rclpy.utilities.remove_ros_args(sys.argv if argv is None else ['prolog_query', *argv])
    args = _parser().parse_args(argv[1:])
    if args.progress and args.mode == 'incremental':
        _parser().error('--progress works with --mode all or once')
    # Our own handlers: Ctrl-C and SIGTERM cancel the query before rclpy shuts down.
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    client = None
    server_gone = False
    try:
        client = PrologClient(args.server, service_timeout=args.wait, name='prolog_query')
        if args.mode == 'incremental':
            return _incremental(client, args)
        if args.progress:
            solutions, truncated = _with_progress(client, args)
        elif args.mode == 'once':
            s = client.once(args.query, timeout=args.timeout, deadline=args.deadline)
            solutions, truncated = ([] if s is None else [s]), False
        else:
            solutions = client.all(args.query, timeout=args.timeout,
                                   max_solutions=args.max_solutions, deadline=args.deadline)
            truncated = client.truncated
        print(format_table(solutions))
        if truncated:
            _say(f'more solutions exist: stopped at the cap of {len(solutions)} '
                 '(--max-solutions, or the server parameter max_solutions)')
        return 0
    except PrologQueryError as exc:
        _say(f'error ({exc.kind}): {exc.message}', prefix=False)
        return EXIT_QUERY_ERROR
    except PrologDeadlineError as exc:
        _say(f'{exc}')
        return EXIT_DEADLINE
    except PrologClientError as exc:
        server_gone = True
        _say(f'{exc}')
        return EXIT_UNAVAILABLE
    except Terminated:
        _say('terminated; the query was cancelled on the server')
        return EXIT_TERMINATED
    except KeyboardInterrupt:
        _say('interrupted; the query was cancelled on the server')
        return EXIT_INTERRUPTED
    finally:
        signal.signal(signal.SIGTERM, previous)
        if client is not None:
            try:
                client.close(finish=not server_gone)
            except KeyboardInterrupt:
                pass
        rclpy.try_shutdown()


def _incremental(client: PrologClient, args: argparse.Namespace) -> int:
    count = 0
    with client.query(args.query, timeout=args.timeout) as q:
        for s in q:
            print(format_solution(s), flush=True)
            count += 1
            if args.max_solutions and count >= args.max_solutions:
                _say(f'stopped after --max-solutions {args.max_solutions}; '
                     'the query may have more')
                return 0
    if count == 0:
        print('false.')
    return 0


def _with_progress(client: PrologClient, args: argparse.Namespace) -> tuple[list, bool]:
    from tqdm import tqdm

    bar = tqdm(unit='projection', file=sys.stderr, dynamic_ncols=True, leave=True)

    def update(fb: Any) -> None:
        if bar.total != fb.total:
            bar.reset(total=fb.total)
        bar.n = fb.index
        bar.set_description(fb.program, refresh=False)
        bar.set_postfix_str(f'{fb.parameters} {fb.outcome or "no events"}', refresh=False)
        bar.refresh()

    try:
        task = client.project(args.query, once=args.mode == 'once', timeout=args.timeout,
                              max_solutions=args.max_solutions, feedback_callback=update)
        solutions = task.result(deadline=args.deadline)
        return solutions, task.wait().truncated
    finally:
        bar.close()


def _say(message: str, prefix: bool = True) -> None:
    print(f'prolog_query: {message}' if prefix else message, file=sys.stderr, flush=True)


def _raise_terminated(signum: int, frame: Any) -> None:
    raise Terminated()


if __name__ == '__main__':
    sys.exit(main())
