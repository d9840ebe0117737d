//! Floating-point images and their file formats: OpenEXR, PNG and PFM.
//!
//! An [`Image`] is a `width × height` grid of pixels with any number of named
//! channels, stored interleaved, row-major, starting from the **top** row (the
//! convention of EXR and PNG; PFM's bottom-to-top rows are flipped on read and
//! write).
//!
//! # What the readers return
//! The values are the ones OpenImageIO hands to `idiff`, so that `penumbra diff`
//! and `idiff` compare the same numbers:
//! - **EXR**: half, float and uint samples converted to `f32` (uint by plain
//!   conversion, not normalised). Only the first layer (part) and its full
//!   resolution level are read. Channels are ordered as OpenImageIO orders them:
//!   grouped by layer prefix (the text before the last `.`; unprefixed channels
//!   first), then `R`, `G`, `B`, `A` in that order, then the others in the
//!   file's (alphabetical) order. The data window is read as the image; a data
//!   window that is not at the origin is accepted and its offset is dropped.
//!   Subsampled channels are refused.
//! - **PNG**: raw normalised code values (`v / 255` for 8-bit, `v / 65535` for
//!   16-bit), **not** linearised: OpenImageIO does not apply the sRGB transfer
//!   curve when reading PNG, and neither do we. Gray, gray+alpha, RGB, RGBA,
//!   palette (expanded) and low bit depths (expanded to 8 bits) are accepted.
//!   Channel names are `Y`, `Y A`, `R G B`, `R G B A`. Like OpenImageIO, colour
//!   is premultiplied by alpha on read, on the integer code values with
//!   truncation (`v · a / 255`; with a gAMA chunk and no sRGB chunk, in that
//!   gamma's space); [`decode_png_with`] can keep it unassociated.
//! - **PFM**: `PF` (RGB) and `Pf` (gray, channel `Y`); the sign of the scale
//!   gives the byte order (negative: little-endian), its magnitude is ignored
//!   (as OpenImageIO does; [`read_scene_input`] applies it, as pbrt-v3 does).
//! - **TGA** (by its `.tga` extension, as pbrt-v3 recognises it): see [`read_scene_input`].
//!
//! Scene inputs (textures, light maps) are read by [`read_scene_input`], which returns what
//! pbrt-v3's `ReadImage` returns (module `scene_input`): RGB, with pbrt-v3's decoders' rules.
//!
//! # Decompression guard
//! Before any pixel data is allocated, a file's header is checked against a cap on the decoded
//! image's size in memory (`width × height × channels × 4` bytes, the `f32` values): a small
//! file whose header claims a huge image (a decompression bomb, or a corrupt header) is refused
//! with [`ImageError::TooLarge`], naming the file, the size it claims and the cap. The cap is
//! [`DEFAULT_MAX_DECODED_BYTES`] (4 GiB), set by the environment variable
//! `PENUMBRA_MAX_IMAGE_BYTES` (bytes) or [`set_max_decoded_bytes`]. How well a file compresses
//! does not matter: a 734-byte, 1024² palette PNG is as welcome as any.
//!
//! # What the writers produce
//! - [`encode_exr`]: every channel as 32-bit float, ZIP-compressed scanlines.
//! - [`encode_png`]: 8-bit, sRGB-encoded (`v · 2^exposure`, sRGB transfer
//!   curve, clamped to [0, 1], rounded), with an `sRGB` chunk; RGB (from the
//!   `R G B` channels, plus `A` unencoded if present) or gray (from `Y` or a
//!   single channel).
//! - [`encode_pfm`]: little-endian `PF` from `R G B`, or `Pf` from `Y` / a
//!   single channel.
//!
//! All file writes go through [`write_atomic`].
//!
//! Malformed, truncated or unknown files are errors ([`ImageError`]), never
//! panics.

use std::fs::{self, File};
use std::io::{self, Cursor, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use thiserror::Error;

use crate::spectrum::{srgb_encode, Rgb};

mod scene_input;

/// An image I/O or image-operation error. File errors name the file.
#[derive(Debug, Error)]
pub enum ImageError {
    /// The file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: io::Error,
    },
    /// The file is not an image we can read: unknown magic number.
    #[error("{}: not an EXR, PNG or PFM file (unrecognised magic number) nor a .tga file", path.display())]
    UnknownFormat {
        /// The file.
        path: PathBuf,
    },
    /// The file has a known format but is malformed, truncated or uses a
    /// feature we do not support.
    #[error("{}: {format}: {message}", path.display())]
    Decode {
        /// The file.
        path: PathBuf,
        /// "EXR", "PNG" or "PFM".
        format: &'static str,
        /// What went wrong.
        message: String,
    },
    /// The image cannot be written in the requested format.
    #[error("{}: cannot write {format}: {message}", path.display())]
    Encode {
        /// The file.
        path: PathBuf,
        /// "EXR", "PNG" or "PFM".
        format: &'static str,
        /// What went wrong.
        message: String,
    },
    /// The file's header claims an image larger than the decompression guard allows.
    #[error(
        "{}: {format} image of {width}×{height}×{channels} values would take {bytes} bytes decoded, \
         over the {cap}-byte limit (raise it with the environment variable PENUMBRA_MAX_IMAGE_BYTES)",
        path.display()
    )]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// "EXR", "PNG", "PFM" or "TGA".
        format: &'static str,
        /// What the header claims.
        width: u64,
        height: u64,
        channels: u64,
        /// `width × height × channels × 4`.
        bytes: u64,
        /// The cap ([`max_decoded_bytes`]).
        cap: u64,
    },
    /// An invalid image operation (inconsistent sizes, bad arguments).
    #[error("{0}")]
    Invalid(String),
}

/// The default cap on a decoded image's size in memory, in bytes (4 GiB of `f32` values, e.g.
/// a 32768 × 16384 RGB environment map); see the module documentation.
pub const DEFAULT_MAX_DECODED_BYTES: u64 = 1 << 32;

/// The cap set by [`set_max_decoded_bytes`] (0: none set).
static MAX_DECODED_BYTES: AtomicU64 = AtomicU64::new(0);

/// The decompression guard's cap, in bytes: [`set_max_decoded_bytes`]'s value, else the
/// environment variable `PENUMBRA_MAX_IMAGE_BYTES`, else [`DEFAULT_MAX_DECODED_BYTES`].
pub fn max_decoded_bytes() -> u64 {
    match MAX_DECODED_BYTES.load(Ordering::Relaxed) {
        0 => {
            static FROM_ENV: std::sync::OnceLock<u64> = std::sync::OnceLock::new();
            *FROM_ENV.get_or_init(|| {
                std::env::var("PENUMBRA_MAX_IMAGE_BYTES")
                    .ok()
                    .and_then(|v| v.trim().parse::<u64>().ok())
                    .filter(|&v| v > 0)
                    .unwrap_or(DEFAULT_MAX_DECODED_BYTES)
            })
        }
        v => v,
    }
}

/// Sets the decompression guard's cap for the process (`None`: back to the environment
/// variable or the default).
pub fn set_max_decoded_bytes(cap: Option<u64>) {
    MAX_DECODED_BYTES.store(cap.unwrap_or(0).max(u64::from(cap.is_some())), Ordering::Relaxed);
}

/// Refuses an image whose decoded values (`width × height × channels` `f32`s) would exceed the
/// cap, before anything is allocated for it.
pub(crate) fn check_decoded_size(
    path: &Path,
    format: &'static str,
    width: u64,
    height: u64,
    channels: u64,
) -> Result<(), ImageError> {
    let cap = max_decoded_bytes();
    let bytes = width.saturating_mul(height).saturating_mul(channels).saturating_mul(4);
    if bytes > cap {
        return Err(ImageError::TooLarge { path: path.to_path_buf(), format, width, height, channels, bytes, cap });
    }
    Ok(())
}

fn decode_err(path: &Path, format: &'static str, message: impl Into<String>) -> ImageError {
    ImageError::Decode { path: path.to_path_buf(), format, message: message.into() }
}

fn encode_err(path: &Path, format: &'static str, message: impl Into<String>) -> ImageError {
    ImageError::Encode { path: path.to_path_buf(), format, message: message.into() }
}

/// Largest number of values (pixels × channels) an image may hold: 2^31.
/// Guards allocations driven by untrusted headers.
pub const MAX_VALUES: usize = 1 << 31;

/// Where a cropped image sits in its full frame: OpenEXR's display window (`full`, from
/// `(0, 0)`) and the data window's top-left pixel (`origin`, in the display window's
/// coordinates). pbrt-v3 writes a render with a crop window this way, so a crop keeps its place.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Frame {
    /// The full image's width and height.
    pub full: (u32, u32),
    /// The image's top-left pixel in the full image (outside it for an overscan data window).
    pub origin: (i32, i32),
}

/// A window `[x0, x1, y0, y1]` (half-open) in a frame's pixels.
pub type Window = [i64; 4];

/// Why two images have no pixels to compare (see [`overlap`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum OverlapError {
    /// They are (parts of) frames of different sizes.
    DifferentFrames { a: (u32, u32), b: (u32, u32) },
    /// The `within` window is empty or leaves the frame.
    BadWithin { within: [u32; 4], full: (u32, u32) },
    /// Their data windows (within `within`) share no pixel.
    Disjoint,
}

impl std::fmt::Display for OverlapError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            OverlapError::DifferentFrames { a, b } => {
                write!(f, "(part of) a {}×{} image against (part of) a {}×{} image", a.0, a.1, b.0, b.1)
            }
            OverlapError::BadWithin { within: c, full } => {
                write!(f, "[{},{})×[{},{}) is empty or outside the {}×{} image", c[0], c[1], c[2], c[3], full.0, full.1)
            }
            OverlapError::Disjoint => write!(f, "the images share no pixel of their frame"),
        }
    }
}

/// The pixels both `a` and `b` hold, where they sit in their common frame: a cropped EXR keeps
/// its place (its data window inside the full display window, as pbrt-v3 writes a render with a
/// crop window), so a crop is compared with the same pixels of the whole image or of another
/// crop. `within` (in the frame's pixels) narrows the window further. Returns the two images cut
/// to the common window and that window, or the images untouched and `None` when both are whole
/// and no `within` is given (then they may differ in size: the caller's comparison decides).
pub fn overlap(a: Image, b: Image, within: Option<[u32; 4]>) -> Result<(Image, Image, Option<Window>), OverlapError> {
    let (fa, fb) = (a.frame_or_whole(), b.frame_or_whole());
    if a.frame.is_none() && b.frame.is_none() && within.is_none() {
        return Ok((a, b, None));
    }
    if fa.full != fb.full {
        return Err(OverlapError::DifferentFrames { a: fa.full, b: fb.full });
    }
    let window = |img: &Image, f: Frame| -> Window {
        let (x, y) = (f.origin.0 as i64, f.origin.1 as i64);
        [x, x + img.width as i64, y, y + img.height as i64]
    };
    let (wa, wb) = (window(&a, fa), window(&b, fb));
    let mut w = [wa[0].max(wb[0]), wa[1].min(wb[1]), wa[2].max(wb[2]), wa[3].min(wb[3])];
    if let Some(c) = within {
        let (fw, fh) = fa.full;
        if c[0] >= c[1] || c[2] >= c[3] || c[1] > fw || c[3] > fh {
            return Err(OverlapError::BadWithin { within: c, full: fa.full });
        }
        w = [w[0].max(c[0] as i64), w[1].min(c[1] as i64), w[2].max(c[2] as i64), w[3].min(c[3] as i64)];
    }
    if w[0] >= w[1] || w[2] >= w[3] {
        return Err(OverlapError::Disjoint);
    }
    let part = |img: Image, at: Window| -> Image {
        if at == w {
            return img;
        }
        let c = |v: i64, o: i64| (v - o) as u32;
        img.crop(c(w[0], at[0]), c(w[1], at[0]), c(w[2], at[2]), c(w[3], at[2]))
            .expect("the common window lies inside each data window")
    };
    Ok((part(a, wa), part(b, wb), Some(w)))
}

/// A floating-point image with named channels, interleaved, row-major from the
/// top row: value `(x, y, c)` is at `data[(y * width + x) * channels.len() + c]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Channel names, e.g. `["R", "G", "B"]` or `["R", "G", "B", "variance.R", …]`.
    pub channels: Vec<String>,
    /// `width * height * channels.len()` values.
    pub data: Vec<f32>,
    /// `Some` for a part of a larger image (a crop), `None` for a whole image; see
    /// [`Image::with_frame`].
    pub frame: Option<Frame>,
}

impl Image {
    /// A zero-filled image. Errors if it would hold more than [`MAX_VALUES`]
    /// values or has no channels.
    pub fn new(width: u32, height: u32, channels: Vec<String>) -> Result<Image, ImageError> {
        let n = checked_len(width, height, channels.len())?;
        Ok(Image { width, height, channels, data: vec![0.0; n], frame: None })
    }

    /// Wraps existing data, checking that its length matches.
    pub fn from_data(width: u32, height: u32, channels: Vec<String>, data: Vec<f32>) -> Result<Image, ImageError> {
        let n = checked_len(width, height, channels.len())?;
        if data.len() != n {
            return Err(ImageError::Invalid(format!(
                "image data has {} values, expected {width}×{height}×{} = {n}",
                data.len(),
                channels.len()
            )));
        }
        Ok(Image { width, height, channels, data, frame: None })
    }

    /// This image placed in a `full` frame at `origin` (its data window); a frame that is the
    /// image itself (origin 0, the same size) is stored as `None`, so equal images compare equal.
    pub fn with_frame(mut self, full: (u32, u32), origin: (i32, i32)) -> Image {
        let whole = origin == (0, 0) && full == (self.width, self.height);
        self.frame = (!whole).then_some(Frame { full, origin });
        self
    }

    /// The full frame's size and this image's origin in it (`(width, height)` and `(0, 0)` for a
    /// whole image).
    pub fn frame_or_whole(&self) -> Frame {
        self.frame.unwrap_or(Frame { full: (self.width, self.height), origin: (0, 0) })
    }

    /// An `R G B` image from row-major (top row first) pixels.
    pub fn from_rgb(width: u32, height: u32, pixels: &[Rgb]) -> Result<Image, ImageError> {
        let data = pixels.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
        Image::from_data(width, height, channel_names(&["R", "G", "B"]), data)
    }

    /// Number of channels.
    pub fn nchannels(&self) -> usize {
        self.channels.len()
    }

    /// Number of pixels.
    pub fn npixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    fn offset(&self, x: u32, y: u32) -> usize {
        (y as usize * self.width as usize + x as usize) * self.channels.len()
    }

    /// Value of channel `c` at pixel `(x, y)`. Panics if out of range (use
    /// [`Image::try_get`] for unchecked input).
    pub fn get(&self, x: u32, y: u32, c: usize) -> f32 {
        assert!(x < self.width && y < self.height && c < self.channels.len(), "Image::get out of range");
        self.data[self.offset(x, y) + c]
    }

    /// Value of channel `c` at pixel `(x, y)`, or `None` if out of range.
    pub fn try_get(&self, x: u32, y: u32, c: usize) -> Option<f32> {
        if x < self.width && y < self.height && c < self.channels.len() {
            Some(self.data[self.offset(x, y) + c])
        } else {
            None
        }
    }

    /// Sets channel `c` at pixel `(x, y)`. Panics if out of range.
    pub fn set(&mut self, x: u32, y: u32, c: usize, v: f32) {
        assert!(x < self.width && y < self.height && c < self.channels.len(), "Image::set out of range");
        let o = self.offset(x, y);
        self.data[o + c] = v;
    }

    /// All channel values of pixel `(x, y)`. Panics if out of range.
    pub fn pixel(&self, x: u32, y: u32) -> &[f32] {
        assert!(x < self.width && y < self.height, "Image::pixel out of range");
        let o = self.offset(x, y);
        &self.data[o..o + self.channels.len()]
    }

    /// Mutable channel values of pixel `(x, y)`. Panics if out of range.
    pub fn pixel_mut(&mut self, x: u32, y: u32) -> &mut [f32] {
        assert!(x < self.width && y < self.height, "Image::pixel_mut out of range");
        let o = self.offset(x, y);
        let n = self.channels.len();
        &mut self.data[o..o + n]
    }

    /// Index of the channel with this exact name.
    pub fn channel_index(&self, name: &str) -> Option<usize> {
        self.channels.iter().position(|c| c == name)
    }

    /// Indices of the colour channels: `R G B` if all present, else `Y` (or the
    /// only channel) three times.
    pub fn rgb_indices(&self) -> Option<[usize; 3]> {
        match (self.channel_index("R"), self.channel_index("G"), self.channel_index("B")) {
            (Some(r), Some(g), Some(b)) => Some([r, g, b]),
            _ => {
                let y = self.channel_index("Y").or(if self.channels.len() == 1 { Some(0) } else { None })?;
                Some([y, y, y])
            }
        }
    }

    /// Colour of pixel `(x, y)` (see [`Image::rgb_indices`]); `None` if the
    /// image has no colour channels or the pixel is out of range.
    pub fn rgb(&self, x: u32, y: u32) -> Option<Rgb> {
        let [r, g, b] = self.rgb_indices()?;
        Some(Rgb::new(self.try_get(x, y, r)?, self.try_get(x, y, g)?, self.try_get(x, y, b)?))
    }

    /// All pixel colours, row-major from the top (see [`Image::rgb_indices`]).
    pub fn to_rgb(&self) -> Option<Vec<Rgb>> {
        let [r, g, b] = self.rgb_indices()?;
        let n = self.channels.len();
        Some(self.data.chunks_exact(n).map(|p| Rgb::new(p[r], p[g], p[b])).collect())
    }

    /// A new image with only the named channels, in the given order.
    pub fn select_channels<S: AsRef<str>>(&self, names: &[S]) -> Result<Image, ImageError> {
        let idx = names
            .iter()
            .map(|n| {
                self.channel_index(n.as_ref()).ok_or_else(|| {
                    ImageError::Invalid(format!("no channel {:?} (image has {})", n.as_ref(), self.channels.join(", ")))
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let n = self.channels.len();
        let data = self.data.chunks_exact(n.max(1)).flat_map(|p| idx.iter().map(move |&i| p[i])).collect();
        let img =
            Image::from_data(self.width, self.height, names.iter().map(|s| s.as_ref().to_string()).collect(), data)?;
        Ok(Image { frame: self.frame, ..img })
    }

    /// The pixels with `x0 <= x < x1`, `y0 <= y < y1` (half-open, pixel units of this image),
    /// framed where they sit in this image's frame.
    pub fn crop(&self, x0: u32, x1: u32, y0: u32, y1: u32) -> Result<Image, ImageError> {
        if x0 >= x1 || y0 >= y1 || x1 > self.width || y1 > self.height {
            return Err(ImageError::Invalid(format!(
                "crop [{x0},{x1})×[{y0},{y1}) is empty or outside the {}×{} image",
                self.width, self.height
            )));
        }
        let n = self.channels.len();
        let mut data = Vec::with_capacity((x1 - x0) as usize * (y1 - y0) as usize * n);
        for y in y0..y1 {
            let a = self.offset(x0, y);
            data.extend_from_slice(&self.data[a..a + (x1 - x0) as usize * n]);
        }
        let f = self.frame_or_whole();
        let origin = (f.origin.0 + x0 as i32, f.origin.1 + y0 as i32);
        Ok(Image::from_data(x1 - x0, y1 - y0, self.channels.clone(), data)?.with_frame(f.full, origin))
    }

    /// Exact `k × k` box downsampling: each output pixel is the mean (in f64)
    /// of a `k × k` block. Refuses (error) sizes not divisible by `k` and
    /// `k == 0`; it never crops silently. `k == 1` returns a copy.
    pub fn box_downsample(&self, k: u32) -> Result<Image, ImageError> {
        if k == 0 || (self.width / k) * k != self.width || (self.height / k) * k != self.height {
            return Err(ImageError::Invalid(format!(
                "box_downsample: {}×{} is not divisible by {k}",
                self.width, self.height
            )));
        }
        let (w, h, n) = (self.width / k, self.height / k, self.channels.len());
        let mut out = Image::new(w, h, self.channels.clone())?;
        let inv = 1.0 / (k as f64 * k as f64);
        let mut acc = vec![0.0f64; n];
        for oy in 0..h {
            for ox in 0..w {
                acc.iter_mut().for_each(|a| *a = 0.0);
                for y in oy * k..(oy + 1) * k {
                    for x in ox * k..(ox + 1) * k {
                        for (a, v) in acc.iter_mut().zip(self.pixel(x, y)) {
                            *a += *v as f64;
                        }
                    }
                }
                for (o, a) in out.pixel_mut(ox, oy).iter_mut().zip(&acc) {
                    *o = (*a * inv) as f32;
                }
            }
        }
        // A crop stays framed where its frame scales by k exactly.
        let (ki, f) = (k as i32, self.frame_or_whole());
        Ok(match f.full.0 % k == 0 && f.full.1 % k == 0 && f.origin.0 % ki == 0 && f.origin.1 % ki == 0 {
            true => out.with_frame((f.full.0 / k, f.full.1 / k), (f.origin.0 / ki, f.origin.1 / ki)),
            false => out,
        })
    }
}

fn checked_len(width: u32, height: u32, nchannels: usize) -> Result<usize, ImageError> {
    if nchannels == 0 {
        return Err(ImageError::Invalid("an image needs at least one channel".into()));
    }
    (width as usize)
        .checked_mul(height as usize)
        .and_then(|p| p.checked_mul(nchannels))
        .filter(|&n| n <= MAX_VALUES)
        .ok_or_else(|| ImageError::Invalid(format!("image {width}×{height}×{nchannels} is too large")))
}

/// Owned channel names from string slices.
pub fn channel_names(names: &[&str]) -> Vec<String> {
    names.iter().map(|s| s.to_string()).collect()
}

// ---------------------------------------------------------------------------
// Reading
// ---------------------------------------------------------------------------

/// An image file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// OpenEXR.
    Exr,
    /// PNG.
    Png,
    /// Portable float map.
    Pfm,
    /// Truevision TGA (read only; recognised by its extension, as pbrt-v3 does: it has no
    /// magic number).
    Tga,
}

impl Format {
    /// Detects the format from the first bytes of a file.
    pub fn from_magic(bytes: &[u8]) -> Option<Format> {
        if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
            Some(Format::Exr)
        } else if bytes.starts_with(&[0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a]) {
            Some(Format::Png)
        } else if bytes.len() >= 3
            && bytes[0] == b'P'
            && (bytes[1] == b'F' || bytes[1] == b'f')
            && bytes[2].is_ascii_whitespace()
        {
            Some(Format::Pfm)
        } else {
            None
        }
    }

    /// The format a file name's extension asks for (case-insensitive), among those penumbra
    /// writes (EXR, PNG, PFM).
    pub fn from_extension(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "exr" => Some(Format::Exr),
            "png" => Some(Format::Png),
            "pfm" => Some(Format::Pfm),
            _ => None,
        }
    }

    /// The format of a file to read: its magic number, else (TGA has none) a `.tga`
    /// extension (any case). [`Format::from_extension`] names only the formats penumbra writes.
    pub fn detect(bytes: &[u8], path: &Path) -> Option<Format> {
        let tga = path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("tga"));
        Format::from_magic(bytes).or_else(|| tga.then_some(Format::Tga))
    }
}

/// Reads an EXR, PNG, PFM or TGA file; the format is detected from its content (TGA from
/// its extension).
pub fn read(path: impl AsRef<Path>) -> Result<Image, ImageError> {
    let path = path.as_ref();
    let bytes = fs::read(path).map_err(|source| ImageError::Io { path: path.to_path_buf(), source })?;
    decode(&bytes, path)
}

/// Reads an image for use as scene input (textures, light maps) as pbrt-v3's `ReadImage`
/// does: always `R G B` channels, with each format's pbrt-v3 rules (see `scene_input`). Any
/// sRGB decoding is the caller's choice.
pub fn read_scene_input(path: impl AsRef<Path>) -> Result<Image, ImageError> {
    let path = path.as_ref();
    let bytes = fs::read(path).map_err(|source| ImageError::Io { path: path.to_path_buf(), source })?;
    scene_input::decode(&bytes, path)
}

/// Decodes an image held in memory; `path` is only used in error messages.
pub fn decode(bytes: &[u8], path: &Path) -> Result<Image, ImageError> {
    match Format::detect(bytes, path) {
        Some(Format::Exr) => decode_exr(bytes, path),
        Some(Format::Png) => decode_png(bytes, path),
        Some(Format::Pfm) => decode_pfm(bytes, path),
        Some(Format::Tga) => scene_input::decode_tga(bytes, path),
        None => Err(ImageError::UnknownFormat { path: path.to_path_buf() }),
    }
}

/// Rank of a channel name inside its layer, as OpenImageIO orders EXR channels.
fn exr_channel_rank(suffix: &str) -> u8 {
    match suffix.to_ascii_lowercase().as_str() {
        "r" | "red" => 0,
        "g" | "green" => 1,
        "b" | "blue" => 2,
        "a" | "alpha" => 3,
        _ => 4,
    }
}

fn exr_layer_and_suffix(name: &str) -> (&str, &str) {
    match name.rfind('.') {
        Some(i) => (&name[..i], &name[i + 1..]),
        None => ("", name),
    }
}

/// The decompression guard for an EXR: the first part's data window and channel count from
/// its header, before the pixels are decoded. A header the exr crate cannot read is left to
/// the decoder's error.
fn check_exr_size(bytes: &[u8], path: &Path) -> Result<(), ImageError> {
    let meta = std::panic::catch_unwind(|| exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false));
    if let Ok(Ok(meta)) = meta {
        if let Some(h) = meta.headers.first() {
            let size = h.layer_size;
            check_decoded_size(path, "EXR", size.width() as u64, size.height() as u64, h.channels.list.len() as u64)?;
        }
    }
    Ok(())
}

/// Decodes an OpenEXR file held in memory (first layer, full resolution).
pub fn decode_exr(bytes: &[u8], path: &Path) -> Result<Image, ImageError> {
    use exr::prelude::{FlatSamples, ReadChannels, ReadLayers, Vec2};
    let err = |m: String| decode_err(path, "EXR", m);
    check_exr_size(bytes, path)?;
    // The exr crate validates headers and chunk tables; decoding is wrapped in
    // catch_unwind as a last line of defence against a panic on hostile input.
    let result = std::panic::catch_unwind(|| {
        exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .from_buffered(Cursor::new(bytes))
    });
    let image = match result {
        Ok(Ok(img)) => img,
        Ok(Err(e)) => return Err(err(e.to_string())),
        Err(_) => return Err(err("decoder failed on malformed data".into())),
    };
    let display = image.attributes.display_window;
    let layer = image.layer_data;
    let (w, h) = (layer.size.width(), layer.size.height());
    let (width, height) = (
        u32::try_from(w).map_err(|_| err("image too wide".into()))?,
        u32::try_from(h).map_err(|_| err("image too tall".into()))?,
    );
    let mut chans: Vec<(String, &FlatSamples)> = Vec::new();
    for ch in layer.channel_data.list.iter() {
        if ch.sampling != Vec2(1, 1) {
            return Err(err(format!("subsampled channel {} is not supported", ch.name)));
        }
        chans.push((ch.name.to_string(), &ch.sample_data));
    }
    // OpenImageIO's order: by layer, then R G B A, then the file order.
    let mut order: Vec<usize> = (0..chans.len()).collect();
    order.sort_by(|&a, &b| {
        let (la, sa) = exr_layer_and_suffix(&chans[a].0);
        let (lb, sb) = exr_layer_and_suffix(&chans[b].0);
        la.cmp(lb).then(exr_channel_rank(sa).cmp(&exr_channel_rank(sb))).then(a.cmp(&b))
    });
    let n = chans.len();
    let npix = checked_len(width, height, n.max(1)).map_err(|e| err(e.to_string()))? / n.max(1);
    if n == 0 {
        return Err(err("no channels".into()));
    }
    for &src in &order {
        if chans[src].1.len() != npix {
            return Err(err(format!("channel {} has {} samples, expected {npix}", chans[src].0, chans[src].1.len())));
        }
    }
    // Interleave in blocks of pixels, so that the strided writes of every channel stay in cache.
    const BLOCK: usize = 4096;
    let mut data = vec![0.0f32; npix * n];
    for (b, out) in data.chunks_mut(BLOCK * n).enumerate() {
        let base = b * BLOCK;
        let len = out.len() / n;
        for (dst, &src) in order.iter().enumerate() {
            let slots = out.iter_mut().skip(dst).step_by(n);
            match chans[src].1 {
                FlatSamples::F16(v) => slots.zip(&v[base..base + len]).for_each(|(o, x)| *o = x.to_f32()),
                FlatSamples::F32(v) => slots.zip(&v[base..base + len]).for_each(|(o, x)| *o = *x),
                FlatSamples::U32(v) => slots.zip(&v[base..base + len]).for_each(|(o, x)| *o = *x as f32),
            }
        }
    }
    let names = order.iter().map(|&i| chans[i].0.clone()).collect();
    let img = Image::from_data(width, height, names, data).map_err(|e| err(e.to_string()))?;
    // The data window's place in the display window (a crop keeps it, as pbrt-v3 writes it).
    let position = layer.attributes.layer_position;
    let origin = (position.x().saturating_sub(display.position.x()), position.y().saturating_sub(display.position.y()));
    match (u32::try_from(display.size.width()), u32::try_from(display.size.height())) {
        (Ok(fw), Ok(fh)) if fw > 0 && fh > 0 => Ok(img.with_frame((fw, fh), origin)),
        _ => Ok(img),
    }
}

/// Decodes a PNG file held in memory into raw normalised values (no sRGB
/// decoding), with colour premultiplied by alpha as OpenImageIO does (see the
/// module documentation).
pub fn decode_png(bytes: &[u8], path: &Path) -> Result<Image, ImageError> {
    decode_png_with(bytes, path, true)
}

/// OpenImageIO's alpha association on read, on integer code values: colour
/// `v` becomes `v · a / max` truncated (or, for a gamma `g != 1` declared by a
/// gAMA chunk, `v · (a / max)^g` truncated).
fn associate_png_alpha(raw: &mut [u32], n: usize, max: u32, gamma: f32) {
    for p in raw.chunks_exact_mut(n) {
        let a = p[n - 1];
        for v in &mut p[..n - 1] {
            *v = if gamma == 1.0 { *v * a / max } else { (*v as f32 * (a as f32 / max as f32).powf(gamma)) as u32 };
        }
    }
}

/// The png crate's own allocation limit: what the decompression guard allows, as raw bytes
/// (the decoder's buffers hold at most 8 bytes per pixel, the guard counts 4 per value).
pub(crate) fn png_limits() -> png::Limits {
    png::Limits { bytes: usize::try_from(max_decoded_bytes()).unwrap_or(usize::MAX) }
}

/// Like [`decode_png`]; with `associate_alpha == false` the colour channels
/// of images with alpha are returned as stored (unassociated).
pub fn decode_png_with(bytes: &[u8], path: &Path, associate_alpha: bool) -> Result<Image, ImageError> {
    let err = |m: String| decode_err(path, "PNG", m);
    let mut decoder = png::Decoder::new_with_limits(Cursor::new(bytes), png_limits());
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder.read_info().map_err(|e| err(e.to_string()))?;
    let (width, height, gamma) = {
        let info = reader.info();
        // OpenImageIO associates alpha in a gamma space only for files with a
        // gAMA chunk and no sRGB chunk (its "oiio:Gamma" attribute).
        let gamma = match (info.srgb, info.gama_chunk) {
            (None, Some(g)) if g.into_value() > 0.0 => 1.0 / g.into_value(),
            _ => 1.0,
        };
        (info.width, info.height, gamma)
    };
    let (color, depth) = reader.output_color_type();
    let names: &[&str] = match color {
        png::ColorType::Grayscale => &["Y"],
        png::ColorType::GrayscaleAlpha => &["Y", "A"],
        png::ColorType::Rgb => &["R", "G", "B"],
        png::ColorType::Rgba => &["R", "G", "B", "A"],
        png::ColorType::Indexed => return Err(err("palette was not expanded".into())),
    };
    let n = names.len();
    check_decoded_size(path, "PNG", width as u64, height as u64, n as u64)?;
    let nvals = checked_len(width, height, n).map_err(|e| err(e.to_string()))?;
    let bps = match depth {
        png::BitDepth::Eight => 1,
        png::BitDepth::Sixteen => 2,
        other => return Err(err(format!("unexpected output bit depth {other:?}"))),
    };
    let size = reader.output_buffer_size().ok_or_else(|| err("image too large".into()))?;
    let mut buf = vec![0u8; size];
    let info = reader.next_frame(&mut buf).map_err(|e| err(e.to_string()))?;
    let line = info.line_size;
    let mut raw: Vec<u32> = Vec::with_capacity(nvals);
    for y in 0..height as usize {
        let row = buf.get(y * line..y * line + width as usize * n * bps).ok_or_else(|| err("short frame".into()))?;
        if bps == 1 {
            raw.extend(row.iter().map(|&v| v as u32));
        } else {
            raw.extend(row.chunks_exact(2).map(|c| u16::from_be_bytes([c[0], c[1]]) as u32));
        }
    }
    let max = if bps == 1 { 255u32 } else { 65535 };
    if associate_alpha && (n == 2 || n == 4) {
        associate_png_alpha(&mut raw, n, max, gamma);
    }
    let data = raw.iter().map(|&v| v as f32 / max as f32).collect();
    // Read up to IEND, so that a file cut after its pixel data is still an error.
    reader.finish().map_err(|e| err(e.to_string()))?;
    Image::from_data(width, height, channel_names(names), data).map_err(|e| err(e.to_string()))
}

/// Decodes a PFM file held in memory (the header's scale is only read for the byte order).
pub fn decode_pfm(bytes: &[u8], path: &Path) -> Result<Image, ImageError> {
    decode_pfm_with_scale(bytes, path).map(|(img, _)| img)
}

/// [`decode_pfm`] and the header's scale.
pub(crate) fn decode_pfm_with_scale(bytes: &[u8], path: &Path) -> Result<(Image, f32), ImageError> {
    let err = |m: &str| decode_err(path, "PFM", m);
    let nch = match bytes.get(..2) {
        Some(b"PF") => 3,
        Some(b"Pf") => 1,
        _ => return Err(err("missing PF/Pf magic")),
    };
    let mut pos = 2;
    let mut token = |what: &str| -> Result<&[u8], ImageError> {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if start == pos || pos - start > 64 {
            return Err(err(&format!("bad or missing {what} in header")));
        }
        Ok(&bytes[start..pos])
    };
    let parse_u32 = |t: &[u8], what: &str| -> Result<u32, ImageError> {
        std::str::from_utf8(t)
            .ok()
            .and_then(|s| s.parse::<u32>().ok())
            .filter(|&v| v > 0)
            .ok_or_else(|| err(&format!("bad {what} in header")))
    };
    let width = parse_u32(token("width")?, "width")?;
    let height = parse_u32(token("height")?, "height")?;
    let scale: f32 = std::str::from_utf8(token("scale")?)
        .ok()
        .and_then(|s| s.parse().ok())
        .filter(|s: &f32| s.is_finite() && *s != 0.0)
        .ok_or_else(|| err("bad scale in header (must be a finite non-zero number)"))?;
    // Exactly one whitespace byte separates the header from the data.
    if pos >= bytes.len() || !bytes[pos].is_ascii_whitespace() {
        return Err(err("truncated header"));
    }
    pos += 1;
    let little = scale < 0.0;
    check_decoded_size(path, "PFM", width as u64, height as u64, nch as u64)?;
    let n = checked_len(width, height, nch).map_err(|e| err(&e.to_string()))?;
    let body = &bytes[pos..];
    if body.len() / 4 < n {
        return Err(err(&format!(
            "truncated: {} data bytes for a {width}×{height}×{nch} image ({} needed)",
            body.len(),
            n * 4
        )));
    }
    let mut data = vec![0.0f32; n];
    let row = width as usize * nch;
    for (file_row, chunk) in body[..n * 4].chunks_exact(row * 4).enumerate() {
        // File rows go bottom to top.
        let y = height as usize - 1 - file_row;
        for (i, b) in chunk.chunks_exact(4).enumerate() {
            let b = [b[0], b[1], b[2], b[3]];
            data[y * row + i] = if little { f32::from_le_bytes(b) } else { f32::from_be_bytes(b) };
        }
    }
    let names = if nch == 3 { channel_names(&["R", "G", "B"]) } else { channel_names(&["Y"]) };
    Ok((Image::from_data(width, height, names, data).map_err(|e| err(&e.to_string()))?, scale))
}

// ---------------------------------------------------------------------------
// Writing
// ---------------------------------------------------------------------------

/// Encodes every channel as a 32-bit float OpenEXR (ZIP scanlines).
pub fn encode_exr(image: &Image, path: &Path) -> Result<Vec<u8>, ImageError> {
    encode_exr_with(image, path, true)
}

/// [`encode_exr`], ZIP-compressed or (`zip` false) uncompressed: the same values, written
/// about 10× faster (deflate is most of the cost of writing a float image).
pub fn encode_exr_with(image: &Image, path: &Path, zip: bool) -> Result<Vec<u8>, ImageError> {
    use exr::prelude::{
        AnyChannel, AnyChannels, Encoding, FlatSamples, Layer, LayerAttributes, SmallVec, Text, Vec2, WritableImage,
    };
    let err = |m: String| encode_err(path, "EXR", m);
    if image.width == 0 || image.height == 0 {
        return Err(err("empty image".into()));
    }
    if image.data.len() != image.npixels() * image.nchannels() || image.channels.is_empty() {
        return Err(err("inconsistent image data length".into()));
    }
    let mut seen = std::collections::HashSet::new();
    let n = image.nchannels();
    let mut list = SmallVec::<[AnyChannel<FlatSamples>; 4]>::new();
    for (c, name) in image.channels.iter().enumerate() {
        if name.is_empty() || !seen.insert(name.as_str()) {
            return Err(err(format!("empty or duplicate channel name {name:?}")));
        }
        let text = Text::new_or_none(name.as_str()).ok_or_else(|| err(format!("invalid channel name {name:?}")))?;
        let samples: Vec<f32> = image.data.iter().skip(c).step_by(n).copied().collect();
        list.push(AnyChannel::new(text, FlatSamples::F32(samples)));
    }
    let size = (image.width as usize, image.height as usize);
    let encoding = if zip { Encoding::SMALL_LOSSLESS } else { Encoding::UNCOMPRESSED };
    // A crop is written as pbrt-v3 writes one: the full frame as the display window, the crop
    // as the data window placed in it.
    let frame = image.frame_or_whole();
    let attributes = LayerAttributes { layer_position: Vec2(frame.origin.0, frame.origin.1), ..Default::default() };
    let layer = Layer::new(size, attributes, encoding, AnyChannels::sort(list));
    let mut exr_image = exr::image::Image::from_layer(layer);
    exr_image.attributes.display_window =
        exr::meta::attribute::IntegerBounds::new(Vec2(0, 0), Vec2(frame.full.0 as usize, frame.full.1 as usize));
    let mut out = Cursor::new(Vec::new());
    // Chunks compress in parallel and are written sorted (line order increasing): the bytes are
    // those of a sequential write (test `parallel_exr_write_is_byte_identical`).
    exr_image.write().to_buffered(&mut out).map_err(|e| err(e.to_string()))?;
    Ok(out.into_inner())
}

fn to_u8(v: f32) -> u8 {
    // NaN maps to 0.
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    (v * 255.0 + 0.5) as u8
}

/// Encodes an 8-bit sRGB PNG: colour values are multiplied by `2^exposure`,
/// sRGB-encoded, clamped to [0, 1] and rounded; alpha (if an `A` channel exists
/// alongside `R G B`) is clamped only.
pub fn encode_png(image: &Image, exposure: f32, path: &Path) -> Result<Vec<u8>, ImageError> {
    let err = |m: String| encode_err(path, "PNG", m);
    if image.width == 0 || image.height == 0 || image.data.len() != image.npixels() * image.nchannels() {
        return Err(err("empty or inconsistent image".into()));
    }
    let gain = exposure.exp2();
    let n = image.nchannels();
    let gray = image.channel_index("R").is_none() || image.channel_index("G").is_none();
    let idx = image.rgb_indices().ok_or_else(|| err("no R G B or Y channel".into()))?;
    let alpha = if gray { None } else { image.channel_index("A") };
    let (color, per) = match (gray, alpha) {
        (true, _) => (png::ColorType::Grayscale, 1),
        (false, None) => (png::ColorType::Rgb, 3),
        (false, Some(_)) => (png::ColorType::Rgba, 4),
    };
    let mut bytes = Vec::with_capacity(image.npixels() * per);
    for p in image.data.chunks_exact(n) {
        for &i in &idx[..if gray { 1 } else { 3 }] {
            bytes.push(to_u8(srgb_encode((p[i] * gain).clamp(0.0, 1.0))));
        }
        if let Some(a) = alpha {
            bytes.push(to_u8(p[a]));
        }
    }
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, image.width, image.height);
        enc.set_color(color);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut w = enc.write_header().map_err(|e| err(e.to_string()))?;
        w.write_image_data(&bytes).map_err(|e| err(e.to_string()))?;
        w.finish().map_err(|e| err(e.to_string()))?;
    }
    Ok(out)
}

/// Encodes already display-ready 8-bit RGB bytes (row-major from the top, 3
/// bytes per pixel) as a PNG, without any transfer curve; for plots and heat maps.
pub fn encode_png_rgb8(width: u32, height: u32, rgb: &[u8], path: &Path) -> Result<Vec<u8>, ImageError> {
    let err = |m: String| encode_err(path, "PNG", m);
    if width == 0 || height == 0 || rgb.len() != width as usize * height as usize * 3 {
        return Err(err("empty image or wrong byte count".into()));
    }
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut w = enc.write_header().map_err(|e| err(e.to_string()))?;
        w.write_image_data(rgb).map_err(|e| err(e.to_string()))?;
        w.finish().map_err(|e| err(e.to_string()))?;
    }
    Ok(out)
}

/// Encodes a little-endian PFM: `PF` from the colour channels (see
/// [`Image::rgb_indices`]), or `Pf` for a single-channel / `Y`-only image.
pub fn encode_pfm(image: &Image, path: &Path) -> Result<Vec<u8>, ImageError> {
    let err = |m: String| encode_err(path, "PFM", m);
    if image.width == 0 || image.height == 0 || image.data.len() != image.npixels() * image.nchannels() {
        return Err(err("empty or inconsistent image".into()));
    }
    let gray = image.channel_index("R").is_none() || image.channel_index("G").is_none();
    let idx = image.rgb_indices().ok_or_else(|| err("no R G B or Y channel".into()))?;
    let idx = if gray { &idx[..1] } else { &idx[..] };
    let mut out = format!("{}\n{} {}\n-1\n", if gray { "Pf" } else { "PF" }, image.width, image.height).into_bytes();
    for y in (0..image.height).rev() {
        for x in 0..image.width {
            let p = image.pixel(x, y);
            for &i in idx {
                out.extend_from_slice(&p[i].to_le_bytes());
            }
        }
    }
    Ok(out)
}

/// Writes `image` to `path` in the format its extension names (`.exr`,
/// `.png` with exposure 0, `.pfm`), atomically (see [`write_atomic`]).
pub fn write(image: &Image, path: impl AsRef<Path>) -> Result<(), ImageError> {
    let path = path.as_ref();
    match Format::from_extension(path) {
        Some(Format::Exr) => write_exr(image, path),
        Some(Format::Png) => write_png(image, path, 0.0),
        Some(Format::Pfm) => write_pfm(image, path),
        Some(Format::Tga) | None => Err(encode_err(path, "image", "unknown extension (expected .exr, .png or .pfm)")),
    }
}

/// Writes a float32 EXR with all channels, atomically.
pub fn write_exr(image: &Image, path: impl AsRef<Path>) -> Result<(), ImageError> {
    let path = path.as_ref();
    let bytes = encode_exr(image, path)?;
    write_atomic(path, |w| w.write_all(&bytes))
}

/// Writes a float32 EXR with all channels, uncompressed, atomically.
pub fn write_exr_uncompressed(image: &Image, path: impl AsRef<Path>) -> Result<(), ImageError> {
    let path = path.as_ref();
    let bytes = encode_exr_with(image, path, false)?;
    write_atomic(path, |w| w.write_all(&bytes))
}

/// Writes an 8-bit sRGB PNG with the given exposure (stops), atomically.
pub fn write_png(image: &Image, path: impl AsRef<Path>, exposure: f32) -> Result<(), ImageError> {
    let path = path.as_ref();
    let bytes = encode_png(image, exposure, path)?;
    write_atomic(path, |w| w.write_all(&bytes))
}

/// Writes a PFM, atomically.
pub fn write_pfm(image: &Image, path: impl AsRef<Path>) -> Result<(), ImageError> {
    let path = path.as_ref();
    let bytes = encode_pfm(image, path)?;
    write_atomic(path, |w| w.write_all(&bytes))
}

static TMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// The permissions of the file at `path` if one exists and may be replaced; an error if it is
/// read-only (no write permission bit at all, which even a privileged user's write would
/// ignore) or the current user may not write it. Replacing a file through a rename needs only
/// the directory's permission, so without this check a protected reference image would be
/// silently replaced (issue 41).
pub fn existing_writable(path: &Path) -> io::Result<Option<fs::Permissions>> {
    let Ok(meta) = fs::metadata(path) else { return Ok(None) };
    if meta.is_dir() {
        return Err(io::Error::new(io::ErrorKind::IsADirectory, "is a directory"));
    }
    if meta.permissions().readonly() {
        return Err(io::Error::new(
            io::ErrorKind::PermissionDenied,
            "the existing file is read-only; it is not replaced (make it writable to overwrite it)",
        ));
    }
    // Opening for writing without truncating changes nothing but asks the OS for this user's right.
    File::options().write(true).open(path).map_err(|e| {
        io::Error::new(e.kind(), format!("the existing file cannot be written ({e}); it is not replaced"))
    })?;
    Ok(Some(meta.permissions()))
}

/// Writes a file atomically: `produce` writes into a new temporary file in the
/// same directory as `path`, which is flushed, fsync'ed and then renamed over
/// `path`. If `produce` or any step fails, the temporary file is removed and an
/// existing file at `path` is left untouched. The directory is fsync'ed after
/// the rename where the platform allows it (best effort).
pub fn write_atomic<F>(path: impl AsRef<Path>, produce: F) -> Result<(), ImageError>
where
    F: FnOnce(&mut dyn Write) -> io::Result<()>,
{
    let path = path.as_ref();
    let io_err = |source| ImageError::Io { path: path.to_path_buf(), source };
    let file_name =
        path.file_name().ok_or_else(|| io_err(io::Error::new(io::ErrorKind::InvalidInput, "not a file path")))?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(file_name);
    tmp_name.push(format!(".tmp-{}-{}", std::process::id(), TMP_COUNTER.fetch_add(1, Ordering::Relaxed)));
    let tmp = dir.join(tmp_name);
    let existing = existing_writable(path).map_err(io_err)?;
    let result = (|| -> io::Result<()> {
        let file = File::options().write(true).create_new(true).open(&tmp)?;
        let mut w = io::BufWriter::new(file);
        produce(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        drop(file);
        // The replacement keeps the replaced file's permissions (not the umask's default).
        if let Some(permissions) = existing {
            fs::set_permissions(&tmp, permissions)?;
        }
        fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = fs::remove_file(&tmp);
        return Err(io_err(e));
    }
    if let Ok(d) = File::open(&dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmpdir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("penumbra-image-{tag}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        d
    }

    fn ramp(w: u32, h: u32, names: &[&str]) -> Image {
        let n = names.len();
        let data = (0..w as usize * h as usize * n).map(|i| (i as f32 * 0.37).sin() * 3.0 + 0.25).collect();
        Image::from_data(w, h, channel_names(names), data).unwrap()
    }

    /// A crop's frame survives an EXR round trip (display and data windows), a whole image has
    /// none, and box downsampling scales the frame where it divides.
    #[test]
    fn exr_keeps_a_crops_frame() {
        let img = ramp(8, 6, &["R", "G", "B"]);
        let c = img.crop(2, 6, 4, 6).unwrap();
        assert_eq!(c.frame, Some(Frame { full: (8, 6), origin: (2, 4) }));
        let back = decode_exr(&encode_exr(&c, Path::new("c.exr")).unwrap(), Path::new("c.exr")).unwrap();
        assert_eq!(back, c);
        let whole = decode_exr(&encode_exr(&img, Path::new("w.exr")).unwrap(), Path::new("w.exr")).unwrap();
        assert_eq!(whole.frame, None);
        assert_eq!(img.crop(0, 8, 0, 6).unwrap().frame, None);
        assert_eq!(c.box_downsample(2).unwrap().frame, Some(Frame { full: (4, 3), origin: (1, 2) }));
        assert_eq!(img.crop(1, 3, 0, 2).unwrap().box_downsample(2).unwrap().frame, None);
        assert_eq!(c.select_channels(&["G"]).unwrap().frame, c.frame);
    }

    /// `overlap` cuts two images of one frame to the pixels both hold, where they sit: a crop
    /// against the whole image, two overlapping crops, a `within` window; different frames and
    /// disjoint crops are refused, and two whole images are left alone.
    #[test]
    fn overlap_places_crops_in_their_frame() {
        let img = ramp(8, 6, &["R", "G", "B"]);
        let (a, b, w) = overlap(img.crop(2, 6, 1, 5).unwrap(), img.clone(), None).unwrap();
        assert_eq!(w, Some([2, 6, 1, 5]));
        assert_eq!((a.data == b.data, a.frame, b.frame), (true, b.frame, Some(Frame { full: (8, 6), origin: (2, 1) })));
        let (a, b, w) =
            overlap(img.crop(0, 4, 0, 3).unwrap(), img.crop(2, 8, 2, 6).unwrap(), Some([0, 8, 0, 6])).unwrap();
        assert_eq!(
            (w, a.data == b.data, a.data == img.crop(2, 4, 2, 3).unwrap().data),
            (Some([2, 4, 2, 3]), true, true)
        );
        let (_, _, w) = overlap(img.clone(), img.clone(), Some([1, 3, 1, 2])).unwrap();
        assert_eq!(w, Some([1, 3, 1, 2]));
        let other = ramp(4, 3, &["R", "G", "B"]);
        assert_eq!(overlap(img.clone(), other.clone(), None).unwrap().2, None);
        assert_eq!(
            overlap(img.crop(0, 2, 0, 2).unwrap(), other, None).unwrap_err(),
            OverlapError::DifferentFrames { a: (8, 6), b: (4, 3) }
        );
        let disjoint = overlap(img.crop(0, 2, 0, 2).unwrap(), img.crop(4, 8, 0, 6).unwrap(), None);
        assert_eq!(disjoint.unwrap_err(), OverlapError::Disjoint);
        assert!(matches!(overlap(img.clone(), img, Some([0, 9, 0, 6])), Err(OverlapError::BadWithin { .. })));
    }

    /// Parallel compression writes the bytes a sequential write does, and reads back the same
    /// values (15 channels, so the blocked interleave of the reader is exercised).
    #[test]
    fn parallel_exr_write_is_byte_identical() {
        let names: Vec<String> = (0..12).map(|i| format!("sh.{i}")).chain(["R", "G", "B"].map(String::from)).collect();
        let refs: Vec<&str> = names.iter().map(|s| s.as_str()).collect();
        let img = ramp(300, 97, &refs);
        let path = Path::new("x.exr");
        let bytes = encode_exr(&img, path).unwrap();
        use exr::prelude::{
            AnyChannel, AnyChannels, Encoding, FlatSamples, Layer, LayerAttributes, SmallVec, Text, WritableImage,
        };
        let n = img.nchannels();
        let mut list = SmallVec::<[AnyChannel<FlatSamples>; 4]>::new();
        for (c, name) in img.channels.iter().enumerate() {
            let samples: Vec<f32> = img.data.iter().skip(c).step_by(n).copied().collect();
            list.push(AnyChannel::new(Text::new_or_none(name.as_str()).unwrap(), FlatSamples::F32(samples)));
        }
        let layer =
            Layer::new((300, 97), LayerAttributes::default(), Encoding::SMALL_LOSSLESS, AnyChannels::sort(list));
        let mut seq = Cursor::new(Vec::new());
        exr::image::Image::from_layer(layer).write().non_parallel().to_buffered(&mut seq).unwrap();
        assert!(bytes == seq.into_inner(), "parallel and sequential EXR bytes differ");
        let plain = encode_exr_with(&img, path, false).unwrap();
        assert!(plain.len() > bytes.len());
        for back in [decode_exr(&bytes, path).unwrap(), decode_exr(&plain, path).unwrap()] {
            for name in &refs {
                let (a, b) = (img.channel_index(name).unwrap(), back.channel_index(name).unwrap());
                for p in 0..img.npixels() {
                    assert_eq!(img.data[p * n + a].to_bits(), back.data[p * n + b].to_bits(), "{name} at {p}");
                }
            }
        }
    }

    #[test]
    fn layout_and_accessors() {
        let img = ramp(3, 2, &["R", "G", "B"]);
        assert_eq!(img.get(2, 1, 1), img.data[(3 + 2) * 3 + 1]);
        assert_eq!(img.pixel(1, 0), &img.data[3..6]);
        assert_eq!(img.channel_index("B"), Some(2));
        assert_eq!(img.try_get(3, 0, 0), None);
        let rgb = img.rgb(1, 1).unwrap();
        assert_eq!(rgb.y, img.get(1, 1, 1));
        let y = ramp(2, 2, &["Y"]);
        assert_eq!(y.rgb(1, 0).unwrap(), Rgb::splat(y.get(1, 0, 0)));
        assert!(Image::from_data(2, 2, channel_names(&["R"]), vec![0.0; 3]).is_err());
        assert!(Image::new(u32::MAX, u32::MAX, channel_names(&["R"])).is_err());
    }

    #[test]
    fn crop_and_select() {
        let img = ramp(4, 3, &["R", "G", "B"]);
        let c = img.crop(1, 3, 1, 3).unwrap();
        assert_eq!((c.width, c.height), (2, 2));
        assert_eq!(c.pixel(1, 1), img.pixel(2, 2));
        assert!(img.crop(0, 5, 0, 1).is_err());
        assert!(img.crop(2, 2, 0, 1).is_err());
        let s = img.select_channels(&["B", "R"]).unwrap();
        assert_eq!(s.pixel(3, 2), &[img.get(3, 2, 2), img.get(3, 2, 0)]);
        assert!(img.select_channels(&["Z"]).is_err());
    }

    #[test]
    fn box_downsample_averages_blocks() {
        let img = Image::from_data(4, 2, channel_names(&["Y"]), vec![1., 2., 3., 4., 5., 6., 7., 8.]).unwrap();
        let d = img.box_downsample(2).unwrap();
        assert_eq!((d.width, d.height), (2, 1));
        assert_eq!(d.data, vec![(1. + 2. + 5. + 6.) / 4., (3. + 4. + 7. + 8.) / 4.]);
        assert!(img.box_downsample(3).is_err());
        assert!(img.box_downsample(0).is_err());
        assert_eq!(img.box_downsample(1).unwrap(), img);
        // The mean of the image is preserved.
        let r = ramp(6, 6, &["R", "G", "B"]);
        let d3 = r.box_downsample(3).unwrap();
        let m = |i: &Image| i.data.iter().map(|&v| v as f64).sum::<f64>() / i.data.len() as f64;
        assert!((m(&r) - m(&d3)).abs() < 1e-6);
    }

    #[test]
    fn exr_roundtrip_with_extra_channels() {
        let d = tmpdir("exr");
        let img = ramp(5, 3, &["R", "G", "B", "variance.R", "variance.G", "variance.B", "depth"]);
        let p = d.join("a.exr");
        write_exr(&img, &p).unwrap();
        let back = read(&p).unwrap();
        // OpenImageIO order: unprefixed layer first (R G B, then others), then layers.
        assert_eq!(back.channels, channel_names(&["R", "G", "B", "depth", "variance.R", "variance.G", "variance.B"]));
        let again = back.select_channels(&img.channels).unwrap();
        assert_eq!(again, img);
        fs::remove_dir_all(d).unwrap();
    }

    #[test]
    fn exr_half_is_read() {
        use exr::prelude::{
            f16, AnyChannel, AnyChannels, Encoding, FlatSamples, Layer, LayerAttributes, SmallVec, WritableImage,
        };
        let d = tmpdir("exrhalf");
        let p = d.join("h.exr");
        let vals = [0.5f32, 1.0, 2.0, -0.25, 65504.0, 0.0];
        let chans = SmallVec::from_vec(vec![AnyChannel::new(
            "Y",
            FlatSamples::F16(vals.iter().map(|&v| f16::from_f32(v)).collect()),
        )]);
        let layer = Layer::new((3, 2), LayerAttributes::default(), Encoding::UNCOMPRESSED, AnyChannels::sort(chans));
        exr::image::Image::from_layer(layer).write().to_file(&p).unwrap();
        let img = read(&p).unwrap();
        assert_eq!(img.channels, vec!["Y"]);
        assert_eq!(img.data, vals);
        fs::remove_dir_all(d).unwrap();
    }

    #[test]
    fn pfm_roundtrip_and_orientation() {
        let d = tmpdir("pfm");
        let img = ramp(3, 2, &["R", "G", "B"]);
        let p = d.join("a.pfm");
        write_pfm(&img, &p).unwrap();
        let bytes = fs::read(&p).unwrap();
        // First stored row is the bottom row (y = 1).
        let header = b"PF\n3 2\n-1\n".len();
        assert_eq!(&bytes[header..header + 4], &img.get(0, 1, 0).to_le_bytes());
        assert_eq!(read(&p).unwrap(), img);
        // Big-endian, gray, width and height on separate lines.
        let mut be = b"Pf\n2\n1\n1.0\n".to_vec();
        be.extend_from_slice(&1.5f32.to_be_bytes());
        be.extend_from_slice(&(-2.0f32).to_be_bytes());
        let g = decode_pfm(&be, Path::new("be.pfm")).unwrap();
        assert_eq!(g.channels, vec!["Y"]);
        assert_eq!(g.data, vec![1.5, -2.0]);
        fs::remove_dir_all(d).unwrap();
    }

    fn encode_raw_png(w: u32, h: u32, color: png::ColorType, depth: png::BitDepth, bytes: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(color);
        enc.set_depth(depth);
        let mut wr = enc.write_header().unwrap();
        wr.write_image_data(bytes).unwrap();
        wr.finish().unwrap();
        out
    }

    #[test]
    fn png_values_are_raw_normalised() {
        let p = Path::new("t.png");
        let b = encode_raw_png(2, 1, png::ColorType::Rgb, png::BitDepth::Eight, &[0, 128, 255, 10, 20, 30]);
        let img = decode_png(&b, p).unwrap();
        assert_eq!(img.channels, channel_names(&["R", "G", "B"]));
        assert_eq!(img.data, vec![0.0, 128.0 / 255.0, 1.0, 10.0 / 255.0, 20.0 / 255.0, 30.0 / 255.0]);
        let b16 =
            encode_raw_png(1, 1, png::ColorType::GrayscaleAlpha, png::BitDepth::Sixteen, &[0x12, 0x34, 0xff, 0xff]);
        let img = decode_png(&b16, p).unwrap();
        assert_eq!(img.channels, channel_names(&["Y", "A"]));
        assert_eq!(img.data, vec![0x1234 as f32 / 65535.0, 1.0]);
        let rgba = encode_raw_png(1, 1, png::ColorType::Rgba, png::BitDepth::Eight, &[1, 2, 3, 4]);
        assert_eq!(decode_png_with(&rgba, p, false).unwrap().data, vec![1. / 255., 2. / 255., 3. / 255., 4. / 255.]);
        // Associated as OpenImageIO does (values checked against oiiotool --dumpdata):
        // 255·128/255 = 128, 127·128/255 = 63.75 -> 63, 200·128/255 -> 100; 100·64/255 -> 25, 50 -> 12, 10 -> 2.
        let rgba =
            encode_raw_png(2, 1, png::ColorType::Rgba, png::BitDepth::Eight, &[255, 127, 200, 128, 100, 50, 10, 64]);
        let got: Vec<f32> = decode_png(&rgba, p).unwrap().data.iter().map(|v| v * 255.0).collect();
        assert_eq!(got, vec![128., 63., 100., 128., 25., 12., 2., 64.]);
        let g1 = encode_raw_png(8, 1, png::ColorType::Grayscale, png::BitDepth::One, &[0b1010_0000]);
        assert_eq!(decode_png(&g1, p).unwrap().data, vec![1., 0., 1., 0., 0., 0., 0., 0.]);
    }

    #[test]
    fn png_writer_encodes_srgb_with_exposure() {
        let img = Image::from_data(3, 1, channel_names(&["Y"]), vec![0.0, 0.214_041_14, 0.5]).unwrap();
        let b = encode_png(&img, 0.0, Path::new("o.png")).unwrap();
        let back = decode_png(&b, Path::new("o.png")).unwrap();
        // sRGB(0.21404114) = 0.5 -> 128; 0.5 -> 0.7354 -> 188.
        assert_eq!(back.data, vec![0.0, 128.0 / 255.0, 188.0 / 255.0]);
        let b = encode_png(&img, 1.0, Path::new("o.png")).unwrap();
        assert_eq!(decode_png(&b, Path::new("o.png")).unwrap().data[2], 1.0);
    }

    #[test]
    fn atomic_write_keeps_old_file_on_failure() {
        let d = tmpdir("atomic");
        let p = d.join("out.bin");
        write_atomic(&p, |w| w.write_all(b"old")).unwrap();
        let r = write_atomic(&p, |w| {
            w.write_all(b"partial")?;
            Err(io::Error::other("producer failed"))
        });
        assert!(matches!(r, Err(ImageError::Io { .. })));
        assert_eq!(fs::read(&p).unwrap(), b"old");
        // No temporary files are left behind.
        assert_eq!(fs::read_dir(&d).unwrap().count(), 1);
        write_atomic(&p, |w| w.write_all(b"new")).unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"new");
        assert!(matches!(write_atomic(d.join("no/such/dir/x"), |_| Ok(())), Err(ImageError::Io { .. })));
        fs::remove_dir_all(d).unwrap();
    }

    #[test]
    fn atomic_write_refuses_a_read_only_file_and_keeps_permissions() {
        use std::os::unix::fs::PermissionsExt;
        let d = tmpdir("readonly");
        let p = d.join("ref.exr");
        write_atomic(&p, |w| w.write_all(b"reference")).unwrap();
        fs::set_permissions(&p, fs::Permissions::from_mode(0o444)).unwrap();
        let r = write_atomic(&p, |w| w.write_all(b"new"));
        let Err(ImageError::Io { source, .. }) = r else { panic!("a read-only file was replaced: {r:?}") };
        assert!(source.to_string().contains("read-only"), "{source}");
        assert_eq!(fs::read(&p).unwrap(), b"reference");
        assert_eq!(fs::metadata(&p).unwrap().permissions().mode() & 0o777, 0o444);
        assert_eq!(fs::read_dir(&d).unwrap().count(), 1, "no temporary file is left");
        // A writable file with a mode other than the umask's default keeps it when replaced.
        fs::set_permissions(&p, fs::Permissions::from_mode(0o640)).unwrap();
        write_atomic(&p, |w| w.write_all(b"new")).unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"new");
        assert_eq!(fs::metadata(&p).unwrap().permissions().mode() & 0o777, 0o640);
        fs::remove_dir_all(d).unwrap();
    }

    #[test]
    fn unknown_and_missing_files_are_errors() {
        assert!(matches!(decode(b"hello", Path::new("x")), Err(ImageError::UnknownFormat { .. })));
        assert!(matches!(read("/nonexistent/penumbra.exr"), Err(ImageError::Io { .. })));
        assert!(decode_pfm(b"PF\n2 2\n0\n", Path::new("z")).is_err());
        assert!(decode_pfm(b"PF\n2 2\n-1\n\0\0\0\0", Path::new("z")).is_err());
    }

    mod fuzz {
        use super::*;
        use proptest::prelude::*;

        fn valid_files() -> Vec<Vec<u8>> {
            let img = ramp(7, 5, &["R", "G", "B", "variance.R"]);
            let p = Path::new("v");
            vec![
                encode_exr(&img, p).unwrap(),
                encode_png(&img, 0.0, p).unwrap(),
                encode_pfm(&img, p).unwrap(),
                encode_raw_png(3, 2, png::ColorType::Rgba, png::BitDepth::Sixteen, &[7u8; 48]),
            ]
        }

        proptest! {
            #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

            #[test]
            fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
                let p = Path::new("r");
                let _ = decode(&bytes, p);
                let _ = decode_exr(&bytes, p);
                let _ = decode_png(&bytes, p);
                let _ = decode_pfm(&bytes, p);
            }

            #[test]
            fn truncated_valid_files_are_errors(which in 0usize..4, frac in 0.0f64..1.0) {
                let files = valid_files();
                let f = &files[which];
                let cut = ((f.len() as f64) * frac) as usize;
                prop_assert!(decode(&f[..cut], Path::new("t")).is_err());
            }

            #[test]
            fn corrupted_valid_files_never_panic(which in 0usize..4, pos in any::<prop::sample::Index>(), byte in any::<u8>()) {
                let mut f = valid_files()[which].clone();
                let i = pos.index(f.len());
                f[i] = byte;
                let _ = decode(&f, Path::new("c"));
            }

            #[test]
            fn magic_with_random_tail_never_panics(which in 0usize..4, tail in proptest::collection::vec(any::<u8>(), 0..256)) {
                let magic: &[u8] = match which {
                    0 => &[0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0],
                    1 => &[0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a],
                    2 => b"PF\n",
                    _ => b"Pf 3 3 -1\n",
                };
                let mut f = magic.to_vec();
                f.extend_from_slice(&tail);
                prop_assert!(decode(&f, Path::new("m")).is_err() || which >= 2);
            }
        }
    }
}
