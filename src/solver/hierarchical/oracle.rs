//! The error-driven oracle: refine where a receiver's answer is wrong, not where much light flows.
//!
//! A constant element holds one value of the gathered irradiance H over its area. What is wrong
//! with that is how much the *total* irradiance, from all its links (its own and those it
//! inherits from its ancestors), varies across it. At the four points x_k where splitting would
//! put its children's centroids:
//!
//! ```text
//! h(x_k) = Σ_{links a ← q, a = r or an ancestor} F(x_k → q) V_aq B_q        (exact point kernel)
//! e_r    = ρ_r · max_k |h(x_k) − mean_k h(x_k)|  +  ρ_r Σ_{own partial links} 2 min(V, 1 − V) F_rq B_q
//! ```
//!
//! (largest RGB channel). The first term is the receiver's variation of the total — a link
//! whose contribution is uniform across r, or whose variation the other links cancel (in the
//! white furnace Σ_q F(x → q) = 1 at every point), adds nothing, however much power it carries
//! [Lischinski, Smits & Greenberg 1994, "Bounds and error estimates for radiosity", §4: the
//! error of a constant element is bounded by the spread of its gathered radiosity across it].
//! The second is the uncertainty of partially visible links, whose visibility varies across the
//! receiver in a way the link's average V hides (where the shadows are) [Holzschuch & Sillion
//! 1998, "An exhaustive error-bounding algorithm for hierarchical radiosity", §3.2: the
//! visibility term of a link's bound].
//!
//! A link r ← q is split on the receiver's side when r's answer is wrong (e_r > ε) and the link
//! is one of its causes: its own variation across r, c_rq = ρ_r V B_q max_k |F(x_k → q) − mean|
//! (+ its visibility term), is at least e_r / (1 + n_r), n_r the number of r's own links (so one
//! of them always qualifies when the own links make the error). It is split on the source's
//! side when q's radiosity varies (ΔB_q: q's own e_q, or the spread of its children's B) enough
//! to matter through the kernel's variation across the pair: ρ_r F_rq V ΔB_q (diam_r + diam_q)
//! / distance > ε [Holzschuch & Sillion 1998, §3.1, the source-radiosity term]. Every decision
//! is taken for the pair (both directions, the larger element first when both ask), from
//! quantities both sides compute alike, so a link and its mirror always agree and the links
//! stay mirror images (energy conservation, see `transfer`).
//!
//! ε is `bf_eps` (absolute, or relative to the largest emission). Refinement stops at the Aeps
//! floor and the maximum depth, as with the other oracles.

use super::HierarchicalSolver;
use crate::form_factor;
use crate::hierarchy::{Element, StopReason};
use crate::link::Link;
use crate::math::{DVec3, Rgb};
use rayon::prelude::*;

/// Per-element inputs of the error oracle, computed once per refinement and updated pass by pass.
#[derive(Default)]
pub(super) struct ErrorField {
    /// e_r: the receiver's error (module docs); 0 for an element without own links.
    pub err: Vec<f64>,
    /// ΔB: how much the element's radiosity varies across it.
    pub spread: Vec<f64>,
    /// Number of own links.
    pub own: Vec<u32>,
    /// h(x_k) at the element's four child points, over its own and its ancestors' links.
    h: Vec<[Rgb; 4]>,
    /// ρ-less visibility term Σ_{own partial links} 2 min(V, 1 − V) F B.
    partial: Vec<Rgb>,
}

/// How one receiver's link list changed in a refinement pass: the links removed, the links added.
pub(super) type ListDelta = (u32, Vec<Link>, Vec<Link>);

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

/// F(x_k → q) at the four child points of `r`, and their mean.
fn kernel_at(r: &Element, pts: &[DVec3; 4], q: &Element) -> ([f64; 4], f64) {
    let mut f = [0.0; 4];
    for (fk, x) in f.iter_mut().zip(pts) {
        *fk = form_factor::point_to_polygon_oriented(*x, r.normal, q.vertices(), q.normal);
    }
    let mean = 0.25 * (f[0] + f[1] + f[2] + f[3]);
    (f, mean)
}

/// The visibility term's weight 2 min(V, 1 − V) of a link (0 when fully visible or hidden).
fn partial_weight(l: &Link) -> f64 {
    let v = f64::from(l.vis).clamp(0.0, 1.0);
    2.0 * v.min(1.0 - v)
}

impl HierarchicalSolver {
    /// The error field of the current state (parallel over elements, deterministic).
    pub(super) fn error_field(&self) -> ErrorField {
        let n = self.hier.len();
        let hp: Vec<([Rgb; 4], Rgb)> =
            (0..n as u32).into_par_iter().with_min_len(64).map(|r| self.element_h(r)).collect();
        let (h, partial): (Vec<[Rgb; 4]>, Vec<Rgb>) = hp.into_iter().unzip();
        let err: Vec<f64> = (0..n).map(|r| self.error_from(r as u32, &h[r], partial[r])).collect();
        let spread: Vec<f64> =
            (0..n).into_par_iter().with_min_len(256).map(|i| self.element_spread(i as u32, err[i])).collect();
        let own = self.links.by_receiver.iter().map(|l| l.len() as u32).collect();
        ErrorField { err, spread, own, h, partial }
    }

    /// Bring `field` up to date after a refinement pass changed link lists as `deltas` says
    /// (and made new elements). An element's h changes by the contributions of the links added
    /// to or removed from its own or an ancestor's list (radiosities do not change during a
    /// refinement), so only those are evaluated; new elements are evaluated whole. Returns the
    /// receivers whose links must be decided again: the changed ones with links, and the
    /// sources of their links (each holds the mirror link, which must get the same verdict).
    pub(super) fn update_error_field(&self, field: &mut ErrorField, deltas: &[ListDelta]) -> Vec<u32> {
        let hier = &self.hier;
        let n = hier.len();
        let old_n = field.err.len();
        // The deltas by receiver (a receiver may have two: its own list replaced, then links
        // pushed down to it as a child); `delta_of[a]`: where a's run starts in `order`.
        let mut order: Vec<u32> = (0..deltas.len() as u32).collect();
        order.sort_by_key(|&k| deltas[k as usize].0);
        let mut delta_of = vec![u32::MAX; n];
        for (i, &k) in order.iter().enumerate().rev() {
            delta_of[deltas[k as usize].0 as usize] = i as u32;
        }
        let fresh: Vec<Option<([Rgb; 4], Rgb)>> = (0..n as u32)
            .into_par_iter()
            .with_min_len(64)
            .map(|e| {
                if e as usize >= old_n {
                    return Some(self.element_h(e));
                }
                let mut touched = false;
                let (mut h, mut partial) = (field.h[e as usize], field.partial[e as usize]);
                let el = hier.get(e);
                let pts = child_points(el);
                for a in hier.ancestors(e) {
                    if delta_of[a as usize] == u32::MAX {
                        continue;
                    }
                    for &k in &order[delta_of[a as usize] as usize..] {
                        let (da, removed, added) = &deltas[k as usize];
                        if *da != a {
                            break;
                        }
                        touched = true;
                        for (ls, sign) in [(removed, -1.0), (added, 1.0)] {
                            for l in ls {
                                let (c, p) = self.link_terms(el, &pts, l, a == e);
                                for (hk, ck) in h.iter_mut().zip(c) {
                                    *hk += ck * sign;
                                }
                                partial += p * sign;
                            }
                        }
                    }
                }
                touched.then_some((h, partial))
            })
            .collect();
        field.err.resize(n, 0.0);
        field.spread.resize(n, 0.0);
        field.own.resize(n, 0);
        field.h.resize(n, [Rgb::ZERO; 4]);
        field.partial.resize(n, Rgb::ZERO);
        let mut decide = super::IdSet::default();
        for (r, f) in fresh.into_iter().enumerate() {
            let Some((h, partial)) = f else { continue };
            field.h[r] = h;
            field.partial[r] = partial;
            let e = self.error_from(r as u32, &h, partial);
            field.err[r] = e;
            field.spread[r] = self.element_spread(r as u32, e);
            let own = &self.links.by_receiver[r];
            field.own[r] = own.len() as u32;
            if !own.is_empty() {
                decide.insert(r as u32);
                for l in own {
                    decide.insert(l.source);
                }
            }
        }
        decide.take_sorted()
    }

    /// Link `l`'s contribution to h at the child points `pts` of `e`, and (when `own`: the
    /// link is `e`'s own) its visibility term.
    fn link_terms(&self, e: &Element, pts: &[DVec3; 4], l: &Link, own: bool) -> ([Rgb; 4], Rgb) {
        let src = self.hier.get(l.source);
        let mut c = [Rgb::ZERO; 4];
        let vb = src.radiosity * f64::from(l.vis).min(1.0);
        if vb.max_channel() > 0.0 {
            let (f, _) = kernel_at(e, pts, src);
            for (ck, fk) in c.iter_mut().zip(f) {
                *ck = vb * fk;
            }
        }
        let p = if own { src.radiosity * (f64::from(l.ff) * partial_weight(l)) } else { Rgb::ZERO };
        (c, p)
    }

    /// h and the visibility term of one element, from all its own and inherited links.
    fn element_h(&self, r: u32) -> ([Rgb; 4], Rgb) {
        let hier = &self.hier;
        let e = hier.get(r);
        let pts = child_points(e);
        let mut h = [Rgb::ZERO; 4];
        let mut partial = Rgb::ZERO;
        for a in hier.ancestors(r) {
            for l in &self.links.by_receiver[a as usize] {
                let (c, p) = self.link_terms(e, &pts, l, a == r);
                for (hk, ck) in h.iter_mut().zip(c) {
                    *hk += ck;
                }
                partial += p;
            }
        }
        (h, partial)
    }

    /// e_r (module docs) from h and the visibility term; 0 without own links.
    fn error_from(&self, r: u32, h: &[Rgb; 4], partial: Rgb) -> f64 {
        if self.links.by_receiver[r as usize].is_empty() {
            return 0.0;
        }
        let e = self.hier.get(r);
        let mean = (h[0] + h[1] + h[2] + h[3]) * 0.25;
        let var = h.iter().map(|hk| hk.abs_diff_max(mean)).fold(0.0, f64::max);
        // ρ per channel: the largest channel of ρ·spread, bounded by ρ_max·spread.
        let rho = e.reflectance.max_channel();
        rho * var + e.reflectance.mul_rgb(partial).max_channel()
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
    fn link_variation(&self, r: u32, l_vis: f32, q: u32) -> (f64, f64) {
        let (re, qe) = (self.hier.get(r), self.hier.get(q));
        let (f, mean) = kernel_at(re, &child_points(re), qe);
        let v = f64::from(l_vis).clamp(0.0, 1.0);
        let vw = 2.0 * v.min(1.0 - v);
        let b = qe.radiosity.max_channel();
        let spread = f.iter().map(|fk| (fk - mean).abs()).fold(0.0, f64::max);
        let rho = re.reflectance.max_channel();
        (rho * b * (v * spread + vw * mean), mean)
    }

    /// The error oracle's decision on the pair (r, q) seen from the link r ← q: the element to
    /// split, or why the link is kept. Symmetric: the link q ← r gets the same element.
    pub(super) fn decide_error(&self, field: &ErrorField, r: u32, link: &Link) -> Result<u32, StopReason> {
        let q = link.source;
        let (lo, hi) = if r < q { (r, q) } else { (q, r) };
        let eps = self.bf_eps;
        let (elo, ehi) = (self.hier.get(lo), self.hier.get(hi));
        let v = f64::from(link.vis).clamp(0.0, 1.0);
        let bound = super::geometric_variation(elo, ehi);
        // Side x's kernels (c_x, F̂_x) are evaluated only where a test below can pass: c_x
        // counts only if x's answer is wrong (e_x > ε), F̂_x only if ρ_x v ΔB_y bound > ε
        // (F̂ ≤ 1). Elsewhere (0, 0) gives the same verdicts at a fraction of the cost.
        let side = |x: &Element, xi: u32, yi: u32| {
            let wanted = field.err[xi as usize] > eps
                || x.reflectance.max_channel() * v * field.spread[yi as usize] * bound > eps;
            if wanted { self.link_variation(xi, link.vis, yi) } else { (0.0, 0.0) }
        };
        let (c_lo, f_lo) = side(elo, lo, hi);
        let (c_hi, f_hi) = side(ehi, hi, lo);
        let wants_recv = |x: u32, c: f64| {
            let e = field.err[x as usize];
            e > eps && c >= e / (1.0 + f64::from(field.own[x as usize]))
        };
        // Split lo when its answer is wrong because of this link, or when hi's answer is wrong
        // because lo's radiosity varies across lo.
        let split_lo = wants_recv(lo, c_lo)
            || ehi.reflectance.max_channel() * f_hi * v * field.spread[lo as usize] * bound > eps;
        let split_hi = wants_recv(hi, c_hi)
            || elo.reflectance.max_channel() * f_lo * v * field.spread[hi as usize] * bound > eps;
        let (first, second) = match (split_lo, split_hi) {
            (false, false) => return Err(StopReason::BelowErrorEps),
            (true, false) => (lo, None),
            (false, true) => (hi, None),
            (true, true) => {
                let lo_larger = super::nearly_equal(elo.area, ehi.area) || elo.area > ehi.area;
                if lo_larger { (lo, Some(hi)) } else { (hi, Some(lo)) }
            }
        };
        match self.can_split(self.hier.get(first)) {
            Ok(()) => Ok(first),
            Err(why) => {
                match second.or(self.params.split_fallback.then_some(if first == lo { hi } else { lo })) {
                    Some(s) if self.can_split(self.hier.get(s)).is_ok() => Ok(s),
                    _ => Err(why),
                }
            }
        }
    }
}
