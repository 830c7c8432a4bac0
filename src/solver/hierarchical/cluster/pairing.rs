//! Linking the cluster tree (SAG94's `Link`, from the root's link with itself): a node is
//! linked with itself as its children's three pairs, two patches get HSA91's element links, a
//! pair whose spheres are apart and that `accept` passes gets one cluster link, and otherwise
//! the larger cluster is split. In a fixed order, whole or a batch at a time.

use super::tree::ClusterTree;
use rayon::prelude::*;

/// A link between two nodes, at least one of them a cluster. Both directions transfer.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct ClusterLink {
    pub a: u32,
    pub b: u32,
    pub vis: f32,
    /// The frame (index into [`FRAMES`](super::FRAMES)) both ends' cosines are taken in.
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

    pub(super) fn link_batched_in<F: Fn(u32, u32) -> bool + Sync>(
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
}
