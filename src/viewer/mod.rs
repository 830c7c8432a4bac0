//! The interactive viewer (feature `gui`): an eframe/egui app with a wgpu viewport.
//!
//! - [`app`]: the app: owns the threads and the state shown, lays the panels out and routes their
//!   answers; the viewport (camera, picking, paint callback), files, drag-and-drop. Its state,
//!   one struct per concern: [`solve`] (the solver thread, its settings and work), [`shown`] (the
//!   state shown and the one held back), [`solve_log`] (solver time, error samples, warm and cold
//!   solves), [`comparison`] (the reference and the scores of the state shown), [`pick`] (the
//!   pick and the hovers), [`framing`] (the camera, the viewport's place), [`drag`] (a slider
//!   drag as one run of the history).
//! - [`view`]: the small `View` trait every panel implements (one type per panel). The panels:
//!   [`top_bar`] (menus, scene field) with [`mesh_menu`]; [`solver_panel`] (settings, steps,
//!   progress line); [`reference_panel`]; [`display`] (the `Display` settings and their
//!   section); [`inspector`] (with [`clusters`]: the picked cluster); [`plots`]; [`status_bar`]; [`history`] (the run history: every
//!   solve kept, the table, the runs overlaid in the plots); [`split`] (two or three runs side by
//!   side, one camera, one exposure; a click picks in a pane's run); [`replay`] (the last solve
//!   round by round, the depth slider); [`matrix`] (the blocking form-factor matrix window).
//! - [`viewport`]: the viewport's picture (paint callback, uniforms); [`legends`]: the overlays'
//!   legends and the matrix highlight drawn over it.
//! - [`pane`]: one solver state drawn beside the viewport (the split view's and replay's panes),
//!   and picking.
//! - [`geometry`]: the viewport's display build (what it was asked for, the numbers it brings).
//! - [`artifacts`]: the `radlab-artifacts` thread that measures the artifact overlays.
//! - [`bench`](mod@bench): frame-time statistics of `--bench-frames`; [`script`]: the scripted runs
//!   (what they wait for, and how they end).
//! - [`builder`]: the `radlab-display` thread that builds GPU vertex arrays off the UI thread.
//! - [`camera`]: orbit / pan / zoom camera and its keys.
//! - [`file_dialog`]: the desktop's file dialog, or an in-app one where none answers.
//! - [`five_times`]: the five-times explorer (exact, disk and point-source form factors).
//! - [`help`]: keyboard shortcuts, the Help menu and window.
//! - [`lecture`]: the Lecture menu (the figures of [`crate::present::figures`]) and the caption panel.
//! - [`options`]: how the viewer starts (`ViewerOptions`).
//! - [`panics`]: a panic on any of these threads becomes a message and, in a scripted run, an
//!   error exit.
//! - [`reference`](mod@reference): the `radlab-reference` thread: cached/computed reference, true error.
//! - [`widgets`]: small widgets the panels share (the log slider).
//! - [`worker`]: the `radlab-solver` thread that owns the hierarchical solver (what the UI sends
//!   and receives); [`solver_thread`]: the thread's side, one command at a time.
//!
//! Rendering is in [`crate::render`]; display lists in [`crate::present::overlay`].

pub mod app;
pub mod artifacts;
pub mod bench;
pub mod builder;
pub mod camera;
pub mod clusters;
pub mod comparison;
pub mod display;
pub mod drag;
pub mod file_dialog;
pub mod five_times;
pub mod framing;
pub mod geometry;
pub mod help;
pub mod history;
pub mod inspector;
pub mod lecture;
pub mod legends;
pub mod matrix;
pub mod mesh_menu;
pub mod options;
pub mod pane;
pub mod panics;
pub mod pick;
pub mod plots;
pub mod reference;
pub mod reference_panel;
pub mod replay;
pub mod script;
pub mod shown;
pub mod solve;
pub mod solve_log;
pub mod solver_panel;
pub mod solver_thread;
pub mod split;
pub mod status_bar;
pub mod top_bar;
pub mod view;
pub mod viewport;
pub mod widgets;
pub mod worker;

pub use app::RadlabApp;
pub use display::{Display, Shading};
use eframe::egui;
pub use options::ViewerOptions;
pub use reference::RefSettings;
pub use reference_panel::RefState;
use std::sync::{Arc, Mutex};

/// Why the viewer could not run.
#[derive(Debug, thiserror::Error)]
pub enum ViewerError {
    #[error("no display (neither DISPLAY nor WAYLAND_DISPLAY is set); use `radlab solve` for headless work")]
    NoDisplay,
    #[error("cannot open a window: {0}; use `radlab solve` for headless work")]
    Window(String),
    #[error("{0}")]
    Script(String),
}

/// True if a window system is reachable (checked before creating the event loop, which would
/// otherwise panic or fail with a long message).
#[must_use]
pub fn display_available() -> bool {
    let set = |k: &str| std::env::var_os(k).is_some_and(|v| !v.is_empty());
    set("DISPLAY") || set("WAYLAND_DISPLAY")
}

/// Open the window and run until it is closed (or a scripted run finishes).
pub fn run(opts: ViewerOptions) -> Result<(), ViewerError> {
    if !display_available() {
        return Err(ViewerError::NoDisplay);
    }
    let scripted =
        opts.screenshot.is_some() || opts.bench_frames.is_some() || !opts.bench_thresholds.is_empty();
    // A panic caught on a viewer thread is reported by the app (status bar; a scripted run's
    // one-line error), not printed by the default hook as well.
    panics::install_hook();
    let mut native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("radlab")
            .with_inner_size([1280.0, 800.0])
            .with_drag_and_drop(true),
        // Dithering only matters for gradients (egui draws none); on a CPU rasteriser it is
        // per-pixel work in every egui draw.
        dithering: false,
        // A depth buffer on egui's pass: the 3-D view is drawn straight into it.
        depth_buffer: crate::render::HOST_DEPTH_BITS,
        ..eframe::NativeOptions::default()
    };
    let opts = ViewerOptions { direct_viewport: true, ..opts };
    if opts.bench_frames.is_some() {
        // Measure drawing, not the display's refresh.
        native.wgpu_options.surface.present_mode = eframe::wgpu::PresentMode::AutoNoVsync;
    }
    let exit: ExitSlot = Arc::new(Mutex::new(None));
    let exit_app = Arc::clone(&exit);
    let result = eframe::run_native(
        "radlab",
        native,
        Box::new(move |cc| {
            let mut app = RadlabApp::new(cc, opts);
            app.panels_from_clear = true;
            Ok(Box::new(ExitReporter { app, exit: exit_app }))
        }),
    );
    result.map_err(|e| ViewerError::Window(e.to_string()))?;
    let code = exit.lock().map_or(None, |mut g| g.take());
    match code {
        // One line on stderr: the run's first failure (the binary prints it).
        Some((c, why)) if c != 0 && scripted => {
            Err(ViewerError::Script(why.unwrap_or_else(|| "the scripted run failed".into())))
        }
        _ => Ok(()),
    }
}

/// The app's exit code and, when it failed, why (one line), passed out of eframe.
type ExitSlot = Arc<Mutex<Option<(i32, Option<String>)>>>;

/// Passes the app's exit code, and why it failed, out of eframe.
struct ExitReporter {
    app: RadlabApp,
    exit: ExitSlot,
}

impl eframe::App for ExitReporter {
    /// The panels' colour: the panels are drawn unfilled over it (`panels_from_clear`).
    fn clear_color(&self, visuals: &egui::Visuals) -> [f32; 4] {
        visuals.panel_fill.to_normalized_gamma_f32()
    }

    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        self.app.ui(ui, frame);
        if let Some(c) = self.app.exit_code()
            && let Ok(mut g) = self.exit.lock()
        {
            *g = Some((c, self.app.exit_error().map(str::to_owned)));
        }
    }
}
