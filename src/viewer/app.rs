//! The eframe application: it owns the threads (solver, display builds, reference, artifacts)
//! and the state shown, lays the panels out and routes what they answer (each panel is a type of
//! its own implementing [`View`]: top bar, side panel sections, inspector, plots, status bar,
//! split view, replay, windows; ARCHITECTURE.md has the layout), and draws the viewport.
//!
//! State is split the way STYLE.md asks: solver settings ([`HierarchicalParams`]) are data sent
//! to the worker; what is shown ([`Display`]) is a `Copy` struct; the solver's state arrives as
//! an immutable `Arc<ViewData>` after each step; GPU geometry is rebuilt from those only when
//! one of them changes.

use super::artifacts::{ArtifactThread, Measured, Measurements};
use super::bench::FrameBench;
use super::builder::{self, Builder, Coloring};
use super::camera::OrbitCamera;
use super::clusters::{self, PickCluster};
use super::display::{self, CLUSTER_LEVELS, Display, DisplayInput, DisplayPanel, Shading};
use super::file_dialog::{Answer, FileDialogs, Purpose};
use super::geometry::{BuildKey, ShownGeometry};
use super::help::{self, Action};
use super::history::{HistoryAction, Ruler, RunHistory};
use super::inspector::{self, Inspector, InspectorInput};
use super::lecture::Lecture;
use super::legends::{self, Legends};
use super::matrix::MatrixAction;
use super::options::ViewerOptions;
use super::pane::{self, PaneStyle};
use super::plots::{Plots, PlotsInput, ResolveMark};
use super::reference::{RefClient, RefReply, RefThread};
use super::reference_panel::{RefState, ReferenceAction, ReferenceInput, ReferencePanel};
use super::replay::{Replay, ReplayInput};
use super::script::{self, BenchScene, Script};
use super::solver_panel::{
    MESH_SOLVE_LABEL, ProgressAction, ProgressInput, ProgressPanel, SolverAction, SolverInput, SolverPanel,
};
use super::split::{SplitAction, SplitInput, SplitView};
use super::status_bar::{SolveNote, SolveStart, StatusBar, StatusInput};
use super::top_bar::{TopBar, TopBarAction, TopBarInput};
use super::view::View;
use super::viewport::{self, Picture, Shade};
use super::worker::{Command, DmeshOptions, Reply, ViewData, Worker};
use crate::math::DVec3;
use crate::present::figures::Figure;
use crate::present::mesh_overlay::Artifact;
use crate::present::overlay::{Highlight, LinkFilter};
use crate::render::SceneRenderer;
use crate::scene::Scene;
use crate::solver::hierarchical::{StepKind, StepReport};
use crate::solver::meshed::{MeshMethod, MeshSolveParams};
use crate::solver::params::HierarchicalParams;
use crate::solver::spec::{Preset, TopLevel};
use eframe::egui::{self, Color32, Pos2, Rect, Sense};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, channel};
use std::time::Instant;

/// Width of the solver/display panel and of the inspector, points (fixed: see `ui`).
const CONTROLS_W: f32 = 290.0;
const INSPECTOR_W: f32 = 320.0;

/// The radlab viewer.
pub struct RadlabApp {
    opts: ViewerOptions,
    scene: Option<Arc<Scene>>,
    scene_spec: String,
    top_bar: TopBar,
    /// Errors shown in the UI (load failures, solver failures); never a crash.
    errors: Vec<String>,
    params: HierarchicalParams,
    /// The top level the solver thread's solver refines (its last Load): the preset's.
    loaded_top: TopLevel,
    solver_panel: SolverPanel,
    /// The mesh solved on: `method` [`MeshMethod::Quadtree`] is the hierarchical solver (with
    /// `params`), anything else a mesh solve with these settings.
    mesh: MeshSolveParams,
    /// The Mesh menu's graded / top-of-hierarchy D-mesh options.
    dmesh: DmeshOptions,
    worker: Option<Worker>,
    progress: Option<(u64, u64)>,
    busy_label: String,
    /// When the solver thread last went from idle to busy (the progress line's clock).
    busy_since: Option<Instant>,
    /// Re-solve once the running command finishes (auto-run after a parameter change).
    resolve_pending: bool,
    /// A parameter change is being re-solved: keep showing the last picture until the new
    /// solve answers (the restart's unlit state goes to `held_view`, shown only if no solve
    /// follows, e.g. after Cancel).
    hold_view: bool,
    held_view: Option<Arc<ViewData>>,
    /// Pictures of solves in progress shown so far (`Reply::Partial`).
    partial_shown: usize,
    /// Where the next Solve starts from (set by the solver thread's answers: a load or a restart,
    /// a retarget that kept the state, a step by hand).
    solve_start: SolveStart,
    /// How the last finished Solve started and how long it took (the status bar says it).
    last_solve: Option<SolveNote>,
    /// Solves finished warm in this window (each a retarget's: finer thresholds, the last
    /// solve's state kept).
    warm_solves: usize,
    /// Where each warm re-solve since the last cold start began (the plots mark them).
    resolve_marks: Vec<ResolveMark>,
    pub auto_run: bool,
    view: Arc<ViewData>,
    last_report: Option<StepReport>,
    /// Every solve of this window (the plots overlay them; the split view shows them).
    pub history: RunHistory,
    /// A slider drag has changed the settings and its solves are not all in: each replaces the
    /// drag's run (`drag_run`), so one drag is one run of the history.
    drag_open: bool,
    drag_run: Option<usize>,
    /// A widget is being dragged (as of the last frame).
    dragging: bool,
    /// The pointwise relative L2 error of state `.0` against the closed form or the reference,
    /// and over the penumbra band (the closed form's).
    state_error: Option<(u64, f64, Option<f64>)>,
    /// What the caption's numbers were last read from: (state, its error, runs, where the
    /// reference stands).
    facts_key: Option<(u64, Option<u64>, usize, usize, u8)>,
    /// Two or three runs side by side in place of the viewport.
    pub split: SplitView,
    /// The last solve round by round, and the depth cut, in place of the viewport.
    pub replay: Replay,
    /// The frames of the solve running now (they come just before its `Done`).
    replay_frames: Option<Vec<Arc<ViewData>>>,
    camera: OrbitCamera,
    home: OrbitCamera,
    origin: DVec3,
    pub display: Display,
    /// Counts the solver states received (identifies `view` in display builds).
    view_seq: u64,
    /// Per-element true error (against a reference); replaces the solver's estimate when set.
    true_error: Option<Arc<Vec<f64>>>,
    /// Solver time since the last restart (sum of the steps' times), seconds.
    solver_time_s: f64,
    /// (solver time, error against the reference) after steps, for the error-vs-time plot.
    error_samples: Vec<[f64; 2]>,
    /// The first state whose score is a sample of `error_samples` (the last restart's).
    samples_from: u64,
    geometry: ShownGeometry,
    /// The reference thread (what it was sent, the scene's reference solution), and where the
    /// current scene's reference stands.
    reference: RefClient,
    pub ref_state: RefState,
    /// Frame times while a scripted benchmark waits for its solve.
    solve_frames: FrameBench,
    /// Longest geometry upload seen (seconds; read from the renderer).
    max_upload_s: f64,
    inspector: Inspector,
    /// The artifact overlays' measurements (their thread, the newest answer).
    artifacts: Measurements,
    /// The element picked (an id of the current solution, or of `selected_run`'s).
    pub selected: Option<u32>,
    /// The run whose solution `selected` belongs to when it was picked in a split view's pane
    /// (`None`: the current solution).
    pub selected_run: Option<usize>,
    /// The cluster picked (an index into the current solution's `clusters`), reached from the
    /// picked element: it counts only while it holds that element's patch
    /// ([`RadlabApp::picked_cluster`]).
    picked_cluster: Option<u32>,
    /// The link of the matrix block hovered this frame (highlighted in the viewport).
    matrix_hover: Option<Highlight>,
    /// The leaf under the pointer in the viewport, while the matrix window is open (its row and
    /// column are highlighted there).
    viewport_hover: Option<u32>,
    has_wgpu: bool,
    viewport_rect: Rect,
    script: Script,
    shot_rx: Option<Receiver<Arc<egui::ColorImage>>>,
    files: FileDialogs,
    status_bar: StatusBar,
    plots: Plots,
    /// The lecture figure opened last and its caption panel.
    pub lecture: Lecture,
    show_help: bool,
    /// Pick the element under this viewport point (fractions, y down) once a solve is shown
    /// (`--pick`, a figure's pick).
    pending_pick: Option<[f32; 2]>,
    /// A Load was sent and its answer has not come yet.
    loading: bool,
    /// Wall time of the last `ui` call (seconds).
    last_ui_s: f64,
    /// On-CPU time of the last `ui` call (benchmarks only).
    last_ui_cpu_s: Option<f64>,
    /// Set when the window should close (scripted runs); read by the runner.
    pub exit_code: Option<i32>,
    /// Why a scripted run failed (its first failure, one line): the runner's error message.
    exit_error: Option<String>,
    /// Leave the side panels unfilled: the window's clear colour (the native runner sets it to
    /// the panel colour) shows through. On a CPU rasteriser egui's textured, blended fill of the
    /// panels costs ~25 ms of CPU per frame at 1280×800; the clear is nearly free. Off by default
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
        let ctx = cc.egui_ctx.clone();
        let display_builder = Builder::spawn(move || ctx.request_repaint());
        let preset = Preset::from_name(&opts.preset).unwrap_or(Preset::Interactive);
        // Until a scene is loaded: framing the unit cube around the origin.
        let start =
            OrbitCamera::frame_all(&crate::scene::Bounds { min: DVec3::splat(-1.0), max: DVec3::splat(1.0) });
        let mut app = RadlabApp {
            scene: None,
            scene_spec: opts.scene.clone(),
            top_bar: TopBar { spec_edit: opts.scene.clone(), ..TopBar::default() },
            errors: Vec::new(),
            params: preset.hierarchical(),
            loaded_top: preset.top(),
            solver_panel: SolverPanel { preset: preset.name().to_owned() },
            mesh: opts.mesh.unwrap_or(MeshSolveParams::new(MeshMethod::Quadtree)),
            dmesh: DmeshOptions::default(),
            worker: None,
            progress: None,
            busy_label: String::new(),
            busy_since: None,
            resolve_pending: false,
            hold_view: false,
            partial_shown: 0,
            solve_start: SolveStart::Cold,
            last_solve: None,
            warm_solves: 0,
            resolve_marks: Vec::new(),
            held_view: None,
            auto_run: true,
            view: Arc::new(ViewData::default()),
            last_report: None,
            history: RunHistory::default(),
            drag_open: false,
            drag_run: None,
            dragging: false,
            state_error: None,
            facts_key: None,
            split: SplitView::default(),
            replay: Replay::default(),
            replay_frames: None,
            camera: start,
            home: start,
            origin: DVec3::ZERO,
            display: opts.display,
            true_error: None,
            solver_time_s: 0.0,
            error_samples: Vec::new(),
            samples_from: 0,
            // Without the display thread the geometry is built on the UI thread (slower, correct).
            geometry: ShownGeometry::new(display_builder.ok()),
            inspector: Inspector::default(),
            view_seq: 0,
            solve_frames: FrameBench::default(),
            max_upload_s: 0.0,
            reference: RefClient::default(),
            ref_state: RefState::None,
            artifacts: Measurements::default(),
            selected: None,
            selected_run: None,
            picked_cluster: None,
            matrix_hover: None,
            viewport_hover: None,
            has_wgpu,
            viewport_rect: Rect::NOTHING,
            script: Script::None,
            shot_rx: None,
            files: FileDialogs::new(opts.desktop_file_dialog),
            status_bar: StatusBar::default(),
            plots: Plots::new(opts.show_plots),
            lecture: Lecture::default(),
            show_help: false,
            pending_pick: opts.pick,
            loading: false,
            exit_code: None,
            exit_error: None,
            last_ui_s: 0.0,
            last_ui_cpu_s: None,
            panels_from_clear: false,
            opts,
        };
        match worker {
            Ok(w) => app.worker = Some(w),
            Err(e) => app.errors.push(e),
        }
        let ctx = cc.egui_ctx.clone();
        match ArtifactThread::spawn(move || ctx.request_repaint()) {
            Ok(t) => app.artifacts = Measurements::new(Some(t)),
            Err(e) => app.errors.push(e),
        }
        let ctx = cc.egui_ctx.clone();
        match RefThread::spawn(app.opts.reference.clone(), move || ctx.request_repaint()) {
            Ok(t) => app.reference = RefClient::new(Some(t)),
            Err(e) => app.errors.push(e),
        }
        if let Some(n) = app.opts.split {
            app.split.on = true;
            app.split.panes = n.clamp(2, 3);
        }
        app.history.open = app.opts.show_history;
        if let Some(frame) = app.opts.replay {
            app.replay.on = true;
            app.replay.start_at = Some(frame);
        }
        app.replay.depth = app.opts.depth_cut;
        if let Some(r) = app.opts.reconstruction {
            app.display.shading = Shading::of(r);
        }
        if app.opts.screenshot.is_some() || app.opts.bench_frames.is_some() {
            app.opts.solve_on_start = true;
            app.script = Script::Solving;
        }
        let spec = app.scene_spec.clone();
        if let Some(f) = app.opts.figure {
            app.open_figure(f);
        } else if !spec.is_empty() {
            app.load_spec(&spec);
        }
        app
    }

    /// Open a lecture figure: its settings, overlays and camera, then its scene, on which the
    /// figure's solves (BFeps sweep) and steps run; the caption panel shows its caption.
    pub fn open_figure(&mut self, f: &'static Figure) {
        // A split figure's split view does not outlive it.
        if self.lecture.figure().is_some_and(|p| p.split) && !f.split {
            self.split.on = false;
        }
        self.solver_panel.preset = f.preset.to_owned();
        // Not `set_params`: the load below starts a solver with these.
        self.params = f.params;
        self.mesh = f.mesh;
        self.dmesh = DmeshOptions::default();
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
        self.pending_pick = f.pick;
        for &bf_eps in f.sweep_bf_eps {
            self.send(Command::SetParams(HierarchicalParams { bf_eps, ..f.params }), "restarting");
            self.step(StepKind::Solve);
        }
        if !f.sweep_bf_eps.is_empty() {
            self.send(Command::SetParams(f.params), "restarting");
        }
        for &m in f.mesh_sweep {
            self.send(Command::SolveMesh(m, DmeshOptions::default()), MESH_SOLVE_LABEL);
        }
        for &k in f.steps {
            self.step(k);
        }
        if f.split {
            self.split.on = true;
            self.split.panes = 2;
            self.replay.on = false;
        }
        let c = f.camera;
        self.camera = self.home;
        self.camera.orbit(-c.yaw_deg.to_radians(), c.pitch_deg.to_radians());
        self.camera.zoom(c.zoom);
        self.lecture.show(f);
    }

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
                Action::ToggleClusters if self.view.clusters.is_empty() => {
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
            self.params = preset.hierarchical();
        }
        self.show_scene(scene);
    }

    /// Show a scene with the settings as they are (a figure's).
    fn show_scene(&mut self, scene: Arc<Scene>) {
        // A figure's caption and pick belong to its scene (`open_figure` sets them again).
        self.lecture.clear();
        if self.script == Script::None {
            self.pending_pick = None;
        }
        // Stop work on the previous scene, and drop what was queued for it.
        if let Some(w) = &self.worker {
            w.cancel_all();
        }
        self.resolve_pending = false;
        self.hold_view = false;
        self.held_view = None;
        let b = scene.bounds();
        self.origin = b.center();
        // The scene's own camera, else the CPU renderer's default (inside closed rooms, the
        // most front-facing direction outside open scenes).
        let c = crate::present::image::Camera::for_scene(&scene);
        let v = crate::scene::Viewpoint { eye: c.eye, target: c.target, up: c.up, fov_y_deg: c.fov_y_deg };
        self.home = OrbitCamera::from_viewpoint(&v, &b);
        self.camera = self.home;
        self.scene_spec.clone_from(&scene.source);
        self.replay.clear();
        self.replay_frames = None;
        self.selected = None;
        self.selected_run = None;
        self.picked_cluster = None;
        self.true_error = None;
        self.error_samples.clear();
        self.samples_from = self.view_seq + 1;
        self.last_report = None;
        self.last_solve = None;
        self.state_error = None;
        self.reference.view = None;
        self.artifacts.clear();
        if self.reference.load(&scene, false) {
            self.ref_state = RefState::Looking;
        }
        self.set_view(Arc::new(ViewData::default()));
        for w in &scene.warnings {
            self.status_bar.message = format!("{}: {w}", scene.name);
        }
        self.scene = Some(Arc::clone(&scene));
        let params = self.params;
        let top = self.top();
        self.loaded_top = top;
        self.send(Command::Load { scene, params, top }, "loading");
        self.loading = self.worker.is_some();
        if self.opts.solve_on_start {
            self.step(StepKind::Solve);
        }
    }

    fn send(&mut self, cmd: Command, label: &str) {
        if let Some(w) = &mut self.worker {
            if !w.busy() {
                self.busy_since = Some(Instant::now());
            }
            w.send(cmd);
            label.clone_into(&mut self.busy_label);
        }
    }

    /// How the last finished Solve started (cold, warm, after steps) and how long it took.
    #[must_use]
    pub fn last_solve(&self) -> Option<SolveNote> {
        self.last_solve
    }

    /// Solves finished warm in this window: each after a threshold made finer, from the last
    /// solve's hierarchy, links and radiosity.
    #[must_use]
    pub fn warm_solves(&self) -> usize {
        self.warm_solves
    }

    /// Where each warm re-solve since the last cold start began (the plots mark them).
    #[must_use]
    pub fn resolve_marks(&self) -> &[ResolveMark] {
        &self.resolve_marks
    }

    /// How many pictures of solves in progress have been shown (a long solve sends one after
    /// a round at most every `worker::PARTIAL_EVERY`).
    #[must_use]
    pub fn partial_pictures(&self) -> usize {
        self.partial_shown
    }

    /// True while the solver thread has work.
    #[must_use]
    pub fn busy(&self) -> bool {
        self.worker.as_ref().is_some_and(Worker::busy)
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
    pub fn plots_layout(&self) -> &[super::plots::PlotLayout] {
        if self.plots.open { self.plots.layout() } else { &[] }
    }

    /// The current solver state.
    #[must_use]
    pub fn view(&self) -> &Arc<ViewData> {
        &self.view
    }

    /// What the last solver step on this scene reported (`None` until one has run).
    #[must_use]
    pub fn last_report(&self) -> Option<&StepReport> {
        self.last_report.as_ref()
    }

    /// Errors shown in the UI.
    #[must_use]
    pub fn errors(&self) -> &[String] {
        &self.errors
    }

    /// Replace the error overlay's values with the true error against a reference (indexed by
    /// element id, units of B), or go back to the solver's estimate with `None`.
    pub fn set_true_error(&mut self, err: Option<Vec<f64>>) {
        self.true_error = err.map(Arc::new);
    }

    /// Solver time since the last restart (load, reset, parameter change), seconds.
    #[must_use]
    pub fn solver_time_s(&self) -> f64 {
        self.solver_time_s
    }

    /// Record the error against a reference of the current state (any scalar norm, e.g. the
    /// relative L1 error), plotted against [`RadlabApp::solver_time_s`].
    pub fn push_error_sample(&mut self, error: f64) {
        if error.is_finite() {
            self.error_samples.push([self.solver_time_s, error]);
        }
    }

    /// Run a solver step (as the buttons do). On a mesh other than the quadtree, Solve is the
    /// mesh solve and the hierarchical steps are refused (a status line says so).
    pub fn step(&mut self, kind: StepKind) {
        self.lecture.on_step(kind);
        if self.mesh.method != MeshMethod::Quadtree {
            if kind == StepKind::Solve {
                self.send(Command::SolveMesh(self.mesh, self.dmesh), MESH_SOLVE_LABEL);
            } else {
                self.status_bar.message =
                    format!("{kind:?} steps the quadtree: pick the quadtree mesh first");
            }
            return;
        }
        let label = match kind {
            StepKind::Refine => "refining",
            StepKind::Gather => "gathering",
            StepKind::PushPull => "push-pull",
            StepKind::Iterate => "iterating",
            StepKind::Solve => "solving",
        };
        self.send(Command::Step(kind), label);
    }

    /// Choose a preset by name, as the Solver panel's preset box does: its settings and its top
    /// level (a new solver where that changes). Unknown names are shown as an error.
    pub fn select_preset(&mut self, name: &str) {
        let Some(preset) = Preset::from_name(name) else {
            self.errors.push(format!("unknown preset {name:?} (one of {})", Preset::names()));
            return;
        };
        name.clone_into(&mut self.solver_panel.preset);
        self.set_params(preset.hierarchical());
    }

    /// What the solver thread's hierarchical solver refines on the scene shown: "quadtree" (the
    /// input patches) or "contact" (the contact mesh).
    #[must_use]
    pub fn hierarchical_mesh(&self) -> &'static str {
        let Some(scene) = &self.scene else { return "quadtree" };
        let plan = crate::solver::spec::Plan::Hierarchical { params: self.params, top: self.loaded_top };
        crate::solver::spec::SolveSpec { plan, estimate: false }.resolved(scene).mesh_name()
    }

    /// The top level the current preset refines ([`Preset::top`]; the last preset chosen while
    /// its settings are edited).
    #[must_use]
    pub fn top(&self) -> TopLevel {
        Preset::from_name(&self.solver_panel.preset).map_or(TopLevel::Patches, Preset::top)
    }

    /// Change the solver parameters and, with auto-run, re-solve with them: warm where only the
    /// thresholds got finer (the solver keeps its hierarchy, links and radiosity and refines on
    /// from them, [`Command::Retarget`]), else from a restart. Without auto-run the solver
    /// restarts from the input patches, for stepping by hand.
    pub fn set_params(&mut self, p: HierarchicalParams) {
        if p == self.params {
            return;
        }
        if let Err(e) = p.validate() {
            self.errors.push(e);
            return;
        }
        self.params = p;
        self.lecture.leave();
        // What runs or waits for the old settings is obsolete: the running step stops and the
        // queued ones are dropped (a cancel alone is lost when it lands between two commands).
        if self.busy()
            && let Some(w) = &self.worker
        {
            w.cancel_all();
        }
        let top = self.top();
        match self.scene.clone() {
            // Another preset's top level (the ladder's contact mesh, the teaching presets'
            // patches): a new solver on it.
            Some(scene) if top != self.loaded_top => {
                self.loaded_top = top;
                self.send(Command::Load { scene, params: p, top }, "meshing");
            }
            _ if self.auto_run => self.send(Command::Retarget(p), "re-solving"),
            _ => self.send(Command::SetParams(p), "restarting"),
        }
        if self.auto_run {
            self.resolve_pending = true;
            // Only when something is shown: a first solve has nothing to keep.
            self.hold_view = !self.view.elements.is_empty();
        }
    }

    /// The mesh solved on and its settings.
    #[must_use]
    pub fn mesh(&self) -> MeshSolveParams {
        self.mesh
    }

    /// Solve on another mesh (or order): re-solve at once with auto-run, keeping the last
    /// picture until the new one comes. Bad settings are shown, not applied.
    pub fn set_mesh(&mut self, m: MeshSolveParams) {
        if m == self.mesh {
            return;
        }
        if m.method != MeshMethod::Quadtree
            && let Err(e) = m.validate()
        {
            self.errors.push(e);
            return;
        }
        self.mesh = m;
        self.lecture.leave();
        if self.auto_run && self.scene.is_some() {
            self.resolve_pending = true;
        }
    }

    /// The Mesh menu's D-mesh options (graded, top of the hierarchy).
    #[must_use]
    pub fn dmesh(&self) -> DmeshOptions {
        self.dmesh
    }

    /// Solve the discontinuity meshes with D-mesh options `d` (re-solving with auto-run when they
    /// change the solve on the mesh chosen).
    pub fn set_dmesh(&mut self, d: DmeshOptions) {
        let old = std::mem::replace(&mut self.dmesh, d);
        let changes_solve = d != old && (d.apply_to(&self.mesh) || old.apply_to(&self.mesh));
        if changes_solve {
            self.lecture.leave();
        }
        self.resolve_pending |= changes_solve && self.auto_run && self.scene.is_some();
    }

    /// The artifact overlay to draw and its samples, when they were measured on the state shown.
    fn artifact_samples(&self) -> Option<(Artifact, Arc<crate::eval::artifacts::ArtifactSamples>)> {
        self.artifacts.samples(self.display.artifact, self.view_seq)
    }

    /// The newest artifact measurement of the state shown (`None`: not asked, or not answered
    /// yet), or why there is none.
    #[must_use]
    pub fn artifacts(&self) -> Option<&Result<Measured, String>> {
        self.artifacts.of(self.view_seq)
    }

    /// Ask the artifacts thread to measure the state shown, once per state and reference (only
    /// while an artifact overlay is on, and not a solve's intermediate picture).
    fn request_artifacts(&mut self) {
        if self.display.artifact.is_none() || self.view.elements.is_empty() || self.busy() || self.loading {
            return;
        }
        if let Some(scene) = &self.scene {
            self.artifacts.request(self.view_seq, scene, &self.view, self.reference.view.as_ref());
        }
    }

    /// The critical edges drawn by kind (`None` while the overlay is off or not built yet).
    #[must_use]
    pub fn critical_counts(&self) -> Option<crate::mesh::discontinuity::SegmentCounts> {
        self.geometry.critical_counts.filter(|_| self.display.critical)
    }

    /// True when the state shown is a mesh solve (not the quadtree's).
    #[must_use]
    pub fn mesh_view(&self) -> bool {
        self.view.mesh.is_some()
    }

    /// Block until the solver thread is idle and apply its replies, then until the reference
    /// thread has scored the result, then until the display is built (tests, scripted runs).
    pub fn wait_for_solver(&mut self) {
        let mut replies = Vec::new();
        if let Some(w) = &mut self.worker {
            w.wait_idle(|r| replies.push(r));
        }
        for r in replies {
            self.apply(r);
        }
        loop {
            self.request_evaluation();
            let Some(replies) = self.reference.wait_idle() else { break };
            for r in replies {
                self.apply_ref(r);
            }
        }
        self.request_artifacts();
        self.artifacts.poll(true);
        self.request_geometry();
        self.poll_geometry(true);
        self.split.wait();
        self.replay.wait();
        self.report_thread_panics();
    }

    fn poll_worker(&mut self) {
        let mut replies = Vec::new();
        if let Some(w) = &mut self.worker {
            while let Some(r) = w.poll() {
                replies.push(r);
            }
        }
        for r in replies {
            self.apply(r);
        }
        if self.resolve_pending && !self.busy() {
            self.resolve_pending = false;
            self.step(StepKind::Solve);
        }
        if self.hold_view && !self.resolve_pending && !self.busy() {
            // No solve follows the restart (cancelled): show the solver's state.
            self.hold_view = false;
            if let Some(v) = self.held_view.take() {
                self.set_view(v);
            }
        }
    }

    fn apply(&mut self, r: Reply) {
        match r {
            // The previous scene's last answers (its running step, cancelled): not shown.
            Reply::Done { .. }
            | Reply::Cancelled { .. }
            | Reply::Partial { .. }
            | Reply::Progress { .. }
            | Reply::Replay { .. }
            | Reply::Retargeted
                if self.loading => {}
            Reply::Replay { frames } => self.replay_frames = Some(frames),
            // The load of a scene opened before the one shown now (its Load ran before the
            // cancel that dropped what was queued): not shown, the newer load's answer follows.
            Reply::Loaded { scene, .. } if self.scene.as_ref().is_some_and(|s| !Arc::ptr_eq(s, &scene)) => {}
            Reply::Loaded { view, .. } => {
                self.loading = false;
                // A reload on another top level (a preset change) keeps the last picture until
                // its solve is done, as a parameter change does.
                if self.hold_view {
                    self.held_view = Some(view);
                } else {
                    self.set_view(view);
                }
                self.progress = None;
                self.solver_time_s = 0.0;
                self.error_samples.clear();
                self.solve_start = SolveStart::Cold;
                self.resolve_marks.clear();
                // The loaded state is the first sample (unless held back: the next shown).
                self.samples_from = self.view_seq + u64::from(self.hold_view);
            }
            Reply::Done { report, view } => {
                // A restart, or a solve cancelled by the next restart (a slider dragged on):
                // the last finished picture stays until the re-solve answers.
                let superseded = self.hold_view && report.as_ref().is_none_or(|r| r.cancelled);
                // A solve that finished on an earlier setting while the next one was queued: a
                // finished picture, shown, but the hold goes on for the restart that follows.
                let earlier = view.mesh.is_none() && view.params != self.params;
                if superseded {
                    self.held_view = Some(view);
                } else {
                    if !earlier {
                        self.hold_view = false;
                    }
                    self.held_view = None;
                    self.set_view(view);
                }
                // The time a superseded solve spent counts: a warm re-solve goes on from its state.
                if superseded && let Some(r) = &report {
                    self.solver_time_s += r.time_s;
                }
                let report = report.filter(|_| !superseded);
                self.progress = None;
                if report.is_none() {
                    // A restart (superseded or not): the next solve starts from the input patches.
                    self.solve_start = SolveStart::Cold;
                    self.resolve_marks.clear();
                    // SetParams / Reset restart the solver: element ids start over, and the
                    // last step's report no longer describes what is shown (unless held back).
                    if !superseded {
                        self.last_report = None;
                    }
                    self.solver_time_s = 0.0;
                    self.error_samples.clear();
                    self.samples_from = self.view_seq + u64::from(superseded);
                    // (A pick in a split pane's run stays: that solution is kept.)
                    if self.selected_run.is_none() {
                        self.selected = None;
                    }
                }
                if let Some(rep) = report {
                    if self.view.mesh.is_none() {
                        self.note_step(&rep);
                    }
                    self.solver_time_s += rep.time_s;
                    self.last_report = Some(rep);
                    if rep.kind == StepKind::Solve
                        && let Some(frames) = self.replay_frames.take()
                    {
                        self.replay.set_frames(frames, Arc::clone(&self.view));
                    } else if self.view.mesh.is_some() {
                        // A mesh solve has no rounds: the replay of an earlier solve is stale.
                        self.replay.clear();
                    }
                    if rep.kind == StepKind::Solve && !rep.cancelled {
                        let name = self.scene.as_ref().map_or("", |s| s.name.as_str()).to_owned();
                        let over = self.drag_run.filter(|_| self.drag_open);
                        let view = Arc::clone(&self.view);
                        let n =
                            self.history.record_over(over, &name, self.solver_time_s, self.view_seq, view);
                        // A run that is never the state shown (a figure's queued solves) is
                        // scored all the same.
                        if matches!(self.ref_state, RefState::Ready { .. }) {
                            self.score_runs();
                        }
                        if self.drag_open {
                            self.drag_run = Some(n);
                            self.end_drag_when_done();
                        }
                    }
                }
                if self.picked_here().is_some_and(|s| s as usize >= self.view.elements.len()) {
                    self.selected = None;
                }
                if self.script == Script::Solving && !self.busy() {
                    self.script = Script::after_solve(self.opts.bench_frames.is_some());
                }
            }
            Reply::Progress { done, total } => self.progress = Some((done, total)),
            // A long solve's picture so far; not while a restart holds the last picture back
            // (that one stays until the solve answers).
            Reply::Partial { view } => {
                if !self.hold_view {
                    self.set_view(view);
                    self.partial_shown += 1;
                }
            }
            Reply::Skipped => {}
            // Finer thresholds, the solver's state kept: the Solve that follows is warm.
            Reply::Retargeted => self.solve_start = SolveStart::Warm,
            // A mesh solve dropped on Cancel: the picture shown stays.
            Reply::Cancelled { report } => {
                self.progress = None;
                self.last_report = Some(report);
                if self.script == Script::Solving && !self.busy() {
                    self.script = Script::after_solve(self.opts.bench_frames.is_some());
                }
            }
            Reply::Baked(Ok(what)) => self.status_bar.message = what,
            Reply::Baked(Err(e)) => self.errors.push(e),
            Reply::Failed(e) => {
                self.loading = false;
                self.progress = None;
                self.hold_view = false;
                if let Some(v) = self.held_view.take() {
                    self.set_view(v);
                }
                self.script_failed(e.clone());
                self.status_bar.message.clone_from(&e);
                self.errors.push(e);
            }
        }
    }

    /// What a finished step of the hierarchical solver tells about the next Solve's start, and a
    /// finished Solve about itself: how it started and how long it took (the status bar's line),
    /// and where a warm one began (marked in the plots: its first gather, the solver time then).
    /// Call before the step's time is added to the solver time.
    fn note_step(&mut self, rep: &StepReport) {
        if rep.kind != StepKind::Solve {
            self.solve_start = SolveStart::Stepped;
            return;
        }
        if rep.cancelled {
            return;
        }
        if self.solve_start == SolveStart::Warm {
            self.warm_solves += 1;
            // The replay's first frame is the state the solve started from.
            let gathers = self.replay_frames.as_ref().and_then(|f| f.first()).map(|f| f.residuals.len());
            if let Some(gathers) = gathers {
                let threshold = super::history::oracle_threshold(&self.view.params);
                self.resolve_marks.push(ResolveMark { gathers, time_s: self.solver_time_s, threshold });
            }
        }
        self.last_solve = Some(SolveNote { start: self.solve_start, time_s: rep.time_s });
        self.solve_start = SolveStart::Stepped;
    }

    /// A scripted run cannot go on: it ends with an error, whose message is its first
    /// failure's (`message`, one line; nothing in a window: the error list shows it).
    fn script_failed(&mut self, message: String) {
        if self.script != Script::None {
            self.exit_code = Some(1);
            self.exit_error.get_or_insert(message);
        }
    }

    /// Why the scripted run failed (`exit_code` 1), in one line.
    #[must_use]
    pub fn exit_error(&self) -> Option<&str> {
        self.exit_error.as_deref()
    }

    /// A viewer thread panicked (`message`: one line from [`super::panics::catching`]): the
    /// status bar and the error list say so; a scripted run ends with it as its error instead
    /// of waiting for an answer that will not come.
    fn thread_panicked(&mut self, message: String) {
        self.script_failed(message.clone());
        self.status_bar.message.clone_from(&message);
        self.errors.push(message);
    }

    /// Report the display builds (viewport, split panes, replay) and artifact measurements
    /// that panicked since the last call.
    fn report_thread_panics(&mut self) {
        let mut panics = Vec::new();
        panics.extend(self.geometry.take_failure());
        panics.extend(self.split.take_failures());
        panics.extend(self.replay.take_failure());
        panics.extend(self.artifacts.take_panic());
        for p in panics {
            self.thread_panicked(p);
        }
    }

    /// Compute the reference of the current scene on the reference thread (uses the disk
    /// cache; the UI stays live and shows the elapsed time).
    pub fn compute_reference(&mut self) {
        if let Some(scene) = &self.scene
            && self.reference.load(scene, true)
        {
            self.ref_state = RefState::Looking;
        }
    }

    /// Stop the reference computation started by [`RadlabApp::compute_reference`]; the scene
    /// is left without a reference (nothing is cached).
    pub fn cancel_reference(&mut self) {
        self.reference.cancel();
    }

    /// (work finished, work) of the reference computation.
    #[must_use]
    pub fn reference_progress(&self) -> (usize, usize) {
        self.reference.progress()
    }

    /// The (solver time, rel L2 error against the reference) points of the error plot.
    #[must_use]
    pub fn error_samples(&self) -> &[[f64; 2]] {
        &self.error_samples
    }

    /// Send the current solver state to the reference thread for scoring, once.
    fn request_evaluation(&mut self) {
        if matches!(self.ref_state, RefState::Ready { .. }) && !self.view.elements.is_empty() {
            self.reference.evaluate(self.view_seq, &self.view, self.solver_time_s);
        }
    }

    fn poll_reference(&mut self) {
        for r in self.reference.poll() {
            self.apply_ref(r);
        }
        self.request_evaluation();
    }

    fn apply_ref(&mut self, r: RefReply) {
        let current = |source: &str, s: &Self| s.scene.as_ref().is_some_and(|sc| sc.source == source);
        match r {
            RefReply::Computing { source, points, samples } if current(&source, self) => {
                self.ref_state = RefState::Computing { points, samples, since: Instant::now() };
            }
            RefReply::Missing { source } if current(&source, self) => self.ref_state = RefState::Missing,
            RefReply::Cancelled { source } if current(&source, self) => {
                self.ref_state = RefState::Missing;
                self.status_bar.message = "reference computation cancelled".into();
            }
            RefReply::Solution { source, view } if current(&source, self) => {
                self.reference.view = Some(Arc::clone(&view));
                let samples = self.opts.reference.params.paths.samples;
                let name = self.scene_name().to_owned();
                self.history.record_reference(&name, samples, view);
            }
            RefReply::Ready { source, points, samples, how } if current(&source, self) => {
                self.ref_state = RefState::Ready { points, samples, how };
                self.reference.rescore();
                self.score_runs();
            }
            RefReply::Evaluated(e) if self.reference.scored_run(e.view_seq) => {
                self.history.set_reference_error(e.view_seq, e.rel_l2, e.band_l2, e.ruler);
            }
            RefReply::Evaluated(e) => {
                self.history.set_reference_error(e.view_seq, e.rel_l2, e.band_l2, e.ruler);
                if e.view_seq == self.view_seq {
                    self.true_error = Some(Arc::new(e.per_element));
                    self.state_error = e.rel_l2.is_finite().then_some((e.view_seq, e.rel_l2, e.band_l2));
                }
                // (Not a state from before the last restart, answered late.)
                if e.rel_l2.is_finite() && e.view_seq >= self.samples_from {
                    self.error_samples.push([e.solver_time_s, e.rel_l2]);
                }
            }
            RefReply::Failed(e) => {
                self.ref_state = RefState::Failed(e.clone());
                self.errors.push(e);
            }
            RefReply::Panicked(e) => {
                self.ref_state = RefState::Failed(e.clone());
                self.thread_panicked(e);
            }
            // Answers about a scene no longer shown.
            RefReply::Computing { .. }
            | RefReply::Missing { .. }
            | RefReply::Ready { .. }
            | RefReply::Solution { .. }
            | RefReply::Cancelled { .. } => {}
        }
    }

    /// Send the earlier runs of this scene that still keep their solution to the reference thread,
    /// so that their error, too, is the one against the reference (the split view compares them).
    fn score_runs(&mut self) {
        let runs = self.history.unscored(self.scene_name());
        self.reference.score_runs(runs, self.view_seq);
    }

    /// A drag is over once released and its last value's solve is in: the next solve is a run
    /// of its own.
    fn end_drag_when_done(&mut self) {
        if self.drag_open && !self.dragging && !self.resolve_pending && !self.busy() {
            self.drag_open = false;
            self.drag_run = None;
        }
    }

    /// The pointwise relative L2 error of the state shown against the closed form or the
    /// reference, once scored.
    #[must_use]
    pub fn state_error(&self) -> Option<f64> {
        self.state_error.filter(|e| e.0 == self.view_seq).map(|e| e.1)
    }

    /// The same over the penumbra band, where the closed form gives the band.
    #[must_use]
    pub fn state_band_error(&self) -> Option<f64> {
        self.state_error.filter(|e| e.0 == self.view_seq).and_then(|e| e.2)
    }

    /// The state's error in one line: against the closed form or the reference when scored,
    /// else the solver's estimate, else why there is none.
    #[must_use]
    pub fn error_line(&self) -> String {
        let against = self.ruler().the();
        match (self.state_error(), &self.ref_state) {
            (Some(e), _) => {
                let band = self.state_band_error();
                let band = band.map_or(String::new(), |b| {
                    format!(", penumbra band {}", crate::present::figures::percent(b))
                });
                format!(
                    "error {} against {against} (pointwise rel L2{band})",
                    crate::present::figures::percent(e)
                )
            }
            (None, RefState::Ready { .. } | RefState::Looking) => {
                format!("error: scoring against {against}…")
            }
            (None, _) if self.mesh_view() => {
                "error unknown: a mesh solve has no estimate of its own (Compute reference)".into()
            }
            // The estimate is of a converged solve's discretisation error, not of the bounces
            // still missing from a stepped one.
            (None, _) if self.last_report.is_none_or(|r| r.kind != StepKind::Solve || r.cancelled) => {
                "error unknown: not solved to convergence (Compute reference for the true error)".into()
            }
            (None, _) => match super::history::estimate_of(&self.view) {
                Some(e) => format!(
                    "error ≈ {} (solver's estimate; Compute reference for the true one)",
                    crate::present::figures::percent(e)
                ),
                None => "error unknown".into(),
            },
        }
    }

    /// Read the caption's numbers from the state shown, while it is the figure's and settled
    /// (the figure's steps done), when the state, its error or the runs changed.
    fn update_caption_facts(&mut self) {
        let (Some(figure), Some(scene)) = (self.lecture.figure(), self.scene.clone()) else { return };
        if !self.lecture.following() || self.busy() || self.loading || self.hold_view {
            return;
        }
        let error = self.state_error();
        let band = self.state_band_error();
        let reference = match self.ref_state {
            RefState::None => 0,
            RefState::Looking => 1,
            RefState::Missing => 2,
            RefState::Computing { .. } => 3,
            RefState::Ready { .. } => 4,
            RefState::Failed(_) => 5,
        };
        let scored = self.history.runs().iter().filter(|r| r.reference.is_some()).count();
        let key = (self.view_seq, error.map(f64::to_bits), self.history.len(), scored, reference);
        if self.facts_key == Some(key) && self.lecture.has_facts() {
            return;
        }
        self.facts_key = Some(key);
        let input = super::lecture::FactsInput {
            figure,
            scene: &scene,
            view: &self.view,
            view_seq: self.view_seq,
            history: &self.history,
            error,
            band,
        };
        let facts = super::lecture::caption_facts(&input);
        let line = self.error_line();
        self.lecture.set_facts(facts, line);
    }

    /// The lecture figure's caption as shown now (its numbers filled from the state).
    #[must_use]
    pub fn caption(&self) -> Option<String> {
        self.lecture.caption()
    }

    fn set_view(&mut self, view: Arc<ViewData>) {
        self.view = view;
        self.view_seq += 1;
    }

    /// The true error list, when it matches the current solver state.
    fn true_error(&self) -> Option<&Arc<Vec<f64>>> {
        self.true_error.as_ref().filter(|e| e.len() == self.view.elements.len())
    }

    /// The error heatmap has something to show: the solver's estimate (quadtree), or the true
    /// error against a reference (any mesh; a mesh solve has no estimate of its own).
    #[must_use]
    pub fn error_applies(&self) -> bool {
        !self.mesh_view() || self.true_error().is_some()
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
            &self.view,
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
        match &self.ref_state {
            RefState::Ready { how, .. } if how == super::reference::CLOSED_FORM => Ruler::ClosedForm,
            _ => Ruler::Reference,
        }
    }

    /// What the display settings ask of a geometry build (the split view's panes use them too).
    fn build_settings(&self) -> builder::Settings {
        let d = &self.display;
        let mesh_view = self.mesh_view();
        let picked = self.picked_here();
        let picked_cluster = self.picked_cluster();
        let show_links = !mesh_view && (d.links || (picked.is_some() && d.selected_links_only));
        let links = show_links.then(|| {
            let mut filter = d.link_filter;
            filter.element = if d.selected_links_only {
                // Nothing picked: nothing to show; a cluster picked: its cluster links only.
                Some(picked.filter(|_| picked_cluster.is_none()).unwrap_or(u32::MAX))
            } else {
                None
            };
            filter
        });
        builder::Settings {
            coloring: if d.error && self.error_applies() {
                Coloring::Error
            } else {
                match d.shading {
                    Shading::Smooth => Coloring::Smooth,
                    Shading::Flat => Coloring::Flat,
                    Shading::Nodal => Coloring::Nodal,
                }
            },
            links,
            link_alpha: d.link_alpha,
            links_xray: d.links_xray,
            cluster_links: d.cluster_links,
            origin: self.origin,
            depth_limit: None,
            critical: d.critical,
            clusters: d
                .clusters
                .then(|| (d.clusters_from, d.clusters_from.saturating_add(CLUSTER_LEVELS - 1))),
            picked_cluster,
        }
    }

    /// Ask for a display build when the solver state or a display setting it depends on
    /// changed. The build runs on the `radlab-display` thread; the UI keeps showing the previous
    /// geometry until [`RadlabApp::poll_geometry`] picks the new one up.
    fn request_geometry(&mut self) {
        let settings = self.build_settings();
        let key = BuildKey {
            view_seq: self.view_seq,
            true_error: self.true_error().map(|e| Arc::as_ptr(e) as usize),
            artifacts: self.artifact_samples().map(|(a, s)| (a, Arc::as_ptr(&s) as usize)),
            settings,
        };
        let (view, view_seq, true_error) =
            (Arc::clone(&self.view), self.view_seq, self.true_error().cloned());
        let (scene, artifacts) = (self.scene.clone(), self.artifact_samples());
        let ev = self.geometry.request(key, self.display.auto_exposure, |seq| builder::Request {
            seq,
            view,
            view_seq,
            true_error,
            settings,
            scene,
            artifacts,
        });
        self.apply_exposure(ev);
    }

    /// Pick up a finished display build (`wait`: block for it).
    fn poll_geometry(&mut self, wait: bool) {
        let ev = self.geometry.poll(wait, self.display.auto_exposure);
        self.apply_exposure(ev);
    }

    /// The auto exposure of a new build, if any.
    fn apply_exposure(&mut self, ev: Option<f32>) {
        if let Some(ev) = ev {
            self.display.exposure_ev = ev;
        }
    }

    /// How the mesh shader draws the current solution (the panes too, less the pick).
    fn shade(&self) -> Shade {
        let d = &self.display;
        Shade {
            exposure_ev: d.exposure_ev,
            srgb: d.srgb,
            error: d.error && self.error_applies(),
            quadtree: d.quadtree,
            picked: self.picked_here(),
        }
    }

    // ------------------------------------------------------------------------------------------
    // Panels

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
            mesh: (self.mesh, self.dmesh),
            top,
        };
        match self.top_bar.ui(ui, input) {
            Some(TopBarAction::OpenFigure(f)) => self.open_figure(f),
            Some(TopBarAction::ChooseFile(purpose)) => self.files.choose(purpose),
            Some(TopBarAction::Load(spec)) => self.load_spec(&spec),
            Some(TopBarAction::Screenshot) => self.request_screenshot(ui.ctx()),
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
        let input = SolverInput {
            params: self.params,
            method: self.mesh.method,
            busy: self.busy(),
            scene_area: self.scene.as_ref().map(|s| s.total_area()),
        };
        match self.solver_panel.ui(ui, input) {
            Some(SolverAction::Step(kind)) => self.step(kind),
            Some(SolverAction::Reset) => {
                self.lecture.leave();
                self.send(Command::Reset, "resetting");
            }
            Some(SolverAction::SetParams(p)) => {
                // A drag's values make one run (`drag_open`).
                if ui.ctx().dragged_id().is_some() && p != self.params {
                    if !self.drag_open {
                        self.drag_run = None;
                    }
                    self.drag_open = true;
                }
                self.set_params(p);
            }
            None => {}
        }
        let input = ProgressInput {
            auto_run: &mut self.auto_run,
            busy: self.worker.as_ref().is_some_and(Worker::busy),
            label: &self.busy_label,
            since: self.busy_since,
            progress: self.progress,
            last_report: self.last_report.as_ref(),
        };
        if ProgressPanel.ui(ui, input) == Some(ProgressAction::Cancel) {
            if let Some(w) = &self.worker {
                w.cancel();
            }
            self.resolve_pending = false;
        }

        ui.separator();
        let input = ReferenceInput {
            state: &self.ref_state,
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
        let input = DisplayInput { display: &mut self.display, view: &self.view, error_applies };
        DisplayPanel.ui(ui, input);
    }

    // ------------------------------------------------------------------------------------------
    // Viewport

    fn viewport(&mut self, ui: &mut egui::Ui) {
        let rect = ui.available_rect_before_wrap();
        self.viewport_rect = rect;
        let response = ui.allocate_rect(rect, Sense::click_and_drag());
        let aspect = f64::from(rect.width() / rect.height().max(1.0));

        // Camera: left-drag orbit, right/middle-drag or shift-drag pan, wheel zoom, keys.
        self.camera.interact(ui, &response, rect);
        self.camera_keys(ui);
        if response.clicked()
            && let Some(pos) = response.interact_pointer_pos()
        {
            self.pick_at(pos, rect);
        }
        // While the matrix is open, the leaf under the pointer is highlighted there.
        self.viewport_hover = if self.lecture.matrix.open {
            response.hover_pos().and_then(|pos| self.pick_id(pos, rect))
        } else {
            None
        };

        self.request_geometry();
        self.poll_geometry(false);
        let picture = Picture {
            geometry: &self.geometry,
            view_proj: self.camera.view_proj(aspect, self.origin),
            origin: self.origin,
            shade: self.shade(),
            has_wgpu: self.has_wgpu,
            view: &self.view,
            highlight: self.highlight(),
            legends: Legends {
                display: &self.display,
                view: &self.view,
                picked: self.picked_here().is_some(),
                picked_cluster: self.picked_cluster(),
                link_stats: self.geometry.link_stats,
                cluster_link_stats: self.geometry.cluster_link_stats,
                link_scale: self.geometry.link_scale,
                error_scale: self.geometry.error_scale,
                critical: self.critical_counts(),
                artifacts: self.artifacts(),
                error: (self.display.error && self.error_applies()).then(|| self.error_label()),
                busy: self.busy(),
                split_on: self.split.on,
                stale: self.stale_note(),
            },
        };
        viewport::paint(ui, rect, &picture);
        ui.horizontal(|_| {});
        let _ = response;
    }

    /// While a settings change is re-solved, the picture shown is the last finished solve's: what
    /// it is and what comes (`None` while the picture is the settings' own).
    #[must_use]
    pub fn stale_note(&self) -> Option<String> {
        let held = self.hold_view || (self.resolve_pending && self.view.params != self.params);
        if !held || self.view.elements.is_empty() || self.view.mesh.is_some() {
            return None;
        }
        let (shown, next) = (&self.view.params, &self.params);
        let what = super::history::oracle_threshold(shown);
        let target = super::history::oracle_threshold(next);
        let to = if what == target { "the new settings".to_owned() } else { target };
        Some(format!("Stale: the last finished solve ({what}), shown until the re-solve at {to} is ready"))
    }

    /// The blocking matrix at the top of the inspector column, beside the viewport (drawn
    /// before the viewport, so that a hovered block's link shows in the same frame). The matrix
    /// ↔ viewport link: the element hovered in the viewport (else the picked one) is
    /// highlighted in the matrix; a hovered block's link is highlighted in the viewport.
    fn matrix_panel(&mut self, ui: &mut egui::Ui) {
        self.matrix_hover = None;
        let element = self.viewport_hover.or(self.picked_here());
        match self.lecture.matrix_panel(ui, &self.view, element) {
            Some(MatrixAction::Pick(id)) => {
                self.selected = Some(id);
                self.selected_run = None;
                self.display.selected_links_only = true;
            }
            Some(MatrixAction::Hover(h)) => self.matrix_hover = Some(h),
            None => {}
        }
    }

    /// The camera's keys ([`OrbitCamera::keys`]; F frames the scene, R goes back to its camera).
    fn camera_keys(&mut self, ui: &egui::Ui) {
        let scene = self.scene.as_ref();
        self.camera.keys(ui, &self.home, || scene.map(|s| s.bounds()));
    }

    /// Name of the scene shown ("" without one).
    fn scene_name(&self) -> &str {
        self.scene.as_ref().map_or("", |s| s.name.as_str())
    }

    /// Before a pane view (split, replay) draws in place of the viewport: the camera's keys, and
    /// the current solution's build, which sets the auto exposure every pane shares. Returns how
    /// the panes draw.
    fn pane_frame(&mut self, ui: &egui::Ui) -> PaneStyle {
        self.viewport_rect = ui.available_rect_before_wrap();
        self.viewport_hover = None;
        self.camera_keys(ui);
        self.request_geometry();
        self.poll_geometry(false);
        PaneStyle {
            uniforms: viewport::uniforms(
                self.camera.view_proj(1.0, self.origin),
                self.shade(),
                ui.ctx().pixels_per_point(),
            ),
            origin: self.origin,
            has_wgpu: self.has_wgpu,
        }
    }

    /// The split view in place of the viewport: the runs of the history side by side, with the
    /// viewport's camera (its keys too) and exposure.
    fn split_view(&mut self, ui: &mut egui::Ui) {
        let style = self.pane_frame(ui);
        let settings = self.build_settings();
        let scene = self.scene.as_ref().map_or("", |s| s.name.as_str());
        let picked = self.selected.zip(self.selected_run).map(|(id, run)| (run, id));
        let input =
            SplitInput { history: &self.history, scene, camera: &mut self.camera, settings, style, picked };
        match self.split.ui(ui, input) {
            Some(SplitAction::OpenHistory) => self.history.open = true,
            Some(SplitAction::Pick { run, element }) => {
                self.selected = element;
                self.selected_run = element.map(|_| run);
                // The panes were drawn before the pick: outline it in the next frame.
                ui.ctx().request_repaint();
            }
            None => {}
        }
    }

    /// The refinement replay in place of the viewport.
    fn replay_view(&mut self, ui: &mut egui::Ui) {
        let style = self.pane_frame(ui);
        let settings = self.build_settings();
        self.replay.ui(ui, ReplayInput { camera: &mut self.camera, settings, style });
    }

    /// Where the viewport was drawn in the last frame (points).
    #[must_use]
    pub fn viewport_rect(&self) -> Rect {
        self.viewport_rect
    }

    /// The solver parameters in use.
    #[must_use]
    pub fn params(&self) -> HierarchicalParams {
        self.params
    }

    /// Frame the whole scene, keeping the view direction.
    pub fn frame_all(&mut self) {
        if let Some(s) = &self.scene {
            self.camera.reframe(&s.bounds());
        }
    }

    /// Pick the element under a viewport point; while the cluster boxes are drawn, the cluster
    /// around it at the levels shown too ([`clusters::at_shown_level`]).
    fn pick_at(&mut self, pos: Pos2, rect: Rect) {
        self.selected = self.pick_id(pos, rect);
        self.selected_run = None;
        let deepest = self.display.clusters_from.saturating_add(CLUSTER_LEVELS - 1);
        self.picked_cluster = self
            .selected
            .filter(|_| self.display.clusters)
            .and_then(|id| clusters::at_shown_level(&self.view, id, deepest));
    }

    /// The picked cluster: an index into the current solution's `clusters` that holds the
    /// picked element's patch (`None` without one, or when the element is a split pane's run's).
    #[must_use]
    pub fn picked_cluster(&self) -> Option<u32> {
        let c = self.picked_cluster?;
        self.picked_here().filter(|&id| clusters::chain_of_element(&self.view, id).contains(&c)).map(|_| c)
    }

    /// Pick cluster `c` of the current solution (`None`: the element alone); ignored unless it
    /// holds the picked element's patch (the inspector's up / down walk that chain).
    pub fn pick_cluster(&mut self, c: Option<u32>) {
        self.picked_cluster = c;
        if c.is_some() && self.picked_cluster().is_none() {
            self.picked_cluster = None;
        }
    }

    /// The leaf under a viewport point.
    fn pick_id(&self, pos: Pos2, rect: Rect) -> Option<u32> {
        pane::pick(&self.view, &self.camera, pos, rect)
    }

    /// The picked element when it is one of the current solution (not a split pane's run's).
    fn picked_here(&self) -> Option<u32> {
        self.selected.filter(|_| self.selected_run.is_none())
    }

    /// The picked element and the solution it belongs to (the current one, or a split pane's
    /// run's while that run keeps its solution).
    fn picked(&self) -> Option<(u32, &Arc<ViewData>)> {
        let id = self.selected?;
        match self.selected_run {
            None => Some((id, &self.view)),
            Some(n) => self.history.runs().iter().find(|r| r.number == n)?.view.as_ref().map(|v| (id, v)),
        }
    }

    /// What the viewport highlights this frame: the link of the matrix block hovered, else (while
    /// the matrix is open) the element under the pointer.
    #[must_use]
    pub fn highlight(&self) -> Option<Highlight> {
        self.matrix_hover.or(self.viewport_hover.map(Highlight::Element))
    }

    /// The leaf under the pointer in the viewport (tracked while the matrix window is open).
    #[must_use]
    pub fn viewport_hover(&self) -> Option<u32> {
        self.viewport_hover
    }

    /// Pick the element under a point given in viewport-relative coordinates (0..1, y down).
    pub fn pick_relative(&mut self, x: f32, y: f32) {
        let r = self.viewport_rect;
        if r.is_positive() {
            self.pick_at(Pos2::new(r.left() + x * r.width(), r.top() + y * r.height()), r);
        }
    }

    fn file_answer(&mut self, answer: Answer) {
        match answer {
            Answer::Chosen(Purpose::Open, path) => self.load_spec(&path.to_string_lossy()),
            Answer::Chosen(Purpose::ExportBake { lightmap, .. }, path) => self.export_bake(path, lightmap),
            Answer::Cancelled(_) => self.status_bar.message = "no file chosen".into(),
            Answer::FellBack(note) => self.status_bar.message = note,
        }
    }

    /// Write the solution shown as a baked glTF (on the solver thread), at the display's
    /// exposure: vertex colours per element, or with `lightmap` the original meshes with a
    /// lightmap of that size (the CLI's `--bake-lightmap SIZE`); the answer is one line in the
    /// status bar, or an error.
    pub fn export_bake(&mut self, path: PathBuf, lightmap: Option<u32>) {
        let Some(scene) = &self.scene else { return };
        let overwrites_input = std::fs::canonicalize(&path)
            .is_ok_and(|p| std::fs::canonicalize(&scene.source).is_ok_and(|s| s == p));
        if overwrites_input {
            self.errors.push(format!(
                "export {}: that is the scene shown; refusing to overwrite it",
                path.display()
            ));
            return;
        }
        let ev = self.display.exposure_ev;
        let options = crate::present::bake::BakeOptions {
            exposure: 2f64.powf(f64::from(ev)),
            exposure_rule: format!(
                "the viewer's exposure 2^EV, EV = {ev:.1}{}",
                if self.display.auto_exposure {
                    " (auto: the 95th percentile of the lit surfaces' luminance at 0.8)"
                } else {
                    ""
                }
            ),
            scene_label: self.scene_spec.clone(),
            params: serde_json::to_value(self.params).ok(),
        };
        let form = lightmap.map_or(crate::present::bake::BakeForm::Elements, |size| {
            crate::present::bake::BakeForm::Lightmap(crate::present::bake::LightmapParams::new(size))
        });
        self.send(Command::Bake { path, options, form }, "baking");
    }

    fn request_screenshot(&mut self, ctx: &egui::Context) {
        let (tx, rx) = channel();
        ctx.request_screenshot(move |img| {
            let _ = tx.send(img);
        });
        self.shot_rx = Some(rx);
        ctx.request_repaint();
    }

    fn handle_screenshot(&mut self, ctx: &egui::Context) {
        let Some(rx) = &self.shot_rx else { return };
        let Ok(img) = rx.try_recv() else {
            ctx.request_repaint();
            return;
        };
        self.shot_rx = None;
        let whole = self.opts.screenshot_window && self.script == Script::WaitingShot;
        let shot = script::crop(&img, self.viewport_rect, whole, ctx.pixels_per_point());
        let path = self.opts.screenshot.clone().unwrap_or_else(|| {
            let name = self.scene.as_ref().map_or("radlab".to_owned(), |s| s.name.clone());
            PathBuf::from(format!("{name}-{}.png", self.geometry.generation))
        });
        let saved = match shot.save_png(&path) {
            Ok(()) => {
                self.status_bar.message = format!("saved {}", path.display());
                true
            }
            Err(e) => {
                self.errors.push(format!("screenshot: {e}"));
                self.script_failed(format!("screenshot: {e}"));
                false
            }
        };
        if self.script == Script::WaitingShot {
            if saved {
                println!("radlab: wrote {}", path.display());
            }
            self.script = Script::Done;
            self.exit_code.get_or_insert(0);
        }
    }

    fn run_script(&mut self, ctx: &egui::Context) {
        // The display is final when the newest build is shown and the reference thread has
        // nothing left to report (its look-up or a score changes the error overlay).
        let current = self.geometry.current()
            && !self.split.building()
            && !self.replay.building()
            && !self.reference.busy()
            && !self.artifacts.busy();
        match &mut self.script {
            Script::None | Script::Done | Script::WaitingShot => {}
            Script::Solving => {
                if self.opts.bench_frames.is_some() {
                    // Keep drawing while the solver runs: the UI must not wait on it.
                    self.solve_frames.tick(Instant::now(), self.last_ui_s, self.last_ui_cpu_s);
                    self.camera.orbit(0.002, 0.0);
                    ctx.request_repaint();
                }
            }
            Script::Settle(n) => {
                let n = *n;
                if n == 0 {
                    // The display thread may still be building the last change.
                    if current {
                        self.script = Script::WaitingShot;
                        self.request_screenshot(ctx);
                    }
                } else {
                    self.script = Script::Settle(n - 1);
                }
                ctx.request_repaint();
            }
            Script::Bench { warmup, bench } => {
                if *warmup > 0 || !current {
                    *warmup -= usize::from(current && *warmup > 0);
                } else {
                    bench.tick(Instant::now(), self.last_ui_s, self.last_ui_cpu_s);
                }
                // Spin the camera a little so every frame really redraws.
                self.camera.orbit(0.002, 0.0);
                if bench.frames() >= self.opts.bench_frames.unwrap_or(0) {
                    let scene = BenchScene {
                        elements: self.view.stats.elements,
                        leaves: self.view.leaves.len(),
                        triangles: self.geometry.geometry.mesh.triangles(),
                        links: self.view.links.len(),
                        links_drawn: self.geometry.geometry.links.len() / 2,
                        quadtree: self.display.quadtree,
                        rebuild_s: self.geometry.rebuild_s,
                        max_upload_s: self.max_upload_s,
                    };
                    script::print_bench(bench, &self.solve_frames, &scene);
                    self.script = Script::Done;
                    self.exit_code.get_or_insert(0);
                }
                ctx.request_repaint();
            }
        }
    }
}

impl eframe::App for RadlabApp {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let started = Instant::now();
        let cpu_started = self.opts.bench_frames.and_then(|_| super::bench::thread_cpu_s());
        if let Some(rs) = frame.wgpu_render_state()
            && let Some(r) = rs.renderer.read().callback_resources.get::<SceneRenderer>()
        {
            self.max_upload_s = self.max_upload_s.max(r.last_upload_s);
        }
        let ctx = ui.ctx().clone();
        self.poll_worker();
        self.poll_reference();
        self.request_artifacts();
        self.artifacts.poll(false);
        self.shortcuts(&ctx);
        if let Some([x, y]) = self.pending_pick
            && !self.busy()
            && !self.view.links.is_empty()
            && self.viewport_rect.is_positive()
        {
            self.pick_relative(x, y);
            self.display.selected_links_only = true;
            self.pending_pick = None;
        }
        help::window(&ctx, &mut self.show_help);
        if self.history.open && self.history.window(&ctx) == Some(HistoryAction::ShowSplit) {
            self.split.on = true;
        }
        self.lecture.windows(&ctx);
        if let Some(answer) = self.files.show(&ctx) {
            self.file_answer(answer);
        }
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

        let mut frame = egui::Frame::side_top_panel(ui.style());
        if self.panels_from_clear {
            frame = frame.fill(Color32::TRANSPARENT);
        }
        egui::Panel::top("top").frame(frame).show(ui, |ui| self.top_bar(ui));
        egui::Panel::bottom("status").frame(frame).show(ui, |ui| {
            let input = StatusInput {
                view: &self.view,
                last_report: self.last_report.as_ref(),
                last_solve: self.last_solve,
            };
            self.status_bar.ui(ui, input);
        });
        self.dragging = ctx.dragged_id().is_some();
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
                egui::ScrollArea::vertical().auto_shrink([false, false]).id_salt("inspector_scroll").show(
                    ui,
                    |ui| {
                        self.matrix_panel(ui);
                        // The true error is the current solution's.
                        let true_error = self.true_error().filter(|_| self.selected_run.is_none()).cloned();
                        let picked = self.picked().map(|(id, v)| (id, Arc::clone(v)));
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
                                view: &self.view,
                                history: &self.history,
                                error_samples: &self.error_samples,
                                marks: &self.resolve_marks,
                                ruler,
                            };
                            self.plots.ui(ui, input);
                        }
                    },
                );
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

        self.report_thread_panics();
        self.handle_screenshot(&ctx);
        self.run_script(&ctx);
        if self.busy() {
            ctx.request_repaint_after(std::time::Duration::from_millis(100));
        }
        if let Some(code) = self.exit_code
            && (self.script == Script::Done || code != 0)
        {
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
        self.last_ui_s = started.elapsed().as_secs_f64();
        self.last_ui_cpu_s = cpu_started.and_then(|a| super::bench::thread_cpu_s().map(|b| b - a));
    }
}
