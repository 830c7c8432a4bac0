//! How the viewer starts ([`ViewerOptions`]: the `radlab view` flags, the overlays of
//! `--overlay` among them as the [`Display`] it opens with).

use super::display::Display;
use super::reference::RefSettings;
use crate::present::figures::Figure;
use crate::solver::meshed::{DisplayReconstruction, MeshSolveParams};
use std::path::PathBuf;

/// How the viewer starts.
#[derive(Clone, Debug)]
pub struct ViewerOptions {
    /// `builtin:NAME` or a path; empty: start without a scene (tests call `set_scene`).
    pub scene: String,
    /// The preset asked for (`--preset`): the viewer opens at exactly that one. `None`: at the
    /// default, [`Preset::DEFAULT`](crate::solver::spec::Preset::DEFAULT), reached in two steps
    /// when the scene opens solved (not in a refinement replay): a first picture at
    /// [`FIRST_PICTURE`](super::solve::FIRST_PICTURE), then a warm re-solve on to the default
    /// ([`Opening`](super::solve::Opening)).
    pub preset: Option<String>,
    /// What is shown at start: the overlays `radlab view --overlay` turns on (its `Overlay`
    /// values name these settings; a lecture figure's own replace them).
    pub display: Display,
    /// Solve with the current preset whenever a scene is loaded (at start, Load, Open, a
    /// dropped file), on the solver thread: the viewer opens on a solved scene. Off: the input
    /// patches, unsolved, for stepping by hand.
    pub solve_on_start: bool,
    /// Scripted use: write the viewport to this PNG once solved, then close.
    pub screenshot: Option<PathBuf>,
    /// Benchmark: after solving, draw this many frames, print the median frame time, close.
    pub bench_frames: Option<usize>,
    /// Benchmark: after solving, set the threshold (ε, BFeps) to each of these in turn, as the
    /// Solver panel's slider does, print how long each new picture took to be on screen, close.
    pub bench_thresholds: Vec<f64>,
    /// Pick the element under this viewport point once solved (fractions of the viewport,
    /// y down), and show its links (scripted screenshots of the inspector).
    pub pick: Option<[f32; 2]>,
    /// Scripted screenshots capture the whole window instead of the viewport.
    pub screenshot_window: bool,
    /// Show the plots window open.
    pub show_plots: bool,
    /// Where the reference solution comes from (settings and disk cache).
    pub reference: RefSettings,
    /// Try the desktop's file dialog (xdg portal) before the in-app one (tests turn it off).
    pub desktop_file_dialog: bool,
    /// egui's render pass has a [`crate::render::DEPTH_FORMAT`] depth buffer (the native window
    /// asks for one): draw the 3-D view straight into it instead of through an offscreen copy.
    pub direct_viewport: bool,
    /// Open this lecture figure instead of `scene` (its settings, overlays, camera, caption).
    pub figure: Option<&'static Figure>,
    /// Then these lecture figures, in turn: each opens once the solves before it are done, so
    /// that each leaves its runs in the history (the split view sets them side by side).
    pub then_figures: Vec<&'static Figure>,
    /// Open the split view with this many panes (2 or 3).
    pub split: Option<usize>,
    /// Open the run history window.
    pub show_history: bool,
    /// Open the refinement replay at this frame of the first solve (0: its start).
    pub replay: Option<usize>,
    /// Cut the quadtrees at this depth in the refinement replay.
    pub depth_cut: Option<u8>,
    /// The mesh solved on (`None`: the quadtree, the hierarchical solver).
    pub mesh: Option<MeshSolveParams>,
    /// How the solution is drawn (`None`: each element's own function, its value with its slope).
    pub reconstruction: Option<DisplayReconstruction>,
}

impl Default for ViewerOptions {
    fn default() -> Self {
        ViewerOptions {
            scene: "builtin:cornell".into(),
            preset: None,
            display: Display::default(),
            solve_on_start: true,
            screenshot: None,
            bench_frames: None,
            bench_thresholds: Vec::new(),
            pick: None,
            screenshot_window: false,
            show_plots: false,
            reference: RefSettings::default(),
            desktop_file_dialog: true,
            direct_viewport: false,
            figure: None,
            then_figures: Vec::new(),
            split: None,
            show_history: false,
            replay: None,
            depth_cut: None,
            mesh: None,
            reconstruction: None,
        }
    }
}
