use super::*;
use crate::sh::quadrature::{project, SphereQuadrature};
use crate::Rgb;

fn o(n: usize) -> ShOrder {
    ShOrder::new(n).unwrap()
}

fn map(w: usize, h: usize, mut f: impl FnMut(usize, usize) -> [f32; 3]) -> RgbMap {
    RgbMap { width: w, height: h, texels: (0..w * h).map(|k| Rgb::from(f(k % w, k / w))).collect() }
}

fn random_map(w: usize, h: usize, seed: u64) -> RgbMap {
    let mut rng = crate::rng::Rng::new(seed);
    map(w, h, |_, _| [rng.uniform_f32(), 2.0 * rng.uniform_f32(), 0.5 + rng.uniform_f32()])
}

fn max_diff(a: &ShRgb, b: &ShRgb) -> f64 {
    a.coeffs.iter().zip(&b.coeffs).flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c]).abs())).fold(0.0, f64::max)
}

#[test]
fn constant_light_is_exact() {
    let m = RgbMap::constant(Rgb::new(0.5, 2.0, 3.0));
    let p = project_lat_long_world(&m, Mat3::from_rotation_x(0.7), o(5)).unwrap();
    assert_eq!(p.coeffs[0], [0.5 * SQRT_4PI, 2.0 * SQRT_4PI, 3.0 * SQRT_4PI]);
    assert!(p.coeffs[1..].iter().all(|c| *c == [0.0; 3]));
    // A uniform 4×2 map is the same function: exact up to rounding.
    let u = map(4, 2, |_, _| [0.5, 2.0, 3.0]);
    let p = project_lat_long(&u, o(5)).unwrap();
    assert!((p.coeffs[0][1] - 2.0 * SQRT_4PI).abs() < 1e-12);
    assert!(p.coeffs[1..].iter().all(|c| c.iter().all(|v| v.abs() < 1e-12)));
}

/// The exact separable projection equals a brute-force world-space quadrature of pbrt-v3's
/// own bilinear lookup (kinks at texel centres limit the quadrature: it converges as it is
/// refined, and the exact value is where it converges to).
#[test]
fn exact_projection_matches_quadrature_of_the_lookup() {
    let m = random_map(16, 8, 4);
    let exact = project_lat_long(&m, o(6)).unwrap();
    let coarse = project_lat_long_quadrature(&m, Mat3::IDENTITY, o(6), 4);
    let fine = project_lat_long_quadrature(&m, Mat3::IDENTITY, o(6), 32);
    let (dc, df) = (max_diff(&exact, &coarse), max_diff(&exact, &fine));
    assert!(df < 2e-4, "fine quadrature {df:e}");
    assert!(df < 0.3 * dc, "converges to the exact value: {dc:e} → {df:e}");
}

/// Projection through the light's transform = the rotation of its light-space projection,
/// checked against the independent world-space quadrature, for a proper rotation (pbrt's
/// `Rotate -90 1 0 0`, as the suite's scenes), a random one, a mirror and a uniform scale.
#[test]
fn projection_through_transform_is_the_rotated_projection() {
    let m = random_map(16, 8, 8);
    let light = project_lat_long(&m, o(5)).unwrap();
    let mirror = Mat3::from_diagonal(glam::Vec3::new(-1.0, 1.0, 1.0));
    let transforms = [
        Mat3::from_rotation_x(-std::f32::consts::FRAC_PI_2),
        Mat3::from_axis_angle(glam::Vec3::new(0.3, -0.5, 0.8).normalize(), 2.1),
        mirror * Mat3::from_rotation_z(0.4),
        Mat3::from_rotation_y(1.0) * 3.0,
    ];
    for t in transforms {
        let world = project_lat_long_world(&m, t, o(5)).unwrap();
        let r = t.as_dmat3() * (1.0 / t.as_dmat3().determinant().abs().cbrt());
        let mut rotated = ShRgb::zero(o(5));
        ShRotation::new(o(5), r).unwrap().apply_rgb(&light.coeffs, &mut rotated.coeffs).unwrap();
        assert!(max_diff(&world, &rotated) < 1e-6, "{t}");
        let brute = project_lat_long_quadrature(&m, t, o(5), 32);
        assert!(max_diff(&world, &brute) < 2e-4, "{t}: {:e}", max_diff(&world, &brute));
    }
    // A non-orthogonal transform falls back to the quadrature.
    let skew = Mat3::from_diagonal(glam::Vec3::new(1.0, 2.0, 1.0));
    let p = project_lat_long_world(&m, skew, o(3)).unwrap();
    assert!(max_diff(&p, &project_lat_long_quadrature(&m, skew, o(3), 4)) < 1e-12);
    assert!(project_lat_long_world(&m, Mat3::ZERO, o(3)).is_err());
    assert!(project_lat_long(&RgbMap { width: 0, height: 0, texels: vec![] }, o(3)).is_err());
    assert!(project_lat_long(&RgbMap { width: 4, height: 4, texels: vec![Rgb::ONE; 3] }, o(3)).is_err());
}

/// A map sampling an order-2 function at its texel centres projects onto that function's
/// coefficients up to the bilinear interpolation's O(h²), and the SH reconstruction at a
/// direction matches the lookup there.
#[test]
fn map_of_a_band_limited_function_recovers_its_coefficients() {
    let c: Vec<f64> = vec![3.0, 0.4, -0.3, 0.5, 0.2, -0.1, 0.3, 0.15, -0.25];
    let f = |d: DVec3| crate::sh::quadrature::reconstruct(&c, d);
    let (w, h) = (256, 128);
    let m = map(w, h, |i, j| {
        let (theta, phi) = ((j as f64 + 0.5) * PI / h as f64, (i as f64 + 0.5) * 2.0 * PI / w as f64);
        let v = f(DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())) as f32;
        [v, 2.0 * v, 0.5 * v]
    });
    let p = project_lat_long(&m, o(4)).unwrap();
    for i in 0..16 {
        let want = c.get(i).copied().unwrap_or(0.0);
        assert!((p.coeffs[i][0] - want).abs() < 2e-3, "c{i}: {} vs {want}", p.coeffs[i][0]);
        assert!((p.coeffs[i][1] - 2.0 * want).abs() < 4e-3);
    }
    let q = project(o(3), f, &SphereQuadrature::exact_for_degree(4));
    assert!((q[4] - c[4]).abs() < 1e-12);
    let d = DVec3::new(0.2, 0.5, -0.7).normalize();
    assert!((p.eval(d)[0] - f(d)).abs() < 5e-3);
}
