//! The glossy lobe's Fresnel factor: Heitz et al.'s Schlick split, or the material's exact
//! Fresnel at the LTC-weighted mean direction of the visible region (`"fresnel" "average"`),
//! with rings around the total-internal-reflection circle of a dielectric seen from its
//! dense side.

use super::region::{LightLoop, Visible};
use crate::common::ltc::{ltc_integrate_vector, LtcCoeffs};
use crate::common::params::{ParamSpec, Params};
use crate::common::spherical_polygon::{self, cone::BoundingCone};
use glam::DVec3;
use penumbra_core::geometry::Frame;
use penumbra_core::material::LtcFresnel;
use penumbra_core::spectrum::luminance;
use penumbra_core::Rgb;
use penumbra_parser::Diagnostic;

/// How the glossy lobe's Fresnel factor is applied to the LTC integral.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FresnelMode {
    /// Heitz et al.'s split: `magnitude · (F0 + (1 − F0) · fresnel)` with the material's
    /// normal-incidence reflectance `F0` (exact for Schlick's Fresnel).
    Schlick,
    /// The material's exact Fresnel at the half-vector between ωo and the visible region's
    /// LTC-weighted mean direction, per light triangle (handles pbrt-v3's plastic, whose
    /// dielectric Fresnel is not Schlick-like).
    Average,
}

impl FresnelMode {
    /// `"string fresnel"`, read by `ltc` and `ratio`.
    pub const PARAM: ParamSpec = ParamSpec::choice(
        "fresnel",
        &["average", "schlick"],
        "glossy Fresnel: the material's exact one at the visible region's mean direction, or Heitz et al.'s Schlick split",
    );

    /// Reads [`FresnelMode::PARAM`]; an unknown value warns and uses `"average"`.
    pub fn from_params(params: &Params) -> Result<FresnelMode, Diagnostic> {
        params.choice("fresnel", [FresnelMode::Average, FresnelMode::Schlick])
    }
}

/// What the average Fresnel of a region needs at one shading point.
pub(super) struct FresnelAverage<'a> {
    pub(super) fresnel: &'a LtcFresnel,
    pub(super) coeffs: &'a LtcCoeffs,
    pub(super) frame: &'a Frame<DVec3>,
    pub(super) wo_local: DVec3,
    wo_world: DVec3,
}

impl<'a> FresnelAverage<'a> {
    pub(super) fn new(
        fresnel: &'a LtcFresnel,
        coeffs: &'a LtcCoeffs,
        frame: &'a Frame<DVec3>,
        wo_local: DVec3,
    ) -> FresnelAverage<'a> {
        FresnelAverage { fresnel, coeffs, frame, wo_local, wo_world: frame.from_local(wo_local) }
    }

    /// The LTC integral's vector form factor of `loops`.
    fn ltc_of(&self, loops: &[Vec<DVec3>]) -> DVec3 {
        ltc_integrate_vector(&self.coeffs.minv, self.frame, loops)
    }

    /// The material's exact Fresnel at the half-vector between ωo and the LTC-weighted mean
    /// direction of a region (its vector form factor `vff` in the cosine space, mapped back by
    /// M: Heitz et al.'s proxy direction).
    fn fresnel_of(&self, vff: DVec3) -> Rgb {
        let dir = (self.coeffs.m() * vff).normalize_or_zero();
        let h = (self.wo_local + dir).normalize_or_zero();
        let cos_d = if h == DVec3::ZERO { 1.0 } else { self.wo_local.dot(h).clamp(0.0, 1.0) };
        fresnel_at(self.fresnel, cos_d as f32)
    }

    /// Adds to `out` the Fresnel-weighted LTC integral of the visible region `vis` of the
    /// light `light` (`v` its LTC integral, `vff` its vector form factor, oriented as `v` is).
    ///
    /// A dielectric seen from its dense side (pbrt-v3's plastic: FresnelDielectric(1.5, 1))
    /// reflects totally beyond the critical angle: F = 1 wherever ωo·ωi < t_c, a kink no single
    /// mean direction captures. The region is split along that circle (a 16-gon) when it
    /// straddles it: F = 1 outside, rings of mean-direction Fresnel inside. (Decided on the
    /// whole light, so that a shadowed point is split wherever the unshadowed one is: the same
    /// Fresnel treatment, never brighter.)
    pub(super) fn add(&self, light: &LightLoop, vis: &Visible, v: f64, vff: DVec3, out: &mut Rgb) {
        let split = tir_threshold(self.fresnel).map(|tc| {
            let rho = tc.clamp(-1.0, 1.0).acos();
            match light.cone() {
                Some(c) => match c.against_circle(self.wo_world, rho) {
                    (true, _) => TirSplit::Inside,
                    (_, true) => TirSplit::Outside,
                    _ => TirSplit::Straddles(tc),
                },
                None => TirSplit::Straddles(tc),
            }
        });
        match split {
            None | Some(TirSplit::Inside) => *out += self.fresnel_of(vff) * v as f32,
            Some(TirSplit::Outside) => *out += Rgb::splat(v as f32),
            Some(TirSplit::Straddles(tc)) => self.add_rings(tc, light, vis, v, vff, out),
        }
    }

    /// The straddling case of [`Self::add`]. Outside the critical circle F = 1. Inside, F climbs
    /// steeply towards it (from 0.04 to 1 within ~12° of θd for η = 1.5), and the Fresnel at
    /// one mean direction underestimates a region's average there (F is convex): nested
    /// circles where F = 1/2, 1/4 and 1/8 split the inside into rings, each with the Fresnel at
    /// its own LTC-weighted mean direction.
    fn add_rings(&self, tc: f64, light: &LightLoop, vis: &Visible, v: f64, vff: DVec3, out: &mut Rgb) {
        let ts = fresnel_circles(self.fresnel, tc);
        // With occluders, each ring's Fresnel is the whole light's in that ring, so that a
        // shadowed value never exceeds the unshadowed one (the mean direction of a thin ring's
        // visible part swings with the shadow).
        let light_rings = if vis.single {
            None
        } else {
            let l = positive(&light.l);
            let w = self.ltc_of(&l);
            Some(self.rings(&ts, &l, (w.z.abs(), if w.z < 0.0 { -w } else { w })))
        };
        let visible_rings = match &light_rings {
            // The light minus its part behind the occluder: ring by ring, the light's rings
            // (just taken) minus that part's, instead of the light's again.
            Some(lr) if vis.cut => {
                let mut behind = vis.loops[1].clone();
                behind.reverse();
                let behind = [behind];
                let w = self.ltc_of(&behind);
                let br = self.rings(&ts, &behind, (w.z, w));
                lr.iter().zip(&br).map(|(l, b)| ((l.0 - b.0).max(0.0), l.1 - b.1)).collect()
            }
            _ => {
                let visible = if vis.single { positive(&vis.loops[0]) } else { vis.loops.clone() };
                self.rings(&ts, &visible, (v, vff))
            }
        };
        let ring_fresnel = |k: usize, vff: DVec3| if k == 0 { Rgb::ONE } else { self.fresnel_of(vff) };
        for (k, &(vk, vffk)) in visible_rings.iter().enumerate() {
            if vk == 0.0 {
                continue;
            }
            let f = match light_rings.as_ref().and_then(|lr| lr.get(k)) {
                Some(&(lv, lvff)) if lv > 0.0 => ring_fresnel(k, lvff),
                _ => ring_fresnel(k, vffk),
            };
            *out += f * vk as f32;
        }
    }

    /// (LTC integral, vector form factor) of `region` within each ring between the circles
    /// `ts` around ωo, from the outermost (beyond the critical circle) to the innermost cap;
    /// `total` is the whole region's.
    fn rings(&self, ts: &[f64], region: &[Vec<DVec3>], total: (f64, DVec3)) -> Vec<(f64, DVec3)> {
        let all: Vec<DVec3> = region.iter().flatten().copied().collect();
        let cone = BoundingCone::of(&all);
        let mut out = Vec::with_capacity(ts.len() + 1);
        let mut outer = total;
        let mut region = region.to_vec();
        for &t in ts {
            if region.is_empty() {
                out.push((0.0, DVec3::ZERO));
                continue;
            }
            let rho = t.clamp(-1.0, 1.0).acos();
            let inner = match cone.as_ref().map(|c| c.against_circle(self.wo_world, rho)) {
                Some((true, _)) => {
                    // Wholly inside this circle: nothing in the ring (and `region` may still be
                    // the caller's loop of either orientation).
                    out.push((0.0, DVec3::ZERO));
                    continue;
                }
                Some((_, true)) => Vec::new(), // wholly outside
                // F is continuous across every circle (it reaches 1 at the critical one): a
                // 16-gon's error only moves area between rings of nearly the same F (images
                // unchanged from 64-gons to 1e-4).
                _ => clip_to_cap(&region, self.wo_world, t, 16),
            };
            let inner_total = if inner.is_empty() {
                (0.0, DVec3::ZERO)
            } else {
                let w = self.ltc_of(&inner);
                (w.z, w)
            };
            out.push(((outer.0 - inner_total.0).max(0.0), outer.1 - inner_total.1));
            outer = inner_total;
            region = inner;
        }
        out.push((outer.0.max(0.0), outer.1));
        out
    }
}

/// A single loop (either orientation) turned positive: Sutherland–Hodgman keeps each loop's
/// orientation.
fn positive(l: &[DVec3]) -> Vec<Vec<DVec3>> {
    let mut l = l.to_vec();
    if spherical_polygon::solid_angle(&l) < 0.0 {
        l.reverse();
    }
    vec![l]
}

/// Where a region lies with respect to the total-internal-reflection circle.
enum TirSplit {
    Inside,
    Outside,
    /// Carries the threshold `t_c` on `ωo·ωi`.
    Straddles(f64),
}

/// For a dielectric Fresnel seen from the dense side (`eta_i > eta_t`), the value `t_c` of
/// `ωo·ωi` below which reflection is total: `cos θd = √((1 + ωo·ωi)/2)` reaches the critical
/// `√(1 − (η_t/η_i)²)` at `t_c = 1 − 2 (η_t/η_i)²`.
pub(super) fn tir_threshold(f: &LtcFresnel) -> Option<f64> {
    match *f {
        LtcFresnel::Dielectric { eta_i, eta_t } if eta_i > eta_t && eta_t > 0.0 => {
            let r = (eta_t / eta_i) as f64;
            Some(1.0 - 2.0 * r * r)
        }
        _ => None,
    }
}

/// The critical circle `tc` and the circles where the dielectric's Fresnel is 1/2, 1/4 and 1/8,
/// increasing (memoised per thread: one material's values are needed at every shading point).
fn fresnel_circles(f: &LtcFresnel, tc: f64) -> Vec<f64> {
    thread_local! {
        static MEMO: std::cell::RefCell<Vec<(LtcFresnel, Vec<f64>)>> = const { std::cell::RefCell::new(Vec::new()) };
    }
    MEMO.with(|m| {
        if let Some((_, ts)) = m.borrow().iter().find(|(g, _)| g == f) {
            return ts.clone();
        }
        let mut ts = vec![tc];
        for y in [0.5, 0.25, 0.125] {
            if let Some(t) = fresnel_circle(f, y) {
                if t > ts[ts.len() - 1] + 1e-4 && t < 1.0 {
                    ts.push(t);
                }
            }
        }
        let mut m = m.borrow_mut();
        if m.len() >= 16 {
            m.clear();
        }
        m.push((*f, ts.clone()));
        ts
    })
}

/// For a dielectric seen from its dense side, the value `t` of `ωo·ωi` at which the Fresnel
/// reflectance (at the half-vector) equals `y` (between its normal-incidence value and 1),
/// by bisection on `cos θd` (F decreases with it); `None` otherwise.
fn fresnel_circle(f: &LtcFresnel, y: f32) -> Option<f64> {
    let tc = tir_threshold(f)?;
    let f_of = |c: f64| luminance(fresnel_at(f, c as f32));
    let (mut lo, mut hi) = (((1.0 + tc) / 2.0).max(0.0).sqrt(), 1.0f64);
    if !(f_of(hi) < y && f_of(lo) >= y) {
        return None;
    }
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if f_of(mid) >= y {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(2.0 * hi * hi - 1.0)
}

/// The part of `region` (oriented loops, each within an open hemisphere) inside the cap
/// `{ω : ω·axis ≥ t}` approximated by its inscribed `n`-gon: Sutherland–Hodgman against the
/// polygon's `n` great-circle half-spaces, exact in every additive integral and far cheaper
/// than a general overlay. Caps of a hemisphere or more (t ≤ 0.02: not convex enough) go
/// through [`spherical_polygon::intersection`].
pub(super) fn clip_to_cap(region: &[Vec<DVec3>], axis: DVec3, t: f64, n: usize) -> Vec<Vec<DVec3>> {
    clip_to_cap_inside(region, axis, t, n).0
}

/// [`clip_to_cap`], and whether every loop of `region` lay wholly inside the `n`-gon (nothing
/// cut: the result is `region` itself); always `false` for a cap of a hemisphere or more.
pub(super) fn clip_to_cap_inside(region: &[Vec<DVec3>], axis: DVec3, t: f64, n: usize) -> (Vec<Vec<DVec3>>, bool) {
    let cap = cap_loop(axis, t, n);
    if t <= 0.02 {
        return (spherical_polygon::intersection(region, &[cap]), false);
    }
    let sign = if cap[0].cross(cap[1]).dot(axis) >= 0.0 { 1.0 } else { -1.0 };
    let planes: Vec<DVec3> = (0..n).map(|i| cap[i].cross(cap[(i + 1) % n]) * sign).collect();
    let mut inside = true;
    let loops = region
        .iter()
        .filter_map(|l| {
            let (c, cut) = spherical_polygon::clip_to_halfspaces(l, planes.iter().copied());
            inside &= !cut;
            (c.len() >= 3).then_some(c)
        })
        .collect();
    (loops, inside)
}

/// The circle `{ω : ω·axis = t}` as an `n`-gon of unit directions (its arcs bow slightly
/// towards `axis`; a 16-gon covers 97.5 % of the cap's area).
fn cap_loop(axis: DVec3, t: f64, n: usize) -> Vec<DVec3> {
    thread_local! {
        /// (n, cos and sin of 2πk/n): the last polygon's angles.
        static ANGLES: std::cell::RefCell<(usize, Vec<(f64, f64)>)> = const { std::cell::RefCell::new((0, Vec::new())) };
    }
    let (u, v) = spherical_polygon::orthonormal_basis(axis);
    let r = (1.0 - t * t).max(0.0).sqrt();
    ANGLES.with(|a| {
        let mut a = a.borrow_mut();
        if a.0 != n {
            let angles = (0..n)
                .map(|k| {
                    let phi = std::f64::consts::TAU * k as f64 / n as f64;
                    (phi.cos(), phi.sin())
                })
                .collect();
            *a = (n, angles);
        }
        a.1.iter().map(|&(c, s)| axis * t + (u * c + v * s) * r).collect()
    })
}

/// The material's own Fresnel reflectance at `cos_d` (pbrt-v3's definitions).
pub fn fresnel_at(f: &LtcFresnel, cos_d: f32) -> Rgb {
    f.evaluate(cos_d)
}

/// The BRDF's integral over the visible region is `magnitude · (F0 + (1 − F0) · fresnel)` times
/// the normalised LTC integral (Heitz et al.'s Schlick split); the material's own Fresnel is
/// reduced to its normal-incidence reflectance `F0` (per channel).
pub(super) fn fresnel_weight(f: &LtcFresnel, magnitude: f32, fresnel: f32) -> Rgb {
    let f0 = match *f {
        LtcFresnel::Dielectric { eta_i, eta_t } => {
            let r = (eta_t - eta_i) / (eta_t + eta_i);
            Rgb::splat(r * r)
        }
        LtcFresnel::Conductor { eta, k } => {
            // Normal incidence from vacuum: ((η−1)² + k²) / ((η+1)² + k²).
            let one = Rgb::ONE;
            ((eta - one) * (eta - one) + k * k) / ((eta + one) * (eta + one) + k * k)
        }
        LtcFresnel::Schlick { f0 } => f0,
        LtcFresnel::NoOp => Rgb::ONE,
    };
    magnitude * (f0 + (Rgb::ONE - f0) * fresnel)
}
