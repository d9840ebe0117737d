"""Scene loading and rendering: the CLI's image bit for bit, no copy, errors, stats, the GIL."""

import subprocess
import threading
import time

import numpy as np
import pytest

import penumbra

OPTS = dict(spp=4, resolution=(32, 24), seed=3)


def cli_render(cli, scene, out, integrator, extra=()):
    cmd = [str(cli), "render", str(scene), "-i", integrator, "--spp", "4", "--resolution", "32x24",
           "--seed", "3", "--quiet", "-o", str(out), *extra]
    subprocess.run(cmd, check=True)
    return penumbra.read_image(out)


@pytest.mark.parametrize("integrator", ["directlighting", "ltc", "path"])
def test_render_equals_cli_bit_for_bit(cli, scene_path, tmp_path, integrator):
    r = penumbra.load(scene_path).render(integrator=integrator, **OPTS)
    ref = cli_render(cli, scene_path, tmp_path / "cli.exr", integrator)
    assert r.image.shape == (24, 32, 3) and r.image.dtype == np.float32
    # Bit for bit: compare the float32 bit patterns (NaN-safe, -0.0 distinct).
    assert np.array_equal(r.image.view(np.uint32), ref.view(np.uint32))
    assert r.image.max() > 0


def test_params_and_crop_equal_cli(cli, scene_path, tmp_path):
    r = penumbra.load(scene_path).render(integrator="ltc", params={"shadows": False}, crop=(8, 24, 4, 20), **OPTS)
    ref = cli_render(cli, scene_path, tmp_path / "c.exr", "ltc", ["--param", "shadows=false", "--crop", "8,24,4,20"])
    assert r.image.shape == (16, 16, 3)
    assert np.array_equal(r.image.view(np.uint32), ref.view(np.uint32))


def test_image_is_the_renderers_buffer_not_a_copy(scene_path):
    r = penumbra.load(scene_path).render(integrator="ltc", **OPTS)
    img = r.image
    assert img.__array_interface__["data"][0] == r._buffer_address
    assert not img.flags.owndata and img.base is not None  # owned by the Rust buffer
    assert img.flags.c_contiguous and img.flags.writeable
    assert r.image is r.image  # the same array on every access


def test_variance_channels_and_stats(scene_path):
    r = penumbra.load(scene_path).render(integrator="directlighting", variance=True, **OPTS)
    assert sorted(r.channels) == ["variance.B", "variance.G", "variance.R"]
    assert all(c.shape == (24, 32) and c.dtype == np.float32 for c in r.channels.values())
    assert (r.channels["variance.R"] >= 0).all()
    s = r.stats
    assert s["integrator"] == "directlighting" and s["spp"] == 4 and s["seed"] == 3
    assert s["resolution"] == [32, 24] and s["image"] is None
    assert s["stats"]["rays"] > 0 and "render_seconds" in s
    assert r.spp == 4 and r.integrator == "directlighting"


def test_info(scene_path):
    info = penumbra.load(scene_path).info()
    assert info["integrator"] == "directlighting" and info["resolution"] == (256, 256)
    assert info["pixelsamples"] == 16 and info["area_lights"] == {"diffuse": 1}
    assert "shapes:" in info["summary"]


def test_parse_error_has_location(tmp_path):
    bad = tmp_path / "bad.pbrt"
    bad.write_text('WorldBegin\nShape "sphere"\n  "float radius" [ 1 \nWorldEnd\n')
    with pytest.raises(penumbra.SceneError) as e:
        penumbra.load(bad)
    err = e.value
    assert err.file.endswith("bad.pbrt") and err.line >= 3 and err.column >= 1
    assert str(err).startswith(f"{err.file}:{err.line}:{err.column}: ")


def test_missing_file_raises_scene_error(tmp_path):
    with pytest.raises(penumbra.SceneError):
        penumbra.load(tmp_path / "nope.pbrt")


def test_parameter_typo_names_valid_ones(scene_path):
    s = penumbra.load(scene_path)
    with pytest.raises(penumbra.ParamError, match="nsamples"):
        s.render(integrator="ambientocclusion", params={"nsamplez": 4}, **OPTS)
    with pytest.raises(penumbra.ParamError, match="valid names"):
        s.render(integrator="ltcc", **OPTS)
    with pytest.raises(ValueError, match="shadows"):  # ParamError is a ValueError
        s.render(integrator="ltc", params={"shadows": "maybe"}, **OPTS)
    with pytest.raises(penumbra.ParamError):
        s.render(spp=0)
    with pytest.raises(penumbra.ParamError, match="outside"):
        s.render(crop=(0, 64, 0, 8), resolution=(32, 24), spp=1)


def test_integrators_registry():
    names = {e["name"]: e for e in penumbra.integrators()}
    assert {"directlighting", "path", "ltc", "ambientocclusion"} <= set(names)
    ao = {p["name"]: p for p in names["ambientocclusion"]["params"]}
    assert ao["nsamples"]["type"] == "integer" and ao["nsamples"]["doc"]


def test_gil_released_while_rendering(scene_path):
    s = penumbra.load(scene_path)
    ticks = 0
    stop = threading.Event()

    def count():
        nonlocal ticks
        while not stop.is_set():
            ticks += 1
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    t0 = time.perf_counter()
    s.render(integrator="path", spp=16, resolution=(64, 64), threads=1)
    elapsed = time.perf_counter() - t0
    stop.set()
    t.join()
    # With the GIL held the counter could not move during the render at all; released, it
    # ticks about once a millisecond (a quarter of that is ample margin under load).
    assert ticks > elapsed * 1000 / 4, (ticks, elapsed)


def test_progress_callback(scene_path):
    calls = []
    penumbra.load(scene_path).render(integrator="ltc", spp=4, resolution=(64, 64), progress=lambda d, t: calls.append((d, t)))
    assert calls and calls[-1][0] == calls[-1][1] and calls[-1][1] > 0


def test_progress_callback_exception_cancels(scene_path):
    def boom(done, total):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        penumbra.load(scene_path).render(integrator="path", spp=64, resolution=(128, 128), progress=boom)


def test_read_write_roundtrip(tmp_path):
    a = np.random.default_rng(1).random((5, 7, 3), dtype=np.float32)
    penumbra.write_image(tmp_path / "a.exr", a)
    assert np.array_equal(penumbra.read_image(tmp_path / "a.exr"), a)
    penumbra.write_image(tmp_path / "a.png", a)
    assert penumbra.read_image(tmp_path / "a.png").shape == (5, 7, 3)
    with pytest.raises(ValueError, match="R, G, B"):
        penumbra.read_image(tmp_path / "a.exr", channels=["Z"])


def test_cli_warnings_are_python_warnings(scene_path):
    with pytest.warns(penumbra.SceneWarning, match=r"quad-cube.pbrt:7:1: 4 samples per pixel raised to 16"):
        penumbra.load(scene_path).render(integrator="ltc", **OPTS)
