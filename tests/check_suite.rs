//! `penumbra check --suite`: the binary on small suites of the default scene (32×32,
//! `directlighting`, `random` sampler). The biased cases' reference scene is the default one
//! with its light's radiance L scaled by 1.02: direct lighting is linear in L, so the
//! reference's expectation is exactly 2 % brighter. Unbiased cases are A/B pairs of independent
//! seeds (Welch) and converged references; the gate's false-alarm rate and power are measured
//! in tests/check_calibration.rs (0/100 false alarms at α = 0.01; a 1 % bias found with
//! probability 0.80 at 16 spp against a converged reference, 1.00 at 64 spp).

use penumbra::pipeline::DEFAULT_SCENE;
use std::path::{Path, PathBuf};
use std::process::Command;

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("penumbra-check-suite-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    std::fs::write(d.join("scene.pbrt"), DEFAULT_SCENE).unwrap();
    let bright = DEFAULT_SCENE.replace("\"rgb L\" [ 12 12 12 ]", "\"rgb L\" [ 12.24 12.24 12.24 ]");
    assert_ne!(bright, DEFAULT_SCENE, "the default scene's light changed: update this test");
    std::fs::write(d.join("bright.pbrt"), bright).unwrap();
    d
}

const DEFAULTS: &str = "[defaults]\nscene = \"scene.pbrt\"\nresolution = [32, 32]\nsampler = \"random\"\nintegrator = \"directlighting\"\nspp = 16\n\n";

struct Run {
    code: i32,
    stdout: String,
    stderr: String,
    junit: String,
    html: String,
}

fn run(d: &Path, suite: &str, extra: &[&str]) -> Run {
    let s = d.join("suite.toml");
    std::fs::write(&s, format!("{DEFAULTS}{suite}")).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(["check", "--suite"])
        .arg(&s)
        .args(["--threads", "2"])
        .args(extra)
        .output()
        .unwrap();
    let read = |n: &str| std::fs::read_to_string(d.join("check-out").join(n)).unwrap_or_default();
    Run {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into(),
        stderr: String::from_utf8_lossy(&out.stderr).into(),
        junit: read("junit.xml"),
        html: read("report.html"),
    }
}

/// Four unbiased cases pass (two A/B pairs of independent 16-spp renders, a 16-spp render
/// against a 512-spp reference made by --make-references, ltc against itself with a
/// tolerance: its only noise is the pixel samples' positions, so the reference has the same
/// seed — with independent seeds the 32×32 image means differ by 0.24 %); the reports list them all, with every image embedded.
#[test]
fn unbiased_cases_pass() {
    let d = dir("pass");
    let suite = "[[case]]\nname = \"ab-1\"\nseed = 1\n\n[[case]]\nname = \"ab-2\"\nseed = 2\n\n\
        [[case]]\nname = \"converged\"\nkind = \"converged\"\nseed = 3\nreference = \"refs/dl-512.exr\"\nreference_spp = 512\n\n\
        [[case]]\nname = \"ltc\"\nintegrator = \"ltc\"\nkind = \"tolerance\"\nrel = 0.001\nabs = 1e-6\nreference_seed = 0\n";
    let r = run(&d, suite, &["--make-references"]);
    assert_eq!(r.code, 0, "stdout:\n{}\nstderr:\n{}", r.stdout, r.stderr);
    assert_eq!(r.stdout.matches("PASS ").count(), 4, "{}", r.stdout);
    assert!(d.join("refs/dl-512.exr").exists() && d.join("refs/dl-512.stats.json").exists());
    assert!(r.junit.contains("tests=\"4\" failures=\"0\" errors=\"0\""), "{}", r.junit);
    assert_eq!(r.junit.matches("<testcase ").count(), 4);
    assert_eq!(r.html.matches("data:image/png;base64,").count(), 4 * 6, "six images per case");
    assert!(!r.html.contains("src=\"http"), "no external assets");
    let _ = std::fs::remove_dir_all(&d);
}

/// A 2 % brighter reference: the A/B Welch case at 64 spp, the converged case at 16 spp and
/// the tolerance case (ltc, 0.1 %) fail; exit status 2; JUnit and HTML say which and why;
/// the failing case's maps are written.
#[test]
fn a_two_percent_bias_fails() {
    let d = dir("fail");
    let suite = "[[case]]\nname = \"unbiased\"\nseed = 4\n\n\
        [[case]]\nname = \"ab-biased\"\nspp = 64\nseed = 1\nreference = \"refs/bright-64.exr\"\n\n\
        [[case]]\nname = \"conv-biased\"\nkind = \"converged\"\nseed = 2\nreference = \"refs/bright-512.exr\"\nreference_spp = 512\n\n\
        [[case]]\nname = \"ltc-biased\"\nintegrator = \"ltc\"\nkind = \"tolerance\"\nrel = 0.001\nreference = \"refs/bright-ltc.exr\"\n";
    // The references: rendered from bright.pbrt by a suite of their own (--make-references).
    let refs = "[[case]]\nname = \"r64\"\nscene = \"bright.pbrt\"\nspp = 64\nseed = 9\nreference = \"refs/bright-64.exr\"\n\n\
        [[case]]\nname = \"r512\"\nscene = \"bright.pbrt\"\nseed = 9\nreference = \"refs/bright-512.exr\"\nreference_spp = 512\n\n\
        [[case]]\nname = \"rltc\"\nscene = \"bright.pbrt\"\nintegrator = \"ltc\"\nkind = \"tolerance\"\nrel = 0.001\nreference_seed = 0\nreference = \"refs/bright-ltc.exr\"\n";
    let m = run(&d, refs, &["--make-references"]);
    assert_eq!(m.code, 0, "making the references: {}\n{}", m.stdout, m.stderr);
    let r = run(&d, suite, &[]);
    assert_eq!(r.code, 2, "stdout:\n{}\nstderr:\n{}", r.stdout, r.stderr);
    assert!(r.stdout.contains("PASS  unbiased"), "{}", r.stdout);
    for name in ["ab-biased", "conv-biased", "ltc-biased"] {
        assert!(r.stdout.contains(&format!("FAIL  {name}")), "{name}:\n{}", r.stdout);
        assert!(d.join(format!("check-out/{name}.pvalue.png")).exists());
    }
    assert!(r.junit.contains("tests=\"4\" failures=\"3\" errors=\"0\""), "{}", r.junit);
    assert_eq!(r.junit.matches("<failure message=").count(), 3);
    // Each failing case is marked twice: in the summary table and in its section's heading.
    assert_eq!(r.html.matches("class=\"FAIL\"").count(), 2 * 3);
    let _ = std::fs::remove_dir_all(&d);
}

/// A missing reference without --make-references is an error of that case (exit 4, JUnit
/// `<error>`), the other cases still run; a suite with an unknown key names file:line:column.
#[test]
fn errors_are_clear() {
    let d = dir("errors");
    let r =
        run(&d, "[[case]]\nname = \"missing\"\nreference = \"nope.exr\"\n\n[[case]]\nname = \"ok\"\nseed = 5\n", &[]);
    assert_eq!(r.code, 4, "{}\n{}", r.stdout, r.stderr);
    assert!(r.stdout.contains("ERROR missing") && r.stdout.contains("--make-references"), "{}", r.stdout);
    assert!(r.stdout.contains("PASS  ok"), "{}", r.stdout);
    assert!(r.junit.contains("<error message="), "{}", r.junit);
    let r = run(&d, "[[case]]\nname = \"x\"\nspp = 16\nsamples = 4\n", &[]);
    assert_eq!(r.code, 4);
    assert!(r.stderr.contains("suite.toml:11:1: unknown key `samples`"), "{}", r.stderr);
    let r = run(&d, "[[case]]\nname = \"x\"\nkind = \"tolerance\"\n", &[]);
    assert!(r.code == 4 && r.stderr.contains("needs `abs` and/or `rel`"), "{}", r.stderr);
    let _ = std::fs::remove_dir_all(&d);
}
