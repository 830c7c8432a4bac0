//! Gather (HSA91, sec. 4): every receiver sums, over its own links, what its sources send, in
//! parallel (Jacobi):
//!
//! ```text
//! gathered_p = Σ_{links p ← q} F_pq V_pq B_q  (+ with slopes, (A_q/A_p) src_slope_pq · M_q)
//! ```
//! F_pq V_pq is fixed between refinements, so the links are flattened once into a
//! [`GatherPlan`]; ancestors' links reach the leaves in [`super::push_pull`].

use super::closure::Closure;
use super::parts::{ClusterIrradiance, GatherState};
use super::push_pull::{Chain, fill_slopes, push_pull_rec};
use super::{HierarchicalSolver, StepKind, StepReport, disjoint_mut};
use crate::math::Rgb;
use crate::solver::hierarchy::{Element, Hierarchy};
use crate::solver::link::{Link, LinkStore};
use rayon::prelude::*;
use std::sync::atomic::Ordering;
use std::time::Instant;

/// Every receiver's links with F·V > 0, flattened for gathering (links do not change between
/// refinements): source (high bit set when fully visible) and weight F·V, in list order.
///
/// After a refinement only the receivers whose lists changed get new entries, appended at the
/// end ([`GatherPlan::update`]); their old entries stay behind unused until they outweigh the
/// used ones, and then the plan is rebuilt whole: rebuilding it after every round would read
/// every link each time.
#[derive(Debug, Default)]
pub(super) struct GatherPlan {
    /// Receiver r's links are `start[r]..end[r]`.
    start: Vec<u32>,
    end: Vec<u32>,
    /// Entries in use (the others belong to lists replaced since the last rebuild).
    live: usize,
    source: Vec<u32>,
    weight: Vec<f64>,
    /// Each link's `slope` (empty when slopes are not pushed).
    slope: Vec<[f32; 2]>,
    /// Each link's moment weight (A_source / A_receiver)·`src_slope` (empty likewise).
    moment: Vec<[f32; 2]>,
}

pub(super) const FULL_BIT: u32 = 1 << 31;

/// One block of receivers' part of a [`GatherPlan`] while it is rebuilt: each receiver's count
/// of links, and the links' entries.
#[derive(Default)]
struct PlanBlock {
    counts: Vec<u32>,
    source: Vec<u32>,
    weight: Vec<f64>,
    slope: Vec<[f32; 2]>,
    moment: Vec<[f32; 2]>,
}

impl PlanBlock {
    /// The entries of receivers `ids` (in that order): their links with F·V > 0.
    fn of(lists: &[Vec<Link>], ids: impl Iterator<Item = usize>, slopes: Option<&Hierarchy>) -> Self {
        let mut b = PlanBlock { counts: Vec::with_capacity(ids.size_hint().0), ..PlanBlock::default() };
        for r in ids {
            let before = b.source.len();
            for l in &lists[r] {
                let wl = f64::from(l.ff) * f64::from(l.vis);
                if wl > 0.0 {
                    debug_assert!(l.source < FULL_BIT, "element ids stay below 2^31");
                    b.source.push(l.source | if l.vis >= 1.0 { FULL_BIT } else { 0 });
                    b.weight.push(wl);
                    if let Some(hier) = slopes {
                        debug_assert!(l.slope_set, "slopes are filled before the plan");
                        b.slope.push(l.slope);
                        let ratio = hier.get(l.source).area / hier.get(r as u32).area;
                        b.moment.push(l.src_slope.map(|x| (f64::from(x) * ratio) as f32));
                    }
                }
            }
            b.counts.push((b.source.len() - before) as u32);
        }
        b
    }
}

/// Receivers per block when the gather plan is built in parallel.
pub(super) const PLAN_BLOCK: usize = 256;

impl GatherPlan {
    /// Rebuild the plan from `links`, reusing its buffers. Built in parallel over blocks of
    /// receivers: each block flattens its receivers' links once into its own buffers (the link
    /// lists are scattered over the heap, so every pass over them waits on memory, and counting
    /// first and filling after would take two), then the blocks
    /// are copied into place side by side. The same arrays as a serial pass in receiver order.
    fn rebuild(&mut self, links: &LinkStore, slopes: Option<&Hierarchy>) {
        let lists = &links.by_receiver;
        let blocks: Vec<PlanBlock> = lists
            .par_chunks(PLAN_BLOCK)
            .enumerate()
            .map(|(k, block)| PlanBlock::of(lists, k * PLAN_BLOCK..k * PLAN_BLOCK + block.len(), slopes))
            .collect();
        self.start.clear();
        self.end.clear();
        let mut total = 0u32;
        for b in &blocks {
            for &c in &b.counts {
                self.start.push(total);
                total += c;
                self.end.push(total);
            }
        }
        self.live = total as usize;
        self.source.resize(total as usize, 0);
        self.weight.resize(total as usize, 0.0);
        let n_slopes = if slopes.is_some() { total as usize } else { 0 };
        self.slope.clear();
        self.slope.resize(n_slopes, [0.0; 2]);
        self.moment.clear();
        self.moment.resize(n_slopes, [0.0; 2]);
        // Disjoint output ranges, one per block of receivers.
        let (mut source, mut weights) = (&mut self.source[..], &mut self.weight[..]);
        let (mut slope, mut moment) = (&mut self.slope[..], &mut self.moment[..]);
        let mut out = Vec::with_capacity(blocks.len());
        for b in &blocks {
            let (len, len_s) = (b.source.len(), b.slope.len());
            let (s, s_rest) = std::mem::take(&mut source).split_at_mut(len);
            let (w, w_rest) = std::mem::take(&mut weights).split_at_mut(len);
            let (g, g_rest) = std::mem::take(&mut slope).split_at_mut(len_s);
            let (m, m_rest) = std::mem::take(&mut moment).split_at_mut(len_s);
            (source, weights, slope, moment) = (s_rest, w_rest, g_rest, m_rest);
            out.push((b, s, w, g, m));
        }
        out.into_par_iter().for_each(|(b, s, w, g, m)| {
            s.copy_from_slice(&b.source);
            w.copy_from_slice(&b.weight);
            g.copy_from_slice(&b.slope);
            m.copy_from_slice(&b.moment);
        });
    }

    /// Replace the entries of the receivers `changed` (sorted, distinct) by their lists' now,
    /// appended at the end; elements new since the last update start with none. Rebuilds the
    /// whole plan instead when the unused entries would outnumber the used ones.
    fn update(&mut self, links: &LinkStore, slopes: Option<&Hierarchy>, changed: &[u32]) {
        let lists = &links.by_receiver;
        let n = lists.len();
        let old: usize = changed
            .iter()
            .filter(|&&r| (r as usize) < self.start.len())
            .map(|&r| (self.end[r as usize] - self.start[r as usize]) as usize)
            .sum();
        let added: usize = changed.iter().map(|&r| lists[r as usize].len()).sum();
        let live = self.live - old;
        if self.source.len() + added > 2 * (live + added) + (1 << 16)
            || self.source.len() + added >= FULL_BIT as usize
        {
            self.rebuild(links, slopes);
            return;
        }
        self.start.resize(n, 0);
        self.end.resize(n, 0);
        let blocks: Vec<PlanBlock> = changed
            .par_chunks(PLAN_BLOCK)
            .map(|ids| PlanBlock::of(lists, ids.iter().map(|&r| r as usize), slopes))
            .collect();
        let mut at = self.source.len() as u32;
        let mut live = live;
        for (ids, b) in changed.chunks(PLAN_BLOCK).zip(&blocks) {
            for (&r, &c) in ids.iter().zip(&b.counts) {
                self.start[r as usize] = at;
                at += c;
                self.end[r as usize] = at;
                live += c as usize;
            }
            self.source.extend_from_slice(&b.source);
            self.weight.extend_from_slice(&b.weight);
            self.slope.extend_from_slice(&b.slope);
            self.moment.extend_from_slice(&b.moment);
        }
        self.live = live;
    }

    /// Debug check: every receiver has the same entries in `self` (updated) as in `whole`
    /// (rebuilt).
    #[cfg(debug_assertions)]
    fn assert_same(&self, whole: &GatherPlan) {
        assert_eq!(self.start.len(), whole.start.len(), "the plan covers every element");
        for r in 0..whole.start.len() {
            let (a, b) = (
                self.start[r] as usize..self.end[r] as usize,
                whole.start[r] as usize..whole.end[r] as usize,
            );
            assert_eq!(self.source[a.clone()], whole.source[b.clone()], "receiver {r}'s sources");
            assert_eq!(self.weight[a.clone()], whole.weight[b.clone()], "receiver {r}'s weights");
            if !whole.slope.is_empty() {
                assert_eq!(self.slope[a.clone()], whole.slope[b.clone()], "receiver {r}'s slopes");
                assert_eq!(self.moment[a], whole.moment[b], "receiver {r}'s moments");
            }
        }
    }

    /// (Σ F·V·B + moment terms over receiver `r`'s links, the same over the fully visible ones
    /// without moments, Σ slope·B), in list order, with source radiosities `b` and the sources'
    /// radiosity moments `mu` (in each source's tangent basis; empty: none).
    fn gather(&self, r: usize, b: impl Fn(u32) -> Rgb, mu: &[[Rgb; 2]]) -> (Rgb, Rgb, [Rgb; 2]) {
        let (lo, hi) = (self.start[r] as usize, self.end[r] as usize);
        let mut g = Rgb::ZERO;
        let mut full = Rgb::ZERO;
        let mut slope = [Rgb::ZERO; 2];
        for (&s, &w) in self.source[lo..hi].iter().zip(&self.weight[lo..hi]) {
            let t = b(s & !FULL_BIT) * w;
            g += t;
            if s & FULL_BIT != 0 {
                full += t;
            }
        }
        if !self.slope.is_empty() {
            for (&s, &[gu, gv]) in self.source[lo..hi].iter().zip(&self.slope[lo..hi]) {
                let bs = b(s & !FULL_BIT);
                slope[0] += bs * f64::from(gu);
                slope[1] += bs * f64::from(gv);
            }
            if !mu.is_empty() {
                for (&s, &[mu_w, mv_w]) in self.source[lo..hi].iter().zip(&self.moment[lo..hi]) {
                    // Elements made since the last push-pull have no moment yet (none: 0).
                    if let Some(&[mu_u, mu_v]) = mu.get((s & !FULL_BIT) as usize) {
                        g += mu_u * f64::from(mu_w) + mu_v * f64::from(mv_w);
                    }
                }
            }
        }
        (g, full, slope)
    }
}

impl GatherPlan {
    /// [`GatherPlan::gather`] of one number per source (`v` by element id, its sources' first
    /// moments `mu`): (Σ F·V v plus the moment terms, Σ slope·v), the same sums in the same
    /// order. Receivers new since the plan was made have no entries (0).
    pub(super) fn gather_scalar(&self, r: usize, v: &[f64], mu: &[[f64; 2]]) -> (f64, [f64; 2]) {
        if r >= self.start.len() {
            return (0.0, [0.0; 2]);
        }
        let (lo, hi) = (self.start[r] as usize, self.end[r] as usize);
        let mut g = 0.0;
        let mut slope = [0.0; 2];
        for (&s, &w) in self.source[lo..hi].iter().zip(&self.weight[lo..hi]) {
            g += v[(s & !FULL_BIT) as usize] * w;
        }
        if !self.slope.is_empty() {
            for (&s, &[gu, gv]) in self.source[lo..hi].iter().zip(&self.slope[lo..hi]) {
                let vs = v[(s & !FULL_BIT) as usize];
                slope[0] += vs * f64::from(gu);
                slope[1] += vs * f64::from(gv);
            }
            for (&s, &[mu_w, mv_w]) in self.source[lo..hi].iter().zip(&self.moment[lo..hi]) {
                if let Some(&[mu_u, mu_v]) = mu.get((s & !FULL_BIT) as usize) {
                    g += mu_u * f64::from(mu_w) + mu_v * f64::from(mv_w);
                }
            }
        }
        (g, slope)
    }
}

/// Recompute Σ F and Σ F·V of every receiver of `hier` whose link list changed since the last
/// call (`changed`); input patches' rows include what they gather through cluster links
/// (`cluster_fv`).
pub(super) fn update_sums(hier: &mut Hierarchy, links: &LinkStore, cluster_fv: &[f64], changed: &[u32]) {
    let links = &links.by_receiver;
    disjoint_mut(&mut hier.elements, changed.iter().copied())
        .into_par_iter()
        .zip(changed.par_iter())
        .with_min_len(256)
        .for_each(|(e, &r)| {
            let ls = &links[r as usize];
            e.f_sum = ls.iter().filter(|l| l.vis >= 1.0).map(|l| f64::from(l.ff)).sum();
            e.fv_sum = ls.iter().map(|l| f64::from(l.ff) * f64::from(l.vis)).sum();
            e.fv_partial = e.fv_sum - e.f_sum;
        });
    for &r in changed {
        if let Some(&fv) = cluster_fv.get(r as usize) {
            let e = &mut hier.elements[r as usize];
            e.fv_sum += fv;
            e.fv_partial += fv;
        }
    }
}

impl GatherState {
    /// Have the links changed since the plan was made?
    pub(super) fn links_changed(&self) -> bool {
        !self.plan_valid || !self.plan_changed.is_empty()
    }

    /// Bring the plan up to date with `links`: the changed receivers' entries, or the whole plan
    /// when it is not valid. `slopes`: the mesh, when the links' slopes are gathered.
    pub(super) fn sync_plan(&mut self, links: &LinkStore, slopes: Option<&Hierarchy>) {
        if self.plan_valid {
            let mut changed = std::mem::take(&mut self.plan_changed);
            changed.sort_unstable();
            changed.dedup();
            self.plan.update(links, slopes, &changed);
            #[cfg(debug_assertions)]
            {
                let mut whole = GatherPlan::default();
                whole.rebuild(links, slopes);
                self.plan.assert_same(&whole);
            }
        } else {
            self.plan.rebuild(links, slopes);
        }
        self.plan_valid = true;
        self.plan_changed.clear();
    }

    /// One Jacobi gather: every element of `els` sums, in parallel, what its sources sent
    /// before it (their radiosity and first `moment`, or with the rows closed what the
    /// `closure` has them send).
    pub(super) fn jacobi(&mut self, els: &mut [Element], closure: &Closure, moment: &[[Rgb; 2]]) {
        // Sources' radiosity in a compact array (read once per link, in any order).
        let mut b = std::mem::take(&mut self.b_prev);
        b.resize(els.len(), Rgb::ZERO);
        if closure.active() {
            b.copy_from_slice(&closure.sent);
        } else {
            b.par_iter_mut().zip(els.par_iter()).with_min_len(1024).for_each(|(b, e)| *b = e.radiosity);
        }
        let mu = if closure.active() { &closure.sent_moment } else { moment };
        let plan = &self.plan;
        els.par_iter_mut().enumerate().with_min_len(256).for_each(|(r, e)| {
            (e.gathered, e.gathered_full, e.gathered_slope) = plan.gather(r, |s| b[s as usize], mu);
        });
        self.b_prev = b;
    }

    /// One Gauss–Seidel sweep: input patch by input patch, its elements gather from the newest
    /// radiosities (and `moment`), its cluster irradiance is added, and it is pushed and pulled
    /// at once (`push_slopes`: with the links' slopes).
    pub(super) fn gauss_seidel(
        &self,
        hier: &mut Hierarchy,
        moment: &[[Rgb; 2]],
        cluster_h: Option<&ClusterIrradiance>,
        push_slopes: bool,
    ) {
        for root in 0..hier.roots as u32 {
            let ids = subtree(hier, root);
            let g: Vec<(Rgb, Rgb, [Rgb; 2])> = ids
                .iter()
                .map(|&r| self.plan.gather(r as usize, |s| hier.get(s).radiosity, moment))
                .collect();
            for (&r, (g, full, slope)) in ids.iter().zip(g) {
                let e = &mut hier.elements[r as usize];
                (e.gathered, e.gathered_full, e.gathered_slope) = (g, full, slope);
            }
            if let Some((h, slopes)) = cluster_h {
                let e = &mut hier.elements[root as usize];
                e.gathered += h[root as usize];
                if let Some(s) = slopes.get(root as usize) {
                    add_slope(&mut e.gathered_slope, *s);
                }
            }
            push_pull_rec(&mut hier.elements, root, Chain::default(), push_slopes);
        }
    }
}

impl HierarchicalSolver {
    /// One gather over every link (the lecture's `Gather`), Jacobi: every receiver reads the
    /// radiosities of the previous iteration. With `gauss_seidel`, gathers and pushes patch by
    /// patch instead, each patch using the newest values (then push-pull is already done).
    pub fn gather_step(&mut self) -> StepReport {
        self.setup.cancel.store(false, Ordering::Relaxed);
        self.gather_inner()
    }

    pub(super) fn gather_inner(&mut self) -> StepReport {
        let t = Instant::now();
        let params = self.setup.params;
        // The links as one contiguous plan, brought up to date after they change.
        let links_changed = self.gather.links_changed();
        if links_changed {
            if params.push_slopes {
                // At most 16 rays a point: the slope reads a ramp, not a fraction to a percent.
                let vis = params.vis_slopes.then(|| super::push_pull::VisSlopes {
                    accel: &self.setup.accel,
                    seed: params.seed,
                    rays: params.rays.min(16),
                    floor: params.cause_tail * self.setup.bf_eps,
                });
                let cast = fill_slopes(
                    &mut self.hier,
                    &mut self.graph.links,
                    &self.oracle.error_kernels,
                    vis.as_ref(),
                );
                self.log.stats.rays += cast;
            }
            self.gather.sync_plan(&self.graph.links, params.push_slopes.then_some(&self.hier));
        }
        // Closed rows: balance the enclosed leaves' rows for these links, and what every element
        // sends (`closure`).
        if self.closure_applies() {
            let (setup, closure, els) = (&self.setup, &mut self.closure, &self.hier.elements);
            if links_changed || !closure.balanced {
                closure.prepare(&setup.scene, &setup.accel, params.seed);
                closure.balance_rows(els, &params, &self.gather.plan);
            }
            if closure.active() {
                closure.pull_sent(els, params.push_slopes);
            }
        }
        // What the input patches gather through cluster links, from the radiosities before
        // this gather (both sweeps).
        let cluster_h = self.cluster.irradiance(&self.hier, params.push_slopes);
        if params.gauss_seidel {
            let before: Vec<Rgb> = self.hier.elements.iter().map(|e| e.radiosity).collect();
            self.gather.gauss_seidel(
                &mut self.hier,
                &self.push_pull.moment,
                cluster_h.as_ref(),
                params.push_slopes,
            );
            // Recomputes the same leaf values (nothing was gathered since each root's push) and
            // measures the change against the values before the sweep.
            self.push_pull_flat(Some(&before), true);
        } else {
            self.gather.jacobi(&mut self.hier.elements, &self.closure, &self.push_pull.moment);
            if let Some((h, slopes)) = &cluster_h {
                for (e, h) in self.hier.elements.iter_mut().zip(h) {
                    e.gathered += *h;
                }
                // Empty without `push_slopes`.
                for (e, s) in self.hier.elements.iter_mut().zip(slopes) {
                    add_slope(&mut e.gathered_slope, *s);
                }
            }
        }
        self.log.stats.gather_s += t.elapsed().as_secs_f64();
        self.log.gathered_once = true;
        self.log.stats.iterations += 1;
        self.report(StepKind::Gather, t, 0, 0)
    }
}

/// The ids of `root`'s subtree in `hier`, depth first.
pub(super) fn subtree(hier: &Hierarchy, root: u32) -> Vec<u32> {
    let mut out = Vec::new();
    let mut stack = vec![root];
    while let Some(id) = stack.pop() {
        out.push(id);
        if let Some(c) = hier.get(id).children() {
            stack.extend(c.iter().rev());
        }
    }
    out
}

/// Add a patch's cluster-link slope ([`cluster::ClusterTransfer::slopes`]) to its root
/// element's gathered slope (the same tangent basis: the patch's normal).
fn add_slope(slope: &mut [Rgb; 2], add: [Rgb; 2]) {
    slope[0] += add[0];
    slope[1] += add[1];
}
