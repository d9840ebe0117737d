#!/usr/bin/env python3
"""Render the `path`/`whitted` reference images with the real pbrt-v3 and box-downsample them.

Usage: python3 tools/render_path_references.py [NAME ...]   (default: every case below)

For each case, a temporary copy of the public scene is written beside it (so that its relative
`Include`s and file names resolve as pbrt-v3 resolves them) with only the options pbrt-v3 has no
flag for replaced: `Sampler` (the scene's own type, `pixelsamples` = SPP), `PixelFilter "box"`
(box-downsampling is exact only for a box filter), `Film` (RES x RES, float32 `.pfm`) and, where a
case says so, `Integrator`. `../shared/tools/pbrt-v3/pbrt --quiet --nthreads 2` renders it; the
image is box-downsampled to 64x64 (each output pixel averages (RES/64)^2 pixels, i.e.
(RES/64)^2 * SPP samples) and written as float32 EXR to tests/data/path-references/NAME.exr, and
the case, its sample count and pbrt-v3's wall time go to tests/data/path-references/timings.tsv.
Needs `pip install OpenEXR numpy` and `../shared` beside the repository.
"""
import os, subprocess, sys, tempfile, time
import numpy as np
import OpenEXR

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pbrt_scene import rewrite  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PBRT = os.path.join(ROOT, "..", "shared", "tools", "pbrt-v3", "pbrt")
OUT = os.path.join(ROOT, "tests", "data", "path-references")
OUT_RES = 64

# (name, scene under scenes/public, integrator override or None, spp, render resolution)
CASES = [
    ("cornell-box", "wumpf-lightdam/scenes/cornell-box/scene.pbrt", None, 1024, 128),
    ("killeroo-simple", "mmp-pbrt-v3/scenes/killeroo-simple.pbrt", None, 1024, 128),
    ("glass-whitted", "hackmad-pbrt-v3-rs/scenes/materials/glass.pbrt", None, 256, 128),
    ("mirror-whitted", "hackmad-pbrt-v3-rs/scenes/materials/mirror.pbrt", None, 256, 128),
    ("glass-path", "hackmad-pbrt-v3-rs/scenes/materials/glass.pbrt", "path", 1024, 128),
    ("bump-whitted", "hackmad-pbrt-v3-rs/scenes/materials/bump.pbrt", None, 256, 128),
    ("bump-path", "hackmad-pbrt-v3-rs/scenes/materials/bump.pbrt", "path", 512, 128),
]

def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")
    assert kind == b"PF", kind
    return data.reshape(h, w, 3)[::-1].astype(np.float64)  # PFM rows run bottom to top


def main():
    names = sys.argv[1:]
    os.makedirs(OUT, exist_ok=True)
    tsv = os.path.join(OUT, "timings.tsv")
    rows = {}
    if os.path.exists(tsv):
        for line in open(tsv).read().splitlines()[1:]:
            rows[line.split("\t")[0]] = line
    for name, rel, integrator, spp, res in CASES:
        if names and name not in names:
            continue
        scene = os.path.join(ROOT, "scenes", "public", rel)
        with tempfile.TemporaryDirectory() as tmp:
            pfm = os.path.join(tmp, name + ".pfm")
            copy = os.path.join(os.path.dirname(scene), f"_ref_{name}.pbrt")
            with open(copy, "w") as f:
                f.write(rewrite(open(scene).read(), spp, res, pfm, integrator))
            try:
                t0 = time.time()
                subprocess.run([PBRT, "--quiet", "--nthreads", "2", copy], check=True)
                seconds = time.time() - t0
            finally:
                os.remove(copy)
            img = read_pfm(pfm)
        k = res // OUT_RES
        small = img.reshape(OUT_RES, k, OUT_RES, k, 3).mean(axis=(1, 3)).astype(np.float32)
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
                  "comments": f"pbrt-v3 13d871f {rel} integrator {integrator or 'scene'} box filter "
                              f"{res}x{res} {spp} spp, box-downsampled {k}x{k}"}
        channels = {c: OpenEXR.Channel(np.ascontiguousarray(small[:, :, i])) for i, c in enumerate("RGB")}
        with OpenEXR.File(header, channels) as o:
            o.write(os.path.join(OUT, name + ".exr"))
        rows[name] = f"{name}\t{rel}\t{integrator or 'scene'}\t{spp}\t{res}\t{seconds:.1f}"
        print(name, small.shape, float(small.mean()), f"{seconds:.1f} s", flush=True)
    with open(tsv, "w") as f:
        f.write("name\tscene\tintegrator\tspp\tresolution\tpbrt_seconds\n")
        for name, *_ in CASES:
            if name in rows:
                f.write(rows[name] + "\n")


if __name__ == "__main__":
    main()
