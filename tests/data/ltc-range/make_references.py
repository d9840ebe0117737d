#!/usr/bin/env python3
"""Render the ltc-range references with the real pbrt-v3.

Usage: python3 tests/data/ltc-range/make_references.py [--spp N] [--keep DIR] [CELL ...]
(default: every cell of cells.txt, 4096 spp).

Each cell is template.pbrt with `@FLOOR@` replaced by the cell's material directives (cells.txt),
its `Sampler` set to N samples and its `Film` to a float32 `.pfm`. `../shared/tools/pbrt-v3/pbrt
--quiet --nthreads 2` (niced) renders the 64x64 image with pbrt-v3's `directlighting` (strategy
all, maxdepth 1, box filter); the image is box-averaged over 8x8 pixel blocks and the 8x8 image
of block means is written as refs/CELL.pfm (float32; the image mean is its mean). With --keep,
the full 64x64 render is kept as DIR/CELL.pfm. `timings.tsv` lists each cell's samples and
pbrt-v3's wall time. Needs numpy and `../shared` beside the repository.
"""
import os, subprocess, sys, tempfile, time
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(HERE)))
PBRT = os.path.join(ROOT, "..", "shared", "tools", "pbrt-v3", "pbrt")
RES, BLOCK = 64, 8


def cells():
    out, name = [], None
    for line in open(os.path.join(HERE, "cells.txt")).read().splitlines():
        if line.startswith("## "):
            name = line[3:].strip()
            out.append([name, []])
        elif name is not None and not line.startswith("#"):
            out[-1][1].append(line)
    return [(n, "\n".join(t)) for n, t in out]


def scene_text(floor, spp, pfm):
    text = open(os.path.join(HERE, "template.pbrt")).read().replace("@FLOOR@", floor)
    text = text.replace('"integer pixelsamples" [ 16 ]', f'"integer pixelsamples" [ {spp} ]')
    return text.replace('"string filename" [ "out.exr" ]', f'"string filename" [ "{pfm}" ]')


def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")
    assert kind == b"PF", kind
    return data.reshape(h, w, 3)[::-1].astype(np.float64)  # PFM rows run bottom to top


def write_pfm(path, img):
    h, w, _ = img.shape
    with open(path, "wb") as f:
        f.write(f"PF\n{w} {h}\n-1\n".encode())
        f.write(np.ascontiguousarray(img[::-1], dtype="<f4").tobytes())


def main():
    args, spp, keep = sys.argv[1:], 4096, None
    while args and args[0].startswith("--"):
        if args[0] == "--spp":
            spp, args = int(args[1]), args[2:]
        elif args[0] == "--keep":
            keep, args = args[1], args[2:]
        else:
            sys.exit(f"unknown option {args[0]}")
    os.makedirs(os.path.join(HERE, "refs"), exist_ok=True)
    tsv = os.path.join(HERE, "timings.tsv")
    rows = {}
    if os.path.exists(tsv):
        for line in open(tsv).read().splitlines()[1:]:
            rows[line.split("\t")[0]] = line
    all_cells = cells()
    for name, floor in all_cells:
        if args and name not in args:
            continue
        with tempfile.TemporaryDirectory() as tmp:
            pfm = os.path.join(tmp, name + ".pfm")
            path = os.path.join(tmp, name + ".pbrt")
            open(path, "w").write(scene_text(floor, spp, pfm))
            t0 = time.time()
            subprocess.run(["nice", "-n", "10", PBRT, "--quiet", "--nthreads", "2", path], check=True)
            seconds = time.time() - t0
            img = read_pfm(pfm)
        if keep:
            os.makedirs(keep, exist_ok=True)
            write_pfm(os.path.join(keep, name + ".pfm"), img)
        k = RES // BLOCK
        blocks = img.reshape(k, BLOCK, k, BLOCK, 3).mean(axis=(1, 3))
        write_pfm(os.path.join(HERE, "refs", name + ".pfm"), blocks)
        rows[name] = f"{name}\t{spp}\t{seconds:.1f}"
        print(name, f"mean {blocks.mean():.6f}", f"{seconds:.1f} s", flush=True)
        with open(tsv, "w") as f:
            f.write("cell\tspp\tpbrt_seconds\n")
            for n, _ in all_cells:
                if n in rows:
                    f.write(rows[n] + "\n")


if __name__ == "__main__":
    main()
