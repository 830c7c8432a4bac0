//! The transfer through the cluster links [SAG94, Sillion 1995]: a link r ← s delivers
//! ```text
//! φ = I_s(−ω) V / (π d² + P_r(ω) + P_s(−ω)),   I_s(w) ≈ ½ (S·w + T·|w|)
//! ```
//! a patch receiver takes φ max(0, n·ω) at once, a cluster receiver keeps U = Σ φ ω and
//! W = Σ φ |ω|, pushed down the tree and read by each member patch as H = ½ (n·U + |n|·W).
//! The radiosity moments S and T are pulled up the tree from the patches first.

use super::frames::{FRAMES, abs_in};
use super::pairing::ClusterLink;
use super::slope::PatchSlope;
use super::tree::{ClusterTree, LEAF};
use crate::math::{DVec3, Rgb};
use crate::solver::hierarchy::Hierarchy;
use rayon::prelude::*;

/// Per-channel vector: one `Rgb` per axis.
type Vec3Rgb = [Rgb; 3];

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
pub(super) struct Incoming {
    pub(super) src: u32,
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
    pub(super) start: Vec<u32>,
    pub(super) incoming: Vec<Incoming>,
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
    pub(super) leaf: Vec<u32>,
    /// Each patch's factor s_p ≤ 1 on both ends of its cluster links (empty: all 1), so the
    /// transfer from q to p is s_p s_q times the cluster transfer: reciprocal still
    /// ([`ClusterTransfer::bound_rows`]).
    pub(super) scale: Vec<f64>,
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

    /// The irradiance, and the slopes when `with_slopes` (else no slopes, an empty list): the
    /// moments pulled up the tree, every receiving node's links summed, U and W pushed down,
    /// and the receiving end's factor applied.
    fn transfer(
        &mut self,
        tree: &ClusterTree,
        hier: &Hierarchy,
        b: &(impl Fn(u32) -> Rgb + Sync),
        with_slopes: bool,
    ) -> (Vec<Rgb>, Vec<[Rgb; 2]>) {
        if self.start.len() != tree.len() + 1 || self.leaf.len() != hier.roots {
            // No links (or a tree of another scene): nothing is gathered.
            let slopes = if with_slopes { vec![[Rgb::ZERO; 2]; hier.roots] } else { Vec::new() };
            return (vec![Rgb::ZERO; hier.roots], slopes);
        }
        self.pull_moments(tree, hier, b);
        let m = self.clusters.len();
        self.u.clear();
        self.u.resize(m, [Rgb::ZERO; 3]);
        self.w.clear();
        self.w.resize(m, [[Rgb::ZERO; 3]; FRAMES.len()]);
        let links = Links {
            patches: Patches { hier, b, scale: &self.scale },
            nodes: &self.nodes,
            s: &self.s,
            t: &self.t,
            start: &self.start,
            incoming: &self.incoming,
        };
        links.gather_clusters(&self.clusters, &mut self.u, &mut self.w);
        let (mut h, mut slopes) = links.gather_patches(&self.leaf, with_slopes);
        self.push_down(tree, hier, &mut h);
        self.scale_receivers(&mut h, &mut slopes);
        (h, slopes)
    }

    /// Pull the radiosity moments S and T up the tree (children have larger ids, so larger
    /// slots), from the patches' own.
    fn pull_moments(&mut self, tree: &ClusterTree, hier: &Hierarchy, b: &(impl Fn(u32) -> Rgb + Sync)) {
        let patches = Patches { hier, b, scale: &self.scale };
        let m = self.clusters.len();
        self.s.clear();
        self.s.resize(m, [Rgb::ZERO; 3]);
        self.t.clear();
        self.t.resize(m, [[Rgb::ZERO; 3]; FRAMES.len()]);
        for k in (0..m).rev() {
            let kids = tree.nodes[self.clusters[k] as usize].kids;
            let [(s0, t0), (s1, t1)] = kids.map(|kid| match self.nodes[kid as usize] {
                Node { patch: LEAF, slot, .. } => (self.s[slot as usize], self.t[slot as usize]),
                Node { patch, .. } => patches.moments(patch),
            });
            for c in 0..3 {
                self.s[k][c] = s0[c] + s1[c];
                for f in 0..FRAMES.len() {
                    self.t[k][f][c] = t0[f][c] + t1[f][c];
                }
            }
        }
    }

    /// Push U and W down (parents first; the root has none); leaves read their parent's with
    /// their normal into `h`.
    fn push_down(&mut self, tree: &ClusterTree, hier: &Hierarchy, h: &mut [Rgb]) {
        for i in 0..tree.len() {
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
    }

    /// The receiving end's factor ([`ClusterTransfer::bound_rows`]) on what each patch gathered.
    fn scale_receivers(&self, h: &mut [Rgb], slopes: &mut [[Rgb; 2]]) {
        for (p, &sp) in self.scale.iter().enumerate().filter(|(_, s)| **s < 1.0) {
            h[p] *= sp;
            if let Some(g) = slopes.get_mut(p) {
                *g = g.map(|g| g * sp);
            }
        }
    }
}

/// The patches as sources: radiosity `b`, times each patch's factor on both ends of its
/// cluster links (`scale`; empty: all 1).
struct Patches<'a, B> {
    hier: &'a Hierarchy,
    b: &'a B,
    scale: &'a [f64],
}

impl<B: Fn(u32) -> Rgb + Sync> Patches<'_, B> {
    fn factor(&self, p: u32) -> f64 {
        self.scale.get(p as usize).copied().unwrap_or(1.0)
    }

    /// A patch's moments, S = A B n and T = A B |n| per frame.
    fn moments(&self, p: u32) -> (Vec3Rgb, [Vec3Rgb; FRAMES.len()]) {
        let e = self.hier.get(p);
        let ab = (self.b)(p) * (e.area * self.factor(p));
        let (mut s, mut t) = ([Rgb::ZERO; 3], [[Rgb::ZERO; 3]; FRAMES.len()]);
        axpy(&mut s, e.normal, ab);
        for (f, tf) in t.iter_mut().enumerate() {
            axpy(tf, abs_in(f, e.normal), ab);
        }
        (s, t)
    }

    /// What patch `p` sends towards the unit direction `dir`.
    fn intensity(&self, p: u32, dir: DVec3) -> Rgb {
        let e = self.hier.get(p);
        (self.b)(p) * (e.area * self.factor(p) * e.normal.dot(dir).max(0.0))
    }
}

/// The links as the receiving nodes gather them: the sources' moments (pulled up) and the
/// links grouped by receiver. The nodes' centres, patches and slots are read from the compact
/// `nodes` (the tree's are 240 bytes, and the sources are visited at random).
struct Links<'a, B> {
    patches: Patches<'a, B>,
    nodes: &'a [Node],
    s: &'a [Vec3Rgb],
    t: &'a [[Vec3Rgb; FRAMES.len()]],
    start: &'a [u32],
    incoming: &'a [Incoming],
}

impl<B: Fn(u32) -> Rgb + Sync> Links<'_, B> {
    /// Intensity of node `x` towards the unit direction `dir` (cosines in frame `f`; `abs_dir`:
    /// |dir| in that frame).
    fn intensity(&self, x: u32, dir: DVec3, abs_dir: DVec3, f: usize) -> Rgb {
        match self.nodes[x as usize] {
            Node { patch: LEAF, slot, .. } => {
                let i = slot as usize;
                clamp0((dot(&self.s[i], dir) + dot(&self.t[i][f], abs_dir)) * 0.5)
            }
            Node { patch, .. } => self.patches.intensity(patch, dir),
        }
    }

    /// Node `r`'s incoming links.
    fn links_of(&self, r: usize) -> &[Incoming] {
        &self.incoming[self.start[r] as usize..self.start[r + 1] as usize]
    }

    /// Node `r`'s incoming links, in link order: (ω, |ω| in the link's frame, the frame, φ).
    fn gather(&self, r: usize) -> impl Iterator<Item = (DVec3, DVec3, usize, Rgb)> + '_ {
        let centre = self.nodes[r].centre;
        self.links_of(r).iter().map(move |inc| {
            let d = self.nodes[inc.src as usize].centre - centre;
            let d2 = d.length_squared();
            let omega = d / d2.sqrt();
            let f = usize::from(inc.frame);
            let abs_omega = abs_in(f, omega);
            // r gathers from the direction ω what the source sends towards −ω.
            let phi = self.intensity(inc.src, -omega, abs_omega, f) * f64::from(inc.coef);
            (omega, abs_omega, f, phi)
        })
    }

    /// Each receiving cluster sums its incoming links into its U and W, in parallel.
    fn gather_clusters(&self, clusters: &[u32], u: &mut [Vec3Rgb], w: &mut [[Vec3Rgb; FRAMES.len()]]) {
        u.par_iter_mut().zip(w.par_iter_mut()).enumerate().with_min_len(256).for_each(|(k, (u, w))| {
            for (omega, abs_omega, f, phi) in self.gather(clusters[k] as usize) {
                axpy(u, omega, phi);
                axpy(&mut w[f], abs_omega, phi);
            }
        });
    }

    /// What each patch gathers through its own links, at once with its normal, and (when
    /// `with_slopes`) their slope; in parallel.
    fn gather_patches(&self, leaf: &[u32], with_slopes: bool) -> (Vec<Rgb>, Vec<[Rgb; 2]>) {
        let roots = self.patches.hier.roots;
        if with_slopes {
            (0..roots).into_par_iter().with_min_len(256).map(|p| self.patch_gathers(leaf, p, true)).unzip()
        } else {
            let h =
                (0..roots).into_par_iter().with_min_len(256).map(|p| self.patch_gathers(leaf, p, false).0);
            (h.collect(), Vec::new())
        }
    }

    /// What patch `p` gathers through its own links (its node `leaf[p]`), and their slope
    /// ([`PatchSlope`]) when `with_slopes`.
    fn patch_gathers(&self, leaf: &[u32], p: usize, with_slopes: bool) -> (Rgb, [Rgb; 2]) {
        let Some(r) = leaf.get(p).filter(|&&r| r != LEAF).map(|&r| r as usize) else {
            return (Rgb::ZERO, [Rgb::ZERO; 2]);
        };
        let links = self.links_of(r);
        if links.is_empty() {
            return (Rgb::ZERO, [Rgb::ZERO; 2]);
        }
        let e = self.patches.hier.get(p as u32);
        let slope = if with_slopes { PatchSlope::new(e) } else { None };
        let mut direct = Rgb::ZERO;
        let mut grad = [Rgb::ZERO; 2];
        for ((omega, _, _, phi), inc) in self.gather(r).zip(links) {
            direct += phi * e.normal.dot(omega).max(0.0);
            if let Some(s) = &slope {
                let [gu, gv] = s.gradient(self.nodes[r].centre, self.nodes[inc.src as usize].centre, inc.reg);
                grad[0] += phi * gu;
                grad[1] += phi * gv;
            }
        }
        (direct, slope.map_or([Rgb::ZERO; 2], |s| s.limit(direct, grad)))
    }
}
