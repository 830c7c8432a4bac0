//! The pair of polygons the polygon-to-polygon integrals share: the receiver's parameterisation
//! (pieces mapped from the unit square) and its clip to the half-space in front of the source.
//!
//! Every polygon is cut into pieces with a map from the unit square: a quad by its bilinear map,
//! a triangle as a quad collapsed onto its third vertex (the Duffy map, Jacobian ∝ 1 − v),
//! larger convex polygons as a fan of triangles.
//!
//! ```text
//!   v3 ──── v2          v2 (= v3)
//!   │  (u,v) │          │ ╲
//!   v0 ──── v1          v0 ─ v1
//! ```

use super::IN_PLANE_REL;
use crate::math::{DVec3, newell_normal, polygon_area};

/// The adaptive quadrature's relative tolerance is at least this many ε × (largest coordinate
/// magnitude / size of the pair): below that, rounding of the input dominates the kernel.
const PRECISION_FLOOR: f64 = 16.0;

/// One piece of a polygon with its map from the unit square (bilinear; a triangle is a quad
/// collapsed onto its third vertex).
#[derive(Copy, Clone, Debug)]
pub(super) struct Piece {
    v: [DVec3; 4],
}

impl Piece {
    #[inline]
    pub(super) fn point(&self, u: f64, v: f64) -> DVec3 {
        let [v0, v1, v2, v3] = self.v;
        let a = v0 + (v1 - v0) * u;
        let b = v3 + (v2 - v3) * u;
        a + (b - a) * v
    }

    /// Area element |∂x/∂u × ∂x/∂v| (signed along the polygon normal, clamped at 0).
    #[inline]
    pub(super) fn jacobian(&self, u: f64, v: f64, normal: DVec3) -> f64 {
        let [v0, v1, v2, v3] = self.v;
        let xu = (v1 - v0) * (1.0 - v) + (v2 - v3) * v;
        let xv = (v3 - v0) * (1.0 - u) + (v2 - v1) * u;
        normal.dot(xu.cross(xv)).max(0.0)
    }

    /// Physical lengths of the u and v directions (longest of the two opposite edges).
    pub(super) fn lengths(&self) -> (f64, f64) {
        let [v0, v1, v2, v3] = self.v;
        ((v1 - v0).length().max((v2 - v3).length()), (v3 - v0).length().max((v2 - v1).length()))
    }
}

/// Cut a convex polygon into pieces: a quad stays whole, a triangle is one collapsed quad,
/// anything larger is a fan of triangles from vertex 0.
pub(super) fn pieces(verts: &[DVec3]) -> Vec<Piece> {
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
pub(super) struct Prepared {
    pub(super) front: Vec<DVec3>,
    pub(super) normal_from: DVec3,
    pub(super) normal_to: DVec3,
    pub(super) area: f64,
    /// Relative accuracy the coordinates allow: rounding of coordinates of magnitude |x| is
    /// ~ε|x|, relative to the pair's size (see [`PRECISION_FLOOR`]).
    pub(super) precision: f64,
}

/// Two polygons' unit normals, the area of `from` and the pair's size (the largest distance
/// from `from`'s first vertex); `None` when either is degenerate or not finite.
pub(super) fn pair_frame(from: &[DVec3], to: &[DVec3]) -> Option<(DVec3, DVec3, f64, f64)> {
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

pub(super) fn prepare(from: &[DVec3], to: &[DVec3]) -> Option<Prepared> {
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

/// The part of the convex polygon `pts` on or in front of the plane through `origin` with
/// normal `n` (heights within `eps` count as on the plane).
pub(super) fn clip_to_front(pts: &[DVec3], origin: DVec3, n: DVec3, eps: f64) -> Vec<DVec3> {
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
