//! The built-in scenes: assets equal the writer's output for the code geometry, every scene loads
//! through the glTF loader, validates, emits, has the expected patch counts, and closed rooms
//! face inward.
//!
//! Regenerate the assets after changing `src/scene/builtin.rs` or the writer:
//! `RADLAB_WRITE_ASSETS=1 cargo test --no-default-features --test builtin_scenes`, then once more
//! without the variable (the assets are embedded with `include_bytes!`, so the first run's other
//! tests still load the old copies).

use radlab::math::DVec3;
use radlab::scene::builtin::{BUILTINS, build, load};
use radlab::scene::gltf::gltf_string;
use radlab::scene::{Scene, SceneError};
use std::path::PathBuf;

/// Positions, ρ and E go through f32 in the file: relative round-off of f32 (2^-24) with margin.
const F32_REL: f64 = 1e-6;
/// Coordinates of the scenes are at most ~1000 units: absolute f32 position error bound.
const POS_ABS: f64 = 1e-3 * F32_REL * 1e3;

const CODE_BUILT: &[&str] = &[
    "cornell",
    "perpendicular",
    "parallel",
    "furnace",
    "cube-one-light",
    "table-room",
    "shadow-wide",
    "shadow-narrow",
    "thin-pole",
];

fn asset_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/scenes").join(format!("{name}.gltf"))
}

#[test]
fn assets_equal_writer_output() {
    let write = std::env::var_os("RADLAB_WRITE_ASSETS").is_some();
    for name in CODE_BUILT {
        let scene = build(name).unwrap();
        let text = gltf_string(&scene).unwrap();
        let path = asset_path(name);
        if write {
            std::fs::write(&path, &text).unwrap();
        }
        let on_disk = std::fs::read_to_string(&path).unwrap();
        assert!(
            on_disk == text,
            "{} differs from write_gltf(build({name:?})); regenerate with RADLAB_WRITE_ASSETS=1",
            path.display()
        );
    }
}

fn close(a: f64, b: f64, abs: f64) -> bool {
    (a - b).abs() <= abs + F32_REL * a.abs().max(b.abs())
}

#[test]
fn loaded_builtins_match_code_geometry() {
    for name in CODE_BUILT {
        let built = build(name).unwrap();
        let loaded = load(name).unwrap();
        assert_eq!(loaded.source, format!("builtin:{name}"));
        assert_eq!(loaded.patches.len(), built.patches.len(), "{name}: patch count (quads must merge back)");
        for (i, (a, b)) in built.patches.iter().zip(&loaded.patches).enumerate() {
            assert_eq!(a.vertices.len(), b.vertices.len(), "{name} patch {i}");
            for (p, q) in a.vertices.iter().zip(&b.vertices) {
                assert!(p.distance(*q) <= POS_ABS + F32_REL * p.length(), "{name} patch {i}: {p} vs {q}");
            }
            assert_eq!(a.name, b.name, "{name} patch {i}");
            assert_eq!(a.mesh, b.mesh, "{name} patch {i}");
            assert_eq!(a.material, b.material, "{name} patch {i}");
            for c in 0..3 {
                assert!(close(a.reflectance.0[c], b.reflectance.0[c], 0.0), "{name} patch {i} rho");
                assert!(close(a.emission.0[c], b.emission.0[c], 0.0), "{name} patch {i} E");
            }
        }
        match (built.camera, loaded.camera) {
            (None, None) => {}
            (Some(a), Some(b)) => {
                assert!(a.eye.distance(b.eye) <= POS_ABS + F32_REL * a.eye.length(), "{name} camera eye");
                let da = (a.target - a.eye).normalize();
                let db = (b.target - b.eye).normalize();
                assert!(da.dot(db) > 1.0 - F32_REL, "{name} camera direction");
                assert!(close(a.fov_y_deg, b.fov_y_deg, 0.0), "{name} fov");
                assert!(b.up.dot(a.up.reject_from(da).normalize()) > 1.0 - F32_REL, "{name} camera up");
            }
            (a, b) => panic!("{name}: camera {a:?} vs {b:?}"),
        }
    }
}

fn check_common(name: &str, s: &Scene) {
    assert!(s.validate().is_empty(), "{name}: {:?}", s.validate());
    assert!(s.patches.iter().any(|p| p.is_emitter()), "{name}: no emitter");
    assert!(s.emitted_power().max_channel() > 0.0);
}

/// Every patch of a closed box faces the box's centre.
fn faces_inward(s: &Scene, patches: impl Iterator<Item = usize>) {
    let c = s.bounds().center();
    for i in patches {
        let p = &s.patches[i];
        assert!(p.normal.dot(c - p.centroid) > 0.0, "{}: patch {i} ({}) faces outward", s.name, p.name);
    }
}

#[test]
fn every_builtin_loads_validates_and_emits() {
    for (name, _) in BUILTINS {
        let s = load(name).unwrap();
        check_common(name, &s);
        assert!(!s.patches.is_empty());
    }
    assert!(matches!(load("nope"), Err(SceneError::UnknownBuiltin { .. })));
    assert!(build("nope").is_none());
    assert!(build("splash_room").is_none());
}

#[test]
fn simple_scenes_have_expected_counts_and_orientation() {
    let p = load("perpendicular").unwrap();
    assert_eq!(p.patches.len(), 2);
    assert!(p.patches[0].normal.dot(p.patches[1].normal).abs() < 1e-12);
    // Both face into the quarter space between them.
    assert!(p.patches[0].normal.dot(DVec3::Y) > 0.99 && p.patches[1].normal.dot(DVec3::X) > 0.99);

    let q = load("parallel").unwrap();
    assert_eq!(q.patches.len(), 2);
    assert!(q.patches[0].normal.dot(q.patches[1].normal) < -0.999);
    assert!((q.patches[0].centroid.distance(q.patches[1].centroid) - 1.0).abs() < 1e-6);

    for name in ["furnace", "cube-one-light"] {
        let s = load(name).unwrap();
        assert_eq!(s.patches.len(), 6, "{name}");
        assert!((s.total_area() - 6.0).abs() < 1e-6, "{name}");
        faces_inward(&s, 0..6);
    }
    let f = load("furnace").unwrap();
    assert!(f.patches.iter().all(|p| p.emission.0 == [1.0; 3] && p.reflectance.0 == [0.5; 3]));
    let c = load("cube-one-light").unwrap();
    assert_eq!(c.patches.iter().filter(|p| p.is_emitter()).count(), 1);
}

#[test]
fn cornell_box_is_the_published_one() {
    let s = load("cornell").unwrap();
    // floor 1 + ceiling 4 + light 1 + back 1 + right 1 + left (non-planar: 2 triangles) + 2 blocks × 5.
    assert_eq!(s.patches.len(), 20);
    assert_eq!(s.patches.iter().filter(|p| p.vertices.len() == 3).count(), 2, "left wall is two triangles");
    let b = s.bounds();
    assert!(close(b.max.x, 556.0, 0.0) && close(b.max.y, 548.8, 0.0) && close(b.max.z, 559.2, 0.0));
    let light: Vec<_> = s.patches.iter().filter(|p| p.is_emitter()).collect();
    assert_eq!(light.len(), 1);
    assert!(close(light[0].area, 130.0 * 105.0, 1e-6));
    assert!(light[0].normal.dot(-DVec3::Y) > 0.999, "light faces down");
    // Walls, floor, ceiling and light face the inside of the box; blocks face outward.
    let room: Vec<usize> = (0..s.patches.len()).filter(|&i| !s.patches[i].mesh.contains("block")).collect();
    faces_inward(&s, room.into_iter());
    for (mesh, h) in [("short_block", 165.0), ("tall_block", 330.0)] {
        let faces: Vec<_> = s.patches.iter().filter(|p| p.mesh == mesh).collect();
        assert_eq!(faces.len(), 5);
        let c = faces.iter().map(|p| p.centroid).sum::<DVec3>() / 5.0;
        for p in &faces {
            assert!(p.normal.dot(p.centroid - c) > 0.0, "{}: faces inward", p.name);
        }
        assert!(faces.iter().any(|p| close(p.centroid.y, h, 1e-6) && p.normal.y > 0.999));
    }
    let cam = s.camera.unwrap();
    assert!(cam.eye.distance(DVec3::new(278.0, 273.0, -800.0)) < 1e-3);
    assert!(close(cam.fov_y_deg, 39.3077, 1e-3));
    let white = s.patches.iter().find(|p| p.material == "white").unwrap();
    assert!(close(white.reflectance.0[0], 0.725, 0.0));
}

#[test]
fn table_room_is_closed_with_a_small_light() {
    let s = load("table-room").unwrap();
    // floor + 4 walls + 4 ceiling pieces + light + table top 6 + 4 legs × 4 sides.
    assert_eq!(s.patches.len(), 1 + 4 + 4 + 1 + 6 + 16);
    let room: Vec<usize> = (0..s.patches.len())
        .filter(|&i| ["floor", "walls", "ceiling", "light"].contains(&s.patches[i].mesh.as_str()))
        .collect();
    assert_eq!(room.len(), 10);
    faces_inward(&s, room.into_iter());
    let light_area: f64 = s.patches.iter().filter(|p| p.is_emitter()).map(|p| p.area).sum();
    let ceiling_area: f64 = s.patches.iter().filter(|p| p.mesh == "ceiling").map(|p| p.area).sum();
    assert!(close(light_area + ceiling_area, 16.0, 1e-9), "light fills the hole in the ceiling");
    assert!(light_area < 0.02 * s.total_area(), "small light");
    assert!(s.camera.is_some());
}

#[test]
fn splash_rooms_load_with_the_rho_clamp() {
    for (name, polygons) in [("splash_room", 216), ("splash_largeroom", 305)] {
        let s = load(name).unwrap();
        // Each SPLASH-2 polygon is one primitive: a triangle, or a planar convex quad stored as two
        // triangles which merge back. So one patch per polygon, in polygon order; except wall 1,
        // which the poster (polygon 6) covers in its own plane: it is cut around the poster into
        // four pieces (`scene::decal`), the first in its place and three at the end.
        assert_eq!(s.patches.len(), polygons + 3, "{name}");
        assert!(
            s.patches[..polygons].iter().enumerate().all(|(i, p)| p.primitive == i),
            "{name}: one patch per polygon"
        );
        assert!(
            s.patches[polygons..].iter().all(|p| p.primitive == 1 && p.name.starts_with("mesh0/1/0#cut")),
            "{name}"
        );
        assert!(
            s.warnings.iter().any(|w| w.contains("1 patch(es) cut around 1 coplanar decal(s)")),
            "{name}: {:?}",
            s.warnings
        );
        let wall: f64 = s.patches.iter().filter(|p| p.primitive == 1).map(|p| p.area).sum();
        let (w1, poster) = (1694.0 * 1600.0, 435.0 * 498.4);
        assert!((wall - (w1 - poster)).abs() < 0.01 * poster, "{name}: wall 1 minus the poster, {wall}");
        assert!(
            s.patches.iter().filter(|p| p.vertices.len() == 4).count() > polygons / 2,
            "{name}: quads merged"
        );
        assert!(s.warnings.iter().any(|w| w.contains("clamped")), "{name}: {:?}", s.warnings);
        assert!(s.patches.iter().all(|p| p.reflectance.max_channel() <= radlab::scene::RHO_MAX));
    }
}
