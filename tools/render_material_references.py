#!/usr/bin/env python3
"""Render the material reference images (`disney`, `fourier`, `hair`, `subsurface`) with the real
pbrt-v3. Python standard library only.

Usage: python3 tools/render_material_references.py [NAME ...]   (default: every case below)

Each case renders `scenes/materials/SCENE.pbrt` (128x32, box filter, halton) with
`../shared/tools/pbrt-v3/pbrt --quiet --nthreads 2`, from a temporary copy beside the scene (so its
`Include` and `.bsdf` paths resolve as pbrt-v3 resolves them) in which only what pbrt-v3 has no
flag for is changed: the sampler's `pixelsamples`, the `Integrator` line and the output file
(float32 `.pfm`). pbrt-v3's PFM is kept as written, at tests/data/material-references/NAME.pfm;
the case, its sample count and pbrt-v3's wall time go to tests/data/material-references/timings.tsv.
Needs `../shared` beside the repository.
"""
import os, re, subprocess, sys, time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PBRT = os.path.join(ROOT, "..", "shared", "tools", "pbrt-v3", "pbrt")
OUT = os.path.join(ROOT, "tests", "data", "material-references")

# (name, scene under scenes/materials, Integrator directive, spp)
CASES = [
    ("disney-reflection-dl", "disney-reflection", 'Integrator "directlighting"', 4096),
    ("disney-reflection-path", "disney-reflection", 'Integrator "path"', 4096),
    ("disney-transmission-dl", "disney-transmission", 'Integrator "directlighting"', 4096),
    ("disney-transmission-path", "disney-transmission", 'Integrator "path"', 4096),
    ("fourier-dl", "fourier", 'Integrator "directlighting"', 512),
    ("fourier-path", "fourier", 'Integrator "path"', 2048),
    ("hair-dl", "hair", 'Integrator "directlighting"', 4096),
    ("hair-path", "hair", 'Integrator "path"', 1024),
    ("subsurface-dl", "subsurface", 'Integrator "directlighting"', 1024),
    ("subsurface-path", "subsurface", 'Integrator "path"', 1024),
]


def rewrite(text, spp, integrator, out):
    text = re.sub(r'"integer pixelsamples"\s*\[\s*\d+\s*\]', f'"integer pixelsamples" [{spp}]', text)
    text = re.sub(r'^Integrator\s+"[^"]*".*$', integrator, text, flags=re.M)
    return re.sub(r'"string filename"\s*"[^"]*"', f'"string filename" "{out}"', text)


def main():
    names = sys.argv[1:]
    os.makedirs(OUT, exist_ok=True)
    tsv = os.path.join(OUT, "timings.tsv")
    rows = {}
    if os.path.exists(tsv):
        for line in open(tsv).read().splitlines()[1:]:
            rows[line.split("\t")[0]] = line
    for name, scene, integrator, spp in CASES:
        if names and name not in names:
            continue
        src = os.path.join(ROOT, "scenes", "materials", scene + ".pbrt")
        out = os.path.join(OUT, name + ".pfm")
        copy = os.path.join(os.path.dirname(src), f"_ref_{name}.pbrt")
        with open(copy, "w") as f:
            f.write(rewrite(open(src).read(), spp, integrator, out))
        try:
            t0 = time.time()
            subprocess.run(["nice", "-n", "10", PBRT, "--quiet", "--nthreads", "2", copy], check=True)
            seconds = time.time() - t0
        finally:
            os.remove(copy)
        rows[name] = f"{name}\t{scene}\t{integrator.split()[1].strip(chr(34))}\t{spp}\t{seconds:.1f}"
        print(rows[name], flush=True)
        # After every case, so that an interrupted run keeps what it finished.
        with open(tsv, "w") as f:
            f.write("name\tscene\tintegrator\tspp\tpbrt_seconds\n")
            for case, *_ in CASES:
                if case in rows:
                    f.write(rows[case] + "\n")


if __name__ == "__main__":
    main()
