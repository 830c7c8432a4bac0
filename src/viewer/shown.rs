//! The solver state shown ([`Shown`]): the newest picture the solver thread sent and its
//! number, the picture held back while a settings change is re-solved, and what the last step
//! reported.

use super::worker::ViewData;
use crate::solver::hierarchical::StepReport;
use std::sync::Arc;

/// The solver state shown and the one held back.
#[derive(Default)]
pub struct Shown {
    /// The solver state drawn (the viewport, the inspector, the plots read it).
    pub(super) view: Arc<ViewData>,
    /// Counts the solver states received (identifies `view` in display builds, scores, the
    /// history).
    pub(super) seq: u64,
    /// A parameter change is being re-solved: keep showing the last picture until the new
    /// solve answers (the restart's unlit state goes to `held`, shown only if no solve follows,
    /// e.g. after Cancel).
    pub(super) hold: bool,
    pub(super) held: Option<Arc<ViewData>>,
    /// Pictures of solves in progress shown so far (`Reply::Partial`).
    pub(super) partials: usize,
    /// What the last solver step on this scene reported (`None` until one has run).
    pub(super) last_report: Option<StepReport>,
    /// The replay frames of the solve running now (they come just before its `Done`).
    pub(super) replay_frames: Option<Vec<Arc<ViewData>>>,
}

impl Shown {
    /// Show `view`: a new state, with a number of its own.
    pub fn set(&mut self, view: Arc<ViewData>) {
        self.view = view;
        self.seq += 1;
    }

    /// Stop holding the last picture back and show the state held instead, if any (no solve
    /// follows the restart that held it).
    pub fn release(&mut self) {
        self.hold = false;
        if let Some(v) = self.held.take() {
            self.set(v);
        }
    }

    /// The gathers of the state the solve running now started from (its first replay frame).
    #[must_use]
    pub fn start_gathers(&self) -> Option<usize> {
        self.replay_frames.as_ref().and_then(|f| f.first()).map(|f| f.residuals.len())
    }
}
