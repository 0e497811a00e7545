#!/bin/sh
# build.sh - builds the libFuzzer harnesses with clang (ASan + UBSan).
# Usage: tests/fuzz/build.sh [OUTDIR]   (default: build-fuzz in the repository root)
# Needs clang/clang++ (libFuzzer ships with Debian's clang) and the same
# libraries as the normal build (OpenMesh, cJSON; for import/: tinygltf,
# Assimp, stb).
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
out=${1:-$root/build-fuzz}
mkdir -p "$out/obj"
CC=${CC:-clang}
CXX=${CXX:-clang++}
san="-fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer"
flags="-g -O1 $san -fsanitize=fuzzer-no-link -D_POSIX_C_SOURCE=200809L -D_DEFAULT_SOURCE -I$root/core -I$root/mesh -I$root/import -I$root/scene"
objs=""
for src in "$root"/core/*.c "$root"/mesh/*.c "$root"/import/*.c "$root"/scene/*.c; do
  o="$out/obj/$(basename "$(dirname "$src")")_$(basename "$src" .c).o"
  $CC -std=c11 $flags -c "$src" -o "$o"
  objs="$objs $o"
done
for src in "$root"/mesh/*.cpp "$root"/import/*.cpp; do
  o="$out/obj/$(basename "$(dirname "$src")")_$(basename "$src" .cpp).o"
  $CXX -std=c++17 $flags -D_USE_MATH_DEFINES -c "$src" -o "$o"
  objs="$objs $o"
done
$CC -std=c11 $flags -Wall -Wextra -DFUZZ_BASE_DIR="\"$root/tests/data/scenes\"" -c "$here/fuzz_scene.c" -o "$out/obj/fuzz_scene.o"
$CC -std=c11 $flags -Wall -Wextra -c "$here/fuzz_mesh.c" -o "$out/obj/fuzz_mesh.o"
$CC -std=c11 $flags -Wall -Wextra -c "$here/fuzz_model.c" -o "$out/obj/fuzz_model.o"
# -ltinygltf before -lassimp: Assimp's libdraco carries its own, differently
# built copy of tinygltf's functions, and the first library in the NEEDED
# list wins (as in the top-level CMakeLists.txt).
for f in fuzz_scene fuzz_mesh fuzz_model; do
  $CXX $san -fsanitize=fuzzer "$out/obj/$f.o" $objs -lOpenMeshCore -lcjson -ltinygltf -lassimp -lstb -lpthread -lm \
    -o "$out/$f"
done
echo "built $out/fuzz_scene, $out/fuzz_mesh and $out/fuzz_model"
