//! Link coefficients: the Galerkin form factor of a pair of elements, one number for both
//! directions.
//!
//! ```text
//! G_pq = ∫_p ∫_q cosθ_p cosθ_q / (π r²) dA_q dA_p = ∫_p F(x → q) dA_x = A_p F_pq = A_q F_qp
//! ```
//!
//! [Cohen & Wallace 1993, eq. 4.8 (the area-averaged form factor) and sec. 4.4 (reciprocity);
//! Hanrahan, Salzman, Aupperle 1991, sec. 3 (links carry F between two elements of the hierarchy)].
//! A link p ← q gathers `F_pq = G_pq / A_p`, the mirror link q ← p gathers `F_qp = G_pq / A_q`:
//! what q sends to p through the pair is exactly what p receives, so the hierarchy conserves
//! energy (the power balance of a converged solve is exact up to the iteration's tolerance),
//! whatever the rule below.
//!
//! ## How it is computed
//! G is integrated over one element of the pair (the smaller, ties broken by the lower id, so both
//! directions compute the very same number) with the exact point-to-polygon kernel to the other
//! ([`form_factor::point_to_polygon_oriented`], Lambert's contour integral). The rule follows the
//! accuracy asked for (`HierarchicalParams::link_tol`, relative) and the gap `g` between the two
//! elements' bounding spheres relative to the integrated element's diameter `s`:
//!
//! ```text
//!   input patches, touching / near (g < s/2) ──► adaptive cubature to 1e-7 (1e-4 with link_tol 0;
//!                 there, boxes apart: n×n Gauss–Legendre for the boxes' gap, n as below, to 1e-4)
//!   five-times rule (optional, centroids ≥ 5 diameters of either apart) ──► disk formula
//!   link_tol = 0 (SPLASH-2's rule) ──► the kernel at the smaller element's centroid (1 point;
//!                 input patches apart that straddle: at the centroid of the part in front)
//!   otherwise ──► n×n Gauss–Legendre, n = ⌈ln(1/link_tol) / (2 ln ρ)⌉, ρ = 1 + 2g/s + √((1 + 2g/s)² − 1);
//!                 straddling (apart) ──► the same n over the part in front of the other's plane
//!                 touching (g ≤ 0), or n > MAX_GAUSS ──► adaptive cubature to link_tol
//!   adaptive ──► instead the double contour integral where its error estimate meets the
//!                 tolerance (form_factor::polygon_to_polygon_contour)
//!   n ≥ 3, every edge pair parallel or perpendicular ──► instead the exact double contour
//!                 integral (form_factor::polygon_to_polygon_axial)
//! ```
//!
//! For an analytic integrand whose nearest singularity lies a distance g from an interval of
//! length s, the n-point Gauss rule converges like ρ^(−2n) with that ρ [Trefethen 2008, "Is
//! Gauss quadrature better than Clenshaw–Curtis?", Thm. 4.5]; the rule picks the smallest n whose
//! bound meets the tolerance. Where the kernel's derivative is log-singular (shared edges,
//! contact) a Gauss rule does not converge at that rate, so those pairs are integrated
//! adaptively, or by the contour integral, whose inner integral is closed and whose outer rule is
//! graded towards the singular points: cheaper than cubature for the same tolerance, and exact for
//! axis-aligned pairs (rooms, boxes, shelves and their quadtree elements). Pairs apart keep their
//! Gauss rules, where the contour integral costs as much. A straddling pair (a wall and a shelf
//! whose plane cuts it) exchanges nothing behind the cutting plane and a transfer analytic in x in
//! front of it, so a Gauss rule over the clipped pieces ([`form_factor::polygon_to_polygon_rule`])
//! converges as for any pair at that distance. The pairs of input patches carry a closed box's
//! whole answer (the white furnace is exact only if Σ F = 1), hence their tight tolerances. What
//! each choice measured: docs/solver.md, "Link coefficients".

use crate::geometry::form_factor;
use crate::math::DVec3;
use crate::solver::hierarchy::Element;
use std::sync::OnceLock;

/// Relative tolerance of the adaptive rule for pairs of input patches: tight, as the root links
/// of a closed box are its whole answer (the white furnace is exact to 1e-6 only if Σ F = 1 to
/// better than that).
pub(super) const ROOT_REL_TOL: f64 = 1e-7;
/// Absolute tolerance (in units of F, of the smaller element of the pair, so of both
/// directions' F) of the adaptive rule for pairs of input patches. A grazing pair whose form
/// factor is 1e-12 cannot be had to a relative tolerance, and needs none: what matters is each
/// patch's Σ F, which a closed box needs to 1e-6. Its few large F are held by [`ROOT_REL_TOL`];
/// a patch with k partners sums at most k · 1e-8 more, below 1e-6 for the few hundred partners
/// of a furnished room's patch. A tighter bound spends most of the initial linking on small-F
/// pairs that straddle or touch, for the same error: chosen by measurement, see
/// docs/solver.md#how-the-tolerances-were-chosen.
pub(super) const ROOT_ABS_TOL: f64 = 1e-8;
/// With SPLASH-2's one-point rule (`link_tol` 0), near input patch pairs are still integrated
/// adaptively (one point at a centroid next to a shared edge can exceed the whole pair's F and
/// create light), but only to this: the rest of that preset is accurate to a few percent. Looser
/// leaves a closed box's Σ F above 1 (the solve creates light); tighter makes that preset's
/// initial linking many times slower. Near pairs whose bounding boxes are apart take the Gauss
/// rule of their box gap to this tolerance instead (`rule_gap`). Chosen by measurement, see
/// docs/solver.md#how-the-tolerances-were-chosen.
const ONE_POINT_ROOT_TOL: f64 = 1e-4;
pub(super) const ELEMENT_ABS_TOL: f64 = 1e-8;
/// The error oracle at a relative threshold ε integrates refined pairs adaptively (touching,
/// near) to `max(link_tol, LINK_TOL_PER_EPS · ε)` (`HierarchicalSolver::accuracy`): the
/// lecture's "only compute things to the required precision". The oracle accepts an element
/// whose gathered radiosity is wrong by ε of the mean; a coefficient off by ε/100 moves its
/// link's transfer by a hundredth of that. Reciprocity, and so the power balance, stay exact at
/// any tolerance (one G per pair). ε/100 rather than looser because a scene of many touching
/// pairs (table legs on a floor) loses accuracy at ε/20; the Gauss rules of pairs apart keep
/// `link_tol`, as loosening them too made a closed room create light at `quality`
/// (`tests/hierarchical.rs` `quality_creates_no_light_in_the_closed_rooms`). Chosen by
/// measurement, see docs/solver.md#how-the-tolerances-were-chosen.
pub(super) const LINK_TOL_PER_EPS: f64 = 0.01;
/// `min_gap` of [`coupling`] when nothing bounds the pair's distance but its centroids.
pub(super) const NO_GAP_BOUND: f64 = f64::NEG_INFINITY;
/// Largest Gauss–Legendre order per axis; a pair that needs more is integrated adaptively.
const MAX_GAUSS: usize = 8;
/// A pair whose bounding-sphere gap is below this fraction of the integrated element's diameter
/// is "near": adaptive cubature.
const NEAR_GAP: f64 = 0.5;
/// The lecture's five-times rule: a polygon at least this many of its diameters away acts as a
/// disk for the form factor.
pub(super) const FIVE_TIMES: f64 = 5.0;

/// Gauss–Legendre rules on [0, 1] for n = 1..=MAX_GAUSS, computed once.
fn rules() -> &'static [Vec<(f64, f64)>] {
    static RULES: OnceLock<Vec<Vec<(f64, f64)>>> = OnceLock::new();
    RULES.get_or_init(|| (1..=MAX_GAUSS).map(form_factor::gauss_legendre).collect())
}

/// How a pair's coupling is integrated.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub(super) enum Rule {
    /// Disk formula at the integrated element's centroid (the five-times rule).
    Disk,
    /// n×n Gauss–Legendre over the integrated element.
    Gauss(usize),
    /// n×n Gauss–Legendre over each piece of the integrated element's part in front of the
    /// other's plane (a straddling pair apart from each other: the transfer is smooth there and
    /// 0 behind, so the rule integrates the smooth part only).
    GaussClipped(usize),
    /// Adaptive cubature to a relative tolerance.
    Adaptive,
}

/// Which element of the pair is integrated over: the smaller (ties: the lower id). `true`: `a`.
fn integrate_over_a(a: &Element, a_id: u32, b: &Element, b_id: u32) -> bool {
    if super::refine::nearly_equal(a.area, b.area) { a_id < b_id } else { a.area < b.area }
}

/// How accurately link coefficients are computed (from `HierarchicalParams`).
#[derive(Copy, Clone, Debug, PartialEq)]
pub(super) struct Accuracy {
    /// Relative tolerance of a refined pair's coupling; 0: one point (SPLASH-2's rule).
    pub tol: f64,
    /// Relative tolerance of the adaptive cubature of refined pairs (those that touch, are near,
    /// or need more than `MAX_GAUSS` points), at least `tol` ([`LINK_TOL_PER_EPS`]).
    pub adaptive_tol: f64,
    /// Allow the disk formula for pairs five diameters apart.
    pub five_times: bool,
}

/// The rule for integrating over `x` with the kernel to `y`.
#[cfg(test)]
pub(super) fn rule(x: &Element, y: &Element, straddle: bool, root: bool, acc: Accuracy) -> Rule {
    rule_gap(x, y, straddle, root, acc, NO_GAP_BOUND)
}

/// [`rule`], with `min_gap` a lower bound of the two elements' distance known otherwise (the
/// centroids' distance less the half diameters says two small pieces side by side touch).
fn rule_gap(x: &Element, y: &Element, straddle: bool, root: bool, acc: Accuracy, min_gap: f64) -> Rule {
    let d = x.centroid.distance(y.centroid);
    let gap = (d - 0.5 * (x.diam + y.diam)).max(min_gap);
    if root && gap < NEAR_GAP * x.diam {
        // One-point presets integrate input patches to ONE_POINT_ROOT_TOL: near pairs whose
        // bounding boxes are apart (a box's face and the wall behind it) keep the kernel
        // analytic over x, and the Gauss rule for their box gap (a lower bound of their
        // distance) meets the tolerance with a tenth of the adaptive rule's evaluations.
        let bg = box_gap(x, y);
        if acc.tol <= 0.0
            && bg > 0.0
            && let Some(n) = gauss_order(bg, x.diam, ONE_POINT_ROOT_TOL)
        {
            return if straddle { Rule::GaussClipped(n) } else { Rule::Gauss(n) };
        }
        return Rule::Adaptive;
    }
    if acc.five_times && d >= FIVE_TIMES * y.diam && d >= FIVE_TIMES * x.diam {
        return Rule::Disk;
    }
    if acc.tol <= 0.0 {
        // One point; for input patches apart that straddle, at the centroid of the part in
        // front (the whole element's centroid may lie behind the other's plane).
        return if root && straddle { Rule::GaussClipped(1) } else { Rule::Gauss(1) };
    }
    if gap <= 0.0 || x.diam <= 0.0 {
        return Rule::Adaptive;
    }
    match gauss_order(gap, x.diam, acc.tol) {
        None => Rule::Adaptive,
        Some(n) if straddle => Rule::GaussClipped(n),
        Some(n) => Rule::Gauss(n),
    }
}

/// The Gauss–Legendre order per axis whose convergence bound meets `tol` for an element of
/// diameter `diam` at distance `gap` from the kernel's singularity (module docs); `None` above
/// [`MAX_GAUSS`].
fn gauss_order(gap: f64, diam: f64, tol: f64) -> Option<usize> {
    let r = 2.0 * gap / diam;
    let rho = 1.0 + r + ((1.0 + r) * (1.0 + r) - 1.0).sqrt();
    let n = ((1.0 / tol).ln() / (2.0 * rho.ln())).ceil();
    (n.is_finite() && n <= MAX_GAUSS as f64).then(|| (n as usize).max(1))
}

/// The distance between the two elements' bounding boxes: a lower bound of their distance.
pub(super) fn box_gap(a: &Element, b: &Element) -> f64 {
    let bounds = |e: &Element| {
        e.vertices()
            .iter()
            .fold((DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)), |(lo, hi), v| {
                (lo.min(*v), hi.max(*v))
            })
    };
    let ((alo, ahi), (blo, bhi)) = (bounds(a), bounds(b));
    let d = (blo - ahi).max(alo - bhi).max(DVec3::ZERO);
    d.length()
}

/// G = A_a F_ab = A_b F_ba of two elements (ids `a_id`, `b_id`), independent of their order.
/// `straddle`: one element has vertices on both sides of the other's plane (see `pair_sides`);
/// `root`: both are input patches (tighter tolerance). `min_gap`: a lower bound of the
/// elements' distance known otherwise ([`box_gap`]; [`NO_GAP_BOUND`] when none): the small
/// patches a clustered scene links pair by pair are mostly near each other without touching,
/// and the centroid rule alone sent them all to adaptive cubature.
#[allow(clippy::too_many_arguments)]
pub(super) fn coupling(
    a: &Element,
    a_id: u32,
    b: &Element,
    b_id: u32,
    straddle: bool,
    root: bool,
    acc: Accuracy,
    min_gap: f64,
) -> f64 {
    let (x, y) = if integrate_over_a(a, a_id, b, b_id) { (a, b) } else { (b, a) };
    let rule = rule_gap(x, y, straddle, root, acc, min_gap);
    // Near pairs take the double contour integral, a few dozen closed-form inner integrals per
    // edge pair where the cubature spends hundreds of kernel evaluations on a contact's
    // log-singular derivative (exact for axis-aligned pairs); axis-aligned pairs apart have it
    // in closed form too, cheaper than 3×3 kernel evaluations.
    let f = match rule {
        Rule::Adaptive => {
            let (rel, abs) = adaptive_tols(root, acc);
            form_factor::polygon_to_polygon_contour(x.vertices(), y.vertices(), rel, abs)
        }
        Rule::Gauss(3..) | Rule::GaussClipped(3..) => {
            form_factor::polygon_to_polygon_axial(x.vertices(), y.vertices())
        }
        _ => None,
    };
    match f {
        Some(f) => x.area * f,
        None => by_rule(x, y, rule, root, acc),
    }
}

/// The relative and absolute tolerances of the adaptive rule for a pair (see the constants).
fn adaptive_tols(root: bool, acc: Accuracy) -> (f64, f64) {
    if root && acc.tol <= 0.0 {
        (ONE_POINT_ROOT_TOL, ROOT_ABS_TOL)
    } else if root {
        (ROOT_REL_TOL, ROOT_ABS_TOL)
    } else {
        (acc.adaptive_tol.max(ROOT_REL_TOL), ELEMENT_ABS_TOL)
    }
}

/// G by `rule` over `x` (the smaller of the pair), ≥ 0.
fn by_rule(x: &Element, y: &Element, rule: Rule, root: bool, acc: Accuracy) -> f64 {
    let g = match rule {
        Rule::Disk => x.area * form_factor::disk(x.centroid, x.normal, y.centroid, y.normal, y.area),
        Rule::Gauss(n) => x.area * gauss(x, y, n),
        Rule::GaussClipped(n) => {
            x.area * form_factor::polygon_to_polygon_rule(x.vertices(), y.vertices(), &rules()[n - 1])
        }
        Rule::Adaptive => {
            let (rel, abs) = adaptive_tols(root, acc);
            let q = form_factor::polygon_to_polygon_adaptive(x.vertices(), y.vertices(), rel, abs);
            x.area * q.value
        }
    };
    if g.is_finite() { g.max(0.0) } else { 0.0 }
}

/// F_xy = (1/A_x) ∫_x F(p → y) dA_p by the n×n Gauss–Legendre rule on x's bilinear map (a
/// triangle is a quad collapsed onto its third vertex; the Jacobian carries the collapse).
fn gauss(x: &Element, y: &Element, n: usize) -> f64 {
    let v = x.vertices();
    let (v0, v1, v2) = (v[0], v[1], v[2]);
    let v3 = if v.len() == 4 { v[3] } else { v[2] };
    let rule = &rules()[n - 1];
    let (yv, yn) = (y.vertices(), y.normal);
    let mut sum = 0.0;
    let mut wsum = 0.0;
    for &(u, wu) in rule {
        for &(t, wt) in rule {
            let du = (v1 - v0) * (1.0 - t) + (v2 - v3) * t;
            let dv = (v3 - v0) * (1.0 - u) + (v2 - v1) * u;
            let jac = du.cross(dv).length();
            let p: DVec3 =
                v0 * ((1.0 - u) * (1.0 - t)) + v1 * (u * (1.0 - t)) + v2 * (u * t) + v3 * ((1.0 - u) * t);
            let w = wu * wt * jac;
            sum += w * form_factor::point_to_polygon_oriented(p, x.normal, yv, yn);
            wsum += w;
        }
    }
    // Σ w·jac is the element's area to rounding for a planar bilinear map (exact for the rule).
    if wsum > 0.0 { sum / wsum } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rgb;
    use crate::scene::{Patch, Scene};
    use crate::solver::hierarchy::Hierarchy;

    fn patch(verts: Vec<DVec3>) -> Patch {
        Patch::new(verts, Rgb::splat(0.5), Rgb::ZERO, "p", 0, "p", "m").expect("valid patch")
    }

    fn hier(patches: Vec<Patch>) -> Hierarchy {
        Hierarchy::from_scene(&Scene::new("t", "t", patches))
    }

    /// Unit square at height h facing down, offset sideways by `dx`, scaled by `s`.
    fn square_down(dx: f64, h: f64, s: f64) -> Patch {
        patch(vec![
            DVec3::new(dx, 0.0, h),
            DVec3::new(dx, s, h),
            DVec3::new(dx + s, s, h),
            DVec3::new(dx + s, 0.0, h),
        ])
    }

    fn floor() -> Patch {
        patch(vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ])
    }

    const ACC: Accuracy = Accuracy { tol: 1e-4, adaptive_tol: 1e-4, five_times: false };

    /// Parallel unit squares at distance 1: F = 0.1998248957 (Howell's catalog, C-11; the value
    /// 0.1998202406 is a typo, see tests/classical_solvers.rs); adjacent
    /// perpendicular squares: 0.2000437761. The root rule is adaptive (the pairs are near) and
    /// must hit both to its tolerance, ROOT_REL_TOL.
    #[test]
    fn root_couplings_match_the_catalog() {
        let h = hier(vec![floor(), square_down(0.0, 1.0, 1.0)]);
        let g = coupling(h.get(0), 0, h.get(1), 1, false, true, ACC, NO_GAP_BOUND);
        assert!((g - 0.199_824_895_7).abs() < ROOT_REL_TOL * g, "parallel: {g}");
        let wall = patch(vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 0.0),
        ]);
        let h = hier(vec![floor(), wall]);
        let g = coupling(h.get(0), 0, h.get(1), 1, false, true, ACC, NO_GAP_BOUND);
        assert!((g - 0.200_043_776_1).abs() < ROOT_REL_TOL * g, "perpendicular: {g}");
    }

    /// The same number serves both directions, bit for bit, whatever the order of the call.
    #[test]
    fn coupling_is_symmetric_bit_for_bit() {
        for (dx, h, s) in [(0.3, 0.7, 0.2), (2.0, 1.0, 0.5), (0.0, 0.05, 1.0), (0.5, 3.0, 1.0)] {
            let hr = hier(vec![floor(), square_down(dx, h, s)]);
            let ab = coupling(hr.get(0), 0, hr.get(1), 1, false, false, ACC, NO_GAP_BOUND);
            let ba = coupling(hr.get(1), 1, hr.get(0), 0, false, false, ACC, NO_GAP_BOUND);
            assert_eq!(ab.to_bits(), ba.to_bits(), "dx {dx} h {h} s {s}");
            assert!(ab > 0.0);
        }
    }

    /// A pair apart whose one element straddles the other's plane (a wall cut by a shelf's
    /// plane) takes the Gauss rule over the part in front, and meets the tolerance as the
    /// adaptive rule does, for either element integrated over.
    #[test]
    fn straddling_pairs_apart_meet_the_tolerance() {
        for (x0, lo, hi, s) in [(2.0, -0.5, 0.5, 1.0), (1.5, -0.2, 0.6, 0.8), (4.0, -1.0, 0.3, 2.0)] {
            // A wall facing −x at x = x0, from z = lo to hi (the floor's plane z = 0 cuts it).
            let wall = patch(vec![
                DVec3::new(x0, 0.0, lo),
                DVec3::new(x0, 0.0, hi),
                DVec3::new(x0, s, hi),
                DVec3::new(x0, s, lo),
            ]);
            let hr = hier(vec![floor(), wall]);
            let (p, q) = (hr.get(0), hr.get(1));
            let exact = p.area * form_factor::polygon_to_polygon(p.vertices(), q.vertices(), 1e-11);
            assert!(exact > 0.0);
            for tol in [1e-2, 1e-3, 1e-4, 1e-6] {
                let acc = Accuracy { tol, adaptive_tol: tol, five_times: false };
                let g = coupling(p, 0, q, 1, true, false, acc, NO_GAP_BOUND);
                let rel = (g - exact).abs() / exact;
                let (x, y) = if p.area < q.area { (p, q) } else { (q, p) };
                let chosen = rule(x, y, true, false, acc);
                assert!(
                    rel < tol,
                    "x0 {x0} lo {lo} hi {hi} tol {tol}: {g} vs {exact} ({rel:.2e}, rule {chosen:?})"
                );
                // The rule itself (axis-aligned, `coupling` takes the closed form).
                let by = by_rule(x, y, chosen, false, acc);
                let rel = (by - exact).abs() / exact;
                assert!(
                    rel < tol,
                    "x0 {x0} lo {lo} hi {hi} tol {tol}: {chosen:?} {by} vs {exact} ({rel:.2e})"
                );
                // (x0 = 1.5 is near: the bounding spheres overlap, adaptive.)
                if tol >= 1e-3 && x0 >= 2.0 {
                    assert!(matches!(chosen, Rule::GaussClipped(_)), "x0 {x0} tol {tol}: {chosen:?}");
                }
            }
        }
    }

    /// One-point presets: near input patches whose boxes are apart take the Gauss rule of their
    /// box gap, and meet the roots' tolerance as the adaptive rule does (opposite faces of a
    /// unit cube; a small square over the floor, offset and tilted off it; a wall cut by the
    /// floor's plane).
    #[test]
    fn near_input_patches_apart_meet_the_one_point_root_tolerance() {
        let one_point = Accuracy { tol: 0.0, adaptive_tol: 0.0, five_times: false };
        let tilted = patch(vec![
            DVec3::new(0.2, 0.1, 0.3),
            DVec3::new(0.2, 0.9, 0.3),
            DVec3::new(0.9, 0.9, 0.55),
            DVec3::new(0.9, 0.1, 0.55),
        ]);
        let wall = patch(vec![
            DVec3::new(1.2, 0.0, -0.3),
            DVec3::new(1.2, 0.0, 0.7),
            DVec3::new(1.2, 1.0, 0.7),
            DVec3::new(1.2, 1.0, -0.3),
        ]);
        let mut gauss = 0;
        for (q, straddle) in [
            (square_down(0.0, 1.0, 1.0), false),
            (square_down(0.0, 0.3, 1.0), false),
            (square_down(0.3, 0.2, 0.5), false),
            (square_down(-0.4, 0.25, 0.8), false),
            (tilted, false),
            (wall, true),
        ] {
            let hr = hier(vec![floor(), q]);
            let (p, q) = (hr.get(0), hr.get(1));
            let (x, y) = if integrate_over_a(p, 0, q, 1) { (p, q) } else { (q, p) };
            let exact = x.area * form_factor::polygon_to_polygon(x.vertices(), y.vertices(), 1e-11);
            let g = coupling(p, 0, q, 1, straddle, true, one_point, NO_GAP_BOUND);
            let chosen = rule(x, y, straddle, true, one_point);
            let rel = (g - exact).abs() / exact;
            assert!(rel < ONE_POINT_ROOT_TOL, "{:?}: {g} vs {exact} ({rel:.2e}, {chosen:?})", y.centroid);
            // The rule itself (most of these pairs are axis-aligned: `coupling` takes the
            // closed form).
            let by = by_rule(x, y, chosen, true, one_point);
            let rel = (by - exact).abs() / exact;
            assert!(rel < ONE_POINT_ROOT_TOL, "{:?}: {chosen:?} {by} vs {exact} ({rel:.2e})", y.centroid);
            gauss += usize::from(matches!(chosen, Rule::Gauss(_) | Rule::GaussClipped(_)));
        }
        assert!(gauss >= 4, "{gauss} pairs took a Gauss rule");
    }

    /// Across distances, the rules `rule` picks for a tolerance agree with a tight adaptive
    /// integration to that tolerance.
    #[test]
    fn chosen_rules_are_accurate_at_every_distance() {
        for (dx, h, s) in
            [(0.2, 0.4, 0.3), (0.0, 1.5, 0.5), (1.0, 0.6, 0.25), (0.3, 0.15, 0.1), (3.0, 2.0, 1.0)]
        {
            let hr = hier(vec![floor(), square_down(dx, h, s)]);
            let (p, q) = (hr.get(0), hr.get(1));
            let exact = q.area * form_factor::polygon_to_polygon(q.vertices(), p.vertices(), 1e-11);
            for tol in [1e-3, 1e-4, 1e-6] {
                let acc = Accuracy { tol, adaptive_tol: tol, five_times: false };
                let g = coupling(p, 0, q, 1, false, false, acc, NO_GAP_BOUND);
                let rel = (g - exact).abs() / exact;
                assert!(
                    rel < tol,
                    "dx {dx} h {h} s {s} tol {tol}: {g} vs {exact} ({rel:.2e}, rule {:?})",
                    rule(q, p, false, false, acc)
                );
            }
        }
    }
}
