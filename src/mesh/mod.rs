//! Meshing given shadows: discontinuity meshes of the receivers [Heckbert 1992; Lischinski,
//! Tampieri & Greenberg 1992; Campbell & Fussell 1990].
//!
//! Radiosity on a receiver lit by a polygonal emitter past polygonal occluders,
//!
//! ```text
//! B(x) = E(x) + ρ(x) ∫_emitter  B_e cosθ cosθ' / (π r²) · V(x, y) dA_y
//! ```
//!
//! is smooth except on *critical curves* where the visible part of the emitter changes
//! topology. A mesh whose element edges follow those curves represents the shadow with no
//! staircase (the lecture's "meshing given shadows": artifacts A, D and E). This module finds the
//! curves (straight segments on the receiver plane) and builds two meshes from them.
//!
//! ## Parts (the algorithm's own vocabulary)
//! - [`discontinuity`]: the critical segments on a receiver — D0 where surfaces touch, D1/D2 from
//!   the EV and VE wedges of an emitter and its occluders [Lischinski et al. 1992; Heckbert 1992].
//! - [`cdt`]: Heckbert's constrained Delaunay mesh — the receiver boundary and the critical
//!   segments as constraints, Delaunay refinement (minimum angle, maximum area), via `spade`.
//! - [`bsp`]: Campbell & Fussell's BSP mesh — the receiver split recursively by the critical
//!   segments' supporting lines into convex pieces.
//! - [`grade`]: a discontinuity mesh graded to a budget — pieces split where the direct light
//!   varies (the penumbrae) and by area elsewhere, every patch included.
//! - [`remesh`]: a whole scene remeshed: every receiver with critical segments replaced by its
//!   mesh's pieces, each keeping the patch's material, so any solver runs on it (p = 0).
//!
//! This file holds what all of them share: a receiver polygon in its own 2-D frame
//! ([`ReceiverPlane`]) and the clipping of segments against it.
//!
//! ## Tolerance
//! One length per receiver, `snap × diameter` ([`ReceiverPlane::tolerance`]): segment end points
//! that close to the boundary are moved onto it, segments shorter than it and segments along the
//! boundary (closer than it to one edge line at both ends) are dropped, end points closer than
//! it are merged. Everything else is exact up to rounding; `spade` uses exact predicates.

pub mod bsp;
pub mod cdt;
pub mod discontinuity;
pub mod grade;
pub mod remesh;

use crate::math::{DVec3, orthonormal_basis, polygon_area, polygon_normal};
use glam::DVec2;

/// Default snapping length, relative to the receiver's diameter.
pub const DEFAULT_SNAP: f64 = 1e-7;

/// Errors of the meshers. Input never panics: degenerate receivers and segments are reported
/// or skipped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    #[error("receiver polygon is degenerate: {cause}")]
    DegenerateReceiver { cause: String },
    #[error("constrained Delaunay triangulation failed: {cause}")]
    Triangulation { cause: String },
    #[error(
        "the discontinuity mesh has {count} patches, more than the cap of {cap} (the solvers need O(n²) memory): raise the cap or mesh fewer receivers"
    )]
    TooManyPatches { count: usize, cap: usize },
    #[error("invalid parameter: {0}")]
    Parameter(String),
}

/// A planar convex receiver polygon in an orthonormal frame of its plane:
/// `x = origin + s·u + t·v`, `u × v = normal`, so the 2-D polygon is counter-clockwise.
#[derive(Clone, Debug)]
pub struct ReceiverPlane {
    pub origin: DVec3,
    pub u: DVec3,
    pub v: DVec3,
    pub normal: DVec3,
    /// The polygon in (s, t), counter-clockwise.
    pub polygon: Vec<DVec2>,
    /// Unit inward normals of the 2-D edges (edge k runs from vertex k to k + 1).
    inward: Vec<DVec2>,
    /// Absolute snapping length (see the module docs).
    pub tolerance: f64,
}

/// A 2-D segment on a receiver, after clipping and snapping.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Segment2 {
    pub a: DVec2,
    pub b: DVec2,
}

impl ReceiverPlane {
    /// The frame of a convex polygon (3 or more vertices, any planar convex polygon), with
    /// `snap` the snapping length relative to its diameter.
    pub fn new(vertices: &[DVec3], snap: f64) -> Result<ReceiverPlane, MeshError> {
        let degenerate = |cause: &str| MeshError::DegenerateReceiver { cause: cause.into() };
        if vertices.len() < 3 {
            return Err(degenerate("fewer than 3 vertices"));
        }
        if vertices.iter().any(|p| !p.is_finite()) {
            return Err(degenerate("non-finite vertex"));
        }
        if !(snap.is_finite() && snap >= 0.0) {
            return Err(MeshError::Parameter(format!("snap must be finite and ≥ 0 (got {snap})")));
        }
        let normal = polygon_normal(vertices);
        let area = polygon_area(vertices);
        let diameter =
            vertices.iter().flat_map(|a| vertices.iter().map(move |b| a.distance(*b))).fold(0.0, f64::max);
        if normal == DVec3::ZERO || !(area > 1e-24 * diameter * diameter) {
            return Err(degenerate("zero area"));
        }
        let (mut u, mut v) = orthonormal_basis(normal);
        if u.cross(v).dot(normal) < 0.0 {
            std::mem::swap(&mut u, &mut v);
        }
        let origin = vertices[0];
        let polygon: Vec<DVec2> =
            vertices.iter().map(|p| DVec2::new((*p - origin).dot(u), (*p - origin).dot(v))).collect();
        let n = polygon.len();
        let inward = (0..n)
            .map(|k| {
                let e = polygon[(k + 1) % n] - polygon[k];
                e.perp().normalize_or_zero()
            })
            .collect();
        Ok(ReceiverPlane { origin, u, v, normal, polygon, inward, tolerance: snap * diameter })
    }

    /// Plane coordinates of a point (its projection onto the plane).
    #[must_use]
    pub fn to_2d(&self, p: DVec3) -> DVec2 {
        DVec2::new((p - self.origin).dot(self.u), (p - self.origin).dot(self.v))
    }

    /// The 3-D point of plane coordinates `p`.
    #[must_use]
    pub fn to_3d(&self, p: DVec2) -> DVec3 {
        self.origin + p.x * self.u + p.y * self.v
    }

    /// Area of the 2-D polygon.
    #[must_use]
    pub fn area(&self) -> f64 {
        polygon_area_2d(&self.polygon)
    }

    /// Signed distance of `p` from edge `k`'s line, positive inside.
    #[must_use]
    pub fn edge_distance(&self, k: usize, p: DVec2) -> f64 {
        self.inward[k].dot(p - self.polygon[k])
    }

    /// True if `p` is inside the polygon or within the tolerance of it.
    #[must_use]
    pub fn contains(&self, p: DVec2) -> bool {
        (0..self.polygon.len()).all(|k| self.edge_distance(k, p) >= -self.tolerance)
    }

    /// Clip a 2-D segment to the polygon (Cyrus–Beck), snap its end points onto edges within the
    /// tolerance, and drop it when it is shorter than the tolerance, runs along the boundary, or
    /// misses the polygon.
    #[must_use]
    pub fn clip(&self, a: DVec2, b: DVec2) -> Option<Segment2> {
        if !(a.is_finite() && b.is_finite()) {
            return None;
        }
        let d = b - a;
        let constraints = (0..self.polygon.len()).map(|k| (self.edge_distance(k, a), self.inward[k].dot(d)));
        let (s0, s1) = clip_interval(0.0, 1.0, constraints)?;
        let (a, b) = (self.snap(a + s0 * d), self.snap(a + s1 * d));
        if a.distance(b) <= self.tolerance {
            return None;
        }
        // Along the boundary: both ends on the same edge line.
        let on_boundary = (0..self.polygon.len()).any(|k| {
            self.edge_distance(k, a).abs() <= self.tolerance
                && self.edge_distance(k, b).abs() <= self.tolerance
        });
        (!on_boundary).then_some(Segment2 { a, b })
    }

    /// Move a point within the tolerance of an edge line onto it (onto the vertex near a corner).
    fn snap(&self, p: DVec2) -> DVec2 {
        let n = self.polygon.len();
        if let Some(vertex) = self.polygon.iter().find(|q| p.distance(**q) <= self.tolerance) {
            return *vertex;
        }
        for k in 0..n {
            let dist = self.edge_distance(k, p);
            if dist.abs() <= self.tolerance {
                return p - dist * self.inward[k];
            }
        }
        p
    }

    /// Project, clip and snap 3-D segments; drop the tiny and boundary ones and duplicates (end
    /// points within the tolerance, either direction). Sorted, so the output is deterministic
    /// whatever the input order.
    #[must_use]
    pub fn prepare(&self, segments: &[[DVec3; 2]]) -> Vec<Segment2> {
        let mut out: Vec<Segment2> = segments
            .iter()
            .filter_map(|[a, b]| self.clip(self.to_2d(*a), self.to_2d(*b)))
            .map(|s| if lex_less(s.b, s.a) { Segment2 { a: s.b, b: s.a } } else { s })
            .collect();
        out.sort_by(|x, y| {
            [x.a.x, x.a.y, x.b.x, x.b.y]
                .iter()
                .zip([y.a.x, y.a.y, y.b.x, y.b.y].iter())
                .map(|(p, q)| p.total_cmp(q))
                .find(|o| o.is_ne())
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        let tol = self.tolerance;
        let mut kept: Vec<Segment2> = Vec::with_capacity(out.len());
        for s in out {
            let duplicate = kept
                .iter()
                .rev()
                .take_while(|k| s.a.x - k.a.x <= tol)
                .any(|k| k.a.distance(s.a) <= tol && k.b.distance(s.b) <= tol);
            if !duplicate {
                kept.push(s);
            }
        }
        kept
    }
}

/// Lexicographic (x, then y) order of 2-D points.
fn lex_less(p: DVec2, q: DVec2) -> bool {
    p.x < q.x || (p.x == q.x && p.y < q.y)
}

/// Area of a counter-clockwise 2-D polygon (shoelace; negative if clockwise).
#[must_use]
pub fn polygon_area_2d(poly: &[DVec2]) -> f64 {
    let n = poly.len();
    if n < 3 {
        return 0.0;
    }
    let o = poly[0];
    (1..n - 1).map(|i| (poly[i] - o).perp_dot(poly[i + 1] - o)).sum::<f64>() * 0.5
}

/// The sub-interval of `[lo, hi]` where every affine constraint `c0 + c1·s ≥ 0` holds, or `None`
/// if it is empty. A constraint with `c1 = 0` keeps everything or nothing; NaN rejects.
#[must_use]
pub fn clip_interval(
    lo: f64,
    hi: f64,
    constraints: impl IntoIterator<Item = (f64, f64)>,
) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (lo, hi);
    for (c0, c1) in constraints {
        if !(c0.is_finite() && c1.is_finite()) {
            return None;
        }
        if c1 == 0.0 {
            if c0 < 0.0 {
                return None;
            }
        } else if c1 > 0.0 {
            lo = lo.max(-c0 / c1);
        } else {
            hi = hi.min(-c0 / c1);
        }
        if !(lo <= hi) {
            return None;
        }
    }
    Some((lo, hi))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> ReceiverPlane {
        let v = |x, z| DVec3::new(x, 0.0, z);
        ReceiverPlane::new(&[v(0.0, 0.0), v(0.0, 1.0), v(1.0, 1.0), v(1.0, 0.0)], 1e-9).unwrap()
    }

    #[test]
    fn frame_is_counter_clockwise_and_round_trips() {
        let r = square();
        assert!((r.area() - 1.0).abs() < 1e-12, "area {}", r.area());
        let p = DVec3::new(0.3, 0.0, 0.7);
        assert!(r.to_3d(r.to_2d(p)).distance(p) < 1e-12);
        assert!(r.normal.dot(DVec3::Y) > 0.99);
    }

    #[test]
    fn clip_snaps_and_drops_boundary_and_tiny_segments() {
        let r = square();
        let c = |p: DVec3| r.to_2d(p);
        // Through the middle, past both sides: clipped to the square.
        let s = r.clip(c(DVec3::new(-1.0, 0.0, 0.5)), c(DVec3::new(2.0, 0.0, 0.5))).unwrap();
        assert!((s.a.distance(s.b) - 1.0).abs() < 1e-9);
        // Along an edge: dropped. Outside: dropped. Shorter than the tolerance: dropped.
        assert!(r.clip(c(DVec3::new(0.0, 0.0, 0.2)), c(DVec3::new(0.0, 0.0, 0.8))).is_none());
        assert!(r.clip(c(DVec3::new(2.0, 0.0, 0.2)), c(DVec3::new(3.0, 0.0, 0.8))).is_none());
        assert!(r.clip(c(DVec3::new(0.5, 0.0, 0.5)), c(DVec3::new(0.5, 0.0, 0.5 + 1e-12))).is_none());
        // NaN: dropped, no panic.
        assert!(r.clip(DVec2::NAN, DVec2::ZERO).is_none());
    }

    #[test]
    fn degenerate_receivers_are_errors() {
        let v = |x| DVec3::new(x, 0.0, 0.0);
        assert!(ReceiverPlane::new(&[v(0.0), v(1.0), v(2.0)], 1e-9).is_err());
        assert!(ReceiverPlane::new(&[v(0.0), v(1.0)], 1e-9).is_err());
    }
}
