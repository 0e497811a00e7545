#!/bin/sh
# hier-scaling.sh RADRAY [SCALES...] - the hierarchical radiosity pass on
# scenes/room.json (its mirror set to 0) at patch areas scaled by each SCALE
# (the roots are 16 x the patch area, the smallest element 1/16 of it):
# leaves, links, pass seconds and peak memory per run, then the exponent b of
# links = a N^b fitted over the leaves N (least squares in log-log), and
# links / (N log2 N). notes/radiosity.md has the table this printed.
set -eu
radray=${1:?usage: hier-scaling.sh RADRAY [SCALES...]}
shift
[ $# -gt 0 ] || set -- 8 4 2 1 0.5 0.25
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
printf '%8s %10s %12s %9s %9s\n' scale leaves links pass_s peak_MB
for k in "$@"; do
    area=$(awk -v k="$k" 'BEGIN { printf "%.6g", 0.002 * k }')
    edge=$(awk -v k="$k" 'BEGIN { printf "%.6g", 0.25 * sqrt(k) }')
    /usr/bin/time -f '%M' -o "$out/mem" "$radray" render scenes/room.json --set radiosity.method=hierarchical \
        --set materials.mirror.mirror=0 --set radiosity.patch_area="$area" --set radiosity.patch_edge="$edge" \
        --width 16 --spp 1 -o "$out/room.exr" >"$out/log" 2>&1
    line=$(grep '^radiosity ' "$out/log")
    leaves=$(echo "$line" | awk '{ print $2 }')
    links=$(echo "$line" | awk '{ print $4 }')
    secs=$(echo "$line" | sed 's/.*refinement \([0-9.]*\) s.*solves \([0-9.]*\) s.*/\1 \2/' | awk '{ print $1 + $2 }')
    mem=$(awk '{ printf "%.0f", $1 / 1024 }' "$out/mem")
    printf '%8s %10s %12s %9s %9s\n' "$k" "$leaves" "$links" "$secs" "$mem"
    echo "$leaves $links" >>"$out/fit"
done
awk '{ x = log($1); y = log($2); n++; sx += x; sy += y; sxx += x * x; sxy += x * y; r[n] = $2 / ($1 * log($1) / log(2)) }
     END { b = (n * sxy - sx * sy) / (n * sxx - sx * sx); printf "links ~ N^%.3f over %d runs; links / (N log2 N):", b, n;
           for (i = 1; i <= n; i++) printf " %.2f", r[i]; printf "\n" }' "$out/fit"
