//! The log-log plot of error versus time (SVG and PNG, drawn with plotters and an embedded font).

use super::args::Metric;
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
        chart
            .draw_series(pts.iter().map(|p| {
                EmptyElement::at((p.0, p.1))
                    + Text::new(p.2.to_string(), (5, -16), ("sans-serif", 11).into_font().color(&RGBColor(90, 90, 90)))
            }))
            .map_err(e)?;
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

/// Draws the plot as SVG text and as PNG bytes.
pub fn render_plots(title: &str, metric: Metric, series: &[Series]) -> Result<(String, Vec<u8>), String> {
    use plotters::prelude::*;
    plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
        .map_err(|_| "the embedded plot font is invalid".to_string())?;
    let mut svg = String::new();
    draw_chart(SVGBackend::with_string(&mut svg, PLOT_SIZE).into_drawing_area(), title, metric, series)?;
    let (w, h) = PLOT_SIZE;
    let mut rgb = vec![255u8; w as usize * h as usize * 3];
    draw_chart(BitMapBackend::with_buffer(&mut rgb, PLOT_SIZE).into_drawing_area(), title, metric, series)?;
    let png = image::encode_png_rgb8(w, h, &rgb, Path::new("sweep.png")).map_err(|e| e.to_string())?;
    Ok((svg, png))
}
