#!/bin/sh
# bunny-room.sh OUT.json [N] - writes a room furnished with N Stanford bunnies
# (scenes/meshes/bunny.ply, 3,674 triangles each; default N = 273, so
# 1,003,002 bunny triangles) on a grid on the floor of a closed 20 x 4 x 20 m
# diffuse room lit by four ceiling panels: the >= 1M-triangle room of the
# hierarchical radiosity measurements (notes/radiosity.md).
set -eu
out=${1:?usage: bunny-room.sh OUT.json [N]}
n=${2:-273}
mesh=$(cd "$(dirname "$0")/../scenes/meshes" && pwd)/bunny.ply
{
    printf '{"format":"radray-scene/1","name":"bunny-room",\n'
    printf ' "camera":{"type":"lookat","eye":[10,3.2,19.5],"target":[10,0.5,8],"up":[0,1,0],"fov":60,"width":320,"height":200},\n'
    printf ' "materials":{"wall":{"diffuse":[0.7,0.68,0.64]},"clay":{"diffuse":[0.75,0.5,0.35]},'
    printf '"lamp":{"diffuse":0,"emission":[12,11,9]}},\n'
    printf ' "render":{"spp":4,"seed":1},\n'
    printf ' "objects":[\n  {"name":"room","type":"box","material":"wall","flip":true,"min":[0,0,0],"max":[20,4,20]}'
    for lx in 5 15; do
        for lz in 5 15; do
            printf ',\n  {"type":"quad","material":"lamp","vertices":[[%s,3.998,%s],[%s,3.998,%s],[%s,3.998,%s],[%s,3.998,%s]]}' \
                $((lx - 1)) $((lz - 1)) $((lx + 1)) $((lz - 1)) $((lx + 1)) $((lz + 1)) $((lx - 1)) $((lz + 1))
        done
    done
    awk -v n="$n" -v mesh="$mesh" 'BEGIN {
        side = int(sqrt(n - 1)) + 1; step = 19.0 / side;
        for (i = 0; i < n; i++) {
            x = 0.5 + step * (i % side + 0.5); z = 0.5 + step * (int(i / side) + 0.5);
            printf ",\n  {\"type\":\"mesh\",\"material\":\"clay\",\"file\":\"%s\",\"transform\":[{\"scale\":0.08},", mesh;
            printf "{\"rotate\":{\"axis\":[0,1,0],\"degrees\":%d}},{\"translate\":[%.4f,0.00025,%.4f]}]}", (i * 37) % 360, x, z
        }
    }'
    printf '\n ]}\n'
} >"$out"
