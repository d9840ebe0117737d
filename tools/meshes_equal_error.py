#!/usr/bin/env python3
"""Equal-error time of `silhouette` and `sheared-ao` against the ray tracers on mesh-heavy
scenes under an environment (issues 37 item 2 and 38 item 2), generated from `penumbra sweep`.

    python3 tools/meshes_equal_error.py --references REF    # pbrt-v3 ground truth (minutes)
    python3 tools/meshes_equal_error.py --run OUT REF [NAME]  # the sweeps (quiet machine!)
    python3 tools/meshes_equal_error.py OUT > docs/integrators/meshes-equal-error.md

Scenes (256², 2 threads): scenes/meshes/killeroos-sky (66.5k triangles, uniform white sky:
`silhouette --param mode=ao` and `sheared-ao` against `ambientocclusion --param nsamples=1`,
pbrt-v3's `ambientocclusion` value), scenes/meshes/staircase-sky (12 box steps and a wall, the
same three), scenes/meshes/killeroos-studio (the studio map: `silhouette`'s default `shade`
against `directlighting`) and, for `sheared-ao` against `ambientocclusion`, the suite's
scenes/suite/ao/blinds and spheres-on-plane (their references: ../shared/references/ao/); and
`silhouette` on killeroos-sky against `ambientocclusion --param nsamples=64` on a copy of the
scene with `Sampler "random"` (independent rays, the paper's kind of QMC: VARIANTS).
References: the real pbrt-v3 (../shared/tools/pbrt-v3/pbrt) at 4096 spp (`ambientocclusion`
nsamples 1, cossample) and 1024 spp (studio, `directlighting`), written as PFM and converted to
EXR by `penumbra convert` (REF/NAME.exr, 256², for the sweeps; and box-downsampled 4×4 to 64²
into tests/data/references/meshes/, for the tests). Each sweep: `penumbra sweep SCENE
--reference REF/NAME.exr -i INTEGRATOR [--param ...] [--budgets ...] --time-limit T --threads 2
--no-flip`, one integrator per sweep (their `--param`s differ); the time limit bounds the sum
of an integrator's renders.
"""
import json
import os
import re
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from sweeplib import downsample_pfm, time_to  # noqa: E402

EXE = os.environ.get("PENUMBRA", "target/release/penumbra")
PBRT = os.environ.get("PBRT", "../shared/tools/pbrt-v3/pbrt")
# scene, reference spp (None: a suite scene, whose pbrt-v3 reference ../shared/references/ao/
# NAME.ambientocclusion.exr already exists), baseline first: [(label, integrator, params, time
# limit, budgets)] (budgets None: doubling from 1 spp until the time limit)
AO = ("ambientocclusion", "ambientocclusion", ["nsamples=1"], 40, None)
SHEARED = ("sheared-ao", "sheared-ao", [], 40, None)
SCENES = [
    ("killeroos-sky", 4096, [
        ("ambientocclusion", "ambientocclusion", ["nsamples=1"], 150, None),
        ("silhouette", "silhouette", ["mode=ao"], 240, [1, 2, 4, 8, 16, 32]),
        SHEARED,
    ]),
    ("staircase-sky", 4096, [
        AO,
        ("silhouette", "silhouette", ["mode=ao"], 40, [1, 2, 4, 8, 16]),
        SHEARED,
    ]),
    ("killeroos-studio", 1024, [
        ("directlighting", "directlighting", [], 200, None),
        ("silhouette", "silhouette", [], 260, [1, 2, 4, 8, 16]),
    ]),
    ("blinds", None, [AO, SHEARED]),
    ("spheres-on-plane", None, [AO, SHEARED]),
]
# The paper's QMC used "independent sampling sets at each pixel": the same scene with the
# sampler replaced by pbrt-v3's "random" (independent uniform samples; a copy next to the
# original, with only that line changed), against which the listed integrators' renders of
# the original are compared: (scene, sampler, baseline (label, integrator, params, time
# limit, budgets), the integrators' labels).
VARIANTS = [
    ("killeroos-sky", "random",
     ("ambientocclusion-random", "ambientocclusion", ["nsamples=64"], 300, None), ["silhouette"]),
]


def scene_path(name, spp):
    return f"scenes/meshes/{name}.pbrt" if spp else f"scenes/suite/ao/{name}.pbrt"


def reference_path(ref, name, spp):
    return f"{ref}/{name}.exr" if spp else f"../shared/references/ao/{name}.ambientocclusion.exr"


def references(ref):
    """Render pbrt-v3's ground truth for every scene into REF/NAME.exr (and the 64² copies)."""
    os.makedirs(ref, exist_ok=True)
    for name, spp, _ in SCENES:
        if spp is None:
            continue
        path = scene_path(name, spp)
        text = open(path).read()
        with tempfile.TemporaryDirectory() as tmp:
            pfm = os.path.join(tmp, name + ".pfm")
            text = re.sub(r'"integer pixelsamples" \[ \d+ \]', f'"integer pixelsamples" [ {spp} ]', text)
            text = re.sub(r'"string filename" \[ "[^"]*" \]', f'"string filename" [ "{pfm}" ]', text)
            # Next to the original, so that its relative includes and map resolve.
            copy = os.path.join("scenes/meshes", f".ref-{name}.pbrt")
            open(copy, "w").write(text)
            try:
                subprocess.run([PBRT, "--quiet", "--nthreads", "2", copy], check=True)
            finally:
                os.remove(copy)
            subprocess.run([EXE, "convert", pfm, os.path.join(ref, name + ".exr")], check=True)
            small = os.path.join(tmp, name + ".64.pfm")
            downsample_pfm(pfm, small, 4)
            test_name = name + (".ao" if integrator_of(name) == "ambientocclusion" else "")
            subprocess.run([EXE, "convert", small, f"tests/data/references/meshes/{test_name}.exr"],
                           check=True)


def integrator_of(name):
    return next(runs[0][1] for n, _, runs in SCENES if n == name)


def sweep(scene, reference, out, integrator, params, limit, budgets):
    cmd = [EXE, "sweep", scene, "--reference", reference, "-i", integrator, "--time-limit",
           str(limit), "--threads", "2", "--no-flip", "-q", "-o", out]
    if budgets:
        cmd += ["--budgets", ",".join(map(str, budgets))]
    for p in params:
        cmd += ["--param", p]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)


def run(out, ref, only=None):
    for name, spp, runs in SCENES:
        if only and name != only:
            continue
        for label, integrator, params, limit, budgets in runs:
            sweep(scene_path(name, spp), reference_path(ref, name, spp), f"{out}/{name}/{label}",
                  integrator, params, limit, budgets)
    for name, sampler, (label, integrator, params, limit, budgets), _ in VARIANTS:
        if only and name != only:
            continue
        text = open(scene_path(name, 1)).read()
        text, n = re.subn(r'Sampler "\w+"', f'Sampler "{sampler}"', text)
        assert n == 1, f"{name}: one Sampler line expected"
        copy = os.path.join("scenes/meshes", f".{sampler}-{name}.pbrt")
        open(copy, "w").write(text)
        try:
            sweep(copy, reference_path(ref, name, 1), f"{out}/{name}/{label}", integrator, params,
                  limit, budgets)
        finally:
            os.remove(copy)


def rows(out, name, label):
    return json.load(open(f"{out}/{name}/{label}/sweep.json"))["rows"]


def ticked(params):
    return "".join(f" `{x}`" for x in params)


def compare(out, name, base, runs, against):
    """Table rows: each render of `runs` (label, params) against the sweep `base`."""
    o = rows(out, name, base)
    ox = [r["total_s"] for r in o]
    oy = [r["rmse"] for r in o]
    first = True
    for label, params in runs:
        for r in rows(out, name, label):
            ts, rs, _ = time_to(ox, oy, r, "< its first render")
            print(f"| {name if first else ''} | `{label}`{ticked(params)} | {r['spp']} | "
                  f"{r['rmse']:.3g} | {r['total_s']:.3g} | {against} | {ts} | {rs} |")
            first = False


def renders(out, name, label):
    return ", ".join(f"{r['spp']}: {r['rmse']:.3g} at {r['total_s']:.3g}"
                     for r in rows(out, name, label))


HEADER = ("| scene | integrator | spp | RMSE | time (s) | against | its time to that RMSE (s) "
          "| time ratio |\n|---|---|---|---|---|---|---|---|")


def table(out):
    print(__doc__.split("\n\n")[0].replace('"""', ""))
    print()
    print("Generated by `python3 tools/meshes_equal_error.py OUT` from the sweeps that "
          "`python3 tools/meshes_equal_error.py --run OUT REF` ran (its docstring gives the "
          "commands). Wall times on 2 threads of an otherwise idle 2-core machine; times include "
          "the scene build (`silhouette`'s dual-edge hierarchy and radiance tables, the BVH), not "
          "parsing. For each render of `silhouette` and `sheared-ao`: its RMSE against pbrt-v3, "
          "its time, the time the ray tracer needs for the same RMSE (log-log interpolation "
          "between its two renders that bracket it; ~ marks an extrapolation past its largest "
          "budget) and the ratio of the two (below 1: ahead of the ray tracer).")
    print()
    print(HEADER)
    for name, _, runs in SCENES:
        base = runs[0][0]
        compare(out, name, base, [(r[0], r[2]) for r in runs[1:]], f"`{base}`")
    print()
    print("Against independent rays (the paper's kind of QMC): the same renders against "
          "`ambientocclusion` on the scene with `Sampler \"random\"` in place of its Halton "
          "sampler (a copy with only that line changed).")
    print()
    print(HEADER)
    for name, sampler, (base, _, bparams, _, _), labels in VARIANTS:
        runs = next(r for n, _, r in SCENES if n == name)
        compare(out, name, base, [(r[0], r[2]) for r in runs if r[0] in labels],
                f"`ambientocclusion`{ticked(bparams)}, {sampler} sampler")
    print()
    print("The ray tracers' renders (spp: RMSE at seconds):")
    print()
    for name, _, runs in SCENES:
        label, _, params, _, _ = runs[0]
        print(f"- {name}, `{label}`{ticked(params)}: {renders(out, name, label)}")
    for name, sampler, (label, _, params, _, _), _ in VARIANTS:
        print(f"- {name} with the {sampler} sampler, `ambientocclusion`{ticked(params)}: "
              f"{renders(out, name, label)}")


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--references":
        references(sys.argv[2])
    elif len(sys.argv) in (4, 5) and sys.argv[1] == "--run":
        run(sys.argv[2], sys.argv[3], sys.argv[4] if len(sys.argv) == 5 else None)
    elif len(sys.argv) == 2:
        table(sys.argv[1])
    else:
        sys.exit(__doc__)
