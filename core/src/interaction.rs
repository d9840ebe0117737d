//! What a ray query finds: the local geometry at a hit ([`SurfaceInteraction`]) and the
//! scene object a mesh comes from ([`SceneObject`]). Lights, materials and textures
//! read these; the scene ([`crate::scene`]) produces them, so the arrows point one way:
//! `scene` → `light`/`material`/`texture` → `interaction` → `geometry`.

use crate::geometry::{offset_ray_origin, Frame, Ray, RayDifferential, RayOffsets};
use glam::{Vec2, Vec3};
use penumbra_parser::FileLoc;

/// One shape directive (or one shape of one object instance) in the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneObject {
    /// The shape type as written (`"sphere"`, `"trianglemesh"`…).
    pub kind: String,
    pub loc: FileLoc,
    /// Index into `SceneDescription::materials`; `None` means no surface (pbrt-v3's `Material "none"`).
    pub material: Option<usize>,
    /// Index into `SceneDescription::area_lights`.
    pub area_light: Option<usize>,
    /// Which `ObjectInstance` this came from, if any.
    pub instance: Option<usize>,
    /// `"bool occluder" false` on the shape: analytic visibility methods ignore it as an
    /// occluder (a penumbra extension; pbrt-v3 reports the parameter unused and renders).
    pub occluder: bool,
}

/// Screen-space derivatives at a hit, from the ray's offset rays (pbrt-v3's
/// `SurfaceInteraction::dpdx`, `dpdy`, `dudx`, `dvdx`, `dudy`, `dvdy`): the change of the
/// point and of its (u, v) over one pixel step of the ray in x and in y. All zero when the
/// ray has no offset rays (then textures point-sample and bump mapping takes a fixed step,
/// as in pbrt-v3).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Differentials {
    pub dpdx: Vec3,
    pub dpdy: Vec3,
    pub dudx: f32,
    pub dvdx: f32,
    pub dudy: f32,
    pub dvdy: f32,
}

/// The local geometry at a ray hit, with pbrt-v3's conventions for normals.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceInteraction {
    pub p: Vec3,
    /// Conservative absolute error bound on `p`.
    pub p_error: Vec3,
    /// Geometric normal (pbrt-v3's `n`; see `crate::mesh` for its orientation rules).
    pub n: Vec3,
    pub uv: Vec2,
    pub dpdu: Vec3,
    pub dpdv: Vec3,
    /// Shading frame (z = shading normal, pbrt-v3's `shading.n`).
    pub shading: Frame,
    /// pbrt-v3's `shading.dpdu`, `shading.dpdv`: the tangents bump mapping perturbs (unit
    /// vectors for triangle meshes with normals or tangents, the surface's own ∂p/∂u, ∂p/∂v
    /// otherwise).
    pub shading_dpdu: Vec3,
    pub shading_dpdv: Vec3,
    /// pbrt-v3's `shading.dndu`, `shading.dndv`: how the (unflipped) shading normal turns
    /// with (u, v); zero for flat triangles.
    pub dndu: Vec3,
    pub dndv: Vec3,
    /// Screen-space derivatives (zero without ray differentials).
    pub diff: Differentials,
    /// Direction towards the ray origin.
    pub wo: Vec3,
    pub mesh: u32,
    pub tri: u32,
    /// Where `n` is not normal to the surface the ray crossed (pbrt-v3's hyperboloid, whose
    /// `n` is `∂p/∂u × ∂p/∂v` along its segment `p1 → p2`, up to 160° off its surface): the
    /// hit triangle's normal, on the side the ray arrived from; zero otherwise. See
    /// [`Self::ray_origin`].
    pub wall: Vec3,
    /// With `wall`: the (smooth) normal of the surface the triangles approximate, on the side
    /// the ray arrived from.
    pub surface: Vec3,
    /// The time of the ray that found the hit (pbrt-v3's `Interaction::time`): rays spawned
    /// here take it.
    pub time: f32,
}

impl Default for SurfaceInteraction {
    fn default() -> Self {
        SurfaceInteraction {
            p: Vec3::ZERO,
            p_error: Vec3::ZERO,
            n: Vec3::Z,
            uv: Vec2::ZERO,
            dpdu: Vec3::X,
            dpdv: Vec3::Y,
            shading: Frame { x: Vec3::X, y: Vec3::Y, z: Vec3::Z },
            shading_dpdu: Vec3::X,
            shading_dpdv: Vec3::Y,
            dndu: Vec3::ZERO,
            dndv: Vec3::ZERO,
            diff: Differentials::default(),
            wo: Vec3::Z,
            mesh: 0,
            tri: 0,
            wall: Vec3::ZERO,
            surface: Vec3::ZERO,
            time: 0.0,
        }
    }
}

impl SurfaceInteraction {
    /// pbrt-v3's `ComputeDifferentials`: where the ray's offset rays meet the tangent plane
    /// at `p` gives ∂p/∂x and ∂p/∂y, and ∂(u, v)/∂(x, y) by least squares in the two
    /// coordinates the normal is least aligned with. Without offset rays, or when an offset
    /// ray runs parallel to the plane, the differentials are zero.
    pub fn compute_differentials(&mut self, ray: &RayDifferential) {
        self.diff = ray.offsets.map_or_else(Differentials::default, |o| self.differentials_from(&o));
    }

    fn differentials_from(&self, o: &RayOffsets) -> Differentials {
        let n = self.n;
        let d = n.dot(self.p);
        let plane = |org: Vec3, dir: Vec3| {
            let t = -(n.dot(org) - d) / n.dot(dir);
            t.is_finite().then(|| org + t * dir)
        };
        let (Some(px), Some(py)) = (plane(o.rx_o, o.rx_d), plane(o.ry_o, o.ry_d)) else {
            return Differentials::default();
        };
        let (dpdx, dpdy) = (px - self.p, py - self.p);
        let a = n.abs();
        let dim = if a.x > a.y && a.x > a.z {
            [1, 2]
        } else if a.y > a.z {
            [0, 2]
        } else {
            [0, 1]
        };
        let m = [[self.dpdu[dim[0]], self.dpdv[dim[0]]], [self.dpdu[dim[1]], self.dpdv[dim[1]]]];
        let (dudx, dvdx) = solve_2x2(m, [dpdx[dim[0]], dpdx[dim[1]]]).unwrap_or((0.0, 0.0));
        let (dudy, dvdy) = solve_2x2(m, [dpdy[dim[0]], dpdy[dim[1]]]).unwrap_or((0.0, 0.0));
        Differentials { dpdx, dpdy, dudx, dvdx, dudy, dvdy }
    }

    /// The origin of a ray leaving the surface in direction `w`: `p` offset off the surface to
    /// `w`'s side of `n`, so the ray cannot re-hit it.
    ///
    /// Where `n` is not normal to the surface ([`Self::wall`]), pbrt-v3 still offsets along
    /// `n`, which puts the origin on one side of its surface or the other, and a ray whose
    /// origin is not on the side it heads to meets the surface at once and is blocked (its
    /// analytic intersection finds the root beside the origin). That decides, smoothly with
    /// the surface's normal `g`: blocked iff sign(w·n)·sign(n·g) ≠ sign(w·g). penumbra makes
    /// the same decision with the smooth `g` and enforces it on the tessellation: the origin
    /// goes to the hit triangle's side away from `w` (the ray then crosses its own triangle)
    /// or towards it. Offsetting along `n` as for other surfaces let rays through the
    /// tessellated surface (+16 % ambient occlusion on a two-sheet hyperboloid's inside), and
    /// deciding with the triangle's normal left rings along its rows.
    #[inline]
    pub fn ray_origin(&self, w: Vec3) -> Vec3 {
        if self.wall == Vec3::ZERO {
            return offset_ray_origin(self.p, self.p_error, self.n, w);
        }
        let g = self.surface;
        let side_n = w.dot(self.n) >= 0.0;
        let origin_side = side_n == (self.n.dot(g) >= 0.0);
        let blocked = origin_side != (w.dot(g) >= 0.0);
        offset_ray_origin(self.p, self.p_error, self.wall, if blocked { -w } else { w })
    }
    /// A ray leaving the surface in direction `d`, offset so it cannot re-hit this surface.
    pub fn spawn_ray(&self, d: Vec3) -> Ray {
        Ray::new(self.ray_origin(d), d, f32::INFINITY).at_time(self.time)
    }
    /// A shadow ray from this surface to point `p` (stops just short of it).
    pub fn spawn_ray_to(&self, p: Vec3) -> Ray {
        let o = self.ray_origin(p - self.p);
        Ray::new(o, p - o, 1.0 - SHADOW_EPSILON).at_time(self.time)
    }
    /// A shadow ray between this surface and another surface point, both ends offset.
    pub fn spawn_ray_to_surface(&self, p: Vec3, p_error: Vec3, n: Vec3) -> Ray {
        let o = self.ray_origin(p - self.p);
        let t = offset_ray_origin(p, p_error, n, o - p);
        Ray::new(o, t - o, 1.0 - SHADOW_EPSILON).at_time(self.time)
    }
}

/// pbrt-v3's `ShadowEpsilon`.
pub const SHADOW_EPSILON: f32 = 0.0001;

/// pbrt-v3's `SolveLinearSystem2x2`: `m · x = b`, `None` when `m` is (nearly) singular or the
/// solution is not finite.
pub fn solve_2x2(m: [[f32; 2]; 2], b: [f32; 2]) -> Option<(f32, f32)> {
    let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    if det.abs() < 1e-10 {
        return None;
    }
    let x0 = (m[1][1] * b[0] - m[0][1] * b[1]) / det;
    let x1 = (m[0][0] * b[1] - m[1][0] * b[0]) / det;
    (x0.is_finite() && x1.is_finite()).then_some((x0, x1))
}
