//! Images as pbrt-v3's `ReadImage` (`core/imageio.cpp`) reads them for textures and light
//! maps: always three channels `R G B`, from
//! - **PNG** as lodepng's `lodepng_decode24` gives them (pbrt-v3's PNG reader): 8-bit RGB,
//!   divided by 255. Grey is replicated; 1, 2 and 4-bit grey is scaled by `255 / (2^bits − 1)`
//!   (integer division, as lodepng); 16-bit samples keep their high byte (pbrt-v3 sees a
//!   16-bit PNG at 8 bits); palette entries are looked up (an index past the palette is black,
//!   as in lodepng); alpha (an alpha channel, a palette's or a `tRNS` key colour) is dropped,
//!   not composited; `gAMA`, `cHRM`, `sRGB` and `iCCP` are ignored. Interlaced files are
//!   de-interlaced.
//! - **TGA** as the `targa.c` pbrt-v3 bundles reads them: true-colour (24 and 32 bits, BGR(A),
//!   alpha dropped), grey (8 bits) and colour-mapped (8-bit indices into a 16, 24 or 32-bit
//!   map), uncompressed or run-length encoded (packets may cross rows), any of the four origins
//!   (the descriptor's right-to-left and top-to-bottom bits). 16-bit (A1R5G5B5) pixels and map
//!   entries are decoded as TGA defines them (5 bits per channel, scaled to 8): pbrt-v3 reads
//!   their bytes as if they were B, G, R — garbage no scene can rely on.
//! - **EXR** as OpenEXR's `RgbaInputFile` gives them: the unprefixed `R`, `G`, `B` channels
//!   (a missing one is 0); without any of them, luminance `Y` as grey (with `RY`, `BY`
//!   chroma, converted with Rec. 709 weights). A file with neither is refused (pbrt-v3 would
//!   read it as black).
//! - **PFM**, multiplied by the magnitude of the header's scale when it is not 1 (pbrt-v3 does;
//!   [`super::decode_pfm`] ignores it, as OpenImageIO does).

use super::{check_decoded_size, decode_err, decode_exr, decode_pfm_with_scale, png_limits, Format, Image, ImageError};
use std::io::Cursor;
use std::path::Path;

/// Decodes a scene input held in memory (the format from its magic number, or `.tga`).
pub(super) fn decode(bytes: &[u8], path: &Path) -> Result<Image, ImageError> {
    match Format::detect(bytes, path) {
        Some(Format::Png) => decode_png_rgb8(bytes, path),
        Some(Format::Tga) => decode_tga(bytes, path).map(grey_to_rgb),
        Some(Format::Exr) => exr_rgb(decode_exr(bytes, path)?, path),
        Some(Format::Pfm) => {
            let (mut img, scale) = decode_pfm_with_scale(bytes, path)?;
            let s = scale.abs();
            if s != 1.0 {
                img.data.iter_mut().for_each(|v| *v *= s);
            }
            Ok(grey_to_rgb(img))
        }
        None => Err(ImageError::UnknownFormat { path: path.to_path_buf() }),
    }
}

/// `Y` images as `R G B` (grey replicated); others unchanged.
fn grey_to_rgb(img: Image) -> Image {
    if img.channels.len() != 1 {
        return img;
    }
    let data = img.data.iter().flat_map(|&v| [v, v, v]).collect();
    Image { channels: super::channel_names(&["R", "G", "B"]), data, ..img }
}

/// OpenEXR's `RgbaInputFile` view of a decoded EXR (see the module documentation).
fn exr_rgb(img: Image, path: &Path) -> Result<Image, ImageError> {
    let idx = |name: &str| img.channel_index(name);
    let n = img.nchannels();
    let pick = |px: &[f32], i: Option<usize>| i.map_or(0.0, |i| px[i]);
    let data: Vec<f32> = match (idx("R"), idx("G"), idx("B"), idx("Y")) {
        (None, None, None, Some(y)) => {
            let (ry, by) = (idx("RY"), idx("BY"));
            // OpenEXR's YCA to RGB with its default (Rec. 709) luminance weights.
            const W: [f32; 3] = [0.2126, 0.7152, 0.0722];
            img.data
                .chunks_exact(n)
                .flat_map(|px| {
                    let yv = px[y];
                    if ry.is_none() && by.is_none() {
                        return [yv, yv, yv];
                    }
                    let r = (pick(px, ry) + 1.0) * yv;
                    let b = (pick(px, by) + 1.0) * yv;
                    let g = (yv - r * W[0] - b * W[2]) / W[1];
                    [r, g, b]
                })
                .collect()
        }
        (None, None, None, None) => {
            return Err(decode_err(
                path,
                "EXR",
                format!("no R, G, B or Y channel (it has {}); pbrt-v3 would read it as black", img.channels.join(", ")),
            ))
        }
        (r, g, b, _) => img.data.chunks_exact(n).flat_map(|px| [pick(px, r), pick(px, g), pick(px, b)]).collect(),
    };
    Image::from_data(img.width, img.height, super::channel_names(&["R", "G", "B"]), data)
}

/// The `(r, g, b)` lodepng's `lodepng_decode24` gives every pixel of a PNG, over 255.
fn decode_png_rgb8(bytes: &[u8], path: &Path) -> Result<Image, ImageError> {
    let err = |m: String| decode_err(path, "PNG", m);
    let mut decoder = png::Decoder::new_with_limits(Cursor::new(bytes), png_limits());
    decoder.set_transformations(png::Transformations::IDENTITY);
    let mut reader = decoder.read_info().map_err(|e| err(e.to_string()))?;
    let (width, height, color, depth, palette) = {
        let info = reader.info();
        let palette = info.palette.as_ref().map(|p| p.to_vec()).unwrap_or_default();
        (info.width, info.height, info.color_type, info.bit_depth as u32, palette)
    };
    check_decoded_size(path, "PNG", width as u64, height as u64, 3)?;
    let samples = match color {
        png::ColorType::Grayscale | png::ColorType::Indexed => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
    };
    let size = reader.output_buffer_size().ok_or_else(|| err("image too large".into()))?;
    let mut buf = vec![0u8; size];
    let info = reader.next_frame(&mut buf).map_err(|e| err(e.to_string()))?;
    reader.finish().map_err(|e| err(e.to_string()))?;
    let (w, line) = (width as usize, info.line_size);
    let mut data = Vec::with_capacity(w * height as usize * 3);
    for y in 0..height as usize {
        let row = buf.get(y * line..(y + 1) * line).ok_or_else(|| err("short frame".into()))?;
        for x in 0..w {
            let rgb = match color {
                png::ColorType::Indexed => {
                    let i = packed_sample(row, x, depth) as usize;
                    // lodepng: an index past the palette is black.
                    palette.get(3 * i..3 * i + 3).map_or([0, 0, 0], |c| [c[0], c[1], c[2]])
                }
                png::ColorType::Grayscale if depth < 8 => {
                    let v = (packed_sample(row, x, depth) * 255 / ((1 << depth) - 1)) as u8;
                    [v, v, v]
                }
                _ => {
                    // 8 or 16 bits per sample; lodepng keeps the high byte of a 16-bit one.
                    let step = (depth / 8) as usize;
                    let at = |c: usize| row[(x * samples + c) * step];
                    match color {
                        png::ColorType::Grayscale | png::ColorType::GrayscaleAlpha => [at(0); 3],
                        _ => [at(0), at(1), at(2)],
                    }
                }
            };
            data.extend(rgb.iter().map(|&v| v as f32 / 255.0));
        }
    }
    Image::from_data(width, height, super::channel_names(&["R", "G", "B"]), data)
}

/// Sample `x` of a row of `depth`-bit (1, 2, 4 or 8) samples packed from the high bit.
fn packed_sample(row: &[u8], x: usize, depth: u32) -> u32 {
    let bit = x * depth as usize;
    let byte = row[bit / 8] as u32;
    let shift = 8 - depth - (bit % 8) as u32;
    (byte >> shift) & ((1 << depth) - 1)
}

/// A TGA header's fields (`targa.c`'s `tga_image`).
struct TgaHeader {
    id_length: usize,
    image_type: u8,
    cmap_origin: usize,
    cmap_length: usize,
    cmap_depth: u32,
    width: usize,
    height: usize,
    depth: u32,
    descriptor: u8,
}

const TGA_COLORMAP: u8 = 1;
const TGA_MONO: u8 = 3;
const TGA_RLE: u8 = 8;

impl TgaHeader {
    fn read(b: &[u8], err: impl Fn(&str) -> ImageError) -> Result<TgaHeader, ImageError> {
        if b.len() < 18 {
            return Err(err("premature end of file (header)"));
        }
        let u16le = |i: usize| u16::from_le_bytes([b[i], b[i + 1]]) as usize;
        let h = TgaHeader {
            id_length: b[0] as usize,
            image_type: b[2],
            cmap_origin: u16le(3),
            cmap_length: u16le(5),
            cmap_depth: b[7] as u32,
            width: u16le(12),
            height: u16le(14),
            depth: b[16] as u32,
            descriptor: b[17],
        };
        let cmap_present = match b[1] {
            0 => false,
            1 => true,
            _ => return Err(err("invalid color map type")),
        };
        let base = h.image_type & !TGA_RLE;
        if h.image_type == 0 {
            return Err(err("no image data included"));
        }
        if !matches!(h.image_type, 1 | 2 | 3 | 9 | 10 | 11) {
            return Err(err(&format!("invalid image type {}", h.image_type)));
        }
        let mapped = base == TGA_COLORMAP;
        if mapped != cmap_present {
            return Err(err(if mapped {
                "color-mapped image without color map"
            } else {
                "non-color-mapped image with extraneous color map"
            }));
        }
        if mapped && (h.cmap_length == 0 || !matches!(h.cmap_depth, 16 | 24 | 32)) {
            return Err(err("color map has zero length or an invalid depth"));
        }
        if h.width == 0 || h.height == 0 {
            return Err(err("the image dimensions are zero"));
        }
        let depth_ok = match base {
            TGA_COLORMAP | TGA_MONO => h.depth == 8,
            _ => matches!(h.depth, 16 | 24 | 32),
        };
        if !depth_ok {
            return Err(err(&format!("invalid pixel depth {} for image type {}", h.depth, h.image_type)));
        }
        Ok(h)
    }
}

/// One TGA pixel or colour-map entry of `depth` bits (16: A1R5G5B5; 24: BGR; 32: BGRA) as RGB.
fn tga_bgr(p: &[u8], depth: u32) -> [f32; 3] {
    match depth {
        16 => {
            let v = u16::from_le_bytes([p[0], p[1]]);
            let five = |s: u16| {
                let c = ((v >> s) & 31) as u32;
                ((c << 3) | (c >> 2)) as f32 / 255.0
            };
            [five(10), five(5), five(0)]
        }
        _ => [p[2] as f32 / 255.0, p[1] as f32 / 255.0, p[0] as f32 / 255.0],
    }
}

/// Decodes a TGA held in memory: `R G B`, or `Y` for grey images, top row first.
pub(crate) fn decode_tga(bytes: &[u8], path: &Path) -> Result<Image, ImageError> {
    let err = |m: &str| decode_err(path, "TGA", m);
    let h = TgaHeader::read(bytes, err)?;
    let mono = h.image_type & !TGA_RLE == TGA_MONO;
    let nch = if mono { 1 } else { 3 };
    check_decoded_size(path, "TGA", h.width as u64, h.height as u64, nch as u64)?;
    let mut pos = 18 + h.id_length;
    let cmap: &[u8] = if h.image_type & !TGA_RLE == TGA_COLORMAP {
        let n = h.cmap_length * h.cmap_depth as usize / 8;
        let m = bytes.get(pos..pos + n).ok_or_else(|| err("premature end of file (color map)"))?;
        pos += n;
        m
    } else {
        &[]
    };
    let bpp = h.depth as usize / 8;
    let npix = h.width * h.height;
    let raw = tga_pixels(&bytes[pos.min(bytes.len())..], npix, bpp, h.image_type & TGA_RLE != 0, err)?;
    let mut data = vec![0.0f32; npix * nch];
    let (right_to_left, top_to_bottom) = (h.descriptor & 0x10 != 0, h.descriptor & 0x20 != 0);
    let cbpp = h.cmap_depth as usize / 8;
    for (i, p) in raw.chunks_exact(bpp).enumerate() {
        let (fx, fy) = (i % h.width, i / h.width);
        let x = if right_to_left { h.width - 1 - fx } else { fx };
        let y = if top_to_bottom { fy } else { h.height - 1 - fy };
        let out = &mut data[(y * h.width + x) * nch..(y * h.width + x + 1) * nch];
        if mono {
            out[0] = p[0] as f32 / 255.0;
        } else if h.image_type & !TGA_RLE == TGA_COLORMAP {
            let k = (p[0] as usize).checked_sub(h.cmap_origin).filter(|&k| k < h.cmap_length);
            let k = k.ok_or_else(|| err("color map index out of range"))?;
            out.copy_from_slice(&tga_bgr(&cmap[k * cbpp..(k + 1) * cbpp], h.cmap_depth));
        } else {
            out.copy_from_slice(&tga_bgr(p, h.depth));
        }
    }
    let names: &[&str] = if mono { &["Y"] } else { &["R", "G", "B"] };
    Image::from_data(h.width as u32, h.height as u32, super::channel_names(names), data)
}

/// The `npix` pixels of `bpp` bytes in file order: stored as they are, or run-length encoded
/// (a packet header's high bit: one pixel repeated, else literal pixels; `count = low 7 bits
/// + 1`; packets may cross rows; a packet past the last pixel is an error, as in `targa.c`).
fn tga_pixels(
    b: &[u8],
    npix: usize,
    bpp: usize,
    rle: bool,
    err: impl Fn(&str) -> ImageError,
) -> Result<Vec<u8>, ImageError> {
    let n = npix * bpp;
    if !rle {
        return b.get(..n).map(<[u8]>::to_vec).ok_or_else(|| err("premature end of file (pixel data)"));
    }
    let mut out = Vec::with_capacity(n);
    let mut pos = 0;
    while out.len() < n {
        let head = *b.get(pos).ok_or_else(|| err("premature end of file (RLE data)"))?;
        pos += 1;
        let count = (head & 0x7f) as usize + 1;
        if out.len() + count * bpp > n {
            return Err(err("RLE data is corrupt (a packet runs past the last pixel)"));
        }
        let take = if head & 0x80 != 0 { bpp } else { count * bpp };
        let chunk = b.get(pos..pos + take).ok_or_else(|| err("premature end of file (RLE data)"))?;
        pos += take;
        if head & 0x80 != 0 {
            (0..count).for_each(|_| out.extend_from_slice(chunk));
        } else {
            out.extend_from_slice(chunk);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::super::{decode as decode_any, ImageError};
    use super::*;

    fn png(
        w: u32,
        h: u32,
        color: png::ColorType,
        depth: png::BitDepth,
        data: &[u8],
        extra: &[(&str, &[u8])],
    ) -> Vec<u8> {
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(color);
        enc.set_depth(depth);
        for (kind, bytes) in extra {
            match *kind {
                "PLTE" => enc.set_palette(bytes.to_vec()),
                "tRNS" => enc.set_trns(bytes.to_vec()),
                _ => unreachable!(),
            }
        }
        let mut wr = enc.write_header().unwrap();
        wr.write_image_data(data).unwrap();
        wr.finish().unwrap();
        out
    }

    /// The 8-bit code values of every pixel, as the decoder returns them (× 255).
    fn codes(bytes: &[u8], name: &str) -> Vec<[u8; 3]> {
        let img = decode(bytes, Path::new(name)).unwrap();
        assert_eq!(img.channels, ["R", "G", "B"]);
        img.data
            .chunks_exact(3)
            .map(|p| {
                p.iter().for_each(|v| assert_eq!((v * 255.0).round() / 255.0, *v, "not an 8-bit code value"));
                [0, 1, 2].map(|c| (p[c] * 255.0).round() as u8)
            })
            .collect()
    }

    /// Every PNG layout lodepng reads, against its `lodepng_decode24` rules.
    #[test]
    fn png_layouts_decode_as_lodepng_decode24() {
        use png::{BitDepth as D, ColorType as C};
        // Grey at 1, 2, 4 bits: v · 255 / (2^bits − 1).
        assert_eq!(
            codes(&png(8, 1, C::Grayscale, D::One, &[0b1011_0000], &[]), "g1.png")[..4],
            [[255; 3], [0; 3], [255; 3], [255; 3]]
        );
        assert_eq!(
            codes(&png(4, 1, C::Grayscale, D::Two, &[0b0001_1011], &[]), "g2.png"),
            [[0; 3], [85; 3], [170; 3], [255; 3]]
        );
        assert_eq!(codes(&png(2, 1, C::Grayscale, D::Four, &[0x7f], &[]), "g4.png"), [[119; 3], [255; 3]]);
        assert_eq!(codes(&png(2, 1, C::Grayscale, D::Eight, &[3, 200], &[]), "g8.png"), [[3; 3], [200; 3]]);
        // 16 bits: the high byte (0x12ff -> 0x12, not rounded to 0x13).
        assert_eq!(codes(&png(1, 1, C::Grayscale, D::Sixteen, &[0x12, 0xff], &[]), "g16.png"), [[0x12; 3]]);
        // Grey + alpha: alpha dropped, not composited (8 and 16 bits).
        assert_eq!(codes(&png(1, 1, C::GrayscaleAlpha, D::Eight, &[90, 0], &[]), "ga8.png"), [[90; 3]]);
        assert_eq!(codes(&png(1, 1, C::GrayscaleAlpha, D::Sixteen, &[0xab, 1, 0, 0], &[]), "ga16.png"), [[0xab; 3]]);
        // RGB and RGBA, 8 and 16 bits.
        assert_eq!(codes(&png(1, 1, C::Rgb, D::Eight, &[1, 2, 3], &[]), "rgb8.png"), [[1, 2, 3]]);
        assert_eq!(codes(&png(1, 1, C::Rgb, D::Sixteen, &[1, 9, 2, 9, 3, 9], &[]), "rgb16.png"), [[1, 2, 3]]);
        assert_eq!(codes(&png(1, 1, C::Rgba, D::Eight, &[10, 20, 30, 0], &[]), "rgba8.png"), [[10, 20, 30]]);
        assert_eq!(
            codes(&png(1, 1, C::Rgba, D::Sixteen, &[10, 0, 20, 0, 30, 0, 0, 0], &[]), "rgba16.png"),
            [[10, 20, 30]]
        );
        // Grey / RGB with a tRNS key colour: the colour stays.
        assert_eq!(
            codes(&png(2, 1, C::Grayscale, D::Eight, &[7, 8], &[("tRNS", &[0, 7])]), "gk.png"),
            [[7; 3], [8; 3]]
        );
        assert_eq!(
            codes(&png(1, 1, C::Rgb, D::Eight, &[4, 5, 6], &[("tRNS", &[0, 4, 0, 5, 0, 6])]), "rk.png"),
            [[4, 5, 6]]
        );
        // Palette at 1, 2, 4, 8 bits, with per-entry alpha (tRNS) that is dropped; an index past
        // the palette is black.
        let plte: &[u8] = &[255, 0, 0, 0, 255, 0, 0, 0, 255];
        let trns: &[u8] = &[0, 128];
        let pal =
            |d, data: &[u8], w| codes(&png(w, 1, C::Indexed, d, data, &[("PLTE", plte), ("tRNS", trns)]), "p.png");
        assert_eq!(pal(D::One, &[0b0100_0000], 2), [[255, 0, 0], [0, 255, 0]]);
        assert_eq!(pal(D::Two, &[0b1001_1100], 4), [[0, 0, 255], [0, 255, 0], [0, 0, 0], [255, 0, 0]]);
        assert_eq!(pal(D::Four, &[0x21], 2), [[0, 0, 255], [0, 255, 0]]);
        assert_eq!(pal(D::Eight, &[2, 0, 9], 3), [[0, 0, 255], [255, 0, 0], [0, 0, 0]]);
    }

    /// pbrt-v3-scenes' `textures/lines.png` is a 1024² 1-bit palette PNG of 734 bytes: its
    /// decoded size is thousands of times its file size, which must not matter.
    #[test]
    fn highly_compressed_palette_png_loads() {
        let (w, h) = (1024u32, 1024u32);
        let mut data = vec![0u8; (w / 8 * h) as usize];
        for y in 0..h as usize {
            for x in 0..w as usize {
                if x % 64 < 2 || y % 64 < 2 {
                    data[y * 128 + x / 8] |= 0x80 >> (x % 8);
                }
            }
        }
        let plte: &[u8] = &[20, 20, 20, 240, 240, 240];
        let bytes = png(w, h, png::ColorType::Indexed, png::BitDepth::One, &data, &[("PLTE", plte)]);
        assert!(bytes.len() * 1100 < (w * h * 3) as usize, "{} bytes is not that small", bytes.len());
        let img = decode(&bytes, Path::new("lines.png")).unwrap();
        assert_eq!((img.width, img.height), (w, h));
        assert_eq!(img.pixel(1, 5), &[240.0 / 255.0; 3]);
        assert_eq!(img.pixel(5, 5), &[20.0 / 255.0; 3]);
        // The same file through the general reader (OpenImageIO's values).
        let any = decode_any(&bytes, Path::new("lines.png")).unwrap();
        assert_eq!(any.pixel(5, 5), &[20.0 / 255.0; 3]);
    }

    /// A header claiming a 100000² image in a 100-byte file is refused before anything is
    /// allocated, naming the file, the claimed size and the cap.
    #[test]
    fn decompression_guard_refuses_what_the_header_claims() {
        let small = png(4, 4, png::ColorType::Rgb, png::BitDepth::Eight, &[0; 48], &[]);
        // Patch IHDR's width and height (bytes 16..24) and its CRC (bytes 29..33).
        let mut bomb = small.clone();
        bomb[16..20].copy_from_slice(&100_000u32.to_be_bytes());
        bomb[20..24].copy_from_slice(&100_000u32.to_be_bytes());
        let crc = crc32(&bomb[12..29]);
        bomb[29..33].copy_from_slice(&crc.to_be_bytes());
        for r in [decode(&bomb, Path::new("bomb.png")), decode_any(&bomb, Path::new("bomb.png"))] {
            match r {
                Err(e @ ImageError::TooLarge { .. }) => {
                    let m = e.to_string();
                    assert!(m.contains("bomb.png") && m.contains("100000×100000×3") && m.contains("limit"), "{m}");
                }
                other => panic!("{other:?}"),
            }
        }
        let mut tga = tga_header(2, 24, 0x20, 60000, 60000);
        tga.extend_from_slice(&[0; 30]);
        assert!(matches!(decode_any(&tga, Path::new("bomb.tga")), Err(ImageError::TooLarge { .. })));
    }

    fn crc32(bytes: &[u8]) -> u32 {
        let mut c = 0xffff_ffffu32;
        for &b in bytes {
            c ^= b as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 { 0xedb8_8320 ^ (c >> 1) } else { c >> 1 };
            }
        }
        !c
    }

    fn tga_header(image_type: u8, depth: u8, descriptor: u8, w: u16, h: u16) -> Vec<u8> {
        let mut b = vec![0u8; 18];
        b[2] = image_type;
        b[12..14].copy_from_slice(&w.to_le_bytes());
        b[14..16].copy_from_slice(&h.to_le_bytes());
        b[16] = depth;
        b[17] = descriptor;
        b
    }

    /// The four pixels of a 2×2 TGA, `[top-left, top-right, bottom-left, bottom-right]`.
    fn tga_quad(bytes: &[u8]) -> Vec<Vec<f32>> {
        let img = decode_any(bytes, Path::new("t.TGA")).unwrap();
        assert_eq!((img.width, img.height), (2, 2));
        [(0, 0), (1, 0), (0, 1), (1, 1)].iter().map(|&(x, y)| img.pixel(x, y).to_vec()).collect()
    }

    /// True-colour, grey and colour-mapped TGAs, stored and run-length encoded, from every
    /// origin, decode to the same image.
    #[test]
    fn tga_types_depths_and_origins() {
        // The image: top-left red, top-right green, bottom-left blue, bottom-right white.
        let rgb = [[255u8, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255]];
        let want: Vec<Vec<f32>> = rgb.iter().map(|c| c.iter().map(|&v| v as f32 / 255.0).collect()).collect();
        // File order of the image positions for each origin: descriptor bits 0x20 (top to
        // bottom) and 0x10 (right to left).
        let orders = [(0x00u8, [2, 3, 0, 1]), (0x20, [0, 1, 2, 3]), (0x10, [3, 2, 1, 0]), (0x30, [1, 0, 3, 2])];
        for (desc, order) in orders {
            for depth in [24u8, 32] {
                let px = |k: usize| {
                    let [r, g, b] = rgb[k];
                    if depth == 32 {
                        vec![b, g, r, 7]
                    } else {
                        vec![b, g, r]
                    }
                };
                let mut raw = tga_header(2, depth, desc | if depth == 32 { 8 } else { 0 }, 2, 2);
                order.iter().for_each(|&k| raw.extend(px(k)));
                assert_eq!(tga_quad(&raw), want, "type 2, {depth} bits, descriptor {desc:#x}");
                // RLE: a literal packet of two, then two run packets of one.
                let mut rle = tga_header(10, depth, desc, 2, 2);
                rle.push(0x01);
                rle.extend(px(order[0]));
                rle.extend(px(order[1]));
                for &k in &order[2..] {
                    rle.push(0x80);
                    rle.extend(px(k));
                }
                assert_eq!(tga_quad(&rle), want, "type 10, {depth} bits, descriptor {desc:#x}");
            }
            // Colour-mapped: a 24-bit map of the four colours, origin 0.
            let mut cm = tga_header(1, 8, desc, 2, 2);
            cm[1] = 1;
            cm[5..7].copy_from_slice(&4u16.to_le_bytes());
            cm[7] = 24;
            rgb.iter().for_each(|[r, g, b]| cm.extend([*b, *g, *r]));
            cm.extend(order.iter().map(|&k| k as u8));
            assert_eq!(tga_quad(&cm), want, "type 1, descriptor {desc:#x}");
            // Grey, stored and as one run of four.
            let mut mono = tga_header(3, 8, desc, 2, 2);
            mono.extend(order.iter().map(|&k| [10u8, 20, 30, 40][k]));
            let g: Vec<Vec<f32>> = [10u8, 20, 30, 40].iter().map(|&v| vec![v as f32 / 255.0]).collect();
            assert_eq!(tga_quad(&mono), g, "type 3, descriptor {desc:#x}");
            let mut run = tga_header(11, 8, desc, 2, 2);
            run.extend([0x83, 99]);
            assert!(tga_quad(&run).iter().all(|p| p == &[99.0 / 255.0]));
        }
        // 16 bits (A1R5G5B5): 5-bit channels scaled to 8; a 16-bit colour map.
        let mut t16 = tga_header(2, 16, 0x20, 2, 2);
        for v in [0x7c00u16, 0x03e0, 0x001f, 0x7fff] {
            t16.extend(v.to_le_bytes());
        }
        assert_eq!(tga_quad(&t16), want);
        // Scene input: grey becomes R = G = B.
        let mut mono = tga_header(3, 8, 0x20, 2, 2);
        mono.extend([1, 2, 3, 4]);
        let img = decode(&mono, Path::new("m.tga")).unwrap();
        assert_eq!(img.pixel(1, 1), &[4.0 / 255.0; 3]);
    }

    #[test]
    fn malformed_tgas_are_errors() {
        let ok = {
            let mut b = tga_header(2, 24, 0x20, 2, 2);
            b.extend([0u8; 12]);
            b
        };
        assert!(decode_any(&ok, Path::new("x.tga")).is_ok());
        let cases: Vec<(Vec<u8>, &str)> = vec![
            (ok[..20].to_vec(), "premature end"),
            (ok[..10].to_vec(), "premature end"),
            (
                {
                    let mut b = ok.clone();
                    b[2] = 0;
                    b
                },
                "no image data",
            ),
            (
                {
                    let mut b = ok.clone();
                    b[2] = 5;
                    b
                },
                "invalid image type",
            ),
            (
                {
                    let mut b = ok.clone();
                    b[16] = 8;
                    b
                },
                "invalid pixel depth",
            ),
            (
                {
                    let mut b = ok.clone();
                    b[12] = 0;
                    b
                },
                "dimensions are zero",
            ),
            (
                {
                    let mut b = ok.clone();
                    b[1] = 1;
                    b
                },
                "extraneous color map",
            ),
            (
                {
                    let mut b = tga_header(10, 24, 0, 2, 2);
                    b.extend([0x84, 1, 2, 3]);
                    b
                },
                "RLE data is corrupt",
            ),
            (
                {
                    let mut b = tga_header(1, 8, 0, 1, 1);
                    b[1] = 1;
                    b[5] = 1;
                    b[7] = 24;
                    b.extend([1, 2, 3, 5]);
                    b
                },
                "index out of range",
            ),
        ];
        for (bytes, what) in cases {
            let e = decode_any(&bytes, Path::new("bad.tga")).unwrap_err().to_string();
            assert!(e.contains("bad.tga") && e.contains(what), "{what}: {e}");
        }
        // Without the extension a TGA is not recognised (it has no magic number).
        assert!(matches!(decode_any(&ok, Path::new("x.img")), Err(ImageError::UnknownFormat { .. })));
    }

    #[test]
    fn exr_channels_as_rgba_input_file_and_pfm_scale() {
        use super::super::{channel_names, encode_exr, encode_pfm, Image};
        let p = Path::new("e.exr");
        let exr = |names: &[&str], data: Vec<f32>| {
            let img = Image::from_data(1, 1, channel_names(names), data).unwrap();
            decode(&encode_exr(&img, p).unwrap(), p)
        };
        assert_eq!(exr(&["Y"], vec![0.25]).unwrap().data, [0.25; 3]);
        assert_eq!(exr(&["R"], vec![0.5]).unwrap().data, [0.5, 0.0, 0.0]);
        assert_eq!(exr(&["A", "B", "G", "R"], vec![1.0, 0.3, 0.2, 0.1]).unwrap().data, [0.1, 0.2, 0.3]);
        // Luminance/chroma: R = (RY + 1) Y, B = (BY + 1) Y, G from the Rec. 709 weights.
        let c = exr(&["BY", "RY", "Y"], vec![-0.5, 1.0, 0.4]).unwrap().data;
        assert!((c[0] - 0.8).abs() < 1e-6 && (c[2] - 0.2).abs() < 1e-6, "{c:?}");
        assert!((0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2] - 0.4).abs() < 1e-6);
        let e = exr(&["diffuse.R", "diffuse.G"], vec![1.0, 1.0]).unwrap_err().to_string();
        assert!(e.contains("no R, G, B or Y channel"), "{e}");
        // PFM: pbrt-v3 multiplies by |scale| when it is not 1.
        let img = Image::from_data(1, 1, channel_names(&["Y"]), vec![0.5]).unwrap();
        let mut bytes = encode_pfm(&img, Path::new("s.pfm")).unwrap();
        let header = b"Pf\n1 1\n-1\n".len();
        let mut scaled = b"Pf\n1 1\n-2.5\n".to_vec();
        scaled.extend_from_slice(&bytes[header..]);
        assert_eq!(decode(&scaled, Path::new("s.pfm")).unwrap().data, [1.25; 3]);
        assert_eq!(decode_any(&scaled, Path::new("s.pfm")).unwrap().data, [0.5]);
        bytes.truncate(header);
        assert!(decode(&bytes, Path::new("s.pfm")).is_err());
    }
}
