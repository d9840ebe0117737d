//! [`Scene::build`]: the stages that turn a parsed scene into a renderable one, each timed
//! into the [`BuildReport`], each built only when the [`Requirements`] ask for it.

use super::cutout::{self, CutoutTest};
use super::{BuildOptions, BuildReport, Crop, Requirements, Scene};
use crate::accel::{Accel, AccelKind, Mover};
use crate::camera::Camera;
use crate::film::FilmSpec;
use crate::filter::create_filter;
use crate::geometry::{Bounds2i, Bounds3};
use crate::interaction::SceneObject;
use crate::light::Lights;
use crate::material::Materials;
use crate::mesh::{EdgeAdjacency, TriangleMesh};
use crate::motion::MovingTransform;
use crate::sampler::{create_sampler, Sampler};
use crate::shapes::{build_shape_moving, ShapeContext, Tessellation, TriangleBudget};
use crate::texture::Textures;
use glam::IVec2;
use penumbra_parser::{AnimatedTransform, DiagSink, Diagnostic, SceneDescription, ShapeDesc};
use std::sync::Arc;
use std::time::Instant;

impl Scene {
    /// Builds what `req` asks for. Warnings go to `warnings`; unused parameters of
    /// every entity the build consumed are reported there too.
    pub fn build(
        desc: &SceneDescription,
        req: Requirements,
        opts: &BuildOptions,
        warnings: &DiagSink,
    ) -> Result<Scene, Diagnostic> {
        let mut report = BuildReport::default();
        let t0 = Instant::now();
        let film = film_spec(desc, opts, warnings)?;
        warnings.extend(desc.film.params.report_unused("film \"image\""));
        let camera = Camera::from_scene(desc, film.full_resolution, warnings)?;
        warnings.extend(desc.camera.entity.params.report_unused(&format!("camera \"{}\"", desc.camera.entity.kind)));
        let filter =
            create_filter(&desc.filter).map_err(|e| Diagnostic::error(Some(desc.filter.loc.clone()), e.to_string()))?;
        warnings.extend(desc.filter.params.report_unused(&format!("filter \"{}\"", desc.filter.kind)));
        let sampler = sampler(desc, req, opts, warnings)?;
        report.stages.push(("camera, film, sampler".into(), t0.elapsed().as_secs_f64(), String::new()));
        warn_media(desc, warnings);

        let t1 = Instant::now();
        let Shapes { meshes, objects, movers } = shapes(desc, warnings)?;
        let ntris: usize = meshes.iter().map(|m| m.triangle_count()).sum();
        report.stages.push((
            "shapes".into(),
            t1.elapsed().as_secs_f64(),
            format!("{} meshes, {} triangles", meshes.len(), ntris),
        ));

        let mut bounds = Bounds3::EMPTY;
        for m in &meshes {
            for p in &m.positions {
                bounds.extend(*p);
            }
        }
        // A moving shape's whole motion (lights sized by the scene's bounds reach it anywhere).
        for m in &movers {
            for o in &m.object {
                let mut b = Bounds3::EMPTY;
                o.positions.iter().for_each(|p| b.extend(*p));
                if !b.is_empty() {
                    let (lo, hi) = m.transform.motion_bounds(b.min.as_dvec3(), b.max.as_dvec3());
                    if lo.is_finite() && hi.is_finite() {
                        bounds.extend(lo.as_vec3());
                        bounds.extend(hi.as_vec3());
                    }
                }
            }
        }
        // Textures: those of the cut-outs (every query tests them) and, when asked, the
        // materials' — one table, so a texture both use is built (and reported) once.
        let mut textures = Textures::new(desc);
        let t = Instant::now();
        let cutouts = cutout::build_textures(&meshes, &mut textures, warnings)?;
        if cutouts {
            report.stages.push((
                "cut-outs".into(),
                t.elapsed().as_secs_f64(),
                format!("{} textures", textures.built_count()),
            ));
        }
        let materials = if req.materials {
            let m = materials(desc, &objects, &mut textures, warnings, &mut report)?;
            if !req.subsurface {
                warn_interface_only(desc, &m, warnings);
            }
            Some(m)
        } else {
            None
        };
        let textures = (req.materials || cutouts).then(|| Arc::new(textures));
        let accel = if req.accel {
            let mut kind = accel_kind(desc, warnings);
            if kind == AccelKind::Embree && meshes.iter().any(|m| m.curves.is_some()) {
                warnings.warn(
                    Some(desc.accelerator.loc.clone()),
                    "Accelerator \"embree\": the scene has curves, which penumbra gives Embree no geometry for: using \"bvh\"",
                );
                kind = AccelKind::Bvh;
            }
            if kind == AccelKind::Embree && !movers.is_empty() {
                let o = &objects[movers[0].meshes[0] as usize];
                warnings.warn(
                    Some(desc.accelerator.loc.clone()),
                    format!(
                        "Accelerator \"embree\": shape \"{}\" at {} moves (animated transform), which penumbra gives \
                         Embree no geometry for: using \"bvh\"",
                        o.kind, o.loc
                    ),
                );
                kind = AccelKind::Bvh;
            }
            let mut a = Accel::build_moving(&meshes, kind, &movers);
            if let Some(test) = textures.as_ref().and_then(|t| CutoutTest::new(&meshes, t.clone())) {
                a.set_filter(Arc::new(test));
            }
            let by = if a.kind() == AccelKind::Embree { " (Embree)" } else { "" };
            let (pieces, moving) = (a.curve_piece_count(), a.mover_count());
            let mut what = format!("{} triangles", a.triangle_count() - pieces - moving);
            if pieces > 0 {
                what += &format!(", {pieces} curve pieces");
            }
            if moving > 0 {
                what += &format!(", {moving} moving shapes (each a hierarchy of its own)");
            }
            what += by;
            if a.duplicates > 0 {
                warnings.warn(
                    a.duplicates_in.and_then(|m| objects.get(m)).map(|o| o.loc.clone()),
                    format!(
                        "{} triangles repeat an earlier triangle of their shape (the same corners): \
                         traced once",
                        a.duplicates
                    ),
                );
            }
            report.stages.push(("bvh".into(), a.build_seconds, what));
            Some(a)
        } else {
            None
        };
        let adjacency = if req.adjacency { adjacency(&meshes, &mut report) } else { Vec::new() };
        let lights = if req.lights {
            let t = Instant::now();
            let l = Lights::build(desc, &meshes, &objects, bounds, warnings)?;
            report.stages.push(("lights".into(), t.elapsed().as_secs_f64(), format!("{} lights", l.len())));
            Some(l)
        } else {
            None
        };
        Ok(Scene {
            camera,
            film,
            filter,
            sampler,
            meshes,
            objects,
            accel,
            adjacency,
            lights,
            materials,
            textures,
            bounds,
            integrator: desc.integrator.clone(),
            report,
            prepared: None,
            mover_lookup: mover_lookup(&movers),
            movers,
        })
    }
}

impl Scene {
    /// Everything [`Scene::build`] checks for `req` — the same warnings and errors, at the same
    /// locations — without building the acceleration structure (`penumbra info`).
    pub fn check(
        desc: &SceneDescription,
        req: Requirements,
        opts: &BuildOptions,
        warnings: &DiagSink,
    ) -> Result<Scene, Diagnostic> {
        Scene::build(desc, Requirements { accel: false, ..req }, opts, warnings)
    }
}

/// The film the build makes: resolution, `--resolution`, crop and pixel bounds applied.
pub fn film_spec(desc: &SceneDescription, opts: &BuildOptions, warnings: &DiagSink) -> Result<FilmSpec, Diagnostic> {
    let e = &desc.film;
    let p = &e.params;
    if e.kind != "image" {
        warnings.warn(
            Some(e.loc.clone()),
            format!("film \"{}\" is not pbrt-v3's \"image\": treating it as \"image\"", e.kind),
        );
    }
    let mut res = (p.get_one_int("xresolution", 1280), p.get_one_int("yresolution", 720));
    if res.0 <= 0 || res.1 <= 0 || res.0 > 1 << 16 || res.1 > 1 << 16 {
        return Err(Diagnostic::error(
            Some(e.loc.clone()),
            format!("film resolution {}x{} is out of range", res.0, res.1),
        ));
    }
    let file_res = (res.0 as u32, res.1 as u32);
    if let Some(r) = opts.resolution {
        res = (r.0 as i32, r.1 as i32);
    }
    let full = (res.0 as u32, res.1 as u32);
    let mut crop = [0.0f32, 1.0, 0.0, 1.0];
    if let Some(c) = p.get_floats("cropwindow") {
        if c.len() == 4 {
            crop = [c[0], c[1], c[2], c[3]];
        } else {
            warnings.warn(p.loc_of("cropwindow").cloned(), "\"cropwindow\" needs 4 values: ignored");
        }
    }
    let mut pixel_bounds = FilmSpec::crop_to_pixels(full, crop);
    if let Some(pb) = p.get_ints("pixelbounds") {
        if pb.len() == 4 && opts.resolution.is_none() {
            pixel_bounds = pixel_bounds.intersect(&Bounds2i::new(IVec2::new(pb[0], pb[2]), IVec2::new(pb[1], pb[3])));
        }
    }
    match opts.crop {
        Some(Crop::Fraction(c)) => pixel_bounds = FilmSpec::crop_to_pixels(full, c),
        Some(Crop::Pixels(c)) => {
            pixel_bounds = Bounds2i::new(IVec2::new(c[0], c[2]), IVec2::new(c[1], c[3]))
                .intersect(&Bounds2i::new(IVec2::ZERO, IVec2::new(full.0 as i32, full.1 as i32)))
        }
        None => {}
    }
    if pixel_bounds.is_empty() {
        return Err(Diagnostic::error(Some(e.loc.clone()), "the crop window / pixel bounds contain no pixels"));
    }
    let _ = file_res;
    p.get_floats("diagonal");
    Ok(FilmSpec {
        full_resolution: full,
        pixel_bounds,
        filename: p.get_one_string("filename", "pbrt.exr"),
        scale: p.get_one_float("scale", 1.0),
        max_sample_luminance: p.get_one_float("maxsampleluminance", f32::INFINITY),
    })
}

/// The scene's sampler, with `--spp` applied and the count raised to the integrator's
/// `min_pixel_samples` (with a warning saying why).
fn sampler(
    desc: &SceneDescription,
    req: Requirements,
    opts: &BuildOptions,
    warnings: &DiagSink,
) -> Result<Box<dyn Sampler>, Diagnostic> {
    let sampler_with = |spp: Option<u32>, warnings: &DiagSink| {
        create_sampler(&desc.sampler, spp, opts.seed, warnings)
            .map_err(|e| Diagnostic::error(Some(e.loc().clone()), e.to_string()))
    };
    let mut sampler = sampler_with(opts.spp, warnings)?;
    if let Some((min, why)) = req.min_pixel_samples {
        let n = sampler.samples_per_pixel();
        if n < min {
            sampler = sampler_with(Some(min), warnings)?;
            warnings.warn(
                Some(desc.sampler.loc.clone()),
                format!("{n} samples per pixel raised to {}: {why}", sampler.samples_per_pixel()),
            );
        }
    }
    warnings.extend(desc.sampler.params.report_unused(&format!("sampler \"{}\"", desc.sampler.kind)));
    Ok(sampler)
}

/// Media are parsed but not rendered: one warning when the scene has any.
/// The backend the scene's `Accelerator` asks for: `"embree"` is Embree where this build has
/// it; everything else (pbrt-v3's `"bvh"` and `"kdtree"`) is the BVH, with a warning for
/// what is not.
fn accel_kind(desc: &SceneDescription, warnings: &DiagSink) -> AccelKind {
    let e = &desc.accelerator;
    match e.kind.as_str() {
        "bvh" => AccelKind::Bvh,
        "embree" if AccelKind::EMBREE_AVAILABLE => AccelKind::Embree,
        "embree" => {
            warnings.warn(
                Some(e.loc.clone()),
                "Accelerator \"embree\": this penumbra was built without Embree (cargo feature \"embree\"): using \"bvh\"",
            );
            AccelKind::Bvh
        }
        other => {
            warnings.warn(Some(e.loc.clone()), format!("Accelerator \"{other}\" is not implemented: using \"bvh\""));
            AccelKind::Bvh
        }
    }
}

fn warn_media(desc: &SceneDescription, warnings: &DiagSink) {
    if !desc.media.is_empty() || desc.shapes.iter().any(|s| s.inside_medium.is_some() || s.outside_medium.is_some()) {
        warnings.warn(
            desc.media.first().map(|m| m.entity.loc.clone()),
            "participating media are not supported: rendering as if every medium were vacuum",
        );
    }
}

/// Every shape directive, then every shape of every object instance (with the instance's
/// transform), as world-space meshes with one [`SceneObject`] each; the meshes of shapes that
/// move (their own or their instance's transform animated) are at their start transforms and
/// are also listed as [`Mover`]s: one per shape directive, one per animated instance (as
/// pbrt-v3 makes one `TransformedPrimitive` of each).
fn shapes(desc: &SceneDescription, warnings: &DiagSink) -> Result<Shapes, Diagnostic> {
    let mut ctx = ShapeContext::for_scene(desc, warnings, Tessellation::default());
    ctx.budget = TriangleBudget::from_env().map_err(|e| Diagnostic::error(None, e))?;
    let mut out = Shapes::default();
    let fixed = AnimatedTransform::default();
    for s in &desc.shapes {
        out.add(s, None, &fixed, &s.render_from_object, &ctx)?;
        warnings.extend(s.entity.params.report_unused(&format!("shape \"{}\"", s.entity.kind)));
    }
    for (ii, inst) in desc.instances.iter().enumerate() {
        let Some(def) = desc.instance_definitions.get(inst.definition) else { continue };
        let moving_instance = inst.render_from_instance.is_animated();
        let first_mover = out.movers.len();
        for own in &def.shapes {
            let mut s = own.clone();
            s.render_from_object.start = inst.render_from_instance.start.compose(&s.render_from_object.start);
            s.render_from_object.end = inst.render_from_instance.end.compose(&s.render_from_object.end);
            out.add(&s, Some(ii), &inst.render_from_instance, &own.render_from_object, &ctx)?;
        }
        // An animated instance moves as one: its shapes' movers merge into one hierarchy.
        if moving_instance && out.movers.len() > first_mover + 1 {
            let mut merged = out.movers.split_off(first_mover);
            let mut one = merged.remove(0);
            let same = merged.iter().all(|m| m.transform == one.transform);
            if same {
                for m in merged {
                    one.meshes.extend(m.meshes);
                    one.object.extend(m.object);
                }
                out.movers.push(one);
            } else {
                out.movers.push(one);
                out.movers.extend(merged);
            }
        }
    }
    Ok(out)
}

#[derive(Default)]
struct Shapes {
    meshes: Vec<TriangleMesh>,
    objects: Vec<SceneObject>,
    movers: Vec<Mover>,
}

impl Shapes {
    /// One shape's mesh and object (nothing for a shape that tessellates to no triangles).
    /// (The parser has dropped the area light of a moving shape, with pbrt-v3's warning.)
    /// `s.render_from_object` is world from object (the instance's transform composed in);
    /// `outer` is the instance's transform (identity for a shape directive) and `own` the
    /// shape's, so that the shape moves by `outer(t) · own(t)`.
    fn add(
        &mut self,
        s: &ShapeDesc,
        instance: Option<usize>,
        outer: &AnimatedTransform,
        own: &AnimatedTransform,
        ctx: &ShapeContext,
    ) -> Result<(), Diagnostic> {
        let Some((mesh, object)) = build_shape_moving(s, ctx)? else { return Ok(()) };
        if let Some(object) = object {
            let transform = MovingTransform::new(outer, own);
            match transform {
                Some(transform) => {
                    let mut o = mesh.clone();
                    o.positions = object.positions;
                    o.normals = object.normals;
                    o.tangents = object.tangents;
                    o.quadric = None;
                    self.movers.push(Mover { transform, meshes: vec![self.meshes.len() as u32], object: vec![o] });
                }
                None => ctx.warnings.warn(
                    Some(s.entity.loc.clone()),
                    format!(
                        "shape \"{}\": animated transform with a singular keyframe or TransformTimes end <= start: no \
                         motion (using its start transform)",
                        s.entity.kind
                    ),
                ),
            }
        }
        self.meshes.push(mesh);
        self.objects.push(SceneObject {
            kind: s.entity.kind.clone(),
            loc: s.entity.loc.clone(),
            material: s.material,
            area_light: s.area_light,
            instance,
            occluder: s.entity.params.get_one_bool("occluder", true),
        });
        Ok(())
    }
}

/// [`Scene::mover_lookup`] of `movers`.
fn mover_lookup(movers: &[Mover]) -> Vec<(u32, u32, u32)> {
    let mut v: Vec<(u32, u32, u32)> = movers
        .iter()
        .enumerate()
        .flat_map(|(i, m)| m.meshes.iter().enumerate().map(move |(k, &mesh)| (mesh, i as u32, k as u32)))
        .collect();
    v.sort_unstable();
    v
}

/// Every mesh's edge adjacency (timed into `report`).
fn adjacency(meshes: &[TriangleMesh], report: &mut BuildReport) -> Vec<EdgeAdjacency> {
    let t = Instant::now();
    let adjacency: Vec<EdgeAdjacency> = meshes.iter().map(TriangleMesh::build_adjacency).collect();
    let edges: usize = adjacency.iter().map(|a| a.edges.len()).sum();
    report.stages.push(("adjacency".into(), t.elapsed().as_secs_f64(), format!("{edges} edges")));
    adjacency
}

/// The materials some object uses, with the textures they reference built in `textures`
/// (timed into `report`).
fn materials(
    desc: &SceneDescription,
    objects: &[SceneObject],
    textures: &mut Textures,
    warnings: &DiagSink,
    report: &mut BuildReport,
) -> Result<Materials, Diagnostic> {
    let t2 = Instant::now();
    let mut used = vec![false; desc.materials.len()];
    for o in objects {
        if let Some(m) = o.material.and_then(|m| used.get_mut(m)) {
            *m = true;
        }
    }
    let materials = Materials::build(desc, &used, textures, warnings)?;
    report.stages.push((
        "materials".into(),
        t2.elapsed().as_secs_f64(),
        format!(
            "{} materials, {} textures, {} images",
            materials.built_count(),
            textures.built_count(),
            textures.image_count()
        ),
    ));
    Ok(materials)
}

/// One warning per material type with a BSSRDF, for an integrator that renders none.
fn warn_interface_only(desc: &SceneDescription, materials: &Materials, warnings: &DiagSink) {
    let mut warned = std::collections::HashSet::new();
    for (i, md) in desc.materials.iter().enumerate() {
        let Some(m) = materials.get(i).filter(|m| m.may_have_bssrdf()) else { continue };
        if warned.insert(m.type_name()) {
            warnings.warn(
                Some(md.entity.loc.clone()),
                format!(
                    "material \"{}\": its subsurface scattering (BSSRDF) is rendered by \"path\" only; this \
                     integrator renders its surface (BSDF) alone, as pbrt-v3's directlighting and whitted do",
                    m.type_name()
                ),
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::CameraSample;
    use glam::{Vec2, Vec3};

    fn scene(path: &str, accelerator: &str) -> (Scene, DiagSink) {
        let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path);
        let mut desc = penumbra_parser::parse_file(&file).unwrap_or_else(|e| panic!("{e}")).scene;
        desc.accelerator.kind = accelerator.into();
        let w = DiagSink::new();
        let req = Requirements { accel: true, ..Default::default() };
        let opts = BuildOptions { resolution: Some((48, 48)), ..Default::default() };
        (Scene::build(&desc, req, &opts, &w).unwrap_or_else(|e| panic!("{e}")), w)
    }

    /// `Accelerator "embree"` builds Embree where this build has it (else the BVH, with a
    /// warning), and the two answer alike on scenes: the camera rays' first hits, and rays
    /// spawned from those hits towards a point above (the quad-cube's ground is the plane
    /// y = 0, whose points have no rounding error, so its rays start exactly on it).
    #[test]
    fn embree_scenes_answer_as_the_bvh() {
        for (path, above) in [
            ("scenes/suite/ltc/quad-cube.pbrt", Vec3::new(0.1, 2.9, 0.2)),
            ("scenes/public/mmp-pbrt-v3/scenes/killeroo-simple.pbrt", Vec3::new(0.0, 300.0, 0.0)),
        ] {
            let (bvh, _) = scene(path, "bvh");
            let (other, w) = scene(path, "embree");
            let accel = other.accel.as_ref().expect("accel");
            if AccelKind::EMBREE_AVAILABLE {
                assert_eq!(accel.kind(), AccelKind::Embree);
            } else {
                assert_eq!(accel.kind(), AccelKind::Bvh);
                assert!(w.take().iter().any(|d| d.message.contains("built without Embree")));
            }
            let (mut hits, mut shadowed) = (0, 0);
            for y in 0..48 {
                for x in 0..48 {
                    let s = CameraSample {
                        p_film: Vec2::new(x as f32 + 0.5, y as f32 + 0.5),
                        p_lens: Vec2::ZERO,
                        time: 0.0,
                    };
                    let ray = bvh.camera.generate_ray(&s);
                    let (a, b) = (bvh.intersect(&ray), other.intersect(&ray));
                    assert_eq!(a.map(|h| (h.mesh, h.tri)), b.map(|h| (h.mesh, h.tri)), "{path} pixel ({x}, {y})");
                    let Some(h) = a else { continue };
                    hits += 1;
                    let si = bvh.interaction(&ray, &h);
                    let up = si.spawn_ray_to(above);
                    let o = bvh.occluded(&up);
                    assert_eq!(o, other.occluded(&up), "{path} pixel ({x}, {y}): shadow ray");
                    shadowed += o as usize;
                }
            }
            assert!(hits > 500 && shadowed < hits / 2, "{path}: {hits} hits, {shadowed} shadowed");
        }
    }

    /// A scene with moving shapes asks Embree in vain: the BVH answers (it alone holds moving
    /// groups), with a warning naming the moving shape; both give the same camera-ray hits.
    #[test]
    fn embree_with_moving_shapes_falls_back_to_the_bvh() {
        let (bvh, _) = scene("scenes/real/shape-motion.pbrt", "bvh");
        let (other, w) = scene("scenes/real/shape-motion.pbrt", "embree");
        assert_eq!(other.accel.as_ref().unwrap().kind(), AccelKind::Bvh);
        assert!(!other.movers.is_empty() && other.uses_time());
        let messages: Vec<String> = w.take().into_iter().map(|d| d.message).collect();
        let expected = if AccelKind::EMBREE_AVAILABLE { "shape \"sphere\" at" } else { "built without Embree" };
        assert!(messages.iter().any(|m| m.contains(expected)), "{messages:?}");
        let mut hits = 0;
        for y in 0..48 {
            for x in 0..48 {
                let s = CameraSample {
                    p_film: Vec2::new(x as f32 + 0.5, y as f32 + 0.5),
                    p_lens: Vec2::ZERO,
                    time: (x + 48 * y) as f32 / 2304.0,
                };
                let ray = bvh.camera.generate_ray(&s);
                let (a, b) = (bvh.intersect(&ray), other.intersect(&ray));
                assert_eq!(a, b);
                hits += a.is_some() as usize;
            }
        }
        assert!(hits > 1000, "{hits}");
    }
}
