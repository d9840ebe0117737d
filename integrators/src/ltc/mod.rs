//! `ltc`: analytic shading and soft shadows from polygonal area lights — seed 004
//! (`../shared/seeds/004_*`: Heitz et al.'s Linearly Transformed Cosines with analytic
//! visibility from spherical polygon Booleans).
//!
//! At each shading point and for each emitting triangle of each area light, the
//! triangle is projected onto the sphere of directions, the occluders between the
//! point and the triangle are projected too, and the visible part (light minus the
//! union of occluders, [`spherical_polygon::difference`]) is integrated in closed form:
//! the clamped cosine for the Lambertian lobe (exact), and a Linearly Transformed
//! Cosine fitted to the Trowbridge–Reitz lobe for the glossy part.
//!
//! Occluders come from a bounding-volume hierarchy over the scene's objects,
//! queried with the cone from the shading point around the light triangle's
//! bounding sphere (the paper's `GetBetween`). An occluder is represented by its
//! silhouette loop when it is closed and convex (mode `silhouette`, or `auto` when
//! the builder proves it convex) and by its triangles otherwise (`per-triangle`, which
//! also takes every light triangle on its own: the paper's Sect. 4.4).
//! Occluder geometry beyond the light triangle's plane cannot shadow it: triangles
//! are clipped to the half-space of the shading point first, and a convex object
//! straddling that plane is taken triangle by triangle. The triangles of one object
//! that need no clipping (and lie in the open hemisphere around the light) are
//! subtracted as the outline of their union ([`spherical_polygon::triangle_chains`]: each
//! taken positively oriented from the point, shared edges cancelled, the rest covers
//! by winding number), which is exact and has far fewer edges than the triangles —
//! for a closed mesh, its silhouette edges (`"bool mergeoccluders" "false"`: one by one).
//!
//! Point, spot, distant, goniometric and projection lights get exact hard shadows
//! (one shadow ray, the real BSDF). Infinite lights, and materials that do not reduce
//! to a Lambertian plus a GGX lobe, fall back to `directlighting`'s estimator for
//! that light or that point, with one warning each.
//!
//! Perfectly specular lobes (mirror, smooth glass, uber's `Kr`/`Kt`/opacity) are followed as
//! `directlighting` follows them (pbrt-v3's `SpecularReflect`/`SpecularTransmit`, one 2D
//! sample each) up to `"integer maxdepth"` (5), and the surfaces they reach are shaded the
//! same way as a camera ray's (analytic area lights, the rest as above), sample by sample:
//! pixel shading applies to the first surfaces only.
//!
//! The shading itself (scene preparation, occluders, integration, Fresnel) is
//! [`crate::common::ltc_shading`], shared with `ratio`; pixel shading and the lights LTC does
//! not shade are in [`crate::common`] too. This file: parameters, the estimator, specular chains.

use crate::common::direct::estimate_direct_with;
use crate::common::direct::{has_specular, specular};
use crate::common::ltc_shading::{BudgetedLighting, FresnelMode, Glossy, LtcShader, Mode, OverBudget, ShaderSettings};
use crate::common::other_lights::{add_other_lights, warn_infinite_lights, Coverage, FallbackWarning};
use crate::common::params::{ParamSpec, Params};
use crate::common::pixel_shading::{parse_shading, SharedPixel, SHADING};
use crate::common::{max_depth, max_depth_param};
use penumbra_core::bxdf::BxdfFlags;
use penumbra_core::camera::CameraSample;
use penumbra_core::film::Film;
use penumbra_core::geometry::RayDifferential;
use penumbra_core::integrator::{
    render_pixels, Integrator, PixelEstimator, Preparation, RadianceBound, RenderContext, RenderError, RenderStats,
    SampleContext, ThreadStats,
};
use penumbra_core::light::Light;
use penumbra_core::sampler::Sampler;
use penumbra_core::scene::{Requirements, Scene, SurfacePoint};
use penumbra_core::Rgb;
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};

pub struct LtcIntegrator {
    pub mode: Mode,
    pub shadows: bool,
    pub glossy: Glossy,
    pub fresnel: FresnelMode,
    /// `"string shading" "pixel"` (default): the samples of a pixel only resolve visibility
    /// (edges, which surface is seen); each surface seen in the pixel is shaded once
    /// (multisample antialiasing). `"sample"`: every sample is shaded.
    pub pixel_shading: bool,
    /// Occluder triangles of one object that lie wholly in front of the light are subtracted as
    /// their outline (`"bool mergeoccluders"`, default true; false: triangle by triangle).
    pub merge_occluders: bool,
    /// With pixel shading, at least this many camera samples per pixel (`"integer
    /// coveragesamples"`, default 16; 1: the sampler's count as it is). They cost a camera ray
    /// each, not a shading: below ~16 the image's error is the aliasing of edges, not noise.
    pub coverage_samples: u32,
    /// pbrt-v3's `"integer maxdepth"` (5): how many surfaces a camera ray's specular chain
    /// may meet (the first included), as in `directlighting`.
    pub max_depth: u32,
}

/// Why `ltc` raises the sampler's count (the scene build's warning says it).
const COVERAGE_REASON: &str = "ltc shades each surface a pixel sees once, and the camera samples only resolve which \
     surfaces those are and where their edges run (a camera ray each); \"integer coveragesamples\" sets this floor";

/// The parameters `ltc` reads.
pub const PARAMS: &[ParamSpec] = &[
    ParamSpec::choice(
        "mode",
        &["auto", "silhouette", "per-triangle", "pertriangle"],
        "occluders as silhouettes where proven convex, always as silhouettes, or triangle by triangle (pertriangle: the same)",
    ),
    ParamSpec::bool("shadows", true, "false: the unshadowed term"),
    Glossy::PARAM,
    FresnelMode::PARAM,
    SHADING,
    ParamSpec::bool("mergeoccluders", true, "subtract an object's triangles as their outline (false: one by one; same image)"),
    ParamSpec::int("coveragesamples", 16, "at least this many camera samples per pixel with pixel shading (edge anti-aliasing)")
        .range(1, 1024),
    max_depth(1024),
];

impl LtcIntegrator {
    pub fn create(params: &ParamSet, warnings: &DiagSink) -> Result<Box<dyn Integrator>, Diagnostic> {
        let p = Params::new("ltc", PARAMS, params, warnings);
        let mode = p.choice("mode", [Mode::Auto, Mode::Silhouette, Mode::PerTriangle, Mode::PerTriangle])?;
        Ok(Box::new(LtcIntegrator {
            mode,
            shadows: p.bool("shadows")?,
            glossy: Glossy::from_params(&p)?,
            fresnel: FresnelMode::from_params(&p)?,
            pixel_shading: parse_shading(&p)?,
            merge_occluders: p.bool("mergeoccluders")?,
            coverage_samples: p.count("coveragesamples")?,
            max_depth: max_depth_param(&p)?,
        }))
    }
}

struct Estimator<'a> {
    ltc: &'a LtcIntegrator,
    shader: &'a LtcShader,
    fallback: FallbackWarning<'a>,
    /// The scene has lights other than area lights.
    other_lights: bool,
    /// Shadows are asked for and an occluder has an alpha cut-out: every light goes through
    /// directlighting's estimator (whose shadow rays honour the cut-out).
    cutouts: bool,
}

impl LtcIntegrator {
    /// What the shading is asked to do.
    pub fn shader_settings(&self) -> ShaderSettings {
        ShaderSettings {
            mode: self.mode,
            shadows: self.shadows,
            glossy: self.glossy,
            fresnel: self.fresnel,
            merge_occluders: self.merge_occluders,
        }
    }
}

impl Estimator<'_> {
    /// Radiance from `hit`, the `depth`-th surface of a camera ray's specular chain (0: the
    /// first); `area` is its analytic area lighting when already computed for the pixel.
    #[allow(clippy::too_many_arguments)]
    fn shade(
        &self,
        ray: &RayDifferential,
        hit: &SurfacePoint,
        area: Option<BudgetedLighting>,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
        depth: u32,
    ) -> Rgb {
        let SurfacePoint { si, le, .. } = hit;
        let mut l = *le;
        // With the pixel's lighting integrated already, only the sample's albedo is needed (and
        // whether the material transmits, which the shared value does not say).
        let none = OverBudget::default();
        let (lit, coverage, over) = match area {
            // An alpha cut-out in the scene: every light through directlighting's estimator.
            _ if self.cutouts => (None, Coverage::None, none),
            Some(BudgetedLighting { lighting: (diffuse, specular), over }) => {
                let lit = LtcShader::diffuse_albedo(scene, si).map(|kd| kd * diffuse + specular);
                let transmits = lit.is_some()
                    && may_transmit(scene, si)
                    && self.shader.lobes(scene, si).is_some_and(|d| d.transmits);
                (lit, Coverage::of(lit.is_some(), transmits), if lit.is_some() { over } else { none.clone() })
            }
            None => match self.shader.lobes(scene, si) {
                Some(d) => {
                    let BudgetedLighting { lighting: (diffuse, specular), over } =
                        self.shader.area_lights_budgeted(scene, si, &d, self.ltc.shadows, &mut Vec::new());
                    (Some(d.diffuse * diffuse + specular), Coverage::of(true, d.transmits), over)
                }
                None => (None, Coverage::None, none),
            },
        };
        if let Some(v) = lit {
            l += v;
        }
        // The BSDF only for what the LTC does not shade (delta and infinite lights, materials
        // without an LTC form, transmission) and for specular lobes to follow.
        let follow = depth + 1 < self.ltc.max_depth;
        let may_be_specular = || scene.material_of(si).is_some_and(|(m, _, _)| m.may_be_specular());
        let rest = coverage != Coverage::Area || self.other_lights || !over.is_empty();
        if rest || (follow && may_be_specular()) {
            if let Some(hit) = hit.with_bsdf(scene) {
                if rest {
                    add_other_lights(&mut l, &hit, coverage, scene, sampler, stats, &self.fallback);
                    self.over_budget_lights(&mut l, &hit, coverage, &over, scene, sampler, stats);
                }
                if follow && has_specular(&hit.bsdf) {
                    for kind in [BxdfFlags::REFLECTION, BxdfFlags::TRANSMISSION] {
                        l += specular(&hit.si, &hit.bsdf, ray, sampler, stats, kind, |r, sampler, stats| {
                            let (next, queries) = scene.first_point(r);
                            stats.add_continued(queries);
                            match next {
                                Ok(h) => self.shade(r, &h, None, scene, sampler, stats, depth + 1),
                                Err(escaped) => escaped,
                            }
                        });
                    }
                }
            }
        }
        l
    }
}

impl Estimator<'_> {
    /// Adds the lights the analytic shading left to `directlighting`'s estimator at `hit` (over
    /// the cost budget: `over`), one sample of it each (two 2D samples), through the lobes the
    /// analytic shading covers (with `Coverage::Reflection`, [`add_other_lights`] has taken the
    /// transmission lobes).
    #[allow(clippy::too_many_arguments)]
    fn over_budget_lights(
        &self,
        l: &mut Rgb,
        hit: &penumbra_core::scene::SurfaceHit,
        coverage: Coverage,
        over: &OverBudget,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
    ) {
        if over.is_empty() || coverage == Coverage::None || hit.bsdf.num_components(BxdfFlags::NON_SPECULAR) == 0 {
            return;
        }
        let flags = match coverage {
            Coverage::Reflection => BxdfFlags::REFLECTION | BxdfFlags::DIFFUSE | BxdfFlags::GLOSSY,
            _ => BxdfFlags::NON_SPECULAR,
        };
        for (k, light) in scene.light_list().iter().enumerate() {
            if self.shader.light_group_of(k).is_some_and(|g| over.has(g)) {
                let (u_light, u_scatter) = (sampler.get_2d(), sampler.get_2d());
                *l += estimate_direct_with(&hit.si, &hit.bsdf, flags, u_scatter, k, light, u_light, scene, stats);
            }
        }
    }
}

/// Whether the material at `si` may have transmission lobes its LTC form leaves out (a cheap
/// test before the full description).
fn may_transmit(scene: &Scene, si: &penumbra_core::interaction::SurfaceInteraction) -> bool {
    use penumbra_core::material::Material;
    scene.material_of(si).is_some_and(|(m, _, _)| matches!(m, Material::Translucent { .. } | Material::Mix { .. }))
}

impl PixelEstimator for Estimator<'_> {
    type Shared = SharedPixel<BudgetedLighting>;

    fn li(&self, ray: &RayDifferential, cx: SampleContext) -> Rgb {
        let SampleContext { scene, sampler, stats, aov: _ } = cx;
        let (first, queries) = scene.first_point(ray);
        stats.add_continued(queries);
        match first {
            Ok(h) => self.shade(ray, &h, None, scene, sampler, stats, 0),
            Err(escaped) => escaped,
        }
    }

    fn shares_pixel_work(&self) -> bool {
        self.ltc.pixel_shading && !self.cutouts
    }

    fn begin_pixel(
        &self,
        rays: &[RayDifferential],
        samples: &[CameraSample],
        scene: &Scene,
        stats: &mut ThreadStats,
    ) -> Option<Self::Shared> {
        Some(self.shader.trace_pixel_budgeted(rays, samples, scene, self.ltc.shadows, stats))
    }

    fn li_shared(&self, ray: &RayDifferential, cx: SampleContext, shared: &Self::Shared, index: usize) -> Rgb {
        let SampleContext { scene, sampler, stats, aov: _ } = cx;
        match shared.sample(index) {
            (Ok(h), area) => self.shade(ray, h, area, scene, sampler, stats, 0),
            (Err(escaped), _) => *escaped,
        }
    }
}

impl Integrator for LtcIntegrator {
    fn requirements(&self) -> Requirements {
        Requirements {
            accel: true,
            lights: true,
            materials: true,
            // Light shapes and silhouettes (every mode but per-triangle) and occluder outlines.
            adjacency: self.mode != Mode::PerTriangle || (self.shadows && self.merge_occluders),
            min_pixel_samples: (self.pixel_shading && self.coverage_samples > 1)
                .then_some((self.coverage_samples, COVERAGE_REASON)),
            ..Default::default()
        }
    }
    fn render(&self, scene: &Scene, ctx: &RenderContext, film: &mut Film) -> Result<RenderStats, RenderError> {
        warn_infinite_lights("ltc", scene, ctx.warnings);
        let cutout = scene.non_polygonal_occluder().filter(|_| self.shadows);
        if let Some((o, why)) = cutout {
            let why = if why.contains("cut-out") { "has an alpha cut-out" } else { why };
            ctx.warnings.warn(
                Some(o.loc.clone()),
                format!(
                    "ltc: shape \"{}\" {why}, which analytic visibility cannot represent: every light \
                     is rendered with directlighting's estimator (\"bool occluder\" false on the shape keeps ltc's \
                     analytic shadows, without the shape's)",
                    o.kind
                ),
            );
        }
        let mut fallback = FallbackWarning::new("ltc", ctx.warnings);
        // With every light on the estimator, the per-material fallback warning would say less.
        fallback.silent = cutout.is_some();
        // Prepared with the scene (`build_scene`: one build for every render of it), or built here.
        let built;
        let shader = match scene.prepared::<LtcShader>().filter(|s| s.settings == self.shader_settings()) {
            Some(s) => {
                s.reset_counters();
                s
            }
            None => {
                built = LtcShader::new(self.shader_settings(), scene, "ltc");
                &built
            }
        };
        shader.warn_slow_lights(scene, ctx.warnings);
        let est = Estimator {
            ltc: self,
            shader,
            fallback,
            other_lights: scene.light_list().iter().any(|l| !matches!(l, Light::Area(_))),
            cutouts: cutout.is_some(),
        };
        let mut stats = est.shader.with_live_status(ctx, |ctx| render_pixels(&est, scene, ctx, film))?;
        est.shader.finish(&mut stats, ctx.warnings);
        Ok(stats)
    }
    /// Occluders only remove parts of a light's polygon, whose integrand is non-negative
    /// (form factor, LTC), and the pixel clusters do not depend on shadows: the unshadowed
    /// render bounds every pixel.
    /// The analytic shading's per-scene data (objects, light shapes), with one line per area
    /// light for `penumbra info`: how it is taken and when it takes the slow path.
    fn prepare(&self, scene: &Scene) -> Option<Preparation> {
        let shader = LtcShader::new(self.shader_settings(), scene, "ltc");
        let details = shader.light_report(scene);
        let slow = shader.light_groups().iter().filter(|g| shader.light_plan(scene, g).1.is_some()).count();
        Some(Preparation {
            stage: "ltc lights".into(),
            summary: format!("{} area lights, {slow} may take the slow path", shader.light_groups().len()),
            details,
            value: std::sync::Arc::new(shader),
        })
    }
    fn radiance_bound(&self) -> Option<RadianceBound> {
        // The glossy lobes' residual quadrature is exact to a relative 1e-3 of each piece, and the
        // shadowed and unshadowed pieces are integrated separately (measured up to 3.1e-4 apart
        // on stiff/grazing-light's floor; tests/ltc.rs allows the same).
        self.shadows.then(|| RadianceBound::Image(Box::new(LtcIntegrator { shadows: false, ..*self }), 1e-3))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::common::spherical_polygon;
    use glam::DVec3;
    use penumbra_core::scene::BuildOptions;

    /// `ltc` asks the scene build for adjacency (built once there, per mesh, equal to the
    /// mesh's own), except in per-triangle mode without outlines; without the request the
    /// scene has none.
    #[test]
    fn adjacency_is_built_once_by_the_scene_when_asked() {
        let text = "Camera \"perspective\" Film \"rgb\" \"integer xresolution\" 4 \"integer yresolution\" 4
            WorldBegin
            AttributeBegin AreaLightSource \"diffuse\" Translate 0 3 0 Shape \"sphere\" \"float radius\" 0.5 AttributeEnd
            Shape \"trianglemesh\" \"point3 P\" [-1 0 -1 1 0 -1 1 0 1 -1 0 1] \"integer indices\" [0 1 2 0 2 3]
            WorldEnd";
        let parsed = penumbra_parser::parse_str(text, "<test>", None).unwrap();
        let warnings = DiagSink::new();
        let params = ParamSet::default();
        let build = |integrator: &dyn Integrator| {
            Scene::build(&parsed.scene, integrator.requirements(), &BuildOptions::default(), &warnings).unwrap()
        };
        let ltc = LtcIntegrator::create(&params, &warnings).unwrap();
        let scene = build(ltc.as_ref());
        assert_eq!(scene.meshes.len(), 2);
        for (i, mesh) in scene.meshes.iter().enumerate() {
            assert_eq!(scene.adjacency(i), Some(&mesh.build_adjacency()));
        }
        assert!(scene.report.stages.iter().any(|s| s.0 == "adjacency"));
        let per_triangle =
            LtcIntegrator { mode: Mode::PerTriangle, merge_occluders: false, ..ltc_settings(&params, &warnings) };
        assert!(!per_triangle.requirements().adjacency);
        let scene = Scene::build(&parsed.scene, Requirements::default(), &BuildOptions::default(), &warnings).unwrap();
        assert_eq!(scene.adjacency(0), None);
    }

    fn ltc_settings(params: &ParamSet, warnings: &DiagSink) -> LtcIntegrator {
        let pixel_shading = parse_shading(&Params::new("ltc", PARAMS, params, warnings)).unwrap();
        LtcIntegrator {
            mode: Mode::Auto,
            shadows: true,
            glossy: Glossy::Exact,
            fresnel: FresnelMode::Average,
            pixel_shading,
            merge_occluders: true,
            coverage_samples: 16,
            max_depth: 5,
        }
    }

    #[test]
    /// A coplanar light triangle sharing an edge (the other half of a quad light) does not
    /// occlude its neighbour from any point.
    fn coplanar_neighbour_does_not_occlude() {
        let a = [DVec3::new(-0.8, 3.0, -0.8), DVec3::new(0.8, 3.0, -0.8), DVec3::new(0.8, 3.0, 0.8)];
        let b = [DVec3::new(-0.8, 3.0, -0.8), DVec3::new(0.8, 3.0, 0.8), DVec3::new(-0.8, 3.0, 0.8)];
        let mut bad = 0;
        for i in 0..200 {
            let p = DVec3::new(-2.0 + 0.02 * i as f64, 0.0, 0.3 - 0.01 * i as f64);
            let la = spherical_polygon::project(p, &a);
            let lb = spherical_polygon::project(p, &b);
            let ff_a = spherical_polygon::form_factor(&la).abs();
            let d = spherical_polygon::difference(std::slice::from_ref(&la), &[lb]);
            let ff_d = spherical_polygon::form_factor_loops(&d);
            if (ff_a - ff_d).abs() > 1e-6 * ff_a.max(1e-3) {
                bad += 1;
                eprintln!("p {p}: A {ff_a} diff {ff_d} loops {}", d.len());
            }
        }
        assert_eq!(bad, 0);
    }
}
