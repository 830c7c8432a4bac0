//! New links: a pair's Galerkin coupling G = A_p F_pq = A_q F_qp ([`super::super::transfer`])
//! and its visibility V, estimated in the pair's canonical order so that a link and its
//! mirror carry the same F·V·A, with as few rays as the next pass's verdict needs.

use super::pair::{PairSides, new_link, pair_key, pair_sides};
use super::replace::PairOutcome;
use super::verdict::Decision;
use crate::geometry::accel::NO_HIT;
use crate::geometry::visibility::{self, Stop};
use crate::solver::hierarchical::{HierarchicalSolver, transfer};
use crate::solver::hierarchy::{Element, Hierarchy, NONE};
use crate::solver::link::{Link, VisClass};
use crate::solver::params::Oracle;
use rayon::prelude::*;

/// Which visibility classes the next pass would split a new link in.
#[derive(Copy, Clone)]
struct SplitClasses {
    full: bool,
    partial: bool,
}

/// A pair's two elements in canonical order (lower id first) and its key: the rays between
/// them are the same for the link and its mirror.
struct PairRays<'a> {
    lo: &'a Element,
    hi: &'a Element,
    key: u64,
}

/// What a new link's visibility rays settled.
enum LinkVis {
    /// The next pass splits the link whatever its exact V: the V that tells its class
    /// ([`UNMEASURED_VIS`] when it is visible at all), never read otherwise.
    Unmeasured(f32),
    /// V measured, and whether the pair's shaft is empty (V = 1 exactly, for this pair and
    /// all those below it).
    Measured { vis: f64, shaft: bool },
}

/// V of a link the next refinement pass replaces whatever its V (one ray found it positive):
/// above 1, so "fully visible" for the oracle, and never read otherwise (see `make_link`).
pub(super) const UNMEASURED_VIS: f32 = 2.0;

impl HierarchicalSolver {
    /// Whether links weight their visibility samples by the kernel (`visibility_sample`): the
    /// error oracle's do; the other oracles keep the plain fraction (SPLASH-2's semantics).
    pub(in crate::solver::hierarchical) fn weighted_visibility(&self) -> bool {
        self.setup.params.oracle == Oracle::Error
    }

    /// How accurately link coefficients are computed: the Gauss rules to `link_tol`, the
    /// adaptive cubature of touching and near pairs, with the error oracle at a relative ε, to
    /// `max(link_tol, LINK_TOL_PER_EPS · ε)` (see [`transfer::LINK_TOL_PER_EPS`]).
    pub(in crate::solver::hierarchical) fn accuracy(&self) -> transfer::Accuracy {
        let p = &self.setup.params;
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
        let mut link =
            new_link((p, receiver), (q, source), g, 1.0, sides.straddle, self.setup.params.conservative);
        let splits = self.split_classes(receiver, p, &link);
        // Visibility in the pair's canonical order (lower id first): the mirror link gets the
        // very same estimate.
        let (lo, hi) = if receiver < source { (p, q) } else { (q, p) };
        let pair = PairRays { lo, hi, key };
        let (vis, cast) = self.link_visibility(&pair, splits, clear, last);
        match vis {
            LinkVis::Unmeasured(v) => {
                link.vis = v;
                link.unmeasured = true;
            }
            LinkVis::Measured { vis, shaft } => {
                if surely {
                    g = self.coupling(receiver, source, false);
                    link.ff = (g / p.area) as f32;
                    link.g = g as f32;
                }
                link.vis = vis as f32;
                link.clear = shaft;
            }
        }
        (Some((link, self.decide(receiver, p, &link))), cast, g)
    }

    /// Which visibility classes the next pass would split the new link r ← s in (the side
    /// does not depend on V; a split when fully visible implies one when partially visible:
    /// the partial test uses a bound of 1 instead of ≤ 1, a source term b_max ≥ the max channel
    /// of B, and a threshold `partial_bf_factor` ≤ 1 times the full one). The error oracle
    /// decides per pass from its field, never per link: neither.
    fn split_classes(&self, receiver: u32, p: &Element, link: &Link) -> SplitClasses {
        let (full, partial) = if self.setup.params.oracle != Oracle::Error && self.split_side(p, link).is_ok()
        {
            let b = self.pair_b(receiver, link.source);
            (self.wants_split(link, VisClass::Full, b), self.wants_split(link, VisClass::Partial, b))
        } else {
            (false, false)
        };
        debug_assert!(!full || partial, "a full-visibility split must imply a partial one");
        SplitClasses { full, partial }
    }

    /// A new link's visibility, and the rays cast for it. A link that the next refinement pass
    /// splits whatever its exact V is needs only the rays that tell which case it is in: it is
    /// replaced before anyone reads V. When the pass splits it unless V = 0, one unblocked ray
    /// settles it; when it splits it unless V is 0 or 1, one unblocked and one blocked ray do.
    /// A zero or all-visible estimate that would end the link's refinement is confirmed with
    /// more rays ([`Self::confirm_zero`], [`Self::confirm_visible`]).
    fn link_visibility(
        &self,
        pair: &PairRays<'_>,
        splits: SplitClasses,
        clear: bool,
        last: &mut u32,
    ) -> (LinkVis, u64) {
        let error_oracle = self.setup.params.oracle == Oracle::Error;
        let stop = if !self.setup.early_exit {
            Stop::Never
        } else if splits.full {
            Stop::AtVisible
        } else if splits.partial {
            Stop::AtMixed
        } else {
            Stop::Never
        };
        // A pair below one whose shaft was empty (`clear`) lies in that shaft: it sees itself
        // whole, V = 1 exactly, with no ray cast (error oracle, see below).
        let shaft = error_oracle && clear;
        let (vis, cast) =
            if shaft { (1.0, 0) } else { self.pair_visibility(pair, self.setup.params.rays, 0, stop, last) };
        let settled = match stop {
            Stop::Never => false,
            Stop::AtVisible => vis > 0.0,
            Stop::AtMixed => vis > 0.0 && vis < 1.0,
        };
        if settled {
            let v = if stop == Stop::AtVisible { UNMEASURED_VIS } else { vis as f32 };
            return (LinkVis::Unmeasured(v), cast);
        }
        // The error oracle splits partially visible links, so a zero estimate ends a refinement
        // that any other estimate continues: its zeros are replaced by a fresh estimate (below).
        let confirm_zero = splits.full || (splits.partial && self.setup.params.conservative) || error_oracle;
        let (confirmed, more) = if vis == 0.0 && confirm_zero && self.setup.params.zero_confirm > 0 {
            self.confirm_zero(pair, splits, last)
        } else if vis == 1.0
            && !shaft
            && error_oracle
            && self.setup.accel.shaft_clear(
                &self.setup.scene,
                pair.lo.vertices(),
                pair.hi.vertices(),
                [pair.lo.patch, pair.hi.patch],
            )
        {
            // Every ray passed and the pair's shaft is empty (`Accel::shaft_clear`): V = 1
            // exactly, for this pair and all those below it, without the confirmation's rays.
            // (Tested only here: on pairs whose first rays are blocked the test is wasted.)
            (LinkVis::Measured { vis, shaft: true }, 0)
        } else if vis == 1.0
            && !shaft
            && ((splits.partial && self.setup.params.conservative) || error_oracle)
            && self.setup.params.zero_confirm > 0
        {
            self.confirm_visible(pair, splits, last)
        } else {
            (LinkVis::Measured { vis, shaft }, 0)
        };
        (confirmed, cast + more)
    }

    /// A zero estimate re-tested. When the next pass splits this link unless V = 0, a zero
    /// estimate is the only thing that ends its refinement: accepted as it is, each level would
    /// keep only P(estimate > 0) of the link's light (a compounding dark bias). Confirm it with
    /// more rays; the first that passes settles the split. A link split only when partially
    /// visible is re-tested only by the conservative oracle (it refines more round shadows):
    /// its zeros and its all-visible estimates bias in opposite directions, and confirming only
    /// the zeros made splash_room 6 % too bright.
    fn confirm_zero(&self, pair: &PairRays<'_>, splits: SplitClasses, last: &mut u32) -> (LinkVis, u64) {
        let more = self.setup.params.zero_confirm.saturating_mul(self.setup.params.rays);
        let confirm = if self.setup.early_exit && splits.full { Stop::AtVisible } else { Stop::Never };
        let (v2, c2) = self.pair_visibility(pair, more, 0x5EED, confirm, last);
        if v2 > 0.0 && confirm == Stop::AtVisible {
            return (LinkVis::Unmeasured(UNMEASURED_VIS), c2);
        }
        // The fresh estimate alone: E[V] = P(V̂ > 0) V (the split links' new estimates) +
        // P(V̂ = 0) E[V̂₂] = V, unbiased (shadow-wide at 16 rays, error oracle: the receiver
        // was 12 % dark keeping the zeros, 0.4 % with the fresh estimate).
        (LinkVis::Measured { vis: v2, shaft: false }, c2)
    }

    /// An all-visible estimate re-tested. Symmetrically to [`Self::confirm_zero`], it ends a
    /// refinement that any partial one continues (the next pass splits this link only if
    /// partially visible): accepted as it is, each level keeps P(V̂ = 1) · 1 of the link where
    /// V is due, a compounding bright bias that created light (splash_room `interactive`: the
    /// floor's rows of F·V summed to 1.11 with the solver's V, 1.00 with 256 weighted rays;
    /// escaped/emitted −11 %). Confirmed the same way: a blocked ray settles the split, else
    /// the fresh estimate stands (unbiased, as for the zeros).
    fn confirm_visible(&self, pair: &PairRays<'_>, splits: SplitClasses, last: &mut u32) -> (LinkVis, u64) {
        let more = self.setup.params.zero_confirm.saturating_mul(self.setup.params.rays);
        let confirm = if self.setup.early_exit && splits.partial { Stop::AtMixed } else { Stop::Never };
        let (v2, c2) = self.pair_visibility(pair, more, 0x0DE5, confirm, last);
        if v2 > 0.0 && v2 < 1.0 && confirm == Stop::AtMixed {
            return (LinkVis::Unmeasured(v2 as f32), c2);
        }
        (LinkVis::Measured { vis: v2, shaft: false }, c2)
    }

    /// `n` visibility rays between the pair (seed salted by `salt`), stopping as `stop` says;
    /// and the rays cast.
    fn pair_visibility(
        &self,
        pair: &PairRays<'_>,
        n: u32,
        salt: u64,
        stop: Stop,
        last: &mut u32,
    ) -> (f64, u64) {
        let (lo, hi) = (pair.lo, pair.hi);
        let (v, cast) = visibility::visibility_sample(
            &self.setup.accel,
            (lo.vertices(), lo.patch, lo.normal),
            (hi.vertices(), hi.patch, hi.normal),
            n,
            self.setup.params.seed ^ salt,
            pair.key,
            last,
            stop,
            self.weighted_visibility(),
        );
        (v, u64::from(cast))
    }

    /// Measure V of the links still marked unmeasured (refinement stopped, by the link
    /// budget or a cancel, before the pass that would have replaced them).
    pub(super) fn measure_unmeasured(&mut self) {
        let hier = &self.hier;
        let (accel, seed, rays) = (&self.setup.accel, self.setup.params.seed, self.setup.params.rays);
        let weighted = self.weighted_visibility();
        let acc = self.accuracy();
        let cast: u64 = self
            .graph
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
        self.log.stats.rays += cast;
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
pub(in crate::solver::hierarchical) fn coupling_in(
    hier: &Hierarchy,
    acc: transfer::Accuracy,
    r: u32,
    s: u32,
    straddle: bool,
) -> f64 {
    let (p, q) = (hier.get(r), hier.get(s));
    let root = p.parent == NONE && q.parent == NONE;
    transfer::coupling(p, r, q, s, straddle, root, acc, transfer::NO_GAP_BOUND)
}
