//! The rows against the hemispheres: a point's row of form factors is bounded by the part of its
//! hemisphere that front faces fill,
//!
//! ```text
//! row_x = Σ_links F·V  ≤  f_front(x) = ∫_Ω [ray x → ω meets a front face] cos θ dω / π   ≤ 1
//! ```
//!
//! and each share of it by the part those links cover: the cluster links on x's patch and its
//! ancestors in the cluster tree cover the patches of their other ends, the element links every
//! other patch (clustering covers every pair of patches exactly once, [`super::cluster`]).
//! Cosine-distributed rays from each leaf ([`crate::solver::escape::cast_hemisphere`]) measure
//! both fractions; a share above its own is light the solve creates. [Cohen & Wallace 1993,
//! ch. 2: Σ_j F_ij ≤ 1; Smits, Arvo & Greenberg 1994 for the cluster links.]

use super::cluster::ClusterTree;
use super::{HierarchicalSolver, cluster};
use crate::solver::escape::{HemisphereRays, Hit, Region, cast_hemisphere};
use rayon::prelude::*;
use serde::Serialize;

/// One leaf's row of F·V and its hemisphere, as the rays found it.
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize)]
pub struct LeafAudit {
    pub id: u32,
    pub patch: u32,
    pub area: f64,
    /// Its radiosity, mean over the channels.
    pub radiosity: f64,
    /// Σ F·V through element links (own, inherited, with the slopes' shift) and through the
    /// cluster links of its patch.
    pub row_element: f64,
    pub row_cluster: f64,
    /// Cosine-weighted fractions of its hemisphere: front faces of patches its element links
    /// cover, front faces of patches its cluster links cover, back faces, nothing.
    pub front_element: f64,
    pub front_cluster: f64,
    pub back: f64,
    pub out: f64,
    pub rays: u32,
}

impl HierarchicalSolver {
    /// Every leaf's [`LeafAudit`], with `rays` cosine-distributed rays each (seeded, the same
    /// for any thread count). A ray cast per ray: for tests and measurements.
    #[must_use]
    pub fn row_audit(&self, rays: u32, seed: u64) -> Vec<LeafAudit> {
        let rows = self.leaf_rows();
        let clustered = self.cluster.tree.as_deref().filter(|_| !self.cluster.links.is_empty());
        let pos = clustered.map(ClusterTree::positions).unwrap_or_default();
        let (scene, accel, hier, xfer) =
            (&self.setup.scene, &self.setup.accel, &self.hier, &self.cluster.xfer);
        rows.par_iter()
            .with_min_len(64)
            .map(|r| {
                let e = hier.get(r.id);
                let mut a = LeafAudit {
                    id: r.id,
                    patch: e.patch,
                    area: e.area,
                    radiosity: e.radiosity.mean(),
                    row_element: r.row - r.cluster,
                    row_cluster: r.cluster,
                    rays,
                    ..LeafAudit::default()
                };
                let ranges = clustered.map(|t| xfer.covered(t, e.patch)).unwrap_or_default();
                let region = Region { verts: e.vertices(), normal: e.normal, patch: e.patch };
                let set = HemisphereRays { region, rays, key: u64::from(r.id), seed: seed ^ 0xA0D1 };
                cast_hemisphere(scene, accel, set, |hit| match hit {
                    Hit::Out => a.out += 1.0,
                    Hit::Back(_) => a.back += 1.0,
                    Hit::Front(q) if !ranges.is_empty() && cluster::covers(&ranges, pos[q as usize]) => {
                        a.front_cluster += 1.0;
                    }
                    Hit::Front(_) => a.front_element += 1.0,
                });
                let n = f64::from(rays.max(1));
                for x in [&mut a.front_element, &mut a.front_cluster, &mut a.back, &mut a.out] {
                    *x /= n;
                }
                a
            })
            .collect()
    }
}
