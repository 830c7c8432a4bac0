//! The split view: two or three solutions of the run history ([`super::history`]) side by side,
//! seen through **one camera** with **one exposure**, so that what differs between the panes is
//! the solution alone: reference-quality settings against interactive ones, two thresholds, two
//! oracles. Each pane is labelled with its run's settings (preset, oracle, thresholds), size,
//! solver time and error (against the reference, or the solver's estimate, labelled so).
//!
//! ```text
//!  ┌ #3 cornell · interactive ─┐┌ #5 cornell · custom ──────┐
//!  │ BF oracle, BFeps 2.0e-3 … ││ Feps oracle, Feps 5.0e-3 …│   drag in any pane: the one
//!  │ 761 elements · 0.42 s · … ││ 2.3k elements · 1.9 s · … │   camera orbits, every pane
//!  │        (slot 1)           ││        (slot 2)           │   follows
//!  └───────────────────────────┘└───────────────────────────┘
//! ```
//!
//! Each pane builds its geometry from its run's solution with the main view's display settings
//! (shading or error heatmap, quadtree, links; not the picked element, whose id means nothing in
//! another solution) on its own `radlab-display` thread ([`super::builder`]), and draws through the
//! viewport's renderer into its own slot ([`crate::render::ViewportCallback::slot`]). The error
//! heatmap of a pane shows the solver's estimate (the true error is computed for the current
//! solution only).

use super::builder::{self, Builder, Settings};
use super::camera::OrbitCamera;
use super::history::{Run, RunHistory};
use super::view::View;
use crate::math::DVec3;
use crate::render::{FrameParams, Geometry, NO_SELECTION, OVERLAY_PICKED, Uniforms, ViewportCallback};
use eframe::egui::{self, Color32, Rect, Sense, Vec2};
use eframe::egui_wgpu;
use std::sync::Arc;

/// Gap between two panes, points.
const GAP: f32 = 3.0;
/// Fill of a pane's column around its picture (the viewport's background).
const PANE_BACKGROUND: Color32 = Color32::from_rgb(20, 20, 26);

/// What the app lends the split view for one frame.
pub struct SplitInput<'a> {
    pub history: &'a RunHistory,
    /// The one camera of the viewport and every pane.
    pub camera: &'a mut OrbitCamera,
    /// The main view's display settings (the picked element's link filter is dropped).
    pub settings: Settings,
    /// The main view's uniforms (exposure, tone map, overlays); each pane sets its own
    /// view-projection (aspect) and no picked element.
    pub uniforms: Uniforms,
    /// Scene centre subtracted from positions (as in `settings.origin`).
    pub origin: DVec3,
    /// A wgpu renderer is there to draw with.
    pub has_wgpu: bool,
}

/// What the split view asks of the app.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum SplitAction {
    /// Open the run history (to pick the runs shown).
    OpenHistory,
}

/// One pane: the run it shows and that run's geometry.
struct Pane {
    /// (run number, settings) the newest build was requested for.
    key: Option<(usize, Settings)>,
    builder: Option<Builder>,
    seq: u64,
    geometry: Arc<Geometry>,
    /// Bumped when `geometry` changes (the renderer uploads only then).
    generation: u64,
    /// Sequence number of the build shown.
    shown_seq: Option<u64>,
}

impl Pane {
    fn show(&mut self, geometry: Arc<Geometry>, generation: u64) {
        self.geometry = geometry;
        self.generation = generation;
    }
}

/// The split view's state: on or off, how many panes, and each pane's geometry.
#[derive(Default)]
pub struct SplitView {
    pub on: bool,
    /// Panes filled with the newest runs when fewer than two are picked (2 or 3).
    pub panes: usize,
    slots: Vec<Pane>,
    /// Generations handed out so far (unique over all panes).
    generations: u64,
    /// What the last frame showed: (run number, pane rectangle).
    shown: Vec<(usize, Rect)>,
}

impl SplitView {
    #[must_use]
    pub fn new() -> SplitView {
        SplitView { panes: 2, ..SplitView::default() }
    }

    /// The runs shown in the last frame and where: (run number, the rectangle of its picture).
    #[must_use]
    pub fn shown(&self) -> &[(usize, Rect)] {
        &self.shown
    }

    /// True when the split view can show: on, and two runs with a solution to show.
    #[must_use]
    pub fn active(&self, history: &RunHistory) -> bool {
        self.on && history.split_runs(self.panes).len() >= 2
    }

    /// Block until every pane's newest geometry is built (tests and scripted runs only).
    pub fn wait(&mut self) {
        for p in &mut self.slots {
            if let Some(b) = p.builder.as_mut().and_then(Builder::wait) {
                self.generations += 1;
                p.shown_seq = Some(b.seq);
                p.show(b.geometry, self.generations);
            }
        }
    }

    /// True while a pane waits for its geometry.
    #[must_use]
    pub fn building(&self) -> bool {
        self.slots.iter().any(|p| p.builder.as_ref().is_some_and(|b| b.requested > p.shown_seq))
    }

    /// The geometry of pane `i` for `run`: asks for a build when the run or the settings
    /// changed, and picks up a finished one.
    fn pane_geometry(
        &mut self,
        ctx: &egui::Context,
        i: usize,
        run: &Run,
        settings: Settings,
    ) -> (Arc<Geometry>, u64) {
        while self.slots.len() <= i {
            self.slots.push(Pane {
                key: None,
                builder: None,
                seq: 0,
                geometry: Arc::new(Geometry::default()),
                generation: 0,
                shown_seq: None,
            });
        }
        let p = &mut self.slots[i];
        let key = (run.number, settings);
        if p.key.as_ref() != Some(&key)
            && let Some(view) = &run.view
        {
            p.seq += 1;
            let req = builder::Request {
                seq: p.seq,
                view: Arc::clone(view),
                view_seq: run.view_seq,
                true_error: None,
                settings,
            };
            p.key = Some(key);
            if p.builder.is_none() {
                let ctx = ctx.clone();
                p.builder = Builder::spawn(move || ctx.request_repaint()).ok();
            }
            match &mut p.builder {
                Some(b) => b.request(req),
                None => {
                    // No thread: build here (slower, correct).
                    self.generations += 1;
                    p.show(builder::build(&req).geometry, self.generations);
                }
            }
        }
        if let Some(b) = p.builder.as_mut().and_then(Builder::poll) {
            self.generations += 1;
            p.show(b.geometry, self.generations);
            p.shown_seq = Some(b.seq);
        }
        (Arc::clone(&p.geometry), p.generation)
    }
}

impl View for SplitView {
    type Input<'a> = SplitInput<'a>;
    type Action = SplitAction;

    /// The panes, side by side over the whole of `ui`'s available rectangle.
    fn ui(&mut self, ui: &mut egui::Ui, input: SplitInput<'_>) -> Option<SplitAction> {
        let SplitInput { history, camera, mut settings, uniforms, origin, has_wgpu } = input;
        // The picked element's id means nothing in another solution.
        if settings.links.is_some_and(|f| f.element.is_some()) {
            settings.links = None;
        }
        let runs = history.split_runs(self.panes);
        let full = ui.available_rect_before_wrap();
        let n = runs.len().max(1);
        let w = (full.width() - GAP * (n - 1) as f32) / n as f32;
        let ppp = ui.ctx().pixels_per_point();
        let mut action = None;
        self.shown.clear();
        for (i, run) in runs.iter().enumerate() {
            let column = Rect::from_min_size(
                full.min + Vec2::new(i as f32 * (w + GAP), 0.0),
                Vec2::new(w, full.height()),
            );
            let response = ui.allocate_rect(column, Sense::click_and_drag());
            ui.painter().rect_filled(column, 0.0, PANE_BACKGROUND);
            // The label on top, then the viewport's picture scaled to the column (the viewport's
            // aspect: one camera, one framing in every pane).
            let (band, history_asked) = label(ui, column, run);
            if history_asked {
                action = Some(SplitAction::OpenHistory);
            }
            let pic_h = (w * full.height() / full.width().max(1.0)).min(full.height() - band);
            let rect = Rect::from_min_size(column.min + Vec2::new(0.0, band), Vec2::new(w, pic_h.max(1.0)));
            camera.interact(ui, &response, rect);
            let (geometry, generation) = self.pane_geometry(ui.ctx(), i, run, settings);
            let painter = ui.painter_at(rect);
            if has_wgpu {
                let aspect = f64::from(rect.width() / rect.height().max(1.0));
                let m = camera.view_proj(aspect, origin).to_cols_array_2d();
                let frame = FrameParams {
                    uniforms: Uniforms {
                        view_proj: m.map(|c| c.map(|x| x as f32)),
                        selected: NO_SELECTION,
                        overlay: uniforms.overlay & !OVERLAY_PICKED,
                        ..uniforms
                    },
                    size: [
                        (rect.width() * ppp).round().max(1.0) as u32,
                        (rect.height() * ppp).round().max(1.0) as u32,
                    ],
                };
                painter.add(egui_wgpu::Callback::new_paint_callback(
                    rect,
                    ViewportCallback { frame, geometry, generation, slot: i + 1 },
                ));
            } else {
                painter.rect_filled(rect, 0.0, Color32::from_gray(20));
            }
            self.shown.push((run.number, rect));
        }
        for i in 1..n {
            let x = full.left() + i as f32 * (w + GAP) - 0.5 * GAP;
            ui.painter().vline(x, full.y_range(), egui::Stroke::new(GAP, Color32::from_gray(60)));
        }
        action
    }
}

/// The pane's label at the top of its column: run, settings, numbers. Returns the height it
/// takes and whether its "runs…" button was clicked.
fn label(ui: &mut egui::Ui, rect: Rect, run: &Run) -> (f32, bool) {
    let mut clicked = false;
    let mut child = ui.new_child(
        egui::UiBuilder::new().max_rect(rect.shrink(4.0)).layout(egui::Layout::top_down(egui::Align::Min)),
    );
    let frame = egui::Frame::new()
        .fill(Color32::from_black_alpha(170))
        .corner_radius(4.0)
        .inner_margin(6.0)
        .show(&mut child, |ui| {
            ui.set_width(ui.available_width());
            let white = |t: String| egui::RichText::new(t).color(Color32::WHITE);
            ui.horizontal(|ui| {
                ui.add(
                    egui::Label::new(white(run.title()).strong())
                        .selectable(false)
                        .wrap_mode(egui::TextWrapMode::Truncate),
                );
                clicked = ui
                    .small_button("runs…")
                    .on_hover_text("Pick the runs shown side by side (the run history)")
                    .clicked();
            });
            for line in [run.thresholds(), run.numbers()] {
                ui.add(
                    egui::Label::new(white(line).small())
                        .selectable(false)
                        .wrap_mode(egui::TextWrapMode::Wrap),
                );
            }
        });
    (frame.response.rect.bottom() - rect.top() + 4.0, clicked)
}
