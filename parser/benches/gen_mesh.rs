//! Writes a large single-`trianglemesh` pbrt-v3 scene (shared by the benchmark and the `parse_stats` example).

use std::io::Write;
use std::path::Path;

/// Writes about `target_bytes` of scene text to `path`; returns the numeric payload in bytes
/// (4 bytes per parsed f32 or i32).
pub fn write_big_mesh(path: &Path, target_bytes: u64) -> std::io::Result<u64> {
    // Roughly 30 bytes of point text + 48 bytes of index text per vertex.
    let nv = (target_bytes / 68).max(3);
    let nt = 2 * (nv - 2);
    let mut w = std::io::BufWriter::with_capacity(1 << 20, std::fs::File::create(path)?);
    writeln!(w, "LookAt 0 0 -5 0 0 0 0 1 0\nCamera \"perspective\" \"float fov\" [45]\nWorldBegin")?;
    writeln!(w, "Shape \"trianglemesh\"\n  \"point P\" [")?;
    let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (s >> 40) as f64 / (1u64 << 24) as f64
    };
    for i in 0..nv {
        write!(w, "{:.5} {:.5} {:.5}", next() * 2.0 - 1.0, next() * 2.0 - 1.0, next() * 2.0 - 1.0)?;
        w.write_all(if i % 4 == 3 { b"\n" } else { b" " })?;
    }
    writeln!(w, "]\n  \"integer indices\" [")?;
    for t in 0..nt {
        let a = t / 2;
        write!(w, "{} {} {}", a, a + 1, a + 2)?;
        w.write_all(if t % 8 == 7 { b"\n" } else { b" " })?;
    }
    writeln!(w, "]\nWorldEnd")?;
    w.flush()?;
    Ok(nv * 3 * 4 + nt * 3 * 4)
}
