"""prolog_query: send a query to a running projection_server and print a table.

    prolog_query 'member(X, [a, f(Y), "s", 1.5])'
    prolog_query --mode once --timeout 10 'between(1, 3, X)'
"""

from __future__ import annotations

import argparse
import sys

import rclpy

from projection_server.bindings import to_prolog_text
from projection_server.client import PrologClient, PrologClientError, PrologQueryError

__all__ = ['format_table', 'main']


def format_table(solutions: list[dict]) -> str:
    """Solutions as a text table, one row per solution, one column per variable."""
    if not solutions:
        return 'false.'
    names = list(solutions[0])
    if not names:
        return 'true.' if len(solutions) == 1 else f'true ({len(solutions)} times).'
    rows = [[to_prolog_text(s[n]) for n in names] for s in solutions]
    widths = [max(len(n), *(len(r[i]) for r in rows)) for i, n in enumerate(names)]
    line = lambda cells: ' | '.join(c.ljust(w) for c, w in zip(cells, widths)).rstrip()  # noqa: E731
    out = [line(names), '-+-'.join('-' * w for w in widths)]
    out += [line(r) for r in rows]
    return '\n'.join(out)


def main(argv: list[str] | None = None) -> int:
    argv = rclpy.utilities.remove_ros_args(sys.argv if argv is None else ['prolog_query', *argv])
    parser = argparse.ArgumentParser(prog='prolog_query', description=__doc__.splitlines()[0])
    parser.add_argument('query', help='Prolog goal, e.g. "member(X, [a, b])"')
    parser.add_argument('--mode', choices=('all', 'once', 'incremental'), default='all')
    parser.add_argument('--timeout', type=float, default=0.0,
                        help='seconds per solution (0: server default)')
    parser.add_argument('--max-solutions', type=int, default=0)
    parser.add_argument('--server', default='/projection_server')
    parser.add_argument('--wait', type=float, default=10.0,
                        help='seconds to wait for the server to appear')
    args = parser.parse_args(argv[1:])

    rclpy.init()
    client = None
    try:
        client = PrologClient(args.server, service_timeout=args.wait, name='prolog_query')
        if args.mode == 'once':
            s = client.once(args.query, timeout=args.timeout)
            solutions = [] if s is None else [s]
        elif args.mode == 'all':
            solutions = client.all(args.query, timeout=args.timeout,
                                   max_solutions=args.max_solutions)
        else:
            with client.query(args.query, timeout=args.timeout) as q:
                solutions = []
                for s in q:
                    solutions.append(s)
                    if args.max_solutions and len(solutions) >= args.max_solutions:
                        break
        print(format_table(solutions))
        return 0
    except PrologQueryError as exc:
        print(f'error ({exc.kind}): {exc.message}', file=sys.stderr)
        return 1
    except PrologClientError as exc:
        print(f'prolog_query: {exc}', file=sys.stderr)
        return 2
    finally:
        if client is not None:
            client.close()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
