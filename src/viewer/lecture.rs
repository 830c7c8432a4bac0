//! The Lecture menu and the caption panel: every figure of [`crate::figures`] one click away,
//! listed by slide title (the meshing slides in their submenu, [`crate::figures::MESHING`]); the figure shown keeps its caption in a panel under the viewport until
//! it is hidden (the × button or C) or another scene is opened. The menu also opens the
//! blocking form-factor matrix ([`super::matrix`]) and the five-times explorer
//! ([`super::five_times`]).

use super::five_times::FiveTimes;
use super::matrix::{MatrixAction, MatrixInput, MatrixWindow};
use super::worker::ViewData;
use crate::figures::{FIGURES, Figure};
use eframe::egui;
use std::sync::Arc;

/// The figure whose caption is shown, and the explorer windows.
#[derive(Clone, Debug, Default)]
pub struct Lecture {
    figure: Option<&'static Figure>,
    caption_open: bool,
    pub five_times: FiveTimes,
    pub matrix: MatrixWindow,
}

impl Lecture {
    /// Show a figure's caption.
    pub fn show(&mut self, f: &'static Figure) {
        self.figure = Some(f);
        self.caption_open = true;
    }

    /// Forget the figure (another scene was opened by hand).
    pub fn clear(&mut self) {
        self.figure = None;
        self.caption_open = false;
    }

    /// Show or hide the caption of the figure opened last.
    pub fn toggle_caption(&mut self) {
        self.caption_open = !self.caption_open && self.figure.is_some();
    }

    /// The figure opened last, if its scene is still shown.
    #[must_use]
    pub fn figure(&self) -> Option<&'static Figure> {
        self.figure
    }

    /// True while the caption panel is shown.
    #[must_use]
    pub fn caption_open(&self) -> bool {
        self.caption_open && self.figure.is_some()
    }

    /// The Lecture menu: the figures by slide title (returns the one chosen), then the
    /// explorers.
    pub fn menu(&mut self, ui: &mut egui::Ui) -> Option<&'static Figure> {
        let mut chosen = None;
        let item = |ui: &mut egui::Ui, f: &'static Figure, chosen: &mut Option<&'static Figure>| {
            let tip = format!("{} ({}, {}): {}", f.name, f.scene, f.method, f.caption);
            if ui.button(f.slide).on_hover_text(tip).clicked() {
                *chosen = Some(f);
                ui.close();
            }
        };
        ui.menu_button("Lecture", |ui| {
            for f in FIGURES.iter().filter(|f| f.submenu.is_none()) {
                item(ui, f, &mut chosen);
            }
            let mut submenus: Vec<&'static str> = FIGURES.iter().filter_map(|f| f.submenu).collect();
            submenus.dedup();
            for name in submenus {
                ui.menu_button(name, |ui| {
                    for f in FIGURES.iter().filter(|f| f.submenu == Some(name)) {
                        item(ui, f, &mut chosen);
                    }
                })
                .response
                .on_hover_text(
                    "The lecture's meshing slides: discontinuities, discontinuity meshes, h vs p, \
                     meshing options, the five artifacts (solved on the figure's mesh)",
                );
            }
            ui.separator();
            if ui
                .button("Blocking form-factor matrix…")
                .on_hover_text(
                    "Each link of the solution as the block of leaf-to-leaf form factors it stands for",
                )
                .clicked()
            {
                self.matrix.open = true;
                ui.close();
            }
            if ui
                .button("Five-times explorer…")
                .on_hover_text(
                    "A square source over a point receiver: exact, disk and point-source form \
                     factors as you drag the distance and size",
                )
                .clicked()
            {
                self.five_times.open = true;
                ui.close();
            }
        })
        .response
        .on_hover_text(
            "Figures of the radiosity lecture: each opens its scene with the slide's settings, \
             overlays and camera, and a caption saying what to look at",
        );
        chosen
    }

    /// The explorer windows that are open; returns what the matrix asks (a hovered block's
    /// link to highlight, a clicked block's receiver to pick). `element` is the element to
    /// highlight in the matrix (hovered or picked in the viewport).
    pub fn windows(
        &mut self,
        ctx: &egui::Context,
        view: &Arc<ViewData>,
        element: Option<u32>,
    ) -> Option<MatrixAction> {
        if self.five_times.open {
            self.five_times.window(ctx);
        }
        if self.matrix.open { self.matrix.window(ctx, MatrixInput { view, element }) } else { None }
    }

    /// The caption panel at the bottom of the window (call before the central panel).
    pub fn caption_panel(&mut self, ui: &mut egui::Ui, frame: egui::Frame) {
        let Some(f) = self.figure.filter(|_| self.caption_open) else { return };
        egui::Panel::bottom("caption").frame(frame).resizable(false).show(ui, |ui| {
            ui.horizontal(|ui| {
                ui.heading(f.slide);
                ui.weak(format!("figure {} · {} · {}", f.name, f.scene, f.method));
                ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
                    if ui.button("×").on_hover_text("Hide the caption (C shows it again)").clicked() {
                        self.caption_open = false;
                    }
                });
            });
            ui.label(f.caption);
        });
    }
}
