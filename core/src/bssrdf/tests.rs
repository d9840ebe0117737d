//! The BSSRDF machinery: Fresnel moments against quadrature, the profiles' normalisation and
//! radius sampling (chi-square against `pdf_sr`), `kdsubsurface`'s albedo inversion, and the
//! probe estimator's unbiasedness on a plane.

use super::*;
use crate::rng::Rng;
use std::sync::OnceLock;

fn table() -> &'static BssrdfTable {
    static T: OnceLock<BssrdfTable> = OnceLock::new();
    T.get_or_init(|| BssrdfTable::beam_diffusion(0.0, 1.33))
}

/// pbrt-v3's moments are polynomial fits of `∫₀¹ F_r(µ) µ^i dµ` (i = 1, 2) for light arriving
/// from a medium of index 1 at one of index `1/η` (`Sw` takes the moment at `1/η` for light
/// leaving through the surface; the diffusion boundary at `η` for light inside it).
#[test]
fn fresnel_moments_match_quadrature() {
    for eta in [0.5f32, 0.7, 0.9, 1.1, 1.33, 1.5, 2.0] {
        let n = 20_000;
        let (mut m1, mut m2) = (0.0f64, 0.0f64);
        for k in 0..n {
            let mu = (k as f64 + 0.5) / n as f64;
            let f = fr_dielectric(mu as f32, 1.0, 1.0 / eta) as f64;
            m1 += f * mu / n as f64;
            m2 += f * mu * mu / n as f64;
        }
        assert!((fresnel_moment1(eta) as f64 - m1).abs() < 3e-3, "eta {eta}: {} vs {m1}", fresnel_moment1(eta));
        assert!((fresnel_moment2(eta) as f64 - m2).abs() < 3e-3, "eta {eta}: {} vs {m2}", fresnel_moment2(eta));
    }
}

/// ∫ S_r(r) 2πr dr by the midpoint rule on a log grid (the profiles fall off exponentially).
fn radial_integral(f: impl Fn(f32) -> f64, r_min: f64, r_max: f64) -> f64 {
    let n = 20_000;
    let (l0, l1) = (r_min.ln(), r_max.ln());
    let mut s = 0.0;
    for k in 0..n {
        let (a, b) = ((l0 + (l1 - l0) * k as f64 / n as f64).exp(), (l0 + (l1 - l0) * (k + 1) as f64 / n as f64).exp());
        let r = 0.5 * (a + b);
        s += f(r as f32) * 2.0 * std::f64::consts::PI * r * (b - a);
    }
    s
}

/// Burley's profile is normalised: `∫ S_r 2πr dr = R`, and its pdf integrates to 1.
#[test]
fn disney_profile_is_normalised() {
    let p = Profile::Disney { r: Rgb::new(0.8, 0.5, 0.2), d: Rgb::new(0.05, 0.1, 0.3) };
    for c in 0..3 {
        let total = radial_integral(|r| p.sr(r)[c] as f64, 1e-6, 100.0);
        assert!((total - [0.8, 0.5, 0.2][c]).abs() < 1e-3, "channel {c}: {total}");
        let pdf = radial_integral(|r| p.pdf_sr(c, r) as f64, 1e-6, 100.0);
        assert!((pdf - 1.0).abs() < 1e-3, "channel {c}: {pdf}");
    }
}

/// The tabulated profile integrates to its effective albedo, its pdf to 1, and both grow with
/// the single-scattering albedo (ρ_eff(0) = 0).
#[test]
fn tabulated_profile_is_normalised() {
    let t = table();
    assert_eq!(t.rho_eff[0], 0.0);
    assert!(t.rho_eff.windows(2).all(|w| w[1] > w[0]), "{:?}", &t.rho_eff[..5]);
    // Without absorption the dipole's effective albedo slightly exceeds 1 (measured 1.019).
    assert!(t.rho_eff[99] > 0.95 && t.rho_eff[99] < 1.05, "{}", t.rho_eff[99]);
    for (sigma_a, sigma_s) in [(0.01f32, 1.0f32), (0.5, 2.0), (1.0, 0.5)] {
        let p = Profile::tabulated(t, Rgb::splat(sigma_a), Rgb::splat(sigma_s));
        let rho = sigma_s / (sigma_a + sigma_s);
        let rho_eff = crate::interpolation::catmull_rom(&t.rho_samples, &t.rho_eff, rho);
        let r_max = t.radius_samples[63] / (sigma_a + sigma_s);
        let total = radial_integral(|r| p.sr(r).x as f64, 1e-7, r_max as f64);
        assert!(
            (total - rho_eff as f64).abs() < 5e-3 * rho_eff as f64,
            "σa {sigma_a} σs {sigma_s}: {total} vs {rho_eff}"
        );
        let pdf = radial_integral(|r| p.pdf_sr(0, r) as f64, 1e-7, r_max as f64);
        assert!((pdf - 1.0).abs() < 5e-3, "σa {sigma_a} σs {sigma_s}: {pdf}");
    }
}

/// Sampled radii follow `pdf_sr · 2πr` (chi-square over radius bins of equal expected mass).
#[test]
fn chi2_radius_sampling() {
    let t = table();
    let profiles = [
        Profile::tabulated(t, Rgb::new(0.02, 0.5, 2.0), Rgb::new(3.0, 1.0, 0.5)),
        Profile::Disney { r: Rgb::ONE, d: Rgb::new(0.05, 0.1, 0.3) },
    ];
    for (k, p) in profiles.iter().enumerate() {
        for ch in 0..3 {
            let mut rng = Rng::new(600 + (k * 3 + ch) as u64);
            let n = 100_000;
            let radii: Vec<f32> = (0..n).filter_map(|_| p.sample_sr(ch, rng.uniform_f32())).collect();
            // Bin edges: quantiles of the sampled radii; expected mass per bin by quadrature.
            let mut sorted = radii.clone();
            sorted.sort_by(f32::total_cmp);
            let bins = 40;
            let edges: Vec<f64> = (0..=bins)
                .map(|b| {
                    if b == 0 {
                        1e-9
                    } else {
                        sorted[(b * (n - 1)) / bins] as f64 * if b == bins { 1.0001 } else { 1.0 }
                    }
                })
                .collect();
            let mut obs = vec![0.0f64; bins];
            let mut exp = vec![0.0f64; bins];
            for r in &radii {
                let b = edges.partition_point(|e| *e <= *r as f64).clamp(1, bins) - 1;
                obs[b] += 1.0;
            }
            for b in 0..bins {
                exp[b] = n as f64 * radial_integral(|r| p.pdf_sr(ch, r) as f64, edges[b].max(1e-9), edges[b + 1]);
            }
            let (chi2, dof, pv) = crate::goodness_of_fit::chi2_test(&obs, &exp, 5.0);
            assert!(pv > 1e-4, "profile {k} channel {ch}: chi2 {chi2} dof {dof} p {pv}");
        }
    }
}

/// `kdsubsurface`'s inversion: the coefficients it returns have the requested effective albedo
/// and the requested mean free path `1/σ_t`.
#[test]
fn subsurface_from_diffuse_round_trip() {
    let t = table();
    let kd = Rgb::new(0.1, 0.5, 0.85);
    let mfp = Rgb::new(0.5, 1.0, 2.0);
    let (s, a) = subsurface_from_diffuse(t, kd, mfp);
    for c in 0..3 {
        assert!((1.0 / (s[c] + a[c]) - mfp[c]).abs() < 1e-5);
        let rho = s[c] / (s[c] + a[c]);
        let rho_eff = crate::interpolation::catmull_rom(&t.rho_samples, &t.rho_eff, rho);
        assert!((rho_eff - kd[c]).abs() < 1e-4, "channel {c}: {rho_eff} vs {}", kd[c]);
    }
}

/// On a plane through the entry point the probe estimator `S_p / pdf` (0 when the probe misses,
/// as the two tangent axes always do on a plane) is unbiased for `∫ S_p dA = ρ_eff`: within 4
/// standard errors.
#[test]
fn probe_estimator_is_unbiased_on_a_plane() {
    let t = table();
    let profile = Profile::tabulated(t, Rgb::new(0.05, 0.2, 0.8), Rgb::new(2.0, 1.5, 1.0));
    let b = SeparableBssrdf {
        p: Vec3::new(0.3, -0.2, 0.0),
        ns: Vec3::Z,
        ss: Vec3::X,
        ts: Vec3::Y,
        eta: 1.33,
        material: 0,
        profile,
    };
    let mut rng = Rng::new(77);
    let n = 400_000;
    let (mut s, mut s2) = (Rgb::ZERO.as_dvec3(), Rgb::ZERO.as_dvec3());
    for _ in 0..n {
        let Some(pr) = b.probe(rng.uniform_f32(), Vec2::new(rng.uniform_f32(), rng.uniform_f32())) else { continue };
        // Intersect the segment with the plane z = 0.
        let d = pr.to - pr.from;
        if d.z.abs() < 1e-12 || pr.from.z * pr.to.z > 0.0 {
            continue;
        }
        let pi = pr.from + d * (-pr.from.z / d.z);
        let pdf = b.pdf_sp(pi, Vec3::Z);
        if pdf > 0.0 {
            let v = (b.sp(pi) / pdf).as_dvec3();
            s += v;
            s2 += v * v;
        }
    }
    let m = s / n as f64;
    let se = ((s2 / n as f64 - m * m) / n as f64).to_array().map(|v| v.max(0.0).sqrt());
    for c in 0..3 {
        let sigma_t = [2.05f32, 1.7, 1.8][c];
        let rho = [2.0f32, 1.5, 1.0][c] / sigma_t;
        let want = crate::interpolation::catmull_rom(&t.rho_samples, &t.rho_eff, rho) as f64;
        assert!((m[c] - want).abs() < 4.0 * se[c] + 2e-3 * want, "channel {c}: {} ± {} vs {want}", m[c], se[c]);
    }
}
