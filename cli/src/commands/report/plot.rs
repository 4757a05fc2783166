//! `kage report`'s plots: relative RMSE against a cost (shade time per frame, or rays cast),
//! log–log, one series per method whose points are labelled with their configuration; drawn
//! with plotters as PNG and SVG. Text uses the Ubuntu Light face egui ships
//! (`epaint_default_fonts`), since machines without system fonts must draw it too.

use super::Row;
use anyhow::{Result, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};
use std::path::Path;
use std::sync::OnceLock;

/// A plot's horizontal axis: what it reads from a row, and how it is labelled.
pub struct Axis {
    /// The axis description.
    pub label: &'static str,
    /// The row's value on this axis (rows without one are left out).
    pub value: fn(&Row) -> Option<f64>,
}

/// Shade time per frame.
pub const SHADE_TIME: Axis = Axis { label: "shade time per frame (s)", value: |r| Some(r.shade_s) };

/// Rays cast (the indirect rows).
pub const RAYS: Axis = Axis { label: "rays cast", value: |r| r.rays.map(|n| n as f64) };

/// Each method's colour, in legend order.
pub const METHODS: [(&str, [u8; 3]); 12] = [
    ("bspvt", [220, 50, 40]),
    ("ltc-exact-vis", [40, 120, 220]),
    ("ltc-unshadowed", [120, 120, 120]),
    ("monte-carlo", [40, 170, 70]),
    ("ratio-estimator", [200, 140, 0]),
    ("prt", [150, 40, 180]),
    ("prt-self", [0, 170, 170]),
    ("indirect-gather", [90, 60, 20]),
    ("hsh-cache", [230, 100, 180]),
    ("hsh-cache-no-gradients", [160, 160, 40]),
    ("hsh-cache-numerical-gradients", [60, 200, 120]),
    ("hsh-cache-wide-blend", [100, 100, 230]),
];

/// Plot size in pixels.
pub const SIZE: (u32, u32) = (960, 600);

/// One method's points: (cost, relative RMSE, configuration), by increasing cost.
struct Series {
    method: &'static str,
    colour: RGBColor,
    points: Vec<(f64, f64, String)>,
}

/// Writes `STEM.png` and `STEM.svg` into `dir`.
pub fn write(dir: &Path, stem: &str, title: &str, rows: &[Row], axis: &Axis) -> Result<()> {
    fonts()?;
    let series = series(rows, axis);
    let (w, h) = SIZE;
    let mut pixels = vec![0u8; (w * h * 3) as usize];
    draw(BitMapBackend::with_buffer(&mut pixels, SIZE).into_drawing_area(), title, &series, axis)?;
    let png = dir.join(format!("{stem}.png"));
    let image = image::RgbImage::from_raw(w, h, pixels).ok_or_else(|| anyhow!("plot buffer size"))?;
    image.save(&png).map_err(|e| anyhow!("writing {}: {e}", png.display()))?;
    let svg = dir.join(format!("{stem}.svg"));
    draw(SVGBackend::new(&svg, SIZE).into_drawing_area(), title, &series, axis)
        .map_err(|e| anyhow!("writing {}: {e}", svg.display()))
}

/// Registers the plots' font once per process.
fn fonts() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED
        .get_or_init(|| register_font("sans-serif", FontStyle::Normal, epaint_default_fonts::UBUNTU_LIGHT).is_ok());
    ok.then_some(()).ok_or_else(|| anyhow!("the plot font does not load"))
}

fn series(rows: &[Row], axis: &Axis) -> Vec<Series> {
    METHODS
        .iter()
        .map(|&(method, [r, g, b])| {
            let mut points: Vec<(f64, f64, String)> = rows
                .iter()
                .filter(|row| row.method == method)
                .filter_map(|row| Some(((axis.value)(row)?.max(1e-6), row.rel_rmse.max(1e-5), row.config.clone())))
                .collect();
            points.sort_by(|p, q| p.0.total_cmp(&q.0));
            Series { method, colour: RGBColor(r, g, b), points }
        })
        .filter(|s| !s.points.is_empty())
        .collect()
}

/// The data's bounds, widened so that no point sits on the frame.
fn bounds(series: &[Series]) -> ((f64, f64), (f64, f64)) {
    let all = || series.iter().flat_map(|s| &s.points);
    let span = |v: Vec<f64>| {
        let (lo, hi) = v.iter().fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(*x), b.max(*x)));
        (lo / 1.6, hi * 1.6)
    };
    let (x, y) = (span(all().map(|p| p.0).collect()), span(all().map(|p| p.1).collect()));
    // Room on the right for the last point's configuration label.
    ((x.0, x.1 * 4.0), y)
}

/// A tick value with three significant digits and no trailing zeros (0.3, 0.0125, 120000).
fn tick(v: &f64) -> String {
    let decimals = (2 - v.abs().max(1e-12).log10().floor() as i32).max(0) as usize;
    let text = format!("{v:.decimals$}");
    if text.contains('.') { text.trim_end_matches('0').trim_end_matches('.').to_string() } else { text }
}

fn draw<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, title: &str, series: &[Series], axis: &Axis) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |err: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("drawing the plot: {err}");
    root.fill(&WHITE).map_err(e)?;
    let ((x0, x1), (y0, y1)) = bounds(series);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(14)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc(axis.label)
        .y_desc("relative RMSE against the reference")
        .x_label_formatter(&tick)
        .y_label_formatter(&tick)
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 16))
        .draw()
        .map_err(e)?;
    for s in series {
        let colour = s.colour;
        chart
            .draw_series(LineSeries::new(s.points.iter().map(|p| (p.0, p.1)), colour.stroke_width(2)))
            .map_err(e)?
            .label(s.method)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(3)));
        let label = ("sans-serif", 11).into_font().color(&colour);
        chart
            .draw_series(s.points.iter().map(|(x, y, config)| {
                EmptyElement::at((*x, *y))
                    + Circle::new((0, 0), 4, colour.filled())
                    + Text::new(config.clone(), (6, -14), label.clone())
            }))
            .map_err(e)?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(e)?;
    root.present().map_err(e)
}

#[cfg(test)]
mod tests {
    #[test]
    fn ticks_have_three_significant_digits_and_no_trailing_zeros() {
        let ticks: Vec<String> =
            [0.3, 0.30000000000000004, 0.0125, 1.0, 120_000.0, 0.001].iter().map(super::tick).collect();
        assert_eq!(ticks, ["0.3", "0.3", "0.0125", "1", "120000", "0.001"]);
    }
}
