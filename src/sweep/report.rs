//! What a sweep writes as rows arrive: `sweep.csv`, `sweep.json`, and (through
//! [`Outputs::write_report`]) the summary and the plots.

use super::args::SweepArgs;
use super::plot::{render_plots, Series};
use super::row::{Metric, Row};
use super::summary::{default_target, summary_markdown, SummaryInput};
use crate::cli::format::num;
use penumbra_core::image;
use serde_json::{json, Value};
use std::fmt::Write as _;
use std::path::Path;

pub const CSV_HEADER: &str =
    "integrator,budget,build_s,render_s,total_s,mae,rmse,psnr,max_err,relmse,smape,flip,nan_count";

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

pub fn csv_text(rows: &[Row]) -> String {
    let mut s = String::from(CSV_HEADER);
    s.push('\n');
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{}",
            csv_field(&r.integrator),
            r.budget,
            r.build_s,
            r.render_s,
            r.total_s,
            r.mae,
            r.rmse,
            r.psnr,
            r.max_err,
            r.relmse,
            r.smape,
            r.flip.map(|v| v.to_string()).unwrap_or_default(),
            r.nan_count
        );
    }
    s
}

fn row_json(r: &Row) -> Value {
    json!({
        "integrator": r.integrator,
        "budget": r.budget,
        "spp": r.spp,
        "build_s": num(r.build_s),
        "render_s": num(r.render_s),
        "total_s": num(r.total_s),
        "mae": num(r.mae),
        "rmse": num(r.rmse),
        "psnr": num(r.psnr),
        "max_err": num(r.max_err),
        "relmse": num(r.relmse),
        "smape": num(r.smape),
        "flip": r.flip.map(num).unwrap_or(Value::Null),
        "nan_count": r.nan_count,
    })
}

fn write_text(path: &Path, text: &str) -> Result<(), String> {
    image::write_atomic(path, |w| w.write_all(text.as_bytes())).map_err(|e| e.to_string())
}

/// What the sweep writes, kept up to date as rows arrive.
pub struct Outputs<'a> {
    dir: &'a Path,
    scene: String,
    reference: Value,
    reference_label: String,
    integrators: Vec<String>,
    metric: Metric,
    budget_name: String,
    threads: usize,
    args_json: Value,
    /// `sweep --collect`: each item's machine and timings file.
    items: Option<Value>,
}

impl<'a> Outputs<'a> {
    /// The outputs under `--output`, with the reference as `sweep.json` and the summary name it.
    pub fn new(args: &'a SweepArgs, integrators: &[String], reference: Value, reference_label: String) -> Self {
        let threads = penumbra_core::integrator::resolve_threads(args.flags.threads);
        Outputs {
            dir: &args.output,
            scene: args.scene.display().to_string(),
            reference,
            reference_label,
            integrators: integrators.to_vec(),
            metric: args.metric,
            budget_name: match &args.budget_param {
                Some(p) => format!("parameter \"{}\"", p.trim()),
                None => "samples per pixel".into(),
            },
            threads,
            args_json: json!({
                "budgets": args.budgets,
                "time_limit": args.time_limit,
                "max_budget": args.max_budget,
                "budget_param": args.budget_param,
                "spp": args.spp,
                "params": args.flags.params,
                "seed": args.flags.seed,
                "resolution": crate::cli::resolution_text(args.flags.resolution),
                "crop": crate::cli::crop_text(args.crop),
            }),
            items: None,
        }
    }

    /// Records the items a `--collect` gathered (written to `sweep.json`).
    pub fn with_items(mut self, items: Value) -> Self {
        self.items = Some(items);
        self
    }

    pub fn write_tables(&self, rows: &[Row], complete: bool) -> Result<(), String> {
        write_text(&self.dir.join("sweep.csv"), &csv_text(rows))?;
        let machine_threads = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
        let doc = json!({
            "scene": self.scene,
            "reference": self.reference,
            "integrators": self.integrators,
            "metric": self.metric.column(),
            "budget": self.budget_name,
            "machine": { "threads": machine_threads },
            "threads": self.threads,
            "arguments": self.args_json,
            "complete": complete,
            "rows": rows.iter().map(row_json).collect::<Vec<_>>(),
        });
        let mut doc = doc;
        if let (Some(items), Some(map)) = (&self.items, doc.as_object_mut()) {
            map.insert("items".into(), items.clone());
        }
        write_text(&self.dir.join("sweep.json"), &(serde_json::to_string_pretty(&doc).unwrap_or_default() + "\n"))
    }

    /// The plot (if there is anything to plot) and the summary; returns the summary text and
    /// whether the plot was written.
    pub fn write_report(
        &self,
        rows: &[Row],
        target: Option<f64>,
        stopped: Option<&str>,
    ) -> Result<(String, bool), String> {
        let target = match target {
            Some(e) => Some((e, "given with --target-error".to_string())),
            None => default_target(rows, &self.integrators, self.metric),
        };
        let summary = summary_markdown(
            rows,
            &SummaryInput {
                scene: &self.scene,
                reference: &self.reference_label,
                metric: self.metric,
                budget_name: &self.budget_name,
                target,
                threads: self.threads,
                integrators: &self.integrators,
                stopped,
            },
        );
        write_text(&self.dir.join("summary.md"), &summary)?;
        let series: Vec<Series> = self
            .integrators
            .iter()
            .map(|n| {
                let pts = rows
                    .iter()
                    .filter(|r| &r.integrator == n)
                    .filter_map(|r| Some((r.total_s, self.metric.of(r)?, r.budget)))
                    .filter(|&(t, e, _)| t > 0.0 && e > 0.0 && t.is_finite() && e.is_finite())
                    .collect();
                (n.clone(), pts)
            })
            .filter(|s: &Series| !s.1.is_empty())
            .collect();
        let (png, svg) = (self.dir.join("sweep.png"), self.dir.join("sweep.svg"));
        if series.is_empty() {
            let _ = std::fs::remove_file(&png);
            let _ = std::fs::remove_file(&svg);
            Ok((summary, false))
        } else {
            let name = Path::new(&self.scene).file_name().map(|s| s.to_string_lossy().into_owned());
            let title = format!("{}: {} vs time", name.unwrap_or_else(|| self.scene.clone()), self.metric.label());
            let (svg_text, png_bytes) = render_plots(&title, self.metric, &series)?;
            write_text(&svg, &svg_text)?;
            image::write_atomic(&png, |w| w.write_all(&png_bytes)).map_err(|e| e.to_string())?;
            Ok((summary, true))
        }
    }
}
