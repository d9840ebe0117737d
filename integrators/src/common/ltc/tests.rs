use super::fit::{m_from_params, minv_params};
use super::*;
use crate::common::spherical_polygon::{form_factor, orthonormal_basis, solid_angle, winding_number_loops};
use glam::{Vec2, Vec3};
use penumbra_core::bxdf::{Bxdf, Fresnel};
use penumbra_core::microfacet::MicrofacetDistribution;
use penumbra_core::rng::Rng;
use std::f64::consts::PI;

fn table() -> &'static Ltc {
    Ltc::ggx().expect("embedded LTC table must parse")
}

/// MC estimate of ∫ f cos over `accept` with core's BSDF (VNDF sampling), and the standard error.
fn mc_bsdf(alpha: f32, wo: Vec3, n: usize, seed: u64, accept: impl Fn(DVec3) -> bool) -> (f64, f64) {
    let bxdf =
        Bxdf::microfacet_reflection(Vec3::ONE, MicrofacetDistribution::trowbridge_reitz(alpha, alpha), Fresnel::NoOp);
    let mut rng = Rng::new(seed);
    let (mut s, mut s2) = (0.0, 0.0);
    for _ in 0..n {
        let u = Vec2::new(rng.uniform_f32(), rng.uniform_f32());
        if let Some(bs) = bxdf.sample_f(wo, u) {
            if bs.pdf > 0.0 && bs.wi.z > 0.0 && accept(bs.wi.as_dvec3()) {
                let v = bs.f.x as f64 * bs.wi.z as f64 / bs.pdf as f64;
                s += v;
                s2 += v * v;
            }
        }
    }
    let m = s / n as f64;
    (m, ((s2 / n as f64 - m * m).max(0.0) / n as f64).sqrt())
}

#[test]
fn embedded_table_is_valid() {
    let t = table();
    assert_eq!((t.n_theta, t.n_alpha), (64, 64));
    for c in &t.cells {
        assert!(c.iter().all(|v| v.is_finite()));
        assert!(c[4] > 0.0 && c[4] <= 1.0 + 1e-3, "magnitude {}", c[4]);
        assert!((0.0..=1.0).contains(&c[5]), "fresnel {}", c[5]);
        // a cell is the shape [m11, m22, m13, θz] of M (see `m_from_shape`)
        let m = m_from_shape([c[0] as f64, c[1] as f64, c[2] as f64, c[3] as f64]);
        assert!(m.determinant() > 0.0, "{c:?}");
    }
    // round trip of the format
    assert_eq!(Ltc::from_bytes(&t.to_bytes()).as_ref(), Ok(t));
    assert!(Ltc::from_bytes(b"LTC1").is_err());
    assert!(Ltc::from_bytes(&t.to_bytes()[..100]).is_err());
}

#[test]
fn stored_inverse_matches_fit_matrix() {
    let p = [0.7, -0.3, 0.2, 1.4];
    let prod = minv_from_params(minv_params(p)) * m_from_params(p);
    let d = prod.determinant();
    assert!(d > 0.0);
    let s = prod.col(1).y; // the middle entries are 1 so the product is the identity
    for (i, c) in [prod.col(0), prod.col(1), prod.col(2)].iter().enumerate() {
        for k in 0..3 {
            let want = if i == k { s } else { 0.0 };
            assert!((c[k] - want).abs() < 1e-12);
        }
    }
}

#[test]
fn magnitude_matches_bsdf_directional_albedo() {
    let t = table();
    for &(j, i) in &[(63usize, 0usize), (63, 40), (50, 10), (40, 30), (30, 50), (20, 5), (45, 60), (10, 20)] {
        let (alpha, cos) = (t.row_alpha(j), t.column_cos_theta(i).max(fit::MIN_COS_THETA));
        let c = t.eval(cos as f32, alpha as f32);
        let wo = Vec3::new((1.0 - cos * cos).sqrt() as f32, 0.0, cos as f32);
        let (mc, se) = mc_bsdf(alpha as f32, wo, 200_000, 17 + i as u64, |_| true);
        let rel = (c.magnitude as f64 - mc).abs() / mc;
        assert!(
            rel < 0.01 && (c.magnitude as f64 - mc).abs() < 0.01 * mc + 4.0 * se,
            "alpha {alpha} cos {cos}: {} vs {mc} ± {se}",
            c.magnitude
        );
    }
}

#[test]
fn lambertian_identity_gives_the_form_factor() {
    let mut rng = Rng::new(3);
    let frame = Frame::toward(DVec3::new(0.2, -0.3, 0.9).normalize(), DVec3::new(0.5, 0.5, 0.7));
    for _ in 0..20 {
        let l: Vec<DVec3> = (0..5)
            .map(|_| {
                frame.from_local(
                    DVec3::new(rng.uniform_f64() - 0.5, rng.uniform_f64() - 0.5, rng.uniform_f64() * 0.6 - 0.1)
                        + frame.z,
                )
            })
            .collect();
        let local: Vec<DVec3> = l.iter().map(|d| frame.to_local(*d)).collect();
        let a = ltc_integrate(&DMat3::IDENTITY, &frame, std::slice::from_ref(&l));
        assert!((a - form_factor(&local)).abs() < 1e-14);
        // scaling M⁻¹ changes nothing
        let b = ltc_integrate(&(DMat3::IDENTITY * 3.0), &frame, &[l]);
        assert!((a - b).abs() < 1e-12);
    }
}

#[test]
fn shading_frame_puts_wo_in_the_xz_plane() {
    let n = DVec3::new(0.3, 0.4, 0.8).normalize();
    let wo = DVec3::new(-0.5, 0.1, 0.6).normalize();
    let f = Frame::toward(n, wo);
    let l = f.to_local(wo);
    assert!(l.y.abs() < 1e-14 && l.x > 0.0 && (l.z - wo.dot(n)).abs() < 1e-14);
    assert!((f.x.cross(f.y) - f.z).length() < 1e-14);
    let g = Frame::toward(n, n);
    assert!((g.x.dot(n)).abs() < 1e-14 && (g.x.length() - 1.0).abs() < 1e-14);
}

fn random_quad(rng: &mut Rng, center: DVec3) -> Vec<DVec3> {
    let c = center.normalize();
    let (u, v) = orthonormal_basis(c);
    let (su, sv) = (0.1 + 0.6 * rng.uniform_f64(), 0.1 + 0.6 * rng.uniform_f64());
    let r = rng.uniform_f64() * PI;
    let (a, b) = (u * r.cos() + v * r.sin(), v * r.cos() - u * r.sin());
    let mut q = vec![c - a * su - b * sv, c + a * su - b * sv, c + a * su + b * sv, c - a * su + b * sv];
    if solid_angle(&q) < 0.0 {
        q.reverse();
    }
    q
}

#[test]
fn ltc_integral_of_random_polygons_matches_the_brdf() {
    // Reports the RMS error of magnitude·∫LTC against MC of the real BRDF·cos, relative to the
    // albedo, and the RMS relative error for polygons holding at least 10% of the albedo.
    let t = table();
    let mut rng = Rng::new(8);
    let (mut sq_abs, mut n_abs, mut sq_rel, mut n_rel, mut worst) = (0.0, 0, 0.0, 0, 0.0f64);
    for &alpha in &[0.05f64, 0.15, 0.3, 0.6, 1.0] {
        for &cos in &[0.95f64, 0.75, 0.5, 0.25] {
            let c = t.eval(cos as f32, alpha as f32);
            let phi0 = 2.0 * PI * rng.uniform_f64();
            let sin = (1.0 - cos * cos).sqrt();
            let wo = DVec3::new(sin * phi0.cos(), sin * phi0.sin(), cos);
            let frame = Frame::toward(DVec3::Z, wo);
            let refl = DVec3::new(-wo.x, -wo.y, wo.z);
            for k in 0..3 {
                let center = (refl
                    + 0.5 * DVec3::new(rng.uniform_f64() - 0.5, rng.uniform_f64() - 0.5, rng.uniform_f64() - 0.3))
                .normalize();
                let center = DVec3::new(center.x, center.y, center.z.abs() + 0.05);
                let q = random_quad(&mut rng, center);
                let loops = vec![q];
                let ltc = c.magnitude as f64 * ltc_integrate(&c.minv, &frame, &loops);
                let (mc, se) =
                    mc_bsdf(alpha as f32, wo.as_vec3(), 40_000, 1000 + k, |d| winding_number_loops(&loops, d) > 0);
                let e = (ltc - mc).abs() / c.magnitude as f64;
                worst = worst.max(e);
                sq_abs += e * e;
                n_abs += 1;
                if mc > 0.1 * c.magnitude as f64 {
                    let r = (ltc - mc).abs() / mc;
                    sq_rel += r * r;
                    n_rel += 1;
                }
                assert!(
                    (ltc - mc).abs() < 0.08 * c.magnitude as f64 + 4.0 * se,
                    "alpha {alpha} cos {cos}: {ltc} vs {mc} ± {se}"
                );
            }
        }
    }
    let rms_abs = (sq_abs / n_abs as f64).sqrt();
    let rms_rel = (sq_rel / n_rel.max(1) as f64).sqrt();
    eprintln!("LTC vs BRDF: RMS |err|/albedo = {rms_abs:.4} (worst {worst:.4}, {n_abs} polygons); RMS relative error (mc > 10% albedo) = {rms_rel:.4} ({n_rel} polygons)");
    assert!(rms_abs < 0.03, "{rms_abs}");
}

/// `sample` against `pdf`: the samples are binned by their preimage `u = M⁻¹ω/|M⁻¹ω|` in the
/// LTC's cosine space (bins of `u_z` and `φ` over the upper hemisphere, the LTC's exact support,
/// so no bin straddles the edge of the support where a midpoint rule would miss mass), and each
/// bin's expected count is `pdf` integrated over the bin's image `ω = Mu/|Mu|`, with the
/// Jacobian `|det M| / |Mu|³` of that map computed from `M` (not from `pdf`'s formula).
#[test]
fn sample_and_pdf_agree_by_chi_square() {
    let t = table();
    for &(cos, alpha) in &[(0.9f32, 0.5f32), (0.5, 0.3), (0.2, 0.8), (0.7, 2.5), (0.3, 0.01)] {
        let c = t.eval(cos, alpha);
        let m = c.m();
        let det_m = m.determinant().abs();
        let (nt, np) = (16usize, 32usize);
        let n = 200_000usize;
        let mut rng = Rng::new(31);
        let mut obs = vec![0.0; nt * np];
        for _ in 0..n {
            let w = c.sample(DVec2::new(rng.uniform_f64(), rng.uniform_f64()));
            let u = (c.minv * w).normalize_or_zero();
            let ti = ((u.z * nt as f64) as usize).min(nt - 1);
            let phi = u.y.atan2(u.x).rem_euclid(2.0 * PI);
            let pi = ((phi / (2.0 * PI) * np as f64) as usize).min(np - 1);
            obs[ti * np + pi] += 1.0;
        }
        // expected: the pdf over each bin's image, a 12×12 midpoint rule in (u_z, φ)
        let sub = 12;
        let mut exp = vec![0.0; nt * np];
        let mut total = 0.0;
        for ti in 0..nt {
            for pi in 0..np {
                let mut s = 0.0;
                for a in 0..sub {
                    for b in 0..sub {
                        let z = (ti as f64 + (a as f64 + 0.5) / sub as f64) / nt as f64;
                        let phi = 2.0 * PI * (pi as f64 + (b as f64 + 0.5) / sub as f64) / np as f64;
                        let r = (1.0 - z * z).max(0.0).sqrt();
                        let mu = m * DVec3::new(r * phi.cos(), r * phi.sin(), z);
                        let l = mu.length();
                        s += c.pdf(mu / l) * det_m / (l * l * l);
                    }
                }
                let area = (1.0 / nt as f64) * (2.0 * PI / np as f64);
                exp[ti * np + pi] = s / (sub * sub) as f64 * area * n as f64;
                total += s / (sub * sub) as f64 * area;
            }
        }
        assert!((total - 1.0).abs() < 5e-3, "cos {cos} alpha {alpha}: pdf integrates to {total}");
        let (chi2, dof, p) = penumbra_core::goodness_of_fit::chi2_test(&obs, &exp, 5.0);
        assert!(p > 1e-3, "cos {cos} alpha {alpha}: chi2 {chi2} dof {dof} p {p}");
    }
}

#[test]
fn lookup_clamps_and_never_panics() {
    for &(c, a) in &[(f32::NAN, 0.5), (2.0, -1.0), (-1.0, 1e9), (0.5, f32::NAN), (0.0, 0.0), (1.0, 1.0)] {
        let l = Ltc::lookup(c, a);
        assert!(l.magnitude.is_finite() && l.magnitude > 0.0);
        assert!(l.minv.determinant() > 0.0);
    }
}
