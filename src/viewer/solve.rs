//! The solver thread as the app drives it ([`SolveState`]): the settings it solves with (the
//! hierarchical parameters, the top level loaded, the mesh and its D-mesh options), what it is
//! doing (the progress line's label, clock and counts) and what waits on it (a re-solve after a
//! settings change, a Load not answered yet, the opening's way on to the default preset).

use super::solver_panel::MESH_SOLVE_LABEL;
use super::worker::{Command, DmeshOptions, Reply, Worker};
use crate::solver::hierarchical::StepKind;
use crate::solver::meshed::{MeshMethod, MeshSolveParams};
use crate::solver::params::HierarchicalParams;
use crate::solver::spec::{Preset, TopLevel};
use std::time::Instant;

/// The preset of the opening's first picture: the viewer opened without a preset asked for
/// solves at this one first, shows it, and goes on warm to [`Preset::DEFAULT`] ([`Opening`]).
pub const FIRST_PICTURE: Preset = Preset::Interactive;

/// The viewer's way to the default preset when it opens without one asked for: a first picture
/// at [`FIRST_PICTURE`] (about a quarter of the default's time on the built-in rooms), then a
/// warm re-solve ([`super::worker::Command::Retarget`]) that refines on from its hierarchy,
/// links and radiosity to the default. Whatever the user does to the solver first (a setting, a
/// preset, a step, Reset, Cancel, another mesh or scene) ends it: the step that has not started
/// is not sent.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub enum Opening {
    /// Nothing waits: a preset was asked for, the opening is over, or the user took over.
    #[default]
    Off,
    /// The first picture is being solved; `then` follows it, warm.
    FirstPicture { then: Preset },
    /// The warm re-solve on to `to` runs (the Solver panel names it already).
    GoingOn { to: Preset },
}

impl Opening {
    /// What the status bar says while the opening goes on to the default: "first picture at
    /// interactive; refining on to quality…" (`None` in the other stages).
    #[must_use]
    pub fn note(self) -> Option<String> {
        match self {
            Opening::GoingOn { to } => {
                Some(format!("first picture at {}; refining on to {}…", FIRST_PICTURE.name(), to.name()))
            }
            Opening::Off | Opening::FirstPicture { .. } => None,
        }
    }
}

/// Whether the error estimates the solver thread owes give way to a command sent.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Urgency {
    /// The user's command: the estimates give way to it ([`Worker::send`]).
    Now,
    /// Queued behind them: a figure's sweep, whose runs each need theirs ([`Worker::queue`]).
    Queued,
}

/// The solver thread, its settings and its work in progress.
pub struct SolveState {
    /// The solver thread (`None`: it could not be started; the error list says why).
    pub(super) worker: Option<Worker>,
    pub(super) params: HierarchicalParams,
    /// The top level the solver thread's solver refines (its last Load): the preset's.
    pub(super) loaded_top: TopLevel,
    /// The mesh solved on: `method` [`MeshMethod::Quadtree`] is the hierarchical solver (with
    /// `params`), anything else a mesh solve with these settings.
    pub(super) mesh: MeshSolveParams,
    /// The Mesh menu's graded / top-of-hierarchy D-mesh options.
    pub(super) dmesh: DmeshOptions,
    /// Re-solve after every settings change (the progress line's checkbox).
    pub(super) auto_run: bool,
    /// (work done, work) of the running command, as the solver thread last reported it.
    pub(super) progress: Option<(u64, u64)>,
    /// What the running command does, in a word ("solving").
    pub(super) busy_label: String,
    /// When the solver thread last went from idle to busy (the progress line's clock).
    pub(super) busy_since: Option<Instant>,
    /// Re-solve once the running command finishes (auto-run after a parameter change).
    pub(super) resolve_pending: bool,
    /// A Load was sent and its answer has not come yet.
    pub(super) loading: bool,
    /// The opening's way on to the default preset (none once the user takes over).
    pub(super) opening: Opening,
}

impl SolveState {
    /// The settings to start with, on the solver thread `worker`.
    #[must_use]
    pub fn new(
        worker: Option<Worker>,
        params: HierarchicalParams,
        top: TopLevel,
        mesh: MeshSolveParams,
    ) -> SolveState {
        SolveState {
            worker,
            params,
            loaded_top: top,
            mesh,
            dmesh: DmeshOptions::default(),
            auto_run: true,
            progress: None,
            busy_label: String::new(),
            busy_since: None,
            resolve_pending: false,
            loading: false,
            opening: Opening::Off,
        }
    }

    /// Send a command to the solver thread, the error estimates being computed giving way to it
    /// ([`Worker::send`]); `label` is what the progress line calls it.
    pub fn send(&mut self, cmd: Command, label: &str) {
        self.send_as(cmd, label, Urgency::Now);
    }

    /// Send a command to the solver thread: now ([`Worker::send`]) or behind the estimates owed
    /// ([`Worker::queue`]: a figure's sweep).
    pub fn send_as(&mut self, cmd: Command, label: &str, urgency: Urgency) {
        if let Some(w) = &mut self.worker {
            if !w.busy() {
                self.busy_since = Some(Instant::now());
            }
            match urgency {
                Urgency::Now => w.send(cmd),
                Urgency::Queued => w.queue(cmd),
            }
            label.clone_into(&mut self.busy_label);
        }
    }

    /// True while the solver thread has work.
    #[must_use]
    pub fn busy(&self) -> bool {
        self.worker.as_ref().is_some_and(Worker::busy)
    }

    /// Stop the running command and drop those queued.
    pub fn cancel_all(&self) {
        if let Some(w) = &self.worker {
            w.cancel_all();
        }
    }

    /// Ask the running command to stop early.
    pub fn cancel(&self) {
        if let Some(w) = &self.worker {
            w.cancel();
        }
    }

    /// The replies that have come (never blocks).
    pub fn poll(&mut self) -> Vec<Reply> {
        let mut replies = Vec::new();
        if let Some(w) = &mut self.worker {
            while let Some(r) = w.poll() {
                replies.push(r);
            }
        }
        replies
    }

    /// How long the error estimates owed for an answer wait for its picture, from now on
    /// ([`Worker::waits_for_pictures`]; zero: not at all).
    pub fn picture_wait(&self, at_most: std::time::Duration) {
        if let Some(w) = &self.worker {
            w.waits_for_pictures(at_most);
        }
    }

    /// The pictures of the answers received so far are on screen ([`Worker::pictures_shown`]).
    pub fn pictures_shown(&self) {
        if let Some(w) = &self.worker {
            w.pictures_shown();
        }
    }

    /// Block until the solver thread is idle; every reply that came on the way.
    pub fn wait_idle(&mut self) -> Vec<Reply> {
        let mut replies = Vec::new();
        if let Some(w) = &mut self.worker {
            w.wait_idle(|r| replies.push(r));
        }
        replies
    }

    /// The command a step of `kind` sends, with the progress line's label. On a mesh other than
    /// the quadtree, Solve is the mesh solve and the hierarchical steps are refused (why, in one
    /// line).
    pub fn step_command(&self, kind: StepKind) -> Result<(Command, &'static str), String> {
        if self.mesh.method != MeshMethod::Quadtree {
            return if kind == StepKind::Solve {
                Ok((Command::SolveMesh(self.mesh, self.dmesh), MESH_SOLVE_LABEL))
            } else {
                Err(format!("{kind:?} steps the quadtree: pick the quadtree mesh first"))
            };
        }
        let label = match kind {
            StepKind::Refine => "refining",
            StepKind::Gather => "gathering",
            StepKind::PushPull => "push-pull",
            StepKind::Iterate => "iterating",
            StepKind::Solve => "solving",
        };
        Ok((Command::Step(kind), label))
    }
}
