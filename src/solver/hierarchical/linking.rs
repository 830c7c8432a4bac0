//! The first links: every pair of input patches that face each other and are not fully
//! occluded (HSA91's initial linking, O(k²) in the k input patches), or, with clustering
//! (Smits, Arvo & Greenberg 1994; Sillion 1995), links between the clusters of a hierarchy built
//! from the BVH, pushed down to patch pairs only where the cluster bound exceeds the threshold:
//!
//! ```text
//! Link(A, B) if Accept(A, B) else for each child c of the larger of A, B: Link(c, other)
//! ```
//! The cluster tree and its transfer are in [`super::cluster`].

use super::cluster::{ClusterLink, ClusterTransfer, ClusterTree, Pairing};
use super::refine::{new_link, pair_key, pair_sides};
use super::{
    ClusterEnd, ClusterInfo, ClusterLinkView, HierarchicalSolver, ROOT_CONFIRM_RAYS, cluster, transfer,
};
use crate::geometry::accel::NO_HIT;
use crate::geometry::visibility::{self, Stop};
use crate::math::newell_normal;
use crate::solver::link::Link;
use crate::solver::params::Oracle;
use rayon::prelude::*;
use std::sync::Arc;
use std::time::Instant;

/// Cached initial links: ((rays, seed, conservative, weighted), links per root receiver, pairs skipped).
pub(super) type InitialLinks = ((u32, u64, bool, bool), Vec<Vec<Link>>, usize);

/// What `install_chunk` makes of one pairing: a cluster link, or a patch pair's two links
/// (none when the pair is skipped), and the rays cast.
pub(super) type Made = (Option<ClusterLink>, Option<(u32, u32, Link, Link)>, u64);
/// One patch's row of initial links: (q, link p ← q, link q ← p) for q > p, pairs skipped, rays.
pub(super) type PairRow = (Vec<(u32, Link, Link)>, usize, u64);

/// Pairings made (in parallel) and installed at a time by `install_chunk`.
const INSTALL_CHUNK: usize = 1 << 16;

/// The couplings of the patch pairs a clustered scene links one by one are integrated to this
/// many times `link_tol` (relative; `interactive`: 1e-2 instead of 1e-3).
///
/// Why looser than element links: these pairs are neighbouring small pieces (a leg on the
/// floor, books side by side), most of them touching or nearly so, where the adaptive
/// cubature's cost grows fast with the tolerance. Their error is not what limits the solve: the
/// cluster links beside them carry a point approximation good to a few percent and 4-ray
/// visibility, and the rooms that reach the link budget keep one value per patch, so a coupling
/// 1 % off moves the answer by far less than that. Chosen by measurement, see
/// docs/scale.md#clustering. Presets with one-point couplings (`link_tol` 0) keep one point.
const CLUSTERED_PAIR_TOL_FACTOR: f64 = 10.0;

/// With the error oracle, a cluster link is accepted only while its bound is below this share
/// of ε (the BF oracle keeps SPLASH-2's whole BFeps).
///
/// Why: ε bounds the error of what a receiver gathers, and a node gathers through many cluster
/// links (tens on the furnished rooms), each tested alone; the bound has no term for what a
/// cluster link cannot see (its visibility is one estimate for all members, so a patch behind
/// a shelf gathers what the open ones do). Subdividing the failing links as clusters does not
/// help; what helps is reaching patch pairs sooner, whose element links have their own rays and
/// the oracle's refinement. Every share below 1 beats finer thresholds at share 1. Chosen by
/// measurement on furnished-10k, see docs/scale.md#accuracy-on-the-furnished-rooms.
pub(super) const ERROR_CLUSTER_SHARE: f64 = 0.03;

/// Failing cluster links subdivided at a time.
const CLUSTER_REFINE_CHUNK: usize = 1024;

/// Links being installed (`install_start` … `install_finish`).
struct Installing {
    lists: Vec<Vec<Link>>,
    cluster_links: Vec<ClusterLink>,
    created: usize,
    skipped: usize,
    rays: u64,
}

impl HierarchicalSolver {
    /// Does this solve cluster (decided by `params.cluster` and the patch count)?
    pub(super) fn clustering(&self) -> bool {
        self.setup.params.cluster.applies(self.hier.roots)
    }

    /// Each cluster node's largest radiosity (leaves: their patch's `b_max`).
    pub(super) fn cluster_b_max(&self, tree: &ClusterTree) -> Vec<f64> {
        let mut b = vec![0.0_f64; tree.len()];
        for i in (0..tree.len()).rev() {
            let node = &tree.nodes[i];
            b[i] = if node.is_leaf() {
                self.hier.get(tree.patch(i as u32)).b_max
            } else {
                b[node.kids[0] as usize].max(b[node.kids[1] as usize])
            };
        }
        b
    }

    /// Is a cluster link between nodes `a` and `b` (spheres apart) accurate enough? The BF
    /// oracle's test with cluster bounds ([`cluster`]); the Feps oracle's with F alone.
    pub(super) fn cluster_accept(&self, tree: &ClusterTree, b_max: &[f64], a: u32, b: u32) -> bool {
        self.cluster_accept_in(tree, b_max, a, b, None)
    }

    /// [`Self::cluster_accept`] with the link's frame when it is known (a cluster link keeps
    /// it: the four frames' sums cost more than the rest of the test).
    fn cluster_accept_in(
        &self,
        tree: &ClusterTree,
        b_max: &[f64],
        a: u32,
        b: u32,
        frame: Option<u8>,
    ) -> bool {
        let (na, nb) = (&tree.nodes[a as usize], &tree.nodes[b as usize]);
        let d = na.center.distance(nb.center);
        let gap = d - na.radius - nb.radius;
        if gap <= 0.0 {
            return false;
        }
        // F bounds from the projected areas facing the other end (the whole member area, as
        // SPLASH-2's A/(π d²) has it, made 1.3–1.5× the links on the furnished rooms for the
        // same error), over the gap between the spheres (the centres' distance instead doubled
        // furnished-2k's error against the unclustered solve, 4.8 → 8.9 %).
        let w = (nb.center - na.center) / d;
        let pg2 = std::f64::consts::PI * gap * gap;
        let f = frame.unwrap_or_else(|| cluster::link_frame(na, nb, w));
        let (f_ab, f_ba) =
            ((nb.projected_area(-w, f) / pg2).min(1.0), (na.projected_area(w, f) / pg2).min(1.0));
        match self.setup.params.oracle {
            Oracle::Feps => f_ab.max(f_ba) < self.setup.params.feps,
            Oracle::Bf | Oracle::Error => {
                let var = (2.0 * (na.radius + nb.radius) / d).min(1.0);
                let bf = (na.rho_max * b_max[b as usize] * f_ab).max(nb.rho_max * b_max[a as usize] * f_ba);
                let share = if self.setup.params.oracle == Oracle::Error { ERROR_CLUSTER_SHARE } else { 1.0 };
                bf * var < share * self.setup.bf_eps
            }
        }
    }

    /// The first linking of a clustered solve: link the cluster tree's root with itself.
    /// Returns the links made (element links, and cluster links counted twice).
    pub(super) fn cluster_linking(&mut self) -> usize {
        let tree =
            Arc::clone(self.cluster.tree.get_or_insert_with(|| Arc::new(ClusterTree::build(&self.hier))));
        let b_max = self.cluster_b_max(&tree);
        let mut inst = self.install_start(Vec::new());
        let accept = |a: u32, b: u32| self.cluster_accept(&tree, &b_max, a, b);
        tree.link_batched(0, 0, &accept, &mut |pairs| self.install_chunk(&tree, &mut inst, pairs));
        self.install_finish(&tree, inst)
    }

    /// Test every cluster link again with the current radiosities and replace those that fail
    /// by their subdivision. Returns the links made and whether any cluster link changed.
    pub(super) fn cluster_refine(&mut self) -> (usize, bool) {
        let Some(tree) = self.cluster.tree.clone() else { return (0, false) };
        let b_max = self.cluster_b_max(&tree);
        let keep: Vec<bool> = self
            .cluster
            .links
            .par_iter()
            .with_min_len(64)
            .map(|l| self.cluster_accept_in(&tree, &b_max, l.a, l.b, Some(l.frame)))
            .collect();
        if keep.iter().all(|&k| k) {
            return (0, false);
        }
        let links = std::mem::take(&mut self.cluster.links);
        let kept = links.iter().zip(&keep).filter(|(_, k)| **k).map(|(l, _)| *l).collect();
        let mut inst = self.install_start(kept);
        // The failing links' subdivisions, in link order, a chunk of links at a time.
        let failed: Vec<ClusterLink> =
            links.iter().zip(&keep).filter(|(_, k)| !**k).map(|(l, _)| *l).collect();
        drop(links);
        let accept = |a: u32, b: u32| self.cluster_accept(&tree, &b_max, a, b);
        // A deadline stops the subdivisions before a chunk that, with the gathers after it, would
        // not fit: the failing links left stay as they are, unrefined. The links a gather would
        // then go through: those kept, those made, the failing ones left.
        let kept_links = if self.setup.deadline.is_some() {
            inst.lists.iter().map(Vec::len).sum::<usize>() + inst.cluster_links.len()
        } else {
            0
        };
        let mut chunk_s = 0.0;
        for (k, chunk) in failed.chunks(CLUSTER_REFINE_CHUNK).enumerate() {
            let left = failed.len() - k * CLUSTER_REFINE_CHUNK;
            if !self.fits_deadline(chunk_s, kept_links + inst.created + left) {
                inst.cluster_links.extend_from_slice(&failed[k * CLUSTER_REFINE_CHUNK..]);
                break;
            }
            let t = Instant::now();
            let parts: Vec<Vec<Pairing>> = chunk
                .par_iter()
                .map(|l| {
                    let mut out = Vec::new();
                    tree.link(l.a, l.b, &accept, &mut out);
                    out
                })
                .collect();
            self.install_chunk(&tree, &mut inst, &parts.concat());
            chunk_s = t.elapsed().as_secs_f64();
        }
        (self.install_finish(&tree, inst), true)
    }

    /// Begin installing pairings after the cluster links `kept`: the patches' link lists are
    /// taken out of the store until [`Self::install_finish`].
    fn install_start(&mut self, kept: Vec<ClusterLink>) -> Installing {
        // The old transfer (its incoming links and moments: 0.2 GB at 100 k patches) is not
        // needed while the new links are made.
        self.cluster.xfer = ClusterTransfer::default();
        Installing {
            lists: std::mem::take(&mut self.graph.links.by_receiver),
            cluster_links: kept,
            created: 0,
            skipped: 0,
            rays: 0,
        }
    }

    /// Make the links of `pairs` (cluster links with their visibility, element links of patch
    /// pairs as `initial_linking` does) and add them to `inst`, in pair order.
    fn install_chunk(&self, tree: &ClusterTree, inst: &mut Installing, pairs: &[Pairing]) {
        let (rays, seed) = (self.setup.params.rays.max(4), self.setup.params.seed);
        let acc = self.clustered_pair_accuracy();
        let make = |pair: &Pairing| -> Made {
            match *pair {
                Pairing::Cluster(a, b) => {
                    let (na, nb) = (&tree.nodes[a as usize], &tree.nodes[b as usize]);
                    let w = (nb.center - na.center).normalize();
                    let frame = cluster::link_frame(na, nb, w);
                    if cluster::carries_nothing(na, nb, w, frame) {
                        return (None, None, 0);
                    }
                    let (vis, cast) = tree.visibility(&self.hier, &self.setup.accel, a, b, rays, seed);
                    (Some(ClusterLink { a, b, vis, frame }), None, u64::from(cast))
                }
                Pairing::Patches(p, q) => {
                    let (links, cast) = self.root_pair(p, q, acc, false);
                    (None, links.map(|(pq, qp)| (p, q, pq, qp)), cast)
                }
            }
        };
        // In chunks: a made pair takes ~130 bytes until installed, and all of them at once
        // were the peak of the process (furnished-30k: 3.7 M pairs, 0.48 GB of its 0.50 GB).
        for chunk in pairs.chunks(INSTALL_CHUNK) {
            let made: Vec<Made> = chunk.par_iter().with_min_len(16).map(make).collect();
            for (cl, el, cast) in made {
                inst.rays += cast;
                if let Some(cl) = cl {
                    inst.cluster_links.push(cl);
                    inst.created += 2;
                } else if let Some((p, q, pq, qp)) = el {
                    inst.lists[p as usize].push(pq);
                    inst.lists[q as usize].push(qp);
                    inst.created += 2;
                } else {
                    inst.skipped += 1;
                }
            }
        }
    }

    /// Put the links installed into the store, update the patches' cluster rows. Returns the
    /// links made (element links, and cluster links counted twice).
    fn install_finish(&mut self, tree: &ClusterTree, inst: Installing) -> usize {
        let Installing { mut lists, mut cluster_links, created, skipped, rays } = inst;
        // Lists grown a push at a time hold up to twice their links.
        lists[..self.hier.roots].par_iter_mut().with_min_len(256).for_each(Vec::shrink_to_fit);
        cluster_links.shrink_to_fit();
        self.graph.links.by_receiver = lists;
        self.cluster.links = cluster_links;
        self.log.stats.rays += rays;
        self.log.stats.pairs_skipped += skipped;
        // Each patch's Σ F·V through the cluster links (the transfer with B = 1), bounded by
        // what its hemisphere sees of the patches they cover.
        self.cluster.xfer = ClusterTransfer::new(tree, &self.cluster.links);
        let bound = self.cluster.xfer.bound_rows(
            tree,
            &self.hier,
            &self.setup.scene,
            &self.setup.accel,
            self.setup.params.seed,
        );
        self.log.stats.rays += bound.rays;
        self.log.stats.cluster_rows_cut = bound.cut;
        self.cluster.fv = bound.rows;
        created
    }

    /// The accuracy of the couplings of the patch pairs a clustered scene links one by one:
    /// [`CLUSTERED_PAIR_TOL_FACTOR`] × `link_tol` (one point stays one point).
    fn clustered_pair_accuracy(&self) -> transfer::Accuracy {
        let acc = self.accuracy();
        transfer::Accuracy {
            tol: acc.tol * CLUSTERED_PAIR_TOL_FACTOR,
            adaptive_tol: acc.adaptive_tol * CLUSTERED_PAIR_TOL_FACTOR,
            ..acc
        }
    }

    /// The `max` cluster links of largest form factor, largest first (ties: link order), as
    /// drawn: the centres of their two nodes (a patch's: its centroid), their visibility, and
    /// the larger of their two unoccluded form factors in the clusters' point approximation,
    /// `min(1, P_b(−ω) / (π d²))` with P the projected area of the far end towards the near
    /// one (empty when the solve does not cluster). Only the kept links are built: the 100 k
    /// room has 4 M cluster links.
    #[must_use]
    pub fn cluster_link_views(&self, max: usize) -> Vec<ClusterLinkView> {
        let Some(tree) = &self.cluster.tree else { return Vec::new() };
        let index = cluster_index(tree);
        let end = |node: u32| match index[node as usize] {
            u32::MAX => ClusterEnd::Patch(tree.patch(node)),
            i => ClusterEnd::Cluster(i),
        };
        let ends = |l: &ClusterLink| {
            let (na, nb) = (&tree.nodes[l.a as usize], &tree.nodes[l.b as usize]);
            let d = na.center.distance(nb.center).max(f64::MIN_POSITIVE);
            let w = (nb.center - na.center) / d;
            let f = cluster::link_frame(na, nb, w);
            let pd2 = std::f64::consts::PI * d * d;
            let ff = (nb.projected_area(-w, f) / pd2).max(na.projected_area(w, f) / pd2).min(1.0);
            (na.center, nb.center, ff)
        };
        let mut order: Vec<(f64, u32)> =
            self.cluster.links.par_iter().enumerate().map(|(i, l)| (ends(l).2, i as u32)).collect();
        let by_f = |x: &(f64, u32), y: &(f64, u32)| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1));
        if order.len() > max && max > 0 {
            order.select_nth_unstable_by(max - 1, by_f);
        }
        order.truncate(max);
        order.sort_unstable_by(by_f);
        order
            .into_iter()
            .map(|(_, i)| {
                let l = &self.cluster.links[i as usize];
                let (from, to, ff) = ends(l);
                ClusterLinkView { from, to, vis: l.vis, ff, ends: [end(l.a), end(l.b)] }
            })
            .collect()
    }

    /// The cluster tree's nodes of two patches or more, in tree order, with their link counts;
    /// and per input patch the index of the smallest of them holding it (both empty when the
    /// solve does not cluster).
    #[must_use]
    pub fn cluster_infos(&self) -> (Vec<ClusterInfo>, Vec<u32>) {
        let Some(tree) = &self.cluster.tree else { return (Vec::new(), Vec::new()) };
        let mut links = vec![0u32; tree.len()];
        for l in &self.cluster.links {
            links[l.a as usize] += 1;
            links[l.b as usize] += 1;
        }
        let index = cluster_index(tree);
        let mut infos = Vec::new();
        let mut patch_cluster = vec![u32::MAX; self.hier.roots];
        for (i, n) in tree.nodes.iter().enumerate() {
            let parent = (n.parent != cluster::LEAF).then(|| index[n.parent as usize]);
            if n.is_leaf() {
                if let Some(p) = parent {
                    patch_cluster[tree.patch(i as u32) as usize] = p;
                }
                continue;
            }
            infos.push(ClusterInfo {
                depth: n.depth,
                bmin: n.bmin,
                bmax: n.bmax,
                patches: n.hi - n.lo,
                links: links[i],
                parent,
            });
        }
        (infos, patch_cluster)
    }

    /// The form-factor accuracy of input patch pairs: they carry a closed scene's whole
    /// answer, so to 1e-7 (one point with SPLASH-2's rule), never the disk formula.
    pub(super) fn root_accuracy(&self) -> transfer::Accuracy {
        let tol = if self.setup.params.link_tol > 0.0 { transfer::ROOT_REL_TOL } else { 0.0 };
        transfer::Accuracy { tol, adaptive_tol: tol, five_times: false }
    }

    /// The two links of input patches `pi` < `qi` (p ← q, q ← p), or None when they face away
    /// or are fully occluded; and the rays cast. Visibility once per unordered pair, used both
    /// ways.
    /// `root`: integrate the coupling to the input pairs' tolerance (`root_accuracy`); else to
    /// `acc`, as element links are (the small patches of a clustered scene).
    pub(super) fn root_pair(
        &self,
        pi: u32,
        qi: u32,
        acc: transfer::Accuracy,
        root: bool,
    ) -> (Option<(Link, Link)>, u64) {
        let (rays, seed, conservative) =
            (self.setup.params.rays, self.setup.params.seed, self.setup.params.conservative);
        let weighted = self.weighted_visibility();
        let (p, q) = (self.hier.get(pi), self.hier.get(qi));
        let sides = pair_sides(p, q);
        if !sides.facing {
            return (None, 0);
        }
        // Newell normals of the input polygons (as `visibility::visible_fraction`).
        let (n_p, n_q) = (newell_normal(p.vertices()), newell_normal(q.vertices()));
        let mut last = NO_HIT;
        let mut cast = 0u64;
        let mut vis = |n_rays: u32, salt: u64| {
            let (v, c) = visibility::visibility_sample(
                &self.setup.accel,
                (p.vertices(), pi, n_p),
                (q.vertices(), qi, n_q),
                n_rays,
                seed ^ salt,
                pair_key(pi, qi),
                &mut last,
                Stop::Never,
                weighted,
            );
            cast += u64::from(c);
            v
        };
        // Input pairs of an unclustered scene are confirmed with ROOT_CONFIRM_RAYS; the small
        // patches a clustered scene links pair by pair as refined links are (`zero_confirm` ×
        // rays: the 32 rays were a third of a 100 k-patch room's rays).
        let confirm = if root { ROOT_CONFIRM_RAYS } else { self.setup.params.zero_confirm * rays };
        let mut v = vis(rays, 0);
        // With the error oracle, a pair whose rays all passed and whose shaft is empty sees
        // itself whole: V = 1 without confirmation (as `make_pair_link`), and so do all the
        // pairs below it.
        let clear = v == 1.0
            && self.setup.params.oracle == Oracle::Error
            && self.setup.accel.shaft_clear(
                &self.setup.scene,
                p.vertices(),
                q.vertices(),
                [p.patch, q.patch],
            );
        if v == 0.0 {
            // Confirm full occlusion with more rays before dropping the pair.
            if confirm == 0 || vis(confirm, 0x5EED) == 0.0 {
                return (None, cast);
            }
            v = 1.0 / f64::from(confirm + rays);
        } else if v == 1.0 && !clear && conservative && confirm > 0 {
            // All rays passed: the oracle keeps a fully visible link and splits a
            // partially visible one, whose children are estimated afresh, so an
            // accepted false 1 is a bright bias that only grows (splash_room
            // `interactive`: the floor–wall pairs at V 0.65 read 1 with 4 rays, the
            // floor's F·V summed to 1.11, and the solve created 11 % of its light).
            // Confirmed with more rays; the first blocked one makes it partial.
            let v2 = vis(confirm, 0x0DE5);
            if v2 < 1.0 {
                v = (f64::from(rays) + v2 * f64::from(confirm)) / f64::from(rays + confirm);
            }
        }
        // One Galerkin coupling serves both links (A_p F_pq = A_q F_qp exactly). Computed
        // once the pair is known to be visible: near pairs take adaptive cubature, the larger
        // part of a clustered solve, and a fully occluded pair needs none.
        // The small patches of a clustered scene are placed by their bounding boxes' gap.
        let min_gap = if root { transfer::NO_GAP_BOUND } else { transfer::box_gap(p, q) };
        let g = transfer::coupling(p, pi, q, qi, sides.straddle, root, acc, min_gap);
        if g <= 0.0 && !sides.straddle {
            return (None, cast);
        }
        let v = v as f32;
        let mut links = (
            new_link((p, pi), (q, qi), g, v, sides.straddle, conservative),
            new_link((q, qi), (p, pi), g, v, sides.straddle, conservative),
        );
        (links.0.clear, links.1.clear) = (clear, clear);
        (Some(links), cast)
    }

    /// Link every pair of input patches that face each other and are not fully occluded.
    pub(super) fn initial_linking(&mut self) -> usize {
        let key = (
            self.setup.params.rays,
            self.setup.params.seed,
            self.setup.params.conservative,
            self.weighted_visibility(),
        );
        if let Some((k, cached, skipped)) = &self.graph.initial_cache
            && *k == key
        {
            let n = cached.iter().map(Vec::len).sum();
            for (i, l) in cached.iter().enumerate() {
                self.graph.links.by_receiver[i] = l.clone();
            }
            self.log.stats.pairs_skipped = *skipped;
            return n;
        }
        let n = self.hier.roots as u32;
        let root_acc = self.root_accuracy();
        let rows: Vec<PairRow> = (0..n)
            .into_par_iter()
            .map(|pi| {
                let mut out = Vec::new();
                let mut skipped = 0;
                let mut cast = 0u64;
                for qi in pi + 1..n {
                    let (links, c) = self.root_pair(pi, qi, root_acc, true);
                    cast += c;
                    match links {
                        Some((pq, qp)) => out.push((qi, pq, qp)),
                        None => skipped += 1,
                    }
                }
                (out, skipped, cast)
            })
            .collect();
        let mut lists: Vec<Vec<Link>> = vec![Vec::new(); n as usize];
        let mut skipped = 0;
        for (pi, (row, sk, cast)) in rows.into_iter().enumerate() {
            skipped += sk;
            self.log.stats.rays += cast;
            for (qi, pq, qp) in row {
                lists[pi].push(pq);
                lists[qi as usize].push(qp);
            }
        }
        // Receiver lists in source order, whatever order the pairs were visited in.
        for l in &mut lists {
            l.sort_by_key(|l| l.source);
        }
        let total = lists.iter().map(Vec::len).sum();
        for (i, l) in lists.iter().enumerate() {
            self.graph.links.by_receiver[i] = l.clone();
        }
        self.log.stats.pairs_skipped = skipped;
        self.graph.initial_cache = Some((key, lists, skipped));
        total
    }
}

/// Node id → index among the tree's clusters (nodes of two patches or more, in tree order, as
/// [`HierarchicalSolver::cluster_infos`] lists them); `u32::MAX` for a leaf.
fn cluster_index(tree: &ClusterTree) -> Vec<u32> {
    let mut next = 0;
    tree.nodes
        .iter()
        .map(|n| {
            if n.is_leaf() {
                u32::MAX
            } else {
                next += 1;
                next - 1
            }
        })
        .collect()
}
