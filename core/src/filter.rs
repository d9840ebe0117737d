//! Pixel reconstruction filters with pbrt-v3's parameters, default radii and formulas.

use glam::Vec2;
use penumbra_parser::{Entity, FileLoc};
use std::f32::consts::PI;

/// A separable-or-not reconstruction filter centred at the origin, zero outside `radius`.
pub trait Filter: Send + Sync {
    fn radius(&self) -> Vec2;
    fn evaluate(&self, p: Vec2) -> f32;
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FilterError {
    #[error("{loc}: filter \"{name}\" unknown (valid filters: {valid})")]
    Unknown { name: String, loc: FileLoc, valid: String },
    #[error("{loc}: filter \"{filter}\": invalid \"{param}\" {value}: {reason}")]
    InvalidParameter { filter: String, param: String, value: f32, reason: String, loc: FileLoc },
}

/// The names `create_filter` accepts.
pub const FILTER_NAMES: [&str; 5] = ["box", "gaussian", "mitchell", "sinc", "triangle"];

fn inside(p: Vec2, r: Vec2) -> bool {
    p.x.abs() <= r.x && p.y.abs() <= r.y
}

/// Constant 1 over the box |x| ≤ rx, |y| ≤ ry (edges included, as pbrt-v3's film does).
#[derive(Clone, Debug)]
pub struct BoxFilter {
    pub radius: Vec2,
}

impl Filter for BoxFilter {
    fn radius(&self) -> Vec2 {
        self.radius
    }
    fn evaluate(&self, p: Vec2) -> f32 {
        if inside(p, self.radius) {
            1.0
        } else {
            0.0
        }
    }
}

/// (rx − |x|)(ry − |y|), clamped at 0.
#[derive(Clone, Debug)]
pub struct TriangleFilter {
    pub radius: Vec2,
}

impl Filter for TriangleFilter {
    fn radius(&self) -> Vec2 {
        self.radius
    }
    fn evaluate(&self, p: Vec2) -> f32 {
        (self.radius.x - p.x.abs()).max(0.0) * (self.radius.y - p.y.abs()).max(0.0)
    }
}

/// exp(−α x²) − exp(−α rx²) per axis (clamped at 0), so that the filter reaches 0 at its radius.
#[derive(Clone, Debug)]
pub struct GaussianFilter {
    pub radius: Vec2,
    pub alpha: f32,
    exp_x: f32,
    exp_y: f32,
}

impl GaussianFilter {
    pub fn new(radius: Vec2, alpha: f32) -> Self {
        GaussianFilter {
            radius,
            alpha,
            exp_x: (-alpha * radius.x * radius.x).exp(),
            exp_y: (-alpha * radius.y * radius.y).exp(),
        }
    }
    fn gaussian(&self, d: f32, expv: f32) -> f32 {
        ((-self.alpha * d * d).exp() - expv).max(0.0)
    }
}

impl Filter for GaussianFilter {
    fn radius(&self) -> Vec2 {
        self.radius
    }
    fn evaluate(&self, p: Vec2) -> f32 {
        if !inside(p, self.radius) {
            return 0.0;
        }
        self.gaussian(p.x, self.exp_x) * self.gaussian(p.y, self.exp_y)
    }
}

/// Mitchell–Netravali cubic with parameters B and C, stretched so that its support [−2, 2] maps to the radius.
#[derive(Clone, Debug)]
pub struct MitchellFilter {
    pub radius: Vec2,
    pub b: f32,
    pub c: f32,
}

impl MitchellFilter {
    /// The 1D cubic at `x` ∈ [−1, 1] (in units of the radius).
    fn mitchell_1d(&self, x: f32) -> f32 {
        let (b, c) = (self.b, self.c);
        let x = (2.0 * x).abs();
        let v = if x > 1.0 {
            (-b - 6.0 * c) * x * x * x
                + (6.0 * b + 30.0 * c) * x * x
                + (-12.0 * b - 48.0 * c) * x
                + (8.0 * b + 24.0 * c)
        } else {
            (12.0 - 9.0 * b - 6.0 * c) * x * x * x + (-18.0 + 12.0 * b + 6.0 * c) * x * x + (6.0 - 2.0 * b)
        };
        v * (1.0 / 6.0)
    }
}

impl Filter for MitchellFilter {
    fn radius(&self) -> Vec2 {
        self.radius
    }
    fn evaluate(&self, p: Vec2) -> f32 {
        if !inside(p, self.radius) {
            return 0.0;
        }
        self.mitchell_1d(p.x / self.radius.x) * self.mitchell_1d(p.y / self.radius.y)
    }
}

/// pbrt-v3's "sinc": sinc(x) windowed by the Lanczos window sinc(x / τ), per axis, zero beyond the radius.
#[derive(Clone, Debug)]
pub struct LanczosSincFilter {
    pub radius: Vec2,
    pub tau: f32,
}

fn sinc(x: f32) -> f32 {
    let x = x.abs();
    if x < 1e-5 {
        1.0
    } else {
        (PI * x).sin() / (PI * x)
    }
}

impl LanczosSincFilter {
    fn windowed_sinc(&self, x: f32, radius: f32) -> f32 {
        let x = x.abs();
        if x > radius {
            return 0.0;
        }
        sinc(x) * sinc(x / self.tau)
    }
}

impl Filter for LanczosSincFilter {
    fn radius(&self) -> Vec2 {
        self.radius
    }
    fn evaluate(&self, p: Vec2) -> f32 {
        self.windowed_sinc(p.x, self.radius.x) * self.windowed_sinc(p.y, self.radius.y)
    }
}

/// Builds the filter of a `PixelFilter` directive (parameters `xwidth`, `ywidth` — radii, as in
/// pbrt-v3 — plus `alpha` for gaussian, `B`/`C` for mitchell, `tau` for sinc). Does not report unused
/// parameters (the caller does).
pub fn create_filter(entity: &Entity) -> Result<Box<dyn Filter>, FilterError> {
    let ps = &entity.params;
    let (default_r, name) = match entity.kind.as_str() {
        "box" => (0.5, "box"),
        "triangle" => (2.0, "triangle"),
        "gaussian" => (2.0, "gaussian"),
        "mitchell" => (2.0, "mitchell"),
        "sinc" => (4.0, "sinc"),
        other => {
            return Err(FilterError::Unknown {
                name: other.to_string(),
                loc: entity.loc.clone(),
                valid: FILTER_NAMES.join(", "),
            })
        }
    };
    let param = |key: &str, default: f32, positive: bool| -> Result<f32, FilterError> {
        let v = ps.get_one_float(key, default);
        let ok = v.is_finite() && if positive { v > 0.0 } else { true };
        if ok {
            Ok(v)
        } else {
            Err(FilterError::InvalidParameter {
                filter: name.to_string(),
                param: key.to_string(),
                value: v,
                reason: if positive { "must be a finite positive number".into() } else { "must be finite".into() },
                loc: ps.loc_of(key).cloned().unwrap_or_else(|| entity.loc.clone()),
            })
        }
    };
    let radius = Vec2::new(param("xwidth", default_r, true)?, param("ywidth", default_r, true)?);
    Ok(match name {
        "box" => Box::new(BoxFilter { radius }),
        "triangle" => Box::new(TriangleFilter { radius }),
        "gaussian" => Box::new(GaussianFilter::new(radius, param("alpha", 2.0, false)?)),
        "mitchell" => {
            Box::new(MitchellFilter { radius, b: param("B", 1.0 / 3.0, false)?, c: param("C", 1.0 / 3.0, false)? })
        }
        _ => Box::new(LanczosSincFilter { radius, tau: param("tau", 3.0, true)? }),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use penumbra_parser::{Param, ParamSet, ParamValue};

    fn make(kind: &str, params: &[(&str, f32)]) -> Result<Box<dyn Filter>, FilterError> {
        let mut ps = ParamSet::new();
        for (k, v) in params {
            ps.add(Param::new(*k, ParamValue::Float(vec![*v]), FileLoc::builtin()));
        }
        create_filter(&Entity::new(kind, ps, FileLoc::builtin()))
    }

    const POINTS: [(f32, f32); 7] =
        [(0.0, 0.0), (0.3, -0.2), (-1.1, 0.7), (1.9, 1.2), (0.49, -0.5), (2.5, 0.1), (3.7, -3.9)];

    fn close(a: f32, b: f64) -> bool {
        (a as f64 - b).abs() <= 1e-5 * (1.0 + b.abs())
    }

    #[test]
    fn defaults_radii() {
        for (k, r) in [("box", 0.5), ("triangle", 2.0), ("gaussian", 2.0), ("mitchell", 2.0), ("sinc", 4.0)] {
            assert_eq!(make(k, &[]).unwrap().radius(), Vec2::splat(r), "{k}");
        }
        let f = make("gaussian", &[("xwidth", 1.5), ("ywidth", 3.0)]).unwrap();
        assert_eq!(f.radius(), Vec2::new(1.5, 3.0));
    }

    #[test]
    fn box_filter() {
        let f = make("box", &[]).unwrap();
        for (x, y) in POINTS {
            let expect = if x.abs() <= 0.5 && y.abs() <= 0.5 { 1.0 } else { 0.0 };
            assert_eq!(f.evaluate(Vec2::new(x, y)), expect, "({x},{y})");
        }
        assert_eq!(f.evaluate(Vec2::new(0.5, -0.5)), 1.0);
        assert_eq!(f.evaluate(Vec2::new(0.5001, 0.0)), 0.0);
    }

    #[test]
    fn triangle_filter() {
        let f = make("triangle", &[]).unwrap();
        for (x, y) in POINTS {
            let e = (2.0 - (x as f64).abs()).max(0.0) * (2.0 - (y as f64).abs()).max(0.0);
            assert!(close(f.evaluate(Vec2::new(x, y)), e), "({x},{y})");
        }
        assert_eq!(f.evaluate(Vec2::new(0.0, 0.0)), 4.0);
    }

    #[test]
    fn gaussian_filter() {
        let f = make("gaussian", &[]).unwrap();
        let g = |d: f64| ((-2.0 * d * d).exp() - (-8.0f64).exp()).max(0.0);
        for (x, y) in POINTS {
            let e = if x.abs() <= 2.0 && y.abs() <= 2.0 { g(x as f64) * g(y as f64) } else { 0.0 };
            assert!(close(f.evaluate(Vec2::new(x, y)), e), "({x},{y}) {} {e}", f.evaluate(Vec2::new(x, y)));
        }
        assert_eq!(f.evaluate(Vec2::new(2.0, 0.0)), 0.0);
        let f = make("gaussian", &[("alpha", 0.5), ("xwidth", 3.0)]).unwrap();
        let e = ((-0.5f64).exp() - (-4.5f64).exp()) * (1.0 - (-2.0f64).exp());
        assert!(close(f.evaluate(Vec2::new(1.0, 0.0)), e));
    }

    #[test]
    fn mitchell_filter() {
        // The Mitchell–Netravali kernel k(t) on t ∈ [0, 2], written from the paper's piecewise form.
        fn k(t: f64, b: f64, c: f64) -> f64 {
            let t = t.abs();
            let v = if t < 1.0 {
                (12.0 - 9.0 * b - 6.0 * c) * t.powi(3) + (-18.0 + 12.0 * b + 6.0 * c) * t * t + (6.0 - 2.0 * b)
            } else if t < 2.0 {
                (-b - 6.0 * c) * t.powi(3)
                    + (6.0 * b + 30.0 * c) * t * t
                    + (-12.0 * b - 48.0 * c) * t
                    + (8.0 * b + 24.0 * c)
            } else {
                0.0
            };
            v / 6.0
        }
        let f = make("mitchell", &[]).unwrap();
        let third = 1.0 / 3.0;
        for (x, y) in POINTS {
            // Radius 2 maps to t = 2: t = 2 x / r = x.
            let e = k(x as f64, third, third) * k(y as f64, third, third);
            assert!(close(f.evaluate(Vec2::new(x, y)), e), "({x},{y}) {} {e}", f.evaluate(Vec2::new(x, y)));
        }
        assert!(close(f.evaluate(Vec2::ZERO), ((6.0 - 2.0 * third) / 6.0f64).powi(2)));
        let f = make("mitchell", &[("B", 0.0), ("C", 0.5), ("xwidth", 1.0), ("ywidth", 1.0)]).unwrap();
        for (x, y) in [(0.3f32, 0.1f32), (0.75, -0.6), (1.2, 0.0)] {
            let e = k(2.0 * x as f64, 0.0, 0.5) * k(2.0 * y as f64, 0.0, 0.5);
            assert!(close(f.evaluate(Vec2::new(x, y)), e), "({x},{y})");
        }
    }

    #[test]
    fn sinc_filter() {
        let s =
            |x: f64| if x.abs() < 1e-5 { 1.0 } else { (std::f64::consts::PI * x).sin() / (std::f64::consts::PI * x) };
        let w = |x: f64| if x.abs() > 4.0 { 0.0 } else { s(x) * s(x / 3.0) };
        let f = make("sinc", &[]).unwrap();
        for (x, y) in POINTS.iter().copied().chain([(4.2, 0.0), (1.5, 2.5)]) {
            let e = w(x as f64) * w(y as f64);
            assert!((f.evaluate(Vec2::new(x, y)) as f64 - e).abs() < 1e-5, "({x},{y})");
        }
        assert_eq!(f.evaluate(Vec2::new(4.01, 0.0)), 0.0);
    }

    #[test]
    fn zero_outside_radius() {
        for k in FILTER_NAMES {
            let f = make(k, &[]).unwrap();
            let r = f.radius();
            for p in [Vec2::new(r.x * 1.01, 0.0), Vec2::new(0.0, -r.y * 1.01), r * 1.5, Vec2::new(-100.0, 3.0)] {
                assert_eq!(f.evaluate(p), 0.0, "{k} {p:?}");
            }
            assert!(f.evaluate(Vec2::ZERO) > 0.0);
        }
    }

    #[test]
    fn errors() {
        match make("lanczos", &[]) {
            Err(FilterError::Unknown { valid, .. }) => assert!(valid.contains("mitchell")),
            _ => panic!("expected unknown filter error"),
        }
        for bad in [0.0, -1.0, f32::NAN] {
            assert!(matches!(make("box", &[("xwidth", bad)]), Err(FilterError::InvalidParameter { .. })));
        }
        assert!(make("sinc", &[("tau", 0.0)]).is_err());
    }
}
