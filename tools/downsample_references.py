#!/usr/bin/env python3
"""Box-downsample the pbrt-v3 reference renders in ../shared/references into tests/data/references.

Usage: python3 tools/downsample_references.py [FACTOR]   (default 4: 256x256 -> 64x64)

Box-downsampling is exact for a box pixel filter (the references use one) and divides the
per-pixel noise by about FACTOR. The references were rendered by the real pbrt-v3 (see
tests/data/references/README.md for provenance); needs `pip install OpenEXR numpy`.
"""
import os, shutil, sys
import numpy as np
import OpenEXR

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
src = os.path.join(root, "..", "shared", "references")
dst = os.path.join(root, "tests", "data", "references")
k = int(sys.argv[1]) if len(sys.argv) > 1 else 4

for folder in sorted(os.listdir(src)):
    sdir = os.path.join(src, folder)
    if not os.path.isdir(sdir):
        continue
    os.makedirs(os.path.join(dst, folder), exist_ok=True)
    for name in sorted(os.listdir(sdir)):
        path = os.path.join(sdir, name)
        if name.endswith(".tsv"):
            shutil.copy(path, os.path.join(dst, folder, name))
            continue
        if not name.endswith(".exr"):
            continue
        with OpenEXR.File(path) as f:
            ch = f.channels()
            rgb = np.stack([np.asarray(ch[c].pixels, dtype=np.float64) for c in "RGB"], axis=-1) if "R" in ch else np.asarray(ch["RGB"].pixels, dtype=np.float64)
        h, w, _ = rgb.shape
        small = rgb[: h - h % k, : w - w % k].reshape(h // k, k, w // k, k, 3).mean(axis=(1, 3)).astype(np.float32)
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
                  "comments": f"box-downsampled {k}x{k} from pbrt-v3 reference {folder}/{name}"}
        channels = {c: OpenEXR.Channel(np.ascontiguousarray(small[:, :, i])) for i, c in enumerate("RGB")}
        out = os.path.join(dst, folder, name)
        with OpenEXR.File(header, channels) as o:
            o.write(out)
        print(out, small.shape, float(small.mean()))
shutil.copy(os.path.join(src, "README.md"), os.path.join(dst, "PBRT_README.md"))
