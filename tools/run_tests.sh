#!/usr/bin/env bash
# The whole test suite (called by `make test` inside tools/with_env.sh).
# Each run gets its own ROS domain and loopback-only discovery, so that test runs
# on one machine never see each other's nodes.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-$(( 10 + $$ % 90 ))}
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export PYTHONDONTWRITEBYTECODE=1
# --import-mode=importlib: test the installed package, not the source tree.
paths=(test)
for a in "$@"; do [ -e "${a%%::*}" ] && paths=(); done   # explicit test paths given
exec pytest -p no:cacheprovider --import-mode=importlib -q "$@" "${paths[@]}"
