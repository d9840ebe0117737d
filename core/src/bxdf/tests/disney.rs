//! `disney`'s lobes: closed-form albedos, sampling against the pdfs (chi-square, lobes and whole
//! BSDFs), reciprocity, energy bounds and the separable masking term.

use super::*;
use crate::bxdf::disney::{fr_schlick, schlick_weight};

fn diffuse_family() -> Vec<(String, DisneyLobe)> {
    let r = Rgb::new(0.8, 0.5, 0.3);
    let mut v = vec![("diffuse".to_string(), DisneyLobe::Diffuse { r }), ("sheen".into(), DisneyLobe::Sheen { r })];
    for rough in [0.0, 0.5, 1.0] {
        v.push((format!("fake-ss {rough}"), DisneyLobe::FakeSubsurface { r, roughness: rough }));
        v.push((format!("retro {rough}"), DisneyLobe::Retro { r, roughness: rough }));
    }
    v
}

/// Clearcoats of `clearcoatgloss` 0 and 0.5 (GTR1 alpha 0.1, 0.0505); gloss 1 (alpha 0.001)
/// puts a third of its half vectors within 0.6° of the normal, finer than the chi-square's
/// cells can integrate: [`clearcoat_half_vectors_follow_gtr1`] tests it.
fn clearcoats() -> Vec<(String, DisneyLobe)> {
    [0.1f32, 0.0505]
        .iter()
        .map(|&g| (format!("clearcoat {g}"), DisneyLobe::Clearcoat { weight: Rgb::ONE, gloss: g }))
        .collect()
}

#[test]
fn chi2_disney_lobes() {
    for (k, (name, l)) in diffuse_family().into_iter().chain(clearcoats()).enumerate() {
        let b = Bxdf::Disney(l);
        for (j, wo) in wos().into_iter().chain([-dir(0.7, 1.3)]).enumerate() {
            check_lobe(&name, &b, wo, 3000 + (k * 10 + j) as u64);
        }
    }
}

/// The whole Disney BSDFs the material builds (see `material::disney`), sampled as `Bsdf` samples
/// them, against `Bsdf::pdf`.
fn disney_bsdfs() -> Vec<(&'static str, Bsdf)> {
    let c = Rgb::new(0.7, 0.5, 0.3);
    let spec = |metallic: f32, ax: f32, ay: f32| {
        Bxdf::microfacet_reflection(
            Rgb::ONE,
            Md::disney(ax, ay),
            Fresnel::Disney { r0: Rgb::splat(0.04) * (1.0 - metallic) + c * metallic, metallic, eta: 1.5 },
        )
    };
    let m = TransportMode::Radiance;
    vec![
        (
            "disney default",
            tilted_bsdf(
                &[
                    Bxdf::Disney(DisneyLobe::Diffuse { r: c }),
                    Bxdf::Disney(DisneyLobe::Retro { r: c, roughness: 0.5 }),
                    spec(0.0, 0.25, 0.25),
                ],
                1.0,
            ),
        ),
        (
            "disney sheen clearcoat anisotropic",
            tilted_bsdf(
                &[
                    Bxdf::Disney(DisneyLobe::Diffuse { r: 0.5 * c }),
                    Bxdf::Disney(DisneyLobe::Retro { r: 0.5 * c, roughness: 0.8 }),
                    Bxdf::Disney(DisneyLobe::Sheen { r: c }),
                    spec(0.5, 0.15, 0.6),
                    Bxdf::Disney(DisneyLobe::Clearcoat { weight: Rgb::ONE, gloss: 0.05 }),
                ],
                1.0,
            ),
        ),
        (
            "disney thin",
            tilted_bsdf(
                &[
                    Bxdf::Disney(DisneyLobe::Diffuse { r: 0.3 * c }),
                    Bxdf::Disney(DisneyLobe::FakeSubsurface { r: 0.3 * c, roughness: 0.4 }),
                    Bxdf::Disney(DisneyLobe::Retro { r: 0.6 * c, roughness: 0.4 }),
                    spec(0.0, 0.16, 0.16),
                    Bxdf::microfacet_transmission(c, tr(0.3), 1.0, 1.5, m),
                    Bxdf::lambertian_transmission(0.4 * c),
                ],
                1.0,
            ),
        ),
        (
            "disney spectrans",
            tilted_bsdf(
                &[spec(0.0, 0.2, 0.2), Bxdf::microfacet_transmission(c, Md::disney(0.2, 0.2), 1.0, 1.5, m)],
                1.0,
            ),
        ),
    ]
}

#[test]
fn chi2_disney_bsdfs() {
    for (k, (name, b)) in disney_bsdfs().iter().enumerate() {
        for (j, wo_l) in [dir(0.15, 0.3), dir(0.9, 2.0), dir(1.35, 4.5), -dir(0.5, 1.0)].into_iter().enumerate() {
            let wo = b.local_to_world(wo_l);
            let name = format!("{name} wo={wo_l}");
            check_sampling(
                &name,
                3500 + (k * 10 + j) as u64,
                |u| {
                    b.sample_f(wo, u, BxdfFlags::ALL).map(|s| {
                        let f = b.f(wo, s.wi, BxdfFlags::ALL);
                        assert!((s.f - f).abs().max_element() <= 1e-3 * f.max_element().max(1.0), "{name}: f");
                        (s.wi, s.pdf)
                    })
                },
                |wi| b.pdf(wo, wi, BxdfFlags::ALL),
            );
        }
    }
}

/// Burley's diffuse at normal incidence reflects `R ∫ (1 − (1 − µ)^5 / 2) 2µ dµ = R (1 − 1/42)`:
/// every cosine-sampled weight `π f` is `R (1 − F_i/2)` exactly, so the mean is the closed form
/// within its standard error.
#[test]
fn disney_diffuse_albedo_closed_form() {
    let b = Bxdf::Disney(DisneyLobe::Diffuse { r: Rgb::ONE });
    let (m, se, _) = albedo(&b, Vec3::Z, 200_000, 71);
    let expect = 1.0 - 1.0 / 42.0;
    assert!((m - expect).abs() < 4.0 * se + 1e-6, "{m} ± {se} vs {expect}");
    // Grazing outgoing direction: (1 − 1/2) of it.
    let (m, se, _) = albedo(&b, dir(std::f32::consts::FRAC_PI_2 - 1e-4, 0.0), 200_000, 72);
    let expect = 0.5 * (1.0 - 1.0 / 42.0);
    assert!((m - expect).abs() < 4.0 * se + 1e-3, "grazing: {m} ± {se} vs {expect}");
}

/// For every lobe and whole BSDF, the importance-sampled albedo `E[f |cos| / pdf]` equals the
/// quadrature of `f |cos|` over the sphere (an estimator whose pdf missed part of `f` would
/// fall short), within 4 standard errors plus the quadrature's error.
#[test]
fn disney_sampled_albedo_matches_quadrature() {
    let lobes: Vec<(String, Bxdf)> = diffuse_family()
        .into_iter()
        .chain(clearcoats().into_iter().take(2))
        .map(|(n, l)| (n, Bxdf::Disney(l)))
        .collect();
    for (k, (name, b)) in lobes.iter().enumerate() {
        for (j, wo) in [dir(0.2, 0.5), dir(1.1, 2.0)].into_iter().enumerate() {
            let q = sphere_integral(1200, 240, |wi| {
                if same_hemisphere(wo, wi) {
                    (b.f(wo, wi).x * wi.z.abs()) as f64
                } else {
                    0.0
                }
            });
            let (m, se) = albedo_channel(b, wo, 0, 200_000, 3700 + (k * 10 + j) as u64);
            assert!((m - q).abs() < 4.0 * se + 2e-3 * q.max(0.01), "{name} wo {wo}: {m} ± {se} vs quadrature {q}");
        }
    }
}

fn albedo_channel(b: &Bxdf, wo: Vec3, c: usize, n: usize, seed: u64) -> (f64, f64) {
    let mut rng = Pcg::new(seed);
    let (mut s, mut s2) = (0.0f64, 0.0f64);
    for _ in 0..n {
        if let Some(x) = b.sample_f(wo, rng.v2()) {
            let w = (x.f[c] * x.wi.z.abs() / x.pdf) as f64;
            s += w;
            s2 += w * w;
        }
    }
    let m = s / n as f64;
    (m, ((s2 / n as f64 - m * m).max(0.0) / n as f64).sqrt())
}

#[test]
fn disney_lobes_are_reciprocal() {
    let mut rng = Pcg::new(5);
    let mut lobes: Vec<Bxdf> = diffuse_family().into_iter().chain(clearcoats()).map(|(_, l)| Bxdf::Disney(l)).collect();
    let f = Fresnel::Disney { r0: Rgb::new(0.9, 0.6, 0.2), metallic: 0.6, eta: 1.4 };
    lobes.push(Bxdf::microfacet_reflection(Rgb::ONE, Md::disney(0.2, 0.5), f));
    for b in lobes {
        for _ in 0..2000 {
            let wo = cosine_sample_hemisphere(rng.v2());
            let wi = cosine_sample_hemisphere(rng.v2());
            let (a, c) = (b.f(wo, wi), b.f(wi, wo));
            assert!((a - c).abs().max_element() <= 1e-4 * a.max_element().max(1.0), "{b:?}: {a} vs {c}");
        }
    }
}

/// A white metal (Disney Fresnel with `metallic` 1 and `R0` = 1 is 1 everywhere) reflects at
/// most what arrives: the separable `G1 G1` is below the height-correlated `G`, so the albedo is
/// at most that of the plain Trowbridge–Reitz lobe; at normal incidence and α = 0.01 both are 1.
#[test]
fn disney_white_metal_furnace() {
    let f = Fresnel::Disney { r0: Rgb::ONE, metallic: 1.0, eta: 1.5 };
    assert_eq!(f.evaluate(0.3), Rgb::ONE);
    for a in [0.01f32, 0.2, 0.6] {
        let disney = Bxdf::microfacet_reflection(Rgb::ONE, Md::disney(a, a), f);
        let plain = Bxdf::microfacet_reflection(Rgb::ONE, tr(a), NOOP);
        for (k, wo) in [Vec3::Z, dir(0.8, 1.0), dir(1.4, 3.0)].into_iter().enumerate() {
            let (md, sd, mx) = albedo(&disney, wo, 100_000, 3800 + k as u64);
            let (mp, sp, _) = albedo(&plain, wo, 100_000, 3800 + k as u64);
            assert!(mx <= 1.0 + 1e-4, "alpha {a} wo {wo}: weight {mx}");
            assert!(md <= mp + 1e-6, "alpha {a} wo {wo}: {md} ± {sd} vs {mp} ± {sp}");
            if a == 0.01 && k == 0 {
                assert!(md > 0.999, "{md}");
            }
        }
        // Separable versus height-correlated: G1(o) G1(i) ≤ 1 / (1 + Λo + Λi).
        let d = Md::disney(a, a);
        let h = tr(a);
        let (o, i) = (dir(1.2, 0.3), dir(0.9, 2.5));
        assert!(d.g(o, i) <= h.g(o, i) && (d.g(o, i) - h.g1(o) * h.g1(i)).abs() < 1e-6);
        assert_eq!(d.d(dir(0.4, 1.0)), h.d(dir(0.4, 1.0)));
    }
}

#[test]
fn schlick_terms() {
    assert_eq!(schlick_weight(1.0), 0.0);
    assert_eq!(schlick_weight(0.0), 1.0);
    assert_eq!(schlick_weight(-0.5), 1.0);
    assert!((schlick_weight(0.5) - 0.03125).abs() < 1e-7);
    let r0 = Rgb::new(0.04, 0.5, 1.0);
    assert_eq!(fr_schlick(r0, 1.0), r0);
    assert_eq!(fr_schlick(r0, 0.0), Rgb::ONE);
    // The Disney Fresnel interpolates the dielectric and Schlick terms by `metallic`.
    let f = |m: f32| Fresnel::Disney { r0, metallic: m, eta: 1.5 }.evaluate(0.7);
    assert!((f(0.0) - Rgb::splat(fr_dielectric(0.7, 1.0, 1.5))).abs().max_element() < 1e-7);
    assert!((f(1.0) - fr_schlick(r0, 0.7)).abs().max_element() < 1e-7);
    assert!((f(0.25) - (0.75 * f(0.0) + 0.25 * f(1.0))).abs().max_element() < 1e-6);
}

/// The clearcoat's half vectors follow GTR1 at every gloss: seen from the normal, the sampled
/// `cos θ_h` mapped through GTR1's CDF, `u = 1 − ln(1 − cos²θ_h (1 − α²)) / ln α²`, is uniform
/// over the accepted range (reflections below the horizon, θ_h > 45°, are rejected).
#[test]
fn clearcoat_half_vectors_follow_gtr1() {
    for (k, alpha) in [0.1f32, 0.0505, 0.001].into_iter().enumerate() {
        let b = Bxdf::Disney(DisneyLobe::Clearcoat { weight: Rgb::ONE, gloss: alpha });
        let a2 = (alpha as f64).powi(2);
        // In terms of sin²θ_h (1 − cos² loses the small angles of the sharpest lobe).
        let cdf = |s2: f64| 1.0 - (s2 + a2 - s2 * a2).ln() / a2.ln();
        let u45 = cdf(0.5);
        let mut rng = Pcg::new(3900 + k as u64);
        let bins = 50;
        let mut hist = vec![0.0f64; bins];
        let n = 100_000;
        let mut kept = 0usize;
        for _ in 0..n {
            if let Some(s) = b.sample_f(Vec3::Z, rng.v2()) {
                // wi = 2 cos θ_h h − z: its x, y are exact to f32's relative precision.
                let xy2 = (s.wi.x as f64).powi(2) + (s.wi.y as f64).powi(2);
                let z = (1.0 - xy2).sqrt();
                let u = cdf(xy2 / (xy2 + (1.0 + z).powi(2))) / u45;
                hist[((u * bins as f64) as usize).min(bins - 1)] += 1.0;
                kept += 1;
            }
        }
        let expected = vec![kept as f64 / bins as f64; bins];
        let (chi2, dof, p) = crate::goodness_of_fit::chi2_test(&hist, &expected, 5.0);
        assert!(p > P_MIN, "alpha {alpha}: chi2 {chi2} dof {dof} p {p}");
        let accepted = kept as f64 / n as f64;
        let sd = (u45 * (1.0 - u45) / n as f64).sqrt();
        assert!((accepted - u45).abs() < 4.0 * sd + 1e-4, "alpha {alpha}: accepted {accepted} vs {u45}");
    }
}
