//! `penumbra info [SCENE] [-i NAME]`: what a scene contains, checked as `render` checks it.

use crate::{cli_params, pipeline};
use penumbra_core::integrator::{build_scene, check_scene, resolve_threads};
use penumbra_core::scene::BuildOptions;
use penumbra_parser::{DiagSink, Entity, Param, ParamValue, SceneDescription, ShapeDesc};
use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct InfoArgs {
    /// The pbrt-v3 scene file (default: the embedded default scene, as `render`).
    pub scene: Option<PathBuf>,
    /// Check and describe the build for this integrator (default: the scene's, as `render`).
    #[arg(short = 'i', long = "integrator", value_parser = crate::cli_params::integrator_arg)]
    pub integrator: Option<String>,
    /// Integrator parameter `key=value`, as for `render` (repeatable).
    #[arg(long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,
}

/// Parses the scene, prints what it contains, then runs `render`'s scene build for the chosen
/// integrator without its BVH: every warning and error `render` reports before rendering, with
/// the same locations and exit status.
pub fn run(args: InfoArgs) -> ExitCode {
    let parsed = match pipeline::load_scene(args.scene.as_deref()) {
        Ok(p) => p,
        Err(e) => {
            eprint!("{e}");
            return ExitCode::FAILURE;
        }
    };
    // As `render`: a bad `--param` is a usage error.
    let params = match cli_params::parse_all(&args.params)
        .and_then(|p| pipeline::conform_params(&parsed.scene, args.integrator.as_deref(), &p))
    {
        Ok(p) => p,
        Err(d) => {
            eprint!("{d}");
            return ExitCode::from(crate::exit::USAGE);
        }
    };
    let warnings = DiagSink::new();
    warnings.extend(parsed.warnings);
    print!("{}", summary(&parsed.scene));
    let checked = check(&parsed.scene, &args, &params, &warnings);
    for w in warnings.take() {
        eprint!("{w}");
    }
    match checked {
        Ok(text) => {
            print!("{text}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprint!("{e}");
            ExitCode::FAILURE
        }
    }
}

/// What the chosen integrator would build (after checking it all but the BVH).
fn check(desc: &SceneDescription, args: &InfoArgs, params: &[Param], warnings: &DiagSink) -> Result<String, String> {
    let integrator =
        pipeline::choose_integrator(desc, args.integrator.as_deref(), params, warnings).map_err(|d| d.to_string())?;
    let req = integrator.requirements();
    // The cost estimate traces camera rays: only then is the acceleration structure built.
    let scene = if integrator.estimates_cost() {
        build_scene(integrator.as_ref(), desc, &BuildOptions::default(), warnings)
    } else {
        check_scene(integrator.as_ref(), desc, &BuildOptions::default(), warnings)
    }
    .map_err(|d| d.to_string())?;
    let mut o = String::new();
    let mut builds: Vec<&str> = Vec::new();
    for (on, what) in
        [(req.accel, "bvh"), (req.lights, "lights"), (req.materials, "materials"), (req.adjacency, "adjacency")]
    {
        if on {
            builds.push(what);
        }
    }
    builds.extend(scene.report.prepared.as_deref());
    let _ = writeln!(
        o,
        "{} builds: {} ({} spp)",
        pipeline::integrator_name(desc, args.integrator.as_deref()),
        if builds.is_empty() { "geometry only".to_string() } else { builds.join(", ") },
        scene.sampler.samples_per_pixel()
    );
    for (stage, seconds, detail) in &scene.report.stages {
        let _ = writeln!(
            o,
            "  {stage}: {seconds:.3} s{}",
            if detail.is_empty() { String::new() } else { format!(" ({detail})") }
        );
    }
    if req.accel && !integrator.estimates_cost() {
        let _ = writeln!(o, "  bvh: not built by info");
    }
    for line in &scene.report.details {
        let _ = writeln!(o, "    {line}");
    }
    if let Some(e) = integrator.estimate_cost(&scene, resolve_threads(0)) {
        for line in &e.lines {
            let _ = writeln!(o, "{line}");
        }
        if let Some(w) = &e.warning {
            let _ = writeln!(o, "warning: {w}");
        }
    }
    Ok(o)
}

/// Reads a parameter without marking it used (the summary must not hide unused-parameter warnings).
fn ints<'a>(e: &'a Entity, name: &str) -> Option<&'a [i32]> {
    match &e.params.find(name)?.value {
        ParamValue::Int(v) => Some(v),
        _ => None,
    }
}

fn one_int(e: &Entity, name: &str, default: i32) -> i32 {
    ints(e, name).and_then(|v| v.first().copied()).unwrap_or(default)
}

fn one_float(e: &Entity, name: &str) -> Option<f32> {
    match &e.params.find(name)?.value {
        ParamValue::Float(v) => v.first().copied(),
        _ => None,
    }
}

/// Triangles a shape stands for, where the scene text says (`None` for other shapes).
pub fn triangles(s: &ShapeDesc) -> Option<u64> {
    let e = &s.entity;
    match e.kind.as_str() {
        "trianglemesh" | "loopsubdiv" => ints(e, "indices").map(|v| v.len() as u64 / 3),
        "heightfield" => {
            let (nu, nv) = (one_int(e, "nu", 0) as i64, one_int(e, "nv", 0) as i64);
            Some(((nu - 1).max(0) * (nv - 1).max(0) * 2) as u64)
        }
        _ => None,
    }
}

/// Cubic Bézier segments a `curve` shape stands for, as pbrt-v3's `CreateCurveShape` counts
/// them (`None` for other shapes or a malformed curve; the build reports those).
pub fn curve_segments(s: &ShapeDesc) -> Option<u64> {
    let e = &s.entity;
    if e.kind != "curve" {
        return None;
    }
    let n = match &e.params.find("P")?.value {
        ParamValue::Point3(v) => (v.len() / 3) as i64,
        _ => return None,
    };
    let degree = one_int(e, "degree", 3) as i64;
    let bspline = matches!(&e.params.find("basis").map(|p| &p.value), Some(ParamValue::String(v)) if v.first().is_some_and(|b| b == "bspline"));
    let segments = if bspline { n - degree } else { (n - 1) / degree.max(1) };
    (segments > 0).then_some(segments as u64)
}

fn counts<'a>(it: impl Iterator<Item = &'a str>) -> String {
    let mut m: BTreeMap<&str, usize> = BTreeMap::new();
    for k in it {
        *m.entry(k).or_default() += 1;
    }
    if m.is_empty() {
        return "none".into();
    }
    m.iter().map(|(k, n)| format!("{k} x{n}")).collect::<Vec<_>>().join(", ")
}

/// The text `penumbra info` prints for a parsed scene.
pub fn summary(scene: &SceneDescription) -> String {
    let mut o = String::new();
    let _ =
        writeln!(o, "shapes: {} ({})", scene.shapes.len(), counts(scene.shapes.iter().map(|s| s.entity.kind.as_str())));
    let inst_shapes: Vec<&ShapeDesc> = scene.instance_definitions.iter().flat_map(|d| d.shapes.iter()).collect();
    let _ = writeln!(
        o,
        "instance definitions: {} with {} shape(s) ({}); instance uses: {}",
        scene.instance_definitions.len(),
        inst_shapes.len(),
        counts(inst_shapes.iter().map(|s| s.entity.kind.as_str())),
        scene.instances.len()
    );
    let tri_top: u64 = scene.shapes.iter().filter_map(triangles).sum();
    let tri_inst: u64 = inst_shapes.iter().filter_map(|s| triangles(s)).sum();
    let _ = writeln!(o, "triangles (from the text): {tri_top} (+{tri_inst} in instance definitions)");
    let seg_top: u64 = scene.shapes.iter().filter_map(curve_segments).sum();
    let seg_inst: u64 = inst_shapes.iter().filter_map(|s| curve_segments(s)).sum();
    if seg_top + seg_inst > 0 {
        let _ = writeln!(
            o,
            "curve segments (from the text): {seg_top} (+{seg_inst} in instance definitions), intersected as curves"
        );
    }
    let _ =
        writeln!(o, "lights: {} ({})", scene.lights.len(), counts(scene.lights.iter().map(|l| l.entity.kind.as_str())));
    let emitters = scene.shapes.iter().filter(|s| s.area_light.is_some()).count();
    let _ = writeln!(
        o,
        "area lights: {} ({}), on {emitters} shape(s)",
        scene.area_lights.len(),
        counts(scene.area_lights.iter().map(|e| e.kind.as_str()))
    );
    let _ = writeln!(
        o,
        "materials: {} ({})",
        scene.materials.len(),
        counts(scene.materials.iter().map(|m| m.entity.kind.as_str()))
    );
    let named: Vec<String> = scene
        .materials
        .iter()
        .filter_map(|m| m.name.as_ref().map(|n| format!("\"{n}\" ({})", m.entity.kind)))
        .collect();
    if !named.is_empty() {
        let _ = writeln!(o, "named materials: {}", named.join(", "));
    }
    let _ = writeln!(
        o,
        "textures: {} ({})",
        scene.textures.len(),
        counts(scene.textures.iter().map(|t| t.entity.kind.as_str()))
    );
    if !scene.media.is_empty() {
        let _ = writeln!(
            o,
            "media: {} ({})",
            scene.media.len(),
            counts(scene.media.iter().map(|m| m.entity.kind.as_str()))
        );
    }
    let cam = &scene.camera.entity;
    match one_float(cam, "fov") {
        Some(f) => {
            let _ = writeln!(o, "camera: {} (fov {f})", cam.kind);
        }
        None if cam.kind == "perspective" => {
            let _ = writeln!(o, "camera: perspective (fov 90, default)");
        }
        None => {
            let _ = writeln!(o, "camera: {}", cam.kind);
        }
    }
    let film = &scene.film;
    let _ =
        writeln!(o, "film: {} {}x{}", film.kind, one_int(film, "xresolution", 640), one_int(film, "yresolution", 480));
    let _ =
        writeln!(o, "sampler: {} ({} pixelsamples)", scene.sampler.kind, one_int(&scene.sampler, "pixelsamples", 16));
    let _ = writeln!(o, "filter: {}", scene.filter.kind);
    let _ = writeln!(o, "integrator: {}", scene.integrator.kind);
    o
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_counts_shapes_triangles_lights_and_defaults() {
        let text = r#"
            LookAt 0 0 -5 0 0 0 0 1 0
            Camera "perspective" "float fov" [ 35 ]
            WorldBegin
            LightSource "point" "rgb I" [1 1 1]
            AttributeBegin
              AreaLightSource "diffuse" "rgb L" [1 1 1]
              Shape "trianglemesh" "integer indices" [0 1 2 0 2 3] "point P" [0 0 0 1 0 0 1 1 0 0 1 0]
            AttributeEnd
            MakeNamedMaterial "gold" "string type" "metal"
            NamedMaterial "gold"
            Shape "heightfield" "integer nu" 3 "integer nv" 4 "float Pz" [0 0 0 0 0 0 0 0 0 0 0 0]
            Shape "sphere"
            Texture "c" "spectrum" "checkerboard"
            ObjectBegin "o"
              Shape "loopsubdiv" "integer indices" [0 1 2] "point P" [0 0 0 1 0 0 0 1 0]
            ObjectEnd
            ObjectInstance "o"
            ObjectInstance "o"
            WorldEnd
        "#;
        let out = penumbra_parser::parse_str(text, "info-test.pbrt", None).unwrap();
        let s = summary(&out.scene);
        assert!(s.contains("shapes: 3 (heightfield x1, sphere x1, trianglemesh x1)"), "{s}");
        assert!(s.contains("instance definitions: 1 with 1 shape(s) (loopsubdiv x1); instance uses: 2"), "{s}");
        // 2 mesh triangles + (3-1)*(4-1)*2 = 12 heightfield triangles; 1 loopsubdiv control triangle.
        assert!(s.contains("triangles (from the text): 14 (+1 in instance definitions)"), "{s}");
        assert!(s.contains("lights: 1 (point x1)"), "{s}");
        assert!(s.contains("area lights: 1 (diffuse x1), on 1 shape(s)"), "{s}");
        assert!(s.contains("named materials: \"gold\" (metal)"), "{s}");
        assert!(s.contains("textures: 1 (checkerboard x1)"), "{s}");
        assert!(s.contains("camera: perspective (fov 35)"), "{s}");
        assert!(s.contains("film: image 640x480"), "{s}");
        assert!(s.contains("sampler: halton (16 pixelsamples)"), "{s}");
        assert!(s.contains("filter: box"), "{s}");
        assert!(s.contains("integrator: path"), "{s}");
        // The summary reads parameters without marking them used.
        assert_eq!(out.scene.camera.entity.params.report_unused("camera").len(), 1);
    }
}
