//! F from→to by the double contour integral [Sparrow 1963; Cohen & Wallace 1993, eq. 4.17]:
//!
//! ```text
//! A_from F = (1/2π) ∮_from ∮_to ln r  dx_from · dx_to
//! ```
//!
//! Perpendicular edge pairs contribute nothing; parallel pairs have a closed form
//! ([`parallel_edges_log`]); oblique pairs take the closed inner integral and graded
//! Gauss–Legendre rules for the outer one, climbing a ladder of rules pair by pair until the
//! estimated error meets the tolerance ([`super::oblique`]). Exact for touching pairs, where
//! cubature needs hundreds of kernel evaluations to resolve the contact.

use super::IN_PLANE_REL;
use super::oblique::{OBLIQUE_APRIORI, ObliquePair, Rung, oblique_ladder, rung_error};
use super::pair::{clip_to_front, pair_frame};
use crate::math::{DVec3, newell_normal};
use std::f64::consts::PI;

/// Exact form factor F from→to of two convex polygons each entirely on or in front of the
/// other's plane, whose edges are pairwise parallel or perpendicular (boxes, rooms, shelves and
/// the quadtree elements of their faces), by the double contour integral [Sparrow 1963; Cohen
/// & Wallace 1993, eq. 4.17]:
///
/// ```text
/// A_from F = (1/2π) ∮_from ∮_to ln r  dx_from · dx_to
/// ```
///
/// Perpendicular edges contribute nothing (dx · dx = 0); a parallel pair's double integral of
/// ln r has the closed form [`parallel_edges_log`]. `None` when the polygons are degenerate,
/// not mutually in front, or have an edge pair at another angle (use the quadrature then).
/// Touching pairs (a box on the floor, a wall meeting the floor) are exact, where cubature
/// needs hundreds of kernel evaluations to resolve the contact's log-singular derivative.
#[must_use]
pub fn polygon_to_polygon_axial(from: &[DVec3], to: &[DVec3]) -> Option<f64> {
    // Most pairs that are not axial show it in their own edges: decline before clipping.
    if edge_dirs(from).any(|u| edge_dirs(to).any(|v| !(perpendicular(u, v) || parallel(u, v)))) {
        return None;
    }
    contour(from, to, None, 0.0, 0.0).ok()
}

/// Form factor F from→to of two convex polygons by the double contour integral of
/// [`polygon_to_polygon_axial`], for edges at any angle: parallel pairs in closed form
/// ([`parallel_edges_log`]), the others with the inner integral in closed form and the outer
/// by Gauss–Legendre rules graded towards where the integrand is singular
/// ([`ObliquePair`]), to the relative tolerance `rel_tol` or the absolute `abs_tol` (in
/// units of F), whichever is looser. Touching, shared-edge and near pairs alike: where adaptive
/// cubature spends hundreds of kernel evaluations on a contact's log-singular derivative, this
/// costs a few dozen closed-form inner integrals per edge pair.
/// `None` when the polygons are degenerate, when the contour terms cancel so far that rounding
/// could exceed the tolerance (small pairs far apart: use a cubature rule there), or when the
/// rules' error estimate still exceeds it with every edge pair on the finest rule (see
/// [`super::oblique::OBLIQUE_LADDER`]).
#[must_use]
pub fn polygon_to_polygon_contour(from: &[DVec3], to: &[DVec3], rel_tol: f64, abs_tol: f64) -> Option<f64> {
    // Start at the cheapest rule that meets the tolerance where the oblique terms' sum is a
    // few times the result; the edge pairs whose estimate is largest then take the finer
    // rules, one step at a time, until the sum meets it (on splash_room's root pairs at 1e-4,
    // the first step settles 235 of 402).
    let ladder = oblique_ladder();
    let k = ladder.iter().skip(1).position(|r| (r.len() as f64).powi(-8) <= OBLIQUE_APRIORI * rel_tol);
    let k = k.map_or(ladder.len() - 1, |k| k + 1);
    contour(from, to, Some((ladder, k)), rel_tol, abs_tol).ok()
}

/// Gauss–Legendre rules of growing order for [`ObliquePair`], and the rung of the first
/// value (the rung below it gives its error estimate).
type Ladder<'a> = (&'a [Vec<(f64, f64)>], usize);

/// The double contour integral of [`polygon_to_polygon_axial`] / [`polygon_to_polygon_contour`]
/// (`oblique`: the rules for edge pairs at other angles, else `Err` on the first); `rel_tol`
/// and `abs_tol` as for [`polygon_to_polygon_contour`].
fn contour(
    from: &[DVec3],
    to: &[DVec3],
    oblique: Option<Ladder<'_>>,
    rel_tol: f64,
    abs_tol: f64,
) -> Result<f64, Declined> {
    let (nf, nt, area, scale) = pair_frame(from, to).ok_or(Declined::Geometry)?;
    let eps = IN_PLANE_REL * scale;
    // Only the part of each in front of the other's plane exchanges light: clip both (a clip
    // edge runs along the planes' intersection, parallel or perpendicular to axial edges).
    let (from_c, to_c) = (clip_to_front(from, to[0], nt, eps), clip_to_front(to, from[0], nf, eps));
    // Nothing in front, or only an edge: nothing exchanged (coplanar pairs too).
    if from_c.len() < 3 || to_c.len() < 3 {
        return Ok(0.0);
    }
    let (from, to) = (&from_c[..], &to_c[..]);
    if newell_normal(from).length() <= eps * eps || newell_normal(to).length() <= eps * eps {
        return Ok(0.0);
    }
    // The parallel pairs' closed forms, and the oblique pairs on their current rungs.
    let (mut exact, mut exact_magnitude) = (0.0, 0.0);
    let mut rungs: Vec<Rung> = Vec::new();
    for i in 0..from.len() {
        let (a, b) = (from[i], from[(i + 1) % from.len()]);
        let (da, la) = ((b - a).normalize_or_zero(), (b - a).length());
        if la <= 0.0 {
            continue;
        }
        for j in 0..to.len() {
            let (c, d) = (to[j], to[(j + 1) % to.len()]);
            let (dc, lc) = ((d - c).normalize_or_zero(), (d - c).length());
            if lc <= 0.0 {
                continue;
            }
            if perpendicular(da, dc) {
                continue;
            }
            let cos = da.dot(dc);
            if parallel(da, dc) {
                let t = parallel_edges_log(a, da, la, c, lc, cos.signum());
                exact += t;
                exact_magnitude += t.abs();
            } else if let Some((ladder, k)) = oblique {
                let pair = ObliquePair::new(a, da, la, c, dc, lc);
                let (below, value) = (pair.integrate(&ladder[k - 1]), pair.integrate(&ladder[k]));
                rungs.push(Rung { pair, cos, rung: k, value, error: rung_error(below, value) * cos.abs() });
            } else {
                return Err(Declined::Geometry);
            }
        }
    }
    loop {
        let sum = exact + rungs.iter().map(|r| r.cos * r.value).sum::<f64>();
        let magnitude = exact_magnitude + rungs.iter().map(|r| (r.cos * r.value).abs()).sum::<f64>();
        if magnitude == 0.0 {
            return Ok(0.0);
        }
        // What may be wrong, against what is allowed (in units of the sum, 2π A F).
        let allowed = (rel_tol * sum.abs()).max(abs_tol * 2.0 * PI * area);
        if !(sum.abs() > 1e-7 * magnitude || CONTOUR_ROUNDING * magnitude <= allowed) {
            return Err(Declined::Cancellation);
        }
        let rule_error: f64 = rungs.iter().map(|r| r.error).sum();
        if rule_error <= allowed {
            let f = sum / (2.0 * PI * area);
            return if f.is_finite() { Ok(f.clamp(0.0, 1.0)) } else { Err(Declined::Geometry) };
        }
        // The edge pair with the largest estimate that has a finer rule takes it (the first
        // of equals: the order of the edges decides, not the sort).
        let Some((ladder, _)) = oblique else { return Err(Declined::Rule) };
        let worst = rungs
            .iter_mut()
            .filter(|r| r.rung + 1 < ladder.len())
            .reduce(|best, r| if r.error > best.error { r } else { best });
        let Some(r) = worst else { return Err(Declined::Rule) };
        r.rung += 1;
        let below = r.value;
        r.value = r.pair.integrate(&ladder[r.rung]);
        r.error = rung_error(below, r.value) * r.cos.abs();
        if !r.error.is_finite() {
            return Err(Declined::Rule);
        }
    }
}

/// Rounding of the contour terms' sum, relative to their magnitude (generous: f64 sums of a
/// few dozen terms of logarithms).
const CONTOUR_ROUNDING: f64 = 1e-13;

/// Why [`contour`] gave no result.
#[derive(Debug)]
enum Declined {
    /// Degenerate polygons, or (axial only) an oblique edge pair.
    Geometry,
    /// The terms cancel so far that rounding could exceed the tolerance.
    Cancellation,
    /// The oblique terms' error estimate exceeds the tolerance on the finest rule.
    Rule,
}

/// parallel when its sine is ([`perpendicular`], [`parallel`]).
const AXIAL_REL: f64 = 1e-12;

/// The unit directions of a polygon's edges (zero for a repeated vertex).
fn edge_dirs(p: &[DVec3]) -> impl Iterator<Item = DVec3> + '_ {
    (0..p.len()).map(move |i| (p[(i + 1) % p.len()] - p[i]).normalize_or_zero())
}

/// Are the unit directions `u` and `v` perpendicular (within [`AXIAL_REL`])? Their edge pair
/// adds nothing to the contour integral (dx · dy = 0).
fn perpendicular(u: DVec3, v: DVec3) -> bool {
    u.dot(v).abs() <= AXIAL_REL
}

/// Are the unit directions `u` and `v` parallel (within [`AXIAL_REL`])? By the sine, not the
/// cosine: [`parallel_edges_log`] takes the lines' distance at one point, off by sin θ times
/// the length where they are not quite parallel (two faces of a turned box whose float vertices
/// nearly share an edge: 1 − cos θ below 1e-12, and the distance changing by 2e-5 along a
/// 160-long edge made F 3e-8 read 1e-7).
fn parallel(u: DVec3, v: DVec3) -> bool {
    u.cross(v).length() <= AXIAL_REL
}

/// ∫∫ ln r (dx · dy) over the segments x = a + s·u, s ∈ [0, la] and y = c + t·σu, t ∈ [0, lc]
/// (σ = ±1: the second runs along or against the first): with w = s − σt + (a − c)·u and δ the
/// lines' distance, ln r = ½ ln(w² + δ²), and twice integrating it gives
/// F₂(w) = ¼ (w² − δ²) ln(w² + δ²) − ¾ w² + δ w atan(w/δ).
fn parallel_edges_log(a: DVec3, u: DVec3, la: f64, c: DVec3, lc: f64, sigma: f64) -> f64 {
    let diff = a - c;
    let ax = diff.dot(u);
    let delta = (diff - u * ax).length();
    let f2 = |w: f64| {
        let r2 = w * w + delta * delta;
        let log = if r2 > 0.0 { r2.ln() } else { 0.0 };
        let at = if delta > 0.0 { delta * w * (w / delta).atan() } else { 0.0 };
        0.25 * (w * w - delta * delta) * log - 0.75 * w * w + at
    };
    if sigma > 0.0 {
        // ∫₀^lc f(ax + s − t) dt = F₁(ax + s) − F₁(ax + s − lc), then over s.
        (f2(ax + la) - f2(ax)) - (f2(ax + la - lc) - f2(ax - lc))
    } else {
        // dx · dy = −ds dt; ∫₀^lc f(ax + s + t) dt = F₁(ax + s + lc) − F₁(ax + s).
        -((f2(ax + la + lc) - f2(ax + lc)) - (f2(ax + la) - f2(ax)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::form_factor::{gauss_legendre, polygon_to_polygon};
    use crate::math::polygon_area;

    fn quad(o: DVec3, u: DVec3, v: DVec3) -> Vec<DVec3> {
        vec![o, o + u, o + u + v, o + v]
    }

    /// The double contour integral of axis-aligned polygons matches the adaptive cubature to
    /// 1e-9 (touching, apart, parallel, perpendicular, partial contact), and declines pairs it
    /// cannot do.
    #[test]
    fn axial_pairs_are_exact() {
        let (x, y, z) = (DVec3::X, DVec3::Y, DVec3::Z);
        let floor = quad(DVec3::ZERO, x, y);
        let cases: Vec<(&str, Vec<DVec3>, Vec<DVec3>)> = vec![
            // Facing the floor from above, CCW seen from below.
            ("parallel at 1", floor.clone(), quad(z, y, x)),
            ("parallel offset", floor.clone(), quad(DVec3::new(0.5, -0.3, 0.4), y * 0.7, x * 1.3)),
            // A wall crossing the floor's plane: the part above it counts.
            ("perpendicular, straddling", floor.clone(), quad(DVec3::new(0.2, -0.1, -0.5), z * 1.0, x * 0.6)),
            // A wall on the floor's edge y = 0, facing +y.
            ("perpendicular, shared edge", floor.clone(), quad(DVec3::ZERO, z, x)),
            ("perpendicular, partial edge", floor.clone(), quad(DVec3::new(0.3, 0.0, 0.0), z * 0.5, x * 1.2)),
            // A box's face standing on the floor sees the floor in front of it only.
            (
                "box face standing on the floor",
                floor.clone(),
                quad(DVec3::new(0.2, 0.4, 0.0), z * 0.3, x * 0.3),
            ),
            (
                "box face, the floor's piece",
                quad(DVec3::new(0.5, 0.25, 0.0), x * 0.25, y * 0.25),
                quad(DVec3::new(0.2, 0.4, 0.0), z * 0.3, x * 0.3),
            ),
            ("perpendicular, apart", floor.clone(), quad(DVec3::new(0.1, -0.2, 0.15), z * 0.6, x * 0.5)),
            (
                "small wall piece, far along",
                quad(DVec3::new(0.5, 0.5, 0.0), x * 0.25, y * 0.25),
                quad(DVec3::ZERO, z * 0.25, x * 0.25),
            ),
        ];
        for (name, from, to) in &cases {
            let exact = polygon_to_polygon(from, to, 1e-12);
            let axial = polygon_to_polygon_axial(from, to).unwrap_or_else(|| panic!("{name}: declined"));
            assert!((axial - exact).abs() <= 1e-9 * exact.max(1e-3), "{name}: {axial} vs {exact}");
            let back = polygon_to_polygon_axial(to, from).unwrap();
            let (af, at) = (polygon_area(from), polygon_area(to));
            assert!((af * axial - at * back).abs() <= 1e-12 * af, "{name}: reciprocity");
        }
        // Catalog values: parallel unit squares at 1, perpendicular with a common edge.
        let pf = polygon_to_polygon_axial(&floor, &quad(z, y, x)).unwrap();
        assert!((pf - 0.199_824_895_7).abs() < 1e-9, "{pf}");
        let pp = polygon_to_polygon_axial(&floor, &quad(DVec3::ZERO, z, x)).unwrap();
        assert!((pp - 0.200_043_776).abs() < 1e-8, "{pp}");
        // Declined: a 45° edge. Facing away: nothing.
        let tri = vec![DVec3::new(0.0, 0.0, 1.0), DVec3::new(0.0, 1.0, 1.0), DVec3::new(1.0, 0.0, 1.0)];
        assert_eq!(polygon_to_polygon_axial(&floor, &tri), None);
        assert_eq!(polygon_to_polygon_axial(&floor, &quad(z, x, y)), Some(0.0));
    }

    /// The double contour integral with oblique edge pairs matches 1e-12 cubature to the
    /// tolerance asked (1e-3, 1e-4, 1e-7): turned boxes on a floor (touching along an edge at
    /// 30°), a tilted panel on a shared edge, T-junctions, triangles, pairs apart; both
    /// directions agree (reciprocity); axial pairs get the axial closed form's very number.
    #[test]
    fn oblique_pairs_match_the_cubature() {
        let (x, y, z) = (DVec3::X, DVec3::Y, DVec3::Z);
        let floor = quad(DVec3::ZERO, x, y);
        let turn = |deg: f64| {
            let (s, c) = deg.to_radians().sin_cos();
            DVec3::new(c, s, 0.0)
        };
        let (t30, t120) = (turn(30.0), turn(120.0));
        let tilt = (y + z).normalize();
        let cases: Vec<(&str, Vec<DVec3>, Vec<DVec3>)> = vec![
            // A face of a box turned by 30°, standing on the floor (its normal along t120).
            ("turned face on the floor", floor.clone(), quad(DVec3::new(0.3, 0.2, 0.0), z * 0.4, t30 * 0.5)),
            (
                "turned face, floor piece",
                quad(DVec3::new(0.25, 0.5, 0.0), x * 0.25, y * 0.25),
                quad(DVec3::new(0.3, 0.2, 0.0), z * 0.4, t30 * 0.5),
            ),
            // A panel on the floor's edge y = 0, tilted by 45° over it.
            ("tilted panel, shared edge", floor.clone(), quad(DVec3::ZERO, tilt, x)),
            (
                "tilted panel, partial edge",
                floor.clone(),
                quad(DVec3::new(0.2, 0.0, 0.0), tilt * 0.7, x * 0.5),
            ),
            // A triangle standing on the floor, base at 30°.
            (
                "triangle on the floor",
                floor.clone(),
                vec![
                    DVec3::new(0.2, 0.3, 0.0),
                    DVec3::new(0.2, 0.3, 0.0) + t30 * 0.6,
                    DVec3::new(0.2, 0.3, 0.0) + t30 * 0.3 + z * 0.5,
                ],
            ),
            // Apart, near: a turned square above the floor facing down.
            ("turned square above", floor.clone(), quad(DVec3::new(0.5, 0.1, 0.3), t120 * 0.4, t30 * 0.4)),
            ("turned wall apart", floor.clone(), quad(DVec3::new(0.3, 0.2, 0.05), z * 0.4, t30 * 0.5)),
            // A turned face reaching over the floor's edge (clipped by nothing, partly outside).
            ("turned face over the edge", floor.clone(), quad(DVec3::new(0.8, 0.3, 0.0), z * 0.4, t30 * 0.5)),
            // Triangles facing each other across a corner.
            ("triangles at a corner", vec![DVec3::ZERO, x, y], vec![DVec3::ZERO, z, x * 0.7 + y * 0.7]),
        ];
        for (name, from, to) in &cases {
            let exact = polygon_to_polygon(from, to, 1e-12);
            assert!(exact > 1e-3, "{name}: a case that exchanges light ({exact})");
            let (af, at) = (polygon_area(from), polygon_area(to));
            for tol in [1e-3, 1e-4, 1e-7] {
                let f = polygon_to_polygon_contour(from, to, tol, 0.0)
                    .unwrap_or_else(|| panic!("{name}: declined"));
                assert!((f - exact).abs() <= tol * exact, "{name}, {tol:e}: {f} vs {exact}");
                let back = polygon_to_polygon_contour(to, from, tol, 0.0).unwrap();
                assert!((af * f - at * back).abs() <= 2.0 * tol * af * f, "{name}, {tol:e}: reciprocity");
            }
        }
        // The axial pairs' closed form is the same number.
        let box_face = quad(DVec3::new(0.2, 0.4, 0.0), z * 0.3, x * 0.3);
        let axial = polygon_to_polygon_axial(&floor, &box_face).unwrap();
        assert_eq!(polygon_to_polygon_contour(&floor, &box_face, 1e-4, 0.0), Some(axial));
    }

    /// Two faces of a turned box whose float vertices nearly share an edge (splash_room's
    /// furniture): they face almost away, F = 3.2268e-8, and their clipped parts are slivers
    /// 2e-5 wide along a 160-long edge. The nearly parallel edges must take the oblique rule
    /// (the parallel closed form read 0 one way and 9.7e-8 the other), and the result meets the
    /// absolute tolerance or is declined.
    #[test]
    fn contour_of_a_nearly_shared_edge_meets_its_tolerance() {
        let v = DVec3::new;
        let a = vec![
            v(426.24676513671875, 114.15879821777344, -471.197998046875),
            v(276.8982849121094, 53.78450012207031, -435.511962890625),
            v(242.07681274414063, 118.5205078125, -427.1959228515625),
            v(391.42529296875, 178.89480590820313, -462.8819580078125),
        ];
        let b = vec![
            v(461.68572998046875, 114.15879821777344, -368.20703125),
            v(312.3371887207031, 53.78450012207031, -332.52099609375),
            v(276.8982238769531, 53.78450012207031, -435.511962890625),
            v(426.24676513671875, 114.15879821777344, -471.197998046875),
        ];
        // The converged value (the rules at 64 and 128 nodes agree to 3e-12 of it; adaptive
        // cubature stops at its 2 M evaluation cap at 3.2264e-8).
        let exact = 3.226_79e-8;
        let fine = [gauss_legendre(64), gauss_legendre(128)];
        let f = contour(&a, &b, Some((&fine, 1)), 1.0, 1.0).unwrap();
        assert!((f - exact).abs() < 1e-12, "{f}");
        let back = contour(&b, &a, Some((&fine, 1)), 1.0, 1.0).unwrap() * polygon_area(&b) / polygon_area(&a);
        assert!((back - exact).abs() < 1e-12, "{back}");
        for (rel, abs) in [(1e-4, 1e-8), (1e-7, 1e-8), (1e-7, 1e-10)] {
            for (from, to, scale) in [(&a, &b, 1.0), (&b, &a, polygon_area(&b) / polygon_area(&a))] {
                if let Some(f) = polygon_to_polygon_contour(from, to, rel, abs) {
                    assert!(
                        (f * scale - exact).abs() <= (rel * exact).max(abs * scale),
                        "{rel:e} {abs:e}: {f}"
                    );
                }
            }
        }
    }

    /// Two adjacent faces of a turned box in splash_room (outward normals at 90°), whose float
    /// vertices are up to 2e-3 apart along their shared 232-long edge: they see each other only
    /// through slivers, F = 7.0e-7 and 8.6e-8. The terms of the nearly parallel edge pairs are
    /// ~1e6 times the sum and cancel, so at the solver's tolerance for input patches (1e-4, or
    /// 1e-8 in F) three edge pairs climb to the 32-node rule while the others stay on 6 nodes.
    /// The result meets the tolerance both ways round, and reciprocity holds to it.
    #[test]
    fn contour_climbs_only_the_edge_pairs_that_need_it() {
        let v = DVec3::new;
        let a = vec![
            v(298.4709167480469, -566.6668090820313, 97.59332275390625),
            v(509.4880065917969, -518.14697265625, 179.592041015625),
            v(500.6932067871094, -485.80908203125, 176.1739501953125),
            v(289.6761169433594, -534.3289184570313, 94.17523193359375),
        ];
        let b = vec![
            v(289.6761169433594, -534.3289184570313, 94.17523193359375),
            v(500.6932067871094, -485.8091125488281, 176.17462158203125),
            v(635.9310913085938, -485.8091125488281, -65.50457763671875),
            v(424.91400146484375, -534.3289184570313, -147.50396728515625),
        ];
        let settled = |from: &[DVec3], to: &[DVec3]| {
            let exact = polygon_to_polygon(from, to, 1e-10);
            assert!(exact > 5e-8, "{exact}");
            let f =
                polygon_to_polygon_contour(from, to, 1e-4, 1e-8).expect("settled by the contour integral");
            assert!((f - exact).abs() <= (1e-4 * exact).max(1e-8), "{f} vs {exact}");
            f
        };
        let (fab, fba) = (settled(&a, &b), settled(&b, &a));
        let (aa, ab) = (polygon_area(&a), polygon_area(&b));
        assert!((aa * fab - ab * fba).abs() <= 1e-8 * (aa + ab), "reciprocity");
    }
}
