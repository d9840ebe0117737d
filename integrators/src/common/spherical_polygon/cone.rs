//! Cones of directions bounding spherical loops: a cheap overlap test before any polygon
//! clipping (most shading points see most lights unoccluded).

use glam::DVec3;

/// A cone of directions containing a loop: unit `axis` and the half-angle's cosine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundingCone {
    pub axis: DVec3,
    pub cos: f64,
}

impl BoundingCone {
    /// The cone around the loop `l` (directions, any length) along the mean of its unit
    /// vertices; `None` when the loop is too wide for a useful cone (beyond ~90°).
    pub fn of(l: &[DVec3]) -> Option<BoundingCone> {
        let sum: DVec3 = l.iter().map(|d| d.normalize_or_zero()).sum();
        let axis = sum.normalize_or_zero();
        if axis == DVec3::ZERO {
            return None;
        }
        // The loop's arcs bulge at most to their endpoints' great circles; for loops within a
        // hemisphere around `axis` the vertex bound holds for the arcs when every vertex is
        // within 90° of the axis (minor arcs between two points of a cap stay in the cap).
        let cos = l.iter().map(|d| d.normalize_or_zero().dot(axis)).fold(1.0, f64::min);
        (cos > 1e-3).then_some(BoundingCone { axis, cos })
    }

    /// Whether the two cones may share a direction (angle between the axes below the sum of
    /// the half-angles, with a margin of 1e-6 rad).
    pub fn overlaps(&self, o: &BoundingCone) -> bool {
        let (a, b) = (self.cos.clamp(-1.0, 1.0).acos(), o.cos.clamp(-1.0, 1.0).acos());
        self.axis.dot(o.axis).clamp(-1.0, 1.0).acos() < a + b + 1e-6
    }

    /// Where the cone lies with respect to the circle `{ω : ω·w = cos ρ}` (angle `rho` around
    /// the unit `w`): `(wholly inside, wholly outside)`.
    pub fn against_circle(&self, w: DVec3, rho: f64) -> (bool, bool) {
        let gamma = self.axis.dot(w).clamp(-1.0, 1.0).acos();
        let beta = self.cos.clamp(-1.0, 1.0).acos();
        (gamma + beta < rho, gamma - beta > rho)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cone_contains_its_loop_and_overlap_is_angular() {
        let l = [DVec3::new(1.0, 0.1, 0.0), DVec3::new(1.0, -0.1, 0.1), DVec3::new(1.0, 0.0, -0.1)];
        let c = BoundingCone::of(&l).unwrap();
        for d in l {
            assert!(d.normalize().dot(c.axis) >= c.cos - 1e-12);
        }
        // The same loop turned by 90° about z: axes ~90° apart, half-angles ~0.1 rad.
        let turned: Vec<DVec3> = l.iter().map(|d| DVec3::new(-d.y, d.x, d.z)).collect();
        let t = BoundingCone::of(&turned).unwrap();
        assert!(!c.overlaps(&t) && c.overlaps(&c));
        // A loop around the whole equator has no useful cone.
        let eq: Vec<DVec3> = (0..8)
            .map(|k| {
                let phi = std::f64::consts::FRAC_PI_4 * k as f64;
                DVec3::new(phi.cos(), phi.sin(), 0.0)
            })
            .collect();
        assert!(BoundingCone::of(&eq).is_none());
        let (inside, outside) = c.against_circle(DVec3::X, 0.5);
        assert!(inside && !outside);
        let (inside, outside) = c.against_circle(DVec3::Y, 0.5);
        assert!(!inside && outside);
    }
}
