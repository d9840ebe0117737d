#!/usr/bin/env python3
"""The bumpy-sphere scene of docs/integrators/silhouette.md's cost-against-n table (issue 37).

An open UV sphere of n_phi azimuth steps and n_phi/2 rings (no pole caps: each pole ring is a
boundary, 2 n_phi boundary edges tested at every point), radius
1 + 0.08 sin 5θ cos 7φ + 0.04 sin(11θ + 3φ), over a ground quad, a white "infinite" light,
camera at (3.5, -4, 2.5). Triangles: n_phi (n_phi/2 - 1) 2 (960, 3 968, 16 128, 65 024 for
n_phi = 32, 64, 128, 256) plus the ground's 2.

    python3 tools/silhouette_bumpy_sphere.py 64 > /tmp/bumpy64.pbrt
"""
import math
import sys


def main():
    nphi = int(sys.argv[1]) if len(sys.argv) > 1 else 64
    rings = nphi // 2
    pts, idx = [], []
    for j in range(rings):
        th = math.pi * (j + 0.5) / rings
        for i in range(nphi):
            ph = 2.0 * math.pi * i / nphi
            r = 1.0 + 0.08 * math.sin(5 * th) * math.cos(7 * ph) + 0.04 * math.sin(11 * th + 3 * ph)
            pts.append((r * math.sin(th) * math.cos(ph), r * math.sin(th) * math.sin(ph), r * math.cos(th)))
    for j in range(rings - 1):
        for i in range(nphi):
            a, b = j * nphi + i, j * nphi + (i + 1) % nphi
            c, d = a + nphi, b + nphi
            idx += [a, c, b, b, c, d]
    out = [
        "LookAt 3.5 -4 2.5  0 0 0  0 0 1",
        'Camera "perspective" "float fov" [ 40 ]',
        'Film "image" "integer xresolution" [ 64 ] "integer yresolution" [ 64 ] "string filename" [ "bumpy.exr" ]',
        'Sampler "halton" "integer pixelsamples" [ 1 ]',
        "WorldBegin",
        'LightSource "infinite" "rgb L" [ 1 1 1 ]',
        'Material "matte" "rgb Kd" [ 0.5 0.5 0.5 ]',
        'Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ] "point P" [ -4 -4 -1.2 4 -4 -1.2 4 4 -1.2 -4 4 -1.2 ]',
        'Shape "trianglemesh" "integer indices" [ ' + " ".join(map(str, idx)) + " ]",
        '  "point P" [ ' + " ".join("%.7g %.7g %.7g" % p for p in pts) + " ]",
        "WorldEnd",
    ]
    print("\n".join(out))


if __name__ == "__main__":
    main()
