//! The run history: every solve the viewer finishes is kept as a [`Run`] (its scene, settings,
//! elements, links, solver time and error) so that runs can be compared, not remembered: the
//! plots overlay them (links against elements with the n and n² guides, error against solver
//! time) and two or three of them fill the split view ([`super::split`]).
//!
//! Solves on a uniform or discontinuity mesh ([`crate::solver::meshed`]) are runs too, named by
//! their mesh and order ("discontinuity-cdt p1-continuous"), one plot series per mesh and order;
//! they have no estimate of their own, so their error is known once a reference scores them.
//! Two of them side by side in the split view are the lecture's h vs p.
//!
//! ## Memory
//! Every run keeps its numbers (about 300 bytes; beyond [`MAX_RUNS`] the oldest are dropped), but
//! only the newest [`KEEP_SOLUTIONS`] runs, and the runs picked for the split view, keep their
//! solution (an `Arc<ViewData>`: ~150 bytes per element and ~16 per link, so ~3 MB for a
//! 10 000-element, 100 000-link solve). A run whose solution was dropped stays in the list and in
//! the plots but can no longer be shown.
//!
//! ## Error
//! A run's error is the relative L2 error of its solution against the scene's reference when
//! there is one (the reference thread scores every solver state, [`super::reference`]; that is
//! the pointwise ruler of `radlab reference`), else the solver's own estimate of
//! that number without a reference
//! ([`crate::solver::hierarchical::estimate::global_relative_l2`]), always labelled as an
//! estimate.

use super::view::View;
use super::worker::{Estimates, ViewData};
use crate::solver::hierarchical::estimate::global_relative_l2;
use crate::solver::meshed::{MeshMethod, MeshSolveParams};
use crate::solver::params::{AreaEps, HierarchicalParams, Oracle};
use eframe::egui;
use std::sync::Arc;

/// Runs that keep their solution for the split view (the newest; picked runs in addition).
pub const KEEP_SOLUTIONS: usize = 6;
/// Runs kept at all (numbers only beyond [`KEEP_SOLUTIONS`]); the oldest go first.
pub const MAX_RUNS: usize = 500;
/// Most runs picked for the split view at once.
pub const MAX_PICKED: usize = 3;

/// What an error is measured against: the scene's Monte Carlo reference, or the closed form of a
/// single-bounce scene (exact, no noise).
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub enum Ruler {
    #[default]
    Reference,
    ClosedForm,
}

impl Ruler {
    /// What labels say an error is "vs": "reference", "closed form".
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Ruler::Reference => "reference",
            Ruler::ClosedForm => "closed form",
        }
    }

    /// The same in a sentence: "the reference", "the closed form".
    #[must_use]
    pub fn the(self) -> &'static str {
        match self {
            Ruler::Reference => "the reference",
            Ruler::ClosedForm => "the closed form",
        }
    }
}

/// The error of a run, and where it comes from.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum RunError {
    /// Relative L2 error against the reference solution.
    Reference(f64),
    /// Relative L2 error against the closed form of a single-bounce scene.
    ClosedForm(f64),
    /// The solver's own estimate of its relative L2 error (no reference).
    Estimate(f64),
    /// The reference's own Monte Carlo noise: its relative standard error.
    Noise(f64),
    /// The solver's estimate is being computed (it follows the solve's answer).
    Estimating,
    /// The solver's estimate was given up: a newer command came first.
    NotEstimated,
    /// Neither (nothing reflected yet, or no estimate).
    Unknown,
}

impl RunError {
    /// The value, whichever it is.
    #[must_use]
    pub fn value(self) -> Option<f64> {
        match self {
            RunError::Reference(e) | RunError::ClosedForm(e) | RunError::Estimate(e) | RunError::Noise(e) => {
                Some(e)
            }
            RunError::Estimating | RunError::NotEstimated | RunError::Unknown => None,
        }
    }

    /// "error 4.12 % (vs reference)", "error 0.81 % (vs closed form)" or "error ≈ 3.20 %
    /// (solver's estimate)".
    #[must_use]
    pub fn label(self) -> String {
        match self {
            RunError::Reference(e) => format!("error {:.2} % (vs reference)", 100.0 * e),
            RunError::ClosedForm(e) => format!("error {:.2} % (vs closed form)", 100.0 * e),
            RunError::Estimate(e) => format!("error ≈ {:.2} % (solver's estimate)", 100.0 * e),
            RunError::Noise(e) => format!("standard error {:.2} % (Monte Carlo noise)", 100.0 * e),
            RunError::Estimating => "error: estimating…".to_owned(),
            RunError::NotEstimated => "error: not estimated (a newer command came first)".to_owned(),
            RunError::Unknown => "error unknown".to_owned(),
        }
    }

    /// The table's short form: "4.12 % vs ref.", "0.81 % vs closed form" or "≈ 3.20 % est.".
    #[must_use]
    pub fn short(self) -> String {
        match self {
            RunError::Reference(e) => format!("{:.2} % vs ref.", 100.0 * e),
            RunError::ClosedForm(e) => format!("{:.2} % vs closed form", 100.0 * e),
            RunError::Estimate(e) => format!("≈ {:.2} % est.", 100.0 * e),
            RunError::Noise(e) => format!("± {:.2} % noise", 100.0 * e),
            RunError::Estimating => "estimating…".to_owned(),
            RunError::NotEstimated => "not estimated".to_owned(),
            RunError::Unknown => "–".to_owned(),
        }
    }
}

/// What made a run.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum RunKind {
    /// A Solve of the hierarchical solver.
    Solve,
    /// The scene's Monte Carlo reference (`radlab reference`, pointwise), shown as a run (its
    /// points' cells the elements) so that the split view can set it beside solves; left out of
    /// the plots.
    Reference {
        points: usize,
        /// Paths per point.
        samples: u32,
        /// Its relative standard error (area-weighted, against the reflected radiosity).
        noise: Option<f64>,
    },
}

/// One finished solve (or the scene's reference).
#[derive(Clone, Debug)]
pub struct Run {
    /// 1, 2, … in the order solved (shown as "#n").
    pub number: usize,
    pub kind: RunKind,
    /// Name of the scene solved.
    pub scene: String,
    /// The preset's name, or "custom" when the settings differ from every preset; a mesh
    /// solve's mesh and order ("discontinuity-cdt p1-continuous").
    pub preset: String,
    pub params: HierarchicalParams,
    /// A solve on a uniform or discontinuity mesh: its settings (`params` are then unused).
    pub mesh: Option<MeshSolveParams>,
    /// Leaves of the solution (the elements that carry radiosity).
    pub elements: usize,
    /// Its unknowns ([`ViewData::unknowns`]: fewer than the elements on a p = 1 continuous mesh).
    pub unknowns: usize,
    pub links: usize,
    /// Solver time since the solver's last restart (every step that led to this solution), s.
    pub time_s: f64,
    /// The solver's estimate of its relative L2 error.
    pub estimate: Option<f64>,
    /// The relative L2 error against the reference (or the closed form, `ruler`), once the
    /// reference thread has scored it.
    pub reference: Option<f64>,
    /// What `reference` was measured against.
    pub ruler: Ruler,
    /// The same over the penumbra band, where the reference is a closed form.
    pub band: Option<f64>,
    /// The viewer's number of the solver state (matches the reference thread's answer).
    pub view_seq: u64,
    /// The solution, while kept (see the module docs).
    pub view: Option<Arc<ViewData>>,
}

impl Run {
    /// The error shown: against the reference if known, else the estimate (a reference: its
    /// noise).
    #[must_use]
    pub fn error(&self) -> RunError {
        if let RunKind::Reference { noise, .. } = self.kind {
            return noise.map_or(RunError::Unknown, RunError::Noise);
        }
        match (self.reference, self.estimate) {
            (Some(e), _) if self.ruler == Ruler::ClosedForm => RunError::ClosedForm(e),
            (Some(e), _) => RunError::Reference(e),
            (None, Some(e)) => RunError::Estimate(e),
            (None, None) => match self.view.as_ref().map(|v| v.estimates) {
                Some(Estimates::Pending) => RunError::Estimating,
                Some(Estimates::Dropped) => RunError::NotEstimated,
                Some(Estimates::Included) | None => RunError::Unknown,
            },
        }
    }

    /// "#3 cornell · interactive".
    #[must_use]
    pub fn title(&self) -> String {
        format!("#{} {} · {}", self.number, self.scene, self.preset)
    }

    /// The oracle and its thresholds, e.g. "BF oracle, BFeps 2.0e-3, Feps 5.0e-2 · Aeps 1e-4 A".
    #[must_use]
    pub fn thresholds(&self) -> String {
        match (self.kind, &self.mesh) {
            (RunKind::Solve, Some(m)) => mesh_settings(m),
            (RunKind::Solve, None) => thresholds(&self.params),
            (RunKind::Reference { points, samples, .. }, _) => {
                format!("Monte Carlo reference: {points} points × {samples} paths (radlab reference)")
            }
        }
    }

    /// "761 elements · 5321 links · 0.42 s · error ≈ 3.20 % (solver's estimate)".
    #[must_use]
    pub fn numbers(&self) -> String {
        if let RunKind::Reference { .. } = self.kind {
            return format!("{} points · {}", self.elements, self.error().label());
        }
        let unknowns = if self.unknowns == self.elements {
            String::new()
        } else {
            format!(" · {} unknowns", self.unknowns)
        };
        let band = self
            .band
            .map_or(String::new(), |b| format!(" · penumbra band {}", crate::present::figures::percent(b)));
        // A mesh solve couples every pair of its elements: form-factor entries, as the status
        // bar counts them, not links.
        let coupled = if self.mesh.is_some() { "form-factor entries" } else { "links" };
        format!(
            "{} elements{unknowns} · {} {coupled} · {:.2} s · {}{band}",
            self.elements,
            self.links,
            self.time_s,
            self.error().label()
        )
    }

    /// The plots' series this run belongs to: runs of one scene with one oracle (or one mesh
    /// and order).
    #[must_use]
    pub fn series(&self) -> String {
        match &self.mesh {
            Some(m) => format!("{} · {}", self.scene, m.label()),
            None => format!("{} · {}", self.scene, oracle_name(self.params.oracle)),
        }
    }
}

fn oracle_name(o: Oracle) -> &'static str {
    match o {
        Oracle::Feps => "Feps oracle",
        Oracle::Bf => "BF oracle",
        Oracle::Error => "error oracle",
    }
}

/// The settings that decide a hierarchical solve's accuracy, in one line.
#[must_use]
pub fn thresholds(p: &HierarchicalParams) -> String {
    let oracle = match p.oracle {
        Oracle::Feps if p.feps == 0.0 => "Feps 0 (every pair refined to the floor)".to_owned(),
        Oracle::Feps => format!("Feps {:.1e}", p.feps),
        Oracle::Bf => format!(
            "BFeps {:.1e}{}, Feps {:.1e}",
            p.bf_eps,
            if p.bf_relative { " E_max" } else { "" },
            p.feps
        ),
        Oracle::Error => {
            format!("ε {:.1e}{}", p.bf_eps, if p.bf_relative { " of mean B" } else { "" })
        }
    };
    let aeps = match p.aeps {
        AreaEps::Relative(r) => format!("Aeps {r:.0e} A"),
        AreaEps::Absolute(a) => format!("Aeps {a:.1e}"),
    };
    format!("{}, {oracle} · {aeps} · {} rays", oracle_name(p.oracle), p.rays)
}

/// The threshold the oracle refines by, e.g. "BFeps 1.0e-3", "Feps 5.0e-3" or "ε 5.0e-2" (the
/// error oracle's, the ladder's).
#[must_use]
pub fn oracle_threshold(p: &HierarchicalParams) -> String {
    match p.oracle {
        Oracle::Feps => format!("Feps {:.1e}", p.feps),
        Oracle::Bf => format!("BFeps {:.1e}", p.bf_eps),
        Oracle::Error => format!("ε {:.1e}", p.bf_eps),
    }
}

/// A mesh solve's settings in one line, e.g. "discontinuity-cdt, refined to 20° · p = 1
/// continuous · 16 rays".
#[must_use]
pub fn mesh_settings(m: &MeshSolveParams) -> String {
    let mesh = match m.method {
        MeshMethod::Uniform => format!("uniform, elements {:.1e} of the diagonal", m.element_size_rel),
        MeshMethod::DiscontinuityCdt if m.cdt_min_angle_deg > 0.0 => {
            format!("discontinuity-cdt, refined to {:.0}°", m.cdt_min_angle_deg)
        }
        other => other.name().to_owned(),
    };
    let order = match (m.order, m.continuous) {
        (crate::geometry::basis::Order::Constant, _) => "p = 0",
        (crate::geometry::basis::Order::Linear, false) => "p = 1 discontinuous",
        (crate::geometry::basis::Order::Linear, true) => "p = 1 continuous",
    };
    format!("{mesh} · {order} · {} rays", m.rays)
}

/// The name of the preset `p` is, "uniform mesh" for the form-factor oracle at Feps = 0 (no pair
/// is ever accurate enough: every element is split to the area floor and every pair of leaves
/// linked, as the lecture figures' uniform meshes, [`crate::present::figures::uniform`]), or "custom".
#[must_use]
pub fn preset_name(p: &HierarchicalParams) -> String {
    if p.oracle == Oracle::Feps && p.feps == 0.0 {
        return "uniform mesh".to_owned();
    }
    crate::solver::spec::Preset::ALL
        .iter()
        .find(|preset| preset.hierarchical() == *p)
        .map_or_else(|| "custom".to_owned(), |preset| preset.name().to_owned())
}

/// The solver's estimate of the relative L2 error of a solver state (its leaves); `None` while
/// its estimates are being computed, or when they were given up ([`ViewData::estimates`]).
#[must_use]
pub fn estimate_of(view: &ViewData) -> Option<f64> {
    if view.estimates != Estimates::Included {
        return None;
    }
    global_relative_l2(view.leaves.iter().map(|&l| {
        let e = &view.elements[l as usize];
        (e.area, (e.radiosity - e.emission).mean(), Some(e.error_estimate))
    }))
}

/// A named line of points of a plot.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    pub name: String,
    pub points: Vec<[f64; 2]>,
}

/// What the history panel asks of the app.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum HistoryAction {
    /// Show the split view (with the picked runs).
    ShowSplit,
}

/// Every solve of this window, and the runs picked for the split view.
#[derive(Clone, Debug, Default)]
pub struct RunHistory {
    runs: Vec<Run>,
    /// Numbers of the runs picked for the split view, in the order picked.
    picked: Vec<usize>,
    /// The history window is open.
    pub open: bool,
}

impl RunHistory {
    /// Keep a finished solve in place of run `over` when that is the newest run (the solves of
    /// one slider drag make one run, each replacing the one before), else as a new run.
    /// Returns its number.
    pub fn record_over(
        &mut self,
        over: Option<usize>,
        scene: &str,
        time_s: f64,
        view_seq: u64,
        view: Arc<ViewData>,
    ) -> usize {
        if let Some(n) = over
            && self.runs.last().is_some_and(|r| r.number == n && r.kind == RunKind::Solve)
        {
            // Numbered after the one before it: the same number again.
            self.runs.pop();
        }
        self.record(scene, time_s, view_seq, view);
        self.runs.last().map_or(0, |r| r.number)
    }

    /// Keep a finished solve (numbered after the last one; its settings are the view's);
    /// older solutions are dropped past [`KEEP_SOLUTIONS`].
    pub fn record(&mut self, scene: &str, time_s: f64, view_seq: u64, view: Arc<ViewData>) {
        let params = view.params;
        let mesh = view.mesh.as_ref().map(|m| m.params);
        self.push(Run {
            number: 0,
            kind: RunKind::Solve,
            scene: scene.to_owned(),
            preset: mesh.map_or_else(|| preset_name(&params), |m| m.label()),
            params,
            mesh,
            elements: view.stats.leaves,
            unknowns: view.unknowns(),
            links: view.stats.links,
            time_s,
            // A mesh solve has no estimate of its own.
            estimate: if mesh.is_some() { None } else { estimate_of(&view) },
            reference: None,
            ruler: Ruler::Reference,
            band: None,
            view_seq,
            view: Some(view),
        });
    }

    /// Add a run, numbered after the last one; the oldest goes past [`MAX_RUNS`], older
    /// solutions past [`KEEP_SOLUTIONS`].
    fn push(&mut self, run: Run) {
        let number = self.runs.last().map_or(1, |r| r.number + 1);
        self.runs.push(Run { number, ..run });
        if self.runs.len() > MAX_RUNS {
            let gone = self.runs.remove(0).number;
            self.picked.retain(|&n| n != gone);
        }
        self.evict();
    }

    /// Keep the scene's reference as a run (once per scene and reference settings).
    pub fn record_reference(&mut self, scene: &str, samples: u32, view: Arc<ViewData>) {
        let points = view.leaves.len();
        let same = |r: &Run| {
            r.scene == scene
                && matches!(r.kind, RunKind::Reference { points: n, samples: s, .. } if n == points && s == samples)
        };
        if let Some(r) = self.runs.iter_mut().find(|r| same(r)) {
            r.view.get_or_insert(view);
            return;
        }
        // The noise: its standard errors, weighed as the solver's estimates are.
        let noise = estimate_of(&view);
        self.push(Run {
            number: 0,
            kind: RunKind::Reference { points, samples, noise },
            scene: scene.to_owned(),
            preset: "reference".to_owned(),
            params: view.params,
            mesh: None,
            elements: points,
            unknowns: points,
            links: 0,
            time_s: 0.0,
            estimate: None,
            reference: None,
            ruler: Ruler::Reference,
            band: None,
            view_seq: 0,
            view: Some(view),
        });
    }

    /// Drop the solutions of runs that are neither among the newest [`KEEP_SOLUTIONS`] nor picked.
    fn evict(&mut self) {
        let keep_from = self.runs.len().saturating_sub(KEEP_SOLUTIONS);
        for (i, r) in self.runs.iter_mut().enumerate() {
            if i < keep_from && !self.picked.contains(&r.number) {
                r.view = None;
            }
        }
    }

    /// Whether a run keeps state `of` (one [`Self::fold_estimates`] replaces).
    #[must_use]
    pub fn keeps(&self, of: &Arc<ViewData>) -> bool {
        self.runs.iter().any(|r| r.view.as_ref().is_some_and(|v| Arc::ptr_eq(v, of)))
    }

    /// The error estimates of solution `of` arrived, or were given up (`view`: it with them, or
    /// marked so): the runs that keep it keep `view` instead, and their estimated error is read
    /// from it (none where given up: the run says "not estimated").
    pub fn fold_estimates(&mut self, of: &Arc<ViewData>, view: &Arc<ViewData>) {
        for r in &mut self.runs {
            if r.view.as_ref().is_some_and(|v| Arc::ptr_eq(v, of)) {
                r.view = Some(Arc::clone(view));
                if r.mesh.is_none() && r.kind == RunKind::Solve {
                    r.estimate = estimate_of(view);
                }
            }
        }
    }

    /// The reference thread scored solver state `view_seq` against `ruler`: its run (if one)
    /// gets the error (and the penumbra band's, `band`).
    pub fn set_reference_error(&mut self, view_seq: u64, rel_l2: f64, band: Option<f64>, ruler: Ruler) {
        if let Some(r) = self.runs.iter_mut().rev().find(|r| r.view_seq == view_seq)
            && rel_l2.is_finite()
        {
            r.reference = Some(rel_l2);
            r.ruler = ruler;
            r.band = band.filter(|b| b.is_finite());
        }
    }

    /// Solves of `scene` that keep their solution but have no error against the reference yet:
    /// (view number, solver time, solution), for the reference thread to score once the scene
    /// has a reference.
    #[must_use]
    pub fn unscored(&self, scene: &str) -> Vec<(u64, f64, Arc<ViewData>)> {
        self.runs
            .iter()
            .filter(|r| r.kind == RunKind::Solve && r.scene == scene && r.reference.is_none())
            .filter_map(|r| r.view.as_ref().map(|v| (r.view_seq, r.time_s, Arc::clone(v))))
            .collect()
    }

    /// All runs, oldest first.
    #[must_use]
    pub fn runs(&self) -> &[Run] {
        &self.runs
    }

    #[must_use]
    pub fn len(&self) -> usize {
        self.runs.len()
    }

    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.runs.is_empty()
    }

    /// Runs that still keep their solution.
    #[must_use]
    pub fn kept(&self) -> usize {
        self.runs.iter().filter(|r| r.view.is_some()).count()
    }

    /// Numbers of the runs picked for the split view.
    #[must_use]
    pub fn picked(&self) -> &[usize] {
        &self.picked
    }

    /// Pick run `number` for the split view, or unpick it; at most [`MAX_PICKED`] (the oldest
    /// pick goes). Runs without their solution cannot be picked.
    pub fn toggle_pick(&mut self, number: usize) {
        if let Some(i) = self.picked.iter().position(|&n| n == number) {
            self.picked.remove(i);
            self.evict();
        } else if self.runs.iter().any(|r| r.number == number && r.view.is_some()) {
            if self.picked.len() == MAX_PICKED {
                self.picked.remove(0);
            }
            self.picked.push(number);
            self.evict();
        }
    }

    /// The runs the split view shows: the picked ones when two or more are picked (in the order
    /// solved), else the pick and the newest runs of `scene` with a solution, up to `panes`.
    #[must_use]
    pub fn split_runs(&self, panes: usize, scene: &str) -> Vec<&Run> {
        let with_view = |n: usize| self.runs.iter().find(|r| r.number == n && r.view.is_some());
        let mut out: Vec<&Run> = self.picked.iter().filter_map(|&n| with_view(n)).collect();
        if out.len() < 2 {
            for r in self.runs.iter().rev().filter(|r| r.view.is_some() && r.scene == scene) {
                if out.len() >= panes {
                    break;
                }
                if !out.iter().any(|o| o.number == r.number) {
                    out.push(r);
                }
            }
        }
        out.sort_by_key(|r| r.number);
        out
    }

    /// Forget every run.
    pub fn clear(&mut self) {
        self.runs.clear();
        self.picked.clear();
    }

    /// Links against elements, log₁₀ both, one series per scene and oracle (sorted by elements).
    #[must_use]
    pub fn links_series(&self) -> Vec<Series> {
        self.series_of(|r| {
            (r.elements > 0 && r.links > 0).then(|| [(r.elements as f64).log10(), (r.links as f64).log10()])
        })
    }

    /// Error (log₁₀) against solver time, one series per scene and oracle and per kind of error
    /// (against the reference, the closed form, or the solver's estimate: never mixed in one
    /// line, each named so).
    #[must_use]
    pub fn error_series(&self) -> Vec<Series> {
        let mut out = Vec::new();
        for ruler in [Ruler::Reference, Ruler::ClosedForm] {
            let mut measured = self.series_of(|r| {
                r.reference.filter(|e| *e > 0.0 && r.ruler == ruler).map(|e| [r.time_s, e.log10()])
            });
            for s in &mut measured {
                s.name = format!("{} (vs {})", s.name, ruler.name());
            }
            out.append(&mut measured);
        }
        let mut est = self.series_of(|r| {
            r.reference
                .is_none()
                .then_some(r.estimate)
                .flatten()
                .filter(|e| *e > 0.0)
                .map(|e| [r.time_s, e.log10()])
        });
        for s in &mut est {
            s.name.push_str(" (estimate)");
        }
        out.append(&mut est);
        out
    }

    /// The runs grouped by [`Run::series`] (in order of first appearance), each series' points
    /// sorted by x.
    fn series_of(&self, point: impl Fn(&Run) -> Option<[f64; 2]>) -> Vec<Series> {
        let mut out: Vec<Series> = Vec::new();
        for r in self.runs.iter().filter(|r| r.kind == RunKind::Solve) {
            let Some(p) = point(r) else { continue };
            let name = r.series();
            match out.iter_mut().find(|s| s.name == name) {
                Some(s) => s.points.push(p),
                None => out.push(Series { name, points: vec![p] }),
            }
        }
        for s in &mut out {
            s.points.sort_by(|a, b| a[0].total_cmp(&b[0]));
        }
        out
    }

    /// The history window (when open).
    pub fn window(&mut self, ctx: &egui::Context) -> Option<HistoryAction> {
        let mut open = self.open;
        let mut action = None;
        egui::Window::new("Run history")
            .open(&mut open)
            .default_pos([300.0, 430.0])
            .default_width(620.0)
            .show(ctx, |ui| action = self.ui(ui, ()));
        self.open = open;
        action
    }
}

impl View for RunHistory {
    type Input<'a> = ();
    type Action = HistoryAction;

    /// The table of runs (newest first) with a pick box each for the split view.
    fn ui(&mut self, ui: &mut egui::Ui, (): ()) -> Option<HistoryAction> {
        let mut action = None;
        ui.label(format!(
            "{} runs; the newest {KEEP_SOLUTIONS} (and the picked ones) keep their solution for the split view",
            self.runs.len()
        ));
        if self.runs.is_empty() {
            ui.weak("Every Solve is listed here with its settings, size, time and error.");
        }
        let mut toggle = None;
        egui::ScrollArea::vertical().max_height(260.0).id_salt("history_rows").show(ui, |ui| {
            egui::Grid::new("history").num_columns(8).striped(true).show(ui, |ui| {
                for h in ["split", "run", "settings", "elements", "links", "time", "error"] {
                    ui.strong(h);
                }
                ui.end_row();
                for r in self.runs.iter().rev() {
                    let mut on = self.picked.contains(&r.number);
                    let tip = if r.view.is_some() {
                        "Show this run in the split view (pick two or three)"
                    } else {
                        "Its solution was dropped (only the newest runs keep theirs): solve it again to show it"
                    };
                    let pick = ui
                        .add_enabled(r.view.is_some(), egui::Checkbox::without_text(&mut on))
                        .on_hover_text(tip)
                        .on_disabled_hover_text(tip);
                    // Its accessible name (screen readers, UI tests): the box has no text.
                    let name = format!("pick run #{} for the split view", r.number);
                    ui.ctx().accesskit_node_builder(pick.id, |b| b.set_label(name));
                    if pick.changed() {
                        toggle = Some(r.number);
                    }
                    ui.label(format!("#{} {}", r.number, r.scene));
                    ui.label(&r.preset).on_hover_text(r.thresholds());
                    ui.monospace(r.elements.to_string());
                    ui.monospace(r.links.to_string());
                    match r.kind {
                        RunKind::Solve => ui.monospace(format!("{:.2} s", r.time_s)),
                        RunKind::Reference { .. } => ui.monospace("–"),
                    };
                    ui.label(r.error().short()).on_hover_text(r.error().label());
                    ui.end_row();
                }
            });
        });
        if let Some(n) = toggle {
            self.toggle_pick(n);
        }
        ui.horizontal(|ui| {
            let shown = self.split_runs(MAX_PICKED, self.runs.last().map_or("", |r| r.scene.as_str())).len();
            if ui
                .add_enabled(shown >= 2, egui::Button::new("Show in split view"))
                .on_hover_text(
                    "Side by side with one camera and one exposure: the picked runs, or the newest ones",
                )
                .on_disabled_hover_text("Needs two runs that keep their solution: solve twice")
                .clicked()
            {
                action = Some(HistoryAction::ShowSplit);
            }
            if ui.button("Clear").on_hover_text("Forget every run (the plots start over)").clicked() {
                self.clear();
            }
        });
        action
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{DVec3, Rgb};
    use crate::present::overlay::{ElementCore, ElementView};

    /// A one-leaf solver state with `links` links, lit to `b` with estimate `est`.
    fn view(params: HierarchicalParams, links: usize, b: f64, est: f64) -> Arc<ViewData> {
        let e = ElementView {
            core: ElementCore {
                id: 0,
                patch: 0,
                parent: None,
                depth: 0,
                vertices: [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
                n_vertices: 4,
                area: 1.0,
                reflectance: Rgb::splat(0.5),
                emission: Rgb::ZERO,
                radiosity: Rgb::splat(b),
                error_estimate: est,
            },
            leaf: true,
            stop: "",
        };
        let mut v = ViewData { elements: vec![e], leaves: vec![0], params, ..ViewData::default() };
        v.stats.leaves = 1;
        v.stats.links = links;
        Arc::new(v)
    }

    /// A run recorded before its estimates says "estimating…"; they fold in as its estimate, or,
    /// given up, it says "not estimated" and has no estimate (none of 0, none plotted).
    #[test]
    fn a_runs_estimate_follows_or_is_given_up() {
        let mut h = RunHistory::default();
        let p = HierarchicalParams::interactive();
        let pending =
            |est| Arc::new(ViewData { estimates: Estimates::Pending, ..(*view(p, 10, 1.0, est)).clone() });
        let (first, second) = (pending(0.0), pending(0.0));
        h.record("box", 0.1, 1, Arc::clone(&first));
        h.record("box", 0.2, 2, Arc::clone(&second));
        assert!(h.runs().iter().all(|r| r.error() == RunError::Estimating && r.estimate.is_none()));
        assert!(h.keeps(&first) && h.keeps(&second), "the runs keep the states they recorded");
        assert!(!h.keeps(&pending(0.0)), "an equal state that no run keeps");
        h.fold_estimates(&first, &Arc::new(first.with_estimates(&[0.05])));
        assert!(!h.keeps(&first), "the run keeps the state with its estimates instead");
        h.fold_estimates(&second, &Arc::new(second.without_estimates()));
        assert!((h.runs()[0].estimate.unwrap() - 0.05).abs() < 1e-12);
        let given_up = &h.runs()[1];
        assert_eq!((given_up.error(), given_up.estimate), (RunError::NotEstimated, None));
        assert_eq!(given_up.error().short(), "not estimated");
        let plotted: usize = h.error_series().iter().map(|s| s.points.len()).sum();
        assert_eq!(plotted, 1, "only the estimated run is plotted");
    }

    #[test]
    fn keeps_every_run_but_only_the_newest_solutions() {
        let mut h = RunHistory::default();
        let p = HierarchicalParams::interactive();
        for i in 0..KEEP_SOLUTIONS + 3 {
            h.record("box", 0.1 * i as f64, i as u64, view(p, 10 + i, 1.0, 0.02));
        }
        assert_eq!(h.len(), KEEP_SOLUTIONS + 3);
        assert_eq!(h.kept(), KEEP_SOLUTIONS, "memory is bounded");
        assert!(h.runs()[0].view.is_none() && h.runs().last().unwrap().view.is_some());
        assert_eq!(h.runs()[2].preset, "bf");
        // A picked run keeps its solution when it ages past the window.
        let newest_old = h.runs()[3].number;
        h.toggle_pick(newest_old);
        assert_eq!(h.picked(), &[newest_old]);
        h.toggle_pick(1); // dropped already: cannot be picked
        assert_eq!(h.picked(), &[newest_old]);
        for i in 0..KEEP_SOLUTIONS {
            h.record("box", 1.0, 100 + i as u64, view(p, 5, 1.0, 0.02));
        }
        assert_eq!(h.kept(), KEEP_SOLUTIONS + 1);
        assert!(h.runs()[3].view.is_some());
    }

    #[test]
    fn the_split_view_takes_the_picks_or_the_newest_runs() {
        let mut h = RunHistory::default();
        let p = HierarchicalParams::interactive();
        for i in 0..4 {
            h.record("box", 1.0, i, view(p, 10, 1.0, 0.02));
        }
        let numbers = |rs: Vec<&Run>| rs.iter().map(|r| r.number).collect::<Vec<_>>();
        h.record("other", 1.0, 9, view(p, 10, 1.0, 0.02));
        assert_eq!(numbers(h.split_runs(2, "box")), vec![3, 4], "the newest two of the scene");
        assert_eq!(numbers(h.split_runs(3, "box")), vec![2, 3, 4]);
        assert_eq!(numbers(h.split_runs(3, "other")), vec![5], "one run of that scene");
        h.toggle_pick(1);
        assert_eq!(numbers(h.split_runs(2, "box")), vec![1, 4], "one pick and the newest");
        h.toggle_pick(5);
        assert_eq!(numbers(h.split_runs(3, "box")), vec![1, 5], "two picks: those, whatever the scene");
        for n in [3, 4] {
            h.toggle_pick(n);
        }
        assert_eq!(h.picked(), &[5, 3, 4], "at most three, the oldest pick goes");
    }

    /// The solves of one drag make one run: each replaces the drag's run while it is the newest;
    /// a run of its own otherwise.
    #[test]
    fn a_drag_records_over_its_own_run() {
        let mut h = RunHistory::default();
        let bf = HierarchicalParams::interactive();
        let first = h.record_over(None, "box", 0.1, 1, view(bf, 10, 2.0, 0.1));
        let drag = h.record_over(None, "box", 0.1, 2, view(bf, 20, 2.0, 0.1));
        assert_eq!((first, drag), (1, 2));
        let again = h.record_over(Some(drag), "box", 0.1, 3, view(bf, 30, 2.0, 0.1));
        assert_eq!(again, drag, "the drag's next solve replaces its run");
        assert_eq!(h.len(), 2);
        assert_eq!((h.runs()[1].links, h.runs()[1].view_seq), (30, 3), "the newest solve's numbers");
        // Only while it is the newest run: the run before it stays.
        h.set_reference_error(2, 0.1, Some(0.4), Ruler::ClosedForm);
        assert_eq!(h.record_over(Some(first), "box", 0.1, 4, view(bf, 40, 2.0, 0.1)), 3);
        assert_eq!(h.len(), 3);
        assert_eq!(h.runs()[1].band, None, "the replaced solve's score is not the new one's");
        h.set_reference_error(4, 0.1, Some(0.4), Ruler::ClosedForm);
        assert!(h.runs()[2].numbers().contains("penumbra band 40.00 %"), "{}", h.runs()[2].numbers());
        assert!(h.runs()[2].numbers().contains("(vs closed form)"), "{}", h.runs()[2].numbers());
    }

    #[test]
    fn errors_prefer_the_reference_and_series_overlay_runs() {
        let mut h = RunHistory::default();
        let mut feps = HierarchicalParams::lecture();
        let bf = HierarchicalParams::interactive();
        h.record("box", 0.5, 7, view(bf, 100, 2.0, 0.1));
        feps.feps = 0.01;
        h.record("box", 0.2, 8, view(feps, 40, 2.0, 0.3));
        h.record("box", 0.1, 9, view(bf, 20, 2.0, 0.2));
        // est = sqrt(A est² / A B²) = est / B.
        assert!((h.runs()[0].estimate.unwrap() - 0.05).abs() < 1e-12);
        assert_eq!(h.runs()[1].preset, "custom");
        assert!(matches!(h.runs()[0].error(), RunError::Estimate(_)));
        assert_eq!(h.unscored("box").len(), 3);
        h.set_reference_error(7, 0.04, None, Ruler::Reference);
        assert_eq!(h.unscored("box").iter().map(|u| u.0).collect::<Vec<_>>(), vec![8, 9]);
        assert_eq!(h.runs()[0].error(), RunError::Reference(0.04));
        assert!(h.runs()[0].error().label().contains("vs reference"));
        assert!(h.runs()[1].error().label().contains("estimate"));

        let links = h.links_series();
        assert_eq!(links.len(), 2, "{links:?}");
        assert_eq!(links[0].name, "box · BF oracle");
        assert_eq!((links[0].points.len(), links[1].points.len()), (2, 1));
        assert_eq!(links[1].points, vec![[0.0, 40f64.log10()]]);
        let err = h.error_series();
        let names: Vec<&str> = err.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(
            names,
            ["box · BF oracle (vs reference)", "box · Feps oracle (estimate)", "box · BF oracle (estimate)"]
        );
        assert_eq!(err[0].points, vec![[0.5, 0.04f64.log10()]]);
        assert_eq!(h.runs()[1].title(), "#2 box · custom");
        assert_eq!(preset_name(&crate::present::figures::uniform(1e-3)), "uniform mesh");
        // The reference: one run per scene and settings, its noise as its error, not plotted.
        for _ in 0..2 {
            h.record_reference("box", 64, view(HierarchicalParams::default(), 0, 2.0, 0.02));
        }
        assert_eq!(h.len(), 4);
        let r = &h.runs()[3];
        assert_eq!(r.error(), RunError::Noise(0.01));
        assert!(r.thresholds().contains("× 64 paths") && r.numbers().contains("Monte Carlo noise"));
        assert_eq!(h.links_series(), links, "the reference is not plotted");
        assert!(
            h.runs()[1].thresholds().starts_with("Feps oracle, Feps 1.0e-2"),
            "{}",
            h.runs()[1].thresholds()
        );
    }
}
