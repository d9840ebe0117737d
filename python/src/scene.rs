//! `penumbra.load` → `Scene` → `Scene.render` → `Render`: the CLI's `render` pipeline
//! ([`penumbra_cli::pipeline`]) with its checks, the image handed to numpy without a copy.

use crate::convert::split_image;
use crate::errors::{emit_warnings, param_error, scene_error, ParamError};
use crate::run::cancellable;
use numpy::{PyArray3, PyUntypedArrayMethods};
use penumbra_cli::cli::{check_crop, full_resolution, parse_crop, parse_resolution};
use penumbra_cli::pipeline::{self, PipelineError, RenderOptions, StatsContext};
use penumbra_cli::{cli_params, info};
use penumbra_core::integrator::RenderError;
use penumbra_core::scene::{BuildOptions, Crop};
use penumbra_parser::{DiagSink, SceneDescription};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

/// A parsed pbrt-v3 scene: parse once, render many times (each render builds from a fresh
/// copy of the parsed description, so each reports its own warnings as the CLI would).
#[pyclass(frozen, module = "penumbra")]
pub struct Scene {
    desc: SceneDescription,
    label: String,
    parse_seconds: f64,
}

/// Parses a pbrt-v3 scene file (its Includes, meshes and textures are read when rendering).
///
/// Raises SceneError (with `file`, `line`, `column`) for a scene the CLI would refuse; emits
/// SceneWarning for what it would warn about.
#[pyfunction]
pub fn load(py: Python<'_>, path: PathBuf) -> PyResult<Scene> {
    let t0 = Instant::now();
    let parsed = py.detach(|| pipeline::load_scene(Some(&path))).map_err(|d| scene_error(py, &d))?;
    let warnings = DiagSink::new();
    warnings.extend(parsed.warnings);
    emit_warnings(py, &warnings)?;
    Ok(Scene { desc: parsed.scene, label: path.display().to_string(), parse_seconds: t0.elapsed().as_secs_f64() })
}

/// Parses pbrt-v3 scene text (relative paths resolve against `base_dir`, default the current
/// directory); `None` is penumbra's embedded default scene.
#[pyfunction]
#[pyo3(signature = (text=None, name="<string>", base_dir=None))]
pub fn load_string(py: Python<'_>, text: Option<&str>, name: &str, base_dir: Option<PathBuf>) -> PyResult<Scene> {
    let t0 = Instant::now();
    let parsed = match text {
        None => pipeline::load_scene(None),
        Some(t) => {
            let dir = base_dir.unwrap_or_else(|| PathBuf::from("."));
            penumbra_parser::parse_str(t, name, Some(&dir))
        }
    }
    .map_err(|d| scene_error(py, &d))?;
    let warnings = DiagSink::new();
    warnings.extend(parsed.warnings);
    emit_warnings(py, &warnings)?;
    let label = if text.is_none() { pipeline::DEFAULT_SCENE_NAME.to_string() } else { name.to_string() };
    Ok(Scene { desc: parsed.scene, label, parse_seconds: t0.elapsed().as_secs_f64() })
}

/// A finished render: `image` (float32, (H, W, 3), linear R, G, B; the renderer's buffer,
/// not a copy), `channels` (each extra channel, e.g. `sh.*`, `albedo.*`, `variance.R`, as a
/// (H, W) float32 array), `stats` (the dictionary `penumbra render` writes to stats.json).
#[pyclass(frozen, module = "penumbra")]
pub struct Render {
    #[pyo3(get)]
    pub image: Py<PyArray3<f32>>,
    #[pyo3(get)]
    pub channels: Py<PyDict>,
    #[pyo3(get)]
    pub stats: Py<PyAny>,
    #[pyo3(get)]
    pub integrator: String,
    #[pyo3(get)]
    pub spp: u32,
    /// Address of the renderer's R, G, B buffer that `image` took over (the zero-copy test).
    #[pyo3(get, name = "_buffer_address")]
    pub buffer_address: usize,
}

#[pymethods]
impl Render {
    fn __repr__(&self, py: Python<'_>) -> String {
        let shape = self.image.bind(py).shape().to_vec();
        format!("<penumbra.Render {} {}x{} at {} spp>", self.integrator, shape[1], shape[0], self.spp)
    }
}

/// `crop=`: a string `"x0,x1,y0,y1"` or four numbers, pixels (all ints) or fractions.
fn crop_arg(obj: &Bound<'_, PyAny>) -> PyResult<Crop> {
    if let Ok(s) = obj.extract::<String>() {
        return parse_crop(&s).map_err(ParamError::new_err);
    }
    let items: Vec<Bound<'_, PyAny>> = obj.extract()?;
    if items.len() != 4 {
        return Err(ParamError::new_err(format!("crop expects 4 values x0, x1, y0, y1, got {}", items.len())));
    }
    let all_int = items.iter().all(|v| v.is_instance_of::<pyo3::types::PyInt>());
    let text: Vec<String> = if all_int {
        items.iter().map(|v| v.extract::<i64>().map(|i| i.to_string())).collect::<PyResult<_>>()?
    } else {
        items.iter().map(|v| v.extract::<f64>().map(|f| format!("{f:?}"))).collect::<PyResult<_>>()?
    };
    parse_crop(&text.join(",")).map_err(ParamError::new_err)
}

/// `resolution=`: `(W, H)` or `"WxH"`, checked as `--resolution`.
fn resolution_arg(obj: &Bound<'_, PyAny>) -> PyResult<(u32, u32)> {
    let text = match obj.extract::<String>() {
        Ok(s) => s,
        Err(_) => {
            let (w, h): (i64, i64) = obj.extract()?;
            format!("{w}x{h}")
        }
    };
    parse_resolution(&text).map_err(ParamError::new_err)
}

/// `params=` as `--param key=value` arguments (bools as true/false, sequences comma-separated).
pub fn param_args(params: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<String>> {
    let Some(d) = params else { return Ok(Vec::new()) };
    let mut out = Vec::new();
    for (k, v) in d.iter() {
        let key: String = k.extract()?;
        let value = if let Ok(b) = v.extract::<bool>() {
            b.to_string()
        } else if v.is_instance_of::<pyo3::types::PyString>() {
            v.extract::<String>()?
        } else if let Ok(items) = v.extract::<Vec<Bound<'_, PyAny>>>() {
            items.iter().map(|i| i.str().map(|s| s.to_string())).collect::<PyResult<Vec<_>>>()?.join(",")
        } else {
            v.str()?.to_string()
        };
        out.push(format!("{key}={value}"));
    }
    Ok(out)
}

/// `spp=`: 1..=2^24, as `--spp`.
pub fn spp_arg(spp: Option<i64>) -> PyResult<Option<u32>> {
    let max = penumbra_core::sampler::MAX_SAMPLES;
    match spp {
        None => Ok(None),
        Some(n) if n >= 1 && n <= max => Ok(Some(n as u32)),
        Some(n) => Err(ParamError::new_err(format!("spp must lie in 1..={max}, got {n}"))),
    }
}

fn pipeline_error(py: Python<'_>, e: PipelineError) -> PyErr {
    match e {
        PipelineError::Scene(d) => scene_error(py, &d),
        PipelineError::Render(RenderError::Cancelled) => {
            pyo3::exceptions::PyKeyboardInterrupt::new_err("render cancelled")
        }
        other => pyo3::exceptions::PyRuntimeError::new_err(other.to_string()),
    }
}

#[pymethods]
impl Scene {
    /// What the scene contains (the counts and text `penumbra info` prints), its film,
    /// sampler, camera and integrator.
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = &self.desc;
        let out = PyDict::new(py);
        out.set_item("file", &self.label)?;
        let count = |kinds: Vec<&str>| {
            let mut m: BTreeMap<String, usize> = BTreeMap::new();
            for k in kinds {
                *m.entry(k.to_string()).or_default() += 1;
            }
            m
        };
        out.set_item("shapes", count(d.shapes.iter().map(|s| s.entity.kind.as_str()).collect()))?;
        out.set_item("lights", count(d.lights.iter().map(|l| l.entity.kind.as_str()).collect()))?;
        out.set_item("area_lights", count(d.area_lights.iter().map(|e| e.kind.as_str()).collect()))?;
        out.set_item("materials", count(d.materials.iter().map(|m| m.entity.kind.as_str()).collect()))?;
        out.set_item("textures", count(d.textures.iter().map(|t| t.entity.kind.as_str()).collect()))?;
        out.set_item("instances", d.instances.len())?;
        out.set_item("triangles", d.shapes.iter().filter_map(info::triangles).sum::<u64>())?;
        out.set_item("camera", d.camera.entity.kind.as_str())?;
        out.set_item("film", d.film.kind.as_str())?;
        out.set_item("resolution", full_resolution(d, None))?;
        out.set_item("sampler", d.sampler.kind.as_str())?;
        let spp = d.sampler.params.find("pixelsamples").and_then(|p| match &p.value {
            penumbra_parser::ParamValue::Int(v) => v.first().copied(),
            _ => None,
        });
        out.set_item("pixelsamples", spp)?;
        out.set_item("integrator", d.integrator.kind.as_str())?;
        out.set_item("renders_with", pipeline::integrator_name(d, None))?;
        out.set_item("files_read", d.files_read.iter().map(|p| p.display().to_string()).collect::<Vec<_>>())?;
        out.set_item("summary", info::summary(d))?;
        Ok(out)
    }

    /// Renders the scene as `penumbra render` does (the same image bit for bit for the same
    /// options) and returns a Render. Nothing is written to disk.
    ///
    /// integrator: overrides the scene's (`-i`); params: integrator parameters (`--param`,
    /// checked against what the integrator declares: an unknown name raises ParamError naming
    /// the valid ones); spp; seed; resolution (W, H); crop (x0, x1, y0, y1) in pixels (ints)
    /// or fractions; threads (default all cores); variance: add `variance.R/G/B` channels;
    /// progress: called as progress(done_tiles, total_tiles) on this thread (raising in it
    /// cancels the render). The GIL is released while rendering; Ctrl-C cancels the render
    /// and raises KeyboardInterrupt.
    #[pyo3(signature = (integrator=None, params=None, spp=None, seed=0, resolution=None, crop=None, threads=None, variance=false, progress=None))]
    #[allow(clippy::too_many_arguments)]
    fn render(
        &self,
        py: Python<'_>,
        integrator: Option<String>,
        params: Option<&Bound<'_, PyDict>>,
        spp: Option<i64>,
        seed: u64,
        resolution: Option<&Bound<'_, PyAny>>,
        crop: Option<&Bound<'_, PyAny>>,
        threads: Option<usize>,
        variance: bool,
        progress: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Render> {
        let integrator = integrator.map(|n| cli_params::integrator_arg(&n).map_err(ParamError::new_err)).transpose()?;
        let spp = spp_arg(spp)?;
        let resolution = resolution.map(resolution_arg).transpose()?;
        let crop = crop.map(crop_arg).transpose()?;
        if let Some(c) = crop {
            check_crop(c, full_resolution(&self.desc, resolution)).map_err(ParamError::new_err)?;
        }
        let param_text = param_args(params)?;
        let parsed = cli_params::parse_all(&param_text)
            .and_then(|p| pipeline::conform_params(&self.desc, integrator.as_deref(), &p))
            .map_err(|d| param_error(&d))?;
        let (threads, _) = cli_params::thread_count(threads.unwrap_or(0));
        let desc = self.desc.clone();
        let warnings = DiagSink::new();
        let result = cancellable(py, progress, |cancel, prog| {
            let report = |done: u64, total: u64| prog.set(done, total);
            let opts = RenderOptions {
                integrator: integrator.as_deref(),
                params: &parsed,
                build: BuildOptions { spp, seed, crop, resolution },
                threads,
                with_variance: variance,
                cancel,
                progress: Some(&report),
            };
            pipeline::render(&desc, &opts, &warnings)
        })?;
        emit_warnings(py, &warnings)?;
        let rendered = result.map_err(|e| pipeline_error(py, e))?;
        let stats = pipeline::stats_json(
            &rendered,
            &StatsContext {
                scene: &self.label,
                parameters: &param_text,
                image: None,
                seed,
                exposure: 0.0,
                parse_seconds: self.parse_seconds,
            },
        );
        let stats = py.import("json")?.call_method1("loads", (stats.to_string(),))?;
        let (integrator, spp) = (rendered.integrator.clone(), rendered.stats.spp);
        let (image, channels, buffer_address) = split_image(py, rendered.image)?;
        Ok(Render {
            image: image.unbind(),
            channels: channels.unbind(),
            stats: stats.unbind(),
            integrator,
            spp,
            buffer_address,
        })
    }

    fn __repr__(&self) -> String {
        format!("<penumbra.Scene {}>", self.label)
    }
}
