#!/usr/bin/env python3
"""The pbrt-v3 conformance matrix: writes one small scene per cell into tests/conformance/ and
renders each cell's references with the real pbrt-v3.

Usage:
  python3 tools/conformance.py scenes             # (re)write the scenes, assets and cells.tsv
  python3 tools/conformance.py render [NAME ...]  # render missing references (all given NAMEs)
  python3 tools/conformance.py render --force ... # re-render even where a reference exists
  python3 tools/conformance.py list               # the cells, one a line

Needs Python 3.11 and numpy; `render` needs `../shared/tools/pbrt-v3/pbrt` (pbrt-v3 at commit
13d871faae88) beside the repository and, for the Fourier cell's table, nothing more: the
`.bsdf` file is checked in (see tests/conformance/README.md).

Every cell is a complete pbrt-v3 scene: the options block (camera, sampler at the test's sample
count, box pixel filter, film 32x32 unless the cell says otherwise, `Integrator
"directlighting"`) and a world that isolates what the cell tests: a material on a floor and a
sphere under one quad light, seen at a grazing-ish angle so that its lobes matter; a light type
over a matte floor with an occluder; a shape over a matte floor under a quad light and a dim
sky; the same scene through each camera, sampler and pixel filter; a few closed rooms for
interreflection. References (`ref/NAME.KIND.pfm`, float32 RGB):
  direct  pbrt-v3 `directlighting` (the cell's own integrator line: strategy all, maxdepth 5);
  path    pbrt-v3 `path` (maxdepth 5) -- only for cells where a path differs from direct light;
  ao      pbrt-v3 `ambientocclusion` (nsamples 1, cossample true) for the geometry cells.
Each is rendered at twice the cell's resolution with REF_SPP samples per pixel (512; environment
variable CONFORMANCE_REF_SPP; the count of every reference is in timings.tsv) (box filter,
halton unless the cell tests a sampler) and box-downsampled 2x2, so a reference pixel averages
4 * REF_SPP samples; cells with a wider pixel filter render at their own resolution with
4 * REF_SPP samples instead (downsampling is exact only for a box filter). pbrt-v3 runs as
`nice -n 10 pbrt --quiet --nthreads 2`; its wall time goes to timings.tsv.
"""
import math
import os
import resource
import struct
import subprocess
import sys
import tempfile
import time
import zlib

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(ROOT, "tests", "conformance")
ASSETS = os.path.join(OUT, "assets")
REFS = os.path.join(OUT, "ref")
PBRT = os.path.join(ROOT, "..", "shared", "tools", "pbrt-v3", "pbrt")
REF_SPP = int(os.environ.get("CONFORMANCE_REF_SPP", "512"))
RES = 32

# ---------------------------------------------------------------------------------------------
# Assets: tiny images and data files, generated deterministically.


def write_pfm(path, img):
    """`img`: H x W x 3 float array, row 0 at the top (written bottom to top, little-endian)."""
    img = np.asarray(img, dtype="<f4")
    h, w, _ = img.shape
    with open(path, "wb") as f:
        f.write(b"PF\n%d %d\n-1\n" % (w, h))
        f.write(np.ascontiguousarray(img[::-1]).tobytes())


def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")
    assert kind == b"PF", kind
    return data.reshape(h, w, 3)[::-1].astype(np.float64)


def write_png8(path, rgb8):
    """8-bit RGB PNG (stdlib zlib)."""
    h, w, _ = rgb8.shape
    raw = b"".join(b"\x00" + bytes(rgb8[y].astype(np.uint8).tobytes()) for y in range(h))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
    with open(path, "wb") as f:
        f.write(png)


def gen_assets():
    os.makedirs(ASSETS, exist_ok=True)
    # An 8x8 colour pattern (smooth gradient times a coarse checker) for image textures.
    y, x = np.mgrid[0:8, 0:8] + 0.5
    checker = ((np.floor(x / 2) + np.floor(y / 2)) % 2) * 0.5 + 0.3
    tex = np.stack([checker * (0.4 + 0.6 * x / 8), checker * (0.3 + 0.6 * y / 8), checker * 0.5], axis=-1)
    write_pfm(os.path.join(ASSETS, "pattern8.pfm"), tex)
    write_png8(os.path.join(ASSETS, "pattern8.png"), np.round(np.clip(tex, 0, 1) ** (1 / 2.2) * 255))
    # A smooth grey height field (two sinusoid periods) for bump and roughness maps.
    y, x = np.mgrid[0:16, 0:16] + 0.5
    h = 0.5 + 0.25 * np.sin(2 * math.pi * x / 8) * np.cos(2 * math.pi * y / 16)
    write_pfm(os.path.join(ASSETS, "height16.pfm"), np.repeat(h[:, :, None], 3, axis=2))
    # Lat-long maps: goniometric pattern (16x8), projection slide (8x8), environment (32x16).
    v, u = np.mgrid[0:8, 0:16] + 0.5
    gon = 0.3 + 0.7 * np.cos(math.pi * (v / 8 - 0.5)) ** 2 * (0.6 + 0.4 * np.cos(2 * math.pi * u / 16))
    write_pfm(os.path.join(ASSETS, "gonio16x8.pfm"), np.stack([gon, gon * 0.8, gon * 0.6], axis=-1))
    v, u = np.mgrid[0:8, 0:8] + 0.5
    slide = np.stack([0.2 + 0.8 * u / 8, 0.2 + 0.8 * v / 8, 0.6 * np.ones_like(u)], axis=-1)
    write_pfm(os.path.join(ASSETS, "slide8.pfm"), slide)
    v, u = np.mgrid[0:16, 0:32] + 0.5
    theta, phi = math.pi * v / 16, 2 * math.pi * u / 32
    sky = 0.3 + 0.5 * np.clip(np.cos(theta), 0, 1)
    sun = 25.0 * np.exp(-(((theta - 0.7) / 0.18) ** 2 + ((phi - 2.0) / 0.25) ** 2))
    env = np.stack([sky * 0.7 + sun, sky * 0.85 + sun * 0.9, sky + sun * 0.7], axis=-1)
    env[12:] *= 0.2  # a dark lower hemisphere (bands below the horizon)
    write_pfm(os.path.join(ASSETS, "env32x16.pfm"), env)
    # Synthetic metal spectra (not a measured metal: smooth curves of a gold-like shape) as .spd files.
    lam = np.arange(360, 831, 10)
    eta = 0.2 + 1.3 / (1 + np.exp((lam - 520) / 25))
    k = 1.8 + 2.2 * (lam - 360) / 470
    for name, val in (("synthetic.eta.spd", eta), ("synthetic.k.spd", k)):
        with open(os.path.join(ASSETS, name), "w") as f:
            f.write("# synthetic metal spectrum for the conformance matrix (wavelength nm, value)\n")
            f.writelines(f"{l} {v:.6f}\n" for l, v in zip(lam, val))
    gen_ply(os.path.join(ASSETS, "icosahedron.ply"))
    # A single-element lens for the realistic camera (radius, thickness, eta, aperture diameter; mm).
    with open(os.path.join(ASSETS, "singlet.dat"), "w") as f:
        f.write("# a biconvex singlet (f = 60 mm), then the aperture stop\n")
        f.write("60.0 8.0 1.5 30.0\n-60.0 10.0 1.0 30.0\n0.0 30.0 0.0 20.0\n")


def gen_ply(path):
    """An icosahedron (subdivided once, projected to the unit sphere) as an ASCII PLY with normals."""
    t = (1 + 5 ** 0.5) / 2
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
             (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
             (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
             (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    verts = [np.array(v, dtype=float) / np.linalg.norm(v) for v in verts]
    mid = {}

    def midpoint(a, b):
        key = (min(a, b), max(a, b))
        if key not in mid:
            m = verts[a] + verts[b]
            verts.append(m / np.linalg.norm(m))
            mid[key] = len(verts) - 1
        return mid[key]

    new = []
    for a, b, c in faces:
        ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
        new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
    with open(path, "w") as f:
        f.write(f"ply\nformat ascii 1.0\nelement vertex {len(verts)}\nproperty float x\nproperty float y\n"
                f"property float z\nproperty float nx\nproperty float ny\nproperty float nz\n"
                f"element face {len(new)}\nproperty list uchar int vertex_indices\nend_header\n")
        for v in verts:
            f.write("%.6f %.6f %.6f %.6f %.6f %.6f\n" % (*v, *v))
        for a, b, c in new:
            f.write(f"3 {a} {b} {c}\n")


# ---------------------------------------------------------------------------------------------
# Scene pieces.


def mesh(points, indices, normals=None, uv=None):
    s = 'Shape "trianglemesh" "integer indices" [ %s ]\n    "point P" [ %s ]' % (
        " ".join(map(str, indices)), " ".join(f"{c:g}" for p in points for c in p))
    if normals:
        s += '\n    "normal N" [ %s ]' % " ".join(f"{c:g}" for n in normals for c in n)
    if uv:
        s += '\n    "float uv" [ %s ]' % " ".join(f"{c:g}" for p in uv for c in p)
    return s + "\n"


def quad_light(l="6 6 6", y=2.2, x0=-1.0, x1=1.0, z0=1.5, z1=3.5, extra=""):
    """A one-sided quad emitter facing down (−y), black so that it reflects nothing."""
    pts = [(x0, y, z0), (x1, y, z0), (x1, y, z1), (x0, y, z1)]
    return ('AttributeBegin\n  AreaLightSource "diffuse" "rgb L" [ %s ]%s\n  Material "matte" "rgb Kd" [ 0 0 0 ]\n  '
            % (l, extra)) + mesh(pts, [0, 1, 2, 0, 2, 3], [(0, -1, 0)] * 4) + "AttributeEnd\n"


def floor(material, extent=20.0, uv_scale=8.0):
    e = extent
    return ("AttributeBegin\n" + material + "\n" +
            mesh([(-e, 0, -e), (e, 0, -e), (e, 0, e), (-e, 0, e)], [0, 2, 1, 0, 3, 2], None,
                 [(0, 0), (uv_scale, 0), (uv_scale, uv_scale), (0, uv_scale)]) + "AttributeEnd\n")


def sphere_at(material, x, y, z, r, extra=""):
    return f'AttributeBegin\n{material}\n  Translate {x} {y} {z}\n{extra}  Shape "sphere" "float radius" [ {r} ]\nAttributeEnd\n'


MAT_CAMERA = 'LookAt 0 2.5 -5  0 0.3 1.5  0 1 0\nCamera "perspective" "float fov" [ 40 ]\n'
GEO_CAMERA = 'LookAt 0 2.2 -4  0 0.5 1  0 1 0\nCamera "perspective" "float fov" [ 40 ]\n'
CHECKER_FLOOR = ('Texture "checks" "spectrum" "checkerboard" "float uscale" [ 2 ] "float vscale" [ 2 ]\n'
                 '    "rgb tex1" [ 0.7 0.7 0.7 ] "rgb tex2" [ 0.2 0.25 0.3 ]\n'
                 'Material "matte" "texture Kd" "checks"')
MATTE_FLOOR = 'Material "matte" "rgb Kd" [ 0.5 0.5 0.5 ]'


class Cell:
    def __init__(self, name, group, what, world, *, camera=MAT_CAMERA, sampler="halton", spp=64, res=(RES, RES),
                 pixel_filter='PixelFilter "box"', integrator='Integrator "directlighting"', refs=("direct", "path"),
                 head=""):
        self.name, self.group, self.what, self.world = name, group, what, world
        self.camera, self.sampler, self.spp, self.res = camera, sampler, spp, res
        self.pixel_filter, self.integrator, self.refs, self.head = pixel_filter, integrator, refs, head

    def box(self):
        return self.pixel_filter == 'PixelFilter "box"'

    def options(self, spp, res, filename, integrator):
        if self.sampler.startswith("stratified"):
            # pbrt-v3's stratified sampler takes its count as xsamples x ysamples.
            n = int(round(math.sqrt(spp)))
            assert n * n == spp, spp
            count = f'"integer xsamples" [ {n} ] "integer ysamples" [ {n} ]'
        else:
            count = f'"integer pixelsamples" [ {spp} ]'
        kind, _, params = self.sampler.partition(" ")
        sampler = f'Sampler "{kind}" {count}' + (" " + params if params else "")
        return (f"{self.camera}{self.head}{sampler}\n{self.pixel_filter}\n"
                f'Film "image" "integer xresolution" [ {res[0]} ] "integer yresolution" [ {res[1]} ]\n'
                f'    "string filename" [ "{filename}" ]\n{integrator}\n')

    def text(self):
        return (f"# conformance cell {self.name}: {self.what}\n# Generated by tools/conformance.py; pbrt-v3 syntax.\n"
                + self.options(self.spp, self.res, self.name + ".exr", self.integrator) + "WorldBegin\n" + self.world
                + "WorldEnd\n")

    def ref_text(self, kind, filename):
        integrator = {
            "direct": self.integrator,
            "path": 'Integrator "path" "integer maxdepth" [ 5 ]',
            "ao": 'Integrator "ambientocclusion" "integer nsamples" [ 1 ] "bool cossample" "true"',
        }[kind]
        if self.box():
            spp, res = REF_SPP, (2 * self.res[0], 2 * self.res[1])
        else:
            spp, res = 4 * REF_SPP, self.res
        if self.sampler.startswith("stratified"):
            spp = int(round(math.sqrt(spp))) ** 2  # xsamples x ysamples: 512 -> 23^2 = 529
        return self.options(spp, res, filename, integrator) + "WorldBegin\n" + self.world + "WorldEnd\n", spp, res


CELLS = []


def add(*a, **k):
    c = Cell(*a, **k)
    assert all(c.name != o.name for o in CELLS), c.name
    CELLS.append(c)


ROUGHNESS = ["0.001", "0.01", "0.05", "0.1", "0.2", "0.4", "0.6", "0.8", "1"]
RAW_ALPHA = ["0.01", "0.1", "0.5", "1", "2", "3"]
SHORT_ROUGHNESS = ["0.01", "0.1", "0.4", "1"]
SHORT_ALPHA = ["0.5", "2"]


def material_scene(material, light=None, floor_material=None, named=""):
    """A floor and a sphere of `material` under the quad light."""
    light = light or quad_light()
    fl = floor_material or material
    return named + light + floor(fl) + sphere_at(material, -1.0, 0.6, 3.0, 0.6)


def transmissive_scene(material, named=""):
    """A sphere and a tilted panel of `material` over a checker floor, the quad light above and a
    second one under the panel: what passes through the material is seen."""
    panel = ("AttributeBegin\n" + material + "\n  Translate 0.9 0.9 1.2\n  Rotate -60 1 0 0\n" +
             mesh([(-0.7, -0.7, 0), (0.7, -0.7, 0), (0.7, 0.7, 0), (-0.7, 0.7, 0)], [0, 1, 2, 0, 2, 3],
                  None, [(0, 0), (1, 0), (1, 1), (0, 1)]) + "AttributeEnd\n")
    back = quad_light("3 3 3", y=0.01, x0=0.5, x1=1.3, z0=1.8, z1=2.4).replace("0 -1 0", "0 1 0").replace(
        "[ 0 1 2 0 2 3 ]", "[ 0 2 1 0 3 2 ]")
    return named + quad_light() + back + floor(CHECKER_FLOOR) + sphere_at(material, -1.0, 0.6, 3.0, 0.6) + panel


def materials():
    g = "material"
    add("matte-default", g, "matte, default parameters", material_scene('Material "matte"'))
    add("matte-sigma", g, "matte, Oren-Nayar sigma 30, coloured Kd",
        material_scene('Material "matte" "rgb Kd" [ 0.6 0.45 0.3 ] "float sigma" [ 30 ]'))
    add("plastic-default", g, "plastic, default parameters", material_scene('Material "plastic"'))
    for r in ROUGHNESS:
        add(f"plastic-r{r}", g, f"plastic Kd 0.2 Ks 0.8, roughness {r} (remapped)",
            material_scene(f'Material "plastic" "rgb Kd" [ 0.2 0.2 0.2 ] "rgb Ks" [ 0.8 0.8 0.8 ] "float roughness" [ {r} ]'))
    for a in RAW_ALPHA:
        add(f"plastic-a{a}", g, f"plastic Kd 0.2 Ks 0.8, alpha {a} (remaproughness false)",
            material_scene(f'Material "plastic" "rgb Kd" [ 0.2 0.2 0.2 ] "rgb Ks" [ 0.8 0.8 0.8 ] '
                           f'"float roughness" [ {a} ] "bool remaproughness" "false"'))
    add("metal-default", g, "metal, default parameters (pbrt-v3's copper, roughness 0.01)", material_scene('Material "metal"'))
    for r in ROUGHNESS:
        add(f"metal-r{r}", g, f"metal (copper), roughness {r} (remapped)",
            material_scene(f'Material "metal" "float roughness" [ {r} ]'))
    for a in RAW_ALPHA:
        add(f"metal-a{a}", g, f"metal (copper), alpha {a} (remaproughness false)",
            material_scene(f'Material "metal" "float roughness" [ {a} ] "bool remaproughness" "false"'))
    add("metal-aniso", g, "metal, uroughness 0.05 vroughness 0.4",
        material_scene('Material "metal" "float uroughness" [ 0.05 ] "float vroughness" [ 0.4 ]'))
    add("metal-aniso-raw", g, "metal, alpha u 0.02 v 0.6 (remaproughness false)",
        material_scene('Material "metal" "float uroughness" [ 0.02 ] "float vroughness" [ 0.6 ] "bool remaproughness" "false"'))
    add("metal-spd", g, "metal, eta and k from .spd files (synthetic spectra), roughness 0.2",
        material_scene('Material "metal" "spectrum eta" "assets/synthetic.eta.spd" "spectrum k" "assets/synthetic.k.spd" '
                       '"float roughness" [ 0.2 ]'))
    add("metal-spectrum", g, "metal, eta and k as inline sampled spectra, roughness 0.2",
        material_scene('Material "metal" "spectrum eta" [ 400 1.5 500 1.0 600 0.3 700 0.2 ] '
                       '"spectrum k" [ 400 1.9 500 1.9 600 3.0 700 4.0 ] "float roughness" [ 0.2 ]'))
    add("metal-rgb", g, "metal, RGB eta and k (gold-like), roughness 0.2",
        material_scene('Material "metal" "rgb eta" [ 0.143 0.374 1.442 ] "rgb k" [ 3.983 2.385 1.603 ] "float roughness" [ 0.2 ]'))
    add("mirror-default", g, "mirror, default Kr 0.9", material_scene('Material "mirror"'))
    add("mirror-kr", g, "mirror, Kr (0.9, 0.6, 0.3)", material_scene('Material "mirror" "rgb Kr" [ 0.9 0.6 0.3 ]'))
    add("glass-default", g, "glass, default parameters (smooth, eta 1.5)", transmissive_scene('Material "glass"'))
    add("glass-colour", g, "glass, Kr 0.9, Kt (0.9, 0.7, 0.5), index 1.33",
        transmissive_scene('Material "glass" "rgb Kr" [ 0.9 0.9 0.9 ] "rgb Kt" [ 0.9 0.7 0.5 ] "float index" [ 1.33 ]'))
    for r in ["0.01", "0.1", "0.4"]:
        add(f"glass-r{r}", g, f"rough glass, u/v roughness {r} (remapped)",
            transmissive_scene(f'Material "glass" "float uroughness" [ {r} ] "float vroughness" [ {r} ]'))
    add("glass-aniso", g, "rough glass, uroughness 0.05 vroughness 0.3",
        transmissive_scene('Material "glass" "float uroughness" [ 0.05 ] "float vroughness" [ 0.3 ]'))
    add("substrate-default", g, "substrate, default parameters", material_scene('Material "substrate"'))
    for r in SHORT_ROUGHNESS:
        add(f"substrate-r{r}", g, f"substrate Kd 0.3 Ks 0.5, u/v roughness {r} (remapped)",
            material_scene(f'Material "substrate" "rgb Kd" [ 0.3 0.3 0.3 ] "rgb Ks" [ 0.5 0.5 0.5 ] '
                           f'"float uroughness" [ {r} ] "float vroughness" [ {r} ]'))
    for a in SHORT_ALPHA:
        add(f"substrate-a{a}", g, f"substrate Kd 0.3 Ks 0.5, alpha {a} (remaproughness false)",
            material_scene(f'Material "substrate" "rgb Kd" [ 0.3 0.3 0.3 ] "rgb Ks" [ 0.5 0.5 0.5 ] '
                           f'"float uroughness" [ {a} ] "float vroughness" [ {a} ] "bool remaproughness" "false"'))
    add("substrate-aniso", g, "substrate, uroughness 0.02 vroughness 0.3",
        material_scene('Material "substrate" "float uroughness" [ 0.02 ] "float vroughness" [ 0.3 ]'))
    add("uber-default", g, "uber, default parameters", material_scene('Material "uber"'))
    for r in SHORT_ROUGHNESS:
        add(f"uber-r{r}", g, f"uber Kd 0.3 Ks 0.6, roughness {r} (remapped)",
            material_scene(f'Material "uber" "rgb Kd" [ 0.3 0.3 0.3 ] "rgb Ks" [ 0.6 0.6 0.6 ] "float roughness" [ {r} ]'))
    add("uber-a2", g, "uber Kd 0.3 Ks 0.6, alpha 2 (remaproughness false)",
        material_scene('Material "uber" "rgb Kd" [ 0.3 0.3 0.3 ] "rgb Ks" [ 0.6 0.6 0.6 ] "float roughness" [ 2 ] '
                       '"bool remaproughness" "false"'))
    add("uber-aniso", g, "uber, uroughness 0.02 vroughness 0.3",
        material_scene('Material "uber" "float uroughness" [ 0.02 ] "float vroughness" [ 0.3 ]'))
    add("uber-specular", g, "uber with Kr 0.3 and Kt 0.3 (specular reflection and transmission)",
        transmissive_scene('Material "uber" "rgb Kr" [ 0.3 0.3 0.3 ] "rgb Kt" [ 0.3 0.3 0.3 ]'))
    add("uber-opacity", g, "uber with opacity 0.6 (passes 40 % straight through)",
        transmissive_scene('Material "uber" "rgb Kd" [ 0.5 0.3 0.2 ] "rgb opacity" [ 0.6 0.6 0.6 ]'))
    add("translucent-default", g, "translucent, default parameters", transmissive_scene('Material "translucent"'))
    for r in SHORT_ROUGHNESS:
        add(f"translucent-r{r}", g, f"translucent Kd 0.4 Ks 0.4, roughness {r} (remapped)",
            transmissive_scene(f'Material "translucent" "rgb Kd" [ 0.4 0.4 0.4 ] "rgb Ks" [ 0.4 0.4 0.4 ] "float roughness" [ {r} ]'))
    add("translucent-a2", g, "translucent, alpha 2 (remaproughness false), reflect 0.3 transmit 0.7",
        transmissive_scene('Material "translucent" "rgb Kd" [ 0.4 0.4 0.4 ] "rgb Ks" [ 0.4 0.4 0.4 ] "float roughness" [ 2 ] '
                           '"bool remaproughness" "false" "rgb reflect" [ 0.3 0.3 0.3 ] "rgb transmit" [ 0.7 0.7 0.7 ]'))
    named = ('MakeNamedMaterial "a" "string type" "matte" "rgb Kd" [ 0.7 0.3 0.2 ]\n'
             'MakeNamedMaterial "b" "string type" "metal" "float roughness" [ 0.1 ]\n')
    add("mix-default", g, "mix of matte and metal, default amount 0.5",
        material_scene('Material "mix" "string namedmaterial1" "a" "string namedmaterial2" "b"', named=named))
    add("mix-amount", g, "mix of matte and metal, amount (0.2, 0.5, 0.8)",
        material_scene('Material "mix" "string namedmaterial1" "a" "string namedmaterial2" "b" "rgb amount" [ 0.2 0.5 0.8 ]',
                       named=named))
    add("mix-textured", g, "mix of matte and metal, amount a checkerboard",
        material_scene('Material "mix" "string namedmaterial1" "a" "string namedmaterial2" "b" "texture amount" "mixchecks"',
                       named=named + 'Texture "mixchecks" "spectrum" "checkerboard" "float uscale" [ 4 ] "float vscale" [ 4 ]\n'
                       '    "rgb tex1" [ 0.1 0.1 0.1 ] "rgb tex2" [ 0.9 0.9 0.9 ]\n'))
    # Materials another issue implements (35): their cells record what penumbra does.
    add("disney-default", g, "disney, default parameters", material_scene('Material "disney"'))
    add("disney-metallic", g, "disney, metallic 0.7, roughness 0.3, clearcoat 0.5, sheen 0.5, anisotropic 0.5",
        material_scene('Material "disney" "rgb color" [ 0.8 0.5 0.3 ] "float metallic" [ 0.7 ] "float roughness" [ 0.3 ] '
                       '"float clearcoat" [ 0.5 ] "float sheen" [ 0.5 ] "float anisotropic" [ 0.5 ]'))
    add("disney-thin", g, "disney, thin surface with difftrans 0.5 and spectrans 0.3",
        transmissive_scene('Material "disney" "bool thin" "true" "float difftrans" [ 0.5 ] "float spectrans" [ 0.3 ]'))
    add("fourier-gold", g, "fourier, pbrt-v3's measured roughgold_alpha_0.2.bsdf",
        material_scene('Material "fourier" "string bsdffile" "assets/roughgold_alpha_0.2.bsdf"'))
    add("hair-default", g, "hair, default parameters, on a cylinder (pbrt-v3 takes h from v)",
        quad_light() + floor(MATTE_FLOOR) +
        'AttributeBegin\n  Material "hair"\n  Translate -0.2 0.35 0.8\n  Rotate 90 0 1 0\n'
        '  Shape "cylinder" "float radius" [ 0.3 ] "float zmin" [ -1.2 ] "float zmax" [ 1.2 ]\nAttributeEnd\n')
    add("hair-color", g, "hair, color (0.6, 0.3, 0.2), beta_m 0.2, beta_n 0.5, on a cylinder",
        quad_light() + floor(MATTE_FLOOR) +
        'AttributeBegin\n  Material "hair" "rgb color" [ 0.6 0.3 0.2 ] "float beta_m" [ 0.2 ] "float beta_n" [ 0.5 ]\n'
        '  Translate -0.2 0.35 0.8\n  Rotate 90 0 1 0\n'
        '  Shape "cylinder" "float radius" [ 0.3 ] "float zmin" [ -1.2 ] "float zmax" [ 1.2 ]\nAttributeEnd\n')
    add("subsurface-default", g, "subsurface, default parameters", material_scene('Material "subsurface"'))
    add("kdsubsurface-default", g, "kdsubsurface, default parameters", material_scene('Material "kdsubsurface"'))


def textures():
    g = "texture"
    m = lambda t: material_scene(t, floor_material=t)  # noqa: E731
    add("bump-bilerp", g, "matte with a bilerp bump map (linear in u, v: exact finite differences)",
        material_scene('Material "matte" "texture bumpmap" "bl"',
                       named='Texture "bl" "float" "bilerp" "float v00" [ 0 ] "float v01" [ 0.05 ] "float v10" [ 0.1 ] "float v11" [ 0 ]\n'))
    add("bump-image", g, "plastic with an image bump map (smooth, bilinear, trilinear filtering)",
        material_scene('Material "plastic" "texture bumpmap" "hb"',
                       named='Texture "hb" "float" "imagemap" "string filename" "assets/height16.pfm" "bool trilinear" "true"\n'
                             '    "float uscale" [ 1 ] "float vscale" [ 1 ]\nTexture "hbs" "float" "scale" "texture tex1" "hb" "float tex2" [ 0.02 ]\n'
                       ).replace('"texture bumpmap" "hb"', '"texture bumpmap" "hbs"'))
    add("bump-metal-fbm", g, "metal with an fbm bump map (pbrt-v3 clamps octaves by the ray footprint)",
        material_scene('Material "metal" "float roughness" [ 0.2 ] "texture bumpmap" "fb"',
                       named='Texture "fb0" "float" "fbm" "integer octaves" [ 4 ] "float roughness" [ 0.5 ]\n'
                             'Texture "fb" "float" "scale" "texture tex1" "fb0" "float tex2" [ 0.03 ]\n'))
    add("tex-checker2d", g, "matte Kd 2D checkerboard (closed-form antialiasing)",
        m('Texture "c" "spectrum" "checkerboard" "float uscale" [ 3 ] "float vscale" [ 3 ] "rgb tex1" [ 0.8 0.2 0.1 ] '
          '"rgb tex2" [ 0.1 0.3 0.7 ]\nMaterial "matte" "texture Kd" "c"'))
    add("tex-checker3d", g, "matte Kd 3D checkerboard",
        m('Texture "c" "spectrum" "checkerboard" "integer dimension" [ 3 ] "rgb tex1" [ 0.8 0.2 0.1 ] '
          '"rgb tex2" [ 0.1 0.3 0.7 ]\nMaterial "matte" "texture Kd" "c"'))
    add("tex-image-trilinear", g, "matte Kd image map (PFM, magnified, trilinear filtering)",
        m('Texture "t" "spectrum" "imagemap" "string filename" "assets/pattern8.pfm" "bool trilinear" "true"\n'
          'Material "matte" "texture Kd" "t"'))
    add("tex-image-ewa", g, "matte Kd image map (PFM, pbrt-v3's default EWA filtering)",
        m('Texture "t" "spectrum" "imagemap" "string filename" "assets/pattern8.pfm"\nMaterial "matte" "texture Kd" "t"'))
    add("tex-image-png", g, "matte Kd image map (8-bit sRGB PNG, trilinear, clamp wrap)",
        m('Texture "t" "spectrum" "imagemap" "string filename" "assets/pattern8.png" "bool trilinear" "true" '
          '"string wrap" "clamp"\nMaterial "matte" "texture Kd" "t"'))
    add("tex-roughness-image", g, "plastic roughness from a float image map",
        m('Texture "r" "float" "imagemap" "string filename" "assets/height16.pfm" "bool trilinear" "true"\n'
          'Material "plastic" "rgb Kd" [ 0.2 0.2 0.2 ] "rgb Ks" [ 0.8 0.8 0.8 ] "texture roughness" "r"'))
    add("tex-scale-mix", g, "Kd = mix(scale(checker, 0.8), constant, uv texture)",
        m('Texture "c" "spectrum" "checkerboard" "float uscale" [ 2 ] "float vscale" [ 2 ] "rgb tex1" [ 1 1 1 ] "rgb tex2" [ 0.2 0.2 0.2 ]\n'
          'Texture "s" "spectrum" "scale" "texture tex1" "c" "rgb tex2" [ 0.8 0.6 0.4 ]\n'
          'Texture "k" "spectrum" "constant" "rgb value" [ 0.1 0.5 0.3 ]\n'
          'Texture "u" "float" "bilerp" "float v00" [ 0 ] "float v01" [ 1 ] "float v10" [ 0.3 ] "float v11" [ 0.7 ]\n'
          'Texture "m" "spectrum" "mix" "texture tex1" "s" "texture tex2" "k" "texture amount" "u"\n'
          'Material "matte" "texture Kd" "m"'))
    add("tex-uv", g, "matte Kd 'uv' texture", m('Texture "t" "spectrum" "uv"\nMaterial "matte" "texture Kd" "t"'))
    add("tex-dots", g, "matte Kd dots",
        m('Texture "t" "spectrum" "dots" "float uscale" [ 4 ] "float vscale" [ 4 ] "rgb inside" [ 0.8 0.2 0.1 ] '
          '"rgb outside" [ 0.2 0.4 0.6 ]\nMaterial "matte" "texture Kd" "t"'))
    # pbrt-v3's marble spline is a cubic Bezier whose parameter runs to 5 for t = 1 (its `first`
    # control point is min(1, floor(6t))), so it extrapolates: 1.5 x the spline reaches 40.6 /
    # 38.7 / 42.2 (R/G/B) at t = 1 and exceeds 1 from t ~ 0.36 on. An albedo above 1 makes `path`
    # an energy-gaining random walk dominated by rare long paths (at x 0.5 the cell's path mean
    # was +7.3 % off pbrt-v3's with no variance estimate seeing it); x 0.022 keeps the albedo
    # below 0.93 everywhere while the bright veins are that extrapolation (texture.rs's unit
    # test checks it against pbrt-v3's formula).
    add("tex-marble", g, "matte Kd marble x 0.022 (spline extrapolated to 42: albedo < 0.93; pbrt-v3 clamps noise octaves by the ray footprint)",
        m('Texture "marble" "spectrum" "marble" "float scale" [ 2 ] "integer octaves" [ 4 ]\n'
          'Texture "t" "spectrum" "scale" "texture tex1" "marble" "rgb tex2" [ 0.022 0.022 0.022 ]\nMaterial "matte" "texture Kd" "t"'))
    add("tex-fbm-windy-wrinkled", g, "Kd = scale of fbm, windy and wrinkled float textures (octave clamping)",
        m('Texture "f" "float" "fbm"\nTexture "w" "float" "windy"\nTexture "r" "float" "wrinkled"\n'
          'Texture "fw" "float" "scale" "texture tex1" "f" "texture tex2" "w"\n'
          'Texture "t" "spectrum" "mix" "rgb tex1" [ 0.2 0.3 0.6 ] "rgb tex2" [ 0.8 0.6 0.3 ] "texture amount" "r"\n'
          'Material "matte" "texture Kd" "t" "texture sigma" "fw"'))
    add("tex-mappings", g, "checkerboards through spherical, cylindrical and planar mappings",
        quad_light() +
        'Texture "p" "spectrum" "checkerboard" "string mapping" "planar" "vector v1" [ 1 0 0 ] "vector v2" [ 0 0 1 ]\n'
        '    "rgb tex1" [ 0.7 0.7 0.7 ] "rgb tex2" [ 0.2 0.25 0.3 ]\n' + floor('Material "matte" "texture Kd" "p"') +
        'AttributeBegin\n  Texture "s" "spectrum" "imagemap" "string mapping" "spherical" "string filename" "assets/pattern8.pfm"\n'
        '    "bool trilinear" "true"\n  Material "matte" "texture Kd" "s"\n'
        '  Translate -1.2 0.6 1\n  Shape "sphere" "float radius" [ 0.6 ]\nAttributeEnd\n'
        'AttributeBegin\n  Texture "y" "spectrum" "imagemap" "string mapping" "cylindrical" "string filename" "assets/pattern8.pfm"\n'
        '    "bool trilinear" "true"\n  Material "matte" "texture Kd" "y"\n'
        '  Translate 1 0.5 1.2\n  Rotate -90 1 0 0\n  Shape "cylinder" "float radius" [ 0.4 ] "float zmin" [ -0.5 ] "float zmax" [ 0.5 ]\n'
        'AttributeEnd\n')


def light_scene(light, occluder='Material "matte" "rgb Kd" [ 0.6 0.5 0.4 ]'):
    return light + floor(MATTE_FLOOR) + sphere_at(occluder, -0.3, 0.5, 1.2, 0.5) + (
        'AttributeBegin\n  Material "plastic" "rgb Kd" [ 0.3 0.4 0.5 ] "rgb Ks" [ 0.5 0.5 0.5 ] "float roughness" [ 0.05 ]\n'
        '  Translate 1.1 0.3 0.6\n  Rotate 30 0 1 0\n' +
        mesh([(-0.3, -0.3, -0.3), (0.3, -0.3, -0.3), (0.3, 0.3, -0.3), (-0.3, 0.3, -0.3),
              (-0.3, -0.3, 0.3), (0.3, -0.3, 0.3), (0.3, 0.3, 0.3), (-0.3, 0.3, 0.3)],
             [0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4, 2, 3, 7, 2, 7, 6, 1, 2, 6, 1, 6, 5, 0, 4, 7, 0, 7, 3]) +
        "AttributeEnd\n")


def lights():
    g = "light"
    add("light-point", g, "point light", light_scene('LightSource "point" "rgb I" [ 8 8 8 ] "point from" [ 0.5 2.5 1.5 ]'))
    add("light-point-xform", g, "point light placed by the CTM, with scale",
        light_scene('AttributeBegin\n  Translate -1 2 0.5\n  LightSource "point" "rgb I" [ 4 3 2 ] "rgb scale" [ 2 2 2 ]\nAttributeEnd\n'))
    add("light-spot", g, "spot light, cone 30, delta 10",
        light_scene('LightSource "spot" "rgb I" [ 20 20 20 ] "point from" [ 0 3 0 ] "point to" [ 0 0 1.5 ] '
                    '"float coneangle" [ 30 ] "float conedeltaangle" [ 10 ]'))
    add("light-spot-wide", g, "spot light, cone 60, delta 40, from the side",
        light_scene('LightSource "spot" "rgb I" [ 15 12 9 ] "point from" [ 2.5 2 0 ] "point to" [ 0 0 1.5 ] '
                    '"float coneangle" [ 60 ] "float conedeltaangle" [ 40 ]'))
    add("light-distant", g, "distant light", light_scene('LightSource "distant" "rgb L" [ 2 2 2 ] "point from" [ 1 3 -1 ] "point to" [ 0 0 0 ]'))
    add("light-goniometric", g, "goniometric light (lat-long intensity map)",
        light_scene('AttributeBegin\n  Translate 0 2.5 1.5\n  Rotate -90 1 0 0\n'
                    '  LightSource "goniometric" "rgb I" [ 10 10 10 ] "string mapname" "assets/gonio16x8.pfm"\nAttributeEnd\n'))
    add("light-projection", g, "projection light (slide image, fov 50)",
        light_scene('AttributeBegin\n  Translate 0 3 -0.5\n  Rotate 56.3 1 0 0\n'
                    '  LightSource "projection" "rgb I" [ 15 15 15 ] "string mapname" "assets/slide8.pfm" "float fov" [ 50 ]\nAttributeEnd\n'))
    add("light-quad", g, "diffuse area light on a triangle mesh (quad)", light_scene(quad_light()))
    add("light-quad-twosided", g, "two-sided diffuse area light on a tilted quad",
        light_scene('AttributeBegin\n  AreaLightSource "diffuse" "rgb L" [ 4 4 4 ] "bool twosided" "true"\n'
                    '  Material "matte" "rgb Kd" [ 0 0 0 ]\n  Translate 0.4 1.6 2.5\n  Rotate 70 1 0 0\n' +
                    mesh([(-0.8, -0.5, 0), (0.8, -0.5, 0), (0.8, 0.5, 0), (-0.8, 0.5, 0)], [0, 1, 2, 0, 2, 3]) + "AttributeEnd\n"))
    add("light-quad-samples", g, "quad light with nsamples 4 and a blackbody spectrum L",
        light_scene(quad_light("6 6 6", extra=' "integer nsamples" [ 4 ]').replace('"rgb L" [ 6 6 6 ]', '"blackbody L" [ 3500 6 ]')))
    add("light-sphere", g, "diffuse area light on a sphere",
        light_scene('AttributeBegin\n  AreaLightSource "diffuse" "rgb L" [ 8 8 8 ]\n  Material "matte" "rgb Kd" [ 0 0 0 ]\n'
                    '  Translate 0.6 1.8 2.2\n  Shape "sphere" "float radius" [ 0.3 ]\nAttributeEnd\n'))
    add("light-disk", g, "diffuse area light on a disk facing down",
        light_scene('AttributeBegin\n  AreaLightSource "diffuse" "rgb L" [ 6 6 6 ]\n  Material "matte" "rgb Kd" [ 0 0 0 ]\n'
                    '  Translate 0 2.2 2.5\n  Rotate 90 1 0 0\n  Shape "disk" "float radius" [ 0.8 ]\nAttributeEnd\n'))
    add("light-cylinder", g, "diffuse area light on a cylinder",
        light_scene('AttributeBegin\n  AreaLightSource "diffuse" "rgb L" [ 5 5 5 ]\n  Material "matte" "rgb Kd" [ 0 0 0 ]\n'
                    '  Translate 0 1.9 2.3\n  Rotate 90 0 1 0\n  Shape "cylinder" "float radius" [ 0.15 ] "float zmin" [ -1 ] "float zmax" [ 1 ]\n'
                    'AttributeEnd\n'))
    add("light-reversed", g, "quad light emitting upward (ReverseOrientation) under a white ceiling",
        light_scene('AttributeBegin\n  AreaLightSource "diffuse" "rgb L" [ 6 6 6 ]\n  Material "matte" "rgb Kd" [ 0 0 0 ]\n'
                    '  ReverseOrientation\n' +
                    mesh([(-1, 2.2, 2), (1, 2.2, 2), (1, 2.2, 4), (-1, 2.2, 4)], [0, 1, 2, 0, 2, 3]) + "AttributeEnd\n"
                    'AttributeBegin\n  Material "matte" "rgb Kd" [ 0.8 0.8 0.8 ]\n' +
                    mesh([(-6, 3, -6), (6, 3, -6), (6, 3, 8), (-6, 3, 8)], [0, 1, 2, 0, 2, 3]) + "AttributeEnd\n"))
    add("light-three", g, "three quad lights of different colours and sizes",
        light_scene(quad_light("4 1 1", x0=-2, x1=-1, z0=1, z1=2) + quad_light("1 4 1", y=2.5, x0=-0.5, x1=0.5, z0=2.5, z1=4.5)
                    + quad_light("1 1 8", y=1.5, x0=1.2, x1=1.6, z0=1.5, z1=1.9)))
    add("light-infinite", g, "infinite light, constant",
        light_scene('LightSource "infinite" "rgb L" [ 0.8 0.9 1 ]'))
    add("light-infinite-map", g, "infinite light, lat-long map with a sun",
        light_scene('LightSource "infinite" "string mapname" "assets/env32x16.pfm"'))
    add("light-infinite-map-turned", g, "infinite light, lat-long map, turned, scaled, nsamples 4",
        light_scene('AttributeBegin\n  Rotate -90 1 0 0\n  Rotate 60 0 0 1\n'
                    '  LightSource "infinite" "string mapname" "assets/env32x16.pfm" "rgb scale" [ 0.5 0.6 0.7 ] "integer nsamples" [ 4 ]\n'
                    'AttributeEnd\n'))


def geometry_scene(shape):
    """`shape` (an attribute block) over a matte floor under a quad light and a dim sky."""
    return (quad_light("5 5 5", y=2.5, x0=-1.5, x1=0.5, z0=1.5, z1=3) + 'LightSource "infinite" "rgb L" [ 0.15 0.15 0.2 ]\n'
            + floor(MATTE_FLOOR) + shape)


def shape_block(body, material='Material "matte" "rgb Kd" [ 0.7 0.5 0.3 ]', xf="  Translate 0 0.6 1\n"):
    return f"AttributeBegin\n  {material}\n{xf}{body}AttributeEnd\n"


GEO_REFS = ("direct", "path", "ao")


def shapes():
    g = "shape"

    def s(name, what, body, **k):
        add(f"shape-{name}", g, what, geometry_scene(shape_block(body, **k)), camera=GEO_CAMERA, refs=GEO_REFS)

    s("sphere", "sphere", '  Shape "sphere" "float radius" [ 0.6 ]\n')
    s("sphere-partial", "partial sphere: zmin -0.3, zmax 0.5, phimax 270 (open)",
      '  Rotate -90 1 0 0\n  Shape "sphere" "float radius" [ 0.6 ] "float zmin" [ -0.3 ] "float zmax" [ 0.5 ] "float phimax" [ 270 ]\n')
    s("ellipsoid", "sphere under a non-uniform scale and rotation",
      '  Rotate 30 0 0 1\n  Scale 1.4 0.6 0.8\n  Shape "sphere" "float radius" [ 0.6 ]\n')
    s("disk", "disk with inner radius and phimax 300, tilted",
      '  Rotate -60 1 0 0\n  Shape "disk" "float radius" [ 0.7 ] "float innerradius" [ 0.2 ] "float phimax" [ 300 ]\n')
    s("cylinder", "open cylinder, phimax 300",
      '  Rotate -90 1 0 0\n  Translate 0 0 -0.6\n  Shape "cylinder" "float radius" [ 0.5 ] "float zmin" [ 0 ] "float zmax" [ 1 ] "float phimax" [ 300 ]\n')
    s("cone", "cone, phimax 300", '  Rotate -90 1 0 0\n  Translate 0 0 -0.6\n  Shape "cone" "float radius" [ 0.6 ] "float height" [ 1.1 ] "float phimax" [ 300 ]\n')
    s("paraboloid", "paraboloid", '  Rotate -90 1 0 0\n  Translate 0 0 -0.6\n  Shape "paraboloid" "float radius" [ 0.6 ] "float zmin" [ 0 ] "float zmax" [ 1.1 ]\n')
    s("hyperboloid", "hyperboloid (one sheet)",
      '  Rotate -90 1 0 0\n  Shape "hyperboloid" "point p1" [ 0.5 0 -0.5 ] "point p2" [ 0 0.5 0.5 ] "float phimax" [ 360 ]\n')
    s("trianglemesh", "triangle mesh with shading normals and uv (a bent quad strip)",
      "  " + mesh([(-0.8, -0.5, 0.2), (0, -0.5, -0.2), (0.8, -0.5, 0.2), (-0.8, 0.5, 0.2), (0, 0.5, -0.2), (0.8, 0.5, 0.2)],
                  [0, 1, 4, 0, 4, 3, 1, 2, 5, 1, 5, 4],
                  [(-0.45, 0, -0.9), (0, 0, -1), (0.45, 0, -0.9), (-0.45, 0, -0.9), (0, 0, -1), (0.45, 0, -0.9)],
                  [(0, 0), (0.5, 0), (1, 0), (0, 1), (0.5, 1), (1, 1)]))
    s("plymesh", "PLY mesh (subdivided icosahedron with vertex normals)",
      '  Scale 0.6 0.6 0.6\n  Shape "plymesh" "string filename" "assets/icosahedron.ply"\n')
    s("loopsubdiv", "Loop subdivision surface of a tetrahedron, 3 levels",
      '  Scale 2.5 2.5 2.5\n  Shape "loopsubdiv" "integer levels" [ 3 ] "integer indices" [ 0 1 2 0 3 1 0 2 3 1 3 2 ]\n'
      '    "point P" [ 0 0.8 0  0.75 -0.4 0.4  -0.75 -0.4 0.4  0 -0.4 -0.8 ]\n')
    # Raised 0.05 above the floor: its zero-height corner triangles were coplanar with the floor,
    # and which of two coplanar surfaces a ray hits is pbrt-v3's (and penumbra's) accident.
    s("heightfield", "height field 5x4, 0.05 above the floor",
      '  Translate -0.8 -0.55 -0.5\n  Rotate -90 1 0 0\n  Scale 1.6 1.2 1\n'
      '  Shape "heightfield" "integer nu" [ 5 ] "integer nv" [ 4 ] "float Pz" [ 0 0.2 0.5 0.2 0  0.1 0.6 0.9 0.4 0.1  0 0.3 0.7 0.5 0.2  0 0 0.2 0.1 0 ]\n')
    s("instances", "object instances (ObjectBegin/ObjectInstance), one mirrored",
      "", xf="")
    CELLS[-1].world = geometry_scene(
        'ObjectBegin "blob"\n  Material "matte" "rgb Kd" [ 0.3 0.6 0.4 ]\n  Shape "sphere" "float radius" [ 0.35 ]\n'
        '  Translate 0.3 0 0\n  Shape "cylinder" "float radius" [ 0.15 ] "float zmin" [ -0.3 ] "float zmax" [ 0.3 ]\nObjectEnd\n'
        'AttributeBegin\n  Translate -0.6 0.5 1\n  Scale 1.5 1.5 1.5\n  ObjectInstance "blob"\nAttributeEnd\n'
        'AttributeBegin\n  Translate 0.7 0.5 1.2\n  Scale -1.5 1.5 1.5\n  ObjectInstance "blob"\nAttributeEnd\n')
    s("curve", "curve shapes (flat, ribbon, cylinder)", "", xf="")
    CELLS[-1].world = geometry_scene(
        'AttributeBegin\n  Material "matte" "rgb Kd" [ 0.7 0.5 0.3 ]\n'
        '  Shape "curve" "string type" "cylinder" "point P" [ -0.8 0.1 1  -0.3 1.2 1  0.3 -0.2 1  0.8 0.9 1 ] "float width" [ 0.1 ]\n'
        '  Shape "curve" "string type" "flat" "point P" [ -0.8 0.1 0.6  -0.3 0.9 0.6  0.3 0.2 0.6  0.8 0.7 0.6 ] "float width0" [ 0.15 ] "float width1" [ 0.05 ]\n'
        '  Shape "curve" "string type" "ribbon" "point P" [ -0.8 0.2 1.5  -0.3 0.8 1.5  0.3 0.4 1.5  0.8 1.0 1.5 ]\n'
        '    "normal N" [ 0 0 -1  0 1 -1 ] "float width" [ 0.2 ]\nAttributeEnd\n')
    s("nurbs", "NURBS patch (bicubic, 4x4 control points)", "", xf="")
    pw = " ".join(f"{x - 0.75:g} {0.2 + (0.4 if 0 < i < 3 and 0 < j < 3 else 0):g} {z + 0.5:g}"
                  for j, z in enumerate([0, 0.5, 1, 1.5]) for i, x in enumerate([0, 0.5, 1, 1.5]))
    CELLS[-1].world = geometry_scene(
        'AttributeBegin\n  Material "matte" "rgb Kd" [ 0.7 0.5 0.3 ]\n'
        '  Shape "nurbs" "integer nu" [ 4 ] "integer nv" [ 4 ] "integer uorder" [ 4 ] "integer vorder" [ 4 ]\n'
        '    "float uknots" [ 0 0 0 0 1 1 1 1 ] "float vknots" [ 0 0 0 0 1 1 1 1 ] "float u0" [ 0 ] "float u1" [ 1 ] "float v0" [ 0 ] "float v1" [ 1 ]\n'
        f'    "point P" [ {pw} ]\nAttributeEnd\n')


BASE_GEOMETRY = geometry_scene(shape_block('  Shape "sphere" "float radius" [ 0.6 ]\n') +
                               shape_block('  Rotate -90 1 0 0\n  Shape "cylinder" "float radius" [ 0.25 ] "float zmin" [ -0.4 ] "float zmax" [ 0.4 ]\n',
                                           material='Material "plastic" "rgb Kd" [ 0.2 0.3 0.6 ] "float roughness" [ 0.2 ]',
                                           xf="  Translate 1.1 0.4 0.4\n"))


def cameras_samplers_filters():
    g = "camera"

    def cam(name, what, camera, res=(RES, RES)):
        add(f"camera-{name}", g, what, BASE_GEOMETRY, camera=camera, res=res, refs=GEO_REFS)

    cam("perspective-aspect", "perspective, 32x24 film (fov on the short axis), screenwindow default", GEO_CAMERA, res=(32, 24))
    cam("perspective-dof", "perspective, lens radius 0.15, focal distance 4",
        GEO_CAMERA.replace('[ 40 ]', '[ 40 ] "float lensradius" [ 0.15 ] "float focaldistance" [ 4 ]'))
    cam("orthographic", "orthographic, screenwindow [-2 2 -2 2]",
        'LookAt 0 2.2 -4  0 0.5 1  0 1 0\nCamera "orthographic" "float screenwindow" [ -2 2 -2 2 ]\n')
    cam("orthographic-dof", "orthographic, lens radius 0.1, focal distance 4",
        'LookAt 0 2.2 -4  0 0.5 1  0 1 0\nCamera "orthographic" "float screenwindow" [ -2 2 -2 2 ] "float lensradius" [ 0.1 ] "float focaldistance" [ 4 ]\n')
    cam("environment", "environment camera (lat-long), 32x16", 'LookAt 0 1 0.5  0 1 2  0 1 0\nCamera "environment"\n', res=(32, 16))
    cam("realistic", "realistic camera, a single-element lens",
        'LookAt 0 2.2 -4  0 0.5 1  0 1 0\nCamera "realistic" "string lensfile" "assets/singlet.dat" "float aperturediameter" [ 10 ] '
        '"float focusdistance" [ 5 ]\n')
    g = "sampler"
    for s in ["sobol", "random", "stratified", "02sequence", "maxmindist"]:
        add(f"sampler-{s}", g, f"the {s} sampler (64 spp)", BASE_GEOMETRY, camera=GEO_CAMERA, sampler=s, refs=("direct",))
    add("sampler-stratified-nojitter", g, "stratified sampler without jitter (8x8 strata)", BASE_GEOMETRY, camera=GEO_CAMERA,
        sampler='stratified "bool jitter" "false"', refs=("direct",))
    g = "filter"
    for f, params in [("gaussian", ""), ("mitchell", ""), ("triangle", ' "float xwidth" [ 1.5 ] "float ywidth" [ 1.5 ]'),
                      ("sinc", "")]:
        add(f"filter-{f}", g, f"{f} pixel filter{params and ' (width 1.5)'}", BASE_GEOMETRY, camera=GEO_CAMERA,
            pixel_filter=f'PixelFilter "{f}"{params}', refs=("direct",))


def rooms():
    g = "room"
    walls = [((-2, 0, -2), (2, 0, -2), (2, 0, 2), (-2, 0, 2), "0.6 0.6 0.6"),  # floor
             ((-2, 3, -2), (-2, 3, 2), (2, 3, 2), (2, 3, -2), "0.6 0.6 0.6"),  # ceiling
             ((-2, 0, 2), (2, 0, 2), (2, 3, 2), (-2, 3, 2), "0.6 0.6 0.6"),  # back
             ((-2, 0, -2), (-2, 0, 2), (-2, 3, 2), (-2, 3, -2), "0.7 0.15 0.1"),  # left
             ((2, 0, -2), (2, 3, -2), (2, 3, 2), (2, 0, 2), "0.1 0.6 0.15")]  # right
    cam = 'LookAt 0 1.5 -5.5  0 1.5 0  0 1 0\nCamera "perspective" "float fov" [ 40 ]\n'

    def room(wall_material):
        s = quad_light("10 10 10", y=2.99, x0=-0.5, x1=0.5, z0=-0.5, z1=0.5)
        for a, b, c, d, kd in walls:
            s += "AttributeBegin\n" + wall_material(kd) + "\n" + mesh([a, b, c, d], [0, 1, 2, 0, 2, 3]) + "AttributeEnd\n"
        return s

    box = ('AttributeBegin\n  Material "matte" "rgb Kd" [ 0.7 0.7 0.7 ]\n  Translate 0.6 0.6 0.5\n  Rotate 20 0 1 0\n'
           '  Scale 0.6 0.6 0.6\n  Shape "plymesh" "string filename" "assets/icosahedron.ply"\nAttributeEnd\n')
    add("room-matte", g, "closed room with coloured matte walls and a ceiling light (interreflection)",
        room(lambda kd: f'  Material "matte" "rgb Kd" [ {kd} ]') + box, camera=cam)
    add("room-glossy", g, "closed room with glossy plastic walls (roughness 0.1) and a glass sphere",
        room(lambda kd: f'  Material "plastic" "rgb Kd" [ {kd} ] "rgb Ks" [ 0.3 0.3 0.3 ] "float roughness" [ 0.1 ]')
        + sphere_at('Material "glass"', -0.6, 0.5, 0.3, 0.5), camera=cam)
    add("room-metal", g, "closed room with matte walls and a rough copper (default metal) sphere",
        room(lambda kd: f'  Material "matte" "rgb Kd" [ {kd} ]') + sphere_at('Material "metal" "float roughness" [ 0.3 ]', 0, 0.7, 0.5, 0.7),
        camera=cam)


def all_cells():
    CELLS.clear()
    materials()
    textures()
    lights()
    shapes()
    cameras_samplers_filters()
    rooms()
    # A floor-only world, lit directly, reflects nothing back: there a path is the same estimate
    # as direct lighting. Every cell here has an object above its floor, so `path` has its own
    # reference wherever the cell asks for one.
    return CELLS


# ---------------------------------------------------------------------------------------------


def write_scenes():
    gen_assets()
    cells = all_cells()
    keep = {c.name + ".pbrt" for c in cells}
    for f in os.listdir(OUT):
        if f.endswith(".pbrt") and f not in keep:
            os.remove(os.path.join(OUT, f))
    for c in cells:
        with open(os.path.join(OUT, c.name + ".pbrt"), "w") as f:
            f.write(c.text())
    with open(os.path.join(OUT, "cells.tsv"), "w") as f:
        f.write("name\tgroup\tspp\twidth\theight\trefs\twhat\n")
        for c in cells:
            f.write(f"{c.name}\t{c.group}\t{c.spp}\t{c.res[0]}\t{c.res[1]}\t{','.join(c.refs)}\t{c.what}\n")
    print(f"{len(cells)} cells written to {os.path.relpath(OUT, ROOT)}")


def render(names, force):
    cells = all_cells()
    os.makedirs(REFS, exist_ok=True)
    tsv = os.path.join(OUT, "timings.tsv")
    rows = {}
    if os.path.exists(tsv):
        for line in open(tsv).read().splitlines()[1:]:
            rows[tuple(line.split("\t")[:2])] = line
    for c in cells:
        if names and c.name not in names and c.group not in names:
            continue
        for kind in c.refs:
            out = os.path.join(REFS, f"{c.name}.{kind}.pfm")
            if os.path.exists(out) and not force:
                continue
            with tempfile.TemporaryDirectory() as tmp:
                pfm = os.path.join(tmp, "out.pfm")
                text, spp, res = c.ref_text(kind, pfm)
                scene = os.path.join(OUT, f"_ref_{c.name}.{kind}.pbrt")
                with open(scene, "w") as f:
                    f.write(text)
                try:
                    t0, c0 = time.time(), resource.getrusage(resource.RUSAGE_CHILDREN)
                    r = subprocess.run(["nice", "-n", "10", PBRT, "--quiet", "--nthreads", "2", scene],
                                       capture_output=True, text=True)
                    seconds = time.time() - t0
                    c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
                    cpu = c1.ru_utime - c0.ru_utime + c1.ru_stime - c0.ru_stime
                finally:
                    os.remove(scene)
                if r.returncode != 0 or not os.path.exists(pfm):
                    print(f"{c.name} {kind}: pbrt-v3 failed ({r.returncode}): {r.stderr.strip()[-400:]}", flush=True)
                    rows[(c.name, kind)] = f"{c.name}\t{kind}\tFAILED\t\t\t{seconds:.1f}\t{cpu:.1f}"
                    continue
                img = read_pfm(pfm)
            if res != c.res:
                img = img.reshape(c.res[1], 2, c.res[0], 2, 3).mean(axis=(1, 3))
                per_pixel = 4 * spp
            else:
                per_pixel = spp
            write_pfm(out, img)
            rows[(c.name, kind)] = f"{c.name}\t{kind}\t{per_pixel}\t{res[0]}x{res[1]}\t{spp}\t{seconds:.1f}\t{cpu:.1f}"
            print(f"{c.name} {kind}: mean {img.mean():.5f}, {seconds:.1f} s ({cpu:.1f} s CPU)", flush=True)
            write_timings(tsv, cells, rows)
    write_timings(tsv, cells, rows)


def write_timings(tsv, cells, rows):
    with open(tsv, "w") as f:
        f.write("cell\tkind\tsamples_per_pixel\tpbrt_resolution\tpbrt_spp\tpbrt_seconds\tpbrt_cpu_seconds\n")
        for c in cells:
            for kind in c.refs:
                if (c.name, kind) in rows:
                    f.write(rows[(c.name, kind)] + "\n")


def main():
    args = sys.argv[1:]
    if not args or args[0] not in ("scenes", "render", "list"):
        sys.exit(__doc__)
    if args[0] == "scenes":
        write_scenes()
    elif args[0] == "list":
        for c in all_cells():
            print(f"{c.name:32} {c.group:9} {','.join(c.refs):15} {c.what}")
    else:
        force = "--force" in args
        render([a for a in args[1:] if a != "--force"], force)


if __name__ == "__main__":
    main()
