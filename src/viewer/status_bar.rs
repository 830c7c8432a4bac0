//! The status bar at the bottom of the window, two rows: the solution's size (elements, links by
//! visibility, cluster links) and one line of news (a file saved, a warning); then the phases'
//! times, how the last Solve started (warm from the last solve's state, or cold) and how long it
//! took, and what the last step reported.

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
    /// How the last finished Solve started and how long it took.
    pub last_solve: Option<SolveNote>,
    /// The state's error estimates are on their way, or were given up: what that means for what
    /// is shown.
    pub estimates: Option<&'a str>,
}

/// Where a Solve started from.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum SolveStart {
    /// The input patches: a scene loaded, a restart (settings that are not only finer
    /// thresholds, or auto-run off), a Reset.
    Cold,
    /// The last solve's hierarchy, links and radiosity, its thresholds made finer
    /// ([`crate::solver::hierarchical::HierarchicalSolver::retarget`]): it refines and gathers
    /// only what the finer thresholds add.
    Warm,
    /// Where the steps taken by hand left the solver.
    Stepped,
}

/// How the last finished Solve started and how long it took: the status bar's "re-solved warm
/// in 0.42 s" or "solved cold in 1.10 s".
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct SolveNote {
    pub start: SolveStart,
    /// Wall time of the Solve alone (s).
    pub time_s: f64,
}

impl SolveNote {
    /// "re-solved warm in 0.42 s", "solved cold in 1.10 s", "solved in 0.05 s".
    #[must_use]
    pub fn text(&self) -> String {
        let t = self.time_s;
        match self.start {
            SolveStart::Warm => format!("re-solved warm in {t:.2} s"),
            SolveStart::Cold => format!("solved cold in {t:.2} s"),
            SolveStart::Stepped => format!("solved in {t:.2} s"),
        }
    }
}

/// What the solve note's hover text says.
const SOLVE_NOTE_TIP: &str = "How the last Solve started and how long it took. Warm: a threshold \
     made finer (Feps, BFeps, Aeps, or a larger depth or link cap) keeps the hierarchy, the links \
     and the radiosity, and the solve refines and gathers only what the finer threshold adds. Cold: \
     from the input patches (a new scene, a coarser threshold, another setting, Reset, or any change \
     with auto-run off).";

impl View for StatusBar {
    type Input<'a> = StatusInput<'a>;
    type Action = ();

    fn ui(&mut self, ui: &mut egui::Ui, input: StatusInput<'_>) -> Option<()> {
        let StatusInput { view, last_report, last_solve, estimates } = input;
        let s = &view.stats;
        // Two rows, always (the window's layout does not move as the text changes): what the
        // solution is, then what the solver did. Each fits a 1200-point window; the last item of
        // a row is cut at the window's edge (its whole text in its hover text) rather than
        // wrapped onto a third row.
        ui.horizontal(|ui| {
            ui.label(format!("{} elements ({} leaves)", s.elements, s.leaves));
            ui.separator();
            if let Some(m) = &view.mesh {
                ui.label(format!("{}: {} form-factor entries", m.label(), s.links));
            } else {
                ui.label(format!(
                    "{} links (full {}, partial {}, none {})",
                    s.links, s.links_full, s.links_partial, s.links_none
                ));
                if s.cluster_links > 0 {
                    ui.label(format!("+ {} cluster links ({} clusters)", s.cluster_links, s.clusters));
                }
            }
            if view.pushed_for_display {
                ui.separator();
                ui.label("B shown pushed-pulled").on_hover_text(
                    "The solver has gathered; its own radiosity changes at the next Push-pull. \
                     The view shows that result already.",
                );
            }
            if let Some(note) = estimates {
                ui.separator();
                ui.label(note).on_hover_text(ESTIMATES_TIP);
            }
            if !self.message.is_empty() {
                ui.separator();
                let news = egui::RichText::new(&self.message).weak();
                ui.add(egui::Label::new(news).truncate()).on_hover_text(&self.message);
            }
        });
        ui.horizontal(|ui| {
            if let Some(m) = &view.mesh {
                // A mesh solve: no links, no refine / gather / push-pull phases.
                ui.label(format!("solve {:.3}s (meshing {:.3}s)", m.solve_s, m.meshing_s));
                return;
            }
            ui.label(format!(
                "refine {:.3}s · gather {:.3}s · push-pull {:.3}s",
                s.refine_s, s.gather_s, s.push_pull_s
            ))
            .on_hover_text("Time in each phase since the last cold start");
            if let Some(n) = last_solve {
                ui.separator();
                ui.label(n.text()).on_hover_text(SOLVE_NOTE_TIP);
            }
            if let Some(r) = last_report {
                ui.separator();
                let last = format!("last: {}", describe(r, view.residuals.len()));
                ui.add(egui::Label::new(&last).truncate()).on_hover_text(format!("{last}\n\n{RESIDUAL_TIP}"));
            }
        });
        None
    }
}

/// What the status bar's "estimating the error…" and "error not estimated" mean.
const ESTIMATES_TIP: &str = "The solver's own error estimate of every element costs about as much \
     as the solve: the picture, the report and the history entry come at once, and the estimates \
     (error overlay, inspector, the run's estimated error) follow. A newer command (a step, a \
     setting) does not wait for them: they are given up, and the state is not estimated.";

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
