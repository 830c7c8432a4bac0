//! The threads' answers applied to the app: the solver thread's (a scene loaded, a step or solve
//! done, progress, a picture in progress, a failure), the reference thread's (where the reference
//! stands, the scores of the states), the artifact measurements asked for, and the panics of
//! any of them.

use super::RadlabApp;
use crate::solver::hierarchical::{StepKind, StepReport};
use crate::viewer::reference::{Evaluation, RefReply};
use crate::viewer::reference_panel::RefState;
use crate::viewer::status_bar::SolveStart;
use crate::viewer::worker::{Reply, ViewData};
use std::sync::Arc;
use std::time::Instant;

impl RadlabApp {
    /// Block until the solver thread is idle and apply its replies, then until the reference
    /// thread has scored the result, then until the display is built (tests, scripted runs).
    pub fn wait_for_solver(&mut self) {
        // No frames are drawn while this blocks: the estimates owed do not wait for pictures.
        self.solve.picture_wait(std::time::Duration::ZERO);
        for r in self.solve.wait_idle() {
            self.apply(r);
        }
        loop {
            self.request_evaluation();
            let Some(replies) = self.comparison.reference.wait_idle() else { break };
            for r in replies {
                self.apply_ref(r);
            }
        }
        self.request_artifacts();
        self.artifacts.poll(true);
        self.request_geometry();
        self.poll_geometry(true);
        self.split.wait();
        self.replay.wait();
        self.report_thread_panics();
        self.solve.picture_wait(crate::viewer::worker::PICTURE_WAIT);
    }

    /// Block until the solver thread has answered every command sent and apply the answers, not
    /// waiting for the error estimates that follow a step's (tests).
    pub fn wait_for_answers(&mut self) {
        if let Some(w) = &mut self.solve.worker {
            let mut replies = Vec::new();
            w.wait_answered(|r| replies.push(r));
            for r in replies {
                self.apply(r);
            }
        }
    }

    /// Apply the solver thread's replies so far; then start the re-solve that waits for it to be
    /// idle, or show the state held back when none follows.
    pub(super) fn poll_worker(&mut self) {
        for r in self.solve.poll() {
            self.apply(r);
        }
        if self.solve.resolve_pending && !self.busy() {
            self.solve.resolve_pending = false;
            self.send_step(StepKind::Solve);
        }
        if self.shown.hold && !self.solve.resolve_pending && !self.busy() {
            // No solve follows the restart (cancelled): show the solver's state.
            self.shown.release();
        }
    }

    fn apply(&mut self, r: Reply) {
        match r {
            // The previous scene's last answers (its running step, cancelled): not shown.
            Reply::Done { .. }
            | Reply::Cancelled { .. }
            | Reply::Partial { .. }
            | Reply::Progress { .. }
            | Reply::Replay { .. }
            | Reply::Retargeted
                if self.solve.loading => {}
            Reply::Replay { frames } => self.shown.replay_frames = Some(frames),
            // The load of a scene opened before the one shown now (its Load ran before the
            // cancel that dropped what was queued): not shown, the newer load's answer follows.
            Reply::Loaded { scene, .. } if self.scene.as_ref().is_some_and(|s| !Arc::ptr_eq(s, &scene)) => {}
            Reply::Loaded { view, .. } => self.loaded(view),
            Reply::Done { report, view } => self.done(report, view),
            Reply::Progress { done, total } => self.solve.progress = Some((done, total)),
            // A long solve's picture so far; not while a restart holds the last picture back
            // (that one stays until the solve answers).
            Reply::Partial { view } => {
                if !self.shown.hold {
                    self.shown.set(view);
                    self.shown.partials += 1;
                }
            }
            Reply::Skipped => {}
            // Finer thresholds, the solver's state kept: the Solve that follows is warm.
            Reply::Retargeted => self.log.start = SolveStart::Warm,
            // A mesh solve dropped on Cancel: the picture shown stays.
            Reply::Cancelled { report } => {
                self.solve.progress = None;
                self.shown.last_report = Some(report);
                self.script.solver_answered(
                    !self.busy(),
                    self.opts.bench_frames.is_some(),
                    &self.opts.bench_thresholds,
                );
            }
            // The error estimates of a state a step answered with: folded into it wherever it is
            // still shown or kept (dropped when it no longer is).
            Reply::Estimates { of, view } => self.estimated(&of, &view),
            // Given up (a newer command came first): the state is marked "not estimated"
            // wherever it is kept, as the estimates would have been folded in (the marked copy
            // made only then: a drag's steps replace the states they give up).
            Reply::EstimatesDropped { of } => {
                if self.keeps(&of) {
                    self.estimated(&of, &Arc::new(of.without_estimates()));
                }
            }
            Reply::Baked(Ok(what)) => self.status_bar.message = what,
            Reply::Baked(Err(e)) => self.errors.push(e),
            Reply::Failed(e) => self.solver_failed(e),
        }
    }

    /// The error estimates of state `of` arrived, or were given up (`view`: that state with them,
    /// or marked so): it is replaced by `view` where it is shown, held back, kept by a run of
    /// the history or by the replay.
    /// The state keeps its number (its display build, scores and artifacts stay its own; the
    /// viewport rebuilds as the `Arc` changed).
    fn estimated(&mut self, of: &Arc<ViewData>, view: &Arc<ViewData>) {
        if Arc::ptr_eq(&self.shown.view, of) {
            self.shown.view = Arc::clone(view);
        }
        if let Some(held) = self.shown.held.as_mut().filter(|h| Arc::ptr_eq(h, of)) {
            *held = Arc::clone(view);
        }
        self.history.fold_estimates(of, view);
        self.replay.fold_estimates(of, view);
    }

    /// Whether state `of` is shown, held back, or kept by a run of the history or the replay
    /// (where [`Self::estimated`] folds its estimates in).
    fn keeps(&self, of: &Arc<ViewData>) -> bool {
        Arc::ptr_eq(&self.shown.view, of)
            || self.shown.held.as_ref().is_some_and(|h| Arc::ptr_eq(h, of))
            || self.history.keeps(of)
            || self.replay.keeps(of)
    }

    /// The scene's solver is ready: its first state (held back where a reload on another top
    /// level keeps the last picture), the solver's clock from zero.
    fn loaded(&mut self, view: Arc<ViewData>) {
        self.solve.loading = false;
        // A reload on another top level (a preset change) keeps the last picture until its
        // solve is done, as a parameter change does.
        if self.shown.hold {
            self.shown.held = Some(view);
        } else {
            self.shown.set(view);
        }
        self.solve.progress = None;
        // The loaded state is the first sample (unless held back: the next shown).
        self.log.restart(self.shown.seq + u64::from(self.shown.hold));
    }

    /// A command finished (`report`: the step's; `None` for a restart): its state shown or held
    /// back, the step or restart recorded.
    fn done(&mut self, report: Option<StepReport>, view: Arc<ViewData>) {
        // A restart, or a solve cancelled by the next restart (a slider dragged on): the last
        // finished picture stays until the re-solve answers.
        let superseded = self.shown.hold && report.as_ref().is_none_or(|r| r.cancelled);
        // A solve that finished on an earlier setting while the next one was queued: a finished
        // picture, shown, but the hold goes on for the restart that follows.
        let earlier = view.mesh.is_none() && view.params != self.solve.params;
        if superseded {
            self.shown.held = Some(view);
        } else {
            if !earlier {
                self.shown.hold = false;
            }
            self.shown.held = None;
            self.shown.set(view);
        }
        // The time a superseded solve spent counts: a warm re-solve goes on from its state.
        if superseded && let Some(r) = &report {
            self.log.solver_time_s += r.time_s;
        }
        self.solve.progress = None;
        match report.filter(|_| !superseded) {
            None => self.restarted(superseded),
            Some(rep) => self.stepped(rep),
        }
        // (Before the script hears of it: a first picture's solve is not the last.)
        self.opening_after(report.filter(|_| !superseded));
        if self.pick.here().is_some_and(|s| s as usize >= self.shown.view.elements.len()) {
            self.pick.selected = None;
        }
        // The next figure asked for opens once the solves before it are done.
        if !self.busy() && !self.opts.then_figures.is_empty() {
            let next = self.opts.then_figures.remove(0);
            self.open_figure(next);
        }
        self.script.solver_answered(
            !self.busy(),
            self.opts.bench_frames.is_some(),
            &self.opts.bench_thresholds,
        );
    }

    /// The solver restarted (superseded or not): the next solve starts from the input patches.
    fn restarted(&mut self, superseded: bool) {
        // SetParams / Reset restart the solver: element ids start over, and the last step's
        // report no longer describes what is shown (unless held back).
        if !superseded {
            self.shown.last_report = None;
        }
        self.log.restart(self.shown.seq + u64::from(superseded));
        // (A pick in a split pane's run stays: that solution is kept.)
        if self.pick.selected_run.is_none() {
            self.pick.selected = None;
        }
    }

    /// A step or solve finished: its report and time recorded, its replay frames handed over,
    /// and a finished Solve recorded as a run.
    fn stepped(&mut self, rep: StepReport) {
        if self.shown.view.mesh.is_none() {
            let start_gathers = self.shown.start_gathers();
            self.log.note_step(&rep, start_gathers, &self.shown.view.params);
        }
        self.log.solver_time_s += rep.time_s;
        self.shown.last_report = Some(rep);
        if rep.kind == StepKind::Solve
            && let Some(frames) = self.shown.replay_frames.take()
        {
            self.replay.set_frames(frames, Arc::clone(&self.shown.view));
        } else if self.shown.view.mesh.is_some() {
            // A mesh solve has no rounds: the replay of an earlier solve is stale.
            self.replay.clear();
        }
        if rep.kind == StepKind::Solve && !rep.cancelled {
            self.record_solve();
        }
    }

    /// A finished Solve: a run of the history (the drag's run, replaced, while a slider drag
    /// goes on), scored where the reference is known.
    fn record_solve(&mut self) {
        let name = self.scene_name().to_owned();
        let view = Arc::clone(&self.shown.view);
        let (over, time_s) = (self.drag.run_over(), self.log.solver_time_s);
        let n = self.history.record_over(over, &name, time_s, self.shown.seq, view);
        // A run that is never the state shown (a figure's queued solves) is scored all the same.
        if self.comparison.ready() {
            self.score_runs();
        }
        if self.drag.recorded(n) {
            self.end_drag_when_done();
        }
    }

    /// The solver thread failed (or stopped): the held picture comes back, and the error is
    /// shown (a scripted run ends with it).
    fn solver_failed(&mut self, e: String) {
        self.leave_opening();
        self.solve.loading = false;
        self.solve.progress = None;
        self.shown.release();
        self.script_failed(e.clone());
        self.status_bar.message.clone_from(&e);
        self.errors.push(e);
    }

    /// A drag is over once released and its last value's solve is in: the next solve is a run
    /// of its own.
    pub(super) fn end_drag_when_done(&mut self) {
        let settled = !self.solve.resolve_pending && !self.busy();
        self.drag.end_when_done(settled);
    }

    /// Send the current solver state to the reference thread for scoring, once.
    fn request_evaluation(&mut self) {
        if self.comparison.ready() && !self.shown.view.elements.is_empty() {
            self.comparison.reference.evaluate(self.shown.seq, &self.shown.view, self.log.solver_time_s);
        }
    }

    /// Apply the reference thread's replies so far, and send it the state shown to score.
    pub(super) fn poll_reference(&mut self) {
        for r in self.comparison.reference.poll() {
            self.apply_ref(r);
        }
        self.request_evaluation();
    }

    fn apply_ref(&mut self, r: RefReply) {
        let current = |source: &str, s: &Self| s.scene.as_ref().is_some_and(|sc| sc.source == source);
        match r {
            RefReply::Computing { source, points, samples } if current(&source, self) => {
                self.comparison.state = RefState::Computing { points, samples, since: Instant::now() };
            }
            RefReply::Missing { source } if current(&source, self) => {
                self.comparison.state = RefState::Missing;
            }
            RefReply::Cancelled { source } if current(&source, self) => {
                self.comparison.state = RefState::Missing;
                self.status_bar.message = "reference computation cancelled".into();
            }
            RefReply::Solution { source, view } if current(&source, self) => {
                self.comparison.reference.view = Some(Arc::clone(&view));
                let samples = self.opts.reference.params.paths.samples;
                let name = self.scene_name().to_owned();
                self.history.record_reference(&name, samples, view);
            }
            RefReply::Ready { source, points, samples, how } if current(&source, self) => {
                self.comparison.state = RefState::Ready { points, samples, how };
                self.comparison.reference.rescore();
                self.score_runs();
            }
            RefReply::Evaluated(e) if self.comparison.reference.scored_run(e.view_seq) => {
                self.history.set_reference_error(e.view_seq, e.rel_l2, e.band_l2, e.ruler);
            }
            RefReply::Evaluated(e) => self.evaluated(e),
            RefReply::Unscored { view_seq } => {
                self.comparison.reference.scored_run(view_seq);
            }
            RefReply::Failed(e) => {
                self.comparison.state = RefState::Failed(e.clone());
                self.errors.push(e);
            }
            RefReply::Panicked(e) => {
                self.comparison.state = RefState::Failed(e.clone());
                self.thread_panicked(e);
            }
            // Answers about a scene no longer shown.
            RefReply::Computing { .. }
            | RefReply::Missing { .. }
            | RefReply::Ready { .. }
            | RefReply::Solution { .. }
            | RefReply::Cancelled { .. } => {}
        }
    }

    /// A state's score: its run's error, and the state shown's true error, error and error
    /// sample.
    fn evaluated(&mut self, e: Evaluation) {
        self.history.set_reference_error(e.view_seq, e.rel_l2, e.band_l2, e.ruler);
        if e.view_seq == self.shown.seq {
            self.comparison.true_error = Some(Arc::new(e.per_element));
            self.comparison.state_error = e.rel_l2.is_finite().then_some((e.view_seq, e.rel_l2, e.band_l2));
        }
        // (Not a state from before the last restart, answered late.)
        self.log.sample(e.view_seq, e.solver_time_s, e.rel_l2);
    }

    /// Send the earlier runs of this scene that still keep their solution to the reference thread,
    /// so that their error, too, is the one against the reference (the split view compares them).
    fn score_runs(&mut self) {
        let runs = self.history.unscored(self.scene_name());
        self.comparison.reference.score_runs(runs, self.shown.seq);
    }

    /// Ask the artifacts thread to measure the state shown, once per state and reference (only
    /// while an artifact overlay is on, and not a solve's intermediate picture).
    pub(super) fn request_artifacts(&mut self) {
        let view = &self.shown.view;
        if self.display.artifact.is_none() || view.elements.is_empty() || self.busy() || self.solve.loading {
            return;
        }
        if let Some(scene) = &self.scene {
            self.artifacts.request(self.shown.seq, scene, view, self.comparison.reference.view.as_ref());
        }
    }

    /// Report the display builds (viewport, split panes, replay) and artifact measurements
    /// that panicked since the last call.
    pub(super) fn report_thread_panics(&mut self) {
        let mut panics = Vec::new();
        panics.extend(self.geometry.take_failure());
        panics.extend(self.split.take_failures());
        panics.extend(self.replay.take_failure());
        panics.extend(self.artifacts.take_panic());
        for p in panics {
            self.thread_panicked(p);
        }
    }
}
