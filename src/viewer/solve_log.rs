//! What the solves since the last restart have done ([`SolveLog`]): the solver time, the error
//! samples of the error-vs-time plot, how the next Solve starts (cold, warm, after steps), the
//! warm re-solves and where each began, and how the last Solve went (the status bar's line).

use super::plots::ResolveMark;
use super::status_bar::{SolveNote, SolveStart};
use crate::solver::hierarchical::{StepKind, StepReport};
use crate::solver::params::HierarchicalParams;

/// The solver's clock and the record of its solves.
pub struct SolveLog {
    /// Where the next Solve starts from (set by the solver thread's answers: a load or a
    /// restart, a retarget that kept the state, a step by hand).
    pub(super) start: SolveStart,
    /// How the last finished Solve started and how long it took (the status bar says it).
    pub(super) last_solve: Option<SolveNote>,
    /// Solves finished warm in this window (each a retarget's: finer thresholds, the last
    /// solve's state kept).
    pub(super) warm_solves: usize,
    /// Where each warm re-solve since the last cold start began (the plots mark them).
    pub(super) resolve_marks: Vec<ResolveMark>,
    /// Solver time since the last restart (sum of the steps' times), seconds.
    pub(super) solver_time_s: f64,
    /// (solver time, error against the reference) after steps, for the error-vs-time plot.
    pub(super) error_samples: Vec<[f64; 2]>,
    /// The first state whose score is a sample of `error_samples` (the last restart's).
    pub(super) samples_from: u64,
}

impl Default for SolveLog {
    fn default() -> SolveLog {
        SolveLog {
            start: SolveStart::Cold,
            last_solve: None,
            warm_solves: 0,
            resolve_marks: Vec::new(),
            solver_time_s: 0.0,
            error_samples: Vec::new(),
            samples_from: 0,
        }
    }
}

impl SolveLog {
    /// The solver restarted from the input patches (a load, new settings, a reset): its clock
    /// starts over, the next Solve is cold, and the error samples start at state `first_sample`.
    pub fn restart(&mut self, first_sample: u64) {
        self.solver_time_s = 0.0;
        self.error_samples.clear();
        self.start = SolveStart::Cold;
        self.resolve_marks.clear();
        self.samples_from = first_sample;
    }

    /// What a finished step of the hierarchical solver tells about the next Solve's start, and a
    /// finished Solve about itself: how it started and how long it took (the status bar's line),
    /// and where a warm one began (marked in the plots: `start_gathers`, the gathers of the
    /// state it started from, at the solver time then; `params`, the settings it solved to).
    /// Call before the step's time is added to the solver time.
    pub fn note_step(&mut self, rep: &StepReport, start_gathers: Option<usize>, params: &HierarchicalParams) {
        if rep.kind != StepKind::Solve {
            self.start = SolveStart::Stepped;
            return;
        }
        if rep.cancelled {
            return;
        }
        if self.start == SolveStart::Warm {
            self.warm_solves += 1;
            if let Some(gathers) = start_gathers {
                // A solve that went back to a state solved earlier (a coarser threshold) leaves
                // the warm re-solves begun after that state: they are no longer in its plot.
                self.resolve_marks.retain(|m| m.gathers <= gathers);
                let threshold = super::history::oracle_threshold(params);
                self.resolve_marks.push(ResolveMark { gathers, time_s: self.solver_time_s, threshold });
            }
        }
        self.last_solve = Some(SolveNote { start: self.start, time_s: rep.time_s });
        self.start = SolveStart::Stepped;
    }

    /// Record an error sample of the state scored at solver time `solver_time_s` (not a state
    /// from before the last restart, answered late; not an error that is not finite).
    pub fn sample(&mut self, view_seq: u64, solver_time_s: f64, error: f64) {
        if error.is_finite() && view_seq >= self.samples_from {
            self.error_samples.push([solver_time_s, error]);
        }
    }
}
