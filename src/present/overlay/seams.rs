//! Seams where input patches meet: collinear, overlapping edges of different patches' root
//! elements, found by a sweep over x, and on each the leaf corners of its partner patches, which
//! are inserted into the boundaries of the leaves along it (positions, parameter coordinates and
//! values interpolated along the leaf edge), so both sides rasterise the same edges.

use super::ElementView;
use super::quantize::{ANY_PATCH, Key, Quantizer};
use super::smooth::BoundaryPoint;
use crate::math::DVec3;
use std::collections::HashMap;

/// Where input patches meet: pairs of collinear, overlapping patch edges of different patches,
/// and on each edge the leaf corners of its partner patches (projected onto it).
///
/// ```text
///   patch P (coarse)         ● a corner of a Q leaf on the shared edge, inside a P leaf's edge:
///  ┌────────────────┐        inserted into that P leaf's boundary (and every P corner into
///  ├───●────●───●───┤        Q's), so both sides of the seam rasterise the same edges
///  │ Q │    │   │   │
/// ```
///
/// Patch edges are the edges of the root elements (`parent == None`); without roots in the
/// element list there are no seams.
pub(super) struct Seams {
    edges: Vec<SeamEdge>,
    /// Seam edges of each patch.
    by_patch: HashMap<u32, Vec<usize>>,
    /// Distance (scene units) within which a point is on an edge.
    tol: f64,
}

struct SeamEdge {
    a: DVec3,
    /// Unit direction a → b.
    dir: DVec3,
    len: f64,
    /// Partner patches' leaf corners on this edge: (parameter along `dir`, canonical position),
    /// sorted by parameter.
    points: Vec<(f64, DVec3)>,
}

impl SeamEdge {
    fn new(a: DVec3, b: DVec3) -> Option<SeamEdge> {
        let len = (b - a).length();
        (len > 0.0 && len.is_finite()).then(|| SeamEdge { a, dir: (b - a) / len, len, points: Vec::new() })
    }
    /// Parameter of `p` along the edge if `p` lies on it (within `tol`).
    fn param(&self, p: DVec3, tol: f64) -> Option<f64> {
        let w = p - self.a;
        let t = w.dot(self.dir);
        ((w - t * self.dir).length_squared() <= tol * tol && t >= -tol && t <= self.len + tol).then_some(t)
    }
}

/// Points are on a seam edge when within this fraction of the scene's diagonal of it: input
/// vertices stored as f32 (glTF) agree to ~1e-7 of the scene's size.
pub const SEAM_REL: f64 = 1e-6;

impl Seams {
    pub(super) fn build(
        elements: &[ElementView],
        leaves: &[u32],
        quant: &Quantizer,
        canonical: &crate::math::WordMap<Key, DVec3>,
    ) -> Seams {
        let tol = SEAM_REL * quant.diag;
        let mut edges: Vec<(u32, SeamEdge)> = Vec::new();
        for r in elements.iter().filter(|e| e.parent.is_none()) {
            let v = r.verts();
            for i in 0..v.len() {
                if let Some(edge) = SeamEdge::new(v[i], v[(i + 1) % v.len()]) {
                    edges.push((r.patch, edge));
                }
            }
        }
        // Pairs of collinear, overlapping edges of different patches (sweep over x).
        let lo_x = |e: &SeamEdge| e.a.x.min(e.a.x + e.dir.x * e.len);
        let hi_x = |e: &SeamEdge| e.a.x.max(e.a.x + e.dir.x * e.len);
        let mut order: Vec<usize> = (0..edges.len()).collect();
        order.sort_by(|&i, &j| lo_x(&edges[i].1).total_cmp(&lo_x(&edges[j].1)));
        let mut partners: Vec<Vec<usize>> = vec![Vec::new(); edges.len()];
        for (k, &i) in order.iter().enumerate() {
            let (pi, ei) = &edges[i];
            for &j in &order[k + 1..] {
                let (pj, ej) = &edges[j];
                if lo_x(ej) > hi_x(ei) + tol {
                    break;
                }
                if pi == pj {
                    continue;
                }
                let b = ej.a + ej.dir * ej.len;
                let collinear = |e: &SeamEdge, p: DVec3| {
                    let w = p - e.a;
                    (w - w.dot(e.dir) * e.dir).length_squared() <= tol * tol
                };
                if !(collinear(ei, ej.a) && collinear(ei, b)) {
                    continue;
                }
                let (t0, t1) = (ei.dir.dot(ej.a - ei.a), ei.dir.dot(b - ei.a));
                if t0.max(t1) > tol && t0.min(t1) < ei.len - tol {
                    partners[i].push(j);
                    partners[j].push(i);
                }
            }
        }
        let mut by_patch: HashMap<u32, Vec<usize>> = HashMap::new();
        for (i, (p, _)) in edges.iter().enumerate() {
            if !partners[i].is_empty() {
                by_patch.entry(*p).or_default().push(i);
            }
        }
        if by_patch.is_empty() {
            return Seams { edges: Vec::new(), by_patch, tol };
        }
        // Each seam edge's own leaf corners, then handed to its partners.
        let mut own: Vec<Vec<DVec3>> = vec![Vec::new(); edges.len()];
        for &l in leaves {
            let e = &elements[l as usize];
            let Some(seam) = by_patch.get(&e.patch) else { continue };
            for v in e.verts() {
                for &i in seam {
                    if edges[i].1.param(*v, tol).is_some() {
                        own[i].push(canonical.get(&quant.key(ANY_PATCH, *v)).copied().unwrap_or(*v));
                    }
                }
            }
        }
        for (i, pts) in own.iter().enumerate() {
            for &j in &partners[i] {
                let target = &edges[j].1;
                let mut add: Vec<(f64, DVec3)> =
                    pts.iter().filter_map(|p| target.param(*p, tol).map(|t| (t, *p))).collect();
                edges[j].1.points.append(&mut add);
            }
        }
        for (_, e) in &mut edges {
            e.points.sort_by(|a, b| a.0.total_cmp(&b.0));
            e.points.dedup_by(|a, b| (a.0 - b.0).abs() <= tol);
        }
        Seams { edges: edges.into_iter().map(|(_, e)| e).collect(), by_patch, tol }
    }

    pub(super) fn is_empty(&self) -> bool {
        self.by_patch.is_empty()
    }

    /// Insert the partner corners strictly inside the leaf edge a → b of `patch` into
    /// `out[start..]` (the edge's start point and its own T-vertices, in order; `end` is the next
    /// corner), with parameter coordinates and smooth values interpolated along the edge.
    pub(super) fn insert(
        &self,
        patch: u32,
        a: DVec3,
        b: DVec3,
        out: &mut Vec<BoundaryPoint>,
        start: usize,
        end: BoundaryPoint,
    ) {
        let Some(seam) = self.by_patch.get(&patch) else { return };
        for &i in seam {
            let edge = &self.edges[i];
            let (Some(ta), Some(tb)) = (edge.param(a, self.tol), edge.param(b, self.tol)) else { continue };
            // Strictly inside: more than `tol` from either end. A leaf edge no longer than
            // 2·tol along the seam (a sliver, a collapsed corner) has no inside.
            let (lo, hi) = (ta.min(tb) + self.tol, ta.max(tb) - self.tol);
            if !(lo < hi) {
                continue;
            }
            let first = edge.points.partition_point(|p| p.0 <= lo);
            let last = edge.points.partition_point(|p| p.0 < hi);
            let Some(inside) = edge.points.get(first..last).filter(|s| !s.is_empty()) else { continue };
            // Fraction along a → b of each point already there, and of the new ones.
            let len = (b - a).length();
            let s_of = |p: DVec3| (p - a).dot(b - a) / (len * len);
            let mut own: Vec<(f64, BoundaryPoint)> =
                out[start..].iter().map(|p| (s_of(p.position), *p)).collect();
            own.push((1.0, end));
            let mut merged: Vec<BoundaryPoint> = Vec::with_capacity(own.len() + inside.len());
            let mut k = 0; // own[k] is the next own point at or after the current position
            let points: Box<dyn Iterator<Item = &(f64, DVec3)>> =
                if ta <= tb { Box::new(inside.iter()) } else { Box::new(inside.iter().rev()) };
            for &(_, p) in points {
                let s = s_of(p);
                while k < own.len() && own[k].0 <= s {
                    if k + 1 < own.len() {
                        merged.push(own[k].1);
                    }
                    k += 1;
                }
                // Skip points that coincide with one already there (same canonical position).
                let near = |q: &BoundaryPoint| (q.position - p).length_squared() <= self.tol * self.tol;
                if merged.last().is_some_and(near) || own.get(k).is_some_and(|q| near(&q.1)) {
                    continue;
                }
                let (Some(prev), Some(next)) = (k.checked_sub(1).map(|i| own[i]), own.get(k).copied()) else {
                    continue;
                };
                let f =
                    if next.0 > prev.0 { ((s - prev.0) / (next.0 - prev.0)).clamp(0.0, 1.0) } else { 0.0 };
                let lerp2 = |x: [f64; 2], y: [f64; 2]| [x[0] + f * (y[0] - x[0]), x[1] + f * (y[1] - x[1])];
                merged.push(BoundaryPoint {
                    position: p,
                    uv: lerp2(prev.1.uv, next.1.uv),
                    value: prev.1.value + (next.1.value - prev.1.value) * f,
                });
            }
            while k + 1 < own.len() {
                merged.push(own[k].1);
                k += 1;
            }
            out.truncate(start);
            out.extend(merged);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::present::overlay::VertexField;
    use crate::present::overlay::test_support::{EXACT, quad, right_edge_boundary};

    #[test]
    fn boundary_has_the_corners_of_the_neighbouring_patch() {
        // Patch 0: one 2×2 leaf (its own root). Patch 1 on its right: a root split into four, so
        // its corner (2,1) lies inside patch 0's right edge, and (2,1.5) of a finer leaf too.
        let mut root = quad(1, 0, 2.0, 0.0, 2.0, 0.0);
        root.patch = 1;
        root.leaf = false;
        let mut els = vec![quad(0, 0, 0.0, 0.0, 2.0, 10.0), root];
        for (x, y, s) in [(2.0, 0.0, 1.0), (3.0, 0.0, 1.0), (3.0, 1.0, 1.0), (2.0, 1.0, 0.5), (2.5, 1.0, 0.5)]
        {
            let mut e = quad(els.len() as u32, 1, x, y, s, 4.0);
            e.patch = 1;
            e.parent = Some(1);
            els.push(e);
        }
        for (x, y) in [(2.0, 1.5), (2.5, 1.5)] {
            let mut e = quad(els.len() as u32, 2, x, y, 0.5, 4.0);
            e.patch = 1;
            e.parent = Some(1);
            els.push(e);
        }
        let leaves: Vec<u32> = (0..els.len() as u32).filter(|&i| i != 1).collect();
        let f = VertexField::build(&els, &leaves);
        // Interpolated along the edge: parameters on u = 1, values those of patch 0's own corners
        // (its only leaf: 10 everywhere), not patch 1's.
        let b = right_edge_boundary(&f, &els[0]);
        assert!(b.iter().all(|p| (p.value.r() - 10.0).abs() < EXACT), "{b:?}");
        // Patch 1's leaf at (2,0): its own T-vertex (2.5,1) only (its edge x = 2 from y = 1 to 0
        // holds no corner of patch 0).
        let b2: Vec<[f64; 2]> = f.boundary(&els[2]).iter().map(|p| [p.position.x, p.position.y]).collect();
        assert_eq!(b2, vec![[2.0, 0.0], [3.0, 0.0], [3.0, 1.0], [2.5, 1.0], [2.0, 1.0]]);
        // Without roots there are no seams.
        let no_roots: Vec<ElementView> = els
            .iter()
            .cloned()
            .map(|mut e| {
                e.parent = Some(0);
                e
            })
            .collect();
        assert_eq!(VertexField::build(&no_roots, &leaves).boundary(&no_roots[0]).len(), 4);
    }
}
