//! A pane: one solver state drawn in a rectangle of its own, beside (or instead of) the viewport,
//! with the viewport's camera and exposure. The split view ([`super::split`]) shows two or three,
//! the refinement replay ([`super::replay`]) one.
//!
//! A pane builds its geometry on its own `radlab-display` thread ([`super::builder`]) whenever the
//! state or the display settings change, and draws through the viewport's renderer into a slot
//! of its own ([`crate::render::ViewportCallback::slot`]). A build that panics leaves the pane's
//! picture as it was and says why once ([`Pane::take_failure`]). [`pick`] finds the element under
//! a point of a pane (or of the viewport).

use super::builder::{self, BuildFailed, Builder, Coloring, Settings};
use super::camera::OrbitCamera;
use super::worker::{Estimates, ViewData};
use crate::math::DVec3;
use crate::present::overlay;
use crate::render::{
    FrameParams, Geometry, NO_SELECTION, OVERLAY_PICKED, OVERLAY_QUADTREE, Uniforms, ViewportCallback,
};
use eframe::egui::{self, Color32, Pos2, Rect};
use eframe::egui_wgpu;
use std::sync::Arc;

/// What a pane draws with, besides its geometry: lent by the app each frame.
#[derive(Copy, Clone, Debug)]
pub struct PaneStyle {
    /// The main view's uniforms (exposure, tone map, overlays); the pane sets its own
    /// view-projection (its aspect) and no picked element (ids differ between solutions).
    pub uniforms: Uniforms,
    /// Scene centre subtracted from positions (as in the build settings).
    pub origin: DVec3,
    /// A wgpu renderer is there to draw with.
    pub has_wgpu: bool,
}

impl PaneStyle {
    /// The same without the element edges (the quadtree / mesh edges overlay).
    #[must_use]
    pub fn without_edges(self) -> PaneStyle {
        PaneStyle {
            uniforms: Uniforms { overlay: self.uniforms.overlay & !OVERLAY_QUADTREE, ..self.uniforms },
            ..self
        }
    }
}

/// The leaf of `view` under the point `pos` of a picture drawn into `rect` through `camera` (the
/// viewport's and every pane's picking).
#[must_use]
pub fn pick(view: &ViewData, camera: &OrbitCamera, pos: Pos2, rect: Rect) -> Option<u32> {
    let aspect = f64::from(rect.width() / rect.height().max(1.0));
    let nx = f64::from((pos.x - rect.left()) / rect.width()) * 2.0 - 1.0;
    let ny = 1.0 - f64::from((pos.y - rect.top()) / rect.height()) * 2.0;
    let (o, dir) = camera.ray(nx, ny, aspect);
    overlay::pick(&view.elements, &view.leaves, o, dir).map(|(id, _)| id)
}

/// The geometry of one pane and the thread that builds it.
pub struct Pane {
    /// Renderer slot (0 is the viewport's).
    slot: usize,
    /// (what is shown, with the error heatmap the address of its state, settings) the newest
    /// build was requested for; "what" is the caller's key (the state's address changes when its
    /// estimates arrive).
    key: Option<(u64, usize, Settings)>,
    builder: Option<Builder>,
    seq: u64,
    geometry: Arc<Geometry>,
    /// Bumped when `geometry` changes (the renderer uploads only then).
    generation: u64,
    /// Sequence number of the newest build answered (shown, or failed).
    shown_seq: Option<u64>,
    /// Why the newest failed build failed, until taken.
    failure: Option<String>,
}

impl Pane {
    /// A pane that draws into renderer slot `slot` (≥ 1).
    #[must_use]
    pub fn new(slot: usize) -> Pane {
        Pane {
            slot,
            key: None,
            builder: None,
            seq: 0,
            geometry: Arc::new(Geometry::default()),
            generation: 0,
            shown_seq: None,
            failure: None,
        }
    }

    fn show(&mut self, seq: u64, geometry: Arc<Geometry>) {
        self.geometry = geometry;
        self.generation += 1;
        self.shown_seq = Some(seq);
    }

    /// A build failed: the picture stays, and the request counts as answered.
    fn fail(&mut self, f: BuildFailed) {
        self.shown_seq = self.shown_seq.max(Some(f.seq));
        self.failure = Some(f.message);
    }

    /// Pick up the builder's answers (`wait`: block for the newest).
    fn pick_up(&mut self, wait: bool) {
        let Some(b) = self.builder.as_mut() else { return };
        let built = if wait { b.wait() } else { b.poll() };
        let failed = b.take_failure();
        if let Some(built) = built {
            self.show(built.seq, built.geometry);
        }
        if let Some(f) = failed {
            self.fail(f);
        }
    }

    /// Why the newest failed build failed (once; `None` when none failed since the last call).
    pub fn take_failure(&mut self) -> Option<String> {
        self.failure.take()
    }

    /// Ask for the geometry of `view` (identified by `key`) with `settings` if it is not the one
    /// asked for last, and pick up a finished build.
    pub fn update(&mut self, ctx: &egui::Context, key: u64, view: &Arc<ViewData>, mut settings: Settings) {
        // The error heatmap of a state whose estimates were given up: nothing to show (all zeros).
        if settings.coloring == Coloring::Error && view.estimates == Estimates::Dropped {
            settings.coloring = Coloring::Smooth;
        }
        let estimated = if settings.coloring == Coloring::Error { Arc::as_ptr(view) as usize } else { 0 };
        let key = (key, estimated, settings);
        // The error heatmap of a state whose estimates are on their way: the last build stays
        // until they come (a heatmap of zeros would be blank).
        let waits = settings.coloring == Coloring::Error && view.estimates_pending() && self.key.is_some();
        if self.key != Some(key) && !waits {
            self.seq += 1;
            let req = builder::Request {
                seq: self.seq,
                view: Arc::clone(view),
                view_seq: key.0,
                true_error: None,
                settings,
                scene: None,
                artifacts: None,
            };
            self.key = Some(key);
            if self.builder.is_none() {
                let ctx = ctx.clone();
                self.builder = Builder::spawn(move || ctx.request_repaint()).ok();
            }
            match &mut self.builder {
                Some(b) => b.request(req),
                // No thread: build here (slower, correct).
                None => match builder::try_build(&req) {
                    Ok(built) => self.show(req.seq, built.geometry),
                    Err(f) => self.fail(f),
                },
            }
        }
        self.pick_up(false);
    }

    /// Block until the newest geometry is built (tests and scripted runs only).
    pub fn wait(&mut self) {
        self.pick_up(true);
    }

    /// True while the newest geometry asked for is not shown yet.
    #[must_use]
    pub fn building(&self) -> bool {
        self.builder.as_ref().is_some_and(|b| b.requested > self.shown_seq)
    }

    /// Draw the geometry into `rect` through `camera`, outlining the element `picked` (an id of
    /// this pane's solution).
    pub fn paint(
        &self,
        ui: &egui::Ui,
        rect: Rect,
        camera: &OrbitCamera,
        style: PaneStyle,
        picked: Option<u32>,
    ) {
        let painter = ui.painter_at(rect);
        if !style.has_wgpu {
            painter.rect_filled(rect, 0.0, Color32::from_gray(20));
            return;
        }
        let ppp = ui.ctx().pixels_per_point();
        let aspect = f64::from(rect.width() / rect.height().max(1.0));
        let m = camera.view_proj(aspect, style.origin).to_cols_array_2d();
        let frame = FrameParams {
            uniforms: Uniforms {
                view_proj: m.map(|c| c.map(|x| x as f32)),
                selected: picked.unwrap_or(NO_SELECTION),
                overlay: (style.uniforms.overlay & !OVERLAY_PICKED)
                    | if picked.is_some() { OVERLAY_PICKED } else { 0 },
                ..style.uniforms
            },
            size: [
                (rect.width() * ppp).round().max(1.0) as u32,
                (rect.height() * ppp).round().max(1.0) as u32,
            ],
        };
        painter.add(egui_wgpu::Callback::new_paint_callback(
            rect,
            ViewportCallback {
                frame,
                geometry: Arc::clone(&self.geometry),
                generation: self.generation,
                slot: self.slot,
            },
        ));
    }
}
