#!/usr/bin/env python3
"""sheared-ao against ambientocclusion as rays get dearer: the scene of
tools/sheared_ao_crossover_scene.py at several loopsubdiv levels (same limit surface, 3 x 20 x 4^L
triangles), 64², 4 spp halton, seed 0, one thread (docs/integrators/sheared-ao.md, "Crossover
against triangle count").

Error: RMSE against ambientocclusion with 1024 rays per camera sample on the same camera samples
("same-sample MC", as tools/sheared_ao_table.py). Cost: callgrind instructions of the whole
process minus those of the same command at 1x1 pixel, 1 spp (parse, tessellation, BVH): the
render's own instructions. ambientocclusion at nsamples 16 and 64 gives its cost as a + b·N and
its error as c·N^-1/2 (fitted through the two), so the N and the instructions at which it reaches
sheared-ao's error are interpolated.

    python3 tools/sheared_ao_crossover.py [levels...]   (default 2 4 5 7; needs valgrind)
"""
import concurrent.futures as cf
import math
import os
import re
import struct
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.environ.get("PENUMBRA", os.path.join(ROOT, "target/release/penumbra"))
OUT = os.environ.get("OUT", "/tmp/shao-crossover")
COMMON = ["--spp", "4", "--resolution", "64x64", "--threads", "1", "--seed", "0"]


def pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        n = 3 if kind == b"PF" else 1
        v = struct.unpack(("<" if scale < 0 else ">") + "f" * (w * h * n), f.read())
    return [v[i * n] for i in range(w * h)]


def run(scene, tag, args, cg=False):
    out = os.path.join(OUT, f"{tag}.pfm")
    cmd = [BIN, "render", scene, *args, "-o", out]
    if cg:
        cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={OUT}/{tag}.cg", *cmd]
    r = subprocess.run(cmd, capture_output=True, text=True, check=True)
    if cg:
        return int(re.search(r"Collected : (\d+)", r.stderr).group(1))
    return pfm(out)


def main():
    levels = [int(a) for a in sys.argv[1:]] or [2, 4, 5, 7]
    os.makedirs(OUT, exist_ok=True)
    print("| triangles | sheared-ao RMSE | its G Ir | AO Ir per ray | AO rays for that RMSE | AO G Ir there | ratio |")
    print("|---|---|---|---|---|---|---|")
    for L in levels:
        scene = os.path.join(OUT, f"crossover-{L}.pbrt")
        with open(scene, "w") as f:
            subprocess.run([sys.executable, os.path.join(ROOT, "tools/sheared_ao_crossover_scene.py"), str(L)],
                           stdout=f, check=True)
        ao = ["-i", "ambientocclusion", "--param"]
        jobs = {
            "base": (["-i", "ambientocclusion", "--spp", "1", "--resolution", "1x1", "--threads", "1"], True),
            "shao": (["-i", "sheared-ao", *COMMON], True),
            "ao16": ([*ao, "nsamples=16", *COMMON], True),
            "ao64": ([*ao, "nsamples=64", *COMMON], True),
        }
        with cf.ThreadPoolExecutor(2) as ex:
            ir = dict(zip(jobs, ex.map(lambda k: run(scene, f"L{L}-{k}", *jobs[k]), jobs)))
        ref = run(scene, f"L{L}-ref", [*ao, "nsamples=1024", *COMMON[:-4], "--threads", "2", "--seed", "0"])
        img = {k: run(scene, f"L{L}-{k}", jobs[k][0]) for k in ("shao", "ao16", "ao64")}
        rmse = {k: math.sqrt(sum((a - b) ** 2 for a, b in zip(v, ref)) / len(ref)) for k, v in img.items()}
        cost = {k: ir[k] - ir["base"] for k in ("shao", "ao16", "ao64")}
        b = (cost["ao64"] - cost["ao16"]) / (48 * 64 * 64 * 4)  # per occlusion ray
        a = cost["ao16"] - 16 * b * 64 * 64 * 4
        # RMSE = c N^-p through the two AO points
        p = math.log(rmse["ao16"] / rmse["ao64"]) / math.log(4)
        n_eq = 16 * (rmse["ao16"] / rmse["shao"]) ** (1 / p)
        ao_eq = a + b * n_eq * 64 * 64 * 4
        print(f"| {3 * 20 * 4 ** L + 2} | {rmse['shao']:.4f} | {cost['shao'] / 1e9:.3f} | {b:.0f} | {n_eq:.0f} "
              f"(AO RMSE {rmse['ao16']:.4f} @16, {rmse['ao64']:.4f} @64) | {ao_eq / 1e9:.3f} | "
              f"{cost['shao'] / ao_eq:.2f} |", flush=True)


if __name__ == "__main__":
    main()
