//! The row bound of the cluster links: each patch's row of F·V through them is held within
//! what its own hemisphere sees of the patches they cover (cosine-distributed rays), by one
//! factor per patch on both ends of its links, so the transfer stays reciprocal.
//! ```text
//! row_p = s_p Σ_q F_pq s_q  ≤  seen_p,      s = min(1, seen / F s)
//! ```

use super::transfer::ClusterTransfer;
use super::tree::{ClusterTree, LEAF};
use crate::geometry::accel::Accel;
use crate::math::Rgb;
use crate::solver::hierarchy::Hierarchy;
use rayon::prelude::*;

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
                    let set = crate::solver::escape::HemisphereRays { region, rays, key, seed };
                    crate::solver::escape::cast_hemisphere(scene, accel, set, |hit| {
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
