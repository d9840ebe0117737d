//! Cameras with pbrt-v3's conventions: left-handed camera space looking down
//! +z, `fov` spanning the shorter image axis, the screen window, thin lenses, and the
//! `realistic` camera's lens systems ([`crate::lens`]).

use crate::geometry::{Ray, RayDifferential, RayOffsets};
use crate::lens::{parse_float_file, LensSystem};
use crate::motion::Motion;
use glam::{DMat4, DVec2, DVec3, Vec2, Vec3};
use penumbra_parser::{CameraDesc, DiagSink, Diagnostic, SceneDescription, Transform};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A point on the film (absolute raster coordinates of the full image), the lens and time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraSample {
    pub p_film: Vec2,
    pub p_lens: Vec2,
    pub time: f32,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    Perspective {
        tan_half_fov: f32,
    },
    Orthographic,
    /// Latitude-longitude over the whole sphere.
    Environment,
    /// pbrt-v3's `RealisticCamera`: rays traced through [`Camera::lens`].
    Realistic,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    pub projection: Projection,
    /// The camera's transform at shutter open (`ActiveTransform StartTime`).
    pub world_from_camera: Transform,
    /// The camera's motion when its transform is animated (pbrt-v3's `CameraToWorld`
    /// `AnimatedTransform`): each ray takes the transform at its time.
    pub motion: Option<Motion>,
    pub resolution: (u32, u32),
    /// `[x0, x1, y0, y1]` in screen space.
    pub screen_window: [f32; 4],
    pub lens_radius: f32,
    pub focal_distance: f32,
    pub shutter: (f32, f32),
    /// The sample count the ray differentials are scaled for (`None`: the render's own).
    /// pbrt-v3 scales them by 1/√spp, so its texture filtering depends on the sample count and
    /// the resolution; a render compared with a reference made at another count or resolution
    /// sets this so that both filter textures over the same footprint (`tests/matrix`: a
    /// reference at 2× the resolution and N spp filters as 1× at 4N).
    pub footprint_spp: Option<u32>,
    /// The `realistic` camera's focused lens system.
    pub lens: Option<Arc<LensSystem>>,
}

/// What the camera reads from outside its own description: the film's `"diagonal"` (mm,
/// the `realistic` camera's film size) and the directory its `lensfile` resolves against.
pub struct CameraContext {
    pub film_diagonal_mm: f32,
    pub base_dir: PathBuf,
}

impl Default for CameraContext {
    fn default() -> Self {
        CameraContext { film_diagonal_mm: 35.0, base_dir: PathBuf::from(".") }
    }
}

fn concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o == Vec2::ZERO {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, std::f32::consts::FRAC_PI_4 * (o.y / o.x))
    } else {
        (o.y, std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (o.x / o.y))
    };
    r * Vec2::new(theta.cos(), theta.sin())
}

impl Camera {
    /// Builds the camera from its description (pbrt-v3's parameters and defaults);
    /// `resolution` is the film's full resolution.
    pub fn from_desc(desc: &CameraDesc, resolution: (u32, u32), warnings: &DiagSink) -> Result<Camera, Diagnostic> {
        Self::from_desc_in(desc, resolution, &CameraContext::default(), warnings)
    }

    /// The scene's camera: [`Camera::from_desc`] with the film's `"diagonal"` and lens files
    /// resolved as pbrt-v3 resolves them.
    pub fn from_scene(
        desc: &SceneDescription,
        resolution: (u32, u32),
        warnings: &DiagSink,
    ) -> Result<Camera, Diagnostic> {
        let cx = CameraContext {
            film_diagonal_mm: desc.film.params.get_one_float("diagonal", 35.0),
            base_dir: desc.base_dir.clone(),
        };
        Self::from_desc_in(&desc.camera, resolution, &cx, warnings)
    }

    /// [`Camera::from_desc`] in context `cx`.
    pub fn from_desc_in(
        desc: &CameraDesc,
        resolution: (u32, u32),
        cx: &CameraContext,
        warnings: &DiagSink,
    ) -> Result<Camera, Diagnostic> {
        let p = &desc.entity.params;
        let loc = Some(desc.entity.loc.clone());
        let motion = Motion::new(&desc.world_from_camera);
        if desc.world_from_camera.is_animated() && motion.is_none() {
            warnings.warn(
                loc.clone(),
                "animated camera transform with a singular keyframe or TransformTimes end <= start: no motion \
                 blur, using the transform at shutter open",
            );
        }
        let mut shutter = (p.get_one_float("shutteropen", 0.0), p.get_one_float("shutterclose", 1.0));
        if shutter.1 < shutter.0 {
            warnings.warn(loc.clone(), "shutterclose < shutteropen: swapping them");
            shutter = (shutter.1, shutter.0);
        }
        let (w, h) = (resolution.0.max(1) as f32, resolution.1.max(1) as f32);
        let frame = p.get_one_float("frameaspectratio", w / h);
        let mut screen = if frame > 1.0 { [-frame, frame, -1.0, 1.0] } else { [-1.0, 1.0, -1.0 / frame, 1.0 / frame] };
        if let Some(sw) = p.get_floats("screenwindow") {
            if sw.len() == 4 {
                screen = [sw[0], sw[1], sw[2], sw[3]];
            } else {
                warnings.warn(
                    p.loc_of("screenwindow").cloned(),
                    format!("\"screenwindow\" needs 4 values, got {}: ignored", sw.len()),
                );
            }
        }
        if !(frame.is_finite() && frame > 0.0)
            || screen.iter().any(|v| !v.is_finite())
            || screen[0] == screen[1]
            || screen[2] == screen[3]
        {
            return Err(Diagnostic::error(loc, "degenerate camera screen window or frame aspect ratio"));
        }
        let kind = desc.entity.kind.as_str();
        let projection = match kind {
            "realistic" => Projection::Realistic,
            "perspective" => {
                let mut fov = p.get_one_float("fov", 90.0);
                let half = p.get_one_float("halffov", -1.0);
                if half > 0.0 {
                    fov = 2.0 * half;
                }
                if !(fov > 0.0 && fov < 180.0) {
                    return Err(Diagnostic::error(
                        p.loc_of("fov").cloned().or(loc),
                        format!("fov must be in (0, 180) degrees, got {fov}"),
                    ));
                }
                Projection::Perspective { tan_half_fov: (fov.to_radians() * 0.5).tan() }
            }
            "orthographic" => Projection::Orthographic,
            "environment" => Projection::Environment,
            other => {
                return Err(Diagnostic::error(
                    loc,
                    format!(
                        "unknown camera \"{other}\" (expected perspective, orthographic, environment or realistic)"
                    ),
                ))
            }
        };
        let lens = match projection {
            Projection::Realistic => Some(Arc::new(realistic_lens(desc, cx, shutter, warnings)?)),
            _ => None,
        };
        let (lens_radius, focal_distance) = if matches!(projection, Projection::Environment | Projection::Realistic) {
            (0.0, 1e6)
        } else {
            (p.get_one_float("lensradius", 0.0).max(0.0), p.get_one_float("focaldistance", 1e6))
        };
        Ok(Camera {
            projection,
            world_from_camera: desc.world_from_camera.start,
            motion,
            resolution: (resolution.0.max(1), resolution.1.max(1)),
            screen_window: screen,
            lens_radius,
            focal_distance,
            shutter,
            footprint_spp: None,
            lens,
        })
    }

    /// Whether [`Camera::generate_ray`] reads `CameraSample::p_lens` (a thin lens or a lens
    /// system).
    pub fn uses_lens(&self) -> bool {
        self.lens_radius > 0.0 || self.lens.is_some()
    }

    /// Whether [`Camera::generate_ray`] needs `CameraSample::time` for its own transform (when
    /// the camera moves; the scene's moving shapes need it too: [`crate::scene::Scene::uses_time`]).
    pub fn uses_time(&self) -> bool {
        self.motion.is_some()
    }

    /// The ray time of a sample's time in [0, 1): pbrt-v3's `Lerp(sample.time, shutterOpen,
    /// shutterClose)`.
    #[inline]
    pub fn ray_time(&self, time: f32) -> f32 {
        self.shutter.0 + time * (self.shutter.1 - self.shutter.0)
    }

    /// The world-from-camera matrix of a sample's time (`CameraSample::time` in [0, 1) maps
    /// onto the shutter interval as pbrt-v3's `Lerp(sample.time, shutterOpen, shutterClose)`).
    fn world_from_camera_at(&self, time: f32) -> CameraToWorld<'_> {
        match &self.motion {
            Some(m) => CameraToWorld::Moving(m.at(self.ray_time(time))),
            None => CameraToWorld::Fixed(&self.world_from_camera),
        }
    }

    /// The camera ray for a film sample, in world space, with a unit direction (for a
    /// `realistic` camera the ray the lens system blocks is some ray of weight 0: see
    /// [`Camera::generate_ray_weighted`]).
    pub fn generate_ray(&self, s: &CameraSample) -> Ray {
        self.generate_ray_weighted(s).0
    }

    /// The camera ray and its weight, pbrt-v3's `GenerateRay`: 1, except for the `realistic`
    /// camera, whose weight (cos⁴θ times the exit pupil's area, relative to the film centre's
    /// with `simpleweighting`) multiplies the radiance the ray brings, and is 0 for rays the
    /// lens system blocks (their radiance is not estimated; the sample still counts in the
    /// pixel's filter weight, as pbrt-v3's film counts it).
    pub fn generate_ray_weighted(&self, s: &CameraSample) -> (Ray, f32) {
        let m = self.world_from_camera_at(s.time);
        if let Some(lens) = &self.lens {
            let u = DVec2::new(s.p_lens.x as f64, s.p_lens.y as f64);
            let p = DVec2::new(s.p_film.x as f64, s.p_film.y as f64);
            return match lens.generate(p, self.resolution, u) {
                Some((r, w)) => (self.to_world(&m, r.o.as_vec3(), r.d.as_vec3(), s.time), w as f32),
                // Blocked: the axis ray, never traced.
                None => (self.to_world(&m, Vec3::ZERO, Vec3::Z, s.time), 0.0),
            };
        }
        let (o, d) = self.camera_space_ray(s.p_film, s.p_lens);
        (self.to_world(&m, o, d, s.time), 1.0)
    }

    /// The camera ray with its offset rays one pixel step away in x and y (pbrt-v3's
    /// `GenerateRayDifferential`; the caller scales them to the sample spacing with
    /// [`RayDifferential::scale_offsets`]). Perspective and orthographic cameras shift the
    /// film point by one pixel through the same lens point, as pbrt-v3's do; the environment
    /// camera takes pbrt-v3's generic `Camera::GenerateRayDifferential`, a finite difference
    /// over 0.05 pixel.
    pub fn generate_ray_differential(&self, s: &CameraSample) -> RayDifferential {
        self.generate_ray_differential_weighted(s).0
    }

    /// [`Camera::generate_ray_differential`] with the ray's weight
    /// ([`Camera::generate_ray_weighted`]). The `realistic` camera's offsets are pbrt-v3's
    /// generic finite differences over ±0.05 pixel; as in pbrt-v3, when both shifts of an axis
    /// are blocked by the lens system the sample's weight is 0.
    pub fn generate_ray_differential_weighted(&self, s: &CameraSample) -> (RayDifferential, f32) {
        if self.lens.is_some() {
            let (ray, w) = self.generate_ray_weighted(s);
            if w == 0.0 {
                return (RayDifferential { ray, offsets: None }, 0.0);
            }
            let shifted = |dp: Vec2| -> Option<(Vec3, Vec3)> {
                [0.05f32, -0.05].into_iter().find_map(|eps| {
                    let (r, wr) = self.generate_ray_weighted(&CameraSample { p_film: s.p_film + dp * eps, ..*s });
                    (wr != 0.0).then(|| (ray.o + (r.o - ray.o) / eps, ray.d + (r.d - ray.d) / eps))
                })
            };
            let (Some((rx_o, rx_d)), Some((ry_o, ry_d))) = (shifted(Vec2::X), shifted(Vec2::Y)) else {
                return (RayDifferential { ray, offsets: None }, 0.0);
            };
            return (RayDifferential { ray, offsets: Some(RayOffsets { rx_o, rx_d, ry_o, ry_d }) }, w);
        }
        let (o, d) = self.camera_space_ray(s.p_film, s.p_lens);
        let m = self.world_from_camera_at(s.time);
        let ray = self.to_world(&m, o, d, s.time);
        let shifted = |dx: f32, dy: f32| self.camera_space_ray(s.p_film + Vec2::new(dx, dy), s.p_lens);
        let offsets = match self.projection {
            Projection::Perspective { .. } | Projection::Orthographic => {
                let ((rx_o, rx_d), (ry_o, ry_d)) = (shifted(1.0, 0.0), shifted(0.0, 1.0));
                Some(self.offsets_to_world(&m, rx_o, rx_d, ry_o, ry_d))
            }
            Projection::Environment => {
                const EPS: f32 = 0.05;
                let rx = self.generate_ray(&CameraSample { p_film: s.p_film + Vec2::new(EPS, 0.0), ..*s });
                let ry = self.generate_ray(&CameraSample { p_film: s.p_film + Vec2::new(0.0, EPS), ..*s });
                Some(RayOffsets {
                    rx_o: ray.o + (rx.o - ray.o) / EPS,
                    rx_d: ray.d + (rx.d - ray.d) / EPS,
                    ry_o: ray.o + (ry.o - ray.o) / EPS,
                    ry_d: ray.d + (ry.d - ray.d) / EPS,
                })
            }
            Projection::Realistic => None,
        };
        (RayDifferential { ray, offsets }, 1.0)
    }

    /// The camera ray as the render driver hands it to estimators: with its offset rays scaled
    /// by `1/√spp` (pbrt-v3's `ScaleDifferentials`), so they span the spacing of a pixel's
    /// `spp` samples ([`Camera::footprint_spp`] in place of `spp` when set).
    pub fn sample_ray(&self, s: &CameraSample, spp: u32) -> RayDifferential {
        self.sample_ray_weighted(s, spp).0
    }

    /// [`Camera::sample_ray`] with the ray's weight ([`Camera::generate_ray_weighted`]): what
    /// the render driver multiplies the estimate by.
    pub fn sample_ray_weighted(&self, s: &CameraSample, spp: u32) -> (RayDifferential, f32) {
        let (mut ray, w) = self.generate_ray_differential_weighted(s);
        ray.scale_offsets(1.0 / (self.footprint_spp.unwrap_or(spp).max(1) as f32).sqrt());
        (ray, w)
    }

    /// Camera-space origin and (unnormalised) direction of the ray through film point
    /// `p_film` and lens point `p_lens`.
    fn camera_space_ray(&self, p_film: Vec2, p_lens: Vec2) -> (Vec3, Vec3) {
        let (w, h) = (self.resolution.0 as f32, self.resolution.1 as f32);
        match self.projection {
            Projection::Environment => {
                let theta = std::f32::consts::PI * p_film.y / h;
                let phi = 2.0 * std::f32::consts::PI * p_film.x / w;
                (Vec3::ZERO, Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()))
            }
            _ => {
                let [x0, x1, y0, y1] = self.screen_window;
                let sx = x0 + (p_film.x / w) * (x1 - x0);
                let sy = y1 - (p_film.y / h) * (y1 - y0);
                let (mut o, mut d) = match self.projection {
                    // Not normalised here: the world direction is normalised once, in `to_world`.
                    Projection::Perspective { tan_half_fov } => {
                        (Vec3::ZERO, Vec3::new(sx * tan_half_fov, sy * tan_half_fov, 1.0))
                    }
                    _ => (Vec3::new(sx, sy, 0.0), Vec3::Z),
                };
                if self.lens_radius > 0.0 {
                    let lens = self.lens_radius * concentric_disk(p_lens);
                    // The plane of focus is z = focal_distance in camera space.
                    let focus = o + d * (self.focal_distance / d.z);
                    // pbrt-v3 starts the ray at the lens point itself, for the orthographic
                    // camera too (not at the film point moved by it): its orthographic depth
                    // of field converges every ray through the lens disk at the camera's
                    // origin, whatever its screen window. penumbra renders what pbrt-v3
                    // renders (the conformance cell camera-orthographic-dof was −16 %).
                    o = Vec3::new(lens.x, lens.y, 0.0);
                    d = focus - o;
                }
                (o, d)
            }
        }
    }

    fn to_world(&self, m: &CameraToWorld, o: Vec3, d: Vec3, time: f32) -> Ray {
        let (ow, dw) = point_and_direction_to_world(m, o, d);
        Ray::new(ow, dw, f32::INFINITY).at_time(self.ray_time(time))
    }

    fn offsets_to_world(&self, m: &CameraToWorld, rx_o: Vec3, rx_d: Vec3, ry_o: Vec3, ry_d: Vec3) -> RayOffsets {
        let (rx_o, rx_d) = point_and_direction_to_world(m, rx_o, rx_d);
        let (ry_o, ry_d) = point_and_direction_to_world(m, ry_o, ry_d);
        RayOffsets { rx_o, rx_d, ry_o, ry_d }
    }
}

/// The `realistic` camera's lens system from its parameters (pbrt-v3's
/// `CreateRealisticCamera`): `lensfile` (required), `aperturediameter` (mm, 1),
/// `focusdistance` (10), `simpleweighting` (true).
fn realistic_lens(
    desc: &CameraDesc,
    cx: &CameraContext,
    shutter: (f32, f32),
    warnings: &DiagSink,
) -> Result<LensSystem, Diagnostic> {
    let p = &desc.entity.params;
    let loc = Some(desc.entity.loc.clone());
    let file = p.get_one_string("lensfile", "");
    let file_loc = p.loc_of("lensfile").cloned().or(loc.clone());
    if file.is_empty() {
        return Err(Diagnostic::error(loc, "camera \"realistic\": no lens description file (\"string lensfile\")"));
    }
    let path = resolve(&cx.base_dir, &file);
    let text = std::fs::read_to_string(&path).map_err(|e| {
        Diagnostic::error(file_loc.clone(), format!("cannot read lens file \"{}\": {e}", path.display()))
    })?;
    let data = parse_float_file(&text)
        .map_err(|e| Diagnostic::error(file_loc.clone(), format!("lens file \"{}\": {e}", path.display())))?;
    let aperture = p.get_one_float("aperturediameter", 1.0) as f64;
    let focus = p.get_one_float("focusdistance", 10.0) as f64;
    let simple = p.get_one_bool("simpleweighting", true);
    let mut warn = |m: String| warnings.warn(loc.clone(), format!("camera \"realistic\": {m}"));
    if simple {
        warn(
            "\"simpleweighting\" (the default) weights rays by cos⁴θ and the exit pupil's area relative to \
              the film centre's, as pbrt-v3 does: pixel values depend a little on the aperture"
                .into(),
        );
    }
    LensSystem::new(
        &data,
        aperture,
        focus,
        cx.film_diagonal_mm as f64 * 0.001,
        simple,
        (shutter.1 - shutter.0) as f64,
        &mut warn,
    )
    .map_err(|e| Diagnostic::error(loc.clone(), format!("camera \"realistic\" with \"{}\": {e}", path.display())))
}

fn resolve(base: &Path, name: &str) -> PathBuf {
    let p = PathBuf::from(name);
    if p.is_absolute() {
        p
    } else {
        base.join(p)
    }
}

/// The camera's transform at one time.
enum CameraToWorld<'a> {
    Fixed(&'a Transform),
    Moving(DMat4),
}

/// A camera-space point and direction in world space by `m` (the direction normalised).
fn point_and_direction_to_world(m: &CameraToWorld, o: Vec3, d: Vec3) -> (Vec3, Vec3) {
    let (ow, dw) = match m {
        CameraToWorld::Fixed(t) => (
            DVec3::from(t.apply_point([o.x as f64, o.y as f64, o.z as f64])),
            DVec3::from(t.apply_vector([d.x as f64, d.y as f64, d.z as f64])),
        ),
        CameraToWorld::Moving(m) => (m.project_point3(o.as_dvec3()), m.transform_vector3(d.as_dvec3())),
    };
    (ow.as_vec3(), dw.normalize_or_zero().as_vec3())
}

#[cfg(test)]
mod tests {
    use super::*;
    use penumbra_parser::{AnimatedTransform, Entity, Param, ParamSet, ParamValue};

    fn cam(kind: &str, params: ParamSet, res: (u32, u32)) -> Camera {
        let cfw = Transform::look_at([0.0, 0.0, -5.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]).unwrap();
        let desc = CameraDesc {
            entity: Entity::new(kind, params, penumbra_parser::FileLoc::builtin()),
            camera_from_world: AnimatedTransform::fixed(cfw),
            world_from_camera: AnimatedTransform::fixed(cfw.inverse()),
            medium: None,
        };
        Camera::from_desc(&desc, res, &DiagSink::new()).unwrap()
    }

    fn sample(x: f32, y: f32) -> CameraSample {
        CameraSample { p_film: Vec2::new(x, y), p_lens: Vec2::splat(0.5), time: 0.0 }
    }

    #[test]
    fn fov_spans_the_shorter_axis_and_image_y_points_down() {
        let mut ps = ParamSet::new();
        ps.add(Param::new("fov", ParamValue::Float(vec![90.0]), penumbra_parser::FileLoc::builtin()));
        let c = cam("perspective", ps, (200, 100));
        // Top edge centre of a 200×100 image: 45° above the axis (fov on the shorter, vertical axis).
        let r = c.generate_ray(&sample(100.0, 0.0));
        assert!((r.d.y - std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-5, "{:?}", r.d);
        assert!((r.o - Vec3::new(0.0, 0.0, -5.0)).length() < 1e-6);
        // Left edge: x = -2 in screen space (camera +x is LookAt's cross(up, dir)).
        let l = c.generate_ray(&sample(0.0, 50.0));
        assert!((l.d.x / l.d.z - (-2.0)).abs() < 1e-4, "{:?}", l.d);
    }

    #[test]
    fn orthographic_and_environment_rays() {
        let o = cam("orthographic", ParamSet::new(), (100, 100));
        let r = o.generate_ray(&sample(100.0, 100.0));
        assert!((r.o - Vec3::new(1.0, -1.0, -5.0)).length() < 1e-5 && (r.d - Vec3::Z).length() < 1e-6, "{r:?}");
        let e = cam("environment", ParamSet::new(), (200, 100));
        let up = e.generate_ray(&sample(0.0, 0.0));
        assert!((up.d - Vec3::Y).length() < 1e-5);
    }

    /// The offset rays of each projection, turned into the differentials of a plane facing the
    /// camera at distance 5 with u = x/2, v = y/3: the pixel footprint on the plane in closed
    /// form (one pixel of the screen window at that distance, over √spp).
    #[test]
    fn differentials_on_a_facing_plane_are_the_pixel_footprint() {
        use crate::interaction::SurfaceInteraction;
        let res = 64u32;
        let spp = 16u32;
        let plane_hit = |r: &RayDifferential| {
            let t = -r.o.z / r.d.z;
            let p = r.o + t * r.d;
            let mut si = SurfaceInteraction {
                p,
                n: -Vec3::Z,
                uv: Vec2::new(p.x / 2.0, p.y / 3.0),
                dpdu: Vec3::new(2.0, 0.0, 0.0),
                dpdv: Vec3::new(0.0, 3.0, 0.0),
                ..Default::default()
            };
            si.compute_differentials(r);
            si.diff
        };
        let mut fov90 = ParamSet::new();
        fov90.add(Param::new("fov", ParamValue::Float(vec![90.0]), penumbra_parser::FileLoc::builtin()));
        // Perspective, fov 90 on a square image: the screen window [-1, 1]² spans 10 at distance 5.
        let mut ortho = ParamSet::new();
        ortho.add(Param::new(
            "screenwindow",
            ParamValue::Float(vec![-2.0, 2.0, -2.0, 2.0]),
            penumbra_parser::FileLoc::builtin(),
        ));
        for (kind, params, span) in [("perspective", fov90, 10.0f32), ("orthographic", ortho, 4.0)] {
            let c = cam(kind, params, (res, res));
            let centre = sample(res as f32 / 2.0, res as f32 / 2.0);
            let d = plane_hit(&c.sample_ray(&centre, spp));
            let step = span / res as f32 / (spp as f32).sqrt();
            let close = |a: f32, b: f32| (a.abs() - b).abs() <= 2e-3 * b;
            assert!(close(d.dpdx.length(), step) && close(d.dpdy.length(), step), "{kind}: {d:?} vs {step}");
            assert!(close(d.dudx, step / 2.0) && close(d.dvdy, step / 3.0), "{kind}: {d:?}");
            assert!(d.dvdx.abs() < 1e-6 && d.dudy.abs() < 1e-6, "{kind}: {d:?}");
            // Without scaling: one whole pixel.
            let full = plane_hit(&c.generate_ray_differential(&centre));
            assert!(close(full.dpdx.length(), span / res as f32), "{kind}: {full:?}");
            // `footprint_spp` replaces the render's count: 2048 at 64 spp spans 1/√2048 pixel.
            let c2048 = Camera { footprint_spp: Some(2048), ..c.clone() };
            let f = plane_hit(&c2048.sample_ray(&centre, 64));
            assert!(close(f.dpdx.length(), span / res as f32 / 2048f32.sqrt()), "{kind}: {f:?}");
        }
        // The environment camera's offsets are a 0.05-pixel finite difference of its directions:
        // at the equator, one pixel in x turns the direction by 2π/width.
        let e = cam("environment", ParamSet::new(), (128, 64));
        let r = e.generate_ray_differential(&sample(17.3, 32.0));
        let o = r.offsets.unwrap();
        let turn = (o.rx_d - r.d).length();
        assert!((turn - std::f32::consts::TAU / 128.0).abs() < 2e-3 * turn, "{turn}");
        assert!((o.ry_d - r.d).length() > 0.0 && o.rx_o == r.o);
    }

    /// The `realistic` camera with the conformance matrix's singlet (f ≈ 61 mm, 10 mm stop)
    /// focused at 5 m, 5 m from the plane z = 0: rays from one film point through different
    /// lens points meet on that plane (the spot there is a small fraction of the bundle's width
    /// 1 m before it); the image is upright and unmirrored as the perspective camera's; the
    /// film centre's weight is 1 (cos⁴ of a near-zero angle, its own pupil bound) and the
    /// corners' smaller; a missing lens file is an error naming it.
    #[test]
    fn realistic_camera_focuses_orients_and_weights_as_pbrt_v3() {
        let loc = penumbra_parser::FileLoc::builtin;
        let dir = std::env::temp_dir().join(format!("penumbra-lens-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("singlet.dat"), "# singlet\n60 8 1.5 30\n-60 10 1 30\n0 30 0 20\n").unwrap();
        let params = |file: &str| {
            let mut ps = ParamSet::new();
            ps.add(Param::new("lensfile", ParamValue::String(vec![file.into()]), loc()));
            ps.add(Param::new("aperturediameter", ParamValue::Float(vec![10.0]), loc()));
            ps.add(Param::new("focusdistance", ParamValue::Float(vec![5.0]), loc()));
            ps
        };
        let cfw = Transform::look_at([0.0, 0.0, -5.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]).unwrap();
        let desc = |ps: ParamSet| CameraDesc {
            entity: Entity::new("realistic", ps, loc()),
            camera_from_world: AnimatedTransform::fixed(cfw),
            world_from_camera: AnimatedTransform::fixed(cfw.inverse()),
            medium: None,
        };
        let cx = CameraContext { film_diagonal_mm: 35.0, base_dir: dir.clone() };
        let c = Camera::from_desc_in(&desc(params("singlet.dat")), (64, 64), &cx, &DiagSink::new()).unwrap();
        assert!(c.uses_lens());
        let hit = |r: &Ray, z: f32| r.o + r.d * ((z - r.o.z) / r.d.z);
        // Near the film centre and through the middle of the pupil: the singlet's spherical
        // aberration and field curvature move its focus by metres at 5 m (measured: the
        // pupil's outer half focuses near 1 m, as does a film point 4 mm off the axis), which
        // is what pbrt-v3 renders too.
        let through = |p_film: Vec2, z: f32| -> Vec<Vec3> {
            [(0.45, 0.5), (0.55, 0.5), (0.5, 0.45), (0.5, 0.55), (0.47, 0.53)]
                .into_iter()
                .map(|(i, j)| {
                    let (r, w) = c.generate_ray_weighted(&CameraSample { p_film, p_lens: Vec2::new(i, j), time: 0.0 });
                    assert!(w > 0.0, "lens sample ({i}, {j}) blocked");
                    hit(&r, z)
                })
                .collect()
        };
        let centre_px = Vec2::new(32.5, 31.5);
        let (at_focus, before) = (through(centre_px, 0.0), through(centre_px, -1.0));
        let spread =
            |v: &[Vec3]| v.iter().map(|a| v.iter().map(|b| (*a - *b).length()).fold(0.0, f32::max)).fold(0.0, f32::max);
        let (sf, sb) = (spread(&at_focus), spread(&before));
        // Measured 22 µm against 242 µm (0.09; the thick-lens focus is paraxial, these rays are
        // not quite); focused 1 m off, the two would swap.
        assert!(sf < 0.2 * sb && sb > 1e-4, "spot {sf} at focus, {sb} 1 m before");
        // Upright and unmirrored: the scene point seen is on the side of the perspective
        // camera's ray through the same pixel.
        let p_film = Vec2::new(20.5, 12.5);
        let persp = cam("perspective", ParamSet::new(), (64, 64)).generate_ray(&sample(p_film.x, p_film.y));
        let (q, seen) = (hit(&persp, 0.0), through(p_film, 0.0)[0]);
        assert!(q.x.signum() == seen.x.signum() && q.y.signum() == seen.y.signum(), "{q} vs {seen}");
        let centre =
            c.generate_ray_weighted(&CameraSample { p_film: Vec2::splat(32.0), p_lens: Vec2::splat(0.5), time: 0.0 });
        assert!((centre.1 - 1.0).abs() < 1e-4, "{}", centre.1);
        let corner =
            c.generate_ray_weighted(&CameraSample { p_film: Vec2::splat(0.5), p_lens: Vec2::splat(0.5), time: 0.0 });
        assert!(corner.1 < 0.95, "{}", corner.1);
        let e = Camera::from_desc_in(&desc(params("missing.dat")), (64, 64), &cx, &DiagSink::new()).unwrap_err();
        assert!(e.message.contains("missing.dat"), "{}", e.message);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
