//! The orientation predicate the contour test is decided by.
//!
//! `orient3d(a, b, c, d)` is the sign of `det[a−d, b−d, c−d]`: positive when `d` sees the
//! triangle `a b c` clockwise (it lies on the side of the plane opposite to `(b−a)×(c−a)`).
//! A double-precision evaluation decides when it is farther from zero than Shewchuk's
//! static bound (`o3derrboundA`); otherwise the determinant is evaluated again in
//! double-double arithmetic (differences exactly as two-term sums, products by FMA), which
//! decides everything but configurations within ~1e-30 of the permanent of being coplanar;
//! those are reported as coplanar (0). Every caller (the hierarchy's leaf test and the
//! brute-force oracle) uses this one function, so they agree exactly.

use glam::DVec3;

const EPS: f64 = f64::EPSILON * 0.5;
/// Shewchuk's `o3derrboundA`.
const ERR_A: f64 = (7.0 + 56.0 * EPS) * EPS;

/// Sign of `det[a−d, b−d, c−d]` (−1, 0, 1).
pub fn orient3d(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> i8 {
    let (ad, bd, cd) = (a - d, b - d, c - d);
    let bc = bd.y * cd.z - bd.z * cd.y;
    let ca = cd.y * ad.z - cd.z * ad.y;
    let ab = ad.y * bd.z - ad.z * bd.y;
    let det = ad.x * bc + bd.x * ca + cd.x * ab;
    let permanent = ((bd.y * cd.z).abs() + (bd.z * cd.y).abs()) * ad.x.abs()
        + ((cd.y * ad.z).abs() + (cd.z * ad.y).abs()) * bd.x.abs()
        + ((ad.y * bd.z).abs() + (ad.z * bd.y).abs()) * cd.x.abs();
    if det.abs() > ERR_A * permanent {
        return sign(det);
    }
    if permanent == 0.0 {
        return 0;
    }
    let dd = |p: DVec3| [Dd::diff(p.x, d.x), Dd::diff(p.y, d.y), Dd::diff(p.z, d.z)];
    let (ad, bd, cd) = (dd(a), dd(b), dd(c));
    let minor = |u: &[Dd; 3], v: &[Dd; 3], i: usize, j: usize| u[i].mul(v[j]).sub(u[j].mul(v[i]));
    let det =
        ad[0].mul(minor(&bd, &cd, 1, 2)).add(bd[0].mul(minor(&cd, &ad, 1, 2))).add(cd[0].mul(minor(&ad, &bd, 1, 2)));
    let v = det.hi + det.lo;
    if v.abs() > 1e-30 * permanent {
        sign(v)
    } else {
        0
    }
}

fn sign(v: f64) -> i8 {
    if v > 0.0 {
        1
    } else if v < 0.0 {
        -1
    } else {
        0
    }
}

/// A double-double number `hi + lo`, `|lo| ≤ ulp(hi)/2`.
#[derive(Clone, Copy, Debug)]
struct Dd {
    hi: f64,
    lo: f64,
}

impl Dd {
    fn two_sum(a: f64, b: f64) -> Dd {
        let s = a + b;
        let bb = s - a;
        Dd { hi: s, lo: (a - (s - bb)) + (b - bb) }
    }
    fn diff(a: f64, b: f64) -> Dd {
        Dd::two_sum(a, -b)
    }
    fn add(self, o: Dd) -> Dd {
        let s = Dd::two_sum(self.hi, o.hi);
        let lo = s.lo + self.lo + o.lo;
        Dd::two_sum(s.hi, lo)
    }
    fn sub(self, o: Dd) -> Dd {
        self.add(Dd { hi: -o.hi, lo: -o.lo })
    }
    fn mul(self, o: Dd) -> Dd {
        let p = self.hi * o.hi;
        let e = self.hi.mul_add(o.hi, -p);
        let lo = e + (self.hi * o.lo + self.lo * o.hi);
        Dd::two_sum(p, lo)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signs_of_simple_configurations() {
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        // (b−a)×(c−a) = +z: a point above sees the triangle counter-clockwise.
        assert_eq!(orient3d(a, b, c, DVec3::new(0.2, 0.2, 1.0)), -1);
        assert_eq!(orient3d(a, b, c, DVec3::new(0.2, 0.2, -1.0)), 1);
        assert_eq!(orient3d(a, b, c, DVec3::new(5.0, -3.0, 0.0)), 0);
    }

    /// Points displaced from a plane by one ulp-scale step: the f64 determinant is pure
    /// rounding there, the double-double one still sees the side (checked against a
    /// displacement large enough for plain f64).
    #[test]
    fn near_coplanar_points_get_the_side_of_their_displacement() {
        let a = DVec3::new(0.1, 0.2, 0.3);
        let b = DVec3::new(1.7, -0.4, 0.9);
        let c = DVec3::new(-0.6, 1.3, 0.2);
        let n = (b - a).cross(c - a);
        let mut rng = 0x9e3779b97f4a7c15u64;
        let mut next = || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut checked = 0;
        for _ in 0..2000 {
            let (s, t) = (next() * 3.0 - 1.0, next() * 3.0 - 1.0);
            let on = a + s * (b - a) + t * (c - a);
            for k in [1e-13, -1e-13, 1e-9, -1e-9] {
                let d = on + n * k;
                // The exact side of `d` (the plane through rounded a, b, c): the sign of the
                // displacement, as long as the rounding of `on` (≲ 1e-16) is smaller.
                let expected = if k > 0.0 { -1 } else { 1 };
                assert_eq!(orient3d(a, b, c, d), expected, "{d:?} at {k}");
                checked += 1;
            }
        }
        assert_eq!(checked, 8000);
    }
}
