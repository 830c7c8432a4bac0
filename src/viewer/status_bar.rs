//! The status bar at the bottom of the window: the solution's size (elements, links by
//! visibility, cluster links), the phases' times, what the last step reported, and one line of
//! news (a file saved, a warning).

use super::view::View;
use super::worker::ViewData;
use crate::solver::hierarchical::StepReport;
use eframe::egui;

/// The status bar and its line of news.
#[derive(Clone, Debug, Default)]
pub struct StatusBar {
    /// The news shown at the end of the bar ("saved x.png", a scene's warning); empty: none.
    pub message: String,
}

/// What the status bar is lent for one frame.
pub struct StatusInput<'a> {
    pub view: &'a ViewData,
    pub last_report: Option<&'a StepReport>,
}

impl View for StatusBar {
    type Input<'a> = StatusInput<'a>;
    type Action = ();

    fn ui(&mut self, ui: &mut egui::Ui, input: StatusInput<'_>) -> Option<()> {
        let StatusInput { view, last_report } = input;
        let s = &view.stats;
        ui.horizontal(|ui| {
            ui.label(format!("{} elements ({} leaves)", s.elements, s.leaves));
            ui.separator();
            if let Some(m) = &view.mesh {
                // A mesh solve: no links, no refine / gather / push-pull phases.
                ui.label(format!(
                    "{}: {} form-factor entries · solve {:.3}s (meshing {:.3}s)",
                    m.label(),
                    s.links,
                    m.solve_s,
                    m.meshing_s
                ));
                if !self.message.is_empty() {
                    ui.separator();
                    ui.weak(&self.message);
                }
                return;
            }
            ui.label(format!(
                "{} links (full {}, partial {}, none {})",
                s.links, s.links_full, s.links_partial, s.links_none
            ));
            if s.cluster_links > 0 {
                ui.label(format!("+ {} cluster links ({} clusters)", s.cluster_links, s.clusters));
            }
            ui.separator();
            ui.label(format!(
                "refine {:.3}s · gather {:.3}s · push-pull {:.3}s",
                s.refine_s, s.gather_s, s.push_pull_s
            ));
            ui.separator();
            if let Some(r) = last_report {
                ui.label(format!(
                    "last: {:?} {:.3}s, residual {:.2e}{}{}",
                    r.kind,
                    r.time_s,
                    r.residual,
                    if r.converged { ", converged" } else { "" },
                    if r.cancelled { ", cancelled" } else { "" }
                ));
            }
            if view.pushed_for_display {
                ui.separator();
                ui.label("B shown pushed-pulled").on_hover_text(
                    "The solver has gathered; its own radiosity changes at the next Push-pull. \
                     The view shows that result already.",
                );
            }
            if !self.message.is_empty() {
                ui.separator();
                ui.weak(&self.message);
            }
        });
        None
    }
}
