#!/usr/bin/env bash
# The single source of Locus's build and test dependencies (Debian 12 packages only).
# Idempotent: installs only what is missing, quiet when everything is already there.
set -euo pipefail

PACKAGES=(
  # toolchain
  build-essential cmake ninja-build pkg-config git ccache
  # design card libraries
  libasound2-dev libasound2-plugins libjack-jackd2-dev jackd2 libeigen3-dev libfftw3-dev
  libyaml-cpp-dev libbluetooth-dev
  # HAL backends: BlueZ over D-Bus (sdbus-c++ needs libsystemd-dev for pkg-config), MQTT link
  libsdbus-c++-dev libsystemd-dev libmosquitto-dev
  # well-kept libraries for what is not our business
  libspdlog-dev libfmt-dev libcli11-dev nlohmann-json3-dev libsndfile1-dev libboost-dev
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev valgrind
  # real components the integration tests start themselves (docs: ../shared/docs/real-components.md)
  dbus python3-dbusmock mosquitto mosquitto-clients sox
  # TLS certificates for the MQTT TLS test (tests/integration/mqtt)
  openssl
  # reference checks and plots (never runtime dependencies of the service)
  python3-numpy python3-scipy python3-matplotlib python3-yaml
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
[ ${#missing[@]} -eq 0 ] && exit 0

SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
echo "install-deps: installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
# jackd2 asks whether to enable realtime scheduling; answer no non-interactively.
echo "jackd2 jackd/tweak_rt_limits boolean false" | $SUDO debconf-set-selections 2>/dev/null || true
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
