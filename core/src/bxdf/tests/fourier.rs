//! `fourier`: the reader against the generator's definition (`tools/make_fourier_bsdf.py`) at
//! the table's nodes, sampling against the pdf (chi-square), the sampled albedo against
//! quadrature, located errors for every malformed field, and a fuzz-style property test
//! (no input panics).

use super::*;
use crate::bxdf::fourier::{FourierError, FourierTable};
use proptest::prelude::*;
use std::path::Path;
use std::sync::OnceLock;

const LAYERED: &[u8] = include_bytes!("../../../../scenes/materials/layered.bsdf");
const MONO: &[u8] = include_bytes!("../../../../scenes/materials/mono.bsdf");

fn table(bytes: &'static [u8], cell: &'static OnceLock<FourierTable>) -> &'static FourierTable {
    cell.get_or_init(|| FourierTable::from_bytes(bytes, Path::new("test.bsdf")).expect("valid test table"))
}

fn layered() -> &'static FourierTable {
    static T: OnceLock<FourierTable> = OnceLock::new();
    table(LAYERED, &T)
}

fn mono() -> &'static FourierTable {
    static T: OnceLock<FourierTable> = OnceLock::new();
    table(MONO, &T)
}

/// The generator's BSDF (see `tools/make_fourier_bsdf.py`): diffuse plus an exponential lobe
/// about the mirror (reflection) or straight-through (transmission) direction.
struct Analytic {
    kappa: f64,
    kd: [f64; 3],
    ks: [f64; 3],
    kt: [f64; 3],
    ts: [f64; 3],
}

impl Analytic {
    fn f(&self, mu_i: f64, mu_o: f64, cos_phi: f64) -> [f64; 3] {
        let refl = mu_i * mu_o < 0.0;
        let (diff, lobe) = if refl { (self.kd, self.ks) } else { (self.kt, self.ts) };
        let k = self.kappa;
        let norm = k / (2.0 * std::f64::consts::PI * (1.0 - (-2.0 * k).exp()));
        let s = (1.0 - mu_i * mu_i).max(0.0).sqrt() * (1.0 - mu_o * mu_o).max(0.0).sqrt();
        let e = norm * (k * (s * cos_phi + (mu_i * mu_o).abs() - 1.0)).exp();
        [0, 1, 2].map(|c| diff[c] / std::f64::consts::PI + lobe[c] * e)
    }
}

const LAYERED_DEF: Analytic = Analytic {
    kappa: 6.0,
    kd: [0.25, 0.15, 0.05],
    ks: [0.20, 0.28, 0.35],
    kt: [0.25, 0.15, 0.05],
    ts: [0.20, 0.28, 0.35],
};

/// wo at elevation cosine `mu_o` (azimuth 0), and wi with `cos(−wi) = mu_i` at azimuth `phi`
/// from wo (pbrt-v3's `FourierBSDF` conventions).
fn pair(mu_i: f32, mu_o: f32, phi: f32) -> (Vec3, Vec3) {
    let so = (1.0 - mu_o * mu_o).max(0.0).sqrt();
    let si = (1.0 - mu_i * mu_i).max(0.0).sqrt();
    (Vec3::new(so, 0.0, mu_o), -Vec3::new(si * phi.cos(), si * phi.sin(), mu_i))
}

#[test]
fn fourier_table_header() {
    let t = layered();
    assert_eq!((t.n_channels, t.m_max, t.mu.len(), t.eta), (3, 12, 15, 1.5));
    assert_eq!((mono().n_channels, mono().mu.len(), mono().eta), (1, 11, 1.0));
    assert_eq!((t.mu[0], t.mu[7], t.mu[14]), (-1.0, 0.0, 1.0));
}

/// At the nodes the splines are the tabulated values, so `f` is the generator's BSDF up to
/// the series' truncation (coefficients below 1e-6 of the zeroth, or past 12) and f32
/// rounding; in radiance transport the transmission is scaled by 1/η² entering (µ_i > 0)
/// and η² leaving. Green is recovered from luminance, red and blue.
#[test]
fn fourier_matches_its_definition_at_the_nodes() {
    let t = layered();
    let mut checked = 0;
    for (i, &mu_i) in t.mu.iter().enumerate() {
        for &mu_o in &t.mu {
            if mu_i == 0.0 || mu_o == 0.0 {
                continue;
            }
            for phi in [0.0f32, 0.7, 2.0, 3.1] {
                let (wo, wi) = pair(mu_i, mu_o, phi);
                let want = LAYERED_DEF.f(mu_i as f64, mu_o as f64, phi.cos() as f64);
                let eta2 = if mu_i * mu_o > 0.0 {
                    if mu_i > 0.0 {
                        1.0 / (1.5f64 * 1.5)
                    } else {
                        1.5 * 1.5
                    }
                } else {
                    1.0
                };
                for mode in [TransportMode::Importance, TransportMode::Radiance] {
                    let got = Bxdf::Fourier(FourierBxdf::new(t, mode)).f(wo, wi);
                    let scale = if mode == TransportMode::Radiance { eta2 } else { 1.0 };
                    for c in 0..3 {
                        let w = want[c] * scale;
                        assert!(
                            (got[c] as f64 - w).abs() <= 2e-4 * w + 1e-5,
                            "node {i} mu_i {mu_i} mu_o {mu_o} phi {phi} channel {c} {mode:?}: {} vs {w}",
                            got[c]
                        );
                    }
                }
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 14 * 14 * 4);
}

#[test]
fn chi2_fourier() {
    for (k, (name, t)) in [("layered", layered()), ("mono", mono())].into_iter().enumerate() {
        let b = Bxdf::Fourier(FourierBxdf::new(t, TransportMode::Radiance));
        for (j, wo) in [dir(0.1, 0.3), dir(0.8, 1.0), dir(1.3, 4.0), -dir(0.5, 2.0)].into_iter().enumerate() {
            check_lobe(name, &b, wo, 5000 + (k * 10 + j) as u64);
        }
    }
}

/// The importance-sampled albedo equals the quadrature of `f |cos|` over the sphere (the pdf
/// covers `f`); without the radiance scaling of refraction it is at most 1.
#[test]
fn fourier_sampled_albedo_matches_quadrature() {
    for (k, (name, t)) in [("layered", layered()), ("mono", mono())].into_iter().enumerate() {
        let b = Bxdf::Fourier(FourierBxdf::new(t, TransportMode::Importance));
        for (j, wo) in [dir(0.2, 0.0), dir(1.2, 1.0), -dir(0.6, 0.5)].into_iter().enumerate() {
            let q = sphere_integral(900, 180, |wi| (b.f(wo, wi).x * wi.z.abs()) as f64);
            let mut rng = Pcg::new(5100 + (k * 10 + j) as u64);
            let n = 200_000;
            let (mut s, mut s2) = (0.0f64, 0.0f64);
            for _ in 0..n {
                if let Some(x) = b.sample_f(wo, rng.v2()) {
                    let w = (x.f.x * x.wi.z.abs() / x.pdf) as f64;
                    s += w;
                    s2 += w * w;
                }
            }
            let m = s / n as f64;
            let se = ((s2 / n as f64 - m * m).max(0.0) / n as f64).sqrt();
            assert!((m - q).abs() < 4.0 * se + 3e-3 * q, "{name} wo {wo}: sampled {m} ± {se} vs quadrature {q}");
            assert!(q < 1.0, "{name} wo {wo}: albedo {q}");
        }
    }
}

// --- malformed files -------------------------------------------------------------------------

fn err(bytes: &[u8]) -> FourierError {
    FourierTable::from_bytes(bytes, Path::new("bad.bsdf")).expect_err("malformed file accepted")
}

fn with_i32(at: usize, v: i32) -> Vec<u8> {
    let mut b = MONO.to_vec();
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
    b
}

fn with_f32(at: usize, v: f32) -> Vec<u8> {
    with_i32(at, v.to_bits() as i32)
}

#[test]
fn malformed_files_give_located_errors() {
    let n_mu = mono().mu.len();
    let cdf_at = 64 + 4 * n_mu;
    let series_at = cdf_at + 4 * n_mu * n_mu;
    let cases: Vec<(Vec<u8>, u64, &str)> = vec![
        (b"SCATFUN".to_vec(), 7, "64-byte header"),
        (MONO[..40].to_vec(), 40, "64-byte header"),
        (
            {
                let mut b = MONO.to_vec();
                b[3] = b'X';
                b
            },
            0,
            "SCATFUN",
        ),
        (
            {
                let mut b = MONO.to_vec();
                b[7] = 2;
                b
            },
            0,
            "version 1",
        ),
        (with_i32(8, 3), 8, "flags 1"),
        (with_i32(12, 1), 12, "nMu"),
        (with_i32(12, -5), 12, "nMu"),
        (with_i32(16, -1), 16, "nCoeffs"),
        (with_i32(20, 0), 20, "mMax"),
        (with_i32(24, 2), 24, "nChannels 1 or 3"),
        (with_i32(28, 4), 28, "nBases 1"),
        (with_f32(44, -1.0), 44, "eta"),
        (with_f32(44, f32::NAN), 44, "eta"),
        (with_f32(64 + 4 * 3, -0.9), 64 + 4 * 3, "mu[3] >= mu[2]"),
        (with_f32(64 + 4, f32::INFINITY), 64 + 4, "finite mu[1]"),
        (with_f32(cdf_at + 8, f32::NAN), (cdf_at + 8) as u64, "finite cdf[2]"),
        (with_i32(series_at + 8 * 5, -3), (series_at + 8 * 5) as u64, "offset"),
        (with_i32(series_at + 8 * 5 + 4, 1000), (series_at + 8 * 5) as u64, "length ≤ mMax"),
        (with_i32(series_at + 8 * 5, i32::MAX), (series_at + 8 * 5) as u64, "≤ nCoeffs"),
        (MONO[..MONO.len() - 200].to_vec(), (MONO.len() - 200) as u64, "bytes for the header's sizes"),
    ];
    for (bytes, offset, expected) in cases {
        let e = err(&bytes);
        assert_eq!(e.offset, Some(offset), "{e}");
        assert!(e.message.contains(expected), "{e} (wanted \"{expected}\")");
        assert!(e.to_string().contains("bad.bsdf") && e.to_string().contains(&format!("byte {offset}")), "{e}");
    }
}

/// A header claiming 2³⁰ nodes and coefficients in a 3 KB file is refused before anything is
/// allocated for it (the sizes are checked against the file's length).
#[test]
fn header_sizes_are_bounded_by_the_file() {
    for (at, v) in [(12usize, 1 << 30), (16, i32::MAX), (12, 46341)] {
        let e = err(&with_i32(at, v));
        assert!(e.message.contains("bytes for the header's sizes"), "{e}");
    }
    // And through the file reader: a missing file is an error naming it, not a panic.
    let e = FourierTable::read(Path::new("/nonexistent/x.bsdf")).unwrap_err();
    assert!(e.offset.is_none() && e.to_string().contains("x.bsdf"), "{e}");
}

fn exercise(t: FourierTable) {
    let t: &'static FourierTable = Box::leak(Box::new(t));
    let b = Bxdf::Fourier(FourierBxdf::new(t, TransportMode::Radiance));
    let mut rng = Pcg::new(1);
    for _ in 0..20 {
        let (wo, wi) =
            (crate::sampling::uniform_sample_sphere(rng.v2()), crate::sampling::uniform_sample_sphere(rng.v2()));
        let (f, p) = (b.f(wo, wi), b.pdf(wo, wi));
        assert!(f.is_finite() && p.is_finite() && p >= 0.0);
        if let Some(s) = b.sample_f(wo, rng.v2()) {
            assert!(s.wi.is_finite() && s.f.is_finite() && s.pdf > 0.0);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]
    /// Random corruption (overwritten bytes, truncation) of a valid file never panics: it is
    /// either an error located within the file or a table that evaluates and samples finitely.
    #[test]
    fn corrupt_files_never_panic(
        edits in proptest::collection::vec((0usize..4000, any::<u8>()), 0..12),
        cut in 0usize..4000,
    ) {
        let mut b = MONO.to_vec();
        for (at, v) in edits {
            if at < b.len() {
                b[at] = v;
            }
        }
        b.truncate(cut.max(1));
        match FourierTable::from_bytes(&b, Path::new("fuzz.bsdf")) {
            Ok(t) => exercise(t),
            Err(e) => prop_assert!(e.offset.is_some_and(|o| o <= b.len() as u64), "{}", e),
        }
    }
}
