//! The point-to-polygon kernel in closed form: Lambert's contour integral
//!
//! ```text
//! F(x → j) = 1/(2π) Σ_k β_k n·γ_k          [Cohen & Wallace 1993, eq. 4.17; Baum, Rushmeier, Winget 1989]
//! ```
//!
//! β_k the angle edge k subtends at x, γ_k the unit normal of the plane through x and edge k. The
//! source is first clipped against the receiver's tangent plane; a point in the source's plane
//! takes the limit from the front. Angles by a polynomial `atan2` ([`angle`]), triangles and quads
//! by a fixed-size path whose four edge terms are computed side by side ([`edge_terms4`]), the
//! same bits as the general loop. Also the lecture's disk approximation ([`disk`]).

use super::IN_PLANE_REL;
use crate::math::{DVec3, newell_normal};
use std::f64::consts::PI;

/// it, so a receiver touching the source plane does not clip vertices away by rounding.
const CLIP_REL: f64 = 1e-12;
/// In the source plane, an edge whose cross product is below this fraction of |a||b| is collinear
/// with the receiver point (angles then come from the in-plane limit, not from `atan2`).
const COLLINEAR_REL: f64 = 1e-12;

/// Exact form factor from a differential area at `p` with unit normal `n` to a convex polygon
/// (counter-clockwise seen from its front).
///
/// One-sided: 0 when `p` is behind the polygon's plane (it radiates only from its front).
/// The polygon is first clipped against the receiver's tangent plane, so only the part in front
/// of `p` counts. Never NaN: a point in the polygon's plane — on an edge, a vertex, inside the
/// polygon (contact) — gives the limit as `p` approaches from the front; non-finite input gives 0.
#[must_use]
pub fn point_to_polygon(p: DVec3, n: DVec3, verts: &[DVec3]) -> f64 {
    if verts.len() < 3 {
        return 0.0;
    }
    let src_n = newell_normal(verts).normalize_or_zero();
    point_to_polygon_unit(p, n, verts, src_n)
}

/// [`point_to_polygon`] with the source's unit normal given (e.g. a hierarchy element's, which
/// is its patch's): no normal to recompute per evaluation.
#[must_use]
pub fn point_to_polygon_oriented(p: DVec3, n: DVec3, verts: &[DVec3], src_n: DVec3) -> f64 {
    if verts.len() < 3 {
        return 0.0;
    }
    point_to_polygon_unit(p, n, verts, src_n)
}

/// [`point_to_polygon`] with the source's unit normal precomputed: triangles and quads (every
/// element of a hierarchy, nearly every input patch) by [`point_to_small_polygon`], larger
/// polygons by [`point_to_polygon_general`]. Both give the same bits.
#[inline]
pub(super) fn point_to_polygon_unit(p: DVec3, n: DVec3, verts: &[DVec3], src_n: DVec3) -> f64 {
    match *verts {
        [a, b, c] => point_to_small_polygon(p, n, [a, b, c], src_n),
        [a, b, c, d] => point_to_small_polygon(p, n, [a, b, c, d], src_n),
        _ => point_to_polygon_general(p, n, verts, src_n),
    }
}

/// [`point_to_polygon_general`] for a polygon of `K` ≤ 4 vertices known at compile time: the
/// same floating-point operations in the same order, so the same bits (tested on random
/// polygons), but each vertex's offset from `p` and height over the tangent plane computed
/// once (the general loop computes both twice), no index arithmetic, the loops unrolled, no
/// clip copy when the whole polygon lies in front of the tangent plane (most evaluations), and
/// the edge terms four at a time ([`edge_terms4`]). The rare point in the source's plane takes
/// the general path.
#[inline]
fn point_to_small_polygon<const K: usize>(p: DVec3, n: DVec3, verts: [DVec3; K], src_n: DVec3) -> f64 {
    if src_n == DVec3::ZERO {
        return 0.0;
    }
    let a = verts.map(|v| v - p);
    let scale = a.iter().map(|a| a.length_squared()).fold(0.0, f64::max).sqrt();
    if !(scale > 0.0 && scale.is_finite()) {
        return 0.0;
    }
    let dist = verts.iter().map(|v| src_n.dot(p - *v)).sum::<f64>() / K as f64;
    if dist.is_nan() || dist < -IN_PLANE_REL * scale {
        return 0.0; // behind
    }
    if dist <= IN_PLANE_REL * scale {
        return point_to_polygon_general(p, n, &verts, src_n);
    }
    // Off the source's plane a vertex on the tangent plane stays on it (height 0).
    let h = a.map(|a| {
        let h = n.dot(a);
        if h.abs() <= CLIP_REL * scale { 0.0 } else { h }
    });
    let sum = if h.iter().all(|&h| h >= 0.0) {
        // Nothing clipped: the contour is the polygon itself, one group of four lanes (a
        // triangle's fourth repeats its first edge, unused).
        let from: [DVec3; 4] = std::array::from_fn(|i| a[i % K]);
        let to: [DVec3; 4] = std::array::from_fn(|i| a[(i + 1) % K]);
        match edge_terms4(from, to, n) {
            Some(terms) => terms[..K].iter().fold(0.0, |sum, t| sum + t),
            None => (0..K).fold(0.0, |sum, i| sum + edge_term(a[i], a[(i + 1) % K], n)),
        }
    } else {
        let mut clipped = [DVec3::ZERO; 8];
        let mut m = 0usize;
        for i in 0..K {
            let j = if i + 1 == K { 0 } else { i + 1 };
            let (da, db) = (h[i], h[j]);
            if da >= 0.0 {
                clipped[m] = a[i];
                m += 1;
            }
            if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
                let t = da / (da - db);
                clipped[m] = a[i] + (a[j] - a[i]) * t;
                m += 1;
            }
        }
        if m < 3 {
            return 0.0;
        }
        contour_sum(&clipped[..m], n)
    };
    let f = -sum / (2.0 * PI);
    if f.is_nan() { 0.0 } else { f.clamp(0.0, 1.0) }
}

/// [`point_to_polygon`] with the source's unit normal precomputed, any convex polygon.
fn point_to_polygon_general(p: DVec3, n: DVec3, verts: &[DVec3], src_n: DVec3) -> f64 {
    if src_n == DVec3::ZERO {
        return 0.0;
    }
    let scale = verts.iter().map(|v| (*v - p).length_squared()).fold(0.0, f64::max).sqrt();
    if !(scale > 0.0 && scale.is_finite()) {
        return 0.0;
    }
    // Distance in front of the source plane, averaged over the vertices (planar up to rounding).
    let dist = verts.iter().map(|v| src_n.dot(p - *v)).sum::<f64>() / verts.len() as f64;
    if dist.is_nan() || dist < -IN_PLANE_REL * scale {
        return 0.0; // behind
    }
    let in_plane = dist <= IN_PLANE_REL * scale;
    // In the plane, evaluate at the projection so every edge is exactly in the plane of p.
    let p = if in_plane { p - src_n * dist } else { p };

    // Clip against the receiver's tangent plane: keep n·(v − p) ≥ 0. A convex polygon clipped
    // by one plane gains at most one vertex; room for 2k keeps a non-convex input from panicking.
    let k = verts.len();
    let mut small = [DVec3::ZERO; 8];
    let mut large = Vec::new();
    let clipped: &mut [DVec3] = if k <= 4 {
        &mut small
    } else {
        large.resize(2 * k, DVec3::ZERO);
        &mut large
    };
    // A vertex on the tangent plane: off the plane it is still on it; in the plane, the limit
    // from the front moves it by −δ n·n_src, so its side is the sign of −n·n_src.
    let on_plane = if in_plane { -n.dot(src_n) } else { 0.0 };
    let on_plane = if on_plane.abs() <= CLIP_REL { 0.0 } else { on_plane };
    let height = |v: DVec3| {
        let h = n.dot(v);
        if h.abs() <= CLIP_REL * scale { on_plane } else { h }
    };
    let mut m = 0usize;
    for i in 0..k {
        let a = verts[i] - p;
        let b = verts[(i + 1) % k] - p;
        let (da, db) = (height(a), height(b));
        if da >= 0.0 {
            clipped[m] = a;
            m += 1;
        }
        if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
            let t = da / (da - db);
            clipped[m] = a + (b - a) * t;
            m += 1;
        }
    }
    if m < 3 {
        return 0.0;
    }
    let mut sum = 0.0;
    for i in 0..m {
        let a = clipped[i];
        let b = clipped[(i + 1) % m];
        sum += if in_plane { edge_term_in_plane(a, b, n, src_n) } else { edge_term(a, b, n) };
    }
    // The source faces p, so its contour runs clockwise seen from p: the sum is negative.
    let f = -sum / (2.0 * PI);
    if f.is_nan() { 0.0 } else { f.clamp(0.0, 1.0) }
}

/// atan(√z)/√z on z ∈ [0, tan²(π/8)], a degree-11 polynomial in z (Chebyshev fit with mpmath,
/// relative error 1.3e-18), highest degree first.
const ATAN_POLY: [f64; 12] = [
    -0.017805397205419446,
    0.03796525745386593,
    -0.05035102456601552,
    0.05846878297330872,
    -0.06662951813629191,
    0.07692045330902225,
    -0.09090896809064027,
    0.11111110744919658,
    -0.14285714279250245,
    0.19999999999940893,
    -0.3333333333333312,
    1.0,
];
const TAN_PI_8: f64 = 0.41421356237309503;

/// The angle atan2(y, x) ∈ [0, π] for y ≥ 0 (an edge's subtended angle from |a × b| and a·b):
/// reduced to atan(t), |t| ≤ tan(π/8), by octant symmetry and atan(t) = π/4 + atan((t−1)/(t+1)),
/// then a polynomial. Within a few ulps of `f64::atan2` (tested) and about twice as fast; other
/// inputs (y < 0, zero, non-finite) go to `f64::atan2`.
#[inline(always)]
fn angle(y: f64, x: f64) -> f64 {
    let ax = x.abs();
    if !(y > 0.0 && y.is_finite() && ax.is_finite()) {
        return y.atan2(x);
    }
    let swap = y > ax;
    let t = if swap { ax / y } else { y / ax };
    let (base, t) =
        if t > TAN_PI_8 { (std::f64::consts::FRAC_PI_4, (t - 1.0) / (t + 1.0)) } else { (0.0, t) };
    let z = t * t;
    let mut g = ATAN_POLY[0];
    for &c in &ATAN_POLY[1..] {
        g = g * z + c;
    }
    let a = base + t * g;
    let a = if swap { std::f64::consts::FRAC_PI_2 - a } else { a };
    if x < 0.0 { PI - a } else { a }
}

/// Σ [`edge_term`] over the edges of the closed contour `c` (vectors from the receiver point),
/// in order, four edges at a time by [`edge_terms4`] (a last group of fewer repeats its first
/// edge in the unused lanes); edge by edge if a group meets one of `angle`'s special cases.
#[inline(always)]
fn contour_sum(c: &[DVec3], n: DVec3) -> f64 {
    let m = c.len();
    let next = |e: usize| if e + 1 == m { 0 } else { e + 1 };
    let mut sum = 0.0;
    for first in (0..m).step_by(4) {
        let edge = |i: usize| if first + i < m { first + i } else { first };
        let from: [DVec3; 4] = std::array::from_fn(|i| c[edge(i)]);
        let to: [DVec3; 4] = std::array::from_fn(|i| c[next(edge(i))]);
        let Some(terms) = edge_terms4(from, to, n) else {
            return (0..m).fold(0.0, |sum, e| sum + edge_term(c[e], c[next(e)], n));
        };
        for t in &terms[..(m - first).min(4)] {
            sum += t;
        }
    }
    sum
}

/// [`edge_term`] of four edges `a[i] → b[i]` lane by lane: the same operations as `edge_term`
/// and [`angle`] (the octant reduction by selects instead of branches, `min / max` for the
/// ratio the branch divides), on arrays the compiler turns into vector instructions (the four
/// edges' divisions, square roots and polynomials side by side instead of four dependent
/// chains). The same bits as `edge_term` (tested).
/// None when an edge takes one of `angle`'s special cases (a zero, or non-finite input): then
/// `edge_term` edge by edge.
#[inline(always)]
fn edge_terms4(a: [DVec3; 4], b: [DVec3; 4], n: DVec3) -> Option<[f64; 4]> {
    use std::array::from_fn;
    let c: [DVec3; 4] = from_fn(|i| a[i].cross(b[i]));
    let cl: [f64; 4] = from_fn(|i| c[i].length());
    let x: [f64; 4] = from_fn(|i| a[i].dot(b[i]));
    let ax: [f64; 4] = x.map(f64::abs);
    if !(0..4).all(|i| cl[i] > 0.0 && cl[i].is_finite() && ax[i].is_finite()) {
        return None;
    }
    let t: [f64; 4] = from_fn(|i| ax[i].min(cl[i]) / ax[i].max(cl[i]));
    let reduced: [f64; 4] = from_fn(|i| (t[i] - 1.0) / (t[i] + 1.0));
    let far: [bool; 4] = from_fn(|i| t[i] > TAN_PI_8);
    let t: [f64; 4] = from_fn(|i| if far[i] { reduced[i] } else { t[i] });
    let z: [f64; 4] = from_fn(|i| t[i] * t[i]);
    let mut g = [ATAN_POLY[0]; 4];
    for &coef in &ATAN_POLY[1..] {
        g = from_fn(|i| g[i] * z[i] + coef);
    }
    let base: [f64; 4] = from_fn(|i| if far[i] { std::f64::consts::FRAC_PI_4 } else { 0.0 });
    let r: [f64; 4] = from_fn(|i| base[i] + t[i] * g[i]);
    let r: [f64; 4] = from_fn(|i| if cl[i] > ax[i] { std::f64::consts::FRAC_PI_2 - r[i] } else { r[i] });
    let r: [f64; 4] = from_fn(|i| if x[i] < 0.0 { PI - r[i] } else { r[i] });
    let nc: [f64; 4] = from_fn(|i| n.dot(c[i]));
    Some(from_fn(|i| r[i] * nc[i] / cl[i]))
}

/// β n·γ for edge a→b (vectors from the receiver point), p strictly off the source plane.
#[inline(always)]
fn edge_term(a: DVec3, b: DVec3, n: DVec3) -> f64 {
    let c = a.cross(b);
    let cl = c.length();
    if cl <= 0.0 {
        return 0.0; // repeated clip vertex
    }
    angle(cl, a.dot(b)) * n.dot(c) / cl
}

/// Limit of β n·γ for edge a→b as p approaches the source plane from the front (p in the plane).
///
/// An edge not through p lies in the plane with p: γ = ±n_src and β is its in-plane angle.
/// An edge through p (p inside it: β → π; p at an end: β → π/2) has γ → the outward in-plane
/// normal of the edge, `(b − a) × n_src`.
fn edge_term_in_plane(a: DVec3, b: DVec3, n: DVec3, src_n: DVec3) -> f64 {
    let c = a.cross(b);
    let cl = c.length();
    let (la, lb) = (a.length(), b.length());
    if cl > COLLINEAR_REL * la * lb {
        return angle(cl, a.dot(b)) * c.dot(src_n).signum() * n.dot(src_n);
    }
    let out = (b - a).cross(src_n).normalize_or_zero();
    let beta = if la == 0.0 || lb == 0.0 {
        0.5 * PI
    } else if a.dot(b) < 0.0 {
        PI
    } else {
        0.0
    };
    beta * n.dot(out)
}

/// Disk approximation of the form factor from a differential area at `p` (unit normal `n`) to a
/// source of area `src_area` at `src_centroid` facing `src_normal`:
/// `F ≈ A cosθ cosθ' / (π r² + A)` (the lecture; exact for a coaxial disk). Cosines clamped at 0.
/// At r = 0 (the point on the centroid) the limit along the normals is 1.
#[must_use]
pub fn disk(p: DVec3, n: DVec3, src_centroid: DVec3, src_normal: DVec3, src_area: f64) -> f64 {
    let d = src_centroid - p;
    let r2 = d.length_squared();
    if r2 <= 0.0 {
        return if n.dot(src_normal) < 0.0 { 1.0 } else { 0.0 };
    }
    let r = r2.sqrt();
    let cos_r = (n.dot(d) / r).max(0.0);
    let cos_s = (-src_normal.dot(d) / r).max(0.0);
    let f = src_area * cos_r * cos_s / (PI * r2 + src_area);
    if f.is_nan() { 0.0 } else { f.min(1.0) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Pcg32;

    /// The fixed-size kernel (`point_to_small_polygon`, with its four-lane edge terms) gives
    /// the very bits of the general one for triangles and quads: random convex polygons of all
    /// sizes and positions, receivers in front, behind, in the plane, on edges and vertices,
    /// tangent planes that clip the source or graze its vertices.
    #[test]
    fn small_polygon_kernel_is_the_general_one_bit_for_bit() {
        let mut rng = Pcg32::keyed(7, 15);
        let mut r = move || rng.next_f64();
        let unit =
            |r: &mut dyn FnMut() -> f64| DVec3::new(r() - 0.5, r() - 0.5, r() - 0.5).normalize_or_zero();
        let (mut compared, mut positive, mut clipped, mut in_plane) = (0, 0, 0, 0);
        for case in 0..40_000 {
            // A convex polygon: 3 or 4 points on an ellipse in a random plane, counter-clockwise.
            let k = 3 + case % 2;
            let scale = 10f64.powf(r() * 6.0 - 3.0);
            let centre = DVec3::new(r() - 0.5, r() - 0.5, r() - 0.5) * 10.0 * scale;
            let src_n = unit(&mut r);
            let e1 = src_n.any_orthonormal_vector();
            let e2 = src_n.cross(e1);
            let (ra, rb) = (scale * (0.1 + r()), scale * (0.1 + r()));
            let mut angles: Vec<f64> = (0..k).map(|_| r() * 2.0 * PI).collect();
            angles.sort_by(f64::total_cmp);
            let verts: Vec<DVec3> =
                angles.iter().map(|t| centre + e1 * (ra * t.cos()) + e2 * (rb * t.sin())).collect();
            // The receiver: anywhere, in the source's plane, on a vertex or an edge.
            let p = match case % 7 {
                0 => centre + (e1 * (r() - 0.5) + e2 * (r() - 0.5)) * 3.0 * scale,
                1 => verts[0],
                2 => verts[0] + (verts[1] - verts[0]) * r(),
                _ => centre + DVec3::new(r() - 0.5, r() - 0.5, r() - 0.5) * 4.0 * scale,
            };
            // Its normal: random, or with the tangent plane through a vertex.
            let n = if case % 5 == 0 {
                let w = (verts[case % k] - p).normalize_or_zero();
                w.cross(unit(&mut r)).normalize_or_zero()
            } else {
                unit(&mut r)
            };
            if n == DVec3::ZERO {
                continue;
            }
            let fast = point_to_polygon_unit(p, n, &verts, src_n);
            let general = point_to_polygon_general(p, n, &verts, src_n);
            assert_eq!(fast.to_bits(), general.to_bits(), "case {case}: {fast:e} vs {general:e}");
            compared += 1;
            positive += usize::from(fast > 0.0);
            clipped += usize::from(verts.iter().any(|v| n.dot(*v - p) < 0.0) && fast > 0.0);
            in_plane += usize::from(src_n.dot(p - centre).abs() <= 1e-9 * scale && case % 7 != 0);
        }
        // Every branch exercised: values, clipped sources, points in the plane.
        assert!(
            compared > 39_000 && positive > 10_000 && clipped > 1_000 && in_plane > 1_000,
            "{compared} {positive} {clipped} {in_plane}"
        );
    }

    /// The polynomial angle agrees with `f64::atan2` to a few ulps everywhere in [0, π],
    /// including tiny, near-π/2 and near-π angles and the octant boundaries.
    #[test]
    fn fast_angle_matches_atan2() {
        // Measured ≤ 2 ulps (relative); 4 leaves room for other CPUs' rounding of the divisions.
        const ANGLE_TOL: f64 = 4.0 * f64::EPSILON;
        let mut rng = Pcg32::keyed(11, 3);
        let mut worst: f64 = 0.0;
        let mut check = |y: f64, x: f64| {
            let (a, b) = (angle(y, x), y.atan2(x));
            let err = (a - b).abs() / b.abs().max(1e-300);
            worst = worst.max(err);
            assert!(err <= ANGLE_TOL, "angle({y:e}, {x:e}) = {a:e}, atan2 = {b:e}");
        };
        for _ in 0..200_000 {
            let th = rng.next_f64() * PI;
            let r = 10f64.powf(rng.next_f64() * 40.0 - 20.0);
            check(r * th.sin().abs(), r * th.cos());
        }
        for th in [1e-300, 1e-12, TAN_PI_8.atan(), PI / 4.0, PI / 2.0, 3.0 * PI / 4.0, PI - 1e-9] {
            check(th.sin(), th.cos());
        }
        check(1.0, 0.0);
        check(1.0, -0.0);
        check(1e-30, -1.0);
        assert_eq!(angle(0.0, -1.0), PI);
        assert_eq!(angle(0.0, 1.0), 0.0);
        assert!(worst > 0.0, "the comparison must exercise rounding");
    }

    /// Closed form for a point under a coaxial disk: r²/(r²+h²); a 512-gon inscribed in the disk
    /// differs by O(1/512²) relative.
    #[test]
    fn point_to_many_sided_polygon_matches_disk_closed_form() {
        let (r, h) = (0.7, 1.3);
        let n_sides = 512;
        let verts: Vec<DVec3> = (0..n_sides)
            .rev() // clockwise from above = counter-clockwise seen from below (the front)
            .map(|i| {
                let a = 2.0 * PI * f64::from(i) / f64::from(n_sides);
                DVec3::new(r * a.cos(), r * a.sin(), h)
            })
            .collect();
        // The inscribed polygon lies between the disk of its apothem r·cos(π/n) and the disk of r.
        let t = 2.0 * PI / f64::from(n_sides);
        let f = point_to_polygon(DVec3::ZERO, DVec3::Z, &verts[..]);
        let f_in = r * r * (t / 2.0).cos().powi(2) / (r * r * (t / 2.0).cos().powi(2) + h * h);
        let f_out = r * r / (r * r + h * h);
        assert!(f > f_in - 1e-12 && f < f_out + 1e-12, "{f_in} <= {f} <= {f_out}");
    }

    #[test]
    fn behind_is_zero_and_clipping_halves_a_symmetric_polygon() {
        let sq = [
            DVec3::new(-1.0, -1.0, 1.0),
            DVec3::new(-1.0, 1.0, 1.0),
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(1.0, -1.0, 1.0),
        ];
        assert!(point_to_polygon(DVec3::ZERO, DVec3::Z, &sq) > 0.0);
        assert_eq!(point_to_polygon(DVec3::new(0.0, 0.0, 2.0), -DVec3::Z, &sq), 0.0);
        // Receivers facing +x and −x see mirror-image halves of the square: equal form factors.
        let fx = point_to_polygon(DVec3::ZERO, DVec3::X, &sq);
        let fmx = point_to_polygon(DVec3::ZERO, -DVec3::X, &sq);
        assert!((fx - fmx).abs() < 1e-14 && fx > 0.0);
    }

    #[test]
    fn closed_cube_sums_to_one_from_any_interior_point() {
        // Unit cube with inward-facing faces (CCW seen from inside).
        let c = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        let faces = [
            [c(0., 0., 0.), c(1., 0., 0.), c(1., 1., 0.), c(0., 1., 0.)], // floor z=0, normal +z
            [c(0., 0., 1.), c(0., 1., 1.), c(1., 1., 1.), c(1., 0., 1.)], // ceiling, normal −z
            [c(0., 0., 0.), c(0., 0., 1.), c(1., 0., 1.), c(1., 0., 0.)], // y=0, normal +y
            [c(0., 1., 0.), c(1., 1., 0.), c(1., 1., 1.), c(0., 1., 1.)], // y=1, normal −y
            [c(0., 0., 0.), c(0., 1., 0.), c(0., 1., 1.), c(0., 0., 1.)], // x=0, normal +x
            [c(1., 0., 0.), c(1., 0., 1.), c(1., 1., 1.), c(1., 1., 0.)], // x=1, normal −x
        ];
        for f in &faces {
            let n = crate::math::polygon_normal(f);
            assert!((n.dot(DVec3::splat(0.5) - f[0])) > 0.0, "face must point inward");
        }
        for (p, n) in
            [(c(0.3, 0.6, 0.0), DVec3::Z), (c(0.5, 0.5, 1.0), -DVec3::Z), (c(0.0, 0.2, 0.9), DVec3::X)]
        {
            let s: f64 = faces.iter().map(|f| point_to_polygon(p, n, f)).sum();
            assert!((s - 1.0).abs() < 1e-12, "sum {s}");
        }
        // From a point on an edge of the cube (in the plane of two faces): the in-plane limits
        // still sum to one. (At a corner the limit depends on the direction of approach.)
        for (p, n) in
            [(c(0.0, 0.4, 0.0), DVec3::Z), (c(1.0, 1.0, 0.5), -DVec3::X), (c(0.3, 0.0, 1.0), DVec3::Y)]
        {
            let s: f64 = faces.iter().map(|f| point_to_polygon(p, n, f)).sum();
            assert!((s - 1.0).abs() < 1e-12, "sum {s} at {p}");
        }
    }

    #[test]
    fn disk_is_exact_for_coaxial_disk() {
        let (r, h) = (0.5_f64, 2.0_f64);
        let a = PI * r * r;
        let f = disk(DVec3::ZERO, DVec3::Z, DVec3::new(0.0, 0.0, h), -DVec3::Z, a);
        assert!((f - r * r / (r * r + h * h)).abs() < 1e-15);
    }
}
