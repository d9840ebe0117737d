//! `penumbra check`'s gate, calibrated on real renders (through the library, images kept in
//! memory): its false-alarm rate on an unchanged integrator over many seeds, and its power
//! against a 1 % and a 0.3 % bias and a local defect at stated samples per pixel.
//!
//! Scene: the embedded default scene (a quad light, a cube and its soft shadow on a glossy
//! plane), `directlighting`, the `random` sampler (independent samples: the case the per-value
//! variances describe exactly), box filter, 32×32 pixels.

mod common;

use common::{render_desc, Opts};
use penumbra::check::gate::{self, GateOptions, RefMode, Side};
use penumbra::pipeline::DEFAULT_SCENE;

struct Renders {
    desc: penumbra_parser::SceneDescription,
}

impl Renders {
    fn new() -> Renders {
        let parsed = penumbra_parser::parse_str(DEFAULT_SCENE, "<default>", None).expect("default scene");
        Renders { desc: parsed.scene }
    }

    fn side(&self, spp: u32, seed: u64) -> Side {
        let o =
            Opts { spp: Some(spp), seed, resolution: Some((32, 32)), sampler: Some("random"), ..Default::default() };
        let r = render_desc(&self.desc, &o);
        Side::from_image(&r.channels, Some(r.spp as f64)).expect("R G B and variance")
    }
}

fn scaled(s: &Side, k: f32) -> Side {
    Side { mean: s.mean.iter().map(|v| v * k).collect(), ..s.clone() }
}

/// The test image with pixels 8 ≤ x < 12, 8 ≤ y < 12 scaled by `k` (a 4×4 defect).
fn defect(s: &Side, k: f32) -> Side {
    let mut d = s.clone();
    for y in 8..12 {
        for x in 8..12 {
            for c in 0..3 {
                d.mean[(y * s.width + x) * 3 + c] *= k;
            }
        }
    }
    d
}

/// Fraction of the (test, reference) pairs the gate fails.
fn rate(pairs: &[(Side, &Side)], o: &GateOptions) -> f64 {
    let failed = pairs.iter().filter(|(t, r)| !gate::run(t, r, o).expect("gate").passed).count();
    failed as f64 / pairs.len() as f64
}

/// The same estimator at `k` times the samples: the mean of `k` independent renders (their
/// variance of the mean divided by `k`), what one render at k·spp gives under the `random`
/// sampler.
fn merged(renders: &[Side]) -> Side {
    let k = renders.len() as f32;
    let mut out = renders[0].clone();
    let n = out.mean.len();
    out.mean = (0..n).map(|i| renders.iter().map(|r| r.mean[i]).sum::<f32>() / k).collect();
    out.variance =
        Some((0..n).map(|i| renders.iter().map(|r| r.variance.as_ref().unwrap()[i]).sum::<f32>() / (k * k)).collect());
    out.spp = renders[0].spp.map(|s| s * k as f64);
    out
}

#[test]
fn false_alarms_and_power() {
    let r = Renders::new();
    let alpha = GateOptions::default().alpha;
    let welch = GateOptions::default();
    let converged = GateOptions { mode: RefMode::Converged, ..Default::default() };
    // 101 renders at 16 spp: 100 Welch comparisons of consecutive ones (each pair independent
    // renders); each against a 2048-spp reference treated as converged (1/128 of their noise).
    let a16: Vec<Side> = (0..101).map(|s| r.side(16, s + 1)).collect();
    let conv = r.side(2048, 1_000_000);
    // 16 renders at 256 spp (each the mean of 16 at 16 spp would do as well; rendered whole).
    let a256: Vec<Side> = (0..16).map(|s| r.side(256, 5_000 + s)).collect();

    let consecutive =
        |f: &dyn Fn(&Side) -> Side| -> Vec<(Side, &Side)> { a16.windows(2).map(|w| (f(&w[0]), &w[1])).collect() };
    let vs_conv = |tests: &[Side], f: &dyn Fn(&Side) -> Side| -> Vec<(Side, &Side)> {
        tests.iter().map(|t| (f(t), &conv)).collect()
    };
    let same = |s: &Side| s.clone();
    let fa_welch = rate(&consecutive(&same), &welch);
    let fa_conv = rate(&vs_conv(&a16[..100], &same), &converged);
    let fa_welch256 = rate(&vs_conv(&a256, &same), &welch);
    let p1_welch = rate(&consecutive(&|s| scaled(s, 1.01)), &welch);
    let p1_conv = rate(&vs_conv(&a16[..100], &|s| scaled(s, 1.01)), &converged);
    let p03_welch256 = rate(&vs_conv(&a256, &|s| scaled(s, 1.003)), &welch);
    let pd_welch = rate(&consecutive(&|s| defect(s, 0.8)), &welch);
    let pd_conv = rate(&vs_conv(&a16[..100], &|s| defect(s, 0.8)), &converged);
    // 25 images at 64 spp, each the mean of 4 of the 16-spp renders.
    let a64: Vec<Side> = a16[..100].chunks(4).map(merged).collect();
    let fa_conv64 = rate(&vs_conv(&a64, &same), &converged);
    let p1_conv64 = rate(&vs_conv(&a64, &|s| scaled(s, 1.01)), &converged);
    let p03_conv64 = rate(&vs_conv(&a64, &|s| scaled(s, 1.003)), &converged);
    let pd_conv64 = rate(&vs_conv(&a64, &|s| defect(s, 0.8)), &converged);
    eprintln!("check calibration: default scene 32x32, directlighting, random sampler, family-wise alpha {alpha}");
    eprintln!(
        "  false alarms: Welch 16 vs 16 spp {fa_welch:.3} (100 pairs); against the 2048-spp reference as converged: \
         16 spp {fa_conv:.3} (100), 64 spp {fa_conv64:.3} (25); Welch 256 vs 2048 spp {fa_welch256:.3} (16)"
    );
    eprintln!("  power, 1 % bias: Welch 16 vs 16 spp {p1_welch:.2}; converged reference: 16 spp {p1_conv:.2}, 64 spp {p1_conv64:.2}");
    eprintln!(
        "  power, 0.3 % bias: converged reference, 64 spp {p03_conv64:.2}; Welch 256 vs 2048 spp {p03_welch256:.2}"
    );
    eprintln!("  power, 4x4 pixels 20 % darker: Welch 16 vs 16 spp {pd_welch:.2}; converged reference: 16 spp {pd_conv:.2}, 64 spp {pd_conv64:.2}");
    // The calibration: no more false alarms than alpha allows (these are fixed seeds: the
    // rates are what the renderer and the gate give, not a random draw per run).
    assert!(fa_welch <= alpha && fa_conv <= alpha, "false-alarm rate above alpha: {fa_welch}, {fa_conv}");
    assert!(fa_conv64 == 0.0 && fa_welch256 == 0.0, "false alarms: {fa_conv64}, {fa_welch256}");
    // The power it is documented with (docs/check.md).
    assert!(
        p1_conv64 >= 0.9 && p03_welch256 >= 0.9,
        "power: 1 % at 64 spp {p1_conv64}, 0.3 % at 256 spp {p03_welch256}"
    );
    assert!(p1_conv >= 0.6 && pd_conv64 >= 0.5, "power: 1 % at 16 spp {p1_conv}, defect at 64 spp {pd_conv64}");
}
