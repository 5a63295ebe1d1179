#!/usr/bin/env bash
# The whole test suite (called by `make test` inside tools/with_env.sh).
# Each run gets its own ROS domains and loopback-only discovery, so that test runs
# on one machine never see each other's nodes.
# The suite runs in TEST_PROCESSES processes (pytest-xdist, default 2: most of its time is
# one simulation worker's, so a second process uses the second core), a file's tests in
# one of them; each process has the domain ROS_DOMAIN_ID plus its index (test/conftest.py).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
processes=${TEST_PROCESSES:-2}
# An even domain, the next one for the second process.
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-$(( 10 + ($$ % 45) * 2 ))}
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export PYTHONDONTWRITEBYTECODE=1
# --import-mode=importlib: test the installed package, not the source tree.
paths=(test)
for a in "$@"; do [ -e "${a%%::*}" ] && paths=(); done   # explicit test paths given
parallel=()
[ "$processes" -gt 1 ] && parallel=(-n "$processes" --dist loadfile)
exec pytest -p no:cacheprovider --import-mode=importlib -q "${parallel[@]}" "$@" "${paths[@]}"
