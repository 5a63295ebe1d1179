# Pinned versions and checksums of what tools/bootstrap.sh builds; sourced by it.
CACHE_DIR=${PROJECTION_SERVER_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/projection_server}
SWIPL_VERSION=9.2.9
SWIPL_SUITE=trixie
SWIPL_SHA256=6d6f2dd6e4558bccb7c87cc7a5cbcf582503384a5fa890efba0ae91a0aaf2258
JANUS_SWI_VERSION=1.5.3
