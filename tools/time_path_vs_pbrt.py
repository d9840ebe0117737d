#!/usr/bin/env python3
"""Whole-process wall time of penumbra's `path` against pbrt-v3's, same scene, same spp, 2 threads.

Usage: python3 tools/time_path_vs_pbrt.py [RUNS]   (default 3; run from anywhere, at normal priority)

Each case is a temporary copy of a public scene beside it with the `Sampler` count and the `Film`
resolution set (tools/render_path_references.py's rewrite, keeping the scene's own filter);
`../shared/tools/pbrt-v3/pbrt --quiet --nthreads 2` and `target/release/penumbra render --threads 2
--quiet` render that same file, interleaved (pbrt-v3, penumbra, pbrt-v3, ...). Prints every time,
the medians and penumbra's time over pbrt-v3's. Build penumbra first: `cargo build --release`.
"""
import os, statistics, subprocess, sys, tempfile, time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from render_path_references import PBRT, ROOT, rewrite  # noqa: E402

PENUMBRA = os.path.join(ROOT, "target", "release", "penumbra")
# (name, scene under scenes/public, spp, resolution)
CASES = [
    ("cornell-box", "wumpf-lightdam/scenes/cornell-box/scene.pbrt", 16, 256),
    ("killeroo-simple", "mmp-pbrt-v3/scenes/killeroo-simple.pbrt", 16, 256),
]


def wall(cmd):
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main():
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    for name, rel, spp, res in CASES:
        scene = os.path.join(ROOT, "scenes", "public", rel)
        with tempfile.TemporaryDirectory() as tmp:
            copy = os.path.join(os.path.dirname(scene), f"_time_{name}.pbrt")
            with open(copy, "w") as f:
                f.write(rewrite(open(scene).read(), spp, res, os.path.join(tmp, "pbrt.pfm"), None, box_filter=False))
            pbrt = [PBRT, "--quiet", "--nthreads", "2", copy]
            ours = [PENUMBRA, "render", copy, "--threads", "2", "--quiet", "-o", os.path.join(tmp, "penumbra.exr")]
            try:
                times = {"pbrt-v3": [], "penumbra": []}
                for _ in range(runs):
                    times["pbrt-v3"].append(wall(pbrt))
                    times["penumbra"].append(wall(ours))
            finally:
                os.remove(copy)
        med = {k: statistics.median(v) for k, v in times.items()}
        print(f"{name} {res}x{res} {spp} spp, 2 threads: pbrt-v3 {['%.2f' % t for t in times['pbrt-v3']]} "
              f"median {med['pbrt-v3']:.2f} s; penumbra {['%.2f' % t for t in times['penumbra']]} "
              f"median {med['penumbra']:.2f} s; penumbra / pbrt-v3 = {med['penumbra'] / med['pbrt-v3']:.2f}", flush=True)


if __name__ == "__main__":
    main()
