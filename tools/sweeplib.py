"""Shared helpers of the tools that turn `penumbra sweep` runs into documentation tables
(ltc_equal_time.py, meshes_equal_error.py)."""
import array
import math


def pfm_mean(path):
    """Mean of R, G, B of a PFM image."""
    with open(path, "rb") as f:
        kind = f.readline().strip()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        a = array.array("f")
        a.frombytes(f.read())
    if scale > 0:
        a.byteswap()
    n = 3 if kind == b"PF" else 1
    assert len(a) == w * h * n
    return sum(a) / len(a)


def loglog(xs, ys, y):
    """x at which the piecewise log-log curve (xs, ys) with ys decreasing reaches y."""
    pts = sorted(zip(xs, ys))
    for (x0, y0), (x1, y1) in zip(pts, pts[1:]):
        if (y0 >= y >= y1) or (y0 <= y <= y1):
            if y0 == y1:
                return x0, False
            t = (math.log(y) - math.log(y0)) / (math.log(y1) - math.log(y0))
            return math.exp(math.log(x0) + t * (math.log(x1) - math.log(x0))), False
    if y > max(ys):
        return None, False
    (x0, y0), (x1, y1) = pts[-2], pts[-1]
    slope = (math.log(y1) - math.log(y0)) / (math.log(x1) - math.log(x0))
    if slope >= 0:
        return None, True
    return math.exp(math.log(x1) + (math.log(y) - math.log(y1)) / slope), True
