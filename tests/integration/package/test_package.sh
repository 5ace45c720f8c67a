#!/usr/bin/env bash
# test_package.sh BUILD_DIR [CPACK]: build the .debs of BUILD_DIR with cpack, check them, unpack the
# locus package into a scratch root, replay a scene with its binaries, verify its systemd unit.
set -uo pipefail
build=$(cd "$1" && pwd); cpack=${2:-cpack}
tmp=$(mktemp -d "${TMPDIR:-/tmp}/locus-package.XXXXXX"); trap 'rm -rf "$tmp"' EXIT
fails=0; passes=0
ok() { echo "ok   - $*"; passes=$((passes + 1)); }
fail() { echo "FAIL - $*"; fails=$((fails + 1)); }
finish() { echo "$passes passed, $fails failed"; [ $fails -eq 0 ]; exit $?; }

# 1. cpack, into the scratch directory (staging there too, not in the build tree).
if "$cpack" -G DEB --config "$build/CPackConfig.cmake" -B "$tmp/out" > "$tmp/cpack.log" 2>&1; then
  ok "cpack -G DEB"
else
  fail "cpack -G DEB"; cat "$tmp/cpack.log"; finish
fi
arch=$(dpkg --print-architecture)
deb=$(ls "$tmp"/out/locus_*_"$arch".deb 2>/dev/null | head -1)
dev=$(ls "$tmp"/out/locus-dev_*_"$arch".deb 2>/dev/null | head -1)
[ -n "$deb" ] && ok "locus package: $(basename "$deb")" || { fail "no locus_*_$arch.deb"; ls -l "$tmp/out"; finish; }
[ -n "$dev" ] && ok "locus-dev package: $(basename "$dev")" || fail "no locus-dev_*_$arch.deb"

# 2. Control data: Depends from dpkg-shlibdeps (every backend's library, versioned) plus adduser;
#    conffiles; the maintainer scripts.
field() { dpkg-deb -f "$deb" "$1"; }
depends=$(field Depends)
echo "     Depends: $depends"
for lib in libc6 libstdc++6 libyaml-cpp0.7 libfftw3-single3 libsndfile1 libasound2 libjack-jackd2-0 \
           libsdbus-c++1 libmosquitto1 libcpp-httplib0.11 adduser; do
  re=$(sed 's/[+.]/\\&/g' <<<"$lib")
  if grep -qE "(^|, |\\| )$re( |,|$)" <<<"$depends"; then ok "Depends names $lib"; else fail "Depends lacks $lib"; fi
done
grep -qE "libc6 \\(>= [0-9]" <<<"$depends" && ok "Depends are versioned (shlibs)" || fail "unversioned libc6"
[ "$(field Architecture)" = "$arch" ] && ok "Architecture: $arch" || fail "Architecture: $(field Architecture)"
dpkg-deb -e "$deb" "$tmp/control"
for f in postinst prerm postrm conffiles; do
  [ -f "$tmp/control/$f" ] && ok "control: $f" || fail "control: no $f"
done
grep -qx /etc/locus/board.yaml "$tmp/control/conffiles" && ok "conffiles: /etc/locus/board.yaml" || fail "conffiles: $(cat "$tmp/control/conffiles")"
grep -q "adduser --quiet --system --group" "$tmp/control/postinst" && ok "postinst creates the locus system user" || fail "postinst: no system user"
sh -n "$tmp/control/postinst" && sh -n "$tmp/control/prerm" && sh -n "$tmp/control/postrm" && ok "maintainer scripts parse (sh -n)" || fail "maintainer script syntax"

# 3. Contents.
dpkg-deb -c "$deb" | awk '{print $6}' | sed 's|^\./|/|' > "$tmp/contents"
for f in /usr/bin/locusd /usr/bin/locus /usr/lib/systemd/system/locus@.service /etc/locus/board.yaml \
         /etc/locus/pi-2mic-hat.yaml /etc/locus/pi-usb-mic.yaml /usr/share/locus/config/amil.yaml \
         /usr/share/doc/locus/raspberry-pi.md; do
  grep -qx "$f" "$tmp/contents" && ok "contains $f" || fail "missing $f"
done
grep -qE "^/usr/lib/(.*/)?liblocus\\.so\\.0" "$tmp/contents" && ok "contains liblocus.so.0" || fail "missing liblocus.so.0"
grep -qE "/include/|\\.so$|/cmake/" "$tmp/contents" && fail "development files in the runtime package" || ok "no development files in locus"
# list to a file first: `grep -q` closing the pipe early kills dpkg-deb with SIGPIPE under pipefail
[ -n "$dev" ] && dpkg-deb -c "$dev" > "$tmp/dev-contents" && grep -q "include/locus/plugin.hpp" "$tmp/dev-contents" && ok "locus-dev holds the plugin API headers" || fail "locus-dev without plugin.hpp"

# 4. Unpacked into a scratch root: its binaries find their libraries (liblocus from the root itself),
#    check the shipped board configs, simulate and replay a scene, and print estimates.
root="$tmp/root"
dpkg-deb -x "$deb" "$root" && ok "dpkg-deb -x into a scratch root" || { fail "dpkg-deb -x"; finish; }
ldd "$root/usr/bin/locusd" > "$tmp/ldd" 2>&1
grep -q "not found" "$tmp/ldd" && { fail "unresolved libraries"; cat "$tmp/ldd"; } || ok "every library of locusd resolves"
grep -E "liblocus\\.so\\.0 => $root/" "$tmp/ldd" > /dev/null && ok "locusd loads liblocus from the package (RUNPATH \$ORIGIN)" ||
  { fail "liblocus not from the package"; grep liblocus "$tmp/ldd"; }
"$root/usr/bin/locus" version > "$tmp/version" 2>&1 && ok "locus version: $(head -1 "$tmp/version")" || { fail "locus version"; cat "$tmp/version"; }
for cfg in "$root"/etc/locus/*.yaml; do
  "$root/usr/bin/locus" check-config "$cfg" > "$tmp/check" 2>&1 && ok "check-config $(basename "$cfg")" || { fail "check-config $(basename "$cfg")"; cat "$tmp/check"; }
done
"$root/usr/bin/locus" simulate amil "$tmp/scene" --seed 3 > "$tmp/sim.log" 2>&1 && ok "locus simulate amil" || { fail "simulate"; cat "$tmp/sim.log"; finish; }
"$root/usr/bin/locusd" --config "$root/usr/share/locus/config/amil.yaml" --scene "$tmp/scene" --speed max \
  > "$tmp/estimates.jsonl" 2> "$tmp/locusd.err"; s=$?
[ $s -eq 0 ] && ok "packaged locusd replays the scene (exit 0)" || { fail "locusd exit $s"; tail -20 "$tmp/locusd.err"; }
n=$(grep -c '"type":"estimate"' "$tmp/estimates.jsonl")
[ "$n" -ge 12 ] && ok "$n estimates printed (12 listeners)" || { fail "only $n estimates"; head -5 "$tmp/estimates.jsonl"; }
"$root/usr/bin/locus" eval "$tmp/scene" "$tmp/estimates.jsonl" --metric amil > "$tmp/eval.log" 2>&1 &&
  ok "locus eval accepts the estimates" || { fail "locus eval"; tail -5 "$tmp/eval.log"; }

# 5. The unit: `systemd-analyze verify` inside the scratch root (--root: ExecStart/ExecStartPre must be
#    executables of the package), with the host's targets and slices the unit orders itself against.
#    systemd 252 only warns about unknown keys and bad values, so any output at all is a failure.
if ! command -v systemd-analyze > /dev/null; then
  fail "systemd-analyze not installed (tools/install-deps.sh installs systemd)"
else
  units=$(dirname "$(command -v systemctl || echo /usr/bin/systemctl)")/../lib/systemd/system
  [ -d /usr/lib/systemd/system ] && units=/usr/lib/systemd/system
  cp -n "$units"/*.target "$units"/*.slice "$root/usr/lib/systemd/system/" 2>/dev/null
  systemd-analyze verify --root="$root" locus@board.service > "$tmp/verify" 2>&1; s=$?
  if [ $s -eq 0 ] && [ ! -s "$tmp/verify" ]; then ok "systemd-analyze verify locus@board.service: clean"
  else fail "systemd-analyze verify (exit $s)"; cat "$tmp/verify"; fi
  # The verifier does look: a unit naming a binary the package lacks fails.
  sed 's|/usr/bin/locusd|/usr/bin/no-such-locusd|' "$root/usr/lib/systemd/system/locus@.service" \
    > "$root/usr/lib/systemd/system/broken@.service"
  systemd-analyze verify --root="$root" broken@board.service > /dev/null 2>&1 &&
    fail "verify accepted a unit with a missing ExecStart" || ok "verify refuses a unit with a missing ExecStart"
  rm -f "$root/usr/lib/systemd/system/broken@.service"
  systemd-analyze security --offline=yes --root="$root" --threshold=30 locus@board.service > "$tmp/security" 2>&1; s=$?
  exposure=$(grep -o "Overall exposure level for locus@board.service: [0-9.]*" "$tmp/security" | awk '{print $NF}')
  [ $s -eq 0 ] && ok "sandbox exposure ${exposure:-?} (systemd-analyze security, threshold 3.0)" ||
    { fail "sandbox exposure ${exposure:-?} above 3.0"; grep "✗" "$tmp/security"; }
  for key in "User=locus" "AmbientCapabilities=CAP_SYS_NICE" "ProtectSystem=strict" "SupplementaryGroups=audio bluetooth" \
             "StandardError=journal"; do
    grep -qx "$key" "$root/usr/lib/systemd/system/locus@.service" && ok "unit: $key" || fail "unit lacks $key"
  done
fi
finish
