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
//! A click in a pane picks the element under it in that pane's solution: the inspector shows it
//! (from that run) and the pane outlines it.
//!
//! Each pane ([`super::pane`]) builds its geometry from its run's solution with the main view's
//! display settings (shading or error heatmap, quadtree, links; not the picked element, whose id
//! means nothing in another solution; not the edges of the reference's cells) and draws into its
//! own renderer slot (1, 2, 3). The error
//! heatmap of a pane shows the solver's estimate (the true error is computed for the current
//! solution only). A pane's label sits at the top of its column and its picture fills the rest,
//! at the picture's own aspect; the field of view widens in a pane narrower than the viewport
//! ([`pane_camera`]), so that every pane shows at least what the viewport would (a tall pane
//! adds room above and below, never crops the sides).

use super::builder::Settings;
use super::camera::OrbitCamera;
use super::history::{Run, RunHistory, RunKind};
use super::pane::{Pane, PaneStyle, pick};
use super::view::View;
use eframe::egui::{self, Color32, Rect, Sense, Vec2};

/// Gap between two panes, points.
const GAP: f32 = 3.0;
/// Fill of a pane's column around its picture (the viewport's background).
pub const PANE_BACKGROUND: Color32 = Color32::from_rgb(20, 20, 26);

/// What the app lends the split view for one frame.
pub struct SplitInput<'a> {
    pub history: &'a RunHistory,
    /// Name of the scene shown (the newest runs of this scene fill unpicked panes).
    pub scene: &'a str,
    /// The one camera of the viewport and every pane.
    pub camera: &'a mut OrbitCamera,
    /// The main view's display settings (the picked element's link filter is dropped).
    pub settings: Settings,
    pub style: PaneStyle,
    /// The element picked in a pane: (run number, element id in that run's solution).
    pub picked: Option<(usize, u32)>,
}

/// What the split view asks of the app.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum SplitAction {
    /// Open the run history (to pick the runs shown).
    OpenHistory,
    /// A click in the picture of run `run`'s pane: the element of that run's solution under it
    /// (`None`: nothing there).
    Pick { run: usize, element: Option<u32> },
}

/// The split view's state: on or off, how many panes, and each pane's geometry.
pub struct SplitView {
    pub on: bool,
    /// Panes filled with the newest runs when fewer than two are picked (2 or 3).
    pub panes: usize,
    slots: Vec<Pane>,
    /// What the last frame showed: (run number, the rectangle of its picture).
    shown: Vec<(usize, Rect)>,
}

impl Default for SplitView {
    fn default() -> Self {
        SplitView { on: false, panes: 2, slots: Vec::new(), shown: Vec::new() }
    }
}

/// Renderer slot of the first pane (0 is the viewport's).
const FIRST_SLOT: usize = 1;

impl SplitView {
    /// The runs shown in the last frame and where: (run number, the rectangle of its picture).
    #[must_use]
    pub fn shown(&self) -> &[(usize, Rect)] {
        &self.shown
    }

    /// True when the split view can show: on, and two runs with a solution to show.
    #[must_use]
    pub fn active(&self, history: &RunHistory, scene: &str) -> bool {
        self.on && history.split_runs(self.panes, scene).len() >= 2
    }

    /// Block until every pane's newest geometry is built (tests and scripted runs only).
    pub fn wait(&mut self) {
        self.slots.iter_mut().for_each(Pane::wait);
    }

    /// True while a pane waits for its geometry.
    #[must_use]
    pub fn building(&self) -> bool {
        self.slots.iter().any(Pane::building)
    }

    /// Why the panes' failed builds failed, since the last call.
    pub fn take_failures(&mut self) -> Vec<String> {
        self.slots.iter_mut().filter_map(Pane::take_failure).collect()
    }
}

impl View for SplitView {
    type Input<'a> = SplitInput<'a>;
    type Action = SplitAction;

    /// The panes, side by side over the whole of `ui`'s available rectangle.
    fn ui(&mut self, ui: &mut egui::Ui, input: SplitInput<'_>) -> Option<SplitAction> {
        let SplitInput { history, scene, camera, mut settings, style, picked } = input;
        // The picked element's id means nothing in another solution.
        if settings.links.is_some_and(|f| f.element.is_some()) {
            settings.links = None;
        }
        let runs = history.split_runs(self.panes, scene);
        let full = ui.available_rect_before_wrap();
        let n = runs.len().max(1);
        let w = (full.width() - GAP * (n - 1) as f32) / n as f32;
        let mut action = None;
        self.shown.clear();
        // The labels on top of their columns first: every picture starts under the tallest,
        // so that the panes' pictures are one size and line up.
        let mut columns = Vec::with_capacity(runs.len());
        for (i, run) in runs.iter().enumerate() {
            let column = Rect::from_min_size(
                full.min + Vec2::new(i as f32 * (w + GAP), 0.0),
                Vec2::new(w, full.height()),
            );
            let response = ui.allocate_rect(column, Sense::click_and_drag());
            ui.painter().rect_filled(column, 0.0, PANE_BACKGROUND);
            let (band, history_asked) = label(ui, column, run);
            if history_asked {
                action = Some(SplitAction::OpenHistory);
            }
            columns.push((column, response, band));
        }
        let band = columns.iter().map(|c| c.2).fold(0.0, f32::max).min(full.height() - 1.0);
        // Each picture from under the labels to the column's foot, at its own aspect; one camera,
        // widened to show at least the viewport's framing.
        for (i, (run, (column, response, _))) in runs.iter().zip(columns).enumerate() {
            let rect = Rect::from_min_max(column.min + Vec2::new(0.0, band), column.max);
            camera.interact(ui, &response, rect);
            let seen = pane_camera(camera, aspect(rect), aspect(full));
            while self.slots.len() <= i {
                self.slots.push(Pane::new(FIRST_SLOT + self.slots.len()));
            }
            if let Some(view) = &run.view {
                self.slots[i].update(ui.ctx(), run.number as u64, view, settings);
                // A click in the picture picks in this run's solution.
                if response.clicked()
                    && let Some(pos) = response.interact_pointer_pos().filter(|p| rect.contains(*p))
                {
                    let element = pick(view, &seen, pos, rect);
                    action = Some(SplitAction::Pick { run: run.number, element });
                }
            }
            let outlined = picked.filter(|p| p.0 == run.number).map(|p| p.1);
            // The reference's cells are its points' (tens of thousands), not a mesh a solver
            // chose: their edges would hide its picture.
            let style = match run.kind {
                RunKind::Reference { .. } => style.without_edges(),
                RunKind::Solve => style,
            };
            self.slots[i].paint(ui, rect, &seen, style, outlined);
            self.shown.push((run.number, rect));
        }
        for i in 1..n {
            let x = full.left() + i as f32 * (w + GAP) - 0.5 * GAP;
            ui.painter().vline(x, full.y_range(), egui::Stroke::new(GAP, Color32::from_gray(60)));
        }
        action
    }
}

/// Width over height of `r` (1 for an empty rectangle).
fn aspect(r: Rect) -> f64 {
    if r.width() > 0.0 && r.height() > 0.0 { f64::from(r.width() / r.height()) } else { 1.0 }
}

/// The camera a pane of aspect `pane` draws and picks through: `camera` itself, its vertical
/// field of view widened when the pane is narrower than the `framing` aspect (the viewport's) so
/// that the pane shows the viewport's whole width — the same horizontal field, more above and
/// below:
///
/// ```text
/// tan(fov′ / 2) = tan(fov / 2) · framing / pane      (pane < framing)
/// ```
#[must_use]
pub fn pane_camera(camera: &OrbitCamera, pane: f64, framing: f64) -> OrbitCamera {
    let mut c = *camera;
    if pane > 0.0 && framing > pane {
        let half = (0.5 * camera.fov_y_deg).to_radians().tan() * framing / pane;
        c.fov_y_deg = 2.0 * half.atan().to_degrees();
    }
    c
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
            // The title shrinks (truncated) before the button does.
            egui::Sides::new().shrink_left().truncate().show(
                ui,
                |ui| ui.add(egui::Label::new(white(run.title()).strong()).selectable(false)),
                |ui| {
                    clicked = ui
                        .small_button("runs…")
                        .on_hover_text("Pick the runs shown side by side (the run history)")
                        .clicked();
                },
            );
            for line in [run.thresholds(), run.numbers()] {
                ui.add(egui::Label::new(white(line)).selectable(false).wrap_mode(egui::TextWrapMode::Wrap));
            }
        });
    (frame.response.rect.bottom() - rect.top() + 4.0, clicked)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Bounds;

    /// A pane narrower than the viewport sees the viewport's whole width (the same horizontal
    /// field of view) and more above and below; a wider one keeps the vertical field.
    #[test]
    fn a_narrow_pane_widens_the_field_to_the_viewports_width() {
        let b = Bounds { min: crate::math::DVec3::splat(-1.0), max: crate::math::DVec3::splat(1.0) };
        let cam = OrbitCamera::frame_all(&b);
        let half_tan = |c: &OrbitCamera| (0.5 * c.fov_y_deg).to_radians().tan();
        let (framing, pane) = (1.2, 0.5);
        let seen = pane_camera(&cam, pane, framing);
        let horizontal = |c: &OrbitCamera, aspect: f64| half_tan(c) * aspect;
        assert!((horizontal(&seen, pane) - horizontal(&cam, framing)).abs() < 1e-12);
        assert!(seen.fov_y_deg > cam.fov_y_deg);
        assert_eq!(seen.target, cam.target, "only the field of view changes");
        assert_eq!(pane_camera(&cam, 2.0, framing), cam, "a wider pane keeps the camera");
    }
}
