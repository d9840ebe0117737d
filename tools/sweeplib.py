"""Shared helpers of the tools that turn `penumbra sweep` runs into documentation tables
(ltc_equal_time.py, meshes_equal_error.py)."""
import array
import math


def read_pfm(path):
    """(channels, width, height, values) of a PFM image, values as little-endian floats."""
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
    return n, w, h, a


def pfm_mean(path):
    """Mean of R, G, B of a PFM image."""
    a = read_pfm(path)[3]
    return sum(a) / len(a)


def downsample_pfm(src, dst, k):
    """Box-downsample a colour PFM k×k (exact for the box pixel filter; divides noise by ~k)."""
    n, w, h, a = read_pfm(src)
    assert n == 3
    out = array.array("f", [0.0] * ((w // k) * (h // k) * 3))
    for y in range(h - h % k):
        for x in range(w - w % k):
            o = ((y // k) * (w // k) + x // k) * 3
            i = (y * w + x) * 3
            for c in range(3):
                out[o + c] += a[i + c] / (k * k)
    with open(dst, "wb") as f:
        f.write(b"PF\n%d %d\n-1.0\n" % (w // k, h // k))
        out.tofile(f)


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


def time_to(xs, ys, row, before_first):
    """The baseline's time to `row`'s RMSE on its curve (xs: times, ys: RMSEs) and the ratio of
    `row`'s time to it, as table cells (~: extrapolated), and the ratio as a number (or None)."""
    t, extrap = loglog(xs, ys, row["rmse"])
    if t is None:
        return ("below its curve" if extrap else before_first), "", None
    mark = "~" if extrap else ""
    return f"{mark}{t:.3g}", f"{mark}{row['total_s'] / t:.2f}", row["total_s"] / t
