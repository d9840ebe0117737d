//! Precomputation per sphere (seed 003 §4.3.1), by ray casting from the sphere's centre
//! against its own object through the scene's BVH (other objects' hits are passed through):
//! - the *surface colour environment* `c_S`: the Lambertian albedo of the object's surface in
//!   each direction, projected to SH per channel (eq. 4.11);
//! - the *surface sample points*: position and outward normal in each geodesic direction
//!   (eqs. 4.12–4.13).
//!
//! Both apply the thesis's rules to the hits of a ray from the centre in direction `ω`:
//! 1. among the hits on the back side of the surface (the ray leaves the solid there), the
//!    farthest one in the sphere's segment `P_S` — the surface points closer to this sphere
//!    than to any other of its set by `|p − x_S|/r_S` (eq. 4.10) — is used;
//! 2. back-side hits only outside `P_S`: black / invalid (another sphere of the set covers
//!    that direction and hides this one there: the occlusion by intersecting spheres of the
//!    same set is baked in);
//! 3. no back-side hit (the centre is outside the solid in that direction): the ray in `−ω`,
//!    front sides only; its nearest hit is used (the thesis does not restrict it to `P_S`),
//!    black / invalid when there is none.
//!
//! "Back side" is decided by the outward normal when the mesh is closed and consistently wound
//! (its winding sign says which way is out); otherwise by parity along the ray (the centre
//! is inside iff the ray crosses the surface an odd number of times; crossings alternate).

use super::super::split_lambertian;
use crate::shexp::sphereset::{Sphere, SphereSet};
use glam::{DVec3, Vec3};
use penumbra_core::geometry::Ray;
use penumbra_core::interaction::SurfaceInteraction;
use penumbra_core::scene::Scene;
use penumbra_core::sh::{self, ShOrder, SphereQuadrature};

/// Hits followed along one ray before giving up (a pathological stack of surfaces).
const MAX_HITS: usize = 256;

/// A surface sample point of a sphere: the hit (for shadow rays) and its outward unit
/// shading normal.
#[derive(Clone, Debug)]
pub struct SurfaceSample {
    pub si: SurfaceInteraction,
    pub n: DVec3,
}

/// What one sphere keeps of its object's surface.
#[derive(Clone, Debug)]
pub struct SphereSurface {
    /// `c_S`, one SH vector per channel.
    pub colour: [Vec<f64>; 3],
    /// One per geodesic direction; `None` where the rules give no point.
    pub samples: Vec<Option<SurfaceSample>>,
    /// Intersection queries made.
    pub rays: u64,
}

/// How the side of a hit is decided for one object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sides {
    /// Closed and consistently wound: the winding normal times this sign points out.
    Winding(f32),
    /// Anything else: by the parity of the crossings along the ray.
    Parity,
}

impl Sides {
    pub fn of(scene: &Scene, object: usize) -> Sides {
        let Some(mesh) = scene.meshes.get(object) else { return Sides::Parity };
        let consistent = match scene.adjacency(object) {
            Some(adj) if !adj.edges.is_empty() => adj.is_closed_manifold(),
            _ => mesh.build_adjacency().is_closed_manifold(),
        };
        let sign = mesh.winding_sign();
        if consistent && sign != 0.0 {
            Sides::Winding(sign as f32)
        } else {
            Sides::Parity
        }
    }
}

/// One crossing of the object's surface along a ray.
struct Crossing {
    si: SurfaceInteraction,
    /// The ray leaves the solid here (back side).
    exit: bool,
    /// The outward geometric normal.
    out: Vec3,
}

/// Every crossing of `object`'s surface along the ray from `o` in direction `d`, nearest first.
fn crossings(scene: &Scene, object: usize, sides: Sides, o: Vec3, d: Vec3, rays: &mut u64) -> Vec<Crossing> {
    let mut out = Vec::new();
    let mut ray = Ray::new(o, d, f32::INFINITY);
    for _ in 0..MAX_HITS {
        *rays += 1;
        let Some(hit) = scene.intersect(&ray) else { break };
        let si = scene.interaction(&ray, &hit);
        if hit.mesh as usize == object {
            let wn = scene.meshes[object].winding_normal(hit.tri as usize);
            if wn != Vec3::ZERO {
                let (exit, out_n) = match sides {
                    Sides::Winding(s) => {
                        let n = wn * s;
                        (n.dot(d) > 0.0, n)
                    }
                    // Fixed below, once the count is known.
                    Sides::Parity => (false, wn),
                };
                out.push(Crossing { si, exit, out: out_n });
            }
        }
        ray = si.spawn_ray(d);
    }
    if sides == Sides::Parity {
        let inside = out.len() % 2 == 1;
        for (k, c) in out.iter_mut().enumerate() {
            c.exit = (k % 2 == 0) == inside;
            // The outward normal faces along the ray at an exit, against it at an entry.
            if (c.out.dot(d) > 0.0) != c.exit {
                c.out = -c.out;
            }
        }
    }
    out
}

/// Whether surface point `p` lies in the segment `P_S` of leaf `leaf` (eq. 4.10; ties go to the
/// lower index).
fn in_segment(leaves: &[Sphere], leaf: usize, p: DVec3) -> bool {
    let d = |s: &Sphere| p.distance(s.center) / s.radius;
    let own = d(&leaves[leaf]);
    leaves.iter().enumerate().all(|(k, s)| k == leaf || (if k < leaf { d(s) > own } else { d(s) >= own }))
}

/// The crossing the rules pick for direction `d` from `leaf`'s centre (see the module doc).
fn pick(scene: &Scene, set: &SphereSet, sides: Sides, leaf: usize, d: DVec3, rays: &mut u64) -> Option<Crossing> {
    let c = set.leaves[leaf].center.as_vec3();
    let dir = d.as_vec3();
    let along = crossings(scene, set.object, sides, c, dir, rays);
    if along.iter().any(|x| x.exit) {
        return along.into_iter().rev().find(|x| x.exit && in_segment(&set.leaves, leaf, x.si.p.as_dvec3()));
    }
    crossings(scene, set.object, sides, c, -dir, rays).into_iter().find(|x| !x.exit)
}

/// The Lambertian albedo at a crossing and its outward shading normal.
fn albedo_and_normal(scene: &Scene, x: &Crossing) -> (penumbra_core::Rgb, DVec3) {
    let Some(bsdf) = scene.bsdf(&x.si) else { return (penumbra_core::Rgb::ZERO, x.out.as_dvec3()) };
    let (kd, _) = split_lambertian(&bsdf);
    let ns = bsdf.shading_normal();
    let ns = if ns.dot(x.out) < 0.0 { -ns } else { ns };
    let n = ns.as_dvec3().normalize_or_zero();
    (kd, if n == DVec3::ZERO { x.out.as_dvec3().normalize_or_zero() } else { n })
}

/// `c_S` and the sample points of leaf `leaf` of `set`: `colour_dirs` is the quadrature the
/// colour is projected with, `sample_dirs` the geodesic directions.
pub fn sphere_surface(
    scene: &Scene,
    set: &SphereSet,
    sides: Sides,
    leaf: usize,
    order: ShOrder,
    colour_dirs: &SphereQuadrature,
    sample_dirs: &[DVec3],
) -> SphereSurface {
    let k = order.coeffs();
    let mut colour = [vec![0.0; k], vec![0.0; k], vec![0.0; k]];
    let mut y = vec![0.0; k];
    let mut rays = 0;
    for (d, w) in colour_dirs.dirs.iter().zip(&colour_dirs.weights) {
        let Some(x) = pick(scene, set, sides, leaf, *d, &mut rays) else { continue };
        let (kd, _) = albedo_and_normal(scene, &x);
        if kd == penumbra_core::Rgb::ZERO {
            continue;
        }
        sh::basis::eval_unit(order, *d, &mut y);
        for (ch, c) in colour.iter_mut().enumerate() {
            let a = w * kd[ch] as f64;
            c.iter_mut().zip(&y).for_each(|(o, yi)| *o += a * yi);
        }
    }
    let samples = sample_dirs
        .iter()
        .map(|d| {
            let x = pick(scene, set, sides, leaf, *d, &mut rays)?;
            let (_, n) = albedo_and_normal(scene, &x);
            (n != DVec3::ZERO).then_some(SurfaceSample { si: x.si, n })
        })
        .collect();
    SphereSurface { colour, samples, rays }
}
