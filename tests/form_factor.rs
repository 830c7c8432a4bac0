//! Form-factor kernels against closed forms evaluated here [Howell, "A Catalog of Radiation Heat
//! Transfer Configuration Factors", B-3, C-11, C-14], reciprocity, enclosure sums, and Monte
//! Carlo consistency.

use radlab::geometry::form_factor::{
    disk, point_to_polygon, point_to_polygon_mc, polygon_to_polygon, polygon_to_polygon_adaptive,
    polygon_to_polygon_fixed, polygon_to_polygon_mc,
};
use radlab::math::{DVec3, polygon_area};
use std::f64::consts::PI;

/// The target for area-to-area quadrature (relative).
const QUAD_TARGET: f64 = 1e-6;
/// Tolerance asked of the adaptive quadrature: two orders below the target, since its error
/// estimate is the target's guard.
const QUAD_ASK: f64 = 1e-8;
/// The error estimate is an estimate: at coarse tolerances the true error of shared-edge pairs
/// reached 1.5× the tolerance in a sweep (parallel and perpendicular catalog cases).
const TOL_SLACK: f64 = 2.0;
/// The target for the exact point kernel (relative).
const POINT_TARGET: f64 = 1e-9;
/// Monte Carlo estimates must fall within this many standard errors (≈ 6e-5 two-sided chance
/// of a miss per check for a normal estimate).
const MC_SIGMAS: f64 = 4.0;

fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

/// Directly opposed parallel rectangles a×b at distance c [Howell C-11].
fn parallel_closed_form(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / c, b / c);
    let (x2, y2) = (x * x, y * y);
    2.0 / (PI * x * y)
        * (((1.0 + x2) * (1.0 + y2) / (1.0 + x2 + y2)).sqrt().ln()
            + x * (1.0 + y2).sqrt() * (x / (1.0 + y2).sqrt()).atan()
            + y * (1.0 + x2).sqrt() * (y / (1.0 + x2).sqrt()).atan()
            - x * x.atan()
            - y * y.atan())
}

/// Perpendicular rectangles with a common edge of length l, from the one of width w to the one
/// of height h [Howell C-14].
fn perpendicular_closed_form(l: f64, w: f64, h: f64) -> f64 {
    let (ww, hh) = (w / l, h / l);
    let (w2, h2) = (ww * ww, hh * hh);
    let s = (w2 + h2).sqrt();
    let ln_term = ((1.0 + w2) * (1.0 + h2) / (1.0 + w2 + h2)).ln()
        + w2 * (w2 * (1.0 + w2 + h2) / ((1.0 + w2) * (w2 + h2))).ln()
        + h2 * (h2 * (1.0 + w2 + h2) / ((1.0 + h2) * (h2 + w2))).ln();
    1.0 / (PI * ww)
        * (ww * (1.0 / ww).atan() + hh * (1.0 / hh).atan() - s * (1.0 / s).atan() + 0.25 * ln_term)
}

/// Rectangle [0,a]×[0,b] at z = 0 facing +z, and its opposite at z = c facing −z.
fn parallel_pair(a: f64, b: f64, c: f64) -> (Vec<DVec3>, Vec<DVec3>) {
    (
        vec![v(0., 0., 0.), v(a, 0., 0.), v(a, b, 0.), v(0., b, 0.)],
        vec![v(0., 0., c), v(0., b, c), v(a, b, c), v(a, 0., c)],
    )
}

/// Horizontal l×w (facing +z) and vertical l×h (facing +y) sharing the edge y = z = 0.
fn perpendicular_pair(l: f64, w: f64, h: f64) -> (Vec<DVec3>, Vec<DVec3>) {
    (
        vec![v(0., 0., 0.), v(l, 0., 0.), v(l, w, 0.), v(0., w, 0.)],
        vec![v(0., 0., 0.), v(0., 0., h), v(l, 0., h), v(l, 0., 0.)],
    )
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

#[test]
fn parallel_rectangles_match_closed_form_including_near_contact_and_slivers() {
    for (a, b, c) in [
        (1.0, 1.0, 1.0),
        (2.0, 0.5, 0.3),
        (1.0, 1.0, 0.01),
        (1.0, 0.01, 1.0),
        (1.0, 0.01, 0.01),
        (3.0, 1.0, 10.0),
    ] {
        let (from, to) = parallel_pair(a, b, c);
        let exact = parallel_closed_form(a, b, c);
        let q = polygon_to_polygon_adaptive(&from, &to, QUAD_ASK, 0.0);
        assert!(q.converged, "{a}×{b} at {c}: not converged after {} evaluations", q.evaluations);
        assert!(rel(q.value, exact) < QUAD_TARGET, "{a}×{b} at {c}: {} vs {exact}", q.value);
        // The error estimate is honest: the true error is below it (with a rounding floor).
        assert!(
            (q.value - exact).abs() <= q.error + 1e-14,
            "{a}×{b} at {c}: error {} > estimate {}",
            (q.value - exact).abs(),
            q.error
        );
    }
}

#[test]
fn perpendicular_rectangles_with_common_edge_match_closed_form() {
    for (l, w, h) in [(1.0, 1.0, 1.0), (1.0, 3.0, 0.5), (1.0, 0.01, 1.0), (1.0, 1.0, 0.01), (2.0, 0.7, 1.3)] {
        let (from, to) = perpendicular_pair(l, w, h);
        let exact = perpendicular_closed_form(l, w, h);
        let f = polygon_to_polygon(&from, &to, QUAD_ASK);
        assert!(rel(f, exact) < QUAD_TARGET, "l={l} w={w} h={h}: {f} vs {exact}");
        // Coarse tolerances (what the solvers ask) are honoured too, despite the log-singular
        // kernel at the shared edge.
        for tol in [1e-3, 1e-4, 1e-5] {
            let f = polygon_to_polygon(&from, &to, tol);
            assert!(rel(f, exact) < TOL_SLACK * tol, "l={l} w={w} h={h} tol {tol}: {f} vs {exact}");
        }
    }
}

#[test]
fn reciprocity_holds_for_assorted_pairs() {
    let tri = vec![v(0.2, 0.1, 0.0), v(1.4, 0.3, 0.1), v(0.5, 1.2, 0.05)];
    let tilted = vec![v(0.0, 0.0, 1.0), v(0.0, 1.0, 1.4), v(1.5, 1.0, 1.2), v(1.5, 0.0, 0.8)];
    let (p1, p2) = perpendicular_pair(1.0, 3.0, 0.5);
    let (s1, s2) = parallel_pair(1.0, 0.01, 0.01);
    for (i, j) in [(&tri, &tilted), (&p1, &p2), (&s1, &s2)] {
        let fij = polygon_to_polygon(i, j, QUAD_ASK);
        let fji = polygon_to_polygon(j, i, QUAD_ASK);
        assert!(fij > 0.0 && fji > 0.0);
        let (ai, aj) = (polygon_area(i), polygon_area(j));
        assert!(rel(ai * fij, aj * fji) < QUAD_TARGET, "A_i F_ij = {} vs A_j F_ji = {}", ai * fij, aj * fji);
    }
}

/// A closed 1×2×3 box, inward-facing, with the floor cut into a triangle pair and one wall into
/// two unequal quads: every row of form factors sums to one.
#[test]
fn closed_box_rows_sum_to_one() {
    let (x, y, z) = (1.0, 2.0, 3.0);
    let faces: Vec<Vec<DVec3>> = vec![
        vec![v(0., 0., 0.), v(x, 0., 0.), v(x, y, 0.)], // floor, two triangles (+z)
        vec![v(0., 0., 0.), v(x, y, 0.), v(0., y, 0.)],
        vec![v(0., 0., z), v(0., y, z), v(x, y, z), v(x, 0., z)], // ceiling (−z)
        vec![v(0., 0., 0.), v(0., 0., 0.7), v(x, 0., 0.7), v(x, 0., 0.)], // y = 0 (+y), two quads
        vec![v(0., 0., 0.7), v(0., 0., z), v(x, 0., z), v(x, 0., 0.7)],
        vec![v(0., y, 0.), v(x, y, 0.), v(x, y, z), v(0., y, z)], // y = y (−y)
        vec![v(0., 0., 0.), v(0., y, 0.), v(0., y, z), v(0., 0., z)], // x = 0 (+x)
        vec![v(x, 0., 0.), v(x, 0., z), v(x, y, z), v(x, y, 0.)], // x = x (−x)
    ];
    let centre = v(x / 2.0, y / 2.0, z / 2.0);
    for f in &faces {
        let n = radlab::math::polygon_normal(f);
        assert!(n.dot(centre - f[0]) > 0.0, "faces point inward");
    }
    for (i, fi) in faces.iter().enumerate() {
        let sum: f64 = faces.iter().map(|fj| polygon_to_polygon(fi, fj, QUAD_ASK)).sum();
        assert!((sum - 1.0).abs() < QUAD_TARGET, "row {i} sums to {sum}");
    }
}

/// Parallel differential element at a corner of an a×b rectangle at distance c [Howell B-3].
#[test]
fn point_kernel_matches_corner_closed_form() {
    for (a, b, c) in [(1.0_f64, 1.0_f64, 1.0_f64), (0.3, 2.0, 0.7), (1e-3, 1.0, 1.0), (5.0, 4.0, 1e-3)] {
        let (x, y) = (a / c, b / c);
        let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
        let exact = (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * PI);
        let rect = [v(0., 0., c), v(0., b, c), v(a, b, c), v(a, 0., c)];
        let f = point_to_polygon(DVec3::ZERO, DVec3::Z, &rect);
        assert!(rel(f, exact) < POINT_TARGET, "{a}×{b} at {c}: {f} vs {exact}");
        // The same, far from the origin: rounding of 1e6 coordinates is ~1e-10 of the geometry.
        let o = DVec3::splat(1e6);
        let moved: Vec<DVec3> = rect.iter().map(|p| *p + o).collect();
        let g = point_to_polygon(o, DVec3::Z, &moved);
        assert!(rel(g, exact) < 1e-6, "translated: {g} vs {exact}");
    }
}

/// A point on the axis of a regular n-gon (circumradius R, apothem r_a = R cos(π/n)) at height h:
/// each of the n edges subtends β = acos((R² cos(2π/n) + h²)/(R² + h²)) with n·γ = r_a/√(h² + r_a²),
/// so F = n β r_a / (2π √(h² + r_a²)); as n → ∞ this tends to the disk's R²/(R² + h²).
#[test]
fn point_kernel_matches_regular_polygon_and_disk() {
    for (sides, big_r, h) in [(3u32, 1.0_f64, 0.5_f64), (8, 0.7, 1.3), (64, 2.0, 0.1), (1024, 0.7, 1.3)] {
        let verts: Vec<DVec3> = (0..sides)
            .rev()
            .map(|i| {
                let t = 2.0 * PI * f64::from(i) / f64::from(sides);
                v(big_r * t.cos(), big_r * t.sin(), h)
            })
            .collect();
        let n = f64::from(sides);
        let ra = big_r * (PI / n).cos();
        let beta = ((big_r * big_r * (2.0 * PI / n).cos() + h * h) / (big_r * big_r + h * h)).acos();
        let exact = n * beta * ra / (2.0 * PI * (h * h + ra * ra).sqrt());
        let f = point_to_polygon(DVec3::ZERO, DVec3::Z, &verts);
        assert!(rel(f, exact) < POINT_TARGET, "{sides}-gon: {f} vs {exact}");
        // Inscribed polygon ⊂ disk of radius R, ⊃ disk of radius r_a: F is bracketed by the
        // disk closed forms (which also are what `disk` returns for the same areas).
        let (lo, hi) = (ra * ra / (ra * ra + h * h), big_r * big_r / (big_r * big_r + h * h));
        assert!(f >= lo - 1e-15 && f <= hi + 1e-15);
        let d_hi = disk(DVec3::ZERO, DVec3::Z, v(0., 0., h), -DVec3::Z, PI * big_r * big_r);
        assert!(rel(d_hi, hi) < 1e-14);
    }
}

#[test]
fn point_on_shared_edge_gives_the_limit_not_nan() {
    // Vertical unit square x = 0 facing +x; receivers on the floor facing +z.
    let wall = [v(0., 0., 0.), v(0., 1., 0.), v(0., 1., 1.), v(0., 0., 1.)];
    let on_edge = point_to_polygon(v(0.0, 0.5, 0.0), DVec3::Z, &wall);
    let near = point_to_polygon(v(1e-9, 0.5, 0.0), DVec3::Z, &wall);
    // Near the edge the kernel varies like δ·ln δ, so at δ = 1e-9 it is within ~1e-7 of its limit.
    assert!((on_edge - near).abs() < 1e-7, "{on_edge} vs {near}");
    assert!(
        (on_edge - 0.5).abs() < 1e-6,
        "an infinitesimal strip at the foot of a wall sees ~half of it: {on_edge}"
    );
    for p in [v(0., 0., 0.), v(0., 1., 0.), v(0., 0.5, 0.5), v(0., 2.0, 0.0), v(-1e-300, 0.5, 0.0)] {
        let f = point_to_polygon(p, DVec3::Z, &wall);
        assert!(f.is_finite() && (0.0..=1.0).contains(&f), "{p}: {f}");
    }
    // Contact: a receiver facing the source from inside it sees all of it.
    assert!((point_to_polygon(v(0., 0.5, 0.5), -DVec3::X, &wall) - 1.0).abs() < 1e-12);
    // A tilted receiver touching the source inside it sees the half in front of its tangent plane.
    assert!((point_to_polygon(v(0., 0.5, 0.5), DVec3::Z, &wall) - 0.5).abs() < 1e-12);
    // Non-convex (bow-tie) input must not panic.
    let bowtie = [v(0., 0., 1.), v(1., 1., 1.), v(1., 0., 1.), v(0., 1., 1.), v(0.5, 2., 1.), v(2., 0.5, 1.)];
    assert!(point_to_polygon(v(0.5, 0.5, 0.0), DVec3::X, &bowtie).is_finite());
    // Garbage in, zero out.
    assert_eq!(point_to_polygon(v(f64::NAN, 0., 0.), DVec3::Z, &wall), 0.0);
    assert_eq!(
        point_to_polygon(v(1., 0., 0.), DVec3::Z, &[v(0., 0., 0.), v(0., 1., 0.), v(0., 2., 0.)]),
        0.0
    );
    assert_eq!(polygon_to_polygon(&wall, &wall[..2], QUAD_ASK), 0.0);
}

#[test]
fn facing_away_and_coplanar_pairs_are_zero() {
    let (from, to) = parallel_pair(1.0, 1.0, 1.0);
    let flipped: Vec<DVec3> = to.iter().rev().copied().collect();
    assert_eq!(polygon_to_polygon(&from, &flipped, QUAD_ASK), 0.0);
    let beside = vec![v(1., 0., 0.), v(2., 0., 0.), v(2., 1., 0.), v(1., 1., 0.)];
    assert_eq!(polygon_to_polygon(&from, &beside, QUAD_ASK), 0.0);
}

#[test]
fn fixed_quadrature_converges_for_separated_pairs() {
    let (from, to) = parallel_pair(1.0, 1.0, 2.0);
    let exact = parallel_closed_form(1.0, 1.0, 2.0);
    let errs: Vec<f64> =
        [1, 2, 4, 8].iter().map(|&n| rel(polygon_to_polygon_fixed(&from, &to, n), exact)).collect();
    // Smooth kernel: Gauss–Legendre converges fast (each doubling gains orders of magnitude).
    assert!(errs[3] < QUAD_TARGET, "{errs:?}");
    assert!(errs[1] < errs[0] && errs[2] < errs[1], "{errs:?}");
}

#[test]
fn monte_carlo_is_within_four_standard_errors() {
    let cases = [
        parallel_pair(1.0, 1.0, 1.0),
        parallel_pair(2.0, 0.5, 0.3),
        perpendicular_pair(1.0, 1.0, 1.0),
        perpendicular_pair(1.0, 0.01, 1.0),
    ];
    let exacts = [
        parallel_closed_form(1.0, 1.0, 1.0),
        parallel_closed_form(2.0, 0.5, 0.3),
        perpendicular_closed_form(1.0, 1.0, 1.0),
        perpendicular_closed_form(1.0, 0.01, 1.0),
    ];
    for (seed, ((from, to), exact)) in cases.iter().zip(exacts).enumerate() {
        let (f, se) = polygon_to_polygon_mc(from, to, 4000, seed as u64);
        assert!(se > 0.0 && se < 0.05, "standard error {se}");
        assert!((f - exact).abs() < MC_SIGMAS * se, "case {seed}: {f} ± {se} vs {exact}");
        // Deterministic for a seed.
        assert_eq!(polygon_to_polygon_mc(from, to, 4000, seed as u64), (f, se));
    }
    // Point to rectangle, area sampling of cosθ cosθ'/(π r²).
    let rect = [v(0., 0., 1.), v(0., 1., 1.), v(1., 1., 1.), v(1., 0., 1.)];
    let exact = point_to_polygon(DVec3::ZERO, DVec3::Z, &rect);
    let (f, se) = point_to_polygon_mc(DVec3::ZERO, DVec3::Z, &rect, 20_000, 7);
    assert!((f - exact).abs() < MC_SIGMAS * se, "{f} ± {se} vs {exact}");
}

/// A wall standing on the middle of a floor (a T-junction: the wall's foot crosses the floor's
/// interior). Part of the floor is behind the wall's plane, where the one-sided kernel jumps to
/// 0; the receiver must be clipped to the front part before integrating, or an oblique jump
/// costs the cubature a staircase of millions of evaluations.
#[test]
fn wall_standing_inside_a_floor() {
    // Aligned with the floor's edges: Howell C-14 with l = 2 on the front 2/3.4 of the floor.
    let floor = vec![v(-0.7, -1., 0.), v(1., -1., 0.), v(1., 1., 0.), v(-0.7, 1., 0.)];
    let wall = vec![v(0., -1., 0.), v(0., 1., 0.), v(0., 1., 1.), v(0., -1., 1.)]; // faces +x
    let (exact, front) = (perpendicular_closed_form(2.0, 1.0, 1.0), 2.0 / 3.4);
    let q = polygon_to_polygon_adaptive(&floor, &wall, QUAD_ASK, 0.0);
    assert!(rel(q.value, front * exact) < QUAD_TARGET, "{} vs {}", q.value, front * exact);
    assert!(rel(polygon_to_polygon(&wall, &floor, QUAD_ASK), exact) < QUAD_TARGET);
    // Oblique (rotated 0.5 rad): integrating over the floor (clipped) must agree with
    // integrating over the wall (no jump there) through reciprocity, at a bounded cost.
    let d = v(-0.5f64.sin(), 0.5f64.cos(), 0.0);
    let wall = vec![d * -0.8, d * 0.8, d * 0.8 + DVec3::Z, d * -0.8 + DVec3::Z];
    let q = polygon_to_polygon_adaptive(&floor, &wall, QUAD_ASK, 0.0);
    assert!(q.converged && q.evaluations < 200_000, "{q:?}: the jump was not clipped away");
    let back = polygon_to_polygon(&wall, &floor, QUAD_ASK);
    let (af, aw) = (polygon_area(&floor), polygon_area(&wall));
    assert!(rel(af * q.value, aw * back) < QUAD_TARGET, "{} vs {}", af * q.value, aw * back);
    let (f, se) = polygon_to_polygon_mc(&floor, &wall, 4000, 3);
    assert!((f - q.value).abs() < MC_SIGMAS * se, "{f} ± {se} vs {}", q.value);
    let fixed = polygon_to_polygon_fixed(&floor, &wall, 8);
    assert!(rel(fixed, q.value) < 1e-2, "fixed 8×8 on the clipped floor: {fixed} vs {}", q.value);
}
