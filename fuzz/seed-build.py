#!/usr/bin/env python3
"""Seeds for the `scene_build` fuzz target: every suite and public scene that is one file (no Include)
and at most 64 KiB with its PLY,
as `scene text` or, for one that reads a PLY mesh, `scene text with the filename "mesh.ply"`,
a NUL byte and that PLY's bytes. Writes fuzz/corpus/scene_build/ (run from anywhere)."""
import pathlib
import re

MAX_LEN = 1 << 16
root = pathlib.Path(__file__).resolve().parent.parent
out = root / "fuzz" / "corpus" / "scene_build"
out.mkdir(parents=True, exist_ok=True)
n = 0
for scene in sorted(root.glob("scenes/**/*.pbrt")):
    text = scene.read_bytes()
    if b"Include" in text or b"Import" in text:
        continue
    plys = re.findall(rb'"string filename"\s*\[?\s*"([^"]+\.ply)"', text)
    data = text
    if plys:
        ply = scene.parent / plys[0].decode()
        if not ply.is_file() or ply.stat().st_size > 1 << 20:
            continue
        data = text.replace(b'"' + plys[0] + b'"', b'"mesh.ply"') + b"\0" + ply.read_bytes()
    if len(data) > MAX_LEN:
        continue  # the smoke run's -max_len: large meshes make slow inputs, not new paths
    (out / scene.relative_to(root).as_posix().replace("/", "_")).write_bytes(data)
    n += 1
print(f"{n} seeds in {out}")
