//! pbrt-v3's `RealisticCamera` lens system (pbrt-v3 book §6.4; `src/cameras/realistic.cpp`):
//! spherical element interfaces and an aperture stop read from a lens file, focused by the
//! thick-lens approximation, rays traced from the film through every element, sampled over the
//! exit pupil's bounds (64 bounds by distance from the film centre, found once from 2²⁰ traced
//! rays each), weighted by cos⁴θ and the bound's area.
//!
//! Coordinates: camera space (left-handed, looking down +z) with the film at z = 0 and the
//! rear element at z = `rear_z()`; the "lens space" of the tracing routines is camera space
//! with z negated, as pbrt-v3's `CameraToLens`. Lengths are in metres (the lens file's
//! millimetres × 0.001).

use crate::sampler::lowdiscrepancy::radical_inverse;
use glam::{DVec2, DVec3};
use rayon::prelude::*;

/// One interface of the lens system, as pbrt-v3's `LensElementInterface` (metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LensElement {
    /// 0 for the aperture stop; positive when the centre of curvature lies towards the film.
    pub curvature_radius: f64,
    /// Distance along the axis to the next interface (towards the film); the last one's is the
    /// distance to the film, set by focusing.
    pub thickness: f64,
    /// Index of refraction of the medium on the film side (0 or 1: air).
    pub eta: f64,
    pub aperture_radius: f64,
}

/// An axis-aligned rectangle on the plane of the rear element.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds2d {
    pub min: DVec2,
    pub max: DVec2,
}

impl Bounds2d {
    fn empty() -> Bounds2d {
        Bounds2d { min: DVec2::splat(f64::INFINITY), max: DVec2::splat(f64::NEG_INFINITY) }
    }
    fn inside(&self, p: DVec2) -> bool {
        p.x >= self.min.x && p.x <= self.max.x && p.y >= self.min.y && p.y <= self.max.y
    }
    fn union(&mut self, p: DVec2) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }
    pub fn area(&self) -> f64 {
        let d = self.max - self.min;
        d.x * d.y
    }
    fn lerp(&self, t: DVec2) -> DVec2 {
        self.min + (self.max - self.min) * t
    }
}

/// A ray in lens or camera space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LensRay {
    pub o: DVec3,
    pub d: DVec3,
}

impl LensRay {
    fn at(&self, t: f64) -> DVec3 {
        self.o + self.d * t
    }
    fn flip_z(self) -> LensRay {
        let f = DVec3::new(1.0, 1.0, -1.0);
        LensRay { o: self.o * f, d: self.d * f }
    }
}

/// The number of exit-pupil bounds by film radius, and of rays traced for each (pbrt-v3's).
pub const PUPIL_BOUNDS: usize = 64;
pub const PUPIL_SAMPLES: usize = 1024 * 1024;

/// A focused lens system with its exit-pupil bounds.
#[derive(Clone, Debug, PartialEq)]
pub struct LensSystem {
    pub elements: Vec<LensElement>,
    /// The film's diagonal in metres (pbrt-v3's `Film "diagonal"`, millimetres there).
    pub film_diagonal: f64,
    pub exit_pupil: Vec<Bounds2d>,
    pub simple_weighting: bool,
    /// `shutterclose − shutteropen`, for the weight without `simpleweighting`.
    pub shutter_length: f64,
}

/// pbrt-v3's `ReadFloatFile`: numbers separated by white space, `#` comments to the end of
/// the line; anything else is an error.
pub fn parse_float_file(text: &str) -> Result<Vec<f64>, String> {
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("");
        for tok in line.split_whitespace() {
            let v: f64 = tok.parse().map_err(|_| format!("line {}: unexpected text \"{tok}\"", n + 1))?;
            out.push(v);
        }
    }
    Ok(out)
}

/// pbrt-v3's `Quadratic` (in f64): the roots in increasing order.
fn quadratic(a: f64, b: f64, c: f64) -> Option<(f64, f64)> {
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 || a == 0.0 {
        return None;
    }
    let root = disc.sqrt();
    let q = if b < 0.0 { -0.5 * (b - root) } else { -0.5 * (b + root) };
    let (t0, t1) = (q / a, c / q);
    Some(if t0 > t1 { (t1, t0) } else { (t0, t1) })
}

/// One element's interface for a lens-space ray at `element_z` (its vertex): the hit on its
/// sphere (or the stop's plane), the aperture test, then refraction from `eta_i` into `eta_t`
/// (the stop only moves the ray). `None` when the element blocks the ray or reflects it totally.
fn pass_element(e: &LensElement, element_z: f64, r: &mut LensRay, eta_i: f64, eta_t: f64) -> Option<()> {
    let is_stop = e.curvature_radius == 0.0;
    let (t, n) = if is_stop {
        ((element_z - r.o.z) / r.d.z, DVec3::ZERO)
    } else {
        intersect_spherical(e.curvature_radius, element_z + e.curvature_radius, r)?
    };
    if !(t >= 0.0) {
        return None;
    }
    let p = r.at(t);
    if p.x * p.x + p.y * p.y > e.aperture_radius * e.aperture_radius {
        return None;
    }
    r.o = p;
    if !is_stop {
        r.d = refract(-r.d.normalize(), n, eta_i / eta_t)?;
    }
    Some(())
}

/// pbrt-v3's `Refract`: `wi` and `n` on the same side, `eta` = ηi/ηt.
fn refract(wi: DVec3, n: DVec3, eta: f64) -> Option<DVec3> {
    let cos_i = n.dot(wi);
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = eta * eta * sin2_i;
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(eta * -wi + (eta * cos_i - cos_t) * n)
}

/// pbrt-v3's `IntersectSphericalElement`: the hit's parameter and the normal facing the ray.
fn intersect_spherical(radius: f64, z_center: f64, ray: &LensRay) -> Option<(f64, DVec3)> {
    let o = ray.o - DVec3::new(0.0, 0.0, z_center);
    let a = ray.d.length_squared();
    let b = 2.0 * ray.d.dot(o);
    let c = o.length_squared() - radius * radius;
    let (t0, t1) = quadratic(a, b, c)?;
    let use_closer = (ray.d.z > 0.0) ^ (radius < 0.0);
    let t = if use_closer { t0.min(t1) } else { t0.max(t1) };
    if !(t >= 0.0) {
        return None;
    }
    let n = (o + t * ray.d).normalize();
    let n = if n.dot(-ray.d) < 0.0 { -n } else { n };
    Some((t, n))
}

impl LensSystem {
    /// pbrt-v3's `RealisticCamera` constructor: `data` is the lens file's values (radius,
    /// thickness, η, aperture diameter per interface, millimetres), `aperture_diameter` the
    /// stop's diameter in millimetres (clamped to the file's, with a warning), the system
    /// focused at `focus_distance` (metres) by the thick-lens approximation. Errors where
    /// pbrt-v3 fails a check or exits.
    pub fn new(
        data: &[f64],
        aperture_diameter: f64,
        focus_distance: f64,
        film_diagonal: f64,
        simple_weighting: bool,
        shutter_length: f64,
        warn: &mut dyn FnMut(String),
    ) -> Result<LensSystem, String> {
        if data.is_empty() || !data.len().is_multiple_of(4) {
            return Err(format!("the lens file must hold a multiple of four values, got {}", data.len()));
        }
        if data.iter().any(|v| !v.is_finite()) {
            return Err("the lens file holds a non-finite value".into());
        }
        if !(film_diagonal.is_finite() && film_diagonal > 0.0) {
            return Err(format!("film \"diagonal\" must be positive, got {} mm", film_diagonal * 1000.0));
        }
        let mut elements = Vec::with_capacity(data.len() / 4);
        for e in data.chunks_exact(4) {
            let mut aperture = e[3];
            if e[0] == 0.0 {
                if aperture_diameter > e[3] {
                    warn(format!(
                        "specified aperture diameter {aperture_diameter} is greater than maximum possible {}: clamping it",
                        e[3]
                    ));
                } else {
                    aperture = aperture_diameter;
                }
            }
            elements.push(LensElement {
                curvature_radius: e[0] * 0.001,
                thickness: e[1] * 0.001,
                eta: e[2],
                aperture_radius: aperture * 0.001 / 2.0,
            });
        }
        if elements.iter().any(|e| !(e.aperture_radius > 0.0)) {
            return Err("every lens interface (and the aperture stop) needs a positive aperture diameter".into());
        }
        let mut lens = LensSystem { elements, film_diagonal, exit_pupil: Vec::new(), simple_weighting, shutter_length };
        let thickness = lens.focus_thick_lens(focus_distance)?;
        if !(thickness.is_finite() && thickness > 0.0) {
            return Err(format!("focusing at {focus_distance} puts the film at {thickness} m from the rear element"));
        }
        lens.elements.last_mut().expect("non-empty").thickness = thickness;
        lens.exit_pupil = (0..PUPIL_BOUNDS)
            .into_par_iter()
            .map(|i| {
                let r0 = i as f64 / PUPIL_BOUNDS as f64 * film_diagonal / 2.0;
                let r1 = (i + 1) as f64 / PUPIL_BOUNDS as f64 * film_diagonal / 2.0;
                lens.bound_exit_pupil(r0, r1)
            })
            .collect();
        if !(lens.exit_pupil[0].area() > 0.0) {
            return Err("the lens system passes no light at the film centre".into());
        }
        Ok(lens)
    }

    /// The rear element's z (camera space): the distance from the film.
    pub fn rear_z(&self) -> f64 {
        self.elements.last().map_or(0.0, |e| e.thickness)
    }

    /// The front element's z (camera space).
    pub fn front_z(&self) -> f64 {
        self.elements.iter().map(|e| e.thickness).sum()
    }

    fn rear_radius(&self) -> f64 {
        self.elements.last().map_or(0.0, |e| e.aperture_radius)
    }

    /// pbrt-v3's `TraceLensesFromFilm`: a camera-space ray from the film out through the
    /// elements, or `None` when an element or the stop blocks it (or it is totally reflected).
    pub fn trace_from_film(&self, r_camera: &LensRay) -> Option<LensRay> {
        let mut element_z = 0.0;
        let mut r = r_camera.flip_z();
        for i in (0..self.elements.len()).rev() {
            let e = &self.elements[i];
            element_z -= e.thickness;
            if e.curvature_radius == 0.0 && r.d.z >= 0.0 {
                return None;
            }
            let eta_t = if i > 0 && self.elements[i - 1].eta != 0.0 { self.elements[i - 1].eta } else { 1.0 };
            pass_element(e, element_z, &mut r, e.eta, eta_t)?;
        }
        Some(r.flip_z())
    }

    /// pbrt-v3's `TraceLensesFromScene`: a camera-space ray from the scene in through the
    /// elements towards the film.
    pub fn trace_from_scene(&self, r_camera: &LensRay) -> Option<LensRay> {
        let mut element_z = -self.front_z();
        let mut r = r_camera.flip_z();
        for (i, e) in self.elements.iter().enumerate() {
            let eta_i = if i == 0 || self.elements[i - 1].eta == 0.0 { 1.0 } else { self.elements[i - 1].eta };
            let eta_t = if e.eta != 0.0 { e.eta } else { 1.0 };
            pass_element(e, element_z, &mut r, eta_i, eta_t)?;
            element_z += e.thickness;
        }
        Some(r.flip_z())
    }

    /// pbrt-v3's `ComputeCardinalPoints`: (principal plane z, focal point z), lens space.
    fn cardinal_points(r_in: &LensRay, r_out: &LensRay) -> (f64, f64) {
        let tf = -r_out.o.x / r_out.d.x;
        let fz = -r_out.at(tf).z;
        let tp = (r_in.o.x - r_out.o.x) / r_out.d.x;
        let pz = -r_out.at(tp).z;
        (pz, fz)
    }

    /// pbrt-v3's `FocusThickLens`: the rear element's distance from the film that focuses at
    /// `focus_distance`.
    fn focus_thick_lens(&self, focus_distance: f64) -> Result<f64, String> {
        let x = 0.001 * self.film_diagonal;
        let blocked = "a ray parallel to the axis does not pass the lens system for the thick-lens approximation \
                       (is the aperture stop extremely small?)";
        let r_scene = LensRay { o: DVec3::new(x, 0.0, self.front_z() + 1.0), d: DVec3::new(0.0, 0.0, -1.0) };
        let r_film = self.trace_from_scene(&r_scene).ok_or(blocked)?;
        let (pz0, fz0) = Self::cardinal_points(&r_scene, &r_film);
        let r_film2 = LensRay { o: DVec3::new(x, 0.0, self.rear_z() - 1.0), d: DVec3::new(0.0, 0.0, 1.0) };
        let r_scene2 = self.trace_from_film(&r_film2).ok_or(blocked)?;
        let (pz1, _) = Self::cardinal_points(&r_film2, &r_scene2);
        let f = fz0 - pz0;
        let z = -focus_distance;
        let c = (pz1 - z - pz0) * (pz1 - z - 4.0 * f - pz0);
        if !(c > 0.0) {
            return Err(format!(
                "focusdistance {focus_distance} is too short for this lens system (effective focal length {:.4} m)",
                f
            ));
        }
        let delta = 0.5 * (pz1 - z + pz0 - c.sqrt());
        Ok(self.rear_z() + delta)
    }

    /// The effective focal length (metres) and where the lens focuses rays from the film
    /// centre; for tests and reports.
    pub fn effective_focal_length(&self) -> Option<f64> {
        let x = 0.001 * self.film_diagonal;
        let r_scene = LensRay { o: DVec3::new(x, 0.0, self.front_z() + 1.0), d: DVec3::new(0.0, 0.0, -1.0) };
        let r_film = self.trace_from_scene(&r_scene)?;
        let (pz, fz) = Self::cardinal_points(&r_scene, &r_film);
        Some(fz - pz)
    }

    /// pbrt-v3's `FocusDistance`: where a ray from the film centre through the lens near the
    /// axis crosses the axis in the scene (camera z; infinite when it does not).
    pub fn focus_distance(&self) -> f64 {
        let bounds = self.bound_exit_pupil(0.0, 0.001 * self.film_diagonal);
        for scale in [0.1, 0.01, 0.001] {
            let lu = scale * bounds.max.x;
            let r = LensRay { o: DVec3::ZERO, d: DVec3::new(lu, 0.0, self.rear_z()) };
            if let Some(out) = self.trace_from_film(&r) {
                let t = -out.o.x / out.d.x;
                let z = out.at(t).z;
                return if z < 0.0 { f64::INFINITY } else { z };
            }
        }
        f64::INFINITY
    }

    /// pbrt-v3's `BoundExitPupil`: the bounds, on the rear element's plane, of the points
    /// through which rays from the film segment x ∈ [x0, x1] pass the whole system.
    fn bound_exit_pupil(&self, x0: f64, x1: f64) -> Bounds2d {
        let rear = self.rear_radius();
        let proj = Bounds2d { min: DVec2::splat(-1.5 * rear), max: DVec2::splat(1.5 * rear) };
        let mut bounds = Bounds2d::empty();
        let mut exiting = 0usize;
        let rear_z = self.rear_z();
        for i in 0..PUPIL_SAMPLES {
            let t = (i as f64 + 0.5) / PUPIL_SAMPLES as f64;
            let p_film = DVec3::new(x0 + (x1 - x0) * t, 0.0, 0.0);
            let u = DVec2::new(radical_inverse(0, i as u64) as f64, radical_inverse(1, i as u64) as f64);
            let p = proj.lerp(u);
            let p_rear = DVec3::new(p.x, p.y, rear_z);
            if bounds.inside(p) || self.trace_from_film(&LensRay { o: p_film, d: p_rear - p_film }).is_some() {
                bounds.union(p);
                exiting += 1;
            }
        }
        if exiting == 0 {
            return proj;
        }
        let d = proj.max - proj.min;
        let grow = 2.0 * d.length() / (PUPIL_SAMPLES as f64).sqrt();
        Bounds2d { min: bounds.min - DVec2::splat(grow), max: bounds.max + DVec2::splat(grow) }
    }

    /// pbrt-v3's `SampleExitPupil`: a point on the rear element's plane within the exit
    /// pupil's bounds for film point `p_film` (camera-space x, y), and the bounds' area.
    fn sample_exit_pupil(&self, p_film: DVec2, u: DVec2) -> (DVec3, f64) {
        let r_film = p_film.length();
        let n = self.exit_pupil.len();
        let idx = ((r_film / (self.film_diagonal / 2.0) * n as f64) as usize).min(n - 1);
        let b = self.exit_pupil[idx];
        let p = b.lerp(u);
        let (s, c) = if r_film != 0.0 { (p_film.y / r_film, p_film.x / r_film) } else { (0.0, 1.0) };
        (DVec3::new(c * p.x - s * p.y, s * p.x + c * p.y, self.rear_z()), b.area())
    }

    /// The film's physical extent (pbrt-v3's `Film::GetPhysicalExtent`): half widths in x and
    /// y, metres, for a full resolution `res`.
    pub fn film_half_extent(&self, res: (u32, u32)) -> DVec2 {
        let aspect = res.1 as f64 / res.0 as f64;
        let x = (self.film_diagonal * self.film_diagonal / (1.0 + aspect * aspect)).sqrt();
        DVec2::new(x / 2.0, aspect * x / 2.0)
    }

    /// pbrt-v3's `RealisticCamera::GenerateRay` in camera space: the ray leaving the front
    /// element for raster point `p_raster` (of a full resolution `res`) and lens sample `u`,
    /// with its weight; `None` when the lens system blocks it (weight 0).
    pub fn generate(&self, p_raster: DVec2, res: (u32, u32), u: DVec2) -> Option<(LensRay, f64)> {
        let half = self.film_half_extent(res);
        let s = DVec2::new(p_raster.x / res.0 as f64, p_raster.y / res.1 as f64);
        let p2 = -half + 2.0 * half * s;
        let p_film = DVec3::new(-p2.x, p2.y, 0.0);
        let (p_rear, area) = self.sample_exit_pupil(DVec2::new(p_film.x, p_film.y), u);
        let r_film = LensRay { o: p_film, d: p_rear - p_film };
        let out = self.trace_from_film(&r_film)?;
        let cos = r_film.d.normalize().z;
        let cos4 = (cos * cos) * (cos * cos);
        let w = if self.simple_weighting {
            cos4 * area / self.exit_pupil[0].area()
        } else {
            self.shutter_length * cos4 * area / (self.rear_z() * self.rear_z())
        };
        Some((out, w))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The conformance matrix's singlet: a biconvex lens R = ±60 mm, 8 mm thick, η 1.5, then
    /// the stop. Lensmaker's equation (thick lens): 1/f = (η−1)(1/R1 − 1/R2 + (η−1)d/(η R1 R2)).
    const SINGLET: [f64; 12] = [60.0, 8.0, 1.5, 30.0, -60.0, 10.0, 1.0, 30.0, 0.0, 30.0, 0.0, 20.0];

    fn singlet(focus: f64) -> LensSystem {
        LensSystem::new(&SINGLET, 10.0, focus, 0.035, true, 1.0, &mut |_| {}).unwrap()
    }

    #[test]
    fn thick_lens_focal_length_matches_the_lensmakers_equation() {
        let l = singlet(5.0);
        let (n, r1, r2, d) = (1.5, 0.060, -0.060, 0.008);
        let f = 1.0 / ((n - 1.0) * (1.0 / r1 - 1.0 / r2 + (n - 1.0) * d / (n * r1 * r2)));
        let got = l.effective_focal_length().unwrap();
        // Paraxial closed form vs a ray 35 µm off the axis: spherical aberration ~1e-6 relative.
        assert!((got - f).abs() < 1e-5 * f, "{got} vs {f}");
    }

    #[test]
    fn focusing_puts_the_focus_at_the_requested_distance() {
        for focus in [1.0, 5.0, 20.0] {
            let l = singlet(focus);
            // The traced focus of a ray through a tenth of the pupil (pbrt-v3's `FocusDistance`)
            // agrees with the paraxial thick-lens focus up to the singlet's spherical
            // aberration: measured 0.0026 dioptres (4.936 m for 5 m); a wrong principal plane
            // or sign moves it by tens of dioptres.
            let got = l.focus_distance();
            assert!((1.0 / got - 1.0 / focus).abs() < 0.005, "{focus}: {got}");
        }
    }

    #[test]
    fn rays_from_the_film_and_back_from_the_scene_retrace_the_same_path() {
        let l = singlet(5.0);
        let r = LensRay { o: DVec3::new(0.002, -0.001, 0.0), d: DVec3::new(0.001, 0.002, l.rear_z()) };
        let out = l.trace_from_film(&r).unwrap();
        let back = l.trace_from_scene(&LensRay { o: out.o + out.d * 0.1, d: -out.d }).unwrap();
        // The reversed ray lands on the film point it came from.
        let t = -back.o.z / back.d.z;
        let p = back.o + back.d * t;
        assert!((p - r.o).length() < 1e-9, "{p:?} vs {:?}", r.o);
    }

    #[test]
    fn exit_pupil_bounds_contain_every_passing_ray_and_the_stop_limits_them() {
        let l = singlet(5.0);
        // Off-axis film points: random points on the rear element that pass lie in the bound.
        let mut rng = crate::rng::Rng::new(7);
        for i in [0usize, 20, 63] {
            let x = (i as f64 + 0.5) / 64.0 * l.film_diagonal / 2.0;
            let b = l.exit_pupil[i];
            let mut passed = 0;
            for _ in 0..20000 {
                let u = DVec2::new(rng.uniform_f32() as f64, rng.uniform_f32() as f64) * 2.0 - 1.0;
                let p = u * l.rear_radius();
                let r = LensRay {
                    o: DVec3::new(x, 0.0, 0.0),
                    d: DVec3::new(p.x, p.y, l.rear_z()) - DVec3::new(x, 0.0, 0.0),
                };
                if l.trace_from_film(&r).is_some() {
                    passed += 1;
                    assert!(b.inside(p), "bound {i}: {p:?} outside {b:?}");
                }
            }
            assert!(passed > 100, "bound {i}: {passed}");
        }
        // The stop (10 mm here) is the limit near the axis: the pupil is about as wide as the
        // stop seen through the rear element, well inside the element itself (20 mm wide).
        let w = l.exit_pupil[0].max.x - l.exit_pupil[0].min.x;
        assert!(w > 0.008 && w < 0.016, "{w}");
    }

    #[test]
    fn bad_lens_files_are_errors() {
        let mut w = |_| {};
        assert!(LensSystem::new(&SINGLET[..7], 10.0, 5.0, 0.035, true, 1.0, &mut w).is_err());
        // A focus distance inside the focal length cannot be focused.
        assert!(LensSystem::new(&SINGLET, 10.0, 0.01, 0.035, true, 1.0, &mut w).is_err());
        assert!(parse_float_file("1 2 # c\n3 x").is_err());
        assert_eq!(parse_float_file("# head\n1 2\n-3.5e1 4 # tail").unwrap(), vec![1.0, 2.0, -35.0, 4.0]);
    }
}
