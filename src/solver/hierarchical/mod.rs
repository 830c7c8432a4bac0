//! Hierarchical radiosity [Hanrahan, Salzman, Aupperle 1991 (HSA91), "A Rapid Hierarchical
//! Radiosity Algorithm", SIGGRAPH '91]: quadtree elements, `Refine` with Feps/Aeps or a BF oracle,
//! links, recursive `Gather`, push-pull — O(n) interactions instead of n².
//!
//! ```text
//! B_p = E_p + ρ_p Σ_{links p←q on p and its ancestors} F_pq V_pq B_q
//! ```
//!
//! ## Files, in the lecture's vocabulary
//! - this file: the solver, its step API (`refine_step`, `gather_step`, `push_pull_step`,
//!   `iterate`, `solve`) and what it reports (stats, snapshots, the solution);
//! - [`linking`]: the first links, between input patches or clusters;
//! - [`refine`]: `Refine`, the passes that split links the oracle rejects;
//! - [`oracle`]: the refinement criteria (Feps, BF, the error oracle) and the papers they follow;
//! - [`transfer`]: a link's coefficient, the Galerkin coupling G = A_p F_pq = A_q F_qp;
//! - [`gather`]: `Gather`, each receiver's sum over its links;
//! - [`push_pull`]: push-pull, the reflection at the leaves and the power balance;
//! - [`estimate`]: the solver's own estimate of its pointwise error;
//! - [`cluster`]: the cluster hierarchy above the input patches and its transfer;
//! - [`deadline`]: a time budget's end, and the estimates that leave the gathers their time;
//! - `checkpoint`: solved states kept, so that a coarser threshold goes back to one;
//! - `audit`: every leaf's row of F·V against what rays find in its hemisphere ([`LeafAudit`]);
//! - `parts`: the solver's state, in named parts.
//!
//! ## The solver's parts
//! [`HierarchicalSolver`] holds the mesh (`Hierarchy`: elements, radiosity, gathered sums) and
//! named parts, each with what one stage owns; a pass takes the parts it reads and writes:
//! ```text
//!  Setup          scene, BVH, parameters, resolved Aeps/BFeps, cancel/deadline read by all
//!  LinkGraph      links by receiver, the initial-link cache, the pair memo     refine → gather
//!  GatherState    the links flattened into a plan, the changed receivers       gather
//!  PushPullState  push-pull's per-element sums, the first moments of B          push-pull → gather
//!  OracleState    refine's per-element B cache, row floors, error kernels       refine
//!  ClusterState   the cluster tree, its links and transfer                      linking, gather
//!  Closure        enclosed patches, the leaves' scales and balanced rows        gather, push-pull
//!  RunLog         statistics, residuals, convergence, the power balance         every step
//! ```
//! The gather's sweeps are `GatherState` methods taking the mesh, the closure and the moments;
//! push-pull's are `PushPullState` methods whose residual and power sums the `RunLog` records;
//! the closed rows' balance is a `Closure` method taking the elements and parameters; the error
//! estimate reads the mesh, links, BVH and closure. Refinement and linking change the mesh, the
//! links, the oracle's cache and the clusters together, and stay methods of the solver.
//!
//! ## How it works
//! ```text
//!  refine_step ──► gather_step ──► push_pull_step ──► (BF oracle: refine again) ──► …
//!   │                │                 │
//!   │                │                 └ push: H_leaf = Σ_ancestors gathered; B_leaf = E + ρ·H
//!   │                │                   pull: B_parent = Σ (A_child/A) B_child
//!   │                └ per receiver (parallel): gathered = Σ_links F·V·B_source   (Jacobi)
//!   └ passes until nothing splits; each pass:
//!       A (parallel, read-only)  decide per link: keep / split source / split receiver
//!                                (first pass: every link; later: the verdicts made with the
//!                                new links, the oracle's inputs being fixed during a refinement)
//!       B (sorted ids)           split the chosen elements → deterministic element ids
//!       C (parallel)             form factors + visibility + verdicts of the replacement links
//!       D (receiver order)       install the links
//! ```
//! `solve` runs the loop: refine, then `round_iterations` gathers, until a refinement adds at
//! most `settle` of the links (or the last allowed round comes); those are gathered to
//! convergence.
//! - **Refine** (the lecture's `Refine(p, q, Feps, Aeps)`): if the oracle ([`oracle`], and
//!   `refine::decide` for Feps and BF) is satisfied, keep the link; else split the element with
//!   the larger estimate unless it is at the Aeps floor or the maximum depth. Each link caches
//!   its estimates, split side and error bound (`Link`), so re-applying an oracle after a gather
//!   costs a multiply per link.
//! - **Mirror links**: every decision is symmetric in the pair, and a pair's coupling G and
//!   visibility V are computed once ([`transfer`], `visibility::visibility_sample` in the pair's
//!   canonical order), so the links q ← p mirror p ← q at every level and what a source sends is
//!   what its receiver gathers: the power balance closes (`EnergyBalance`).
//! - **Push-pull with slopes** (`push_slopes`): a link also carries how its transfer varies
//!   across its receiver and its source; push moves an ancestor's irradiance along the slope,
//!   the gather adds the source's first moment of radiosity ([`push_pull`]):
//!   ```text
//!   H_leaf = Σ_{links a ← s, a = leaf or an ancestor} [ F_as V B_s + slope_as · (c_leaf − c_a)
//!            + (A_s / A_a) src_slope_as · M_s ]
//!   ```
//! - **Closed rows** ([`closure`]): on enclosed patches a symmetric scaling of the leaves'
//!   operator brings every row of F·V to exactly 1 without creating light.
//!
//! Why each of these, with the measurements that chose them: docs/solver.md ("Hierarchical
//! radiosity": oracles, link coefficients, visibility and its confirmations, push-pull with
//! slopes, the row check, closed rows).
//! - **Parallel and deterministic**: element ids are assigned serially in sorted order, visibility
//!   jitter is keyed by the (receiver, source) ids, and parallel results are collected in order,
//!   so every count and value is identical for any thread count.
//!
//! Restarting with new parameters (`set_params`) reuses the BVH and, when `rays` and `seed` are
//! unchanged, the visibility of the initial patch pairs; elements and links are rebuilt.

mod audit;
mod checkpoint;
mod closure;
pub mod cluster;
pub mod deadline;
pub mod estimate;
mod gather;
mod linking;
mod oracle;
mod parts;
mod push_pull;
mod refine;
mod transfer;

pub use audit::LeafAudit;
use parts::{ClusterState, GatherState, LinkGraph, OracleState, PushPullState, RunLog, Setup};
use push_pull::{Chain, leaf_irradiance};

use super::params::{HierarchicalParams, Oracle};
use crate::geometry::accel::Accel;
use crate::math::{DVec3, Rgb, polygon_centroid, polygon_normal};
use crate::scene::Scene;
use crate::solver::hierarchy::{Element, Hierarchy, NONE, StopReason};
use crate::solver::link::{Link, LinkStore, VisClass};
use crate::solver::{PhaseTimes, Progress, Solution, SolveStats, SolvedElement};
use cluster::ClusterLink;
use serde::Serialize;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

pub use crate::solver::hierarchy::StopReason as ElementStopReason;

/// Rays used to confirm that an input patch pair is fully occluded before it is left unlinked,
/// and (conservative oracles) that an all-visible estimate is not partial.
const ROOT_CONFIRM_RAYS: u32 = 32;

/// Which step a report describes.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum StepKind {
    Refine,
    Gather,
    PushPull,
    Iterate,
    Solve,
}

/// What one step did.
#[derive(Copy, Clone, Debug, Serialize)]
pub struct StepReport {
    pub kind: StepKind,
    pub time_s: f64,
    /// Elements split.
    pub refined: usize,
    /// Links created.
    pub new_links: usize,
    /// Largest change of a leaf's radiosity in the last gather, relative to the largest
    /// reflected radiosity (0 before any gather).
    pub residual: f64,
    pub converged: bool,
    pub cancelled: bool,
}

/// Statistics of the hierarchy.
#[derive(Clone, Debug, Default, Serialize)]
pub struct HierarchicalStats {
    pub elements: usize,
    pub leaves: usize,
    pub links: usize,
    pub links_full: usize,
    pub links_partial: usize,
    pub links_none: usize,
    /// Input patch pairs left unlinked because they face away or are fully occluded (clustered:
    /// also the pairs of nodes accepted for a cluster link whose transfer is zero both ways).
    pub pairs_skipped: usize,
    pub depth_histogram: Vec<usize>,
    pub rays: u64,
    /// Links created by refinement, including those later replaced by finer ones.
    pub links_created: u64,
    pub refine_s: f64,
    /// Parts of `refine_s`: initial linking of the input patches; the oracle on every link
    /// (parallel); splitting elements (serial); computing replacement links, form factors and
    /// rays (parallel); installing them (serial).
    pub refine_initial_s: f64,
    pub refine_decide_s: f64,
    pub refine_split_s: f64,
    pub refine_links_s: f64,
    pub refine_install_s: f64,
    /// Refinement passes (decide → split → link → install), over all refinements.
    pub refine_passes: usize,
    /// Receivers whose links the oracle examined, over all passes.
    pub refine_decided: usize,
    pub gather_s: f64,
    pub push_pull_s: f64,
    pub iterations: usize,
    pub rounds: usize,
    pub bytes_per_link: usize,
    pub bytes_per_element: usize,
    pub memory_bytes: usize,
    pub links_per_element: f64,
    /// Refinement stopped at `max_links`.
    pub budget_hit: bool,
    /// Nodes of the cluster tree (0: not clustered).
    pub clusters: usize,
    /// Links with a cluster at one end at least (each moves light both ways; `links` counts
    /// element links, one per direction).
    pub cluster_links: usize,
    /// Input patches whose row through the cluster links their hemisphere bound cut
    /// (`cluster::ClusterTransfer::bound_rows`), at the last linking.
    pub cluster_rows_cut: usize,
}

/// What every element shows, whichever solver made it: its place in the hierarchy, geometry,
/// material and radiosity. [`ElementInfo`] and the viewer's element
/// (`present::overlay::ElementView`) hold one and dereference to it.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct ElementCore {
    /// The element's index in its list.
    pub id: u32,
    /// Input patch index.
    pub patch: u32,
    pub parent: Option<u32>,
    /// Depth below the input patch (0 = the patch itself).
    pub depth: u8,
    /// `n_vertices` (3 or 4) valid entries, counter-clockwise seen from the front.
    pub vertices: [DVec3; 4],
    pub n_vertices: u8,
    pub area: f64,
    pub reflectance: Rgb,
    pub emission: Rgb,
    pub radiosity: Rgb,
    /// The solver's own error estimate for B (units of B); 0 where it has none.
    pub error_estimate: f64,
}

impl ElementCore {
    /// The valid vertices (at most four, whatever `n_vertices` says).
    #[must_use]
    pub fn verts(&self) -> &[DVec3] {
        &self.vertices[..usize::from(self.n_vertices).min(4)]
    }
    /// Area centroid (the origin for an element without vertices).
    #[must_use]
    pub fn centroid(&self) -> DVec3 {
        let v = self.verts();
        if v.is_empty() { DVec3::ZERO } else { polygon_centroid(v) }
    }
    /// Unit normal (zero for an element without vertices or area).
    #[must_use]
    pub fn normal(&self) -> DVec3 {
        let v = self.verts();
        if v.is_empty() { DVec3::ZERO } else { polygon_normal(v) }
    }
}

/// Read-only view of one element.
#[derive(Clone, Debug, Serialize)]
pub struct ElementInfo {
    #[serde(flatten)]
    pub core: ElementCore,
    pub children: Option<[u32; 4]>,
    pub gathered: Rgb,
    pub stop: StopReason,
    /// A leaf's linear variation (the slope of the irradiance pushed down to it, times ρ), where
    /// it has one: its radiosity is `slope.at(radiosity, x)` across it.
    pub slope: Option<crate::solver::Slope>,
}

impl std::ops::Deref for ElementInfo {
    type Target = ElementCore;
    fn deref(&self) -> &ElementCore {
        &self.core
    }
}

impl std::ops::DerefMut for ElementInfo {
    fn deref_mut(&mut self) -> &mut ElementCore {
        &mut self.core
    }
}

/// Read-only view of one link.
#[derive(Copy, Clone, Debug, Serialize)]
pub struct LinkInfo {
    pub receiver: u32,
    pub source: u32,
    pub ff: f32,
    pub vis: f32,
    pub err: f32,
}

/// One leaf's row of F·V ([`HierarchicalSolver::leaf_rows`]): what it gathers per unit
/// radiosity of everything it sees, which a point's hemisphere bounds by 1 (by the part of it
/// that front faces fill, in fact: `solver::escape`).
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct LeafRow {
    /// The leaf's element id.
    pub id: u32,
    /// Σ F·V over its own and its ancestors' element links (with the slopes' shift to its
    /// centroid) and its patch's cluster links.
    pub row: f64,
    /// The part of `row` through cluster links.
    pub cluster: f64,
}

/// A cluster link as the viewer draws it ([`HierarchicalSolver::cluster_link_views`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClusterLinkView {
    /// Centres of the two ends.
    pub from: DVec3,
    pub to: DVec3,
    /// Estimated visibility in [0, 1].
    pub vis: f32,
    /// The larger unoccluded form factor of the two directions (point approximation).
    pub ff: f64,
    /// The two ends (the link's `from`, then `to`).
    pub ends: [ClusterEnd; 2],
}

/// One end of a cluster link: a cluster (its index in [`Snapshot::clusters`], the list of
/// [`HierarchicalSolver::cluster_infos`]) or a single input patch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum ClusterEnd {
    Cluster(u32),
    Patch(u32),
}

/// Read-only view of one node of the cluster tree ([`cluster`]).
#[derive(Copy, Clone, Debug, Serialize)]
pub struct ClusterInfo {
    /// Depth in the cluster tree (0: the root).
    pub depth: u8,
    /// Bounding box of the members.
    pub bmin: DVec3,
    pub bmax: DVec3,
    /// Input patches in the cluster.
    pub patches: u32,
    /// Cluster links with this node at one end.
    pub links: u32,
    /// The parent's index in the same list (None: the root).
    pub parent: Option<u32>,
}

/// A copy of the solver's state after a step.
#[derive(Clone, Debug, Serialize)]
pub struct Snapshot {
    pub elements: Vec<ElementInfo>,
    pub links: Vec<LinkInfo>,
    /// The cluster tree's nodes of two patches or more (empty when the solve does not cluster).
    pub clusters: Vec<ClusterInfo>,
    /// Per input patch, the index in `clusters` of the smallest cluster holding it (empty when
    /// the solve does not cluster).
    pub patch_cluster: Vec<u32>,
    pub stats: HierarchicalStats,
    /// Residual after each gather, in order.
    pub residuals: Vec<f64>,
}

/// Mutable references to the elements of `v` at `ids`, which must be strictly increasing.
fn disjoint_mut<T>(v: &mut [T], ids: impl Iterator<Item = u32>) -> Vec<&mut T> {
    let mut out = Vec::new();
    let mut rest = v;
    let mut offset = 0usize;
    for id in ids {
        let (_, tail) = std::mem::take(&mut rest).split_at_mut(id as usize - offset);
        let (item, tail) = tail.split_first_mut().expect("ids within the slice");
        out.push(item);
        rest = tail;
        offset = id as usize + 1;
    }
    out
}

/// A solve gathers on until its power balance closes to this, at every preset
/// (`EnergyBalance::relative_residual`).
pub const ENERGY_TOLERANCE: f64 = 1e-3;

/// The HSA91 solver with a step API: the mesh and its named parts ([`parts`]).
pub struct HierarchicalSolver {
    setup: Setup,
    /// The element quadtrees, one per input patch: geometry, radiosity and the gathered sums.
    hier: Hierarchy,
    graph: LinkGraph,
    gather: GatherState,
    push_pull: PushPullState,
    oracle: OracleState,
    cluster: ClusterState,
    /// Closed rows: which patches are enclosed, the leaves' scale and balanced rows
    /// ([`closure`]).
    closure: closure::Closure,
    log: RunLog,
    /// Solved states kept for a retarget to coarser thresholds ([`checkpoint`]), oldest first.
    kept: Vec<checkpoint::Kept>,
    /// Whether a retarget keeps the state it leaves (`keep_solved_states`).
    keep_states: bool,
}

impl HierarchicalSolver {
    /// Build the BVH and one root element per input patch (no links yet, B = E).
    pub fn new(scene: Arc<Scene>, params: HierarchicalParams) -> Result<Self, String> {
        params.validate()?;
        if scene.patches.is_empty() {
            return Err("the scene has no patches".into());
        }
        let t = Instant::now();
        let accel = Arc::new(Accel::build(&scene));
        let bvh_s = t.elapsed().as_secs_f64();
        Ok(Self::with_accel(scene, accel, params, bvh_s))
    }

    /// Like `new`, sharing an already built BVH.
    #[must_use]
    pub fn with_accel(scene: Arc<Scene>, accel: Arc<Accel>, params: HierarchicalParams, bvh_s: f64) -> Self {
        let hier = Hierarchy::from_scene(&scene);
        let graph = LinkGraph { links: LinkStore::new(hier.len()), ..Default::default() };
        HierarchicalSolver {
            log: RunLog::new(&scene),
            setup: Setup::new(scene, accel, params, bvh_s),
            hier,
            graph,
            gather: GatherState::default(),
            push_pull: PushPullState::default(),
            oracle: OracleState::default(),
            cluster: ClusterState::default(),
            closure: closure::Closure::default(),
            kept: Vec::new(),
            keep_states: true,
        }
    }

    /// Turn off (or on) the early exits of link visibility (see `make_link`). They cast fewer
    /// rays and leave every result the same; turning them off is for checking exactly that.
    pub fn set_early_exit(&mut self, on: bool) {
        self.setup.early_exit = on;
    }

    /// Recompute the error oracle's field for every element in every refinement pass (`true`)
    /// instead of only where links changed. The results are identical; for checking exactly that.
    pub fn set_full_error_passes(&mut self, on: bool) {
        self.setup.full_error_passes = on;
    }

    #[must_use]
    pub fn scene(&self) -> &Arc<Scene> {
        &self.setup.scene
    }
    #[must_use]
    pub fn params(&self) -> HierarchicalParams {
        self.setup.params
    }
    #[must_use]
    pub fn hierarchy(&self) -> &Hierarchy {
        &self.hier
    }
    #[must_use]
    pub fn links(&self) -> &LinkStore {
        &self.graph.links
    }
    #[must_use]
    pub fn accel(&self) -> &Arc<Accel> {
        &self.setup.accel
    }

    /// Restart with new parameters. Reuses the BVH, and the initial patch-pair links when `rays`,
    /// `seed` and `conservative` did not change.
    pub fn set_params(&mut self, p: HierarchicalParams) -> Result<(), String> {
        p.validate()?;
        self.setup.set_params(p);
        self.reset();
        self.kept.clear();
        Ok(())
    }

    /// Change the oracle's thresholds and keep what is solved. With every setting but the
    /// thresholds (Feps, BFeps or ε, Aeps, the depth and link caps) and the row check unchanged,
    /// the solver goes on from the finest solved state whose thresholds are no finer than `p`'s:
    /// the current one when `p` is as fine or finer (Aeps no larger, the caps no smaller), else
    /// one kept from an earlier retarget ([`checkpoint`]; the state left is kept too). The next
    /// [`solve`](Self::solve) refines from that state's hierarchy and links and gathers from
    /// its radiosity (a warm re-solve). Anything else, or no such state, restarts as
    /// [`set_params`](Self::set_params) does. Returns whether a solved state was kept.
    pub fn retarget(&mut self, p: HierarchicalParams) -> Result<bool, String> {
        p.validate()?;
        let old = self.setup.params;
        if !(checkpoint::same_but_thresholds(&old, &p) && self.graph.linked) {
            self.set_params(p)?;
            return Ok(false);
        }
        let area = self.setup.scene.total_area();
        let current_fits = checkpoint::at_least_as_fine(&p, &old, area);
        match self.state_to_restore(&p, current_fits) {
            None if current_fits => {
                // Refine on from here; keep this state for a later way back.
                if p != old {
                    self.keep_current();
                }
                self.go_on_under(p);
            }
            chosen => {
                let chosen = chosen.map(|i| self.kept.remove(i));
                self.keep_current();
                let Some(k) = chosen else {
                    self.setup.set_params(p);
                    self.reset();
                    return Ok(false);
                };
                self.restore(k, p);
            }
        }
        Ok(true)
    }

    /// Back to one element per patch, no links, B = E.
    pub fn reset(&mut self) {
        self.hier = Hierarchy::from_scene(&self.setup.scene);
        self.graph.links = LinkStore::new(self.hier.len());
        self.gather.invalidate();
        self.push_pull.moment.clear();
        self.cluster.links.clear();
        self.cluster.fv.clear();
        self.closure.reset();
        self.graph.linked = false;
        self.log = RunLog::new(&self.setup.scene);
        self.setup.cancel.store(false, Ordering::Relaxed);
    }

    /// Set the returned flag to make a running step return early (`StepReport::cancelled`).
    /// The state stays consistent: refinement stops between passes, gathering between iterations.
    #[must_use]
    pub fn cancel_handle(&self) -> Arc<AtomicBool> {
        Arc::clone(&self.setup.cancel)
    }

    fn cancelled(&self) -> bool {
        self.setup.cancelled()
    }

    /// End the solve's work by `deadline` (`None`: no end; a time budget's end): refinement
    /// stops, as the cancel flag stops it, once another pass and the gathers that converge the
    /// mesh after it would not fit before the deadline ([`deadline::Pace`] estimates both from
    /// the solver's timings), and the gathers ([`solve`](Self::solve)'s and
    /// [`converge`](Self::converge)'s) stop at the deadline, converged or not
    /// ([`gathers_cut`](Self::gathers_cut)). A solve that has not gathered yet gathers once.
    pub fn set_deadline(&mut self, deadline: Option<Instant>) {
        self.setup.deadline = deadline;
    }

    /// Where the deadline stopped the last solve's or convergence's gathers before they
    /// converged and closed the power balance: the residual of the last gather.
    #[must_use]
    pub fn gathers_cut(&self) -> Option<f64> {
        self.log.gathers_cut.then(|| self.log.residuals.last().copied().unwrap_or(0.0))
    }

    /// The links a gather sweep goes through: element and cluster links.
    fn gather_links(&self) -> usize {
        self.graph.links.len() + self.cluster.links.len()
    }

    /// Whether work estimated at `work_s` seconds, leaving `links` links, and the gathers that
    /// converge them fit before the deadline (always, without one); where they do not, the
    /// cancel flag is set, so that the solve stops as a cancelled one does.
    fn fits_deadline(&self, work_s: f64, links: usize) -> bool {
        let Some(deadline) = self.setup.deadline else { return true };
        let threads = rayon::current_num_threads();
        let fits = self.log.pace.fits(deadline, Instant::now(), work_s, links, threads);
        if !fits {
            self.setup.cancel.store(true, Ordering::Relaxed);
        }
        fits
    }

    #[must_use]
    pub fn is_converged(&self) -> bool {
        self.log.converged
    }

    fn report(&self, kind: StepKind, t: Instant, refined: usize, new_links: usize) -> StepReport {
        StepReport {
            kind,
            time_s: t.elapsed().as_secs_f64(),
            refined,
            new_links,
            residual: self.log.residuals.last().copied().unwrap_or(0.0),
            converged: self.log.converged,
            cancelled: self.cancelled(),
        }
    }
}

impl HierarchicalSolver {
    /// Refine, gather, push-pull.
    pub fn iterate(&mut self) -> StepReport {
        self.setup.cancel.store(false, Ordering::Relaxed);
        let t = Instant::now();
        let r = self.refine_inner();
        if r.cancelled {
            return self.report(StepKind::Iterate, t, r.refined, r.new_links);
        }
        self.gather_inner();
        if !self.setup.params.gauss_seidel {
            self.push_pull_step();
        }
        self.report(StepKind::Iterate, t, r.refined, r.new_links)
    }

    /// The HSA91 loop: refine → gather/push-pull (`round_iterations` times, or to convergence)
    /// → refine again with the oracle on the new radiosities → … until a refinement adds at most
    /// `settle` of the links (0: none, to a converged solution) and those are gathered to
    /// convergence, or the caps (`max_rounds`, `max_iterations` per round) are reached; the last
    /// allowed round converges fully.
    pub fn solve(&mut self, progress: Progress) -> StepReport {
        self.solve_observed(progress, &mut |_| {})
    }

    /// [`solve`](Self::solve), calling `on_round` with the solver after every round's gathers
    /// and push-pull (a consistent, displayable state: the viewer shows the picture as it
    /// forms). The result is the same as `solve`'s.
    pub fn solve_observed(&mut self, progress: Progress, on_round: &mut dyn FnMut(&Self)) -> StepReport {
        self.setup.cancel.store(false, Ordering::Relaxed);
        self.log.gathers_cut = false;
        let t = Instant::now();
        if self.log.settled && self.log.converged {
            // Solved under these parameters, nothing changed since: the answer stands.
            return self.report(StepKind::Solve, t, 0, 0);
        }
        let mut refined_total = 0;
        let mut links_total = 0;
        let mut ended_settled = false;
        let rounds = self.setup.params.max_rounds.max(1);
        // Push-pulls inside the loop skip the power sums; one pass at the end makes them.
        let mut energy_due = false;
        for round in 0..rounds {
            progress(u64::from(round), u64::from(rounds));
            // Refinement marks the solution unconverged; remember whether the last gathers had.
            let was_converged = self.log.converged;
            let r = self.refine_inner();
            refined_total += r.refined;
            links_total += r.new_links;
            if r.cancelled {
                break;
            }
            // A refinement that adds few links (at most `settle` of them) ends the refinement:
            // the mesh has settled, and its links are gathered to convergence with no
            // refinement after them. One that adds none to a converged solution leaves it as it
            // stands.
            let small = r.new_links as f64 <= self.setup.params.settle * self.graph.links.len() as f64;
            let settled = round > 0 && small;
            if settled && was_converged && r.new_links == 0 {
                // Nothing changed since the converged gather: the solution stands.
                self.log.converged = true;
                ended_settled = true;
                break;
            }
            // While the mesh still changes, refine again after `round_iterations` gathers.
            let last = settled || round + 1 == rounds || self.setup.params.oracle == Oracle::Feps;
            let cap = if last || small {
                self.setup.params.max_iterations
            } else {
                self.setup.params.round_iterations.min(self.setup.params.max_iterations)
            };
            let iters = self.gather_sweeps(cap);
            energy_due |= !self.setup.params.gauss_seidel;
            self.log.stats.rounds = round as usize + 1;
            if self.log.gathers_cut {
                // The deadline passed: the solve stops as a cancelled one does.
                self.setup.cancel.store(true, Ordering::Relaxed);
            }
            if self.cancelled() || settled || (self.setup.params.oracle == Oracle::Feps && self.log.converged)
            {
                ended_settled = settled && !self.cancelled();
                break;
            }
            if !self.setup.params.gauss_seidel || iters > 0 {
                on_round(self);
            }
        }
        self.close_balance(energy_due);
        // (Not under a deadline: its refinement may have stopped for time, and a later solve
        // with more of it has work to do.)
        self.log.settled =
            ended_settled && self.log.converged && !self.log.gathers_cut && self.setup.deadline.is_none();
        progress(u64::from(rounds), u64::from(rounds));
        self.report(StepKind::Solve, t, refined_total, links_total)
    }

    /// Gather, without refining, until the solution converges (at most `max_iterations` sweeps)
    /// and its power balance closes: what a solve whose refinement was stopped (a time budget)
    /// needs for its answer to be the converged one on the mesh it reached. Resets the cancel
    /// flag first; setting it again stops the gathers too, and so does the deadline
    /// ([`set_deadline`](Self::set_deadline)).
    pub fn converge(&mut self) -> StepReport {
        self.setup.cancel.store(false, Ordering::Relaxed);
        self.log.gathers_cut = false;
        let t = Instant::now();
        let iters = if self.log.converged {
            0
        } else if self.log.gathered_once && self.setup.past_deadline() {
            self.log.gathers_cut = true;
            0
        } else {
            self.gather_sweeps(self.setup.params.max_iterations)
        };
        self.close_balance(!self.setup.params.gauss_seidel && iters > 0);
        self.report(StepKind::Solve, t, 0, 0)
    }

    /// Gather sweeps, each followed (Jacobi) by a push-pull that skips the power sums, until the
    /// solution converges, `cap` sweeps have run, the solve is cancelled or the deadline has
    /// passed (`gathers_cut`); at least one. Returns the sweeps run.
    fn gather_sweeps(&mut self, cap: u32) -> u32 {
        let mut iters = 0;
        loop {
            self.gather_sweep(false);
            iters += 1;
            if self.log.converged || iters >= cap || self.cancelled() {
                return iters;
            }
            if self.setup.past_deadline() {
                self.log.gathers_cut = true;
                return iters;
            }
        }
    }

    /// The end of a solve's gathers: the power sums (`energy_due`: push-pulls that skipped them
    /// ran), then, as far as the gathers converged, the power balance closed: a preset whose
    /// stopping tolerance leaves it open (splash2's 0.005 of B left table-room's at 1.1e-2)
    /// gathers on, without refining, until it closes to ENERGY_TOLERANCE (a bounded number of
    /// sweeps).
    fn close_balance(&mut self, energy_due: bool) {
        if energy_due {
            let te = Instant::now();
            self.energy_pass();
            self.log.stats.push_pull_s += te.elapsed().as_secs_f64();
        }
        let mut extra = 0;
        while self.log.gathered_once
            && self.log.energy.relative_residual() > ENERGY_TOLERANCE
            && extra < self.setup.params.max_iterations
            && !self.cancelled()
        {
            if self.setup.past_deadline() {
                self.log.gathers_cut = true;
                break;
            }
            self.gather_sweep(true);
            extra += 1;
        }
    }

    /// One gather, then (Jacobi) a push-pull, making the power sums when `sums`.
    fn gather_sweep(&mut self, sums: bool) {
        let sweep = Instant::now();
        self.gather_inner();
        if !self.setup.params.gauss_seidel {
            let t = Instant::now();
            self.push_pull_flat(None, sums);
            self.log.stats.push_pull_s += t.elapsed().as_secs_f64();
        }
        // Measured for a deadline's estimates only (counting the links reads every list).
        if self.setup.deadline.is_some() {
            let links = self.gather_links().max(1);
            self.log.pace.sweep_s_per_link = Some(sweep.elapsed().as_secs_f64() / links as f64);
        }
    }

    // ------------------------------------------------------------------------------------------
    // Read-only views
    // ------------------------------------------------------------------------------------------

    /// Statistics of the current state.
    #[must_use]
    pub fn stats(&self) -> HierarchicalStats {
        let mut s = self.log.stats.clone();
        s.elements = self.hier.len();
        s.leaves = self.hier.elements.iter().filter(|e| e.is_leaf()).count();
        s.links = self.graph.links.len();
        s.links_full = 0;
        s.links_partial = 0;
        s.links_none = 0;
        for l in self.graph.links.by_receiver.iter().flatten() {
            match l.class() {
                VisClass::Full => s.links_full += 1,
                VisClass::Partial => s.links_partial += 1,
                VisClass::None => s.links_none += 1,
            }
        }
        s.depth_histogram = self.hier.depth_histogram();
        s.bytes_per_link = std::mem::size_of::<Link>();
        s.bytes_per_element = std::mem::size_of::<Element>() + std::mem::size_of::<Vec<Link>>();
        s.memory_bytes =
            self.hier.elements.capacity() * std::mem::size_of::<Element>() + self.graph.links.memory_bytes();
        s.clusters = self.cluster.tree.as_ref().map_or(0, |t| t.len());
        s.cluster_links = self.cluster.links.len();
        s.memory_bytes += self.cluster.links.capacity() * std::mem::size_of::<ClusterLink>()
            + self.cluster.tree.as_ref().map_or(0, |t| t.len() * std::mem::size_of::<cluster::ClusterNode>());
        // A cluster link moves light both ways, as an element link and its mirror do.
        let all = s.links + 2 * s.cluster_links;
        s.links_per_element = if s.elements > 0 { all as f64 / s.elements as f64 } else { 0.0 };
        s
    }

    /// The solver's own a-posteriori error estimate of every element (see [`estimate`]).
    #[must_use]
    pub fn error_estimates(&self) -> Vec<f64> {
        estimate::error_estimates(self)
    }

    /// [`error_estimates`](Self::error_estimates), given up (None) as soon as `stop` is set
    /// (see [`estimate::error_estimates_until`]).
    #[must_use]
    pub fn error_estimates_until(&self, stop: &AtomicBool) -> Option<Vec<f64>> {
        estimate::error_estimates_until(self, stop)
    }

    /// A copy of the elements, links and statistics.
    #[must_use]
    pub fn snapshot(&self) -> Snapshot {
        self.snapshot_with(true)
    }

    /// [`HierarchicalSolver::snapshot`], with the error estimates (their cost is a good part of a
    /// solve's) or with every estimate 0 (the viewer's refinement replay records one per round).
    #[must_use]
    pub fn snapshot_with(&self, estimates: bool) -> Snapshot {
        let est = if estimates { self.error_estimates() } else { vec![0.0; self.hier.elements.len()] };
        let slopes = self.leaf_slopes();
        let elements = self
            .hier
            .elements
            .iter()
            .enumerate()
            .map(|(i, e)| ElementInfo {
                core: ElementCore {
                    id: i as u32,
                    patch: e.patch,
                    parent: e.parent(),
                    depth: e.depth,
                    vertices: e.verts,
                    n_vertices: e.n_verts,
                    area: e.area,
                    reflectance: e.reflectance,
                    emission: e.emission,
                    radiosity: e.radiosity,
                    error_estimate: est[i],
                },
                children: e.children(),
                gathered: e.gathered,
                stop: e.stop,
                slope: slopes.get(i).copied().flatten(),
            })
            .collect();
        let oracle = self.setup.params.oracle;
        let hier = &self.hier;
        let links = self
            .graph
            .links
            .by_receiver
            .iter()
            .enumerate()
            .flat_map(|(r, ls)| {
                ls.iter().map(move |l| LinkInfo {
                    receiver: r as u32,
                    source: l.source,
                    ff: l.ff,
                    vis: l.vis,
                    err: match oracle {
                        Oracle::Feps => l.fmax,
                        Oracle::Bf | Oracle::Error => {
                            l.bf_error(hier.get(l.source).radiosity.max_channel()) as f32
                        }
                    },
                })
            })
            .collect();
        let (clusters, patch_cluster) = self.cluster_infos();
        Snapshot {
            elements,
            links,
            clusters,
            patch_cluster,
            stats: self.stats(),
            residuals: self.log.residuals.clone(),
        }
    }

    /// Each leaf's slope of B, ρ times the irradiance's slope pushed down to it (`Chain`; with
    /// the rows closed, times the leaf's scale, as its irradiance is); empty without
    /// `push_slopes`, None for interior elements and flat leaves.
    fn leaf_slopes(&self) -> Vec<Option<crate::solver::Slope>> {
        if !self.setup.params.push_slopes {
            return Vec::new();
        }
        let scale = &self.closure.scale;
        self.hier
            .elements
            .iter()
            .zip(self.chains())
            .enumerate()
            .map(|(i, (e, own))| {
                let d = if scale.get(i).is_some() {
                    // The leaf's own links' gradient (tangent basis to world), scaled apart from
                    // the inherited rest.
                    let [su, sv] = e.gathered_slope;
                    let (t1, t2) = crate::math::orthonormal_basis(e.normal);
                    let mine = [su * t1.x + sv * t2.x, su * t1.y + sv * t2.y, su * t1.z + sv * t2.z];
                    [0, 1, 2].map(|k| e.reflectance.mul_rgb(leaf_irradiance(own.slope[k], mine[k], scale, i)))
                } else {
                    own.slope.map(|g| e.reflectance.mul_rgb(g))
                };
                (e.is_leaf() && d.iter().any(|g| *g != Rgb::ZERO))
                    .then_some(crate::solver::Slope { centroid: e.centroid, d })
            })
            .collect()
    }

    /// Every element's `Chain` (its own sums and those it inherits), by id: parents first.
    fn chains(&self) -> Vec<Chain> {
        let mut chain: Vec<Chain> = Vec::with_capacity(self.hier.len());
        for e in &self.hier.elements {
            let up = if e.parent == NONE { Chain::default() } else { chain[e.parent as usize] };
            chain.push(up.step(e, self.setup.params.push_slopes));
        }
        chain
    }

    /// The leaves as a [`Solution`] (with the solver's own error estimates).
    #[must_use]
    pub fn solution(&self) -> Solution {
        self.solution_with(true)
    }

    /// The leaves as a [`Solution`], with the solver's own error estimates only if `estimates`
    /// (they cost about as much as the solve itself on a refined scene).
    #[must_use]
    pub fn solution_with(&self, estimates: bool) -> Solution {
        let est = if estimates { Some(self.error_estimates()) } else { None };
        let slopes = self.leaf_slopes();
        let elements: Vec<SolvedElement> = self
            .hier
            .elements
            .iter()
            .enumerate()
            .filter(|(_, e)| e.is_leaf())
            .map(|(i, e)| SolvedElement {
                patch: e.patch as usize,
                vertices: e.vertices().to_vec(),
                area: e.area,
                radiosity: e.radiosity,
                error_estimate: est.as_ref().map(|v| v[i]),
                slope: slopes.get(i).copied().flatten(),
            })
            .collect();
        let patch_radiosity = Solution::patch_averages(self.setup.scene.patches.len(), &elements);
        let st = self.stats();
        let mut energy = self.log.energy;
        if !self.log.gathered_once {
            // Nothing gathered yet: all emitted power is still "in flight", nothing absorbed.
            energy.absorbed = Rgb::ZERO;
            energy.escaped = Rgb::ZERO;
        }
        Solution {
            method: "hierarchical".into(),
            patch_radiosity,
            energy,
            stats: SolveStats {
                patches: self.setup.scene.patches.len(),
                elements: elements.len(),
                links: st.links,
                iterations: st.iterations,
                rays: st.rays,
                time_s: PhaseTimes {
                    load: 0.0,
                    bvh: self.setup.bvh_s,
                    form_factors: st.refine_s,
                    solve: st.gather_s + st.push_pull_s,
                    total: self.setup.bvh_s + st.refine_s + st.gather_s + st.push_pull_s,
                },
                extra: serde_json::to_value(&st).ok(),
            },
            elements,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Patch;
    use refine::{coupling_in, new_link};

    /// The five-times rule's disk estimate against the exact coupling at five diameters or more
    /// (the lecture quotes the rule as good to about a percent; 3 % allows for off-axis pairs).
    const FIVE_TIMES_REL: f64 = 0.03;
    const ACC: transfer::Accuracy = transfer::Accuracy { tol: 1e-6, adaptive_tol: 1e-6, five_times: false };
    const ACC5: transfer::Accuracy = transfer::Accuracy { tol: 1e-6, adaptive_tol: 1e-6, five_times: true };

    fn square(c: DVec3, side: f64, up: bool) -> Patch {
        let h = side / 2.0;
        let mut v = vec![
            c + DVec3::new(-h, -h, 0.0),
            c + DVec3::new(h, -h, 0.0),
            c + DVec3::new(h, h, 0.0),
            c + DVec3::new(-h, h, 0.0),
        ];
        if !up {
            v.reverse();
        }
        Patch::new(v, Rgb::splat(0.5), Rgb::ZERO, "sq", 0, "sq", "m").expect("valid square")
    }

    /// A floor square facing up and a ceiling square facing down, `offset` apart in x, `height` apart in z.
    fn pair(side: f64, offset: f64, height: f64) -> Hierarchy {
        let floor = square(DVec3::ZERO, side, true);
        let ceil = square(DVec3::new(offset, 0.0, height), side, false);
        Hierarchy::from_scene(&Scene::new("t", "t", vec![floor, ceil]))
    }

    #[test]
    fn five_times_rule_is_close_far_away_and_unused_near() {
        for (offset, height) in [(0.0, 8.0), (3.0, 8.0), (6.0, 7.5), (0.0, 20.0)] {
            let h = pair(1.0, offset, height);
            let exact = coupling_in(&h, ACC, 0, 1, false);
            let rule = coupling_in(&h, ACC5, 0, 1, false);
            assert!(exact > 0.0);
            assert_ne!(rule, exact, "offset {offset} height {height}: the rule should apply");
            assert!((rule / exact - 1.0).abs() < FIVE_TIMES_REL, "offset {offset}: {rule} vs {exact}");
        }
        // Closer than five diameters (√2 for a unit square): the quadrature.
        for (offset, height) in [(0.0, 1.0), (2.0, 6.0)] {
            let h = pair(1.0, offset, height);
            assert_eq!(coupling_in(&h, ACC5, 0, 1, false), coupling_in(&h, ACC, 0, 1, false));
        }
        // Far but in the receiver's tangent plane: nothing.
        let h = pair(1.0, 40.0, 0.0);
        assert_eq!(coupling_in(&h, ACC5, 0, 1, false), 0.0);
    }

    /// A link and its mirror carry the same Galerkin coupling: A_p F_pq = A_q F_qp.
    #[test]
    fn links_are_reciprocal() {
        let h = pair(1.0, 0.4, 0.7);
        let g = coupling_in(&h, ACC, 0, 1, false);
        let (p, q) = (h.get(0), h.get(1));
        let pq = new_link((p, 0), (q, 1), g, 1.0, false, false);
        let qp = new_link((q, 1), (p, 0), g, 1.0, false, false);
        assert!((p.area * f64::from(pq.ff) - q.area * f64::from(qp.ff)).abs() < 1e-7 * g);
        // Equal areas and estimates: the tie-break splits the same element from both sides.
        assert_ne!(pq.split_source, qp.split_source);
    }
}
