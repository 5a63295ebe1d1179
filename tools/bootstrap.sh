#!/usr/bin/env bash
# Brings this machine and checkout up to date for projection_server, idempotently.
#
#   tools/bootstrap.sh            # set everything up, print nothing when warm
#
# Expensive artefacts live outside the checkout, keyed by content, so that a fresh
# clone on a machine that built them once reuses them:
#   $PROJECTION_SERVER_CACHE (default: ${XDG_CACHE_HOME:-~/.cache}/projection_server)
#     swipl-<version>-<sha8>/     SWI-Prolog built from Debian's source tarball
#     venv-<key>/                 Python venv: ROS 2 Jazzy wheels, pybullet, rosbags, janus-swi
#     interfaces-<key>/           the msg_defs interface package, built with rosidl
#     tf2_msgs-<key>/             msg_defs/tf2_msgs, where no tf2_msgs can be imported
# Per checkout: install/ holds this package (ament layout), keyed by its sources.
# tools/env.sh prints the environment that ties these together.
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(dirname "$here")
# shellcheck source=tools/versions.sh
source "$here/versions.sh"

log() { printf '[bootstrap] %s\n' "$*" >&2; }
sha() { sha256sum | cut -c1-16; }
# pip warns about this machine's file-based extra indexes that lack a package; noise.
pip_q() { "$venv/bin/pip" install -q "$@" 2> >(grep -v 'is ignored: it is neither' >&2); }

mkdir -p "$CACHE_DIR"
exec 9>"$CACHE_DIR/.lock"
flock 9   # one bootstrap at a time per cache (CI and a developer may share a machine)

sudo_if_needed() { if [ "$(id -u)" = 0 ]; then "$@"; else sudo "$@"; fi; }

# --- 1. Debian packages --------------------------------------------------------------
apt_packages=(cmake ninja-build gcc g++ make pkg-config libgmp-dev libssl-dev zlib1g-dev
  libreadline-dev libedit-dev libyaml-dev libpcre2-dev libarchive-dev uuid-dev
  libtinyxml2-dev libffi-dev)
missing=()
for p in "${apt_packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  log "installing Debian packages: ${missing[*]}"
  sudo_if_needed apt-get update -qq
  sudo_if_needed env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" >/dev/null
fi

# --- 2. SWI-Prolog from Debian's source tarball -----------------------------------------
fetch_swipl_tarball() {
  local dest=$1 tmp
  tmp=$(mktemp -d)
  # A deb-src entry for the suite that carries the version, derived from this machine's
  # own Debian sources (same mirror, same keyring), in a private sources dir: no host
  # name is written here and /etc/apt stays as it was.
  mkdir -p "$tmp/parts"
  awk -v suite="$SWIPL_SUITE" '
    /^URIs:/ && !done { uris=$0 }
    /^Signed-By:/ && !done { key=$0 }
    /^Suites:/ && $0 ~ /bookworm( |$)/ { main=1 }
    /^$/ { if (main && uris != "") done=1 }
    END { print "Types: deb-src"; print uris; print "Suites: " suite;
          print "Components: main"; if (key != "") print key }
  ' /etc/apt/sources.list.d/debian.sources >"$tmp/parts/swipl-src.sources"
  local apt_opts=(-o Dir::Etc::sourcelist=- -o "Dir::Etc::sourceparts=$tmp/parts"
                  -o APT::Get::List-Cleanup=0)
  log "fetching swi-prolog $SWIPL_VERSION source from Debian ($SWIPL_SUITE)"
  sudo_if_needed apt-get update -qq "${apt_opts[@]}" || true
  # apt reports errors for the .dsc/.debian.tar.xz it cannot get; the checksum below
  # is what decides whether the tarball is good.
  (cd "$tmp" && apt-get source --download-only -qq "${apt_opts[@]}" swi-prolog \
     >/dev/null 2>&1 || true)
  local tarball="$tmp/swi-prolog_${SWIPL_VERSION}+dfsg.orig.tar.gz"
  if [ ! -f "$tarball" ] || [ "$(sha256sum "$tarball" | cut -d' ' -f1)" != "$SWIPL_SHA256" ]; then
    log "swi-prolog source tarball missing or its checksum is wrong"; rm -rf "$tmp"; return 1
  fi
  mv "$tarball" "$dest"; rm -rf "$tmp"
}

swipl_prefix="$CACHE_DIR/swipl-$SWIPL_VERSION-${SWIPL_SHA256:0:8}"
if [ ! -f "$swipl_prefix/.complete" ]; then
  tarball="$CACHE_DIR/swi-prolog_${SWIPL_VERSION}+dfsg.orig.tar.gz"
  if [ ! -f "$tarball" ] || [ "$(sha256sum "$tarball" | cut -d' ' -f1)" != "$SWIPL_SHA256" ]; then
    fetch_swipl_tarball "$tarball"
  fi
  build=$(mktemp -d)
  log "building SWI-Prolog $SWIPL_VERSION (a few minutes, once per machine)"
  tar -xzf "$tarball" -C "$build"
  srcdir=$(find "$build" -maxdepth 1 -mindepth 1 -type d | head -1)
  rm -rf "$swipl_prefix"
  (cd "$srcdir" && mkdir -p build && cd build &&
   cmake -G Ninja -DCMAKE_INSTALL_PREFIX="$swipl_prefix" -DSWIPL_PACKAGES_X=OFF \
     -DSWIPL_PACKAGES_JAVA=OFF -DSWIPL_PACKAGES_ODBC=OFF -DBUILD_TESTING=OFF \
     -DINSTALL_DOCUMENTATION=OFF -DCMAKE_BUILD_TYPE=Release .. >"$build/cmake.log" 2>&1 &&
   ninja >"$build/ninja.log" 2>&1 && ninja install >"$build/install.log" 2>&1) || {
    log "SWI-Prolog build failed; last lines of its logs:"; tail -n 30 "$build"/*.log >&2; exit 1; }
  touch "$swipl_prefix/.complete"
  rm -rf "$build"
fi

# --- 3. Python venv --------------------------------------------------------------------
py=${PYTHON:-python3}
py_id=$("$py" -c 'import sys; print(sys.version)' | sha)
venv_key=$( (cat "$here/requirements.txt" "$here/versions.sh" "$here/bootstrap.sh"; echo "$py_id") | sha)
venv="$CACHE_DIR/venv-$venv_key"
if [ ! -f "$venv/.complete" ]; then
  log "creating Python venv $venv"
  rm -rf "$venv"
  "$py" -m venv "$venv"
  pip_q --upgrade pip setuptools wheel
  pip_q -r "$here/requirements.txt"
  # janus-swi is compiled against the SWI-Prolog built above, never a prebuilt wheel.
  PATH="$swipl_prefix/bin:$PATH" pip_q --no-binary janus-swi "janus-swi==$JANUS_SWI_VERSION"
  # The wheels' generator CMake exports name the wheel builder's include directories;
  # point them at this interpreter's (idempotent: matches only the builder's paths).
  inc=$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
  npinc=$("$venv/bin/python" -c 'import numpy; print(numpy.get_include())')
  grep -rl --include='*.cmake' -e '/opt/python/cp311-cp311' "$venv/share" 2>/dev/null |
  while read -r f; do
    sed -i -E "s#/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/(_core|core)/include#$npinc#g; s#/opt/python/cp311-cp311/include/python3.11#$inc#g" "$f"
  done
  touch "$venv/.complete"
fi

# --- 4. Interface packages (msg_defs, and tf2_msgs where none is installed) ---------------
# build_interfaces NAME SRC PREFIX: an ament_cmake interface package built with rosidl.
build_interfaces() {
  local name=$1 src=$2 prefix=$3 build
  log "building interface package $name"
  rm -rf "$prefix"
  build=$(mktemp -d)
  (cd "$build" && PATH="$venv/bin:$PATH" AMENT_PREFIX_PATH="$venv" \
     cmake "$src" -DCMAKE_PREFIX_PATH="$venv" -DPython3_EXECUTABLE="$venv/bin/python" \
       -DCMAKE_INSTALL_PREFIX="$prefix" -DBUILD_TESTING=OFF >"$build/cmake.log" 2>&1 &&
     PATH="$venv/bin:$PATH" AMENT_PREFIX_PATH="$venv" make -j2 install >"$build/make.log" 2>&1) || {
    log "$name build failed; last lines of its logs:"; tail -n 40 "$build"/*.log >&2; exit 1; }
  touch "$prefix/.complete"
  rm -rf "$build"
}
ifc_key=$( (cd "$root/msg_defs" && find . -path ./tf2_msgs -prune -o -type f -print |
  LC_ALL=C sort | xargs sha256sum; echo "$venv_key") | sha)
ifc_prefix="$CACHE_DIR/interfaces-$ifc_key"
[ -f "$ifc_prefix/.complete" ] || build_interfaces msg_defs "$root/msg_defs" "$ifc_prefix"

# A ROS 2 install the user has sourced brings its own tf2_msgs: use that one. Importing the
# message class is not enough (a Python-only copy would import); its C type support must load.
tf2_prefix=
if ! "$venv/bin/python" -c 'from tf2_msgs.msg import TFMessage
TFMessage.__class__.__import_type_support__()' >/dev/null 2>&1; then
  tf2_key=$( (cd "$root/msg_defs/tf2_msgs" && find . -type f | LC_ALL=C sort | xargs sha256sum
    echo "$venv_key") | sha)
  tf2_prefix="$CACHE_DIR/tf2_msgs-$tf2_key"
  [ -f "$tf2_prefix/.complete" ] || build_interfaces tf2_msgs "$root/msg_defs/tf2_msgs" "$tf2_prefix"
fi

# --- 5. This package, installed into the checkout's install/ prefix -----------------------
pkg_key=$( (cd "$root" && git ls-files -co --exclude-standard -- setup.py setup.cfg package.xml \
  resource projection_server prolog config | LC_ALL=C sort | xargs sha256sum; echo "$ifc_key") | sha)
install_prefix="$root/install"
if [ "$(cat "$install_prefix/.key" 2>/dev/null)" != "$pkg_key" ]; then
  log "installing projection_server into $install_prefix"
  rm -rf "$install_prefix" "$root/build"
  pip_q --no-deps --no-build-isolation --prefix "$install_prefix" "$root"
  # `ros2 run projection_server X` looks in lib/<package>; pip puts scripts in bin/.
  mkdir -p "$install_prefix/lib/projection_server"
  mv "$install_prefix"/bin/* "$install_prefix/lib/projection_server/"
  rmdir "$install_prefix/bin"
  rm -rf "$root/build" "$root"/*.egg-info
  echo "$pkg_key" >"$install_prefix/.key"
fi

cat >"$root/.env.paths" <<ENV
SWIPL_PREFIX=$swipl_prefix
VENV=$venv
IFC_PREFIX=$ifc_prefix
TF2_PREFIX=$tf2_prefix
INSTALL_PREFIX=$install_prefix
ENV
