//! `penumbra diff` behaviour that does not need OpenImageIO: exit codes, JSON,
//! crop/channel selection and the heat map.

use std::path::{Path, PathBuf};
use std::process::Command;

use penumbra_core::image::{self, channel_names, Image};
use serde_json::Value;

fn dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("penumbra-diffcli-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn ramp(w: u32, h: u32) -> Image {
    let data = (0..w * h * 3).map(|i| (i % 17) as f32 / 16.0).collect();
    Image::from_data(w, h, channel_names(&["R", "G", "B"]), data).unwrap()
}

fn diff(args: &[&str], a: &Path, b: &Path) -> (i32, Value, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .arg("diff")
        .args(args)
        .arg(a)
        .arg(b)
        .output()
        .expect("run penumbra");
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    let json = serde_json::from_str(&stdout).unwrap_or(Value::Null);
    (out.status.code().unwrap_or(-1), json, stdout)
}

#[test]
fn exit_codes_and_json() {
    let d = dir("codes");
    let (a, b, small, junk) = (d.join("a.exr"), d.join("b.exr"), d.join("s.exr"), d.join("junk.png"));
    let base = ramp(8, 6);
    image::write(&base, &a).unwrap();
    let mut other = base.clone();
    other.set(5, 4, 2, other.get(5, 4, 2) + 0.25);
    image::write(&other, &b).unwrap();
    image::write(&ramp(8, 5), &small).unwrap();
    std::fs::write(&junk, b"\x89PNG\r\n\x1a\n truncated").unwrap();

    assert_eq!(diff(&[], &a, &a).0, 0);
    let (code, j, _) = diff(&["--json"], &a, &b);
    assert_eq!(code, 2);
    assert_eq!((j["max_x"].as_u64(), j["max_y"].as_u64(), j["max_channel"].as_str()), (Some(5), Some(4), Some("B")));
    assert_eq!(j["nfail"].as_u64(), Some(1));
    assert_eq!(j["status"], "fail");
    // One pixel in 48 is 2.08%: allowed by --failpercent 3, then only a warning.
    assert_eq!(diff(&["--failpercent", "3"], &a, &b).0, 1);
    assert_eq!(diff(&["--failpercent", "3", "--warnpercent", "3"], &a, &b).0, 0);
    assert_eq!(diff(&["--warn", "0.3", "--fail", "0.3"], &a, &b).0, 0);
    assert_eq!(diff(&["--warn", "0.1", "--fail", "0.3"], &a, &b).0, 1);
    assert_eq!(diff(&["--fail", "0.3", "--warn", "0.3", "--hardfail", "0.2"], &a, &b).0, 2);
    // Sizes differ: 3, refused; unreadable files: 4 (with a JSON error object).
    assert_eq!(diff(&[], &a, &small).0, 3);
    let (code, j, _) = diff(&["--json"], &a, &junk);
    assert_eq!((code, j["exit_code"].as_u64()), (4, Some(4)));
    assert!(j["error"].as_str().unwrap().contains("junk.png"));
    assert_eq!(diff(&[], &a, &d.join("missing.exr")).0, 4);
    // Crop excluding the changed pixel passes; including it reports original coordinates.
    assert_eq!(diff(&["--crop", "0,4,0,6"], &a, &b).0, 0);
    let (code, j, _) = diff(&["--json", "--crop", "4,8,3,6"], &a, &b);
    assert_eq!((code, j["max_x"].as_u64(), j["max_y"].as_u64()), (2, Some(5), Some(4)));
    assert_eq!(diff(&["--crop", "0,9,0,6"], &a, &b).0, 4);
    // Channel selection.
    assert_eq!(diff(&["--channels", "R,G"], &a, &b).0, 0);
    assert_eq!(diff(&["--channels", "B"], &a, &b).0, 2);
    assert_eq!(diff(&["--channels", "Z"], &a, &b).0, 3);
    // A NaN fails, and is counted rather than averaged.
    let mut nan = base.clone();
    nan.set(1, 1, 0, f32::NAN);
    let n = d.join("nan.pfm");
    image::write(&nan, &n).unwrap();
    let (code, j, _) = diff(&["--json"], &n, &a);
    assert_eq!((code, j["nan_a"].as_u64(), j["max_error"].as_str()), (2, Some(1), Some("inf")));
    assert_eq!(j["mean_error"].as_f64(), Some(0.0));
    std::fs::remove_dir_all(d).unwrap();
}

#[test]
fn text_output_is_idiff_like() {
    let d = dir("text");
    let (a, b) = (d.join("a.pfm"), d.join("b.pfm"));
    let base = ramp(4, 4);
    image::write(&base, &a).unwrap();
    image::write(&Image { data: base.data.iter().map(|v| v + 0.1).collect(), ..base.clone() }, &b).unwrap();
    let (code, _, out) = diff(&[], &a, &b);
    assert_eq!(code, 2);
    for key in [
        "  Mean error = 0.1",
        "  RMS error = 0.1",
        "  Peak SNR = ",
        "  Max error  = 0.1",
        "16 pixels (100%) over 1e-06",
        "FAILURE",
    ] {
        assert!(out.contains(key), "missing {key:?} in\n{out}");
    }
    std::fs::remove_dir_all(d).unwrap();
}

#[test]
fn heatmap_is_written_with_legend() {
    let d = dir("heat");
    let (a, b, h) = (d.join("a.exr"), d.join("b.exr"), d.join("heat.png"));
    let base = ramp(80, 40);
    image::write(&base, &a).unwrap();
    // Error grows left to right.
    let mut other = base.clone();
    for y in 0..40 {
        for x in 0..80 {
            for c in 0..3 {
                other.set(x, y, c, base.get(x, y, c) + x as f32 * 0.01);
            }
        }
    }
    image::write(&other, &b).unwrap();
    let (code, j, _) = diff(&["--json", "--heatmap", h.to_str().unwrap()], &a, &b);
    assert_eq!(code, 2);
    let hm = image::read(&h).unwrap();
    assert_eq!(hm.width, 80);
    assert!(hm.height > 40, "legend band below the map");
    assert!((j["heatmap"]["max"].as_f64().unwrap() - 0.79).abs() < 1e-5);
    // Left column is the colormap's low end, right column its high end (viridis: dark purple to yellow).
    let (left, right) = (hm.pixel(0, 10), hm.pixel(79, 10));
    assert!(left[2] > left[1] && right[0] > right[2] && right[1] > left[1], "{left:?} {right:?}");
    // An unwritable heat-map path is an error (code 4) and leaves no file.
    let bad = d.join("no/such/dir/heat.png");
    assert_eq!(diff(&["--heatmap", bad.to_str().unwrap()], &a, &b).0, 4);
    std::fs::remove_dir_all(d).unwrap();
}
