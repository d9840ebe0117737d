//! `sweep --plan`, `--run-item K`, `--collect`: the sweep's renders as independent items, one
//! per batch job, collected into the sweep's usual outputs.
//!
//! `--plan` writes `OUTDIR/plan.json`: item 0 is the `--reference-spp` reference (when there is
//! one), then one item per integrator and budget. Every mode recomputes the plan from its own
//! arguments (they must be those `--plan` was given; a different plan is refused), so a job
//! needs only the command line and its index. `--run-item K` renders item K into
//! `OUTDIR/items/item-K.exr` (R, G, B, float32) and `item-K.json` (its clocks and machine); the
//! reference goes to the sweep's cache. `--collect` compares each item with the reference in
//! the sweep's order, skipping budgets an integrator already covered as the sweep does, and
//! writes the same `sweep.csv`/`sweep.json`/plot/summary; every row keeps its item's timings.

use super::args::{Setup, SweepArgs};
use super::report::Outputs;
use super::row::Row;
use super::{cache, compare_row, fail, render_one, taken_budget, Failure, Timed};
use crate::cli::cancel_on_interrupt;
use penumbra_core::image::{self, Image};
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};
use std::path::PathBuf;

/// One independent unit of the sweep.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Item {
    pub index: usize,
    /// `"reference"` (the `--reference-spp` render) or `"render"`.
    pub kind: String,
    pub integrator: String,
    /// Samples per pixel, or the `--budget-param` value (the reference: its spp).
    pub budget: u32,
}

/// The items of the sweep `args` describe.
pub fn items(args: &SweepArgs, s: &Setup) -> Result<Vec<Item>, Failure> {
    if args.time_limit.is_some() {
        return Err(fail(
            "--plan/--run-item/--collect: with --time-limit the budgets depend on the renders' times; \
             give --budgets (or the doubling schedule up to --max-budget)",
        ));
    }
    let budgets: Vec<u32> = match &args.budgets {
        Some(b) => b.clone(),
        None => std::iter::successors(Some(1u32), |b| b.checked_mul(2)).take_while(|b| *b <= args.max_budget).collect(),
    };
    let mut out = Vec::new();
    if let (None, Some(n)) = (&args.reference, args.reference_spp) {
        out.push(Item {
            index: 0,
            kind: "reference".into(),
            integrator: args.reference_integrator().into(),
            budget: n,
        });
    }
    for name in &s.integrators {
        for &b in &budgets {
            out.push(Item { index: out.len(), kind: "render".into(), integrator: name.clone(), budget: b });
        }
    }
    Ok(out)
}

fn plan_path(args: &SweepArgs) -> PathBuf {
    args.output.join("plan.json")
}

fn item_paths(args: &SweepArgs, k: usize) -> (PathBuf, PathBuf) {
    let dir = args.output.join("items");
    (dir.join(format!("item-{k}.exr")), dir.join(format!("item-{k}.json")))
}

/// The plan, checked against `OUTDIR/plan.json` when there is one.
fn checked_items(args: &SweepArgs, s: &Setup) -> Result<Vec<Item>, Failure> {
    let items = items(args, s)?;
    let path = plan_path(args);
    if let Ok(text) = std::fs::read_to_string(&path) {
        let doc: Value =
            serde_json::from_str(&text).map_err(|e| fail(format!("{}: not a sweep plan: {e}", path.display())))?;
        let planned: Vec<Item> = serde_json::from_value(doc["items"].clone())
            .map_err(|e| fail(format!("{}: not a sweep plan: {e}", path.display())))?;
        if planned != items {
            return Err(fail(format!(
                "{}: the plan there has {} items, these arguments make {} different ones: give the arguments --plan was given",
                path.display(),
                planned.len(),
                items.len()
            )));
        }
    }
    Ok(items)
}

fn write_json(path: &std::path::Path, v: &Value) -> Result<(), Failure> {
    let text = serde_json::to_string_pretty(v).unwrap_or_default() + "\n";
    image::write_atomic(path, |w| w.write_all(text.as_bytes())).map_err(|e| fail(format!("{}: {e}", path.display())))
}

pub(super) fn plan(args: &SweepArgs, s: &Setup) -> Result<u8, Failure> {
    let items = items(args, s)?;
    std::fs::create_dir_all(&args.output).map_err(|e| fail(format!("cannot create {}: {e}", args.output.display())))?;
    let doc = json!({
        "format": 1,
        "scene": args.scene.display().to_string(),
        "scene_hash": s.scene_identity,
        "integrators": s.integrators,
        "items": items,
    });
    write_json(&plan_path(args), &doc)?;
    let n = items.len();
    eprintln!(
        "{}: {n} items{}: run this command with --run-item K for K = 0 … {} (in any order, anywhere), then with --collect",
        plan_path(args).display(),
        if items.first().is_some_and(|i| i.kind == "reference") { " (item 0: the reference)" } else { "" },
        n.saturating_sub(1)
    );
    println!("{n}");
    Ok(0)
}

pub(super) fn run_item(args: &SweepArgs, s: &mut Setup, k: usize) -> Result<u8, Failure> {
    let items = checked_items(args, s)?;
    let item = items.get(k).ok_or_else(|| {
        fail(format!("--run-item {k}: the plan has {} items (0 … {})", items.len(), items.len().saturating_sub(1)))
    })?;
    let cancel = cancel_on_interrupt();
    let mut seen = std::mem::take(&mut s.seen);
    let say = |m: String| {
        if !args.quiet {
            eprintln!("{m}");
        }
    };
    if item.kind == "reference" {
        cache::reference(args, s, None, &cancel, &mut seen, &say)?;
        return Ok(0);
    }
    let (exr, meta) = item_paths(args, k);
    std::fs::create_dir_all(args.output.join("items"))
        .map_err(|e| fail(format!("cannot create {}: {e}", args.output.join("items").display())))?;
    let (r, total_s) = render_one(args, s, &cancel, &item.integrator, item.budget, &mut seen)??;
    let t = Timed::of(&r, total_s)?;
    image::write(&t.image, &exr).map_err(fail)?;
    write_json(
        &meta,
        &json!({
            "item": item,
            "spp": t.spp,
            "build_s": t.build_s,
            "render_s": t.render_s,
            "total_s": t.total_s,
            "threads": r.stats.threads,
            "rays": r.stats.rays,
            "shadow_rays": r.stats.shadow_rays,
            "machine": crate::shard::machine(),
        }),
    )?;
    say(format!(
        "item {k}: {} at {}: build {:.3} s, render {:.3} s, total {:.3} s -> {}",
        item.integrator,
        item.budget,
        t.build_s,
        t.render_s,
        t.total_s,
        exr.display()
    ));
    Ok(0)
}

/// Item `k`'s render and clocks, as `--run-item` wrote them.
fn read_item(args: &SweepArgs, item: &Item) -> Result<(Timed, Value), String> {
    let (exr, meta) = item_paths(args, item.index);
    let text = std::fs::read_to_string(&meta).map_err(|e| format!("{}: {e}", meta.display()))?;
    let m: Value = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", meta.display()))?;
    if m["item"] != serde_json::to_value(item).unwrap_or_default() {
        return Err(format!("{}: written for another item ({})", meta.display(), m["item"]));
    }
    let image: Image = image::read(&exr).map_err(|e| e.to_string())?;
    let f = |k: &str| m[k].as_f64().unwrap_or(f64::NAN);
    let spp = m["spp"].as_u64().unwrap_or(0) as u32;
    let t = Timed { image, spp, build_s: f("build_s"), render_s: f("render_s"), total_s: f("total_s") };
    Ok((
        t,
        json!({ "index": item.index, "integrator": item.integrator, "budget": item.budget, "machine": m["machine"], "file": meta.display().to_string() }),
    ))
}

pub(super) fn collect(args: &SweepArgs, s: &mut Setup, file_reference: Option<Image>) -> Result<u8, Failure> {
    let items = checked_items(args, s)?;
    if let Some(p) = cache::cached_reference_path(args, s) {
        if !p.exists() {
            return Err(fail(format!("item 0 (the reference) has not run: {} is missing", p.display())));
        }
    }
    let cancel = cancel_on_interrupt();
    let mut seen = std::mem::take(&mut s.seen);
    let say = |m: String| {
        if !args.quiet {
            eprintln!("{m}");
        }
    };
    let reference = cache::reference(args, s, file_reference, &cancel, &mut seen, &say)?;
    let mut missing = Vec::new();
    let mut read = Vec::new();
    for item in items.iter().filter(|i| i.kind == "render") {
        match read_item(args, item) {
            Ok(r) => read.push((item, r)),
            Err(e) => missing.push(format!("item {} ({} at {}): {e}", item.index, item.integrator, item.budget)),
        }
    }
    if !missing.is_empty() {
        return Err(fail(format!(
            "{} of {} items have not run or cannot be read: {}",
            missing.len(),
            items.len(),
            missing.join("; ")
        )));
    }
    let mut rows: Vec<Row> = Vec::new();
    let mut listed = Vec::new();
    for name in &s.integrators {
        // Budgets an integrator already covered are skipped, as the sweep skips them.
        let mut covered = 0u32;
        for (item, (t, info)) in read.iter().filter(|(i, _)| &i.integrator == name) {
            if args.budget_param.is_none() && item.budget <= covered {
                say(format!("{name:>16} {:>6}: skipped ({covered} spp already rendered)", item.budget));
                continue;
            }
            let taken = taken_budget(args, item.budget, t.spp);
            rows.push(compare_row(name, taken, t, &reference.image, !args.no_flip)?);
            covered = covered.max(taken);
            listed.push(info.clone());
        }
    }
    let out = Outputs::new(args, &s.integrators, reference.json, reference.label).with_items(Value::Array(listed));
    out.write_tables(&rows, true).map_err(fail)?;
    let (summary, plotted) = out.write_report(&rows, args.target_error, None).map_err(fail)?;
    print!("{summary}");
    say(format!(
        "collected {} items: wrote {}/{{sweep.csv,sweep.json,{}summary.md}}",
        rows.len(),
        args.output.display(),
        if plotted { "sweep.png,sweep.svg," } else { "" }
    ));
    Ok(0)
}
