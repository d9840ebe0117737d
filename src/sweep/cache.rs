//! The reference of a sweep: a file (`--reference`), or a `--reference-spp` render cached
//! under `OUTDIR/cache/` by a key of everything that determines it.

use super::args::Setup;
use super::{fail, rgb_only, Failure, SweepArgs, EXIT_CANCELLED};
use crate::cli::print_new_warnings;
use crate::pipeline::{self, RenderOptions};
use penumbra_core::fnv::fnv1a64;
use penumbra_core::image::{self, Image};
use penumbra_core::scene::{BuildOptions, Crop};
use penumbra_parser::DiagSink;
use serde_json::{json, Value};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// The cache key of a `--reference-spp` render of the scene whose
/// [`scene_identity`](crate::scene_identity::scene_identity) is `scene`.
pub fn reference_key(
    scene: &str,
    integrator: &str,
    resolution: Option<(u32, u32)>,
    crop: Option<Crop>,
    spp: u32,
    seed: u64,
) -> String {
    let mut key = b"penumbra-sweep-reference-v2\0".to_vec();
    key.extend_from_slice(scene.as_bytes());
    key.extend_from_slice(
        format!("\0integrator={integrator}\0resolution={resolution:?}\0crop={crop:?}\0spp={spp}\0seed={seed}")
            .as_bytes(),
    );
    format!("{:016x}", fnv1a64(&key))
}

/// The seed of the `--reference-spp` render.
fn reference_seed(args: &SweepArgs) -> u64 {
    args.reference_seed.unwrap_or(args.flags.seed.wrapping_add(1))
}

/// Where the `--reference-spp` render is cached (`None` with `--reference`).
pub(super) fn cached_reference_path(args: &SweepArgs, s: &Setup) -> Option<PathBuf> {
    let n = args.reference_spp.filter(|_| args.reference.is_none())?;
    let key =
        reference_key(&s.scene_identity, args.reference_integrator(), s.resolution, s.crop, n, reference_seed(args));
    Some(args.output.join("cache").join(format!("{key}.exr")))
}

/// The image every render is compared with, and how `sweep.json` and the summary name it.
pub(super) struct Reference {
    pub image: Image,
    pub json: Value,
    pub label: String,
}

/// The `--reference` image (`file`, already read), or the `--reference-spp` render: from the
/// cache when it holds one, else rendered and cached.
pub(super) fn reference(
    args: &SweepArgs,
    s: &Setup,
    file: Option<Image>,
    cancel: &Arc<AtomicBool>,
    seen: &mut BTreeSet<String>,
    say: &dyn Fn(String),
) -> Result<Reference, Failure> {
    let mut reference = file;
    let reference_json;
    let reference_label;
    match (&args.reference, args.reference_spp) {
        (Some(p), _) => {
            reference_json = json!({ "kind": "file", "path": p.display().to_string() });
            reference_label = format!("`{}`", p.display());
        }
        (None, Some(n)) => {
            let rseed = reference_seed(args);
            let ri = args.reference_integrator();
            let path = cached_reference_path(args, s).unwrap_or_default();
            let cache_dir = args.output.join("cache");
            let cached = read_cached(&path);
            let was_cached = cached.is_some();
            if let Some(img) = cached {
                say(format!("using cached reference {} ({ri}, {n} spp)", path.display()));
                reference = Some(img);
            } else {
                say(format!("rendering reference: {ri} at {n} spp, seed {rseed}"));
                std::fs::create_dir_all(&cache_dir)
                    .map_err(|e| fail(format!("cannot create {}: {e}", cache_dir.display())))?;
                let t0 = Instant::now();
                let img = render_reference(args, s, (ri, n, rseed), cancel, seen)?;
                image::write(&img, &path).map_err(fail)?;
                say(format!("reference written to {} in {:.2} s", path.display(), t0.elapsed().as_secs_f64()));
                reference = Some(img);
            }
            reference_json = json!({
                "kind": "rendered",
                "integrator": ri,
                "spp": n,
                "seed": rseed,
                "path": path.display().to_string(),
                "cached": was_cached,
            });
            reference_label = format!("{ri} at {n} spp (seed {rseed}), `{}`", path.display());
        }
        (None, None) => return Err(fail("give --reference or --reference-spp")),
    }
    let Some(image) = reference else {
        return Err(fail("no reference"));
    };
    Ok(Reference { image, json: reference_json, label: reference_label })
}

/// The cached reference at `path`, if there is a readable one (a broken one is ignored with
/// a warning, and rendered again).
fn read_cached(path: &Path) -> Option<Image> {
    match image::read(path) {
        Ok(img) => match rgb_only(&img, &path.display().to_string()) {
            Ok(i) => Some(i),
            Err(e) => {
                eprintln!("warning: ignoring cached reference: {}", e.message);
                None
            }
        },
        Err(e) if path.exists() => {
            eprintln!("warning: ignoring unreadable cached reference: {e}");
            None
        }
        Err(_) => None,
    }
}

/// Renders the reference with integrator `ri` at `n` spp and seed `rseed` (R, G, B only).
fn render_reference(
    args: &SweepArgs,
    s: &Setup,
    (ri, n, rseed): (&str, u32, u64),
    cancel: &Arc<AtomicBool>,
    seen: &mut BTreeSet<String>,
) -> Result<Image, Failure> {
    let warnings = DiagSink::new();
    let opts = RenderOptions {
        integrator: Some(ri),
        params: &[],
        build: BuildOptions { spp: Some(n), seed: rseed, crop: s.crop, resolution: s.resolution },
        threads: args.flags.threads,
        with_variance: false,
        cancel,
        progress: None,
    };
    let result = pipeline::render(&s.desc, &opts, &warnings);
    print_new_warnings(&warnings, seen);
    let r = match result {
        Ok(r) => r,
        Err(e) if cancel.load(Ordering::SeqCst) => {
            return Err(Failure { code: EXIT_CANCELLED, message: format!("{e}: nothing was written") })
        }
        Err(e) => return Err(fail(format!("reference render: {e}"))),
    };
    rgb_only(&r.image, "reference render")
}
