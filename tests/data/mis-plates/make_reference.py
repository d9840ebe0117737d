#!/usr/bin/env python3
"""Render the mis-plates reference with the real pbrt-v3 (issue 42).

Usage: python3 tests/data/mis-plates/make_reference.py [--spp N] [--keep FILE.pfm]
(default 128 spp).

scenes/mis-plates/mis-plates.pbrt with its Sampler set to N samples and its Film to a float32
.pfm; `../shared/tools/pbrt-v3/pbrt --quiet --nthreads 1` renders the 256x192 image with
pbrt-v3's `directlighting` (strategy all, maxdepth 1, box filter); the image is box-averaged
over 8x8 pixel blocks and the 32x24 image of block means is written as reference-blocks8.pfm
(float32; the image mean is its mean). Pure Python (no numpy); needs `../shared` beside the
repository.
"""
import os, struct, subprocess, sys, tempfile, time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(HERE)))
PBRT = os.path.join(ROOT, "..", "shared", "tools", "pbrt-v3", "pbrt")
SCENE = os.path.join(ROOT, "scenes", "mis-plates", "mis-plates.pbrt")
W, H, BLOCK = 256, 192, 8


def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        fmt = "<" if scale < 0 else ">"
        data = struct.unpack(fmt + "f" * (w * h * 3), f.read(w * h * 12))
    assert kind == b"PF"
    # PFM rows run bottom to top.
    rows = [data[(h - 1 - y) * w * 3:(h - y) * w * 3] for y in range(h)]
    return w, h, rows


def write_pfm(path, w, h, rows):
    with open(path, "wb") as f:
        f.write(b"PF\n%d %d\n-1.0\n" % (w, h))
        for y in reversed(range(h)):
            f.write(struct.pack("<" + "f" * (w * 3), *rows[y]))


def main():
    spp, keep = 128, None
    args = sys.argv[1:]
    while args:
        a = args.pop(0)
        if a == "--spp":
            spp = int(args.pop(0))
        elif a == "--keep":
            keep = args.pop(0)
    text = open(SCENE).read()
    text = text.replace('"integer pixelsamples" [ 16 ]', f'"integer pixelsamples" [ {spp} ]')
    with tempfile.TemporaryDirectory() as tmp:
        pfm = keep or os.path.join(tmp, "full.pfm")
        text = text.replace('"string filename" [ "mis-plates.exr" ]', f'"string filename" [ "{pfm}" ]')
        scene = os.path.join(tmp, "scene.pbrt")
        open(scene, "w").write(text)
        t0 = time.time()
        subprocess.run([PBRT, "--quiet", "--nthreads", "1", scene], check=True)
        secs = time.time() - t0
        w, h, rows = read_pfm(pfm)
    assert (w, h) == (W, H)
    bw, bh = W // BLOCK, H // BLOCK
    out = []
    for by in range(bh):
        row = []
        for bx in range(bw):
            for c in range(3):
                s = sum(rows[y][x * 3 + c] for y in range(by * BLOCK, (by + 1) * BLOCK)
                        for x in range(bx * BLOCK, (bx + 1) * BLOCK))
                row.append(s / (BLOCK * BLOCK))
        out.append(row)
    write_pfm(os.path.join(HERE, "reference-blocks8.pfm"), bw, bh, out)
    mean = sum(sum(r) for r in out) / (bw * bh * 3)
    print(f"{spp} spp, {secs:.1f} s (pbrt-v3, 1 thread, under load), mean {mean:.6f}")


if __name__ == "__main__":
    main()
