//! Solved states kept for a retarget ([`HierarchicalSolver::retarget`]): a threshold made
//! coarser goes back to the finest state solved at a threshold no finer than it, and refines on
//! from there, instead of starting again from the input patches.
//!
//! A state is kept when a retarget leaves it (the solve had converged at its thresholds): its
//! hierarchy, links, the first moments the gather reads, the error oracle's kernels, the
//! cluster links and transfer, the closed rows and the run log. A retarget picks, among the
//! kept states and the current one, the finest whose thresholds are no finer than asked
//! ([`at_least_as_fine`]); the solve that follows refines it to the new thresholds, warm. So
//! dragging a threshold back and forth re-solves from states already solved, and a kept state
//! at exactly the asked thresholds is that solve's answer again.
//!
//! Memory stays bounded: at most [`MAX_KEPT`] states holding [`MAX_KEPT_LINKS`] links between
//! them, the oldest dropped first; a walk that never turns coarser keeps none
//! ([`HierarchicalSolver::keep_solved_states`]).

use super::HierarchicalSolver;
use super::closure::Closure;
use super::oracle::Kernels;
use super::parts::{ClusterState, PushPullState, RunLog};
use crate::math::Rgb;
use crate::solver::hierarchy::Hierarchy;
use crate::solver::link::LinkStore;
use crate::solver::params::HierarchicalParams;
use std::sync::atomic::Ordering;

/// The most solved states a solver keeps.
pub(super) const MAX_KEPT: usize = 8;

/// The most links the kept states may hold together: a link is 44 bytes, its error-oracle
/// kernels 68 and its share of the elements about 15, so about 0.5 GB.
pub(super) const MAX_KEPT_LINKS: usize = 4_000_000;

/// One solved state and the parameters it was solved at.
pub(super) struct Kept {
    params: HierarchicalParams,
    links_held: usize,
    hier: Hierarchy,
    links: LinkStore,
    moment: Vec<[Rgb; 2]>,
    error_kernels: Vec<Kernels>,
    cluster: ClusterState,
    closure: Closure,
    log: RunLog,
}

/// Whether `p`'s thresholds are as fine as `than`'s or finer (Feps, BFeps or ε, Aeps no larger,
/// the depth and link caps no smaller), on a scene of total area `area`.
pub(super) fn at_least_as_fine(p: &HierarchicalParams, than: &HierarchicalParams, area: f64) -> bool {
    p.feps <= than.feps
        && p.bf_eps <= than.bf_eps
        && p.aeps.resolve(area) <= than.aeps.resolve(area)
        && p.max_depth >= than.max_depth
        && p.max_links >= than.max_links
}

/// Whether `a` and `b` differ in their thresholds at most (and the row check, which the ladder
/// ties to the threshold): a state solved under one can be refined on under the other.
pub(super) fn same_but_thresholds(a: &HierarchicalParams, b: &HierarchicalParams) -> bool {
    HierarchicalParams {
        feps: a.feps,
        bf_eps: a.bf_eps,
        aeps: a.aeps,
        max_depth: a.max_depth,
        max_links: a.max_links,
        row_tol: a.row_tol,
        ..*b
    } == *a
}

impl HierarchicalSolver {
    /// Keep solved states for later retargets to coarser thresholds (on by default). Off, a
    /// coarser threshold restarts from the input patches and nothing is copied; a walk whose
    /// thresholds only get finer turns it off.
    pub fn keep_solved_states(&mut self, on: bool) {
        self.keep_states = on;
        if !on {
            self.kept.clear();
        }
    }

    /// How many solved states are kept ([`keep_solved_states`](Self::keep_solved_states)).
    #[must_use]
    pub fn kept_states(&self) -> usize {
        self.kept.len()
    }

    /// Keep the current state if it is solved (linked, converged, its gathers not cut short) and
    /// fits the bounds, replacing a state kept at the same parameters; the oldest go first.
    pub(super) fn keep_current(&mut self) {
        if !(self.keep_states && self.graph.linked && self.log.converged && !self.log.gathers_cut) {
            return;
        }
        let links_held = self.graph.links.len();
        if links_held > MAX_KEPT_LINKS {
            return;
        }
        let params = self.setup.params;
        self.kept.retain(|k| k.params != params);
        self.kept.push(Kept {
            params,
            links_held,
            hier: self.hier.clone(),
            links: self.graph.links.clone(),
            moment: self.push_pull.moment.clone(),
            error_kernels: self.oracle.error_kernels.clone(),
            cluster: self.cluster.clone(),
            closure: self.closure.clone(),
            log: self.log.clone(),
        });
        while self.kept.len() > MAX_KEPT
            || self.kept.iter().map(|k| k.links_held).sum::<usize>() > MAX_KEPT_LINKS
        {
            self.kept.remove(0);
        }
    }

    /// The kept state to go back to for parameters `p`: the finest kept state no finer than
    /// `p`, if it is finer than the current one (or the current one is finer than `p`).
    pub(super) fn state_to_restore(&self, p: &HierarchicalParams, current_fits: bool) -> Option<usize> {
        let area = self.setup.scene.total_area();
        let (i, k) = self
            .kept
            .iter()
            .enumerate()
            .filter(|(_, k)| at_least_as_fine(p, &k.params, area))
            .max_by_key(|(_, k)| k.links_held)?;
        let better = !current_fits || k.links_held > self.graph.links.len();
        better.then_some(i)
    }

    /// Make kept state `k` the current one, under parameters `p` (the state's own, or finer:
    /// under its own, its log says it is solved, and the next solve has nothing to do).
    pub(super) fn restore(&mut self, k: Kept, p: HierarchicalParams) {
        let own = k.params == p;
        self.hier = k.hier;
        self.graph.links = k.links;
        self.graph.linked = true;
        self.graph.pair_memo = Default::default();
        self.gather.invalidate();
        self.push_pull = PushPullState { moment: k.moment, ..Default::default() };
        self.oracle.b.clear();
        self.oracle.row_floor.clear();
        self.oracle.error_kernels = k.error_kernels;
        self.cluster = k.cluster;
        self.closure = k.closure;
        self.log = k.log;
        if own {
            self.setup.set_params(p);
            self.setup.cancel.store(false, Ordering::Relaxed);
        } else {
            self.go_on_under(p);
        }
    }

    /// Take parameters `p` for the solved state held now: the next solve refines on from it.
    pub(super) fn go_on_under(&mut self, p: HierarchicalParams) {
        self.setup.set_params(p);
        self.log.converged = false;
        self.log.settled = false;
        self.setup.cancel.store(false, Ordering::Relaxed);
    }
}
