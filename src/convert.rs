//! `penumbra convert IN OUT [--exposure S]`: any image penumbra reads to any it writes, so a
//! result can be looked at without another tool. A PNG input is decoded from sRGB (`--linear`:
//! its code values taken as linear), the inverse of the sRGB encoding of a PNG output.

use penumbra::output::{self, MissingDir};
use penumbra_core::image::{self, Format};
use penumbra_core::spectrum::srgb_decode;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct ConvertArgs {
    /// Input image (.exr, .png or .pfm; a PNG's colour is decoded from sRGB to linear unless
    /// --linear, so PNG -> EXR -> PNG is exact).
    pub input: PathBuf,
    /// Output image (.exr, .png or .pfm; a PNG gets R, G, B, sRGB-encoded and clamped to [0, 1]).
    pub output: PathBuf,
    /// Multiply R, G, B (or Y) by 2^S (stops; e.g. -1.65 for an AO image, which is π-scaled).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
    /// PNG input: take its code values as linear (value = code / max) instead of decoding sRGB.
    #[arg(long, conflicts_with = "srgb")]
    pub linear: bool,
    /// PNG input: decode its colour from sRGB (the default; the PNGs penumbra writes are sRGB).
    #[arg(long)]
    pub srgb: bool,
}

pub fn run(args: ConvertArgs) -> ExitCode {
    match convert(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn convert(args: &ConvertArgs) -> Result<(), String> {
    let format = Format::from_extension(&args.output)
        .ok_or_else(|| format!("{}: output must end in .exr, .png or .pfm", args.output.display()))?;
    output::prepare(&args.output, MissingDir::Fail)?;
    let mut img = image::read(&args.input).map_err(|e| e.to_string())?;
    let png_input =
        std::fs::read(&args.input).ok().and_then(|b| Format::detect(&b, &args.input)).is_some_and(|f| f == Format::Png);
    if png_input && !args.linear {
        // Colour only: alpha is linear in a PNG.
        let colour: Vec<usize> = ["R", "G", "B", "Y"].iter().filter_map(|c| img.channel_index(c)).collect();
        let n = img.nchannels();
        for p in img.data.chunks_exact_mut(n) {
            for &c in &colour {
                p[c] = srgb_decode(p[c]);
            }
        }
    }
    if format == Format::Png {
        return image::write_png(&img, &args.output, args.exposure).map_err(|e| e.to_string());
    }
    if args.exposure != 0.0 {
        let gain = args.exposure.exp2();
        let colour: Vec<usize> = ["R", "G", "B", "Y"].iter().filter_map(|c| img.channel_index(c)).collect();
        let n = img.nchannels();
        for p in img.data.chunks_exact_mut(n) {
            for &c in &colour {
                p[c] *= gain;
            }
        }
    }
    if format == Format::Pfm && img.nchannels() > 3 {
        img = img.select_channels(&["R", "G", "B"]).map_err(|e| format!("{}: {e}", args.input.display()))?;
    }
    image::write(&img, &args.output).map_err(|e| e.to_string())
}
