"""Writes sh2-env.pfm: a 128x64 lat-long map (pbrt-v3's parameterisation: column i at
phi = 2pi (i + 1/2)/128, row j at theta = pi (j + 1/2)/64 from light-space +z) sampling, at
its texel centres, an RGB function of SH order <= 2 (bands 0-2):
  R = 1 + 0.3x - 0.2y + 0.4z + 0.2(x^2 - y^2) + 0.1xz
  G = 0.8 - 0.1x + 0.3y - 0.2z + 0.15xy
  B = 0.6 + 0.2z^2
Run: python3 make_env.py (no dependencies). The tests check the file against these formulas."""
import math
import struct

W, H = 128, 64


def radiance(x, y, z):
    return (1 + 0.3 * x - 0.2 * y + 0.4 * z + 0.2 * (x * x - y * y) + 0.1 * x * z,
            0.8 - 0.1 * x + 0.3 * y - 0.2 * z + 0.15 * x * y,
            0.6 + 0.2 * z * z)


rows = []
for j in range(H):
    theta = math.pi * (j + 0.5) / H
    row = []
    for i in range(W):
        phi = 2 * math.pi * (i + 0.5) / W
        d = (math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta))
        row.extend(radiance(*d))
    rows.append(row)
with open("sh2-env.pfm", "wb") as f:
    f.write(b"PF\n%d %d\n-1.0\n" % (W, H))
    for row in reversed(rows):  # PFM stores the bottom row first
        f.write(struct.pack("<%df" % len(row), *row))
