#!/usr/bin/env python3
"""Writes the scene of the sheared-ao crossover measurement (docs/integrators/sheared-ao.md,
"Crossover against triangle count"): three icosahedra refined by pbrt-v3's "loopsubdiv" shape
("integer nlevels" L: 3 x 20 x 4^L triangles, the same limit surface at every L) on a ground
quad under a white sky, so that only the cost of a ray changes with L, not the image.

    python3 tools/sheared_ao_crossover_scene.py L > crossover-L.pbrt
"""
import math
import sys

L = int(sys.argv[1]) if len(sys.argv) > 1 else 4
t = (1 + math.sqrt(5)) / 2
V = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
     (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
F = [0, 11, 5, 0, 5, 1, 0, 1, 7, 0, 7, 10, 0, 10, 11, 1, 5, 9, 5, 11, 4, 11, 10, 2, 10, 7, 6, 7, 1, 8,
     3, 9, 4, 3, 4, 2, 3, 2, 6, 3, 6, 8, 3, 8, 9, 4, 9, 5, 2, 4, 11, 6, 2, 10, 8, 6, 7, 9, 8, 1]
r0 = math.sqrt(1 + t * t)
print(f"""# sheared-ao crossover scene, loopsubdiv nlevels {L}: {3 * 20 * 4 ** L} triangles + 2
LookAt 0 2.2 -3.6  0 0.4 -0.2  0 1 0
Camera "perspective" "float fov" [ 40 ]
Film "image" "integer xresolution" [ 64 ] "integer yresolution" [ 64 ] "string filename" [ "out.exr" ]
Sampler "halton" "integer pixelsamples" [ 4 ]
Integrator "ambientocclusion"
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
Material "matte" "rgb Kd" [ 0.5 0.5 0.5 ]
Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ] "point P" [ -8 0 -8 -8 0 8 8 0 8 8 0 -8 ]""")
# (centre x, y, z, radius of the control icosahedron): touching the ground and each other
for cx, cz, rad in [(-1.0, 0.0, 0.8), (0.55, 0.3, 0.6), (0.2, -1.0, 0.45)]:
    s = rad / r0
    P = " ".join(f"{cx + s * x:.6f} {rad * 0.85 + s * y:.6f} {cz + s * z:.6f}" for x, y, z in V)
    print(f'Shape "loopsubdiv" "integer nlevels" [ {L} ] "integer indices" [ {" ".join(map(str, F))} ] '
          f'"point P" [ {P} ]')
print("WorldEnd")
