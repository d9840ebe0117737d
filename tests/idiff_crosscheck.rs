//! Cross-checks `penumbra diff` against OpenImageIO's `idiff` on generated
//! image pairs. Needs `idiff` (openimageio-tools, see `.ci/deps.sh`); without
//! it the test prints "SKIPPED: idiff not found" and returns, or fails when the `CI`
//! environment variable is set (as `.ci/run` sets it). When OIIO's Python
//! bindings are importable, the numbers are also compared at full precision
//! through `ImageBufAlgo.compare` (idiff prints only 6 significant digits).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use penumbra_core::image::{self, channel_names, Image};
use serde_json::Value;

fn find_on_path(name: &str) -> Option<PathBuf> {
    let mut dirs: Vec<PathBuf> =
        std::env::var_os("PATH").map(|p| std::env::split_paths(&p).collect()).unwrap_or_default();
    if let Some(home) = std::env::var_os("HOME") {
        dirs.push(Path::new(&home).join(".local/bin"));
    }
    dirs.into_iter().map(|d| d.join(name)).find(|p| p.is_file())
}

/// xorshift64*: deterministic noise without dependencies.
struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f32 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545F4914F6CDD1D) >> 40) as f32 + 0.5) / (1u64 << 24) as f32
    }
}

fn noise_image(w: u32, h: u32, names: &[&str], seed: u64, scale: f32) -> Image {
    let mut rng = Rng(seed);
    let n = w as usize * h as usize * names.len();
    let data = (0..n).map(|_| rng.uniform() * scale).collect();
    Image::from_data(w, h, channel_names(names), data).unwrap()
}

fn map(img: &Image, f: impl Fn(usize, f32) -> f32) -> Image {
    Image { data: img.data.iter().enumerate().map(|(i, &v)| f(i, v)).collect(), ..img.clone() }
}

#[derive(Debug)]
struct Idiff {
    mean: f64,
    rms: f64,
    psnr: f64,
    max: f64,
    at: Option<(u32, u32, String)>,
    code: i32,
}

fn value_after<'a>(out: &'a str, key: &str) -> &'a str {
    let line = out.lines().find(|l| l.trim_start().starts_with(key)).unwrap_or_else(|| panic!("no {key:?} in:\n{out}"));
    line.split_once('=').unwrap().1.split_whitespace().next().unwrap()
}

fn run_idiff(idiff: &Path, a: &Path, b: &Path) -> Idiff {
    let out = Command::new(idiff).arg("-v").arg(a).arg(b).output().expect("run idiff");
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    let max_line = text.lines().find(|l| l.trim_start().starts_with("Max error")).expect("max line");
    let at = max_line.split_once("@ (").map(|(_, rest)| {
        let inside = rest.split_once(')').unwrap().0;
        let parts: Vec<&str> = inside.split(", ").collect();
        (parts[0].parse().unwrap(), parts[1].parse().unwrap(), parts[2].to_string())
    });
    Idiff {
        mean: value_after(&text, "Mean error").parse().unwrap(),
        rms: value_after(&text, "RMS error").parse().unwrap(),
        psnr: value_after(&text, "Peak SNR").parse().unwrap(),
        max: value_after(&text, "Max error").parse().unwrap(),
        at,
        code: out.status.code().unwrap_or(-1),
    }
}

const PY: &str = r#"
import sys, OpenImageIO as oiio
for i in range(1, len(sys.argv), 2):
    a = oiio.ImageBuf(sys.argv[i]); b = oiio.ImageBuf(sys.argv[i + 1])
    r = oiio.ImageBufAlgo.compare(a, b, 1e-6, 1e-6)
    print(repr(float(r.meanerror)), repr(float(r.rms_error)), repr(float(r.PSNR)), repr(float(r.maxerror)), r.maxx, r.maxy, r.maxc)
"#;

/// Full-precision numbers from OIIO's `ImageBufAlgo.compare` through its
/// Python bindings, for all pairs in one process (OIIO is slow to start);
/// `None` if no interpreter can import them.
fn run_python(pairs: &[(&Path, &Path)]) -> Option<Vec<[f64; 7]>> {
    for py in ["python3", "/usr/bin/python3", "/usr/local/bin/python3"] {
        let mut cmd = Command::new(py);
        cmd.arg("-c").arg(PY);
        for (a, b) in pairs {
            cmd.arg(a).arg(b);
        }
        let Ok(out) = cmd.output() else { continue };
        if !out.status.success() {
            continue;
        }
        let text = String::from_utf8_lossy(&out.stdout);
        let rows: Vec<[f64; 7]> = text
            .lines()
            .map(|l| {
                let v: Vec<f64> = l.split_whitespace().map(|t| t.parse().unwrap()).collect();
                [v[0], v[1], v[2], v[3], v[4], v[5], v[6]]
            })
            .collect();
        assert_eq!(rows.len(), pairs.len(), "python output:\n{text}");
        return Some(rows);
    }
    None
}

fn run_penumbra(a: &Path, b: &Path) -> (Value, i32) {
    let out =
        Command::new(env!("CARGO_BIN_EXE_penumbra")).args(["diff", "--json"]).arg(a).arg(b).output().expect("run");
    let v: Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("bad JSON ({e}): {}", String::from_utf8_lossy(&out.stdout)));
    (v, out.status.code().unwrap_or(-1))
}

fn num(v: &Value, key: &str) -> f64 {
    match &v[key] {
        Value::Number(n) => n.as_f64().unwrap(),
        Value::String(s) => s.parse().unwrap(),
        other => panic!("{key}: {other}"),
    }
}

/// Agreement within `rel` relative (exact equality covers inf == inf).
fn agree(ours: f64, theirs: f64, rel: f64) -> bool {
    ours == theirs || (ours - theirs).abs() <= rel * theirs.abs().max(1e-300)
}

struct Case {
    name: &'static str,
    a: PathBuf,
    b: PathBuf,
    /// Whether idiff's exit code should equal ours (false where we deviate on purpose).
    same_exit: bool,
}

/// The image pairs, written to `dir`: generated ones in each format, and (when `oiiotool` is
/// found) files written by OIIO itself.
fn write_cases(dir: &Path) -> Vec<Case> {
    let p = |n: &str| dir.join(n);
    let (w, h) = (67u32, 45u32);
    let rgb = ["R", "G", "B"];
    let base = noise_image(w, h, &rgb, 1, 1.0);
    let mut cases = Vec::new();
    let mut add = |name: &'static str, a: &Image, b: &Image, ext: &str, same_exit: bool| {
        let (pa, pb) = (p(&format!("{name}_a.{ext}")), p(&format!("{name}_b.{ext}")));
        image::write(a, &pa).unwrap();
        image::write(b, &pb).unwrap();
        cases.push(Case { name, a: pa, b: pb, same_exit });
    };
    // Noise of amplitude 0.05 around the base.
    let noise = noise_image(w, h, &rgb, 2, 0.1);
    add("noise", &map(&base, |i, v| v + noise.data[i] - 0.05), &base, "exr", true);
    // A constant bias.
    add("bias", &map(&base, |_, v| v + 0.01), &base, "exr", true);
    // One hot pixel (HDR: PSNR's peak becomes 40).
    add("hot", &map(&base, |i, v| if i == (13 * w as usize + 50) * 3 + 1 { 40.0 } else { v }), &base, "exr", true);
    // Negative values: the peak uses |value|.
    add("negative", &map(&base, |_, v| -3.0 * v), &map(&base, |_, v| -3.0 * v + 0.001), "exr", true);
    // Identical images.
    add("same", &base, &base, "exr", true);
    // A single NaN (one mismatch: OIIO leaves it out of the sums, as we do, but
    // does not count it as failing; we fail it on purpose).
    add("nan", &map(&base, |i, v| if i == 100 { f32::NAN } else { v }), &base, "exr", false);
    // Ties in the max error: the first location wins.
    add("ties", &map(&base, |i, v| if i % 97 == 5 { v + 0.5 } else { v }), &base, "exr", true);
    // Extra channels, as the renderer writes them.
    let extra = noise_image(w, h, &["R", "G", "B", "variance.R", "variance.G", "variance.B"], 3, 2.0);
    add("extra", &map(&extra, |i, v| if i % 6 >= 3 { v * 1.5 } else { v }), &extra, "exr", true);
    // PNG vs PNG (8-bit sRGB written by us, compared on raw code values).
    add("png", &map(&base, |_, v| v * 0.8), &base, "png", true);
    // RGBA PNG with alpha < 1: OIIO premultiplies on read, and so do we.
    let rgba = noise_image(w, h, &["R", "G", "B", "A"], 4, 1.0);
    add("png-alpha", &map(&rgba, |i, v| if i % 4 == 3 { v } else { v * 0.7 }), &rgba, "png", true);
    // PFM vs PFM.
    add("pfm", &map(&base, |i, v| v + noise.data[i] * 0.1), &base, "pfm", true);
    // PFM vs EXR.
    {
        let (pa, pb) = (p("mixed_a.pfm"), p("mixed_b.exr"));
        image::write(&map(&base, |i, v| v * (1.0 + noise.data[i])), &pa).unwrap();
        image::write(&base, &pb).unwrap();
        cases.push(Case { name: "pfm-vs-exr", a: pa, b: pb, same_exit: true });
    }
    // Files written by OIIO itself: half EXR and 16-bit PNG.
    let oiiotool = find_on_path("oiiotool");
    if let Some(tool) = &oiiotool {
        // One oiiotool run (OIIO is slow to start): `-d` applies to the outputs after it.
        let ok = Command::new(tool)
            .arg(p("noise_a.exr"))
            .args(["-d", "half", "-o"])
            .arg(p("half_a.exr"))
            .args(["-d", "uint16", "-o"])
            .arg(p("png16_a.png"))
            .arg(p("noise_b.exr"))
            .args(["-d", "half", "-o"])
            .arg(p("half_b.exr"))
            .args(["-d", "uint16", "-o"])
            .arg(p("png16_b.png"))
            .status()
            .unwrap()
            .success();
        assert!(ok, "oiiotool failed");
        cases.push(Case { name: "half-exr", a: p("half_a.exr"), b: p("half_b.exr"), same_exit: true });
        cases.push(Case { name: "png16", a: p("png16_a.png"), b: p("png16_b.png"), same_exit: true });
    } else {
        common::skip_or_fail_in_ci("oiiotool not found: the half-EXR and 16-bit PNG cases");
    }
    cases
}

/// What idiff and penumbra say of each pair (concurrently: idiff takes about a second to
/// start), with OIIO's full-precision numbers when its Python bindings are importable.
fn run_all(idiff: &Path, cases: &[Case]) -> Vec<(Idiff, Value, i32, Option<[f64; 7]>)> {
    let pairs: Vec<(&Path, &Path)> = cases.iter().map(|c| (c.a.as_path(), c.b.as_path())).collect();
    std::thread::scope(|scope| {
        let python = scope.spawn(|| run_python(&pairs));
        let handles: Vec<_> = cases
            .iter()
            .map(|c| {
                scope.spawn(move || {
                    let theirs = run_idiff(idiff, &c.a, &c.b);
                    let (ours, code) = run_penumbra(&c.a, &c.b);
                    (theirs, ours, code)
                })
            })
            .collect();
        let python = python.join().expect("python thread");
        handles
            .into_iter()
            .enumerate()
            .map(|(i, h)| {
                let (theirs, ours, code) = h.join().expect("case thread");
                (theirs, ours, code, python.as_ref().map(|rows| rows[i]))
            })
            .collect::<Vec<_>>()
    })
}

/// Asserts that penumbra agrees with idiff on `c` (to idiff's printed precision) and with OIIO's
/// full-precision numbers when there are any; returns whether those were checked.
fn check_case(c: &Case, theirs: &Idiff, ours: &Value, code: i32, full: Option<[f64; 7]>) -> bool {
    println!(
        "{:>11}: idiff {:?} | ours mean {} rms {} psnr {} max {} @ ({}, {}, {}) exit {code}",
        c.name,
        theirs,
        ours["mean_error"],
        ours["rms_error"],
        ours["psnr"],
        ours["max_error"],
        ours["max_x"],
        ours["max_y"],
        ours["max_channel"]
    );
    // idiff prints 6 significant digits: agreement is up to that rounding.
    let printed = 5.000_1e-6;
    for (key, t) in
        [("mean_error", theirs.mean), ("rms_error", theirs.rms), ("psnr", theirs.psnr), ("max_error", theirs.max)]
    {
        assert!(agree(num(ours, key), t, printed), "{}: {key} ours {} vs idiff {t}", c.name, ours[key]);
    }
    match &theirs.at {
        Some((x, y, ch)) => {
            let at = (
                ours["max_x"].as_u64().unwrap() as u32,
                ours["max_y"].as_u64().unwrap() as u32,
                ours["max_channel"].as_str().unwrap(),
            );
            assert_eq!(at, (*x, *y, ch.as_str()), "{}: max location", c.name);
        }
        None => assert_eq!(num(ours, "max_error"), 0.0, "{}", c.name),
    }
    if c.same_exit {
        assert_eq!(code, theirs.code, "{}: exit code", c.name);
    }
    if let Some([mean, rms, psnr, max, x, y, ch]) = full {
        for (key, t) in [("mean_error", mean), ("rms_error", rms), ("psnr", psnr), ("max_error", max)] {
            assert!(agree(num(ours, key), t, 1e-6), "{}: {key} ours {} vs OIIO {t}", c.name, ours[key]);
        }
        // OIIO reports (0, 0, channel 0) when there is no error at all.
        assert_eq!((num(ours, "max_x"), num(ours, "max_y"), num(ours, "max_c")), (x, y, ch), "{}", c.name);
    }
    full.is_some()
}

#[test]
fn idiff_crosscheck() {
    let Some(idiff) = find_on_path("idiff") else {
        common::skip_or_fail_in_ci("idiff not found (install openimageio-tools; see .ci/deps.sh)");
        return;
    };
    let dir = std::env::temp_dir().join(format!("penumbra-idiff-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let cases = write_cases(&dir);
    let results = run_all(&idiff, &cases);
    let mut python_checked = 0;
    for (c, (theirs, ours, code, full)) in cases.iter().zip(results) {
        python_checked += check_case(c, &theirs, &ours, code, full) as usize;
    }
    // The deliberate deviation: a NaN fails with us, while idiff passes it.
    let nan = cases.iter().find(|c| c.name == "nan").unwrap();
    let (ours, code) = run_penumbra(&nan.a, &nan.b);
    assert_eq!((code, num(&ours, "nan_a"), num(&ours, "nonfinite_mismatched")), (2, 1.0, 1.0));
    println!(
        "cross-checked {} pairs against idiff (printed precision) and {python_checked} at 1e-6 relative through OIIO's Python bindings",
        cases.len()
    );
    if python_checked == 0 {
        common::skip_or_fail_in_ci("OpenImageIO's Python bindings not found: only idiff's 6-digit output was compared");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
