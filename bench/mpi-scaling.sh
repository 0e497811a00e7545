#!/usr/bin/env bash
# bench/mpi-scaling.sh - radray over MPI ranks against threads (issue #18).
#
#   bench/mpi-scaling.sh [BUILD_DIR] [REPEATS]     (default build-mpi, 3)
#
# Needs a build with -DRADRAY_MPI=ON. For each pass, the median of REPEATS
# runs (and min..max) of:
#   1 rank x 1 thread, 2 ranks x 1 thread, 1 rank x 2 threads
# ray-tracing pass: scenes/cornell.json, secondary rays, 200 px, 64 spp
# radiosity pass:   scenes/cornell.json, 51,942 patches (--patch-area 40)
# Times are the passes' own (--stats): render seconds, radiosity pass seconds;
# "exchanged" is what rank 0 put into the merges and gathers.
set -euo pipefail
cd "$(dirname "$0")/.."
B=${1:-build-mpi}
N=${2:-3}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_btl_vader_single_copy_mechanism=${OMPI_MCA_btl_vader_single_copy_mechanism:-none}
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
grep -m1 "model name" /proc/cpuinfo | sed 's/.*: /cpu: /'
echo "cores: $(nproc), repeats: $N"

run() { # ranks threads key args... -> prints the --stats value of key
    local ranks=$1 threads=$2 key=$3; shift 3
    if [ "$ranks" -eq 1 ]; then
        "$B/radray" render "$@" --threads "$threads" -q --stats "$T/s.json" -o "$T/o.exr"
    else
        mpirun --oversubscribe -np "$ranks" "$B/radray" render "$@" --threads "$threads" -q \
            --stats "$T/s.json" -o "$T/o.exr"
    fi
    python3 -c "import json,sys; print(json.load(open('$T/s.json'))['$key'])"
}

median() { sort -g | awk '{a[NR]=$1} END {printf "%.2f s (%.2f..%.2f)", a[int((NR+1)/2)], a[1], a[NR]}'; }

pass() { # label key args...
    local label=$1 key=$2; shift 2
    for cfg in "1 1" "2 1" "1 2"; do
        local r=${cfg% *} t=${cfg#* }
        local m
        m=$(for i in $(seq "$N"); do run "$r" "$t" "$key" "$@"; done | median)
        echo "$label: $r rank(s) x $t thread(s): $m"
    done
}

pass "ray tracing" seconds_render scenes/cornell.json --width 200 --spp 64 --mode secondary
pass "radiosity  " seconds_radiosity scenes/cornell.json --width 32 --spp 1 --mode radiosity --patch-area 40
mpirun --oversubscribe -np 2 "$B/radray" render scenes/cornell.json --width 32 --spp 1 --mode radiosity \
    --patch-area 40 --threads 1 -o "$T/o.exr" | grep "^mpi"
mpirun --oversubscribe -np 2 "$B/radray" render scenes/cornell.json --width 200 --spp 64 --mode secondary \
    --threads 1 -o "$T/o.exr" | grep "^mpi"
