//! The cluster tree: median splits of the input patches' centroids down to single patches
//! (a BVH over the patches), each node with its members' bounds, bounding sphere, area and the
//! projected-area moments the transfer reads; and the visibility of a link between two nodes,
//! cosine-weighted point pairs on area-sampled member patches [SAG94, sec. 4].

use super::frames::{FRAMES, abs_in};
use crate::geometry::accel::{Accel, NO_HIT};
use crate::geometry::visibility::point_on_polygon;
use crate::math::{DVec3, Pcg32, splitmix64};
use crate::solver::hierarchy::Hierarchy;

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

/// The cluster tree over the input patches; node 0 is the root, children have larger ids.
#[derive(Clone, Debug, Default)]
pub struct ClusterTree {
    pub nodes: Vec<ClusterNode>,
    /// The patches in tree order.
    pub order: Vec<u32>,
    /// Running member area over `order` (`cum_area[i]` = area of `order[..i]`).
    cum_area: Vec<f64>,
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

    /// Each patch's position in [`ClusterTree::order`].
    #[must_use]
    pub fn positions(&self) -> Vec<u32> {
        let mut pos = vec![0u32; self.order.len()];
        for (i, &p) in self.order.iter().enumerate() {
            pos[p as usize] = i as u32;
        }
        pos
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
