//! Scenes built in code for the solver tests (independent of the glTF loader), how far a
//! solution of the furnace is from its closed form, and the furnace solved at an oracle's
//! threshold (shared with `examples/conservation.rs`).
#![allow(dead_code)]

use radlab::geometry::accel::Accel;
use radlab::math::{DVec3, Rgb};
use radlab::scene::{Patch, Scene};
use radlab::solver::Solution;
use radlab::solver::params::HierarchicalParams;
use radlab::solver::spec::{self, Plan, Preset, SolveSpec};
use std::sync::Arc;

pub fn quad(v: [[f64; 3]; 4], rho: f64, e: f64, name: &str) -> Patch {
    Patch::new(
        v.iter().map(|a| DVec3::from_array(*a)).collect(),
        Rgb::splat(rho),
        Rgb::splat(e),
        name,
        0,
        name,
        "m",
    )
    .unwrap()
}

/// Unit cube with inward-facing faces: floor, ceiling, y=0, y=1, x=0, x=1.
pub fn cube_faces() -> [[[f64; 3]; 4]; 6] {
    [
        [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]],
        [[0., 0., 1.], [0., 1., 1.], [1., 1., 1.], [1., 0., 1.]],
        [[0., 0., 0.], [0., 0., 1.], [1., 0., 1.], [1., 0., 0.]],
        [[0., 1., 0.], [1., 1., 0.], [1., 1., 1.], [0., 1., 1.]],
        [[0., 0., 0.], [0., 1., 0.], [0., 1., 1.], [0., 0., 1.]],
        [[1., 0., 0.], [1., 0., 1.], [1., 1., 1.], [1., 1., 0.]],
    ]
}

/// Closed cube, every face emitting E with reflectance ρ.
pub fn furnace(rho: f64, e: f64) -> Scene {
    Scene::new("furnace", "test:furnace", cube_faces().iter().map(|f| quad(*f, rho, e, "wall")).collect())
}

/// Closed cube, the ceiling emitting 1, every face reflectance ρ.
/// The worst relative error of B over `solution`'s elements against the closed form of
/// [`furnace`]`(rho, 1.0)`, B = E / (1 − ρ) everywhere.
pub fn furnace_error(solution: &Solution, rho: f64) -> f64 {
    let exact = 1.0 / (1.0 - rho);
    solution.elements.iter().map(|e| (e.radiosity.max_channel() / exact - 1.0).abs()).fold(0.0, f64::max)
}

pub fn cube_one_light(rho: f64) -> Scene {
    let f = cube_faces();
    Scene::new(
        "cube-one-light",
        "test:cube-one-light",
        f.iter().enumerate().map(|(i, v)| quad(*v, rho, if i == 1 { 1.0 } else { 0.0 }, "wall")).collect(),
    )
}

/// Two unit squares sharing the edge x=0..1, y=0, z=0: floor (emitting) and a wall.
pub fn perpendicular() -> Scene {
    Scene::new(
        "perpendicular",
        "test:perpendicular",
        vec![
            quad([[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]], 0.5, 1.0, "floor"),
            quad([[0., 0., 0.], [0., 0., 1.], [1., 0., 1.], [1., 0., 0.]], 0.5, 0.0, "wall"),
        ],
    )
}

/// A closed room with a table under a small ceiling light (shadows).
pub fn table_room() -> Scene {
    let mut p: Vec<Patch> = cube_faces().iter().map(|f| quad(*f, 0.6, 0.0, "room")).collect();
    // light: small quad just below the ceiling, facing down
    p.push(quad(
        [[0.4, 0.4, 0.99], [0.4, 0.6, 0.99], [0.6, 0.6, 0.99], [0.6, 0.4, 0.99]],
        0.0,
        20.0,
        "light",
    ));
    // table top (both faces), at z = 0.4
    p.push(quad([[0.3, 0.3, 0.4], [0.7, 0.3, 0.4], [0.7, 0.7, 0.4], [0.3, 0.7, 0.4]], 0.5, 0.0, "table-top"));
    p.push(quad(
        [[0.3, 0.3, 0.39], [0.3, 0.7, 0.39], [0.7, 0.7, 0.39], [0.7, 0.3, 0.39]],
        0.5,
        0.0,
        "table-bottom",
    ));
    Scene::new("table-room", "test:table-room", p)
}

pub fn solve(scene: Scene, spec: &SolveSpec) -> spec::Solved {
    let scene = Arc::new(scene);
    let accel = Arc::new(Accel::build(&scene));
    spec::solve(&scene, &accel, 0.0, spec, &mut |_, _| {}, None).unwrap()
}

/// `preset`'s spec with its oracle's threshold at `threshold` (the error oracle's area floor
/// following it, as on the ladder), iterated to 1e-10, edited by `edit`.
pub fn furnace_spec(preset: Preset, threshold: f64, edit: impl Fn(&mut HierarchicalParams)) -> SolveSpec {
    let mut s = preset.spec();
    if let Plan::Hierarchical { params, .. } = &mut s.plan {
        *params = HierarchicalParams {
            tolerance: 1e-10,
            max_iterations: 1000,
            ..spec::with_threshold(*params, threshold, true)
        };
        edit(params);
    }
    s
}

/// A furnace solve's (worst relative error of B, leaves, escaped / emitted).
pub fn furnace_solve(rho: f64, spec: &SolveSpec) -> (f64, usize, f64) {
    let s = solve(furnace(rho, 1.0), spec);
    let worst = furnace_error(&s.solution, rho);
    let e = s.solution.energy;
    (worst, s.solution.elements.len(), e.escaped.mean() / e.emitted.mean())
}

/// The oracles' thresholds of the furnace sweeps (Feps; BFeps and ε relative, to the brightest
/// emission and to the mean reflected radiosity): 0.1 down to 1e-4.
pub const THRESHOLDS: [f64; 4] = [0.1, 1e-2, 1e-3, 1e-4];
