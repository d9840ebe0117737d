//! `penumbra relight`: re-shades an image that carries SH transfer channels (`sh.0 … sh.K`,
//! `albedo.R/G/B`; see `penumbra_core::sh`) under new distant lighting, without rendering:
//! per pixel `albedo/π · Σ_i transfer_i L_i`, with `L_i` the world-space SH of the lighting at
//! the image's own order.

use penumbra_core::geometry::Bounds3;
use penumbra_core::image::{self, Image};
use penumbra_core::light::{Light, Lights};
use penumbra_core::sh::transfer::{TransferLayout, TransferShader};
use penumbra_core::sh::{project_infinite_light, ShOrder, ShRgb};
use penumbra_parser::DiagSink;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

#[derive(clap::Args, Debug)]
#[command(group(clap::ArgGroup::new("lighting").required(true).args(["scene", "env"])))]
pub struct RelightArgs {
    /// An EXR with SH transfer channels sh.0…sh.K and albedo.R/G/B (e.g. rendered with
    /// `-i ambientocclusion --param sh=true`).
    pub image: PathBuf,
    /// Light with the infinite lights of this pbrt-v3 scene (their transforms, maps, `L` and `scale`).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Light with this lat-long map (EXR/PFM/PNG) in pbrt-v3's default orientation (+z is θ = 0).
    #[arg(long)]
    pub env: Option<PathBuf>,
    /// Output image (.exr, .png or .pfm): R, G, B.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// ZIP-compress an EXR output (default: uncompressed, 10× faster to write; the same values).
    #[arg(long)]
    pub compress: bool,
    /// Multiply the result by 2^S.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
    /// Print nothing but errors and warnings.
    #[arg(long, short = 'q')]
    pub quiet: bool,
}

/// The world-space SH, at `order`, of the infinite lights of the scene `path` (other lights
/// are ignored, with a warning); an error when it has none.
pub fn scene_lighting(path: &Path, order: ShOrder, warnings: &DiagSink) -> Result<ShRgb, String> {
    let parsed = penumbra_parser::parse_file(path).map_err(|e| e.to_string())?;
    warnings.extend(parsed.warnings);
    lighting_of(&parsed.scene, order, &path.display().to_string(), warnings)
}

/// The world-space SH, at `order`, of the lat-long map `path` as an `infinite` light with no
/// transform, read exactly as pbrt-v3 reads `mapname`.
pub fn env_lighting(path: &Path, order: ShOrder, warnings: &DiagSink) -> Result<ShRgb, String> {
    // pbrt-v3 falls back to a white sky when a map cannot be read; relighting must not.
    image::read_scene_input(path).map_err(|e| format!("cannot read the environment map: {e}"))?;
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let quoted = name.replace('\\', "\\\\").replace('"', "\\\"");
    let text = format!("WorldBegin\nLightSource \"infinite\" \"string mapname\" [ \"{quoted}\" ]\nWorldEnd\n");
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let parsed = penumbra_parser::parse_str(&text, "<relight --env>", Some(&dir)).map_err(|e| e.to_string())?;
    lighting_of(&parsed.scene, order, &path.display().to_string(), warnings)
}

fn lighting_of(
    desc: &penumbra_parser::SceneDescription,
    order: ShOrder,
    what: &str,
    warnings: &DiagSink,
) -> Result<ShRgb, String> {
    let lights = Lights::build(desc, &[], &[], Bounds3::EMPTY, warnings).map_err(|e| e.to_string())?;
    let mut sum = ShRgb::zero(order);
    let mut infinite = 0;
    for l in &lights.lights {
        if let Light::Infinite(inf) = l {
            sum.add(&project_infinite_light(inf, order).map_err(|e| e.to_string())?).map_err(|e| e.to_string())?;
            infinite += 1;
        }
    }
    let others = lights.lights.len() - infinite + desc.area_lights.len();
    if others > 0 {
        warnings.warn(None, format!("relight: {what}: only infinite lights relight; {others} other light(s) ignored"));
    }
    if infinite == 0 {
        return Err(format!("{what} has no infinite light to relight with"));
    }
    Ok(sum)
}

/// `albedo/π · Σ_i transfer_i L_i · scale` per pixel, as an `R G B` image; an error naming what
/// is missing when the image has no transfer or albedo channels.
pub fn relight(img: &Image, light: &ShRgb, scale: f32) -> Result<Image, String> {
    let layout = TransferLayout::find(&img.channels).map_err(|e| e.to_string())?;
    let shader = TransferShader::new(light, layout.order);
    let (w, nc) = (img.width as usize, img.channels.len());
    let mut out = vec![0.0f32; img.npixels() * 3];
    if w > 0 {
        out.par_chunks_mut(3 * w).zip(img.data.par_chunks(nc * w)).for_each(|(o, row)| {
            for (px, dst) in row.chunks_exact(nc).zip(o.chunks_exact_mut(3)) {
                let v = shader.shade(&layout, px);
                dst.copy_from_slice(&[v[0] * scale, v[1] * scale, v[2] * scale]);
            }
        });
    }
    Image::from_data(img.width, img.height, ["R", "G", "B"].map(String::from).to_vec(), out).map_err(|e| e.to_string())
}

/// What `relight` did and how long each step took (seconds).
#[derive(Clone, Debug, Default)]
pub struct RelightTimes {
    pub order: usize,
    pub read: f64,
    pub lighting: f64,
    pub shade: f64,
    pub write: f64,
}

/// The whole command: read, project, shade, write.
pub fn relight_files(args: &RelightArgs, warnings: &DiagSink) -> Result<RelightTimes, String> {
    crate::output::prepare(&args.output, crate::output::MissingDir::Fail)?;
    let t = Instant::now();
    let img = image::read(&args.image).map_err(|e| e.to_string())?;
    let layout = TransferLayout::find(&img.channels).map_err(|e| format!("{}: {e}", args.image.display()))?;
    let read = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let light = match (&args.scene, &args.env) {
        (Some(s), _) => scene_lighting(s, layout.order, warnings)?,
        (None, Some(e)) => env_lighting(e, layout.order, warnings)?,
        (None, None) => return Err("give the lighting: --scene SCENE.pbrt or --env MAP.exr".into()),
    };
    let lighting = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let out = relight(&img, &light, args.exposure.exp2())?;
    let shade = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let exr = image::Format::from_extension(&args.output) == Some(image::Format::Exr);
    if exr && !args.compress {
        image::write_exr_uncompressed(&out, &args.output)
    } else {
        image::write(&out, &args.output)
    }
    .map_err(|e| e.to_string())?;
    Ok(RelightTimes { order: layout.order.n(), read, lighting, shade, write: t.elapsed().as_secs_f64() })
}

pub fn run(args: RelightArgs) -> ExitCode {
    let warnings = DiagSink::new();
    let t = Instant::now();
    let result = relight_files(&args, &warnings);
    for d in warnings.take() {
        eprint!("{d}");
    }
    match result {
        Ok(times) => {
            if !args.quiet {
                eprintln!(
                    "relit {} at SH order {} in {:.3} s (read {:.3}, lighting {:.3}, shade {:.3}, write {:.3})",
                    args.output.display(),
                    times.order,
                    t.elapsed().as_secs_f64(),
                    times.read,
                    times.lighting,
                    times.shade,
                    times.write
                );
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
