//! One parse of a generated ~100 MB `trianglemesh` scene (or of the file given as the
//! first argument): prints MB/s, the numeric payload, and peak RSS (VmHWM).
//!
//! `cargo run --release -p penumbra-parser --example parse_stats [SCENE]`

use penumbra_parser::{ParamValue, SpectrumValue};
use std::time::Instant;

#[path = "../benches/gen_mesh.rs"]
mod gen_mesh;

fn vm(key: &str) -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with(key))?;
    line.split_whitespace().nth(1)?.parse::<u64>().ok().map(|kb| kb * 1024)
}

fn payload(ps: &penumbra_parser::ParamSet) -> u64 {
    ps.params
        .iter()
        .map(|p| match &p.value {
            ParamValue::Int(v) => v.len() as u64 * 4,
            ParamValue::Float(v)
            | ParamValue::Point2(v)
            | ParamValue::Vector2(v)
            | ParamValue::Point3(v)
            | ParamValue::Vector3(v)
            | ParamValue::Normal(v) => v.len() as u64 * 4,
            ParamValue::Spectrum(
                SpectrumValue::Rgb(v) | SpectrumValue::Xyz(v) | SpectrumValue::Blackbody(v) | SpectrumValue::Sampled(v),
            ) => v.len() as u64 * 4,
            _ => 0,
        })
        .sum()
}

fn main() {
    let (path, tmp) = match std::env::args().nth(1) {
        Some(p) => (std::path::PathBuf::from(p), None),
        None => {
            let dir = std::env::temp_dir().join(format!("penumbra-parse-stats-{}", std::process::id()));
            std::fs::create_dir_all(&dir).expect("temp dir");
            let p = dir.join("big-mesh.pbrt");
            gen_mesh::write_big_mesh(&p, 100 << 20).expect("write scene");
            (p, Some(dir))
        }
    };
    let bytes = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    let before = vm("VmHWM:").unwrap_or(0);
    let rss0 = vm("VmRSS:").unwrap_or(0);
    let t = Instant::now();
    let out = match penumbra_parser::parse_file(&path) {
        Ok(o) => o,
        Err(e) => {
            eprint!("{e}");
            std::process::exit(1);
        }
    };
    let secs = t.elapsed().as_secs_f64();
    let hwm = vm("VmHWM:").unwrap_or(0);
    let s = &out.scene;
    let pay: u64 = s.shapes.iter().map(|x| payload(&x.entity.params)).sum::<u64>()
        + s.instance_definitions.iter().flat_map(|d| &d.shapes).map(|x| payload(&x.entity.params)).sum::<u64>();
    let mb = |b: u64| b as f64 / (1024.0 * 1024.0);
    println!("file: {} ({:.1} MiB)", path.display(), mb(bytes));
    println!("parse: {:.3} s, {:.1} MiB/s", secs, mb(bytes) / secs);
    println!("numeric payload (f32/i32): {:.1} MiB", mb(pay));
    println!("RSS before parse: {:.1} MiB (peak so far {:.1} MiB)", mb(rss0), mb(before));
    println!("peak RSS (VmHWM) after parse: {:.1} MiB = {:.2} x payload", mb(hwm), hwm as f64 / pay.max(1) as f64);
    drop(out);
    if let Some(d) = tmp {
        std::fs::remove_dir_all(d).ok();
    }
}
