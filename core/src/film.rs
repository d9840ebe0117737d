//! The film: pixel bounds (with pbrt-v3's crop window), filtered accumulation
//! of samples in tiles, a deterministic merge, per-pixel sample statistics and
//! integrator-declared extra channels.
//!
//! Determinism: tiles are laid on a grid fixed in absolute raster coordinates;
//! each tile sums its samples in a fixed order into its own buffer, and tiles
//! are merged into the film in tile-grid order. A pixel's value therefore does
//! not depend on the thread count, on scheduling, or on the crop window it is
//! rendered in.

use crate::filter::Filter;
use crate::geometry::Bounds2i;
use crate::image::Image;
use crate::Rgb;
use glam::{IVec2, Vec2};

/// `⌊x⌋` as an `i32` (saturating; NaN gives 0, as `x.floor() as i32`), without the library
/// `floorf` call that `f32::floor` compiles to on baseline x86-64.
#[inline]
pub fn floor_i32(x: f32) -> i32 {
    let i = x as i32;
    // The truncation rounds towards zero: one less for a negative non-integer.
    i.saturating_sub(((i as f32) > x) as i32)
}

/// What the film is and where its pixels are.
#[derive(Clone, Debug, PartialEq)]
pub struct FilmSpec {
    pub full_resolution: (u32, u32),
    /// The pixels that are output (pbrt-v3's cropped pixel bounds).
    pub pixel_bounds: Bounds2i,
    pub filename: String,
    /// pbrt-v3's `scale`.
    pub scale: f32,
    /// pbrt-v3's `maxsampleluminance`: samples brighter than this are scaled down to it.
    pub max_sample_luminance: f32,
}

impl FilmSpec {
    /// pbrt-v3's crop window (fractions `[x0, x1, y0, y1]`) to pixel bounds.
    pub fn crop_to_pixels(full: (u32, u32), crop: [f32; 4]) -> Bounds2i {
        let (w, h) = (full.0 as f32, full.1 as f32);
        let c = |v: f32| v.clamp(0.0, 1.0);
        Bounds2i::new(
            IVec2::new((w * c(crop[0].min(crop[1]))).ceil() as i32, (h * c(crop[2].min(crop[3]))).ceil() as i32),
            IVec2::new((w * c(crop[1].max(crop[0]))).ceil() as i32, (h * c(crop[3].max(crop[2]))).ceil() as i32),
        )
    }

    /// The pixels whose samples can contribute to the output (pixel bounds grown by the filter radius).
    pub fn sample_bounds(&self, filter_radius: Vec2) -> Bounds2i {
        let pb = self.pixel_bounds;
        let lo = (pb.min.as_vec2() + Vec2::splat(0.5) - filter_radius).floor().as_ivec2();
        let hi = (pb.max.as_vec2() - Vec2::splat(0.5) + filter_radius).ceil().as_ivec2();
        Bounds2i::new(lo, hi)
    }
}

/// Per-pixel accumulators. Sums are in f64 so that thousands of samples per pixel keep their digits.
#[derive(Clone, Debug, Default)]
pub struct PixelSums {
    /// Σ w·L over filter-weighted samples.
    pub rgb: [f64; 3],
    /// Σ w.
    pub weight: f64,
    /// Σ L and Σ L² over the samples taken *in* this pixel (unweighted), and their count:
    /// the per-pixel variance estimate used by z-tests against references.
    pub own_sum: [f64; 3],
    pub own_sum_sq: [f64; 3],
    pub own_count: u64,
}

impl PixelSums {
    /// Adds `other`'s sums to these (a tile into the film, a shard's sample range into another's).
    pub fn add(&mut self, other: &PixelSums) {
        for c in 0..3 {
            self.rgb[c] += other.rgb[c];
            self.own_sum[c] += other.own_sum[c];
            self.own_sum_sq[c] += other.own_sum_sq[c];
        }
        self.weight += other.weight;
        self.own_count += other.own_count;
    }
}

/// A tile's private accumulation buffer covering its pixels grown by the filter radius.
pub struct FilmTile {
    pub bounds: Bounds2i,
    pub pixels: Vec<PixelSums>,
    /// Σ w·value for each extra channel, `extra_channels` values per pixel.
    pub extra: Vec<f64>,
    pub extra_channels: usize,
}

pub struct Film {
    pub spec: FilmSpec,
    pub extra_channel_names: Vec<String>,
    pixels: Vec<PixelSums>,
    extra: Vec<f64>,
    filter_radius: Vec2,
}

impl FilmTile {
    /// Adds one sample at continuous raster position `p_film`.
    pub fn add_sample(&mut self, filter: &dyn Filter, p_film: Vec2, l: Rgb, extra: &[f32]) {
        let r = filter.radius();
        let pd = p_film - Vec2::splat(0.5);
        // Pixels whose centre lies in (pd − r, pd + r]: half-open, so that a sample exactly on a
        // pixel border (QMC samplers produce them) reaches the same pixels as `sample_bounds`
        // assumes, and crops reproduce the full image bit for bit. (pbrt-v3's closed interval
        // gives such a sample to both neighbours under the box filter; the other filters are 0
        // at their radius.)
        let (b0, b1) = (self.bounds.min, self.bounds.max);
        let (x0, x1) =
            (floor_i32(pd.x - r.x).saturating_add(1).max(b0.x), floor_i32(pd.x + r.x).saturating_add(1).min(b1.x));
        let (y0, y1) =
            (floor_i32(pd.y - r.y).saturating_add(1).max(b0.y), floor_i32(pd.y + r.y).saturating_add(1).min(b1.y));
        let w = self.bounds.width();
        for y in y0..y1 {
            for x in x0..x1 {
                let wt = filter.evaluate(Vec2::new(x as f32 - pd.x, y as f32 - pd.y));
                if wt == 0.0 {
                    continue;
                }
                let i = ((y - self.bounds.min.y) * w + (x - self.bounds.min.x)) as usize;
                let px = &mut self.pixels[i];
                let wt = wt as f64;
                for c in 0..3 {
                    px.rgb[c] += wt * l[c] as f64;
                }
                px.weight += wt;
                let base = i * self.extra_channels;
                for (k, v) in extra.iter().enumerate().take(self.extra_channels) {
                    self.extra[base + k] += wt * *v as f64;
                }
            }
        }
        let own = IVec2::new(floor_i32(p_film.x), floor_i32(p_film.y));
        if self.bounds.contains(own) {
            let i = ((own.y - self.bounds.min.y) * w + (own.x - self.bounds.min.x)) as usize;
            let px = &mut self.pixels[i];
            for c in 0..3 {
                px.own_sum[c] += l[c] as f64;
                px.own_sum_sq[c] += (l[c] as f64) * (l[c] as f64);
            }
            px.own_count += 1;
        }
    }
}

impl Film {
    pub fn new(spec: FilmSpec, filter_radius: Vec2, extra_channel_names: Vec<String>) -> Film {
        let n = spec.pixel_bounds.area().max(0) as usize;
        let ne = extra_channel_names.len();
        Film {
            spec,
            pixels: vec![PixelSums::default(); n],
            extra: vec![0.0; n * ne],
            extra_channel_names,
            filter_radius,
        }
    }

    pub fn pixel_bounds(&self) -> Bounds2i {
        self.spec.pixel_bounds
    }

    /// A tile covering the sample pixels `sample_tile`, grown by the filter radius and clipped to the film.
    pub fn make_tile(&self, sample_tile: Bounds2i) -> FilmTile {
        let r = self.filter_radius;
        let lo = (sample_tile.min.as_vec2() - Vec2::splat(0.5) - r).ceil().as_ivec2();
        let hi = ((sample_tile.max.as_vec2() - Vec2::splat(0.5) + r).floor().as_ivec2()) + IVec2::ONE;
        let bounds = Bounds2i::new(lo, hi).intersect(&self.spec.pixel_bounds);
        let bounds = if bounds.is_empty() { Bounds2i::new(lo, lo) } else { bounds };
        let n = bounds.area() as usize;
        let ne = self.extra_channel_names.len();
        FilmTile { bounds, pixels: vec![PixelSums::default(); n], extra: vec![0.0; n * ne], extra_channels: ne }
    }

    /// Adds a tile's sums (call in a fixed tile order for determinism).
    pub fn merge_tile(&mut self, tile: &FilmTile) {
        let pb = self.spec.pixel_bounds;
        let ne = self.extra_channel_names.len();
        for (k, p) in tile.bounds.iter().enumerate() {
            if !pb.contains(p) {
                continue;
            }
            let i = ((p.y - pb.min.y) * pb.width() + (p.x - pb.min.x)) as usize;
            self.pixels[i].add(&tile.pixels[k]);
            for e in 0..ne {
                self.extra[i * ne + e] += tile.extra[k * ne + e];
            }
        }
    }

    /// An empty film like this one whose pixel bounds are grown by `margin` pixels on every
    /// side, clipped to the full image: for image-space passes whose output at a pixel reads
    /// the film up to `margin` pixels away, so that a crop sees the neighbourhood the full
    /// image would (see [`crate::integrator::render_pixels_with_margin`]).
    pub fn grown(&self, margin: u32) -> Film {
        let m = IVec2::splat(margin.min(i32::MAX as u32) as i32);
        let full = IVec2::new(self.spec.full_resolution.0 as i32, self.spec.full_resolution.1 as i32);
        let pb = self.spec.pixel_bounds;
        // Clipped to the full image, but never smaller than the film itself.
        let grown = if pb.is_empty() {
            pb
        } else {
            Bounds2i::new(
                pb.min.saturating_sub(m).max(IVec2::ZERO).min(pb.min),
                pb.max.saturating_add(m).min(full).max(pb.max),
            )
        };
        let spec = FilmSpec { pixel_bounds: grown, ..self.spec.clone() };
        Film::new(spec, self.filter_radius, self.extra_channel_names.clone())
    }

    /// Copies every accumulator (sums, own-sample statistics, extra channels) of the pixels
    /// this film shares with `src`, which must have the same extra channels (else nothing is
    /// copied and `false` is returned).
    pub fn copy_pixels_from(&mut self, src: &Film) -> bool {
        if src.extra_channel_names != self.extra_channel_names {
            return false;
        }
        let (pb, ne) = (self.spec.pixel_bounds, self.extra_channel_names.len());
        for (i, p) in pb.iter().enumerate() {
            let sb = src.spec.pixel_bounds;
            if !sb.contains(p) {
                continue;
            }
            let j = ((p.y - sb.min.y) * sb.width() + (p.x - sb.min.x)) as usize;
            self.pixels[i] = src.pixels[j].clone();
            self.extra[i * ne..(i + 1) * ne].copy_from_slice(&src.extra[j * ne..(j + 1) * ne]);
        }
        true
    }

    /// Replaces every accumulator of pixel `p` (e.g. with a shard's, when shards are merged);
    /// `extra` holds one weighted sum per extra channel. `false` (nothing changed) for a pixel
    /// outside the film or a wrong number of extra values.
    pub fn set_pixel_sums(&mut self, p: IVec2, sums: &PixelSums, extra: &[f64]) -> bool {
        let (pb, ne) = (self.spec.pixel_bounds, self.extra_channel_names.len());
        if !pb.contains(p) || extra.len() != ne {
            return false;
        }
        let i = ((p.y - pb.min.y) * pb.width() + (p.x - pb.min.x)) as usize;
        self.pixels[i] = sums.clone();
        self.extra[i * ne..(i + 1) * ne].copy_from_slice(extra);
        true
    }

    pub fn pixel_sums(&self, p: IVec2) -> Option<&PixelSums> {
        let pb = self.spec.pixel_bounds;
        pb.contains(p).then(|| &self.pixels[((p.y - pb.min.y) * pb.width() + (p.x - pb.min.x)) as usize])
    }

    /// The filter-weighted sums of the extra channels at `p` (divide by the pixel's
    /// `PixelSums::weight` for their values), in `extra_channel_names` order.
    pub fn pixel_extra(&self, p: IVec2) -> Option<&[f64]> {
        let pb = self.spec.pixel_bounds;
        let ne = self.extra_channel_names.len();
        pb.contains(p).then(|| {
            let i = ((p.y - pb.min.y) * pb.width() + (p.x - pb.min.x)) as usize;
            &self.extra[i * ne..(i + 1) * ne]
        })
    }

    /// Replaces the value of pixel `p` (before the film's `scale`) by `rgb`, for integrators
    /// that post-process the whole image: the weighted sums become `rgb × weight` (the weight
    /// is kept), and the pixel's own-sample statistics are rewritten so that its mean is `rgb`
    /// and [`to_image`](Self::to_image) reports `variance` (the variance of the pixel's
    /// estimate, before `scale`; shown only for pixels with at least 2 own samples). Pixels
    /// outside the film and non-finite inputs are ignored (returns `false`).
    pub fn set_pixel_rgb(&mut self, p: IVec2, rgb: Rgb, variance: [f64; 3]) -> bool {
        let pb = self.spec.pixel_bounds;
        if !pb.contains(p) || !rgb.is_finite() || variance.iter().any(|v| !v.is_finite()) {
            return false;
        }
        let px = &mut self.pixels[((p.y - pb.min.y) * pb.width() + (p.x - pb.min.x)) as usize];
        let n = px.own_count as f64;
        for c in 0..3 {
            let m = rgb[c] as f64;
            px.rgb[c] = m * px.weight;
            px.own_sum[c] = m * n;
            px.own_sum_sq[c] = n * (m * m + variance[c].max(0.0) * (n - 1.0).max(0.0));
        }
        true
    }

    /// The image: `R G B`, then the extra channels, then (if `with_variance`)
    /// `variance.R/G/B`: the estimated variance of each pixel's mean from its own samples.
    pub fn to_image(&self, with_variance: bool) -> Image {
        let pb = self.spec.pixel_bounds;
        let mut channels: Vec<String> = ["R", "G", "B"].iter().map(|s| s.to_string()).collect();
        channels.extend(self.extra_channel_names.iter().cloned());
        if with_variance {
            channels.extend(["variance.R", "variance.G", "variance.B"].iter().map(|s| s.to_string()));
        }
        let nc = channels.len();
        let ne = self.extra_channel_names.len();
        let mut data = Vec::with_capacity(self.pixels.len() * nc);
        let scale = self.spec.scale as f64;
        for (i, px) in self.pixels.iter().enumerate() {
            let inv = if px.weight != 0.0 { 1.0 / px.weight } else { 0.0 };
            for c in 0..3 {
                data.push((px.rgb[c] * inv * scale) as f32);
            }
            for e in 0..ne {
                data.push((self.extra[i * ne + e] * inv) as f32);
            }
            if with_variance {
                let n = px.own_count as f64;
                for c in 0..3 {
                    let v = if n > 1.0 {
                        let mean = px.own_sum[c] / n;
                        ((px.own_sum_sq[c] / n - mean * mean).max(0.0) * n / (n - 1.0)) / n
                    } else {
                        0.0
                    };
                    data.push((v * scale * scale) as f32);
                }
            }
        }
        let image = Image { width: pb.width() as u32, height: pb.height() as u32, channels, data, frame: None };
        // A crop keeps its place in the full frame (written as an EXR's data window, as pbrt-v3 does).
        image.with_frame(self.spec.full_resolution, (pb.min.x, pb.min.y))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::filter::{BoxFilter, Filter};

    #[test]
    fn floor_i32_is_floor() {
        let special = [0.0, -0.0, 0.5, -0.5, 1.0, -1.0, 1e-30, -1e-30, 2.5, -2.5, 8388607.5, -8388607.5, 1e20, -1e20];
        let mut rng = crate::rng::Rng::new(7);
        let random = (0..10_000).map(|_| (rng.uniform_f32() - 0.5) * 1e4);
        for x in special.into_iter().chain(random) {
            assert_eq!(floor_i32(x), x.floor() as i32, "{x}");
        }
        assert_eq!(floor_i32(f32::NAN), 0);
        assert_eq!(floor_i32(f32::INFINITY), i32::MAX);
        assert_eq!(floor_i32(f32::NEG_INFINITY), i32::MIN);
    }

    fn tile_weights(filter: &dyn Filter, p: Vec2) -> Vec<f64> {
        let mut t = FilmTile {
            bounds: Bounds2i::new(IVec2::ZERO, IVec2::new(4, 4)),
            pixels: vec![PixelSums::default(); 16],
            extra: Vec::new(),
            extra_channels: 0,
        };
        t.add_sample(filter, p, Rgb::ONE, &[]);
        t.pixels.iter().map(|px| px.weight).collect()
    }

    /// `set_pixel_rgb` replaces a pixel's value and variance; the other pixels and the extra
    /// channels are untouched.
    #[test]
    fn set_pixel_rgb_replaces_value_and_variance() {
        let spec = FilmSpec {
            full_resolution: (2, 1),
            pixel_bounds: Bounds2i::new(IVec2::ZERO, IVec2::new(2, 1)),
            filename: String::new(),
            scale: 2.0,
            max_sample_luminance: f32::INFINITY,
        };
        let b = BoxFilter { radius: Vec2::splat(0.5) };
        let mut film = Film::new(spec, b.radius(), vec!["a".into()]);
        let mut tile = film.make_tile(film.pixel_bounds());
        for (i, x) in [0.25f32, 0.75].iter().enumerate() {
            tile.add_sample(&b, Vec2::new(*x, 0.5), Rgb::splat(i as f32 + 1.0), &[3.0]);
            tile.add_sample(&b, Vec2::new(1.0 + *x, 0.5), Rgb::splat(5.0), &[7.0]);
        }
        film.merge_tile(&tile);
        assert_eq!(film.pixel_extra(IVec2::new(1, 0)), Some(&[14.0][..]));
        assert_eq!(film.pixel_extra(IVec2::new(2, 0)), None);
        assert!(film.set_pixel_rgb(IVec2::new(0, 0), Rgb::new(0.5, 1.0, 4.0), [0.25, 0.0, 1.0]));
        assert!(!film.set_pixel_rgb(IVec2::new(0, 0), Rgb::new(f32::NAN, 1.0, 4.0), [0.0; 3]));
        assert!(!film.set_pixel_rgb(IVec2::new(-1, 0), Rgb::ONE, [0.0; 3]));
        let img = film.to_image(true);
        // R G B a var.R var.G var.B per pixel; the film's scale (2) applies to values and variances (×4).
        assert_eq!(&img.data[0..7], &[1.0, 2.0, 8.0, 3.0, 1.0, 0.0, 4.0]);
        assert_eq!(&img.data[7..14], &[10.0, 10.0, 10.0, 7.0, 0.0, 0.0, 0.0]);
    }

    /// `grown` clips to the full image and never shrinks the film; `copy_pixels_from` brings
    /// back exactly the film's own pixels, sums and extra channels alike.
    #[test]
    fn grown_film_round_trips_its_pixels() {
        let spec = FilmSpec {
            full_resolution: (10, 6),
            pixel_bounds: Bounds2i::new(IVec2::new(1, 2), IVec2::new(5, 4)),
            filename: String::new(),
            scale: 1.0,
            max_sample_luminance: f32::INFINITY,
        };
        let b = BoxFilter { radius: Vec2::splat(0.5) };
        let mut film = Film::new(spec, b.radius(), vec!["a".into()]);
        let mut grown = film.grown(3);
        assert_eq!(grown.pixel_bounds(), Bounds2i::new(IVec2::new(0, 0), IVec2::new(8, 6)));
        assert_eq!(film.grown(0).pixel_bounds(), film.pixel_bounds());
        let mut tile = grown.make_tile(grown.pixel_bounds());
        for p in grown.pixel_bounds().iter() {
            let v = (p.x * 10 + p.y) as f32;
            tile.add_sample(&b, p.as_vec2() + Vec2::splat(0.5), Rgb::splat(v), &[2.0 * v]);
        }
        grown.merge_tile(&tile);
        assert!(film.copy_pixels_from(&grown));
        let img = film.to_image(false);
        for (i, p) in film.pixel_bounds().iter().enumerate() {
            let v = (p.x * 10 + p.y) as f32;
            assert_eq!(&img.data[i * 4..i * 4 + 4], &[v, v, v, 2.0 * v], "pixel {p}");
        }
        let other = Film::new(film.spec.clone(), b.radius(), Vec::new());
        assert!(!film.copy_pixels_from(&other), "different extra channels are refused");
    }

    /// A sample exactly on a pixel border reaches one pixel under the box filter (the one it
    /// was taken in), so that crops, whose sample bounds assume this, reproduce the full image.
    #[test]
    fn border_samples_reach_one_pixel() {
        let b = BoxFilter { radius: Vec2::splat(0.5) };
        for p in [Vec2::new(1.0, 2.0), Vec2::new(2.0, 1.5), Vec2::new(1.5, 3.0), Vec2::new(1.25, 0.75)] {
            let w = tile_weights(&b, p);
            let own = (p.y.floor() as usize) * 4 + p.x.floor() as usize;
            for (i, wi) in w.iter().enumerate() {
                assert_eq!(*wi, if i == own { 1.0 } else { 0.0 }, "sample {p}: pixel {i}");
            }
        }
        // A wider box reaches the pixels whose centres are within (p − r, p + r].
        let b = BoxFilter { radius: Vec2::splat(1.0) };
        let w = tile_weights(&b, Vec2::new(2.0, 2.0));
        let hit: Vec<usize> = (0..16).filter(|&i| w[i] > 0.0).collect();
        assert_eq!(hit, vec![5, 6, 9, 10]);
    }
}
