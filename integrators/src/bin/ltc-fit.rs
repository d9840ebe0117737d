//! Fits the LTC table for core's Trowbridge–Reitz reflection, writes it in
//! `penumbra_integrators::common::ltc::Ltc`'s binary format and the fit's error per cell beside it.
//!
//! `cargo run --release -p penumbra-integrators --bin ltc-fit -- --out integrators/data/ltc_ggx.bin [--n 64]
//! [--n-alpha N] [--samples 24] [--alpha-min 0.001] [--alpha-max 3] [--report FILE.tsv]`
//!
//! The report (default: the output's name with `_fit.tsv` for `.bin`) has one row per cell:
//! its `α` and `cos θo`, the magnitude `∫ f cos` (256² VNDF quadrature), the table's magnitude
//! error relative to it, and the lobe-shape error `∫ |D_LTC − f̂| dω` at the node and at the
//! middle of the cell (between it and the next row and column: the bilinear interpolation's
//! error), each from 64² samples of both distributions (see `ltc::fit::cell_error`).

use std::fmt::Write as _;
use std::time::Instant;

use penumbra_integrators::common::ltc::fit::{cell_error, fit_table, FitOptions};
use penumbra_integrators::common::ltc::{alpha_axis, alpha_of_axis, Ltc};

fn usage(msg: &str) -> ! {
    eprintln!("ltc-fit: {msg}");
    std::process::exit(2);
}

fn parse<T: std::str::FromStr>(name: &str, val: &str) -> T {
    val.parse().unwrap_or_else(|_| usage(&format!("{name}: cannot read {val:?}")))
}

/// The report (see the module doc) and its summary line.
fn report(table: &Ltc) -> (String, String) {
    let mut out = String::from(
        "# ltc-fit report: per table cell, alpha, cos_theta, magnitude (256^2 VNDF quadrature), \
         magnitude_error (table/quadrature - 1), l1_node and l1_mid (integral of |D_LTC - f/magnitude|, \
         0..2, at the node and at the cell's middle: between rows j, j+1 and columns i, i+1)\n\
         alpha\tcos_theta\tmagnitude\tmagnitude_error\tl1_node\tl1_mid\n",
    );
    let (v0, v1) = (alpha_axis(table.alpha_min as f64), alpha_axis(table.alpha_max as f64));
    let (mut worst_mag, mut worst_node, mut worst_mid, mut sum_mid) = (0.0f64, 0.0f64, 0.0f64, 0.0);
    for j in 0..table.n_alpha {
        let alpha = table.row_alpha(j);
        let alpha_mid = if j + 1 < table.n_alpha {
            alpha_of_axis(v0 + (v1 - v0) * (j as f64 + 0.5) / (table.n_alpha - 1) as f64)
        } else {
            alpha
        };
        for i in 0..table.n_theta {
            let cos = table.column_cos_theta(i);
            let x_mid = ((i as f64 + 0.5).min((table.n_theta - 1) as f64)) / (table.n_theta - 1) as f64;
            let cos_mid = 1.0 - x_mid * x_mid;
            let node = cell_error(table, alpha, cos, 64);
            let mid = cell_error(table, alpha_mid, cos_mid, 64);
            worst_mag = worst_mag.max(node.magnitude_error.abs());
            worst_node = worst_node.max(node.l1);
            worst_mid = worst_mid.max(mid.l1);
            sum_mid += mid.l1;
            let _ = writeln!(
                out,
                "{alpha:.5}\t{cos:.5}\t{:.5}\t{:+.2e}\t{:.4}\t{:.4}",
                node.magnitude, node.magnitude_error, node.l1, mid.l1
            );
        }
    }
    let summary = format!(
        "worst |magnitude error| {worst_mag:.2e}; L1 shape error worst at nodes {worst_node:.4}, between nodes {worst_mid:.4} (mean {:.4})",
        sum_mid / table.cells.len() as f64
    );
    (out, summary)
}

fn main() {
    let mut opts = FitOptions::default();
    let mut out = String::from("integrators/data/ltc_ggx.bin");
    let mut report_path: Option<String> = None;
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut i = 0;
    while i < args.len() {
        let val = args.get(i + 1).cloned().unwrap_or_else(|| usage(&format!("{} needs a value", args[i])));
        match args[i].as_str() {
            "--out" => out = val,
            "--report" => report_path = Some(val),
            "--n" => {
                let n: usize = parse("--n", &val);
                opts.n_theta = n.clamp(2, 1024);
                opts.n_alpha = n.clamp(2, 1024);
            }
            "--n-alpha" => opts.n_alpha = parse::<usize>("--n-alpha", &val).clamp(2, 1024),
            "--samples" => opts.error_samples = parse::<usize>("--samples", &val).clamp(2, 1024),
            "--iter" => opts.max_iter = parse::<usize>("--iter", &val).clamp(1, 100_000),
            "--alpha-min" => opts.alpha_min = parse::<f32>("--alpha-min", &val).clamp(1e-6, 0.5),
            "--alpha-max" => opts.alpha_max = parse::<f32>("--alpha-max", &val).clamp(0.6, 1e3),
            other => usage(&format!("unknown argument {other}")),
        }
        i += 2;
    }
    let report_path = report_path.unwrap_or_else(|| format!("{}_fit.tsv", out.trim_end_matches(".bin")));
    let t0 = Instant::now();
    let (table, fits) = fit_table(&opts, |done, rows| {
        if done % 8 == 0 || done == rows {
            eprintln!("ltc-fit: {done}/{rows} rows, {:.1} s", t0.elapsed().as_secs_f64());
        }
    });
    let errs: Vec<f64> = fits.iter().map(|f| f.error).collect();
    let mean = errs.iter().sum::<f64>() / errs.len().max(1) as f64;
    eprintln!(
        "ltc-fit: {}x{} cells (alpha {}..{}) in {:.1} s; L3 error mean {mean:.3e}",
        opts.n_theta,
        opts.n_alpha,
        opts.alpha_min,
        opts.alpha_max,
        t0.elapsed().as_secs_f64()
    );
    let (text, summary) = report(&table);
    eprintln!("ltc-fit: {summary}");
    for (path, bytes) in [(&out, table.to_bytes()), (&report_path, text.into_bytes())] {
        if let Err(e) = std::fs::write(path, bytes) {
            eprintln!("ltc-fit: cannot write {path}: {e}");
            std::process::exit(1);
        }
        eprintln!("ltc-fit: wrote {path}");
    }
}
