#!/usr/bin/env python3
"""Render the references of scenes/real/ with the real pbrt-v3.

Usage: python3 tools/render_real_references.py [NAME ...]   (default: every scene there)

Each scene is rendered as it is written — its own Sampler, sample count, resolution and pixel
filter — because pbrt-v3's image depends on them beyond noise: it scales the ray differentials
by 1/sqrt(spp), so texture filtering, bump steps and noise octaves change with the sample
count and the resolution. A temporary copy beside the scene changes only the Film's output
to a float32 PFM; `../shared/tools/pbrt-v3/pbrt --quiet --nthreads 2` renders it, and
`penumbra convert` (target/release/penumbra) writes tests/data/real-references/NAME.exr
(float32). pbrt-v3's wall time goes to tests/data/real-references/timings.tsv.
Needs `../shared` beside the repository and a release build of penumbra.
"""
import os, re, subprocess, sys, tempfile, time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PBRT = os.path.join(ROOT, "..", "shared", "tools", "pbrt-v3", "pbrt")
PENUMBRA = os.path.join(ROOT, "target", "release", "penumbra")
SCENES = os.path.join(ROOT, "scenes", "real")
OUT = os.path.join(ROOT, "tests", "data", "real-references")


def main():
    names = sys.argv[1:] or sorted(f[:-5] for f in os.listdir(SCENES) if f.endswith(".pbrt"))
    os.makedirs(OUT, exist_ok=True)
    tsv = os.path.join(OUT, "timings.tsv")
    rows = {}
    if os.path.exists(tsv):
        for line in open(tsv).read().splitlines()[1:]:
            rows[line.split("\t")[0]] = line
    for name in names:
        scene = os.path.join(SCENES, name + ".pbrt")
        text = open(scene).read()
        with tempfile.TemporaryDirectory() as tmp:
            pfm = os.path.join(tmp, name + ".pfm")
            copy, n = re.subn(r'(Film "image"[^\n]*"string filename" )"[^"]*"', lambda m: m.group(1) + f'"{pfm}"', text)
            assert n == 1, f"{name}: expected one Film filename"
            path = os.path.join(SCENES, f".{name}.ref.pbrt")
            open(path, "w").write(copy)
            try:
                t = time.time()
                subprocess.run(["nice", "-n", "10", PBRT, "--quiet", "--nthreads", "2", path], check=True)
                seconds = time.time() - t
            finally:
                os.remove(path)
            subprocess.run([PENUMBRA, "convert", pfm, os.path.join(OUT, name + ".exr")], check=True)
        spp = re.search(r'"integer pixelsamples" \[ *(\d+) *\]', text).group(1)
        xres = re.search(r'"integer xresolution" \[ *(\d+) *\]', text).group(1)
        yres = re.search(r'"integer yresolution" \[ *(\d+) *\]', text).group(1)
        rows[name] = f"{name}\t{spp}\t{xres}x{yres}\t{seconds:.1f}"
        print(rows[name], flush=True)
    with open(tsv, "w") as f:
        f.write("name\tspp\tresolution\tpbrt_seconds\n")
        for k in sorted(rows):
            f.write(rows[k] + "\n")


if __name__ == "__main__":
    main()
