//! The reference solution in the viewer: looks up (or, on request, computes) the independent
//! Monte Carlo reference of [`crate::eval::reference`] for the loaded scene on its own thread,
//! `radlab-reference`, and then scores every new solver state against it, off the UI thread:
//!
//! - the **true error per element** shown by the error heatmap: the mean |B_i − B̂| at 3 × 3
//!   points of leaf i, B̂ the reference interpolated linearly between its points
//!   ([`crate::eval::pointwise::PointInterpolant`]; units of B);
//! - the **pointwise relative L2 error** of the whole solution (the pointwise ruler,
//!   [`crate::eval::pointwise`]: the leaves evaluated at the reference's points, debiased), a point of
//!   the error-against-time plot.
//!
//! The reference is `radlab reference`'s pointwise one (its default: at least 65 536 points,
//! denser where the answer varies fast, 1024 paths each, [`PointParams::standard`]) with its
//! disk cache, so a reference computed on the command line is found here and the other way
//! round. It is drawn as the points' cells.
//!
//! A single-bounce scene ([`crate::geometry::exact::SingleBounce`], e.g. builtin:shadow-narrow) needs none:
//! its reference is the closed form, at as many points on uniform grids
//! ([`crate::eval::reference::points::uniform_points`]) with no noise, and B̂ of the heatmap is the
//! closed form itself. It is ready as soon as the scene loads; it is not drawn nor kept as a run.
//!
//! A computation reports its progress and can be cancelled through a shared
//! [`Control`]; a cancelled computation leaves no cache entry and the scene without reference.
//! A command that panics is answered [`RefReply::Panicked`] ([`super::panics`]), and the thread
//! goes on with the next one.
//!
//! ```text
//!  UI ── Load{scene, compute} ──► "radlab-reference": cache look-up / estimate (seconds–minutes)
//!  UI ◄─ progress / cancel ─────► Arc<Control> (atomics, read every frame)
//!  UI ── Evaluate{view} ────────► per-element error + rel L2 ── Reply ──► UI (heatmap, plot)
//! ```

use super::history::Ruler;
use super::panics;
use super::worker::ViewData;
use crate::eval::reference::{Cache, CacheStatus, Control, Estimate, PointParams, RefPoint, ReferenceError};
use crate::geometry::accel::Accel;
use crate::geometry::exact::SingleBounce;
use crate::math::Rgb;
use crate::present::overlay::ElementView;
use crate::scene::Scene;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::Instant;

/// Where the reference comes from.
#[derive(Clone, Debug)]
pub struct RefSettings {
    pub params: PointParams,
    pub cache: Cache,
}

impl Default for RefSettings {
    fn default() -> Self {
        RefSettings { params: PointParams::standard(), cache: Cache::default_location() }
    }
}

/// What the UI asks.
pub enum RefCommand {
    /// A new scene: look for a cached reference; with `compute`, estimate it when there is none
    /// (progress and cancellation through `control`).
    Load { scene: Arc<Scene>, compute: bool, control: Arc<Control> },
    /// Score a solver state (`view_seq` and `solver_time_s` are passed back).
    Evaluate { view: Arc<ViewData>, view_seq: u64, solver_time_s: f64 },
}

/// What the reference thread answers.
#[derive(Clone, Debug)]
pub enum RefReply {
    /// Computing: at least `points` points × paths per point, for the progress line.
    Computing {
        source: String,
        points: usize,
        samples: u32,
    },
    /// No cached reference for this scene (and none was asked for).
    Missing {
        source: String,
    },
    Ready {
        source: String,
        points: usize,
        samples: u32,
        how: String,
    },
    /// The computation was cancelled (nothing cached; the scene has no reference).
    Cancelled {
        source: String,
    },
    /// The reference as a solver state to draw (its points' cells the leaves, their estimates
    /// the radiosity, the standard error the error estimate; no links): sent just before
    /// `Ready`.
    Solution {
        source: String,
        view: Arc<ViewData>,
    },
    Evaluated(Evaluation),
    /// A state sent for scoring after the scene changed to one without a reference (the app
    /// had not yet heard so): nothing to score it against, and nothing wrong.
    Unscored {
        view_seq: u64,
    },
    Failed(String),
    /// The command panicked (one line: "the reference thread panicked at …"); a `Load` leaves
    /// the scene without reference.
    Panicked(String),
}

/// The score of one solver state.
#[derive(Clone, Debug, PartialEq)]
pub struct Evaluation {
    pub view_seq: u64,
    pub solver_time_s: f64,
    /// Each leaf's error, the mean |B − B̂| at 3 × 3 points of the leaf, B̂ the reference
    /// interpolated linearly between its points (units of B; 0 for interior elements).
    pub per_element: Vec<f64>,
    /// Pointwise relative L2 error of the solution against the reference, debiased by its noise
    /// (see [`crate::eval::pointwise`]).
    pub rel_l2: f64,
    /// The same over the penumbra band (the closed form's only: there the band is exact).
    pub band_l2: Option<f64>,
    /// What it was measured against: the Monte Carlo reference or the closed form.
    pub ruler: Ruler,
}

/// The reference of one scene.
struct Loaded {
    scene: Arc<Scene>,
    points: Vec<RefPoint>,
    /// Each point's cell (to draw the reference).
    cells: Vec<crate::eval::reference::RefElement>,
    estimates: Vec<Estimate>,
    /// B̂ anywhere (the heatmap's).
    truth: Truth,
    /// The points in the penumbra band (the closed form's only, [`exact_band`]).
    band: Option<Vec<bool>>,
}

/// Where the heatmap's B̂ comes from.
enum Truth {
    /// The Monte Carlo reference interpolated linearly between its points, triangulated once per
    /// reference, not per solver state.
    Points(crate::eval::pointwise::PointInterpolant),
    /// The closed form of a single-bounce scene.
    Exact(SingleBounce),
}

impl Truth {
    fn radiosity_at(&self, patch: usize, x: crate::math::DVec3) -> crate::math::Rgb {
        use crate::eval::pointwise::Reconstruction as _;
        match self {
            Truth::Points(interp) => interp.radiosity_at(patch, x),
            Truth::Exact(sb) => sb.patch_radiosity_at(patch, x),
        }
    }
}

/// What the reference panel and the runs call the closed form ([`RefReply::Ready`]'s `how`).
pub const CLOSED_FORM: &str = "the closed form (single bounce)";

/// The points of a single-bounce scene's receiver in its penumbra band: lit(x), the visible part
/// of the emitter's form factor, strictly between the band's bounds
/// ([`crate::eval::penumbra::BandParams::standard`]), exactly (every bit of light there is direct).
fn exact_band(scene: &Scene, sb: &SingleBounce, points: &[RefPoint]) -> Vec<bool> {
    let band = crate::eval::penumbra::BandParams::standard();
    let (emitter, receiver) = (&scene.patches[sb.emitter], &scene.patches[sb.receiver]);
    points
        .iter()
        .map(|p| {
            if p.patch != sb.receiver {
                return false;
            }
            let total = crate::geometry::form_factor::point_to_polygon_oriented(
                p.position,
                receiver.normal,
                &emitter.vertices,
                emitter.normal,
            );
            let lit = if total > 0.0 { sb.visible_form_factor(p.position) / total } else { 0.0 };
            lit > band.lo && lit < band.hi
        })
        .collect()
}

/// Score a solver state against a reference: through each solution's own functions (a p = 1
/// mesh solve's vertex values, else one value an element).
fn evaluate(r: &Loaded, view: &ViewData, view_seq: u64, solver_time_s: f64) -> Result<Evaluation, String> {
    let leaves = view.solved_leaves();
    let fail = |e: crate::eval::metrics::MetricsError| e.to_string();
    let values = match view.mesh.as_ref().and_then(|m| m.coefficients.as_ref().map(|c| (m, c))) {
        Some((m, c)) => {
            let nodal = crate::eval::reconstruction::Nodal::new(&r.scene, &m.solution.elements, c.to_vec())
                .map_err(fail)?;
            crate::eval::pointwise::evaluate(&nodal, &r.points)
        }
        None => {
            let pc = crate::eval::pointwise::PiecewiseConstant::new(&r.scene, &leaves).map_err(fail)?;
            crate::eval::pointwise::evaluate(&pc, &r.points)
        }
    };
    let report = crate::eval::pointwise::compare_points(&r.scene, &r.points, &values, &r.estimates, 0.0)
        .map_err(fail)?;
    let band_l2 = match &r.band {
        Some(band) => {
            crate::eval::pointwise::compare_points_in(&r.scene, &r.points, &values, &r.estimates, band, 0.0)
                .map_err(fail)?
                .map(|b| b.report.scene.l2_debiased)
        }
        None => None,
    };
    // Per leaf: the mean |B − B̂| at 3 × 3 points of the leaf, B̂ the closed form or the
    // reference interpolated linearly between its points (a leaf finer than the points' spacing
    // holds none of them).
    let mut per_element = vec![0.0; view.elements.len()];
    const AT: [f64; 3] = [1.0 / 6.0, 0.5, 5.0 / 6.0];
    for (&l, leaf) in view.leaves.iter().zip(&leaves) {
        let mut sum = 0.0;
        for u in AT {
            for v in AT {
                let x = crate::geometry::visibility::point_on_polygon(&leaf.vertices, u, v);
                sum += (leaf.radiosity_at(x) - r.truth.radiosity_at(leaf.patch, x)).map(f64::abs).mean();
            }
        }
        per_element[l as usize] = sum / 9.0;
    }
    let ruler = match r.truth {
        Truth::Points(_) => Ruler::Reference,
        Truth::Exact(_) => Ruler::ClosedForm,
    };
    Ok(Evaluation { view_seq, solver_time_s, per_element, rel_l2: report.scene.l2_debiased, band_l2, ruler })
}

/// Name of the reference thread in its panic messages.
const THREAD: &str = "reference";

/// Handle of the reference thread (it ends when this is dropped).
pub struct RefThread {
    tx: Sender<RefCommand>,
    rx: Receiver<RefReply>,
    /// Commands sent and not answered yet.
    pending: usize,
    /// Progress and cancellation of the newest `Load`.
    control: Option<Arc<Control>>,
}

impl RefThread {
    /// Start the thread; `notify` is called after each reply (the UI's repaint request).
    pub fn spawn(settings: RefSettings, notify: impl Fn() + Send + 'static) -> Result<RefThread, String> {
        let (tx, cmd_rx) = channel::<RefCommand>();
        let (reply_tx, rx) = channel::<RefReply>();
        std::thread::Builder::new()
            .name("radlab-reference".into())
            .spawn(move || {
                let mut loaded: Option<Loaded> = None;
                while let Ok(cmd) = cmd_rx.recv() {
                    let reply = match cmd {
                        RefCommand::Load { scene, compute, control } => {
                            let answer = panics::catching(THREAD, || {
                                let (reply, l) = load(&settings, scene, compute, &control, &|r| {
                                    let _ = reply_tx.send(r);
                                    notify();
                                });
                                // The closed form is no discrete solution: not drawn, not a run.
                                if let Some(l) = l.as_ref().filter(|l| matches!(l.truth, Truth::Points(_))) {
                                    let source = l.scene.source.clone();
                                    let _ =
                                        reply_tx.send(RefReply::Solution { source, view: solution_view(l) });
                                }
                                (reply, l)
                            });
                            match answer {
                                Ok((reply, l)) => {
                                    loaded = l;
                                    reply
                                }
                                Err(e) => {
                                    loaded = None;
                                    RefReply::Panicked(e)
                                }
                            }
                        }
                        RefCommand::Evaluate { view, view_seq, solver_time_s } => match &loaded {
                            Some(r) => {
                                match panics::catching(THREAD, || evaluate(r, &view, view_seq, solver_time_s))
                                {
                                    Ok(Ok(e)) => RefReply::Evaluated(e),
                                    Ok(Err(e)) => RefReply::Failed(format!("reference comparison: {e}")),
                                    Err(e) => RefReply::Panicked(e),
                                }
                            }
                            None => RefReply::Unscored { view_seq },
                        },
                    };
                    if reply_tx.send(reply).is_err() {
                        return;
                    }
                    notify();
                }
            })
            .map_err(|e| format!("cannot start the reference thread: {e}"))?;
        Ok(RefThread { tx, rx, pending: 0, control: None })
    }

    pub fn send(&mut self, cmd: RefCommand) {
        let control = match &cmd {
            RefCommand::Load { control, .. } => Some(Arc::clone(control)),
            RefCommand::Evaluate { .. } => None,
        };
        if self.tx.send(cmd).is_ok() {
            self.pending += 1;
            if control.is_some() {
                self.control = control;
            }
        }
    }

    /// Look up (and with `compute`, estimate) the reference of `scene`; cancels a computation
    /// still running for the previous request.
    pub fn load(&mut self, scene: Arc<Scene>, compute: bool) {
        self.cancel();
        self.send(RefCommand::Load { scene, compute, control: Arc::new(Control::default()) });
    }

    /// Cancel the running computation, if any (it answers [`RefReply::Cancelled`]).
    pub fn cancel(&self) {
        if let Some(c) = &self.control {
            c.cancel();
        }
    }

    /// (work finished, work) of the newest computation; (0, 0) before it starts.
    #[must_use]
    pub fn progress(&self) -> (usize, usize) {
        self.control.as_ref().map_or((0, 0), |c| c.progress())
    }

    /// True while a command is queued or running.
    #[must_use]
    pub fn busy(&self) -> bool {
        self.pending > 0
    }

    /// Next reply, if any (never blocks).
    pub fn poll(&mut self) -> Option<RefReply> {
        let r = match self.rx.try_recv() {
            Ok(r) => r,
            Err(std::sync::mpsc::TryRecvError::Empty) => return None,
            // Gone with commands unanswered: nothing waits for them.
            Err(std::sync::mpsc::TryRecvError::Disconnected) if self.pending > 0 => {
                self.pending = 0;
                return Some(RefReply::Panicked(format!("the {THREAD} thread stopped")));
            }
            Err(std::sync::mpsc::TryRecvError::Disconnected) => return None,
        };
        if !matches!(r, RefReply::Computing { .. } | RefReply::Solution { .. }) {
            self.pending = self.pending.saturating_sub(1);
        }
        Some(r)
    }

    /// Block until every command is answered (tests and scripted runs only; never in `ui`).
    pub fn wait_idle(&mut self, mut on_reply: impl FnMut(RefReply)) {
        while self.pending > 0 {
            match self.rx.recv() {
                Ok(r) => {
                    if !matches!(r, RefReply::Computing { .. } | RefReply::Solution { .. }) {
                        self.pending -= 1;
                    }
                    on_reply(r);
                }
                Err(_) => {
                    self.pending = 0;
                    on_reply(RefReply::Panicked(format!("the {THREAD} thread stopped")));
                }
            }
        }
    }
}

/// The reference as a solver state: one leaf per point's cell (at depth 0 of its patch), the
/// point's estimate as its radiosity and the mean of its standard error as its error estimate.
fn solution_view(r: &Loaded) -> Arc<ViewData> {
    let elements: Vec<ElementView> = r
        .cells
        .iter()
        .zip(&r.estimates)
        .enumerate()
        .map(|(i, (m, est))| {
            let area = crate::math::polygon_area(&m.vertices);
            let patch = &r.scene.patches[m.patch];
            let e = est.std_error.mean();
            ElementView::flat_leaf(
                i as u32,
                m.patch,
                patch,
                &m.vertices,
                area,
                est.radiosity,
                e,
                "reference point's cell",
            )
        })
        .collect();
    Arc::new(ViewData::of_flat_leaves(elements))
}

fn load(
    settings: &RefSettings,
    scene: Arc<Scene>,
    compute: bool,
    control: &Control,
    progress: &dyn Fn(RefReply),
) -> (RefReply, Option<Loaded>) {
    if control.cancelled() {
        return (RefReply::Cancelled { source: scene.source.clone() }, None);
    }
    let source = scene.source.clone();
    let params = settings.params.batch(settings.params.layout_seed);
    // A single-bounce scene's answer is known: the closed form at as many points, no noise, no
    // cache, nothing to compute by hand.
    if let Ok(sb) = SingleBounce::new(&scene) {
        let set = crate::eval::reference::points::uniform_points(&scene, params.points);
        let estimates = set
            .points
            .iter()
            .map(|p| Estimate { radiosity: sb.patch_radiosity_at(p.patch, p.position), std_error: Rgb::ZERO })
            .collect();
        let cells = set.cell_regions(&scene);
        let points = set.points.len();
        let band = Some(exact_band(&scene, &sb, &set.points));
        let loaded = Loaded { scene, points: set.points, cells, estimates, truth: Truth::Exact(sb), band };
        return (RefReply::Ready { source, points, samples: 0, how: CLOSED_FORM.into() }, Some(loaded));
    }
    let samples = params.paths.samples;
    let loaded = |scene: Arc<Scene>, c: crate::eval::reference::CachedPoints| -> Result<Loaded, String> {
        let cells = c.set.cell_regions(&scene);
        let values: Vec<crate::math::Rgb> = c.estimates.iter().map(|e| e.radiosity).collect();
        let interp = crate::eval::pointwise::PointInterpolant::new(&scene, &c.set.points, &values)
            .map_err(|e| e.to_string())?;
        let truth = Truth::Points(interp);
        Ok(Loaded { scene, points: c.set.points, cells, estimates: c.estimates, truth, band: None })
    };
    // Ready with the loaded reference, or why it cannot be used.
    let ready = |source: String, how: String, scene: Arc<Scene>, c: crate::eval::reference::CachedPoints| {
        let points = c.set.points.len();
        match loaded(scene, c) {
            Ok(l) => (RefReply::Ready { source, points, samples, how }, Some(l)),
            Err(e) => (RefReply::Failed(e), None),
        }
    };
    if !compute {
        return match settings.cache.read_points(&scene, &params) {
            Ok((c, file)) => ready(source, format!("cached {}", file.display()), scene, c),
            Err(_) => (RefReply::Missing { source }, None),
        };
    }
    progress(RefReply::Computing { source: source.clone(), points: params.points as usize, samples });
    let started = Instant::now();
    let accel = Accel::build(&scene);
    match settings.cache.get_or_compute_points(&scene, &accel, &params, control) {
        Ok((mut c, status)) => {
            // Scored as the command line scores it: enclosed points left out.
            c.drop_enclosed(&scene, &accel);
            let how = match status {
                CacheStatus::Hit(f) => format!("cached {}", f.display()),
                CacheStatus::Computed(f) | CacheStatus::Recomputed { file: f, .. } => {
                    format!("computed in {:.1} s, saved {}", started.elapsed().as_secs_f64(), f.display())
                }
            };
            ready(source, how, scene, c)
        }
        Err(ReferenceError::Cancelled) => (RefReply::Cancelled { source }, None),
        Err(e) => (RefReply::Failed(e.to_string()), None),
    }
}

/// What the app keeps of the reference thread: the thread, the scoring it was sent, and the
/// reference solution of the scene shown.
#[derive(Default)]
pub struct RefClient {
    thread: Option<RefThread>,
    /// The solver state last sent for scoring.
    evaluated_seq: u64,
    /// Earlier runs sent for their error only (not the error plot's points).
    scoring_runs: Vec<u64>,
    /// The scene's Monte Carlo reference as flat leaves (once the thread has it).
    pub view: Option<Arc<ViewData>>,
}

impl RefClient {
    /// A client of `thread` (`None`: no reference at all).
    #[must_use]
    pub fn new(thread: Option<RefThread>) -> RefClient {
        RefClient { thread, ..RefClient::default() }
    }

    /// Look up (with `compute`, compute if not cached) the reference of `scene`; false when
    /// there is no thread.
    pub fn load(&mut self, scene: &Arc<Scene>, compute: bool) -> bool {
        let Some(t) = &mut self.thread else { return false };
        t.load(Arc::clone(scene), compute);
        true
    }

    /// Stop the computation (nothing is cached).
    pub fn cancel(&self) {
        if let Some(t) = &self.thread {
            t.cancel();
        }
    }

    /// (work finished, work) of the computation.
    #[must_use]
    pub fn progress(&self) -> (usize, usize) {
        self.thread.as_ref().map_or((0, 0), RefThread::progress)
    }

    /// True while a command is queued or running.
    #[must_use]
    pub fn busy(&self) -> bool {
        self.thread.as_ref().is_some_and(RefThread::busy)
    }

    /// Send solver state `view_seq` for scoring, once.
    pub fn evaluate(&mut self, view_seq: u64, view: &Arc<ViewData>, solver_time_s: f64) {
        if self.evaluated_seq == view_seq {
            return;
        }
        if let Some(t) = &mut self.thread {
            t.send(RefCommand::Evaluate { view: Arc::clone(view), view_seq, solver_time_s });
            self.evaluated_seq = view_seq;
        }
    }

    /// Score the current state again (a new reference).
    pub fn rescore(&mut self) {
        self.evaluated_seq = 0;
    }

    /// Send earlier runs (view_seq, solver time, solution), all but state `current`, for their
    /// error only.
    pub fn score_runs(&mut self, runs: Vec<(u64, f64, Arc<ViewData>)>, current: u64) {
        let Some(t) = &mut self.thread else { return };
        for (view_seq, solver_time_s, view) in runs {
            if view_seq != current && !self.scoring_runs.contains(&view_seq) {
                t.send(RefCommand::Evaluate { view, view_seq, solver_time_s });
                self.scoring_runs.push(view_seq);
            }
        }
    }

    /// True (once) if state `view_seq` was sent by [`RefClient::score_runs`].
    pub fn scored_run(&mut self, view_seq: u64) -> bool {
        let was = self.scoring_runs.contains(&view_seq);
        self.scoring_runs.retain(|&s| s != view_seq);
        was
    }

    /// The replies so far (never blocks).
    pub fn poll(&mut self) -> Vec<RefReply> {
        let mut replies = Vec::new();
        if let Some(t) = &mut self.thread {
            while let Some(r) = t.poll() {
                replies.push(r);
            }
        }
        replies
    }

    /// Block until every command is answered and return the replies; `None` when idle (tests
    /// and scripted runs only).
    pub fn wait_idle(&mut self) -> Option<Vec<RefReply>> {
        let t = self.thread.as_mut().filter(|t| t.busy())?;
        let mut replies = Vec::new();
        t.wait_idle(|r| replies.push(r));
        Some(replies)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{DVec3, Rgb};
    use crate::present::overlay::ElementCore;

    #[test]
    fn cache_miss_compute_hit_and_evaluation() {
        let dir = std::env::temp_dir().join(format!("radlab-viewer-ref-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let settings = RefSettings {
            params: PointParams {
                points: 256,
                paths: crate::eval::reference::ReferenceParams {
                    samples: 8,
                    ..crate::eval::reference::ReferenceParams::quick()
                },
                ..PointParams::quick()
            },
            cache: Cache::at(&dir),
        };
        let scene = Arc::new(Scene::load("builtin:cube-one-light").unwrap());
        let mut t = RefThread::spawn(settings, || {}).unwrap();
        let mut replies = Vec::new();
        t.load(Arc::clone(&scene), false);
        t.wait_idle(|r| replies.push(r));
        assert!(matches!(replies.last(), Some(RefReply::Missing { .. })), "{replies:?}");
        // A state sent before the app heard that the scene has no reference is left unscored,
        // not reported as an error.
        t.send(RefCommand::Evaluate { view: Arc::new(ViewData::default()), view_seq: 3, solver_time_s: 0.1 });
        let mut answers = Vec::new();
        t.wait_idle(|r| answers.push(r));
        assert!(matches!(answers[..], [RefReply::Unscored { view_seq: 3 }]), "{answers:?}");
        t.load(Arc::clone(&scene), true);
        t.wait_idle(|r| replies.push(r));
        assert!(replies.iter().any(|r| matches!(r, RefReply::Computing { .. })));
        assert!(
            matches!(replies.last(), Some(RefReply::Ready { how, .. }) if how.starts_with("computed")),
            "{replies:?}"
        );
        // The reference to draw came with it: a leaf per point's cell, lit.
        let Some(RefReply::Solution { view, .. }) = replies.iter().rev().nth(1) else {
            panic!("{replies:?}")
        };
        assert!(view.leaves.len() >= 6 && view.links.is_empty());
        assert!(view.elements.iter().any(|e| e.radiosity.mean() > 0.0 && e.emission.is_zero()));
        t.load(Arc::clone(&scene), false);
        t.wait_idle(|r| replies.push(r));
        assert!(
            matches!(replies.last(), Some(RefReply::Ready { how, .. }) if how.starts_with("cached")),
            "{replies:?}"
        );

        // A solver state of one element per face, all at B = 0: the error is the reference itself.
        let elements: Vec<ElementView> = scene
            .patches
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let mut vertices = [DVec3::ZERO; 4];
                vertices[..p.vertices.len()].copy_from_slice(&p.vertices);
                ElementView {
                    core: ElementCore {
                        id: i as u32,
                        patch: i as u32,
                        parent: None,
                        depth: 0,
                        vertices,
                        n_vertices: p.vertices.len() as u8,
                        area: p.area,
                        reflectance: p.reflectance,
                        emission: p.emission,
                        radiosity: Rgb::ZERO,
                        error_estimate: 0.0,
                    },
                    leaf: true,
                    stop: "",
                }
            })
            .collect();
        let view = Arc::new(ViewData {
            leaves: (0..elements.len() as u32).collect(),
            elements,
            ..ViewData::default()
        });
        t.send(RefCommand::Evaluate { view: Arc::clone(&view), view_seq: 7, solver_time_s: 0.5 });
        let mut eval = None;
        t.wait_idle(|r| {
            if let RefReply::Evaluated(e) = r {
                eval = Some(e);
            }
        });
        let e = eval.expect("evaluated");
        assert_eq!((e.view_seq, e.solver_time_s), (7, 0.5));
        assert_eq!(e.ruler, Ruler::Reference, "scored against the Monte Carlo reference");
        assert_eq!(e.per_element.len(), 6);
        // The lit faces have B > 0 in the reference, so B = 0 is wrong by B̂ everywhere.
        assert!(e.per_element.iter().all(|&x| x > 0.0), "{:?}", e.per_element);
        assert!(e.rel_l2 > 0.5, "all-black solution: rel L2 {}", e.rel_l2);

        // A state that makes the scoring panic (a leaf past the element list) is answered, and
        // the thread scores the next one.
        let broken = ViewData { leaves: vec![0, 99], ..(*view).clone() };
        t.send(RefCommand::Evaluate { view: Arc::new(broken), view_seq: 8, solver_time_s: 0.5 });
        t.send(RefCommand::Evaluate { view: Arc::clone(&view), view_seq: 9, solver_time_s: 0.5 });
        let mut answers = Vec::new();
        t.wait_idle(|r| answers.push(r));
        assert!(!t.busy());
        match &answers[..] {
            [RefReply::Panicked(p), RefReply::Evaluated(e)] => {
                assert!(p.starts_with("the reference thread panicked"), "{p}");
                assert_eq!(e.view_seq, 9);
            }
            other => panic!("{other:?}"),
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A single-bounce scene's reference is its closed form, ready without a cache or a
    /// computation; each solution is scored through its own functions (p = 1: its vertex
    /// values), over the scene and over the penumbra band.
    #[test]
    fn a_single_bounce_scene_is_scored_against_its_closed_form() {
        use crate::solver::meshed::{MeshMethod, MeshSolveParams};
        let dir = std::env::temp_dir().join(format!("radlab-viewer-exact-{}", std::process::id()));
        let settings = RefSettings {
            params: PointParams { points: 4096, ..PointParams::quick() },
            cache: Cache::at(&dir),
        };
        let scene = Arc::new(Scene::load("builtin:shadow-narrow").unwrap());
        let mut t = RefThread::spawn(settings, || {}).unwrap();
        let mut replies = Vec::new();
        t.load(Arc::clone(&scene), false);
        t.wait_idle(|r| replies.push(r));
        match &replies[..] {
            [RefReply::Ready { points, samples: 0, how, .. }] => {
                assert!(*points >= 4096 && how == CLOSED_FORM, "{points} {how}");
            }
            other => panic!("the closed form, nothing to draw: {other:?}"),
        }
        assert!(!dir.exists(), "nothing cached");
        let mut band = Vec::new();
        let cdt = MeshSolveParams::new(MeshMethod::DiscontinuityCdt);
        for (seq, params) in [(1, cdt), (2, cdt.linear(true))] {
            let m = crate::solver::meshed::solve(&scene, &params, &mut |_, _| {}).unwrap();
            let view = Arc::new(ViewData::of_mesh_solution(&scene, params, m, 0.0));
            t.send(RefCommand::Evaluate { view, view_seq: seq, solver_time_s: 0.0 });
            let mut eval = None;
            t.wait_idle(|r| match r {
                RefReply::Evaluated(e) => eval = Some(e),
                other => panic!("{other:?}"),
            });
            let e = eval.expect("scored");
            assert!(e.rel_l2 > 0.0 && e.rel_l2 < 0.2, "{}: {}", params.label(), e.rel_l2);
            assert_eq!(e.ruler, Ruler::ClosedForm, "scored against the closed form, and says so");
            band.push(e.band_l2.expect("the closed form has a penumbra band"));
        }
        // The lecture's h vs p: linear elements follow the penumbra's ramp.
        assert!(band[1] < 0.25 * band[0], "penumbra band p0 {} against p1 {}", band[0], band[1]);
    }
}
