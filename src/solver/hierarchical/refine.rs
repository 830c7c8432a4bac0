//! Refine (HSA91, sec. 4, the lecture's `Refine(p, q, Feps, Aeps)`): apply the oracle to every link
//! and replace the links it rejects by links to the children of the split side, until nothing
//! splits.
//!
//! ```text
//! Refine(p, q):  if Oracle(p, q) accepts            → Link(p, q)
//!                else if F_pq > F_qp and q splits    → for each child c of q: Refine(p, c)
//!                else if p splits                    → for each child c of p: Refine(c, q)
//!                else                                → Link(p, q)
//! ```
//! Each pass: (A, parallel, read-only) a verdict per link; (B, sorted ids) split the chosen
//! elements so ids are deterministic; (C, parallel) the replacement links' coupling
//! ([`super::transfer`]), visibility and verdicts; (D, receiver order) install them. Every
//! decision is symmetric in the pair, so the links q ← p mirror the links p ← q at every level.
//! The oracles themselves are in [`super::oracle`]; the input patches' (and clusters') first
//! links in [`super::linking`].
//!
//! ## The row check
//! Whatever the oracle, a point's form factors to the rest of the scene sum to at most 1 (its
//! hemisphere). A leaf gathers through its own links and, pushed down, its ancestors' (each the
//! average over the ancestor, moved along its slope):
//!
//! ```text
//! row_x = Σ_{links a ← q, a = x or an ancestor} [ F_aq + slope_aq · (c_x − c_a) ] V_aq   ≤ 1
//! ```
//! Where row_x > 1 the inherited averages overstate x's share (a wall's leaf by a corner, whose
//! view the adjacent wall fills, inherits the whole wall's share of the far walls), its radiosity
//! follows the row, and the solve creates light (the energy balance's escaped power is
//! Σ A_x B_x (1 − row_x)). At each refinement after a gather (`row_split`, with
//! `HierarchicalParams::row_tol`): every leaf whose excess adds more than `row_tol` × the mean
//! reflected radiosity to its answer (ρ_x H_x (row_x − 1) / row_x) marks its ancestors with its
//! excess; of a marked element, the largest links that together carry twice the excess are
//! split on its side, so their averages are replaced by its children's own. The decision
//! reads only the pair's coupling, V and the two elements' marks, so a link and its mirror
//! agree.

use super::*;

/// The row check pushes down, of an element with an excess row below it, the largest links
/// that together carry this multiple of the excess (`row_split`).
pub(super) const ROW_SHARE: f64 = 2.0;

/// V of a link the next refinement pass replaces whatever its V (one ray found it positive):
/// above 1, so "fully visible" for the oracle, and never read otherwise (see `make_link`).
pub(super) const UNMEASURED_VIS: f32 = 2.0;

/// An [`IdSet`] holding at least 1/this of the ids up to its largest is read off its marks.
pub(super) const DENSE_ID_SET: usize = 16;

/// A set of element ids, read back in ascending order (marks instead of sorting duplicates).
#[derive(Default)]
pub(super) struct IdSet {
    mark: Vec<bool>,
    ids: Vec<u32>,
}

impl IdSet {
    pub(super) fn insert(&mut self, id: u32) {
        let i = id as usize;
        if i >= self.mark.len() {
            self.mark.resize(i + 1, false);
        }
        if !self.mark[i] {
            self.mark[i] = true;
            self.ids.push(id);
        }
    }

    pub(super) fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// The ids, ascending; the set is left empty. A dense set is read off its marks (one pass,
    /// no sort).
    pub(super) fn take_sorted(&mut self) -> Vec<u32> {
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

/// Receivers whose link lists the oracle's first pass loads together (see `refine_inner`).
pub(super) const TOUCH_AHEAD: usize = 16;

/// A receiver with at least this many links to split computes their replacements in parallel.
pub(super) const PARALLEL_SPLITS: usize = 32;

/// What `replace_links` made for one receiver.
pub(super) struct Replaced {
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
pub(super) struct Verdict {
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
pub(super) enum Split {
    Source,
    Receiver,
}

/// The oracle's decision on one link: `Ok(side to split)` or `Err(why it is kept)`.
pub(super) type Decision = Result<Split, StopReason>;

/// The replacement links of one split link (in child order) with their verdicts, and the rays
/// cast for them.
pub(super) type NewLinks = ([Option<(Link, Decision)>; 4], u64);

/// One receiver's verdict in pass A.
pub(super) type ReceiverDecision = (u32, Verdict);

/// What a new pair's links share, both directions alike: the Galerkin coupling (NaN when not
/// yet computed, for a link the next pass replaces), the visibility estimate, whether it is
/// only the early-exit placeholder, the rays it cost, and the oracle's geometry of the link that computed it (`new_link`: `fmax`
/// and `bound` are symmetric in the pair, and the mirror splits the same element, so its
/// `split_source` is the opposite).
#[derive(Copy, Clone, Debug)]
pub(super) struct PairOutcome {
    g: f64,
    vis: f32,
    unmeasured: bool,
    clear: bool,
    split_source: bool,
    fmax: f32,
    bound: f32,
    rays: u64,
}

/// The new pairs of one split link, in child order (None: the pair has no link, which is
/// symmetric too: same patch, facing away, or a zero coupling).
pub(super) type SplitOutcome = [Option<PairOutcome>; 4];

/// Shards of the per-pass memo of split links: a split pair is replaced in both receivers'
/// lists in the same pass (the verdicts are symmetric: both split the same element), and the
/// second receiver reuses the first one's four new pairs (coupling, visibility) instead of
/// computing them again. Keyed by the split link, not by each new pair: one look-up per four
/// links (the memo's hash probes and locks, two cache misses each, were 9 % of a `splash2`
/// solve when each new pair had its own entry).
pub(super) struct PairMemo(Vec<MemoShard>);

/// One shard, on its own cache lines: the two threads lock neighbouring shards all the time.
#[repr(align(128))]
#[derive(Default)]
pub(super) struct MemoShard(std::sync::Mutex<PairMap>);

/// A memo shard: keys are already well mixed (`pair_key` packs two ids; the hasher mixes them
/// once with splitmix64 instead of SipHash, a third of the memo's cost).
pub(super) type PairMap =
    std::collections::HashMap<u64, SplitOutcome, std::hash::BuildHasherDefault<KeyHasher>>;

/// splitmix64 of a `u64` key (see `PairMap`).
#[derive(Default)]
pub(super) struct KeyHasher(u64);

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
        PairMemo((0..64).map(|_| MemoShard::default()).collect())
    }
}

impl PairMemo {
    fn shard(&self, key: u64) -> std::sync::MutexGuard<'_, PairMap> {
        let i = ((key ^ (key >> 32)) % self.0.len() as u64) as usize;
        self.0[i].0.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }
    fn get(&self, key: u64) -> Option<SplitOutcome> {
        self.shard(key).get(&key).copied()
    }
    fn put(&self, key: u64, out: SplitOutcome) {
        self.shard(key).insert(key, out);
    }
    fn clear(&mut self) {
        for s in &mut self.0 {
            s.0.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner).clear();
        }
    }
}

impl HierarchicalSolver {
    /// One refinement pass: on the first call, link every mutually visible pair of input
    /// patches; then apply the oracle to every link until nothing splits.
    pub fn refine_step(&mut self) -> StepReport {
        self.cancel.store(false, Ordering::Relaxed);
        self.refine_inner()
    }

    pub(super) fn refine_inner(&mut self) -> StepReport {
        let t = Instant::now();
        let mut new_links = 0;
        if self.params.oracle == Oracle::Error && self.params.bf_relative {
            self.bf_eps = self.error_eps();
        }
        self.oracle_b.clear();
        self.sync_oracle_b();
        // The gather plan is updated where the link lists change (below), if it was whole.
        let plan_whole = self.plan_valid;
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
        // The row check reads the rows of the links the last solution gathered through (none
        // before the first gather). Not with cluster links: their transfer is a bounded
        // approximation whose share of a row no element link's split corrects (furnished-2k
        // `interactive`: 175 k links, then 505 k and the budget).
        self.row_floor =
            if self.gathered_once && self.cluster_links.is_empty() { self.row_floors() } else { Vec::new() };
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
                        let known = err_field
                            .take()
                            .map_or_else(|| std::mem::take(&mut self.error_kernels), |f| f.kernels);
                        err_field = Some(self.error_field(&known));
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
                    None => {
                        let lists = &self.links.by_receiver;
                        let ids: Vec<u32> = (0..self.hier.len() as u32).collect();
                        ids.par_chunks(TOUCH_AHEAD)
                            .flat_map_iter(|chunk| {
                                // Each list is its own allocation: load the first link of all of
                                // the chunk's lists at once, so their cache misses overlap
                                // instead of stalling one receiver after the other.
                                let touched = chunk.iter().fold(0u32, |acc, &r| {
                                    acc ^ lists[r as usize].first().map_or(0, |l| l.source)
                                });
                                std::hint::black_box(touched);
                                chunk
                                    .iter()
                                    .filter(|&&r| !lists[r as usize].is_empty())
                                    .map(|&r| self.decide_receiver(r, None))
                            })
                            .collect()
                    }
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
        self.row_floor = Vec::new();
        // The error oracle's kernels serve the next refinement's field (`oracle::ErrorField`).
        if let Some(f) = err_field {
            self.error_kernels = f.kernels;
        }
        let changed = changed.take_sorted();
        self.update_sums(&changed);
        if plan_whole {
            self.plan_changed.extend_from_slice(&changed);
            self.plan_valid = true;
        }
        self.converged = false;
        self.stats.links_created += new_links as u64;
        self.stats.refine_s += t.elapsed().as_secs_f64();
        self.oracle_b.clear();
        self.report(StepKind::Refine, t, refined, new_links)
    }

    pub(super) fn can_split(&self, e: &Element) -> Result<(), StopReason> {
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
    pub(super) fn source_b(&self, id: u32) -> [f64; 2] {
        self.oracle_b.get(id as usize).copied().unwrap_or_else(|| {
            let e = self.hier.get(id);
            [e.b_max, e.radiosity.max_channel()]
        })
    }

    /// Whether links weight their visibility samples by the kernel (`visibility_sample`): the
    /// error oracle's do; the other oracles keep the plain fraction (SPLASH-2's semantics).
    pub(super) fn weighted_visibility(&self) -> bool {
        self.params.oracle == Oracle::Error
    }

    /// How accurately link coefficients are computed: the Gauss rules to `link_tol`, the
    /// adaptive cubature of touching and near pairs, with the error oracle at a relative ε, to
    /// `max(link_tol, LINK_TOL_PER_EPS · ε)` (see [`transfer::LINK_TOL_PER_EPS`]).
    pub(super) fn accuracy(&self) -> transfer::Accuracy {
        let p = &self.params;
        let adaptive_tol = if p.oracle == Oracle::Error && p.bf_relative && p.link_tol > 0.0 {
            p.link_tol.max(transfer::LINK_TOL_PER_EPS * p.bf_eps)
        } else {
            p.link_tol
        };
        transfer::Accuracy { tol: p.link_tol, adaptive_tol, five_times: p.five_times }
    }

    /// The pair's Galerkin coupling (see [`coupling_in`]).
    pub(super) fn coupling(&self, r: u32, s: u32, straddle: bool) -> f64 {
        coupling_in(&self.hier, self.accuracy(), r, s, straddle)
    }

    /// The oracle's radiosity term of the pair (receiver `r`, source `s`): the larger of the two
    /// elements' `source_b`, so that the link r ← s and its mirror s ← r get the same verdict
    /// and the pair's links stay mirror images (see [`transfer`]: energy is conserved only if
    /// every link has its mirror at the same level).
    pub(super) fn pair_b(&self, r: u32, s: u32) -> [f64; 2] {
        let (a, b) = (self.source_b(r), self.source_b(s));
        [a[0].max(b[0]), a[1].max(b[1])]
    }

    /// Extend the oracle's compact copy of B to every element (see `source_b`).
    pub(super) fn sync_oracle_b(&mut self) {
        let start = self.oracle_b.len();
        let els = &self.hier.elements;
        self.oracle_b
            .extend(els[start.min(els.len())..].iter().map(|e| [e.b_max, e.radiosity.max_channel()]));
    }

    /// The oracle on all of receiver `r`'s links (the first pass of a refinement; later passes
    /// use the verdicts made with the new links, the oracle's inputs not changing during a
    /// refinement).
    pub(super) fn decide_receiver(&self, r: u32, field: Option<&oracle::ErrorField>) -> ReceiverDecision {
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
    pub(super) fn decide(&self, r: u32, p: &Element, link: &Link) -> Decision {
        let class = link.class();
        if class == VisClass::None || !self.wants_split(link, class, self.pair_b(r, link.source)) {
            return match self.row_split(r, link.source, link) {
                Some(x) => Ok(if x == r { Split::Receiver } else { Split::Source }),
                None => Err(self.below_reason()),
            };
        }
        self.split_side(p, link)
    }

    /// Per element, the smallest F·V of its links that the row check splits (0: none): of an
    /// element with leaves below it whose row exceeds 1 by up to x where that matters
    /// (`push_pull::row_excess`), its largest links that together carry [`ROW_SHARE`]·x (all of
    /// them if they carry less).
    pub(super) fn row_floors(&mut self) -> Vec<f32> {
        let mut ex = self.row_excess_now();
        let lists = &self.links.by_receiver;
        ex.par_iter_mut().enumerate().with_min_len(256).filter(|(_, x)| **x > 0.0).for_each(|(r, x)| {
            let mut fv: Vec<f64> =
                lists[r].iter().map(|l| f64::from(l.ff) * f64::from(l.vis).clamp(0.0, 1.0)).collect();
            fv.sort_unstable_by(|a, b| b.total_cmp(a));
            let want = ROW_SHARE * f64::from(*x);
            let mut sum = 0.0;
            let mut floor = f64::INFINITY;
            for f in fv {
                if f <= 0.0 || sum >= want {
                    break;
                }
                sum += f;
                floor = f;
            }
            // (A hair below: the link itself compares G / A in f64.)
            *x = if floor.is_finite() { (floor * (1.0 - 1e-6)) as f32 } else { 0.0 };
        });
        ex
    }

    /// The row check (`HierarchicalParams::row_tol`) on the pair of elements `a`, `b` joined by
    /// `link` (either direction: the same answer for the link and its mirror): the element to
    /// split, if one of them has leaves below it whose row of F·V exceeds 1 and the link is one
    /// of its largest, which together carry [`ROW_SHARE`] times that excess into it (the floor
    /// `HierarchicalSolver::row_floors` computes). The lower id is asked first.
    ///
    /// A point's row of form factors is at most 1 (its hemisphere), whatever the scene. A leaf
    /// whose row exceeds it inherits a coarse link's average F where its own share is smaller
    /// (a wall's leaf by the corner, whose view the adjacent wall fills, inherits the whole
    /// wall's share of the far walls); its radiosity follows the row, and the solve creates
    /// light (table-room `interactive`: escaped −2.1 % of the emitted power). Pushing the
    /// ancestors' links down a level replaces their averages by the children's own.
    pub(super) fn row_split(&self, a: u32, b: u32, link: &Link) -> Option<u32> {
        if self.row_floor.is_empty() {
            return None;
        }
        let v = f64::from(link.vis).clamp(0.0, 1.0);
        let g = f64::from(link.g) * v;
        if g.is_nan() || g <= 0.0 {
            return None;
        }
        let wants = |x: u32| {
            let floor = f64::from(self.row_floor.get(x as usize).copied().unwrap_or(0.0));
            let e = self.hier.get(x);
            floor > 0.0 && g / e.area >= floor && self.can_split(e).is_ok()
        };
        let (lo, hi) = if a < b { (a, b) } else { (b, a) };
        if wants(lo) {
            Some(lo)
        } else if wants(hi) {
            Some(hi)
        } else {
            None
        }
    }

    /// Why a link the oracle does not want to split is kept.
    pub(super) fn below_reason(&self) -> StopReason {
        match self.params.oracle {
            Oracle::Feps => StopReason::BelowFeps,
            Oracle::Bf => StopReason::BelowBfEps,
            Oracle::Error => StopReason::BelowErrorEps,
        }
    }

    /// Does the oracle's estimate call for splitting this link were its visibility of class
    /// `class` (Full or Partial)? `b`: the source's `source_b`.
    pub(super) fn wants_split(&self, link: &Link, class: VisClass, [b_max, b_channel]: [f64; 2]) -> bool {
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
    pub(super) fn split_side(&self, p: &Element, link: &Link) -> Result<Split, StopReason> {
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
    pub(super) fn replace_links(&self, r: u32, splits: &[(u32, Split)]) -> Replaced {
        let old = &self.links.by_receiver[r as usize];
        // The new links of each split link (its source's or its receiver's children, in child
        // order), in parallel when the receiver has many: one busy receiver must not keep a
        // thread waiting. Each split link has its own shadow cache, so the result does not
        // depend on how the work is divided.
        let new_of = |&(i, side): &(u32, Split)| -> NewLinks {
            let l = &old[i as usize];
            let (parent, other) = if side == Split::Source { (l.source, r) } else { (r, l.source) };
            let children = self.hier.get(parent).children().expect("split in phase B");
            let ends = |c: u32| if side == Split::Source { (r, c) } else { (c, l.source) };
            // The mirror link splits the same element: keyed by (split element, other end),
            // both directions find the same entry.
            let key = pair_key(parent, other);
            let mut out = [None; 4];
            let mut rays = 0;
            if let Some(made) = self.pair_memo.get(key) {
                for (k, (c, o)) in children.into_iter().zip(made).enumerate() {
                    let (receiver, source) = ends(c);
                    if let Some(o) = o {
                        out[k] = Some(self.mirror_link(receiver, source, o));
                        // Rays are counted once, by the receiver with the lower id, whichever
                        // direction computed them.
                        rays += if receiver < source { o.rays } else { 0 };
                    }
                }
                return (out, rays);
            }
            let mut last = NO_HIT;
            let mut made: SplitOutcome = [None; 4];
            for (k, c) in children.into_iter().enumerate() {
                let (receiver, source) = ends(c);
                let (nl, outcome) = self.make_link(receiver, source, l.clear, &mut last);
                out[k] = nl;
                made[k] = outcome;
                rays += match outcome {
                    Some(o) if receiver < source => o.rays,
                    _ => 0,
                };
            }
            self.pair_memo.put(key, made);
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

    /// A link receiver ← source, or None when the source contributes nothing geometrically;
    /// and what the mirror link source ← receiver can be made of (see `PairMemo`).
    ///
    /// `last`: the shadow cache (see [`Accel::occluded_cached`]) shared by nearby pairs.
    /// With the link comes the next refinement pass's decision on it (see `decide`).
    pub(super) fn make_link(
        &self,
        receiver: u32,
        source: u32,
        clear: bool,
        last: &mut u32,
    ) -> (Option<(Link, Decision)>, Option<PairOutcome>) {
        let p = self.hier.get(receiver);
        let q = self.hier.get(source);
        if p.patch == q.patch {
            return (None, None);
        }
        let sides = pair_sides(p, q);
        if !sides.facing {
            return (None, None);
        }
        let key = pair_key(receiver.min(source), receiver.max(source));
        let (made, cast, g) = self.make_pair_link(receiver, source, sides, key, clear, last);
        let outcome = made.as_ref().map(|(l, _)| PairOutcome {
            g,
            vis: l.vis,
            unmeasured: l.unmeasured,
            clear: l.clear,
            split_source: l.split_source,
            fmax: l.fmax,
            bound: l.bound,
            rays: cast,
        });
        (made, outcome)
    }

    /// The link receiver ← source of a pair its mirror link made earlier in this pass: what
    /// `new_link` would make of the outcome, without recomputing the symmetric estimates.
    fn mirror_link(&self, receiver: u32, source: u32, out: PairOutcome) -> (Link, Decision) {
        let p = self.hier.get(receiver);
        let link = Link {
            source,
            ff: (out.g / p.area) as f32,
            g: out.g as f32,
            vis: out.vis,
            fmax: out.fmax,
            bound: out.bound,
            split_source: !out.split_source,
            unmeasured: out.unmeasured,
            slope_set: false,
            clear: out.clear,
            slope: [0.0; 2],
            src_slope: [0.0; 2],
        };
        #[cfg(debug_assertions)]
        {
            let q = self.hier.get(source);
            let straddle = pair_sides(p, q).straddle;
            let mut made =
                new_link((p, receiver), (q, source), out.g, out.vis, straddle, self.params.conservative);
            made.unmeasured = out.unmeasured;
            made.clear = out.clear;
            // (Debug formatting: an unmeasured link's coupling is NaN, which `==` rejects.)
            debug_assert_eq!(format!("{link:?}"), format!("{made:?}"), "the mirror of a pair's link");
        }
        (link, self.decide(receiver, p, &link))
    }

    /// `make_link` of a pair not made yet in this pass; also returns the pair's coupling (NaN
    /// when left uncomputed).
    pub(super) fn make_pair_link(
        &self,
        receiver: u32,
        source: u32,
        sides: PairSides,
        key: u64,
        clear: bool,
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
        // A pair below one whose shaft was empty (`clear`) lies in that shaft: it sees itself
        // whole, V = 1 exactly, with no ray cast (error oracle, see below).
        let mut shaft = error_oracle && clear;
        let (vis, mut cast) = if shaft { (1.0, 0) } else { vis_with(rays, 0, stop) };
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
        } else if vis == 1.0
            && !shaft
            && error_oracle
            && self.accel.shaft_clear(&self.scene, lo.vertices(), hi.vertices(), [lo.patch, hi.patch])
        {
            // Every ray passed and the pair's shaft is empty (`Accel::shaft_clear`): V = 1
            // exactly, for this pair and all those below it, without the confirmation's rays.
            // (Tested only here: on pairs whose first rays are blocked the test is wasted.)
            shaft = true;
        } else if vis == 1.0
            && !shaft
            && ((split_partial && self.params.conservative) || error_oracle)
            && self.params.zero_confirm > 0
        {
            // Symmetrically, an all-visible estimate ends a refinement that any partial one
            // continues (the next pass splits this link only if partially visible): accepted as
            // it is, each level keeps P(V̂ = 1) · 1 of the link where V is due, a compounding
            // bright bias that created light (splash_room `interactive`: the floor's rows of
            // F·V summed to 1.11 with the solver's V, 1.00 with 256 weighted rays; escaped/
            // emitted −11 %). Confirmed the same way: a blocked ray settles the split, else the
            // fresh estimate stands (unbiased, as for the zeros).
            let more = self.params.zero_confirm.saturating_mul(rays);
            let confirm = if self.early_exit && split_partial { Stop::AtMixed } else { Stop::Never };
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
        link.clear = shaft;
        (Some((link, self.decide(receiver, p, &link))), cast, g)
    }

    /// Measure V of the links still marked unmeasured (refinement stopped, by the link
    /// budget or a cancel, before the pass that would have replaced them).
    pub(super) fn measure_unmeasured(&mut self) {
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
}

/// Margin (relative to the pair's size) by which `form_factor_surely_positive` wants each
/// element clearly in front of the other's plane: far above the kernel's own in-plane and
/// clipping tolerances (1e-11, 1e-12).
pub(super) const SURE_MARGIN: f64 = 1e-6;

/// Is the pair's coupling certainly positive? True when every vertex of each element lies
/// clearly in front of the other's plane: every point of one then sees the other subtend a
/// positive projected solid angle. Symmetric in the pair.
pub(super) fn form_factor_surely_positive(receiver: &Element, source: &Element) -> bool {
    let margin = SURE_MARGIN * (receiver.diam + source.diam);
    let in_front =
        |a: &Element, b: &Element| b.vertices().iter().all(|&v| a.normal.dot(v - a.centroid) > margin);
    in_front(receiver, source) && in_front(source, receiver)
}

/// The Galerkin coupling G = A_r F_rs = A_s F_sr of elements `r` and `s` (see [`transfer`]),
/// the same number for both orders.
pub(super) fn coupling_in(hier: &Hierarchy, acc: transfer::Accuracy, r: u32, s: u32, straddle: bool) -> f64 {
    let (p, q) = (hier.get(r), hier.get(s));
    let root = p.parent == NONE && q.parent == NONE;
    transfer::coupling(p, r, q, s, straddle, root, acc, transfer::NO_GAP_BOUND)
}

impl HierarchicalSolver {
    /// The area-weighted mean over the leaves of the reflected radiosity B − E (largest channel).
    pub(crate) fn mean_reflected(&self) -> f64 {
        let (mut sum, mut area) = (0.0, 0.0);
        for e in self.hier.elements.iter().filter(|e| e.is_leaf()) {
            sum += (e.radiosity - e.emission).max_channel().max(0.0) * e.area;
            area += e.area;
        }
        if area > 0.0 { sum / area } else { 0.0 }
    }

    /// The error oracle's relative threshold in units of B: `bf_eps` × the area-weighted mean
    /// over the leaves of the reflected radiosity B − E (largest channel); before any gather,
    /// `bf_eps` × the largest emission.
    fn error_eps(&self) -> f64 {
        let mean = self.mean_reflected();
        if mean > 0.0 { self.params.bf_eps * mean } else { resolve_bf_eps(&self.params, &self.scene) }
    }
}

pub(super) fn resolve_bf_eps(p: &HierarchicalParams, scene: &Scene) -> f64 {
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
pub(super) fn new_link(
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
        clear: false,
        slope: [0.0; 2],
        src_slope: [0.0; 2],
    }
}

/// Relative difference below which two areas or estimates count as a tie (broken by id): the
/// same scene moved or scaled computes them with different rounding, and an exact comparison
/// would then split differently (tests/hard_cases.rs `translation_and_scale_invariance`).
pub(super) const TIE_REL: f64 = 1e-9;

/// `a` and `b` equal to [`TIE_REL`] (symmetric, so a link and its mirror agree).
pub(super) fn nearly_equal(a: f64, b: f64) -> bool {
    (a - b).abs() <= TIE_REL * a.abs().max(b.abs())
}

/// The largest exact point-to-polygon form factor from four interior points of `p` (at
/// parameters 1/4, 3/4) to `q`: an estimate for straddling pairs that no single point decides.
pub(super) fn straddle_estimate(p: &Element, q: &Element) -> f64 {
    let mut best: f64 = 0.0;
    for (u, v) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
        let x = visibility::point_on_polygon(p.vertices(), u, v);
        best = best.max(form_factor::point_to_polygon_oriented(x, p.normal, q.vertices(), q.normal));
    }
    best.min(1.0)
}

/// Relative variation of the form factor across a pair of elements, (diam_p + diam_q) / distance,
/// capped at 1: the error bound of a fully visible link in the BF oracle.
pub(super) fn geometric_variation(p: &Element, q: &Element) -> f64 {
    let d = p.centroid.distance(q.centroid);
    if d > 0.0 { ((p.diam + q.diam) / d).min(1.0) } else { 1.0 }
}

/// The disk estimate with absolute cosines (for straddling pairs).
pub(super) fn disk_abs(p: DVec3, n: DVec3, c: DVec3, cn: DVec3, area: f64) -> f64 {
    let d = c - p;
    let r2 = d.length_squared();
    if r2 <= 0.0 {
        return 1.0;
    }
    let r = r2.sqrt();
    area * (n.dot(d) / r).abs() * (cn.dot(d) / r).abs() / (std::f64::consts::PI * r2 + area)
}

/// Stable key of an ordered (receiver, source) pair for the visibility jitter.
pub(super) fn pair_key(receiver: u32, source: u32) -> u64 {
    (u64::from(receiver) << 32) | u64::from(source)
}

/// Signed distances of `q`'s vertices from `p`'s plane, relative to their size.
pub(super) fn plane_sides(p: &Element, q: &Element) -> (bool, bool) {
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
pub(super) struct PairSides {
    /// Each has some part strictly in front of the other's plane.
    pub(super) facing: bool,
    /// One has vertices strictly on both sides of the other's plane.
    pub(super) straddle: bool,
}

pub(super) fn pair_sides(p: &Element, q: &Element) -> PairSides {
    let (q_front, q_back) = plane_sides(p, q);
    let (p_front, p_back) = plane_sides(q, p);
    PairSides { facing: q_front && p_front, straddle: (q_front && q_back) || (p_front && p_back) }
}
