//! Form-factor kernels: pure functions of geometry, `f64` inside.
//!
//! The form factor from a receiver i to a source j is the fraction of the power leaving a
//! diffuse i that arrives at j:
//!
//! ```text
//! F_ij = 1/A_i ∫_i ∫_j cosθ_i cosθ_j / (π r²) dA_j dA_i          [Cohen & Wallace 1993, eq. 4.8]
//!      = 1/A_i ∫_i F(x → j) dA_i
//! ```
//!
//! - [`point_to_polygon`]: the inner integral in closed form, Lambert's contour integral
//!   `F(x → j) = 1/(2π) Σ_k β_k n·γ_k`, β_k the angle edge k subtends at x, γ_k the unit normal of
//!   the plane through x and edge k [Cohen & Wallace 1993, eq. 4.17; Baum, Rushmeier, Winget 1989].
//!   Angles by `atan2` (accurate for tiny and near-π angles); the source is first clipped against
//!   the receiver's tangent plane. Exact to rounding. Triangles and quads (every hierarchy
//!   element) take a fixed-size path whose four edge terms are computed side by side in vector
//!   lanes, the same operations in the same order: the same bits, 30–40 % faster.
//! - [`disk`]: the lecture's disk approximation `F ≈ A cosθ cosθ' / (π r² + A)`.
//! - [`polygon_to_polygon`]: the outer integral by globally adaptive cubature of the exact
//!   kernel (Genz–Malik degree-7 rule with a degree-5 error estimate, bisection along the axis
//!   of largest fourth difference [Genz & Malik 1980; Berntsen, Espelid, Genz 1991]). Near a
//!   shared edge or contact the kernel's derivative is log-singular and the embedded estimate
//!   fails (50× optimistic in tests), so regions near the source are estimated against their
//!   two halves instead; the adaptive split concentrates work there. The receiver is first clipped to the half-space in front of the
//!   source (behind it the one-sided kernel is 0), so the kernel never jumps inside the domain
//!   (a wall standing on a floor at an angle would otherwise need millions of evaluations).
//! - [`polygon_to_polygon_fixed`]: cheap fixed n×n Gauss–Legendre rule of the same kernel.
//! - [`polygon_to_polygon_mc`] / [`point_to_polygon_mc`]: Monte Carlo estimates with their
//!   standard error.
//!
//! ## How the receiver is parameterised
//! Every polygon is cut into pieces with a map from the unit square: a quad by its bilinear map,
//! a triangle as a quad collapsed onto its third vertex (the Duffy map, Jacobian ∝ 1 − v),
//! larger convex polygons as a fan of triangles.
//!
//! ```text
//!   v3 ──── v2          v2 (= v3)
//!   │  (u,v) │          │ ╲
//!   v0 ──── v1          v0 ─ v1
//! ```

use crate::math::{DVec3, Pcg32, newell_normal, polygon_area};
use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::f64::consts::PI;
use std::sync::OnceLock;

/// A point closer than this to the source's plane, relative to its largest distance to a source
/// vertex, counts as lying in the plane: the kernel returns its limit from the front side.
/// (Rounding of the vertex coordinates is ~1e-16 relative; the limit differs from the value at
/// this distance by ~1e-11.)
const IN_PLANE_REL: f64 = 1e-11;
/// A source vertex this close to the receiver's tangent plane (relative, as above) counts as on
/// it, so a receiver touching the source plane does not clip vertices away by rounding.
const CLIP_REL: f64 = 1e-12;
/// In the source plane, an edge whose cross product is below this fraction of |a||b| is collinear
/// with the receiver point (angles then come from the in-plane limit, not from `atan2`).
const COLLINEAR_REL: f64 = 1e-12;
/// Hard cap on kernel evaluations of one adaptive integration (about 100 000 regions, 10 MB;
/// the hardest catalog case at 1e-10 needs 130 000 evaluations).
pub const MAX_EVALUATIONS: u64 = 2_000_000;
/// The adaptive quadrature's relative tolerance is at least this many ε × (largest coordinate
/// magnitude / size of the pair): below that, rounding of the input dominates the kernel.
const PRECISION_FLOOR: f64 = 16.0;

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
fn point_to_polygon_unit(p: DVec3, n: DVec3, verts: &[DVec3], src_n: DVec3) -> f64 {
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
/// chains: 30–40 % less time per kernel evaluation). The same bits as `edge_term` (tested).
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

/// One piece of a polygon with its map from the unit square (bilinear; a triangle is a quad
/// collapsed onto its third vertex).
#[derive(Copy, Clone, Debug)]
struct Piece {
    v: [DVec3; 4],
}

impl Piece {
    #[inline]
    fn point(&self, u: f64, v: f64) -> DVec3 {
        let [v0, v1, v2, v3] = self.v;
        let a = v0 + (v1 - v0) * u;
        let b = v3 + (v2 - v3) * u;
        a + (b - a) * v
    }

    /// Area element |∂x/∂u × ∂x/∂v| (signed along the polygon normal, clamped at 0).
    #[inline]
    fn jacobian(&self, u: f64, v: f64, normal: DVec3) -> f64 {
        let [v0, v1, v2, v3] = self.v;
        let xu = (v1 - v0) * (1.0 - v) + (v2 - v3) * v;
        let xv = (v3 - v0) * (1.0 - u) + (v2 - v1) * u;
        normal.dot(xu.cross(xv)).max(0.0)
    }

    /// Physical lengths of the u and v directions (longest of the two opposite edges).
    fn lengths(&self) -> (f64, f64) {
        let [v0, v1, v2, v3] = self.v;
        ((v1 - v0).length().max((v2 - v3).length()), (v3 - v0).length().max((v2 - v1).length()))
    }
}

/// Cut a convex polygon into pieces: a quad stays whole, a triangle is one collapsed quad,
/// anything larger is a fan of triangles from vertex 0.
fn pieces(verts: &[DVec3]) -> Vec<Piece> {
    match verts.len() {
        0..=2 => Vec::new(),
        3 => vec![Piece { v: [verts[0], verts[1], verts[2], verts[2]] }],
        4 => vec![Piece { v: [verts[0], verts[1], verts[2], verts[3]] }],
        k => (1..k - 1).map(|i| Piece { v: [verts[0], verts[i], verts[i + 1], verts[i + 1]] }).collect(),
    }
}

/// The receiver, its unit normal and area, and the source's unit normal, with the receiver
/// clipped to the half-space in front of the source: behind it the one-sided kernel is 0, and
/// the jump along the cut (the foot of a wall standing on a floor, at any angle) would
/// otherwise cost the cubature a staircase of tiny regions. `None` when nothing can be
/// exchanged (degenerate input, facing away, coplanar).
struct Prepared {
    front: Vec<DVec3>,
    normal_from: DVec3,
    normal_to: DVec3,
    area: f64,
    /// Relative accuracy the coordinates allow: rounding of coordinates of magnitude |x| is
    /// ~ε|x|, relative to the pair's size (see [`PRECISION_FLOOR`]).
    precision: f64,
}

/// Two polygons' unit normals, the area of `from` and the pair's size (the largest distance
/// from `from`'s first vertex); `None` when either is degenerate or not finite.
fn pair_frame(from: &[DVec3], to: &[DVec3]) -> Option<(DVec3, DVec3, f64, f64)> {
    if from.len() < 3 || to.len() < 3 || from.iter().chain(to).any(|v| !v.is_finite()) {
        return None;
    }
    let (nf, nt) = (newell_normal(from), newell_normal(to));
    let area = 0.5 * nf.length();
    let (nf, nt) = (nf.normalize_or_zero(), nt.normalize_or_zero());
    if !(area > 0.0 && area.is_finite()) || nf == DVec3::ZERO || nt == DVec3::ZERO {
        return None;
    }
    let scale = from.iter().chain(to).map(|v| (*v - from[0]).length()).fold(0.0, f64::max);
    Some((nf, nt, area, scale))
}

fn prepare(from: &[DVec3], to: &[DVec3]) -> Option<Prepared> {
    let (nf, nt, area, scale) = pair_frame(from, to)?;
    let eps = IN_PLANE_REL * scale;
    // Every vertex of one on or behind the other's plane: nothing is exchanged.
    let behind = |pts: &[DVec3], origin: DVec3, n: DVec3| pts.iter().all(|v| n.dot(*v - origin) <= eps);
    if behind(to, from[0], nf) || behind(from, to[0], nt) {
        return None;
    }
    let mut front = clip_to_front(from, to[0], nt, eps);
    front.dedup();
    if front.len() > 1 && front.first() == front.last() {
        front.pop();
    }
    let extent = from.iter().chain(to).map(|v| v.abs().max_element()).fold(0.0, f64::max);
    let precision = PRECISION_FLOOR * f64::EPSILON * extent / scale;
    (front.len() >= 3 && polygon_area(&front) > 0.0).then_some(Prepared {
        front,
        normal_from: nf,
        normal_to: nt,
        area,
        precision,
    })
}

/// Result of an adaptive integration.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Quadrature {
    /// The estimate of F from→to.
    pub value: f64,
    /// Estimated absolute error of `value` (sum of the regions' Genz–Malik estimates).
    pub error: f64,
    /// Kernel evaluations spent.
    pub evaluations: u64,
    /// False if [`MAX_EVALUATIONS`] ran out before the tolerance was met.
    pub converged: bool,
}

/// One Genz–Malik evaluation of a rectangle [u0,u1]×[v0,v1] of a piece.
#[derive(Copy, Clone, Debug)]
struct Eval {
    u: [f64; 2],
    v: [f64; 2],
    /// Degree-7 value.
    value: f64,
    /// |degree 7 − degree 5|.
    gm_error: f64,
    /// Split along u (else v) when refining.
    split_u: bool,
}

impl Eval {
    fn halves(&self) -> [([f64; 2], [f64; 2]); 2] {
        if self.split_u {
            let m = 0.5 * (self.u[0] + self.u[1]);
            [([self.u[0], m], self.v), ([m, self.u[1]], self.v)]
        } else {
            let m = 0.5 * (self.v[0] + self.v[1]);
            [(self.u, [self.v[0], m]), (self.u, [m, self.v[1]])]
        }
    }
}

/// A region of the adaptive integration: its value and error estimate, and, for a region near
/// the source, the evaluated halves that gave its estimate (they become its children).
#[derive(Copy, Clone, Debug)]
struct Region {
    piece: u32,
    whole: Eval,
    value: f64,
    error: f64,
    halves: Option<[Eval; 2]>,
}

impl PartialEq for Region {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}
impl Eq for Region {}
impl PartialOrd for Region {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Region {
    /// Largest error first; ties broken by position so the order never depends on the heap.
    fn cmp(&self, o: &Self) -> Ordering {
        self.error
            .total_cmp(&o.error)
            .then(o.piece.cmp(&self.piece))
            .then(o.whole.u[0].total_cmp(&self.whole.u[0]))
            .then(o.whole.v[0].total_cmp(&self.whole.v[0]))
    }
}

/// A region whose centre is closer to the source than this many region diameters is "near":
/// the kernel may be singular within reach (shared edge, contact), where the Genz–Malik
/// estimate is unreliable (it under-estimated a shared-edge error 50× in tests), so its error
/// is estimated by comparison with its two evaluated halves instead.
const NEAR_DIAMETERS: f64 = 1.5;

/// Distance from `p` to a convex polygon with unit normal `n`.
fn distance_to_polygon(p: DVec3, verts: &[DVec3], n: DVec3) -> f64 {
    let h = n.dot(p - verts[0]);
    let q = p - n * h;
    let k = verts.len();
    let inside = (0..k).all(|i| (verts[(i + 1) % k] - verts[i]).cross(q - verts[i]).dot(n) >= 0.0);
    if inside {
        return h.abs();
    }
    (0..k)
        .map(|i| {
            let (a, b) = (verts[i], verts[(i + 1) % k]);
            let e = b - a;
            let t = if e.length_squared() > 0.0 {
                ((p - a).dot(e) / e.length_squared()).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (p - (a + e * t)).length()
        })
        .fold(f64::INFINITY, f64::min)
}

// Genz–Malik degree-7 rule on [-1,1]², with its embedded degree-5 rule (n = 2 dimensions).
const GM_L2: f64 = 0.358_568_582_800_318_1; // √(9/70)
const GM_L4: f64 = 0.948_683_298_050_513_8; // √(9/10)
const GM_L5: f64 = 0.688_247_201_611_685_3; // √(9/19)
const GM_W1: f64 = -3816.0 / 19683.0; // (12824 − 9120·2 + 400·4) / 19683
const GM_W2: f64 = 980.0 / 6561.0;
const GM_W3: f64 = 1020.0 / 19683.0; // (1820 − 400·2) / 19683
const GM_W4: f64 = 200.0 / 19683.0;
const GM_W5: f64 = 6859.0 / 19683.0 / 4.0;
const GM_E1: f64 = -971.0 / 729.0; // (729 − 950·2 + 50·4) / 729
const GM_E2: f64 = 245.0 / 486.0;
const GM_E3: f64 = 65.0 / 1458.0; // (265 − 100·2) / 1458
const GM_E4: f64 = 25.0 / 729.0;

/// Apply the Genz–Malik rule to `g` over [u0,u1]×[v0,v1]: (degree-7 value, |deg7 − deg5|,
/// split along u?).
fn genz_malik(g: &mut impl FnMut(f64, f64) -> f64, u: [f64; 2], v: [f64; 2]) -> (f64, f64, bool) {
    let (cu, cv) = (0.5 * (u[0] + u[1]), 0.5 * (v[0] + v[1]));
    let (hu, hv) = (0.5 * (u[1] - u[0]), 0.5 * (v[1] - v[0]));
    let vol = 4.0 * hu * hv;
    let f0 = g(cu, cv);
    let (u2p, u2m) = (g(cu + GM_L2 * hu, cv), g(cu - GM_L2 * hu, cv));
    let (v2p, v2m) = (g(cu, cv + GM_L2 * hv), g(cu, cv - GM_L2 * hv));
    let (u4p, u4m) = (g(cu + GM_L4 * hu, cv), g(cu - GM_L4 * hu, cv));
    let (v4p, v4m) = (g(cu, cv + GM_L4 * hv), g(cu, cv - GM_L4 * hv));
    let mut s4 = 0.0;
    let mut s5 = 0.0;
    for (su, sv) in [(1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)] {
        s4 += g(cu + su * GM_L4 * hu, cv + sv * GM_L4 * hv);
        s5 += g(cu + su * GM_L5 * hu, cv + sv * GM_L5 * hv);
    }
    let s2 = u2p + u2m + v2p + v2m;
    let s3 = u4p + u4m + v4p + v4m;
    let r7 = vol * (GM_W1 * f0 + GM_W2 * s2 + GM_W3 * s3 + GM_W4 * s4 + GM_W5 * s5);
    let r5 = vol * (GM_E1 * f0 + GM_E2 * s2 + GM_E3 * s3 + GM_E4 * s4);
    // Fourth divided differences pick the axis along which the integrand varies most.
    let ratio = (GM_L2 * GM_L2) / (GM_L4 * GM_L4);
    let du = (u2p + u2m - 2.0 * f0 - ratio * (u4p + u4m - 2.0 * f0)).abs();
    let dv = (v2p + v2m - 2.0 * f0 - ratio * (v4p + v4m - 2.0 * f0)).abs();
    let split_u = if (du - dv).abs() <= 1e-6 * du.max(dv) { hu >= hv } else { du > dv };
    (r7, (r7 - r5).abs(), split_u)
}

/// Number of Genz–Malik evaluations per region.
const GM_POINTS: u64 = 17;

/// Globally adaptive integration of `kernel(x) dA` over the polygon `verts` (unit normal
/// `normal`), the kernel's singular set being the polygon `source` (unit normal `source_n`).
/// Stops when the summed error estimate is at most `max(rel_tol·|∫|, abs_tol)`.
///
/// Far from the source a region's error is the Genz–Malik estimate |deg 7 − deg 5|; near it
/// (see [`NEAR_DIAMETERS`]) the region is evaluated again as two halves, its value is their sum
/// and its error the difference with the whole — a conservative estimate (it is the coarser
/// rule's error), and the halves are reused as children when the region is refined.
fn integrate_adaptive(
    verts: &[DVec3],
    normal: DVec3,
    source: &[DVec3],
    source_n: DVec3,
    rel_tol: f64,
    abs_tol: f64,
    kernel: &mut impl FnMut(DVec3) -> f64,
) -> Quadrature {
    let pcs = pieces(verts);
    let evaluations = std::cell::Cell::new(0u64);
    let mut eval = |piece: u32, u: [f64; 2], v: [f64; 2]| {
        let pc = pcs[piece as usize];
        let mut g = |s: f64, t: f64| {
            let j = pc.jacobian(s, t, normal);
            if j > 0.0 { kernel(pc.point(s, t)) * j } else { 0.0 }
        };
        evaluations.set(evaluations.get() + GM_POINTS);
        let (value, gm_error, split_u) = genz_malik(&mut g, u, v);
        Eval { u, v, value, gm_error, split_u }
    };
    let near = |piece: u32, e: &Eval| {
        let pc = &pcs[piece as usize];
        let (c00, c11) = (pc.point(e.u[0], e.v[0]), pc.point(e.u[1], e.v[1]));
        let (c10, c01) = (pc.point(e.u[1], e.v[0]), pc.point(e.u[0], e.v[1]));
        let diameter = (c11 - c00).length().max((c01 - c10).length());
        let centre = pc.point(0.5 * (e.u[0] + e.u[1]), 0.5 * (e.v[0] + e.v[1]));
        distance_to_polygon(centre, source, source_n) < NEAR_DIAMETERS * diameter
    };
    fn finish(
        piece: u32,
        whole: Eval,
        eval: &mut impl FnMut(u32, [f64; 2], [f64; 2]) -> Eval,
        near: &impl Fn(u32, &Eval) -> bool,
    ) -> Region {
        if near(piece, &whole) {
            let [(u1, v1), (u2, v2)] = whole.halves();
            let halves = [eval(piece, u1, v1), eval(piece, u2, v2)];
            let value = halves[0].value + halves[1].value;
            let error = (whole.value - value).abs().max(halves[0].gm_error + halves[1].gm_error);
            Region { piece, whole, value, error, halves: Some(halves) }
        } else {
            Region { piece, whole, value: whole.value, error: whole.gm_error, halves: None }
        }
    }
    let mut heap = BinaryHeap::new();
    // Start from a grid that makes regions roughly square in space (slivers start split).
    for (ip, pc) in pcs.iter().enumerate() {
        let (lu, lv) = pc.lengths();
        let aspect = if lu > 0.0 && lv > 0.0 { lu / lv } else { 1.0 };
        let nu = aspect.round().clamp(1.0, 16.0) as u32;
        let nv = (1.0 / aspect).round().clamp(1.0, 16.0) as u32;
        for i in 0..nu {
            for j in 0..nv {
                let u = [f64::from(i) / f64::from(nu), f64::from(i + 1) / f64::from(nu)];
                let v = [f64::from(j) / f64::from(nv), f64::from(j + 1) / f64::from(nv)];
                let whole = eval(ip as u32, u, v);
                heap.push(finish(ip as u32, whole, &mut eval, &near));
            }
        }
    }
    // Exact sums (the heap's layout follows from the same sequence of operations every time,
    // so the summation order, and the result, are deterministic).
    let totals =
        |heap: &BinaryHeap<Region>| heap.iter().fold((0.0, 0.0), |(s, e), r| (s + r.value, e + r.error));
    let (mut value, mut error) = totals(&heap);
    let mut since_resum = 0u32;
    let converged = loop {
        if error <= (rel_tol * value.abs()).max(abs_tol) {
            // Confirm with exact sums (the running ones drift).
            (value, error) = totals(&heap);
            if error <= (rel_tol * value.abs()).max(abs_tol) {
                break true;
            }
        }
        if evaluations.get() + 6 * GM_POINTS > MAX_EVALUATIONS {
            break false;
        }
        let Some(r) = heap.pop() else { break true };
        let children = match r.halves {
            Some(h) => h,
            None => {
                let [(u1, v1), (u2, v2)] = r.whole.halves();
                [eval(r.piece, u1, v1), eval(r.piece, u2, v2)]
            }
        };
        value -= r.value;
        error -= r.error;
        for c in children {
            let c = finish(r.piece, c, &mut eval, &near);
            value += c.value;
            error += c.error;
            heap.push(c);
        }
        since_resum += 1;
        if since_resum >= 256 {
            (value, error) = totals(&heap);
            since_resum = 0;
        }
    };
    let (value, error) = totals(&heap);
    Quadrature { value, error, evaluations: evaluations.get(), converged }
}

/// Form factor F from→to by adaptive quadrature of the exact point kernel over `from`, with the
/// error estimate and cost. Stops at `max(rel_tol·F, abs_tol)` estimated absolute error.
#[must_use]
pub fn polygon_to_polygon_adaptive(from: &[DVec3], to: &[DVec3], rel_tol: f64, abs_tol: f64) -> Quadrature {
    let Some(p) = prepare(from, to) else {
        return Quadrature { value: 0.0, error: 0.0, evaluations: 0, converged: true };
    };
    // Never ask for more than the coordinates hold: chasing rounding noise would only burn
    // evaluations up to the cap (a 0.01-sized pair at 1e6 from the origin holds ~1e-7).
    let rel_tol = if rel_tol.is_finite() { rel_tol.max(1e-14).max(p.precision) } else { 1e-6 };
    let abs_tol = if abs_tol.is_finite() { abs_tol.max(0.0) } else { 0.0 };
    let (nf, nt) = (p.normal_from, p.normal_to);
    // The integral is F·A: scale the absolute tolerance by the area.
    let q = integrate_adaptive(&p.front, nf, to, nt, rel_tol, abs_tol * p.area, &mut |x| {
        point_to_polygon_unit(x, nf, to, nt)
    });
    Quadrature { value: q.value / p.area, error: q.error / p.area, ..q }
}

/// Form factor F from→to (`from` the receiver i, `to` the source j, both convex, CCW seen from
/// the front) by adaptive quadrature of the exact point kernel over `from`, to an estimated
/// relative error `rel_tol` (area-weighted average of [`point_to_polygon`]).
///
/// Accurate to ~1e-6 and beyond for touching, shared-edge, sliver and near-contact pairs;
/// 0 for pairs that face away. Reciprocity `A_i F_ij = A_j F_ji` holds to the tolerance.
#[must_use]
pub fn polygon_to_polygon(from: &[DVec3], to: &[DVec3], rel_tol: f64) -> f64 {
    polygon_to_polygon_adaptive(from, to, rel_tol, 0.0).value
}

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
/// [`OBLIQUE_LADDER`]).
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

/// An oblique edge pair of [`contour`] on its rung of the ladder: its ∫∫ ln r ds dt by that
/// rule (`value`, the caller multiplies by `cos`) and the estimate of its error (times |cos|).
struct Rung {
    pair: ObliquePair,
    cos: f64,
    rung: usize,
    value: f64,
    error: f64,
}

/// The error of an edge pair's value by rung `k` of the ladder, from its value by rung `k − 1`:
/// twice their difference. The difference bounds the coarser rule's error, and the finer rule's
/// is smaller; the factor 2 guards against two rules that agree by chance, which a single edge
/// pair can, where a sum over all of a polygon's edges on the same rule rarely does. (Measured on
/// splash_room's contour couplings against 96-node rules, `splash2` and `quality`: the n⁻⁸
/// model's |difference| / ((n_k / n_{k−1})⁸ − 1), the estimate while every edge pair climbed
/// together, let 21 of 552 and 44 of 14 690 couplings exceed their tolerance, up to 14 times,
/// once the edge pairs stop on different rungs; the plain difference 1 of each; twice it none.)
fn rung_error(below: f64, value: f64) -> f64 {
    2.0 * (value - below).abs()
}

/// The Gauss–Legendre rules of [`OBLIQUE_LADDER`], computed once.
fn oblique_ladder() -> &'static [Vec<(f64, f64)>] {
    static RULES: OnceLock<Vec<Vec<(f64, f64)>>> = OnceLock::new();
    RULES.get_or_init(|| OBLIQUE_LADDER.iter().map(|&n| gauss_legendre(n)).collect())
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

/// The node counts of the Gauss–Legendre rules [`polygon_to_polygon_contour`] climbs, edge pair
/// by edge pair: a rule gives the value, its difference from the rule below the error estimate.
const OBLIQUE_LADDER: [usize; 7] = [4, 6, 8, 12, 16, 24, 32];

/// [`polygon_to_polygon_contour`] starts each edge pair on the first rule whose n⁻⁸ is below
/// this times the tolerance: on the test's touching pairs the error is ~5 n⁻⁸ of the oblique
/// terms' sum, which is 0.4–12 times the result.
const OBLIQUE_APRIORI: f64 = 0.1;

/// An edge pair at an oblique angle: segments x = a + s·u, s ∈ [0, la] and y = c + t·v,
/// t ∈ [0, lc], u and v unit and not parallel, with the cuts of the outer interval.
///
/// The inner integral is closed: with p = x(s), τ = (p − c)·v and h the distance from p to y's
/// line, ∫₀^lc ln |p − y(t)| dt = G(lc − τ) − G(−τ), G(w) = ½ w ln(w² + h²) − w + h atan(w / h).
/// It is analytic in s except near the points of x closest to y's ends and to y's line, where
/// r can vanish (a shared vertex, a T-junction, lines that cross): the outer interval is cut
/// there and each piece integrated by a Gauss–Legendre rule in u with
/// s = s₀ + (s₁ − s₀)(3u² − 2u³), which grades the nodes towards both ends and turns an s ln s
/// singularity there into u³ ln u, where an n-point rule errs by O(n⁻⁸).
struct ObliquePair {
    a: DVec3,
    u: DVec3,
    c: DVec3,
    v: DVec3,
    lc: f64,
    /// The outer interval's ends and cuts, sorted (unused cuts at 0).
    cuts: [f64; 5],
    /// Pieces shorter than this are skipped.
    tiny: f64,
}

impl ObliquePair {
    fn new(a: DVec3, u: DVec3, la: f64, c: DVec3, v: DVec3, lc: f64) -> ObliquePair {
        // Where x passes closest to y's ends and to y's line.
        let (w0, b) = (a - c, u.dot(v));
        let cross = (b * w0.dot(v) - w0.dot(u)) / u.cross(v).length_squared();
        let mut cuts = [0.0, (c - a).dot(u), (c + v * lc - a).dot(u), cross, la];
        let tiny = 1e-9 * la;
        for x in &mut cuts[1..4] {
            if !(x.is_finite() && *x > tiny && *x < la - tiny) {
                *x = 0.0;
            }
        }
        cuts.sort_unstable_by(f64::total_cmp);
        ObliquePair { a, u, c, v, lc, cuts, tiny }
    }

    /// ∫∫ ln r ds dt over the pair (the caller multiplies by u·v) by the graded `rule`.
    fn integrate(&self, rule: &[(f64, f64)]) -> f64 {
        let g = |w: f64, h: f64, h2: f64| {
            let r2 = w * w + h2;
            let log = if r2 > 0.0 { 0.5 * w * r2.ln() } else { 0.0 };
            let at = if h > 0.0 { h * (w / h).atan() } else { 0.0 };
            log - w + at
        };
        let inner = |s: f64| {
            let d = self.a + self.u * s - self.c;
            // (The distance to the line by the cross product: |d|² − τ² cancels where it is
            // small.)
            let h = d.cross(self.v).length();
            let tau = d.dot(self.v);
            g(self.lc - tau, h, h * h) - g(-tau, h, h * h)
        };
        let mut sum = 0.0;
        for w in self.cuts.windows(2) {
            let (s0, s1) = (w[0], w[1]);
            let len = s1 - s0;
            if !(len > self.tiny) {
                continue;
            }
            for &(t, wt) in rule {
                let s = s0 + len * t * t * (3.0 - 2.0 * t);
                sum += wt * len * 6.0 * t * (1.0 - t) * inner(s);
            }
        }
        sum
    }
}

/// The part of the convex polygon `pts` on or in front of the plane through `origin` with
/// normal `n` (heights within `eps` count as on the plane).
fn clip_to_front(pts: &[DVec3], origin: DVec3, n: DVec3, eps: f64) -> Vec<DVec3> {
    let height = |v: DVec3| {
        let h = n.dot(v - origin);
        if h.abs() <= eps { 0.0 } else { h }
    };
    let mut out = Vec::with_capacity(pts.len() + 1);
    for i in 0..pts.len() {
        let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
        let (ha, hb) = (height(a), height(b));
        if ha >= 0.0 {
            out.push(a);
        }
        if (ha > 0.0 && hb < 0.0) || (ha < 0.0 && hb > 0.0) {
            out.push(a + (b - a) * (ha / (ha - hb)));
        }
    }
    out
}

/// Edges count as perpendicular when the cosine of their angle is within this of 0, and as
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

/// Nodes and weights of the n-point Gauss–Legendre rule on [0, 1] (Newton on Pₙ; n ≥ 1).
#[must_use]
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let n = n.max(1);
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        // Tricomi's initial guess, then Newton.
        let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let kf = k as f64;
                let p2 = ((2.0 * kf - 1.0) * x * p1 - (kf - 1.0) * p0) / kf;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let dx = p1 / dp;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        out.push((0.5 * (1.0 - x), 0.5 * w));
    }
    out.reverse();
    out
}

/// Form factor F from→to with a fixed n×n Gauss–Legendre rule over each piece of `from`
/// (n² kernel evaluations per piece). Cheap and smooth; accurate when the polygons are far
/// apart compared with their size, not near contact (use [`polygon_to_polygon`] there).
#[must_use]
pub fn polygon_to_polygon_fixed(from: &[DVec3], to: &[DVec3], n: usize) -> f64 {
    polygon_to_polygon_rule(from, to, &gauss_legendre(n))
}

/// [`polygon_to_polygon_fixed`] with the rule given (nodes and weights on [0, 1], as
/// [`gauss_legendre`] makes them), for callers that keep the rules instead of computing one
/// per pair.
#[must_use]
pub fn polygon_to_polygon_rule(from: &[DVec3], to: &[DVec3], rule: &[(f64, f64)]) -> f64 {
    let Some(p) = prepare(from, to) else { return 0.0 };
    let mut sum = 0.0;
    for pc in pieces(&p.front) {
        for &(u, wu) in rule {
            for &(v, wv) in rule {
                let j = pc.jacobian(u, v, p.normal_from);
                if j > 0.0 {
                    sum +=
                        wu * wv * j * point_to_polygon_unit(pc.point(u, v), p.normal_from, to, p.normal_to);
                }
            }
        }
    }
    (sum / p.area).clamp(0.0, 1.0)
}

/// Uniformly distributed point on a convex polygon (fan triangles chosen by area, then the
/// square-root map).
fn sample_polygon(verts: &[DVec3], cumulative: &[f64], rng: &mut Pcg32) -> DVec3 {
    let total = *cumulative.last().unwrap_or(&0.0);
    let x = rng.next_f64() * total;
    let t = cumulative.partition_point(|&c| c <= x).min(cumulative.len() - 1);
    let (a, b, c) = (verts[0], verts[t + 1], verts[t + 2]);
    let su = rng.next_f64().sqrt();
    let v = rng.next_f64();
    a * (1.0 - su) + b * (su * (1.0 - v)) + c * (su * v)
}

/// Cumulative areas of the fan triangles of a convex polygon.
fn fan_cumulative(verts: &[DVec3]) -> Vec<f64> {
    let mut acc = 0.0;
    (1..verts.len() - 1)
        .map(|i| {
            acc += polygon_area(&[verts[0], verts[i], verts[i + 1]]);
            acc
        })
        .collect()
}

/// Mean and standard error of a sample sum.
fn mean_and_error(sum: f64, sum_sq: f64, n: u32) -> (f64, f64) {
    let nf = f64::from(n);
    let mean = sum / nf;
    let var = if n > 1 { ((sum_sq - sum * mean) / (nf - 1.0)).max(0.0) } else { f64::INFINITY };
    (mean, (var / nf).sqrt())
}

/// Monte Carlo estimate of F from→to and its standard error: `samples` independent uniform
/// points on `from`, each scored with the exact point kernel to `to`. The score is bounded in
/// [0, 1], so the variance is finite even for touching polygons (unlike the 1/r² area–area
/// estimator). `samples = 0` gives (0, ∞).
#[must_use]
pub fn polygon_to_polygon_mc(from: &[DVec3], to: &[DVec3], samples: u32, seed: u64) -> (f64, f64) {
    if samples == 0 {
        return (0.0, f64::INFINITY);
    }
    let Some(p) = prepare(from, to) else { return (0.0, 0.0) };
    // Sample the front part only; the rest scores 0, which the area ratio accounts for.
    let cumulative = fan_cumulative(&p.front);
    let ratio = cumulative.last().copied().unwrap_or(0.0) / p.area;
    let mut rng = Pcg32::keyed(seed, 0x0f0f_f0f0);
    let (mut s, mut s2) = (0.0, 0.0);
    for _ in 0..samples {
        let x = sample_polygon(&p.front, &cumulative, &mut rng);
        let f = point_to_polygon_unit(x, p.normal_from, to, p.normal_to);
        s += f;
        s2 += f * f;
    }
    let (mean, se) = mean_and_error(s, s2, samples);
    (mean * ratio, se * ratio)
}

/// Monte Carlo estimate of the point-to-polygon form factor and its standard error: `samples`
/// uniform points y on the polygon scored with `A cosθ cosθ' / (π r²)` (cosines clamped at 0,
/// the source one-sided). `samples = 0` gives (0, ∞).
#[must_use]
pub fn point_to_polygon_mc(p: DVec3, n: DVec3, verts: &[DVec3], samples: u32, seed: u64) -> (f64, f64) {
    if samples == 0 || verts.len() < 3 {
        return (0.0, if samples == 0 { f64::INFINITY } else { 0.0 });
    }
    let src = newell_normal(verts);
    let area = 0.5 * src.length();
    let src = src.normalize_or_zero();
    let cumulative = fan_cumulative(verts);
    let mut rng = Pcg32::keyed(seed, 0xf0f0_0f0f);
    let (mut s, mut s2) = (0.0, 0.0);
    for _ in 0..samples {
        let y = sample_polygon(verts, &cumulative, &mut rng);
        let d = y - p;
        let r2 = d.length_squared();
        let f = if r2 > 0.0 {
            let r = r2.sqrt();
            let cr = (n.dot(d) / r).max(0.0);
            let cs = (-src.dot(d) / r).max(0.0);
            area * cr * cs / (PI * r2)
        } else {
            0.0
        };
        if f.is_finite() {
            s += f;
            s2 += f * f;
        }
    }
    mean_and_error(s, s2, samples)
}

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn gauss_legendre_integrates_polynomials_exactly() {
        for n in 1..=12 {
            let rule = gauss_legendre(n);
            assert!((rule.iter().map(|r| r.1).sum::<f64>() - 1.0).abs() < 1e-14);
            for deg in 0..2 * n {
                let s: f64 = rule.iter().map(|(x, w)| w * x.powi(deg as i32)).sum();
                assert!((s - 1.0 / (deg as f64 + 1.0)).abs() < 1e-13, "n={n} deg={deg}: {s}");
            }
        }
    }

    #[test]
    fn genz_malik_is_degree_seven() {
        for (i, j) in [(0, 0), (1, 0), (3, 2), (7, 0), (0, 7), (4, 3), (6, 1)] {
            let mut g = |u: f64, v: f64| u.powi(i) * v.powi(j);
            let (r7, _, _) = genz_malik(&mut g, [0.2, 1.0], [-0.5, 0.3]);
            let exact = (1.0f64.powi(i + 1) - 0.2f64.powi(i + 1)) / f64::from(i + 1)
                * (0.3f64.powi(j + 1) - (-0.5f64).powi(j + 1))
                / f64::from(j + 1);
            assert!((r7 - exact).abs() < 1e-14, "u^{i} v^{j}: {r7} vs {exact}");
        }
    }
}
