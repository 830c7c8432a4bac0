//! The hierarchical solver's own a-posteriori error estimate per element, without a reference
//! solution. Its quality is measured against the independent reference by Spearman rank
//! correlation (`radlab reference --compare`, tests/metrics.rs).

use super::hierarchical::HierarchicalSolver;
use rayon::prelude::*;

/// The solver's own a-posteriori error estimate of every leaf's radiosity (units of B),
/// without a reference: for each link on the leaf's ancestor chain, ρ · B_source · F · (g + u)
/// with g = receiver diameter / distance (how much F varies across the receiver, capped at 1)
/// and u = √(V(1−V)/rays) (the visibility estimate's standard error); plus half the leaf's
/// difference from its parent (radiosity variation among siblings that a finer mesh would
/// resolve). Indexed by element id; interior elements get the area average of their leaves.
#[must_use]
pub fn error_estimates(solver: &HierarchicalSolver) -> Vec<f64> {
    let hier = solver.hierarchy();
    let rays = f64::from(solver.params().rays.max(1));
    let mut est: Vec<f64> = (0..hier.len() as u32)
        .into_par_iter()
        .map(|x| {
            let leaf = hier.get(x);
            if !leaf.is_leaf() {
                return 0.0;
            }
            let rho = leaf.reflectance.max_channel();
            let mut e = 0.0;
            for a in hier.ancestors(x) {
                let recv = hier.get(a);
                let diam = recv.diameter();
                for l in &solver.links().by_receiver[a as usize] {
                    let src = hier.get(l.source);
                    let dist = recv.centroid.distance(src.centroid).max(1e-300);
                    let g = (diam / dist).min(1.0);
                    let v = f64::from(l.vis);
                    let u = (v * (1.0 - v) / rays).sqrt();
                    e += src.radiosity.max_channel() * f64::from(l.ff) * leaf.norm * (g + u);
                }
            }
            let var = leaf.parent().map_or(0.0, |p| 0.5 * leaf.radiosity.abs_diff_max(hier.get(p).radiosity));
            rho * e + var
        })
        .collect();
    // Interior elements: area-weighted average of their children (children have larger ids).
    for i in (0..hier.len()).rev() {
        if let Some(kids) = hier.elements[i].children() {
            let a = hier.elements[i].area;
            est[i] = kids.iter().map(|&c| est[c as usize] * hier.get(c).area / a).sum();
        }
    }
    est
}
