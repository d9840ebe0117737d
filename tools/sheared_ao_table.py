#!/usr/bin/env python3
"""The `sheared-ao` measurement table (README, integrators/src/sheared_ao/mod.rs): error and
rays of `sheared-ao` at several `nsamples` and of `ambientocclusion` at several `nsamples`, on
`scenes/suite/ao/*` at 64x64, 4 spp (halton, seed 0), one thread.

Two errors per render:
  * against pbrt-v3's 4096-spp reference (tests/data/references/ao/<scene>.ambientocclusion.exr):
    image-mean difference and RMSE. At 4 spp the RMSE is dominated by anti-aliasing of the
    geometry (the camera samples), the same for every estimator;
  * against `ambientocclusion` with 1024 rays per camera sample *on the same camera samples*
    (the integrators draw the same film, time and lens dimensions): the AO estimator's own error,
    which is what `nsamples` trades against rays. `bias` is the image-mean difference.
Rays per pixel are `shadow_rays` (occlusion rays, both passes) from stats.json.

Usage: tools/sheared_ao_table.py [BINARY] [OUTDIR]   (defaults: target/release/penumbra, /tmp/shao-table)
Needs numpy. Renders are cached in OUTDIR; delete it to re-render.
"""
import json
import os
import subprocess
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "target/release/penumbra")
OUT = sys.argv[2] if len(sys.argv) > 2 else "/tmp/shao-table"
RES, SPP = 64, 4


def pfm(path):
    with open(path, "rb") as f:
        f.readline()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")
    return data.reshape(h, w, -1)[..., 0].astype(np.float64)


def render(scene, integrator, params):
    tag = f"{scene}.{integrator}." + ".".join(p.replace("=", "") for p in params)
    out = os.path.join(OUT, tag + ".pfm")
    if not os.path.exists(out):
        cmd = [BIN, "render", os.path.join(ROOT, f"scenes/suite/ao/{scene}.pbrt"), "-i", integrator,
               "--spp", str(SPP), "--resolution", f"{RES}x{RES}", "--threads", "1", "--seed", "0", "-o", out]
        for p in params:
            cmd += ["--param", p]
        subprocess.run(cmd, check=True, capture_output=True)
    stats = json.load(open(out[:-4] + ".stats.json"))["stats"]
    return pfm(out), stats


def reference(scene):
    out = os.path.join(OUT, f"{scene}.pbrt-v3.pfm")
    if not os.path.exists(out):
        ref = os.path.join(ROOT, f"tests/data/references/ao/{scene}.ambientocclusion.exr")
        subprocess.run([BIN, "convert", ref, out], check=True, capture_output=True)
    return pfm(out)


def main():
    os.makedirs(OUT, exist_ok=True)
    print("| scene | integrator | nsamples | shadow rays/px | bias vs same-sample MC | RMSE vs same-sample MC"
          " | mean vs pbrt-v3 | RMSE vs pbrt-v3 | brute-forced cells |")
    print("|---|---|---|---|---|---|---|---|---|")
    for scene in ["spheres-on-plane", "blinds"]:
        ref = reference(scene)
        same, _ = render(scene, "ambientocclusion", ["nsamples=1024"])
        runs = [("sheared-ao", n) for n in (4, 8, 16, 32)] + [("ambientocclusion", n) for n in (8, 32, 64, 128, 256)]
        for integrator, n in runs:
            img, st = render(scene, integrator, [f"nsamples={n}"])
            px = RES * RES
            brute = st["counters"].get("brute_cell_fraction")
            print(f"| {scene} | {integrator} | {n} | {st['shadow_rays'] / px:.1f} "
                  f"| {100 * (img.mean() / same.mean() - 1):+.3f} % | {np.sqrt(((img - same) ** 2).mean()):.4f} "
                  f"| {100 * (img.mean() / ref.mean() - 1):+.3f} % | {np.sqrt(((img - ref) ** 2).mean()):.4f} "
                  f"| {'' if brute is None else f'{brute:.3f}'} |", flush=True)


if __name__ == "__main__":
    main()
