//! A warm re-solve (`HierarchicalSolver::retarget`, `spec::solve_walk`): a finer threshold keeps
//! the hierarchy, the links and the radiosity and refines from there; a coarser one goes back to
//! a state solved no finer than it; anything else restarts.

mod common;

use radlab::geometry::accel::Accel;
use radlab::solver::hierarchical::HierarchicalSolver;
use radlab::solver::spec::{self, Preset};
use std::sync::Arc;

/// Light created or lost beyond the balance: as tests/presets.rs.
const BALANCE_TOL: f64 = 1e-3;
const CREATED_TOL: f64 = 1e-4;

fn ladder(eps: f64) -> radlab::solver::params::HierarchicalParams {
    spec::ladder_params(eps)
}

/// A finer threshold refines from where the coarser solve stopped: the leaves only multiply, the
/// step casts fewer rays than a cold solve at the finer threshold, and it conserves.
#[test]
fn a_finer_threshold_refines_from_the_last_state() {
    let scene = Arc::new(common::table_room());
    let accel = Arc::new(Accel::build(&scene));
    let mut warm = HierarchicalSolver::with_accel(Arc::clone(&scene), Arc::clone(&accel), ladder(0.2), 0.0);
    warm.solve(&mut |_, _| {});
    let coarse = warm.stats();
    assert!(warm.retarget(ladder(0.1)).unwrap(), "a finer threshold keeps the state");
    assert_eq!(warm.stats().leaves, coarse.leaves, "retarget alone changes nothing");
    warm.solve(&mut |_, _| {});
    let fine = warm.stats();
    assert!(fine.leaves > coarse.leaves, "{} leaves after {}", fine.leaves, coarse.leaves);

    let mut cold = HierarchicalSolver::with_accel(Arc::clone(&scene), Arc::clone(&accel), ladder(0.1), 0.0);
    cold.solve(&mut |_, _| {});
    let step_rays = fine.rays - coarse.rays;
    assert!(step_rays < cold.stats().rays, "warm step {step_rays} rays, cold {}", cold.stats().rays);

    let e = warm.solution_with(false).energy;
    assert!(e.relative_residual() < BALANCE_TOL, "{e:?}");
    for c in 0..3 {
        assert!(e.escaped.0[c] >= -CREATED_TOL * e.emitted.0[c], "light created: {e:?}");
    }
    // The same room lit the same way: every patch's average within a few percent of the cold
    // solve's (the two meshes differ: the cold solve's first rounds refine on unconverged light).
    let (w, c) = (warm.solution_with(false), cold.solution_with(false));
    let mean = c.patch_radiosity.iter().map(|b| b.mean()).sum::<f64>() / c.patch_radiosity.len() as f64;
    for (i, (a, b)) in w.patch_radiosity.iter().zip(&c.patch_radiosity).enumerate() {
        let d = (a.mean() - b.mean()).abs() / mean;
        assert!(d < 0.05, "patch {i}: warm {a:?} cold {b:?}");
    }
}

/// A coarser threshold than any solved, or any other setting changed, restarts from one element
/// per patch.
#[test]
fn a_coarser_threshold_or_another_setting_restarts() {
    let scene = Arc::new(common::table_room());
    let mut s = HierarchicalSolver::new(Arc::clone(&scene), ladder(0.1)).unwrap();
    s.solve(&mut |_, _| {});
    assert!(!s.retarget(ladder(0.2)).unwrap(), "coarser");
    assert_eq!(s.stats().leaves, scene.patches.len());
    s.solve(&mut |_, _| {});
    let rays = radlab::solver::params::HierarchicalParams { rays: ladder(0.05).rays + 1, ..ladder(0.05) };
    assert!(!s.retarget(rays).unwrap(), "another ray count");
    assert_eq!(s.stats().leaves, scene.patches.len());
    assert!(s.retarget(ladder(f64::NAN)).is_err(), "invalid parameters are refused");
}

/// A threshold made coarser goes back to the state solved there: after ε 0.2 → 0.1 → 0.2 the
/// solver holds the 0.2 solve's mesh and links again, and its re-solve refines nothing and
/// moves no patch's radiosity by more than the gathers' tolerance; 0.1 again brings back the
/// finer state. A threshold coarser than every kept state restarts, and so does any coarser
/// one with keeping off.
#[test]
fn a_coarser_threshold_goes_back_to_a_kept_state() {
    let scene = Arc::new(common::table_room());
    let mut s = HierarchicalSolver::new(Arc::clone(&scene), ladder(0.2)).unwrap();
    s.solve(&mut |_, _| {});
    let coarse = s.solution_with(false);
    let (leaves, links) = (s.stats().leaves, s.stats().links);
    assert!(s.retarget(ladder(0.1)).unwrap());
    s.solve(&mut |_, _| {});
    let (fine_leaves, fine_links) = (s.stats().leaves, s.stats().links);
    assert!(fine_leaves > leaves, "{fine_leaves} leaves after {leaves}");
    assert_eq!(s.kept_states(), 1, "the coarse state is kept");

    assert!(s.retarget(ladder(0.2)).unwrap(), "back to the kept state");
    assert_eq!((s.stats().leaves, s.stats().links), (leaves, links), "the coarse state's mesh and links");
    assert_eq!(s.kept_states(), 1, "the fine state is kept in its place");
    let (rays, gathers) = (s.stats().rays, s.stats().iterations);
    let rep = s.solve(&mut |_, _| {});
    assert_eq!((s.stats().leaves, s.stats().links), (leaves, links), "nothing more to refine");
    // Kept at exactly these thresholds, the state is that solve's answer again: no refinement,
    // no gather, the same radiosity to the bit.
    assert_eq!(
        (rep.refined, rep.new_links, s.stats().rays, s.stats().iterations),
        (0, 0, rays, gathers),
        "{rep:?}"
    );
    assert!(rep.converged && !rep.cancelled, "{rep:?}");
    let again = s.solution_with(false);
    assert_eq!(again.patch_radiosity, coarse.patch_radiosity, "the coarse solve's answer");
    // A refinement step after it, then a solve: the solve gathers again.
    s.refine_step();
    let rep = s.solve(&mut |_, _| {});
    assert!(s.stats().iterations > gathers && rep.converged, "{rep:?}");

    assert!(s.retarget(ladder(0.1)).unwrap(), "the finer state again");
    assert_eq!((s.stats().leaves, s.stats().links), (fine_leaves, fine_links));

    assert!(!s.retarget(ladder(0.4)).unwrap(), "coarser than every kept state");
    assert_eq!(s.stats().leaves, scene.patches.len());

    let mut off = HierarchicalSolver::new(Arc::clone(&scene), ladder(0.2)).unwrap();
    off.keep_solved_states(false);
    off.solve(&mut |_, _| {});
    assert!(off.retarget(ladder(0.1)).unwrap());
    off.solve(&mut |_, _| {});
    assert_eq!(off.kept_states(), 0);
    assert!(!off.retarget(ladder(0.2)).unwrap(), "nothing kept: a restart");
}

/// `solve_walk` walks the ladder warm on the contact mesh and reports each step.
#[test]
fn the_walk_reports_every_step_and_ends_at_the_last_threshold() {
    let scene = Arc::new(common::table_room());
    let accel = Arc::new(Accel::build(&scene));
    let (solved, steps) = spec::solve_walk(
        &scene,
        &accel,
        0.0,
        &Preset::Draft.spec(),
        &[0.2, 0.1],
        true,
        &mut |_, _| {},
        None,
        spec::Stopped::AsReached,
    )
    .unwrap();
    assert_eq!(steps.len(), 2);
    assert!(!steps[0].warm && steps[1].warm, "{steps:?}");
    assert!(steps[1].leaves > steps[0].leaves, "{steps:?}");
    assert_eq!(spec::threshold(solved.spec.hierarchical().unwrap()), 0.1);
    assert_eq!(solved.solution.method, "hierarchical on contact mesh");
    assert!(solved.solution.energy.relative_residual() < BALANCE_TOL);
}

/// `radlab solve builtin:table-room --threshold THRESHOLDS --json FILE`, which must succeed: its
/// stdout and stderr, and the JSON's `walk`.
fn cli_walk(thresholds: &str, file: &str) -> (String, Vec<serde_json::Value>) {
    let json = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(file);
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_radlab"))
        .args(["solve", "builtin:table-room", "--threshold", thresholds, "--json"])
        .arg(&json)
        .output()
        .unwrap();
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "{text}");
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    (text, doc["walk"].as_array().unwrap().clone())
}

/// `radlab solve --threshold A,B`: the walk in the summary and the JSON's `walk`.
#[test]
fn the_cli_walks_a_threshold_list() {
    let (text, walk) = cli_walk("0.2,0.1", "warm-walk.json");
    assert!(text.contains("threshold 0.1") && text.contains("warm"), "{text}");
    assert_eq!(walk.len(), 2);
    assert_eq!(walk[1]["warm"], true);
    assert_eq!(walk[1]["threshold"], 0.1);
}

/// A walk that turns back (0.2, 0.1, 0.2) ends on the first step's mesh, warm: the same leaves
/// and links as the first step, and the last step casts no rays (nothing is refined again).
#[test]
fn the_cli_walk_turns_back_to_a_solved_threshold() {
    let (text, walk) = cli_walk("0.2,0.1,0.2", "warm-walk-back.json");
    assert_eq!(walk.len(), 3);
    let (first, back) = (&walk[0], &walk[2]);
    assert_eq!(back["warm"], true, "{text}");
    assert_eq!((&back["leaves"], &back["links"]), (&first["leaves"], &first["links"]), "{text}");
    assert!(walk[1]["links"].as_u64() > first["links"].as_u64(), "{text}");
    assert_eq!(back["rays"], 0, "{text}");
}
