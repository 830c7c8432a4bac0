//! Exact single-bounce radiosity: a ruler with no reference noise.
//!
//! A *single-bounce scene* has one emitter (E > 0, ρ = 0), one receiver (ρ > 0, E = 0) and any
//! number of black occluders (ρ = 0, E = 0). Light leaves the emitter, reaches the receiver
//! directly or not at all, and nothing reflects it again, so every solver's exact answer is
//!
//! ```text
//! B(x) = ρ E · F(x → visible part of the emitter)         on the receiver
//! B    = E                                                 on the emitter
//! B    = 0                                                 on an occluder
//! ```
//!
//! with F the point-to-polygon form factor, in closed form by Lambert's contour integral
//! [`crate::geometry::form_factor::point_to_polygon_oriented`] (Cohen & Wallace 1993, eq. 4.17; tested
//! against the catalog). What is left is the visible part, which this module builds exactly.
//!
//! ## How it works
//! An occluder O hides the emitter points y whose segment x→y crosses O. Let h(p) be the height
//! of p above the emitter's plane (h(x) > 0, or x sees nothing). Only the part O⁺ of O with
//! h ≥ 0 can lie between x and the plane, so O is first clipped to h ≥ 0. The hidden set is then
//! the emitter cut by the cone from x through O⁺ — the half-spaces bounded by the planes through
//! x and each edge of O⁺ (Sutherland–Hodgman clipping of a convex polygon, one plane at a time
//! [Sutherland & Hodgman 1974]):
//!
//! ```text
//!            x                    the cone from x through O⁺ meets the emitter's plane in the
//!           /|\                   central projection of O⁺; a point o of O⁺ reaches the plane at
//!          / | \                  y = x + s (o − x), s = h(x) / (h(x) − h(o)) ≥ 1: o lies between
//!     ════O⁺═══════               x and y, so y is hidden. Directions through points with
//!        /   |   \                h(o) ≥ h(x) never reach the plane, so the cone needs no clip
//!   ────[=== E ===]────           on that side.
//! ```
//!
//! Several occluders: the hidden set is the union of the convex pieces H_k = E ∩ cone_k, and
//! its form factor follows by inclusion–exclusion,
//! `F(∪H_k) = Σ F(H_k) − Σ F(H_i ∩ H_j) + …`, each intersection again one convex clip; empty
//! intersections prune their supersets, so the cost follows the overlap of the shadows, not 2^k.
//! `F(visible) = F(E) − F(∪H_k)`: exact up to rounding (the kernel clips every piece to x's
//! tangent plane, so pieces behind x add nothing, consistently).
//!
//! **Element averages** ([`SingleBounce::element_average`]): F(x) is continuous but only C¹
//! across the penumbra's boundaries (where an occluder edge's projection crosses an emitter
//! vertex), so the average over a convex element is integrated by globally adaptive cubature:
//! the element is mapped from the unit square (a quad by its bilinear map, a triangle by the
//! Duffy map, larger convex polygons as a fan of triangles); every region is evaluated with a
//! 5×5 Gauss–Legendre rule and again as its four quarters, its value is the quarters' sum and
//! its error estimate the difference to the whole (the error of the coarser value, so
//! conservative where the rule converges); the region of largest estimate is split until the
//! summed estimate is below the tolerance asked. Tests check the result against the catalog
//! (parallel unit squares, F = 0.199825) to better than 1e-9 and, in penumbrae, against a
//! 4× tighter tolerance.

use crate::geometry::form_factor::point_to_polygon_oriented;
use crate::geometry::form_factor::region::{Region, totals};
use crate::math::{DVec3, Rgb, newell_normal, polygon_area};
use crate::scene::Scene;
use std::collections::BinaryHeap;

/// A vertex within this distance of a clipping plane, relative to the clipped polygon's size,
/// counts as on it (kept, no intersection computed): rounding of the plane through x is ~1e-16
/// relative, and the form factor of a sliver this thin is ~1e-12 of the whole.
const CLIP_REL: f64 = 1e-12;
/// An occluder whose plane passes this close to x (relative to its size) is seen edge-on and
/// hides a set of zero area: it is skipped.
const EDGE_ON_REL: f64 = 1e-12;
/// Cap on kernel-evaluation points of one element average (each costs one visible form factor).
pub const MAX_POINTS: u64 = 4_000_000;
/// Gauss–Legendre points per direction of the element-average rule.
const GL_ORDER: usize = 5;

/// Why a scene is not a single-bounce scene.
#[derive(Debug, thiserror::Error)]
pub enum ExactError {
    #[error("not a single-bounce scene: {0}")]
    NotSingleBounce(String),
}

/// A single-bounce scene, ready to evaluate: which patch is which, and their geometry.
#[derive(Clone, Debug)]
pub struct SingleBounce {
    /// Index of the emitting patch.
    pub emitter: usize,
    /// Index of the reflecting patch.
    pub receiver: usize,
    /// Indices of the black patches.
    pub occluders: Vec<usize>,
    emitter_vertices: Vec<DVec3>,
    emitter_normal: DVec3,
    receiver_normal: DVec3,
    /// ρ_receiver · E_emitter, per channel.
    scale: Rgb,
    emission: Rgb,
    occluder_vertices: Vec<Vec<DVec3>>,
}

/// An element average and what it cost.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct ElementAverage {
    /// Average of ρE·F over the element (the exact element value of a constant-element solver).
    pub radiosity: Rgb,
    /// Average of the visible form factor over the element.
    pub form_factor: f64,
    /// Estimated absolute error of `form_factor` (conservative; see the module docs).
    pub error: f64,
    /// Points at which the visible form factor was evaluated.
    pub points: u64,
    /// False if [`MAX_POINTS`] ran out before the tolerance was met.
    pub converged: bool,
}

impl SingleBounce {
    /// Recognise a single-bounce scene: exactly one patch with E > 0 (its ρ must be 0), exactly
    /// one with ρ > 0 (its E must be 0), every other patch black.
    pub fn new(scene: &Scene) -> Result<SingleBounce, ExactError> {
        let bad = |why: String| Err(ExactError::NotSingleBounce(format!("{}: {why}", scene.source)));
        let emitters: Vec<usize> =
            (0..scene.patches.len()).filter(|&i| scene.patches[i].emission.max_channel() > 0.0).collect();
        let reflectors: Vec<usize> =
            (0..scene.patches.len()).filter(|&i| scene.patches[i].reflectance.max_channel() > 0.0).collect();
        let (&[emitter], &[receiver]) = (emitters.as_slice(), reflectors.as_slice()) else {
            return bad(format!(
                "{} emitting and {} reflecting patches (one of each expected)",
                emitters.len(),
                reflectors.len()
            ));
        };
        if emitter == receiver {
            return bad(format!("patch {emitter} both emits and reflects"));
        }
        let (e, r) = (&scene.patches[emitter], &scene.patches[receiver]);
        let occluders: Vec<usize> =
            (0..scene.patches.len()).filter(|&i| i != emitter && i != receiver).collect();
        Ok(SingleBounce {
            emitter,
            receiver,
            occluder_vertices: occluders.iter().map(|&i| scene.patches[i].vertices.clone()).collect(),
            occluders,
            emitter_vertices: e.vertices.clone(),
            emitter_normal: e.normal,
            receiver_normal: r.normal,
            scale: r.reflectance.mul_rgb(e.emission),
            emission: e.emission,
        })
    }

    /// The form factor from the receiver's point `x` (normal: the receiver's) to the part of the
    /// emitter that `x` sees.
    #[must_use]
    pub fn visible_form_factor(&self, x: DVec3) -> f64 {
        let (n, en) = (self.receiver_normal, self.emitter_normal);
        let total = point_to_polygon_oriented(x, n, &self.emitter_vertices, en);
        if total <= 0.0 {
            return 0.0;
        }
        let cones: Vec<Vec<Plane>> = self.occluder_vertices.iter().filter_map(|o| self.cone(x, o)).collect();
        let hidden = union_form_factor(&self.emitter_vertices, &cones, &|poly: &[DVec3]| {
            point_to_polygon_oriented(x, n, poly, en)
        });
        (total - hidden).clamp(0.0, total)
    }

    /// The exact radiosity at the receiver's point `x`: ρ E F(x → visible emitter).
    #[must_use]
    pub fn radiosity_at(&self, x: DVec3) -> Rgb {
        self.scale * self.visible_form_factor(x)
    }

    /// The exact radiosity at a point `x` of any patch of the scene: E on the emitter, 0 on an
    /// occluder, [`SingleBounce::radiosity_at`] on the receiver.
    #[must_use]
    pub fn patch_radiosity_at(&self, patch: usize, x: DVec3) -> Rgb {
        if patch == self.receiver {
            self.radiosity_at(x)
        } else if patch == self.emitter {
            self.emission
        } else {
            Rgb::ZERO
        }
    }

    /// The pieces of the emitter that `x` does not see, one convex polygon per occluder (before
    /// inclusion–exclusion: they may overlap). For drawing and for tests.
    #[must_use]
    pub fn hidden_pieces(&self, x: DVec3) -> Vec<Vec<DVec3>> {
        self.occluder_vertices
            .iter()
            .filter_map(|o| self.cone(x, o))
            .map(|c| clip_all(&self.emitter_vertices, &c))
            .filter(|p| p.len() >= 3)
            .collect()
    }

    /// The cone from `x` through the part of occluder `o` in front of the emitter's plane, as
    /// inward half-spaces; `None` if that part is empty, seen edge-on, or `x` is behind the
    /// emitter's plane.
    fn cone(&self, x: DVec3, o: &[DVec3]) -> Option<Vec<Plane>> {
        let en = self.emitter_normal;
        let e0 = self.emitter_vertices[0];
        if en.dot(x - e0) <= 0.0 {
            return None;
        }
        let front = clip(o, &Plane { point: e0, normal: en });
        if front.len() < 3 {
            return None;
        }
        let size = front.iter().map(|p| p.distance(front[0])).fold(0.0, f64::max);
        let on = newell_normal(&front).normalize_or_zero();
        if on == DVec3::ZERO || on.dot(x - front[0]).abs() <= EDGE_ON_REL * size.max((x - front[0]).length())
        {
            return None;
        }
        let centre = front.iter().copied().sum::<DVec3>() / front.len() as f64;
        let k = front.len();
        let planes: Vec<Plane> = (0..k)
            .filter_map(|i| {
                let m = (front[i] - x).cross(front[(i + 1) % k] - x).normalize_or_zero();
                if m == DVec3::ZERO {
                    return None;
                }
                let m = if m.dot(centre - x) < 0.0 { -m } else { m };
                Some(Plane { point: x, normal: m })
            })
            .collect();
        Some(planes)
    }

    /// The exact average over a convex element of the receiver (3 or more vertices, in the
    /// receiver's plane), to an estimated absolute error `abs_tol` in the form factor.
    #[must_use]
    pub fn element_average(&self, verts: &[DVec3], abs_tol: f64) -> ElementAverage {
        let q = integrate(verts, abs_tol, &|x| self.visible_form_factor(x));
        ElementAverage {
            radiosity: self.scale * q.value,
            form_factor: q.value,
            error: q.error,
            points: q.points,
            converged: q.converged,
        }
    }
}

/// A half-space {p : normal·(p − point) ≥ 0}.
#[derive(Copy, Clone, Debug)]
struct Plane {
    point: DVec3,
    normal: DVec3,
}

/// Sutherland–Hodgman: the part of the convex polygon `poly` inside the half-space.
fn clip(poly: &[DVec3], plane: &Plane) -> Vec<DVec3> {
    let k = poly.len();
    if k < 3 {
        return Vec::new();
    }
    let size = poly.iter().map(|p| p.distance(poly[0])).fold(0.0, f64::max);
    let tol = CLIP_REL * size;
    let d: Vec<f64> = poly
        .iter()
        .map(|p| {
            let h = plane.normal.dot(*p - plane.point);
            if h.abs() <= tol { 0.0 } else { h }
        })
        .collect();
    let mut out = Vec::with_capacity(k + 1);
    for i in 0..k {
        let j = (i + 1) % k;
        if d[i] >= 0.0 {
            out.push(poly[i]);
        }
        if (d[i] > 0.0 && d[j] < 0.0) || (d[i] < 0.0 && d[j] > 0.0) {
            let t = d[i] / (d[i] - d[j]);
            out.push(poly[i] + (poly[j] - poly[i]) * t);
        }
    }
    if out.len() < 3 || polygon_area(&out) <= 0.0 { Vec::new() } else { out }
}

/// `poly` clipped by every half-space in turn (empty once nothing is left).
fn clip_all(poly: &[DVec3], planes: &[Plane]) -> Vec<DVec3> {
    let mut cur = poly.to_vec();
    for p in planes {
        cur = clip(&cur, p);
        if cur.is_empty() {
            break;
        }
    }
    cur
}

/// F of the union of `poly ∩ cone_k` over k, by inclusion–exclusion with empty intersections
/// pruned (depth first: each subset's intersection is its parent's clipped by one more cone).
fn union_form_factor(poly: &[DVec3], cones: &[Vec<Plane>], f: &dyn Fn(&[DVec3]) -> f64) -> f64 {
    fn rec(
        poly: &[DVec3],
        cones: &[Vec<Plane>],
        start: usize,
        sign: f64,
        f: &dyn Fn(&[DVec3]) -> f64,
    ) -> f64 {
        let mut sum = 0.0;
        for (k, cone) in cones.iter().enumerate().skip(start) {
            let piece = clip_all(poly, cone);
            if piece.is_empty() {
                continue;
            }
            sum += sign * f(&piece) + rec(&piece, cones, k + 1, -sign, f);
        }
        sum
    }
    rec(poly, cones, 0, 1.0, f)
}

/// One parameterised piece of an element: a quad's bilinear map, or a triangle as a quad
/// collapsed onto its third vertex (Duffy).
#[derive(Copy, Clone, Debug)]
struct Piece {
    corners: [DVec3; 4],
}

impl Piece {
    fn point(&self, u: f64, v: f64) -> DVec3 {
        let [a, b, c, d] = self.corners;
        (a * (1.0 - u) + b * u) * (1.0 - v) + (d * (1.0 - u) + c * u) * v
    }
    /// |∂p/∂u × ∂p/∂v|.
    fn jacobian(&self, u: f64, v: f64) -> f64 {
        let [a, b, c, d] = self.corners;
        let du = (b - a) * (1.0 - v) + (c - d) * v;
        let dv = (d - a) * (1.0 - u) + (c - b) * u;
        du.cross(dv).length()
    }
}

fn pieces(verts: &[DVec3]) -> Vec<Piece> {
    match verts.len() {
        0..=2 => Vec::new(),
        3 => vec![Piece { corners: [verts[0], verts[1], verts[2], verts[2]] }],
        4 => vec![Piece { corners: [verts[0], verts[1], verts[2], verts[3]] }],
        k => {
            (1..k - 1).map(|i| Piece { corners: [verts[0], verts[i], verts[i + 1], verts[i + 1]] }).collect()
        }
    }
}

/// Gauss–Legendre nodes and weights on [0, 1], order [`GL_ORDER`].
fn gl_rule() -> [(f64, f64); GL_ORDER] {
    // ±√(5 ∓ 2√(10/7))/3 on [−1, 1], weights (322 ± 13√70)/900 and 128/225.
    let s = (10.0f64 / 7.0).sqrt();
    let x1 = (5.0 - 2.0 * s).sqrt() / 3.0;
    let x2 = (5.0 + 2.0 * s).sqrt() / 3.0;
    let w1 = (322.0 + 13.0 * 70f64.sqrt()) / 900.0;
    let w2 = (322.0 - 13.0 * 70f64.sqrt()) / 900.0;
    let at = |x: f64, w: f64| (0.5 * (1.0 + x), 0.5 * w);
    [at(-x2, w2), at(-x1, w1), at(0.0, 128.0 / 225.0), at(x1, w1), at(x2, w2)]
}

/// The four quarters of the rectangle `[u0,u1]×[v0,v1]`: bit 0 of `q` picks the upper half in u,
/// bit 1 in v.
fn quarter(u: [f64; 2], v: [f64; 2], q: usize) -> ([f64; 2], [f64; 2]) {
    let (mu, mv) = (0.5 * (u[0] + u[1]), 0.5 * (v[0] + v[1]));
    let u = if q & 1 == 0 { [u[0], mu] } else { [mu, u[1]] };
    let v = if q & 2 == 0 { [v[0], mv] } else { [mv, v[1]] };
    (u, v)
}

/// Result of [`integrate`]: the area average of the integrand.
struct Average {
    value: f64,
    error: f64,
    points: u64,
    converged: bool,
}

/// The area average of `g` over the convex polygon `verts`, to an estimated absolute error
/// `abs_tol` (globally adaptive; see the module docs).
fn integrate(verts: &[DVec3], abs_tol: f64, g: &dyn Fn(DVec3) -> f64) -> Average {
    let pcs = pieces(verts);
    let area = polygon_area(verts);
    if pcs.is_empty() || area.is_nan() || area <= 0.0 {
        return Average { value: 0.0, error: 0.0, points: 0, converged: true };
    }
    let rule = gl_rule();
    let points = std::cell::Cell::new(0u64);
    let rect = |piece: usize, u: [f64; 2], v: [f64; 2]| {
        let pc = &pcs[piece];
        let (hu, hv) = (u[1] - u[0], v[1] - v[0]);
        let mut s = 0.0;
        for &(a, wa) in &rule {
            for &(b, wb) in &rule {
                let (uu, vv) = (u[0] + a * hu, v[0] + b * hv);
                let j = pc.jacobian(uu, vv);
                if j > 0.0 {
                    s += wa * wb * j * g(pc.point(uu, vv));
                }
            }
        }
        points.set(points.get() + (GL_ORDER * GL_ORDER) as u64);
        s * hu * hv
    };
    // A region keeps its quarters' values: its value is their sum, its error estimate the
    // difference to the whole, and they are its children's wholes when it is split.
    let region = |piece: u32, u: [f64; 2], v: [f64; 2], whole: f64| {
        let quarters: [f64; 4] = std::array::from_fn(|q| {
            let (qu, qv) = quarter(u, v, q);
            rect(piece as usize, qu, qv)
        });
        let value = quarters.iter().sum();
        Region { piece, u, v, value, error: (whole - value).abs(), detail: quarters }
    };
    let tol = abs_tol.max(0.0) * area;
    let mut heap = BinaryHeap::new();
    for p in 0..pcs.len() {
        let whole = rect(p, [0.0, 1.0], [0.0, 1.0]);
        heap.push(region(p as u32, [0.0, 1.0], [0.0, 1.0], whole));
    }
    let mut error = totals(&heap).1;
    let converged = loop {
        if error <= tol {
            error = totals(&heap).1;
            if error <= tol {
                break true;
            }
        }
        if points.get() + 16 * (GL_ORDER * GL_ORDER) as u64 > MAX_POINTS {
            break false;
        }
        let Some(r) = heap.pop() else { break true };
        error -= r.error;
        for (q, &whole) in r.detail.iter().enumerate() {
            let (qu, qv) = quarter(r.u, r.v, q);
            let c = region(r.piece, qu, qv, whole);
            error += c.error;
            heap.push(c);
        }
    };
    let (value, error) = totals(&heap);
    Average { value: value / area, error: error / area, points: points.get(), converged }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> DVec3 {
        DVec3::new(x, y, z)
    }

    #[test]
    fn clip_keeps_the_inside_and_cuts_exactly() {
        let sq = [v(0., 0., 0.), v(1., 0., 0.), v(1., 1., 0.), v(0., 1., 0.)];
        let half = clip(&sq, &Plane { point: v(0.25, 0., 0.), normal: v(1., 0., 0.) });
        assert!((polygon_area(&half) - 0.75).abs() < 1e-15);
        assert!(clip(&sq, &Plane { point: v(2., 0., 0.), normal: v(1., 0., 0.) }).is_empty());
        assert_eq!(clip(&sq, &Plane { point: v(-1., 0., 0.), normal: v(1., 0., 0.) }).len(), 4);
    }

    #[test]
    fn inclusion_exclusion_counts_overlaps_once() {
        // "Form factor" = area; three overlapping half-planes cut from the unit square.
        let sq = [v(0., 0., 0.), v(1., 0., 0.), v(1., 1., 0.), v(0., 1., 0.)];
        let hp = |x: f64, n: DVec3| vec![Plane { point: v(x, x, 0.), normal: n }];
        let cones = [hp(0.5, v(1., 0., 0.)), hp(0.5, v(0., 1., 0.)), hp(0.75, v(1., 0., 0.))];
        // x ≥ 0.5 or y ≥ 0.5 (the third is inside the first): 1 − 0.25.
        let u = union_form_factor(&sq, &cones, &|p: &[DVec3]| polygon_area(p));
        assert!((u - 0.75).abs() < 1e-14, "{u}");
    }

    #[test]
    fn cubature_integrates_polynomials_and_kinks() {
        let sq = [v(0., 0., 0.), v(2., 0., 0.), v(2., 1., 0.), v(0., 1., 0.)];
        let a = integrate(&sq, 1e-12, &|p| p.x * p.x * p.y);
        assert!((a.value - 2.0 / 3.0).abs() < 1e-13, "{}", a.value);
        // |x − 0.7|, a kink inside: average over [0,2] = (0.7² + 1.3²)/4.
        let k = integrate(&sq, 1e-10, &|p| (p.x - 0.7).abs());
        assert!((k.value - (0.49 + 1.69) / 4.0).abs() < 1e-10, "{}", k.value);
        let tri = [v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.)];
        let t = integrate(&tri, 1e-12, &|p| p.x);
        assert!((t.value - 1.0 / 3.0).abs() < 1e-13, "{}", t.value);
    }
}
