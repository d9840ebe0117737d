//! pbrt-v3's measured/tabulated `fourier` BSDF (`core/reflection.cpp`'s `FourierBSDF` and
//! `FourierBSDFTable::Read`): the layered-material format of Jakob, d'Eon, Jakob & Marschner,
//! "A Comprehensive Framework for Rendering Layered Materials" (SIGGRAPH 2014; files made by
//! `layerlab`). An isotropic BSDF times `|cos θ_i|` is stored as a cosine series in the azimuth
//! difference for every pair of elevation cosines `(µ_i, µ_o)` on a grid of `nMu` nodes in
//! [−1, 1]; between nodes the coefficients are interpolated by Catmull–Rom splines in both
//! cosines. One channel is monochrome; three are luminance, red and blue (green recovered).
//! Sampling: `µ_i` from the per-`µ_o` running integrals of the zeroth coefficient (the file's
//! `cdf` table, interpolated in `µ_o`), then φ from the interpolated series.
//!
//! ## File format (little-endian)
//! A 64-byte header — the 8 bytes `SCATFUN\x01`; `u32 flags` (1: a BSDF, no harmonic
//! extrapolation); `i32 nMu, nCoeffs, mMax, nChannels, nBases, nMetadataBytes, nParameters,
//! nParameterValues`; `f32 eta` (relative index below/above), `f32 alpha[2]`, `f32 unused[2]`
//! — then `f32 mu[nMu]` (non-decreasing: pbrt-v3's files repeat 0), `f32 cdf[nMu²]`, `i32 (offset, length)[nMu²]`
//! (row `µ_o`, column `µ_i`), `f32 coeffs[nCoeffs]` (each pair's `length` coefficients per
//! channel, channel-major); metadata may follow and is ignored. pbrt-v3 reads only files with
//! `flags = 1`, `nBases = 1` and 1 or 3 channels, as here.
//!
//! Unlike pbrt-v3 (which indexes whatever the file says), every size, offset and value is
//! checked when the file is read: a malformed file is a [`FourierError`] naming the file, the
//! byte offset and what was expected, and the header's sizes must fit in the file before
//! anything is allocated (so a corrupt header cannot ask for more memory than the file holds).
//! Tables are cached for the process by path, length and modification time and never freed —
//! pbrt-v3's `FourierMaterial::loadedBSDFs` — so a [`FourierBxdf`] is a plain reference.

use super::{BxdfFlags, TransportMode};
use crate::interpolation::{catmull_rom_weights, fourier, sample_catmull_rom_2d, sample_fourier};
use crate::spectrum::Rgb;
use glam::{Vec2, Vec3};
use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::SystemTime;

/// Largest `.bsdf` file penumbra reads (pbrt-v3's measured files are tens of megabytes).
pub const MAX_FILE_BYTES: u64 = 1 << 30;
const HEADER_BYTES: usize = 64;
const MAGIC: &[u8; 8] = b"SCATFUN\x01";

/// A malformed or unreadable `.bsdf` file: where, and what was expected there.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("tabulated BSDF \"{}\"{}: {message}", path.display(), offset.map(|o| format!(", byte {o}")).unwrap_or_default())]
pub struct FourierError {
    pub path: PathBuf,
    /// Byte offset of the offending field (`None`: the file as a whole).
    pub offset: Option<u64>,
    pub message: String,
}

/// A validated Fourier BSDF table (pbrt-v3's `FourierBSDFTable`).
#[derive(Clone, Debug, PartialEq)]
pub struct FourierTable {
    /// Relative index of refraction (below over above).
    pub eta: f32,
    /// Most coefficients of any series (the longest present, at most the header's `mMax`).
    pub m_max: usize,
    /// 1 or 3.
    pub n_channels: usize,
    /// The elevation-cosine nodes.
    pub mu: Vec<f32>,
    /// Running integrals of `a0` over `µ_i`, one row per `µ_o` node.
    pub cdf: Vec<f32>,
    /// Zeroth coefficient of every pair (row `µ_o`, column `µ_i`).
    pub a0: Vec<f32>,
    /// `(offset, length)` of every pair's series in `coeffs`.
    series: Vec<(u32, u32)>,
    coeffs: Vec<f32>,
}

struct Reader<'a> {
    bytes: &'a [u8],
    path: &'a Path,
}

impl Reader<'_> {
    fn err(&self, offset: usize, message: impl Into<String>) -> FourierError {
        FourierError { path: self.path.to_path_buf(), offset: Some(offset as u64), message: message.into() }
    }
    fn word(&self, offset: usize) -> [u8; 4] {
        let mut w = [0u8; 4];
        w.copy_from_slice(&self.bytes[offset..offset + 4]);
        w
    }
    fn i32_at(&self, offset: usize) -> i32 {
        i32::from_le_bytes(self.word(offset))
    }
    fn f32_at(&self, offset: usize) -> f32 {
        f32::from_le_bytes(self.word(offset))
    }
    /// A count field that must lie in `lo..=hi`.
    fn count(&self, offset: usize, name: &str, lo: i64, hi: i64) -> Result<usize, FourierError> {
        let v = self.i32_at(offset) as i64;
        if v < lo || v > hi {
            return Err(self.err(offset, format!("expected {name} in {lo}..={hi}, found {v}")));
        }
        Ok(v as usize)
    }
    /// `n` finite floats starting at `offset`.
    fn floats(&self, offset: usize, n: usize, name: &str) -> Result<Vec<f32>, FourierError> {
        let mut v = Vec::with_capacity(n);
        for i in 0..n {
            let x = self.f32_at(offset + 4 * i);
            if !x.is_finite() {
                return Err(self.err(offset + 4 * i, format!("expected a finite {name}[{i}], found {x}")));
            }
            v.push(x);
        }
        Ok(v)
    }
}

impl FourierTable {
    /// Parses and validates a `.bsdf` file's bytes (`path` names it in errors).
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<FourierTable, FourierError> {
        let r = Reader { bytes, path };
        if bytes.len() < HEADER_BYTES {
            return Err(r.err(bytes.len(), format!("expected a {HEADER_BYTES}-byte header, the file ends")));
        }
        if &bytes[..8] != MAGIC {
            return Err(r.err(0, "expected the identifier \"SCATFUN\" and version 1"));
        }
        let flags = r.i32_at(8);
        if flags != 1 {
            return Err(r.err(
                8,
                format!("expected flags 1 (a BSDF without harmonic extrapolation, as pbrt-v3 reads), found {flags}"),
            ));
        }
        let n_mu = r.count(12, "nMu (elevation nodes)", 2, i32::MAX as i64)?;
        let n_coeffs = r.count(16, "nCoeffs", 0, i32::MAX as i64)?;
        let m_max = r.count(20, "mMax (longest series)", 1, i32::MAX as i64)?;
        let n_channels = r.i32_at(24);
        if n_channels != 1 && n_channels != 3 {
            return Err(r.err(24, format!("expected nChannels 1 or 3 (as pbrt-v3 reads), found {n_channels}")));
        }
        let n_channels = n_channels as usize;
        let n_bases = r.i32_at(28);
        if n_bases != 1 {
            return Err(r.err(28, format!("expected nBases 1 (untextured; as pbrt-v3 reads), found {n_bases}")));
        }
        let eta = r.f32_at(44);
        if !(eta.is_finite() && eta > 0.0) {
            return Err(r.err(44, format!("expected a positive relative index of refraction eta, found {eta}")));
        }
        // What the header's sizes need, in u64 (no overflow for any i32 values), against the file.
        let (nm, nc) = (n_mu as u64, n_coeffs as u64);
        let need = HEADER_BYTES as u64 + 4 * (nm + nm * nm + 2 * nm * nm + nc);
        if need > bytes.len() as u64 {
            return Err(r.err(
                bytes.len(),
                format!(
                    "expected {need} bytes for the header's sizes (nMu {n_mu}, nCoeffs {n_coeffs}), the file has {}",
                    bytes.len()
                ),
            ));
        }
        let n2 = n_mu * n_mu;
        let mu_at = HEADER_BYTES;
        let cdf_at = mu_at + 4 * n_mu;
        let series_at = cdf_at + 4 * n2;
        let coeffs_at = series_at + 8 * n2;
        let mu = r.floats(mu_at, n_mu, "mu")?;
        // Non-decreasing, not increasing: pbrt-v3's own files repeat the node 0 (the two
        // hemispheres' grids meet there; `roughgold_alpha_0.2.bsdf` has mu[28] = mu[29] = 0), and
        // an empty interval is never the one a lookup or a sample lands in.
        if let Some(i) = (1..n_mu).find(|&i| !(mu[i] >= mu[i - 1])) {
            return Err(r.err(mu_at + 4 * i, format!("expected mu[{i}] >= mu[{}] (non-decreasing nodes)", i - 1)));
        }
        let cdf = r.floats(cdf_at, n2, "cdf")?;
        let coeffs = r.floats(coeffs_at, n_coeffs, "coefficient")?;
        let mut series = Vec::with_capacity(n2);
        let mut a0 = Vec::with_capacity(n2);
        for i in 0..n2 {
            let at = series_at + 8 * i;
            let (offset, length) = (r.i32_at(at) as i64, r.i32_at(at + 4) as i64);
            let end = offset + length * n_channels as i64;
            if offset < 0 || length < 0 || length > m_max as i64 || end > n_coeffs as i64 {
                return Err(r.err(
                    at,
                    format!(
                        "expected a series (offset, length) with 0 ≤ length ≤ mMax ({m_max}) and offset + \
                         length × {n_channels} ≤ nCoeffs ({n_coeffs}), found ({offset}, {length})"
                    ),
                ));
            }
            series.push((offset as u32, length as u32));
            a0.push(if length > 0 { coeffs[offset as usize] } else { 0.0 });
        }
        // Scratch buffers are sized by the longest series present, not by the header's claim.
        let m_max = series.iter().map(|s| s.1 as usize).max().unwrap_or(0).clamp(1, m_max);
        Ok(FourierTable { eta, m_max, n_channels, mu, cdf, a0, series, coeffs })
    }

    /// Reads a `.bsdf` file (at most [`MAX_FILE_BYTES`]).
    pub fn read(path: &Path) -> Result<FourierTable, FourierError> {
        let whole = |message: String| FourierError { path: path.to_path_buf(), offset: None, message };
        let len = std::fs::metadata(path).map_err(|e| whole(format!("cannot read: {e}")))?.len();
        if len > MAX_FILE_BYTES {
            return Err(whole(format!("is {len} bytes; penumbra reads tabulated BSDFs of at most {MAX_FILE_BYTES}")));
        }
        let bytes = std::fs::read(path).map_err(|e| whole(format!("cannot read: {e}")))?;
        Self::from_bytes(&bytes, path)
    }

    /// [`Self::read`] through the process-wide cache (see the module doc).
    pub fn cached(path: &Path) -> Result<&'static FourierTable, FourierError> {
        type Key = (PathBuf, u64, Option<SystemTime>);
        static CACHE: Mutex<Option<HashMap<Key, &'static FourierTable>>> = Mutex::new(None);
        let canonical = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
        let meta = std::fs::metadata(&canonical).ok();
        let key = (canonical, meta.as_ref().map_or(0, |m| m.len()), meta.and_then(|m| m.modified().ok()));
        let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(t) = cache.as_ref().and_then(|c| c.get(&key)) {
            return Ok(t);
        }
        let table: &'static FourierTable = Box::leak(Box::new(Self::read(path)?));
        cache.get_or_insert_with(HashMap::new).insert(key, table);
        Ok(table)
    }

    /// The coefficients of pair (`µ_i` node `i`, `µ_o` node `o`): `length` per channel.
    fn ak(&self, i: usize, o: usize) -> (&[f32], usize) {
        let (offset, m) = self.series[o * self.mu.len() + i];
        let (offset, m) = (offset as usize, m as usize);
        (&self.coeffs[offset..offset + m * self.n_channels], m)
    }

    /// The spline-interpolated series at `(µ_i, µ_o)` into `ak` (`n_channels × m_max`, zeroed
    /// here); returns the longest series used, `None` outside the nodes.
    fn interpolate(&self, mu_i: f32, mu_o: f32, ak: &mut [f32], channels: usize) -> Option<usize> {
        let (oi, wi) = catmull_rom_weights(&self.mu, mu_i)?;
        let (oo, wo) = catmull_rom_weights(&self.mu, mu_o)?;
        ak.iter_mut().for_each(|a| *a = 0.0);
        let mut m_max = 0;
        for (b, wob) in wo.iter().enumerate() {
            for (a, wia) in wi.iter().enumerate() {
                let weight = wia * wob;
                if weight == 0.0 {
                    continue;
                }
                let (ap, m) = self.ak((oi + a as isize) as usize, (oo + b as isize) as usize);
                m_max = m_max.max(m);
                for c in 0..channels {
                    for k in 0..m {
                        ak[c * self.m_max + k] += weight * ap[c * m + k];
                    }
                }
            }
        }
        Some(m_max)
    }
}

thread_local! {
    static SCRATCH: RefCell<Vec<f32>> = const { RefCell::new(Vec::new()) };
}

/// pbrt-v3's `CosDPhi`: cosine of the azimuth between two directions (1 when either is vertical).
fn cos_d_phi(a: Vec3, b: Vec3) -> f32 {
    let (axy, bxy) = (a.x * a.x + a.y * a.y, b.x * b.x + b.y * b.y);
    if axy == 0.0 || bxy == 0.0 {
        return 1.0;
    }
    ((a.x * b.x + a.y * b.y) / (axy * bxy).sqrt()).clamp(-1.0, 1.0)
}

/// The lobe: a table, the transport mode and `mix`'s weight.
#[derive(Clone, Copy, Debug)]
pub struct FourierBxdf {
    pub table: &'static FourierTable,
    pub mode: TransportMode,
    pub scale: Rgb,
}

impl PartialEq for FourierBxdf {
    fn eq(&self, other: &Self) -> bool {
        std::ptr::eq(self.table, other.table) && self.mode == other.mode && self.scale == other.scale
    }
}

impl FourierBxdf {
    pub fn new(table: &'static FourierTable, mode: TransportMode) -> Self {
        FourierBxdf { table, mode, scale: Rgb::ONE }
    }

    pub fn flags(&self) -> BxdfFlags {
        BxdfFlags::REFLECTION | BxdfFlags::TRANSMISSION | BxdfFlags::GLOSSY
    }

    pub fn scaled(self, s: Rgb) -> Self {
        FourierBxdf { scale: self.scale * s, ..self }
    }

    /// `1/|µ_i|`, with pbrt-v3's η² for radiance crossing the boundary.
    fn value_scale(&self, mu_i: f32, mu_o: f32) -> f32 {
        let mut scale = if mu_i != 0.0 { 1.0 / mu_i.abs() } else { 0.0 };
        if self.mode == TransportMode::Radiance && mu_i * mu_o > 0.0 {
            let eta = if mu_i > 0.0 { 1.0 / self.table.eta } else { self.table.eta };
            scale *= eta * eta;
        }
        scale
    }

    /// The colour of the interpolated series `ak` at `cos φ`, given its luminance `y`.
    fn colour(&self, ak: &[f32], m: usize, y: f32, cos_phi: f32, scale: f32) -> Rgb {
        let t = self.table;
        let rgb = if t.n_channels == 1 {
            Rgb::splat(y * scale)
        } else {
            let r = fourier(&ak[t.m_max..t.m_max + m], cos_phi as f64);
            let b = fourier(&ak[2 * t.m_max..2 * t.m_max + m], cos_phi as f64);
            let g = 1.39829 * y - 0.100913 * b - 0.297375 * r;
            (Rgb::new(r, g, b) * scale).max(Rgb::ZERO)
        };
        rgb * self.scale
    }

    pub fn f(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let t = self.table;
        let (mu_i, mu_o) = (-wi.z, wo.z);
        let cos_phi = cos_d_phi(-wi, wo);
        SCRATCH.with(|s| {
            let mut ak = s.borrow_mut();
            ak.resize(t.m_max * t.n_channels, 0.0);
            let Some(m) = t.interpolate(mu_i, mu_o, &mut ak, t.n_channels) else { return Rgb::ZERO };
            let y = fourier(&ak[..m], cos_phi as f64).max(0.0);
            self.colour(&ak, m, y, cos_phi, self.value_scale(mu_i, mu_o))
        })
    }

    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let t = self.table;
        let (mu_i, mu_o) = (-wi.z, wo.z);
        let cos_phi = cos_d_phi(-wi, wo);
        let Some((oo, wo_w)) = catmull_rom_weights(&t.mu, mu_o) else { return 0.0 };
        let n = t.mu.len();
        let mut rho = 0.0;
        for (o, w) in wo_w.iter().enumerate() {
            if *w != 0.0 {
                rho += w * t.cdf[(oo + o as isize) as usize * n + n - 1] * 2.0 * std::f32::consts::PI;
            }
        }
        SCRATCH.with(|s| {
            let mut ak = s.borrow_mut();
            ak.resize(t.m_max * t.n_channels, 0.0);
            let Some(m) = t.interpolate(mu_i, mu_o, &mut ak, 1) else { return 0.0 };
            let y = fourier(&ak[..m], cos_phi as f64);
            if rho > 0.0 && y > 0.0 {
                y / rho
            } else {
                0.0
            }
        })
    }

    /// pbrt-v3's `Sample_f` direction: `µ_i` by the interpolated `cdf` (`u.y`), φ by the
    /// interpolated luminance series (`u.x`).
    pub fn sample_wi(&self, wo: Vec3, u: Vec2) -> Option<Vec3> {
        let t = self.table;
        let mu_o = wo.z;
        let s = sample_catmull_rom_2d(&t.mu, &t.mu, &t.a0, &t.cdf, mu_o, u.y)?;
        let mu_i = s.x;
        let phi = SCRATCH.with(|sc| {
            let mut ak = sc.borrow_mut();
            ak.resize(t.m_max * t.n_channels, 0.0);
            let m = t.interpolate(mu_i, mu_o, &mut ak, 1)?;
            (m > 0 && ak[0] > 0.0).then(|| sample_fourier(&ak[..m], u.x).phi)
        })?;
        let sin2_i = (1.0 - mu_i * mu_i).max(0.0);
        let sin2_o = (1.0 - wo.z * wo.z).max(0.0);
        let mut norm = (sin2_i / sin2_o).sqrt();
        if !norm.is_finite() {
            norm = 0.0;
        }
        let (sin_phi, cos_phi) = phi.sin_cos();
        let wi = -Vec3::new(norm * (cos_phi * wo.x - sin_phi * wo.y), norm * (sin_phi * wo.x + cos_phi * wo.y), mu_i);
        let wi = wi.try_normalize()?;
        Some(wi)
    }
}
