#!/usr/bin/env bash
# Installs every Debian package lightfarm needs to build, test and benchmark.
# Idempotent: packages already present are skipped, so a second run costs a dpkg query.
set -euo pipefail

packages=(
  # toolchain
  build-essential cmake ninja-build pkg-config git clang libclang-rt-14-dev
  # renderer core
  libembree-dev libopenimageio-dev openimageio-tools libtbb-dev libspdlog-dev libfmt-dev
  libeigen3-dev libcli11-dev nlohmann-json3-dev libmetis-dev libsvm-dev libnanovdb-dev libopenvdb-dev
  libnanoflann-dev
  # farm
  libgrpc++-dev libgrpc-dev protobuf-compiler protobuf-compiler-grpc libprotobuf-dev
  libsqlite3-dev libssl-dev libcpp-httplib-dev openssl
  # tests, benchmarks, reports
  libgtest-dev libgmock-dev libbenchmark-dev gnuplot-nox
)
# Only the full suite needs these: the Slurm recipes' test starts a single-node Slurm, the
# Kubernetes manifests' test reads YAML and probes gRPC health from Python, the dashboard's test
# drives headless Chromium, the Python client's tests install it into a venv and run pytest. A
# build of chosen targets (LIGHTFARM_TARGETS, as render-example.sh does) skips them.
[ -n "${LIGHTFARM_TARGETS:-}" ] || packages+=(slurm-wlm munge python3-yaml python3-grpcio
  chromium chromium-driver python3-venv python3-pip python3-pytest python3-numpy python3-openimageio)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

echo "install-deps: installing ${missing[*]}" >&2
sudo_cmd=()
[ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
