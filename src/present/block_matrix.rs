//! The blocking form-factor matrix: the n × n matrix of leaf-to-leaf form factors that a uniform
//! mesh would need, with each hierarchical link drawn as the block of entries it stands for
//! [Hanrahan, Salzman, Aupperle 1991, fig. 3].
//!
//! ## How it works
//! The leaves are numbered in depth-first order of the quadtrees (patch by patch, children in
//! order), so the leaves below any element are one run `[start, end)` of that numbering. A link
//! receiver p ← source q then covers rows `p.start..p.end` and columns `q.start..q.end`: one
//! number, F_pq, standing in for every entry of that block. The blocks tile the matrix where
//! light is exchanged; their count is the link count, O(n), against the n² entries.
//!
//! ```text
//!           source leaves →
//!   r  ┌──────────┬──┬──┐
//!   e  │  one big │  │  │   a big block: two large, distant elements, one link
//!   c  │   link   ├──┼──┤
//!   ↓  │          │  │  │   small blocks: near pairs, split down to small elements
//!      └──────────┴──┴──┘
//! ```

use crate::present::overlay::{ElementView, LinkView};

/// One link as a block of the leaf-to-leaf matrix.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Block {
    /// Leaf rows `[start, end)` (the receiver's leaves).
    pub rows: (u32, u32),
    /// Leaf columns `[start, end)` (the source's leaves).
    pub cols: (u32, u32),
    pub receiver: u32,
    pub source: u32,
    pub ff: f32,
    /// Visible fraction of the link.
    pub vis: f32,
}

/// The matrix: `n` leaves on each side, one block per link.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BlockMatrix {
    pub n: u32,
    pub blocks: Vec<Block>,
    /// Each element's leaf run `[start, end)`, indexed by element id.
    pub runs: Vec<(u32, u32)>,
}

impl BlockMatrix {
    /// Number the leaves depth-first and turn every link into its block. Elements are indexed
    /// by id; parents come before their children (the hierarchy's arena order).
    #[must_use]
    pub fn build(elements: &[ElementView], links: &[LinkView]) -> BlockMatrix {
        let n = elements.len();
        let mut children: Vec<Vec<u32>> = vec![Vec::new(); n];
        let mut roots = Vec::new();
        for e in elements {
            match e.parent {
                Some(p) if (p as usize) < n => children[p as usize].push(e.id),
                _ => roots.push(e.id),
            }
        }
        let mut runs = vec![(0u32, 0u32); n];
        let mut next = 0u32;
        // Iterative depth-first walk: (element, children visited).
        let mut stack: Vec<(u32, bool)> = roots.iter().rev().map(|&r| (r, false)).collect();
        while let Some((id, done)) = stack.pop() {
            let i = id as usize;
            if done {
                runs[i].1 = next;
                continue;
            }
            runs[i].0 = next;
            if children[i].is_empty() {
                next += 1;
                runs[i].1 = next;
            } else {
                stack.push((id, true));
                stack.extend(children[i].iter().rev().map(|&c| (c, false)));
            }
        }
        let blocks = links
            .iter()
            .filter(|l| (l.receiver as usize) < n && (l.source as usize) < n)
            .map(|l| Block {
                rows: runs[l.receiver as usize],
                cols: runs[l.source as usize],
                receiver: l.receiver,
                source: l.source,
                ff: l.ff,
                vis: l.vis,
            })
            .collect();
        BlockMatrix { n: next, blocks, runs }
    }

    /// The block covering entry (row, col), if a link covers it (the last one drawn there).
    #[must_use]
    pub fn at(&self, row: u32, col: u32) -> Option<&Block> {
        self.blocks
            .iter()
            .rev()
            .find(|b| (b.rows.0..b.rows.1).contains(&row) && (b.cols.0..b.cols.1).contains(&col))
    }

    /// Fraction of the n² entries that the blocks cover (each entry once in a converged
    /// hierarchical solution of a closed scene, where every pair of leaves exchanges light
    /// through exactly one link or none).
    #[must_use]
    pub fn covered(&self) -> f64 {
        let n2 = f64::from(self.n) * f64::from(self.n);
        if n2 == 0.0 {
            return 0.0;
        }
        self.blocks
            .iter()
            .map(|b| f64::from(b.rows.1 - b.rows.0) * f64::from(b.cols.1 - b.cols.0))
            .sum::<f64>()
            / n2
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::hierarchical::HierarchicalSolver;
    use crate::solver::params::HierarchicalParams;

    #[test]
    fn blocks_cover_each_leaf_pair_at_most_once_and_runs_nest() {
        let scene = std::sync::Arc::new(crate::scene::builtin::load("perpendicular").unwrap());
        let mut s = HierarchicalSolver::new(scene, HierarchicalParams::lecture()).unwrap();
        s.refine_step();
        let v = views(&s.snapshot());
        let m = BlockMatrix::build(&v.0, &v.1);
        let leaves = v.0.iter().filter(|e| e.leaf).count() as u32;
        assert_eq!(m.n, leaves);
        assert_eq!(m.blocks.len(), v.1.len());
        // A parent's run is the union of its children's.
        for e in &v.0 {
            if let Some(p) = e.parent {
                let (ps, pe) = m.runs[p as usize];
                let (cs, ce) = m.runs[e.id as usize];
                assert!(ps <= cs && ce <= pe && cs < ce, "element {} outside its parent", e.id);
            }
        }
        // Leaf pairs across the two squares exchange light through exactly one link each way;
        // a square does not see itself.
        let mut count = vec![0u8; (leaves * leaves) as usize];
        for b in &m.blocks {
            for r in b.rows.0..b.rows.1 {
                for c in b.cols.0..b.cols.1 {
                    count[(r * leaves + c) as usize] += 1;
                }
            }
        }
        assert!(count.iter().all(|&c| c <= 1), "an entry covered twice");
        let covered = count.iter().filter(|&&c| c == 1).count() as f64 / f64::from(leaves * leaves);
        assert!((covered - m.covered()).abs() < 1e-12);
        assert!(covered > 0.3 && covered < 0.7, "about the two off-diagonal quarters: {covered}");
        assert!(m.blocks.len() < (leaves * leaves) as usize / 4, "far fewer links than entries");
        let b = m.blocks[0];
        assert!(m.at(b.rows.0, b.cols.0).is_some());
    }

    /// The snapshot's elements and links as the viewer shows them.
    fn views(s: &crate::solver::hierarchical::Snapshot) -> (Vec<ElementView>, Vec<LinkView>) {
        (
            s.elements.iter().map(ElementView::from_info).collect(),
            s.links.iter().map(LinkView::from_info).collect(),
        )
    }
}
