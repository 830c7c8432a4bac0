//! One frame of the app (`eframe::App::ui`): the threads' answers picked up, the shortcuts and
//! windows, then the panels laid out (top bar, status bar, caption, the side panel's sections,
//! the inspector column, the picture in the middle), each panel's answer applied before the next
//! is drawn; then the scripted run's turn.

use super::RadlabApp;
use crate::render::SceneRenderer;
use crate::viewer::clusters::PickCluster;
use crate::viewer::display::{self, DisplayInput, DisplayPanel};
use crate::viewer::help::{self, Action};
use crate::viewer::history::HistoryAction;
use crate::viewer::inspector::InspectorInput;
use crate::viewer::lecture::{FactsInput, caption_facts};
use crate::viewer::matrix::MatrixAction;
use crate::viewer::plots::PlotsInput;
use crate::viewer::reference_panel::{ReferenceAction, ReferenceInput, ReferencePanel};
use crate::viewer::solver_panel::{ProgressAction, ProgressInput, ProgressPanel, SolverAction, SolverInput};
use crate::viewer::status_bar::StatusInput;
use crate::viewer::top_bar::{TopBarAction, TopBarInput};
use crate::viewer::view::View;
use crate::viewer::worker::Command;
use eframe::egui::{self, Color32};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// Width of the solver/display panel and of the inspector, points (fixed: see `panels`).
const CONTROLS_W: f32 = 290.0;
const INSPECTOR_W: f32 = 320.0;

impl eframe::App for RadlabApp {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let started = Instant::now();
        let cpu_started = self.opts.bench_frames.and_then(|_| crate::viewer::bench::thread_cpu_s());
        if let Some(rs) = frame.wgpu_render_state()
            && let Some(r) = rs.renderer.read().callback_resources.get::<SceneRenderer>()
        {
            self.script.max_upload_s = self.script.max_upload_s.max(r.last_upload_s);
        }
        let ctx = ui.ctx().clone();
        self.poll_worker();
        if let Some(w) = &self.solve.worker {
            w.set_partial_estimates(self.display.error || self.pick.selected.is_some());
        }
        self.poll_reference();
        self.request_artifacts();
        self.artifacts.poll(false);
        self.shortcuts(&ctx);
        self.pick_when_solved();
        self.windows(&ctx);
        self.load_dropped_files(ui);
        self.panels(ui, &ctx);
        self.report_thread_panics();
        self.handle_screenshot(&ctx);
        self.run_script(&ctx);
        // The display shows the newest answer: the error estimates owed for it may start.
        if self.geometry.current() {
            self.solve.pictures_shown();
        }
        if self.busy() {
            ctx.request_repaint_after(crate::viewer::solver_panel::BUSY_REPAINT);
        }
        if self.script.should_close() {
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
        self.script.last_ui_s = started.elapsed().as_secs_f64();
        self.script.last_ui_cpu_s =
            cpu_started.and_then(|a| crate::viewer::bench::thread_cpu_s().map(|b| b - a));
    }
}

impl RadlabApp {
    /// Apply the keyboard shortcuts pressed this frame ([`help::SHORTCUTS`]).
    fn shortcuts(&mut self, ctx: &egui::Context) {
        for a in help::pressed(ctx) {
            match a {
                Action::Step(k) if !self.busy() => self.step(k),
                Action::Step(_) => {}
                Action::ToggleQuadtree => self.display.quadtree ^= true,
                Action::ToggleLinks => self.display.links ^= true,
                Action::ToggleError => self.display.error ^= true,
                Action::ToggleCritical => self.display.critical ^= true,
                Action::CycleArtifact => {
                    self.display.artifact = display::next_artifact(self.display.artifact)
                }
                Action::ToggleClusters if self.shown.view.clusters.is_empty() => {
                    self.status_bar.message = "no clusters: this solve does not cluster".into();
                }
                Action::ToggleClusters => self.display.clusters ^= true,
                Action::ToggleCaption => self.lecture.toggle_caption(),
                Action::ToggleHelp => self.show_help ^= true,
                Action::ToggleSplit => {
                    self.split.on ^= true;
                    self.replay.on &= !self.split.on;
                }
                Action::ToggleHistory => self.history.open ^= true,
            }
        }
    }

    /// The pick waiting for a solve (`--pick`, a figure's), once one is shown in the viewport.
    fn pick_when_solved(&mut self) {
        if let Some([x, y]) = self.pick.pending
            && !self.busy()
            && !self.shown.view.links.is_empty()
            && self.framing.rect.is_positive()
        {
            self.pick_relative(x, y);
            self.display.selected_links_only = true;
            self.pick.pending = None;
        }
    }

    /// The windows over the panels: help, the run history, the lecture's, the file dialog.
    fn windows(&mut self, ctx: &egui::Context) {
        help::window(ctx, &mut self.show_help);
        if self.history.open && self.history.window(ctx) == Some(HistoryAction::ShowSplit) {
            self.split.on = true;
        }
        self.lecture.windows(ctx);
        if let Some(answer) = self.files.show(ctx) {
            self.file_answer(answer);
        }
    }

    /// Open the glTF files dropped on the window (others are refused in the error list).
    fn load_dropped_files(&mut self, ui: &egui::Ui) {
        let dropped: Vec<PathBuf> =
            ui.input(|i| i.raw.dropped_files.iter().map(|f| f.path().to_path_buf()).collect());
        for path in dropped {
            let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
            if matches!(ext.as_deref(), Some("gltf" | "glb")) {
                self.load_spec(&path.to_string_lossy());
            } else {
                self.errors.push(format!("{}: not a .gltf/.glb file", path.display()));
            }
        }
    }

    /// Lay the panels out: top bar, status bar, caption, the side panel, the inspector column,
    /// and the viewport or the pane view in its place.
    fn panels(&mut self, ui: &mut egui::Ui, ctx: &egui::Context) {
        let mut frame = egui::Frame::side_top_panel(ui.style());
        if self.panels_from_clear {
            frame = frame.fill(Color32::TRANSPARENT);
        }
        egui::Panel::top("top").frame(frame).show(ui, |ui| self.top_bar(ui));
        egui::Panel::bottom("status").frame(frame).show(ui, |ui| {
            let input = StatusInput {
                view: &self.shown.view,
                last_report: self.shown.last_report.as_ref(),
                last_solve: self.log.last_solve,
                estimates: self.estimates_note(),
            };
            self.status_bar.ui(ui, input);
        });
        self.drag.dragging = ctx.dragged_id().is_some();
        self.end_drag_when_done();
        self.update_caption_facts();
        self.lecture.caption_panel(ui, frame);
        // Fixed widths: the panels do not widen with their longest line (a long error, a link
        // table, a folded-out option); text wraps or is cut instead.
        egui::Panel::left("controls").frame(frame).resizable(false).exact_size(CONTROLS_W).show(ui, |ui| {
            egui::ScrollArea::vertical().auto_shrink([false, false]).show(ui, |ui| self.controls(ui));
        });
        egui::Panel::right("inspector").frame(frame).resizable(false).exact_size(INSPECTOR_W).show(
            ui,
            |ui| {
                // Vertically: text wraps at the column's edge (the link table scrolls sideways
                // in a box of its own rather than widening the panel).
                egui::ScrollArea::vertical()
                    .auto_shrink([false, false])
                    .id_salt("inspector_scroll")
                    .show(ui, |ui| self.inspector_column(ui));
            },
        );
        egui::CentralPanel::no_frame().show(ui, |ui| {
            if self.replay.on {
                self.replay_view(ui);
            } else if self.split.active(&self.history, self.scene_name()) {
                self.split_view(ui);
            } else {
                self.viewport(ui);
            }
        });
    }

    fn top_bar(&mut self, ui: &mut egui::Ui) {
        let top = self.hierarchical_mesh();
        let input = TopBarInput {
            lecture: &mut self.lecture,
            split: &mut self.split,
            replay: &mut self.replay,
            history: &mut self.history,
            show_help: &mut self.show_help,
            show_plots: &mut self.plots.open,
            scene: self.scene.as_deref(),
            scene_spec: &self.scene_spec,
            mesh: (self.solve.mesh, self.solve.dmesh),
            top,
        };
        match self.top_bar.ui(ui, input) {
            Some(TopBarAction::OpenFigure(f)) => self.open_figure(f),
            Some(TopBarAction::ChooseFile(purpose)) => self.files.choose(purpose),
            Some(TopBarAction::Load(spec)) => self.load_spec(&spec),
            Some(TopBarAction::Screenshot) => self.script.request_screenshot(ui.ctx()),
            Some(TopBarAction::SetMesh(m, d)) => {
                self.set_dmesh(d);
                self.set_mesh(m);
            }
            None => {}
        }
    }

    /// The side panel: the Solver, progress, Reference and Display sections, in that order
    /// (each one's answer is applied before the next is drawn).
    fn controls(&mut self, ui: &mut egui::Ui) {
        self.solver_section(ui);
        self.progress_line(ui);
        ui.separator();
        let input = ReferenceInput {
            state: &self.comparison.state,
            progress: self.reference_progress(),
            error: self.state_error(),
        };
        match ReferencePanel.ui(ui, input) {
            Some(ReferenceAction::Compute) => self.compute_reference(),
            Some(ReferenceAction::Cancel) => self.cancel_reference(),
            None => {}
        }
        ui.separator();
        let error_applies = self.error_applies();
        let input = DisplayInput { display: &mut self.display, view: &self.shown.view, error_applies };
        DisplayPanel.ui(ui, input);
    }

    /// The Solver section: the settings and the steps.
    fn solver_section(&mut self, ui: &mut egui::Ui) {
        let input = SolverInput {
            params: self.solve.params,
            method: self.solve.mesh.method,
            busy: self.busy(),
            scene_area: self.scene.as_ref().map(|s| s.total_area()),
        };
        match self.solver_panel.ui(ui, input) {
            Some(SolverAction::Step(kind)) => self.step(kind),
            Some(SolverAction::Reset) => {
                self.lecture.leave();
                self.leave_opening();
                self.solve.send(Command::Reset, "resetting");
            }
            Some(SolverAction::SetParams(p)) => {
                // A drag's values make one run.
                if ui.ctx().dragged_id().is_some() && p != self.solve.params {
                    self.drag.changed();
                }
                self.set_params(p);
            }
            None => {}
        }
    }

    /// The progress line: auto-run, what the solver thread does, Cancel.
    fn progress_line(&mut self, ui: &mut egui::Ui) {
        let busy = self.busy();
        let s = &mut self.solve;
        let input = ProgressInput {
            auto_run: &mut s.auto_run,
            busy,
            label: &s.busy_label,
            since: s.busy_since,
            progress: s.progress,
            last_report: self.shown.last_report.as_ref(),
        };
        if ProgressPanel.ui(ui, input) == Some(ProgressAction::Cancel) {
            self.leave_opening();
            self.solve.cancel();
            self.solve.resolve_pending = false;
        }
    }

    /// The inspector column: the matrix (when open), the inspector, the plots (when open).
    fn inspector_column(&mut self, ui: &mut egui::Ui) {
        self.matrix_panel(ui);
        // The true error is the current solution's.
        let true_error = self.true_error().filter(|_| self.pick.selected_run.is_none()).cloned();
        let picked =
            self.pick.with_solution(&self.shown.view, &self.history).map(|(id, v)| (id, Arc::clone(v)));
        let cluster = self.picked_cluster();
        let ruler = self.ruler();
        let input = InspectorInput {
            errors: &mut self.errors,
            picked: picked.as_ref().map(|(id, v)| (*id, v)),
            cluster,
            scene: self.scene.as_deref(),
            true_error: true_error.as_deref().map(Vec::as_slice),
            ruler,
            selected_links_only: &mut self.display.selected_links_only,
        };
        if let Some(PickCluster(c)) = self.inspector.ui(ui, input) {
            self.pick_cluster(c);
        }
        if self.plots.open {
            ui.separator();
            ui.heading("Convergence plots");
            let input = PlotsInput {
                view: &self.shown.view,
                history: &self.history,
                error_samples: &self.log.error_samples,
                marks: &self.log.resolve_marks,
                ruler,
            };
            self.plots.ui(ui, input);
        }
    }

    /// The blocking matrix at the top of the inspector column, beside the viewport (drawn
    /// before the viewport, so that a hovered block's link shows in the same frame). The matrix
    /// ↔ viewport link: the element hovered in the viewport (else the picked one) is
    /// highlighted in the matrix; a hovered block's link is highlighted in the viewport.
    fn matrix_panel(&mut self, ui: &mut egui::Ui) {
        self.pick.matrix_hover = None;
        let element = self.pick.viewport_hover.or(self.pick.here());
        match self.lecture.matrix_panel(ui, &self.shown.view, element) {
            Some(MatrixAction::Pick(id)) => {
                self.pick.selected = Some(id);
                self.pick.selected_run = None;
                self.display.selected_links_only = true;
            }
            Some(MatrixAction::Hover(h)) => self.pick.matrix_hover = Some(h),
            None => {}
        }
    }

    /// Read the caption's numbers from the state shown, while it is the figure's and settled
    /// (the figure's steps done), when the state, its error or the runs changed.
    fn update_caption_facts(&mut self) {
        let (Some(figure), Some(scene)) = (self.lecture.figure(), self.scene.clone()) else { return };
        let settled = !self.busy() && !self.solve.loading && !self.shown.hold && !self.estimates_pending();
        if !self.lecture.following() || !settled {
            return;
        }
        let error = self.state_error();
        let band = self.state_band_error();
        let scored = self.history.runs().iter().filter(|r| r.reference.is_some()).count();
        let stage = self.comparison.stage();
        let key = (self.shown.seq, error.map(f64::to_bits), self.history.len(), scored, stage);
        if !self.lecture.wants_facts(key) {
            return;
        }
        let input = FactsInput {
            figure,
            scene: &scene,
            view: &self.shown.view,
            view_seq: self.shown.seq,
            history: &self.history,
            error,
            band,
        };
        let facts = caption_facts(&input);
        let line = self.error_line();
        self.lecture.set_facts(facts, line);
    }
}
