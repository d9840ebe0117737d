//! A suite case's renders: penumbra in-process (EXR with variance channels and a
//! `.stats.json` with the samples per pixel, as `penumbra render --variance` writes), or
//! pbrt-v3's binary for references.

use super::spec::Case;
use crate::cli_params;
use crate::pipeline::{self, RenderOptions};
use penumbra_core::image;
use penumbra_core::scene::BuildOptions;
use penumbra_parser::{DiagSink, Entity};
use std::path::Path;
use std::sync::atomic::AtomicBool;

/// What to render: the case's test side or its reference side.
pub struct Request<'a> {
    pub case: &'a Case,
    pub integrator: Option<&'a str>,
    pub params: &'a [String],
    pub spp: Option<u32>,
    pub seed: u64,
}

impl<'a> Request<'a> {
    pub fn test(case: &'a Case) -> Request<'a> {
        Request { case, integrator: case.integrator.as_deref(), params: &case.params, spp: case.spp, seed: case.seed }
    }

    /// The reference by penumbra: `reference_integrator` (default the case's), its own
    /// parameters, `reference_spp` (default the case's spp) and an independent seed.
    pub fn reference(case: &'a Case) -> Request<'a> {
        let integrator = case.reference_integrator.as_deref().or(case.integrator.as_deref());
        let params = if case.reference_integrator.is_some() { &case.reference_params } else { &case.params };
        Request { case, integrator, params, spp: case.reference_spp.or(case.spp), seed: case.reference_seed }
    }
}

/// Renders `req` into `output` (EXR, with variance) and its stats beside it; returns the
/// warnings' messages.
pub fn penumbra(req: &Request, output: &Path, threads: usize, cancel: &AtomicBool) -> Result<Vec<String>, String> {
    let c = req.case;
    let mut parsed = pipeline::load_scene(c.scene.as_deref()).map_err(|d| d.to_string().trim_end().to_string())?;
    if let Some(s) = &c.sampler {
        parsed.scene.sampler = Entity::default_of(s);
    }
    let warnings = DiagSink::new();
    warnings.extend(std::mem::take(&mut parsed.warnings));
    let params = cli_params::parse_all(req.params)
        .and_then(|p| pipeline::conform_params(&parsed.scene, req.integrator, &p))
        .map_err(|d| format!("{}: params: {}", c.at, d.to_string().trim_end()))?;
    let opts = RenderOptions {
        integrator: req.integrator,
        params: &params,
        build: BuildOptions { spp: req.spp, seed: req.seed, crop: None, resolution: c.resolution },
        threads,
        with_variance: true,
        cancel,
        progress: None,
    };
    let r = pipeline::render(&parsed.scene, &opts, &warnings).map_err(|e| e.to_string())?;
    image::write(&r.image, output).map_err(|e| e.to_string())?;
    let stats = serde_json::json!({
        "scene": c.scene.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| "<default>".into()),
        "integrator": r.integrator,
        "parameters": req.params,
        "image": output.display().to_string(),
        "spp": r.stats.spp,
        "seed": req.seed,
        "render_seconds": r.stats.render_seconds,
        "written_by": "penumbra check --suite",
    });
    write_stats(output, &stats)?;
    Ok(warnings.take().iter().map(|d| d.message.clone()).collect())
}

/// `NAME.stats.json` beside `image`.
pub fn write_stats(image: &Path, stats: &serde_json::Value) -> Result<(), String> {
    let stem = image.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let path = image.with_file_name(format!("{stem}.stats.json"));
    let text = serde_json::to_string_pretty(stats).unwrap_or_default();
    image::write_atomic(&path, |w| w.write_all(text.as_bytes())).map_err(|e| format!("{}: {e}", path.display()))
}

/// Renders the case's reference with pbrt-v3 (`pbrt --outfile REF SCENE`): the scene file as
/// it is, so the case's `integrator`, `spp`, `resolution` and `sampler` overrides cannot apply
/// (an error rather than a silently different reference). Records `reference_spp` when given.
pub fn pbrt(case: &Case, pbrt: &Path, output: &Path, threads: usize) -> Result<(), String> {
    let overrides: Vec<&str> = [
        ("integrator", case.reference_integrator.is_some()),
        ("spp", case.spp.is_some()),
        ("resolution", case.resolution.is_some()),
        ("sampler", case.sampler.is_some()),
    ]
    .iter()
    .filter(|(_, set)| *set)
    .map(|(k, _)| *k)
    .collect();
    if !overrides.is_empty() {
        return Err(format!(
            "{}: case {:?}: pbrt-v3 renders the scene file as it is; the case overrides {} (write them into the scene instead)",
            case.at,
            case.name,
            overrides.join(", ")
        ));
    }
    let scene = case.scene.as_deref().ok_or_else(|| format!("{}: a pbrt-v3 reference needs a scene", case.at))?;
    let mut cmd = std::process::Command::new(pbrt);
    cmd.arg("--outfile").arg(output);
    if threads > 0 {
        cmd.arg("--nthreads").arg(threads.to_string());
    }
    let out = cmd.arg(scene).output().map_err(|e| format!("{}: {e}", pbrt.display()))?;
    if !out.status.success() || !output.exists() {
        let err = String::from_utf8_lossy(&out.stderr);
        let tail: Vec<&str> = err.lines().rev().take(5).collect();
        return Err(format!(
            "{} failed ({}): {}",
            pbrt.display(),
            out.status,
            tail.into_iter().rev().collect::<Vec<_>>().join(" | ")
        ));
    }
    if let Some(spp) = case.reference_spp {
        write_stats(output, &serde_json::json!({ "spp": spp, "written_by": "pbrt-v3 via penumbra check --suite" }))?;
    }
    Ok(())
}
