//! A pair of elements as the oracle sees it: the link with its cached estimates (the disk
//! formula F ≈ A_q cos θ_p cos θ_q / (π r² + A_q), the split side, the error bound), how the
//! two sit relative to each other's planes, and the pair's key for the visibility jitter.

use crate::geometry::{form_factor, visibility};
use crate::math::DVec3;
use crate::solver::hierarchy::Element;
use crate::solver::link::Link;

/// A link receiver `p` ← source `q` with the oracle's geometry cached: the Galerkin form factor
/// F_pq = G / A_p (`g` the pair's coupling, see [`transfer`]), the disk estimates F_pq, F_qp
/// (with |cos| for straddling pairs, whose centroids may lie behind each other's planes while
/// parts of the elements still see each other), which side to split (the larger estimate's:
/// F_pq > F_qp → the source; on a tie, the larger element, then the lower id, so that the
/// mirror link q ← p splits the same element), and the error bound.
pub(in crate::solver::hierarchical) fn new_link(
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
pub(in crate::solver::hierarchical) fn nearly_equal(a: f64, b: f64) -> bool {
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
pub(in crate::solver::hierarchical) fn pair_key(receiver: u32, source: u32) -> u64 {
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
pub(in crate::solver::hierarchical) struct PairSides {
    /// Each has some part strictly in front of the other's plane.
    pub(in crate::solver::hierarchical) facing: bool,
    /// One has vertices strictly on both sides of the other's plane.
    pub(in crate::solver::hierarchical) straddle: bool,
}

pub(in crate::solver::hierarchical) fn pair_sides(p: &Element, q: &Element) -> PairSides {
    let (q_front, q_back) = plane_sides(p, q);
    let (p_front, p_back) = plane_sides(q, p);
    PairSides { facing: q_front && p_front, straddle: (q_front && q_back) || (p_front && p_back) }
}
