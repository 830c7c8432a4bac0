//! Every oracle conserves: the white furnace, B = E / (1 − ρ) everywhere, under every oracle of
//! the hierarchical solver and every threshold; and no preset creates light on a built-in scene.

mod common;

use radlab::geometry::accel::Accel;
use radlab::scene::Scene;
use radlab::solver::params::HierarchicalParams;
use radlab::solver::spec::{self, Plan, Preset, SolveSpec};
use std::sync::Arc;

fn solve(scene: Scene, spec: &SolveSpec) -> spec::Solved {
    let scene = Arc::new(scene);
    let accel = Arc::new(Accel::build(&scene));
    spec::solve(&scene, &accel, 0.0, spec, &mut |_, _| {}, None).unwrap()
}

/// `preset`'s spec with its oracle's threshold at `threshold`, iterated to 1e-10.
fn furnace_spec(preset: Preset, threshold: f64) -> SolveSpec {
    let mut s = preset.spec();
    if let Plan::Hierarchical { params, .. } = &mut s.plan {
        *params = HierarchicalParams {
            tolerance: 1e-10,
            max_iterations: 1000,
            ..spec::with_threshold(*params, threshold, true)
        };
    }
    s
}

/// (worst relative error of B, leaves, escaped / emitted).
fn furnace_error(preset: Preset, rho: f64, threshold: f64) -> (f64, usize, f64) {
    let s = solve(common::furnace(rho, 1.0), &furnace_spec(preset, threshold));
    let exact = 1.0 / (1.0 - rho);
    let worst = s
        .solution
        .elements
        .iter()
        .map(|e| (e.radiosity.max_channel() / exact - 1.0).abs())
        .fold(0.0, f64::max);
    let e = s.solution.energy;
    (worst, s.solution.elements.len(), e.escaped.mean() / e.emitted.mean())
}

/// The furnace table (release: `cargo test --release --test furnace_oracles -- --ignored
/// --nocapture`).
#[test]
#[ignore = "a measurement: prints the furnace table"]
fn furnace_table() {
    let pick = |var: &str, name: &str| std::env::var(var).map_or(true, |v| v.split(',').any(|x| x == name));
    for preset in [Preset::Bf, Preset::Lecture, Preset::Quality, Preset::Splash2] {
        for rho in [0.5, 0.9] {
            for threshold in [0.1, 0.01, 1e-3, 1e-4] {
                if !pick("PRESETS", preset.name()) || !pick("THRESHOLDS", &threshold.to_string()) {
                    continue;
                }
                let t = std::time::Instant::now();
                let (worst, leaves, escaped) = furnace_error(preset, rho, threshold);
                println!(
                    "{:<8} rho {rho} threshold {threshold:<6}: worst {worst:.2e}  leaves {leaves:>7}  escaped {escaped:+.2e}  {:.2} s",
                    preset.name(),
                    t.elapsed().as_secs_f64()
                );
            }
        }
    }
}

/// Every preset on every built-in scene: escaped and absorbed against the emitted power
/// (release: `cargo test --release --test furnace_oracles -- --ignored --nocapture`).
#[test]
#[ignore = "a measurement: prints the energy table"]
fn energy_table() {
    let pick = |var: &str, name: &str| std::env::var(var).map_or(true, |v| v.split(',').any(|x| x == name));
    for &(name, _) in radlab::scene::builtin::BUILTINS {
        for preset in Preset::ALL {
            if !pick("SCENES", name) || !pick("PRESETS", preset.name()) {
                continue;
            }
            let t = std::time::Instant::now();
            let s = solve(Scene::load(&format!("builtin:{name}")).unwrap(), &preset.spec());
            let e = s.solution.energy;
            let worst = (0..3).map(|c| e.escaped.0[c] / e.emitted.0[c]).fold(f64::INFINITY, f64::min);
            let absorbed = (0..3).map(|c| e.absorbed.0[c] / e.emitted.0[c]).fold(0.0, f64::max);
            println!(
                "{name:<17} {:<12} escaped {worst:+.2e}  absorbed {absorbed:.4}  residual {:.1e}  leaves {:>7}  {:.2} s",
                preset.name(),
                e.relative_residual(),
                s.solution.elements.len(),
                t.elapsed().as_secs_f64()
            );
        }
    }
}

#[test]
#[ignore = "diagnosis"]
fn odd_rows() {
    use radlab::solver::discontinuity::HierarchicalOnMesh;
    let scene = Arc::new(Scene::load("builtin:splash_room").unwrap());
    let preset = Preset::from_name(&std::env::var("PRESET").unwrap_or("draft".into())).unwrap();
    let s = preset.spec().resolved(&scene);
    let Plan::Hierarchical { params, top: spec::TopLevel::Mesh(mesh) } = s.plan else { panic!() };
    let params = HierarchicalParams { close_rows: std::env::var_os("ON").is_some(), ..params };
    let mut m = HierarchicalOnMesh::new(&scene, &mesh, params).unwrap();
    m.solver.solve(&mut |_, _| {});
    let audit = m.solver.row_audit(1024, 7);
    let pieces = m.solver.scene();
    let mut n = 0;
    for a in &audit {
        let row = a.row_element + a.row_cluster;
        let front = a.front_element + a.front_cluster;
        let want: Vec<u32> = std::env::var("PIECES").map(|v| v.split(',').map(|x| x.parse().unwrap()).collect()).unwrap_or_default();
        if (want.is_empty() && (row - front).abs() > 0.15) || want.contains(&a.patch) {
            n += 1;
            if n < 40 {
                let p = &pieces.patches[a.patch as usize];
                println!(
                    "leaf {} piece {} '{}' area {:.3e} row {row:.3} front {front:.3} back {:.3} out {:.3} B {:.3}",
                    a.id, a.patch, p.name, a.area, a.back, a.out, a.radiosity
                );
            }
        }
    }
    println!("{n} of {} leaves off by > 0.15", audit.len());
}
