//! Scenes built in code for the solver tests (independent of the glTF loader), and how far a
//! solution of the furnace is from its closed form.
#![allow(dead_code)]

use radlab::math::{DVec3, Rgb};
use radlab::scene::{Patch, Scene};
use radlab::solver::Solution;

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
