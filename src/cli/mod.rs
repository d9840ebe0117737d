//! What every subcommand shares, so that flags, ranges and messages are one: the render flags
//! ([`RenderFlags`], flattened into `render`, `sweep` and `stability`), the `--spp` range
//! ([`spp_parser`]), the parsers of `--crop` and `--resolution`, Ctrl-C handling, writing an image
//! with its `stats.json`, warnings printed once, and the reports' number formats ([`format`]).

pub mod format;

use penumbra_core::image::Image;
use penumbra_core::scene::Crop;
use penumbra_parser::{DiagSink, SceneDescription};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// The flags that say how a scene renders, the same in every subcommand that renders.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct RenderFlags {
    /// Integrator parameter `key=value` (repeatable): one the integrator declares (`penumbra
    /// render --help` lists them), its value of the declared type; with several integrators,
    /// each must declare it.
    #[arg(long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,
    /// Worker threads (default: all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Sampler seed (`stability`: the same for the base and every variant; `sweep
    /// --reference-spp` renders its reference with --reference-seed).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Film resolution `WxH` (default: the scene's; `stability`: the scene's aspect with its
    /// longer side 48 pixels).
    #[arg(long, value_name = "WxH", value_parser = parse_resolution)]
    pub resolution: Option<(u32, u32)>,
}

/// The range of every samples-per-pixel flag (`--spp`, `--reference-spp`): 1..=2^24, as the
/// scene's sampler accepts.
pub fn spp_parser() -> clap::builder::RangedI64ValueParser<u32> {
    clap::value_parser!(u32).range(1..=penumbra_core::sampler::MAX_SAMPLES)
}

/// `--crop x0,x1,y0,y1`: pixel bounds (integers, half-open) or, if any value has a decimal
/// point, fractions of the image as pbrt-v3's `cropwindow` (a clap value parser: a malformed
/// value is a usage error).
pub fn parse_crop(s: &str) -> Result<Crop, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 4 {
        return Err(format!("--crop expects 4 comma-separated values x0,x1,y0,y1, got \"{s}\""));
    }
    if parts.iter().any(|p| p.contains('.')) {
        let v: Result<Vec<f32>, _> = parts.iter().map(|p| p.parse::<f32>()).collect();
        let v = v.map_err(|_| format!("--crop expects x0,x1,y0,y1: \"{s}\" is not four numbers"))?;
        Ok(Crop::Fraction([v[0], v[1], v[2], v[3]]))
    } else {
        let v: Result<Vec<i32>, _> = parts.iter().map(|p| p.parse::<i32>()).collect();
        let v = v.map_err(|_| format!("--crop expects x0,x1,y0,y1: \"{s}\" is not four integers"))?;
        Ok(Crop::Pixels([v[0], v[1], v[2], v[3]]))
    }
}

/// `--crop` as it is recorded in reports: `x0,x1,y0,y1` (fractions keep their decimal point).
pub fn crop_text(c: Option<Crop>) -> Option<String> {
    c.map(|c| match c {
        Crop::Pixels([a, b, c, d]) => format!("{a},{b},{c},{d}"),
        Crop::Fraction([a, b, c, d]) => format!("{a:?},{b:?},{c:?},{d:?}"),
    })
}

/// The film's full resolution: `--resolution`, else the scene's (pbrt-v3's default 1280×720).
pub fn full_resolution(scene: &SceneDescription, resolution: Option<(u32, u32)>) -> (i32, i32) {
    match resolution {
        Some((w, h)) => (w as i32, h as i32),
        None => {
            let p = &scene.film.params;
            (p.get_one_int("xresolution", 1280), p.get_one_int("yresolution", 720))
        }
    }
}

/// A `--crop` must lie inside the image and contain a pixel (as `diff --crop`): not clamped.
pub fn check_crop(crop: Crop, (w, h): (i32, i32)) -> Result<(), String> {
    let bad = match crop {
        Crop::Pixels([x0, x1, y0, y1]) => !(0 <= x0 && x0 < x1 && x1 <= w && 0 <= y0 && y0 < y1 && y1 <= h),
        Crop::Fraction([x0, x1, y0, y1]) => !(0.0 <= x0 && x0 < x1 && x1 <= 1.0 && 0.0 <= y0 && y0 < y1 && y1 <= 1.0),
    };
    if !bad || w <= 0 || h <= 0 {
        // (An out-of-range film resolution is the scene build's located error.)
        return Ok(());
    }
    Err(match crop {
        Crop::Pixels([x0, x1, y0, y1]) => format!(
            "--crop {x0},{x1},{y0},{y1} is outside the {w}x{h} image: pixel bounds need 0 <= x0 < x1 <= {w} and 0 <= y0 < y1 <= {h}"
        ),
        Crop::Fraction([x0, x1, y0, y1]) => format!(
            "--crop {x0},{x1},{y0},{y1}: fractions need 0 <= x0 < x1 <= 1 and 0 <= y0 < y1 <= 1"
        ),
    })
}

/// `--resolution WxH`, each side in 1..=65536 (a clap value parser: a malformed value is a
/// usage error).
pub fn parse_resolution(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("--resolution expects WxH with W and H in 1..=65536 (e.g. 64x48), got \"{s}\"");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let w: u32 = w.trim().parse().map_err(|_| bad())?;
    let h: u32 = h.trim().parse().map_err(|_| bad())?;
    if w == 0 || h == 0 || w > 1 << 16 || h > 1 << 16 {
        return Err(bad());
    }
    Ok((w, h))
}

/// `--resolution` as it is recorded in reports: `WxH`.
pub fn resolution_text(r: Option<(u32, u32)>) -> Option<String> {
    r.map(|(w, h)| format!("{w}x{h}"))
}

pub fn has_extension(path: &Path, ext: &str) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case(ext))
}

/// `out.exr` → `out.stats.json`.
pub fn stats_path(image: &Path) -> PathBuf {
    let stem = image.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "penumbra".into());
    image.with_file_name(format!("{stem}.stats.json"))
}

/// A flag set by the first Ctrl-C (renders stop at the next tile, then exit with status 130,
/// as a shell reports SIGINT); a second one exits with 130 at once.
pub fn cancel_on_interrupt() -> Arc<AtomicBool> {
    let cancel = Arc::new(AtomicBool::new(false));
    let c = cancel.clone();
    let _ = ctrlc::set_handler(move || {
        if c.swap(true, Ordering::SeqCst) {
            std::process::exit(crate::exit::INTERRUPTED.into());
        }
    });
    cancel
}

/// Writes the image (R, G, B only unless it is an EXR; a PNG with `exposure` stops), then `stats`
/// beside it; returns the image written.
pub fn write_outputs(
    mut image: Image,
    output: &Path,
    exposure: f32,
    stats: &serde_json::Value,
) -> Result<Image, String> {
    if !has_extension(output, "exr") && image.channels.len() > 3 {
        image = image.select_channels(&["R", "G", "B"]).map_err(|e| e.to_string())?;
    }
    if has_extension(output, "png") {
        penumbra_core::image::write_png(&image, output, exposure)
    } else {
        penumbra_core::image::write(&image, output)
    }
    .map_err(|e| e.to_string())?;
    let sp = stats_path(output);
    let text = serde_json::to_string_pretty(stats).unwrap_or_default();
    penumbra_core::image::write_atomic(&sp, |w| w.write_all(text.as_bytes())).map_err(|e| e.to_string())?;
    Ok(image)
}

/// Prints the warnings of `w` not printed before.
pub fn print_new_warnings(w: &DiagSink, seen: &mut BTreeSet<String>) {
    for d in w.take() {
        let text = d.to_string();
        if seen.insert(text.clone()) {
            eprint!("{text}");
        }
    }
}
