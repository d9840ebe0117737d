//! The integration of one light piece at one shading point: the light's spherical loop minus
//! the occluders' (after a bounding-cone cull), then the diffuse form factor and the glossy
//! lobe's LTC integral with its Fresnel factor.

use super::fresnel::{FresnelAverage, FresnelMode};
use super::region::{cull_occluders, LightLoop, Occluders, Visible};
use crate::common::ltc::{ltc_integrate_vector, LtcCoeffs};
use crate::common::spherical_polygon;
use glam::DVec3;
use penumbra_core::geometry::Frame;
use penumbra_core::material::LtcSpecular;
use penumbra_core::Rgb;

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

/// Adds the diffuse form factor and the LTC integrals of the part of the light piece `piece`
/// (world positions) not covered by the `occ` loops, the glossy lobe's Fresnel applied as
/// `fresnel` says.
pub(super) fn integrate_piece(
    fresnel: FresnelMode,
    at: &PieceFrame,
    piece: &[DVec3],
    mut occ: Occluders,
    acc: &mut Accum,
) {
    let light = LightLoop::new(spherical_polygon::project(at.p, piece));
    cull_occluders(&mut occ, &light);
    let vis = Visible::of(&light, &occ);
    // The diffuse form factor in the shading frame, then the LTC integral together with
    // its vector form factor (one pass over the edges for both).
    let ff: f64 = vis
        .loops
        .iter()
        .map(|l| spherical_polygon::horizon_vector_form_factor(l.len(), |i| at.frame.to_local(l[i])).z)
        .sum();
    acc.diffuse_ff += if vis.single { ff.abs() } else { ff };
    let Some((s, coeffs)) = &at.spec else { return };
    let lv = ltc_integrate_vector(&coeffs.minv, &at.frame, &vis.loops);
    let v = if vis.single { lv.z.abs() } else { lv.z };
    acc.spec_int += v;
    if fresnel == FresnelMode::Average && v != 0.0 {
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
