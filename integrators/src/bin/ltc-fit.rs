//! Fits the LTC table for core's Trowbridge–Reitz reflection and writes it in
//! `penumbra_integrators::common::ltc::Ltc`'s binary format.
//!
//! `cargo run --release -p penumbra-integrators --bin ltc-fit -- --out integrators/data/ltc_ggx.bin [--n 64] [--samples 24]`

use std::time::Instant;

use penumbra_integrators::common::ltc::fit::{fit_table, FitOptions};

fn main() {
    let mut opts = FitOptions::default();
    let mut out = String::from("integrators/data/ltc_ggx.bin");
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut i = 0;
    while i < args.len() {
        let val = args.get(i + 1).cloned().unwrap_or_default();
        match args[i].as_str() {
            "--out" => out = val,
            "--n" => {
                let n = val.parse().unwrap_or(64usize).clamp(2, 1024);
                opts.n_theta = n;
                opts.n_alpha = n;
            }
            "--samples" => opts.error_samples = val.parse().unwrap_or(24usize).clamp(2, 1024),
            "--iter" => opts.max_iter = val.parse().unwrap_or(400usize).clamp(1, 100_000),
            "--alpha-min" => opts.alpha_min = val.parse().unwrap_or(1e-3f32).clamp(1e-6, 0.5),
            other => {
                eprintln!("ltc-fit: unknown argument {other}");
                std::process::exit(2);
            }
        }
        i += 2;
    }
    let t0 = Instant::now();
    let (table, fits) = fit_table(&opts, |done, rows| {
        if done % 8 == 0 || done == rows {
            eprintln!("ltc-fit: {done}/{rows} rows, {:.1} s", t0.elapsed().as_secs_f64());
        }
    });
    let errs: Vec<f64> = fits.iter().map(|f| f.error).collect();
    let mean = errs.iter().sum::<f64>() / errs.len().max(1) as f64;
    let worst = fits.iter().max_by(|a, b| a.error.total_cmp(&b.error));
    eprintln!(
        "ltc-fit: {}x{} cells in {:.1} s; L3 error mean {mean:.3e}",
        opts.n_theta,
        opts.n_alpha,
        t0.elapsed().as_secs_f64()
    );
    if let Some(w) = worst {
        eprintln!(
            "ltc-fit: worst cell alpha {:.4} cos {:.4}: {:.3e} params {:?}",
            w.alpha, w.cos_theta, w.error, w.params
        );
    }
    if let Err(e) = std::fs::write(&out, table.to_bytes()) {
        eprintln!("ltc-fit: cannot write {out}: {e}");
        std::process::exit(1);
    }
    eprintln!("ltc-fit: wrote {out}");
}
