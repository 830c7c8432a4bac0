//! The refinement replay: the last solve as it went, scrubbed with a slider — the state it started
//! from, the state after each round of the HSA91 loop (refine the links the oracle rejects, then
//! gather; [`crate::solver::hierarchical::HierarchicalSolver::solve_observed`]), and the result —
//! with the mesh, the links and the radiosity as they were then. A depth slider cuts the
//! quadtrees at a level: every element below it is drawn as its ancestor at that depth (with the
//! area average of its radiosity, as push-pull leaves it), and only the links between elements at
//! or above it are drawn, so the hierarchy can be shown level by level.
//!
//! ```text
//!  round ─────●──────────  after round 2 of 5 · 412 elements · 3 021 links · residual 2e-3
//!  [x] cut at depth ──●──  3
//!  ┌──────────────────────────────────────────────┐
//!  │      the frame, with the viewport's camera    │   (renderer slot REPLAY_SLOT)
//!  └──────────────────────────────────────────────┘
//! ```
//!
//! The frames come from the solver thread (`worker::Reply::Replay`, at most
//! `worker::REPLAY_BUDGET_BYTES` of them); they carry no error estimates (computing them each
//! round would cost a good part of the solve), so the error heatmap shows only on the result.

use super::builder::{Coloring, Settings};
use super::camera::OrbitCamera;
use super::pane::{Pane, PaneStyle};
use super::split::PANE_BACKGROUND;
use super::view::View;
use super::worker::{Estimates, ViewData};
use eframe::egui::{self, Rect, Sense};
use std::sync::Arc;

/// Width of the round and depth sliders, points (one step of a 20-round solve is a finger wide).
const SLIDER_W: f32 = 240.0;

/// Renderer slot of the replay (the viewport is 0, the split view's panes 1 to 3).
pub const REPLAY_SLOT: usize = 4;

/// What the app lends the replay for one frame.
pub struct ReplayInput<'a> {
    /// The viewport's camera.
    pub camera: &'a mut OrbitCamera,
    /// The main view's display settings.
    pub settings: Settings,
    pub style: PaneStyle,
}

/// The replay's frames, the one shown and the depth cut.
pub struct Replay {
    pub on: bool,
    frames: Vec<Arc<ViewData>>,
    /// Index of the frame shown.
    pub position: usize,
    /// Show the quadtrees down to this depth (`None`: to the leaves).
    pub depth: Option<u8>,
    /// Where the slider goes when the next frames arrive (`radlab view --replay`); else the result.
    pub start_at: Option<usize>,
    /// Bumped by every new set of frames (with `position`, it names the state the pane shows).
    epoch: u64,
    pane: Pane,
}

impl Default for Replay {
    fn default() -> Self {
        Replay {
            on: false,
            frames: Vec::new(),
            position: 0,
            depth: None,
            start_at: None,
            epoch: 0,
            pane: Pane::new(REPLAY_SLOT),
        }
    }
}

impl Replay {
    /// The frames of a finished solve and its result; the slider goes to the result (or to
    /// `start_at`, once).
    pub fn set_frames(&mut self, mut frames: Vec<Arc<ViewData>>, result: Arc<ViewData>) {
        frames.push(result);
        self.position = self.start_at.take().unwrap_or(usize::MAX).min(frames.len() - 1);
        self.frames = frames;
        self.epoch += 1;
    }

    /// The error estimates of the result `of` arrived (`view`: it with them): the last frame
    /// shows them.
    pub fn fold_estimates(&mut self, of: &Arc<ViewData>, view: &Arc<ViewData>) {
        if let Some(last) = self.frames.last_mut().filter(|f| Arc::ptr_eq(f, of)) {
            *last = Arc::clone(view);
        }
    }

    /// Whether the last frame is state `of` (the one [`Self::fold_estimates`] replaces).
    #[must_use]
    pub fn keeps(&self, of: &Arc<ViewData>) -> bool {
        self.frames.last().is_some_and(|f| Arc::ptr_eq(f, of))
    }

    /// Forget the frames (another scene).
    pub fn clear(&mut self) {
        self.frames.clear();
        self.position = 0;
        self.epoch += 1;
    }

    /// Frames to scrub through (the start, the rounds, the result).
    #[must_use]
    pub fn frames(&self) -> usize {
        self.frames.len()
    }

    /// The frame shown.
    #[must_use]
    pub fn frame(&self) -> Option<&Arc<ViewData>> {
        self.frames.get(self.position)
    }

    /// Block until the frame's geometry is built (tests and scripted runs only).
    pub fn wait(&mut self) {
        self.pane.wait();
    }

    /// True while the frame's geometry is being built.
    #[must_use]
    pub fn building(&self) -> bool {
        self.pane.building()
    }

    /// Why the frame's failed build failed, once.
    pub fn take_failure(&mut self) -> Option<String> {
        self.pane.take_failure()
    }

    /// What frame `i` is, in words.
    #[must_use]
    pub fn describe(&self, i: usize) -> String {
        let Some(v) = self.frames.get(i) else { return String::new() };
        let n = self.frames.len();
        let when = if i == 0 {
            "start".to_owned()
        } else if i + 1 == n {
            "result".to_owned()
        } else {
            format!("after round {i} of {}", n - 1)
        };
        let residual = v.residuals.last().map_or(String::new(), |r| format!(" · residual {r:.1e}"));
        format!(
            "{when}: {} elements · {} links · {} gathers{residual}",
            v.stats.leaves,
            v.stats.links,
            v.residuals.len()
        )
    }
}

impl View for Replay {
    type Input<'a> = ReplayInput<'a>;
    type Action = ();

    /// The sliders over the frame, which fills the rest of `ui`.
    fn ui(&mut self, ui: &mut egui::Ui, input: ReplayInput<'_>) -> Option<()> {
        let ReplayInput { camera, mut settings, style } = input;
        let full = ui.available_rect_before_wrap();
        ui.painter().rect_filled(full, 0.0, PANE_BACKGROUND);
        let mut bar = ui.new_child(egui::UiBuilder::new().max_rect(full.shrink(6.0)));
        bar.spacing_mut().slider_width = SLIDER_W;
        if self.frames.is_empty() {
            bar.label("Refinement replay: press Solve; its rounds are recorded here, to scrub through.");
        } else {
            let last = self.frames.len() - 1;
            bar.horizontal(|ui| {
                ui.label("round");
                ui.add_enabled(last > 0, egui::Slider::new(&mut self.position, 0..=last).show_value(false))
                    .on_hover_text(
                        "Scrub through the last solve: its start, the state after each round of refine + \
                         gathers, its result (mesh, links and radiosity as they were)",
                    );
                // Wrapped in the room beside the slider, not cut at the viewport's edge.
                ui.add(egui::Label::new(self.describe(self.position)).wrap());
            });
            let deepest = self.frame().map_or(0, |v| v.stats.depth_histogram.len().saturating_sub(1));
            let deepest = u8::try_from(deepest).unwrap_or(u8::MAX);
            bar.horizontal(|ui| {
                let mut cut = self.depth.is_some();
                ui.checkbox(&mut cut, "cut at depth").on_hover_text(
                    "Show the quadtrees down to a level: deeper elements drawn as their ancestor there \
                     (area-averaged radiosity), and only the links at or above it",
                );
                let mut d = self.depth.unwrap_or(deepest).min(deepest);
                ui.add_enabled(cut, egui::Slider::new(&mut d, 0..=deepest.max(1)))
                    .on_hover_text("Quadtree depth (0: the input patches)");
                self.depth = cut.then_some(d);
            });
        }
        let top = bar.min_rect().bottom() + 6.0;
        let rect = Rect::from_min_max(egui::pos2(full.left(), top), full.max);
        if rect.height() < 1.0 {
            return None;
        }
        let response = ui.allocate_rect(rect, Sense::click_and_drag());
        camera.interact(ui, &response, rect);
        let view = self.frames.get(self.position)?;
        // Frames before the result carry no estimates (nor the result before they come, or where
        // they were given up): the heatmap would be blank.
        let estimated = self.position + 1 == self.frames.len() && view.estimates == Estimates::Included;
        if settings.coloring == Coloring::Error && !estimated {
            settings.coloring = Coloring::Smooth;
        }
        if settings.links.is_some_and(|f| f.element.is_some()) {
            settings.links = None;
        }
        settings.depth_limit = self.depth;
        let key = (self.epoch << 20) | self.position as u64;
        self.pane.update(ui.ctx(), key, view, settings);
        self.pane.paint(ui, rect, camera, style, None);
        None
    }
}
