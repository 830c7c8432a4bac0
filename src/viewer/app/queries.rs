//! What the app tells about the state shown (its tests, scripted runs and panels read these):
//! the solver's settings and work, the solution and its scores, the overlays' numbers, the
//! pick, the caption, and the lines that say what the picture is.

use super::RadlabApp;
use crate::present::overlay::Highlight;
use crate::scene::Scene;
use crate::solver::hierarchical::{StepKind, StepReport};
use crate::solver::meshed::MeshSolveParams;
use crate::solver::params::HierarchicalParams;
use crate::viewer::artifacts::Measured;
use crate::viewer::history::Ruler;
use crate::viewer::plots::{PlotLayout, ResolveMark};
use crate::viewer::reference_panel::RefState;
use crate::viewer::solve::Opening;
use crate::viewer::status_bar::SolveNote;
use crate::viewer::worker::{DmeshOptions, Estimates, ViewData};
use crate::viewer::{inspector, legends};
use eframe::egui::Rect;
use std::sync::Arc;

impl RadlabApp {
    /// How the last finished Solve started (cold, warm, after steps) and how long it took.
    #[must_use]
    pub fn last_solve(&self) -> Option<SolveNote> {
        self.log.last_solve
    }

    /// Solves finished warm in this window: each after a threshold made finer, from the last
    /// solve's hierarchy, links and radiosity.
    #[must_use]
    pub fn warm_solves(&self) -> usize {
        self.log.warm_solves
    }

    /// Where each warm re-solve since the last cold start began (the plots mark them).
    #[must_use]
    pub fn resolve_marks(&self) -> &[ResolveMark] {
        &self.log.resolve_marks
    }

    /// How many pictures of solves in progress have been shown (a long solve sends one after
    /// a round at most every `worker::PARTIAL_EVERY`).
    #[must_use]
    pub fn partial_pictures(&self) -> usize {
        self.shown.partials
    }

    /// True while the solver thread has work.
    #[must_use]
    pub fn busy(&self) -> bool {
        self.solve.busy()
    }

    /// The preset the Solver panel names (the last chosen; the settings may be edited since).
    #[must_use]
    pub fn preset(&self) -> &str {
        &self.solver_panel.preset
    }

    /// Where the opening's way on to the default preset stands (opened without a preset asked
    /// for).
    #[must_use]
    pub fn opening(&self) -> Opening {
        self.solve.opening
    }

    /// True while every settings change is re-solved at once (the progress line's checkbox).
    #[must_use]
    pub fn auto_run(&self) -> bool {
        self.solve.auto_run
    }

    /// The scene shown.
    #[must_use]
    pub fn scene(&self) -> Option<&Arc<Scene>> {
        self.scene.as_ref()
    }

    /// Solves finished in this window (the runs of the history and of the plots).
    #[must_use]
    pub fn solve_runs(&self) -> usize {
        self.history.len()
    }

    /// True while the plots panel is open.
    #[must_use]
    pub fn plots_shown(&self) -> bool {
        self.plots.open
    }

    /// Where the last frame drew the plots and their legends.
    #[must_use]
    pub fn plots_layout(&self) -> &[PlotLayout] {
        if self.plots.open { self.plots.layout() } else { &[] }
    }

    /// The current solver state.
    #[must_use]
    pub fn view(&self) -> &Arc<ViewData> {
        &self.shown.view
    }

    /// What the last solver step on this scene reported (`None` until one has run).
    #[must_use]
    pub fn last_report(&self) -> Option<&StepReport> {
        self.shown.last_report.as_ref()
    }

    /// Errors shown in the UI.
    #[must_use]
    pub fn errors(&self) -> &[String] {
        &self.errors
    }

    /// Solver time since the last restart (load, reset, parameter change), seconds.
    #[must_use]
    pub fn solver_time_s(&self) -> f64 {
        self.log.solver_time_s
    }

    /// What the solver thread's hierarchical solver refines on the scene shown: "quadtree" (the
    /// input patches) or "contact" (the contact mesh).
    #[must_use]
    pub fn hierarchical_mesh(&self) -> &'static str {
        let Some(scene) = &self.scene else { return "quadtree" };
        let plan =
            crate::solver::spec::Plan::Hierarchical { params: self.solve.params, top: self.solve.loaded_top };
        crate::solver::spec::SolveSpec { plan, estimate: false }.resolved(scene).mesh_name()
    }

    /// The solver parameters in use.
    #[must_use]
    pub fn params(&self) -> HierarchicalParams {
        self.solve.params
    }

    /// The mesh solved on and its settings.
    #[must_use]
    pub fn mesh(&self) -> MeshSolveParams {
        self.solve.mesh
    }

    /// The Mesh menu's D-mesh options (graded, top of the hierarchy).
    #[must_use]
    pub fn dmesh(&self) -> DmeshOptions {
        self.solve.dmesh
    }

    /// The newest artifact measurement of the state shown (`None`: not asked, or not answered
    /// yet), or why there is none.
    #[must_use]
    pub fn artifacts(&self) -> Option<&Result<Measured, String>> {
        self.artifacts.of(self.shown.seq)
    }

    /// The critical edges drawn by kind (`None` while the overlay is off or not built yet).
    #[must_use]
    pub fn critical_counts(&self) -> Option<crate::mesh::discontinuity::SegmentCounts> {
        self.geometry.critical_counts.filter(|_| self.display.critical)
    }

    /// True when the state shown is a mesh solve (not the quadtree's).
    #[must_use]
    pub fn mesh_view(&self) -> bool {
        self.shown.view.mesh.is_some()
    }

    /// The scripted run's exit code, once it has one (the window closes with it).
    #[must_use]
    pub fn exit_code(&self) -> Option<i32> {
        self.script.exit_code
    }

    /// Why the scripted run failed (`exit_code` 1), in one line.
    #[must_use]
    pub fn exit_error(&self) -> Option<&str> {
        self.script.exit_error.as_deref()
    }

    /// Where the current scene's reference stands.
    #[must_use]
    pub fn ref_state(&self) -> &RefState {
        &self.comparison.state
    }

    /// (work finished, work) of the reference computation.
    #[must_use]
    pub fn reference_progress(&self) -> (usize, usize) {
        self.comparison.reference.progress()
    }

    /// The (solver time, rel L2 error against the reference) points of the error plot.
    #[must_use]
    pub fn error_samples(&self) -> &[[f64; 2]] {
        &self.log.error_samples
    }

    /// The pointwise relative L2 error of the state shown against the closed form or the
    /// reference, once scored.
    #[must_use]
    pub fn state_error(&self) -> Option<f64> {
        self.comparison.state_error(self.shown.seq)
    }

    /// The same over the penumbra band, where the closed form gives the band.
    #[must_use]
    pub fn state_band_error(&self) -> Option<f64> {
        self.comparison.band_error(self.shown.seq)
    }

    /// The state's error in one line: against the closed form or the reference when scored,
    /// else the solver's estimate, else why there is none.
    #[must_use]
    pub fn error_line(&self) -> String {
        let against = self.ruler().the();
        let percent = crate::present::figures::percent;
        match (self.state_error(), &self.comparison.state) {
            (Some(e), _) => {
                let band = self.state_band_error();
                let band = band.map_or(String::new(), |b| format!(", penumbra band {}", percent(b)));
                format!("error {} against {against} (pointwise rel L2{band})", percent(e))
            }
            (None, RefState::Ready { .. } | RefState::Looking) => {
                format!("error: scoring against {against}…")
            }
            (None, _) if self.estimates_pending() => {
                "error: estimating… (the solver's estimate follows the picture)".into()
            }
            (None, _) if self.shown.view.estimates == Estimates::Dropped => {
                "error: not estimated (a newer command came first; Compute reference for the true \
                 one)"
                    .into()
            }
            (None, _) if self.mesh_view() => {
                "error unknown: a mesh solve has no estimate of its own (Compute reference)".into()
            }
            // The estimate is of a converged solve's discretisation error, not of the bounces
            // still missing from a stepped one.
            (None, _) if self.shown.last_report.is_none_or(|r| r.kind != StepKind::Solve || r.cancelled) => {
                "error unknown: not solved to convergence (Compute reference for the true error)".into()
            }
            (None, _) => match crate::viewer::history::estimate_of(&self.shown.view) {
                Some(e) => {
                    format!("error ≈ {} (solver's estimate; Compute reference for the true one)", percent(e))
                }
                None => "error unknown".into(),
            },
        }
    }

    /// The lecture figure's caption as shown now (its numbers filled from the state).
    #[must_use]
    pub fn caption(&self) -> Option<String> {
        self.lecture.caption()
    }

    /// The true error list, when it matches the current solver state.
    pub(super) fn true_error(&self) -> Option<&Arc<Vec<f64>>> {
        self.comparison.true_error(self.shown.view.elements.len())
    }

    /// The solver's error estimates of the state shown are on their way: the step answered
    /// without them, and the solver thread computes them next (or after the commands queued
    /// since, when none of those replaces the state).
    #[must_use]
    pub fn estimates_pending(&self) -> bool {
        self.shown.view.estimates_pending() && self.solve.worker.as_ref().is_some_and(|w| w.estimates_owed())
    }

    /// The error overlay would draw the solver's estimates of the state shown, which have not
    /// come yet: the viewport keeps the last state's overlay until they do.
    pub(super) fn overlay_waits_for_estimates(&self) -> bool {
        self.display.error && self.true_error().is_none() && !self.mesh_view() && self.estimates_pending()
    }

    /// Something shown reads the estimates that are on their way (the error overlay, the
    /// inspector, the history and plots, the split view, a figure's caption): a scripted
    /// screenshot waits for them.
    pub(super) fn shows_pending_estimates(&self) -> bool {
        self.estimates_pending()
            && (self.display.error
                || self.pick.here().is_some()
                || self.pick.pending.is_some()
                || self.history.open
                || self.plots.open
                || self.split.on
                || self.lecture.figure().is_some())
    }

    /// What the status bar says of the state's error estimates while they are on their way, or
    /// once they were given up (`None` once they are in, or when none were owed).
    #[must_use]
    pub fn estimates_note(&self) -> Option<&'static str> {
        if self.overlay_waits_for_estimates() {
            Some("estimating the error… (the error overlay shows the last state's until then)")
        } else if self.estimates_pending() {
            Some("estimating the error…")
        } else if self.shown.view.estimates == Estimates::Dropped && !self.mesh_view() {
            Some("error not estimated")
        } else {
            None
        }
    }

    /// The error heatmap has something to show: the solver's estimate (quadtree, unless given
    /// up), or the true error against a reference (any mesh; a mesh solve has no estimate of its
    /// own).
    #[must_use]
    pub fn error_applies(&self) -> bool {
        let estimated = !self.mesh_view() && self.shown.view.estimates != Estimates::Dropped;
        estimated || self.true_error().is_some()
    }

    /// (element links drawn, element links that pass the filter) in the geometry shown.
    #[must_use]
    pub fn link_stats(&self) -> (usize, usize) {
        self.geometry.link_stats
    }

    /// The links legend's line on the cluster links (`None`: the solve has none).
    #[must_use]
    pub fn cluster_link_legend(&self) -> Option<String> {
        legends::cluster_link_note(
            &self.display,
            &self.shown.view,
            self.geometry.cluster_link_stats,
            self.picked_cluster(),
        )
    }

    /// What the error heatmap shows.
    #[must_use]
    pub fn error_label(&self) -> &'static str {
        inspector::error_label(self.true_error().map(|_| self.ruler()))
    }

    /// What the scene's errors are measured against: its closed form (a single-bounce scene) or
    /// its reference.
    #[must_use]
    pub fn ruler(&self) -> Ruler {
        self.comparison.ruler()
    }

    /// While a settings change is re-solved, the picture shown is the last finished solve's: what
    /// it is and what comes (`None` while the picture is the settings' own).
    #[must_use]
    pub fn stale_note(&self) -> Option<String> {
        let view = &self.shown.view;
        let held = self.shown.hold || (self.solve.resolve_pending && view.params != self.solve.params);
        if !held || view.elements.is_empty() || view.mesh.is_some() {
            return None;
        }
        let (shown, next) = (&view.params, &self.solve.params);
        let what = crate::viewer::history::oracle_threshold(shown);
        let target = crate::viewer::history::oracle_threshold(next);
        let to = if what == target { "the new settings".to_owned() } else { target };
        Some(format!("Stale: the last finished solve ({what}), shown until the re-solve at {to} is ready"))
    }

    /// Where the viewport was drawn in the last frame (points).
    #[must_use]
    pub fn viewport_rect(&self) -> Rect {
        self.framing.rect
    }

    /// The picked cluster: an index into the current solution's `clusters` that holds the
    /// picked element's patch (`None` without one, or when the element is a split pane's run's).
    #[must_use]
    pub fn picked_cluster(&self) -> Option<u32> {
        self.pick.cluster(&self.shown.view)
    }

    /// What the viewport highlights this frame: the link of the matrix block hovered, else (while
    /// the matrix is open) the element under the pointer.
    #[must_use]
    pub fn highlight(&self) -> Option<Highlight> {
        self.pick.highlight()
    }

    /// The leaf under the pointer in the viewport (tracked while the matrix window is open).
    #[must_use]
    pub fn viewport_hover(&self) -> Option<u32> {
        self.pick.viewport_hover
    }
}
