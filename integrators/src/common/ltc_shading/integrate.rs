//! The integration of one light piece at one shading point: the light's spherical loop minus
//! the occluders' (after a bounding-cone cull), then the diffuse form factor and each glossy
//! lobe's integral: exact (`"glossy" "exact"`: the LTC integral plus the residual of the
//! material's own lobe by quadrature, [`crate::common::ltc::quadrature`]) or the LTC's alone
//! with its Fresnel factor (`"ltc"`).

use super::fresnel::{clip_to_cap_inside, tir_threshold, FresnelAverage, FresnelMode};
use super::region::{cull_occluders, LightLoop, Occluders, Visible};
use super::settings::{Glossy, ShaderSettings};
use crate::common::ltc::quadrature::{integrate_residual, Lobe, QuadratureStats};
use crate::common::ltc::{ltc_integrate, ltc_integrate_vector, LtcCoeffs};
use crate::common::spherical_polygon as spherical;
use glam::{DMat3, DVec3};
use penumbra_core::geometry::Frame;
use penumbra_core::material::{LtcFresnel, LtcLobe, LtcLobeKind, MAX_LOBES};
use penumbra_core::Rgb;

/// Sums over the pieces of one light: the form factor, and per lobe the LTC integral and its
/// Fresnel-weighted value (`"ltc"`) or the lobe's exact integral (`"exact"`, RGB).
#[derive(Default)]
pub(super) struct Accum {
    pub(super) diffuse_ff: f64,
    pub(super) spec_int: [f64; MAX_LOBES],
    pub(super) spec_fresnel: [Rgb; MAX_LOBES],
    pub(super) exact: [DVec3; MAX_LOBES],
    pub(super) quadrature: QuadratureStats,
}

/// A glossy lobe at a shading point with its LTC (the cosine for a lobe without a GGX warp).
#[derive(Clone, Copy)]
pub(super) struct LobeLtc {
    pub(super) lobe: LtcLobe,
    pub(super) coeffs: LtcCoeffs,
}

/// The shading point as the integration sees it: its position, shading frame (normal on
/// ωo's side), ωo in that frame and the glossy lobes with their LTCs.
pub(super) struct PieceFrame {
    pub(super) p: DVec3,
    pub(super) frame: Frame<DVec3>,
    pub(super) wo_local: DVec3,
    pub(super) lobes: Vec<LobeLtc>,
}

impl PieceFrame {
    /// The angular width (radians) of the point's sharpest lobe: `2α` for a GGX lobe, 1 for the
    /// cosine (and without glossy lobes).
    pub(super) fn lobe_width(&self) -> f64 {
        self.lobes.iter().filter_map(|l| l.lobe.ggx_alpha()).fold(1.0, |w, a| w.min(2.0 * a as f64))
    }
}

/// Relative tolerance of a lobe's quadrature on a piece (of the piece's LTC estimate), and the
/// floor (of the lobe's whole integral) under which a piece's residual is not refined.
const QUADRATURE_REL: f64 = 1e-3;
const QUADRATURE_FLOOR: f64 = 1e-5;

/// Sides of the polygon inscribed in the total-internal-reflection circle that splits a
/// dielectric lobe seen from its dense side (the slivers between it and the circle, where the
/// Fresnel factor is within a few percent of 1, are taken with F = 1).
const TIR_SIDES: usize = 64;

/// The exact integral of `lc`'s lobe over `loops` (oriented; positive loops positive), RGB.
///
/// A dielectric seen from its dense side (pbrt-v3's plastic) reflects totally beyond the
/// critical circle `ωo·ωi = t_c`, where the Fresnel factor has a kink that would make the
/// quadrature refine along it: the integral is taken as the lobe with F = 1 over the region,
/// plus the lobe's `(F − 1)` part over the region's part inside the circle (smooth there); a
/// region wholly inside the circle's inscribed polygon is integrated with F in one quadrature.
fn exact_lobe(at: &PieceFrame, lc: &LobeLtc, loops: &[Vec<DVec3>], st: &mut QuadratureStats) -> DVec3 {
    let wo = at.wo_local;
    let fresnel = lc.lobe.fresnel();
    // The lobe with its Fresnel factor in one quadrature, where the region holds no kink.
    let plain = |st: &mut QuadratureStats| {
        let e = lc.lobe.evaluator(wo);
        exact_piece(at, &lc.coeffs.minv, loops, |w| e.f_cos(w), None, st).0
    };
    let Some(tc) = tir_threshold(&fresnel) else { return plain(st) };
    let wo_world = at.frame.from_local(at.wo_local);
    let (inside, wholly_inside) = clip_to_cap_inside(loops, wo_world, tc, TIR_SIDES);
    if wholly_inside {
        return plain(st);
    }
    let one = LtcLobe { kind: LtcLobeKind::Microfacet(LtcFresnel::NoOp), ..lc.lobe }.evaluator(wo);
    let (whole, tol) = exact_piece(at, &lc.coeffs.minv, loops, |w| one.f_cos(w), None, st);
    if inside.is_empty() {
        return whole;
    }
    let below_one = |w: DVec3| {
        let f1 = one.f_cos(w);
        if f1 == DVec3::ZERO {
            return DVec3::ZERO;
        }
        let h = (wo + w).normalize_or_zero();
        f1 * (fresnel.evaluate(w.dot(h) as f32).as_dvec3() - DVec3::ONE)
    };
    // (To the whole lobe's tolerance: this part's own may be near zero.)
    whole + exact_piece(at, &lc.coeffs.minv, &inside, below_one, Some(tol), st).0
}

/// `∫ f` over `loops` with the LTC `minv`: the LTC integral times `f`'s value at the LTC's peak
/// (×π: `f`'s integral if the LTC fitted it exactly), plus the residual by adaptive quadrature
/// to the absolute tolerance `tol` (default: [`QUADRATURE_REL`] of the LTC estimate plus
/// [`QUADRATURE_FLOOR`] of the peak term); returns the integral and the tolerance used.
fn exact_piece(
    at: &PieceFrame,
    minv: &DMat3,
    loops: &[Vec<DVec3>],
    f: impl Fn(DVec3) -> DVec3,
    tol: Option<f64>,
    st: &mut QuadratureStats,
) -> (DVec3, f64) {
    let minv: DMat3 = *minv;
    let det = minv.determinant();
    if det == 0.0 || !det.is_finite() {
        return (DVec3::ZERO, tol.unwrap_or(0.0));
    }
    let m = minv.inverse();
    let peak = m * DVec3::Z;
    let l = peak.length();
    let base = f(peak / l) * (std::f64::consts::PI * det.recip().abs() / (l * l * l));
    let base = if base.is_finite() { base } else { DVec3::ZERO };
    let analytic = base * ltc_integrate(&minv, &at.frame, loops);
    let tol =
        tol.unwrap_or(QUADRATURE_REL * analytic.abs().max_element() + QUADRATURE_FLOOR * base.abs().max_element());
    (analytic + integrate_residual(&Lobe { minv: &minv, base, f }, &at.frame, loops, tol, st), tol)
}

/// Adds the diffuse form factor and each glossy lobe's integral (as `settings` says: exact, or
/// the LTC's with its Fresnel treatment) of the part of the light piece `piece` (world
/// positions) not covered by the `occ` loops.
pub(super) fn integrate_piece(
    settings: &ShaderSettings,
    at: &PieceFrame,
    piece: &[DVec3],
    mut occ: Occluders,
    acc: &mut Accum,
) {
    // pbrt-v3's reflection lobes are zero below the shading horizon, while a wide LTC (α of
    // 1 and more, seen at a slant) reaches under it: the light is cut at the horizon before
    // anything is integrated (the form factor clips there too), so that neither the LTC nor
    // the quadrature's residual sees what lies below.
    let Some(light) = above_horizon(spherical::project(at.p, piece), at.frame.from_local(DVec3::Z)) else {
        return;
    };
    let light = LightLoop::new(light);
    cull_occluders(&mut occ, &light);
    let vis = Visible::of(&light, &occ);
    // The diffuse form factor in the shading frame, then the LTC integral together with
    // its vector form factor (one pass over the edges for both).
    let ff: f64 =
        vis.loops.iter().map(|l| spherical::horizon_vector_form_factor(l.len(), |i| at.frame.to_local(l[i])).z).sum();
    acc.diffuse_ff += if vis.single { ff.abs() } else { ff };
    if at.lobes.is_empty() {
        return;
    }
    if settings.glossy == Glossy::Exact {
        // A single loop may have either orientation: turned positive.
        let positive;
        let loops = if vis.single && spherical::solid_angle(&vis.loops[0]) < 0.0 {
            positive = vec![vis.loops[0].iter().rev().copied().collect::<Vec<_>>()];
            &positive
        } else {
            &vis.loops
        };
        for (k, lc) in at.lobes.iter().enumerate() {
            acc.exact[k] += exact_lobe(at, lc, loops, &mut acc.quadrature);
        }
        return;
    }
    for (k, lc) in at.lobes.iter().enumerate() {
        let coeffs = &lc.coeffs;
        let lv = ltc_integrate_vector(&coeffs.minv, &at.frame, &vis.loops);
        let v = if vis.single { lv.z.abs() } else { lv.z };
        acc.spec_int[k] += v;
        if settings.fresnel == FresnelMode::Average && v != 0.0 {
            // The region's LTC-space vector form factor (additive over regions), oriented as
            // its integral is taken.
            let vff = if vis.single && lv.z < 0.0 { -lv } else { lv };
            let fresnel = lc.lobe.fresnel();
            FresnelAverage::new(&fresnel, coeffs, &at.frame, at.wo_local).add(
                &light,
                &vis,
                v,
                vff,
                &mut acc.spec_fresnel[k],
            );
        }
    }
}

/// The loop `l` (unit directions) cut to the half-space `d·n ≥ 0` (unchanged when wholly in it;
/// `None` when nothing is left).
fn above_horizon(l: Vec<DVec3>, n: DVec3) -> Option<Vec<DVec3>> {
    if l.iter().all(|d| d.dot(n) >= 0.0) {
        return Some(l);
    }
    let c = spherical::clip_to_halfspace(&l, n);
    (!c.is_empty()).then_some(c)
}
