//! The on-disk cache of fitted leaf sets, keyed by a hash of the mesh and the fit parameters.
//!
//! Location: `$PENUMBRA_CACHE_DIR/spheresets/` if that variable is set (set it empty to turn
//! the cache off), else `$XDG_CACHE_HOME/penumbra/spheresets/`, else
//! `$HOME/.cache/penumbra/spheresets/`. One small text file per mesh, `<key>.spheres`, holding
//! the exact bits of every value. A missing, unreadable, corrupt or unwritable cache is never
//! an error: the set is fitted again and the render goes on (the build report says so).

use super::fit::{Fit, FitParams};
use super::Sphere;
use glam::DVec3;
use penumbra_core::fnv::Fnv1a;
use penumbra_core::mesh::TriangleMesh;
use std::path::{Path, PathBuf};

/// Bumped whenever the fit changes what it produces.
pub const FIT_VERSION: u64 = 4;

/// The default cache directory (see the module doc), `None` when disabled or unknown.
pub fn default_dir() -> Option<PathBuf> {
    if let Some(d) = std::env::var_os("PENUMBRA_CACHE_DIR") {
        return (!d.is_empty()).then(|| PathBuf::from(d).join("spheresets"));
    }
    if let Some(d) = std::env::var_os("XDG_CACHE_HOME").filter(|d| !d.is_empty()) {
        return Some(PathBuf::from(d).join("penumbra").join("spheresets"));
    }
    std::env::var_os("HOME").filter(|d| !d.is_empty()).map(|h| PathBuf::from(h).join(".cache/penumbra/spheresets"))
}

/// The cache key of `mesh` fitted with `params`.
pub fn key(mesh: &TriangleMesh, params: &FitParams) -> u64 {
    let mut h = Fnv1a::new();
    h.u64(FIT_VERSION);
    for v in [params.spheres, params.inner_points, params.surface_points, params.iterations, params.teleports] {
        h.u64(v as u64);
    }
    h.u64(mesh.positions.len() as u64);
    for p in &mesh.positions {
        for c in p.to_array() {
            h.bytes(&c.to_bits().to_le_bytes());
        }
    }
    h.u64(mesh.indices.len() as u64);
    for t in &mesh.indices {
        for i in t {
            h.bytes(&i.to_le_bytes());
        }
    }
    h.finish()
}

fn path(dir: &Path, key: u64) -> PathBuf {
    dir.join(format!("{key:016x}.spheres"))
}

fn hex(v: f64) -> String {
    format!("{:016x}", v.to_bits())
}

fn unhex(s: &str) -> Option<f64> {
    u64::from_str_radix(s, 16).ok().map(f64::from_bits)
}

/// The cached fit for `key` in `dir`, if present and well formed.
pub fn load(dir: &Path, key: u64) -> Option<Fit> {
    let text = std::fs::read_to_string(path(dir, key)).ok()?;
    let mut lines = text.lines();
    if lines.next()? != format!("penumbra spheres v{FIT_VERSION} {key:016x}") {
        return None;
    }
    let head: Vec<&str> = lines.next()?.split_whitespace().collect();
    if head.len() != 5 || head[0] != "fit" {
        return None;
    }
    let (outside_volume, volume) = (unhex(head[1])?, unhex(head[2])?);
    let (inner_points, surface_points) = (head[3].parse().ok()?, head[4].parse().ok()?);
    let mut spheres = Vec::new();
    for l in lines {
        let v: Vec<f64> = l.split_whitespace().map(unhex).collect::<Option<_>>()?;
        if v.len() != 4 || !v.iter().all(|x| x.is_finite()) || !(v[3] > 0.0) {
            return None;
        }
        spheres.push(Sphere { center: DVec3::new(v[0], v[1], v[2]), radius: v[3] });
    }
    (!spheres.is_empty()).then_some(Fit { spheres, outside_volume, volume, inner_points, surface_points })
}

/// Stores `fit` under `key` in `dir` (created if needed; written to a temporary file and
/// renamed, so concurrent renders never read half a file). Errors are returned, for the
/// report; callers ignore them.
pub fn store(dir: &Path, key: u64, fit: &Fit) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let mut s = format!("penumbra spheres v{FIT_VERSION} {key:016x}\n");
    s += &format!("fit {} {} {} {}\n", hex(fit.outside_volume), hex(fit.volume), fit.inner_points, fit.surface_points);
    for sp in &fit.spheres {
        s += &format!("{} {} {} {}\n", hex(sp.center.x), hex(sp.center.y), hex(sp.center.z), hex(sp.radius));
    }
    let tmp = dir.join(format!("{key:016x}.{}.tmp", std::process::id()));
    std::fs::write(&tmp, s)?;
    std::fs::rename(&tmp, path(dir, key)).inspect_err(|_| {
        let _ = std::fs::remove_file(&tmp);
    })
}
