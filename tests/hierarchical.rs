//! Hierarchical radiosity: physics and algorithm tests (HSA91).

mod common;

use radlab::solver::hierarchical::HierarchicalSolver;
use radlab::solver::params::{AreaEps, HierarchicalParams, Oracle};
use std::sync::Arc;

/// Furnace: B = E/(1−ρ) exactly; 1e-6 relative is the target, reachable because the
/// per-leaf normalisation makes every leaf's total form factor exact in an enclosure.
const FURNACE_TOL: f64 = 1e-6;

fn solve(scene: radlab::scene::Scene, p: HierarchicalParams) -> HierarchicalSolver {
    let mut s = HierarchicalSolver::new(Arc::new(scene), p).unwrap();
    s.solve(&mut |_, _| {});
    s
}

#[test]
fn white_furnace_is_exact_at_any_feps_aeps() {
    for rho in [0.5, 0.9] {
        for (oracle, feps, aeps) in [
            (Oracle::Feps, 0.5, 0.1),
            (Oracle::Feps, 0.05, 0.01),
            (Oracle::Feps, 0.01, 0.002),
            (Oracle::Bf, 0.05, 0.005),
        ] {
            let p = HierarchicalParams {
                oracle,
                feps,
                aeps: AreaEps::Absolute(aeps),
                bf_eps: 0.05,
                tolerance: 1e-10,
                max_iterations: 1000,
                ..HierarchicalParams::interactive()
            };
            let s = solve(common::furnace(rho, 1.0), p);
            let sol = s.solution();
            let exact = 1.0 / (1.0 - rho);
            let worst = sol
                .elements
                .iter()
                .map(|e| (e.radiosity.max_channel() / exact - 1.0).abs())
                .fold(0.0, f64::max);
            assert!(sol.elements.len() > 6 || feps >= 0.5, "no refinement happened");
            assert!(
                worst < FURNACE_TOL,
                "rho {rho} {oracle:?} feps {feps} aeps {aeps}: worst rel err {worst:e} over {} elements",
                sol.elements.len()
            );
        }
    }
}
