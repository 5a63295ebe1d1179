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
# tf2_msgs is built only where none is installed (TF2_PREFIX empty otherwise).
prefixes="$INSTALL_PREFIX:$IFC_PREFIX${TF2_PREFIX:+:$TF2_PREFIX}"
libs="$IFC_PREFIX/lib${TF2_PREFIX:+:$TF2_PREFIX/lib}"
pys="$INSTALL_PREFIX/$site:$IFC_PREFIX/$site${TF2_PREFIX:+:$TF2_PREFIX/$site}"
export PYTHONPATH="$pys${PYTHONPATH:+:$PYTHONPATH}"
export LD_LIBRARY_PATH="$libs:$SWIPL_PREFIX/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
# A sourced ROS workspace keeps its prefixes, after this package's (packages resolve first
# here, then in the user's workspaces, then in the venv's wheels).
export AMENT_PREFIX_PATH="$prefixes${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}:$VENV"
export PROJECTION_SERVER_ROOT="$root"
exec "$@"
