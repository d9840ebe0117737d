//! Deterministic shards of one render and their exact merge (`render --tile I/N`,
//! `render --spp-offset K`, `penumbra merge`).
//!
//! A shard renders shard `I` of `N` of the image's pixels ([`penumbra_core::shard`]: whole
//! tiles of the driver's fixed grid, each rectangle rendered as a crop, which is bit-identical
//! to the full image for every integrator) and/or samples `K … K+spp−1` of every pixel's sample
//! sequence. It keeps the film's accumulators (f64 weighted sums, own-sample statistics and
//! extra channels), so `merge` rebuilds the film the single render would have had and writes
//! the image the same way.
//!
//! # File format (`.shard`, version 1)
//! All integers and floats little-endian.
//! 1. The 16 bytes `PENUMBRA-SHARD1\n`.
//! 2. A `u64` byte length `H`, then `H` bytes of UTF-8 JSON: the [`ShardHeader`] (what the
//!    shard is — its [`Identity`], which every shard of one image shares —, its rectangles,
//!    sample range and counters).
//! 3. For each rectangle of `rects`, in order, each pixel in raster order: `rgb[3]`, `weight`,
//!    `own_sum[3]`, `own_sum_sq[3]` as `f64`, `own_count` as `u64`, then one `f64` weighted
//!    sum per extra channel (`identity.extra_channels`).
//! 4. A `u64` FNV-1a hash of every byte before it (a truncated or damaged file is refused).

use crate::pipeline::{self, PipelineError, RenderOptions};
use crate::scene_identity::scene_identity;
use penumbra_core::film::{Film, FilmSpec, PixelSums};
use penumbra_core::fnv::fnv1a64;
use penumbra_core::geometry::Bounds2i;
use penumbra_core::integrator::build_scene;
use penumbra_core::sampler::OffsetSampler;
use penumbra_core::shard_rects::{shard_rects, TileLayout};
use penumbra_core::{IVec2, Vec2};
use penumbra_parser::{DiagSink, Param, ParamValue, SceneDescription};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

pub const MAGIC: &[u8; 16] = b"PENUMBRA-SHARD1\n";
pub const FORMAT_VERSION: u32 = 1;
/// `f64` values per pixel before the extra channels (the `u64` count included).
const SUMS_PER_PIXEL: usize = 11;

/// What every shard of one image has in common; `merge` refuses a shard whose identity differs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Identity {
    /// [`scene_identity`](crate::scene_identity::scene_identity).
    pub scene_hash: String,
    pub integrator: String,
    /// The command line's `--param` values, as given.
    pub params: Vec<String>,
    pub seed: u64,
    pub sampler: String,
    pub full_resolution: [u32; 2],
    /// The pixels the shards partition (the crop, or the whole image): `[x0, x1, y0, y1]`.
    pub image_bounds: [i32; 4],
    /// The film's `scale`, applied when the image is written.
    pub scale: f32,
    pub extra_channels: Vec<String>,
    /// `N` of `--tile I/N` (1 without `--tile`).
    pub tile_count: u32,
    pub tile_layout: String,
}

/// A shard's counters (summed by `merge`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ShardStats {
    pub camera_samples: u64,
    pub rays: u64,
    pub shadow_rays: u64,
    pub bad_samples: u64,
    pub parse_seconds: f64,
    pub build_seconds: f64,
    pub render_seconds: f64,
    pub threads: usize,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShardHeader {
    pub format: u32,
    pub identity: Identity,
    /// `I` of `--tile I/N`.
    pub tile_index: u32,
    /// The shard's pixels, `[x0, x1, y0, y1]` each, in file order.
    pub rects: Vec<[i32; 4]>,
    /// The sample range `spp_offset … spp_offset + spp − 1` of every pixel.
    pub spp_offset: u32,
    pub spp: u32,
    /// Whether shards of other sample ranges can be added to this one (integrator and sampler
    /// allow it; the render was asked with `--spp-offset`).
    pub sample_ranges: bool,
    /// The scene as named on the command line (not compared).
    pub scene: String,
    pub stats: ShardStats,
    /// Where it ran (`hostname`, cores).
    pub machine: serde_json::Value,
}

/// A shard: its header and, for every pixel of its rectangles, the film's accumulators.
#[derive(Clone, Debug)]
pub struct Shard {
    pub header: ShardHeader,
    pub pixels: Vec<PixelSums>,
    /// `identity.extra_channels.len()` values per pixel.
    pub extra: Vec<f64>,
}

/// What to render: shard `index` of `count` of the pixels, and/or a sample range.
#[derive(Clone, Copy, Debug)]
pub struct ShardRequest {
    pub index: u32,
    pub count: u32,
    pub layout: TileLayout,
    /// `--spp-offset K`: samples `K …` of each pixel (`None`: samples from 0, and the shard
    /// cannot be combined with other sample ranges).
    pub spp_offset: Option<u32>,
}

fn bounds_array(b: Bounds2i) -> [i32; 4] {
    [b.min.x, b.max.x, b.min.y, b.max.y]
}

fn array_bounds(a: [i32; 4]) -> Bounds2i {
    Bounds2i::new(IVec2::new(a[0], a[2]), IVec2::new(a[1], a[3]))
}

/// The machine a shard or item ran on, for timing figures.
pub fn machine() -> serde_json::Value {
    let hostname = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .or_else(|_| std::fs::read_to_string("/etc/hostname"))
        .map(|s| s.trim().to_string())
        .ok()
        .or_else(|| std::env::var("HOSTNAME").ok())
        .unwrap_or_default();
    serde_json::json!({
        "hostname": hostname,
        "cores": std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
        "os": std::env::consts::OS,
        "arch": std::env::consts::ARCH,
    })
}

/// The command-line parameters as an identity: `name=value` by name (the last of a repeated
/// name, as the integrator reads them), so `maxdistance=1` and `maxdistance=1.0` agree once
/// typed.
fn param_identity(params: &[Param]) -> Vec<String> {
    let by_name: BTreeMap<&str, &ParamValue> = params.iter().map(|p| (p.name.as_str(), &p.value)).collect();
    by_name.into_iter().map(|(n, v)| format!("{n}={v:?}")).collect()
}

/// Renders the shard `req` asks for (`scene_name` is recorded as given).
pub fn render_shard(
    desc: &SceneDescription,
    scene_name: &str,
    opts: &RenderOptions,
    req: ShardRequest,
    warnings: &DiagSink,
) -> Result<Shard, PipelineError> {
    if req.count == 0 || req.index >= req.count {
        return Err(PipelineError::Invalid(format!(
            "--tile {}/{}: the shard index must be below the shard count (0 ≤ I < N)",
            req.index, req.count
        )));
    }
    let hash = scene_identity(desc).map_err(PipelineError::Invalid)?;
    let integrator = pipeline::choose_integrator(desc, opts.integrator, opts.params, warnings)?;
    if req.spp_offset.is_some() && !integrator.merges_sample_ranges() {
        return Err(PipelineError::Invalid(format!(
            "--spp-offset: {}'s estimate at a pixel depends on all of the pixel's samples (work shared \
             between them, or an image-space pass), so renders of sample ranges would not add up to one \
             render; render it at the full sample count (--tile still splits it)",
            pipeline::integrator_name(desc, opts.integrator)
        )));
    }
    let mut scene = build_scene(integrator.as_ref(), desc, &opts.build, warnings)?;
    let build_seconds = scene.report.total_seconds();
    let sampler = scene.sampler.name().to_string();
    if let Some(k) = req.spp_offset {
        if !scene.sampler.samples_independent_of_count() {
            return Err(PipelineError::Invalid(format!(
                "--spp-offset: sampler \"{sampler}\" lays one pattern over all of a pixel's samples, so the \
                 samples of a range are not those of a longer render; use \"halton\", \"sobol\" or \"random\" \
                 (the scene's Sampler directive) for progressive renders"
            )));
        }
        let inner = std::mem::replace(&mut scene.sampler, Box::new(penumbra_core::sampler::RandomSampler::new(1, 0)));
        scene.sampler =
            Box::new(OffsetSampler::new(inner, k).ok_or_else(|| {
                PipelineError::Invalid(format!("--spp-offset {k}: the sample index would pass 2^32"))
            })?);
    }
    let image = scene.film.pixel_bounds;
    let rects = shard_rects(image, req.index, req.count, req.layout);
    if rects.is_empty() {
        let n = penumbra_core::integrator::tiles(image).len();
        warnings.warn(
            None,
            format!(
                "--tile {}/{}: the image has {n} tile{} of 16x16 pixels, none left for this shard (it is written, empty)",
                req.index,
                req.count,
                if n == 1 { "" } else { "s" }
            ),
        );
    }
    let ne = integrator.extra_channels().len();
    let mut shard = Shard {
        header: ShardHeader {
            format: FORMAT_VERSION,
            identity: Identity {
                scene_hash: hash,
                integrator: pipeline::integrator_name(desc, opts.integrator).to_string(),
                params: param_identity(opts.params),
                seed: opts.build.seed,
                sampler,
                full_resolution: [scene.film.full_resolution.0, scene.film.full_resolution.1],
                image_bounds: bounds_array(image),
                scale: scene.film.scale,
                extra_channels: integrator.extra_channels(),
                tile_count: req.count,
                tile_layout: req.layout.name().to_string(),
            },
            tile_index: req.index,
            rects: rects.iter().map(|r| bounds_array(*r)).collect(),
            spp_offset: req.spp_offset.unwrap_or(0),
            spp: scene.sampler.samples_per_pixel(),
            sample_ranges: req.spp_offset.is_some(),
            scene: scene_name.to_string(),
            stats: ShardStats { build_seconds, ..Default::default() },
            machine: machine(),
        },
        pixels: Vec::new(),
        extra: Vec::new(),
    };
    for r in rects {
        let spec = FilmSpec { pixel_bounds: r, ..scene.film.clone() };
        let (film, stats) = pipeline::render_film(integrator.as_ref(), &scene, spec, opts, warnings)?;
        let s = &mut shard.header.stats;
        s.camera_samples += stats.camera_samples;
        s.rays += stats.rays;
        s.shadow_rays += stats.shadow_rays;
        s.bad_samples += stats.bad_samples;
        s.render_seconds += stats.render_seconds;
        s.threads = stats.threads;
        shard.header.spp = stats.spp;
        for p in r.iter() {
            shard.pixels.push(film.pixel_sums(p).cloned().unwrap_or_default());
            match film.pixel_extra(p) {
                Some(e) => shard.extra.extend_from_slice(e),
                None => shard.extra.extend(std::iter::repeat_n(0.0, ne)),
            }
        }
    }
    Ok(shard)
}

impl Shard {
    pub fn to_bytes(&self) -> Vec<u8> {
        let header = serde_json::to_vec_pretty(&self.header).unwrap_or_default();
        let ne = self.header.identity.extra_channels.len();
        let mut out = Vec::with_capacity(32 + header.len() + self.pixels.len() * 8 * (SUMS_PER_PIXEL + ne));
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&(header.len() as u64).to_le_bytes());
        out.extend_from_slice(&header);
        for (i, px) in self.pixels.iter().enumerate() {
            for v in px.rgb.iter().chain([&px.weight]).chain(&px.own_sum).chain(&px.own_sum_sq) {
                out.extend_from_slice(&v.to_le_bytes());
            }
            out.extend_from_slice(&px.own_count.to_le_bytes());
            for v in &self.extra[i * ne..(i + 1) * ne] {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        let h = fnv1a64(&out);
        out.extend_from_slice(&h.to_le_bytes());
        out
    }

    pub fn from_bytes(bytes: &[u8]) -> Result<Shard, String> {
        if bytes.len() < MAGIC.len() + 16 || &bytes[..MAGIC.len()] != MAGIC {
            return Err("not a penumbra shard file (it does not start with PENUMBRA-SHARD1)".into());
        }
        let (body, tail) = bytes.split_at(bytes.len() - 8);
        let stored = u64::from_le_bytes(tail.try_into().unwrap_or_default());
        if fnv1a64(body) != stored {
            return Err("damaged or truncated shard file (its checksum does not match)".into());
        }
        let mut at = MAGIC.len();
        let u64_at = |at: usize| u64::from_le_bytes(body[at..at + 8].try_into().unwrap_or_default());
        let hlen = u64_at(at) as usize;
        at += 8;
        if hlen > body.len() - at {
            return Err("damaged shard file (header length past the end)".into());
        }
        let header: ShardHeader =
            serde_json::from_slice(&body[at..at + hlen]).map_err(|e| format!("bad shard header: {e}"))?;
        at += hlen;
        if header.format != FORMAT_VERSION {
            return Err(format!("shard format {} (this penumbra reads {FORMAT_VERSION})", header.format));
        }
        let ne = header.identity.extra_channels.len();
        let n: i64 = header.rects.iter().map(|r| array_bounds(*r).area().max(0)).sum();
        let need = n as usize * 8 * (SUMS_PER_PIXEL + ne);
        if body.len() - at != need {
            return Err(format!(
                "damaged shard file: {} bytes of pixels for {n} pixels, expected {need}",
                body.len() - at
            ));
        }
        let mut pixels = Vec::with_capacity(n as usize);
        let mut extra = Vec::with_capacity(n as usize * ne);
        let f = |at: usize| f64::from_bits(u64_at(at));
        for _ in 0..n {
            let v: Vec<f64> = (0..10).map(|k| f(at + 8 * k)).collect();
            pixels.push(PixelSums {
                rgb: [v[0], v[1], v[2]],
                weight: v[3],
                own_sum: [v[4], v[5], v[6]],
                own_sum_sq: [v[7], v[8], v[9]],
                own_count: u64_at(at + 80),
            });
            at += 8 * SUMS_PER_PIXEL;
            extra.extend((0..ne).map(|k| f(at + 8 * k)));
            at += 8 * ne;
        }
        Ok(Shard { header, pixels, extra })
    }

    pub fn write(&self, path: &Path) -> Result<(), String> {
        let bytes = self.to_bytes();
        penumbra_core::image::write_atomic(path, |w| w.write_all(&bytes)).map_err(|e| e.to_string())
    }

    pub fn read(path: &Path) -> Result<Shard, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        Shard::from_bytes(&bytes).map_err(|e| format!("{}: {e}", path.display()))
    }

    /// `tile I/N, samples K..K+n`, for messages.
    fn what(&self) -> String {
        let h = &self.header;
        format!(
            "tile {}/{}, samples {}..{}",
            h.tile_index,
            h.identity.tile_count,
            h.spp_offset,
            h.spp_offset as u64 + h.spp as u64
        )
    }
}

/// Merged shards: the film the single render would have had, and the summed counters.
pub struct Merged {
    pub film: Film,
    pub identity: Identity,
    /// Samples per pixel of the merged image (the sum of the sample ranges).
    pub spp: u32,
    pub stats: ShardStats,
    /// The largest `render_seconds` of one shard (the wall time of a fully parallel run).
    pub max_render_seconds: f64,
    pub shards: Vec<serde_json::Value>,
}

/// The fields in which `b` differs from `a`.
fn identity_differences(a: &Identity, b: &Identity) -> Vec<String> {
    let (ja, jb) = (serde_json::to_value(a).unwrap_or_default(), serde_json::to_value(b).unwrap_or_default());
    let (Some(ma), Some(mb)) = (ja.as_object(), jb.as_object()) else { return vec!["identity".into()] };
    let show = |v: &serde_json::Value| match v.as_array() {
        Some(a) if a.len() > 4 => format!("[{} values]", a.len()),
        _ => v.to_string(),
    };
    ma.iter()
        .filter(|(k, v)| mb.get(*k) != Some(v))
        .map(|(k, v)| format!("{k} {} where the others have {}", show(&mb[k]), show(v)))
        .collect()
}

/// The identity most shards share (the image's); an error naming every shard that differs.
fn common_identity(shards: &[(String, Shard)]) -> Result<Identity, String> {
    let Some((first_name, first)) = shards.first() else { return Err("no shards to merge".into()) };
    // The identity most shards share is the image's; the others are foreign.
    let mut votes: Vec<(&Identity, usize)> = Vec::new();
    for (_, s) in shards {
        match votes.iter_mut().find(|(id, _)| **id == s.header.identity) {
            Some(v) => v.1 += 1,
            None => votes.push((&s.header.identity, 1)),
        }
    }
    let best = votes.iter().map(|v| v.1).max().unwrap_or(0);
    let id = votes.iter().find(|v| v.1 == best).map(|v| v.0).unwrap_or(&first.header.identity).clone();
    let reference = shards.iter().find(|(_, s)| s.header.identity == id).map(|(n, _)| n).unwrap_or(first_name);
    let foreign: Vec<String> = shards
        .iter()
        .filter(|(_, s)| s.header.identity != id)
        .map(|(n, s)| format!("{n} is foreign: {}", identity_differences(&id, &s.header.identity).join(", ")))
        .collect();
    if !foreign.is_empty() {
        return Err(format!("{} (the other shards, e.g. {reference}, agree)", foreign.join("; ")));
    }
    Ok(id)
}

/// Sorts each tile's shards by sample offset and checks that their ranges are contiguous from
/// 0, do not overlap and are the same for every tile; returns those (offset, spp) ranges.
fn tile_sample_ranges(
    by_tile: &mut BTreeMap<u32, Vec<(&String, &Shard)>>,
    id: &Identity,
) -> Result<Vec<(u32, u32)>, String> {
    let mut ranges_of_first: Option<(u32, Vec<(u32, u32)>)> = None;
    for (tile, list) in by_tile.iter_mut() {
        list.sort_by_key(|(_, s)| s.header.spp_offset);
        let mut next = 0u64;
        for (k, (n, s)) in list.iter().enumerate() {
            let h = &s.header;
            let (lo, hi) = (h.spp_offset as u64, h.spp_offset as u64 + h.spp as u64);
            if lo < next {
                let (pn, ps) = list[k - 1];
                return Err(if s.what() == ps.what() {
                    format!("{n} duplicates {pn}: both hold {}", s.what())
                } else {
                    format!("{n} ({}) overlaps {pn} ({})", s.what(), ps.what())
                });
            }
            if lo > next {
                return Err(format!(
                    "samples {next}..{lo} of tile {tile}/{} are missing (between {} and {n})",
                    id.tile_count,
                    if k == 0 { "the start".to_string() } else { list[k - 1].0.clone() }
                ));
            }
            next = hi;
        }
        if let Some((n, _)) = list.iter().find(|(_, s)| list.len() > 1 && !s.header.sample_ranges) {
            return Err(format!(
                "{n} was not rendered with --spp-offset, so it cannot be added to other sample ranges \
                 ({} shards hold tile {tile}/{})",
                list.len(),
                id.tile_count
            ));
        }
        let ranges: Vec<(u32, u32)> = list.iter().map(|(_, s)| (s.header.spp_offset, s.header.spp)).collect();
        match &ranges_of_first {
            None => ranges_of_first = Some((*tile, ranges)),
            Some((t0, r0)) if *r0 != ranges => {
                return Err(format!(
                    "tile {tile}/{} has sample ranges {ranges:?} but tile {t0} has {r0:?}: every tile needs the same (offset, spp) ranges",
                    id.tile_count
                ));
            }
            _ => {}
        }
    }
    Ok(ranges_of_first.map(|r| r.1).unwrap_or_default())
}

/// Checks that the named shards belong together and cover the image exactly once (every
/// tile, each with the same sample ranges, contiguous from 0 and not overlapping), and adds
/// them up. Errors name the foreign, duplicated or missing shard.
pub fn merge(shards: &[(String, Shard)]) -> Result<Merged, String> {
    let id = common_identity(shards)?;
    // Group by tile; each tile's sample ranges in order.
    let mut by_tile: BTreeMap<u32, Vec<(&String, &Shard)>> = BTreeMap::new();
    let image = array_bounds(id.image_bounds);
    let layout = TileLayout::parse(&id.tile_layout).ok_or_else(|| format!("unknown tile layout {}", id.tile_layout))?;
    for (n, s) in shards {
        let h = &s.header;
        if h.tile_index >= id.tile_count {
            return Err(format!("{n}: tile {}/{} does not exist", h.tile_index, id.tile_count));
        }
        let expected: Vec<[i32; 4]> =
            shard_rects(image, h.tile_index, id.tile_count, layout).into_iter().map(bounds_array).collect();
        if h.rects != expected {
            return Err(format!(
                "{n}: its pixels {:?} are not those of tile {}/{} ({expected:?}): made by another penumbra?",
                h.rects, h.tile_index, id.tile_count
            ));
        }
        by_tile.entry(h.tile_index).or_default().push((n, s));
    }
    let missing: Vec<String> = (0..id.tile_count)
        .filter(|i| !by_tile.contains_key(i))
        .map(|i| {
            let rects = shard_rects(image, i, id.tile_count, layout);
            format!(
                "tile {i}/{} (pixels {:?}) is missing",
                id.tile_count,
                rects.iter().map(|r| bounds_array(*r)).collect::<Vec<_>>()
            )
        })
        .collect();
    if !missing.is_empty() {
        return Err(missing.join("; "));
    }
    let ranges = tile_sample_ranges(&mut by_tile, &id)?;
    let spp_total: u64 = ranges.iter().map(|r| r.1 as u64).sum();
    let spp = u32::try_from(spp_total).map_err(|_| format!("{spp_total} samples per pixel in all"))?;

    let full = (id.full_resolution[0], id.full_resolution[1]);
    let spec = FilmSpec {
        full_resolution: full,
        pixel_bounds: image,
        filename: String::new(),
        scale: id.scale,
        max_sample_luminance: f32::INFINITY,
    };
    let mut film = Film::new(spec, Vec2::ZERO, id.extra_channels.clone());
    let ne = id.extra_channels.len();
    let mut stats = ShardStats::default();
    let mut max_render_seconds = 0.0f64;
    let mut listed = Vec::new();
    for (tile, list) in &by_tile {
        let mut i = 0usize;
        for r in shard_rects(image, *tile, id.tile_count, layout) {
            for p in r.iter() {
                let (_, s0) = list[0];
                let mut sums = s0.pixels[i].clone();
                let mut extra = s0.extra[i * ne..(i + 1) * ne].to_vec();
                for (_, s) in &list[1..] {
                    sums.add(&s.pixels[i]);
                    for (e, v) in extra.iter_mut().zip(&s.extra[i * ne..(i + 1) * ne]) {
                        *e += v;
                    }
                }
                film.set_pixel_sums(p, &sums, &extra);
                i += 1;
            }
        }
        for (n, s) in list {
            let h = &s.header.stats;
            stats.camera_samples += h.camera_samples;
            stats.rays += h.rays;
            stats.shadow_rays += h.shadow_rays;
            stats.bad_samples += h.bad_samples;
            stats.parse_seconds += h.parse_seconds;
            stats.build_seconds += h.build_seconds;
            stats.render_seconds += h.render_seconds;
            stats.threads = stats.threads.max(h.threads);
            max_render_seconds = max_render_seconds.max(h.render_seconds);
            listed.push(serde_json::json!({
                "file": n,
                "tile": [s.header.tile_index, id.tile_count],
                "spp_offset": s.header.spp_offset,
                "spp": s.header.spp,
                "stats": s.header.stats,
                "machine": s.header.machine,
            }));
        }
    }
    Ok(Merged { film, identity: id, spp, stats, max_render_seconds, shards: listed })
}
