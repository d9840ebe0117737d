use super::cache::reference_key;
use super::plot::{render_plots, PLOT_SIZE};
use super::report::csv_text;
use super::row::{Metric, Row};
use super::schedule::Schedule;
use super::summary::*;
use penumbra_core::image;
use penumbra_core::scene::Crop;
use std::path::Path;
fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * b.abs().max(1.0)
}

#[test]
fn loglog_interpolation_hand_computed() {
    let p = positive_sorted(&[(16.0, 0.25), (1.0, 1.0), (4.0, 0.5)]);
    assert_eq!(p, vec![(1.0, 1.0), (4.0, 0.5), (16.0, 0.25)]);
    // Halfway between 1 and 4 in log x: sqrt(1 * 0.5).
    assert!(close(interp_loglog(&p, 2.0).unwrap(), 0.5f64.sqrt()));
    // Between 4 and 16 at 8: sqrt(0.5 * 0.25).
    assert!(close(interp_loglog(&p, 8.0).unwrap(), (0.125f64).sqrt()));
    // A quarter of the way from 4 to 16 in log x: 0.5 * (0.5)^(1/4).
    assert!(close(interp_loglog(&p, 4.0 * 4f64.powf(0.25)).unwrap(), 0.5 * 0.5f64.powf(0.25)));
    assert_eq!(interp_loglog(&p, 4.0), Some(0.5));
    assert_eq!(interp_loglog(&p, 16.0), Some(0.25));
    assert_eq!(interp_loglog(&p, 0.5), None);
    assert_eq!(interp_loglog(&p, 17.0), None);
    assert_eq!(interp_loglog(&[], 1.0), None);
    // Zero / NaN errors are dropped, not interpolated through.
    assert_eq!(positive_sorted(&[(1.0, 0.0), (2.0, f64::NAN), (3.0, 1.0)]), vec![(3.0, 1.0)]);
}

#[test]
fn time_to_reach_hand_computed() {
    let run = [(1.0, 1.0), (4.0, 0.5), (16.0, 0.25)];
    // 0.25·√2 is halfway (in log) between 0.5 and 0.25: time √(4·16) = 8.
    match time_to_reach(&run, 0.25 * 2f64.sqrt()) {
        Reach::At(t) => assert!(close(t, 8.0), "{t}"),
        other => panic!("{other:?}"),
    }
    // Exactly an error reached: that render's time.
    match time_to_reach(&run, 0.5) {
        Reach::At(t) => assert!(close(t, 4.0), "{t}"),
        other => panic!("{other:?}"),
    }
    assert_eq!(time_to_reach(&run, 2.0), Reach::AtFirst(1.0));
    assert_eq!(time_to_reach(&run, 0.1), Reach::NotReached);
    assert_eq!(time_to_reach(&run, 0.0), Reach::NotReached);
    // Non-monotone error: the first crossing counts. 0.6 between (1, 1) and (2, 0.5):
    // log t = log 2 · ln(0.6)/ln(0.5).
    let bumpy = [(1.0, 1.0), (2.0, 0.5), (4.0, 0.7), (8.0, 0.3)];
    match time_to_reach(&bumpy, 0.6) {
        Reach::At(t) => assert!(close(t, 2f64.powf(0.6f64.ln() / 0.5f64.ln())), "{t}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn slope_of_power_law() {
    let p: Vec<(f64, f64)> = [1.0, 2.0, 4.0, 8.0].iter().map(|&t: &f64| (t, 3.0 * t.powf(-0.5))).collect();
    assert!((loglog_slope(&p).unwrap() + 0.5).abs() < 1e-12);
    assert_eq!(loglog_slope(&p[..1]), None);
}

#[test]
fn doubling_schedule_stops_before_the_limit() {
    let mut s = Schedule::doubling(Some(10.0), 1 << 20);
    assert_eq!(s.next(), Some(1));
    // 0.5 s fixed + 1 s rendering.
    s.record(1, 1.0, 1.5);
    // Next: 0.5 + 2 = 2.5 s predicted; 1.5 + 2.5 = 4 <= 10.
    assert!(close(Schedule::predict(1, 1.0, 1.5, 2), 2.5));
    assert_eq!(s.next(), Some(2));
    s.record(2, 2.0, 2.5);
    // Spent 4; predicted 0.5 + 4 = 4.5; 8.5 <= 10.
    assert_eq!(s.next(), Some(4));
    s.record(4, 4.0, 4.5);
    // Spent 8.5; predicted 0.5 + 8 = 8.5; 17 > 10: stop.
    assert!(close(s.spent(), 8.5));
    assert_eq!(s.next(), None);
}

#[test]
fn doubling_schedule_caps_and_explicit_lists() {
    let mut s = Schedule::doubling(None, 5);
    let mut got = vec![];
    while let Some(b) = s.next() {
        got.push(b);
        s.record(b, 0.0, 0.0);
    }
    assert_eq!(got, vec![1, 2, 4]);
    // Explicit list without a limit: all of it.
    let mut s = Schedule::explicit(vec![1, 4, 16], None);
    let mut got = vec![];
    while let Some(b) = s.next() {
        got.push(b);
        s.record(b, 100.0, 100.0);
    }
    assert_eq!(got, vec![1, 4, 16]);
    // With a limit: stops when 16 spp would not fit (1 s at 4 spp -> 4 s predicted).
    let mut s = Schedule::explicit(vec![1, 4, 16], Some(5.0));
    s.record(1, 0.25, 0.25);
    assert_eq!(s.next(), Some(4));
    s.record(4, 1.0, 1.0);
    assert_eq!(s.next(), None);
    // A render that took more than asked (ltc's coverage floor: 1 asked, 16 taken): doubling
    // goes on from what was taken, an explicit list's next budget can be skipped.
    let mut s = Schedule::doubling(None, 64);
    assert_eq!(s.next(), Some(1));
    s.record(16, 1.0, 1.0);
    assert_eq!(s.next(), Some(32));
    let mut s = Schedule::explicit(vec![1, 4, 32], None);
    s.record(16, 1.0, 1.0);
    assert_eq!(s.next(), Some(4));
    s.skip();
    assert_eq!(s.next(), Some(32));
}

#[test]
fn reference_keys_differ_in_everything_that_determines_the_render() {
    let k = reference_key("scene", "directlighting", Some((32, 32)), None, 256, 1);
    assert_eq!(k, reference_key("scene", "directlighting", Some((32, 32)), None, 256, 1));
    assert_ne!(k, reference_key("scene", "directlighting", Some((32, 32)), None, 256, 2));
    assert_ne!(k, reference_key("scene", "directlighting", Some((32, 32)), None, 512, 1));
    assert_ne!(k, reference_key("scene", "directlighting", Some((64, 32)), None, 256, 1));
    assert_ne!(k, reference_key("scene", "directlighting", Some((32, 32)), Some(Crop::Pixels([0, 8, 0, 8])), 256, 1));
    assert_ne!(k, reference_key("scene2", "directlighting", Some((32, 32)), None, 256, 1));
    assert_ne!(k, reference_key("scene", "path", Some((32, 32)), None, 256, 1));
    assert_eq!(k.len(), 16);
}

fn row(name: &str, budget: u32, t: f64, e: f64) -> Row {
    Row {
        integrator: name.into(),
        budget,
        spp: budget,
        build_s: 0.0,
        render_s: t,
        total_s: t,
        mae: e,
        rmse: e,
        psnr: 0.0,
        max_err: e,
        relmse: e,
        smape: e,
        flip: None,
        nan_count: 0,
    }
}

#[test]
fn summary_equal_time_and_target() {
    let rows = vec![
        row("directlighting", 1, 1.0, 1.0),
        row("directlighting", 4, 4.0, 0.5),
        row("directlighting", 16, 16.0, 0.25),
        row("ambientocclusion", 1, 0.5, 2.0),
        row("ambientocclusion", 2, 2.0, 1.0),
    ];
    let names = vec!["directlighting".to_string(), "ambientocclusion".to_string()];
    let target = default_target(&rows, &names, Metric::Rmse);
    assert_eq!(target.as_ref().map(|t| t.0), Some(0.25));
    let md = summary_markdown(
        &rows,
        &SummaryInput {
            scene: "s.pbrt",
            reference: "ref.exr",
            metric: Metric::Rmse,
            budget_name: "samples per pixel",
            target,
            threads: 2,
            integrators: &names,
            stopped: None,
        },
    );
    // Equal time = 2 s (ambientocclusion's largest); directlighting there: sqrt(0.5) = 0.7071.
    assert!(md.contains("RMSE at 2.000 s"), "{md}");
    assert!(md.contains("| directlighting | 3 | 1-16 |"), "{md}");
    assert!(md.contains("| 0.7071 |"), "{md}");
    assert!(md.contains("not reached"), "{md}");
    // CSV: a header and one line per row, flip empty.
    let csv = csv_text(&rows);
    assert_eq!(csv.lines().count(), 6);
    assert!(csv.lines().nth(1).unwrap().starts_with("directlighting,1,0,1,1,1,1,0,1,1,1,,0"));
}

#[test]
fn plots_render() {
    let series = vec![
        ("directlighting".to_string(), vec![(0.01, 0.1, 1), (0.02, 0.07, 2), (0.04, 0.05, 4)]),
        ("ambientocclusion".to_string(), vec![(0.005, 0.3, 1)]),
    ];
    let (svg, png) = render_plots("test", Metric::Rmse, &series).unwrap();
    assert!(svg.starts_with("<svg") || svg.starts_with("<?xml"));
    assert!(svg.contains("directlighting"));
    let img = image::decode_png(&png, Path::new("p.png")).unwrap();
    assert_eq!((img.width, img.height), PLOT_SIZE);
    // Something other than the white background was drawn.
    assert!(img.data.iter().any(|&v| v < 0.5));
}
