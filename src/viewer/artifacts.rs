//! The artifact overlays' measurements ([`crate::eval::artifacts::measure_samples`]) on their own
//! thread, `radlab-artifacts`: they shoot shadow rays at thousands of points (the penumbra band)
//! and take seconds on large scenes, so the UI only asks and picks the answer up.
//!
//! The reference is the best the viewer has: the closed form on a single-bounce scene
//! ([`crate::geometry::exact::SingleBounce`], e.g. builtin:shadow-narrow), else the scene's cached Monte
//! Carlo reference (its points' cells, piecewise constant), else none
//! (the answer says to compute one).
//!
//! ```text
//!  UI ── Job {seq, scene, view, reference} ──► "radlab-artifacts" ── Measured {seq, …} ──► UI
//!        (newest only; the UI draws samples                  measure_samples on the view's
//!         only for the state they were measured on)           elements, grid ≤ 40 000 points
//! ```
//!
//! A measurement that panics is answered with the panic's message ([`super::panics`]; the
//! overlay says it, the app reports it once, [`Measurements::take_panic`]) and the thread goes on.

use super::panics;
use super::worker::ViewData;
use crate::eval::artifacts::{ArtifactParams, ArtifactReport, ArtifactSamples, measure_samples};
use crate::eval::pointwise::PiecewiseConstant;
use crate::geometry::exact::SingleBounce;
use crate::math::DVec3;
use crate::present::mesh_overlay::Artifact;
use crate::scene::Scene;
use crate::solver::{Solution, SolveStats};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};

/// Grid points over all reflecting patches the viewer measures on at most (the grid's side per
/// patch follows, between 16 and 128).
pub const MAX_POINTS: usize = 40_000;

/// One measurement to make.
#[derive(Clone)]
pub struct Job {
    pub seq: u64,
    pub scene: Arc<Scene>,
    /// The solver state measured (its leaves, or a mesh solve's own solution).
    pub view: Arc<ViewData>,
    /// The scene's Monte Carlo reference as a state of flat leaves (used where the scene has
    /// no closed form).
    pub reference: Option<Arc<ViewData>>,
}

/// A measurement.
#[derive(Clone, Debug)]
pub struct Measured {
    pub report: ArtifactReport,
    pub samples: Arc<ArtifactSamples>,
    /// What the solution was measured against ("the closed form", "the Monte Carlo reference").
    pub against: &'static str,
    pub time_s: f64,
}

/// The thread's answer to job `seq`.
pub struct Reply {
    pub seq: u64,
    pub result: Result<Measured, String>,
    /// The measurement panicked (`result` holds the message).
    pub panicked: bool,
}

/// Name of the thread in its panic messages.
const THREAD: &str = "artifacts";

/// Measure one job (the thread runs this; tests may call it directly).
pub fn measure(job: &Job) -> Result<Measured, String> {
    let t = std::time::Instant::now();
    let scene = &job.scene;
    let solution = match &job.view.mesh {
        Some(m) => Arc::clone(&m.solution),
        None => {
            let elements = job.view.solved_leaves();
            let patch_radiosity = Solution::patch_averages(scene.patches.len(), &elements);
            Arc::new(Solution {
                method: "hierarchical".into(),
                elements,
                patch_radiosity,
                energy: crate::solver::EnergyBalance::default(),
                stats: SolveStats::default(),
            })
        }
    };
    if solution.elements.is_empty() {
        return Err("nothing solved yet".into());
    }
    let reflecting = scene.patches.iter().filter(|p| p.reflectance.mean() > 0.0).count().max(1);
    let side = ((MAX_POINTS / reflecting) as f64).sqrt().clamp(16.0, 128.0) as u32;
    let params = ArtifactParams { side, ..ArtifactParams::standard() };
    let fail = |e: &dyn std::fmt::Display| format!("artifacts: {e}");
    let (report, samples, against) = if let Ok(sb) = SingleBounce::new(scene) {
        let exact = |p: usize, x: DVec3| sb.patch_radiosity_at(p, x);
        let (r, s) = measure_samples(scene, &solution, &exact, &params).map_err(|e| fail(&e))?;
        (r, s, "the closed form")
    } else if let Some(reference) = &job.reference {
        let regions = reference.solved_leaves();
        let pc = PiecewiseConstant::new(scene, &regions).map_err(|e| fail(&e))?;
        let (r, s) = measure_samples(scene, &solution, &pc, &params).map_err(|e| fail(&e))?;
        (r, s, "the Monte Carlo reference")
    } else {
        return Err("artifacts need a reference: Compute reference, or a single-bounce scene".into());
    };
    Ok(Measured { report, samples: Arc::new(samples), against, time_s: t.elapsed().as_secs_f64() })
}

/// Handle of the thread (it ends when this is dropped).
pub struct ArtifactThread {
    tx: Sender<Job>,
    rx: Receiver<Reply>,
    /// Sequence number of the newest job sent, and of the newest answer received.
    sent: Option<u64>,
    received: Option<u64>,
}

impl ArtifactThread {
    /// Start the thread; `notify` is called after each answer (the UI's repaint request).
    pub fn spawn(notify: impl Fn() + Send + 'static) -> Result<ArtifactThread, String> {
        let (tx, job_rx) = channel::<Job>();
        let (done_tx, rx) = channel::<Reply>();
        std::thread::Builder::new()
            .name("radlab-artifacts".into())
            .spawn(move || {
                while let Ok(mut job) = job_rx.recv() {
                    // Only the newest queued job matters.
                    loop {
                        match job_rx.try_recv() {
                            Ok(newer) => job = newer,
                            Err(TryRecvError::Empty) => break,
                            Err(TryRecvError::Disconnected) => return,
                        }
                    }
                    let (result, panicked) = match panics::catching(THREAD, || measure(&job)) {
                        Ok(result) => (result, false),
                        Err(e) => (Err(e), true),
                    };
                    if done_tx.send(Reply { seq: job.seq, result, panicked }).is_err() {
                        return;
                    }
                    notify();
                }
            })
            .map_err(|e| format!("cannot start the artifacts thread: {e}"))?;
        Ok(ArtifactThread { tx, rx, sent: None, received: None })
    }

    pub fn request(&mut self, job: Job) {
        let seq = job.seq;
        if self.tx.send(job).is_ok() {
            self.sent = Some(seq);
        }
    }

    /// True while the newest job has not been answered.
    #[must_use]
    pub fn busy(&self) -> bool {
        self.sent.is_some_and(|s| self.received.is_none_or(|r| r < s))
    }

    /// The newest answer, if any (never blocks).
    pub fn poll(&mut self) -> Option<Reply> {
        let mut last = None;
        loop {
            match self.rx.try_recv() {
                Ok(r) => last = Some(r),
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => {
                    last = self.stopped().or(last);
                    break;
                }
            }
        }
        if let Some(r) = &last {
            self.received = Some(r.seq);
        }
        last
    }

    /// The thread is gone: the newest job, if unanswered, is answered with that.
    fn stopped(&mut self) -> Option<Reply> {
        let seq = self.sent.filter(|_| self.busy())?;
        self.received = Some(seq);
        Some(Reply { seq, result: Err(format!("the {THREAD} thread stopped")), panicked: true })
    }

    /// Block until the newest job is answered, and return the answer (tests, scripted runs).
    pub fn wait(&mut self) -> Option<Reply> {
        while self.busy() {
            match self.rx.recv() {
                Ok(r) => {
                    self.received = Some(r.seq);
                    if Some(r.seq) == self.sent {
                        return Some(r);
                    }
                }
                Err(_) => return self.stopped(),
            }
        }
        None
    }
}

/// The measurements of the states shown: the thread, the job sent last and the newest answer.
#[derive(Default)]
pub struct Measurements {
    thread: Option<ArtifactThread>,
    /// The newest answer: (state measured, with a reference, the measurement or why not).
    answer: Option<(u64, bool, Result<Measured, String>)>,
    /// The (state, with a reference) of the newest job sent, and its number.
    job: Option<(u64, bool)>,
    seq: u64,
    /// The message of the newest measurement that panicked, until taken.
    panic: Option<String>,
}

impl Measurements {
    /// Measure on `thread` (`None`: never; the overlays then say "measuring…").
    #[must_use]
    pub fn new(thread: Option<ArtifactThread>) -> Measurements {
        Measurements { thread, ..Measurements::default() }
    }

    /// The newest measurement of state `view_seq` (`None`: not asked, or not answered yet), or
    /// why there is none.
    #[must_use]
    pub fn of(&self, view_seq: u64) -> Option<&Result<Measured, String>> {
        match &self.answer {
            Some((seq, _, r)) if *seq == view_seq => Some(r),
            _ => None,
        }
    }

    /// The samples measured on state `view_seq`, to draw as overlay `which`.
    #[must_use]
    pub fn samples(
        &self,
        which: Option<Artifact>,
        view_seq: u64,
    ) -> Option<(Artifact, Arc<ArtifactSamples>)> {
        match self.of(view_seq)? {
            Ok(m) => Some((which?, Arc::clone(&m.samples))),
            Err(_) => None,
        }
    }

    /// Ask for state `view_seq` to be measured, once per state and reference.
    pub fn request(
        &mut self,
        view_seq: u64,
        scene: &Arc<Scene>,
        view: &Arc<ViewData>,
        reference: Option<&Arc<ViewData>>,
    ) {
        let key = (view_seq, reference.is_some());
        if self.job == Some(key) {
            return;
        }
        let Some(t) = &mut self.thread else { return };
        self.seq += 1;
        t.request(Job {
            seq: self.seq,
            scene: Arc::clone(scene),
            view: Arc::clone(view),
            reference: reference.cloned(),
        });
        self.job = Some(key);
    }

    /// Pick up the thread's answer (`wait`: block for it; tests, scripted runs).
    pub fn poll(&mut self, wait: bool) {
        let Some(t) = &mut self.thread else { return };
        let reply = if wait { t.wait() } else { t.poll() };
        let Some(r) = reply else { return };
        if r.panicked {
            self.panic = r.result.as_ref().err().cloned();
        }
        if r.seq == self.seq
            && let Some((view_seq, with_ref)) = self.job
        {
            self.answer = Some((view_seq, with_ref, r.result));
        }
    }

    /// The message of the newest measurement that panicked (once).
    pub fn take_panic(&mut self) -> Option<String> {
        self.panic.take()
    }

    /// Forget the answers (another scene).
    pub fn clear(&mut self) {
        self.answer = None;
        self.job = None;
    }

    /// True while the newest job has not been answered.
    #[must_use]
    pub fn busy(&self) -> bool {
        self.thread.as_ref().is_some_and(ArtifactThread::busy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::meshed::{MeshMethod, MeshSolveParams};

    #[test]
    fn a_mesh_solve_is_measured_against_the_closed_form_and_without_reference_it_says_why() {
        let scene = Arc::new(Scene::load("builtin:shadow-narrow").unwrap());
        let p = MeshSolveParams { element_size_rel: 0.1, ..MeshSolveParams::new(MeshMethod::Uniform) };
        let m = crate::solver::meshed::solve(&scene, &p, &mut |_, _| {}).unwrap();
        let view = Arc::new(ViewData::of_mesh_solution(&scene, p, m, 0.0));
        let mut t = ArtifactThread::spawn(|| {}).unwrap();
        t.request(Job { seq: 3, scene: Arc::clone(&scene), view: Arc::clone(&view), reference: None });
        let r = t.wait().expect("an answer");
        assert_eq!(r.seq, 3);
        let m = r.result.unwrap();
        assert_eq!(m.against, "the closed form");
        assert!(m.report.blocky_shadows.is_some() && !m.samples.band.is_empty());
        assert!(!t.busy());
        // No closed form and no reference: one line saying what to do.
        let cornell = Arc::new(Scene::load("builtin:cornell").unwrap());
        let e = measure(&Job { seq: 4, scene: Arc::clone(&cornell), view, reference: None }).unwrap_err();
        assert!(e.contains("Compute reference") && !e.contains('\n'), "{e}");
        // The quadtree's leaves, against a reference given as flat leaves (here a finer uniform
        // solve standing in for the Monte Carlo one): measured, and the coarse quadtree errs.
        let mut h = crate::solver::hierarchical::HierarchicalSolver::new(
            Arc::clone(&cornell),
            crate::solver::params::HierarchicalParams::interactive(),
        )
        .unwrap();
        h.solve(&mut |_, _| {});
        let quadtree = ViewData::of_solver(&h, false);
        let fine = MeshSolveParams { element_size_rel: 0.08, ..MeshSolveParams::new(MeshMethod::Uniform) };
        let solved = crate::solver::meshed::solve(&cornell, &fine, &mut |_, _| {}).unwrap();
        let reference = Arc::new(ViewData::of_mesh_solution(&cornell, fine, solved, 0.0));
        let m = measure(&Job { seq: 5, scene: cornell, view: quadtree, reference: Some(reference) }).unwrap();
        assert_eq!(m.against, "the Monte Carlo reference");
        assert!(m.report.unresolved.segments > 0 && !m.samples.edges.is_empty(), "{:?}", m.report);
    }
}
