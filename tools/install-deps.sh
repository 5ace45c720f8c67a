#!/usr/bin/env bash
# The single source of Locus's build and test dependencies (Debian 12 packages only).
# Idempotent: installs only what is missing, quiet when everything is already there.
#   tools/install-deps.sh          the native (amd64) build, tests and packaging (./run test, ./run package)
#   tools/install-deps.sh --arm64  also the arm64 cross build (./run package arm64, ./run test-arm64):
#                                  crossbuild-essential-arm64, qemu-user-static and the arm64 (multiarch)
#                                  -dev packages of every library below (adds the arm64 dpkg architecture)
set -euo pipefail
arm64=0
[ "${1:-}" = "--arm64" ] && arm64=1

PACKAGES=(
  # toolchain
  build-essential cmake ninja-build pkg-config git ccache mold
  # design card libraries
  libasound2-dev libasound2-plugins libjack-jackd2-dev jackd2 libeigen3-dev libfftw3-dev
  libyaml-cpp-dev libbluetooth-dev
  # HAL backends: BlueZ over D-Bus (sdbus-c++ needs libsystemd-dev for pkg-config), MQTT link
  libsdbus-c++-dev libsystemd-dev libmosquitto-dev
  # HMAC-SHA256 of signed link messages (link/auth: OpenSSL's libcrypto)
  libssl-dev
  # the live map's HTTP server (locusd --http, tools/map; LOCUS_WITH_HTTP)
  libcpp-httplib-dev
  # well-kept libraries for what is not our business
  libspdlog-dev libfmt-dev libcli11-dev nlohmann-json3-dev libsndfile1-dev libboost-dev
  # tests and benchmarks; clang's libFuzzer for ./run fuzz (tests/fuzz)
  libgtest-dev libgmock-dev libbenchmark-dev valgrind clang libclang-rt-dev
  # real components the integration tests start themselves (docs: ../shared/docs/real-components.md)
  dbus python3-dbusmock mosquitto mosquitto-clients sox
  # TLS certificates for the MQTT TLS test (tests/integration/mqtt)
  openssl
  # the real browser of the live map's test (tests/integration/map: headless Chromium)
  chromium
  # reference checks and plots (never runtime dependencies of the service)
  python3-numpy python3-scipy python3-matplotlib python3-yaml
  # packaging (./run package: cpack DEB, dpkg-shlibdeps from dpkg-dev) and its test
  # (systemd-analyze verify of the unit, adduser for the maintainer scripts)
  dpkg-dev file systemd adduser
)

# The arm64 cross build: the toolchain, the emulator for its tests, and the arm64 -dev package of every
# library in PACKAGES (header-only ones, Architecture: all, serve both). libyaml-cpp-dev is not
# Multi-Arch: same (its arm64 package would remove the amd64 one), so the arm64 build takes the headers
# of the amd64 -dev package and links the arm64 runtime library (cmake/toolchains/aarch64-linux-gnu.cmake).
ARM64_PACKAGES=(
  crossbuild-essential-arm64 qemu-user-static
  libasound2-dev:arm64 libjack-jackd2-dev:arm64 libfftw3-dev:arm64 libyaml-cpp0.7:arm64
  libbluetooth-dev:arm64 libsdbus-c++-dev:arm64 libsystemd-dev:arm64 libmosquitto-dev:arm64 libssl-dev:arm64
  libcpp-httplib-dev:arm64
  libspdlog-dev:arm64 libfmt-dev:arm64 libsndfile1-dev:arm64 libboost-dev:arm64
  libgtest-dev:arm64 libgmock-dev:arm64 libbenchmark-dev:arm64
)
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
if [ $arm64 -eq 1 ]; then
  PACKAGES+=("${ARM64_PACKAGES[@]}")
  if ! dpkg --print-foreign-architectures | grep -qx arm64; then
    echo "install-deps: adding the arm64 dpkg architecture" >&2
    $SUDO dpkg --add-architecture arm64
  fi
fi

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
[ ${#missing[@]} -eq 0 ] && exit 0

echo "install-deps: installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
# jackd2 asks whether to enable realtime scheduling; answer no non-interactively.
echo "jackd2 jackd/tweak_rt_limits boolean false" | $SUDO debconf-set-selections 2>/dev/null || true
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
