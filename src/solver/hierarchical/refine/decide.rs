//! The oracle on one link [HSA91, sec. 4; the BF oracle of SPLASH-2]: whether its estimate
//! calls for a split, which side is split, and why a link is kept; the radiosity terms it
//! reads and the error oracle's threshold.
//! ```text
//! Feps:  max(F_pq, F_qp) ≥ Feps                              → split
//! BF:    B · max(F_pq, F_qp) · bound > BFeps (× partial_bf_factor when partly visible)
//! side:  F_pq > F_qp → the source q, else the receiver p (ties: the larger, then the lower id)
//! ```

use super::verdict::{Decision, ReceiverDecision, Split, Verdict};
use crate::scene::Scene;
use crate::solver::hierarchical::{HierarchicalSolver, oracle};
use crate::solver::hierarchy::{Element, StopReason};
use crate::solver::link::{Link, VisClass};
use crate::solver::params::{HierarchicalParams, Oracle};

impl HierarchicalSolver {
    pub(in crate::solver::hierarchical) fn can_split(&self, e: &Element) -> Result<(), StopReason> {
        if e.depth >= self.setup.params.max_depth {
            Err(StopReason::MaxDepth)
        } else if e.area <= self.setup.aeps || e.area / 4.0 <= 0.0 {
            Err(StopReason::AepsFloor)
        } else {
            Ok(())
        }
    }

    /// A source's (brightest leaf, largest channel of B) for the oracle: from the compact copy
    /// made for this refinement (radiosity does not change during refinement; new children
    /// inherit their parent's values), else from the element.
    pub(super) fn source_b(&self, id: u32) -> [f64; 2] {
        self.oracle.b.get(id as usize).copied().unwrap_or_else(|| {
            let e = self.hier.get(id);
            [e.b_max, e.radiosity.max_channel()]
        })
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
        let start = self.oracle.b.len();
        let els = &self.hier.elements;
        self.oracle
            .b
            .extend(els[start.min(els.len())..].iter().map(|e| [e.b_max, e.radiosity.max_channel()]));
    }

    /// The oracle on all of receiver `r`'s links (the first pass of a refinement; later passes
    /// use the verdicts made with the new links, the oracle's inputs not changing during a
    /// refinement).
    /// `born`: the indices (ascending) of the links the last pass put in r's list.
    pub(super) fn decide_receiver(
        &self,
        r: u32,
        field: Option<&oracle::ErrorField>,
        born: &[u32],
    ) -> ReceiverDecision {
        let p = self.hier.get(r);
        let mut v = Verdict::default();
        // The error oracle decides again only the links with a fresh end (`ErrorField::fresh`)
        // and the new ones: the others keep the verdict they had, to keep them.
        let all = field.is_none_or(|f| f.fresh[r as usize]);
        let mut born = born.iter().copied().peekable();
        for (i, l) in self.graph.links.by_receiver[r as usize].iter().enumerate() {
            let new = born.next_if_eq(&(i as u32)).is_some();
            let d = match field {
                Some(f) if !all && !new && !f.fresh[l.source as usize] => continue,
                Some(f) => self
                    .decide_error(f, r, i, l)
                    .map(|x| if x == r { Split::Receiver } else { Split::Source }),
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

    /// Why a link the oracle does not want to split is kept.
    pub(super) fn below_reason(&self) -> StopReason {
        match self.setup.params.oracle {
            Oracle::Feps => StopReason::BelowFeps,
            Oracle::Bf => StopReason::BelowBfEps,
            Oracle::Error => StopReason::BelowErrorEps,
        }
    }

    /// Does the oracle's estimate call for splitting this link were its visibility of class
    /// `class` (Full or Partial)? `b`: the source's `source_b`.
    pub(super) fn wants_split(&self, link: &Link, class: VisClass, [b_max, b_channel]: [f64; 2]) -> bool {
        match self.setup.params.oracle {
            Oracle::Feps => f64::from(link.fmax) >= self.setup.params.feps,
            // Decided per pass from the error field (`decide_error`), never per link.
            Oracle::Error => false,
            Oracle::Bf => {
                // A partially visible link may see the bright or the dark part of its source
                // (the floor round a box's foot is lit, the part under it is dark and hidden):
                // B_avg · V_avg then counts the darkness twice. Bound it by the source's
                // brightest leaf.
                let partial = class == VisClass::Partial;
                let b = if partial && self.setup.params.conservative { b_max } else { b_channel };
                let (bound, thr) = if partial {
                    (1.0, self.setup.bf_eps * self.setup.params.partial_bf_factor)
                } else {
                    (f64::from(link.bound), self.setup.bf_eps)
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
            Err(why_first) if !self.setup.params.split_fallback => Err(why_first),
            Err(why_first) => match self.can_split(second) {
                Ok(()) => Ok(side(!link.split_source)),
                // The receiver's own limit is what the inspector reports.
                Err(why_second) => Err(if link.split_source { why_second } else { why_first }),
            },
        }
    }

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
    pub(super) fn error_eps(&self) -> f64 {
        let mean = self.mean_reflected();
        if mean > 0.0 {
            self.setup.params.bf_eps * mean
        } else {
            resolve_bf_eps(&self.setup.params, &self.setup.scene)
        }
    }
}

pub(in crate::solver::hierarchical) fn resolve_bf_eps(p: &HierarchicalParams, scene: &Scene) -> f64 {
    if p.bf_relative {
        let e_max = scene.patches.iter().map(|q| q.emission.max_channel()).fold(0.0, f64::max);
        p.bf_eps * e_max
    } else {
        p.bf_eps
    }
}
