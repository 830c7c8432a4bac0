//! Campbell & Fussell's BSP mesh: the receiver split by its critical segments into convex pieces
//! [Campbell & Fussell 1990, "Adaptive mesh generation for global diffuse illumination",
//! SIGGRAPH '90; the lecture's "Campbell et al. BSP mesh"].
//!
//! Each segment, in turn, is filtered down a binary space partition of the receiver: at an inner
//! node it goes to the side(s) of the node's line it lies on (split where it crosses); at a leaf —
//! a convex piece — it splits the piece along its *supporting line*
//!
//! ```text
//! ℓ(x) = n̂·(x − a) = 0,   n̂ = perp(b − a)/|b − a|,   piece → {ℓ ≥ 0} ∩ piece, {ℓ ≤ 0} ∩ piece
//! ```
//!
//! restricted to that piece: a segment cuts only the pieces it passes through, but cuts them
//! from side to side, so every piece stays convex. Pieces are the leaves.
//!
//! ```text
//!   +-----------+        +-----+-----+        +-----+-----+
//!   |     /     |        |    /|     |        |    /|     |
//!   |    /      |   →    |   / |     |   →    |   / +-----+   (a second segment, ending
//!   |           |        |     |     |        |     |     |    inside the right piece,
//!   +-----------+        +-----+-----+        +-----+-----+    splits only that piece)
//! ```
//!
//! The result depends on the segment order (any BSP does); segments are inserted in the sorted
//! order of [`super::ReceiverPlane::prepare`], so it is deterministic.

use super::{ReceiverPlane, Segment2, polygon_area_2d};
use crate::math::DVec3;
use glam::DVec2;

/// A node of the partition: a convex piece, split (inner) or not (leaf).
#[derive(Clone, Debug)]
struct Node {
    piece: Vec<DVec2>,
    /// The splitting line (point, unit normal) and the children (front ℓ ≥ 0, back ℓ ≤ 0).
    split: Option<(DVec2, DVec2, usize, usize)>,
}

/// A receiver's BSP mesh.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BspMesh {
    /// Convex pieces, counter-clockwise seen from the receiver's front, in tree order.
    pub pieces: Vec<Vec<DVec3>>,
    /// Segments inserted (after clipping, snapping and deduplication).
    pub constraints: usize,
}

/// Split a convex polygon by the line through `p` with unit normal `n`: (front, back), either
/// empty when the polygon lies (within `tol`) on one side. Vertices within `tol` of the line go
/// to both sides; consecutive duplicate vertices are dropped.
fn split_polygon(poly: &[DVec2], p: DVec2, n: DVec2, tol: f64) -> (Vec<DVec2>, Vec<DVec2>) {
    let dist: Vec<f64> = poly.iter().map(|q| n.dot(*q - p)).collect();
    if dist.iter().all(|d| *d >= -tol) {
        return (poly.to_vec(), Vec::new());
    }
    if dist.iter().all(|d| *d <= tol) {
        return (Vec::new(), poly.to_vec());
    }
    let (mut front, mut back) = (Vec::new(), Vec::new());
    let m = poly.len();
    for i in 0..m {
        let j = (i + 1) % m;
        let (a, b, da, db) = (poly[i], poly[j], dist[i], dist[j]);
        if da >= -tol {
            front.push(a);
        }
        if da <= tol {
            back.push(a);
        }
        if (da > tol && db < -tol) || (da < -tol && db > tol) {
            let x = a + (b - a) * (da / (da - db));
            front.push(x);
            back.push(x);
        }
    }
    (dedup(front, tol), dedup(back, tol))
}

/// Drop consecutive (cyclically) vertices closer than `tol`.
fn dedup(poly: Vec<DVec2>, tol: f64) -> Vec<DVec2> {
    let mut out: Vec<DVec2> = Vec::with_capacity(poly.len());
    for q in poly {
        if out.last().is_none_or(|l| l.distance(q) > tol) {
            out.push(q);
        }
    }
    while out.len() > 1 && out[0].distance(out[out.len() - 1]) <= tol {
        out.pop();
    }
    out
}

/// The sub-segment of `s` on the side `side` (+1 front, −1 back) of the line, or `None`.
fn clip_to_side(s: Segment2, p: DVec2, n: DVec2, side: f64, tol: f64) -> Option<Segment2> {
    let (da, db) = (side * n.dot(s.a - p), side * n.dot(s.b - p));
    if da <= tol && db <= tol {
        return None;
    }
    if da >= -tol && db >= -tol {
        return Some(s);
    }
    let x = s.a + (s.b - s.a) * (da / (da - db));
    Some(if da > 0.0 { Segment2 { a: s.a, b: x } } else { Segment2 { a: x, b: s.b } })
}

/// Partition a receiver by critical segments (3-D end points on or near its plane; clipped to
/// it here) into convex pieces.
#[must_use]
pub fn partition(plane: &ReceiverPlane, segments: &[[DVec3; 2]]) -> BspMesh {
    let segs = plane.prepare(segments);
    let tol = plane.tolerance;
    let mut nodes = vec![Node { piece: plane.polygon.clone(), split: None }];
    for s in &segs {
        let mut todo = vec![(0usize, *s)];
        while let Some((id, s)) = todo.pop() {
            if s.a.distance(s.b) <= tol {
                continue;
            }
            if let Some((p, n, front, back)) = nodes[id].split {
                // A segment on the node's line splits nothing below it.
                if n.dot(s.a - p).abs() <= tol && n.dot(s.b - p).abs() <= tol {
                    continue;
                }
                if let Some(f) = clip_to_side(s, p, n, 1.0, tol) {
                    todo.push((front, f));
                }
                if let Some(b) = clip_to_side(s, p, n, -1.0, tol) {
                    todo.push((back, b));
                }
                continue;
            }
            let n = (s.b - s.a).perp().normalize_or_zero();
            if n == DVec2::ZERO {
                continue;
            }
            let (f, b) = split_polygon(&nodes[id].piece, s.a, n, tol);
            // A split that would leave a piece thinner than the tolerance is not made.
            let thin = |q: &[DVec2]| q.len() < 3 || polygon_area_2d(q) <= tol * diameter(q);
            if thin(&f) || thin(&b) {
                continue;
            }
            let (fi, bi) = (nodes.len(), nodes.len() + 1);
            nodes.push(Node { piece: f, split: None });
            nodes.push(Node { piece: b, split: None });
            nodes[id].split = Some((s.a, n, fi, bi));
        }
    }
    let pieces = nodes
        .iter()
        .filter(|n| n.split.is_none())
        .map(|n| n.piece.iter().map(|p| plane.to_3d(*p)).collect())
        .collect();
    BspMesh { pieces, constraints: segs.len() }
}

/// Largest distance between two vertices.
fn diameter(q: &[DVec2]) -> f64 {
    q.iter().flat_map(|a| q.iter().map(move |b| a.distance(*b))).fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::polygon_area;

    #[test]
    fn a_cross_makes_four_pieces_and_a_short_segment_splits_one() {
        let v = |x, z| DVec3::new(x, 0.0, z);
        let plane = ReceiverPlane::new(&[v(0.0, 0.0), v(0.0, 1.0), v(1.0, 1.0), v(1.0, 0.0)], 1e-9).unwrap();
        let cross = [[v(0.5, -1.0), v(0.5, 2.0)], [v(-1.0, 0.5), v(2.0, 0.5)]];
        let m = partition(&plane, &cross);
        assert_eq!(m.pieces.len(), 4);
        let area: f64 = m.pieces.iter().map(|p| polygon_area(p)).sum();
        assert!((area - 1.0).abs() < 1e-12);
        // A segment inside one quadrant only: splits that quadrant, not the others.
        let mut more = cross.to_vec();
        more.push([v(0.7, 0.7), v(0.8, 0.8)]);
        assert_eq!(partition(&plane, &more).pieces.len(), 5);
        // Degenerate input: nothing, and no panic.
        assert_eq!(partition(&plane, &[[v(0.3, 0.3), v(0.3, 0.3)]]).pieces.len(), 1);
    }
}
