#!/bin/bash
# bench-pair.sh N BENCH_A BENCH_B [radray-bench options]: runs two radray-bench
# binaries (e.g. this build's and one of the commit before, built in a git
# worktree) in turn, A B A B ..., N times each, and prints per scene and
# workload the median Mrays/s of each and the median of the N pair-by-pair
# ratios A/B with their range (pairing keeps a ratio meaningful on a machine
# whose speed drifts), and the same for build time and bytes per triangle.
# Default options: --threads 1.
set -eu
N=${1:?usage: bench-pair.sh N BENCH_A BENCH_B [options]}
A=${2:?usage: bench-pair.sh N BENCH_A BENCH_B [options]}
B=${3:?usage: bench-pair.sh N BENCH_A BENCH_B [options]}
shift 3
[ $# -gt 0 ] || set -- --threads 1
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for i in $(seq "$N"); do
    "$A" "$@" > "$out/a$i"
    "$B" "$@" > "$out/b$i"
done
python3 - "$out" "$N" <<'PY'
import re, statistics, sys
out, n = sys.argv[1], int(sys.argv[2])
def parse(path):
    d, scene = {}, None
    for line in open(path):
        if line.startswith('== '):
            scene = line.split()[1].rstrip(':')
        elif line.startswith('BVH build'):
            m = re.search(r'(\d+) ms .*?(\d+) nodes.*?([\d.]+) bytes/triangle', line)
            d[(scene, 'build ms', 1)] = float(m.group(1))
            d[(scene, 'bytes/tri', 1)] = float(m.group(3))
        elif line.split() and line.split()[0] in ('primary', 'diffuse', 'shadow', 'packets', 'shadowpk'):
            w = line.split()
            d[(scene, w[0], int(w[1]))] = float(w[4])
    return d
A = [parse(f'{out}/a{i}') for i in range(1, n + 1)]
B = [parse(f'{out}/b{i}') for i in range(1, n + 1)]
print(f'{"scene":<10} {"figure":<10} {"thr":>3} {"A":>9} {"B":>9}  A/B median (min-max), {n} pairs')
for k in A[0]:
    if not all(k in x for x in A + B):
        continue  # a figure only one binary prints (a workload the other has not)
    r = [a[k] / b[k] for a, b in zip(A, B)]
    print(f'{k[0]:<10} {k[1]:<10} {k[2]:>3} {statistics.median(a[k] for a in A):9.2f} '
          f'{statistics.median(b[k] for b in B):9.2f}  {statistics.median(r):.3f} ({min(r):.3f}-{max(r):.3f})')
PY
