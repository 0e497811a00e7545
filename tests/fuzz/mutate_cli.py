#!/usr/bin/env python3
"""mutate_cli.py - mutation fuzzing of the radray command line, as a user or a
script would run it (notes/robustness.md, "CLI mutation runs").

Takes every scene in scenes/ (and every mesh in scenes/meshes/, through a
scene that loads it), mutates it (bytes flipped, cut, duplicated; numbers
replaced by extreme values; keys and brackets dropped), runs

    radray render MUTANT --width 24 --spp 1 -q -o OUT.exr

under a time limit and sorts each run into: ok (exit 0 and OUT.exr and
OUT.png there), refused (exit 2 with a message), crash (killed by a signal,
or exit >= 128 other than 130/143), hang (time limit), silent (a non-zero
exit without a message, or exit 0 without the outputs), partial (a failed
run that left OUT.exr, OUT.png or a hidden temporary). Deterministic for a
seed. Usage:

    tests/fuzz/mutate_cli.py [--radray build/radray] [--count 300] [--timeout 15] [--seed 1] [--keep DIR]
"""
import argparse
import os
import random
import re
import shutil
import subprocess
import sys
import tempfile
import time

EXTREMES = ["1e308", "-1e308", "1e-308", "0", "-0", "-1", "2147483648", "4294967297", "1e999", "3.5",
            "65536", "1048576", "16777216", "0.000001", "-2.5", "123456789012345678901234567890"]


def mutate(data: bytes, rng: random.Random) -> bytes:
    b = bytearray(data)
    for _ in range(rng.randint(1, 2)):
        kind = rng.choice([0, 1, 2, 3, 3, 3, 4, 4, 4, 5, 6])
        if not b:
            break
        i = rng.randrange(len(b))
        if kind == 0:  # flip a byte
            b[i] = rng.randrange(256)
        elif kind == 1:  # cut a span
            del b[i:i + rng.randint(1, 16)]
        elif kind == 2:  # duplicate a span
            j = min(len(b), i + rng.randint(1, 64))
            b[i:i] = b[i:j]
        elif kind == 3 or kind == 4:  # a number -> an extreme value
            text = b.decode("latin-1")
            nums = [m.span() for m in re.finditer(r"-?\d+(\.\d+)?([eE][-+]?\d+)?", text)]
            if nums:
                s, e = rng.choice(nums)
                text = text[:s] + rng.choice(EXTREMES) + text[e:]
                b = bytearray(text.encode("latin-1"))
        elif kind == 5:  # drop a bracket, brace, quote or comma
            pos = [k for k, c in enumerate(b) if c in b'[]{}",:']
            if pos:
                del b[rng.choice(pos)]
        else:  # insert a random byte
            b.insert(i, rng.randrange(256))
    return bytes(b)


def classify(rc, out_exists, png_exists, temps, stderr, timed_out):
    if timed_out:
        return "hang"
    if rc < 0 or (rc >= 128 and rc not in (130, 143)):
        return "crash"
    if rc == 0:
        return "ok" if out_exists and png_exists else "silent"
    if out_exists or png_exists or temps:
        return "partial"
    if not stderr.strip():
        return "silent"
    return "refused" if rc == 2 else "failed"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--radray", default="build/radray")
    ap.add_argument("--count", type=int, default=300)
    ap.add_argument("--timeout", type=float, default=15.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--verbose", action="store_true", help="print every run")
    ap.add_argument("--keep", default=None, help="folder for the inputs that crash, hang, fail silently or leave partial output")
    ap.add_argument("--scene", default=None, help="mutate only this scene of scenes/ (e.g. csg.json), no meshes")
    a = ap.parse_args()
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    radray = os.path.abspath(a.radray)
    scenes = sorted(os.path.join(root, "scenes", f) for f in os.listdir(os.path.join(root, "scenes"))
                    if f.endswith(".json"))
    meshes = sorted(os.path.join(root, "scenes", "meshes", f) for f in os.listdir(os.path.join(root, "scenes", "meshes")))
    if a.scene:
        scenes = [s for s in scenes if os.path.basename(s) == a.scene]
        if not scenes:
            ap.error("--scene: no scenes/%s" % a.scene)
    rng = random.Random(a.seed)
    counts = {}
    bad = []
    work = tempfile.mkdtemp(prefix="radray-mutate-")
    t0 = time.time()
    for k in range(a.count):
        d = os.path.join(work, "run")
        shutil.rmtree(d, ignore_errors=True)
        os.makedirs(os.path.join(d, "meshes"))
        for m in meshes:
            shutil.copy(m, os.path.join(d, "meshes"))
        if k % 3 == 2 and meshes and not a.scene:  # a mutated mesh under an intact scene
            m = meshes[k // 3 % len(meshes)]
            target = os.path.join(d, "meshes", os.path.basename(m))
            with open(m, "rb") as f:
                data = mutate(f.read(), rng)
            with open(target, "wb") as f:
                f.write(data)
            ext = os.path.splitext(m)[1]
            scene = ('{"format":"radray-scene/1","camera":{"type":"lookat","eye":[0,1,4],"target":[0,0,0],'
                     '"up":[0,1,0],"fov":50,"width":24,"height":24},"materials":{"a":{"diffuse":[0.6,0.6,0.6]},'
                     '"e":{"emission":[4,4,4]}},"lights":[{"type":"point","position":[1,3,2],"intensity":4}],'
                     '"objects":[{"type":"mesh","name":"m","material":"a","file":"meshes/%s"},'
                     '{"type":"quad","name":"lamp","material":"e","vertices":[[-1,3,-1],[-1,3,1],[1,3,1],[1,3,-1]]}]}'
                     % os.path.basename(m))
            src = "mesh " + os.path.basename(m)
            del ext
        else:
            s = scenes[k % len(scenes)]
            with open(s, "rb") as f:
                scene = mutate(f.read(), rng).decode("latin-1")
            src = "scene " + os.path.basename(s)
        sp = os.path.join(d, "in.json")
        with open(sp, "w", encoding="latin-1") as f:
            f.write(scene)
        out = os.path.join(d, "o", "out.exr")
        cmd = [radray, "render", sp, "--width", "24", "--spp", "1", "-q", "-o", out]
        timed_out = False
        try:
            p = subprocess.run(cmd, capture_output=True, timeout=a.timeout, cwd=d)
            rc, err = p.returncode, p.stderr.decode("utf-8", "replace")
        except subprocess.TimeoutExpired:
            rc, err, timed_out = -999, "", True
        odir = os.path.join(d, "o")
        temps = [f for f in os.listdir(odir) if ".tmp-" in f] if os.path.isdir(odir) else []
        c = classify(rc, os.path.exists(out), os.path.exists(out[:-4] + ".png"), temps, err, timed_out)
        counts[c] = counts.get(c, 0) + 1
        if a.verbose:
            print("#%d (%s): %s, exit %d: %s" % (k, src, c, rc, err.strip()[:160]))
        if c in ("crash", "hang", "silent", "partial"):
            bad.append((k, src, c, rc, err.strip()[:200]))
            if a.keep:
                os.makedirs(a.keep, exist_ok=True)
                shutil.copytree(d, os.path.join(a.keep, "case-%03d-%s" % (k, c)))
    shutil.rmtree(work, ignore_errors=True)
    print("%d inputs in %.0f s (seed %d, %.0f s limit each): %s" % (
        a.count, time.time() - t0, a.seed, a.timeout, ", ".join("%s %d" % kv for kv in sorted(counts.items()))))
    for k, src, c, rc, err in bad:
        print("  #%d (%s): %s, exit %d: %s" % (k, src, c, rc, err))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
