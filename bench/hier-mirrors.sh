#!/bin/sh
# hier-mirrors.sh RADRAY [WIDTH] [SPP] - the radiosity pass's two methods on the
# shipped mirror scenes: per scene and method, `radray compare` of the
# radiosity display and the hybrid against secondary rays at the same SPP
# (default 64) and WIDTH (default 80), the object table it prints and its
# pass line. notes/radiosity.md ("Links by way of mirrors") has what it printed.
set -eu
radray=${1:?usage: hier-mirrors.sh RADRAY [WIDTH] [SPP]}
width=${2:-80}
spp=${3:-64}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for scene in mirror-corner-2 mirror-corner-3 mirror-room; do
    for method in flat hierarchical; do
        echo "== $scene, $method"
        "$radray" compare "scenes/$scene.json" --modes radiosity,hybrid,secondary --width "$width" --spp "$spp" \
            --set radiosity.method="$method" -o "$out/fig.png" 2>&1 |
            grep -E '^radiosity:|^region|^\(all pixels\)|^(floor|ceiling|left|right|back|front|mirror)'
    done
done
