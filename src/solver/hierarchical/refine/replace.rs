//! Phase C of a refinement pass: the links that replace a receiver's split links (to the
//! split source's children in its own list, to its own children pushed down), with the next
//! pass's verdicts on them. A split pair is replaced in both receivers' lists in the same
//! pass; the second one reuses the first one's new pairs (`PairMemo`) as mirror links.

use super::verdict::{Decision, Split, Verdict};
use crate::geometry::accel::NO_HIT;
use crate::solver::hierarchical::HierarchicalSolver;
use crate::solver::hierarchical::refine::pair_key;
#[cfg(debug_assertions)]
use crate::solver::hierarchical::refine::{new_link, pair_sides};
use crate::solver::hierarchy::NONE;
use crate::solver::link::Link;
use rayon::prelude::*;

/// A receiver with at least this many links to split computes their replacements in parallel.
pub(super) const PARALLEL_SPLITS: usize = 32;

/// What `replace_links` made for one receiver.
pub(super) struct Replaced {
    pub(super) receiver: u32,
    /// Its new own list, and the next pass's verdict on the new links in it.
    pub(super) own: Vec<Link>,
    pub(super) own_verdict: Verdict,
    /// Links pushed down to its children (child k, id `first_child + k`, gets `kids[k]`, in
    /// the order of the split links in the receiver's list), and the verdicts on them.
    pub(super) kids: [Vec<Link>; 4],
    pub(super) kid_verdicts: [Verdict; 4],
    pub(super) first_child: u32,
    pub(super) rays: u64,
    /// The own list gained links (a source was split), at these indices (ascending).
    pub(super) own_changed: bool,
    pub(super) own_new: Vec<u32>,
    pub(super) created: usize,
}

/// The replacement links of one split link (in child order) with their verdicts, and the rays
/// cast for them.
pub(super) type NewLinks = ([Option<(Link, Decision)>; 4], u64);

/// What a new pair's links share, both directions alike: the Galerkin coupling (NaN when not
/// yet computed, for a link the next pass replaces), the visibility estimate, whether it is
/// only the early-exit placeholder, the rays it cost, and the oracle's geometry of the link that computed it (`new_link`: `fmax`
/// and `bound` are symmetric in the pair, and the mirror splits the same element, so its
/// `split_source` is the opposite).
#[derive(Copy, Clone, Debug)]
pub(super) struct PairOutcome {
    pub(super) g: f64,
    pub(super) vis: f32,
    pub(super) unmeasured: bool,
    pub(super) clear: bool,
    pub(super) split_source: bool,
    pub(super) fmax: f32,
    pub(super) bound: f32,
    pub(super) rays: u64,
}

/// The new pairs of one split link, in child order (None: the pair has no link, which is
/// symmetric too: same patch, facing away, or a zero coupling).
pub(super) type SplitOutcome = [Option<PairOutcome>; 4];

/// Shards of the per-pass memo of split links: a split pair is replaced in both receivers'
/// lists in the same pass (the verdicts are symmetric: both split the same element), and the
/// second receiver reuses the first one's four new pairs (coupling, visibility) instead of
/// computing them again. Keyed by the split link, not by each new pair: one look-up per four
/// links (a hash probe and a lock are two cache misses; one entry per new pair would pay them
/// four times).
pub(in crate::solver::hierarchical) struct PairMemo(Vec<MemoShard>);

/// One shard, on its own cache lines: the two threads lock neighbouring shards all the time.
#[repr(align(128))]
#[derive(Default)]
pub(super) struct MemoShard(std::sync::Mutex<PairMap>);

/// A memo shard: `pair_key` packs two ids, mixed once with splitmix64 (`WordHasher`).
pub(super) type PairMap = crate::math::WordMap<u64, SplitOutcome>;

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
    pub(super) fn get(&self, key: u64) -> Option<SplitOutcome> {
        self.shard(key).get(&key).copied()
    }
    pub(super) fn put(&self, key: u64, out: SplitOutcome) {
        self.shard(key).insert(key, out);
    }
    pub(super) fn clear(&mut self) {
        for s in &mut self.0 {
            s.0.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner).clear();
        }
    }
}

impl HierarchicalSolver {
    /// New links replacing the split ones of receiver `r` (its own list, links for its
    /// children), with the next pass's verdicts on them.
    pub(super) fn replace_links(&self, r: u32, splits: &[(u32, Split)]) -> Replaced {
        let old = &self.graph.links.by_receiver[r as usize];
        // The new links of each split link (its source's or its receiver's children, in child
        // order), in parallel when the receiver has many: one busy receiver must not keep a
        // thread waiting. Each split link has its own shadow cache, so the result does not
        // depend on how the work is divided.
        let new_of = |&(i, side): &(u32, Split)| self.split_link(r, &old[i as usize], side);
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
            own_new: Vec::new(),
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
                        rep.own_new.push(rep.own.len() as u32);
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

    /// The replacement links of the split link `l` of receiver `r` (to its source's or its
    /// receiver's children, in child order), with their verdicts, and the rays cast for them:
    /// made here, or the mirror images of those its mirror link made earlier in this pass.
    fn split_link(&self, r: u32, l: &Link, side: Split) -> NewLinks {
        let (parent, other) = if side == Split::Source { (l.source, r) } else { (r, l.source) };
        let children = self.hier.get(parent).children().expect("split in phase B");
        let ends = |c: u32| if side == Split::Source { (r, c) } else { (c, l.source) };
        // The mirror link splits the same element: keyed by (split element, other end),
        // both directions find the same entry.
        let key = pair_key(parent, other);
        let mut out = [None; 4];
        let mut rays = 0;
        if let Some(made) = self.graph.pair_memo.get(key) {
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
        self.graph.pair_memo.put(key, made);
        (out, rays)
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
            let mut made = new_link(
                (p, receiver),
                (q, source),
                out.g,
                out.vis,
                straddle,
                self.setup.params.conservative,
            );
            made.unmeasured = out.unmeasured;
            made.clear = out.clear;
            // (Debug formatting: an unmeasured link's coupling is NaN, which `==` rejects.)
            debug_assert_eq!(format!("{link:?}"), format!("{made:?}"), "the mirror of a pair's link");
        }
        (link, self.decide(receiver, p, &link))
    }
}
