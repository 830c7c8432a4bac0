//! The side panel's Solver section: the hierarchical solver's settings (preset, oracle,
//! thresholds) and the step buttons ([`SolverPanel`]); then auto-run, Cancel and the progress
//! line of the solver thread ([`ProgressPanel`]).

use super::view::View;
use super::widgets::log_slider;
use crate::solver::discontinuity::contact_area_floor;
use crate::solver::hierarchical::{StepKind, StepReport};
use crate::solver::meshed::MeshMethod;
use crate::solver::params::{AreaEps, HierarchicalParams, Oracle};
use crate::solver::spec::Preset;
use eframe::egui;
use std::time::Instant;

/// How often the window redraws while the solver works and nothing else asks for a frame (the
/// progress line's seconds, the solve's partial pictures): each frame costs a software renderer
/// (lavapipe) tens of milliseconds of the cores the solve runs on.
pub const BUSY_REPAINT: std::time::Duration = std::time::Duration::from_millis(250);

/// Width of the progress bars in the side panel.
pub const PANEL_CONTENT_W: f32 = 260.0;

/// The progress line's label while a mesh solve runs.
pub const MESH_SOLVE_LABEL: &str = "solving on the mesh";

/// BFeps the viewer starts the error oracle at (relative to the mean reflected radiosity):
/// coarse enough that the built-in rooms show a solution at once, to be walked down from
/// (docs/solver.md#walking-down-thresholds-warm).
const ERROR_ORACLE_START_EPS: f64 = 0.1;

/// The Solver section and the name of the preset chosen.
#[derive(Clone, Debug)]
pub struct SolverPanel {
    /// The preset shown in the combo box ("custom" settings keep the last name chosen).
    pub preset: String,
}

/// What the Solver section is lent for one frame.
pub struct SolverInput {
    /// The settings in use.
    pub params: HierarchicalParams,
    /// The mesh solved on (the settings apply to the quadtree only).
    pub method: MeshMethod,
    /// The solver thread has work (the step buttons are greyed out).
    pub busy: bool,
    /// The scene's area (an absolute Aeps is shown relative to it).
    pub scene_area: Option<f64>,
}

/// What the Solver section asks of the app.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum SolverAction {
    Step(StepKind),
    /// Back to the input patches.
    Reset,
    /// Restart the solver with these settings.
    SetParams(HierarchicalParams),
}

impl View for SolverPanel {
    type Input<'a> = SolverInput;
    type Action = SolverAction;

    fn ui(&mut self, ui: &mut egui::Ui, input: SolverInput) -> Option<SolverAction> {
        let SolverInput { params, method, busy, scene_area } = input;
        let mut action = None;
        ui.heading("Solver");
        let quadtree = method == MeshMethod::Quadtree;
        ui.add_enabled_ui(quadtree, |ui| {
            action = self.quadtree_controls(ui, params, scene_area).map(SolverAction::SetParams);
        })
        .response
        .on_disabled_hover_text("The hierarchical solver's settings: pick the quadtree mesh to use them");
        let mesh_tip = "Steps the quadtree; on this mesh only Solve runs (the whole mesh solve)";
        ui.separator();
        ui.horizontal_wrapped(|ui| {
            for (label, kind, tip) in [
                (
                    "Refine step",
                    StepKind::Refine,
                    "Initial linking, then the oracle over the existing links (Space)",
                ),
                ("Gather step", StepKind::Gather, "One Jacobi gather over all links (G)"),
                ("Push-pull", StepKind::PushPull, "Push gathered irradiance down, pull radiosity up (P)"),
                ("Iterate", StepKind::Iterate, "Refine + gather + push-pull (I)"),
                ("Solve", StepKind::Solve, "The HSA91 loop until converged, or the mesh solve (S)"),
            ] {
                let enabled = !busy && (quadtree || kind == StepKind::Solve);
                if ui
                    .add_enabled(enabled, egui::Button::new(label))
                    .on_hover_text(tip)
                    .on_disabled_hover_text(if busy { "The solver is busy" } else { mesh_tip })
                    .clicked()
                {
                    action = Some(SolverAction::Step(kind));
                }
            }
            if ui
                .add_enabled(!busy && quadtree, egui::Button::new("Reset"))
                .on_hover_text("Back to the input patches")
                .clicked()
            {
                action = Some(SolverAction::Reset);
            }
        });
        action
    }
}

impl SolverPanel {
    /// The hierarchical solver's settings (preset, oracle, thresholds); returns them if changed
    /// or a preset was chosen.
    fn quadtree_controls(
        &mut self,
        ui: &mut egui::Ui,
        params: HierarchicalParams,
        scene_area: Option<f64>,
    ) -> Option<HierarchicalParams> {
        let mut p = params;
        // The box names the preset chosen last; settings changed since read "(edited)", so a
        // preset's name never stands for values it does not use.
        let shown = match Preset::from_name(&self.preset) {
            Some(preset) if preset.hierarchical() != params => format!("{} (edited)", self.preset),
            _ => self.preset.clone(),
        };
        // Choosing a preset is an answer even when it is the one in use (it ends the opening's
        // way on to the default, `Opening`).
        let chosen = self.preset_box(ui, shown, &mut p);
        egui::ComboBox::from_label("oracle")
            .selected_text(format!("{:?}", p.oracle))
            .show_ui(ui, |ui| {
                ui.selectable_value(&mut p.oracle, Oracle::Feps, "Feps (form factor)");
                ui.selectable_value(&mut p.oracle, Oracle::Bf, "BF (B × F)");
                ui.selectable_value(&mut p.oracle, Oracle::Error, "Error (where the answer is wrong)");
            })
            .response
            .on_hover_text("What decides that a link is accurate enough, or must be split");
        if p.oracle == Oracle::Error && params.oracle != Oracle::Error {
            // The error oracle's BFeps is a fraction of the mean reflected radiosity: the BF
            // presets' 2e-3 would refine to the link budget. Start where it converges in seconds.
            p.bf_eps = ERROR_ORACLE_START_EPS;
            p.bf_relative = true;
        }
        // Each oracle reads one threshold: the others' sliders stay in place, greyed out.
        let reads_feps = p.oracle == Oracle::Feps;
        ui.add_enabled_ui(reads_feps, |ui| {
            log_slider(
                ui,
                "Feps",
                &mut p.feps,
                1e-5,
                1.0,
                "Form-factor threshold of Refine: link when both F estimates are below it",
            );
        })
        .response
        .on_disabled_hover_text("Feps: read by the Feps oracle only");
        let mut aeps_rel = match p.aeps {
            AreaEps::Relative(r) => r,
            AreaEps::Absolute(a) => scene_area.map_or(1e-4, |s| a / s.max(f64::MIN_POSITIVE)),
        };
        let before = aeps_rel;
        log_slider(
            ui,
            "Aeps",
            &mut aeps_rel,
            1e-8,
            1e-1,
            "Smallest element area, as a fraction of the scene's area",
        );
        if aeps_rel != before {
            p.aeps = AreaEps::Relative(aeps_rel);
        }
        // The error oracle's ε is the ladder's threshold (draft 0.2 … reference 0.0125), an
        // error of B relative to the mean reflected radiosity; the BF oracle's is BFeps.
        let (name, tip) = if p.oracle == Oracle::Error {
            (
                "ε",
                "Threshold of the error oracle: the error of B it allows, relative to the scene's mean \
                 reflected radiosity (the ladder: draft 0.2, interactive 0.1, quality 0.05, fine 0.025, \
                 reference 0.0125)"
                    .to_owned(),
            )
        } else {
            let unit = if p.bf_relative { "relative to the brightest emission" } else { "in units of B" };
            (
                "BFeps",
                format!("Threshold of the BF oracle: links whose B × F exceeds it are refined ({unit})"),
            )
        };
        let eps_before = p.bf_eps;
        ui.add_enabled_ui(!reads_feps, |ui| log_slider(ui, name, &mut p.bf_eps, 1e-6, 1.0, &tip))
            .response
            .on_disabled_hover_text("BFeps: read by the BF oracle only");
        if p.bf_eps != eps_before {
            let eps = p.bf_eps;
            p = slide_threshold(HierarchicalParams { bf_eps: eps_before, ..p }, eps);
        }
        // The rays and the depth cap share a row: the side panel fits a 1280 × 800 screen
        // unscrolled with a figure's caption open.
        ui.horizontal(|ui| {
            let rays = ui
                .add(egui::DragValue::new(&mut p.rays).range(1..=256).speed(0.25))
                .on_hover_text("Shadow rays per link (visible fraction); drag or type");
            ui.ctx().accesskit_node_builder(rays.id, |b| b.set_label("rays value"));
            ui.label("rays");
            ui.add_space(16.0);
            let depth = ui
                .add(egui::DragValue::new(&mut p.max_depth).range(1..=20).speed(0.1))
                .on_hover_text("Deepest quadtree level below an input patch: a hard floor on resolution");
            ui.ctx().accesskit_node_builder(depth.id, |b| b.set_label("max depth value"));
            ui.label("max depth");
        });
        (p != params || chosen).then_some(p)
    }

    /// The preset box: the preset chosen last (`shown`: "(edited)" when the settings differ);
    /// choosing one sets every setting of `p` to its values. Returns whether one was chosen.
    fn preset_box(&mut self, ui: &mut egui::Ui, shown: String, p: &mut HierarchicalParams) -> bool {
        let mut chosen = false;
        egui::ComboBox::from_label("preset")
            .selected_text(shown)
            .show_ui(ui, |ui| {
                for preset in Preset::ALL {
                    let name = preset.name();
                    if ui
                        .selectable_label(self.preset == name, name)
                        .on_hover_text(preset.description())
                        .clicked()
                    {
                        self.preset = name.to_owned();
                        *p = preset.hierarchical();
                        chosen = true;
                    }
                }
            })
            .response
            .on_hover_text(
                "Named solver settings (all sliders below at once): the ladder draft … reference \
                 refines the contact mesh by the error oracle, each step halving its threshold; \
                 bf, lecture and splash2 refine the quadtree",
            );
        chosen
    }
}

/// Auto-run, Cancel and the progress line (always there: nothing below moves as work starts and
/// ends).
#[derive(Copy, Clone, Debug, Default)]
pub struct ProgressPanel;

/// What the progress line is lent for one frame.
pub struct ProgressInput<'a> {
    /// Re-solve whenever a parameter changes.
    pub auto_run: &'a mut bool,
    /// The solver thread has work.
    pub busy: bool,
    /// What it does ([`MESH_SOLVE_LABEL`], "refining", …), since when, and its (done, total).
    pub label: &'a str,
    pub since: Option<Instant>,
    pub progress: Option<(u64, u64)>,
    /// What the last step reported (shown while idle).
    pub last_report: Option<&'a StepReport>,
}

/// What the progress line asks of the app.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum ProgressAction {
    /// Stop the running step.
    Cancel,
}

impl View for ProgressPanel {
    type Input<'a> = ProgressInput<'a>;
    type Action = ProgressAction;

    fn ui(&mut self, ui: &mut egui::Ui, input: ProgressInput<'_>) -> Option<ProgressAction> {
        let ProgressInput { auto_run, busy, label, since, progress, last_report } = input;
        let mut action = None;
        ui.horizontal(|ui| {
            ui.checkbox(auto_run, "auto-run").on_hover_text(
                "Re-solve whenever a parameter changes; the last picture stays until the new one is \
                 ready. Off: a change restarts from the input patches, for stepping by hand.",
            );
            // Always there, enabled while busy: the row does not change as work starts and ends.
            if ui
                .add_enabled(busy, egui::Button::new("Cancel"))
                .on_hover_text(
                    "Stop the running step (the state stays consistent). A mesh solve (uniform, \
                     discontinuity, p = 0 or 1) has no cancel hook of its own: it runs on a thread \
                     of its own, Cancel answers at once and keeps the picture shown, and the solve \
                     finishes in the background with its result dropped (the CPU it takes until \
                     then is not given back)",
                )
                .clicked()
            {
                action = Some(ProgressAction::Cancel);
            }
        });
        // While the solver works, what it does, the solve's round and the time so far; then what
        // the last step did.
        let elapsed = since.map_or(0.0, |t| t.elapsed().as_secs_f64());
        let (fraction, text) = match (busy, progress) {
            // A mesh solve counts element pairs, not rounds.
            (true, Some((done, total))) if label == MESH_SOLVE_LABEL => (
                done as f32 / total.max(1) as f32,
                format!(
                    "{} · {:.0} % of the pairs · {elapsed:.1} s",
                    label,
                    100.0 * done as f64 / total.max(1) as f64
                ),
            ),
            (true, Some((done, total))) => (
                done as f32 / total.max(1) as f32,
                format!("{} · round {} of {total} · {elapsed:.1} s", label, (done + 1).min(total)),
            ),
            (true, None) => (0.0, format!("{} · {elapsed:.1} s", label)),
            (false, _) => match last_report {
                Some(r) => (
                    1.0,
                    format!(
                        "{:?} {} in {:.3} s",
                        r.kind,
                        if r.cancelled { "cancelled" } else { "done" },
                        r.time_s
                    ),
                ),
                None => (0.0, "idle".to_owned()),
            },
        };
        // Not animated: an animated bar redraws the window every frame, and on a software
        // renderer those frames take the cores the solver runs on.
        ui.add(egui::ProgressBar::new(fraction).desired_width(PANEL_CONTENT_W).text(text))
            .on_hover_text("The solver thread: progress of the running step, else the last step's time");
        if busy {
            ui.ctx().request_repaint_after(BUSY_REPAINT);
        }
        action
    }
}

/// `p` with the error threshold ε set to `eps` as the Solver panel's slider sets it: on the
/// ladder the area floor follows ε (`discontinuity::contact_area_floor`) and so does the link
/// budget (`spec::follow_ladder_budget`: a finer ε refines further instead of stopping at the
/// coarser one's budget); an Aeps or a budget set by hand stays.
#[must_use]
pub fn slide_threshold(p: HierarchicalParams, eps: f64) -> HierarchicalParams {
    let floor = |e| contact_area_floor(HierarchicalParams { bf_eps: e, ..p }).aeps;
    let mut q = HierarchicalParams { bf_eps: eps, ..p };
    if eps != p.bf_eps && p.aeps == floor(p.bf_eps) {
        q.aeps = floor(eps);
    }
    crate::solver::spec::follow_ladder_budget(q, p.bf_eps)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The slider moves a ladder step's threshold, area floor and link budget together to the
    /// ladder's finer step; an area floor or a budget set by hand stays.
    #[test]
    fn the_slider_moves_the_ladders_floor_and_budget_with_the_threshold() {
        let q = slide_threshold(Preset::Quality.hierarchical(), 0.025);
        let fine = Preset::Fine.hierarchical();
        assert_eq!((q.bf_eps, q.aeps, q.max_links), (fine.bf_eps, fine.aeps, fine.max_links));
        let own = HierarchicalParams { max_links: 1_000, ..Preset::Quality.hierarchical() };
        let q = slide_threshold(own, 0.025);
        assert_eq!((q.aeps, q.max_links), (fine.aeps, 1_000));
        let own = HierarchicalParams { aeps: AreaEps::Absolute(2.0), ..Preset::Quality.hierarchical() };
        let q = slide_threshold(own, 0.025);
        assert_eq!((q.aeps, q.max_links), (AreaEps::Absolute(2.0), fine.max_links));
    }
}
