#!/usr/bin/env bash
# Runs a command in the environment that tools/bootstrap.sh prepared:
#   tools/with_env.sh projection_server --ros-args -p max_engines:=4
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
if [ ! -f "$root/.env.paths" ]; then
  echo "with_env: run tools/bootstrap.sh first (or use the Makefile)" >&2; exit 2
fi
# shellcheck source=/dev/null
source "$root/.env.paths"
site=lib/python3.11/site-packages
export SWI_HOME_DIR="$SWIPL_PREFIX/lib/swipl"
export PATH="$INSTALL_PREFIX/bin:$INSTALL_PREFIX/lib/projection_server:$VENV/bin:$SWIPL_PREFIX/bin:$PATH"
export PYTHONPATH="$INSTALL_PREFIX/$site:$IFC_PREFIX/$site${PYTHONPATH:+:$PYTHONPATH}"
export LD_LIBRARY_PATH="$IFC_PREFIX/lib:$SWIPL_PREFIX/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export AMENT_PREFIX_PATH="$INSTALL_PREFIX:$IFC_PREFIX:$VENV"
export PROJECTION_SERVER_ROOT="$root"
exec "$@"
