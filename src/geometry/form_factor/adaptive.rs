//! F from→to by globally adaptive cubature of the exact point kernel over the receiver:
//!
//! ```text
//! F_ij = 1/A_i ∫_i F(x → j) dA_i                              [Cohen & Wallace 1993, eq. 4.8]
//! ```
//!
//! Genz–Malik degree-7 rule with a degree-5 error estimate on each region, bisection along the
//! axis of largest fourth difference [Genz & Malik 1980; Berntsen, Espelid, Genz 1991]; the
//! regions wait in the error-ordered heap of [`super::region`]. Near the source (a shared edge,
//! contact) the kernel's derivative is log-singular and the embedded estimate fails (50×
//! optimistic in tests), so regions near the source are estimated against their two halves
//! instead. The receiver is first clipped to the half-space in front of the source
//! ([`super::pair`]), so the kernel never jumps inside the domain.

use super::pair::{Piece, pieces, prepare};
use super::point::point_to_polygon_unit;
use super::region::{Region, totals};
use crate::math::DVec3;
use std::collections::BinaryHeap;

/// Hard cap on kernel evaluations of one adaptive integration (about 100 000 regions, 10 MB;
/// the hardest catalog case at 1e-10 needs 130 000 evaluations).
pub const MAX_EVALUATIONS: u64 = 2_000_000;

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

/// What a region of [`integrate_adaptive`] keeps to be refined: its own Genz–Malik evaluation
/// and, for a region near the source, the evaluated halves that gave its estimate (they become
/// its children).
#[derive(Copy, Clone, Debug)]
struct Refine {
    whole: Eval,
    halves: Option<[Eval; 2]>,
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
    ) -> Region<Refine> {
        let (u, v) = (whole.u, whole.v);
        if near(piece, &whole) {
            let [(u1, v1), (u2, v2)] = whole.halves();
            let halves = [eval(piece, u1, v1), eval(piece, u2, v2)];
            let value = halves[0].value + halves[1].value;
            let error = (whole.value - value).abs().max(halves[0].gm_error + halves[1].gm_error);
            Region { piece, u, v, value, error, detail: Refine { whole, halves: Some(halves) } }
        } else {
            let detail = Refine { whole, halves: None };
            Region { piece, u, v, value: whole.value, error: whole.gm_error, detail }
        }
    }
    let mut heap = BinaryHeap::new();
    for (ip, pc) in pcs.iter().enumerate() {
        let (nu, nv) = start_grid(pc);
        for i in 0..nu {
            for j in 0..nv {
                let u = [f64::from(i) / f64::from(nu), f64::from(i + 1) / f64::from(nu)];
                let v = [f64::from(j) / f64::from(nv), f64::from(j + 1) / f64::from(nv)];
                let whole = eval(ip as u32, u, v);
                heap.push(finish(ip as u32, whole, &mut eval, &near));
            }
        }
    }
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
        let children = match r.detail.halves {
            Some(h) => h,
            None => {
                let [(u1, v1), (u2, v2)] = r.detail.whole.halves();
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

/// The grid a piece's integration starts from: regions roughly square in space (slivers start
/// split), at most 16 along a side.
fn start_grid(pc: &Piece) -> (u32, u32) {
    let (lu, lv) = pc.lengths();
    let aspect = if lu > 0.0 && lv > 0.0 { lu / lv } else { 1.0 };
    let nu = aspect.round().clamp(1.0, 16.0) as u32;
    let nv = (1.0 / aspect).round().clamp(1.0, 16.0) as u32;
    (nu, nv)
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
/// relative error `rel_tol` (area-weighted average of [`super::point_to_polygon`]).
///
/// Accurate to ~1e-6 and beyond for touching, shared-edge, sliver and near-contact pairs;
/// 0 for pairs that face away. Reciprocity `A_i F_ij = A_j F_ji` holds to the tolerance.
#[must_use]
pub fn polygon_to_polygon(from: &[DVec3], to: &[DVec3], rel_tol: f64) -> f64 {
    polygon_to_polygon_adaptive(from, to, rel_tol, 0.0).value
}

#[cfg(test)]
mod tests {
    use super::*;

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
