//! `penumbra diff A B`: OpenImageIO idiff's numbers and exit codes, plus
//! relative MSE, SMAPE, FLIP, NaN/Inf counts, JSON output and a heat map.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use crate::cli::format::{fmt_g, num, viridis};
use penumbra_core::image::{self, Image};
use penumbra_core::metrics::{self, CompareResults, MetricsError, Status, Thresholds};
use serde_json::{json, Value};

/// Exit code: images match within thresholds.
pub const EXIT_OK: u8 = 0;
/// Exit code: over the warning threshold.
pub const EXIT_WARN: u8 = 1;
/// Exit code: over the failure threshold.
pub const EXIT_FAIL: u8 = 2;
/// Exit code: different sizes or channel sets.
pub const EXIT_DIFFERENT_SIZE: u8 = 3;
/// Exit code: a file could not be read or written, or a bad option value.
pub const EXIT_FILE: u8 = 4;

#[derive(clap::Args)]
#[command(after_help = "\
Numbers follow OpenImageIO idiff: mean error = mean |A-B| over all values (all pixels and channels),
RMS error, PSNR = 20 log10(peak / RMS) with peak = max(1, largest |value| in either image),
max error and its first location; 'pixels over' counts pixels with any channel over the threshold.
NaN/Inf: matching non-finite pairs are skipped (as idiff); mismatched ones make the max error inf,
count as failing pixels and are kept out of the means (idiff would turn its means into NaN/inf).
Extra metrics over finite pairs: MSE, relative MSE = mean (A-B)^2/(B^2+0.01) (B is the reference),
SMAPE = mean 2|A-B|/(|A|+|B|), and LDR-FLIP of the sRGB-clamped images when built with it.

Exit codes (as idiff): 0 pass, 1 warning, 2 failure, 3 different sizes or channel sets,
4 unreadable file or bad option value; 64 command-line usage error (unknown option, missing or
malformed argument). Unlike idiff, which pads the smaller image with black,
images of different sizes (or with different channel names) are refused with code 3.
A cropped EXR (render --crop) keeps its place in the full frame as pbrt-v3 writes it: the crop is
the data window inside the full display window. Images of the same frame are compared on the pixels
both hold (a crop against the whole image compares the crop's pixels); --crop and reported
locations are in the frame's pixels.
PNGs are compared on their raw code values v/255 (not linearised; colour premultiplied by alpha),
as idiff reads them.")]
pub struct DiffArgs {
    /// Test image (EXR, PNG or PFM).
    pub a: PathBuf,
    /// Reference image (EXR, PNG or PFM).
    pub b: PathBuf,
    /// Warning threshold on the absolute difference of a value.
    #[arg(long, default_value_t = 1e-6)]
    pub warn: f32,
    /// Failure threshold on the absolute difference of a value.
    #[arg(long, default_value_t = 1e-6)]
    pub fail: f32,
    /// Allow this percentage of pixels over the warning threshold.
    #[arg(long, default_value_t = 0.0)]
    pub warnpercent: f32,
    /// Allow this percentage of pixels over the failure threshold.
    #[arg(long, default_value_t = 0.0)]
    pub failpercent: f32,
    /// Warn if any one value's error exceeds this.
    #[arg(long, default_value_t = f32::INFINITY)]
    pub hardwarn: f32,
    /// Fail if any one value's error exceeds this.
    #[arg(long, default_value_t = f32::INFINITY)]
    pub hardfail: f32,
    /// Print one JSON object instead of text (non-finite numbers as "inf"/"nan" strings).
    #[arg(long)]
    pub json: bool,
    /// Write the per-pixel error (max over channels): .png a colour-mapped heat map with a legend,
    /// .exr or .pfm the error values themselves (float, in R, G and B).
    #[arg(long, value_name = "OUT")]
    pub heatmap: Option<PathBuf>,
    /// Compare only pixels x0 <= x < x1, y0 <= y < y1 (of the full frame, for a cropped EXR).
    #[arg(long, value_name = "x0,x1,y0,y1")]
    pub crop: Option<String>,
    /// Compare only these channels (comma-separated names, e.g. R,G,B).
    #[arg(long, value_name = "R,G,B")]
    pub channels: Option<String>,
    /// Skip the FLIP computation.
    #[arg(long)]
    pub no_flip: bool,
}

struct Failure {
    code: u8,
    message: String,
}

fn fail(code: u8, message: impl Into<String>) -> Failure {
    Failure { code, message: message.into() }
}

pub fn run(args: DiffArgs) -> ExitCode {
    match run_inner(&args) {
        Ok(code) => ExitCode::from(code),
        Err(f) => {
            eprintln!("penumbra diff: {}", f.message);
            if args.json {
                println!("{}", json!({ "a": args.a, "b": args.b, "error": f.message, "exit_code": f.code }));
            }
            ExitCode::from(f.code)
        }
    }
}

fn parse_crop(s: &str) -> Result<[u32; 4], Failure> {
    let v: Vec<u32> = s
        .split(',')
        .map(|t| t.trim().parse::<u32>())
        .collect::<Result<_, _>>()
        .map_err(|_| fail(EXIT_FILE, format!("--crop {s:?}: expected four non-negative integers x0,x1,y0,y1")))?;
    match v[..] {
        [x0, x1, y0, y1] => Ok([x0, x1, y0, y1]),
        _ => Err(fail(EXIT_FILE, format!("--crop {s:?}: expected four integers x0,x1,y0,y1"))),
    }
}

fn metrics_failure(e: MetricsError) -> Failure {
    match e {
        MetricsError::Invalid(_) => fail(EXIT_FILE, e.to_string()),
        _ => fail(EXIT_DIFFERENT_SIZE, e.to_string()),
    }
}

fn select(img: Image, which: &Path, args: &DiffArgs) -> Result<Image, Failure> {
    let img = match &args.channels {
        Some(list) => {
            let names: Vec<&str> = list.split(',').map(str::trim).filter(|s| !s.is_empty()).collect();
            if names.is_empty() {
                return Err(fail(EXIT_FILE, "--channels: empty list"));
            }
            img.select_channels(&names).map_err(|e| fail(EXIT_DIFFERENT_SIZE, format!("{}: {e}", which.display())))?
        }
        None => img,
    };
    Ok(img)
}

/// The pixels both images hold, where they sit in their common frame ([`image::overlap`]: a
/// crop is compared with the same pixels of a whole image or of another crop); `--crop` is in
/// the frame's pixels. Returns the two parts and the compared window, or `None` where the images
/// are whole and `--crop` is not given (then nothing is cut).
fn overlap(
    a: Image,
    b: Image,
    args: &DiffArgs,
    crop: Option<[u32; 4]>,
) -> Result<(Image, Image, Option<image::Window>), Failure> {
    image::overlap(a, b, crop).map_err(|e| match e {
        image::OverlapError::DifferentFrames { a: fa, b: fb } => fail(
            EXIT_DIFFERENT_SIZE,
            format!(
                "{} is (part of) a {}×{} image, {} of a {}×{} image",
                args.a.display(),
                fa.0,
                fa.1,
                args.b.display(),
                fb.0,
                fb.1
            ),
        ),
        image::OverlapError::BadWithin { within: c, full: (fw, fh) } => fail(
            EXIT_FILE,
            format!("--crop [{},{})×[{},{}) is empty or outside the {fw}×{fh} image", c[0], c[1], c[2], c[3]),
        ),
        image::OverlapError::Disjoint => fail(
            EXIT_DIFFERENT_SIZE,
            format!("{} and {} (within --crop) share no pixel of their frame", args.a.display(), args.b.display()),
        ),
    })
}

fn run_inner(args: &DiffArgs) -> Result<u8, Failure> {
    let crop = args.crop.as_deref().map(parse_crop).transpose()?;
    for (name, v) in [("warn", args.warn), ("fail", args.fail), ("warnpercent", args.warnpercent)].into_iter().chain([
        ("failpercent", args.failpercent),
        ("hardwarn", args.hardwarn),
        ("hardfail", args.hardfail),
    ]) {
        if v.is_nan() || v < 0.0 {
            return Err(fail(EXIT_FILE, format!("--{name} must be a non-negative number")));
        }
    }
    if let Some(out) = &args.heatmap {
        if image::Format::from_extension(out).is_none() {
            return Err(fail(EXIT_FILE, format!("--heatmap {}: must end in .png, .exr or .pfm", out.display())));
        }
    }
    let a = image::read(&args.a).map_err(|e| fail(EXIT_FILE, e.to_string()))?;
    let b = image::read(&args.b).map_err(|e| fail(EXIT_FILE, e.to_string()))?;
    let a = select(a, &args.a, args)?;
    let b = select(b, &args.b, args)?;
    let (a, b, region) = overlap(a, b, args, crop)?;
    let t = Thresholds {
        warn: args.warn,
        fail: args.fail,
        warnpercent: args.warnpercent,
        failpercent: args.failpercent,
        hardwarn: args.hardwarn,
        hardfail: args.hardfail,
    };
    let mut r = metrics::compare(&a, &b, t.warn, t.fail).map_err(metrics_failure)?;
    let (ox, oy) = region.map(|w| (w[0], w[2])).unwrap_or((0, 0));
    let (max_ax, max_ay) = (r.max_x, r.max_y);
    // Locations in the full frame's pixels.
    r.max_x = (r.max_x as i64 + ox).max(0) as u32;
    r.max_y = (r.max_y as i64 + oy).max(0) as u32;
    let status = r.status(&t);
    let flip = flip_value(&a, &b, args.no_flip);
    let code = match status {
        Status::Pass => EXIT_OK,
        Status::Warn => EXIT_WARN,
        Status::Fail => EXIT_FAIL,
    };

    let heatmap = match &args.heatmap {
        Some(out) => {
            let errs = metrics::error_map(&a, &b).map_err(metrics_failure)?;
            let written = if image::Format::from_extension(out) == Some(image::Format::Png) {
                write_heatmap(out, a.width, a.height, &errs)
            } else {
                write_error_image(out, a.width, a.height, &errs)
            };
            let (lo, hi) = written.map_err(|e| fail(EXIT_FILE, e.to_string()))?;
            Some((out.clone(), lo, hi))
        }
        None => None,
    };

    if args.json {
        println!("{}", report_json(args, &r, &t, status, &flip, heatmap.as_ref(), region));
    } else {
        let values =
            |img: &Image| img.pixel(max_ax, max_ay).iter().map(|&v| fmt_g(v as f64, 6)).collect::<Vec<_>>().join(", ");
        let at_max = format!("{} vs {}", values(&a), values(&b));
        println!("Comparing \"{}\" and \"{}\"", args.a.display(), args.b.display());
        if let Some(w) = region {
            let f = a.frame_or_whole().full;
            println!("  pixels [{},{})×[{},{}) of the {}×{} frame", w[0], w[1], w[2], w[3], f.0, f.1);
        }
        print!("{}", report_text(&r, &t, &flip, &at_max));
        if let Some((out, lo, hi)) = &heatmap {
            println!("  heat map: {} (per-pixel max error, {} to {})", out.display(), fmt_g(*lo, 4), fmt_g(*hi, 4));
        }
        println!(
            "{}",
            match status {
                Status::Pass => "PASS",
                Status::Warn => "WARNING",
                Status::Fail => "FAILURE",
            }
        );
    }
    Ok(code)
}

/// FLIP's value or why it is missing.
type FlipValue = Result<f64, String>;

#[allow(unused_variables)]
fn flip_value(a: &Image, b: &Image, skip: bool) -> FlipValue {
    if skip {
        return Err("skipped (--no-flip)".into());
    }
    #[cfg(feature = "flip")]
    {
        metrics::flip_mean(a, b, 67.0).map_err(|e| e.to_string())
    }
    #[cfg(not(feature = "flip"))]
    {
        Err("not available in this build".into())
    }
}

fn percent(n: u64, of: u64) -> f64 {
    if of == 0 {
        0.0
    } else {
        100.0 * n as f64 / of as f64
    }
}

fn report_json(
    args: &DiffArgs,
    r: &CompareResults,
    t: &Thresholds,
    status: Status,
    flip: &FlipValue,
    heatmap: Option<&(PathBuf, f64, f64)>,
    region: Option<image::Window>,
) -> Value {
    json!({
        "a": args.a,
        "b": args.b,
        "region": region,
        "width": r.width,
        "height": r.height,
        "channels": r.channels,
        "npixels": r.npixels,
        "nvalues": r.nvalues,
        "mean_error": num(r.mean_error),
        "rms_error": num(r.rms_error),
        "psnr": num(r.psnr),
        "psnr_peak": num(r.psnr_peak),
        "max_error": num(r.max_error),
        "max_x": r.max_x,
        "max_y": r.max_y,
        "max_c": r.max_c,
        "max_channel": r.max_channel_name(),
        "nwarn": r.nwarn,
        "nwarn_percent": percent(r.nwarn, r.npixels),
        "nfail": r.nfail,
        "nfail_percent": percent(r.nfail, r.npixels),
        "nan_a": r.nan_a,
        "inf_a": r.inf_a,
        "nan_b": r.nan_b,
        "inf_b": r.inf_b,
        "nonfinite_matched": r.nonfinite_matched,
        "nonfinite_mismatched": r.nonfinite_mismatched,
        "finite_values": r.finite_values,
        "mse": num(r.mse),
        "relmse": num(r.relmse),
        "relmse_epsilon": metrics::RELMSE_EPSILON,
        "smape": num(r.smape),
        "flip": flip.as_ref().map(|&v| num(v)).unwrap_or(Value::Null),
        "flip_status": match flip { Ok(_) => "ok".to_string(), Err(e) => e.clone() },
        "thresholds": {
            "warn": num(t.warn as f64),
            "fail": num(t.fail as f64),
            "warnpercent": num(t.warnpercent as f64),
            "failpercent": num(t.failpercent as f64),
            "hardwarn": num(t.hardwarn as f64),
            "hardfail": num(t.hardfail as f64),
        },
        "heatmap": heatmap.map(|(p, lo, hi)| json!({ "path": p, "min": num(*lo), "max": num(*hi) })),
        "status": match status { Status::Pass => "pass", Status::Warn => "warn", Status::Fail => "fail" },
        "exit_code": status as u8,
    })
}

fn report_text(r: &CompareResults, t: &Thresholds, flip: &FlipValue, values_at_max: &str) -> String {
    let mut s = String::new();
    s += &format!("  Mean error = {}\n", fmt_g(r.mean_error, 6));
    s += &format!("  RMS error = {}\n", fmt_g(r.rms_error, 6));
    s += &format!("  Peak SNR = {}\n", fmt_g(r.psnr, 6));
    s += &format!("  Max error  = {}", fmt_g(r.max_error, 6));
    if r.max_error != 0.0 {
        s += &format!(" @ ({}, {}, {})  values are {values_at_max}", r.max_x, r.max_y, r.max_channel_name());
    }
    s += "\n";
    s += &format!(
        "  {} pixels ({}%) over {}\n",
        r.nwarn,
        fmt_g(percent(r.nwarn, r.npixels), 3),
        fmt_g(t.warn as f64, 6)
    );
    s += &format!(
        "  {} pixels ({}%) over {}\n",
        r.nfail,
        fmt_g(percent(r.nfail, r.npixels), 3),
        fmt_g(t.fail as f64, 6)
    );
    s += &format!(
        "  NaN/Inf values: A {} NaN, {} Inf; B {} NaN, {} Inf; {} mismatched, {} matched\n",
        r.nan_a, r.inf_a, r.nan_b, r.inf_b, r.nonfinite_mismatched, r.nonfinite_matched
    );
    s += &format!("  MSE = {}  relMSE = {}  SMAPE = {}\n", fmt_g(r.mse, 6), fmt_g(r.relmse, 6), fmt_g(r.smape, 6));
    match flip {
        Ok(v) => s += &format!("  FLIP (LDR, mean) = {}\n", fmt_g(*v, 6)),
        Err(e) => s += &format!("  FLIP: {e}\n"),
    }
    s
}

// ---------------------------------------------------------------------------
// Heat map
// ---------------------------------------------------------------------------

/// Colour for non-finite errors (a NaN or Inf against something else).
const NONFINITE_COLOR: [u8; 3] = [255, 0, 255];

/// 3×5 bitmap glyphs, one row per u8 (low 3 bits, bit 2 = leftmost column).
fn glyph(c: char) -> Option<[u8; 5]> {
    Some(match c {
        '0' => [0b111, 0b101, 0b101, 0b101, 0b111],
        '1' => [0b010, 0b110, 0b010, 0b010, 0b111],
        '2' => [0b111, 0b001, 0b111, 0b100, 0b111],
        '3' => [0b111, 0b001, 0b111, 0b001, 0b111],
        '4' => [0b101, 0b101, 0b111, 0b001, 0b001],
        '5' => [0b111, 0b100, 0b111, 0b001, 0b111],
        '6' => [0b111, 0b100, 0b111, 0b101, 0b111],
        '7' => [0b111, 0b001, 0b010, 0b010, 0b010],
        '8' => [0b111, 0b101, 0b111, 0b101, 0b111],
        '9' => [0b111, 0b101, 0b111, 0b001, 0b111],
        '.' => [0b000, 0b000, 0b000, 0b000, 0b010],
        '-' => [0b000, 0b000, 0b111, 0b000, 0b000],
        '+' => [0b000, 0b010, 0b111, 0b010, 0b000],
        'e' => [0b111, 0b101, 0b111, 0b100, 0b111],
        'i' => [0b010, 0b000, 0b010, 0b010, 0b010],
        'n' => [0b000, 0b110, 0b101, 0b101, 0b101],
        'f' => [0b011, 0b100, 0b110, 0b100, 0b100],
        'a' => [0b000, 0b111, 0b011, 0b101, 0b111],
        'm' => [0b000, 0b110, 0b111, 0b101, 0b101],
        ' ' => [0; 5],
        _ => return None,
    })
}

struct Canvas {
    w: u32,
    h: u32,
    rgb: Vec<u8>,
}

impl Canvas {
    fn put(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as u32) < self.w && (y as u32) < self.h {
            let o = (y as usize * self.w as usize + x as usize) * 3;
            self.rgb[o..o + 3].copy_from_slice(&c);
        }
    }

    /// Draws text with glyphs scaled by `s`; returns the width drawn.
    fn text(&mut self, x: i64, y: i64, s: i64, text: &str, c: [u8; 3]) -> i64 {
        let mut cx = x;
        for ch in text.chars() {
            if let Some(g) = glyph(ch) {
                for (row, bits) in g.iter().enumerate() {
                    for col in 0..3 {
                        if bits & (0b100 >> col) != 0 {
                            for dy in 0..s {
                                for dx in 0..s {
                                    self.put(cx + col * s + dx, y + row as i64 * s + dy, c);
                                }
                            }
                        }
                    }
                }
            }
            cx += 4 * s;
        }
        cx - x
    }
}

fn text_width(text: &str, s: i64) -> i64 {
    text.chars().count() as i64 * 4 * s
}

/// Writes the per-pixel error itself (R = G = B = the value the PNG heat map colours) as a
/// float image (.exr or .pfm). Returns the (min, max) finite per-pixel error.
fn write_error_image(out: &Path, w: u32, h: u32, errs: &[f32]) -> Result<(f64, f64), image::ImageError> {
    let finite = errs.iter().filter(|e| e.is_finite()).map(|&e| e as f64);
    let (lo, hi) = finite.fold((f64::INFINITY, 0.0f64), |(lo, hi), e| (lo.min(e), hi.max(e)));
    let data = errs.iter().flat_map(|&e| [e; 3]).collect();
    let img = Image::from_data(w, h, image::channel_names(&["R", "G", "B"]), data)?;
    image::write(&img, out)?;
    Ok((if lo.is_finite() { lo } else { 0.0 }, hi))
}

/// Writes the heat map: the error image on top, mapped linearly from 0 to the
/// largest finite per-pixel error through viridis (non-finite errors in
/// magenta), and under it a legend band with the colour bar and the min/max
/// error printed at its ends. Returns the (min, max) finite per-pixel error.
fn write_heatmap(out: &Path, w: u32, h: u32, errs: &[f32]) -> Result<(f64, f64), image::ImageError> {
    let finite = errs.iter().filter(|e| e.is_finite()).map(|&e| e as f64);
    let (lo, hi) = finite.fold((f64::INFINITY, 0.0f64), |(lo, hi), e| (lo.min(e), hi.max(e)));
    let lo = if lo.is_finite() { lo } else { 0.0 };
    // Legend: scale 2 glyphs (10 px tall), bar 10 px, margins.
    let s = if w >= 64 { 2 } else { 1 };
    let band = (10 + 5 * s + 9) as u32;
    let (cw, ch) = (w, h + band);
    let mut c = Canvas { w: cw, h: ch, rgb: vec![0u8; cw as usize * ch as usize * 3] };
    for y in 0..h {
        for x in 0..w {
            let e = errs[(y * w + x) as usize] as f64;
            let col = if !e.is_finite() {
                NONFINITE_COLOR
            } else if hi > 0.0 {
                viridis(e / hi)
            } else {
                viridis(0.0)
            };
            c.put(x as i64, y as i64, col);
        }
    }
    // Legend band: dark background, colour bar from 0 to max.
    let bar_y = h as i64 + 3;
    for x in 0..w {
        let col = viridis(if w > 1 { x as f64 / (w - 1) as f64 } else { 0.0 });
        for y in bar_y..bar_y + 10 {
            c.put(x as i64, y, col);
        }
    }
    let ty = bar_y + 13;
    let white = [255, 255, 255];
    let left = "0".to_string();
    let right = fmt_g(hi, 3);
    c.text(1, ty, s, &left, white);
    let rw = text_width(&right, s);
    c.text((w as i64 - rw).max(text_width(&left, s) + 4 * s), ty, s, &right, white);
    let mid = format!("min {}", fmt_g(lo, 3));
    let mw = text_width(&mid, s);
    if w as i64 > mw + rw + 16 * s {
        c.text((w as i64 - mw) / 2, ty, s, &mid, [200, 200, 200]);
    }
    let bytes = image::encode_png_rgb8(cw, ch, &c.rgb, out)?;
    image::write_atomic(out, |wr| wr.write_all(&bytes))
        .map(|_| (lo, hi))
        .map_err(|e| image::ImageError::Invalid(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crop_parsing() {
        assert_eq!(parse_crop("1,5, 2,9").ok(), Some([1, 5, 2, 9]));
        assert!(parse_crop("1,2,3").is_err());
        assert!(parse_crop("a,b,c,d").is_err());
        assert!(parse_crop("-1,2,3,4").is_err());
    }
}
