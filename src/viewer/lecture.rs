//! The Lecture menu and the caption panel: every figure of [`crate::present::figures`] one click away,
//! listed by slide title (the meshing slides in their submenu, [`crate::present::figures::MESHING`]); the
//! figure shown keeps its caption in a panel under the viewport until it is hidden (the × button
//! or C) or another scene is opened. The menu also opens the blocking form-factor matrix
//! ([`super::matrix`]) and the five-times explorer ([`super::five_times`]).
//!
//! A caption's numbers are the state's ([`caption_facts`], [`Figure::caption_text`]): read from
//! the solution shown once the figure's steps are done, and again after every step that keeps
//! the state the figure's (a Gather on a stepped figure, [`Figure::follows`]). A step, setting or
//! mesh that leaves it closes the caption; C shows it again as it last stood, marked as the
//! figure's, not the state's.

use super::five_times::FiveTimes;
use super::history::RunHistory;
use super::matrix::{MatrixAction, MatrixInput, MatrixWindow};
use super::worker::ViewData;
use crate::present::figures::{CaptionFacts, FIGURES, Figure};
use crate::scene::Scene;
use crate::solver::hierarchical::StepKind;
use eframe::egui;
use std::sync::Arc;

/// The figure whose caption is shown, and the explorer windows.
#[derive(Clone, Debug, Default)]
pub struct Lecture {
    figure: Option<&'static Figure>,
    caption_open: bool,
    /// The numbers of the state shown (`None` until the figure's steps are done).
    facts: Option<CaptionFacts>,
    /// The error line under the caption's title ("error 4.12 % against the closed form").
    error_line: String,
    /// The state has left the figure's (another step, setting or mesh): what the caption said
    /// last.
    left: Option<String>,
    /// What the caption's numbers were last read from ([`Lecture::wants_facts`]).
    facts_key: Option<FactsKey>,
    pub five_times: FiveTimes,
    pub matrix: MatrixWindow,
}

impl Lecture {
    /// Show a figure's caption (its numbers once its state is there, [`Lecture::set_facts`]).
    pub fn show(&mut self, f: &'static Figure) {
        self.figure = Some(f);
        self.caption_open = true;
        self.facts = None;
        self.error_line.clear();
        self.left = None;
    }

    /// Forget the figure (another scene was opened by hand).
    pub fn clear(&mut self) {
        self.figure = None;
        self.caption_open = false;
        self.facts = None;
        self.left = None;
    }

    /// The numbers of the state shown and its error line, while that state is the figure's.
    pub fn set_facts(&mut self, facts: CaptionFacts, error_line: String) {
        if self.figure.is_some() && self.left.is_none() {
            self.facts = Some(facts);
            self.error_line = error_line;
        }
    }

    /// A step is about to run: one the figure does not follow leaves its state.
    pub fn on_step(&mut self, kind: StepKind) {
        if self.figure.is_some_and(|f| !f.follows(kind)) {
            self.leave();
        }
    }

    /// The state leaves the figure's (a step it does not follow, another setting or mesh, a
    /// reset): the caption closes, keeping what it said last.
    pub fn leave(&mut self) {
        if self.left.is_none() && self.figure.is_some() {
            self.left = self.caption();
            self.caption_open = false;
        }
    }

    /// True when the caption's numbers are to be read (again): it has none, or what they are
    /// read from (`key`) changed since they were last read.
    pub fn wants_facts(&mut self, key: FactsKey) -> bool {
        if self.facts_key == Some(key) && self.has_facts() {
            return false;
        }
        self.facts_key = Some(key);
        true
    }

    /// True once the caption has the numbers of a state.
    #[must_use]
    pub fn has_facts(&self) -> bool {
        self.facts.is_some()
    }

    /// True while the state shown is the figure's.
    #[must_use]
    pub fn following(&self) -> bool {
        self.figure.is_some() && self.left.is_none()
    }

    /// The caption's text: its numbers the state's ("…" until known), or, once the state has
    /// left the figure's, what it said last.
    #[must_use]
    pub fn caption(&self) -> Option<String> {
        let f = self.figure?;
        if let Some(left) = &self.left {
            return Some(left.clone());
        }
        Some(self.facts.as_ref().map_or_else(|| f.caption_outline(), |facts| f.caption_text(facts)))
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
            let tip = format!("{} ({}, {}): {}", f.name, f.scene, f.method, f.caption_outline());
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

    /// The explorer windows that are open (the five-times explorer; the matrix is docked in
    /// the inspector column, [`Lecture::matrix_panel`]).
    pub fn windows(&mut self, ctx: &egui::Context) {
        if self.five_times.open {
            self.five_times.window(ctx);
        }
    }

    /// The blocking matrix, when open, at the top of the inspector column; returns what it asks
    /// (a hovered block's link to highlight, a clicked block's receiver to pick). `element` is
    /// the element to highlight in the matrix (hovered or picked in the viewport).
    pub fn matrix_panel(
        &mut self,
        ui: &mut egui::Ui,
        view: &Arc<ViewData>,
        element: Option<u32>,
    ) -> Option<MatrixAction> {
        if !self.matrix.open {
            return None;
        }
        let action = self.matrix.panel(ui, MatrixInput { view, element });
        ui.separator();
        action
    }

    /// The caption panel at the bottom of the window (call before the central panel).
    pub fn caption_panel(&mut self, ui: &mut egui::Ui, frame: egui::Frame) {
        let Some(f) = self.figure.filter(|_| self.caption_open) else { return };
        let Some(text) = self.caption() else { return };
        egui::Panel::bottom("caption").frame(frame).resizable(false).show(ui, |ui| {
            // The figure's name and method shrink (cut, the whole in their hover text) before the
            // × does: a long slide title never runs under it.
            egui::Sides::new().shrink_left().truncate().show(
                ui,
                |ui| {
                    ui.heading(f.slide);
                    let about = format!("figure {} · {} · {}", f.name, f.scene, f.method);
                    ui.weak(&about).on_hover_text(about);
                },
                |ui| {
                    if ui.button("×").on_hover_text("Hide the caption (C shows it again)").clicked() {
                        self.caption_open = false;
                    }
                },
            );
            if self.left.is_some() {
                ui.weak(
                    "The state shown is no longer the figure's (a step, setting or mesh changed it): \
                     the caption and its numbers are the figure's as it stood. The Lecture menu \
                     opens it again.",
                );
            } else if !self.error_line.is_empty() {
                ui.weak(&self.error_line);
            }
            ui.label(text);
        });
    }
}

/// What a caption's numbers are read from: (state shown, its error's bits, runs of the history,
/// runs scored, where the reference stands).
pub type FactsKey = (u64, Option<u64>, usize, usize, u8);

/// What [`caption_facts`] reads.
pub struct FactsInput<'a> {
    pub figure: &'static Figure,
    pub scene: &'a Scene,
    pub view: &'a ViewData,
    /// The viewer's number of the state shown (its run in `history`, if it is one).
    pub view_seq: u64,
    pub history: &'a RunHistory,
    /// The state's pointwise relative L2 error against the closed form or the reference, and
    /// over the penumbra band (the closed form's).
    pub error: Option<f64>,
    pub band: Option<f64>,
}

/// The numbers a figure's caption quotes, read from the state shown (and, for the split view's
/// other pane and the links plot, from the runs of the history).
#[must_use]
pub fn caption_facts(input: &FactsInput<'_>) -> CaptionFacts {
    let FactsInput { figure, scene, view, view_seq, history, error, band } = *input;
    let uses = |name: &str| crate::present::figures::placeholders(figure.caption).contains(&name);
    let s = &view.stats;
    let mut facts = CaptionFacts {
        leaves: s.leaves,
        links: s.links,
        links_partial: s.links_partial,
        unknowns: view.unknowns(),
        gathers: view.residuals.len(),
        residual: view.residuals.last().copied(),
        error,
        band_error: band,
        ..CaptionFacts::default()
    };
    // The other pane of the split view: the newest other run of the scene with a solution.
    if uses("other_error") || uses("other_unknowns") || uses("other_band_error") {
        let other = history
            .split_runs(2, &scene.name)
            .into_iter()
            .find(|r| r.view_seq != view_seq && r.kind == super::history::RunKind::Solve);
        if let Some(r) = other {
            facts.other_unknowns = Some(r.unknowns);
            facts.other_error = r.reference;
            facts.other_band_error = r.band;
        }
    }
    if uses("series_runs") || uses("series_links_per_leaf") {
        let current = history.runs().iter().rev().find(|r| r.view_seq == view_seq);
        if let Some(series) = current.map(super::history::Run::series) {
            facts.series = history
                .runs()
                .iter()
                .filter(|r| r.kind == super::history::RunKind::Solve && r.series() == series)
                .map(|r| (r.elements, r.links))
                .collect();
        }
    }
    if uses("largest_diameter") || uses("disk_links") {
        let diameter = |id: u32| {
            let v = view.elements[id as usize].verts();
            v.iter().flat_map(|a| v.iter().map(move |b| a.distance(*b))).fold(0.0, f64::max)
        };
        let centroid = |id: u32| {
            let v = view.elements[id as usize].verts();
            v.iter().copied().sum::<crate::math::DVec3>() / v.len().max(1) as f64
        };
        facts.largest_diameter = view.leaves.iter().map(|&l| diameter(l)).reduce(f64::max);
        // The transfer's rule (solver::hierarchical::transfer): the disk once the centres are
        // five diameters of each element apart.
        let five = super::five_times::FIVE;
        facts.disk_links = Some(
            view.links
                .iter()
                .filter(|l| {
                    let d = centroid(l.receiver).distance(centroid(l.source));
                    d >= five * diameter(l.receiver) && d >= five * diameter(l.source)
                })
                .count(),
        );
    }
    if (uses("ff_disk") || uses("ff_exact")) && scene.patches.len() >= 2 {
        // From patch 0 to patch 1, as `radlab form-factor --from 0 --to 1` computes them.
        let (a, b) = (&scene.patches[0], &scene.patches[1]);
        facts.ff_disk =
            Some(crate::geometry::form_factor::disk(a.centroid, a.normal, b.centroid, b.normal, b.area));
        facts.ff_exact =
            Some(crate::geometry::form_factor::polygon_to_polygon(&a.vertices, &b.vertices, 1e-6));
    }
    facts
}
