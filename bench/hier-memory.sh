#!/bin/sh
# hier-memory.sh RADRAY SCENE... - what the hierarchical radiosity pass says it
# held (render's summary, rad__hier_bytes) against what it added to the
# process's peak: the peak of `render --width 16 --spp 1` less the peak of the
# same command with `--mode direct` (scene, BVH and film, no pass). Extra
# render options go in RADRAY_SETS, e.g. RADRAY_SETS="--set
# materials.mirror.mirror=0" for scenes/room.json. notes/radiosity.md
# ("--max-memory and the hierarchical pass") has the table this printed.
set -eu
radray=${1:?usage: hier-memory.sh RADRAY SCENE...}
shift
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
printf '%-24s %10s %12s %10s %10s %8s\n' scene leaves links held_MiB added_MiB ratio
for scene in "$@"; do
    # shellcheck disable=SC2086
    /usr/bin/time -f '%M' -o "$out/base" "$radray" render "$scene" --width 16 --spp 1 --no-png -q \
        --mode direct --set radiosity.method=hierarchical ${RADRAY_SETS:-} -o "$out/d.exr" >/dev/null 2>&1
    # shellcheck disable=SC2086
    /usr/bin/time -f '%M' -o "$out/peak" "$radray" render "$scene" --width 16 --spp 1 --no-png \
        --set radiosity.method=hierarchical ${RADRAY_SETS:-} -o "$out/h.exr" >"$out/log" 2>&1
    line=$(grep '^radiosity ' "$out/log")
    leaves=$(echo "$line" | awk '{ print $2 }')
    links=$(echo "$line" | awk '{ print $4 }')
    held=$(echo "$line" | sed 's/.*held \([0-9.]*\) MiB.*/\1/')
    awk -v s="$(basename "$scene")" -v l="$leaves" -v k="$links" -v h="$held" -v b="$(cat "$out/base")" \
        -v p="$(cat "$out/peak")" 'BEGIN { a = (p - b) / 1024; printf "%-24s %10s %12s %10.1f %10.1f %8.3f\n", s, l, k, h, a, h / a }'
done
