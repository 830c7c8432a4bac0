//! The eframe application: it owns the threads (solver, display builds, reference, artifacts)
//! and the state shown, lays the panels out and routes what they answer (each panel is a type of
//! its own implementing [`View`](super::view::View): top bar, side panel sections, inspector,
//! plots, status bar, split view, replay, windows; ARCHITECTURE.md has the layout), and draws the
//! viewport.
//!
//! State is split the way STYLE.md asks: solver settings ([`HierarchicalParams`]) are data sent
//! to the worker; what is shown ([`Display`]) is a `Copy` struct; the solver's state arrives as
//! an immutable `Arc<ViewData>` after each step; GPU geometry is rebuilt from those only when
//! one of them changes. [`RadlabApp`] holds one state struct per concern, each in its own module
//! with the methods that act on it ([`SolveState`], [`Shown`], [`SolveLog`], [`Comparison`],
//! [`Pick`], [`Framing`], [`SliderDrag`], [`ScriptRun`], and the panels' own states), and the
//! glue between them, in this module and its children:
//!
//! - here: construction, scenes and figures, the solver settings and steps;
//! - `frame`: the frame (`eframe::App::ui`): the panels laid out and their answers applied;
//! - `picture`: the viewport and the pane views in its place, display builds, picking;
//! - `replies`: the solver and reference threads' answers;
//! - `scripted`: files, screenshots and the scripted runs;
//! - `queries`: what the app tells its tests and panels about the state shown.

mod frame;
mod picture;
mod queries;
mod replies;
mod scripted;

use super::artifacts::{ArtifactThread, Measurements};
use super::builder::Builder;
use super::comparison::Comparison;
use super::display::{Display, Shading};
use super::drag::SliderDrag;
use super::file_dialog::FileDialogs;
use super::framing::Framing;
use super::geometry::ShownGeometry;
use super::history::RunHistory;
use super::inspector::Inspector;
use super::lecture::Lecture;
use super::options::ViewerOptions;
use super::pick::Pick;
use super::plots::Plots;
use super::reference::{RefClient, RefThread};
use super::replay::Replay;
use super::script::{Script, ScriptRun};
use super::shown::Shown;
use super::solve::{FIRST_PICTURE, Opening, SolveState, Urgency};
use super::solve_log::SolveLog;
use super::solver_panel::{MESH_SOLVE_LABEL, SolverPanel};
use super::split::SplitView;
use super::status_bar::StatusBar;
use super::top_bar::TopBar;
use super::worker::{Command, DmeshOptions, ViewData, Worker};
use crate::present::figures::Figure;
use crate::present::overlay::LinkFilter;
use crate::render::SceneRenderer;
use crate::scene::Scene;
use crate::solver::hierarchical::{StepKind, StepReport};
use crate::solver::meshed::{MeshMethod, MeshSolveParams};
use crate::solver::params::HierarchicalParams;
use crate::solver::spec::{Preset, TopLevel};
use std::sync::Arc;

/// The radlab viewer.
pub struct RadlabApp {
    opts: ViewerOptions,
    scene: Option<Arc<Scene>>,
    scene_spec: String,
    /// Errors shown in the UI (load failures, solver failures); never a crash.
    errors: Vec<String>,
    /// The solver thread, its settings and its work in progress.
    solve: SolveState,
    /// The solver state shown, and the one held back while a settings change is re-solved.
    shown: Shown,
    /// The solver's clock and the record of its solves since the last restart.
    log: SolveLog,
    /// The scene's reference and the scores of the state shown.
    comparison: Comparison,
    /// The artifact overlays' measurements (their thread, the newest answer).
    artifacts: Measurements,
    /// The element and cluster picked, and what is hovered.
    pub pick: Pick,
    /// The camera and where the viewport is.
    framing: Framing,
    pub display: Display,
    /// The viewport's display build.
    geometry: ShownGeometry,
    has_wgpu: bool,
    /// Every solve of this window (the plots overlay them; the split view shows them).
    pub history: RunHistory,
    /// A slider drag's solves make one run of the history.
    drag: SliderDrag,
    /// Two or three runs side by side in place of the viewport.
    pub split: SplitView,
    /// The last solve round by round, and the depth cut, in place of the viewport.
    pub replay: Replay,
    /// The lecture figure opened last and its caption panel.
    pub lecture: Lecture,
    top_bar: TopBar,
    solver_panel: SolverPanel,
    status_bar: StatusBar,
    inspector: Inspector,
    plots: Plots,
    files: FileDialogs,
    show_help: bool,
    /// What a scripted run waits for, and how it ends.
    script: ScriptRun,
    /// Leave the side panels unfilled: the window's clear colour (the native runner sets it to
    /// the panel colour) shows through. On a CPU rasteriser egui's textured, blended fill of the
    /// panels is a large share of a frame, and the clear is nearly free. Off by default
    /// (egui_kittest clears to transparent).
    pub panels_from_clear: bool,
}

impl RadlabApp {
    /// Build the app: store the viewport renderer in egui's callback resources, start the
    /// solver thread, load the scene.
    pub fn new(cc: &eframe::CreationContext<'_>, opts: ViewerOptions) -> RadlabApp {
        let has_wgpu = if let Some(rs) = &cc.wgpu_render_state {
            let depth = opts.direct_viewport.then_some(crate::render::DEPTH_FORMAT);
            let renderer = SceneRenderer::new(&rs.device, rs.target_format, depth);
            rs.renderer.write().callback_resources.insert(renderer);
            true
        } else {
            false
        };
        let ctx = cc.egui_ctx.clone();
        let worker = Worker::spawn(move || ctx.request_repaint());
        // The frames say when each answer's picture is on screen (`frame.rs`): the error
        // estimates that follow an answer wait for it.
        if let Ok(w) = &worker {
            w.waits_for_pictures(crate::viewer::worker::PICTURE_WAIT);
        }
        let ctx = cc.egui_ctx.clone();
        let display_builder = Builder::spawn(move || ctx.request_repaint());
        // No preset asked for: the default (`start_as_asked` may open on the way to it).
        let asked = opts.preset.as_deref().map(Preset::from_name);
        let preset = asked.flatten().unwrap_or(Preset::DEFAULT);
        let mesh = opts.mesh.unwrap_or(MeshSolveParams::new(MeshMethod::Quadtree));
        let mut app = RadlabApp {
            scene: None,
            scene_spec: opts.scene.clone(),
            errors: Vec::new(),
            solve: SolveState::new(None, preset.hierarchical(), preset.top(), mesh),
            shown: Shown::default(),
            log: SolveLog::default(),
            comparison: Comparison::new(RefClient::default()),
            artifacts: Measurements::default(),
            pick: Pick { pending: opts.pick, ..Pick::default() },
            framing: Framing::default(),
            display: opts.display,
            // Without the display thread the geometry is built on the UI thread (slower, correct).
            geometry: ShownGeometry::new(display_builder.ok()),
            has_wgpu,
            history: RunHistory::default(),
            drag: SliderDrag::default(),
            split: SplitView::default(),
            replay: Replay::default(),
            lecture: Lecture::default(),
            top_bar: TopBar { spec_edit: opts.scene.clone(), ..TopBar::default() },
            solver_panel: SolverPanel { preset: preset.name().to_owned() },
            status_bar: StatusBar::default(),
            inspector: Inspector::default(),
            plots: Plots::new(opts.show_plots),
            files: FileDialogs::new(opts.desktop_file_dialog),
            show_help: false,
            script: ScriptRun::default(),
            panels_from_clear: false,
            opts,
        };
        match worker {
            Ok(w) => app.solve.worker = Some(w),
            Err(e) => app.errors.push(e),
        }
        if let (Some(None), Some(name)) = (asked, &app.opts.preset) {
            let e = format!("unknown preset {name:?} (one of {}); {} used", Preset::names(), preset.name());
            app.errors.push(e);
        }
        app.start_threads(cc);
        app.start_as_asked();
        app
    }

    /// Start the artifacts and reference threads (an error in the list where one cannot start).
    fn start_threads(&mut self, cc: &eframe::CreationContext<'_>) {
        let ctx = cc.egui_ctx.clone();
        match ArtifactThread::spawn(move || ctx.request_repaint()) {
            Ok(t) => self.artifacts = Measurements::new(Some(t)),
            Err(e) => self.errors.push(e),
        }
        let ctx = cc.egui_ctx.clone();
        match RefThread::spawn(self.opts.reference.clone(), move || ctx.request_repaint()) {
            Ok(t) => self.comparison.reference = RefClient::new(Some(t)),
            Err(e) => self.errors.push(e),
        }
    }

    /// What the options ask of the first frames: the split view, the history, the replay and
    /// the reconstruction, a scripted run, and the figure or scene to open (without a preset
    /// asked for, solved on the way to the default: [`Opening`]).
    fn start_as_asked(&mut self) {
        if let Some(n) = self.opts.split {
            self.split.on = true;
            self.split.panes = n.clamp(2, 3);
        }
        self.history.open = self.opts.show_history;
        if let Some(frame) = self.opts.replay {
            self.replay.on = true;
            self.replay.start_at = Some(frame);
        }
        self.replay.depth = self.opts.depth_cut;
        if let Some(r) = self.opts.reconstruction {
            self.display.shading = Shading::of(r);
        }
        if self.opts.screenshot.is_some()
            || self.opts.bench_frames.is_some()
            || !self.opts.bench_thresholds.is_empty()
        {
            // A scripted run waits for the solve it opens with, or (`--no-solve`) goes on at once
            // to its frames: the geometry unsolved.
            self.script.script = if self.opts.solve_on_start {
                Script::Solving
            } else {
                Script::after_solve(self.opts.bench_frames.is_some(), &self.opts.bench_thresholds)
            };
        }
        let spec = self.scene_spec.clone();
        if let Some(f) = self.opts.figure {
            self.open_figure(f);
        } else if !spec.is_empty() {
            // (Not for the refinement replay of the first solve: it opens at the default alone.)
            let progressive = self.opts.preset.is_none()
                && self.opts.solve_on_start
                && self.opts.replay.is_none()
                && self.solve.mesh.method == MeshMethod::Quadtree
                && FIRST_PICTURE != Preset::DEFAULT;
            if progressive {
                self.solver_panel.preset = FIRST_PICTURE.name().to_owned();
            }
            self.load_spec(&spec);
            if progressive && self.scene.is_some() {
                self.solve.opening = Opening::FirstPicture { then: Preset::DEFAULT };
            } else if progressive {
                // Nothing opened: the panel names the default for the next scene.
                self.solver_panel.preset = Preset::DEFAULT.name().to_owned();
                self.solve.params = Preset::DEFAULT.hierarchical();
            }
        }
    }

    /// The user acts on the solver (a setting, a preset, a step, Reset, Cancel, another mesh or
    /// scene): the opening's way on to the default ends, its step not sent if it has not
    /// started, and the status bar's line about it goes.
    fn leave_opening(&mut self) {
        let opening = std::mem::take(&mut self.solve.opening);
        if opening.note().is_some_and(|n| n == self.status_bar.message) {
            self.status_bar.message.clear();
        }
    }

    /// The opening after a command of the solver thread finished (`report`: its step's, `None`
    /// for a restart): its first picture solved, it goes on warm to the default (as choosing it
    /// in the preset box does, with auto-run) when the solver has nothing else to do; then the
    /// default's solve ends it.
    fn opening_after(&mut self, report: Option<StepReport>) {
        let solved = report.is_some_and(|r| r.kind == StepKind::Solve && !r.cancelled);
        let view = &self.shown.view;
        match self.solve.opening {
            Opening::Off => {}
            Opening::FirstPicture { then } => {
                self.solve.opening = Opening::Off;
                let first = view.mesh.is_none() && view.params == FIRST_PICTURE.hierarchical();
                let idle = !self.busy() && !self.solve.resolve_pending && !self.solve.loading;
                if solved && first && idle && self.solve.auto_run {
                    self.select_preset(then.name());
                    if self.busy() || self.solve.resolve_pending {
                        self.solve.opening = Opening::GoingOn { to: then };
                        self.status_bar.message = self.solve.opening.note().unwrap_or_default();
                    }
                }
            }
            // A restart's answer (the state was not kept): the solve follows.
            Opening::GoingOn { .. } if report.is_none() => {}
            Opening::GoingOn { .. } => self.leave_opening(),
        }
    }

    /// Open a lecture figure: its settings, overlays and camera, then its scene, on which the
    /// figure's solves (BFeps sweep) and steps run; the caption panel shows its caption.
    pub fn open_figure(&mut self, f: &'static Figure) {
        // A split figure's split view does not outlive it.
        if self.lecture.figure().is_some_and(|p| p.split) && !f.split {
            self.split.on = false;
        }
        self.take_figure_settings(f);
        let solve = std::mem::replace(&mut self.opts.solve_on_start, false);
        // The figure's settings, not its preset's.
        match Scene::load(f.scene) {
            Ok(s) => self.show_scene(Arc::new(s)),
            Err(e) => {
                self.errors.push(format!("cannot open {}: {e}", f.scene));
                self.script_failed(format!("cannot open {}: {e}", f.scene));
            }
        }
        self.opts.solve_on_start = solve;
        if self.scene.as_ref().is_none_or(|s| s.source != f.scene) {
            return; // the error is shown
        }
        self.pick.pending = f.pick;
        self.queue_figure_solves(f);
        if f.split {
            self.split.on = true;
            self.split.panes = 2;
            self.replay.on = false;
        }
        self.framing.figure_camera(f.camera);
        self.lecture.show(f);
    }

    /// A figure's solver settings, mesh, overlays and windows (before its scene is loaded with
    /// them).
    fn take_figure_settings(&mut self, f: &'static Figure) {
        self.solver_panel.preset = f.preset.to_owned();
        // Not `set_params`: the load that follows starts a solver with these.
        self.solve.params = f.params;
        self.solve.mesh = f.mesh;
        self.solve.dmesh = DmeshOptions::default();
        let o = f.overlays;
        let d = &mut self.display;
        d.quadtree = o.quadtree;
        d.links = o.links;
        d.error = o.error;
        d.critical = o.critical;
        d.artifact = o.artifact;
        d.shading = if o.flat { Shading::Flat } else { Shading::of(f.reconstruction) };
        d.link_filter = LinkFilter { full: !o.partial_links_only, ..LinkFilter::default() };
        d.selected_links_only = false;
        self.plots.open = f.plots;
        self.lecture.matrix.open = f.matrix;
        f.scene.clone_into(&mut self.top_bar.spec_edit);
    }

    /// Queue a figure's work on its scene: its BFeps sweep (a solve each, then its own
    /// settings back), its mesh solves and its steps. Queued behind the error estimates owed
    /// ([`Urgency::Queued`]): each run of the sweep keeps its estimate (the history, the plots and
    /// the captions quote them).
    fn queue_figure_solves(&mut self, f: &'static Figure) {
        let queued = Urgency::Queued;
        for &bf_eps in f.sweep_bf_eps {
            let sweep = Command::SetParams(HierarchicalParams { bf_eps, ..f.params });
            self.solve.send_as(sweep, "restarting", queued);
            self.send_step_as(StepKind::Solve, queued);
        }
        if !f.sweep_bf_eps.is_empty() {
            self.solve.send_as(Command::SetParams(f.params), "restarting", queued);
        }
        for &m in f.mesh_sweep {
            self.solve.send_as(Command::SolveMesh(m, DmeshOptions::default()), MESH_SOLVE_LABEL, queued);
        }
        for &k in f.steps {
            self.send_step_as(k, queued);
        }
    }

    /// Load `builtin:NAME` or a path; errors are shown in the UI.
    pub fn load_spec(&mut self, spec: &str) {
        match Scene::load(spec) {
            Ok(s) => self.set_scene(Arc::new(s)),
            Err(e) => {
                self.errors.push(format!("cannot open {spec}: {e}"));
                self.script_failed(format!("cannot open {spec}: {e}"));
            }
        }
    }

    /// Show a scene (replaces the current one; the camera is framed on it) with the settings of
    /// the preset the Solver panel names: slider values do not carry over from the last scene
    /// while the box names a preset whose values they are not.
    pub fn set_scene(&mut self, scene: Arc<Scene>) {
        if let Some(preset) = Preset::from_name(&self.solver_panel.preset) {
            self.solve.params = preset.hierarchical();
        }
        self.show_scene(scene);
    }

    /// Show a scene with the settings as they are (a figure's).
    fn show_scene(&mut self, scene: Arc<Scene>) {
        self.leave_opening();
        // A figure's caption and pick belong to its scene (`open_figure` sets them again).
        self.lecture.clear();
        if self.script.script == Script::None {
            self.pick.pending = None;
        }
        // Stop work on the previous scene, and drop what was queued for it.
        self.solve.cancel_all();
        self.solve.resolve_pending = false;
        self.shown.hold = false;
        self.shown.held = None;
        self.framing.frame_scene(&scene);
        self.scene_spec.clone_from(&scene.source);
        self.replay.clear();
        self.shown.replay_frames = None;
        self.pick.clear();
        self.log.error_samples.clear();
        self.log.samples_from = self.shown.seq + 1;
        self.shown.last_report = None;
        self.log.last_solve = None;
        self.artifacts.clear();
        self.comparison.open_scene(&scene);
        self.shown.set(Arc::new(ViewData::default()));
        for w in &scene.warnings {
            self.status_bar.message = format!("{}: {w}", scene.name);
        }
        self.scene = Some(Arc::clone(&scene));
        let params = self.solve.params;
        let top = self.top();
        self.solve.loaded_top = top;
        self.solve.send(Command::Load { scene, params, top }, "loading");
        self.solve.loading = self.solve.worker.is_some();
        if self.opts.solve_on_start {
            self.send_step(StepKind::Solve);
        }
    }

    /// Run a solver step (as the buttons do; the user's step ends the opening's way on to the
    /// default). On a mesh other than the quadtree, Solve is the mesh solve and the
    /// hierarchical steps are refused (a status line says so).
    pub fn step(&mut self, kind: StepKind) {
        self.leave_opening();
        self.send_step(kind);
    }

    /// Send a solver step: [`RadlabApp::step`], or one the app queues itself (a load's solve, a
    /// figure's steps, auto-run's re-solve).
    fn send_step(&mut self, kind: StepKind) {
        self.send_step_as(kind, Urgency::Now);
    }

    /// [`RadlabApp::send_step`], now or queued behind the error estimates owed.
    fn send_step_as(&mut self, kind: StepKind, urgency: Urgency) {
        self.lecture.on_step(kind);
        match self.solve.step_command(kind) {
            Ok((cmd, label)) => self.solve.send_as(cmd, label, urgency),
            Err(why) => self.status_bar.message = why,
        }
    }

    /// Choose a preset by name, as the Solver panel's preset box does: its settings and its top
    /// level (a new solver where that changes). Unknown names are shown as an error.
    pub fn select_preset(&mut self, name: &str) {
        self.leave_opening();
        let Some(preset) = Preset::from_name(name) else {
            self.errors.push(format!("unknown preset {name:?} (one of {})", Preset::names()));
            return;
        };
        name.clone_into(&mut self.solver_panel.preset);
        self.set_params(preset.hierarchical());
    }

    /// The top level the current preset refines ([`Preset::top`]; the last preset chosen while
    /// its settings are edited).
    #[must_use]
    pub fn top(&self) -> TopLevel {
        Preset::from_name(&self.solver_panel.preset).map_or(TopLevel::Patches, Preset::top)
    }

    /// Change the solver parameters and, with auto-run, re-solve with them: warm where only the
    /// thresholds changed (the solver refines on from its hierarchy, links and radiosity, or
    /// from a state it solved at a coarser threshold, [`Command::Retarget`]), else from a
    /// restart. Without auto-run the solver
    /// restarts from the input patches, for stepping by hand.
    pub fn set_params(&mut self, p: HierarchicalParams) {
        // Even the settings in use (a preset chosen again) are the user's answer.
        self.leave_opening();
        if p == self.solve.params {
            return;
        }
        if let Err(e) = p.validate() {
            self.errors.push(e);
            return;
        }
        self.solve.params = p;
        self.lecture.leave();
        // What runs or waits for the old settings is obsolete: the running step stops and the
        // queued ones are dropped (a cancel alone is lost when it lands between two commands).
        if self.busy() {
            self.solve.cancel_all();
        }
        let top = self.top();
        match self.scene.clone() {
            // Another preset's top level (the ladder's contact mesh, the teaching presets'
            // patches): a new solver on it.
            Some(scene) if top != self.solve.loaded_top => {
                self.solve.loaded_top = top;
                self.solve.send(Command::Load { scene, params: p, top }, "meshing");
            }
            _ if self.solve.auto_run => self.solve.send(Command::Retarget(p), "re-solving"),
            _ => self.solve.send(Command::SetParams(p), "restarting"),
        }
        if self.solve.auto_run {
            self.solve.resolve_pending = true;
            // Only when something is shown: a first solve has nothing to keep.
            self.shown.hold = !self.shown.view.elements.is_empty();
        }
    }

    /// Solve on another mesh (or order): re-solve at once with auto-run, keeping the last
    /// picture until the new one comes. Bad settings are shown, not applied.
    pub fn set_mesh(&mut self, m: MeshSolveParams) {
        if m == self.solve.mesh {
            return;
        }
        self.leave_opening();
        if m.method != MeshMethod::Quadtree
            && let Err(e) = m.validate()
        {
            self.errors.push(e);
            return;
        }
        self.solve.mesh = m;
        self.lecture.leave();
        if self.solve.auto_run && self.scene.is_some() {
            self.solve.resolve_pending = true;
        }
    }

    /// Solve the discontinuity meshes with D-mesh options `d` (re-solving with auto-run when they
    /// change the solve on the mesh chosen).
    pub fn set_dmesh(&mut self, d: DmeshOptions) {
        let old = std::mem::replace(&mut self.solve.dmesh, d);
        let m = &self.solve.mesh;
        let changes_solve = d != old && (d.apply_to(m) || old.apply_to(m));
        if changes_solve {
            self.lecture.leave();
            self.leave_opening();
        }
        self.solve.resolve_pending |= changes_solve && self.solve.auto_run && self.scene.is_some();
    }

    /// Turn re-solving after every settings change on or off (the progress line's checkbox).
    pub fn set_auto_run(&mut self, on: bool) {
        self.solve.auto_run = on;
    }

    /// Compute the reference of the current scene on the reference thread (uses the disk
    /// cache; the UI stays live and shows the elapsed time).
    pub fn compute_reference(&mut self) {
        if let Some(scene) = &self.scene
            && self.comparison.reference.load(scene, true)
        {
            self.comparison.state = super::reference_panel::RefState::Looking;
        }
    }

    /// Stop the reference computation started by [`RadlabApp::compute_reference`]; the scene
    /// is left without a reference (nothing is cached).
    pub fn cancel_reference(&mut self) {
        self.comparison.reference.cancel();
    }

    /// Replace the error overlay's values with the true error against a reference (indexed by
    /// element id, units of B), or go back to the solver's estimate with `None`.
    pub fn set_true_error(&mut self, err: Option<Vec<f64>>) {
        self.comparison.true_error = err.map(Arc::new);
    }

    /// Record the error against a reference of the current state (any scalar norm, e.g. the
    /// relative L1 error), plotted against [`RadlabApp::solver_time_s`].
    pub fn push_error_sample(&mut self, error: f64) {
        if error.is_finite() {
            self.log.error_samples.push([self.log.solver_time_s, error]);
        }
    }

    /// A scripted run cannot go on: it ends with an error, whose message is its first
    /// failure's (`message`, one line; nothing in a window: the error list shows it).
    fn script_failed(&mut self, message: String) {
        self.script.failed(message);
    }

    /// A viewer thread panicked (`message`: one line from [`super::panics::catching`]): the
    /// status bar and the error list say so; a scripted run ends with it as its error instead
    /// of waiting for an answer that will not come.
    fn thread_panicked(&mut self, message: String) {
        self.script_failed(message.clone());
        self.status_bar.message.clone_from(&message);
        self.errors.push(message);
    }

    /// Name of the scene shown ("" without one).
    fn scene_name(&self) -> &str {
        self.scene.as_ref().map_or("", |s| s.name.as_str())
    }
}
