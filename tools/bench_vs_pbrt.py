#!/usr/bin/env python3
"""penumbra against pbrt-v3: whole-process wall time, same scene file, same spp, 2 threads each.

Usage: python3 tools/bench_vs_pbrt.py [--runs N] [--rows A,B,...] [--quick] [--accel LIST] [--json OUT]
  --runs N   runs per program and row (default 3), interleaved: pbrt-v3, penumbra, pbrt-v3, ...
  --rows     comma-separated row names or substrings of them (default: every row; --list shows them)
  --quick    a quarter of the samples and half the resolution of every row (checks the script)
  --accel    penumbra's ray-query backends to time, comma-separated (`bvh`, `embree`: a build with
             `--features embree`); each is a column of its own, timed in the same interleaved runs
             (default: the scene's, i.e. bvh)
  --json     also write every time and figure to OUT
Environment: PBRT (default ../shared/tools/pbrt-v3/pbrt beside the repository), PENUMBRA
(default target/dist/penumbra, else target/release/penumbra: build it first with
`cargo build --profile dist --features embree`, or without the feature when Embree is not
installed and --accel is not given), THREADS (2).

Each row is a temporary copy of a scene written beside it (so relative paths resolve) with the
`Sampler` count, the `Film` (resolution, a .pfm file) and, where the row says so, the
`Integrator` replaced (tools/pbrt_scene.py); `pbrt --quiet --nthreads 2 COPY` and
`penumbra render COPY --threads 2 --quiet -o OUT.pfm` render that same file. Printed per row:
median and min–max of each program's wall time, penumbra / pbrt-v3 (medians), and the RMSE of
the two images against each other (`penumbra diff`; equal spp, so this is noise, not bias).
Then penumbra's own figures from the `stats.json` of one more, untimed run with `--phases`: parse, scene and BVH
build seconds, render seconds, rays per second (all queries over render time), and the
per-phase estimates of `stats.phases` (core/src/phase.rs: per-thread counters, about one call in
64 timed): camera-ray generation, camera-ray first hits, other closest hits and shadow queries
(calls, estimated thread-seconds, calls per thread-second), shading and light-sampling seconds.
Run it on a quiet machine at normal priority: the times are only as good as the machine is idle.
"""
import argparse, json, os, statistics, struct, subprocess, sys, tempfile, time

TOOLS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, TOOLS)
from pbrt_scene import rewrite  # noqa: E402

ROOT = os.path.dirname(TOOLS)
PBRT = os.environ.get("PBRT", os.path.join(ROOT, "..", "shared", "tools", "pbrt-v3", "pbrt"))
PENUMBRA = os.environ.get("PENUMBRA") or next(
    (p for p in (os.path.join(ROOT, "target", d, "penumbra") for d in ("dist", "release")) if os.access(p, os.X_OK)),
    os.path.join(ROOT, "target", "release", "penumbra"))
THREADS = os.environ.get("THREADS", "2")
AO1 = '"ambientocclusion" "integer nsamples" [ 1 ]'

# (name, integrator shown, scene (repository-relative; public scenes also found under
# ../shared/scenes/public), spp, resolution, Integrator override or None)
ROWS = [
    ("dl-quad-cube", "directlighting", "scenes/suite/ltc/quad-cube.pbrt", 64, 256, None),
    ("dl-objects-sky-sun", "directlighting", "scenes/suite/env/objects-sky-sun.pbrt", 64, 256, None),
    ("dl-spheres-on-plane", "directlighting", "scenes/suite/ao/spheres-on-plane.pbrt", 64, 256, None),
    ("dl-two-lights-metal", "directlighting", "scenes/suite/ltc/two-lights-metal.pbrt", 16, 256, None),
    ("ao-spheres-on-plane", "ambientocclusion", "scenes/suite/ao/spheres-on-plane.pbrt", 256, 256, AO1),
    ("ao-blinds", "ambientocclusion", "scenes/suite/ao/blinds.pbrt", 256, 256, AO1),
    # Mesh-heavy: two loop-subdivided killeroos (79k triangles).
    ("dl-killeroo", "directlighting", "scenes/public/mmp-pbrt-v3/scenes/killeroo-simple.pbrt", 16, 256,
     '"directlighting"'),
    ("path-killeroo", "path", "scenes/public/mmp-pbrt-v3/scenes/killeroo-simple.pbrt", 16, 256, None),
    ("path-cornell-box", "path", "scenes/public/wumpf-lightdam/scenes/cornell-box/scene.pbrt", 16, 256, None),
    # Startup: parse + build of a generated 2M-triangle binary PLY, rendered at 1 spp, 16x16.
    ("startup-2M-triangles", "directlighting", "@grid2m", 1, 16, None),
]

GRID_N = 1000  # (N+1)^2 vertices, 2 N^2 triangles


def write_grid_scene(tmp):
    """A 2M-triangle height field as a binary little-endian PLY, lit by one distant light."""
    n = GRID_N
    ply = os.path.join(tmp, "grid.ply")
    with open(ply, "wb") as f:
        f.write((f"ply\nformat binary_little_endian 1.0\nelement vertex {(n + 1) ** 2}\n"
                 "property float x\nproperty float y\nproperty float z\n"
                 f"element face {2 * n * n}\nproperty list uchar int vertex_indices\nend_header\n").encode())
        row = struct.Struct("<" + "fff" * (n + 1))
        for j in range(n + 1):
            y = j / n * 2 - 1
            vals = []
            for i in range(n + 1):
                x = i / n * 2 - 1
                vals += (x, y, 0.05 * ((i * 7 + j * 13) % 17) / 17)
            f.write(row.pack(*vals))
        face = struct.Struct("<B3i")
        for j in range(n):
            buf = bytearray()
            for i in range(n):
                v = j * (n + 1) + i
                buf += face.pack(3, v, v + 1, v + n + 2) + face.pack(3, v, v + n + 2, v + n + 1)
            f.write(buf)
    scene = os.path.join(tmp, "grid.pbrt")
    with open(scene, "w") as f:
        f.write('LookAt 0 -3 3  0 0 0  0 0 1\nCamera "perspective" "float fov" [ 40 ]\n'
                'Sampler "halton" "integer pixelsamples" [ 1 ]\n'
                'Integrator "directlighting" "integer maxdepth" [ 1 ]\nWorldBegin\n'
                'LightSource "distant" "point from" [ 1 -1 3 ] "point to" [ 0 0 0 ] "rgb L" [ 3 3 3 ]\n'
                f'Material "matte"\nShape "plymesh" "string filename" [ "{ply}" ]\nWorldEnd\n')
    return scene


def find_scene(rel):
    for base in (ROOT, os.path.join(ROOT, "..", "shared")):
        p = os.path.join(base, rel)
        if rel.startswith("scenes/public/"):
            p = os.path.join(base, "scenes", "public", rel[len("scenes/public/"):])
        if os.path.exists(p):
            return os.path.abspath(p)
    sys.exit(f"bench_vs_pbrt: {rel} not found under {ROOT} or ../shared")


def wall(cmd):
    t0 = time.perf_counter()
    r = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    dt = time.perf_counter() - t0
    if r.returncode != 0:
        sys.exit(f"bench_vs_pbrt: {' '.join(cmd)} failed ({r.returncode}):\n{r.stderr[-2000:]}")
    return dt


def rmse(a, b):
    r = subprocess.run([PENUMBRA, "diff", a, b, "--json", "--no-flip"], capture_output=True, text=True)
    try:
        return json.loads(r.stdout)["rms_error"]
    except (ValueError, KeyError):
        return float("nan")


def stage_seconds(stats, name):
    return sum(s["seconds"] for s in stats.get("build", []) if s["stage"] == name)


def penumbra_figures(stats):
    """The per-phase figures of one penumbra run's stats.json."""
    st = stats["stats"]
    render = st["render_seconds"]
    out = {
        "parse_s": stats.get("parse_seconds", float("nan")),
        "build_s": stats.get("build_seconds", float("nan")),
        "shapes_s": stage_seconds(stats, "shapes"),
        "bvh_s": stage_seconds(stats, "bvh"),
        "render_s": render,
        "camera_samples": st["camera_samples"],
        "rays": st["rays"],
        "shadow_rays": st["shadow_rays"],
        "Mrays_per_s": (st["rays"] + st["shadow_rays"]) / max(render, 1e-9) / 1e6,
    }
    for name, p in st.get("phases", {}).items():
        out[f"{name}_calls"] = p["calls"]
        out[f"{name}_s"] = p["seconds"]
    return out


def fmt_times(ts):
    return f"{statistics.median(ts):.2f} s ({min(ts):.2f}–{max(ts):.2f})"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--rows", default="")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--list", action="store_true")
    ap.add_argument("--accel", default="")
    ap.add_argument("--json")
    args = ap.parse_args()
    accels = [a for a in args.accel.split(",") if a] or [None]
    label = lambda a: "penumbra" if a is None else f"penumbra ({a})"  # noqa: E731
    if args.list:
        for r in ROWS:
            print(f"{r[0]:24} {r[1]:17} {r[2]} {r[3]} spp {r[4]}^2")
        return
    wanted = [w for w in args.rows.split(",") if w]
    rows = [r for r in ROWS if not wanted or any(w in r[0] for w in wanted)]
    if not rows:
        sys.exit(f"bench_vs_pbrt: no row matches {args.rows!r} (--list shows them)")
    for exe in (PBRT, PENUMBRA):
        if not os.access(exe, os.X_OK):
            sys.exit(f"bench_vs_pbrt: {exe} is not an executable (set PBRT / PENUMBRA)")
    print(f"pbrt-v3: {PBRT}\npenumbra: {PENUMBRA}\n{THREADS} threads each, {args.runs} interleaved runs"
          f"{', quick' if args.quick else ''}; wall time of the whole process, median (min–max)\n", flush=True)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        grid = None
        for name, integ, rel, spp, res, override in rows:
            if args.quick:
                spp, res = max(1, spp // 4), max(16, res // 2)
            if rel == "@grid2m":
                grid = grid or write_grid_scene(tmp)
                scene = grid
            else:
                scene = find_scene(rel)
            pb_img, pe_img = os.path.join(tmp, f"{name}.pbrt.pfm"), os.path.join(tmp, f"{name}.penumbra.pfm")
            copy = os.path.join(os.path.dirname(scene), f"_bench_{name}.pbrt")
            with open(copy, "w") as f:
                f.write(rewrite(open(scene).read(), spp, res, pb_img, override, box_filter=False))
            pbrt = [PBRT, "--quiet", "--nthreads", THREADS, copy]
            ours = {a: [PENUMBRA, "render", copy, "--threads", THREADS, "--quiet", "-o", pe_img]
                    + ([] if a is None else ["--accel", a]) for a in accels}
            times = {"pbrt-v3": [], **{label(a): [] for a in accels}}
            try:
                for _ in range(args.runs):
                    times["pbrt-v3"].append(wall(pbrt))
                    for a in accels:
                        times[label(a)].append(wall(ours[a]))
                # One more run of the first backend, untimed, recording where its time goes (--phases).
                wall(ours[accels[0]] + ["--phases"])
            finally:
                os.remove(copy)
            stats = json.load(open(pe_img[: -len(".pfm")] + ".stats.json"))
            med = {k: statistics.median(v) for k, v in times.items()}
            ratios = {label(a): med[label(a)] / med["pbrt-v3"] for a in accels}
            row = {"name": name, "integrator": integ, "scene": rel, "spp": spp, "resolution": res, "times": times,
                   "ratio": ratios[label(accels[0])], "ratios": ratios, "rmse": rmse(pe_img, pb_img),
                   "penumbra": penumbra_figures(stats)}
            results.append(row)
            ours_txt = ", ".join(f"{k} {fmt_times(times[k])}, ratio {v:.2f}" for k, v in ratios.items())
            print(f"{name}: pbrt-v3 {fmt_times(times['pbrt-v3'])}, {ours_txt}, RMSE {row['rmse']:.3g}", flush=True)
    cols = "".join(f" {label(a)} | ratio |" for a in accels)
    print(f"\n| case | spp | pbrt-v3 |{cols} RMSE |\n|---|---|---|{'---|---|' * len(accels)}---|")
    for r in results:
        ours_cells = "".join(f" {fmt_times(r['times'][label(a)])} | {r['ratios'][label(a)]:.2f} |" for a in accels)
        print(f"| `{r['integrator']}` {r['name']} {r['resolution']}² | {r['spp']} | {fmt_times(r['times']['pbrt-v3'])} "
              f"|{ours_cells} {r['rmse']:.3g} |")
    print("\npenumbra per phase (an untimed run with --phases: calls, estimated thread-seconds and rate per thread-second)")
    print("| case | parse s | shapes s | BVH s | render s | M rays/s | camera rays | camera-ray hits | closest hits "
          "| shadow | shading s | light sampling s |\n|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in results:
        p = r["penumbra"]

        def rate(k):
            c, s = p.get(f"{k}_calls"), p.get(f"{k}_s")
            return "–" if c is None else f"{c / 1e6:.2f} M, {s:.2f} s, {c / max(s, 1e-9) / 1e6:.2f} M/s"

        def secs(k):
            return "–" if p.get(f"{k}_s") is None else f"{p[f'{k}_s']:.2f}"

        print(f"| {r['name']} | {p['parse_s']:.3f} | {p['shapes_s']:.3f} | {p['bvh_s']:.3f} | {p['render_s']:.2f} "
              f"| {p['Mrays_per_s']:.2f} | {rate('camera_ray')} | {rate('camera_hit')} | {rate('closest_hit')} | {rate('shadow')} "
              f"| {secs('shading')} | {secs('light_sampling')} |")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)


if __name__ == "__main__":
    main()
