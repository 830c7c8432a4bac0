//! The region heap of globally adaptive cubature [Genz & Malik 1980; Berntsen, Espelid, Genz
//! 1991]: the domain, a polygon cut into pieces each mapped from the unit square, is covered by
//! rectangles [u0,u1]×[v0,v1] of the pieces, each with its value and error estimate; the
//! integration splits the region of largest estimate until the summed estimate meets the
//! tolerance.
//!
//! ```text
//! ∫ ≈ Σ_regions value,   error ≈ Σ_regions error;   pop max error → split → push children
//! ```
//!
//! [`super::adaptive`] (Genz–Malik regions checked against their halves near the source) and
//! [`crate::geometry::exact`] (Gauss–Legendre regions checked against their quarters) keep their
//! regions here; each adds what it needs to refine a region as its `detail`.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// A rectangle [u0,u1]×[v0,v1] of piece `piece` of the domain, its value and error estimate, and
/// what its integration keeps to refine it (`detail`). Ordered for a max-heap: largest error
/// first, ties broken by position (piece, then u0, then v0), so the order never depends on the
/// heap's layout.
#[derive(Copy, Clone, Debug)]
pub(crate) struct Region<T> {
    pub(crate) piece: u32,
    pub(crate) u: [f64; 2],
    pub(crate) v: [f64; 2],
    pub(crate) value: f64,
    pub(crate) error: f64,
    pub(crate) detail: T,
}

impl<T> PartialEq for Region<T> {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}
impl<T> Eq for Region<T> {}
impl<T> PartialOrd for Region<T> {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl<T> Ord for Region<T> {
    /// Largest error first; ties broken by position so the order never depends on the heap.
    fn cmp(&self, o: &Self) -> Ordering {
        self.error
            .total_cmp(&o.error)
            .then(o.piece.cmp(&self.piece))
            .then(o.u[0].total_cmp(&self.u[0]))
            .then(o.v[0].total_cmp(&self.v[0]))
    }
}

/// The summed value and error estimate of every region, exactly (the running sums of an
/// integration drift). The heap's layout follows from the same sequence of operations every
/// time, so the summation order, and the result, are deterministic.
pub(crate) fn totals<T>(heap: &BinaryHeap<Region<T>>) -> (f64, f64) {
    heap.iter().fold((0.0, 0.0), |(s, e), r| (s + r.value, e + r.error))
}
