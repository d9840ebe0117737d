"""penumbra: render pbrt-v3 scenes with selectable integrators; images as numpy arrays,
error metrics, regression checks and error-versus-time sweeps (docs/python.md)."""

from os import PathLike
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Path = Union[str, PathLike]
_ImageLike = Union[_Path, "Render", npt.ArrayLike]
_ParamValue = Union[bool, int, float, str, Sequence[Union[int, float]]]

class SceneError(Exception):
    """A scene that cannot be loaded or rendered; `str(e)` starts with `file:line:column:`."""

    file: Optional[str]
    line: Optional[int]
    column: Optional[int]
    message: str
    diagnostic: str
    """The CLI's full report, with the source line and a caret."""

class ParamError(ValueError):
    """An option or parameter the command line would refuse (names the valid ones)."""

class SceneWarning(RuntimeWarning):
    """A warning the CLI prints about a scene (an unsupported feature, an unused parameter)."""

class Render:
    """A finished render."""

    image: npt.NDArray[np.float32]
    """Linear R, G, B, shape (H, W, 3): the renderer's buffer, not a copy."""
    channels: Dict[str, npt.NDArray[np.float32]]
    """Extra channels (e.g. `sh.0`, `albedo.R`, `variance.R`), each (H, W)."""
    stats: Dict[str, Any]
    """What `penumbra render` writes to stats.json (`image` is None)."""
    integrator: str
    spp: int
    """Samples per pixel rendered (an integrator may raise the requested count)."""
    _buffer_address: int

class Scene:
    """A parsed scene: parse once, render many times."""

    def info(self) -> Dict[str, Any]:
        """Counts of shapes, lights, materials, textures; film, sampler, camera, integrator;
        `summary`: the text `penumbra info` prints."""
    def render(
        self,
        integrator: Optional[str] = None,
        params: Optional[Mapping[str, _ParamValue]] = None,
        spp: Optional[int] = None,
        seed: int = 0,
        resolution: Optional[Union[Tuple[int, int], str]] = None,
        crop: Optional[Union[Tuple[float, float, float, float], str]] = None,
        threads: Optional[int] = None,
        variance: bool = False,
        progress: Optional[Callable[[int, int], Any]] = None,
    ) -> Render:
        """Renders as `penumbra render` does (the same image bit for bit); writes nothing.
        The GIL is released; Ctrl-C cancels and raises KeyboardInterrupt; `progress(done,
        total)` is called with tile counts (raising in it cancels)."""

def load(path: _Path) -> Scene:
    """Parses a pbrt-v3 scene file; raises SceneError at file:line:column."""

def load_string(text: Optional[str] = None, name: str = "<string>", base_dir: Optional[_Path] = None) -> Scene:
    """Parses pbrt-v3 scene text (None: the embedded default scene)."""

def integrators() -> List[Dict[str, Any]]:
    """The registry: name, method, reference, params (name, type, pbrt_type, default, range, doc)."""

def diff(
    a: _ImageLike,
    b: _ImageLike,
    warn: float = 1e-6,
    fail: float = 1e-6,
    warnpercent: float = 0.0,
    failpercent: float = 0.0,
    hardwarn: float = ...,
    hardfail: float = ...,
    flip: bool = True,
) -> Dict[str, Any]:
    """`penumbra diff`'s metrics (mean_error, rms_error, psnr, max_error, mse, relmse, smape,
    flip, counts) and `status` ("pass", "warn", "fail")."""

def check(test: _ImageLike, reference: _ImageLike, **options: Any) -> Dict[str, Any]:
    """`penumbra check`'s statistical gate; options as its flags (alpha, correction,
    fail_percent, block, converged_reference, same_estimator, abs, rel, test_spp,
    reference_spp). Returns its --json report (`status`, `exit_code`)."""

def sweep(
    scene: _Path,
    integrators: Sequence[str],
    reference: Optional[Union[_Path, npt.ArrayLike]] = None,
    budgets: Optional[Sequence[int]] = None,
    params: Optional[Mapping[str, _ParamValue]] = None,
    output: Optional[_Path] = None,
    verbose: bool = False,
    **options: Any,
) -> List[Dict[str, Any]]:
    """`penumbra sweep`'s rows: one dict per integrator x budget (integrator, budget, spp,
    build_s, render_s, total_s, mae, rmse, psnr, max_err, relmse, smape, flip, nan_count).
    Give `reference` or `reference_spp=N`; other options as the CLI's flags."""

def relight(
    image: Union[_Path, Render], scene: Optional[_Path] = None, env: Optional[_Path] = None, exposure: float = 0.0
) -> npt.NDArray[np.float32]:
    """`penumbra relight`: re-shades SH transfer channels under a scene's or a map's lighting."""

def read_image(path: _Path, channels: Optional[Sequence[str]] = None) -> npt.NDArray[np.float32]:
    """Reads EXR/PNG/PFM as (H, W, C) float32 (default channels R, G, B)."""

def write_image(
    path: _Path, image: Union[Render, npt.ArrayLike], channels: Optional[Sequence[str]] = None, exposure: float = 0.0
) -> None:
    """Writes EXR (all channels), PNG (sRGB, `exposure` stops) or PFM, atomically."""
