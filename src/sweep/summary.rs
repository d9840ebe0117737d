//! Log-log error-versus-time curves and the Markdown summary of a sweep (error at equal
//! time, time to a target error, convergence slopes).

use super::row::{Metric, Row};
use penumbra_integrators::DIRECT_LIGHTING as REFERENCE_INTEGRATOR;
use std::fmt::Write as _;

/// Points `(x, y)` with positive, finite coordinates, sorted by `x`.
pub fn positive_sorted(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut p: Vec<(f64, f64)> =
        points.iter().copied().filter(|&(x, y)| x > 0.0 && y > 0.0 && x.is_finite() && y.is_finite()).collect();
    p.sort_by(|a, b| a.0.total_cmp(&b.0));
    p
}

/// `y` at `x` on the piecewise-linear curve through `points` in log-log space
/// (`points` as [`positive_sorted`] returns them); `None` outside their `x` range.
pub fn interp_loglog(points: &[(f64, f64)], x: f64) -> Option<f64> {
    if !(x > 0.0) || !x.is_finite() {
        return None;
    }
    let first = points.first()?;
    let last = points.last()?;
    if x < first.0 || x > last.0 {
        return None;
    }
    if let Some(p) = points.iter().find(|p| p.0 == x) {
        return Some(p.1);
    }
    let i = points.windows(2).position(|w| w[0].0 <= x && x <= w[1].0)?;
    let (a, b) = (points[i], points[i + 1]);
    let u = (x.ln() - a.0.ln()) / (b.0.ln() - a.0.ln());
    Some((a.1.ln() + u * (b.1.ln() - a.1.ln())).exp())
}

/// When a run reaches an error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reach {
    /// Already the first render (at this time) is at or below the error.
    AtFirst(f64),
    /// Log-log interpolation between the renders that bracket the error.
    At(f64),
    NotReached,
}

/// The time at which the run `points` (`(time, error)` in budget order) first
/// gets to `target`: log-time interpolated linearly in log-error between the
/// last render above the target and the first at or below it.
pub fn time_to_reach(points: &[(f64, f64)], target: f64) -> Reach {
    let ok = |&(t, e): &(f64, f64)| t > 0.0 && e > 0.0 && t.is_finite() && e.is_finite();
    let pts: Vec<(f64, f64)> = points.iter().copied().filter(ok).collect();
    if !(target > 0.0) || !target.is_finite() {
        return Reach::NotReached;
    }
    let Some(i) = pts.iter().position(|p| p.1 <= target) else {
        return Reach::NotReached;
    };
    if i == 0 {
        return Reach::AtFirst(pts[0].0);
    }
    let (a, b) = (pts[i - 1], pts[i]);
    let u = (target.ln() - a.1.ln()) / (b.1.ln() - a.1.ln());
    Reach::At((a.0.ln() + u * (b.0.ln() - a.0.ln())).exp())
}

/// Least-squares slope of log(y) against log(x) (≈ −0.5 for Monte Carlo noise); `None`
/// with fewer than two distinct `x`.
pub fn loglog_slope(points: &[(f64, f64)]) -> Option<f64> {
    let p = positive_sorted(points);
    if p.len() < 2 {
        return None;
    }
    let n = p.len() as f64;
    let mx = p.iter().map(|q| q.0.ln()).sum::<f64>() / n;
    let my = p.iter().map(|q| q.1.ln()).sum::<f64>() / n;
    let sxx: f64 = p.iter().map(|q| (q.0.ln() - mx).powi(2)).sum();
    let sxy: f64 = p.iter().map(|q| (q.0.ln() - mx) * (q.1.ln() - my)).sum();
    (sxx > 1e-12).then(|| sxy / sxx)
}

/// A number with about four significant digits (scientific outside [1e-3, 1e5)).
pub fn fmt_num(v: f64) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        format!("{v:.3e}")
    } else {
        let digits = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        format!("{v:.digits$}")
    }
}

/// Everything the summary needs besides the rows.
pub struct SummaryInput<'a> {
    pub scene: &'a str,
    pub reference: &'a str,
    pub metric: Metric,
    pub budget_name: &'a str,
    pub target: Option<(f64, String)>,
    pub threads: usize,
    pub integrators: &'a [String],
    /// Why the sweep stopped early, if it did.
    pub stopped: Option<&'a str>,
}

/// An integrator's `(time, error)` points and budgets, in budget order.
type Curve = (String, Vec<(f64, f64)>, Vec<u32>);

fn curves(rows: &[Row], names: &[String], metric: Metric) -> Vec<Curve> {
    names
        .iter()
        .map(|n| {
            let mine: Vec<&Row> = rows.iter().filter(|r| &r.integrator == n).collect();
            let pts = mine.iter().filter_map(|r| Some((r.total_s, metric.of(r)?))).collect();
            (n.clone(), pts, mine.iter().map(|r| r.budget).collect())
        })
        .collect()
}

/// The default target error: directlighting's error at its largest budget, else the
/// smallest error of the first integrator.
pub fn default_target(rows: &[Row], names: &[String], metric: Metric) -> Option<(f64, String)> {
    let valid = |e: &f64| *e > 0.0 && e.is_finite();
    if names.iter().any(|n| n == REFERENCE_INTEGRATOR) {
        if let Some(r) = rows.iter().filter(|r| r.integrator == REFERENCE_INTEGRATOR).max_by_key(|r| r.budget) {
            if let Some(e) = metric.of(r).filter(valid) {
                return Some((
                    e,
                    format!("the {} directlighting reaches at its largest budget, {}", metric.label(), r.budget),
                ));
            }
        }
    }
    let first = names.first()?;
    let e =
        rows.iter().filter(|r| &r.integrator == first).filter_map(|r| metric.of(r)).filter(valid).reduce(f64::min)?;
    Some((e, format!("the smallest {} {first} reached", metric.label())))
}

pub fn summary_markdown(rows: &[Row], s: &SummaryInput) -> String {
    let m = s.metric.label();
    let cs = curves(rows, s.integrators, s.metric);
    let sorted: Vec<Vec<(f64, f64)>> = cs.iter().map(|c| positive_sorted(&c.1)).collect();
    let equal_time = sorted
        .iter()
        .map(|p| p.last().map(|q| q.0))
        .collect::<Option<Vec<f64>>>()
        .and_then(|v| v.into_iter().reduce(f64::min));
    let mut out = String::new();
    let _ = writeln!(out, "# penumbra sweep: {}\n", s.scene);
    let _ = writeln!(out, "Reference: {}. Error: {m} of R, G, B against it. Budget: {}.\n", s.reference, s.budget_name);
    if let Some(why) = s.stopped {
        let _ = writeln!(out, "**The sweep stopped early ({why}): only the renders that finished are included.**\n");
    }
    let eq_head = match equal_time {
        Some(t) => format!("{m} at {} s", fmt_num(t)),
        None => format!("{m} at equal time"),
    };
    let target_head = match &s.target {
        Some((e, _)) => format!("time to {m} {}", fmt_num(*e)),
        None => "time to target".into(),
    };
    let _ = writeln!(
        out,
        "| integrator | renders | budgets | time range (s) | final {m} | {eq_head} | {target_head} | log-log slope |"
    );
    let _ = writeln!(out, "|---|---:|---|---|---:|---:|---:|---:|");
    for ((name, pts, budgets), sp) in cs.iter().zip(&sorted) {
        let budgets_txt = match (budgets.first(), budgets.last()) {
            (Some(a), Some(b)) if a != b => format!("{a}-{b}"),
            (Some(a), _) => a.to_string(),
            _ => "-".into(),
        };
        let range = match (sp.first(), sp.last()) {
            (Some(a), Some(b)) => format!("{}-{}", fmt_num(a.0), fmt_num(b.0)),
            _ => "-".into(),
        };
        let last = pts.last().map(|p| fmt_num(p.1)).unwrap_or_else(|| "-".into());
        let at_eq = match equal_time {
            Some(t) => match interp_loglog(sp, t) {
                Some(e) => fmt_num(e),
                None => format!("n/a (first render took {} s)", sp.first().map(|p| fmt_num(p.0)).unwrap_or_default()),
            },
            None => "-".into(),
        };
        let reach = match &s.target {
            Some(_) if pts.is_empty() => "-".into(),
            Some((e, _)) => match time_to_reach(pts, *e) {
                Reach::AtFirst(t) => format!("<= {} s (first render)", fmt_num(t)),
                Reach::At(t) => format!("{} s", fmt_num(t)),
                Reach::NotReached => "not reached".into(),
            },
            None => "-".into(),
        };
        let slope = loglog_slope(pts).map(|v| format!("{v:.2}")).unwrap_or_else(|| "-".into());
        let _ = writeln!(
            out,
            "| {name} | {} | {budgets_txt} | {range} | {last} | {at_eq} | {reach} | {slope} |",
            budgets.len()
        );
    }
    let _ = writeln!(out, "\nNotes:");
    if let Some(t) = equal_time {
        let _ = writeln!(
            out,
            "- Equal time: each integrator's log({m})-log(time) curve is interpolated linearly at {} s, the largest total time every integrator reached.",
            fmt_num(t)
        );
    }
    if let Some((e, why)) = &s.target {
        let _ = writeln!(
            out,
            "- Target {m} {} ({why}): the time is interpolated in log-log between the last render above it and the first at or below it; \"not reached\" if no render got there.",
            fmt_num(*e)
        );
    }
    let _ = writeln!(
        out,
        "- Times are wall-clock seconds of scene build + render per budget on {} threads (parsing excluded); the slope is the least-squares fit of log({m}) against log(time) (-0.5 for plain Monte Carlo noise).",
        s.threads
    );
    out
}
