#!/usr/bin/env bash
# dev.sh - radray's one entry point for a new machine.
#
#   ./dev.sh render   install missing Debian packages, build, render scenes/cornell.json
#   ./dev.sh test     install missing Debian packages, build, run the test suite,
#                     the MPI tests (Open MPI is installed for them, build-mpi/),
#                     then build and run the suite again under AddressSanitizer + UBSan
#   ./dev.sh build    install missing Debian packages and build (build/radray)
#
# Packages are installed with apt-get (as root, or through sudo when it is there).
set -euo pipefail
cd "$(dirname "$0")"

PACKAGES=(cmake make gcc g++ pkg-config libopenmesh-dev libsuitesparse-dev libopenexr-dev libassimp-dev libtinygltf-dev libstb-dev
          libcmocka-dev libcjson-dev libpng-dev libcairo2-dev)
# The MPI tests' extra packages (./dev.sh test only; radray builds without them).
MPI_PACKAGES=(libopenmpi-dev openmpi-bin)
JOBS=$(nproc 2>/dev/null || echo 2)

install_packages() { # [extra packages...]
    local missing=()
    for p in "${PACKAGES[@]}" "$@"; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
    done
    [ ${#missing[@]} -eq 0 ] && return 0
    echo "dev.sh: installing missing Debian packages: ${missing[*]}"
    local sudo=()
    if [ "$(id -u)" -ne 0 ]; then
        if command -v sudo >/dev/null; then sudo=(sudo); else
            echo "dev.sh: need root or sudo to install: ${missing[*]}" >&2; exit 1
        fi
    fi
    "${sudo[@]}" apt-get update -q
    DEBIAN_FRONTEND=noninteractive "${sudo[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
}

build() { # build DIR [cmake options...]
    local dir=$1; shift
    cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo "$@" >/dev/null
    cmake --build "$dir" -j "$JOBS"
}

cmd=${1:-}
case "$cmd" in
render)
    install_packages
    build build
    build/radray render scenes/cornell.json -o out/cornell.exr
    ;;
test)
    install_packages "${MPI_PACKAGES[@]}"
    build build
    (cd build && ctest --output-on-failure -j "$JOBS")
    echo "dev.sh: running the MPI tests (mpirun -np 2 and 3, build-mpi/)"
    cmake -S . -B build-mpi -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRADRAY_MPI=ON >/dev/null
    cmake --build build-mpi -j "$JOBS" --target radray test_mpi
    (cd build-mpi && ctest --output-on-failure -R '^mpi$')
    echo "dev.sh: running the suite again under AddressSanitizer + UndefinedBehaviorSanitizer"
    build build-asan -DRADRAY_SANITIZE=ON
    (cd build-asan && ASAN_OPTIONS=detect_leaks=1:abort_on_error=0 UBSAN_OPTIONS=print_stacktrace=1 \
        ctest --output-on-failure -j "$JOBS")
    ;;
build)
    install_packages
    build build
    ;;
*)
    echo "usage: ./dev.sh render|test|build" >&2
    exit 2
    ;;
esac
