//! The error-driven oracle: refine where a receiver's answer is wrong, not where much light flows.
//!
//! A leaf holds the gathered irradiance H over its area as a value and, with `push_slopes` (every
//! preset), a slope. What is wrong with that is how much the *total* irradiance, from all its
//! links (its own and those it inherits from its ancestors), varies across it beyond what the
//! leaf holds. The oracle evaluates each own link's exact point kernel F(x → q) at eight points
//! of r: the four x_k where splitting would put its children's centroids, and four c_j just
//! inside its corners (`sample_points`):
//!
//! ```text
//! h(x_k)    = Σ_{links a ← q, a = r or an ancestor} F(x_k → q) V_aq B_q
//! bend_j(q) = F(c_j → q) − Σ_k a_jk F(x_k → q)         (a_jk: the affine fit through the x_k, at c_j)
//! e_r       = ρ_r · s · max_k |h(x_k) − mean_k h(x_k)|  +  ρ_r · max_j |Σ_{own links} V_rq B_q bend_j(q)|
//!           + ρ_r Σ_{own partial links} 2 min(V, 1 − V) F_rq B_q
//! ```
//!
//! (largest RGB channel). The first term is the receiver's variation of the total at the child
//! points — a link whose contribution is uniform across r, or whose variation the other links
//! cancel (in the white furnace Σ_q F(x → q) = 1 at every point), adds nothing, however much
//! power it carries [Lischinski, Smits & Greenberg 1994, "Bounds and error estimates for
//! radiosity", sec. 4: the error of a constant element is bounded by the spread of its gathered
//! radiosity across it]. It counts whole for constant leaves (s = 1) and at
//! [`SLOPED_SPREAD`] with slopes, which hold its affine part. The own links' terms are evaluated
//! exactly; the inherited ones are the least-squares affine fit, in the parent's plane, of the
//! parent's h at its own four points, evaluated at r's (`inherit`), so an element costs its own
//! links only, not Σ (links along its chain of ancestors).
//!
//! The second term is what that affine picture misses: the curvature of r's own links'
//! irradiance, the fit through the child points against the kernel near the corners, summed
//! with signs over the links like h. Four child points alone see a ceiling that darkens towards
//! both walls as flat (equal values at u = 1/4 and 3/4), a fit through them extrapolates that
//! flatness to the edges, and the children inherit it. Inherited links add no bend below the
//! ancestor that holds them: the ancestor's own bend, over its larger area, splits their causes
//! down first.
//!
//! The third term is the uncertainty of partially visible links, whose visibility varies across
//! the receiver in a way the link's average V hides (where the shadows are) [Holzschuch & Sillion
//! 1998, "An exhaustive error-bounding algorithm for hierarchical radiosity", sec. 3.2: the
//! visibility term of a link's bound]. A fourth term catches what eight points cannot see:
//!
//! ```text
//!          + ρ_r |Σ_{own links} V_rq B_q (F_rq − mean_k F(x_k → q))|
//! ```
//!
//! F_rq is the link's Galerkin coefficient, the kernel's true average over r (`transfer`); when
//! the child points' mean misses it, the kernel varies between them (a lamp grazing a wall
//! lights a sliver of a large element that no child point lies in). Summed with signs, like the
//! bend. [The same idea as the a-posteriori quadrature estimates of Lischinski, Smits &
//! Greenberg 1994, sec. 5: compare two rules of different order.]
//!
//! A link r ← q is split on the receiver's side when r's answer is wrong (e_r > ε) and the link
//! is one of its causes: its own share of the error, c_rq = ρ_r V B_q (s max_k |F(x_k → q) −
//! mean| + max_j |bend_j(q)| + |F_rq − mean_k F(x_k → q)|) (+ its visibility term), is among
//! the largest of r's own links, taken largest first until the rest add up to at most
//! `cause_tail` · ε, ε/4 in every preset (so the rest cannot make r wrong again on their own,
//! and a receiver with thousands of small links does not split them all; the share is chosen
//! by measurement, docs/solver.md, "Oracles"). With `ErrorTail::Signed` the rest is what those
//! links add to e_r as it sums them (`own_error`: their terms at the child points with signs,
//! their penumbra terms in quadrature, as e_r then takes them too), not the sum of their c_rq.
//! It is split on the source's side when
//! q's radiosity varies (ΔB_q: q's own e_q, or the spread of its children's B) enough to matter
//! through the kernel's variation across q: ρ_r F_rq V ΔB_q diam_q / distance > ε [Holzschuch &
//! Sillion 1998, sec. 3.1, the source-radiosity term]. Every decision
//! is taken for the pair (both directions, the larger element first when both ask), from
//! quantities both sides compute alike, so a link and its mirror always agree and the links
//! stay mirror images (energy conservation, see `transfer`).
//!
//! ε is `bf_eps` (absolute, or relative to the largest emission). Refinement stops at the Aeps
//! floor and the maximum depth, as with the other oracles.
//!
//! **Cost.** F(x → q) at r's eight points depends on the pair's geometry alone, so it is
//! evaluated once per pair and kept (`ErrorField::kernels`, per receiver sorted by source,
//! carried from one refinement to the next): the field's update, the decisions on both sides of
//! a pair and the links' slopes (`kernel_slope`) look it up, the same numbers as evaluating it
//! each time. Within a refinement, a pass decides only the links the last pass made and those
//! with an end whose verdict inputs changed (`ErrorField::fresh`): a receiver whose list changed
//! reads nothing of it but its cause, and that only while it is wrong.

use super::HierarchicalSolver;
use crate::geometry::form_factor;
use crate::math::{DVec3, Rgb};
use crate::solver::hierarchy::{Element, StopReason};
use crate::solver::link::Link;
use crate::solver::params::ErrorTail;
use rayon::prelude::*;

/// Per-element inputs of the error oracle, computed once per refinement and updated pass by pass.
#[derive(Default)]
pub(super) struct ErrorField {
    /// e_r: the receiver's error (module docs); 0 for an element without own links.
    pub err: Vec<f64>,
    /// ΔB: how much the element's radiosity varies across it.
    pub spread: Vec<f64>,
    /// The smallest c_rq (module docs) of the own links that cause e_r: the largest ones, until
    /// the rest add up to at most `cause_tail` · ε (∞ without own links).
    pub cause: Vec<f64>,
    /// h(x_k) at the element's four child points: its own links' exact terms plus the affine
    /// fit of its parent's h (module docs, "inherited links").
    h: Vec<[Rgb; 4]>,
    /// The own links' exact part of `h`.
    own_h: Vec<[Rgb; 4]>,
    /// ρ-less visibility term Σ_{own partial links} 2 min(V, 1 − V) F B.
    partial: Vec<Rgb>,
    /// ρ-less terms of what the child points miss, per channel: |Σ_{own links} V B (F_rq −
    /// mean_k F(x_k → q))| + max_j |Σ_{own links} V B bend_j(q)| (module docs).
    disc: Vec<Rgb>,
    /// Per element, the exact kernel F(x → q) at its eight points for each source q of
    /// its own links, sorted by q: what `own_terms` evaluated, for the decisions to look up
    /// instead of evaluating again (a pair's kernel is geometry alone, fixed for the pair's
    /// life, so an entry never goes stale).
    pub kernels: Vec<Kernels>,
    /// Per element, (c_rq, F̂_rq) of each own link, in list order: what a verdict reads on the
    /// receiver's side, without a search (the mirror's side looks its kernel up).
    own_var: Vec<Vec<[f64; 2]>>,
    /// Whether the last update changed what the element's verdicts read (its cause while it is
    /// wrong, or its e or ΔB across the threshold; see `sweep`): a kept link is decided again
    /// only if one of its ends is fresh (a new link always is).
    pub fresh: Vec<bool>,
    /// Per element, the affine fit's weights at its c_j (`CornerFit`).
    fits: Vec<CornerFit>,
}

/// One element's kernels at its child points, per linked source: the sources sorted, and the
/// kernels in the same order. Kept apart so that looking a source up searches a dense list of
/// ids (the decisions look up two a link, and the search was bound by memory latency).
#[derive(Clone, Debug, Default)]
pub struct Kernels {
    sources: Vec<u32>,
    values: Vec<Kern>,
}

/// The share of the spread of h across an element that counts as error when the leaves carry
/// slopes: a slope holds the affine part of the variation, but it is limited to keep B ≥ 0 and
/// inherited links bring their ancestors' fit, so half counts. Chosen by measurement
/// (docs/solver.md, "Oracles").
pub(super) const SLOPED_SPREAD: f64 = 0.5;

/// A pair's kernel F(x → q) at the receiver's sample points (`sample_points`): its four child
/// points, then the four c_j near its corners.
pub type Kern = [f64; 8];

/// How far in from each corner, as a fraction of the element's side (of its bilinear
/// parameters; a triangle's points weigh the corner 1 − 4/3 of it), the error oracle evaluates
/// a pair's kernel near the corner: close enough to see a variation that rises towards an edge,
/// off the edge itself, which lies in the plane of the element meeting it there (a wall on a
/// floor), where the point kernel jumps.
pub(super) const NEAR_CORNER: f64 = 0.03;

/// The points where the error oracle evaluates a pair's kernel: `child_points`, then the four
/// c_j near the corners ([`NEAR_CORNER`]; a triangle's first one again as the eighth).
pub(super) fn sample_points(e: &Element) -> [DVec3; 8] {
    let c = child_points(e);
    let v = e.vertices();
    let g: [DVec3; 4] = if v.len() == 4 {
        let at = |u: f64, t: f64| {
            v[0] * ((1.0 - u) * (1.0 - t)) + v[1] * (u * (1.0 - t)) + v[2] * (u * t) + v[3] * ((1.0 - u) * t)
        };
        let (a, b) = (NEAR_CORNER, 1.0 - NEAR_CORNER);
        [at(a, a), at(b, a), at(b, b), at(a, b)]
    } else {
        let w = 1.0 - NEAR_CORNER * 4.0 / 3.0;
        let near = |p: DVec3, q: DVec3, r: DVec3| p * w + (q + r) * (0.5 * (1.0 - w));
        let first = near(v[0], v[1], v[2]);
        [first, near(v[1], v[2], v[0]), near(v[2], v[0], v[1]), first]
    };
    [c[0], c[1], c[2], c[3], g[0], g[1], g[2], g[3]]
}

/// Per point c_j of an element (`sample_points`, the last four), the weights a_jk with which
/// the least-squares affine fit of values at its four child points predicts the value there:
/// Σ_k a_jk f_k.
#[derive(Clone, Default)]
pub(super) struct CornerFit {
    a: [[f64; 4]; 4],
}

impl CornerFit {
    pub(super) fn of(e: &Element, pts: &[DVec3; 8]) -> CornerFit {
        let child = [pts[0], pts[1], pts[2], pts[3]];
        let c = (child[0] + child[1] + child[2] + child[3]) * 0.25;
        let (t1, t2) = crate::math::orthonormal_basis(e.normal);
        let w = FitWeights::new(&child, c, t1, t2);
        let a = std::array::from_fn(|j| {
            let x = pts[4 + j] - c;
            std::array::from_fn(|k| match &w {
                Some(w) => 0.25 + w.u[k] * x.dot(t1) + w.v[k] * x.dot(t2),
                None => 0.25,
            })
        });
        CornerFit { a }
    }

    /// What the affine fit of `f` at the child points misses at each c_j.
    fn bend(&self, f: &Kern) -> [f64; 4] {
        std::array::from_fn(|j| {
            let a = &self.a[j];
            f[4 + j] - (a[0] * f[0] + a[1] * f[1] + a[2] * f[2] + a[3] * f[3])
        })
    }
}

impl Kernels {
    /// The kernel of the pair with source `q`, if held.
    fn get(&self, q: u32) -> Option<Kern> {
        self.sources.binary_search(&q).ok().map(|i| self.values[i])
    }
}

/// The four points where a split would put the children's centroids (see `hierarchy` for the
/// split: quads at their bilinear quarter points, triangles at the sub-triangles' centroids).
pub(super) fn child_points(e: &Element) -> [DVec3; 4] {
    let v = e.vertices();
    if v.len() == 4 {
        let at = |u: f64, t: f64| {
            v[0] * ((1.0 - u) * (1.0 - t)) + v[1] * (u * (1.0 - t)) + v[2] * (u * t) + v[3] * ((1.0 - u) * t)
        };
        [at(0.25, 0.25), at(0.75, 0.25), at(0.75, 0.75), at(0.25, 0.75)]
    } else {
        let (a, b, c) = (v[0], v[1], v[2]);
        let (ab, bc, ca) = ((a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5);
        let third = 1.0 / 3.0;
        [(a + ab + ca) * third, (ab + b + bc) * third, (ca + bc + c) * third, (ab + bc + ca) * third]
    }
}

/// The inherited part of h at a child's points `to`: the least-squares affine fit, in the
/// parent's plane, of the parent's h at its own child points `from`, evaluated at `to`.
/// An affine field is reproduced exactly, so fits of fits down a chain of descendants agree
/// with one fit of the ancestor's field.
fn inherit(from: &[DVec3; 4], normal: DVec3, h: &[Rgb; 4], to: &[DVec3; 4]) -> [Rgb; 4] {
    let c = (from[0] + from[1] + from[2] + from[3]) * 0.25;
    let mean = (h[0] + h[1] + h[2] + h[3]) * 0.25;
    let (t1, t2) = crate::math::orthonormal_basis(normal);
    let Some(w) = FitWeights::new(from, c, t1, t2) else {
        return [mean; 4];
    };
    let (mut gu, mut gv) = (Rgb::ZERO, Rgb::ZERO);
    for ((hk, wu), wv) in h.iter().zip(w.u).zip(w.v) {
        gu += (*hk - mean) * wu;
        gv += (*hk - mean) * wv;
    }
    to.map(|x| mean + gu * (x - c).dot(t1) + gv * (x - c).dot(t2))
}

/// The least-squares affine fit of values at four points of a plane, as weights: the fitted
/// gradient of values h_k is (Σ_k u_k (h_k − mean), Σ_k v_k (h_k − mean)) in the basis (t1, t2).
pub(super) struct FitWeights {
    pub(super) u: [f64; 4],
    pub(super) v: [f64; 4],
}

impl FitWeights {
    /// The fitted gradient of the values at the four points (the first four of `vals`) about
    /// their `mean`.
    fn gradient(&self, vals: &[f64], mean: f64) -> [f64; 2] {
        let (mut gu, mut gv) = (0.0, 0.0);
        for ((x, wu), wv) in vals.iter().zip(self.u).zip(self.v) {
            gu += (x - mean) * wu;
            gv += (x - mean) * wv;
        }
        [gu, gv]
    }

    /// None when the points are (nearly) collinear.
    pub(super) fn new(pts: &[DVec3; 4], c: DVec3, t1: DVec3, t2: DVec3) -> Option<FitWeights> {
        let uv = pts.map(|x| ((x - c).dot(t1), (x - c).dot(t2)));
        let (mut suu, mut suv, mut svv) = (0.0, 0.0, 0.0);
        for (u, v) in uv {
            suu += u * u;
            suv += u * v;
            svv += v * v;
        }
        let det = suu * svv - suv * suv;
        if !(det > 1e-12 * (suu + svv) * (suu + svv)) {
            return None;
        }
        // Gradient (g_u, g_v) = M⁻¹ (b_u, b_v), M = [[suu, suv], [suv, svv]], b = Σ (h − mean)·(u, v).
        Some(FitWeights {
            u: uv.map(|(u, v)| (u * svv - v * suv) / det),
            v: uv.map(|(u, v)| (v * suu - u * suv) / det),
        })
    }
}

/// What [`kernel_slope`] reads of the receiver alone, the same for all its links: its child
/// points, its tangent basis and the affine fit's weights (None: the points are collinear).
pub(super) struct SlopeFrame {
    pts: [DVec3; 4],
    t1: DVec3,
    t2: DVec3,
    w: Option<FitWeights>,
}

impl SlopeFrame {
    pub(super) fn of(r: &Element) -> SlopeFrame {
        let pts = child_points(r);
        let c = (pts[0] + pts[1] + pts[2] + pts[3]) * 0.25;
        let (t1, t2) = crate::math::orthonormal_basis(r.normal);
        SlopeFrame { pts, t1, t2, w: FitWeights::new(&pts, c, t1, t2) }
    }
}

/// The gradient, across `r` in the basis `orthonormal_basis(r.normal)`, of the transfer
/// F(x → q) of the link r ← q with visibility `vis` and Galerkin coefficient `f` (r's average):
/// the least-squares affine fit of the exact point kernel at r's four child points, times V,
/// limited so that f V + gradient·(x − centroid) stays ≥ 0 at r's vertices (so on all of r).
/// `frame`: r's [`SlopeFrame`]; `known`: the kernel at r's child points if already evaluated
/// (the error oracle's [`known_kernel`]), the same numbers.
///
/// With `read` (a partially visible link, `HierarchicalParams::vis_slopes`), the fit is of
/// F(x_k → q) V(x_k), V(x_k) the fraction of q that x_k sees ([`VisRead`]): a penumbra across r
/// is a gradient of V that the link's average hides, and with it the leaf's slope follows the
/// shadow's ramp instead of the unoccluded kernel's. That ramp is convex (flat in the umbra,
/// rising across the penumbra), so its affine fit dips below 0 at the dark edge: the link's
/// share may go below 0 there as far as the rest of r's irradiance keeps r's total ≥ 0.
pub(super) fn kernel_slope(
    frame: &SlopeFrame,
    r: &Element,
    q: &Element,
    vis: f64,
    f: f64,
    known: Option<Kern>,
    read: Option<&VisRead>,
) -> [f64; 2] {
    let SlopeFrame { pts, t1, t2, w: Some(w) } = frame else {
        return [0.0; 2];
    };
    let (t1, t2) = (*t1, *t2);
    let (k, mean) = match known {
        Some(k) => (k, kernel_mean(&k)),
        None => kernel_at4(r, pts, q),
    };
    let Some(read) = read else {
        let [gu, gv] = w.gradient(&k, mean);
        return limit_slope(r, t1, t2, [gu * vis, gv * vis], f * vis);
    };
    let fv: [f64; 4] = std::array::from_fn(|i| k[i] * read.at[i].unwrap_or(vis));
    let g = w.gradient(&fv, 0.25 * (fv[0] + fv[1] + fv[2] + fv[3]));
    limit_slope(r, t1, t2, g, (f * vis).max(read.rest))
}

/// What [`kernel_slope`] reads of a partially visible link's visibility across its receiver.
pub(super) struct VisRead {
    /// V(x_k) at the receiver's four child points (None where no sample faced the point: the
    /// link's V).
    pub at: [Option<f64>; 4],
    /// The receiver's whole irradiance in units of the source's radiosity: how far below 0
    /// the link's own share may go at the receiver's edge.
    pub rest: f64,
}

/// Scale the gradient `g` (basis t1, t2) so that `fv` + g·(x − centroid) stays ≥ 0 at r's
/// vertices.
fn limit_slope(r: &Element, t1: DVec3, t2: DVec3, [gu, gv]: [f64; 2], fv: f64) -> [f64; 2] {
    let reach = r
        .vertices()
        .iter()
        .map(|&x| (gu * (x - r.centroid).dot(t1) + gv * (x - r.centroid).dot(t2)).abs())
        .fold(0.0, f64::max);
    let limit = if reach > fv { fv / reach } else { 1.0 };
    if limit.is_finite() { [gu * limit, gv * limit] } else { [0.0; 2] }
}

/// The child points of a slope frame (where [`kernel_slope`] reads V).
pub(super) fn frame_points(frame: &SlopeFrame) -> &[DVec3; 4] {
    &frame.pts
}

/// F(x_k → q) at the four child points of `r`, and their mean.
fn kernel_at(r: &Element, pts: &[DVec3; 8], q: &Element) -> (Kern, f64) {
    let mut f = [0.0; 8];
    // A triangle's fourth c_j is its first again (`sample_points`).
    let n = if r.vertices().len() == 4 { 8 } else { 7 };
    for (fk, x) in f.iter_mut().zip(pts).take(n) {
        *fk = form_factor::point_to_polygon_oriented(*x, r.normal, q.vertices(), q.normal);
    }
    if n == 7 {
        f[7] = f[4];
    }
    (f, kernel_mean(&f))
}

/// F(x_k → q) at the four child points only (the first four of a [`Kern`]), and their mean.
fn kernel_at4(r: &Element, pts: &[DVec3; 4], q: &Element) -> (Kern, f64) {
    let mut f = [0.0; 8];
    for (fk, x) in f.iter_mut().zip(pts) {
        *fk = form_factor::point_to_polygon_oriented(*x, r.normal, q.vertices(), q.normal);
    }
    (f, kernel_mean(&f))
}

/// The kernel of the pair (r, q) at r's child points, if `kernels` (an error field's, per
/// element, sorted by source) holds it.
pub(super) fn known_kernel(kernels: &[Kernels], r: u32, q: u32) -> Option<Kern> {
    kernels.get(r as usize)?.get(q)
}

/// The mean of the kernel at the four child points (one expression, so the same bits wherever
/// the values come from).
fn kernel_mean(f: &Kern) -> f64 {
    0.25 * (f[0] + f[1] + f[2] + f[3])
}

/// What own links add to an element's error field (one link's, or a sum): the kernel times
/// V B at the child points, at the corners beyond their affine fit, what the child points miss
/// (`ErrorField::disc`), and the penumbra term (squared with `ErrorTail::Signed`).
#[derive(Clone, Default)]
struct LinkTerms {
    h: [Rgb; 4],
    bend: [Rgb; 4],
    disc: Rgb,
    pen: Rgb,
}

impl LinkTerms {
    fn add(&mut self, t: &LinkTerms) {
        for k in 0..4 {
            self.h[k] += t.h[k];
            self.bend[k] += t.bend[k];
        }
        self.disc += t.disc;
        self.pen += t.pen;
    }

    fn sub(&mut self, t: &LinkTerms) {
        for k in 0..4 {
            self.h[k] = self.h[k] - t.h[k];
            self.bend[k] = self.bend[k] - t.bend[k];
        }
        self.disc = self.disc - t.disc;
        self.pen = self.pen - t.pen;
    }

    /// max_j |bend_j| per channel.
    fn bend_max(&self) -> Rgb {
        self.bend.iter().fold(Rgb::ZERO, |m, b| {
            let a = b.map(f64::abs);
            Rgb::new(m.r().max(a.r()), m.g().max(a.g()), m.b().max(a.b()))
        })
    }
}

/// One element's own-link terms of the error field.
struct OwnTerms {
    h: [Rgb; 4],
    partial: Rgb,
    disc: Rgb,
    cause: f64,
    /// The own links' kernels at the child points (`ErrorField::kernels`).
    kernels: Kernels,
    /// (c_rq, F̂_rq) of the own links in list order (`ErrorField::own_var`).
    var: Vec<[f64; 2]>,
    fit: CornerFit,
}

/// F_rq of a link of `r`'s (or of its mirror: the pair's coupling over `r`'s area), the same
/// number from both directions.
fn galerkin(r: &Element, l: &Link) -> f64 {
    f64::from(l.g) / r.area
}

/// c_rq (module docs) of the link r ← q (or its mirror) from the kernel `f` at r's child
/// points and its mean.
/// `bend`: the kernel's bend at r's c_j ([`CornerFit::bend`]); `spread_w`: the spread's weight.
fn variation(r: &Element, q: &Element, l: &Link, f: &Kern, mean: f64, bend: [f64; 4], spread_w: f64) -> f64 {
    let v = f64::from(l.vis).clamp(0.0, 1.0);
    let vw = 2.0 * v.min(1.0 - v);
    let b = q.radiosity.max_channel();
    let spread = spread_w * f[..4].iter().map(|fk| (fk - mean).abs()).fold(0.0, f64::max)
        + bend.iter().map(|x| x.abs()).fold(0.0, f64::max);
    let unseen = (galerkin(r, l) - mean).abs();
    r.reflectance.max_channel() * b * (v * (spread + unseen) + vw * mean)
}

/// The visibility term's weight 2 min(V, 1 − V) of a link (0 when fully visible or hidden).
fn partial_weight(l: &Link) -> f64 {
    let v = f64::from(l.vis).clamp(0.0, 1.0);
    2.0 * v.min(1.0 - v)
}

impl HierarchicalSolver {
    /// The error field of the current state (parallel over elements, deterministic).
    /// `known`: the kernels of an earlier field (`ErrorField::kernels`, per element), reused
    /// where a pair is still linked.
    pub(super) fn error_field(&self, known: &[Kernels]) -> ErrorField {
        let n = self.hier.len();
        let mut field = ErrorField {
            err: vec![0.0; n],
            spread: vec![0.0; n],
            cause: vec![f64::INFINITY; n],
            h: vec![[Rgb::ZERO; 4]; n],
            own_h: Vec::new(),
            partial: Vec::new(),
            disc: Vec::new(),
            kernels: Vec::new(),
            own_var: Vec::new(),
            fresh: Vec::new(),
            fits: Vec::new(),
        };
        let terms: Vec<OwnTerms> = (0..n as u32)
            .into_par_iter()
            .with_min_len(64)
            .map(|r| self.own_terms(r, known.get(r as usize)))
            .collect();
        field.own_h = terms.iter().map(|t| t.h).collect();
        field.partial = terms.iter().map(|t| t.partial).collect();
        field.disc = terms.iter().map(|t| t.disc).collect();
        field.cause = terms.iter().map(|t| t.cause).collect();
        field.fits = terms.iter().map(|t| t.fit.clone()).collect();
        (field.kernels, field.own_var) = terms.into_iter().map(|t| (t.kernels, t.var)).unzip();
        self.sweep(&mut field, vec![true; n], None);
        field
    }

    /// Bring `field` up to date after a refinement pass changed the link lists of `changed`
    /// (and made new elements). Radiosities do not change during a refinement, so only the
    /// changed and the new elements' own terms are evaluated again (whole, in list order: the
    /// same numbers as a full `error_field`), and h is refitted below them. Returns the
    /// receivers whose links must be decided again: those whose h changed with links, and
    /// the sources of their links (each holds the mirror link, which must get the same verdict).
    pub(super) fn update_error_field(&self, field: &mut ErrorField, changed: &[u32]) -> Vec<u32> {
        let n = self.hier.len();
        let old_n = field.err.len();
        let mut dirty = vec![false; n];
        dirty[old_n..].iter_mut().for_each(|d| *d = true);
        for &r in changed {
            dirty[r as usize] = true;
        }
        let todo: Vec<u32> = (0..n as u32).filter(|&r| dirty[r as usize]).collect();
        let kernels = &field.kernels;
        let terms: Vec<OwnTerms> =
            todo.par_iter().with_min_len(16).map(|&r| self.own_terms(r, kernels.get(r as usize))).collect();
        field.err.resize(n, 0.0);
        field.spread.resize(n, 0.0);
        field.cause.resize(n, f64::INFINITY);
        field.h.resize(n, [Rgb::ZERO; 4]);
        field.own_h.resize(n, [Rgb::ZERO; 4]);
        field.partial.resize(n, Rgb::ZERO);
        field.disc.resize(n, Rgb::ZERO);
        field.kernels.resize_with(n, Kernels::default);
        field.own_var.resize_with(n, Vec::new);
        field.fits.resize_with(n, CornerFit::default);
        // The listed elements whose cause did not change (their kept links' verdicts read
        // nothing else of their list).
        let mut same_cause = vec![false; n];
        for (&r, t) in todo.iter().zip(terms) {
            same_cause[r as usize] =
                (r as usize) < old_n && field.cause[r as usize].to_bits() == t.cause.to_bits();
            field.own_var[r as usize] = t.var;
            field.own_h[r as usize] = t.h;
            field.partial[r as usize] = t.partial;
            field.disc[r as usize] = t.disc;
            field.cause[r as usize] = t.cause;
            field.kernels[r as usize] = t.kernels;
            field.fits[r as usize] = t.fit;
        }
        self.sweep(field, dirty, Some(&same_cause))
    }

    /// Refit h, and recompute e and ΔB, of every element marked in `redo` and of all its
    /// descendants, top down (a parent's id is smaller than its children's). Returns the receivers to decide
    /// again (see `update_error_field`). `same_cause`: per element whose list changed, whether
    /// its cause is the same as before (None: a new field, every element is fresh).
    fn sweep(&self, field: &mut ErrorField, mut redo: Vec<bool>, same_cause: Option<&[bool]>) -> Vec<u32> {
        let hier = &self.hier;
        let n = hier.len();
        // The elements whose own lists changed (or that are new) have links to decide whatever
        // their error; the others below them only if the refit changed what a verdict reads.
        let listed = redo.clone();
        for r in 0..n {
            let e = hier.get(r as u32);
            if !redo[r] {
                if e.parent == crate::solver::hierarchy::NONE || !redo[e.parent as usize] {
                    continue;
                }
                redo[r] = true;
            }
            let own = field.own_h[r];
            field.h[r] = if e.parent == crate::solver::hierarchy::NONE {
                own
            } else {
                let p = hier.get(e.parent);
                let up = inherit(&child_points(p), p.normal, &field.h[e.parent as usize], &child_points(e));
                [up[0] + own[0], up[1] + own[1], up[2] + own[2], up[3] + own[3]]
            };
        }
        let errs: Vec<(u32, f64)> = (0..n as u32)
            .into_par_iter()
            .with_min_len(256)
            .filter(|&r| redo[r as usize])
            .map(|r| {
                let i = r as usize;
                (r, self.error_from(r, &field.h[i], field.partial[i] + field.disc[i].map(f64::abs)))
            })
            .collect();
        let eps = self.setup.bf_eps;
        field.fresh.clear();
        field.fresh.resize(n, false);
        let mut decide = super::refine::IdSet::default();
        for &(r, e) in &errs {
            let i = r as usize;
            let spread = self.element_spread(r, e);
            let (e_old, s_old) = (field.err[i], field.spread[i]);
            field.err[i] = e;
            field.spread[i] = spread;
            // A verdict reads the pair's kernels and link (fixed), the threshold and the row
            // floors (fixed during a refinement), r's cause (fixed unless its list changed, and
            // read only while e_r > ε), whether e_r > ε, and ΔB_r only through terms at most
            // ΔB_r that split when they exceed ε: if none of these changed, every link r kept
            // stays kept, and only the links the last pass put in its list (whose mirrors are
            // new in their lists too) are decided.
            let wrong = e > eps;
            let same = same_cause.is_some()
                && (e_old > eps) == wrong
                && (s_old.to_bits() == spread.to_bits() || (s_old <= eps && spread <= eps))
                && (!listed[i] || !wrong || same_cause.is_some_and(|c| c[i]));
            let own = &self.graph.links.by_receiver[r as usize];
            if same {
                if listed[i] && !own.is_empty() {
                    decide.insert(r);
                }
                continue;
            }
            field.fresh[i] = true;
            if !own.is_empty() {
                decide.insert(r);
                for l in own {
                    decide.insert(l.source);
                }
            }
        }
        decide.take_sorted()
    }

    /// The exact terms of one element's own links: their part of h, the visibility term, and
    /// the threshold `cause`. `known`: kernels of r's pairs already evaluated (sorted by source),
    /// the same numbers as evaluating them again.
    fn own_terms(&self, r: u32, known: Option<&Kernels>) -> OwnTerms {
        let e = self.hier.get(r);
        let pts = sample_points(e);
        let fit = CornerFit::of(e, &pts);
        let signed = self.setup.params.error_tail == ErrorTail::Signed;
        let mut sum = LinkTerms::default();
        let own = &self.graph.links.by_receiver[r as usize];
        let (kernels, at) = self.own_kernels(e, &pts, own, known);
        let mut c = Vec::with_capacity(own.len());
        let mut var = Vec::with_capacity(own.len());
        let mut each = Vec::with_capacity(if signed { own.len() } else { 0 });
        for (l, &k) in own.iter().zip(&at) {
            let src = self.hier.get(l.source);
            let f = kernels.values[k as usize];
            let mean = kernel_mean(&f);
            let bend_l = fit.bend(&f);
            let vb = src.radiosity * f64::from(l.vis).min(1.0);
            let mut t = LinkTerms::default();
            if vb.max_channel() > 0.0 {
                t.h = [vb * f[0], vb * f[1], vb * f[2], vb * f[3]];
                t.bend = bend_l.map(|x| vb * x);
                t.disc = vb * (galerkin(e, l) - mean);
            }
            let pen = src.radiosity * (f64::from(l.ff) * partial_weight(l));
            t.pen = if signed { pen.mul_rgb(pen) } else { pen };
            sum.add(&t);
            let cv = variation(e, src, l, &f, mean, bend_l, self.spread_weight());
            c.push(cv);
            var.push([cv, mean]);
            if signed {
                each.push((cv, t));
            }
        }
        let limit = self.setup.params.cause_tail * self.setup.bf_eps;
        let mut cause = f64::INFINITY;
        if signed {
            // The rest's own error, as e_r sums it, after the largest shares are split.
            each.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
            let mut rest = sum.clone();
            for (ck, t) in &each {
                if self.own_error(e, &rest) <= limit {
                    break;
                }
                cause = *ck;
                rest.sub(t);
            }
        } else {
            // The largest variations first, until the others add up to at most cause_tail · ε.
            c.sort_unstable_by(|a, b| b.total_cmp(a));
            let mut tail: f64 = c.iter().sum();
            for &ck in &c {
                if tail <= limit {
                    break;
                }
                cause = ck;
                tail -= ck;
            }
        }
        let partial = if signed { sum.pen.map(|x| x.max(0.0).sqrt()) } else { sum.pen };
        OwnTerms {
            h: sum.h,
            partial,
            disc: sum.disc.map(f64::abs) + sum.bend_max(),
            cause,
            kernels,
            var,
            fit,
        }
    }

    /// The error that links with the summed terms `t` make on their own at `e`, as e_r sums it
    /// (`ErrorTail::Signed`, whose penumbra terms `t.pen` are squares).
    fn own_error(&self, e: &Element, t: &LinkTerms) -> f64 {
        let pen = t.pen.map(|x| x.max(0.0).sqrt());
        self.error_of(e, &t.h, pen + t.disc.map(f64::abs) + t.bend_max())
    }

    /// The kernels of `e`'s own links `own` at its child points `pts`, sorted by source, and
    /// where each link's kernel sits in them (in list order). The kernels of `known` (sorted by
    /// source) are taken by one merge, those of new pairs evaluated: the same numbers as
    /// evaluating every one.
    fn own_kernels(
        &self,
        e: &Element,
        pts: &[DVec3; 8],
        own: &[Link],
        known: Option<&Kernels>,
    ) -> (Kernels, Vec<u32>) {
        // (source, index in the list), sorted: a pair's kernel is geometry alone, so a source
        // linked twice has one kernel, whatever the order.
        let mut keys: Vec<u64> =
            own.iter().enumerate().map(|(i, l)| (u64::from(l.source) << 32) | i as u64).collect();
        keys.sort_unstable();
        let (old_sources, old_values) = known.map_or((&[][..], &[][..]), |k| (&k.sources[..], &k.values[..]));
        let mut next = 0;
        let mut out =
            Kernels { sources: Vec::with_capacity(own.len()), values: Vec::with_capacity(own.len()) };
        let mut at = vec![0u32; own.len()];
        for (pos, key) in keys.iter().enumerate() {
            let (q, i) = ((key >> 32) as u32, (key & 0xFFFF_FFFF) as usize);
            while next < old_sources.len() && old_sources[next] < q {
                next += 1;
            }
            let f = if old_sources.get(next) == Some(&q) {
                old_values[next]
            } else {
                kernel_at(e, pts, self.hier.get(q)).0
            };
            out.sources.push(q);
            out.values.push(f);
            at[i] = pos as u32;
        }
        (out, at)
    }

    /// e_r (module docs) from h and the visibility term; 0 without own links.
    fn error_from(&self, r: u32, h: &[Rgb; 4], partial: Rgb) -> f64 {
        if self.graph.links.by_receiver[r as usize].is_empty() {
            return 0.0;
        }
        self.error_of(self.hier.get(r), h, partial)
    }

    /// e of element `e` with h at its child points and the visibility and curvature terms
    /// `partial` (module docs).
    fn error_of(&self, e: &Element, h: &[Rgb; 4], partial: Rgb) -> f64 {
        let mean = (h[0] + h[1] + h[2] + h[3]) * 0.25;
        let var = h.iter().map(|hk| hk.abs_diff_max(mean)).fold(0.0, f64::max);
        // ρ per channel: the largest channel of ρ·spread, bounded by ρ_max·spread.
        let rho = e.reflectance.max_channel();
        rho * var * self.spread_weight() + e.reflectance.mul_rgb(partial).max_channel()
    }

    /// The weight of the spread of h across an element in its error: 1 for constant leaves
    /// (every variation is wrong), [`SLOPED_SPREAD`] when the leaves carry slopes.
    fn spread_weight(&self) -> f64 {
        if self.setup.params.push_slopes { SLOPED_SPREAD } else { 1.0 }
    }

    /// ΔB of one element: the spread of its children's radiosity about its own, or its error.
    fn element_spread(&self, i: u32, err: f64) -> f64 {
        let hier = &self.hier;
        let e = hier.get(i);
        let kids = e.children().map_or(0.0, |c| {
            c.iter().map(|&k| hier.get(k).radiosity.abs_diff_max(e.radiosity)).fold(0.0, f64::max)
        });
        kids.max(err)
    }

    /// c_rq (module docs) and F̂_rq = mean_k F(x_k → q) of the link r ← q, from r's side.
    fn link_variation(&self, field: &ErrorField, r: u32, l: &Link, q: u32) -> (f64, f64) {
        let (re, qe) = (self.hier.get(r), self.hier.get(q));
        let (f, mean) = match known_kernel(&field.kernels, r, q) {
            Some(f) => (f, kernel_mean(&f)),
            None => kernel_at(re, &sample_points(re), qe),
        };
        let bend = field.fits[r as usize].bend(&f);
        (variation(re, qe, l, &f, mean, bend, self.spread_weight()), mean)
    }

    /// The error oracle's decision on the pair (r, q) seen from the link r ← q: the element to
    /// split, or why the link is kept. Symmetric: the link q ← r gets the same element.
    /// `i`: the link's index in r's list.
    pub(super) fn decide_error(
        &self,
        field: &ErrorField,
        r: u32,
        i: usize,
        link: &Link,
    ) -> Result<u32, StopReason> {
        let q = link.source;
        let (lo, hi) = if r < q { (r, q) } else { (q, r) };
        let eps = self.setup.bf_eps;
        let (elo, ehi) = (self.hier.get(lo), self.hier.get(hi));
        let v = f64::from(link.vis).clamp(0.0, 1.0);
        // Relative variation of the kernel across each side, diam / distance (capped at 1): what
        // turns a source's radiosity spread into an error at the receiver.
        let d = elo.centroid.distance(ehi.centroid);
        let across = |x: &Element| if d > 0.0 { (x.diam / d).min(1.0) } else { 1.0 };
        let (var_lo, var_hi) = (across(elo), across(ehi));
        // Side x's kernels (c_x, F̂_x) are evaluated only where a test below can pass: c_x
        // counts only if x's answer is wrong (e_x > ε), F̂_x only if ρ_x v ΔB_y bound > ε
        // (F̂ ≤ 1). Elsewhere (0, 0) gives the same verdicts at a fraction of the cost.
        let side = |x: &Element, xi: u32, yi: u32, var_y: f64| {
            let wanted = field.err[xi as usize] > eps
                || x.reflectance.max_channel() * v * field.spread[yi as usize] * var_y > eps;
            if !wanted {
                (0.0, 0.0)
            } else if xi == r {
                let [c, f] = field.own_var[r as usize][i];
                (c, f)
            } else {
                self.link_variation(field, xi, link, yi)
            }
        };
        let (c_lo, f_lo) = side(elo, lo, hi, var_hi);
        let (c_hi, f_hi) = side(ehi, hi, lo, var_lo);
        let wants_recv = |x: u32, c: f64| field.err[x as usize] > eps && c >= field.cause[x as usize];
        // Split lo when its answer is wrong because of this link, or when hi's answer is wrong
        // because lo's radiosity varies across lo.
        // A partially visible link's V is the plain average over point pairs, where the transfer
        // wants it weighted by the kernel: where the kernel varies across the source, that
        // average is off by up to 2 min(V, 1 − V) of the link's transfer (a large lamp over a
        // penumbra), and only splitting the source resolves it.
        let vw = 2.0 * v.min(1.0 - v);
        let weighted = |recv: &Element, src: &Element, var_src: f64| {
            recv.reflectance.max_channel() * galerkin(recv, link) * src.radiosity.max_channel() * vw * var_src
        };
        let split_lo = wants_recv(lo, c_lo)
            || ehi.reflectance.max_channel() * f_hi * v * field.spread[lo as usize] * var_lo > eps
            || weighted(ehi, elo, var_lo) > eps;
        let split_hi = wants_recv(hi, c_hi)
            || elo.reflectance.max_channel() * f_lo * v * field.spread[hi as usize] * var_hi > eps
            || weighted(elo, ehi, var_hi) > eps;
        let (first, second) = match (split_lo, split_hi) {
            (false, false) => return self.row_split(lo, hi, link).ok_or(StopReason::BelowErrorEps),
            (true, false) => (lo, None),
            (false, true) => (hi, None),
            (true, true) => {
                let lo_larger = super::refine::nearly_equal(elo.area, ehi.area) || elo.area > ehi.area;
                if lo_larger { (lo, Some(hi)) } else { (hi, Some(lo)) }
            }
        };
        match self.can_split(self.hier.get(first)) {
            Ok(()) => Ok(first),
            Err(why) => {
                match second.or(self.setup.params.split_fallback.then_some(if first == lo { hi } else { lo }))
                {
                    Some(s) if self.can_split(self.hier.get(s)).is_ok() => Ok(s),
                    _ => Err(why),
                }
            }
        }
    }
}
