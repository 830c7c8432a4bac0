//! Element basis functions of order p = 0 and p = 1, and the quadrature rules on an element that
//! the Galerkin solver ([`crate::solver::linear`]) and the reconstructions
//! ([`crate::eval::reconstruction`]) share.
//!
//! A radiosity function on an element e is `B(x) = Σ_k b_k φ_k(x)` [Heckbert & Winget 1991,
//! "Finite element methods for global illumination"; Zatz 1993, "Galerkin radiosity"]:
//!
//! ```text
//! p = 0   one basis function, φ = 1                                  (constant element)
//! p = 1   triangle v0 v1 v2:  φ_k = λ_k, the barycentric coordinates  (linear)
//!         quad v0 v1 v2 v3:   φ_0 = (1−s)(1−t), φ_1 = s(1−t),         (bilinear)
//!                             φ_2 = s t,       φ_3 = (1−s) t
//!                             on x(s, t) = (1−t)[(1−s) v0 + s v1] + t[(1−s) v3 + s v2]
//! ```
//!
//! so a p = 1 element's coefficients are its **vertex values** (nodal basis, `φ_k(v_j) = δ_kj`),
//! and the quad's map is the one [`crate::solver::uniform::mesh_patch`] uses for its grid.
//!
//! **Quadrature** ([`rule`]): an n × n Gauss–Legendre product rule on the element's parameter
//! square — through the bilinear map on a quad, through the Duffy map `(a, b) ↦ (u, v) =
//! (a(1−b), a b)` (Jacobian a) on a triangle [Duffy 1982] — whose points carry their world
//! position, their weight (area) and the basis values there. With n ≥ 2 it integrates the mass
//! matrix `M_kl = ∫_e φ_k φ_l dA` exactly on parallelograms and triangles.

use crate::geometry::form_factor::gauss_legendre;
use crate::math::DVec3;

/// Polynomial order of an element's basis (the lecture's p).
#[derive(Copy, Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Order {
    /// Constant per element.
    Constant,
    /// Linear on triangles, bilinear on quads (vertex values).
    Linear,
}

impl Order {
    /// 0 or 1.
    #[must_use]
    pub fn degree(self) -> u32 {
        match self {
            Order::Constant => 0,
            Order::Linear => 1,
        }
    }

    /// From 0 or 1.
    #[must_use]
    pub fn from_degree(p: u32) -> Option<Order> {
        match p {
            0 => Some(Order::Constant),
            1 => Some(Order::Linear),
            _ => None,
        }
    }

    /// Basis functions on an element with `vertices` corners (3 or 4).
    #[must_use]
    pub fn functions(self, vertices: usize) -> usize {
        match self {
            Order::Constant => 1,
            Order::Linear => vertices,
        }
    }
}

/// Largest number of basis functions on one element (a p = 1 quad).
pub const MAX_FUNCTIONS: usize = 4;

/// Basis values at one point, first `n` used.
pub type Values = [f64; MAX_FUNCTIONS];

/// Local coordinates of a point of an element: (u, v) with λ = (1−u−v, u, v) on a triangle,
/// (s, t) ∈ [0, 1]² on a quad.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Local(pub f64, pub f64);

/// World position of local coordinates on an element (3 or 4 vertices).
#[must_use]
pub fn position(verts: &[DVec3], at: Local) -> DVec3 {
    let Local(s, t) = at;
    if verts.len() == 3 {
        verts[0] + (verts[1] - verts[0]) * s + (verts[2] - verts[0]) * t
    } else {
        verts[0].lerp(verts[1], s).lerp(verts[3].lerp(verts[2], s), t)
    }
}

/// The basis values at local coordinates (module docs); unused slots are 0.
#[must_use]
pub fn values(order: Order, vertices: usize, at: Local) -> Values {
    let Local(s, t) = at;
    match (order, vertices) {
        (Order::Constant, _) => [1.0, 0.0, 0.0, 0.0],
        (Order::Linear, 3) => [1.0 - s - t, s, t, 0.0],
        (Order::Linear, _) => [(1.0 - s) * (1.0 - t), s * (1.0 - t), s * t, (1.0 - s) * t],
    }
}

/// Partial derivatives of the element map at local coordinates: (∂x/∂s, ∂x/∂t).
fn tangents(verts: &[DVec3], at: Local) -> (DVec3, DVec3) {
    let Local(s, t) = at;
    if verts.len() == 3 {
        (verts[1] - verts[0], verts[2] - verts[0])
    } else {
        let ds = (verts[1] - verts[0]) * (1.0 - t) + (verts[2] - verts[3]) * t;
        let dt = (verts[3] - verts[0]) * (1.0 - s) + (verts[2] - verts[1]) * s;
        (ds, dt)
    }
}

/// Local coordinates of the point of the element nearest to `x` (x on or near the element's
/// plane): barycentric on a triangle, Newton on the bilinear map of a quad (exact in one step
/// on a parallelogram), clamped to the element.
#[must_use]
pub fn local_coordinates(verts: &[DVec3], x: DVec3) -> Local {
    let solve = |ds: DVec3, dt: DVec3, r: DVec3| {
        // Least squares [ds dt] (δs, δt) = r.
        let (a, b, c) = (ds.dot(ds), ds.dot(dt), dt.dot(dt));
        let det = a * c - b * b;
        if det.abs() <= f64::MIN_POSITIVE {
            return (0.0, 0.0);
        }
        let (rs, rt) = (ds.dot(r), dt.dot(r));
        ((c * rs - b * rt) / det, (a * rt - b * rs) / det)
    };
    if verts.len() == 3 {
        let (u, v) = solve(verts[1] - verts[0], verts[2] - verts[0], x - verts[0]);
        // Clamp to the triangle: a point outside (rounding of the locator) takes the nearest
        // barycentric coordinates that are all ≥ 0.
        let (u, v) = (u.max(0.0), v.max(0.0));
        let sum = u + v;
        return if sum > 1.0 { Local(u / sum, v / sum) } else { Local(u, v) };
    }
    let mut at = Local(0.5, 0.5);
    for _ in 0..8 {
        let (ds, dt) = tangents(verts, at);
        let (du, dv) = solve(ds, dt, x - position(verts, at));
        at = Local((at.0 + du).clamp(0.0, 1.0), (at.1 + dv).clamp(0.0, 1.0));
        if du.abs().max(dv.abs()) < 1e-13 {
            break;
        }
    }
    at
}

/// One quadrature point of an element: world position, weight (an area: the weights sum to the
/// element's area) and local coordinates.
#[derive(Copy, Clone, Debug)]
pub struct QuadPoint {
    pub x: DVec3,
    pub weight: f64,
    pub at: Local,
}

/// The n × n product rule on an element (module docs), over the part of its parameter domain
/// given by `domain`: the whole element is `Domain::WHOLE`.
#[must_use]
pub fn rule(verts: &[DVec3], n: usize, domain: &Domain) -> Vec<QuadPoint> {
    let gl = gauss_legendre(n);
    let mut out = Vec::with_capacity(gl.len() * gl.len());
    for &(a, wa) in &gl {
        for &(b, wb) in &gl {
            let (at, jac_local) = domain.map(a, b);
            let (ds, dt) = tangents(verts, at);
            let jac = ds.cross(dt).length() * jac_local;
            out.push(QuadPoint { x: position(verts, at), weight: wa * wb * jac, at });
        }
    }
    out
}

/// A piece of an element's parameter domain: a sub-rectangle of the unit square (quads) or a
/// sub-triangle of the unit triangle (triangles), refined by [`Domain::split`].
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum Domain {
    /// s ∈ [s0, s1], t ∈ [t0, t1].
    Rect { s0: f64, s1: f64, t0: f64, t1: f64 },
    /// The triangle of three local points.
    Tri([Local; 3]),
}

impl Domain {
    /// The whole parameter domain of an element with `vertices` corners.
    #[must_use]
    pub fn whole(vertices: usize) -> Domain {
        if vertices == 3 {
            Domain::Tri([Local(0.0, 0.0), Local(1.0, 0.0), Local(0.0, 1.0)])
        } else {
            Domain::Rect { s0: 0.0, s1: 1.0, t0: 0.0, t1: 1.0 }
        }
    }

    /// (a, b) ∈ [0, 1]² to local coordinates, and the Jacobian of that map.
    fn map(&self, a: f64, b: f64) -> (Local, f64) {
        match *self {
            Domain::Rect { s0, s1, t0, t1 } => {
                (Local(s0 + a * (s1 - s0), t0 + b * (t1 - t0)), (s1 - s0) * (t1 - t0))
            }
            Domain::Tri([p0, p1, p2]) => {
                // Duffy: (a, b) ↦ p0 + a(1−b)(p1−p0) + a b (p2−p0), Jacobian a·|det|.
                let (e1, e2) = ((p1.0 - p0.0, p1.1 - p0.1), (p2.0 - p0.0, p2.1 - p0.1));
                let det = (e1.0 * e2.1 - e1.1 * e2.0).abs();
                let (c1, c2) = (a * (1.0 - b), a * b);
                (Local(p0.0 + c1 * e1.0 + c2 * e2.0, p0.1 + c1 * e1.1 + c2 * e2.1), a * det)
            }
        }
    }

    /// The four children: quarters of a rectangle, midpoint split of a triangle.
    #[must_use]
    pub fn split(&self) -> [Domain; 4] {
        match *self {
            Domain::Rect { s0, s1, t0, t1 } => {
                let (sm, tm) = (0.5 * (s0 + s1), 0.5 * (t0 + t1));
                [
                    Domain::Rect { s0, s1: sm, t0, t1: tm },
                    Domain::Rect { s0: sm, s1, t0, t1: tm },
                    Domain::Rect { s0: sm, s1, t0: tm, t1 },
                    Domain::Rect { s0, s1: sm, t0: tm, t1 },
                ]
            }
            Domain::Tri([a, b, c]) => {
                let mid = |p: Local, q: Local| Local(0.5 * (p.0 + q.0), 0.5 * (p.1 + q.1));
                let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
                [
                    Domain::Tri([a, ab, ca]),
                    Domain::Tri([ab, b, bc]),
                    Domain::Tri([ca, bc, c]),
                    Domain::Tri([ab, bc, ca]),
                ]
            }
        }
    }

    /// Corners in local coordinates (3 or 4), in the element's orientation.
    #[must_use]
    pub fn corners(&self) -> Vec<Local> {
        match *self {
            Domain::Rect { s0, s1, t0, t1 } => {
                vec![Local(s0, t0), Local(s1, t0), Local(s1, t1), Local(s0, t1)]
            }
            Domain::Tri(c) => c.to_vec(),
        }
    }

    /// The centroid in local coordinates.
    #[must_use]
    pub fn centre(&self) -> Local {
        let c = self.corners();
        let k = c.len() as f64;
        Local(c.iter().map(|p| p.0).sum::<f64>() / k, c.iter().map(|p| p.1).sum::<f64>() / k)
    }
}

/// The element's mass matrix `M_kl = ∫_e φ_k φ_l dA` (row-major, `order.functions(n)` square)
/// and the integrals `∫_e φ_k dA`.
#[must_use]
pub fn mass(order: Order, verts: &[DVec3]) -> ([[f64; MAX_FUNCTIONS]; MAX_FUNCTIONS], Values) {
    let nf = order.functions(verts.len());
    let mut m = [[0.0; MAX_FUNCTIONS]; MAX_FUNCTIONS];
    let mut integral = [0.0; MAX_FUNCTIONS];
    // 3 points per direction: the integrand is of degree ≤ 3 in each of (a, b) (bilinear φ_k φ_l
    // times the bilinear map's Jacobian, linear in each), so the rule is exact.
    for q in rule(verts, 3, &Domain::whole(verts.len())) {
        let phi = values(order, verts.len(), q.at);
        for k in 0..nf {
            integral[k] += q.weight * phi[k];
            for l in 0..nf {
                m[k][l] += q.weight * phi[k] * phi[l];
            }
        }
    }
    (m, integral)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::polygon_area;

    fn quad() -> Vec<DVec3> {
        // A non-parallelogram planar quad.
        vec![DVec3::new(0., 0., 0.), DVec3::new(2., 0., 0.), DVec3::new(1.5, 1., 0.), DVec3::new(0., 1.2, 0.)]
    }

    fn tri() -> Vec<DVec3> {
        vec![DVec3::new(0., 0., 0.), DVec3::new(1., 0., 1.), DVec3::new(0., 2., 0.)]
    }

    #[test]
    fn rules_integrate_area_and_partition_of_unity() {
        for verts in [quad(), tri()] {
            let area = polygon_area(&verts);
            let whole = Domain::whole(verts.len());
            let sum: f64 = rule(&verts, 4, &whole).iter().map(|q| q.weight).sum();
            assert!((sum - area).abs() < 1e-12 * area, "{sum} vs {area}");
            // The children's rules add up to the whole.
            let parts: f64 = whole.split().iter().flat_map(|d| rule(&verts, 2, d)).map(|q| q.weight).sum();
            assert!((parts - area).abs() < 1e-12 * area);
            let (m, integral) = mass(Order::Linear, &verts);
            let n = verts.len();
            let total: f64 = (0..n).map(|k| (0..n).map(|l| m[k][l]).sum::<f64>()).sum();
            assert!((total - area).abs() < 1e-12 * area, "Σ M = ∫ 1 = area");
            let int: f64 = integral[..n].iter().sum();
            assert!((int - area).abs() < 1e-12 * area);
        }
        // The P1 triangle's mass matrix is A/12 · [2 1 1; 1 2 1; 1 1 2].
        let t = tri();
        let a = polygon_area(&t);
        let (m, _) = mass(Order::Linear, &t);
        assert!((m[0][0] - a / 6.0).abs() < 1e-14 && (m[0][1] - a / 12.0).abs() < 1e-14);
    }

    #[test]
    fn local_coordinates_invert_the_map_and_basis_is_nodal() {
        for verts in [quad(), tri()] {
            let n = verts.len();
            for at in [Local(0.2, 0.3), Local(0.05, 0.9), Local(0.6, 0.1)] {
                let x = position(&verts, at);
                let back = local_coordinates(&verts, x);
                assert!((back.0 - at.0).abs() < 1e-10 && (back.1 - at.1).abs() < 1e-10, "{at:?} → {back:?}");
            }
            for (j, v) in verts.iter().enumerate() {
                let phi = values(Order::Linear, n, local_coordinates(&verts, *v));
                for (k, p) in phi[..n].iter().enumerate() {
                    assert!((p - f64::from(u8::from(j == k))).abs() < 1e-10, "φ_{k}(v_{j}) = {p}");
                }
            }
        }
    }
}
