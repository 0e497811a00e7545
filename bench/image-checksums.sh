#!/bin/bash
# image-checksums.sh RADRAY OUTDIR: renders every example scene (scenes/*.json)
# in every mode at 48 px, 2 spp, and prints "scene mode digest" per EXR: a
# digest of its pixels, all layers (radray-exr-digest, built beside RADRAY),
# not of its bytes, which hold the render time.
# Run it with the binary before and after a change and diff the two lists:
# a refactoring must leave every line the same (notes/architecture.md).
set -u
R=${1:?usage: image-checksums.sh RADRAY OUTDIR}
O=${2:?usage: image-checksums.sh RADRAY OUTDIR}
mkdir -p "$O"
for s in scenes/*.json; do
    n=$(basename "$s" .json)
    for m in whitted secondary radiosity hybrid direct; do
        if ! "$R" render "$s" --mode $m --width 48 --spp 2 -q --no-png -o "$O/$n-$m.exr" \
            --radiosity-cache "$O/$n.cache" 2>/dev/null; then
            echo "$n $m FAILED"
            continue
        fi
        echo "$n $m $("$(dirname "$R")/radray-exr-digest" "$O/$n-$m.exr" | cut -c1-16)"
    done
done
