#!/usr/bin/env python3
"""Writes the small texture files of scenes/real/textures/ (stdlib only, deterministic).

Usage: python3 tools/make_real_textures.py [PENUMBRA]   (PENUMBRA: the binary that converts the
grey PFM to `lum.exr`; default target/release/penumbra)

Every layout pbrt-v3's ReadImage reads, so that renders of scenes/real/image-formats.pbrt by the
real pbrt-v3 check penumbra's readers: PNG at 1, 2, 8 and 16 bits (grey, grey + alpha, RGB,
palette with tRNS), TGA (run-length encoded with a bottom-left origin, colour-mapped with a
top-right origin, grey RLE), EXR with a luminance channel only, PFM with a scale of 2; plus the
bump map and checkerboard the differential scenes use and the cut-out mask of cutout-cards.
"""
import math, os, struct, subprocess, sys, zlib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(ROOT, "scenes", "real", "textures")


def png(path, w, h, color_type, depth, rows, plte=None, trns=None):
    """rows: one bytes object per row, already packed at `depth` bits."""
    def chunk(kind, data):
        c = struct.pack(">I", len(data)) + kind + data
        return c + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
    raw = b"".join(b"\x00" + r for r in rows)
    out = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, depth, color_type, 0, 0, 0))
    if plte:
        out += chunk(b"PLTE", bytes(plte))
    if trns:
        out += chunk(b"tRNS", bytes(trns))
    out += chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
    open(path, "wb").write(out)


def pack(values, depth):
    """Packs samples of `depth` < 8 bits from the high bit."""
    out, acc, n = bytearray(), 0, 0
    for v in values:
        acc = (acc << depth) | v
        n += depth
        if n == 8:
            out.append(acc)
            acc, n = 0, 0
    if n:
        out.append(acc << (8 - n))
    return bytes(out)


def tga(path, image_type, depth, descriptor, w, h, pixels, cmap=None, cmap_depth=0):
    head = struct.pack("<BBBHHBHHHHBB", 0, 1 if cmap else 0, image_type, 0, len(cmap or []) // max(1, cmap_depth // 8),
                       cmap_depth, 0, 0, w, h, depth, descriptor)
    open(path, "wb").write(head + bytes(cmap or b"") + pixels)


def rle(pixels, bpp):
    """Run-length encodes `pixels` (bytes, `bpp` per pixel) with runs and literal packets that
    cross rows."""
    px = [pixels[i:i + bpp] for i in range(0, len(pixels), bpp)]
    out, i = bytearray(), 0
    while i < len(px):
        j = i + 1
        while j < len(px) and j - i < 128 and px[j] == px[i]:
            j += 1
        if j - i > 1:
            out += bytes([0x80 | (j - i - 1)]) + px[i]
            i = j
            continue
        j = i + 1
        while j < len(px) and j - i < 128 and (j + 1 >= len(px) or px[j] != px[j + 1]):
            j += 1
        out += bytes([j - i - 1]) + b"".join(px[i:j])
        i = j
    return bytes(out)


def main():
    os.makedirs(OUT, exist_ok=True)
    t = lambda name: os.path.join(OUT, name)
    # Bump map: grooves across u, a smooth profile every 16 texels, 8-bit grey.
    w, h = 128, 64
    rows = []
    for y in range(h):
        rows.append(bytes(int(255 * (0.5 + 0.5 * math.cos(2 * math.pi * ((x % 16) / 16.0)) ** 8) * (0.8 + 0.2 * math.sin(y / 5.0))) for x in range(w)))
    png(t("grooves.png"), w, h, 0, 8, rows)
    # Checkerboard: 8-texel checks of two colours, RGB 8-bit.
    rows = [bytes(v for x in range(64) for v in ((230, 200, 40) if ((x // 8) + (y // 8)) % 2 else (20, 40, 160))) for y in range(64)]
    png(t("checks.png"), 64, 64, 2, 8, rows)
    # Cut-out mask (alpha): round holes of value 0 on a 16-texel grid, the rest opaque with a
    # fractional band (pbrt-v3 cuts only where alpha is exactly 0), 8-bit grey, 32x32.
    def leaf(x, y):
        if (x % 16 - 7.5) ** 2 + (y % 16 - 7.5) ** 2 < 30:
            return 0
        return 60 if x % 16 < 3 else 255
    rows = [bytes(leaf(x, y) for x in range(32)) for y in range(32)]
    png(t("leaves.png"), 32, 32, 0, 8, rows)
    # RGB 16-bit: low bytes set (pbrt-v3 keeps the high byte).
    rows = [b"".join(struct.pack(">HHH", (x * 4096 + 255) & 0xFFFF, (y * 4096 + 128) & 0xFFFF, ((x + y) * 2048 + 200) & 0xFFFF) for x in range(16)) for y in range(16)]
    png(t("rgb16.png"), 16, 16, 2, 16, rows)
    # Palette, 2 bits, with per-entry alpha (dropped by pbrt-v3).
    plte = [200, 30, 30, 30, 200, 30, 30, 30, 200, 220, 220, 220]
    rows = [pack([(x // 4 + y // 4) % 4 for x in range(16)], 2) for y in range(16)]
    png(t("palette2.png"), 16, 16, 3, 2, rows, plte=plte, trns=[0, 128, 255])
    # Grey + alpha, 8-bit (alpha dropped, not composited).
    rows = [bytes(v for x in range(16) for v in (x * 16, 255 - y * 16)) for y in range(16)]
    png(t("greyalpha.png"), 16, 16, 4, 8, rows)
    # Grey, 1 bit.
    rows = [pack([1 if (x // 4 + y // 2) % 2 else 0 for x in range(32)], 1) for y in range(32)]
    png(t("grey1.png"), 32, 32, 0, 1, rows)
    # TGA, 24-bit RLE, bottom-left origin (rows stored bottom to top), BGR.
    def colour(x, y):
        return (40 + 12 * x, 200 - 10 * y, 120 if (x // 4) % 2 else 30)
    pix = b"".join(bytes(colour(x, y)[::-1]) for y in reversed(range(16)) for x in range(16))
    # Long runs too: the top-left quarter flat.
    pix = bytearray(pix)
    for y in range(8):
        for x in range(8):
            fy = 15 - y
            pix[(fy * 16 + x) * 3:(fy * 16 + x) * 3 + 3] = bytes((10, 90, 250))
    tga(t("rle-bottom.tga"), 10, 24, 0x00, 16, 16, rle(bytes(pix), 3))
    # TGA colour-mapped (24-bit map of 4 colours), top-right origin (rows top to bottom,
    # columns right to left).
    cmap = b"".join(bytes(c[::-1]) for c in [(250, 250, 250), (250, 40, 40), (40, 250, 40), (40, 40, 250)])
    idx = bytes((((15 - xr) // 4) + (y // 4)) % 4 for y in range(16) for xr in range(16))
    tga(t("cmap-topright.tga"), 1, 8, 0x30, 16, 16, idx, cmap=cmap, cmap_depth=24)
    # TGA grey, RLE, top-left origin.
    mono = bytes(min(255, 16 * (x // 2) + 8 * (y // 4)) for y in range(16) for x in range(16))
    tga(t("mono-rle.tga"), 11, 8, 0x20, 16, 16, rle(mono, 1))
    # PFM with scale 2 (little-endian): pbrt-v3 multiplies by |scale|.
    vals = [0.1 + 0.02 * x + 0.01 * y for y in range(16) for x in range(16)]
    body = b"".join(struct.pack("<fff", v, 0.5 * v, 0.25) for v in vals)
    open(t("scaled.pfm"), "wb").write(b"PF\n16 16\n-2\n" + body)
    # EXR with only a luminance channel Y: a grey PFM converted by penumbra (channel Y).
    grey = os.path.join(OUT, "lum.pfm")
    body = b"".join(struct.pack("<f", 0.05 + 0.06 * ((x + y) % 8)) for y in range(16) for x in range(16))
    open(grey, "wb").write(b"Pf\n16 16\n-1\n" + body)
    pen = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "target", "release", "penumbra")
    subprocess.run([pen, "convert", grey, t("lum.exr")], check=True)
    os.remove(grey)


if __name__ == "__main__":
    main()
