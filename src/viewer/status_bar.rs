//! The status bar at the bottom of the window: the solution's size (elements, links by
//! visibility, cluster links), the phases' times, what the last step reported, and one line of
//! news (a file saved, a warning).

use super::view::View;
use super::worker::ViewData;
use crate::solver::hierarchical::{StepKind, StepReport};
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
                ui.label(format!("last: {}", describe(r, view.residuals.len()))).on_hover_text(RESIDUAL_TIP);
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

/// What the residual in the status bar and the residual plot measure.
pub const RESIDUAL_TIP: &str = "Residual: the largest change of a leaf's radiosity in the last \
     gather, relative to the largest reflected radiosity. A gather computes B' = E + ρFB from the \
     B it reads, so this is the residual r = E + ρFB − B of that B: 1 after the first gather (all \
     the light is new), then falling about as the reflectance, bounce by bounce.";

/// What a step did, in one line: "Gather 0.003 s: bounce 2, residual 3.1e-1", "Refine 0.010 s:
/// 24 elements split, 310 links made", … (`gathers`: the gathers of the state shown so far).
#[must_use]
pub fn describe(r: &StepReport, gathers: usize) -> String {
    let what = match r.kind {
        StepKind::Refine => format!("{} elements split, {} links made", r.refined, r.new_links),
        StepKind::Gather => format!("bounce {gathers}, residual {:.2e}", r.residual),
        StepKind::PushPull if r.time_s == 0.0 && gathers > 0 => {
            "nothing gathered since the last push-pull".to_owned()
        }
        StepKind::PushPull => "irradiance pushed down, radiosity pulled up".to_owned(),
        StepKind::Iterate | StepKind::Solve => format!(
            "{} elements split, {} links made, {gathers} gathers, residual {:.2e}",
            r.refined, r.new_links, r.residual
        ),
    };
    let name = match r.kind {
        StepKind::Refine => "Refine",
        StepKind::Gather => "Gather",
        StepKind::PushPull => "Push-pull",
        StepKind::Iterate => "Iterate",
        StepKind::Solve => "Solve",
    };
    let end = if r.cancelled {
        ", cancelled"
    } else if r.converged && r.kind != StepKind::Refine && gathers > 0 {
        ", converged"
    } else {
        ""
    };
    format!("{name} {:.3} s: {what}{end}", r.time_s)
}
