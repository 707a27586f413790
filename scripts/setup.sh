#!/usr/bin/env bash
# One-step set-up for a fresh Debian bookworm machine (as root, no terminal needed):
# installs what is missing, fetches the Debian test meshes, builds Release, then
#   scripts/setup.sh run    builds rtsim alone and runs the main job (rtsim run, default config,
#                           built-in scene)
#   scripts/setup.sh test   builds everything, runs the whole test suite through ctest, then the
#                           fuzz targets briefly
#   scripts/setup.sh build  only builds everything (tests and benchmarks too)
# Environment: BUILD_DIR (default build), RTSIM_SANITIZE=ON for an ASan+UBSan build,
# RTSIM_FUZZ_SECONDS (default 6) for each fuzz target in the test command.
set -euo pipefail
cd "$(dirname "$0")/.."
mode="${1:-run}"
build_dir="${BUILD_DIR:-build}"

packages=(cmake g++ make pkg-config libsystemc-dev libgtest-dev libfmt-dev nlohmann-json3-dev
          libassimp-dev libpng-dev libembree-dev libcli11-dev libzstd-dev zlib1g-dev libxxhash-dev zstd glmark2-data
          librsvg2-bin)
# The test command also fuzzes the input readers (scripts/fuzz.sh): clang and its libFuzzer.
[ "$mode" != test ] || packages+=(clang libclang-rt-14-dev)
# ...renders rtsim report's page in a real browser, and runs a sweep through a one-node Slurm
# cluster it starts (scripts/slurm_local.sh).
[ "$mode" != test ] || packages+=(chromium slurm-wlm munge)
sudo_cmd=""
[ "$(id -u)" -eq 0 ] || sudo_cmd="sudo"
apt_updated=0
apt_update_once() {
    [ "$apt_updated" -eq 1 ] || { $sudo_cmd apt-get update -qq; apt_updated=1; }
}

missing=()
for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# The trace tests run scripts/rtt_reader.py: any python3 on PATH will do.
command -v python3 >/dev/null 2>&1 || missing+=(python3)
if [ ${#missing[@]} -gt 0 ]; then
    echo "[setup] installing: ${missing[*]}"
    apt_update_once
    DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# libcgal-demo ships a data archive of meshes; it depends on libcgal-dev, so unpack the .deb
# into a cache instead of installing it.
mesh_dir=".cache/meshes/cgal"
if [ ! -f "$mesh_dir/.done" ]; then
    echo "[setup] fetching libcgal-demo meshes into $mesh_dir"
    tmp="$(mktemp -d)"
    # Package lists may be missing on a machine that had everything else installed.
    (cd "$tmp" && apt-get download libcgal-demo >/dev/null 2>&1) ||
        { apt_update_once && (cd "$tmp" && apt-get download libcgal-demo >/dev/null 2>&1); } || {
        echo "[setup] cannot download libcgal-demo (needed for the mesh tests)" >&2; exit 1; }
    dpkg -x "$tmp"/libcgal-demo_*.deb "$tmp/x"
    mkdir -p "$mesh_dir"
    tar -xzf "$tmp/x/usr/share/doc/libcgal-dev/data.tar.gz" -C "$tmp" data/meshes
    cp "$tmp"/data/meshes/*.off "$mesh_dir"/
    rm -rf "$tmp"
    touch "$mesh_dir/.done"
fi

# assimp-testmodels ships glTF assets whose nodes share meshes (the milk truck's wheels, an
# engine of 115 placed parts): the instancing tests and bench read them. Unpacked likewise, and
# only those files kept.
model_dir=".cache/meshes/assimp"
if [ ! -f "$model_dir/.done" ]; then
    echo "[setup] fetching assimp-testmodels glTF assets into $model_dir"
    tmp="$(mktemp -d)"
    (cd "$tmp" && apt-get download assimp-testmodels >/dev/null 2>&1) ||
        { apt_update_once && (cd "$tmp" && apt-get download assimp-testmodels >/dev/null 2>&1); } ||
        { echo "[setup] cannot download assimp-testmodels (needed for the glTF tests)" >&2; exit 1; }
    dpkg -x "$tmp"/assimp-testmodels_*.deb "$tmp/x"
    models="$tmp/x/usr/share/assimp/models"
    mkdir -p "$model_dir"
    cp "$models"/glTF/CesiumMilkTruck/CesiumMilkTruck.{gltf,bin} "$model_dir"/
    cp "$models"/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb "$model_dir"/
    rm -rf "$tmp"
    touch "$model_dir/.done"
fi

cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE=Release -DRTSIM_SANITIZE="${RTSIM_SANITIZE:-OFF}" >/dev/null
# A user who only runs needs the simulator (and its assimp module), not the test programs.
targets=()
[ "$mode" != run ] || targets=(--target rtsim)
cmake --build "$build_dir" -j"$(nproc)" "${targets[@]}"

case "$mode" in
    build) ;;
    run) "$build_dir"/rtsim run --out out/default ;;
    test)
        ctest --test-dir "$build_dir" --output-on-failure -j"$(nproc)"
        # A few seconds a target replay the seed corpus and explore a little: built unoptimised,
        # in half the time of -O1 (a long fuzz by hand keeps fuzz.sh's -O1).
        FUZZ_CXX_FLAGS="${FUZZ_CXX_FLAGS:--O0 -g1}" scripts/fuzz.sh "${RTSIM_FUZZ_SECONDS:-6}"
        ;;
    *) echo "usage: scripts/setup.sh [run|test|build]" >&2; exit 2 ;;
esac
