//! The gate's outcome as text and as JSON.

use super::gate::{Correction, Family, GateOptions, Outcome, RefMode};
use serde_json::{json, Value};

const CHANNELS: [&str; 3] = ["R", "G", "B"];

/// A JSON number, or "inf" / "-inf" / "nan" for non-finite values (as `diff --json`).
pub fn num(v: f64) -> Value {
    if v.is_finite() {
        json!(v)
    } else if v.is_nan() {
        json!("nan")
    } else if v > 0.0 {
        json!("inf")
    } else {
        json!("-inf")
    }
}

/// Short significant-digit formatting for reports.
pub fn g(v: f64) -> String {
    if v.is_nan() {
        "nan".into()
    } else if v.is_infinite() {
        if v > 0.0 { "inf" } else { "-inf" }.into()
    } else if v == 0.0 {
        "0".into()
    } else if v.abs() >= 1e-3 && v.abs() < 1e5 {
        let s = format!("{:.4}", v);
        let digits = 4i32 - 1 - v.abs().log10().floor() as i32;
        let s = if digits >= 0 { format!("{:.*}", digits as usize, v) } else { s };
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        format!("{:.3e}", v)
    }
}

pub fn mode_name(m: RefMode) -> &'static str {
    match m {
        RefMode::Welch => "welch",
        RefMode::Converged => "converged-reference",
        RefMode::SameEstimator => "same-estimator",
    }
}

fn describe(o: &Outcome, opts: &GateOptions) -> String {
    if o.noise_free {
        return "noise free: |d| <= abs + rel*|ref|".into();
    }
    match o.mode {
        RefMode::Welch => "Welch's t per value (both noisy)",
        RefMode::Converged => "z per value (converged reference)",
        RefMode::SameEstimator => "pooled two-sample t per value (same estimator)",
    }
    .to_string()
        + match opts.correction {
            Correction::Sidak => ", Sidak",
            Correction::Holm => ", Holm",
        }
}

fn at(o: &Outcome, i: usize) -> String {
    let px = i / 3;
    format!("({}, {}, {})", px % o.width, px / o.width, CHANNELS[i % 3])
}

fn family_json(f: &Family) -> Value {
    json!({
        "count": f.count,
        "rejected": f.rejected,
        "level": num(f.level),
        "alpha": num(f.alpha),
        "worst_p": f.worst.map(|(_, p)| num(p)),
        "failed": f.failed,
    })
}

pub fn text(o: &Outcome, opts: &GateOptions) -> String {
    let mut s = format!(
        "  {}x{}, {}; family-wise alpha {} (a third to each of values, blocks, whole image)\n",
        o.width,
        o.height,
        describe(o, opts),
        g(opts.alpha)
    );
    if opts.tolerance.abs > 0.0 || opts.tolerance.rel > 0.0 {
        s += &format!("  allowed difference: {} + {} * |ref|\n", g(opts.tolerance.abs), g(opts.tolerance.rel));
    }
    let v = &o.values;
    s += &format!(
        "  values: {} of {} rejected at p <= {} (allowed {} %); failing pixels {} of {}",
        v.rejected,
        v.count,
        g(v.level),
        g(100.0 * opts.fail_fraction),
        o.failing_pixels,
        o.width * o.height
    );
    if let Some((i, p)) = v.worst {
        s += &format!("; worst p {} at {} (t {})", g(p), at(o, i), g(o.t[i]));
    }
    s += "\n";
    if o.nonfinite > 0 {
        s += &format!("  non-finite values: {}\n", o.nonfinite);
    }
    let b = &o.blocks;
    s += &format!(
        "  blocks {}x{}: {} of {} rejected at p <= {}",
        opts.block,
        opts.block,
        b.rejected,
        b.count,
        g(b.level)
    );
    if let Some((i, p)) = b.worst {
        let t = &o.block_tests[i];
        let r = t.region;
        s += &format!(
            "; worst p {} at x {}..{}, y {}..{} {} ({:+.3} %)",
            g(p),
            r.x0,
            r.x1,
            r.y0,
            r.y1,
            r.channel.map_or("all", |c| CHANNELS[c]),
            100.0 * t.rel_error()
        );
    }
    s += "\n  mean bias (test - ref)/ref, 95 % CI:";
    for b in &o.bias {
        s += &format!(" {} {:+.3} % [{:+.3}, {:+.3}]", b.channel, 100.0 * b.rel, 100.0 * b.rel_lo, 100.0 * b.rel_hi);
    }
    s += &format!(
        "\n  whole image: {} of {} means rejected at p <= {}\n",
        o.whole.rejected,
        o.whole.count,
        g(o.whole.level)
    );
    for r in &o.reasons {
        s += &format!("  fails: {r}\n");
    }
    s
}

pub fn json(o: &Outcome, opts: &GateOptions) -> Value {
    json!({
        "width": o.width,
        "height": o.height,
        "mode": mode_name(o.mode),
        "noise_free": o.noise_free,
        "alpha": num(opts.alpha),
        "correction": match opts.correction { Correction::Sidak => "sidak", Correction::Holm => "holm" },
        "fail_percent": num(100.0 * opts.fail_fraction),
        "block": opts.block,
        "tolerance": { "abs": num(opts.tolerance.abs), "rel": num(opts.tolerance.rel) },
        "values": family_json(&o.values),
        "worst_value": o.values.worst.map(|(i, p)| json!({
            "x": (i / 3) % o.width, "y": (i / 3) / o.width, "channel": CHANNELS[i % 3], "p": num(p), "t": num(o.t[i]),
        })),
        "failing_pixels": o.failing_pixels,
        "nonfinite": o.nonfinite,
        "blocks": family_json(&o.blocks),
        "worst_block": o.blocks.worst.map(|(i, p)| {
            let t = &o.block_tests[i];
            json!({
                "x0": t.region.x0, "x1": t.region.x1, "y0": t.region.y0, "y1": t.region.y1,
                "channel": t.region.channel.map_or("all", |c| CHANNELS[c]),
                "p": num(p), "z": num(t.z), "rel_error": num(t.rel_error()),
            })
        }),
        "whole": family_json(&o.whole),
        "bias": o.bias.iter().map(|b| json!({
            "channel": b.channel,
            "test_mean": num(b.test_mean),
            "reference_mean": num(b.reference_mean),
            "rel": num(b.rel),
            "rel_ci95": [num(b.rel_lo), num(b.rel_hi)],
            "z": num(b.z),
            "p": num(b.p),
        })).collect::<Vec<_>>(),
        "status": if o.passed { "pass" } else { "fail" },
        "reasons": o.reasons,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formatting() {
        assert_eq!(g(0.0123456), "0.01235");
        assert_eq!(g(1.5), "1.5");
        assert_eq!(g(2.7e-7), "2.700e-7");
        assert_eq!(g(f64::INFINITY), "inf");
        assert_eq!(num(f64::NAN), json!("nan"));
    }
}
