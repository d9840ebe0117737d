//! Parse throughput on a generated ~100 MB `trianglemesh` scene.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};

#[path = "gen_mesh.rs"]
mod gen_mesh;

fn bench(c: &mut Criterion) {
    let dir = std::env::temp_dir().join(format!("penumbra-parse-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("big-mesh.pbrt");
    gen_mesh::write_big_mesh(&path, 100 << 20).expect("write scene");
    let bytes = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    let mut g = c.benchmark_group("parse");
    g.sample_size(10);
    g.throughput(Throughput::Bytes(bytes));
    g.bench_function("trianglemesh-100MB", |b| {
        b.iter(|| penumbra_parser::parse_file(&path).expect("parse"));
    });
    g.finish();
    std::fs::remove_dir_all(&dir).ok();
}

criterion_group!(benches, bench);
criterion_main!(benches);
