//! The solver thread's side of [`super::worker`]: it owns the [`HierarchicalSolver`] and runs
//! the commands one at a time ([`run`]): a load (on the input patches or a mesh of them), new
//! settings, a step or a solve (its progress, pictures in progress and replay frames sent as it
//! goes), a mesh solve on a thread of its own, a bake.

use super::worker::{
    CLUSTER_LINKS_KEPT, Command, DmeshOptions, Estimates, GiveWay, PARTIAL_EVERY, Pictures,
    REPLAY_BUDGET_BYTES, REPLAY_CLUSTER_LINKS, Reply, ViewData, Worker,
};
use crate::scene::Scene;
use crate::solver::hierarchical::{HierarchicalSolver, StepKind, StepReport};
use crate::solver::meshed::{MeshSolution, MeshSolveParams};
use crate::solver::params::HierarchicalParams;
use crate::solver::spec::{Plan, SolveSpec, TopLevel};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};

impl Worker {
    /// Start the thread; `notify` is called after every reply (the UI's repaint request).
    pub fn spawn(notify: impl Fn() + Send + 'static) -> Result<Worker, String> {
        let (tx, cmd_rx) = channel::<(u64, Command)>();
        let (reply_tx, rx) = channel::<Reply>();
        let skip_through = Arc::new(AtomicU64::new(0));
        let skip = Arc::clone(&skip_through);
        let partial_estimates = Arc::new(AtomicBool::new(false));
        let estimates = Arc::clone(&partial_estimates);
        let give_way = Arc::new(GiveWay::default());
        let gives_way = Arc::clone(&give_way);
        let pictures = Arc::new(Pictures::default());
        let shown = Arc::clone(&pictures);
        std::thread::Builder::new()
            .name("radlab-solver".into())
            .spawn(move || {
                // A panic ends the thread (the solver may be half changed): its message is the
                // last answer, and what is still queued is answered "stopped".
                if let Err(e) = super::panics::catching("solver", || {
                    run(
                        &cmd_rx,
                        Shared {
                            skip_through: &skip,
                            partial_estimates: &estimates,
                            give_way: &gives_way,
                            pictures: &shown,
                        },
                        &reply_tx,
                        &notify,
                    )
                }) {
                    let _ = reply_tx.send(Reply::Failed(e));
                    notify();
                }
            })
            .map_err(|e| format!("cannot start the solver thread: {e}"))?;
        Ok(Worker {
            tx,
            rx,
            cancel: None,
            in_flight: 0,
            sent: 0,
            skip_through,
            partial_estimates,
            give_way,
            estimates_owed: false,
            answers_owing: 0,
            pictures,
        })
    }
}

/// The way back to the UI: the replies' channel, the repaint request, and the number of the
/// last command [`super::worker::Worker::cancel_all`] dropped.
struct Link<'a, N: Fn() + Send> {
    tx: &'a Sender<Reply>,
    notify: &'a N,
    skip_through: &'a AtomicU64,
    /// [`super::worker::Worker::set_partial_estimates`].
    partial_estimates: &'a AtomicBool,
    /// Which error estimates give way to a newer command.
    give_way: &'a GiveWay,
    /// Which answers' pictures the UI shows.
    pictures: &'a Pictures,
}

/// What the UI sets and the solver thread reads as it runs: the last command dropped, whether
/// the pictures a solve sends as it goes carry estimates, which estimates give way.
pub(super) struct Shared<'a> {
    pub(super) skip_through: &'a AtomicU64,
    pub(super) partial_estimates: &'a AtomicBool,
    pub(super) give_way: &'a GiveWay,
    pub(super) pictures: &'a Pictures,
}

impl<N: Fn() + Send> Link<'_, N> {
    /// Send a reply and ask for a repaint; false once the UI is gone.
    fn send(&self, r: Reply) -> bool {
        let ok = self.tx.send(r).is_ok();
        (self.notify)();
        ok
    }

    /// True when command `seq` was dropped by a cancel of everything queued.
    fn skipped(&self, seq: u64) -> bool {
        seq <= self.skip_through.load(Ordering::Relaxed)
    }
}

/// How often the solver thread looks whether the picture its owed estimates wait for is shown.
const PICTURE_POLL: std::time::Duration = std::time::Duration::from_millis(5);

/// What the solver thread keeps between commands.
struct SolverThread<'a, N: Fn() + Send> {
    link: Link<'a, N>,
    solver: Option<HierarchicalSolver>,
    /// The input scene, and on a mesh top level the input patch of each of the solver's patches.
    input: Option<Arc<Scene>>,
    origin: Origin,
    /// The solver has gathered since its last push-pull: show the pushed-pulled values.
    unpushed: bool,
    /// The residual of the last gather (what a step that gathers nothing reports).
    last_residual: f64,
    /// The state a step answered with, its error estimates not sent yet ([`Reply::Estimates`]).
    owed: Option<Owed>,
    /// Answers sent whose error estimates follow them ([`Reply::owes_estimates`]).
    answers_owing: u64,
}

/// Error estimates owed: of the state command number `seq` answered with (`of`); `run` says
/// whether that state is a run of the UI's history (a finished Solve), which keeps it.
struct Owed {
    seq: u64,
    run: bool,
    of: Arc<ViewData>,
    /// Which answer owing estimates it was (the first is 1), and when it was sent: the
    /// estimates wait for its picture ([`Pictures`]).
    n: u64,
    sent: std::time::Instant,
}

/// The solver thread's loop: each command answered in turn (those dropped by a cancel of
/// everything queued answered `Skipped`), until either channel closes. A step answers without
/// error estimates (they cost about as much as a solve), and the thread computes them and sends
/// them after the answer ([`Reply::Estimates`]), once the UI shows the answer's picture (or
/// after [`super::worker::PICTURE_WAIT`]; [`Pictures`]): then at once for a finished Solve (a
/// run of the history, which keeps them: a figure's queued solves each need theirs), else once
/// nothing is queued. They give way to a newer command the UI sent ([`Worker::send`]) or a cancel of
/// everything queued ([`Worker::cancel_all`]): not started, or stopped where they are, they are
/// given up ([`Reply::EstimatesDropped`]) and that command runs at once. A command that runs
/// while estimates are owed gives them up too where it replaces the state, and leaves them owed
/// where it does not (a bake). So every state that owes estimates gets them or word that they
/// were given up, before the next state is answered.
pub(super) fn run(
    rx: &Receiver<(u64, Command)>,
    shared: Shared<'_>,
    tx: &Sender<Reply>,
    notify: &(impl Fn() + Send),
) {
    let link = Link {
        tx,
        notify,
        skip_through: shared.skip_through,
        partial_estimates: shared.partial_estimates,
        give_way: shared.give_way,
        pictures: shared.pictures,
    };
    let mut thread = SolverThread {
        link,
        solver: None,
        input: None,
        origin: None,
        unpushed: false,
        last_residual: 0.0,
        owed: None,
        answers_owing: 0,
    };
    loop {
        let next = match &thread.owed {
            // Its picture is not on screen yet: the estimates wait for it, a newer command
            // does not (nor a queued one, unless the estimates are a finished Solve's).
            Some(o)
                if !thread.link.give_way.gives_way(o.seq) && thread.link.pictures.pending(o.n, o.sent) =>
            {
                match if o.run { Err(TryRecvError::Empty) } else { rx.try_recv() } {
                    Err(TryRecvError::Empty) => {
                        std::thread::sleep(PICTURE_POLL);
                        continue;
                    }
                    next => next,
                }
            }
            // (A cancel of everything queued gives way too.)
            Some(o) if o.run && !thread.link.give_way.gives_way(o.seq) => Err(TryRecvError::Empty),
            Some(_) => rx.try_recv(),
            None => rx.recv().map_err(|_| TryRecvError::Disconnected),
        };
        let (seq, cmd) = match next {
            Ok(next) => next,
            Err(TryRecvError::Empty) => {
                if !thread.send_estimates() {
                    break;
                }
                continue;
            }
            Err(TryRecvError::Disconnected) => break,
        };
        let skipped = thread.link.skipped(seq);
        if !skipped && cmd.replaces_the_state() && !thread.give_up_estimates() {
            break;
        }
        let reply = if skipped { Reply::Skipped } else { thread.answer(seq, cmd) };
        thread.answers_owing += u64::from(reply.owes_estimates());
        thread.owed = match &reply {
            Reply::Done { report, view } if view.estimates_pending() => Some(Owed {
                seq,
                run: report.is_some_and(|r| r.kind == StepKind::Solve && !r.cancelled),
                of: Arc::clone(view),
                n: thread.answers_owing,
                sent: std::time::Instant::now(),
            }),
            r if r.estimates_owed_after(true) => thread.owed.take(),
            _ => None,
        };
        if !thread.link.send(reply) {
            break;
        }
    }
}

/// The state shown of solver `s` (pushed and pulled for display when `unpushed`), on the input
/// patches (`origin`), with its error estimates (a restart's or a load's: without links yet,
/// they cost little).
fn view_of(s: &HierarchicalSolver, unpushed: bool, origin: &Origin) -> Arc<ViewData> {
    ViewData::of_solver_on(s, unpushed, true, CLUSTER_LINKS_KEPT, origin.as_deref().map(Vec::as_slice))
}

/// [`view_of`] without the error estimates, marked pending ([`Estimates::Pending`]):
/// a step's answer.
fn view_before_estimates(s: &HierarchicalSolver, unpushed: bool, origin: &Origin) -> Arc<ViewData> {
    let on = origin.as_deref().map(Vec::as_slice);
    let view = ViewData::of_solver_on(s, unpushed, false, CLUSTER_LINKS_KEPT, on);
    Arc::new(ViewData { estimates: Estimates::Pending, ..Arc::unwrap_or_clone(view) })
}

impl<N: Fn() + Send> SolverThread<'_, N> {
    /// Compute the error estimates owed and send them, or word that they were given up (a newer
    /// command came first: [`GiveWay`]); false once the UI is gone.
    fn send_estimates(&mut self) -> bool {
        let Some(Owed { seq, of, .. }) = self.owed.take() else { return true };
        let estimates = self.solver.as_ref().and_then(|s| self.link.give_way.estimates(seq, s));
        self.link.send(match estimates {
            Some(e) => Reply::Estimates { view: Arc::new(of.with_estimates(&e)), of },
            None => Reply::EstimatesDropped { of },
        })
    }

    /// Give up the error estimates owed, if any, and say so; false once the UI is gone.
    fn give_up_estimates(&mut self) -> bool {
        match self.owed.take() {
            Some(Owed { of, .. }) => self.link.send(Reply::EstimatesDropped { of }),
            None => true,
        }
    }

    /// Run command number `seq` and return its answer.
    fn answer(&mut self, seq: u64, cmd: Command) -> Reply {
        // A cancel applies to the command that was running when it was pressed.
        if let Some(s) = &self.solver {
            s.cancel_handle().store(false, Ordering::Relaxed);
        }
        if matches!(cmd, Command::Load { .. } | Command::SetParams(_) | Command::Reset) {
            self.unpushed = false;
            self.last_residual = 0.0;
        }
        match cmd {
            Command::Load { scene, params, top } => self.load(scene, params, top),
            Command::SetParams(p) => match self.solver.as_mut() {
                None => Reply::Failed("no scene loaded".into()),
                Some(s) => match s.set_params(p) {
                    Ok(()) => Reply::Done { report: None, view: view_of(s, false, &self.origin) },
                    Err(e) => Reply::Failed(e),
                },
            },
            Command::Retarget(p) => self.retarget(p),
            Command::Reset => match self.solver.as_mut() {
                None => Reply::Failed("no scene loaded".into()),
                Some(s) => {
                    s.reset();
                    Reply::Done { report: None, view: view_of(s, false, &self.origin) }
                }
            },
            Command::SolveMesh(params, dmesh) => match (self.solver.as_ref(), self.input.as_ref()) {
                (Some(s), Some(scene)) => {
                    let (tx, notify) = (self.link.tx, self.link.notify);
                    solve_mesh(scene, (params, dmesh, s.params()), &s.cancel_handle(), tx, notify)
                }
                _ => Reply::Failed("no scene loaded".into()),
            },
            Command::Bake { path, options, form } => match (self.solver.as_ref(), self.input.as_ref()) {
                (Some(s), Some(scene)) => {
                    let on = (scene, self.origin.as_deref().map(Vec::as_slice));
                    Reply::Baked(bake_to(s, on, self.unpushed, &path, &options, form))
                }
                _ => Reply::Failed("no scene loaded".into()),
            },
            Command::Step(kind) => self.step(seq, kind),
        }
    }

    /// A new solver on `top` of `scene` (the old one stays where that fails).
    fn load(&mut self, scene: Arc<Scene>, params: HierarchicalParams, top: TopLevel) -> Reply {
        match solver_on(&scene, params, top) {
            Ok((s, o)) => {
                let on = o.as_deref().map(Vec::as_slice);
                let view = ViewData::of_solver_on(&s, false, true, CLUSTER_LINKS_KEPT, on);
                self.origin = o;
                self.input = Some(Arc::clone(&scene));
                let r = Reply::Loaded { cancel: s.cancel_handle(), view, scene };
                self.solver = Some(s);
                r
            }
            Err(e) => Reply::Failed(e),
        }
    }

    /// New settings, a solved state kept where only the thresholds changed
    /// ([`HierarchicalSolver::retarget`]), else a restart.
    fn retarget(&mut self, p: HierarchicalParams) -> Reply {
        let Some(s) = self.solver.as_mut() else { return Reply::Failed("no scene loaded".into()) };
        match s.retarget(p) {
            Ok(true) => Reply::Retargeted,
            Ok(false) => {
                self.unpushed = false;
                self.last_residual = 0.0;
                Reply::Done { report: None, view: view_of(s, false, &self.origin) }
            }
            Err(e) => Reply::Failed(e),
        }
    }

    /// One step of the hierarchical solver, or a whole solve (command number `seq`).
    fn step(&mut self, seq: u64, kind: StepKind) -> Reply {
        let Some(s) = self.solver.as_mut() else { return Reply::Failed("no scene loaded".into()) };
        // Each Gather moves one bounce: a gather not yet pushed and pulled is pushed and pulled
        // before any other step, as the lecture's loop does between gathers (else the next
        // gather, or the oracle, reads the radiosities the last gather read; the view has shown
        // the pushed values already).
        if self.unpushed && kind != StepKind::PushPull {
            s.push_pull_step();
            self.unpushed = false;
        }
        let report = match kind {
            StepKind::Refine => s.refine_step(),
            StepKind::Gather => s.gather_step(),
            StepKind::PushPull if self.unpushed => s.push_pull_step(),
            // Nothing gathered since the last push-pull: it would change nothing and record a
            // residual of no gather. Answered as done, the state as it is.
            StepKind::PushPull => StepReport {
                kind,
                time_s: 0.0,
                refined: 0,
                new_links: 0,
                residual: self.last_residual,
                converged: s.is_converged(),
                cancelled: false,
            },
            StepKind::Iterate => s.iterate(),
            StepKind::Solve => {
                let on = self.origin.as_deref().map(Vec::as_slice);
                solve_observed(s, seq, self.unpushed, on, &self.link)
            }
        };
        // Gauss-Seidel gathers push and pull patch by patch themselves; Iterate and Solve end
        // with a push-pull (or stop before their gather).
        self.unpushed = kind == StepKind::Gather && !s.params().gauss_seidel;
        let view = view_before_estimates(s, self.unpushed, &self.origin);
        let mut report = report;
        if self.unpushed {
            // The solver records a gather's residual at its push-pull; the view has it already
            // (`from_gathered_snapshot`): the report says this gather's.
            report.residual = view.residuals.last().copied().unwrap_or(0.0);
            report.converged = report.residual < s.params().tolerance;
        }
        self.last_residual = report.residual;
        Reply::Done { report: Some(report), view }
    }
}

/// A whole solve of command number `seq`, observed as it goes: its progress, a picture after a
/// round at most every [`PARTIAL_EVERY`] (the first round's at once; a snapshot copies every
/// element and link), and the replay's frames (where it starts, `unpushed` as the view showed
/// it, then each round, while they fit in [`REPLAY_BUDGET_BYTES`]), sent just before its answer.
fn solve_observed<N: Fn() + Send>(
    s: &mut HierarchicalSolver,
    seq: u64,
    unpushed: bool,
    on: Option<&[usize]>,
    link: &Link<'_, N>,
) -> StepReport {
    let ptx = link.tx.clone();
    let mut progress = move |done: u64, total: u64| {
        let _ = ptx.send(Reply::Progress { done, total });
    };
    let mut last: Option<std::time::Instant> = None;
    let mut frames = vec![ViewData::of_solver_on(s, unpushed, false, REPLAY_CLUSTER_LINKS, on)];
    let mut budget = REPLAY_BUDGET_BYTES.saturating_sub(frames[0].bytes());
    let mut on_round = |s: &HierarchicalSolver| {
        if budget > 0 {
            let frame = ViewData::of_solver_on(s, false, false, REPLAY_CLUSTER_LINKS, on);
            budget = budget.saturating_sub(frame.bytes());
            if budget > 0 {
                frames.push(frame);
            }
        }
        // `cancel_all` while this solve ran: the flag it set may have landed between two
        // sub-steps (each clears it); set it again.
        if link.skipped(seq) {
            s.cancel_handle().store(true, Ordering::Relaxed);
        }
        let now = std::time::Instant::now();
        if last.is_none_or(|t| now.duration_since(t) >= PARTIAL_EVERY) {
            last = Some(now);
            let estimates = link.partial_estimates.load(Ordering::Relaxed);
            let view = ViewData::of_solver_on(s, false, estimates, CLUSTER_LINKS_KEPT, on);
            let _ = link.tx.send(Reply::Partial { view });
            (link.notify)();
        }
    };
    let report = s.solve_observed(&mut progress, &mut on_round);
    let _ = link.tx.send(Reply::Replay { frames });
    report
}

/// Solve `scene` on the mesh of `params` with the viewer's D-mesh options (`hierarchical`: the
/// solver settings of its top-level solve): [`crate::solver::meshed::solve`] unless they apply,
/// else the hierarchical solver on the mesh [`MeshSolveParams::remesh`] builds (graded or not).
fn solve_on_mesh(
    scene: &Scene,
    params: &MeshSolveParams,
    dmesh: DmeshOptions,
    hierarchical: HierarchicalParams,
    progress: crate::solver::Progress,
) -> Result<MeshSolution, String> {
    if !dmesh.apply_to(params) {
        return crate::solver::meshed::solve(scene, params, progress);
    }
    params.validate()?;
    let mesh = params.remesh()?;
    let d = crate::solver::discontinuity::solve_hierarchical(scene, &mesh, hierarchical, progress)
        .map_err(|e| e.to_string())?;
    Ok(MeshSolution { solution: d.solution, coefficients: None, meshing_s: d.mesh.total_s })
}

/// On a mesh top level, the input patch of each of the solver's patches (`None`: the solver is on
/// the input patches).
type Origin = Option<Arc<Vec<usize>>>;

/// The hierarchical solver on `top` of `scene` (the scene's size resolves [`TopLevel::Auto`]),
/// and on a mesh the input patch of each of its patches.
fn solver_on(
    scene: &Arc<Scene>,
    params: HierarchicalParams,
    top: TopLevel,
) -> Result<(HierarchicalSolver, Origin), String> {
    let spec = SolveSpec { plan: Plan::Hierarchical { params, top }, estimate: false };
    let (s, origin) = crate::solver::spec::setup(scene, None, &spec).map_err(|e| e.to_string())?.into_parts();
    Ok((s, origin.map(Arc::new)))
}

/// How often a mesh solve's waiting solver thread looks at the cancel flag.
const MESH_CANCEL_POLL: std::time::Duration = std::time::Duration::from_millis(20);

/// A mesh solve, its progress forwarded. The mesh solvers have no cancel flag, so the solve runs
/// on a thread of its own ("radlab-mesh-solve") while the solver thread waits for it and watches
/// `cancel`: on Cancel it answers [`Reply::Cancelled`] at once and the solve is left to finish in
/// the background (its progress no longer forwarded, its result dropped; `max_unknowns` keeps it
/// bounded), so the next command runs without waiting for it.
fn solve_mesh(
    scene: &Arc<Scene>,
    (params, dmesh, hierarchical): (MeshSolveParams, DmeshOptions, HierarchicalParams),
    cancel: &AtomicBool,
    tx: &Sender<Reply>,
    notify: &(impl Fn() + Send),
) -> Reply {
    let t = std::time::Instant::now();
    let abandoned = Arc::new(AtomicBool::new(false));
    let (done_tx, done_rx) = channel();
    let (ptx, quiet, on) = (tx.clone(), Arc::clone(&abandoned), Arc::clone(scene));
    let spawned = std::thread::Builder::new().name("radlab-mesh-solve".into()).spawn(move || {
        let mut progress = move |done: u64, total: u64| {
            if !quiet.load(Ordering::Relaxed) {
                let _ = ptx.send(Reply::Progress { done, total });
            }
        };
        let solved = super::panics::catching("mesh solve", || {
            solve_on_mesh(&on, &params, dmesh, hierarchical, &mut progress)
        });
        let _ = done_tx.send(solved.flatten());
    });
    if let Err(e) = spawned {
        return Reply::Failed(format!("cannot start the mesh solve's thread: {e}"));
    }
    notify();
    let report = |cancelled: bool| StepReport {
        kind: StepKind::Solve,
        time_s: t.elapsed().as_secs_f64(),
        refined: 0,
        new_links: 0,
        residual: 0.0,
        converged: !cancelled,
        cancelled,
    };
    loop {
        match done_rx.recv_timeout(MESH_CANCEL_POLL) {
            Ok(Ok(m)) => {
                let report = report(false);
                let mut view = ViewData::of_mesh_solution(scene, params, m, report.time_s);
                if let Some(info) = view.mesh.as_mut() {
                    info.dmesh = dmesh;
                }
                return Reply::Done { report: Some(report), view: Arc::new(view) };
            }
            Ok(Err(e)) => return Reply::Failed(format!("{}{}: {e}", params.label(), dmesh.label(&params))),
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) if cancel.load(Ordering::Relaxed) => {
                abandoned.store(true, Ordering::Relaxed);
                return Reply::Cancelled { report: report(true) };
            }
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                return Reply::Failed(format!("{}: the mesh solve's thread stopped", params.label()));
            }
        }
    }
}

/// Bake the solver's leaves (pushed and pulled first if it has gathered since its last
/// push-pull, as the view shows them) and write the file.
fn bake_to(
    s: &HierarchicalSolver,
    (scene, origin): (&Arc<Scene>, Option<&[usize]>),
    unpushed: bool,
    path: &std::path::Path,
    options: &crate::present::bake::BakeOptions,
    form: crate::present::bake::BakeForm,
) -> Result<String, String> {
    let fail = |e: &dyn std::fmt::Display| format!("export {}: {e}", path.display());
    let format = crate::present::bake::BakeFormat::from_path(path).map_err(|e| fail(&e))?;
    let mut solution = s.solution_with(false);
    if unpushed {
        let v = ViewData::from_gathered_snapshot(s.snapshot(), &s.push_pull_preview());
        for (e, &id) in solution.elements.iter_mut().zip(&v.leaves) {
            e.radiosity = v.elements[id as usize].radiosity;
        }
    }
    if let Some(origin) = origin {
        solution = crate::solver::discontinuity::pull_back(solution, origin, scene.patches.len());
    }
    let bytes =
        crate::present::bake::bake_as(scene, &solution, options, form, format).map_err(|e| fail(&e))?;
    std::fs::write(path, bytes).map_err(|e| fail(&e))?;
    Ok(match form {
        crate::present::bake::BakeForm::Elements => {
            format!("baked {} elements to {}", solution.elements.len(), path.display())
        }
        // The CLI's words (radlab solve --bake-lightmap).
        crate::present::bake::BakeForm::Lightmap(m) => format!(
            "baked {} patches with a {}×{} lightmap to {}",
            scene.patches.len(),
            m.size,
            m.size,
            path.display()
        ),
    })
}
