#!/usr/bin/env python3
"""Generate penumbra's Sobol' generator matrices (core/src/sampler/sobol_matrices.bin).

Source of the direction numbers: the Joe–Kuo "new-joe-kuo-6.21201" table as
bundled with SciPy (scipy/stats/_sobol_direction_numbers.npz, BSD-licensed),
which holds for each dimension its primitive polynomial (`poly`, with both the
leading and the constant term) and its initial direction numbers m_1..m_s
(`vinit`). Dimension 0 is the van der Corput sequence (all m_k = 1).

For each of the first 1024 dimensions we build 52 generator-matrix columns
with 52-bit precision (so that sample indices up to 2^52 are supported, as in
pbrt-v3) and keep the top 32 bits of each column: column j is the 32-bit
number whose most significant bit is the first binary digit of the output
contributed by bit j of the sample index.

Output: 1024 * 52 little-endian u32, dimension-major.

Usage: python3 -m venv v && v/bin/pip install scipy && v/bin/python tools/gen_sobol_matrices.py
The script checks its matrices against scipy.stats.qmc.Sobol (unscrambled)
before writing.
"""
import os
import struct
import sys

import numpy as np
import scipy
from scipy.stats import qmc

N_DIMS = 1024
N_COLS = 52
PREC = 52  # bits of precision used while building the columns

here = os.path.dirname(os.path.abspath(__file__))
out_path = os.path.join(here, "..", "core", "src", "sampler", "sobol_matrices.bin")

table = np.load(os.path.join(os.path.dirname(scipy.__file__), "stats", "_sobol_direction_numbers.npz"))
polys = table["poly"]
vinit = table["vinit"]


def columns(dim):
    """The PREC-bit direction numbers v_0..v_{N_COLS-1} of dimension `dim`."""
    m = [0] * N_COLS
    if dim == 0:
        m = [1] * N_COLS
    else:
        p = int(polys[dim])
        s = p.bit_length() - 1  # degree
        for k in range(s):
            m[k] = int(vinit[dim][k])
        for k in range(s, N_COLS):
            # Bratley–Fox recurrence: m_k = 2a_1 m_{k-1} ^ 4a_2 m_{k-2} ^ ... ^ 2^s m_{k-s} ^ m_{k-s}
            new = m[k - s] ^ (m[k - s] << s)
            for i in range(1, s):
                if (p >> (s - i)) & 1:
                    new ^= m[k - i] << i
            m[k] = new
    # m_k (k 0-based) is an odd integer < 2^(k+1); as a binary fraction it is m_k / 2^(k+1).
    return [m[k] << (PREC - k - 1) for k in range(N_COLS)]


mats = []
for d in range(N_DIMS):
    mats.append([c >> (PREC - 32) for c in columns(d)])
    assert all(0 <= c < 2**32 for c in mats[-1])


def point(index, d):
    v = 0
    j = 0
    while index:
        if index & 1:
            v ^= mats[d][j]
        index >>= 1
        j += 1
    return v


# Check against SciPy's own generator (it enumerates in Gray-code order, so compare sets
# of the first 2^k points, which coincide for the two orders).
check_dims = list(range(0, 12)) + [100, 500, 1023]
k = 10
ref = qmc.Sobol(d=N_DIMS, scramble=False).random_base2(k)[:, check_dims]
ref_set = sorted(tuple(int(round(x * 2**30)) for x in row) for row in ref)
ours = sorted(tuple(point(i, d) >> 2 for d in check_dims) for i in range(2**k))
if ref_set != ours:
    sys.exit("mismatch with scipy.stats.qmc.Sobol")

with open(out_path, "wb") as f:
    for d in range(N_DIMS):
        f.write(struct.pack("<%dI" % N_COLS, *mats[d]))
print("wrote", out_path, os.path.getsize(out_path), "bytes; verified against scipy", scipy.__version__)
