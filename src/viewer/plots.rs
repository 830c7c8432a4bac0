//! The convergence plots under the inspector: the residual per gather of the solution shown,
//! the runs of the history overlaid (links against elements with the n and n² guides, error
//! against solver time), and the error against the reference since the last restart.

use super::history::{RunHistory, Series};
use super::view::View;
use super::worker::ViewData;
use eframe::egui;

/// The plots (shown under the inspector while open).
#[derive(Clone, Debug, Default)]
pub struct Plots {
    pub open: bool,
}

/// What the plots are lent for one frame.
pub struct PlotsInput<'a> {
    /// The solution shown (its residuals).
    pub view: &'a ViewData,
    pub history: &'a RunHistory,
    /// (solver time, rel L2 error against the reference) since the last restart.
    pub error_samples: &'a [[f64; 2]],
}

impl View for Plots {
    type Input<'a> = PlotsInput<'a>;
    type Action = ();

    fn ui(&mut self, ui: &mut egui::Ui, input: PlotsInput<'_>) -> Option<()> {
        use egui_plot::{Legend, Line, Plot, PlotPoints, Points};
        let PlotsInput { view, history, error_samples } = input;
        ui.label("Residual per gather (log₁₀)");
        let res: Vec<[f64; 2]> = view
            .residuals
            .iter()
            .enumerate()
            .filter(|(_, r)| **r > 0.0)
            .map(|(i, r)| [i as f64 + 1.0, r.log10()])
            .collect();
        Plot::new("residual").height(150.0).x_axis_label("gather").y_axis_label("log₁₀ residual").show(
            ui,
            |p| {
                p.line(Line::new("residual", PlotPoints::from(res)));
            },
        );
        // The runs of the history, one series per scene and oracle (line and points each).
        let overlay = |p: &mut egui_plot::PlotUi<'_>, series: Vec<Series>| {
            for s in series {
                p.line(Line::new(s.name.clone(), PlotPoints::from(s.points.clone())));
                p.points(Points::new(s.name, PlotPoints::from(s.points)).radius(3.5));
            }
        };
        ui.label("Links against elements, runs in this window (log₁₀)");
        let links = history.links_series();
        let (lo, hi) = links
            .iter()
            .flat_map(|s| &s.points)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p[0]), b.max(p[0])));
        let (lo, hi) = if lo.is_finite() { (lo - 0.5, hi + 0.5) } else { (1.0, 5.0) };
        Plot::new("links_vs_elements")
            .height(150.0)
            .legend(Legend::default())
            .x_axis_label("log₁₀ elements")
            .y_axis_label("log₁₀ links")
            .show(ui, |p| {
                overlay(p, links);
                p.line(Line::new("n", PlotPoints::from(vec![[lo, lo], [hi, hi]])));
                p.line(Line::new("n²", PlotPoints::from(vec![[lo, 2.0 * lo], [hi, 2.0 * hi]])));
            });
        ui.label("Error against solver time, runs in this window (log₁₀)").on_hover_text(
            "Pointwise relative L2 error against the reference (its noise taken out) when the scene \
             has one, else the solver's own estimate (series marked \"estimate\"); one point per \
             solve",
        );
        Plot::new("runs_error_vs_time")
            .height(150.0)
            .legend(Legend::default())
            .x_axis_label("solver time (s)")
            .y_axis_label("log₁₀ pointwise error")
            .show(ui, |p| overlay(p, history.error_series()));
        if error_samples.is_empty() {
            ui.weak("Error against time appears when a reference solution is loaded.");
        } else {
            ui.label(
                "Error against the reference (pointwise rel L2, log₁₀) vs solver time since the last restart",
            );
            let pts: Vec<[f64; 2]> =
                error_samples.iter().filter(|p| p[1] > 0.0).map(|p| [p[0], p[1].log10()]).collect();
            Plot::new("error_vs_time")
                .height(150.0)
                .x_axis_label("solver time (s)")
                .y_axis_label("log₁₀ pointwise error")
                .show(ui, |p| {
                    p.line(Line::new("error", PlotPoints::from(pts.clone())));
                    p.points(Points::new("steps", PlotPoints::from(pts)).radius(3.0));
                });
        }
        None
    }
}
