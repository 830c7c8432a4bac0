//! Hierarchical radiosity [Hanrahan, Salzman, Aupperle 1991 (HSA91), "A Rapid Hierarchical
//! Radiosity Algorithm", SIGGRAPH '91]: quadtree elements, `Refine` with Feps/Aeps or a BF oracle,
//! links, recursive `Gather`, push-pull — O(n) interactions instead of n².
//!
//! ```text
//! B_p = E_p + ρ_p Σ_{links p←q on p and its ancestors} F_pq V_pq B_q
//! ```
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
//! `solve` runs the loop: refine, then `round_iterations` gathers (to convergence once a
//! refinement adds at most `settle` of the links, or in the last allowed round), until a
//! refinement of the converged solution adds at most `settle` of the links.
//! - **Refine** (the lecture's `Refine(p, q, Feps, Aeps)`): estimate F_pq and F_qp with the disk
//!   formula; if the oracle is satisfied, keep the link; else split the element with the larger
//!   estimate (F_pq > F_qp → split the source q) unless it is at the Aeps floor or the maximum
//!   depth, then keep the link (`split_fallback` splits the other one instead). Each link caches
//!   its estimates, split side and error bound when it is made (`Link`), so re-applying the
//!   oracle after a gather costs one multiply per link.
//! - **Oracles**: `Feps` (both estimates below Feps), and `Bf` (B · max(F_pq, F_qp) · error
//!   bound below BFeps, the SPLASH-2 criterion, with B the larger of the two elements' radiosity
//!   so that a link and its mirror get the same verdict; the bound is (diam_p + diam_q) /
//!   distance, at most 1, for fully visible links and 1 for partially visible ones, which use
//!   `partial_bf_factor` × BFeps: 1/4 in most presets, so shadow boundaries refine first; 1, as
//!   in the SPLASH-2 program, in `splash2`). Pairs whose planes cut each other ("straddling") are
//!   estimated with |cos|. With `conservative` (not in `splash2`), straddling pairs also take the
//!   exact point value at four interior points, and a partially visible link's B is the
//!   brightest leaf (B_avg · V_avg counts a hidden dark part twice).
//! - **Mirror links**: every decision is symmetric in the pair (the split side is the larger
//!   estimate's, ties broken by area, then id), so the links q ← p are the mirror images of the
//!   links p ← q at every level.
//! - **Link form factor** ([`transfer`]): the Galerkin (area-averaged) form factor F_pq = G / A_p
//!   of a coupling G = A_p F_pq = A_q F_qp computed once per pair (quadrature of the exact
//!   point-to-polygon kernel whose order grows as the pair gets closer); visibility V from
//!   stratified point pairs in the pair's canonical order (`visibility::visibility_sample`), so
//!   a link and its mirror carry the same F·V·A and what a source sends through a pair is what
//!   the receiver gathers: the power balance closes (`EnergyBalance`).
//! - **Push-pull with slopes** (`push_slopes`, all presets but `splash2`): a link r ← s also
//!   carries how its transfer F(x → s)·V varies across r (`Link::slope`, the least-squares
//!   gradient of the exact point kernel at r's four child points, limited so the transfer stays
//!   ≥ 0 over r), and its mirror's (`Link::src_slope`, across s). Push moves each ancestor's
//!   irradiance along its slope to the child's centroid instead of copying its average, and
//!   the gather adds, per link, the source's first moment of radiosity M_s = Σ_leaves A B
//!   (c − c_s) / A_s against the source-side slope (a coarse source sends what its bright and
//!   dark parts send):
//!   ```text
//!   H_leaf = Σ_{links a ← s, a = leaf or an ancestor} [ F_as V B_s + slope_as · (c_leaf − c_a)
//!            + (A_s / A_a) src_slope_as · M_s ]
//!   ```
//!   Both corrections integrate to zero over the element they act on (Σ_leaves A (c − c_a) = 0),
//!   so each link still moves exactly its G·V·B; what changes is *where* it lands and where it
//!   comes from. With constants, a leaf's row of form factors is its ancestors' averages, not
//!   its own (Σ F up to 1.18 in cube-one-light at `quality`), its radiosity follows that row,
//!   and the solve created light (escaped/emitted, cube-one-light `interactive` −2.9 %, the
//!   furnace at `lecture` −1.6 %; now −0.45 % and −0.08 %). The energy balance uses the same
//!   rows (`Chain::fv_slope`), so it closes. Leaves keep the slope for their reconstruction
//!   (`solver::Slope`): the pointwise ruler reads them linearly. Pointwise rel L2 at `quality`
//!   (cached references, 65 537 points): cornell 6.6 → 4.6 %, table-room 8.4 → 6.0 %,
//!   splash_room 6.6 → 5.4 %; at `interactive` 11.9 → 8.8 %, 8.9 → 6.2 %, 18.5 → 15.8 %.
//! - **Zero estimates**: a link the oracle would split at any visibility but 0 is refined unless
//!   its estimate is 0, so an accepted noisy zero keeps only P(estimate > 0) · V of its light,
//!   again at every level below. Such zeros are re-tested with `zero_confirm` × rays more rays
//!   (the first that passes settles the split). Measured on splash_room (preset `splash2`,
//!   4 rays): without the test the floor came out 14 % and the whole room 2.6 % darker than the
//!   reference, with 1 ray 40 % darker; with 2 × 4 more rays the floor is 2 % dark at
//!   `partial_bf_factor` 1/4, 4 % at 1 (the preset's). Symmetrically, with `conservative`, an
//!   all-visible estimate of a link split only when partial (and of an input patch pair) is
//!   confirmed with more rays, a blocked one making it partial: accepted false ones made
//!   splash_room's floor gather 11 % too much (escaped/emitted at `interactive` −11 % → +0.1 %).
//! - **No per-leaf normalisation**: until session 9 an option scaled each leaf's inherited
//!   irradiance so that its total form factor matched the point kernel at its centroid. It made
//!   the white furnace exact with centroid links, but one scalar per leaf mixes sources of
//!   different radiosity (Cornell's floor came out 15 % dark, tests/hierarchical.rs
//!   `direct_light_is_not_biased_by_inherited_links`), and with Galerkin links it no longer
//!   applies. Issue 15 §2 asked to remove it unless unbiased on cornell: removed. The furnace is
//!   exact with the error oracle, which does not refine it ([`oracle`]).
//! - **Parallel and deterministic**: element ids are assigned serially in sorted order, visibility
//!   jitter is keyed by the (receiver, source) ids, and parallel results are collected in order,
//!   so every count and value is identical for any thread count.
//!
//! Restarting with new parameters (`set_params`) reuses the BVH and, when `rays` and `seed` are
//! unchanged, the visibility of the initial patch pairs; elements and links are rebuilt.

pub mod cluster;
pub mod estimate;
mod oracle;
mod transfer;

use super::params::{HierarchicalParams, Oracle};
use crate::accel::{Accel, NO_HIT};
use crate::form_factor;
use crate::hierarchy::{Element, Hierarchy, NONE, StopReason};
use crate::link::{Link, LinkStore, VisClass};
use crate::math::{DVec3, Rgb, newell_normal, splitmix64};
use crate::scene::Scene;
use crate::solver::{EnergyBalance, PhaseTimes, Progress, Solution, SolveStats, SolvedElement};
use crate::visibility::{self, Stop};
use cluster::{ClusterLink, ClusterTransfer, ClusterTree, Pairing};
use rayon::prelude::*;
use serde::Serialize;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

pub use crate::hierarchy::StopReason as ElementStopReason;

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
    /// Input patch pairs left unlinked because they face away or are fully occluded.
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
}

/// Read-only view of one element.
#[derive(Clone, Debug, Serialize)]
pub struct ElementInfo {
    pub id: u32,
    pub patch: u32,
    pub parent: Option<u32>,
    pub children: Option<[u32; 4]>,
    pub depth: u8,
    pub vertices: [DVec3; 4],
    pub n_vertices: u8,
    pub area: f64,
    pub reflectance: Rgb,
    pub emission: Rgb,
    pub radiosity: Rgb,
    pub gathered: Rgb,
    pub error_estimate: f64,
    pub stop: StopReason,
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

/// Cached initial links: ((rays, seed, conservative), links per root receiver, pairs skipped).
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

/// Every receiver's links with F·V > 0, flattened for gathering (links do not change between
/// refinements): source (high bit set when fully visible) and weight F·V, in list order.
#[derive(Debug, Default)]
struct GatherPlan {
    /// Receiver r's links are `start[r]..start[r + 1]`.
    start: Vec<u32>,
    source: Vec<u32>,
    weight: Vec<f64>,
    /// Each link's `slope` (empty when slopes are not pushed).
    slope: Vec<[f32; 2]>,
    /// Each link's moment weight (A_source / A_receiver)·`src_slope` (empty likewise).
    moment: Vec<[f32; 2]>,
}

const FULL_BIT: u32 = 1 << 31;

/// Receivers per block when the gather plan is built in parallel.
const PLAN_BLOCK: usize = 256;

impl GatherPlan {
    /// Rebuild the plan from `links`, reusing its buffers. Built in parallel over blocks of
    /// receivers (counts, prefix sums, then each block fills its own range): the same arrays
    /// as a serial pass in receiver order.
    fn rebuild(&mut self, links: &LinkStore, slopes: Option<&Hierarchy>) {
        let lists = &links.by_receiver;
        let weight = |l: &Link| f64::from(l.ff) * f64::from(l.vis);
        self.start.clear();
        self.start.par_extend(
            lists
                .par_iter()
                .with_min_len(PLAN_BLOCK)
                .map(|ls| ls.iter().filter(|l| weight(l) > 0.0).count() as u32),
        );
        let mut total = 0u32;
        for c in &mut self.start {
            (*c, total) = (total, total + *c);
        }
        self.start.push(total);
        self.source.resize(total as usize, 0);
        self.weight.resize(total as usize, 0.0);
        let n_slopes = if slopes.is_some() { total as usize } else { 0 };
        self.slope.clear();
        self.slope.resize(n_slopes, [0.0; 2]);
        self.moment.clear();
        self.moment.resize(n_slopes, [0.0; 2]);
        // Disjoint output ranges, one per block of receivers.
        let (mut source, mut weights) = (&mut self.source[..], &mut self.weight[..]);
        let (mut slope, mut moment) = (&mut self.slope[..], &mut self.moment[..]);
        let mut blocks = Vec::with_capacity(lists.len().div_ceil(PLAN_BLOCK));
        for (k, block) in lists.chunks(PLAN_BLOCK).enumerate() {
            let first = k * PLAN_BLOCK;
            let len = (self.start[first + block.len()] - self.start[first]) as usize;
            let len_s = if slopes.is_some() { len } else { 0 };
            let (s, s_rest) = std::mem::take(&mut source).split_at_mut(len);
            let (w, w_rest) = std::mem::take(&mut weights).split_at_mut(len);
            let (g, g_rest) = std::mem::take(&mut slope).split_at_mut(len_s);
            let (m, m_rest) = std::mem::take(&mut moment).split_at_mut(len_s);
            (source, weights, slope, moment) = (s_rest, w_rest, g_rest, m_rest);
            blocks.push((first, block, s, w, g, m));
        }
        blocks.into_par_iter().for_each(|(first, block, s, w, g, m)| {
            let mut i = 0;
            for (r, l) in block.iter().enumerate().flat_map(|(k, ls)| ls.iter().map(move |l| (first + k, l)))
            {
                let wl = weight(l);
                if wl > 0.0 {
                    debug_assert!(l.source < FULL_BIT, "element ids stay below 2^31");
                    s[i] = l.source | if l.vis >= 1.0 { FULL_BIT } else { 0 };
                    w[i] = wl;
                    if let Some(hier) = slopes {
                        debug_assert!(l.slope_set, "slopes are filled before the plan");
                        g[i] = l.slope;
                        let ratio = hier.get(l.source).area / hier.get(r as u32).area;
                        m[i] = l.src_slope.map(|x| (f64::from(x) * ratio) as f32);
                    }
                    i += 1;
                }
            }
            debug_assert_eq!(i, s.len(), "counted and filled alike");
        });
    }

    /// (Σ F·V·B + moment terms over receiver `r`'s links, the same over the fully visible ones
    /// without moments, Σ slope·B), in list order, with source radiosities `b` and the sources'
    /// radiosity moments `mu` (in each source's tangent basis; empty: none).
    fn gather(&self, r: usize, b: impl Fn(u32) -> Rgb, mu: &[[Rgb; 2]]) -> (Rgb, Rgb, [Rgb; 2]) {
        let (lo, hi) = (self.start[r] as usize, self.start[r + 1] as usize);
        let mut g = Rgb::ZERO;
        let mut full = Rgb::ZERO;
        let mut slope = [Rgb::ZERO; 2];
        for (&s, &w) in self.source[lo..hi].iter().zip(&self.weight[lo..hi]) {
            let t = b(s & !FULL_BIT) * w;
            g += t;
            if s & FULL_BIT != 0 {
                full += t;
            }
        }
        if !self.slope.is_empty() {
            for (&s, &[gu, gv]) in self.source[lo..hi].iter().zip(&self.slope[lo..hi]) {
                let bs = b(s & !FULL_BIT);
                slope[0] += bs * f64::from(gu);
                slope[1] += bs * f64::from(gv);
            }
            if !mu.is_empty() {
                for (&s, &[mu_w, mv_w]) in self.source[lo..hi].iter().zip(&self.moment[lo..hi]) {
                    // Elements made since the last push-pull have no moment yet (none: 0).
                    if let Some(&[mu_u, mu_v]) = mu.get((s & !FULL_BIT) as usize) {
                        g += mu_u * f64::from(mu_w) + mu_v * f64::from(mv_w);
                    }
                }
            }
        }
        (g, full, slope)
    }
}

/// A solve gathers on until its power balance closes to this (`EnergyBalance::relative_residual`;
/// issue 15 §2 asks for 1e-3 at every preset).
pub const ENERGY_TOLERANCE: f64 = 1e-3;

/// V of a link the next refinement pass replaces whatever its V (one ray found it positive):
/// above 1, so "fully visible" for the oracle, and never read otherwise (see `make_link`).
const UNMEASURED_VIS: f32 = 2.0;

/// An [`IdSet`] holding at least 1/this of the ids up to its largest is read off its marks.
const DENSE_ID_SET: usize = 16;

/// A set of element ids, read back in ascending order (marks instead of sorting duplicates).
#[derive(Default)]
struct IdSet {
    mark: Vec<bool>,
    ids: Vec<u32>,
}

impl IdSet {
    fn insert(&mut self, id: u32) {
        let i = id as usize;
        if i >= self.mark.len() {
            self.mark.resize(i + 1, false);
        }
        if !self.mark[i] {
            self.mark[i] = true;
            self.ids.push(id);
        }
    }

    fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// The ids, ascending; the set is left empty. A dense set is read off its marks (one pass,
    /// no sort).
    fn take_sorted(&mut self) -> Vec<u32> {
        let mut ids = std::mem::take(&mut self.ids);
        if ids.len() >= self.mark.len() / DENSE_ID_SET {
            ids.clear();
            for (i, m) in self.mark.iter_mut().enumerate() {
                if *m {
                    *m = false;
                    ids.push(i as u32);
                }
            }
        } else {
            for &i in &ids {
                self.mark[i as usize] = false;
            }
            ids.sort_unstable();
        }
        ids
    }
}

/// A receiver with at least this many links to split computes their replacements in parallel.
const PARALLEL_SPLITS: usize = 32;

type InitialLinks = ((u32, u64, bool, bool), Vec<Vec<Link>>, usize);

/// Initial linking of one patch p: (q, link p←q, link q←p) for q > p, pairs skipped, rays cast.
/// What `install_pairings` makes of one pairing: a cluster link, or a patch pair's two links
/// (none when the pair is skipped), and the rays cast.
type Made = (Option<ClusterLink>, Option<(u32, u32, Link, Link)>, u64);
type PairRow = (Vec<(u32, Link, Link)>, usize, u64);

/// What `replace_links` made for one receiver.
struct Replaced {
    receiver: u32,
    /// Its new own list, and the next pass's verdict on the new links in it.
    own: Vec<Link>,
    own_verdict: Verdict,
    /// Links pushed down to its children (child k, id `first_child + k`, gets `kids[k]`, in
    /// the order of the split links in the receiver's list), and the verdicts on them.
    kids: [Vec<Link>; 4],
    kid_verdicts: [Verdict; 4],
    first_child: u32,
    rays: u64,
    /// The own list gained links (a source was split).
    own_changed: bool,
    created: usize,
}

/// The oracle's verdict on some new links of one list, made when they were created (its
/// inputs do not change during a refinement): the strongest reason among the kept ones, and
/// the ones to split (index in the list, which side).
#[derive(Default)]
struct Verdict {
    reason: StopReason,
    splits: Vec<(u32, Split)>,
}

impl Verdict {
    /// Record link `index`'s verdict.
    fn note(&mut self, index: usize, v: Decision) {
        match v {
            Ok(side) => self.splits.push((index as u32, side)),
            Err(why) => self.keep(why),
        }
    }

    /// Record a kept link's reason (the strongest one stands).
    fn keep(&mut self, why: StopReason) {
        if why.rank() > self.reason.rank() {
            self.reason = why;
        }
    }

    /// Add the verdict on links that follow this verdict's in the same list.
    fn absorb(&mut self, mut later: Verdict) {
        self.keep(later.reason);
        self.splits.append(&mut later.splits);
    }
}

/// What refinement does with one link.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
enum Split {
    Source,
    Receiver,
}

/// The oracle's decision on one link: `Ok(side to split)` or `Err(why it is kept)`.
type Decision = Result<Split, StopReason>;

/// The replacement links of one split link (in child order) with their verdicts, and the rays
/// cast for them.
type NewLinks = ([Option<(Link, Decision)>; 4], u64);

/// One receiver's verdict in pass A.
type ReceiverDecision = (u32, Verdict);

/// The HSA91 solver with a step API.
pub struct HierarchicalSolver {
    scene: Arc<Scene>,
    accel: Arc<Accel>,
    params: HierarchicalParams,
    aeps: f64,
    /// BFeps in units of B (resolved from a relative setting).
    bf_eps: f64,
    hier: Hierarchy,
    links: LinkStore,
    linked: bool,
    /// Initial links of the input patch pairs, reusable while `rays` and `seed` are unchanged.
    initial_cache: Option<InitialLinks>,
    stats: HierarchicalStats,
    residuals: Vec<f64>,
    converged: bool,
    cancel: Arc<AtomicBool>,
    bvh_s: f64,
    energy: EnergyBalance,
    gathered_once: bool,
    /// Scratch for `push_pull_flat`.
    chain: Vec<Chain>,
    /// The same without slopes.
    flat_chain: Vec<FlatChain>,
    /// Scratch for Jacobi gathers: every element's radiosity before the gather (kept between
    /// gathers, so no large allocation per iteration).
    b_prev: Vec<Rgb>,
    /// Each element's first moment of radiosity about its centroid, Σ_leaves A B (c − c_e) / A_e,
    /// in its tangent basis (u, v), from the last push-pull (empty without `push_slopes`).
    moment: Vec<[Rgb; 2]>,
    /// Scratch: the same moments in world coordinates (x, y, z), while pulling.
    moment_world: Vec<[Rgb; 3]>,
    /// The links flattened for gathering (buffers kept between rebuilds).
    gather_plan: GatherPlan,
    /// `gather_plan` matches the current links (cleared when links change).
    plan_valid: bool,
    /// The oracle's compact copy of every element's (b_max, max channel of B) during
    /// refinement; cleared afterwards, as B changes.
    oracle_b: Vec<[f64; 2]>,
    /// Stop casting a new link's rays once they settle what the next refinement pass does
    /// with it (on by default; off only to check that it changes nothing).
    early_exit: bool,
    /// Recompute the error oracle's whole field every pass instead of updating it (off; only to
    /// check that the update changes nothing).
    full_error_passes: bool,
    /// The new pairs of the current refinement pass (see `make_link`).
    pair_memo: PairMemo,
    /// The cluster tree above the input patches (built at the first linking, when
    /// `params.cluster` applies; [`cluster`]).
    clusters: Option<Arc<ClusterTree>>,
    /// Links with a cluster at one end at least.
    cluster_links: Vec<ClusterLink>,
    /// Scratch of the cluster transfer.
    cluster_xfer: ClusterTransfer,
    /// Each input patch's Σ F·V through cluster links (its energy row's share).
    cluster_fv: Vec<f64>,
}

/// What a new pair's links share, both directions alike: the Galerkin coupling (NaN when not
/// yet computed, for a link the next pass replaces), the visibility estimate, whether it is
/// only the early-exit placeholder, and the rays it cost.
#[derive(Copy, Clone, Debug)]
struct PairOutcome {
    g: f64,
    vis: f32,
    unmeasured: bool,
    rays: u64,
}

/// Shards of the per-pass memo of new pairs: a split pair is replaced in both receivers' lists
/// in the same pass (the verdicts are symmetric), and the second receiver reuses the first one's
/// coupling and visibility instead of computing them again.
struct PairMemo(Vec<std::sync::Mutex<PairMap>>);

/// A memo shard: pair keys are already well mixed (`pair_key` packs two ids; the hasher mixes
/// them once with splitmix64 instead of SipHash, a third of the memo's cost).
type PairMap = std::collections::HashMap<u64, PairOutcome, std::hash::BuildHasherDefault<KeyHasher>>;

/// splitmix64 of a `u64` key (see `PairMap`).
#[derive(Default)]
struct KeyHasher(u64);

impl std::hash::Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = splitmix64(self.0 ^ u64::from(b));
        }
    }
    fn write_u64(&mut self, k: u64) {
        self.0 = splitmix64(self.0 ^ k);
    }
}

impl Default for PairMemo {
    fn default() -> Self {
        PairMemo((0..64).map(|_| std::sync::Mutex::default()).collect())
    }
}

impl PairMemo {
    fn shard(&self, key: u64) -> std::sync::MutexGuard<'_, PairMap> {
        let i = ((key ^ (key >> 32)) % self.0.len() as u64) as usize;
        self.0[i].lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }
    fn get(&self, key: u64) -> Option<PairOutcome> {
        self.shard(key).get(&key).copied()
    }
    fn put(&self, key: u64, out: PairOutcome) {
        self.shard(key).insert(key, out);
    }
    fn clear(&mut self) {
        for s in &mut self.0 {
            s.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner).clear();
        }
    }
}

/// Sums an element inherits in push-pull, its own included.
#[derive(Copy, Clone, Debug, Default)]
struct Chain {
    /// Irradiance through fully visible links, at `at`.
    full: Rgb,
    /// The other irradiance, at `at` (with the slopes' shift to `at`).
    rest: Rgb,
    /// World gradient of the irradiance (x, y, z components, each per channel).
    slope: [Rgb; 3],
    /// The point the sums are evaluated at: the centroid of the chain's last element.
    at: DVec3,
    f: f64,
    fv_partial: f64,
    /// World gradient of the row Σ F·V (the own links' `fv_slope`s), and the inherited rows'
    /// shift along it to `at` (included in the energy balance's Σ F·V).
    fv_slope: DVec3,
    fv_shift: f64,
}

impl Chain {
    /// `then` without slopes (`push_slopes` off: SPLASH-2's constants), at the cost it had
    /// before slopes existed.
    fn then_flat(self, e: &Element) -> Chain {
        Chain {
            full: self.full + e.gathered_full,
            rest: self.rest + (e.gathered - e.gathered_full),
            f: self.f + e.f_sum,
            fv_partial: self.fv_partial + e.fv_partial,
            ..Chain::default()
        }
    }

    /// `then` or `then_flat`.
    fn step(self, e: &Element, slopes: bool) -> Chain {
        if slopes { self.then(e) } else { self.then_flat(e) }
    }

    /// The sums of element `e`, whose parent's are `self`: the inherited irradiance moved along
    /// its slope from the parent's centroid to e's, plus e's own.
    fn then(self, e: &Element) -> Chain {
        let d = e.centroid - self.at;
        let shift = self.slope[0] * d.x + self.slope[1] * d.y + self.slope[2] * d.z;
        let [su, sv] = e.gathered_slope;
        let [fu, fv] = e.fv_slope;
        let (t1, t2) = if su == Rgb::ZERO && sv == Rgb::ZERO && fu == 0.0 && fv == 0.0 {
            (DVec3::ZERO, DVec3::ZERO)
        } else {
            crate::math::orthonormal_basis(e.normal)
        };
        Chain {
            full: self.full + e.gathered_full,
            rest: self.rest + shift + (e.gathered - e.gathered_full),
            slope: [
                self.slope[0] + su * t1.x + sv * t2.x,
                self.slope[1] + su * t1.y + sv * t2.y,
                self.slope[2] + su * t1.z + sv * t2.z,
            ],
            at: e.centroid,
            f: self.f + e.f_sum,
            fv_partial: self.fv_partial + e.fv_partial,
            fv_slope: self.fv_slope + t1 * fu + t2 * fv,
            fv_shift: self.fv_shift + self.fv_slope.dot(d),
        }
    }
}

/// What push-pull carries down a chain of ancestors: [`Chain`] with slopes, [`FlatChain`]
/// without (`push_slopes` off: a quarter of the bytes written per element, which is what
/// SPLASH-2's push-pull costs).
trait Sums: Copy + Default {
    /// The sums of element `e`, whose parent's are `self`.
    fn down(self, e: &Element) -> Self;
    /// The irradiance at the element (full + rest).
    fn irradiance(&self) -> Rgb;
    /// Σ F·V inherited from the ancestors (full F plus partial F·V).
    fn inherited_fv(&self) -> f64;
    /// The slopes' shift of the inherited row to the element's centroid.
    fn fv_shift(&self) -> f64;
}

impl Sums for Chain {
    fn down(self, e: &Element) -> Self {
        self.then(e)
    }
    fn irradiance(&self) -> Rgb {
        self.full + self.rest
    }
    fn inherited_fv(&self) -> f64 {
        self.f + self.fv_partial
    }
    fn fv_shift(&self) -> f64 {
        self.fv_shift
    }
}

/// [`Chain`] without slopes.
#[derive(Copy, Clone, Debug, Default)]
struct FlatChain {
    full: Rgb,
    rest: Rgb,
    f: f64,
    fv_partial: f64,
}

impl Sums for FlatChain {
    fn down(self, e: &Element) -> Self {
        FlatChain {
            full: self.full + e.gathered_full,
            rest: self.rest + (e.gathered - e.gathered_full),
            f: self.f + e.f_sum,
            fv_partial: self.fv_partial + e.fv_partial,
        }
    }
    fn irradiance(&self) -> Rgb {
        self.full + self.rest
    }
    fn inherited_fv(&self) -> f64 {
        self.f + self.fv_partial
    }
    fn fv_shift(&self) -> f64 {
        0.0
    }
}

/// The down sweep of push-pull over the whole forest (parents before children): each
/// element's sums from its parent's; each leaf's radiosity B = E + ρ·H and, with `energy`, its
/// absorbed and escaped power. Returns (largest leaf change against `before` or the old value,
/// largest reflected radiosity, absorbed, escaped).
fn push_down<S: Sums>(
    els: &mut [Element],
    chain: &mut Vec<S>,
    before: Option<&[Rgb]>,
    energy: bool,
) -> (f64, f64, Rgb, Rgb) {
    let mut max_change: f64 = 0.0;
    let mut max_reflected: f64 = 0.0;
    let mut absorbed = Rgb::ZERO;
    let mut escaped = Rgb::ZERO;
    chain.clear();
    chain.reserve(els.len());
    for (i, e) in els.iter_mut().enumerate() {
        let up = if e.parent == NONE { S::default() } else { chain[e.parent as usize] };
        let own = up.down(e);
        chain.push(own);
        if e.is_leaf() {
            let h = own.irradiance();
            let b = e.emission + e.reflectance.mul_rgb(h);
            let old = before.and_then(|v| v.get(i).copied()).unwrap_or(e.radiosity);
            max_change = max_change.max(b.abs_diff_max(old));
            max_reflected = max_reflected.max((b - e.emission).max_channel());
            if energy {
                absorbed += (Rgb::ONE - e.reflectance).mul_rgb(h) * e.area;
                let fv = up.inherited_fv() + e.fv_sum + own.fv_shift();
                escaped += b * (e.area * (1.0 - fv));
            }
            e.radiosity = b;
            e.b_max = b.max_channel();
        }
    }
    (max_change, max_reflected, absorbed, escaped)
}

/// The absorbed and escaped power of the elements as they are (see `energy_pass`).
fn energy_sums<S: Sums>(els: &[Element], chain: &mut Vec<S>) -> (Rgb, Rgb) {
    let mut absorbed = Rgb::ZERO;
    let mut escaped = Rgb::ZERO;
    chain.clear();
    chain.reserve(els.len());
    for e in els {
        let up = if e.parent == NONE { S::default() } else { chain[e.parent as usize] };
        let own = up.down(e);
        chain.push(own);
        if e.is_leaf() {
            let h = own.irradiance();
            absorbed += (Rgb::ONE - e.reflectance).mul_rgb(h) * e.area;
            let fv = up.inherited_fv() + e.fv_sum + own.fv_shift();
            escaped += e.radiosity * (e.area * (1.0 - fv));
        }
    }
    (absorbed, escaped)
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
        let links = LinkStore::new(hier.len());
        let aeps = params.aeps.resolve(scene.total_area());
        let bf_eps = resolve_bf_eps(&params, &scene);
        let mut s = HierarchicalSolver {
            scene,
            accel,
            params,
            aeps,
            bf_eps,
            hier,
            links,
            linked: false,
            initial_cache: None,
            stats: HierarchicalStats::default(),
            residuals: Vec::new(),
            converged: false,
            cancel: Arc::new(AtomicBool::new(false)),
            bvh_s,
            energy: EnergyBalance::default(),
            gathered_once: false,
            chain: Vec::new(),
            flat_chain: Vec::new(),
            b_prev: Vec::new(),
            moment: Vec::new(),
            moment_world: Vec::new(),
            gather_plan: GatherPlan::default(),
            plan_valid: false,
            oracle_b: Vec::new(),
            early_exit: true,
            full_error_passes: false,
            pair_memo: PairMemo::default(),
            clusters: None,
            cluster_links: Vec::new(),
            cluster_xfer: ClusterTransfer::default(),
            cluster_fv: Vec::new(),
        };
        s.energy.emitted = s.scene.emitted_power();
        s
    }

    /// Turn off (or on) the early exits of link visibility (see `make_link`). They cast fewer
    /// rays and leave every result the same; turning them off is for checking exactly that.
    pub fn set_early_exit(&mut self, on: bool) {
        self.early_exit = on;
    }

    /// Recompute the error oracle's field for every element in every refinement pass (`true`)
    /// instead of only where links changed. The results are identical; for checking exactly that.
    pub fn set_full_error_passes(&mut self, on: bool) {
        self.full_error_passes = on;
    }

    #[must_use]
    pub fn scene(&self) -> &Arc<Scene> {
        &self.scene
    }
    #[must_use]
    pub fn params(&self) -> HierarchicalParams {
        self.params
    }
    #[must_use]
    pub fn hierarchy(&self) -> &Hierarchy {
        &self.hier
    }
    #[must_use]
    pub fn links(&self) -> &LinkStore {
        &self.links
    }
    #[must_use]
    pub fn accel(&self) -> &Arc<Accel> {
        &self.accel
    }

    /// Restart with new parameters. Reuses the BVH, and the initial patch-pair links when `rays`,
    /// `seed` and `conservative` did not change.
    pub fn set_params(&mut self, p: HierarchicalParams) -> Result<(), String> {
        p.validate()?;
        self.params = p;
        self.aeps = p.aeps.resolve(self.scene.total_area());
        self.bf_eps = resolve_bf_eps(&p, &self.scene);
        self.reset();
        Ok(())
    }

    /// Back to one element per patch, no links, B = E.
    pub fn reset(&mut self) {
        self.hier = Hierarchy::from_scene(&self.scene);
        self.links = LinkStore::new(self.hier.len());
        self.plan_valid = false;
        self.moment.clear();
        self.cluster_links.clear();
        self.cluster_fv.clear();
        self.linked = false;
        self.stats = HierarchicalStats::default();
        self.residuals.clear();
        self.converged = false;
        self.gathered_once = false;
        self.energy = EnergyBalance { emitted: self.scene.emitted_power(), ..Default::default() };
        self.cancel.store(false, Ordering::Relaxed);
    }

    /// Set the returned flag to make a running step return early (`StepReport::cancelled`).
    /// The state stays consistent: refinement stops between passes, gathering between iterations.
    #[must_use]
    pub fn cancel_handle(&self) -> Arc<AtomicBool> {
        Arc::clone(&self.cancel)
    }

    fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }

    #[must_use]
    pub fn is_converged(&self) -> bool {
        self.converged
    }

    fn report(&self, kind: StepKind, t: Instant, refined: usize, new_links: usize) -> StepReport {
        StepReport {
            kind,
            time_s: t.elapsed().as_secs_f64(),
            refined,
            new_links,
            residual: self.residuals.last().copied().unwrap_or(0.0),
            converged: self.converged,
            cancelled: self.cancelled(),
        }
    }

    // ------------------------------------------------------------------------------------------
    // Refinement
    // ------------------------------------------------------------------------------------------

    /// One refinement pass: on the first call, link every mutually visible pair of input
    /// patches; then apply the oracle to every link until nothing splits.
    pub fn refine_step(&mut self) -> StepReport {
        self.cancel.store(false, Ordering::Relaxed);
        self.refine_inner()
    }

    fn refine_inner(&mut self) -> StepReport {
        let t = Instant::now();
        let mut new_links = 0;
        if self.params.oracle == Oracle::Error && self.params.bf_relative {
            self.bf_eps = self.error_eps();
        }
        self.oracle_b.clear();
        self.sync_oracle_b();
        self.plan_valid = false;
        let mut changed = IdSet::default();
        if !self.linked {
            new_links += if self.clustering() { self.cluster_linking() } else { self.initial_linking() };
            self.linked = true;
            for r in 0..self.hier.roots as u32 {
                changed.insert(r);
            }
        } else if !self.cluster_links.is_empty() {
            let (created, touched) = self.cluster_refine();
            new_links += created;
            if touched {
                for r in 0..self.hier.roots as u32 {
                    changed.insert(r);
                }
            }
        }
        self.stats.refine_initial_s += t.elapsed().as_secs_f64();
        let mut refined = 0;
        let mut total_links = self.links.len();
        let mut kept_reason: Vec<StopReason> = Vec::new();
        // The verdicts on the links made by the last pass (None: the first pass, which examines
        // every link, as B has changed since the last refinement).
        let mut pending: Option<Vec<ReceiverDecision>> = None;
        // The error oracle's field, kept up to date pass by pass (`update_error_field`), and the
        // receivers whose link lists the last pass changed.
        let mut err_field: Option<oracle::ErrorField> = None;
        let mut pass_changed: Vec<u32> = Vec::new();
        let track = self.params.oracle == Oracle::Error;
        while !self.cancelled() {
            if total_links >= self.params.max_links {
                self.stats.budget_hit = true;
                break;
            }
            // A: decide, in parallel, read-only (from each link's cached geometry); later passes
            // take the verdicts made with the links.
            let phase = Instant::now();
            // The error oracle examines, after its first pass, the links of the receivers whose
            // error the last pass changed (their own or an ancestor's links changed) and their
            // mirrors; the other oracles take the verdicts made with the new links.
            let decisions: Vec<ReceiverDecision> = if self.params.oracle == Oracle::Error {
                let ids: Vec<u32> = match err_field.as_mut() {
                    Some(f) if !self.full_error_passes => self.update_error_field(f, &pass_changed),
                    _ => {
                        err_field = Some(self.error_field());
                        (0..self.hier.len() as u32).collect()
                    }
                };
                let field = err_field.as_ref();
                ids.into_par_iter()
                    .filter(|&r| !self.links.by_receiver[r as usize].is_empty())
                    .map(|r| self.decide_receiver(r, field))
                    .collect()
            } else {
                match pending.take() {
                    Some(d) => d,
                    None => (0..self.hier.len() as u32)
                        .into_par_iter()
                        .filter(|&r| !self.links.by_receiver[r as usize].is_empty())
                        .map(|r| self.decide_receiver(r, None))
                        .collect(),
                }
            };
            pass_changed.clear();
            self.stats.refine_passes += 1;
            self.stats.refine_decided += decisions.len();
            if decisions.is_empty() {
                break;
            }
            kept_reason.resize(self.hier.len(), StopReason::Unrefined);
            let mut to_split = IdSet::default();
            for (r, Verdict { reason, splits }) in &decisions {
                for &(i, side) in splits {
                    to_split.insert(match side {
                        Split::Source => self.links.by_receiver[*r as usize][i as usize].source,
                        Split::Receiver => *r,
                    });
                }
                // The strongest reason over all the links the receiver keeps, examined now or
                // in an earlier pass.
                // (Written to the leaves once, after the last pass.)
                let kept = &mut kept_reason[*r as usize];
                if reason.rank() > kept.rank() {
                    *kept = *reason;
                }
            }
            self.stats.refine_decide_s += phase.elapsed().as_secs_f64();
            if to_split.is_empty() {
                break;
            }
            let phase = Instant::now();
            // B: split, in id order (children computed in parallel).
            refined += self.hier.split_many(&to_split.take_sorted());
            self.links.grow(self.hier.len());
            self.sync_oracle_b();
            self.stats.refine_split_s += phase.elapsed().as_secs_f64();
            let phase = Instant::now();
            // C: replacement links, in parallel.
            let work: Vec<ReceiverDecision> =
                decisions.into_iter().filter(|(_, v)| !v.splits.is_empty()).collect();
            let results: Vec<Replaced> =
                work.par_iter().map(|(r, v)| self.replace_links(*r, &v.splits)).collect();
            self.pair_memo.clear();
            self.stats.refine_links_s += phase.elapsed().as_secs_f64();
            let phase = Instant::now();
            // D: install, in receiver order: every receiver's own list first, then the links
            // pushed down to children (a child may itself have been a receiver in this pass).
            // The next pass examines exactly the new links, by their verdicts.
            let mut next: Vec<ReceiverDecision> = Vec::new();
            let mut pushed_down = Vec::new();
            let mut owns = Vec::with_capacity(results.len());
            for rep in results {
                let r = rep.receiver;
                self.stats.rays += rep.rays;
                if rep.own_changed {
                    next.push((r, rep.own_verdict));
                }
                new_links += rep.created;
                let pushed: usize = rep.kids.iter().map(Vec::len).sum();
                total_links = total_links + rep.own.len() + pushed - self.links.by_receiver[r as usize].len();
                changed.insert(r);
                if track {
                    pass_changed.push(r);
                }
                owns.push((r, rep.own));
                if pushed > 0 {
                    let first = rep.first_child;
                    for (k, (ls, v)) in rep.kids.into_iter().zip(rep.kid_verdicts).enumerate() {
                        if !ls.is_empty() {
                            pushed_down.push((first + k as u32, ls, v));
                        }
                    }
                }
            }
            // The new own lists replace the old ones in parallel (freeing them is most of it).
            let slots = disjoint_mut(&mut self.links.by_receiver, owns.iter().map(|o| o.0));
            slots.into_par_iter().zip(owns).with_min_len(64).for_each(|(slot, (_, own))| *slot = own);
            for (c, ls, mut v) in pushed_down {
                if track {
                    pass_changed.push(c);
                }
                let list = &mut self.links.by_receiver[c as usize];
                // The child's list may hold links already (its own, just replaced, or earlier ones).
                let offset = list.len() as u32;
                if list.is_empty() {
                    *list = ls;
                } else {
                    list.extend(ls);
                }
                for (i, _) in &mut v.splits {
                    *i += offset;
                }
                next.push((c, v));
                changed.insert(c);
            }
            // In receiver order; a child that was a receiver in this pass too has its own list's
            // verdict first (lower indices), then its parent's pushed links'.
            next.sort_by_key(|d| d.0);
            next.dedup_by(|later, first| {
                let same = later.0 == first.0;
                if same {
                    first.1.absorb(std::mem::take(&mut later.1));
                }
                same
            });
            pending = (self.params.oracle != Oracle::Error).then_some(next);
            self.stats.refine_install_s += phase.elapsed().as_secs_f64();
        }
        if self.stats.budget_hit || self.cancelled() {
            self.measure_unmeasured();
        }
        for (r, kept) in kept_reason.iter().enumerate() {
            let e = &mut self.hier.elements[r];
            if *kept != StopReason::Unrefined && e.is_leaf() {
                e.stop = *kept;
            }
        }
        self.update_sums(&changed.take_sorted());
        self.converged = false;
        self.stats.links_created += new_links as u64;
        self.stats.refine_s += t.elapsed().as_secs_f64();
        self.oracle_b.clear();
        self.report(StepKind::Refine, t, refined, new_links)
    }

    fn can_split(&self, e: &Element) -> Result<(), StopReason> {
        if e.depth >= self.params.max_depth {
            Err(StopReason::MaxDepth)
        } else if e.area <= self.aeps || e.area / 4.0 <= 0.0 {
            Err(StopReason::AepsFloor)
        } else {
            Ok(())
        }
    }

    /// A source's (brightest leaf, largest channel of B) for the oracle: from the compact copy
    /// made for this refinement (radiosity does not change during refinement; new children
    /// inherit their parent's values), else from the element.
    fn source_b(&self, id: u32) -> [f64; 2] {
        self.oracle_b.get(id as usize).copied().unwrap_or_else(|| {
            let e = self.hier.get(id);
            [e.b_max, e.radiosity.max_channel()]
        })
    }

    /// Whether links weight their visibility samples by the kernel (`visibility_sample`): the
    /// error oracle's do; the other oracles keep the plain fraction (SPLASH-2's semantics).
    fn weighted_visibility(&self) -> bool {
        self.params.oracle == Oracle::Error
    }

    /// How accurately link coefficients are computed.
    fn accuracy(&self) -> transfer::Accuracy {
        transfer::Accuracy { tol: self.params.link_tol, five_times: self.params.five_times }
    }

    /// The pair's Galerkin coupling (see [`coupling_in`]).
    fn coupling(&self, r: u32, s: u32, straddle: bool) -> f64 {
        coupling_in(&self.hier, self.accuracy(), r, s, straddle)
    }

    /// The oracle's radiosity term of the pair (receiver `r`, source `s`): the larger of the two
    /// elements' `source_b`, so that the link r ← s and its mirror s ← r get the same verdict
    /// and the pair's links stay mirror images (see [`transfer`]: energy is conserved only if
    /// every link has its mirror at the same level).
    fn pair_b(&self, r: u32, s: u32) -> [f64; 2] {
        let (a, b) = (self.source_b(r), self.source_b(s));
        [a[0].max(b[0]), a[1].max(b[1])]
    }

    /// Extend the oracle's compact copy of B to every element (see `source_b`).
    fn sync_oracle_b(&mut self) {
        let start = self.oracle_b.len();
        let els = &self.hier.elements;
        self.oracle_b
            .extend(els[start.min(els.len())..].iter().map(|e| [e.b_max, e.radiosity.max_channel()]));
    }

    /// The oracle on all of receiver `r`'s links (the first pass of a refinement; later passes
    /// use the verdicts made with the new links, the oracle's inputs not changing during a
    /// refinement).
    fn decide_receiver(&self, r: u32, field: Option<&oracle::ErrorField>) -> ReceiverDecision {
        let p = self.hier.get(r);
        let mut v = Verdict::default();
        for (i, l) in self.links.by_receiver[r as usize].iter().enumerate() {
            let d = match field {
                Some(f) => {
                    self.decide_error(f, r, l).map(|x| if x == r { Split::Receiver } else { Split::Source })
                }
                None => self.decide(r, p, l),
            };
            v.note(i, d);
        }
        (r, v)
    }

    /// The oracle on one link: `Ok(side to split)` or `Err(why it is kept)`.
    fn decide(&self, r: u32, p: &Element, link: &Link) -> Decision {
        let class = link.class();
        if class == VisClass::None || !self.wants_split(link, class, self.pair_b(r, link.source)) {
            return Err(self.below_reason());
        }
        self.split_side(p, link)
    }

    /// Why a link the oracle does not want to split is kept.
    fn below_reason(&self) -> StopReason {
        match self.params.oracle {
            Oracle::Feps => StopReason::BelowFeps,
            Oracle::Bf => StopReason::BelowBfEps,
            Oracle::Error => StopReason::BelowErrorEps,
        }
    }

    /// Does the oracle's estimate call for splitting this link were its visibility of class
    /// `class` (Full or Partial)? `b`: the source's `source_b`.
    fn wants_split(&self, link: &Link, class: VisClass, [b_max, b_channel]: [f64; 2]) -> bool {
        match self.params.oracle {
            Oracle::Feps => f64::from(link.fmax) >= self.params.feps,
            // Decided per pass from the error field (`decide_error`), never per link.
            Oracle::Error => false,
            Oracle::Bf => {
                // A partially visible link may see the bright or the dark part of its source
                // (the floor round a box's foot is lit, the part under it is dark and hidden):
                // B_avg · V_avg then counts the darkness twice. Bound it by the source's
                // brightest leaf.
                let partial = class == VisClass::Partial;
                let b = if partial && self.params.conservative { b_max } else { b_channel };
                let (bound, thr) = if partial {
                    (1.0, self.bf_eps * self.params.partial_bf_factor)
                } else {
                    (f64::from(link.bound), self.bf_eps)
                };
                b > 0.0 && b * f64::from(link.fmax) * bound > thr
            }
        }
    }

    /// The side a link the oracle wants split is split on (`Err`: why it is kept instead, both
    /// elements being at their limits). Does not depend on the link's visibility.
    fn split_side(&self, p: &Element, link: &Link) -> Result<Split, StopReason> {
        let q = self.hier.get(link.source);
        let (first, second) = if link.split_source { (q, p) } else { (p, q) };
        let side = |source: bool| if source { Split::Source } else { Split::Receiver };
        match self.can_split(first) {
            Ok(()) => Ok(side(link.split_source)),
            Err(why_first) if !self.params.split_fallback => Err(why_first),
            Err(why_first) => match self.can_split(second) {
                Ok(()) => Ok(side(!link.split_source)),
                // The receiver's own limit is what the inspector reports.
                Err(why_second) => Err(if link.split_source { why_second } else { why_first }),
            },
        }
    }

    /// New links replacing the split ones of receiver `r` (its own list, links for its
    /// children), with the next pass's verdicts on them.
    fn replace_links(&self, r: u32, splits: &[(u32, Split)]) -> Replaced {
        let old = &self.links.by_receiver[r as usize];
        // The new links of each split link (its source's or its receiver's children, in child
        // order), in parallel when the receiver has many: one busy receiver must not keep a
        // thread waiting. Each split link has its own shadow cache, so the result does not
        // depend on how the work is divided.
        let new_of = |&(i, side): &(u32, Split)| -> NewLinks {
            let l = &old[i as usize];
            let mut last = NO_HIT;
            let mut out = [None; 4];
            let mut rays = 0;
            let parent = if side == Split::Source { l.source } else { r };
            for (k, c) in self.hier.get(parent).children().expect("split in phase B").into_iter().enumerate()
            {
                let (nl, nr) = match side {
                    Split::Source => self.make_link(r, c, &mut last),
                    Split::Receiver => self.make_link(c, l.source, &mut last),
                };
                out[k] = nl;
                rays += nr;
            }
            (out, rays)
        };
        // Few splits: made one by one below, without a list.
        let parallel = splits.len() >= PARALLEL_SPLITS;
        let made: Vec<NewLinks> = if parallel {
            splits.par_iter().with_max_len(PARALLEL_SPLITS / 4).map(new_of).collect()
        } else {
            Vec::new()
        };
        let mut made = made.into_iter();
        let mut rep = Replaced {
            receiver: r,
            own: Vec::with_capacity(old.len() + 3 * splits.len()),
            own_verdict: Verdict::default(),
            kids: Default::default(),
            kid_verdicts: Default::default(),
            first_child: NONE,
            rays: 0,
            own_changed: false,
            created: 0,
        };
        let down = splits.iter().filter(|(_, side)| *side == Split::Receiver).count();
        if down > 0 {
            for k in &mut rep.kids {
                k.reserve_exact(down);
            }
            rep.first_child = self.hier.get(r).first_child;
        }
        // The kept links between split ones are copied in runs.
        let mut kept_from = 0;
        for split in splits {
            let i = split.0 as usize;
            rep.own.extend_from_slice(&old[kept_from..i]);
            kept_from = i + 1;
            let (new, nr) = if parallel { made.next().expect("one per split") } else { new_of(split) };
            rep.rays += nr;
            rep.created += new.iter().flatten().count();
            match split.1 {
                Split::Source => {
                    rep.own_changed = true;
                    for (nl, d) in new.into_iter().flatten() {
                        rep.own_verdict.note(rep.own.len(), d);
                        rep.own.push(nl);
                    }
                }
                Split::Receiver => {
                    for (k, (nl, d)) in new.into_iter().enumerate().filter_map(|(k, n)| Some((k, n?))) {
                        rep.kid_verdicts[k].note(rep.kids[k].len(), d);
                        rep.kids[k].push(nl);
                    }
                }
            }
        }
        rep.own.extend_from_slice(&old[kept_from..]);
        rep
    }

    /// A link receiver ← source, or None when the source contributes nothing geometrically.
    ///
    /// `last`: the shadow cache (see [`Accel::occluded_cached`]) shared by nearby pairs.
    /// With the link comes the next refinement pass's decision on it (see `decide`).
    fn make_link(&self, receiver: u32, source: u32, last: &mut u32) -> (Option<(Link, Decision)>, u64) {
        let p = self.hier.get(receiver);
        let q = self.hier.get(source);
        if p.patch == q.patch {
            return (None, 0);
        }
        let sides = pair_sides(p, q);
        if !sides.facing {
            return (None, 0);
        }
        let key = pair_key(receiver.min(source), receiver.max(source));
        // The mirror link, made earlier in this pass, settled the pair (its rays are counted
        // once, by the receiver with the lower id, whichever direction computed them).
        let canonical = receiver < source;
        if let Some(out) = self.pair_memo.get(key) {
            let mut link = new_link(
                (p, receiver),
                (q, source),
                out.g,
                out.vis,
                sides.straddle,
                self.params.conservative,
            );
            link.unmeasured = out.unmeasured;
            return (Some((link, self.decide(receiver, p, &link))), if canonical { out.rays } else { 0 });
        }
        let (made, cast, g) = self.make_pair_link(receiver, source, sides, key, last);
        if let Some((l, _)) = &made {
            self.pair_memo.put(key, PairOutcome { g, vis: l.vis, unmeasured: l.unmeasured, rays: cast });
        }
        (made, if canonical { cast } else { 0 })
    }

    /// `make_link` of a pair not made yet in this pass; also returns the pair's coupling (NaN
    /// when left uncomputed).
    fn make_pair_link(
        &self,
        receiver: u32,
        source: u32,
        sides: PairSides,
        key: u64,
        last: &mut u32,
    ) -> (Option<(Link, Decision)>, u64, f64) {
        let p = self.hier.get(receiver);
        let q = self.hier.get(source);
        // The exact form factor is needed only by links that outlive the next pass, and to
        // know whether the link exists at all, which a pair clearly in front of each other
        // settles (`form_factor_surely_positive`).
        let surely = !sides.straddle && form_factor_surely_positive(p, q);
        let mut g = if surely { f64::NAN } else { self.coupling(receiver, source, sides.straddle) };
        if g <= 0.0 && !sides.straddle {
            return (None, 0, g);
        }
        let rays = self.params.rays;
        // Visibility in the pair's canonical order (lower id first): the mirror link gets the
        // very same estimate.
        let (lo, hi) = if receiver < source { (p, q) } else { (q, p) };
        let mut vis_with = |n: u32, salt: u64, stop: Stop| {
            let (v, cast) = visibility::visibility_sample(
                &self.accel,
                (lo.vertices(), lo.patch, lo.normal),
                (hi.vertices(), hi.patch, hi.normal),
                n,
                self.params.seed ^ salt,
                key,
                last,
                stop,
                self.weighted_visibility(),
            );
            (v, u64::from(cast))
        };
        let mut link = new_link((p, receiver), (q, source), g, 1.0, sides.straddle, self.params.conservative);
        // Which visibility classes the next pass would split the link in (the side does not
        // depend on V; a split when fully visible implies one when partially visible: the
        // partial test uses a bound of 1 instead of ≤ 1, a source term b_max ≥ the max channel
        // of B, and a threshold `partial_bf_factor` ≤ 1 times the full one).
        let error_oracle = self.params.oracle == Oracle::Error;
        let (split_full, split_partial) = if !error_oracle && self.split_side(p, &link).is_ok() {
            let b = self.pair_b(receiver, source);
            (self.wants_split(&link, VisClass::Full, b), self.wants_split(&link, VisClass::Partial, b))
        } else {
            (false, false)
        };
        debug_assert!(!split_full || split_partial, "a full-visibility split must imply a partial one");
        // A link that the next refinement pass splits whatever its exact V is needs only the
        // rays that tell which case it is in: it is replaced before anyone reads V. When the
        // pass splits it unless V = 0, one unblocked ray settles it; when it splits it unless
        // V is 0 or 1, one unblocked and one blocked ray do.
        let stop = if !self.early_exit {
            Stop::Never
        } else if split_full {
            Stop::AtVisible
        } else if split_partial {
            Stop::AtMixed
        } else {
            Stop::Never
        };
        let (vis, mut cast) = vis_with(rays, 0, stop);
        let settled = match stop {
            Stop::Never => false,
            Stop::AtVisible => vis > 0.0,
            Stop::AtMixed => vis > 0.0 && vis < 1.0,
        };
        if settled {
            link.vis = if stop == Stop::AtVisible { UNMEASURED_VIS } else { vis as f32 };
            link.unmeasured = true;
            return (Some((link, self.decide(receiver, p, &link))), cast, g);
        }
        let mut vis = vis;
        // The error oracle splits partially visible links, so a zero estimate ends a refinement
        // that any other estimate continues: its zeros are replaced by a fresh estimate (below).
        let confirm_zero = split_full || (split_partial && self.params.conservative) || error_oracle;
        if vis == 0.0 && confirm_zero && self.params.zero_confirm > 0 {
            // When the next pass splits this link unless V = 0, a zero estimate is the only
            // thing that ends its refinement: accepted as it is, each level would keep only
            // P(estimate > 0) of the link's light (a compounding dark bias). Confirm it with
            // more rays; the first that passes settles the split. A link split only when
            // partially visible is re-tested only by the conservative oracle (it refines more
            // round shadows): its zeros and its all-visible estimates bias in opposite
            // directions, and confirming only the zeros made splash_room 6 % too bright.
            let more = self.params.zero_confirm.saturating_mul(rays);
            let confirm = if self.early_exit && split_full { Stop::AtVisible } else { Stop::Never };
            let (v2, c2) = vis_with(more, 0x5EED, confirm);
            cast += c2;
            if v2 > 0.0 && confirm == Stop::AtVisible {
                link.vis = UNMEASURED_VIS;
                link.unmeasured = true;
                return (Some((link, self.decide(receiver, p, &link))), cast, g);
            }
            // The fresh estimate alone: E[V] = P(V̂ > 0) V (the split links' new estimates) +
            // P(V̂ = 0) E[V̂₂] = V, unbiased (shadow-wide at 16 rays, error oracle: the receiver
            // was 12 % dark keeping the zeros, 0.4 % with the fresh estimate).
            vis = v2;
        } else if vis == 1.0 && split_partial && self.params.conservative && self.params.zero_confirm > 0 {
            // Symmetrically, an all-visible estimate ends a refinement that any partial one
            // continues (the next pass splits this link only if partially visible): accepted as
            // it is, each level keeps P(V̂ = 1) · 1 of the link where V is due, a compounding
            // bright bias that created light (splash_room `interactive`: the floor's rows of
            // F·V summed to 1.11 with the solver's V, 1.00 with 256 weighted rays; escaped/
            // emitted −11 %). Confirmed the same way: a blocked ray settles the split, else the
            // fresh estimate stands (unbiased, as for the zeros).
            let more = self.params.zero_confirm.saturating_mul(rays);
            let confirm = if self.early_exit { Stop::AtMixed } else { Stop::Never };
            let (v2, c2) = vis_with(more, 0x0DE5, confirm);
            cast += c2;
            if v2 > 0.0 && v2 < 1.0 && confirm == Stop::AtMixed {
                link.vis = v2 as f32;
                link.unmeasured = true;
                return (Some((link, self.decide(receiver, p, &link))), cast, g);
            }
            vis = v2;
        }
        if surely {
            g = self.coupling(receiver, source, false);
            link.ff = (g / p.area) as f32;
            link.g = g as f32;
        }
        link.vis = vis as f32;
        (Some((link, self.decide(receiver, p, &link))), cast, g)
    }

    /// Measure V of the links still marked unmeasured (refinement stopped, by the link
    /// budget or a cancel, before the pass that would have replaced them).
    fn measure_unmeasured(&mut self) {
        let hier = &self.hier;
        let (accel, seed, rays) = (&self.accel, self.params.seed, self.params.rays);
        let weighted = self.weighted_visibility();
        let acc = self.accuracy();
        let cast: u64 = self
            .links
            .by_receiver
            .par_iter_mut()
            .enumerate()
            .map(|(r, ls)| {
                let mut cast = 0;
                let mut last = NO_HIT;
                for l in ls.iter_mut().filter(|l| l.unmeasured) {
                    let (r, s) = (r as u32, l.source);
                    let (p, q) = (hier.get(r), hier.get(s));
                    let g = coupling_in(hier, acc, r, s, pair_sides(p, q).straddle);
                    l.ff = (g / p.area) as f32;
                    l.g = g as f32;
                    // The canonical order, as in `make_link`.
                    let (lo, hi) = if r < s { (p, q) } else { (q, p) };
                    let (v, c) = visibility::visibility_sample(
                        accel,
                        (lo.vertices(), lo.patch, lo.normal),
                        (hi.vertices(), hi.patch, hi.normal),
                        rays,
                        seed,
                        pair_key(r.min(s), r.max(s)),
                        &mut last,
                        Stop::Never,
                        weighted,
                    );
                    l.vis = v as f32;
                    l.unmeasured = false;
                    cast += u64::from(c);
                }
                cast
            })
            .sum();
        self.stats.rays += cast;
    }

    /// Does this solve cluster (decided by `params.cluster` and the patch count)?
    fn clustering(&self) -> bool {
        self.params.cluster.applies(self.hier.roots)
    }

    /// Each cluster node's largest radiosity (leaves: their patch's `b_max`).
    fn cluster_b_max(&self, tree: &ClusterTree) -> Vec<f64> {
        let mut b = vec![0.0_f64; tree.len()];
        for i in (0..tree.len()).rev() {
            let node = &tree.nodes[i];
            b[i] = if node.is_leaf() {
                self.hier.get(tree.patch(i as u32)).b_max
            } else {
                b[node.kids[0] as usize].max(b[node.kids[1] as usize])
            };
        }
        b
    }

    /// Is a cluster link between nodes `a` and `b` (spheres apart) accurate enough? The BF
    /// oracle's test with cluster bounds ([`cluster`]); the Feps oracle's with F alone.
    fn cluster_accept(&self, tree: &ClusterTree, b_max: &[f64], a: u32, b: u32) -> bool {
        let (na, nb) = (&tree.nodes[a as usize], &tree.nodes[b as usize]);
        let d = na.center.distance(nb.center);
        let gap = d - na.radius - nb.radius;
        if gap <= 0.0 {
            return false;
        }
        // F bounds from the projected areas facing the other end (the whole member area, as
        // SPLASH-2's A/(π d²) has it, made 1.3–1.5× the links on the furnished rooms for the
        // same error), over the gap between the spheres (the centres' distance instead doubled
        // furnished-2k's error against the unclustered solve, 4.8 → 8.9 %).
        let w = (nb.center - na.center) / d;
        let pg2 = std::f64::consts::PI * gap * gap;
        let f = cluster::link_frame(na, nb, w);
        let (f_ab, f_ba) =
            ((nb.projected_area(-w, f) / pg2).min(1.0), (na.projected_area(w, f) / pg2).min(1.0));
        match self.params.oracle {
            Oracle::Feps => f_ab.max(f_ba) < self.params.feps,
            Oracle::Bf | Oracle::Error => {
                let var = (2.0 * (na.radius + nb.radius) / d).min(1.0);
                let bf = (na.rho_max * b_max[b as usize] * f_ab).max(nb.rho_max * b_max[a as usize] * f_ba);
                bf * var < self.bf_eps
            }
        }
    }

    /// The first linking of a clustered solve: link the cluster tree's root with itself.
    /// Returns the links made (element links, and cluster links counted twice).
    fn cluster_linking(&mut self) -> usize {
        let tree = Arc::clone(self.clusters.get_or_insert_with(|| Arc::new(ClusterTree::build(&self.hier))));
        let b_max = self.cluster_b_max(&tree);
        let accept = |a: u32, b: u32| self.cluster_accept(&tree, &b_max, a, b);
        let mut pairs = Vec::new();
        tree.link(0, 0, &accept, &mut pairs);
        self.install_pairings(&tree, &pairs, Vec::new())
    }

    /// Test every cluster link again with the current radiosities and replace those that fail
    /// by their subdivision. Returns the links made and whether any cluster link changed.
    fn cluster_refine(&mut self) -> (usize, bool) {
        let Some(tree) = self.clusters.clone() else { return (0, false) };
        let b_max = self.cluster_b_max(&tree);
        let accept = |a: u32, b: u32| self.cluster_accept(&tree, &b_max, a, b);
        let redone: Vec<Option<Vec<Pairing>>> = self
            .cluster_links
            .par_iter()
            .with_min_len(64)
            .map(|l| {
                if accept(l.a, l.b) {
                    return None;
                }
                let mut out = Vec::new();
                tree.link(l.a, l.b, &accept, &mut out);
                Some(out)
            })
            .collect();
        if redone.iter().all(Option::is_none) {
            return (0, false);
        }
        let mut kept = Vec::with_capacity(self.cluster_links.len());
        let mut pairs = Vec::new();
        for (l, r) in self.cluster_links.iter().zip(redone) {
            match r {
                None => kept.push(*l),
                Some(p) => pairs.extend(p),
            }
        }
        (self.install_pairings(&tree, &pairs, kept), true)
    }

    /// Make the links of `pairs` (cluster links with their visibility, element links of patch
    /// pairs as `initial_linking` does), after the cluster links `kept`; update the patches'
    /// cluster rows. Returns the links made.
    fn install_pairings(
        &mut self,
        tree: &Arc<ClusterTree>,
        pairs: &[Pairing],
        kept: Vec<ClusterLink>,
    ) -> usize {
        let (rays, seed) = (self.params.rays.max(4), self.params.seed);
        // A clustered scene's patches are small pieces: their pairs are integrated as element
        // pairs are (the input pairs' 1e-7 took 88 % of a 10 k-patch room's solve).
        let acc = self.accuracy();
        let made: Vec<Made> = pairs
            .par_iter()
            .with_min_len(16)
            .map(|pair| match *pair {
                Pairing::Cluster(a, b) => {
                    let (vis, cast) = tree.visibility(&self.hier, &self.accel, a, b, rays, seed);
                    let (na, nb) = (&tree.nodes[a as usize], &tree.nodes[b as usize]);
                    let frame = cluster::link_frame(na, nb, (nb.center - na.center).normalize());
                    (Some(ClusterLink { a, b, vis, frame }), None, u64::from(cast))
                }
                Pairing::Patches(p, q) => {
                    let (links, cast) = self.root_pair(p, q, acc, false);
                    (None, links.map(|(pq, qp)| (p, q, pq, qp)), cast)
                }
            })
            .collect();
        let mut created = 0;
        let mut skipped = 0;
        self.cluster_links = kept;
        for (cl, el, cast) in made {
            self.stats.rays += cast;
            if let Some(cl) = cl {
                self.cluster_links.push(cl);
                created += 2;
            } else if let Some((p, q, pq, qp)) = el {
                self.links.by_receiver[p as usize].push(pq);
                self.links.by_receiver[q as usize].push(qp);
                created += 2;
            } else {
                skipped += 1;
            }
        }
        self.stats.pairs_skipped += skipped;
        // Each patch's Σ F·V through the cluster links: the transfer with B = 1.
        self.cluster_xfer = ClusterTransfer::new(tree, &self.cluster_links);
        let ones = self.cluster_xfer.irradiance(tree, &self.hier, &|_| Rgb::ONE);
        self.cluster_fv = ones.iter().map(|h| h.0[0]).collect();
        created
    }

    /// The `max` cluster links of largest form factor, largest first (ties: link order), as
    /// drawn: the centres of their two nodes (a patch's: its centroid), their visibility, and
    /// the larger of their two unoccluded form factors in the clusters' point approximation,
    /// `min(1, P_b(−ω) / (π d²))` with P the projected area of the far end towards the near
    /// one (empty when the solve does not cluster). Only the kept links are built: the 100 k
    /// room has 4 M cluster links.
    #[must_use]
    pub fn cluster_link_views(&self, max: usize) -> Vec<ClusterLinkView> {
        let Some(tree) = &self.clusters else { return Vec::new() };
        let ends = |l: &ClusterLink| {
            let (na, nb) = (&tree.nodes[l.a as usize], &tree.nodes[l.b as usize]);
            let d = na.center.distance(nb.center).max(f64::MIN_POSITIVE);
            let w = (nb.center - na.center) / d;
            let f = cluster::link_frame(na, nb, w);
            let pd2 = std::f64::consts::PI * d * d;
            let ff = (nb.projected_area(-w, f) / pd2).max(na.projected_area(w, f) / pd2).min(1.0);
            (na.center, nb.center, ff)
        };
        let mut order: Vec<(f64, u32)> =
            self.cluster_links.par_iter().enumerate().map(|(i, l)| (ends(l).2, i as u32)).collect();
        let by_f = |x: &(f64, u32), y: &(f64, u32)| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1));
        if order.len() > max && max > 0 {
            order.select_nth_unstable_by(max - 1, by_f);
        }
        order.truncate(max);
        order.sort_unstable_by(by_f);
        order
            .into_iter()
            .map(|(_, i)| {
                let l = &self.cluster_links[i as usize];
                let (from, to, ff) = ends(l);
                ClusterLinkView { from, to, vis: l.vis, ff }
            })
            .collect()
    }

    /// The cluster tree's nodes of two patches or more, in tree order, with their link counts;
    /// and per input patch the index of the smallest of them holding it (both empty when the
    /// solve does not cluster).
    #[must_use]
    pub fn cluster_infos(&self) -> (Vec<ClusterInfo>, Vec<u32>) {
        let Some(tree) = &self.clusters else { return (Vec::new(), Vec::new()) };
        let mut links = vec![0u32; tree.len()];
        for l in &self.cluster_links {
            links[l.a as usize] += 1;
            links[l.b as usize] += 1;
        }
        // Node id → index among the clusters (parents come before their children).
        let mut index = vec![u32::MAX; tree.len()];
        let mut infos = Vec::new();
        let mut patch_cluster = vec![u32::MAX; self.hier.roots];
        for (i, n) in tree.nodes.iter().enumerate() {
            let parent = (n.parent != cluster::LEAF).then(|| index[n.parent as usize]);
            if n.is_leaf() {
                if let Some(p) = parent {
                    patch_cluster[tree.patch(i as u32) as usize] = p;
                }
                continue;
            }
            index[i] = infos.len() as u32;
            infos.push(ClusterInfo {
                depth: n.depth,
                bmin: n.bmin,
                bmax: n.bmax,
                patches: n.hi - n.lo,
                links: links[i],
                parent,
            });
        }
        (infos, patch_cluster)
    }

    /// Every input patch's irradiance through the cluster links (None: no cluster links).
    fn cluster_irradiance(&mut self) -> Option<Vec<Rgb>> {
        let tree = self.clusters.as_ref()?;
        if self.cluster_links.is_empty() {
            return None;
        }
        let hier = &self.hier;
        Some(self.cluster_xfer.irradiance(tree, hier, &|p| hier.get(p).radiosity))
    }

    /// The form-factor accuracy of input patch pairs: they carry a closed scene's whole
    /// answer, so to 1e-7 (one point with SPLASH-2's rule), never the disk formula.
    fn root_accuracy(&self) -> transfer::Accuracy {
        transfer::Accuracy {
            tol: if self.params.link_tol > 0.0 { transfer::ROOT_REL_TOL } else { 0.0 },
            five_times: false,
        }
    }

    /// The two links of input patches `pi` < `qi` (p ← q, q ← p), or None when they face away
    /// or are fully occluded; and the rays cast. Visibility once per unordered pair, used both
    /// ways.
    /// `root`: integrate the coupling to the input pairs' tolerance (`root_accuracy`); else to
    /// `acc`, as element links are (the small patches of a clustered scene).
    fn root_pair(
        &self,
        pi: u32,
        qi: u32,
        acc: transfer::Accuracy,
        root: bool,
    ) -> (Option<(Link, Link)>, u64) {
        let (rays, seed, conservative) = (self.params.rays, self.params.seed, self.params.conservative);
        let weighted = self.weighted_visibility();
        let (p, q) = (self.hier.get(pi), self.hier.get(qi));
        let sides = pair_sides(p, q);
        if !sides.facing {
            return (None, 0);
        }
        // One Galerkin coupling serves both links (A_p F_pq = A_q F_qp exactly).
        // The small patches of a clustered scene are placed by their bounding boxes' gap.
        let min_gap = if root { transfer::NO_GAP_BOUND } else { transfer::box_gap(p, q) };
        let g = transfer::coupling(p, pi, q, qi, sides.straddle, root, acc, min_gap);
        if g <= 0.0 && !sides.straddle {
            return (None, 0);
        }
        // Newell normals of the input polygons (as `visibility::visible_fraction`).
        let (n_p, n_q) = (newell_normal(p.vertices()), newell_normal(q.vertices()));
        let mut last = NO_HIT;
        let mut cast = 0u64;
        let mut vis = |n_rays: u32, salt: u64| {
            let (v, c) = visibility::visibility_sample(
                &self.accel,
                (p.vertices(), pi, n_p),
                (q.vertices(), qi, n_q),
                n_rays,
                seed ^ salt,
                pair_key(pi, qi),
                &mut last,
                Stop::Never,
                weighted,
            );
            cast += u64::from(c);
            v
        };
        // Input pairs of an unclustered scene are confirmed with ROOT_CONFIRM_RAYS; the small
        // patches a clustered scene links pair by pair as refined links are (`zero_confirm` ×
        // rays: the 32 rays were a third of a 100 k-patch room's rays).
        let confirm = if root { ROOT_CONFIRM_RAYS } else { self.params.zero_confirm * rays };
        let mut v = vis(rays, 0);
        if v == 0.0 {
            // Confirm full occlusion with more rays before dropping the pair.
            if confirm == 0 || vis(confirm, 0x5EED) == 0.0 {
                return (None, cast);
            }
            v = 1.0 / f64::from(confirm + rays);
        } else if v == 1.0 && conservative && confirm > 0 {
            // All rays passed: the oracle keeps a fully visible link and splits a
            // partially visible one, whose children are estimated afresh, so an
            // accepted false 1 is a bright bias that only grows (splash_room
            // `interactive`: the floor–wall pairs at V 0.65 read 1 with 4 rays, the
            // floor's F·V summed to 1.11, and the solve created 11 % of its light).
            // Confirmed with more rays; the first blocked one makes it partial.
            let v2 = vis(confirm, 0x0DE5);
            if v2 < 1.0 {
                v = (f64::from(rays) + v2 * f64::from(confirm)) / f64::from(rays + confirm);
            }
        }
        let v = v as f32;
        let links = (
            new_link((p, pi), (q, qi), g, v, sides.straddle, conservative),
            new_link((q, qi), (p, pi), g, v, sides.straddle, conservative),
        );
        (Some(links), cast)
    }

    /// Link every pair of input patches that face each other and are not fully occluded.
    fn initial_linking(&mut self) -> usize {
        let key = (self.params.rays, self.params.seed, self.params.conservative, self.weighted_visibility());
        if let Some((k, cached, skipped)) = &self.initial_cache
            && *k == key
        {
            let n = cached.iter().map(Vec::len).sum();
            for (i, l) in cached.iter().enumerate() {
                self.links.by_receiver[i] = l.clone();
            }
            self.stats.pairs_skipped = *skipped;
            return n;
        }
        let n = self.hier.roots as u32;
        let root_acc = self.root_accuracy();
        let rows: Vec<PairRow> = (0..n)
            .into_par_iter()
            .map(|pi| {
                let mut out = Vec::new();
                let mut skipped = 0;
                let mut cast = 0u64;
                for qi in pi + 1..n {
                    let (links, c) = self.root_pair(pi, qi, root_acc, true);
                    cast += c;
                    match links {
                        Some((pq, qp)) => out.push((qi, pq, qp)),
                        None => skipped += 1,
                    }
                }
                (out, skipped, cast)
            })
            .collect();
        let mut lists: Vec<Vec<Link>> = vec![Vec::new(); n as usize];
        let mut skipped = 0;
        for (pi, (row, sk, cast)) in rows.into_iter().enumerate() {
            skipped += sk;
            self.stats.rays += cast;
            for (qi, pq, qp) in row {
                lists[pi].push(pq);
                lists[qi as usize].push(qp);
            }
        }
        // Receiver lists in source order, whatever order the pairs were visited in.
        for l in &mut lists {
            l.sort_by_key(|l| l.source);
        }
        let total = lists.iter().map(Vec::len).sum();
        for (i, l) in lists.iter().enumerate() {
            self.links.by_receiver[i] = l.clone();
        }
        self.stats.pairs_skipped = skipped;
        self.initial_cache = Some((key, lists, skipped));
        total
    }

    /// Recompute Σ F and Σ F·V of every receiver whose link list changed since the last call
    /// (`changed`).
    fn update_sums(&mut self, changed: &[u32]) {
        let links = &self.links.by_receiver;
        disjoint_mut(&mut self.hier.elements, changed.iter().copied())
            .into_par_iter()
            .zip(changed.par_iter())
            .with_min_len(256)
            .for_each(|(e, &r)| {
                let ls = &links[r as usize];
                e.f_sum = ls.iter().filter(|l| l.vis >= 1.0).map(|l| f64::from(l.ff)).sum();
                e.fv_sum = ls.iter().map(|l| f64::from(l.ff) * f64::from(l.vis)).sum();
                e.fv_partial = e.fv_sum - e.f_sum;
            });
        // Input patches' rows include what they gather through cluster links.
        for &r in changed {
            if let Some(&fv) = self.cluster_fv.get(r as usize) {
                let e = &mut self.hier.elements[r as usize];
                e.fv_sum += fv;
                e.fv_partial += fv;
            }
        }
    }

    // ------------------------------------------------------------------------------------------
    // Gather and push-pull
    // ------------------------------------------------------------------------------------------

    /// One gather over every link (the lecture's `Gather`), Jacobi: every receiver reads the
    /// radiosities of the previous iteration. With `gauss_seidel`, gathers and pushes patch by
    /// patch instead, each patch using the newest values (then push-pull is already done).
    pub fn gather_step(&mut self) -> StepReport {
        self.cancel.store(false, Ordering::Relaxed);
        self.gather_inner()
    }

    fn gather_inner(&mut self) -> StepReport {
        let t = Instant::now();
        // The links as one contiguous plan, rebuilt after they change.
        let mut plan = std::mem::take(&mut self.gather_plan);
        if !self.plan_valid {
            if self.params.push_slopes {
                self.fill_slopes();
            }
            plan.rebuild(&self.links, self.params.push_slopes.then_some(&self.hier));
            self.plan_valid = true;
        }
        // What the input patches gather through cluster links, from the radiosities before
        // this gather (both sweeps).
        let cluster_h = self.cluster_irradiance();
        if self.params.gauss_seidel {
            let before: Vec<Rgb> = self.hier.elements.iter().map(|e| e.radiosity).collect();
            for root in 0..self.hier.roots as u32 {
                let ids = self.subtree(root);
                let g: Vec<(Rgb, Rgb, [Rgb; 2])> = ids
                    .iter()
                    .map(|&r| plan.gather(r as usize, |s| self.hier.get(s).radiosity, &self.moment))
                    .collect();
                for (&r, (g, full, slope)) in ids.iter().zip(g) {
                    let e = &mut self.hier.elements[r as usize];
                    (e.gathered, e.gathered_full, e.gathered_slope) = (g, full, slope);
                }
                if let Some(h) = &cluster_h {
                    self.hier.elements[root as usize].gathered += h[root as usize];
                }
                self.push_pull_root(root);
            }
            // Recomputes the same leaf values (nothing was gathered since each root's push) and
            // measures the change against the values before the sweep.
            self.push_pull_flat(Some(&before), true);
            self.stats.gather_s += t.elapsed().as_secs_f64();
        } else {
            // Sources' radiosity in a compact array (read once per link, in any order), then
            // every receiver gathers in parallel.
            let mut b = std::mem::take(&mut self.b_prev);
            b.resize(self.hier.len(), Rgb::ZERO);
            b.par_iter_mut()
                .zip(self.hier.elements.par_iter())
                .with_min_len(1024)
                .for_each(|(b, e)| *b = e.radiosity);
            let mu = &self.moment;
            self.hier.elements.par_iter_mut().enumerate().with_min_len(256).for_each(|(r, e)| {
                (e.gathered, e.gathered_full, e.gathered_slope) = plan.gather(r, |s| b[s as usize], mu);
            });
            if let Some(h) = &cluster_h {
                for (e, h) in self.hier.elements.iter_mut().zip(h) {
                    e.gathered += *h;
                }
            }
            self.b_prev = b;
            self.stats.gather_s += t.elapsed().as_secs_f64();
        }
        self.gather_plan = plan;
        self.gathered_once = true;
        self.stats.iterations += 1;
        self.report(StepKind::Gather, t, 0, 0)
    }

    fn subtree(&self, root: u32) -> Vec<u32> {
        let mut out = Vec::new();
        let mut stack = vec![root];
        while let Some(id) = stack.pop() {
            out.push(id);
            if let Some(c) = self.hier.get(id).children() {
                stack.extend(c.iter().rev());
            }
        }
        out
    }

    /// The radiosity of every element (indexed by id) that `push_pull_step` would give now, the
    /// solver's state untouched: what a viewer shows right after a gather. The same chain sums
    /// (with the links' slopes) and area averages as `push_pull_flat`.
    #[must_use]
    pub fn push_pull_preview(&self) -> Vec<Rgb> {
        let els = &self.hier.elements;
        let mut b: Vec<Rgb> =
            els.iter()
                .zip(self.chains())
                .map(|(e, c)| {
                    if e.is_leaf() { e.emission + e.reflectance.mul_rgb(c.full + c.rest) } else { Rgb::ZERO }
                })
                .collect();
        for i in (0..els.len()).rev() {
            let first = els[i].first_child;
            if first != NONE {
                let area = els[i].area;
                b[i] = (first as usize..first as usize + 4)
                    .fold(Rgb::ZERO, |s, c| s + b[c] * (els[c].area / area));
            }
        }
        b
    }

    /// Fill `Link::slope` of every link that has none yet (parallel over receivers; a link's
    /// slope depends on its two elements and V only, so it is computed once per link).
    fn fill_slopes(&mut self) {
        let hier = &self.hier;
        let sums: Vec<[f64; 2]> = self
            .links
            .by_receiver
            .par_iter_mut()
            .enumerate()
            .with_min_len(64)
            .map(|(r, ls)| {
                let re = hier.get(r as u32);
                for l in ls.iter_mut().filter(|l| !l.slope_set) {
                    let v = f64::from(l.vis).clamp(0.0, 1.0);
                    let se = hier.get(l.source);
                    let g = f64::from(l.g);
                    // Both sides from the same inputs as the mirror link's: bit-identical.
                    (l.slope, l.src_slope) = if v > 0.0 {
                        (
                            oracle::kernel_slope(re, se, v, g / re.area).map(|x| x as f32),
                            oracle::kernel_slope(se, re, v, g / se.area).map(|x| x as f32),
                        )
                    } else {
                        ([0.0; 2], [0.0; 2])
                    };
                    l.slope_set = true;
                }
                // Over every own link (a split may have removed some since the last fill).
                ls.iter().fold([0.0; 2], |[u, v], l| [u + f64::from(l.slope[0]), v + f64::from(l.slope[1])])
            })
            .collect();
        for (e, s) in self.hier.elements.iter_mut().zip(sums) {
            e.fv_slope = s;
        }
    }

    /// Push gathered irradiance down to the leaves (B = E + ρ·H), pull area averages up.
    pub fn push_pull_step(&mut self) -> StepReport {
        let t = Instant::now();
        self.push_pull_flat(None, true);
        self.stats.push_pull_s += t.elapsed().as_secs_f64();
        self.report(StepKind::PushPull, t, 0, 0)
    }

    fn push_pull_root(&mut self, root: u32) {
        self.push_pull_rec(root, Chain::default());
    }

    /// `up`: the irradiance inherited from the ancestors (`Chain`).
    fn push_pull_rec(&mut self, id: u32, up: Chain) -> Rgb {
        let e = &self.hier.elements[id as usize];
        let own = up.step(e, self.params.push_slopes);
        if let Some(kids) = e.children() {
            let area = e.area;
            let mut b = Rgb::ZERO;
            let mut b_max: f64 = 0.0;
            for c in kids {
                let bc = self.push_pull_rec(c, own);
                let child = &self.hier.elements[c as usize];
                b += bc * (child.area / area);
                b_max = b_max.max(child.b_max);
            }
            let e = &mut self.hier.elements[id as usize];
            e.radiosity = b;
            e.b_max = b_max;
            b
        } else {
            let b = e.emission + e.reflectance.mul_rgb(own.full + own.rest);
            let e = &mut self.hier.elements[id as usize];
            e.radiosity = b;
            e.b_max = b.max_channel();
            b
        }
    }

    /// Push-pull over the whole forest in two flat sweeps (parents have smaller ids than their
    /// children): down in id order, each element's inherited sums from its parent's, leaves'
    /// radiosity B = E + ρ·(H_full + H_rest) and their energy terms; then up in reverse
    /// order, area averages. The same values as `push_pull_rec` from every root. The residual is
    /// the largest leaf change against `before` (default: the values before this call).
    fn push_pull_flat(&mut self, before: Option<&[Rgb]>, energy: bool) {
        let n = self.hier.len();
        let slopes = self.params.push_slopes;
        // Per element: its own and inherited sums (full-visibility irradiance, other irradiance,
        // full-visibility F, other F·V; with slopes, their gradients).
        let (max_change, max_reflected, absorbed, escaped) = if slopes {
            push_down(&mut self.hier.elements, &mut self.chain, before, energy)
        } else {
            push_down(&mut self.hier.elements, &mut self.flat_chain, before, energy)
        };
        let els = &mut self.hier.elements;
        // World moments Σ_leaves A B (c − c_e) / A_e while pulling (leaves: 0), then each in its
        // element's tangent basis.
        let world = &mut self.moment_world;
        world.clear();
        world.resize(if slopes { n } else { 0 }, [Rgb::ZERO; 3]);
        for i in (0..n).rev() {
            let first = els[i].first_child;
            if first == NONE {
                continue;
            }
            let (area, at) = (els[i].area, els[i].centroid);
            let mut b = Rgb::ZERO;
            let mut b_max: f64 = 0.0;
            let mut m = [Rgb::ZERO; 3];
            for (k, c) in els[first as usize..first as usize + 4].iter().enumerate() {
                let w = c.area / area;
                b += c.radiosity * w;
                b_max = b_max.max(c.b_max);
                if slopes {
                    let d = (c.centroid - at) * w;
                    let mc = world[first as usize + k];
                    m[0] += mc[0] * w + c.radiosity * d.x;
                    m[1] += mc[1] * w + c.radiosity * d.y;
                    m[2] += mc[2] * w + c.radiosity * d.z;
                }
            }
            els[i].radiosity = b;
            els[i].b_max = b_max;
            if slopes {
                world[i] = m;
            }
        }
        self.moment.clear();
        if slopes {
            self.moment.par_extend(els.par_iter().zip(world.par_iter()).with_min_len(1024).map(|(e, m)| {
                if e.is_leaf() {
                    return [Rgb::ZERO; 2];
                }
                let (t1, t2) = crate::math::orthonormal_basis(e.normal);
                [m[0] * t1.x + m[1] * t1.y + m[2] * t1.z, m[0] * t2.x + m[1] * t2.y + m[2] * t2.z]
            }));
        }
        let residual = if max_reflected > 0.0 { max_change / max_reflected } else { max_change };
        self.residuals.push(residual);
        self.converged = residual < self.params.tolerance;
        if energy {
            self.energy.absorbed = absorbed;
            self.energy.escaped = escaped;
        }
    }

    /// The absorbed and escaped power of the current state, as the last push-pull would have
    /// summed them (the same terms in the same order, with each leaf's B as it left them): for
    /// `solve`, whose iterations skip these sums until the end.
    fn energy_pass(&mut self) {
        let (absorbed, escaped) = if self.params.push_slopes {
            energy_sums(&self.hier.elements, &mut self.chain)
        } else {
            energy_sums(&self.hier.elements, &mut self.flat_chain)
        };
        self.energy.absorbed = absorbed;
        self.energy.escaped = escaped;
    }

    /// Refine, gather, push-pull.
    pub fn iterate(&mut self) -> StepReport {
        self.cancel.store(false, Ordering::Relaxed);
        let t = Instant::now();
        let r = self.refine_inner();
        if r.cancelled {
            return self.report(StepKind::Iterate, t, r.refined, r.new_links);
        }
        self.gather_inner();
        if !self.params.gauss_seidel {
            self.push_pull_step();
        }
        self.report(StepKind::Iterate, t, r.refined, r.new_links)
    }

    /// The HSA91 loop: refine → gather/push-pull (`round_iterations` times, or to convergence)
    /// → refine again with the oracle on the new radiosities → … until a refinement of the
    /// converged solution adds at most `settle` of the links (0: none) and those are gathered to
    /// convergence, or the caps (`max_rounds`, `max_iterations` per round) are reached; the last
    /// allowed round converges fully.
    pub fn solve(&mut self, progress: Progress) -> StepReport {
        self.solve_observed(progress, &mut |_| {})
    }

    /// [`solve`](Self::solve), calling `on_round` with the solver after every round's gathers
    /// and push-pull (a consistent, displayable state: the viewer shows the picture as it
    /// forms). The result is the same as `solve`'s.
    pub fn solve_observed(&mut self, progress: Progress, on_round: &mut dyn FnMut(&Self)) -> StepReport {
        self.cancel.store(false, Ordering::Relaxed);
        let t = Instant::now();
        let mut refined_total = 0;
        let mut links_total = 0;
        let rounds = self.params.max_rounds.max(1);
        // Push-pulls inside the loop skip the power sums; one pass at the end makes them.
        let mut energy_due = false;
        for round in 0..rounds {
            progress(u64::from(round), u64::from(rounds));
            // Refinement marks the solution unconverged; remember whether the last gathers had.
            let was_converged = self.converged;
            let r = self.refine_inner();
            refined_total += r.refined;
            links_total += r.new_links;
            if r.cancelled {
                break;
            }
            // A refinement that adds few links (at most `settle` of them) is gathered to
            // convergence before the next one; on an already converged solution it ends the
            // refinement (the mesh has settled).
            let small = r.new_links as f64 <= self.params.settle * self.links.len() as f64;
            let settled = round > 0 && was_converged && small;
            if settled && r.new_links == 0 {
                // Nothing changed since the converged gather: the solution stands.
                self.converged = true;
                break;
            }
            // While the mesh still changes, refine again after `round_iterations` gathers.
            let last = settled || round + 1 == rounds || self.params.oracle == Oracle::Feps;
            let cap = if last || small {
                self.params.max_iterations
            } else {
                self.params.round_iterations.min(self.params.max_iterations)
            };
            let mut iters = 0;
            loop {
                self.gather_inner();
                if !self.params.gauss_seidel {
                    let t = Instant::now();
                    self.push_pull_flat(None, false);
                    self.stats.push_pull_s += t.elapsed().as_secs_f64();
                    energy_due = true;
                }
                iters += 1;
                if self.converged || iters >= cap || self.cancelled() {
                    break;
                }
            }
            self.stats.rounds = round as usize + 1;
            if self.cancelled() || settled || (self.params.oracle == Oracle::Feps && self.converged) {
                break;
            }
            if !self.params.gauss_seidel || iters > 0 {
                on_round(self);
            }
        }
        if energy_due {
            let te = Instant::now();
            self.energy_pass();
            self.stats.push_pull_s += te.elapsed().as_secs_f64();
        }
        // The power balance closes as far as the gathers converged: a preset whose stopping
        // tolerance leaves it open (splash2's 0.005 of B left table-room's at 1.1e-2) gathers on,
        // without refining, until it closes to ENERGY_TOLERANCE (a bounded number of sweeps).
        let mut extra = 0;
        while self.gathered_once
            && self.energy.relative_residual() > ENERGY_TOLERANCE
            && extra < self.params.max_iterations
            && !self.cancelled()
        {
            self.gather_inner();
            if !self.params.gauss_seidel {
                let t = Instant::now();
                self.push_pull_flat(None, true);
                self.stats.push_pull_s += t.elapsed().as_secs_f64();
            }
            extra += 1;
        }
        progress(u64::from(rounds), u64::from(rounds));
        self.report(StepKind::Solve, t, refined_total, links_total)
    }

    // ------------------------------------------------------------------------------------------
    // Read-only views
    // ------------------------------------------------------------------------------------------

    /// Statistics of the current state.
    #[must_use]
    pub fn stats(&self) -> HierarchicalStats {
        let mut s = self.stats.clone();
        s.elements = self.hier.len();
        s.leaves = self.hier.elements.iter().filter(|e| e.is_leaf()).count();
        s.links = self.links.len();
        s.links_full = 0;
        s.links_partial = 0;
        s.links_none = 0;
        for l in self.links.by_receiver.iter().flatten() {
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
            self.hier.elements.capacity() * std::mem::size_of::<Element>() + self.links.memory_bytes();
        s.clusters = self.clusters.as_ref().map_or(0, |t| t.len());
        s.cluster_links = self.cluster_links.len();
        s.memory_bytes += self.cluster_links.capacity() * std::mem::size_of::<ClusterLink>()
            + self.clusters.as_ref().map_or(0, |t| t.len() * std::mem::size_of::<cluster::ClusterNode>());
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
        let elements = self
            .hier
            .elements
            .iter()
            .enumerate()
            .map(|(i, e)| ElementInfo {
                id: i as u32,
                patch: e.patch,
                parent: e.parent(),
                children: e.children(),
                depth: e.depth,
                vertices: e.verts,
                n_vertices: e.n_verts,
                area: e.area,
                reflectance: e.reflectance,
                emission: e.emission,
                radiosity: e.radiosity,
                gathered: e.gathered,
                error_estimate: est[i],
                stop: e.stop,
            })
            .collect();
        let oracle = self.params.oracle;
        let hier = &self.hier;
        let links = self
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
            residuals: self.residuals.clone(),
        }
    }

    /// Each leaf's slope of B, ρ times the irradiance's slope pushed down to it (`Chain`); empty
    /// without `push_slopes`, None for interior elements and flat leaves.
    fn leaf_slopes(&self) -> Vec<Option<crate::solver::Slope>> {
        if !self.params.push_slopes {
            return Vec::new();
        }
        self.hier
            .elements
            .iter()
            .zip(self.chains())
            .map(|(e, own)| {
                let d = own.slope.map(|g| e.reflectance.mul_rgb(g));
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
            chain.push(up.step(e, self.params.push_slopes));
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
        let patch_radiosity = Solution::patch_averages(self.scene.patches.len(), &elements);
        let st = self.stats();
        let mut energy = self.energy;
        if !self.gathered_once {
            // Nothing gathered yet: all emitted power is still "in flight", nothing absorbed.
            energy.absorbed = Rgb::ZERO;
            energy.escaped = Rgb::ZERO;
        }
        Solution {
            method: "hierarchical".into(),
            patch_radiosity,
            energy,
            stats: SolveStats {
                patches: self.scene.patches.len(),
                elements: elements.len(),
                links: st.links,
                iterations: st.iterations,
                rays: st.rays,
                time_s: PhaseTimes {
                    load: 0.0,
                    bvh: self.bvh_s,
                    form_factors: st.refine_s,
                    solve: st.gather_s + st.push_pull_s,
                    total: self.bvh_s + st.refine_s + st.gather_s + st.push_pull_s,
                },
                extra: serde_json::to_value(&st).ok(),
            },
            elements,
        }
    }
}

/// Margin (relative to the pair's size) by which `form_factor_surely_positive` wants each
/// element clearly in front of the other's plane: far above the kernel's own in-plane and
/// clipping tolerances (1e-11, 1e-12).
const SURE_MARGIN: f64 = 1e-6;

/// Is the pair's coupling certainly positive? True when every vertex of each element lies
/// clearly in front of the other's plane: every point of one then sees the other subtend a
/// positive projected solid angle. Symmetric in the pair.
fn form_factor_surely_positive(receiver: &Element, source: &Element) -> bool {
    let margin = SURE_MARGIN * (receiver.diam + source.diam);
    let in_front =
        |a: &Element, b: &Element| b.vertices().iter().all(|&v| a.normal.dot(v - a.centroid) > margin);
    in_front(receiver, source) && in_front(source, receiver)
}

/// The Galerkin coupling G = A_r F_rs = A_s F_sr of elements `r` and `s` (see [`transfer`]),
/// the same number for both orders.
fn coupling_in(hier: &Hierarchy, acc: transfer::Accuracy, r: u32, s: u32, straddle: bool) -> f64 {
    let (p, q) = (hier.get(r), hier.get(s));
    let root = p.parent == NONE && q.parent == NONE;
    transfer::coupling(p, r, q, s, straddle, root, acc, transfer::NO_GAP_BOUND)
}

/// BFeps in units of B.
impl HierarchicalSolver {
    /// The error oracle's relative threshold in units of B: `bf_eps` × the area-weighted mean
    /// over the leaves of the reflected radiosity B − E (largest channel); before any gather,
    /// `bf_eps` × the largest emission.
    fn error_eps(&self) -> f64 {
        let (mut sum, mut area) = (0.0, 0.0);
        for e in self.hier.elements.iter().filter(|e| e.is_leaf()) {
            sum += (e.radiosity - e.emission).max_channel().max(0.0) * e.area;
            area += e.area;
        }
        let mean = if area > 0.0 { sum / area } else { 0.0 };
        if mean > 0.0 { self.params.bf_eps * mean } else { resolve_bf_eps(&self.params, &self.scene) }
    }
}

fn resolve_bf_eps(p: &HierarchicalParams, scene: &Scene) -> f64 {
    if p.bf_relative {
        let e_max = scene.patches.iter().map(|q| q.emission.max_channel()).fold(0.0, f64::max);
        p.bf_eps * e_max
    } else {
        p.bf_eps
    }
}

/// A link receiver `p` ← source `q` with the oracle's geometry cached: the Galerkin form factor
/// F_pq = G / A_p (`g` the pair's coupling, see [`transfer`]), the disk estimates F_pq, F_qp
/// (with |cos| for straddling pairs, whose centroids may lie behind each other's planes while
/// parts of the elements still see each other), which side to split (the larger estimate's:
/// F_pq > F_qp → the source; on a tie, the larger element, then the lower id, so that the
/// mirror link q ← p splits the same element), and the error bound.
fn new_link(
    (p, p_id): (&Element, u32),
    (q, q_id): (&Element, u32),
    g: f64,
    vis: f32,
    straddle: bool,
    conservative: bool,
) -> Link {
    let est = if straddle { disk_abs } else { form_factor::disk };
    let mut fpq = est(p.centroid, p.normal, q.centroid, q.normal, q.area);
    let mut fqp = est(q.centroid, q.normal, p.centroid, p.normal, p.area);
    if straddle && conservative {
        // Centroid-to-centroid estimates can vanish for a pair whose planes cut each other
        // (a lamp standing on a floor: the floor's centroid lies in the lamp's plane, where the
        // kernel is singular and rounding decides the side) while parts of the pair see each
        // other closely: take the Galerkin values and the largest exact point value at four
        // interior points as well.
        fpq = fpq.max(g / p.area).max(straddle_estimate(p, q));
        fqp = fqp.max(g / q.area).max(straddle_estimate(q, p));
    }
    let q_larger = if nearly_equal(q.area, p.area) { q_id < p_id } else { q.area > p.area };
    Link {
        source: q_id,
        ff: (g / p.area) as f32,
        g: g as f32,
        vis,
        fmax: fpq.max(fqp) as f32,
        bound: geometric_variation(p, q) as f32,
        split_source: if nearly_equal(fpq, fqp) { q_larger } else { fpq > fqp },
        unmeasured: false,
        slope_set: false,
        slope: [0.0; 2],
        src_slope: [0.0; 2],
    }
}

/// Relative difference below which two areas or estimates count as a tie (broken by id): the
/// same scene moved or scaled computes them with different rounding, and an exact comparison
/// would then split differently (tests/hard_cases.rs `translation_and_scale_invariance`).
const TIE_REL: f64 = 1e-9;

/// `a` and `b` equal to [`TIE_REL`] (symmetric, so a link and its mirror agree).
pub(super) fn nearly_equal(a: f64, b: f64) -> bool {
    (a - b).abs() <= TIE_REL * a.abs().max(b.abs())
}

/// The largest exact point-to-polygon form factor from four interior points of `p` (at
/// parameters 1/4, 3/4) to `q`: an estimate for straddling pairs that no single point decides.
fn straddle_estimate(p: &Element, q: &Element) -> f64 {
    let mut best: f64 = 0.0;
    for (u, v) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
        let x = visibility::point_on_polygon(p.vertices(), u, v);
        best = best.max(form_factor::point_to_polygon_oriented(x, p.normal, q.vertices(), q.normal));
    }
    best.min(1.0)
}

/// Relative variation of the form factor across a pair of elements, (diam_p + diam_q) / distance,
/// capped at 1: the error bound of a fully visible link in the BF oracle.
fn geometric_variation(p: &Element, q: &Element) -> f64 {
    let d = p.centroid.distance(q.centroid);
    if d > 0.0 { ((p.diam + q.diam) / d).min(1.0) } else { 1.0 }
}

/// The disk estimate with absolute cosines (for straddling pairs).
fn disk_abs(p: DVec3, n: DVec3, c: DVec3, cn: DVec3, area: f64) -> f64 {
    let d = c - p;
    let r2 = d.length_squared();
    if r2 <= 0.0 {
        return 1.0;
    }
    let r = r2.sqrt();
    area * (n.dot(d) / r).abs() * (cn.dot(d) / r).abs() / (std::f64::consts::PI * r2 + area)
}

/// Stable key of an ordered (receiver, source) pair for the visibility jitter.
fn pair_key(receiver: u32, source: u32) -> u64 {
    (u64::from(receiver) << 32) | u64::from(source)
}

/// Signed distances of `q`'s vertices from `p`'s plane, relative to their size.
fn plane_sides(p: &Element, q: &Element) -> (bool, bool) {
    let tol = 1e-9 * (p.diameter() + q.diameter());
    let mut front = false;
    let mut back = false;
    for v in q.vertices() {
        let d = p.normal.dot(*v - p.centroid);
        front |= d > tol;
        back |= d < -tol;
    }
    (front, back)
}

/// How two elements sit relative to each other's planes (computed once per pair).
#[derive(Copy, Clone)]
struct PairSides {
    /// Each has some part strictly in front of the other's plane.
    facing: bool,
    /// One has vertices strictly on both sides of the other's plane.
    straddle: bool,
}

fn pair_sides(p: &Element, q: &Element) -> PairSides {
    let (q_front, q_back) = plane_sides(p, q);
    let (p_front, p_back) = plane_sides(q, p);
    PairSides { facing: q_front && p_front, straddle: (q_front && q_back) || (p_front && p_back) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Patch;

    /// The five-times rule's disk estimate against the exact coupling at five diameters or more
    /// (the lecture quotes the rule as good to about a percent; 3 % allows for off-axis pairs).
    const FIVE_TIMES_REL: f64 = 0.03;
    const ACC: transfer::Accuracy = transfer::Accuracy { tol: 1e-6, five_times: false };
    const ACC5: transfer::Accuracy = transfer::Accuracy { tol: 1e-6, five_times: true };

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
