//! The row check (`HierarchicalParams::row_tol`).
//!
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

use crate::solver::hierarchical::HierarchicalSolver;
use crate::solver::link::Link;
use rayon::prelude::*;

/// The row check pushes down, of an element with an excess row below it, the largest links
/// that together carry this multiple of the excess (`row_split`).
pub(super) const ROW_SHARE: f64 = 2.0;

impl HierarchicalSolver {
    /// Per element, the smallest F·V of its links that the row check splits (0: none): of an
    /// element with leaves below it whose row exceeds 1 by up to x where that matters
    /// (`push_pull::row_excess`), its largest links that together carry [`ROW_SHARE`]·x (all of
    /// them if they carry less).
    pub(super) fn row_floors(&mut self) -> Vec<f32> {
        let mut ex = self.row_excess_now();
        let lists = &self.graph.links.by_receiver;
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
    /// light (docs/solver.md#the-row-check). Pushing the
    /// ancestors' links down a level replaces their averages by the children's own.
    pub(in crate::solver::hierarchical) fn row_split(&self, a: u32, b: u32, link: &Link) -> Option<u32> {
        if self.oracle.row_floor.is_empty() {
            return None;
        }
        let v = f64::from(link.vis).clamp(0.0, 1.0);
        let g = f64::from(link.g) * v;
        if g.is_nan() || g <= 0.0 {
            return None;
        }
        let wants = |x: u32| {
            let floor = f64::from(self.oracle.row_floor.get(x as usize).copied().unwrap_or(0.0));
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
}
