//! The conservation measurements behind docs/solver.md ("Closed rows"), too long for the test
//! suite (tests/furnace_oracles.rs asserts their claims at coarser settings):
//!
//! ```sh
//! cargo run --release --no-default-features --example conservation -- furnace   # about 2 min
//! cargo run --release --no-default-features --example conservation -- energy    # about 15 min
//! ```
//!
//! `furnace`: the white furnace under every oracle, ρ 0.5 and 0.9, thresholds 0.1 to 1e-4, at
//! the presets' own area floors: the worst relative error of B, the leaves, the escaped power.
//! `energy`: every preset on every built-in scene: escaped and absorbed against the emitted
//! power. Environment filters, comma-separated: `PRESETS`, `THRESHOLDS`, `SCENES`.

#[path = "../tests/common/mod.rs"]
mod common;

use radlab::scene::Scene;
use radlab::solver::spec::Preset;
use std::time::Instant;

/// Whether the comma-separated filter in `var` (absent: everything) lets `name` through.
fn pick(var: &str, name: &str) -> bool {
    std::env::var(var).map_or(true, |v| v.split(',').any(|x| x == name))
}

fn furnace_table() {
    for preset in [Preset::Bf, Preset::Lecture, Preset::Quality, Preset::Splash2] {
        for rho in [0.5, 0.9] {
            for threshold in common::THRESHOLDS {
                if !pick("PRESETS", preset.name()) || !pick("THRESHOLDS", &threshold.to_string()) {
                    continue;
                }
                let t = Instant::now();
                let (worst, leaves, escaped) =
                    common::furnace_solve(rho, &common::furnace_spec(preset, threshold, |_| {}));
                println!(
                    "{:<8} rho {rho} threshold {threshold:<6}: worst {worst:.2e}  leaves {leaves:>7}  escaped {escaped:+.2e}  {:.2} s",
                    preset.name(),
                    t.elapsed().as_secs_f64()
                );
            }
        }
    }
}

fn energy_table() {
    for &(name, _) in radlab::scene::builtin::BUILTINS {
        for preset in Preset::ALL {
            if !pick("SCENES", name) || !pick("PRESETS", preset.name()) {
                continue;
            }
            let t = Instant::now();
            let scene = match Scene::load(&format!("builtin:{name}")) {
                Ok(s) => s,
                Err(e) => {
                    eprintln!("conservation: builtin:{name}: {e}");
                    std::process::exit(1);
                }
            };
            let s = common::solve(scene, &preset.spec());
            let e = s.solution.energy;
            let escaped = (0..3).map(|c| e.escaped.0[c] / e.emitted.0[c]).fold(f64::INFINITY, f64::min);
            let absorbed = (0..3).map(|c| e.absorbed.0[c] / e.emitted.0[c]).fold(0.0, f64::max);
            println!(
                "{name:<17} {:<12} escaped {escaped:+.2e}  absorbed {absorbed:.6}  residual {:.1e}  leaves {:>7}  {:.2} s",
                preset.name(),
                e.relative_residual(),
                s.solution.elements.len(),
                t.elapsed().as_secs_f64()
            );
        }
    }
}

fn main() {
    match std::env::args().nth(1).as_deref() {
        Some("furnace") => furnace_table(),
        Some("energy") => energy_table(),
        _ => {
            eprintln!("usage: conservation furnace|energy (filters: PRESETS, THRESHOLDS, SCENES)");
            std::process::exit(2);
        }
    }
}
