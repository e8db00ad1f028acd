#!/usr/bin/env bash
# Installs, with apt-get, the Debian bookworm packages monoplane needs to build, test and run.
# Idempotent: only packages that are missing are installed, and the script says which.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config git
  libopencv-dev libopencv-contrib-dev
  libeigen3-dev
  liboctomap-dev
  libceres-dev
  cyclonedds-dev cyclonedds-tools libcycloneddsidl0
  # libcrypto's sha256 for the ROS 2 type hashes in the DDS endpoints' USER_DATA.
  libssl-dev
  libsqlite3-dev sqlite3
  libzstd-dev liblz4-dev
  libyaml-cpp-dev
  libcli11-dev
  libspdlog-dev
  libgtest-dev libgmock-dev
  libbenchmark-dev
  # Test only: clang's libFuzzer and sanitizers build the fuzz targets (the fuzz preset), which the
  # test suite runs for a fixed number of inputs; clang-format checks the sources' format.
  clang libclang-rt-dev clang-format
  # Test only: a second DDS vendor (Fast DDS) reads what monoplane publishes.
  libfastrtps-dev libfastcdr-dev fastddsgen
  # Test only: a real browser (headless) renders `monoplane report`'s page in a test.
  chromium
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#packages[@]} required packages are installed"
  exit 0
fi

echo "setup: installing ${#missing[@]} missing package(s): ${missing[*]}"
sudo=""
if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "setup: done"
