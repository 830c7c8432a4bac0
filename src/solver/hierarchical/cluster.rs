//! Clusters above the input patches, so that links grow as n instead of n² [Smits, Arvo &
//! Greenberg 1994, "A clustering algorithm for radiosity in complex environments" (SAG94);
//! Sillion 1995, "A unified hierarchical algorithm for global illumination with scattering
//! volumes and object clusters" (S95)].
//!
//! HSA91 starts from a link between every pair of input patches, so a room of n small
//! polygons starts with n² links (a 10 k-patch room: 14.4 M links, 138 s). Here a binary
//! cluster tree is built over the patches (median splits of their centroids, as a BVH), and
//! linking starts from the root's link with itself:
//! ```text
//! Link(a, b):  a = b            → Link(a₀, a₀), Link(a₀, a₁), Link(a₁, a₁)   (a cluster sees itself)
//!              a, b patches     → the patch pair's element links (HSA91 from there on)
//!              accept(a, b)     → one cluster link a ↔ b
//!              else             → split the larger cluster (never a patch): Link(kᵢ, other)
//! accept(a, b): the bounding spheres are apart (gap g = d − r_a − r_b > 0) and
//!              max(ρ_a B_b F_ab, ρ_b B_a F_ba) · min(1, 2 (r_a + r_b) / d) < BFeps,
//!              F_ab = min(1, A_b / (π g²))       (the BF oracle's form, SPLASH-2's criterion)
//! ```
//! Every pair of distinct patches is covered exactly once: by its own element links or by the
//! one cluster link between two of its ancestors. An accepted pair whose transfer is zero both
//! ways ([`carries_nothing`]: coplanar clusters of a floor, clusters facing away from each
//! other) gets no link at all: on the furnished rooms these were 20–42 % of the cluster links. A big patch (a floor) is never split here:
//! its sphere holds the clusters near it, so it links to each of their patches, and element
//! refinement subdivides it as it does today.
//!
//! **Transfer** (SAG94's oriented clusters; the cosine of each member, not S95's isotropic
//! volume): what a cluster s sends in a direction w is I_s(w) = Σ_j A_j B_j max(0, n_j·w). With
//! max(0, x) = (x + |x|)/2 and |n·w| ≈ Σ_k |n_k| |w_k| (exact for axis-aligned normals),
//! ```text
//! I_s(w) ≈ ½ (S·w + T·|w|),   S = Σ_j A_j B_j n_j,   T = Σ_j A_j B_j |n_j|   (per channel)
//! ```
//! kept per cluster and pulled up the tree in O(n). A link r ← s delivers the flux density
//! φ = I_s(−ω) V / (π d² + P_r(ω) + P_s(−ω)) from the direction ω (r's centre towards s's; P the
//! projected areas facing the other end: Wallace's disk regularisation, symmetric so the link
//! stays reciprocal — the point form π d² alone overestimated close facing clusters and made
//! furnished-4k create 1.4 % of its light, see [`distance_term`]); a patch receiver takes
//! φ max(0, n·ω) at once, a cluster receiver keeps U = Σ φ ω and W = Σ φ |ω|, pushed down the
//! tree and read by each member patch as H = ½ (n·U + |n|·W). Patches' own emission and
//! radiosity B are their root elements' (area averages after push-pull). The irradiance lands
//! on each patch's root element, and push-pull carries it to the leaves.
//!
//! **Visibility** of a cluster link: point pairs on area-weighted member patches of both
//! clusters, only those that face each other, weighted by their two cosines (4 × rays tries
//! at most; when none faces, V = 1: the transfer's cosines already make it small).
//!
//! **Refinement**: after each gather the cluster links are tested again with the new B (as
//! the BF oracle does for element links); a link that fails is replaced by its subdivision.
//!
//! The energy rows (Σ F·V of each patch, for the power balance) are the same transfer with
//! B = 1.

use crate::geometry::accel::{Accel, NO_HIT};
use crate::geometry::visibility::point_on_polygon;
use crate::math::{DVec3, Pcg32, Rgb, splitmix64};
use crate::solver::hierarchy::Hierarchy;
use rayon::prelude::*;

/// No child (a node that stands for one patch).
pub const LEAF: u32 = u32::MAX;

/// One node of the cluster tree: one patch (a leaf) or the union of its two children.
#[derive(Clone, Debug)]
pub struct ClusterNode {
    /// Members: `ClusterTree::order[lo..hi]`.
    pub lo: u32,
    pub hi: u32,
    /// Children (node ids, larger than this node's), or [`LEAF`].
    pub kids: [u32; 2],
    pub parent: u32,
    /// Bounding box of the members' vertices.
    pub bmin: DVec3,
    pub bmax: DVec3,
    /// Area-weighted centroid of the members (a patch: its centroid).
    pub center: DVec3,
    /// Radius of a sphere about `center` holding every member.
    pub radius: f64,
    pub area: f64,
    /// Largest reflectance channel of a member.
    pub rho_max: f64,
    /// Σ A n and, in each of the [`FRAMES`], Σ A |n|: the projected area towards w is about
    /// ½ (S·w + min_f T_f·|w|_f) (see the module docs).
    pub area_s: DVec3,
    pub area_t: [DVec3; FRAMES.len()],
    pub depth: u8,
}

impl ClusterNode {
    #[must_use]
    pub fn is_leaf(&self) -> bool {
        self.kids[0] == LEAF
    }

    /// The members' area projected towards the unit direction `w` (front faces only), as the
    /// transfer reckons it in frame `f`.
    #[must_use]
    pub fn projected_area(&self, w: DVec3, f: u8) -> f64 {
        let f = usize::from(f);
        (0.5 * (self.area_s.dot(w) + self.area_t[f].dot(abs_in(f, w)))).max(0.0)
    }
}

/// A link between two nodes, at least one of them a cluster. Both directions transfer.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct ClusterLink {
    pub a: u32,
    pub b: u32,
    pub vis: f32,
    /// The frame (index into [`FRAMES`]) both ends' cosines are taken in.
    pub frame: u8,
}

/// What linking a pair of nodes gives.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Pairing {
    /// A cluster link (at least one cluster).
    Cluster(u32, u32),
    /// Two patches (root element ids, ascending): HSA91's element links.
    Patches(u32, u32),
}

/// The cluster tree over the input patches; node 0 is the root, children have larger ids.
#[derive(Clone, Debug, Default)]
pub struct ClusterTree {
    pub nodes: Vec<ClusterNode>,
    /// The patches in tree order.
    pub order: Vec<u32>,
    /// Running member area over `order` (`cum_area[i]` = area of `order[..i]`).
    cum_area: Vec<f64>,
}

/// Above this many members on both sides, linking recurses in parallel.
const PARALLEL_MEMBERS: u32 = 256;

/// [`ClusterTree::link_batched`] links pairs of nodes of at most this many members at once.
const BATCH_MEMBERS: u32 = 1024;

/// A step of [`ClusterTree::link_batched`]: a pairing decided, or two nodes to link.
#[derive(Copy, Clone, Debug)]
enum Task {
    Done(Pairing),
    Pairs(u32, u32),
}

impl ClusterTree {
    /// Median splits of the patch centroids along the longest axis of their bounds, down to
    /// single patches (ties broken by patch id: the same tree for any thread count).
    #[must_use]
    pub fn build(hier: &Hierarchy) -> ClusterTree {
        let n = hier.roots;
        let mut order: Vec<u32> = (0..n as u32).collect();
        let mut nodes = Vec::with_capacity(2 * n.max(1) - 1);
        if n > 0 {
            build_rec(hier, &mut order, 0, n, LEAF, 0, &mut nodes);
        }
        let mut cum_area = Vec::with_capacity(n + 1);
        let mut acc = 0.0;
        cum_area.push(0.0);
        for &p in &order {
            acc += hier.get(p).area;
            cum_area.push(acc);
        }
        ClusterTree { nodes, order, cum_area }
    }

    #[must_use]
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The patch a leaf node stands for.
    #[must_use]
    pub fn patch(&self, node: u32) -> u32 {
        self.order[self.nodes[node as usize].lo as usize]
    }

    /// Link nodes `a` and `b` (see the module docs), appending the result to `out` in a fixed
    /// order. `accept` decides a pair with at least one cluster whose spheres are apart.
    pub fn link<F: Fn(u32, u32) -> bool + Sync>(&self, a: u32, b: u32, accept: &F, out: &mut Vec<Pairing>) {
        let (na, nb) = (&self.nodes[a as usize], &self.nodes[b as usize]);
        if a == b {
            if na.is_leaf() {
                return;
            }
            let [k0, k1] = na.kids;
            if na.hi - na.lo >= 2 * PARALLEL_MEMBERS {
                let ((mut x, y), z) = rayon::join(
                    || rayon::join(|| self.collect(k0, k0, accept), || self.collect(k0, k1, accept)),
                    || self.collect(k1, k1, accept),
                );
                x.extend(y);
                x.extend(z);
                out.extend(x);
            } else {
                self.link(k0, k0, accept, out);
                self.link(k0, k1, accept, out);
                self.link(k1, k1, accept, out);
            }
            return;
        }
        if na.is_leaf() && nb.is_leaf() {
            let (p, q) = (self.patch(a), self.patch(b));
            out.push(Pairing::Patches(p.min(q), p.max(q)));
            return;
        }
        let gap = na.center.distance(nb.center) - na.radius - nb.radius;
        if gap > 0.0 && accept(a, b) {
            out.push(Pairing::Cluster(a, b));
            return;
        }
        // Split the larger cluster (a patch is never split here).
        let split_a = !na.is_leaf() && (nb.is_leaf() || na.radius >= nb.radius);
        let (big, other) = if split_a { (na, b) } else { (nb, a) };
        let [k0, k1] = big.kids;
        let pair = |k: u32| if split_a { (k, other) } else { (other, k) };
        let (p0, p1) = (pair(k0), pair(k1));
        if big.hi - big.lo >= PARALLEL_MEMBERS
            && self.nodes[other as usize].hi - self.nodes[other as usize].lo >= PARALLEL_MEMBERS
        {
            let (mut x, y) =
                rayon::join(|| self.collect(p0.0, p0.1, accept), || self.collect(p1.0, p1.1, accept));
            x.extend(y);
            out.extend(x);
        } else {
            self.link(p0.0, p0.1, accept, out);
            self.link(p1.0, p1.1, accept, out);
        }
    }

    /// [`Self::link`] of `a` and `b`, handed to `sink` a batch at a time, in the order `link`
    /// gives them (so the batches put together are `link`'s list): the whole list of a 100 k
    /// patch room is 11 M pairings, 130 MB before its links are made. The recursion is
    /// unrolled down to pairs of nodes of at most [`BATCH_MEMBERS`] members between them;
    /// those are linked in parallel, a few at a time.
    pub fn link_batched<F: Fn(u32, u32) -> bool + Sync>(
        &self,
        a: u32,
        b: u32,
        accept: &F,
        sink: &mut impl FnMut(&[Pairing]),
    ) {
        self.link_batched_in(a, b, accept, BATCH_MEMBERS, sink);
    }

    fn link_batched_in<F: Fn(u32, u32) -> bool + Sync>(
        &self,
        a: u32,
        b: u32,
        accept: &F,
        batch_members: u32,
        sink: &mut impl FnMut(&[Pairing]),
    ) {
        let mut tasks = Vec::new();
        self.unroll(a, b, accept, batch_members, &mut tasks);
        let mut i = 0;
        while i < tasks.len() {
            // About BATCH_MEMBERS × 16 members a batch (a task is at least one pairing).
            let mut j = i;
            let mut members = 0;
            while j < tasks.len() && members < 16 * batch_members {
                members += match tasks[j] {
                    Task::Pairs(x, y) => self.members(x, y),
                    Task::Done(_) => 1,
                };
                j += 1;
            }
            let parts: Vec<Vec<Pairing>> = tasks[i..j]
                .par_iter()
                .map(|t| match *t {
                    Task::Done(p) => vec![p],
                    Task::Pairs(x, y) => self.collect(x, y, accept),
                })
                .collect();
            sink(&parts.concat());
            i = j;
        }
    }

    /// Members of `a` and `b` together (`a` alone when they are one node).
    fn members(&self, a: u32, b: u32) -> u32 {
        let (na, nb) = (&self.nodes[a as usize], &self.nodes[b as usize]);
        if a == b { na.hi - na.lo } else { (na.hi - na.lo) + (nb.hi - nb.lo) }
    }

    /// [`Self::link`]'s recursion, in its order, down to pairs of at most `batch_members` (2 or
    /// more) members (left as tasks) or pairings it decides on the way.
    fn unroll<F: Fn(u32, u32) -> bool + Sync>(
        &self,
        a: u32,
        b: u32,
        accept: &F,
        batch_members: u32,
        out: &mut Vec<Task>,
    ) {
        if self.members(a, b) <= batch_members.max(2) {
            out.push(Task::Pairs(a, b));
            return;
        }
        let (na, nb) = (&self.nodes[a as usize], &self.nodes[b as usize]);
        if a == b {
            let [k0, k1] = na.kids;
            self.unroll(k0, k0, accept, batch_members, out);
            self.unroll(k0, k1, accept, batch_members, out);
            self.unroll(k1, k1, accept, batch_members, out);
            return;
        }
        // More than BATCH_MEMBERS ≥ 2 members: not two patches.
        let gap = na.center.distance(nb.center) - na.radius - nb.radius;
        if gap > 0.0 && accept(a, b) {
            out.push(Task::Done(Pairing::Cluster(a, b)));
            return;
        }
        let split_a = !na.is_leaf() && (nb.is_leaf() || na.radius >= nb.radius);
        let (big, other) = if split_a { (na, b) } else { (nb, a) };
        for k in big.kids {
            if split_a {
                self.unroll(k, other, accept, batch_members, out);
            } else {
                self.unroll(other, k, accept, batch_members, out);
            }
        }
    }

    fn collect<F: Fn(u32, u32) -> bool + Sync>(&self, a: u32, b: u32, accept: &F) -> Vec<Pairing> {
        let mut v = Vec::new();
        self.link(a, b, accept, &mut v);
        v
    }

    /// A member patch of `node` and a point on it, for (u, v, w) ∈ [0,1)³: the patch by area
    /// (`u`), the point on it by (v, w).
    fn sample(&self, hier: &Hierarchy, node: u32, u: f64, v: f64, w: f64) -> (u32, DVec3) {
        let n = &self.nodes[node as usize];
        let (lo, hi) = (n.lo as usize, n.hi as usize);
        let target = self.cum_area[lo] + u * (self.cum_area[hi] - self.cum_area[lo]);
        // The last i in lo..hi with cum_area[i] <= target.
        let i = lo + self.cum_area[lo + 1..hi].partition_point(|&c| c <= target);
        let p = self.order[i.min(hi - 1)];
        (p, point_on_polygon(hier.get(p).vertices(), v, w))
    }

    /// Visible fraction between nodes `a` and `b`: `rays` point pairs that face each other,
    /// weighted by their two cosines (at most 4 × `rays` tries; none facing: 1); and the rays
    /// cast.
    #[must_use]
    pub fn visibility(
        &self,
        hier: &Hierarchy,
        accel: &Accel,
        a: u32,
        b: u32,
        rays: u32,
        seed: u64,
    ) -> (f32, u32) {
        let key = splitmix64((u64::from(a.min(b)) << 32 | u64::from(a.max(b))) ^ 0xC1_u64.rotate_left(56));
        let mut rng = Pcg32::keyed(seed, key);
        let (lo, hi) = if a < b { (a, b) } else { (b, a) };
        let mut last = NO_HIT;
        let (mut wsum, mut wvis) = (0.0, 0.0);
        let mut found = 0;
        for k in 0..4 * rays {
            if found == rays {
                break;
            }
            let strat = (f64::from(k % rays) + rng.next_f64()) / f64::from(rays);
            let (p, x) = self.sample(hier, lo, strat, rng.next_f64(), rng.next_f64());
            let (q, y) = self.sample(hier, hi, rng.next_f64(), rng.next_f64(), rng.next_f64());
            if p == q {
                continue;
            }
            let d = y - x;
            let (cp, cq) = (hier.get(p).normal.dot(d), -hier.get(q).normal.dot(d));
            if cp <= 0.0 || cq <= 0.0 {
                continue;
            }
            found += 1;
            let w = cp * cq / d.length_squared();
            wsum += w;
            if !accel.occluded_cached(x, y, [p, q], &mut last) {
                wvis += w;
            }
        }
        (if wsum > 0.0 { (wvis / wsum) as f32 } else { 1.0 }, found)
    }
}

fn build_rec(
    hier: &Hierarchy,
    order: &mut [u32],
    lo: usize,
    hi: usize,
    parent: u32,
    depth: u8,
    nodes: &mut Vec<ClusterNode>,
) -> u32 {
    let id = nodes.len() as u32;
    let members = &order[lo..hi];
    let (mut bmin, mut bmax) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    let (mut cmin, mut cmax) = (bmin, bmax);
    let (mut area, mut wc, mut rho_max) = (0.0, DVec3::ZERO, 0.0_f64);
    let (mut area_s, mut area_t) = (DVec3::ZERO, [DVec3::ZERO; FRAMES.len()]);
    for &p in members {
        let e = hier.get(p);
        for v in e.vertices() {
            bmin = bmin.min(*v);
            bmax = bmax.max(*v);
        }
        cmin = cmin.min(e.centroid);
        cmax = cmax.max(e.centroid);
        area += e.area;
        area_s += e.normal * e.area;
        for (f, t) in area_t.iter_mut().enumerate() {
            *t += abs_in(f, e.normal) * e.area;
        }
        wc += e.centroid * e.area;
        rho_max = rho_max.max(e.reflectance.max_channel());
    }
    let center = if area > 0.0 { wc / area } else { (bmin + bmax) * 0.5 };
    let mut radius: f64 = 0.0;
    for &p in members {
        for v in hier.get(p).vertices() {
            radius = radius.max(center.distance(*v));
        }
    }
    nodes.push(ClusterNode {
        lo: lo as u32,
        hi: hi as u32,
        kids: [LEAF, LEAF],
        parent,
        bmin,
        bmax,
        center,
        radius,
        area,
        rho_max,
        area_s,
        area_t,
        depth,
    });
    if hi - lo >= 2 {
        let ext = cmax - cmin;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        let mid = (hi - lo) / 2;
        let key = |p: &u32| (hier.get(*p).centroid[axis], *p);
        order[lo..hi].select_nth_unstable_by(mid, |a, b| {
            let (ka, kb) = (key(a), key(b));
            ka.0.total_cmp(&kb.0).then(ka.1.cmp(&kb.1))
        });
        let k0 = build_rec(hier, order, lo, lo + mid, id, depth.saturating_add(1), nodes);
        let k1 = build_rec(hier, order, lo + mid, hi, id, depth.saturating_add(1), nodes);
        nodes[id as usize].kids = [k0, k1];
    }
    id
}

/// Per-channel vector: one `Rgb` per axis.
type Vec3Rgb = [Rgb; 3];

/// Orthonormal frames (rows: the axes) in which |n·w| ≈ Σ_k |n_k| |w_k| is taken; the
/// smallest of the frames' values is kept (each is an upper bound, exact when n or w lies on
/// one of the frame's axes). The world axes, and the world turned 45° about each axis: a
/// cylinder seen at 45° between two axes is overestimated by 41 % in the world frame alone,
/// exactly right in the frame turned about its axis. Furniture turned on the floor, lamp
/// shades and table legs are what a room holds besides axis-aligned boxes.
pub const FRAMES: [[DVec3; 3]; 4] = {
    const H: f64 = std::f64::consts::FRAC_1_SQRT_2;
    [
        [DVec3::X, DVec3::Y, DVec3::Z],
        [DVec3::X, DVec3::new(0.0, H, H), DVec3::new(0.0, -H, H)],
        [DVec3::new(H, 0.0, -H), DVec3::Y, DVec3::new(H, 0.0, H)],
        [DVec3::new(H, H, 0.0), DVec3::new(-H, H, 0.0), DVec3::Z],
    ]
};

/// |v| componentwise in frame `f`.
#[inline]
fn abs_in(f: usize, v: DVec3) -> DVec3 {
    let [a, b, c] = FRAMES[f];
    DVec3::new(a.dot(v).abs(), b.dot(v).abs(), c.dot(v).abs())
}

/// The frame in which the cosines of a link between nodes `a` and `b` along the unit
/// direction `w` are taken: the one whose |·| sums overestimate the two ends' projected areas
/// least (geometry only, so fixed per link). One frame for both ends and both directions keeps
/// the transfer reciprocal: what a sends to b is what b's members gather from a.
#[must_use]
pub fn link_frame(a: &ClusterNode, b: &ClusterNode, w: DVec3) -> u8 {
    let excess = |f: usize| {
        let aw = abs_in(f, w);
        a.area_t[f].dot(aw) + b.area_t[f].dot(aw)
    };
    (1..FRAMES.len()).fold(0, |best, f| if excess(f) < excess(best) { f } else { best }) as u8
}

/// Does a link between nodes `a` and `b` (unit direction `w` from a to b, cosines in frame
/// `f`) transfer nothing either way? Each member's cosine term ½ (n·w + |n|·|w|) is ≥ 0, so a
/// node's projected area towards the other end is 0 only when every member's term is, and then
/// whatever the radiosities, the node neither sends along the link nor receives from it
/// (coplanar clusters of a floor or a wall, clusters facing away from each other). Such a pair
/// needs no link (less than 1e-9 of a node's area counts as 0).
#[must_use]
pub fn carries_nothing(a: &ClusterNode, b: &ClusterNode, w: DVec3, f: u8) -> bool {
    a.projected_area(w, f) <= 1e-9 * a.area || b.projected_area(-w, f) <= 1e-9 * b.area
}

/// The distance term of a link's transfer, `π d² + P_a(ω) + P_b(−ω)` (d the centres' distance,
/// ω the unit direction a → b, P the projected areas facing the other end), the same for both
/// directions so the transfer stays reciprocal. The point form `π d²` alone overestimates F
/// between facing clusters: a flat cluster of radius R under a patch at height h = R is worth
/// F = ½ (a disk seen from a point) and 0.38 (disk to equal disk), the point form says 1. The
/// projected areas regularise it as Wallace's disk approximation does for a point and a disk,
/// F = A / (π d² + A) [Wallace, Elmquist & Haines 1989, "A ray tracing algorithm for
/// progressive radiosity", eq. 4]: two equal facing disks at d = R read 1/3 (exact 0.38), and
/// far links, where P ≪ π d², keep the point form.
fn distance_term(tree: &ClusterTree, l: &ClusterLink) -> f64 {
    let (na, nb) = (&tree.nodes[l.a as usize], &tree.nodes[l.b as usize]);
    let d = nb.center - na.center;
    let d2 = d.length_squared();
    let w = d / d2.sqrt();
    std::f64::consts::PI * d2 + na.projected_area(w, l.frame) + nb.projected_area(-w, l.frame)
}

/// One direction of a cluster link, as its receiver gathers it.
#[derive(Copy, Clone, Debug)]
struct Incoming {
    src: u32,
    /// V / (π d² + P_a + P_b): the link's visibility over its regularised distance term.
    coef: f32,
    /// P_a + P_b, the distance term's regularisation (for the patch receivers' slopes).
    reg: f32,
    frame: u8,
}

/// The cluster links grouped by receiving node (both directions of each), the clusters'
/// radiosity moments (pulled from the patches) and the pushed irradiance.
#[derive(Clone, Debug, Default)]
pub struct ClusterTransfer {
    /// Node r receives `incoming[start[r]..start[r + 1]]`, in link order.
    start: Vec<u32>,
    incoming: Vec<Incoming>,
    /// Each node's centre, patch and slot, compact.
    nodes: Vec<Node>,
    /// The clusters (nodes of two patches or more) by slot, in tree order.
    clusters: Vec<u32>,
    /// Per cluster slot: its radiosity moments S and T (a patch's are read from it), the
    /// pushed irradiance moments U and W (a patch gathers its own links at once).
    s: Vec<Vec3Rgb>,
    t: Vec<[Vec3Rgb; FRAMES.len()]>,
    u: Vec<Vec3Rgb>,
    w: Vec<[Vec3Rgb; FRAMES.len()]>,
    /// Each patch's node (its leaf of the tree).
    leaf: Vec<u32>,
    /// Each patch's factor s_p ≤ 1 on both ends of its cluster links (empty: all 1), so the
    /// transfer from q to p is s_p s_q times the cluster transfer: reciprocal still
    /// ([`ClusterTransfer::bound_rows`]).
    scale: Vec<f64>,
}

/// A node as the transfer reads it.
#[derive(Copy, Clone, Debug)]
struct Node {
    centre: DVec3,
    /// Its patch, or [`LEAF`] for a cluster.
    patch: u32,
    /// A cluster's index into the moments (unused for a patch).
    slot: u32,
}

fn axpy(v: &mut Vec3Rgb, d: DVec3, x: Rgb) {
    v[0] += x * d.x;
    v[1] += x * d.y;
    v[2] += x * d.z;
}

fn dot(v: &Vec3Rgb, d: DVec3) -> Rgb {
    v[0] * d.x + v[1] * d.y + v[2] * d.z
}

fn clamp0(c: Rgb) -> Rgb {
    Rgb(c.0.map(|x| x.max(0.0)))
}

impl ClusterTransfer {
    /// The transfer through `links` (grouped by receiver once; the gathers then run in parallel
    /// over receiving nodes).
    #[must_use]
    pub fn new(tree: &ClusterTree, links: &[ClusterLink]) -> ClusterTransfer {
        let n = tree.len();
        let mut count = vec![0u32; n + 1];
        for l in links {
            count[l.a as usize] += 1;
            count[l.b as usize] += 1;
        }
        let mut start = Vec::with_capacity(n + 1);
        let mut total = 0u32;
        for c in &count[..n] {
            start.push(total);
            total += c;
        }
        start.push(total);
        let mut next = start.clone();
        let mut incoming = vec![Incoming { src: 0, coef: 0.0, reg: 0.0, frame: 0 }; total as usize];
        for l in links {
            let dt = distance_term(tree, l);
            let coef = (f64::from(l.vis) / dt) as f32;
            let d2 = tree.nodes[l.a as usize].center.distance_squared(tree.nodes[l.b as usize].center);
            let reg = (dt - std::f64::consts::PI * d2).max(0.0) as f32;
            for (r, src) in [(l.a, l.b), (l.b, l.a)] {
                let slot = &mut next[r as usize];
                incoming[*slot as usize] = Incoming { src, coef, reg, frame: l.frame };
                *slot += 1;
            }
        }
        let mut clusters = Vec::new();
        let nodes = (0..n as u32)
            .map(|i| {
                let node = &tree.nodes[i as usize];
                let (patch, slot) = if node.is_leaf() {
                    (tree.patch(i), LEAF)
                } else {
                    clusters.push(i);
                    (LEAF, clusters.len() as u32 - 1)
                };
                Node { centre: node.center, patch, slot }
            })
            .collect::<Vec<Node>>();
        let patches =
            nodes.iter().filter(|n| n.patch != LEAF).map(|n| n.patch as usize + 1).max().unwrap_or(0);
        let mut leaf = vec![LEAF; patches];
        for (i, n) in nodes.iter().enumerate().filter(|(_, n)| n.patch != LEAF) {
            leaf[n.patch as usize] = i as u32;
        }
        ClusterTransfer { start, incoming, nodes, clusters, leaf, ..ClusterTransfer::default() }
    }

    /// Irradiance of every patch (indexed by patch) through the cluster links, with patch
    /// radiosities `b` (one per patch).
    pub fn irradiance(
        &mut self,
        tree: &ClusterTree,
        hier: &Hierarchy,
        b: &(impl Fn(u32) -> Rgb + Sync),
    ) -> Vec<Rgb> {
        self.transfer(tree, hier, b, false).0
    }

    /// [`ClusterTransfer::irradiance`] and, per patch, how what it gathers through its own
    /// cluster links (a cluster at the other end, the patch itself at this one) varies across
    /// it: the gradient, per unit length in the patch's tangent basis
    /// ([`crate::math::orthonormal_basis`] of its normal), of the least-squares affine fit of
    /// the links' transfer at the patch's four child points, limited so that the irradiance it
    /// adds stays ≥ 0 at every vertex.
    ///
    /// The transfer lands on each patch as one value at its centre (module docs); a wall lit by
    /// a cluster of furniture beside it is brighter near it, and the value's mean over the
    /// patch stays what the link delivers (the slope's shift averages to zero over the
    /// patch's area), so the power balance does not change. Pushed down to the leaves as the
    /// element links' slopes are (`push_slopes`).
    pub fn irradiance_and_slopes(
        &mut self,
        tree: &ClusterTree,
        hier: &Hierarchy,
        b: &(impl Fn(u32) -> Rgb + Sync),
    ) -> (Vec<Rgb>, Vec<[Rgb; 2]>) {
        self.transfer(tree, hier, b, true)
    }

    /// The irradiance, and the slopes when `with_slopes` (else no slopes, an empty list).
    fn transfer(
        &mut self,
        tree: &ClusterTree,
        hier: &Hierarchy,
        b: &(impl Fn(u32) -> Rgb + Sync),
        with_slopes: bool,
    ) -> (Vec<Rgb>, Vec<[Rgb; 2]>) {
        let n = tree.len();
        if self.start.len() != n + 1 || self.leaf.len() != hier.roots {
            // No links (or a tree of another scene): nothing is gathered.
            let slopes = if with_slopes { vec![[Rgb::ZERO; 2]; hier.roots] } else { Vec::new() };
            return (vec![Rgb::ZERO; hier.roots], slopes);
        }
        let m = self.clusters.len();
        let scale = &self.scale;
        let s_of = |p: u32| scale.get(p as usize).copied().unwrap_or(1.0);
        // A patch's moments, S = A B n and T = A B |n| per frame.
        let leaf_moments = |p: u32| {
            let e = hier.get(p);
            let ab = b(p) * (e.area * s_of(p));
            let (mut s, mut t) = ([Rgb::ZERO; 3], [[Rgb::ZERO; 3]; FRAMES.len()]);
            axpy(&mut s, e.normal, ab);
            for (f, tf) in t.iter_mut().enumerate() {
                axpy(tf, abs_in(f, e.normal), ab);
            }
            (s, t)
        };
        // Pull S and T up the tree (children have larger ids, so larger slots).
        self.s.clear();
        self.s.resize(m, [Rgb::ZERO; 3]);
        self.t.clear();
        self.t.resize(m, [[Rgb::ZERO; 3]; FRAMES.len()]);
        for k in (0..m).rev() {
            let kids = tree.nodes[self.clusters[k] as usize].kids;
            let [(s0, t0), (s1, t1)] = kids.map(|kid| match self.nodes[kid as usize] {
                Node { patch: LEAF, slot, .. } => (self.s[slot as usize], self.t[slot as usize]),
                Node { patch, .. } => leaf_moments(patch),
            });
            for c in 0..3 {
                self.s[k][c] = s0[c] + s1[c];
                for f in 0..FRAMES.len() {
                    self.t[k][f][c] = t0[f][c] + t1[f][c];
                }
            }
        }
        // Intensity of node x towards the unit direction `dir` (cosines in frame f; `abs_dir`:
        // |dir| in that frame). The nodes' centres, patches and slots are read from the compact
        // `nodes` (the tree's are 240 bytes, and the sources are visited at random).
        let (s_moment, t_moment, nodes) = (&self.s, &self.t, &self.nodes);
        let intensity = |x: u32, dir: DVec3, abs_dir: DVec3, f: usize| -> Rgb {
            match nodes[x as usize] {
                Node { patch: LEAF, slot, .. } => {
                    let i = slot as usize;
                    clamp0((dot(&s_moment[i], dir) + dot(&t_moment[i][f], abs_dir)) * 0.5)
                }
                Node { patch, .. } => {
                    let e = hier.get(patch);
                    b(patch) * (e.area * s_of(patch) * e.normal.dot(dir).max(0.0))
                }
            }
        };
        let (start, incoming) = (&self.start, &self.incoming);
        // Node r's incoming links, in link order: (ω, |ω| in the link's frame, the frame, φ).
        let gather = |r: usize| {
            let centre = nodes[r].centre;
            incoming[start[r] as usize..start[r + 1] as usize].iter().map(move |inc| {
                let d = nodes[inc.src as usize].centre - centre;
                let d2 = d.length_squared();
                let omega = d / d2.sqrt();
                let f = usize::from(inc.frame);
                let abs_omega = abs_in(f, omega);
                // r gathers from the direction ω what the source sends towards −ω.
                let phi = intensity(inc.src, -omega, abs_omega, f) * f64::from(inc.coef);
                (omega, abs_omega, f, phi)
            })
        };
        // Each receiving node sums its incoming links in parallel: a cluster into its U and W,
        // a patch at once with its normal.
        self.u.clear();
        self.u.resize(m, [Rgb::ZERO; 3]);
        self.w.clear();
        self.w.resize(m, [[Rgb::ZERO; 3]; FRAMES.len()]);
        let clusters = &self.clusters;
        self.u.par_iter_mut().zip(self.w.par_iter_mut()).enumerate().with_min_len(256).for_each(
            |(k, (u, w))| {
                for (omega, abs_omega, f, phi) in gather(clusters[k] as usize) {
                    axpy(u, omega, phi);
                    axpy(&mut w[f], abs_omega, phi);
                }
            },
        );
        // What each patch gathers through its own links, at once with its normal (and their
        // slope).
        let leaf = &self.leaf;
        let direct = |p: usize| {
            let Some(r) = leaf.get(p).filter(|&&r| r != LEAF).map(|&r| r as usize) else {
                return (Rgb::ZERO, [Rgb::ZERO; 2]);
            };
            let links = &incoming[start[r] as usize..start[r + 1] as usize];
            if links.is_empty() {
                return (Rgb::ZERO, [Rgb::ZERO; 2]);
            }
            let e = hier.get(p as u32);
            let slope = if with_slopes { PatchSlope::new(e) } else { None };
            let mut direct = Rgb::ZERO;
            let mut grad = [Rgb::ZERO; 2];
            for ((omega, _, _, phi), inc) in gather(r).zip(links) {
                direct += phi * e.normal.dot(omega).max(0.0);
                if let Some(s) = &slope {
                    let [gu, gv] = s.gradient(nodes[r].centre, nodes[inc.src as usize].centre, inc.reg);
                    grad[0] += phi * gu;
                    grad[1] += phi * gv;
                }
            }
            (direct, slope.map_or([Rgb::ZERO; 2], |s| s.limit(direct, grad)))
        };
        let (mut h, mut slopes): (Vec<Rgb>, Vec<[Rgb; 2]>) = if with_slopes {
            (0..hier.roots).into_par_iter().with_min_len(256).map(direct).unzip()
        } else {
            ((0..hier.roots).into_par_iter().with_min_len(256).map(|p| direct(p).0).collect(), Vec::new())
        };
        // Push U and W down (parents first; the root has none); leaves read their parent's
        // with their normal.
        for i in 0..n {
            let parent = tree.nodes[i].parent;
            let Node { patch, slot, .. } = self.nodes[i];
            if parent == LEAF {
                continue;
            }
            let up = self.nodes[parent as usize].slot as usize;
            if patch == LEAF {
                let (u, w) = (self.u[up], self.w[up]);
                let k = slot as usize;
                for (mine, up) in self.u[k].iter_mut().zip(u) {
                    *mine += up;
                }
                for (mine_f, up_f) in self.w[k].iter_mut().zip(w) {
                    for (mine, up) in mine_f.iter_mut().zip(up_f) {
                        *mine += up;
                    }
                }
            } else {
                let nrm = hier.get(patch).normal;
                let mut hw = dot(&self.u[up], nrm);
                for f in 0..FRAMES.len() {
                    hw += dot(&self.w[up][f], abs_in(f, nrm));
                }
                h[patch as usize] += clamp0(hw * 0.5);
            }
        }
        // The receiving end's factor.
        for (p, &sp) in self.scale.iter().enumerate().filter(|(_, s)| **s < 1.0) {
            h[p] *= sp;
            if let Some(g) = slopes.get_mut(p) {
                *g = g.map(|g| g * sp);
            }
        }
        (h, slopes)
    }
}

/// Cosine-distributed rays from each patch whose cluster row [`ClusterTransfer::bound_rows`]
/// checks (the standard error of the fraction they measure is at most 1/(2√32) ≈ 0.09).
pub const BOUND_RAYS: u32 = 32;

/// The upper end of the hemisphere bound: the fraction `hits / rays` measured, plus two standard
/// errors of it and one ray's worth (so a fraction measured 0 still allows 1/rays: a row below
/// that is never cut, and a true fraction is exceeded by its bound with probability ≲ 2 %).
#[must_use]
pub fn hemisphere_bound(hits: u32, rays: u32) -> f64 {
    let n = f64::from(rays.max(1));
    let f = f64::from(hits) / n;
    (f + 2.0 * (f * (1.0 - f) / n).sqrt() + 1.0 / n).min(1.0)
}

/// Unless a row is clearly below the fraction its first [`BOUND_RAYS`] measure, this many times
/// as many rays again measure it.
pub const BOUND_RAYS_MORE: u32 = 8;

/// What [`ClusterTransfer::bound_rows`] did.
#[derive(Clone, Debug, Default)]
pub struct RowBound {
    /// Each patch's row through the cluster links, bounded (the energy balance's share).
    pub rows: Vec<f64>,
    /// Patches whose row the bound cut, and Σ A (row − bounded row) over them.
    pub cut: usize,
    pub cut_area_row: f64,
    pub rays: u64,
}

/// Is the patch at position `at` of the tree order in one of `ranges` (sorted, disjoint)?
#[must_use]
pub fn covers(ranges: &[(u32, u32)], at: u32) -> bool {
    let i = ranges.partition_point(|r| r.0 <= at);
    i > 0 && at < ranges[i - 1].1
}

impl ClusterTree {
    /// Each patch's position in [`ClusterTree::order`].
    #[must_use]
    pub fn positions(&self) -> Vec<u32> {
        let mut pos = vec![0u32; self.order.len()];
        for (i, &p) in self.order.iter().enumerate() {
            pos[p as usize] = i as u32;
        }
        pos
    }
}

impl ClusterTransfer {
    /// The patches the cluster links of patch `p` cover — those on its node and its ancestors
    /// cover the members of their other ends — as ranges of [`ClusterTree::order`]: disjoint
    /// (every pair of patches is covered once), sorted (for [`covers`]). Empty when `p` has no
    /// node in this transfer.
    #[must_use]
    pub fn covered(&self, tree: &ClusterTree, p: u32) -> Vec<(u32, u32)> {
        let mut ranges = Vec::new();
        let Some(&(mut at)) = self.leaf.get(p as usize) else { return ranges };
        if self.start.len() != tree.len() + 1 {
            return ranges;
        }
        while at != LEAF {
            for inc in &self.incoming[self.start[at as usize] as usize..self.start[at as usize + 1] as usize]
            {
                let n = &tree.nodes[inc.src as usize];
                ranges.push((n.lo, n.hi));
            }
            at = tree.nodes[at as usize].parent;
        }
        ranges.sort_unstable();
        ranges
    }

    /// Bound every patch's row of F·V through the cluster links by what its own hemisphere
    /// sees of the patches those links cover (the links on its node and its ancestors' cover
    /// the members of their other ends):
    ///
    /// ```text
    /// row_p = s_p Σ_q F_pq s_q  ≤  seen_p,      s = min(1, seen / F s)  (per patch)
    /// ```
    ///
    /// with seen_p the [`hemisphere_bound`] of the fraction of [`BOUND_RAYS`] cosine-distributed
    /// rays from p (first hits, `escape::cast_hemisphere`) that meet the front face of a
    /// covered patch, and F the cluster transfer with B = 1. One factor per patch on both ends
    /// keeps the transfer reciprocal, so what is sent is what is gathered and the power balance
    /// still closes; every s ≤ 1, so a row only shrinks, and each ends within its bound. The
    /// factors are the third iterate of s ← min(1, seen / F s) from s = 1, which is feasible and
    /// cuts less than the first: that one cuts a row at its own end and again at its sources'.
    ///
    /// Why: a cluster link's transfer takes one direction (centre to centre), one visibility
    /// for all its members and the members' summed cosines. A member below the other end's
    /// horizon, one hidden behind its neighbours, or a dense stack whose members shadow one
    /// another then gathers what its hemisphere cannot hold: a box's face on stacked-boxes-10k
    /// gathered 0.22 through cluster links where its rays (4 096) find 0.007 of its hemisphere
    /// on the patches they cover. The rays measure the member's own share [Smits, Arvo &
    /// Greenberg 1994 bound a cluster's transfer by its members' areas; this bounds it by the
    /// receiving member's visible hemisphere]. Rows at most 1/`BOUND_RAYS` are never cut, and
    /// are not traced.
    pub fn bound_rows(
        &mut self,
        tree: &ClusterTree,
        hier: &Hierarchy,
        scene: &crate::scene::Scene,
        accel: &Accel,
        seed: u64,
    ) -> RowBound {
        self.scale.clear();
        let ones = self.irradiance(tree, hier, &|_| Rgb::ONE);
        let rows: Vec<f64> = ones.iter().map(|h| h.0[0]).collect();
        let rays = BOUND_RAYS;
        let floor = hemisphere_bound(0, rays);
        if rows.iter().all(|&r| r <= floor) {
            return RowBound { rows, ..RowBound::default() };
        }
        let pos = tree.positions();
        let leaf = &self.leaf;
        // Per patch: its bound (infinite where not traced), and the rays cast.
        let bounds: Vec<(f64, u32)> = rows
            .par_iter()
            .enumerate()
            .with_min_len(64)
            .map(|(p, &row)| {
                if row <= floor || leaf.get(p).is_none_or(|&l| l == LEAF) {
                    return (f64::INFINITY, 0);
                }
                let ranges = self.covered(tree, p as u32);
                let e = hier.get(p as u32);
                let region =
                    crate::solver::escape::Region { verts: e.vertices(), normal: e.normal, patch: p as u32 };
                // The fraction seen with `rays` rays; unless the row is clearly below it (by two
                // standard errors), with [`BOUND_RAYS_MORE`] times as many more (another
                // stream), so that a row is held within about 0.06 of the fraction, not 0.2.
                let seen = |rays: u32, key: u64| {
                    let mut seen = 0u32;
                    crate::solver::escape::cast_hemisphere(scene, accel, region, rays, key, seed, |hit| {
                        if let crate::solver::escape::Hit::Front(q) = hit
                            && covers(&ranges, pos[q as usize])
                        {
                            seen += 1;
                        }
                    });
                    seen
                };
                let (mut hits, mut cast) = (seen(rays, p as u64), rays);
                let f = f64::from(hits) / f64::from(rays);
                if row > f - 2.0 * (f * (1.0 - f) / f64::from(rays)).sqrt() {
                    let more = rays * BOUND_RAYS_MORE;
                    hits += seen(more, !(p as u64));
                    cast += more;
                }
                (hemisphere_bound(hits, cast), cast)
            })
            .collect();
        let cast = bounds.iter().map(|&(_, r)| u64::from(r)).sum();
        if rows.iter().zip(&bounds).all(|(r, b)| r <= &b.0) {
            return RowBound { rows, rays: cast, ..RowBound::default() };
        }
        // The factors: s = T(s) = min(1, bound / F s), F s the row with each source weighted by
        // its own factor. T reverses order, so from s = 1 its iterates alternate about its fixed
        // point; the odd ones are feasible (s_p (F s)_p ≤ bound_p) and grow towards it. Three
        // iterates: the first alone cuts a row twice, once at its end and once at its sources'.
        let step = |x: &mut ClusterTransfer, s: &[f64]| -> Vec<f64> {
            x.scale.clear();
            let fs = x.irradiance(tree, hier, &|q| Rgb::splat(s[q as usize]));
            fs.iter().zip(&bounds).map(|(f, b)| if f.0[0] > b.0 { b.0 / f.0[0] } else { 1.0 }).collect()
        };
        let mut scale = vec![1.0; rows.len()];
        for _ in 0..3 {
            scale = step(self, &scale);
        }
        let cut: Vec<usize> = (0..scale.len()).filter(|&p| scale[p] < 1.0).collect();
        self.scale = scale;
        let bounded: Vec<f64> = self.irradiance(tree, hier, &|_| Rgb::ONE).iter().map(|h| h.0[0]).collect();
        debug_assert!(
            bounded.iter().zip(&bounds).all(|(r, b)| *r <= b.0 * (1.0 + 1e-9)),
            "a row above its bound"
        );
        let cut_area_row = cut.iter().map(|&p| hier.get(p as u32).area * (rows[p] - bounded[p])).sum();
        RowBound { rows: bounded, cut: cut.len(), cut_area_row, rays: cast }
    }
}

/// A patch's fit of its cluster links' transfer ([`ClusterTransfer::irradiance_and_slopes`]).
struct PatchSlope<'a> {
    pts: [DVec3; 4],
    /// The patch's centroid, where the slope's shift is zero (push-pull's).
    centroid: DVec3,
    normal: DVec3,
    t1: DVec3,
    t2: DVec3,
    fit: super::oracle::FitWeights,
    vertices: &'a [DVec3],
}

impl<'a> PatchSlope<'a> {
    fn new(e: &'a crate::solver::hierarchy::Element) -> Option<PatchSlope<'a>> {
        let pts = super::oracle::child_points(e);
        let c = (pts[0] + pts[1] + pts[2] + pts[3]) * 0.25;
        let (t1, t2) = crate::math::orthonormal_basis(e.normal);
        let fit = super::oracle::FitWeights::new(&pts, c, t1, t2)?;
        Some(PatchSlope { pts, centroid: e.centroid, normal: e.normal, t1, t2, fit, vertices: e.vertices() })
    }

    /// The gradient (basis t1, t2) of the transfer from a node centred at `src` to this patch
    /// (centred at `at`), relative to its value at `at`: the distance term π d² + reg and the
    /// receiver's cosine evaluated at the fit points.
    fn gradient(&self, at: DVec3, src: DVec3, reg: f32) -> [f64; 2] {
        let reg = f64::from(reg);
        let pi = std::f64::consts::PI;
        let d0 = src - at;
        let at_centre = pi * d0.length_squared() + reg;
        let vals = self.pts.map(|x| {
            let d = src - x;
            let l2 = d.length_squared();
            if !(l2 > 0.0) {
                return 0.0;
            }
            at_centre / (pi * l2 + reg) * (self.normal.dot(d) / l2.sqrt()).max(0.0)
        });
        let mean = (vals[0] + vals[1] + vals[2] + vals[3]) * 0.25;
        let (mut gu, mut gv) = (0.0, 0.0);
        for ((v, wu), wv) in vals.iter().zip(self.fit.u).zip(self.fit.v) {
            gu += (v - mean) * wu;
            gv += (v - mean) * wv;
        }
        if gu.is_finite() && gv.is_finite() { [gu, gv] } else { [0.0; 2] }
    }

    /// `grad` scaled down, per channel, so that `value` plus the slope's shift stays ≥ 0 at
    /// every vertex of the patch.
    fn limit(&self, value: Rgb, grad: [Rgb; 2]) -> [Rgb; 2] {
        let mut scale = [1.0f64; 3];
        for v in self.vertices {
            let (du, dv) = ((*v - self.centroid).dot(self.t1), (*v - self.centroid).dot(self.t2));
            for (ch, scale) in scale.iter_mut().enumerate() {
                let shift = grad[0].0[ch] * du + grad[1].0[ch] * dv;
                if shift < 0.0 && value.0[ch] + shift < 0.0 {
                    *scale = scale.min((value.0[ch].max(0.0) / -shift).max(0.0));
                }
            }
        }
        grad.map(|g| Rgb(std::array::from_fn(|ch| g.0[ch] * scale[ch])))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::form_factor;
    use crate::scene::{Patch, Scene};

    /// The six outward faces of a cube of side `s` at `c`, turned by `yaw` radians about y.
    fn cube(c: DVec3, s: f64, yaw: f64) -> Vec<Patch> {
        let rot = glam::DQuat::from_rotation_y(yaw);
        let h = s / 2.0;
        let mut out = Vec::new();
        for n in [DVec3::X, DVec3::NEG_X, DVec3::Y, DVec3::NEG_Y, DVec3::Z, DVec3::NEG_Z] {
            let t1 = if n.x.abs() > 0.5 { DVec3::Y } else { DVec3::X };
            let t2 = n.cross(t1);
            let v = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                .map(|(a, b)| c + rot * ((n + t1 * a + t2 * b) * h))
                .to_vec();
            out.push(Patch::new(v, Rgb::splat(0.5), Rgb::ZERO, "cube", 0, "face", "m").expect("valid face"));
        }
        out
    }

    fn hierarchy(patches: Vec<Patch>) -> Hierarchy {
        Hierarchy::from_scene(&Scene::new("t", "test", patches))
    }

    /// Every member patch of a node.
    fn members(t: &ClusterTree, node: u32) -> Vec<u32> {
        let n = &t.nodes[node as usize];
        t.order[n.lo as usize..n.hi as usize].to_vec()
    }

    /// Four cubes in a row and a turned one (30 patches), and their tree.
    fn cubes_in_a_row() -> (Hierarchy, ClusterTree) {
        let mut patches = Vec::new();
        for k in 0..4 {
            patches.extend(cube(DVec3::new(3.0 * f64::from(k), 0.0, 0.0), 1.0, 0.0));
        }
        patches.extend(cube(DVec3::new(0.0, 5.0, 2.0), 2.0, 0.3));
        let hier = hierarchy(patches);
        let tree = ClusterTree::build(&hier);
        (hier, tree)
    }

    #[test]
    fn linking_covers_every_pair_of_patches_exactly_once() {
        // Cubes in a row and a turned one: 30 patches; an arbitrary (but deterministic) accept.
        let (hier, tree) = cubes_in_a_row();
        assert_eq!(tree.len(), 2 * hier.roots - 1, "a binary tree down to single patches");
        let mut pairs = Vec::new();
        tree.link(0, 0, &|a, b| (a + b) % 3 == 0, &mut pairs);
        let n = hier.roots;
        let mut count = vec![0u32; n * n];
        let mut clusters = 0;
        for pair in &pairs {
            let (xs, ys) = match *pair {
                Pairing::Cluster(a, b) => {
                    clusters += 1;
                    assert!(!(tree.nodes[a as usize].is_leaf() && tree.nodes[b as usize].is_leaf()));
                    (members(&tree, a), members(&tree, b))
                }
                Pairing::Patches(p, q) => {
                    assert!(p < q, "patch pairs ascending");
                    (vec![p], vec![q])
                }
            };
            for &x in &xs {
                for &y in &ys {
                    count[x.min(y) as usize * n + x.max(y) as usize] += 1;
                }
            }
        }
        assert!(clusters > 0, "the test accepts some cluster links");
        for p in 0..n {
            for q in p + 1..n {
                assert_eq!(count[p * n + q], 1, "pair ({p}, {q}) covered {} times", count[p * n + q]);
            }
            assert_eq!(count[p * n + p], 0, "patch {p} linked to itself");
        }
    }

    #[test]
    fn batched_linking_gives_the_same_pairings_in_the_same_order() {
        // 30 patches linked in batches of pairs of at most 4 members: the batches put together
        // are `link`'s list, pairing for pairing.
        let (_, tree) = cubes_in_a_row();
        let accept = |a: u32, b: u32| (a + b).is_multiple_of(3);
        let mut whole = Vec::new();
        tree.link(0, 0, &accept, &mut whole);
        for batch_members in [1, 4, 7, 1024] {
            let mut batches = Vec::new();
            tree.link_batched_in(0, 0, &accept, batch_members, &mut |p| batches.push(p.to_vec()));
            assert_eq!(batches.concat(), whole, "batches of {batch_members}");
            if batch_members == 1024 {
                assert_eq!(batches.len(), 1, "30 patches are one batch");
            } else {
                assert!(batches.len() > 1, "batches of {batch_members}: {}", batches.len());
            }
        }
    }

    #[test]
    fn frames_make_boxes_and_turned_boxes_exact() {
        // Cubes turned 45° about y, not at all, and 0.3 rad, each linked to a far cube turned
        // alike: seen in several directions, the frame the link takes gives the exact
        // projected area of the first two (Σ A max(0, n·w)), and for the third at most the
        // world frame's overestimate.
        for (yaw, exact_expected) in [(std::f64::consts::FRAC_PI_4, true), (0.0, true), (0.3, false)] {
            let mut patches = cube(DVec3::ZERO, 1.0, yaw);
            patches.extend(cube(DVec3::new(0.0, 0.0, 100.0), 1.0, yaw));
            let hier = hierarchy(patches.clone());
            let tree = ClusterTree::build(&hier);
            // The root's two children: the two cubes (split along z, the longest extent).
            let [k0, k1] = tree.nodes[0].kids;
            let (near, other) = if tree.nodes[k0 as usize].center.z < 50.0 { (k0, k1) } else { (k1, k0) };
            let near_node = &tree.nodes[near as usize];
            for w in [
                DVec3::X,
                DVec3::new(1.0, 0.0, 1.0).normalize(),
                DVec3::new(1.0, 1.0, 0.0).normalize(),
                DVec3::new(0.3, -0.5, 0.8).normalize(),
            ] {
                let exact: f64 = patches[..6].iter().map(|p| p.area * p.normal.dot(w).max(0.0)).sum();
                let f = link_frame(near_node, &tree.nodes[other as usize], w);
                let approx = near_node.projected_area(w, f);
                assert!(approx >= exact * (1.0 - 1e-12), "yaw {yaw}, w {w}: {approx} < exact {exact}");
                if exact_expected {
                    assert!((approx - exact).abs() <= 1e-12 * exact, "yaw {yaw}, w {w}: {approx} vs {exact}");
                } else {
                    let world = near_node.projected_area(w, 0);
                    assert!(
                        approx <= world * (1.0 + 1e-12),
                        "yaw {yaw}, w {w}: frame {f} worse than the world's"
                    );
                }
            }
        }
    }

    /// Two clusters of cubes; one cluster link between them.
    fn two_clusters(distance: f64) -> (Hierarchy, ClusterTree, Vec<ClusterLink>, u32, u32) {
        let mut patches = Vec::new();
        patches.extend(cube(DVec3::ZERO, 1.0, 0.0));
        patches.extend(cube(DVec3::new(1.5, 0.2, 0.0), 0.7, 0.4));
        patches.extend(cube(DVec3::new(0.3, 0.0, distance), 1.2, 0.9));
        patches.extend(cube(DVec3::new(-1.0, 0.5, distance + 0.2), 0.5, 0.0));
        let hier = hierarchy(patches);
        let tree = ClusterTree::build(&hier);
        let [a, b] = tree.nodes[0].kids;
        let w = (tree.nodes[b as usize].center - tree.nodes[a as usize].center).normalize();
        let frame = link_frame(&tree.nodes[a as usize], &tree.nodes[b as usize], w);
        (hier, tree, vec![ClusterLink { a, b, vis: 0.8, frame }], a, b)
    }

    #[test]
    fn a_cluster_link_delivers_what_its_source_sends() {
        // Power gathered by a's members with b's radiosities B equals Σ_b A_j B_j F_j→a, where
        // F_j→a is b's members' row through the link (the transfer with B = 1 on a): the link
        // is reciprocal, so the power balance closes.
        let (hier, tree, links, a, b) = two_clusters(8.0);
        let in_a = members(&tree, a);
        let in_b = members(&tree, b);
        let bs = |p: u32| Rgb::new(0.1 + 0.07 * f64::from(p % 5), 0.3, 0.05 * f64::from(p % 3));
        let mut x = ClusterTransfer::new(&tree, &links);
        let h = x.irradiance(&tree, &hier, &|p| if in_b.contains(&p) { bs(p) } else { Rgb::ZERO });
        let received: Rgb = in_a.iter().fold(Rgb::ZERO, |s, &p| s + h[p as usize] * hier.get(p).area);
        let rows = x.irradiance(&tree, &hier, &|p| if in_a.contains(&p) { Rgb::ONE } else { Rgb::ZERO });
        let sent: Rgb =
            in_b.iter().fold(Rgb::ZERO, |s, &p| s + bs(p) * (hier.get(p).area * rows[p as usize].0[0]));
        assert!(received.max_channel() > 0.0);
        for c in 0..3 {
            assert!((received.0[c] - sent.0[c]).abs() <= 1e-12 * sent.0[c].abs(), "{received:?} vs {sent:?}");
        }
    }

    /// A floor lit by a cluster (a cube) standing above one end of it gets the link's transfer
    /// as a slope, not only a constant: brighter towards the cube, its mean unchanged (the
    /// slope is about the floor's centroid), never negative at a corner.
    #[test]
    fn a_patch_gathers_a_cluster_links_slope_towards_its_source() {
        let mut patches = vec![
            Patch::new(
                vec![
                    DVec3::ZERO,
                    DVec3::new(10.0, 0.0, 0.0),
                    DVec3::new(10.0, 0.0, -10.0),
                    DVec3::new(0.0, 0.0, -10.0),
                ],
                Rgb::splat(0.5),
                Rgb::ZERO,
                "floor",
                0,
                "floor",
                "m",
            )
            .expect("valid floor"),
        ];
        patches.extend(cube(DVec3::new(8.5, 3.0, -5.0), 1.0, 0.3));
        let hier = hierarchy(patches);
        assert!(hier.get(0).normal.y > 0.99, "the floor faces up");
        let tree = ClusterTree::build(&hier);
        // The floor's leaf, and the largest cluster of cube faces.
        let floor = (0..tree.len() as u32).find(|&i| members(&tree, i) == [0]).expect("the floor's leaf");
        let cube_node = (0..tree.len() as u32)
            .filter(|&i| !members(&tree, i).contains(&0))
            .max_by_key(|&i| members(&tree, i).len())
            .expect("a cluster of cube faces");
        assert!(members(&tree, cube_node).len() >= 2, "a cluster, not a patch");
        let (na, nb) = (&tree.nodes[floor as usize], &tree.nodes[cube_node as usize]);
        let w = (nb.center - na.center).normalize();
        let links = vec![ClusterLink { a: floor, b: cube_node, vis: 1.0, frame: link_frame(na, nb, w) }];
        let mut x = ClusterTransfer::new(&tree, &links);
        let (h, slopes) =
            x.irradiance_and_slopes(&tree, &hier, &|p| if p == 0 { Rgb::ZERO } else { Rgb::ONE });
        let e = hier.get(0);
        let [gu, gv] = slopes[0];
        assert!(h[0].0[0] > 0.0, "the floor gathers from the cube: {:?}", h[0]);
        let (t1, t2) = crate::math::orthonormal_basis(e.normal);
        let grad = t1 * gu.0[0] + t2 * gv.0[0];
        assert!(grad.x > 0.0, "brighter towards the cube (+x): gradient {grad}");
        let at = |v: DVec3| h[0].0[0] + grad.dot(v - e.centroid);
        let (near, far) = (at(DVec3::new(10.0, 0.0, -5.0)), at(DVec3::new(0.0, 0.0, -5.0)));
        assert!(near > 1.5 * far, "near edge {near} vs far edge {far}");
        for v in e.vertices() {
            assert!(at(*v) >= -1e-12, "corner {v}: {}", at(*v));
        }
        // The cube's own faces gather nothing through the link from the black floor.
        assert!((1..7).all(|p| slopes[p] == [Rgb::ZERO; 2] && h[p] == Rgb::ZERO));
        // The same irradiance without the slopes.
        assert_eq!(x.irradiance(&tree, &hier, &|p| if p == 0 { Rgb::ZERO } else { Rgb::ONE }), h);
    }

    /// A 4 × 4 grid of squares making the unit square at height `z`, facing up or down.
    fn grid(z: f64, up: bool) -> Vec<Patch> {
        let mut out = Vec::new();
        for i in 0..4 {
            for j in 0..4 {
                let (x, y) = (f64::from(i) * 0.25, f64::from(j) * 0.25);
                let mut v = vec![
                    DVec3::new(x, y, z),
                    DVec3::new(x + 0.25, y, z),
                    DVec3::new(x + 0.25, y + 0.25, z),
                    DVec3::new(x, y + 0.25, z),
                ];
                if !up {
                    v.reverse();
                }
                out.push(
                    Patch::new(v, Rgb::splat(0.5), Rgb::ZERO, "grid", 0, "sq", "m").expect("valid square"),
                );
            }
        }
        out
    }

    #[test]
    fn coplanar_and_turned_away_clusters_carry_nothing() {
        // Two 4 × 4 grids side by side in one plane (a floor's clusters), and the same two
        // facing each other across a gap: only the facing pair exchanges light. One grid moved
        // to face away from the other (below it, facing down) carries nothing either.
        let pair = |second: Vec<Patch>| {
            let mut patches = grid(0.0, true);
            patches.extend(second);
            let hier = hierarchy(patches);
            let tree = ClusterTree::build(&hier);
            let [a, b] = tree.nodes[0].kids;
            let (na, nb) = (tree.nodes[a as usize].clone(), tree.nodes[b as usize].clone());
            let w = (nb.center - na.center).normalize();
            carries_nothing(&na, &nb, w, link_frame(&na, &nb, w))
        };
        let beside: Vec<Patch> = grid(0.0, true)
            .into_iter()
            .map(|p| {
                let v = p.vertices.iter().map(|v| *v + DVec3::new(3.0, 0.0, 0.0)).collect();
                Patch::new(v, Rgb::splat(0.5), Rgb::ZERO, "grid", 0, "sq", "m").expect("valid square")
            })
            .collect();
        assert!(pair(beside), "coplanar grids exchange nothing");
        assert!(!pair(grid(1.5, false)), "facing grids exchange light");
        assert!(pair(grid(-1.5, false)), "a grid below facing down sees nothing of one facing up");
    }

    #[test]
    fn near_facing_clusters_are_not_overestimated() {
        // Two unit squares 1.5 apart, facing, each a cluster of 16 pieces (their spheres are
        // 0.09 apart, so linking accepts the pair). The point form A/(π d²) reads F = 0.141 where
        // the exact F is 0.115 (+23 %: light created in a closed room); the regularised distance
        // term must land within 6 %, and the transfer stays reciprocal.
        let mut patches = grid(0.0, true);
        patches.extend(grid(1.5, false));
        let hier = hierarchy(patches);
        let tree = ClusterTree::build(&hier);
        let [a, b] = tree.nodes[0].kids;
        let (in_a, in_b) = (members(&tree, a), members(&tree, b));
        assert_eq!((in_a.len(), in_b.len()), (16, 16), "the tree splits floor from ceiling");
        let (na, nb) = (&tree.nodes[a as usize], &tree.nodes[b as usize]);
        let d = na.center.distance(nb.center);
        assert!(d - na.radius - nb.radius > 0.0, "the spheres are apart");
        let w = (nb.center - na.center) / d;
        let frame = link_frame(na, nb, w);
        let links = vec![ClusterLink { a, b, vis: 1.0, frame }];
        let mut x = ClusterTransfer::new(&tree, &links);
        let area = |ids: &[u32]| ids.iter().map(|&i| hier.get(i).area).sum::<f64>();
        // F from `from` to `to`: 16 × 16 pieces, the exact kernel at each receiving centroid.
        let exact = |from: &[u32], to: &[u32]| {
            from.iter()
                .map(|&i| {
                    let e = hier.get(i);
                    let f: f64 = to
                        .iter()
                        .map(|&j| {
                            let s = hier.get(j);
                            form_factor::point_to_polygon_oriented(
                                e.centroid,
                                e.normal,
                                s.vertices(),
                                s.normal,
                            )
                        })
                        .sum();
                    f * e.area
                })
                .sum::<f64>()
                / area(from)
        };
        let f_exact = exact(&in_a, &in_b);
        let point = nb.projected_area(-w, frame) / (std::f64::consts::PI * d * d);
        assert!(point > 1.15 * f_exact, "the point form overestimates: {point} vs {f_exact}");
        let one_on = |on: &[u32]| {
            let on = on.to_vec();
            move |p: u32| if on.contains(&p) { Rgb::ONE } else { Rgb::ZERO }
        };
        let h = x.irradiance(&tree, &hier, &one_on(&in_b));
        let f_ab = in_a.iter().map(|&i| h[i as usize].0[0] * hier.get(i).area).sum::<f64>() / area(&in_a);
        assert!(
            (f_ab - f_exact).abs() <= 0.06 * f_exact,
            "transfer {f_ab} vs exact {f_exact} (point form {point})"
        );
        let h = x.irradiance(&tree, &hier, &one_on(&in_a));
        let f_ba = in_b.iter().map(|&i| h[i as usize].0[0] * hier.get(i).area).sum::<f64>() / area(&in_b);
        assert!((f_ab * area(&in_a) - f_ba * area(&in_b)).abs() <= 1e-12, "reciprocal: {f_ab} vs {f_ba}");
    }

    #[test]
    fn far_clusters_transfer_the_exact_form_factors() {
        // B = 1 on b, V = 1: each member of a gathers Σ_j F(x_i → j) (the exact point kernel at
        // its centroid, no occlusion), to the point approximation's accuracy: (r_a + r_b) / d
        // is 0.08 here; 3 % allowed on the total, 8 % per member.
        let (hier, tree, mut links, a, b) = two_clusters(40.0);
        links[0].vis = 1.0;
        let in_a = members(&tree, a);
        let in_b = members(&tree, b);
        let mut x = ClusterTransfer::new(&tree, &links);
        let h = x.irradiance(&tree, &hier, &|p| if in_b.contains(&p) { Rgb::ONE } else { Rgb::ZERO });
        let (mut tot_exact, mut tot) = (0.0, 0.0);
        for &i in &in_a {
            let e = hier.get(i);
            let exact: f64 = in_b
                .iter()
                .map(|&j| {
                    let s = hier.get(j);
                    form_factor::point_to_polygon_oriented(e.centroid, e.normal, s.vertices(), s.normal)
                })
                .sum();
            let got = h[i as usize].0[0];
            tot_exact += exact * e.area;
            tot += got * e.area;
            if exact > 1e-5 {
                assert!((got - exact).abs() <= 0.08 * exact, "member {i}: {got} vs exact {exact}");
            } else {
                assert!(got <= 1e-5, "member {i} faces away but gathers {got}");
            }
        }
        assert!((tot - tot_exact).abs() <= 0.03 * tot_exact, "total {tot} vs exact {tot_exact}");
    }

    /// A square of side `side` centred at `c` in the plane z = c.z, facing up or down.
    fn square(c: DVec3, side: f64, up: bool) -> Patch {
        let h = side / 2.0;
        let mut v: Vec<DVec3> =
            [(-h, -h), (h, -h), (h, h), (-h, h)].iter().map(|&(x, y)| c + DVec3::new(x, y, 0.0)).collect();
        if !up {
            v.reverse();
        }
        Patch::new(v, Rgb::splat(0.5), Rgb::ZERO, "sq", 0, "sq", "m").expect("valid square")
    }

    /// A unit square on the floor under four dense stacks of twelve squares facing down, each
    /// linked to it by the cluster links that cover it (its leaf with the sibling of every node
    /// on its way to the root), all with V = 1: the members' summed cosines over the distance
    /// term give the square a row of 1.60, where its hemisphere holds 0.30 of front faces (the
    /// stacks' lowest squares; the eleven above each hide behind them). The bound cuts the row
    /// to what the square's rays see (0.38), leaves the hidden squares (which see only
    /// the back of the square below) almost nothing, and keeps the transfer reciprocal.
    #[test]
    fn a_dense_stack_of_occluders_is_bounded_by_the_hemisphere() {
        let mut patches = vec![square(DVec3::ZERO, 1.0, true)];
        for (x, y) in [(2.0, 0.0), (-2.0, 0.0), (0.0, 2.0), (0.0, -2.0)] {
            for i in 0..12 {
                patches.push(square(DVec3::new(x, y, 2.0 + 0.08 * f64::from(i)), 1.6, false));
            }
        }
        let scene = Scene::new("t", "test", patches);
        let accel = Accel::build(&scene);
        let hier = Hierarchy::from_scene(&scene);
        let tree = ClusterTree::build(&hier);
        let leaf = (0..tree.len() as u32).find(|&i| members(&tree, i) == [0]).expect("the square's leaf");
        let mut links = Vec::new();
        let mut at = leaf;
        while tree.nodes[at as usize].parent != LEAF {
            let parent = &tree.nodes[tree.nodes[at as usize].parent as usize];
            let sibling = if parent.kids[0] == at { parent.kids[1] } else { parent.kids[0] };
            let (na, nb) = (&tree.nodes[leaf as usize], &tree.nodes[sibling as usize]);
            let w = (nb.center - na.center).normalize();
            links.push(ClusterLink { a: leaf, b: sibling, vis: 1.0, frame: link_frame(na, nb, w) });
            at = tree.nodes[at as usize].parent;
        }
        let others: Vec<u32> = (1..hier.roots as u32).collect();
        let mut x = ClusterTransfer::new(&tree, &links);
        let unbounded = x.irradiance(&tree, &hier, &|_| Rgb::ONE)[0].0[0];
        let region = crate::solver::escape::Region {
            verts: hier.get(0).vertices(),
            normal: hier.get(0).normal,
            patch: 0,
        };
        let seen = crate::solver::escape::hemisphere(&scene, &accel, region, 1 << 14, 1, 2).front;
        assert!((0.25..0.45).contains(&seen), "the stacks' lowest squares fill {seen} of the hemisphere");
        assert!(unbounded > 1.0, "the unbounded row {unbounded} exceeds the hemisphere");
        let bound = x.bound_rows(&tree, &hier, &scene, &accel, 0);
        let row = bound.rows[0];
        assert!(row <= seen + 0.08 && row >= 0.8 * seen, "bounded row {row} against the {seen} seen");
        // Every hidden square (all but each stack's lowest) sees only the back of the one below.
        for q in (1..hier.roots).filter(|q| (q - 1) % 12 != 0) {
            assert!(bound.rows[q] <= 0.01, "hidden square {q}: row {}", bound.rows[q]);
        }
        assert!(bound.cut >= 1 && bound.cut_area_row > 0.0, "the square's row is cut: {bound:?}");
        // Reciprocal still: what the square gathers from the stacks is what they send to it.
        let bs = |p: u32| Rgb::new(0.2 + 0.05 * f64::from(p % 7), 0.4, 0.1 * f64::from(p % 3));
        let h = x.irradiance(&tree, &hier, &|p| if p == 0 { Rgb::ZERO } else { bs(p) });
        let received = h[0] * hier.get(0).area;
        let rows = x.irradiance(&tree, &hier, &|p| if p == 0 { Rgb::ONE } else { Rgb::ZERO });
        let sent =
            others.iter().fold(Rgb::ZERO, |s, &p| s + bs(p) * (hier.get(p).area * rows[p as usize].0[0]));
        for c in 0..3 {
            assert!((received.0[c] - sent.0[c]).abs() <= 1e-12 * sent.0[c], "{received:?} vs {sent:?}");
        }
    }
}
