//! The side panel's Reference section: where the current scene's reference solution stands
//! ([`RefState`]: looked up in the disk cache, missing, being computed, ready), with the buttons
//! that compute or cancel it and the current state's error against it.

use super::solver_panel::PANEL_CONTENT_W;
use super::view::View;
use eframe::egui::{self, Color32};
use std::time::Instant;

/// Height reserved for the Reference section: its heading row (with the button that applies)
/// and one row, in every state.
const REFERENCE_PANEL_H: f32 = 54.0;

/// Where the reference solution of the current scene stands.
#[derive(Clone, Debug, PartialEq)]
pub enum RefState {
    /// No scene, or no reference thread.
    None,
    /// Looking in the disk cache.
    Looking,
    /// Not cached: the "Compute reference" button offers to compute it.
    Missing,
    Computing {
        points: usize,
        samples: u32,
        since: Instant,
    },
    Ready {
        points: usize,
        samples: u32,
        how: String,
    },
    Failed(String),
}

/// The Reference section (its state is the app's [`RefState`]).
#[derive(Copy, Clone, Debug, Default)]
pub struct ReferencePanel;

/// What the Reference section is lent for one frame.
pub struct ReferenceInput<'a> {
    pub state: &'a RefState,
    /// (work finished, work) of a computation.
    pub progress: (usize, usize),
    /// The current state's pointwise rel L2 error against the reference, once scored.
    pub error: Option<f64>,
}

/// What the Reference section asks of the app.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum ReferenceAction {
    /// Compute the reference (on the reference thread; saved in the disk cache).
    Compute,
    /// Stop the computation.
    Cancel,
}

impl View for ReferencePanel {
    type Input<'a> = ReferenceInput<'a>;
    type Action = ReferenceAction;

    fn ui(&mut self, ui: &mut egui::Ui, input: ReferenceInput<'_>) -> Option<ReferenceAction> {
        // A fixed height: the panels below stay put as the reference's state changes.
        let top = ui.cursor().top();
        let action = contents(ui, input);
        let used = ui.cursor().top() - top;
        ui.add_space((REFERENCE_PANEL_H - used).max(0.0));
        action
    }
}

/// The section's two rows: the heading with the button that applies (Compute, Cancel) or the
/// state's error against it, then where the reference stands.
fn contents(ui: &mut egui::Ui, input: ReferenceInput<'_>) -> Option<ReferenceAction> {
    let ReferenceInput { state, progress, error } = input;
    let mut action = None;
    let compute_tip = "Independent Monte Carlo reference (radlab reference), on a background thread; \
                       saved in the disk cache";
    ui.horizontal(|ui| {
        ui.heading("Reference");
        ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| match state {
            RefState::Missing | RefState::Failed(_) => {
                if ui.button("Compute reference").on_hover_text(compute_tip).clicked() {
                    action = Some(ReferenceAction::Compute);
                }
            }
            RefState::Computing { .. } => {
                if ui
                    .button("Cancel reference")
                    .on_hover_text("Stop the computation (nothing is cached)")
                    .clicked()
                {
                    action = Some(ReferenceAction::Cancel);
                }
            }
            RefState::Ready { .. } => {
                if let Some(e) = error {
                    ui.label(format!("pointwise rel L2 {:.2} %", e * 100.0)).on_hover_text(
                        "The current state's error at the reference's points, its noise taken \
                         out; the plots show it against solver time",
                    );
                }
            }
            RefState::None | RefState::Looking => {}
        });
    });
    match state.clone() {
        RefState::None => {
            ui.weak("no scene");
        }
        RefState::Looking => {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label("looking in the cache…");
            });
        }
        RefState::Missing => {
            ui.label("none cached for this scene");
        }
        RefState::Computing { points, samples, since } => {
            let (done, total) = progress;
            let total = if total == 0 { points } else { total };
            ui.add(
                egui::ProgressBar::new(done as f32 / total.max(1) as f32)
                    .desired_width(PANEL_CONTENT_W)
                    .text(format!("{done}/{total} · {:.0} s", since.elapsed().as_secs_f64())),
            )
            .on_hover_text(format!(
                "Computing the reference: at least {} points × {samples} paths",
                crate::eval::pointwise::thousands(points)
            ));
            ui.ctx().request_repaint_after(std::time::Duration::from_millis(250));
        }
        RefState::Ready { points, samples, how } => {
            let what = if samples == 0 {
                // The closed form of a single-bounce scene (no paths, no noise).
                format!("closed form at {} points", crate::eval::pointwise::thousands(points))
            } else {
                format!("{} points × {samples} paths", crate::eval::pointwise::thousands(points))
            };
            ui.label(what).on_hover_text(how);
        }
        RefState::Failed(e) => {
            ui.add(
                egui::Label::new(egui::RichText::new(&e).color(Color32::from_rgb(255, 150, 130))).truncate(),
            )
            .on_hover_text(e);
        }
    }
    action
}
