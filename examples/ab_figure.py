#!/usr/bin/env python3
"""An A/B figure end to end in Python: error against time for two integrators on a suite scene.

    python examples/ab_figure.py                      # directlighting vs ltc on quad-cube
    python examples/ab_figure.py -a path -b directlighting --scene scenes/suite/ltc/torus-nonconvex.pbrt

Renders a reference (directlighting at --reference-spp, another seed), then each integrator at
doubling samples per pixel, timing every render and computing its RMSE against the reference with
numpy; prints the table, writes it as CSV, and plots RMSE against seconds on log-log axes
(ab_figure.png) when matplotlib is installed. `penumbra.sweep` computes the same rows in one call
(the last lines show it).
"""

import argparse
import csv
import time
from pathlib import Path

import numpy as np

import penumbra

ROOT = Path(__file__).resolve().parents[1]


def rmse(a, b):
    return float(np.sqrt(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=ROOT / "scenes/suite/ltc/quad-cube.pbrt", type=Path)
    ap.add_argument("-a", default="directlighting")
    ap.add_argument("-b", default="ltc")
    ap.add_argument("--resolution", default="64x64")
    ap.add_argument("--reference-spp", type=int, default=1024)
    ap.add_argument("--budgets", default="16,32,64,128")
    ap.add_argument("-o", "--output", default="ab_figure", help="writes OUTPUT.csv (and OUTPUT.png)")
    args = ap.parse_args()
    w, h = (int(v) for v in args.resolution.split("x"))
    budgets = [int(b) for b in args.budgets.split(",")]

    scene = penumbra.load(args.scene)  # parsed once, rendered many times
    t0 = time.perf_counter()
    ref = scene.render(integrator="directlighting", spp=args.reference_spp, resolution=(w, h), seed=1)
    print(f"reference: directlighting {ref.spp} spp in {time.perf_counter() - t0:.2f} s")

    rows = []
    for name in (args.a, args.b):
        for spp in budgets:
            t0 = time.perf_counter()
            r = scene.render(integrator=name, spp=spp, resolution=(w, h))
            seconds = time.perf_counter() - t0
            rows.append(dict(integrator=name, spp=r.spp, seconds=seconds,
                             render_s=r.stats["render_seconds"], rmse=rmse(r.image, ref.image)))
            print(f"{name:>16} {r.spp:>6} spp  {seconds:8.3f} s  RMSE {rows[-1]['rmse']:.5f}")

    out = Path(args.output)
    with open(out.with_suffix(".csv"), "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print(f"wrote {out.with_suffix('.csv')} (install matplotlib for the plot)")
    else:
        fig, ax = plt.subplots(figsize=(5, 4))
        for name in (args.a, args.b):
            pts = [(r["seconds"], r["rmse"]) for r in rows if r["integrator"] == name]
            ax.loglog(*zip(*pts), marker="o", label=name)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("RMSE vs reference")
        ax.set_title(args.scene.name)
        ax.legend()
        fig.tight_layout()
        fig.savefig(out.with_suffix(".png"), dpi=120)
        print(f"wrote {out.with_suffix('.csv')} and {out.with_suffix('.png')}")

    # The same measurement in one call: penumbra.sweep's rows (a pandas.DataFrame takes them as they are).
    swept = penumbra.sweep(args.scene, [args.a, args.b], reference=ref.image, budgets=budgets, resolution=(w, h))
    print("sweep:", [(r["integrator"], r["spp"], round(r["rmse"], 5)) for r in swept])


if __name__ == "__main__":
    main()
