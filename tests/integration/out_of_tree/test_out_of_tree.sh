#!/usr/bin/env bash
# test_out_of_tree.sh <build dir> <source dir> <locus_load_plugin> [<dir with a wrong-ABI plugin>]
#
# 1. cmake --install <build dir> into a temporary prefix, and check the installed package is
#    self-contained (Locus::api needs only its headers and liblocus.so: no yaml-cpp, spdlog, ...).
# 2. Configure and build examples/out-of-tree-plugin against that prefix (CMAKE_PREFIX_PATH only).
# 3. Load the built .so with `locus plugins --plugin-dir` (build tree and installed copy) and with
#    locus_load_plugin, which runs the detector on a synthetic clipped block.
# 4. A directory holding a wrong-ABI plugin makes `locus plugins` fail with exit 3 and a clear error.
# Every step fails the test loudly; temporary directories are always removed.
set -euo pipefail

if [ $# -lt 3 ]; then
  echo "usage: $0 <build dir> <source dir> <locus_load_plugin> [<wrong-abi plugin dir>]" >&2
  exit 2
fi
BUILD=$(cd "$1" && pwd)
SRC=$(cd "$2" && pwd)
DRIVER=$3
WRONG_ABI_DIR=${4:-}

TMP=$(mktemp -d "${TMPDIR:-/tmp}/locus-out-of-tree.XXXXXX")
trap 'rm -rf "$TMP"' EXIT
TMP=$(cd "$TMP" && pwd)  # normalised (the CLI prints plugin origins as dir/name)
PREFIX=$TMP/prefix
PLUGIN_BUILD=$TMP/plugin-build
PLUGINS=$TMP/plugins
LOG=$TMP/log

step() { echo "==> $*"; }
fail() {
  echo "FAIL: $*" >&2
  if [ -s "$LOG" ]; then
    echo "---- output ----" >&2
    cat "$LOG" >&2
  fi
  exit 1
}
run() {  # run <description> <command...>: output to $LOG, shown on failure
  local what=$1
  shift
  "$@" >"$LOG" 2>&1 || fail "$what (exit $?): $*"
}

# -------------------------------------------------------------------------------------------- install
step "install $BUILD into $PREFIX"
run "cmake --install" cmake --install "$BUILD" --prefix "$PREFIX"
CONFIG_DIR=$(dirname "$(find "$PREFIX" -name LocusConfig.cmake -print -quit)")
[ -f "$CONFIG_DIR/LocusConfig.cmake" ] || fail "no LocusConfig.cmake installed under $PREFIX"
for f in LocusConfigVersion.cmake LocusTargets.cmake; do
  [ -f "$CONFIG_DIR/$f" ] || fail "$f not installed in $CONFIG_DIR"
done
for h in plugin.hpp detector.hpp localizer.hpp params.hpp events.hpp host.hpp; do
  [ -f "$PREFIX/include/locus/$h" ] || fail "header locus/$h not installed"
done
ls "$PREFIX"/lib*/liblocus.so >/dev/null 2>&1 || fail "liblocus.so not installed"
PRIVATE_DEPS='yaml|spdlog|fmt::|nlohmann|CLI11|fftw|sndfile|jack|Eigen|Boost|GTest|benchmark'
# IMPORTED_LINK_DEPENDENT_LIBRARIES is CMake's record of liblocus.so's own (private, shared) runtime
# dependencies, a linker search hint; it puts no requirement on a consumer (the build below proves it).
if grep -v '^[[:space:]]*#' "$CONFIG_DIR"/*.cmake | grep -v 'IMPORTED_LINK_DEPENDENT_LIBRARIES' | grep -E -i "$PRIVATE_DEPS"; then
  fail "the installed CMake package refers to a private dependency (lines above)"
fi
# Every installed header compiles on its own with nothing but the prefix on the include path.
CXX_BIN=${CXX:-c++}
for h in "$PREFIX"/include/locus/*; do
  if grep -E -i -n "#include <($PRIVATE_DEPS)" "$h"; then
    fail "installed header $h includes a private dependency"
  fi
  echo "#include <locus/$(basename "$h")>" >"$TMP/header_check.cpp"
  run "installed header locus/$(basename "$h") does not compile on its own" \
    "$CXX_BIN" -std=c++20 -fsyntax-only -I"$PREFIX/include" "$TMP/header_check.cpp"
done

# ------------------------------------------------------------------------------ build the example plugin
step "configure examples/out-of-tree-plugin against $PREFIX"
GENERATOR=()
command -v ninja >/dev/null && GENERATOR=(-G Ninja)
# Only the temporary prefix may provide Locus: no package registries, and not the build tree.
run "configure the out-of-tree plugin" \
  cmake -S "$SRC/examples/out-of-tree-plugin" -B "$PLUGIN_BUILD" "${GENERATOR[@]}" \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_PREFIX_PATH="$PREFIX" \
  -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF -DCMAKE_FIND_USE_SYSTEM_PACKAGE_REGISTRY=OFF
grep -q "Locus_DIR:PATH=$CONFIG_DIR" "$PLUGIN_BUILD/CMakeCache.txt" ||
  fail "find_package(Locus) did not use the installed package ($(grep Locus_DIR "$PLUGIN_BUILD/CMakeCache.txt"))"
step "build it"
run "build the out-of-tree plugin" cmake --build "$PLUGIN_BUILD"
SO=$(find "$PLUGIN_BUILD" -maxdepth 2 -name 'libclip_detector.so' -print -quit)
[ -n "$SO" ] || fail "libclip_detector.so was not built in $PLUGIN_BUILD"
nm -D --defined-only "$SO" > "$TMP/nm" && grep -q ' T locus_plugin_enum$' "$TMP/nm" || fail "$SO does not export locus_plugin_enum"
mkdir -p "$PLUGINS"
cp "$SO" "$PLUGINS/"
PLUGIN_SO=$PLUGINS/libclip_detector.so

# ----------------------------------------------------------------------------- load it: locus plugins
check_cli() {  # check_cli <locus binary>
  local locus=$1 rc=0
  step "$locus plugins --plugin-dir $PLUGINS"
  "$locus" plugins --plugin-dir "$PLUGINS" >"$TMP/out" 2>"$TMP/err" || rc=$?
  cat "$TMP/out" "$TMP/err" >"$LOG"
  [ "$rc" -eq 0 ] || fail "locus plugins exited $rc"
  grep -E -q '^clip_detector([^a-z0-9_]|$)' "$TMP/out" || fail "no line starting with clip_detector"
  local line
  line=$(grep -E '^clip_detector([^a-z0-9_]|$)' "$TMP/out" | head -n1)
  for word in detector 1.0.0 "$PLUGIN_SO"; do
    case "$line" in *"$word"*) ;; *) fail "the clip_detector line does not mention '$word': $line" ;; esac
  done
  grep -q 'threshold' "$TMP/out" || fail "the parameter schema (threshold) is not printed"
  grep -q 'min_run_samples' "$TMP/out" || fail "the parameter schema (min_run_samples) is not printed"
  cat "$TMP/out"

  if [ -n "$WRONG_ABI_DIR" ]; then
    step "$locus plugins --plugin-dir $WRONG_ABI_DIR (must be refused)"
    rc=0
    "$locus" plugins --plugin-dir "$WRONG_ABI_DIR" >"$TMP/out" 2>"$TMP/err" || rc=$?
    cat "$TMP/out" "$TMP/err" >"$LOG"
    [ "$rc" -eq 3 ] || fail "locus plugins with a wrong-ABI library exited $rc, expected 3"
    grep -q 'ABI 999' "$TMP/err" || fail "the wrong-ABI error on stderr does not name ABI 999"
    cat "$TMP/err"
  fi
}
[ -x "$BUILD/bin/locus" ] || fail "$BUILD/bin/locus is not built"
check_cli "$BUILD/bin/locus"
[ -x "$PREFIX/bin/locus" ] || fail "locus is not installed in $PREFIX/bin"
check_cli "$PREFIX/bin/locus"

# ------------------------------------------------------------------- load it: driver, one clipped block
step "$DRIVER $PLUGIN_SO"
run "locus_load_plugin" "$DRIVER" "$PLUGIN_SO"
cat "$LOG"
grep -q '^plugin clip_detector detector 1.0.0$' "$LOG" || fail "the driver did not register clip_detector"
# Channel 1 goes -0.5 -> -1.0 between frames 99 and 100: the -0.99 crossing is at 99.98.
[ "$(grep -c '^event ' "$LOG")" -eq 1 ] || fail "expected exactly one event"
grep -q '^event audio_detection channel=1 frame=99.9800 amplitude=1.000$' "$LOG" ||
  fail "unexpected detection (want channel=1 frame=99.9800 amplitude=1.000)"

echo "PASS: out-of-tree plugin built against the installed package and loaded"
