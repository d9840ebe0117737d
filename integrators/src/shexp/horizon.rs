//! The light under the horizon that passes the ground plane's edge.
//!
//! `shexp` cuts the environment at the ground plane's horizon ([`super::lighting`]) as if the
//! plane were infinite. A real floor ends: from a receiver at height `h`, the directions below
//! the horizon whose rays land beyond the plane's outline see the environment. On
//! `ao/spheres-on-plane` (a 12 × 12 plane, white sky) that light is 7–10 % of the spheres'
//! shading, and its absence was most of `shexp`'s error against pbrt-v3.
//!
//! [`HorizonGap`] adds it, per receiver, without sphere-set visibility (the objects stand on
//! the plane, so they seldom block the thin band between the horizon and the plane's edge):
//!
//! `E_gap(p, N) = ∫_φ ∫_{e ∈ gap(φ)} L(φ, −e) max(0, N·ω) cos e de dφ`
//!
//! in the plane's frame (azimuth φ, depression `e` below the horizon). Along each azimuth the
//! depressions whose rays miss the plane are found exactly from the outline (the plane
//! mesh's boundary edges, even–odd rule, so holes and concave outlines work); the receiver's
//! cosine `N·ω = N_h cos e − N_z sin e` is positive on one interval found in closed form; and
//! the environment enters through two cumulative tables per azimuth,
//! `A(e) = ∫₀^e L cos² e' de'` and `B(e) = ∫₀^e L sin e' cos e' de'`, so each interval costs
//! `N_h ΔA − N_z ΔB`. φ is integrated by the midpoint rule over [`AZIMUTHS`] bins whose
//! radiance is box-filtered over the bin.

use super::bright::EnvSource;
use super::lighting::frame;
use crate::shexp::sphereset::GroundPlane;
use glam::{DVec3, Vec2};
use penumbra_core::mesh::TriangleMesh;
use penumbra_core::sh::quadrature::gauss_legendre;
use std::collections::HashMap;
use std::f64::consts::{FRAC_PI_2, PI};

/// Azimuth bins (quadrature nodes) around the receiver.
pub const AZIMUTHS: usize = 64;
/// Depression steps of the cumulative tables over `[0, π/2]`.
const DEPRESSIONS: usize = 128;
/// Radiance samples per table cell: across the azimuth bin, and Gauss–Legendre nodes per
/// depression step.
const AZ_SUB: usize = 4;
const E_NODES: usize = 3;
/// Outlines with more boundary segments than this are replaced by their convex hull (each
/// receiver tests every segment along every azimuth).
pub const MAX_SEGMENTS: usize = 512;

pub struct HorizonGap {
    origin: DVec3,
    /// The plane's frame: `e1`, `e2` in the plane, `g` its unit normal towards the objects.
    e1: DVec3,
    e2: DVec3,
    g: DVec3,
    /// Outline segments in plane coordinates `(a, b)`.
    segments: Vec<[f64; 4]>,
    /// `(cos φ_k, sin φ_k)` of each azimuth bin's centre.
    dirs: Vec<(f64, f64)>,
    /// `AZIMUTHS × (DEPRESSIONS + 1)` cumulative `A` and `B` per channel.
    a: Vec<[f64; 3]>,
    b: Vec<[f64; 3]>,
    /// The outline was replaced by its convex hull.
    pub hull: bool,
}

/// The boundary edges of a mesh (edges of exactly one triangle, vertices welded by position).
fn boundary_edges(mesh: &TriangleMesh) -> Vec<(DVec3, DVec3)> {
    let mut ids: HashMap<[u32; 3], u32> = HashMap::new();
    let welded: Vec<u32> = mesh
        .positions
        .iter()
        .map(|p| {
            let key = p.to_array().map(|c| if c == 0.0 { 0 } else { c.to_bits() });
            let next = ids.len() as u32;
            *ids.entry(key).or_insert(next)
        })
        .collect();
    let mut pos = vec![DVec3::ZERO; ids.len()];
    for (i, &w) in welded.iter().enumerate() {
        pos[w as usize] = mesh.positions[i].as_dvec3();
    }
    let mut count: HashMap<(u32, u32), u32> = HashMap::new();
    for t in &mesh.indices {
        let v = t.map(|i| welded.get(i as usize).copied().unwrap_or(0));
        for (a, b) in [(v[0], v[1]), (v[1], v[2]), (v[2], v[0])] {
            if a != b {
                *count.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
    }
    let mut edges: Vec<(u32, u32)> = count.into_iter().filter(|&(_, c)| c == 1).map(|(e, _)| e).collect();
    edges.sort_unstable();
    edges.into_iter().map(|(a, b)| (pos[a as usize], pos[b as usize])).collect()
}

/// The convex hull of 2D points as closed segments (monotone chain).
fn hull_segments(mut pts: Vec<[f64; 2]>) -> Vec<[f64; 4]> {
    pts.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    pts.dedup();
    if pts.len() < 3 {
        return Vec::new();
    }
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
    let mut h: Vec<[f64; 2]> = Vec::with_capacity(2 * pts.len());
    for pass in 0..2 {
        let start = h.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> =
            if pass == 0 { Box::new(pts.iter()) } else { Box::new(pts.iter().rev()) };
        for &p in iter {
            while h.len() >= start + 2 && cross(h[h.len() - 2], h[h.len() - 1], p) <= 0.0 {
                h.pop();
            }
            h.push(p);
        }
        h.pop();
    }
    (0..h.len()).map(|i| [h[i][0], h[i][1], h[(i + 1) % h.len()][0], h[(i + 1) % h.len()][1]]).collect()
}

/// The summed radiance of `sources` towards world direction `d`.
fn radiance(sources: &[(&EnvSource, glam::Mat3)], d: DVec3) -> [f64; 3] {
    let mut out = [0.0; 3];
    for (src, light_from_world) in sources {
        let w = (*light_from_world * d.as_vec3()).normalize_or_zero();
        if w == glam::Vec3::ZERO {
            continue;
        }
        let theta = (w.x * w.x + w.y * w.y).sqrt().atan2(w.z);
        let phi = penumbra_core::sampling::spherical_phi(w);
        let c = src.map.lookup(Vec2::new(phi / (2.0 * std::f32::consts::PI), theta / std::f32::consts::PI));
        for (o, v) in out.iter_mut().zip(c.to_array()) {
            *o += v as f64;
        }
    }
    out
}

impl HorizonGap {
    /// `sources`: the environments as `shexp` shades them (bright regions already split off);
    /// `mesh`: the ground plane's world-space mesh. `None` when the plane has no outline
    /// (every edge shared: a closed surface cannot be a ground plane, but nothing is assumed).
    pub fn build(sources: &[EnvSource], plane: GroundPlane, mesh: &TriangleMesh) -> Option<HorizonGap> {
        let g = plane.normal.normalize();
        let (e1, e2) = frame(g);
        let origin = plane.point;
        let to2 = |p: DVec3| [(p - origin).dot(e1), (p - origin).dot(e2)];
        let edges = boundary_edges(mesh);
        if edges.is_empty() {
            return None;
        }
        let mut segments: Vec<[f64; 4]> = edges
            .iter()
            .map(|&(a, b)| {
                let (a, b) = (to2(a), to2(b));
                [a[0], a[1], b[0], b[1]]
            })
            .collect();
        let hull = segments.len() > MAX_SEGMENTS;
        if hull {
            segments = hull_segments(edges.iter().flat_map(|&(a, b)| [to2(a), to2(b)]).collect());
        }
        let light: Vec<(&EnvSource, glam::Mat3)> = sources.iter().map(|s| (s, s.world_from_light.inverse())).collect();
        let (ex, ew) = gauss_legendre(E_NODES);
        let dirs: Vec<(f64, f64)> = (0..AZIMUTHS)
            .map(|k| {
                let phi = 2.0 * PI * (k as f64 + 0.5) / AZIMUTHS as f64;
                (phi.cos(), phi.sin())
            })
            .collect();
        let de = FRAC_PI_2 / DEPRESSIONS as f64;
        let dphi = 2.0 * PI / AZIMUTHS as f64;
        let stride = DEPRESSIONS + 1;
        let mut a = vec![[0.0; 3]; AZIMUTHS * stride];
        let mut b = vec![[0.0; 3]; AZIMUTHS * stride];
        for k in 0..AZIMUTHS {
            let subs: Vec<DVec3> = (0..AZ_SUB)
                .map(|s| {
                    let phi = dphi * (k as f64 + (s as f64 + 0.5) / AZ_SUB as f64);
                    e1 * phi.cos() + e2 * phi.sin()
                })
                .collect();
            let (mut sa, mut sb) = ([0.0; 3], [0.0; 3]);
            for j in 0..DEPRESSIONS {
                for (&x, &w) in ex.iter().zip(&ew) {
                    let e = de * (j as f64 + 0.5 * (x + 1.0));
                    let (se, ce) = e.sin_cos();
                    let mut l = [0.0; 3];
                    for h in &subs {
                        for (o, v) in l.iter_mut().zip(radiance(&light, *h * ce - g * se)) {
                            *o += v / AZ_SUB as f64;
                        }
                    }
                    let w = 0.5 * w * de;
                    for c in 0..3 {
                        sa[c] += w * l[c] * ce * ce;
                        sb[c] += w * l[c] * se * ce;
                    }
                }
                a[k * stride + j + 1] = sa;
                b[k * stride + j + 1] = sb;
            }
        }
        Some(HorizonGap { origin, e1, e2, g, segments, dirs, a, b, hull })
    }

    /// The cumulative tables of azimuth bin `k` at depression `e` (linear in between).
    #[inline]
    fn cumulative(&self, k: usize, e: f64) -> ([f64; 3], [f64; 3]) {
        let x = (e / FRAC_PI_2 * DEPRESSIONS as f64).clamp(0.0, DEPRESSIONS as f64);
        let j = (x as usize).min(DEPRESSIONS - 1);
        let f = x - j as f64;
        let base = k * (DEPRESSIONS + 1) + j;
        let (a0, a1, b0, b1) = (self.a[base], self.a[base + 1], self.b[base], self.b[base + 1]);
        ([0, 1, 2].map(|c| a0[c] + f * (a1[c] - a0[c])), [0, 1, 2].map(|c| b0[c] + f * (b1[c] - b0[c])))
    }

    /// Whether the ray from `p` in unit direction `d`, below the horizon, passes the plane:
    /// it meets the plane's plane outside the outline (even–odd rule). `false` from on or
    /// below the plane, and for `d` on or above the horizon.
    pub fn passes(&self, p: DVec3, d: DVec3) -> bool {
        let rel = p - self.origin;
        let (h, down) = (rel.dot(self.g), -d.dot(self.g));
        if !(h > 0.0) || !(down > 0.0) || !h.is_finite() {
            return false;
        }
        let q = rel + d * (h / down);
        let (x, y) = (q.dot(self.e1), q.dot(self.e2));
        // Crossings of the ray from (x, y) along +x, half-open in y.
        let mut inside = false;
        for sg in &self.segments {
            let (ax, ay, bx, by) = (sg[0], sg[1], sg[2], sg[3]);
            if (ay > y) != (by > y) {
                let cx = ax + (y - ay) / (by - ay) * (bx - ax);
                if cx > x {
                    inside = !inside;
                }
            }
        }
        !inside
    }

    /// `E_gap` per channel at `p` with unit normal `n` (zero on or below the plane).
    pub fn irradiance(&self, p: DVec3, n: DVec3) -> [f64; 3] {
        let rel = p - self.origin;
        let h = rel.dot(self.g);
        let mut out = [0.0; 3];
        if !(h > 0.0) || !h.is_finite() {
            return out;
        }
        let foot = [rel.dot(self.e1), rel.dot(self.e2)];
        // N_h's mean over a bin is its centre value times sinc(Δφ/2): the midpoint rule's error
        // on the smooth factor, removed.
        let half = PI / AZIMUTHS as f64;
        let sinc = half.sin() / half;
        let (nx, ny, nz) = (n.dot(self.e1), n.dot(self.e2), n.dot(self.g));
        let mut rs: Vec<f64> = Vec::with_capacity(8);
        for (k, &(c, s)) in self.dirs.iter().enumerate() {
            let nh = nx * c + ny * s;
            // N·ω = nh cos e − nz sin e over e ∈ [0, π/2]: one interval where it is positive.
            let (f0, f1) = (nh, -nz);
            let (pa, pb) = if f0 <= 0.0 && f1 <= 0.0 {
                continue;
            } else if f0 >= 0.0 && f1 >= 0.0 {
                (0.0, FRAC_PI_2)
            } else {
                let e0 = nh.abs().atan2(nz.abs());
                if f0 > 0.0 {
                    (0.0, e0)
                } else {
                    (e0, FRAC_PI_2)
                }
            };
            // Where the ray along azimuth k crosses the outline (half-open in the side test, so
            // a vertex on the ray counts once).
            rs.clear();
            for sg in &self.segments {
                let (ax, ay, bx, by) = (sg[0] - foot[0], sg[1] - foot[1], sg[2] - foot[0], sg[3] - foot[1]);
                let (sa, sb) = (c * ay - s * ax, c * by - s * bx);
                if (sa > 0.0) != (sb > 0.0) {
                    let t = sa / (sa - sb);
                    let r = (ax + t * (bx - ax)) * c + (ay + t * (by - ay)) * s;
                    if r > 0.0 {
                        rs.push(r);
                    }
                }
            }
            rs.sort_unstable_by(f64::total_cmp);
            // Outside the outline on [r_prev, r]: depressions [atan(h / r), atan(h / r_prev)].
            let mut inside = rs.len() % 2 == 1;
            let mut e_hi = FRAC_PI_2;
            for i in 0..=rs.len() {
                let e_lo = if i < rs.len() { h.atan2(rs[i]) } else { 0.0 };
                if !inside {
                    let (ea, eb) = (e_lo.max(pa), e_hi.min(pb));
                    if eb > ea {
                        let ((a0, b0), (a1, b1)) = (self.cumulative(k, ea), self.cumulative(k, eb));
                        for ch in 0..3 {
                            out[ch] += nh * sinc * (a1[ch] - a0[ch]) - nz * (b1[ch] - b0[ch]);
                        }
                    }
                }
                inside = !inside;
                e_hi = e_lo;
            }
        }
        let dphi = 2.0 * PI / AZIMUTHS as f64;
        out.map(|v| (v * dphi).max(0.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Mat3, Vec3};
    use penumbra_core::light::RgbMap;
    use penumbra_core::Rgb;

    fn quad_mesh(pts: &[[f32; 3]], tris: &[[u32; 3]]) -> TriangleMesh {
        TriangleMesh {
            positions: pts.iter().map(|p| Vec3::from_array(*p)).collect(),
            indices: tris.to_vec(),
            ..Default::default()
        }
    }

    fn square(half: f32) -> TriangleMesh {
        quad_mesh(
            &[[-half, 0.0, -half], [-half, 0.0, half], [half, 0.0, half], [half, 0.0, -half]],
            &[[0, 1, 2], [0, 2, 3]],
        )
    }

    fn ground() -> GroundPlane {
        GroundPlane { object: 0, point: DVec3::ZERO, normal: DVec3::Y, behind: false }
    }

    fn white() -> Vec<EnvSource> {
        vec![EnvSource { map: RgbMap::constant(Rgb::ONE), world_from_light: Mat3::IDENTITY }]
    }

    /// A map brighter towards +x in world (light space = world here), so the gap's azimuth
    /// matters.
    fn gradient() -> Vec<EnvSource> {
        let (w, h) = (64, 32);
        let mut texels = Vec::new();
        for t in 0..h {
            for s in 0..w {
                let phi = 2.0 * PI * (s as f64 + 0.5) / w as f64;
                let theta = PI * (t as f64 + 0.5) / h as f64;
                let x = theta.sin() * phi.cos();
                let v = (1.0 + 0.8 * x) as f32;
                texels.push(Rgb::new(v, 0.5 * v, 0.25));
            }
        }
        vec![EnvSource { map: RgbMap { width: w, height: h, texels }, world_from_light: Mat3::IDENTITY }]
    }

    /// The gap by brute force: a fine grid over the lower hemisphere, each direction's ray
    /// tested against the mesh's triangles.
    fn brute(sources: &[EnvSource], mesh: &TriangleMesh, p: DVec3, n: DVec3) -> [f64; 3] {
        let light: Vec<(&EnvSource, Mat3)> = sources.iter().map(|s| (s, s.world_from_light.inverse())).collect();
        let (nphi, ne) = (720, 720);
        let mut out = [0.0; 3];
        for i in 0..nphi {
            let phi = 2.0 * PI * (i as f64 + 0.5) / nphi as f64;
            for j in 0..ne {
                let e = FRAC_PI_2 * (j as f64 + 0.5) / ne as f64;
                let d = DVec3::new(e.cos() * phi.cos(), -e.sin(), e.cos() * phi.sin());
                let c = n.dot(d);
                if c <= 0.0 {
                    continue;
                }
                // Where the ray meets y = 0, and whether that point is on a triangle.
                let t = p.y / e.sin();
                let q = p + d * t;
                let on = mesh.indices.iter().any(|tri| {
                    let v = tri.map(|k| mesh.positions[k as usize].as_dvec3());
                    let s = |a: DVec3, b: DVec3| (b.x - a.x) * (q.z - a.z) - (b.z - a.z) * (q.x - a.x);
                    let (s0, s1, s2) = (s(v[0], v[1]), s(v[1], v[2]), s(v[2], v[0]));
                    (s0 >= 0.0 && s1 >= 0.0 && s2 >= 0.0) || (s0 <= 0.0 && s1 <= 0.0 && s2 <= 0.0)
                });
                if on {
                    continue;
                }
                let l = radiance(&light, d);
                let w = c * e.cos() * (2.0 * PI / nphi as f64) * (FRAC_PI_2 / ne as f64);
                for ch in 0..3 {
                    out[ch] += w * l[ch];
                }
            }
        }
        out
    }

    fn cases() -> Vec<(DVec3, DVec3)> {
        vec![
            (DVec3::new(0.3, 0.5, -0.2), DVec3::new(1.0, 0.0, 0.0)),
            (DVec3::new(-1.0, 1.5, 0.7), DVec3::new(0.3, -0.6, 0.5).normalize()),
            (DVec3::new(2.5, 0.2, 2.9), DVec3::new(-0.2, 0.4, -0.9).normalize()),
            (DVec3::new(0.0, 0.8, 0.0), DVec3::new(0.0, -1.0, 0.0)),
            (DVec3::new(4.0, 1.0, 0.5), DVec3::new(-1.0, 0.1, 0.0).normalize()),
        ]
    }

    /// An L-shaped (concave) outline in the plane y = 0.
    fn l_shape() -> TriangleMesh {
        quad_mesh(
            &[
                [-3.0, 0.0, -3.0],
                [-3.0, 0.0, 3.0],
                [0.0, 0.0, 3.0],
                [0.0, 0.0, 0.0],
                [3.0, 0.0, 0.0],
                [3.0, 0.0, -3.0],
                [0.0, 0.0, -3.0],
            ],
            &[[0, 1, 2], [0, 2, 3], [0, 3, 6], [6, 3, 4], [6, 4, 5]],
        )
    }

    /// A square with a square hole, in the plane y = 0.
    fn holed_square() -> TriangleMesh {
        quad_mesh(
            &[
                [-3.0, 0.0, -3.0],
                [-3.0, 0.0, 3.0],
                [3.0, 0.0, 3.0],
                [3.0, 0.0, -3.0],
                [-1.0, 0.0, -1.0],
                [-1.0, 0.0, 1.0],
                [1.0, 0.0, 1.0],
                [1.0, 0.0, -1.0],
            ],
            &[[0, 1, 5], [0, 5, 4], [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]],
        )
    }

    #[test]
    fn gap_light_matches_ray_casting() {
        // A square, an L-shaped outline (concave) and a square with a square hole.
        let (l_shape, holed) = (l_shape(), holed_square());
        let mut worst: f64 = 0.0;
        for mesh in [square(3.0), l_shape, holed] {
            for sources in [white(), gradient()] {
                let gap = HorizonGap::build(&sources, ground(), &mesh).unwrap();
                assert!(!gap.hull);
                for (p, n) in cases() {
                    let got = gap.irradiance(p, n);
                    let want = brute(&sources, &mesh, p, n);
                    for c in 0..3 {
                        // Relative to the unshadowed lower hemisphere's scale (π × radiance).
                        let err = (got[c] - want[c]).abs() / PI;
                        worst = worst.max(err);
                        assert!(err < 4e-3, "{p} {n} ch {c}: {} vs {}", got[c], want[c]);
                    }
                }
            }
        }
        eprintln!("worst |gap − ray casting| / π: {worst:.2e}");
    }

    /// `passes` against ray casting: the square, L-shaped and holed outlines, directions on a
    /// grid below (and some above) the horizon from points over and beside the planes.
    #[test]
    fn passes_agrees_with_ray_casting() {
        let on = |mesh: &TriangleMesh, q: DVec3| {
            mesh.indices.iter().any(|tri| {
                let v = tri.map(|k| mesh.positions[k as usize].as_dvec3());
                let s = |a: DVec3, b: DVec3| (b.x - a.x) * (q.z - a.z) - (b.z - a.z) * (q.x - a.x);
                let (s0, s1, s2) = (s(v[0], v[1]), s(v[1], v[2]), s(v[2], v[0]));
                (s0 >= 0.0 && s1 >= 0.0 && s2 >= 0.0) || (s0 <= 0.0 && s1 <= 0.0 && s2 <= 0.0)
            })
        };
        let (l_shape, holed) = (l_shape(), holed_square());
        let (mut tested, mut missed) = (0, 0);
        for mesh in [square(3.0), l_shape, holed] {
            let gap = HorizonGap::build(&white(), ground(), &mesh).unwrap();
            for (p, _) in cases() {
                for i in 0..97 {
                    let phi = 2.0 * PI * (i as f64 + 0.31) / 97.0;
                    for j in 0..41 {
                        let e = PI * ((j as f64 + 0.47) / 41.0 - 0.1);
                        let d = DVec3::new(e.cos() * phi.cos(), -e.sin(), e.cos() * phi.sin());
                        let want = d.y < 0.0 && !on(&mesh, p + d * (p.y / -d.y));
                        tested += 1;
                        missed += usize::from(gap.passes(p, d) != want);
                    }
                }
            }
            assert!(!gap.passes(DVec3::new(0.5, 0.0, 0.5), DVec3::new(1.0, -1.0, 0.0).normalize()));
            assert!(!gap.passes(DVec3::new(0.5, -1.0, 0.5), DVec3::new(1.0, -1.0, 0.0).normalize()));
        }
        assert_eq!(missed, 0, "{missed} of {tested} directions disagree");
    }

    #[test]
    fn closed_forms_far_from_and_under_an_endless_plane() {
        let sources = white();
        // Far outside a small plane nothing below the horizon is blocked: the cosine-weighted
        // lower half of N's hemisphere, π (1 − cos β) / 2 for N at β from the plane's normal.
        let small = square(0.01);
        let gap = HorizonGap::build(&sources, ground(), &small).unwrap();
        for beta in [0.0f64, 0.4, 1.2, FRAC_PI_2, 2.3, PI] {
            let n = DVec3::new(beta.sin(), beta.cos(), 0.0);
            let got = gap.irradiance(DVec3::new(50.0, 1.0, 20.0), n)[0];
            let want = PI * (1.0 - beta.cos()) / 2.0;
            assert!((got - want).abs() < 2e-4 * PI, "β {beta}: {got} vs {want}");
        }
        // Over a huge plane the gap closes; on the plane there is none.
        let huge = square(1e6);
        let gap = HorizonGap::build(&sources, ground(), &huge).unwrap();
        let got = gap.irradiance(DVec3::new(0.0, 1.0, 0.0), DVec3::X)[0];
        assert!(got < 1e-5, "{got}");
        assert_eq!(gap.irradiance(DVec3::new(0.0, 0.0, 0.0), DVec3::X), [0.0; 3]);
        assert_eq!(gap.irradiance(DVec3::new(0.0, -1.0, 0.0), DVec3::X), [0.0; 3]);
    }

    #[test]
    fn large_outlines_use_their_hull() {
        // A fan of many triangles around a disk: the boundary has more segments than allowed.
        let k = MAX_SEGMENTS + 10;
        let mut pts = vec![[0.0f32, 0.0, 0.0]];
        for i in 0..k {
            let a = 2.0 * std::f32::consts::PI * i as f32 / k as f32;
            pts.push([3.0 * a.cos(), 0.0, 3.0 * a.sin()]);
        }
        let tris: Vec<[u32; 3]> = (0..k as u32).map(|i| [0, 1 + (i + 1) % k as u32, 1 + i]).collect();
        let disk = quad_mesh(&pts, &tris);
        let gap = HorizonGap::build(&white(), ground(), &disk).unwrap();
        assert!(gap.hull);
        let (p, n) = (DVec3::new(0.5, 0.7, 0.2), DVec3::new(1.0, 0.0, 0.0));
        let got = gap.irradiance(p, n)[0];
        let want = brute(&white(), &disk, p, n)[0];
        assert!((got - want).abs() < 2e-3 * PI, "{got} vs {want}");
    }
}
