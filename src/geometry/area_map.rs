//! The area-uniform map from the unit square onto a triangle or convex quad: stratified samples
//! on (u, v) stay stratified on the polygon. The reference samples elements and emitters with it,
//! the lit fraction places its emitter grid with it, the metrics evaluate solutions at its points.

use crate::math::{DVec3, polygon_area};

/// Map (u, v) ∈ [0,1)² to a point of a triangle, uniform in area (the square-root map,
/// [Shirley & Chiu 1997; pbrt-v4 §A.5.5]).
fn triangle_point(a: DVec3, b: DVec3, c: DVec3, u: f64, v: f64) -> DVec3 {
    let su = u.sqrt();
    a * (1.0 - su) + b * (su * (1.0 - v)) + c * (su * v)
}

/// An area-uniform map from the unit square onto a triangle or convex quad: a quad is cut along
/// its 0–2 diagonal, and u picks the half in proportion to its area (so strata stay strata).
#[derive(Clone, Copy, Debug)]
pub struct AreaMap {
    v: [DVec3; 4],
    quad: bool,
    /// Fraction of the area in triangle (0, 1, 2).
    split: f64,
}

impl AreaMap {
    /// The map onto `verts` (3 or 4 vertices, convex).
    #[must_use]
    pub fn new(verts: &[DVec3]) -> Self {
        let mut v = [verts[0]; 4];
        v[..verts.len()].copy_from_slice(verts);
        if verts.len() == 4 {
            let a1 = polygon_area(&verts[..3]);
            let a2 = polygon_area(&[verts[0], verts[2], verts[3]]);
            let total = a1 + a2;
            let split = if total > 0.0 { a1 / total } else { 0.5 };
            AreaMap { v, quad: true, split }
        } else {
            AreaMap { v, quad: false, split: 1.0 }
        }
    }
    /// The point at (u, v) ∈ [0,1)².
    #[must_use]
    pub fn point(&self, u: f64, v: f64) -> DVec3 {
        let w = &self.v;
        if !self.quad || u < self.split {
            let uu = if self.quad { u / self.split } else { u };
            triangle_point(w[0], w[1], w[2], uu.min(1.0), v)
        } else {
            let uu = (u - self.split) / (1.0 - self.split);
            triangle_point(w[0], w[2], w[3], uu.min(1.0), v)
        }
    }
}

/// A point of a triangle or convex quad from (u, v) ∈ [0,1)², uniform in area (the map the
/// reference samples elements with, the penumbra's emitter grid and the metrics' points).
#[must_use]
pub fn area_point(verts: &[DVec3], u: f64, v: f64) -> DVec3 {
    AreaMap::new(verts).point(u, v)
}
