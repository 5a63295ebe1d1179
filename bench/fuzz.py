"""The query service's fuzz test with many more examples than CI runs.

    tools/with_env.sh python bench/fuzz.py [--examples 2000]

Runs test/service/test_service_ros.py's property test (random text, grammar-shaped goals,
deep terms, random request fields) against a live node; prints pytest's summary and the
examples' time statistics. Every answer must arrive within its limit and the node must
answer a plain query after each.
"""

from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

import harness


def main() -> int:
    parser = harness.arguments(__doc__)
    parser.add_argument('--examples', type=int, default=2000)
    args = parser.parse_args()
    root = Path(__file__).resolve().parent.parent
    env = {**os.environ, 'PROJECTION_SERVER_FUZZ_EXAMPLES': str(args.examples)}
    print(f'fuzzing the live node with {args.examples} random requests', flush=True)
    return subprocess.call(
        [str(root / 'tools' / 'run_tests.sh'), 'test/service/test_service_ros.py',
         '-k', 'fuzzed', '-p', 'no:warnings', '--hypothesis-show-statistics'],
        cwd=root, env=env)


if __name__ == '__main__':
    sys.exit(main())
