//! The speed-against-error plot: a log-log PNG, one panel per scene, time on x and pointwise
//! relative L2 error on y, one colour per method with its Pareto-optimal rows joined, the 1 %, 2 % and
//! 5 % targets dashed and the band below the reference's resolution shaded (plotters, bitmap
//! backend, DejaVu Sans shipped with the crate).

use super::envelope::pareto;
use super::{BenchError, BenchReport, Row, SceneSummary, TARGETS};
use std::path::Path;

/// A time axis label: two decimals, or as many as a tick below 0.01 s needs to show one
/// significant digit (0.001 s read "0.00").
fn time_tick(x: f64) -> String {
    let decimals = if x > 0.0 && x < 0.01 { (-x.log10()).ceil() as usize } else { 2 };
    format!("{x:.decimals$}")
}

/// DejaVu Sans (Bitstream Vera licence, assets/fonts/LICENSE-DejaVu.txt), registered with plotters.
static FONT: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");

pub(crate) fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // Registering fails only for a malformed font, and this one is shipped with the crate.
        let _ = plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, FONT);
    });
}

/// Log-log PNG: time on x, relative L2 error on y, one panel per scene, one curve (colour) per
/// method, Pareto-optimal points of each method joined by a line, the 1 %, 2 % and 5 % levels dashed.
pub fn plot_png(report: &BenchReport, path: &Path) -> Result<(), BenchError> {
    use plotters::prelude::*;
    register_font();
    let n = report.scenes.len().max(1);
    let cols = n.min(2);
    let rows_n = n.div_ceil(cols);
    let (pw, ph) = (640u32, 460u32);
    let (w, h) = (pw * cols as u32, ph * rows_n as u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    let err = |e: &dyn std::fmt::Display| BenchError::Output(format!("plot {}: {e}", path.display()));
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let panels = root.split_evenly((rows_n, cols));
        for (sc, area) in report.scenes.iter().zip(panels) {
            draw_panel(report, sc, &area).map_err(|e| err(&e))?;
        }
        root.present().map_err(|e| err(&e))?;
    }
    write_png_rgb(path, w, h, &buf)
}

/// One scene's panel of [`plot_png`]: its rows that ran with an error above 0, each method's
/// points and Pareto front, the targets dashed, the band below the reference's resolution shaded.
fn draw_panel(
    report: &BenchReport,
    sc: &SceneSummary,
    area: &plotters::drawing::DrawingArea<plotters::prelude::BitMapBackend<'_>, plotters::coord::Shift>,
) -> Result<(), String> {
    use plotters::prelude::*;
    let colours = [
        ("uniform", RGBColor(31, 119, 180)),
        ("progressive", RGBColor(255, 127, 14)),
        ("hierarchical", RGBColor(44, 160, 44)),
    ];
    let pts: Vec<&Row> = report
        .rows
        .iter()
        .filter(|r| r.scene == sc.scene && r.status == "ok" && r.rel_l2_debiased > 0.0)
        .collect();
    let (mut t0, mut t1, mut e0, mut e1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
    for r in &pts {
        t0 = t0.min(r.time_s);
        t1 = t1.max(r.time_s);
        e0 = e0.min(r.error());
        e1 = e1.max(r.error());
    }
    if pts.is_empty() {
        (t0, t1, e0, e1) = (1e-3, 1.0, 1e-3, 1.0);
    }
    let (t0, t1) = (t0.max(1e-6) / 1.5, t1.max(1e-6) * 1.5);
    let (e0, e1) = ((e0.min(0.01) / 1.5).max(1e-6), (e1.max(0.05) * 1.5).min(100.0));
    let mut chart = ChartBuilder::on(area)
        .caption(sc.scene.trim_start_matches("builtin:"), ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d((t0..t1).log_scale(), (e0..e1).log_scale())
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc("pointwise relative L2 error")
        .light_line_style(WHITE.mix(0.0))
        .y_label_formatter(&|y| format!("{:.2}%", 100.0 * y))
        .x_label_formatter(&|x| time_tick(*x))
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(|e| e.to_string())?;
    if sc.resolution.is_finite() && sc.resolution > e0 {
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(t0, e0), (t1, sc.resolution)],
                BLACK.mix(0.08).filled(),
            )))
            .map_err(|e| e.to_string())?
            .label("below reference resolution")
            .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], BLACK.mix(0.15).filled()));
    }
    for target in TARGETS {
        chart
            .draw_series(DashedLineSeries::new(
                [(t0, target), (t1, target)],
                6,
                4,
                BLACK.mix(0.4).stroke_width(1),
            ))
            .map_err(|e| e.to_string())?;
    }
    for (m, col) in colours {
        let mine: Vec<(f64, f64)> =
            pts.iter().filter(|r| r.method == m).map(|r| (r.time_s, r.error())).collect();
        if mine.is_empty() {
            continue;
        }
        chart
            .draw_series(mine.iter().map(|&p| Circle::new(p, 4, col.mix(0.5).filled())))
            .map_err(|e| e.to_string())?
            .label(m)
            .legend(move |(x, y)| Circle::new((x + 10, y), 4, col.filled()));
        let front = pareto(&mine);
        chart.draw_series(LineSeries::new(front.clone(), col.stroke_width(2))).map_err(|e| e.to_string())?;
        chart
            .draw_series(front.iter().map(|&p| Circle::new(p, 5, col.stroke_width(2))))
            .map_err(|e| e.to_string())?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.3))
        .label_font(("sans-serif", 14))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| e.to_string())?;
    Ok(())
}

pub(crate) fn write_png_rgb(path: &Path, w: u32, h: u32, rgb: &[u8]) -> Result<(), BenchError> {
    let err = |e: &dyn std::fmt::Display| BenchError::Output(format!("{}: {e}", path.display()));
    let file = std::fs::File::create(path).map_err(|e| err(&e))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut wr = enc.write_header().map_err(|e| err(&e))?;
    wr.write_image_data(rgb).map_err(|e| err(&e))?;
    wr.finish().map_err(|e| err(&e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_ticks_show_a_significant_digit() {
        assert_eq!(time_tick(0.001), "0.001");
        assert_eq!(time_tick(0.0001), "0.0001");
        assert_eq!(time_tick(0.01), "0.01");
        assert_eq!(time_tick(0.1), "0.10");
        assert_eq!(time_tick(10.0), "10.00");
    }
}
