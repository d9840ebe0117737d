//! The integration of one light piece at one shading point: the light's spherical loop minus
//! the occluders' (after a bounding-cone cull), then the diffuse form factor and the glossy
//! lobe's LTC integral with its Fresnel factor.

use super::fresnel::{FresnelAverage, FresnelMode};
use super::occluders::Occluders;
use super::LtcShader;
use glam::DVec3;
use penumbra_core::geometry::Frame;
use penumbra_core::ltc::{ltc_integrate_vector, LtcCoeffs};
use penumbra_core::material::LtcSpecular;
use penumbra_core::spherical::{self, cone::BoundingCone};
use penumbra_core::Rgb;
use std::cell::OnceCell;

/// Sums over the pieces of one light.
#[derive(Default)]
pub(super) struct Accum {
    pub(super) diffuse_ff: f64,
    pub(super) spec_int: f64,
    pub(super) spec_fresnel: Rgb,
}

/// The shading point as the integration sees it: its position, shading frame (normal on
/// ωo's side), ωo in that frame and the glossy lobe with its LTC.
pub(super) struct PieceFrame {
    pub(super) p: DVec3,
    pub(super) frame: Frame<DVec3>,
    pub(super) wo_local: DVec3,
    pub(super) spec: Option<(LtcSpecular, LtcCoeffs)>,
}

/// A light piece seen from the shading point, with its bounding cone computed when first
/// needed (for the occluder cull and the Fresnel split).
pub(super) struct LightLoop {
    pub(super) l: Vec<DVec3>,
    cone: OnceCell<Option<BoundingCone>>,
}

impl LightLoop {
    fn new(l: Vec<DVec3>) -> LightLoop {
        LightLoop { l, cone: OnceCell::new() }
    }

    pub(super) fn cone(&self) -> Option<BoundingCone> {
        *self.cone.get_or_init(|| BoundingCone::of(&self.l))
    }
}

/// The visible part of a light piece.
pub(super) struct Visible {
    /// Oriented loops; with `single`, the light's own loop, of either orientation (its
    /// integrals are taken by magnitude).
    pub(super) loops: Vec<Vec<DVec3>>,
    pub(super) single: bool,
    /// `loops` is `[light⁺, −(light⁺ ∩ occluder)]` (one convex occluder).
    pub(super) cut: bool,
}

impl Visible {
    fn unoccluded(light: &LightLoop) -> Visible {
        Visible { loops: vec![light.l.clone()], single: true, cut: false }
    }

    /// The light minus the occluders. One convex occluder loop (a convex object's silhouette,
    /// a triangle) — most occluded points of most scenes — is clipped against directly;
    /// anything else goes through the planar Boolean.
    fn of(light: &LightLoop, occ: &Occluders) -> Visible {
        if occ.is_empty() {
            return Visible::unoccluded(light);
        }
        let light_loops = std::slice::from_ref(&light.l);
        match (&occ.loops[..], occ.chains.is_empty()) {
            ([o], true) => match spherical::difference_convex(&light.l, o) {
                // Missed after all (the cones overlapped): the light's own loop, as unoccluded.
                Some(v) if v.len() == 1 => Visible::unoccluded(light),
                Some(v) => {
                    let cut = v.len() == 2;
                    Visible { loops: v, single: false, cut }
                }
                None => Visible { loops: spherical::difference(light_loops, &occ.loops), single: false, cut: false },
            },
            _ => {
                let v = spherical::difference_chains(light_loops, &occ.loops, &occ.chains);
                Visible { loops: v, single: false, cut: false }
            }
        }
    }
}

/// Keeps only occluder loops whose bounding cone meets the light's: most shading points see
/// most lights unoccluded and then need no polygon clipping at all. (A chain's covered region
/// lies within its vertices' cone too: dropping one of its loops changes the winding only
/// outside the light.)
fn cull_occluders(occ: &mut Occluders, light: &LightLoop) {
    if occ.is_empty() {
        return;
    }
    if let Some(lc) = light.cone() {
        occ.loops.retain(|o| BoundingCone::of(o).is_none_or(|oc| oc.overlaps(&lc)));
        occ.chains.retain(|o| BoundingCone::of(o).is_none_or(|oc| oc.overlaps(&lc)));
    }
}

impl LtcShader<'_> {
    /// Adds the diffuse form factor and the LTC integrals of the part of the light piece
    /// `piece` (world positions) not covered by the `occ` loops.
    pub(super) fn integrate_piece(&self, at: &PieceFrame, piece: &[DVec3], mut occ: Occluders, acc: &mut Accum) {
        let light = LightLoop::new(spherical::project(at.p, piece));
        cull_occluders(&mut occ, &light);
        let vis = Visible::of(&light, &occ);
        // The diffuse form factor in the shading frame, then the LTC integral together with
        // its vector form factor (one pass over the edges for both).
        let ff: f64 = vis
            .loops
            .iter()
            .map(|l| spherical::horizon_vector_form_factor(l.len(), |i| at.frame.to_local(l[i])).z)
            .sum();
        acc.diffuse_ff += if vis.single { ff.abs() } else { ff };
        let Some((s, coeffs)) = &at.spec else { return };
        let lv = ltc_integrate_vector(&coeffs.minv, &at.frame, &vis.loops);
        let v = if vis.single { lv.z.abs() } else { lv.z };
        acc.spec_int += v;
        if self.ltc.fresnel == FresnelMode::Average && v != 0.0 {
            // The region's LTC-space vector form factor (additive over regions), oriented as
            // its integral is taken.
            let vff = if vis.single && lv.z < 0.0 { -lv } else { lv };
            FresnelAverage::new(&s.fresnel, coeffs, &at.frame, at.wo_local).add(
                &light,
                &vis,
                v,
                vff,
                &mut acc.spec_fresnel,
            );
        }
    }
}
