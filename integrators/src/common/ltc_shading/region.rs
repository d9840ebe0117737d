//! A light piece and what hides it, as spherical loops seen from the shading point: the
//! light's loop (with its bounding cone), the occluders' loops and chains, and the visible
//! region (the light minus the occluders).

use crate::common::spherical_polygon::{self, cone::BoundingCone};
use glam::DVec3;
use std::cell::OnceCell;

/// What may hide a light piece from the shading point, projected: loops each covering a
/// region of its own, and chains covering by winding number (outlines of adjacent triangles).
#[derive(Default)]
pub(super) struct Occluders {
    pub(super) loops: Vec<Vec<DVec3>>,
    pub(super) chains: Vec<Vec<DVec3>>,
}

impl Occluders {
    pub(super) fn is_empty(&self) -> bool {
        self.loops.is_empty() && self.chains.is_empty()
    }
}

/// A light piece seen from the shading point, with its bounding cone computed when first
/// needed (for the occluder cull and the Fresnel split).
pub(super) struct LightLoop {
    pub(super) l: Vec<DVec3>,
    cone: OnceCell<Option<BoundingCone>>,
}

impl LightLoop {
    pub(super) fn new(l: Vec<DVec3>) -> LightLoop {
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
    pub(super) fn of(light: &LightLoop, occ: &Occluders) -> Visible {
        if occ.is_empty() {
            return Visible::unoccluded(light);
        }
        let light_loops = std::slice::from_ref(&light.l);
        match (&occ.loops[..], occ.chains.is_empty()) {
            ([o], true) => match spherical_polygon::difference_convex(&light.l, o) {
                // Missed after all (the cones overlapped): the light's own loop, as unoccluded.
                Some(v) if v.len() == 1 => Visible::unoccluded(light),
                Some(v) => {
                    let cut = v.len() == 2;
                    Visible { loops: v, single: false, cut }
                }
                None => {
                    Visible { loops: spherical_polygon::difference(light_loops, &occ.loops), single: false, cut: false }
                }
            },
            _ => {
                let v = spherical_polygon::difference_chains(light_loops, &occ.loops, &occ.chains);
                Visible { loops: v, single: false, cut: false }
            }
        }
    }
}

/// Keeps only occluder loops whose bounding cone meets the light's: most shading points see
/// most lights unoccluded and then need no polygon clipping at all. (A chain's covered region
/// lies within its vertices' cone too: dropping one of its loops changes the winding only
/// outside the light.)
pub(super) fn cull_occluders(occ: &mut Occluders, light: &LightLoop) {
    if occ.is_empty() {
        return;
    }
    if let Some(lc) = light.cone() {
        occ.loops.retain(|o| BoundingCone::of(o).is_none_or(|oc| oc.overlaps(&lc)));
        occ.chains.retain(|o| BoundingCone::of(o).is_none_or(|oc| oc.overlaps(&lc)));
    }
}
