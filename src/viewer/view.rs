//! The small interface of the viewer's panels (after the egui demo's `View`): a
//! panel is one type that keeps its own state, draws itself each frame from what the app lends
//! it, and answers with what it asks the app to do. The app only lays the panels out and routes
//! those answers, so a panel never reaches into the app (no import cycle) and can be tested alone.
//!
//! ```text
//!  RadlabApp ── Input (borrowed, this frame) ──► panel.ui(ui, input) ── Option<Action> ──► app
//! ```
//!
//! Implemented by [`super::top_bar::TopBar`], [`super::mesh_menu::MeshMenu`],
//! [`super::solver_panel::SolverPanel`], [`super::solver_panel::ProgressPanel`],
//! [`super::reference_panel::ReferencePanel`], [`super::display::DisplayPanel`],
//! [`super::inspector::Inspector`], [`super::plots::Plots`], [`super::status_bar::StatusBar`],
//! [`super::history::RunHistory`], [`super::split::SplitView`], [`super::replay::Replay`] and
//! [`super::matrix::MatrixWindow`].

use eframe::egui;

/// One panel of the viewer.
pub trait View {
    /// What the app lends the panel for one frame.
    type Input<'a>;
    /// What the panel asks the app to do.
    type Action;
    /// Draw the panel into `ui`.
    fn ui(&mut self, ui: &mut egui::Ui, input: Self::Input<'_>) -> Option<Self::Action>;
}
