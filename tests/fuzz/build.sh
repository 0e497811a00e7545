#!/bin/sh
# build.sh - builds the libFuzzer harnesses with clang (ASan + UBSan).
# Usage: tests/fuzz/build.sh [OUTDIR]   (default: build-fuzz in the repository root)
# Needs clang/clang++ (libFuzzer ships with Debian's clang) and the same
# libraries as the normal build (OpenMesh, cJSON).
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
out=${1:-$root/build-fuzz}
mkdir -p "$out/obj"
CC=${CC:-clang}
CXX=${CXX:-clang++}
san="-fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer"
flags="-g -O1 $san -fsanitize=fuzzer-no-link -D_POSIX_C_SOURCE=200809L -D_DEFAULT_SOURCE -I$root/core -I$root/mesh -I$root/scene"
objs=""
for src in "$root"/core/*.c "$root"/mesh/*.c "$root"/scene/*.c; do
  o="$out/obj/$(basename "$(dirname "$src")")_$(basename "$src" .c).o"
  $CC -std=c11 $flags -c "$src" -o "$o"
  objs="$objs $o"
done
for src in "$root"/mesh/*.cpp; do
  o="$out/obj/mesh_$(basename "$src" .cpp).o"
  $CXX -std=c++17 $flags -D_USE_MATH_DEFINES -c "$src" -o "$o"
  objs="$objs $o"
done
$CC -std=c11 $flags -Wall -Wextra -DFUZZ_BASE_DIR="\"$root/tests/data/scenes\"" -c "$here/fuzz_scene.c" -o "$out/obj/fuzz_scene.o"
$CC -std=c11 $flags -Wall -Wextra -c "$here/fuzz_mesh.c" -o "$out/obj/fuzz_mesh.o"
for f in fuzz_scene fuzz_mesh; do
  $CXX $san -fsanitize=fuzzer "$out/obj/$f.o" $objs -lOpenMeshCore -lcjson -lm -o "$out/$f"
done
echo "built $out/fuzz_scene and $out/fuzz_mesh"
