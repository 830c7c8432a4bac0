//! The convergence plots under the inspector: the residual per gather of the solution shown,
//! the runs of the history overlaid (links against elements with the n and n² guides, error
//! against solver time), and the error against the reference (or the closed form) since the
//! last cold start. A warm re-solve (a threshold made finer, the solver's state kept) goes on
//! from the last solve: its gathers and its error follow the last solve's in the same plots, and
//! a dashed line marks where each began.
//!
//! The plots share the column's height left below the inspector (each between
//! [`PLOT_H_MIN`] and [`PLOT_H_MAX`]), so that at 1280 × 800 they fit unscrolled while no picked
//! element's link table takes the column.
//!
//! The inspector column is narrow, so a legend never sits on a plot: each plot that has one
//! draws it below, one entry per line (a swatch in the series' colour and its whole name,
//! wrapped rather than cut).

use super::history::{Ruler, RunHistory, Series};
use super::view::View;
use super::worker::ViewData;
use eframe::egui::{self, Color32, Rect, Vec2};
use egui_plot::{Line, LineStyle, Plot, PlotPoints, PlotUi, Points, VLine};

/// Height of each plot, points: the column's height left, shared, within these bounds.
pub const PLOT_H_MIN: f32 = 90.0;
pub const PLOT_H_MAX: f32 = 150.0;

/// Colours of the run series, in order (repeated past the last): distinct on the dark theme,
/// none of them the guides' grey.
const SERIES_COLORS: [Color32; 6] = [
    Color32::from_rgb(100, 160, 255),
    Color32::from_rgb(255, 140, 60),
    Color32::from_rgb(90, 200, 120),
    Color32::from_rgb(230, 90, 160),
    Color32::from_rgb(230, 210, 80),
    Color32::from_rgb(160, 120, 240),
];
/// The n and n² guides: dashed, grey and muted red.
const GUIDE_N: Color32 = Color32::from_gray(170);
const GUIDE_N2: Color32 = Color32::from_rgb(190, 110, 110);
/// The single-series plots (residual, error since the restart).
const SINGLE: Color32 = Color32::from_rgb(255, 120, 100);
/// Where a warm re-solve began: dashed, light blue.
const MARK: Color32 = Color32::from_rgb(140, 200, 255);
/// Thresholds named in the marks' legend entry (the newest).
const MARKS_NAMED: usize = 3;

/// Where a warm re-solve began: after `gathers` gathers of the solution it went on from, at
/// solver time `time_s`, to refine to `threshold` ("BFeps 1.0e-3").
#[derive(Clone, Debug, PartialEq)]
pub struct ResolveMark {
    pub gathers: usize,
    pub time_s: f64,
    pub threshold: String,
}

/// The plots (shown under the inspector while open).
#[derive(Clone, Debug, Default)]
pub struct Plots {
    pub open: bool,
    /// Where the last frame drew each plot, and its legend below it when it has one.
    layout: Vec<PlotLayout>,
    /// Height the last frame took besides the plots themselves (titles, legends), points.
    besides: Option<f32>,
}

/// Where a plot and its legend were drawn (screen points).
#[derive(Clone, Debug, PartialEq)]
pub struct PlotLayout {
    /// The plot's id ("residual", "links_vs_elements", …).
    pub id: &'static str,
    pub plot: Rect,
    pub legend: Option<Rect>,
}

impl Plots {
    /// The plots, open or not.
    #[must_use]
    pub fn new(open: bool) -> Plots {
        Plots { open, layout: Vec::new(), besides: None }
    }

    /// Where the last frame drew the plots and their legends.
    #[must_use]
    pub fn layout(&self) -> &[PlotLayout] {
        &self.layout
    }
}

/// What the plots are lent for one frame.
pub struct PlotsInput<'a> {
    /// The solution shown (its residuals).
    pub view: &'a ViewData,
    pub history: &'a RunHistory,
    /// (solver time, rel L2 error against the reference) since the last restart.
    pub error_samples: &'a [[f64; 2]],
    /// Where each warm re-solve since the last cold start began.
    pub marks: &'a [ResolveMark],
    /// What the error samples are measured against.
    pub ruler: Ruler,
}

/// One legend entry: the colour, whether the series is a dashed guide, and the name.
type Entry = (Color32, bool, String);

impl View for Plots {
    type Input<'a> = PlotsInput<'a>;
    type Action = ();

    fn ui(&mut self, ui: &mut egui::Ui, input: PlotsInput<'_>) -> Option<()> {
        let PlotsInput { view, history, error_samples, marks, ruler } = input;
        self.layout.clear();
        let top = ui.cursor().top();
        let n_plots = if error_samples.is_empty() { 3.0 } else { 4.0 };
        let room = ui.clip_rect().bottom() - top;
        let plot_h = ((room - self.besides.unwrap_or(170.0)) / n_plots).clamp(PLOT_H_MIN, PLOT_H_MAX);
        let mark_names = || {
            let from = marks.len().saturating_sub(MARKS_NAMED);
            let named: Vec<&str> = marks[from..].iter().map(|m| m.threshold.as_str()).collect();
            let more = if from > 0 { "…, " } else { "" };
            (MARK, true, format!("a warm re-solve begins ({more}{})", named.join(", ")))
        };
        let mark_lines = |p: &mut PlotUi<'_>, x: &dyn Fn(&ResolveMark) -> f64| {
            for (i, m) in marks.iter().enumerate() {
                let name = format!("warm re-solve {}: {}", i + 1, m.threshold);
                p.vline(VLine::new(name, x(m)).color(MARK).style(LineStyle::dashed_dense()));
            }
        };

        ui.label("Residual per gather (log₁₀)").on_hover_text(super::status_bar::RESIDUAL_TIP);
        // One point per gather (every step's, a solve's too), joined by a line; a warm re-solve's
        // gathers follow the solve it went on from.
        let res: Vec<[f64; 2]> = view
            .residuals
            .iter()
            .enumerate()
            .filter(|(_, r)| **r > 0.0)
            .map(|(i, r)| [i as f64 + 1.0, r.log10()])
            .collect();
        let plot = Plot::new("residual")
            .height(plot_h)
            .x_axis_label("gather")
            // Short: the label runs along the plot's height, which may be the smallest.
            .y_axis_label("log₁₀ r")
            .show(ui, |p| {
                p.line(Line::new("residual", PlotPoints::from(res.clone())).color(SINGLE));
                p.points(Points::new("gathers", PlotPoints::from(res)).radius(3.0).color(SINGLE));
                // Between the last gather before the re-solve and its first.
                mark_lines(p, &|m| m.gathers as f64 + 0.5);
            })
            .response
            .rect;
        let legend = (!marks.is_empty()).then(|| draw_legend(ui, "residual", &[mark_names()]));
        self.layout.push(PlotLayout { id: "residual", plot, legend });

        ui.label("Links against elements, runs in this window (log₁₀)");
        let links = history.links_series();
        let (lo, hi) = links
            .iter()
            .flat_map(|s| &s.points)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p[0]), b.max(p[0])));
        let (lo, hi) = if lo.is_finite() { (lo - 0.5, hi + 0.5) } else { (1.0, 5.0) };
        let mut entries = series_entries(&links);
        entries.push((GUIDE_N, true, "n".to_owned()));
        entries.push((GUIDE_N2, true, "n²".to_owned()));
        let plot = Plot::new("links_vs_elements")
            .height(plot_h)
            .x_axis_label("log₁₀ elements")
            .y_axis_label("log₁₀ links")
            .show(ui, |p| {
                overlay(p, links);
                let guide = |name: &str, color, pts: Vec<[f64; 2]>| {
                    Line::new(name, PlotPoints::from(pts)).color(color).style(LineStyle::dashed_loose())
                };
                p.line(guide("n", GUIDE_N, vec![[lo, lo], [hi, hi]]));
                p.line(guide("n²", GUIDE_N2, vec![[lo, 2.0 * lo], [hi, 2.0 * hi]]));
            })
            .response
            .rect;
        let legend = draw_legend(ui, "links_vs_elements", &entries);
        self.layout.push(PlotLayout { id: "links_vs_elements", plot, legend: Some(legend) });

        ui.label("Error against solver time, runs in this window (log₁₀)").on_hover_text(
            "Pointwise relative L2 error against the reference (its noise taken out), or against \
             the closed form on a single-bounce scene, each series named so; without either, the \
             solver's own estimate (series marked \"estimate\"); one point per solve",
        );
        let series = history.error_series();
        let entries = series_entries(&series);
        let plot = Plot::new("runs_error_vs_time")
            .height(plot_h)
            .x_axis_label("solver time (s)")
            .y_axis_label("log₁₀ error")
            .show(ui, |p| overlay(p, series))
            .response
            .rect;
        let legend = draw_legend(ui, "runs_error_vs_time", &entries);
        self.layout.push(PlotLayout { id: "runs_error_vs_time", plot, legend: Some(legend) });

        if error_samples.is_empty() {
            ui.weak("Error against time appears when a reference solution is loaded.");
        } else {
            ui.label(format!(
                "Error against {} (pointwise rel L2, log₁₀) vs solver time since the last cold start",
                ruler.the()
            ));
            let pts: Vec<[f64; 2]> =
                error_samples.iter().filter(|p| p[1] > 0.0).map(|p| [p[0], p[1].log10()]).collect();
            let plot = Plot::new("error_vs_time")
                .height(plot_h)
                .x_axis_label("solver time (s)")
                .y_axis_label("log₁₀ error")
                .show(ui, |p| {
                    p.line(Line::new("error", PlotPoints::from(pts.clone())).color(SINGLE).allow_band(false));
                    p.points(Points::new("steps", PlotPoints::from(pts)).color(SINGLE).radius(3.0));
                    mark_lines(p, &|m| m.time_s);
                })
                .response
                .rect;
            let legend = (!marks.is_empty()).then(|| draw_legend(ui, "error_vs_time", &[mark_names()]));
            self.layout.push(PlotLayout { id: "error_vs_time", plot, legend });
        }
        let used = ui.cursor().top() - top;
        self.besides = Some(used - n_plots * plot_h);
        None
    }
}
/// The colour of the `i`-th run series.
fn series_color(i: usize) -> Color32 {
    SERIES_COLORS[i % SERIES_COLORS.len()]
}

/// The legend entries of the run series, in their colours.
fn series_entries(series: &[Series]) -> Vec<Entry> {
    series.iter().enumerate().map(|(i, s)| (series_color(i), false, s.name.clone())).collect()
}

/// The runs of the history, one series per scene and oracle: a line and its points, one colour.
fn overlay(p: &mut PlotUi<'_>, series: Vec<Series>) {
    for (i, s) in series.into_iter().enumerate() {
        let c = series_color(i);
        // No band: two solves a pixel apart in time would turn the whole line into a filled
        // min/max band (egui_plot's drawing of dense series).
        p.line(Line::new(s.name.clone(), PlotPoints::from(s.points.clone())).color(c).allow_band(false));
        p.points(Points::new(s.name, PlotPoints::from(s.points)).color(c).radius(3.5));
    }
}

/// A plot's legend below it: one entry per line, a swatch (dashed for a guide) and the series'
/// whole name, wrapped to the column. Returns where it was drawn.
fn draw_legend(ui: &mut egui::Ui, id: &str, entries: &[Entry]) -> Rect {
    ui.push_id(id, |ui| {
        ui.vertical(|ui| {
            ui.spacing_mut().item_spacing.y = 1.0;
            for (color, dashed, name) in entries {
                ui.horizontal(|ui| {
                    let (r, _) = ui.allocate_exact_size(Vec2::new(18.0, 12.0), egui::Sense::hover());
                    let y = r.center().y;
                    let stroke = egui::Stroke::new(2.0, *color);
                    if *dashed {
                        for k in 0..3 {
                            let x = r.left() + 7.0 * k as f32;
                            ui.painter().hline(x..=(x + 4.0).min(r.right()), y, stroke);
                        }
                    } else {
                        ui.painter().hline(r.x_range(), y, stroke);
                        ui.painter().circle_filled(r.center(), 3.5, *color);
                    }
                    ui.add(egui::Label::new(name.as_str()).wrap());
                });
            }
        })
        .response
        .rect
    })
    .inner
}
