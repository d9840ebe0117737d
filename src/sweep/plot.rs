//! The log-log plot of error versus time (SVG and PNG, drawn with plotters and an embedded font).

use super::row::Metric;
use penumbra_core::image;
use std::path::Path;

static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans-ascii.ttf");

const COLOURS: [(u8, u8, u8); 8] = [
    (31, 119, 180),
    (214, 39, 40),
    (44, 160, 44),
    (255, 127, 14),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (23, 190, 207),
];

/// One plotted line: the integrator and its renders' (time, error, budget).
pub type Series = (String, Vec<(f64, f64, u32)>);

pub const PLOT_SIZE: (u32, u32) = (800, 560);

fn tick(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e4).contains(&a) {
        format!("{v:.0e}")
    } else {
        let s = format!("{v:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    }
}

fn draw_chart<DB: plotters::prelude::DrawingBackend>(
    root: plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    metric: Metric,
    series: &[Series],
) -> Result<(), String> {
    use plotters::prelude::*;
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let all = series.iter().flat_map(|s| s.1.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
    for &(x, y, _) in all {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if !(x0 <= x1 && y0 <= y1) {
        return Err("nothing to plot".into());
    }
    let pad = |lo: f64, hi: f64| {
        let r = (hi / lo).max(1.0).ln();
        let m = (0.08 * r).max(0.15);
        (lo * (-m).exp(), hi * m.exp())
    };
    let (x0, x1) = pad(x0, x1);
    let (y0, y1) = pad(y0, y1);
    root.fill(&WHITE).map_err(e)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(14)
        .x_label_area_size(48)
        .y_label_area_size(70)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("total time: build + render (s)")
        .y_desc(format!("{} vs reference", metric.label()))
        .x_labels(8)
        .y_labels(8)
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| tick(*v))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(205, 205, 205))
        .draw()
        .map_err(e)?;
    for (i, (name, pts)) in series.iter().enumerate() {
        let (r, g, b) = COLOURS[i % COLOURS.len()];
        let colour = RGBColor(r, g, b);
        chart
            .draw_series(LineSeries::new(pts.iter().map(|p| (p.0, p.1)), colour.stroke_width(2)))
            .map_err(e)?
            .label(name.as_str())
            .legend(move |(x, y)| {
                EmptyElement::at((x, y))
                    + PathElement::new(vec![(0, 0), (22, 0)], colour.stroke_width(2))
                    + Circle::new((11, 0), 4, colour.filled())
            });
        chart.draw_series(pts.iter().map(|p| Circle::new((p.0, p.1), 4, colour.filled()))).map_err(e)?;
    }
    // Budget labels: placed beside their points where they overlap nothing already placed.
    let anchors: Vec<((i32, i32), String)> =
        series.iter().flat_map(|s| s.1.iter()).map(|p| (chart.backend_coord(&(p.0, p.1)), p.2.to_string())).collect();
    let boxes: Vec<(i32, i32)> = anchors.iter().map(|(_, t)| label_size(t)).collect();
    let points: Vec<(i32, i32)> = anchors.iter().map(|a| a.0).collect();
    let font = ("sans-serif", LABEL_FONT_PX).into_font().color(&RGBColor(90, 90, 90));
    for (i, at) in place_labels(&points, &boxes, root.dim_in_pixel()).into_iter().enumerate() {
        if let Some(at) = at {
            root.draw(&Text::new(anchors[i].1.clone(), at, font.clone())).map_err(e)?;
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerLeft)
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.4))
        .draw()
        .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}

const LABEL_FONT_PX: u32 = 11;
/// The radius of a plotted point's marker, in pixels.
const MARKER_PX: i32 = 4;

/// A budget label's box in pixels (the embedded font's digits are about 0.6 em wide).
fn label_size(text: &str) -> (i32, i32) {
    ((text.len() as f64 * 0.6 * LABEL_FONT_PX as f64).ceil() as i32, LABEL_FONT_PX as i32 + 2)
}

/// Places one label per point: the first of eight positions around its point (above right
/// first) whose box stays inside `area` and overlaps neither a label placed before it nor any
/// point's marker. A label that fits nowhere is left out (its budget is in the CSV), so labels
/// never overlap each other. Returns each label's top-left corner.
fn place_labels(points: &[(i32, i32)], sizes: &[(i32, i32)], area: (u32, u32)) -> Vec<Option<(i32, i32)>> {
    type Rect = (i32, i32, i32, i32);
    let overlaps = |a: Rect, b: Rect| a.0 < b.2 && b.0 < a.2 && a.1 < b.3 && b.1 < a.3;
    let markers: Vec<Rect> =
        points.iter().map(|&(x, y)| (x - MARKER_PX, y - MARKER_PX, x + MARKER_PX + 1, y + MARKER_PX + 1)).collect();
    let mut placed: Vec<Rect> = Vec::new();
    let gap = MARKER_PX + 2;
    points
        .iter()
        .zip(sizes)
        .map(|(&(x, y), &(w, h))| {
            let candidates = [
                (x + gap, y - gap - h),
                (x + gap, y + gap),
                (x - gap - w, y - gap - h),
                (x - gap - w, y + gap),
                (x + gap, y - h / 2),
                (x - gap - w, y - h / 2),
                (x - w / 2, y - gap - h),
                (x - w / 2, y + gap),
            ];
            let fits = |&(cx, cy): &(i32, i32)| {
                let r = (cx, cy, cx + w, cy + h);
                cx >= 0
                    && cy >= 0
                    && r.2 <= area.0 as i32
                    && r.3 <= area.1 as i32
                    && !placed.iter().chain(&markers).any(|&o| overlaps(r, o))
            };
            let at = candidates.iter().copied().find(|c| fits(c))?;
            placed.push((at.0, at.1, at.0 + w, at.1 + h));
            Some(at)
        })
        .collect()
}

/// Registers the embedded font as plotters' "sans-serif" (for every drawing of the application).
pub fn register_font() -> Result<(), String> {
    plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, FONT)
        .map_err(|_| "the embedded plot font is invalid".to_string())
}

/// Draws the plot as SVG text and as PNG bytes.
pub fn render_plots(title: &str, metric: Metric, series: &[Series]) -> Result<(String, Vec<u8>), String> {
    use plotters::prelude::*;
    register_font()?;
    let mut svg = String::new();
    draw_chart(SVGBackend::with_string(&mut svg, PLOT_SIZE).into_drawing_area(), title, metric, series)?;
    let (w, h) = PLOT_SIZE;
    let mut rgb = vec![255u8; w as usize * h as usize * 3];
    draw_chart(BitMapBackend::with_buffer(&mut rgb, PLOT_SIZE).into_drawing_area(), title, metric, series)?;
    let png = image::encode_png_rgb8(w, h, &rgb, Path::new("sweep.png")).map_err(|e| e.to_string())?;
    Ok((svg, png))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_of_coincident_and_close_points_never_overlap() {
        // Two integrators at the same budgets, one point nearly on top of the other's,
        // in a cluster (what made the labels overlap before).
        let mut points = Vec::new();
        for i in 0..6 {
            points.push((100 + 9 * i, 200 - 7 * i));
            points.push((102 + 9 * i, 201 - 7 * i));
        }
        let texts: Vec<String> = (0..points.len()).map(|i| (1u32 << (i / 2)).to_string()).collect();
        let sizes: Vec<(i32, i32)> = texts.iter().map(|t| label_size(t)).collect();
        let at = place_labels(&points, &sizes, PLOT_SIZE);
        let rects: Vec<_> =
            at.iter().zip(&sizes).filter_map(|(a, s)| a.map(|(x, y)| (x, y, x + s.0, y + s.1))).collect();
        assert!(rects.len() >= points.len() / 2, "too many labels left out: {} of {}", rects.len(), points.len());
        for (i, a) in rects.iter().enumerate() {
            for b in &rects[i + 1..] {
                assert!(!(a.0 < b.2 && b.0 < a.2 && a.1 < b.3 && b.1 < a.3), "{a:?} overlaps {b:?}");
            }
        }
        // An isolated point gets its label above and to the right.
        assert_eq!(place_labels(&[(400, 300)], &[(12, 13)], PLOT_SIZE), vec![Some((406, 281))]);
    }
}
