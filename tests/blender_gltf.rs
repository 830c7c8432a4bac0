//! glTF as Blender writes it: the scenes in `tests/scenes/blender/`, authored and
//! exported by Blender's own exporter (`scripts/blender_scenes.py`, docs/blender_gltf.md), load
//! as authored. Each scene is there twice, as `.glb` and as glTF-separate (`.gltf` + `.bin` +
//! image files); both must give the same patches.
//!
//! What Blender itself says each scene is, world-space vertices per mesh in glTF's +Y-up frame,
//! is in `expected.json` (written by the script); the colours and strengths below are the ones
//! the script paints and sets.

use radlab::math::{DVec3, Rgb};
use radlab::scene::Scene;
use radlab::scene::gltf::{LoadOptions, load};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Positions pass through f32 and Blender's own f32 matrices: unit-size coordinates agree to
/// well within this.
const POS_TOL: f64 = 1e-5;
/// A PNG texel is exact; the texture mean of a patch inside one colour region is that colour.
const PNG_TOL: f64 = 1e-6;
/// JPEG (quality 100, 4:2:0 or 4:4:4) of a flat colour decodes within a couple of sRGB levels:
/// 3/255 in sRGB is at most ~0.012 in linear near 1.
const JPEG_TOL: f64 = 0.012;
/// Material factors are f32 in the file.
const F32_TOL: f64 = 1e-6;

/// sRGB bytes painted by the script (FLOOR_LEFT, FLOOR_RIGHT, WALL).
const FLOOR_LEFT: [u8; 3] = [200, 100, 50];
const FLOOR_RIGHT: [u8; 3] = [50, 150, 220];
const WALL: [u8; 3] = [180, 160, 120];

fn dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/blender")
}

fn linear(srgb: [u8; 3]) -> Rgb {
    let f = |b: u8| {
        let c = f64::from(b) / 255.0;
        if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
    };
    Rgb::new(f(srgb[0]), f(srgb[1]), f(srgb[2]))
}

fn close(a: Rgb, b: Rgb, tol: f64) -> bool {
    (0..3).all(|k| (a.0[k] - b.0[k]).abs() <= tol)
}

/// Both exports of a scene.
fn both(name: &str) -> Vec<(String, Scene)> {
    ["glb", "gltf"]
        .iter()
        .map(|ext| {
            let file = dir().join(format!("{name}.{ext}"));
            let scene = load(&file, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
            (format!("{name}.{ext}"), scene)
        })
        .collect()
}

fn expected() -> Value {
    let text = std::fs::read_to_string(dir().join("expected.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// Every mesh's patch corners are exactly the world-space vertices Blender reports for it
/// (node transforms and the hierarchy applied, Z-up turned into +Y-up).
fn check_world_vertices(label: &str, scene: &Scene, scene_name: &str) {
    let exp = expected();
    let meshes = exp["scenes"][scene_name].as_object().unwrap();
    for (mesh, verts) in meshes {
        let want: Vec<DVec3> = verts
            .as_array()
            .unwrap()
            .iter()
            .map(|v| {
                let c: Vec<f64> = v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
                DVec3::new(c[0], c[1], c[2])
            })
            .collect();
        let got: Vec<DVec3> =
            scene.patches.iter().filter(|p| &p.mesh == mesh).flat_map(|p| p.vertices.clone()).collect();
        assert!(!got.is_empty(), "{label}: no patches of mesh {mesh:?}");
        for w in &want {
            assert!(
                got.iter().any(|g| g.distance(*w) < POS_TOL),
                "{label}: mesh {mesh:?}: Blender's vertex {w:?} is no patch corner"
            );
        }
        for g in &got {
            assert!(
                want.iter().any(|w| g.distance(*w) < POS_TOL),
                "{label}: mesh {mesh:?}: patch corner {g:?} is no vertex of Blender's"
            );
        }
    }
}

#[test]
fn files_were_written_by_blender() {
    let exp = expected();
    assert!(exp["blender"].as_str().is_some_and(|v| v.starts_with("5.")), "{}", exp["blender"]);
    for name in ["room", "hierarchy", "materials", "light", "two_sided", "shadow"] {
        let text = std::fs::read_to_string(dir().join(format!("{name}.gltf"))).unwrap();
        let json: Value = serde_json::from_str(&text).unwrap();
        let generator = json["asset"]["generator"].as_str().unwrap_or("");
        assert!(generator.contains("Blender"), "{name}.gltf: generator {generator:?}");
    }
}

#[test]
fn room_textures_are_averaged_into_reflectance() {
    for (label, scene) in both("room") {
        check_world_vertices(&label, &scene, "room");
        // Floor: two quads (two triangles each, merged back), wall, panel; all single-sided.
        assert_eq!(scene.patches.len(), 4, "{label}: {:?}", scene.warnings);
        let floor: Vec<_> = scene.patches.iter().filter(|p| p.material == "floor").collect();
        assert_eq!(floor.len(), 2, "{label}");
        for p in &floor {
            assert_eq!(p.vertices.len(), 4, "{label}: floor patch is not a quad");
            assert!(p.normal.distance(DVec3::Y) < POS_TOL, "{label}: floor normal {:?}", p.normal);
            // u = x / 2: the left quad (x < 1) is painted FLOOR_LEFT, the right one FLOOR_RIGHT.
            let want = if p.centroid.x < 1.0 { linear(FLOOR_LEFT) } else { linear(FLOOR_RIGHT) };
            assert!(close(p.reflectance, want, PNG_TOL), "{label}: {:?} vs {want:?}", p.reflectance);
        }
        let wall: Vec<_> = scene.patches.iter().filter(|p| p.material == "wall").collect();
        assert_eq!(wall.len(), 1, "{label}");
        assert!(wall[0].normal.distance(DVec3::Z) < POS_TOL, "{label}: wall normal {:?}", wall[0].normal);
        assert!(
            close(wall[0].reflectance, linear(WALL), JPEG_TOL),
            "{label}: wall {:?} vs {:?}",
            wall[0].reflectance,
            linear(WALL)
        );
        // Emission colour (1, 0.8, 0.6) × strength 5, through KHR_materials_emissive_strength.
        let lamp: Vec<_> = scene.patches.iter().filter(|p| p.material == "lamp").collect();
        assert_eq!(lamp.len(), 1, "{label}");
        assert!(close(lamp[0].emission, Rgb::new(5.0, 4.0, 3.0), 5.0 * F32_TOL), "{:?}", lamp[0].emission);
        assert!(close(lamp[0].reflectance, Rgb::splat(0.2), F32_TOL), "{:?}", lamp[0].reflectance);
        assert!(lamp[0].normal.distance(-DVec3::Y) < POS_TOL, "{label}: panel faces {:?}", lamp[0].normal);
        assert!(scene.warnings.iter().all(|w| !w.contains("texture")), "{label}: {:?}", scene.warnings);
    }
}

#[test]
fn hierarchy_transforms_are_applied() {
    for (label, scene) in both("hierarchy") {
        // ChildPlane (1 quad) under the empty, GrandCube (6 quads) under the plane.
        assert_eq!(scene.patches.len(), 7, "{label}");
        check_world_vertices(&label, &scene, "hierarchy");
        // The cube's faces stay outward after three rotations and two non-uniform scales.
        let cube: Vec<_> = scene.patches.iter().filter(|p| p.mesh == "GrandCube").collect();
        let centre = cube.iter().map(|p| p.centroid).sum::<DVec3>() / cube.len() as f64;
        for p in &cube {
            assert!(p.normal.dot(p.centroid - centre) > 0.0, "{label}: {} faces inward", p.name);
        }
    }
}

#[test]
fn several_materials_become_several_primitives() {
    for (label, scene) in both("materials") {
        check_world_vertices(&label, &scene, "materials");
        assert_eq!(scene.patches.len(), 7, "{label}");
        let blocks: Vec<_> = scene.patches.iter().filter(|p| p.mesh == "Blocks").collect();
        assert_eq!(blocks.len(), 6, "{label}");
        let mut prims: Vec<usize> = blocks.iter().map(|p| p.primitive).collect();
        prims.dedup();
        assert_eq!(prims.len(), 3, "{label}: primitives {prims:?}");
        for (name, rho, n) in [
            ("red", Rgb::new(0.8, 0.1, 0.1), 2),
            ("green", Rgb::new(0.1, 0.7, 0.2), 2),
            ("glass", Rgb::splat(0.9), 2),
            ("blue", Rgb::new(0.1, 0.2, 0.6), 1),
        ] {
            let ps: Vec<_> = scene.patches.iter().filter(|p| p.material == name).collect();
            assert_eq!(ps.len(), n, "{label}: {name}");
            assert!(ps.iter().all(|p| close(p.reflectance, rho, F32_TOL)), "{label}: {name}");
        }
        // The glass material's transmission is an extension radlab does not read: named once.
        let w: Vec<_> = scene.warnings.iter().filter(|w| w.contains("KHR_materials_transmission")).collect();
        assert_eq!(w.len(), 1, "{label}: {:?}", scene.warnings);
        assert!(w[0].contains("not supported") && !w[0].contains('\n'), "{}", w[0]);
    }
}

#[test]
fn point_light_is_skipped_with_one_warning() {
    for (label, scene) in both("light") {
        check_world_vertices(&label, &scene, "light");
        assert_eq!(scene.patches.len(), 1, "{label}");
        assert!(scene.patches.iter().all(|p| p.emission == Rgb::ZERO));
        let w: Vec<_> = scene.warnings.iter().filter(|w| w.contains("KHR_lights_punctual")).collect();
        assert_eq!(w.len(), 1, "{label}: {:?}", scene.warnings);
        assert!(w[0].contains("1 light") && w[0].contains("skipped"), "{}", w[0]);
        assert!(!scene.warnings.iter().any(|w| w.contains("not supported")), "{:?}", scene.warnings);
    }
}

#[test]
fn double_sided_plane_gives_two_back_to_back_patches() {
    for (label, scene) in both("two_sided") {
        check_world_vertices(&label, &scene, "two_sided");
        assert_eq!(scene.patches.len(), 2, "{label}");
        let (front, back) = (&scene.patches[0], &scene.patches[1]);
        assert!(front.normal.distance(DVec3::Y) < POS_TOL, "{label}: {:?}", front.normal);
        assert!(back.normal.distance(-DVec3::Y) < POS_TOL, "{label}: {:?}", back.normal);
        assert!((front.area - 4.0).abs() < POS_TOL && (back.area - 4.0).abs() < POS_TOL);
    }
}

#[test]
fn glb_and_separate_exports_give_the_same_patches() {
    for name in ["room", "hierarchy", "materials", "light", "two_sided", "shadow"] {
        let s = both(name);
        let (a, b) = (&s[0].1, &s[1].1);
        assert_eq!(a.patches.len(), b.patches.len(), "{name}");
        for (p, q) in a.patches.iter().zip(&b.patches) {
            assert_eq!(p.vertices, q.vertices, "{name}: {}", p.name);
            assert_eq!(p.reflectance, q.reflectance, "{name}: {}", p.name);
            assert_eq!(p.emission, q.emission, "{name}: {}", p.name);
        }
    }
}

/// A copy of the separate room export in a temp folder, with its JSON edited.
fn edited_room(tag: &str, edit: impl FnOnce(&mut Value)) -> Result<Scene, String> {
    let tmp = std::env::temp_dir().join(format!("radlab_blender_{tag}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp).unwrap();
    for f in ["room.bin", "floor.png", "wall.jpg"] {
        std::fs::copy(dir().join(f), tmp.join(f)).unwrap();
    }
    let mut json: Value =
        serde_json::from_str(&std::fs::read_to_string(dir().join("room.gltf")).unwrap()).unwrap();
    edit(&mut json);
    let file = tmp.join("room.gltf");
    std::fs::write(&file, serde_json::to_string(&json).unwrap()).unwrap();
    let result = load(&file, &LoadOptions::default()).map_err(|e| e.to_string());
    let _ = std::fs::remove_dir_all(&tmp);
    result
}

#[test]
fn texture_mean_is_multiplied_by_base_color_factor() {
    let scene = edited_room("factor", |j| {
        j["materials"][1]["pbrMetallicRoughness"]["baseColorFactor"] =
            serde_json::json!([0.5, 1.0, 0.25, 1.0]);
    });
    let scene = scene.unwrap();
    let wall = scene.patches.iter().find(|p| p.material == "wall").unwrap();
    let w = linear(WALL);
    let want = Rgb::new(0.5 * w.0[0], w.0[1], 0.25 * w.0[2]);
    assert!(close(wall.reflectance, want, JPEG_TOL), "{:?} vs {want:?}", wall.reflectance);
}

#[test]
fn missing_texture_file_is_a_warning_and_the_factor_is_used() {
    let scene = edited_room("missing", |j| j["images"][0]["uri"] = "nowhere.png".into());
    let scene = scene.unwrap();
    let floor = scene.patches.iter().find(|p| p.material == "floor").unwrap();
    assert_eq!(floor.reflectance, Rgb::splat(1.0f64.min(radlab::scene::RHO_MAX)));
    assert!(
        scene.warnings.iter().any(|w| w.contains("nowhere.png") && w.contains("not found")),
        "{:?}",
        scene.warnings
    );
}

/// CRC-32 (IEEE) for hand-made PNG chunks.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    !crc
}

/// A PNG whose header claims `w × h` RGB pixels, with an empty image stream: a decoder that
/// believed the header would allocate the whole image before finding the data missing.
fn png_header(w: u32, h: u32) -> Vec<u8> {
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = w.to_be_bytes().to_vec();
    ihdr.extend(h.to_be_bytes());
    ihdr.extend([8, 2, 0, 0, 0]);
    let empty_zlib = [0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01];
    for (kind, data) in [(b"IHDR", &ihdr[..]), (b"IDAT", &empty_zlib[..]), (b"IEND", &[][..])] {
        let mut chunk = kind.to_vec();
        chunk.extend(data);
        out.extend((data.len() as u32).to_be_bytes());
        out.extend(&chunk);
        out.extend(crc32(&chunk).to_be_bytes());
    }
    out
}

#[test]
fn oversized_texture_is_refused_before_decoding() {
    for (w, h) in [(8193, 16), (16, 100_000), (8192, 8193)] {
        let tag = format!("big{w}x{h}");
        let tmp = std::env::temp_dir().join(format!("radlab_blender_png_{tag}_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&tmp);
        std::fs::create_dir_all(&tmp).unwrap();
        for f in ["room.bin", "room.gltf", "wall.jpg"] {
            std::fs::copy(dir().join(f), tmp.join(f)).unwrap();
        }
        std::fs::write(tmp.join("floor.png"), png_header(w, h)).unwrap();
        let err = load(&tmp.join("room.gltf"), &LoadOptions::default()).map(|_| ()).unwrap_err().to_string();
        let _ = std::fs::remove_dir_all(&tmp);
        assert!(err.contains("room.gltf") && err.contains("floor.png"), "{err}");
        assert!(err.contains(&format!("{w}×{h}")) && !err.contains('\n'), "{err}");
    }
    // Below the side cap but above a lowered pixel cap.
    let tmp = std::env::temp_dir().join(format!("radlab_blender_png_cap_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp).unwrap();
    for f in ["room.bin", "room.gltf", "floor.png", "wall.jpg"] {
        std::fs::copy(dir().join(f), tmp.join(f)).unwrap();
    }
    let opts = LoadOptions { max_texture_pixels: 255, ..LoadOptions::default() };
    let err = load(&tmp.join("room.gltf"), &opts).map(|_| ()).unwrap_err().to_string();
    let _ = std::fs::remove_dir_all(&tmp);
    assert!(err.contains("16×16") && err.contains("255 pixels"), "{err}");
}

/// Issue 16 on a Blender scene: `shadow` (a 2 × 2 floor, a 0.5 × 0.5 occluder at height 0.5 and
/// a 0.2 × 0.2 lamp at height 1.5, all centred; E = 10). The lamp's corners against the
/// occluder's edges put the umbra's and penumbra's edges on the floor at |x|, |z| = 0.325 and
/// 0.425 (x = l + (b − l) · 1.5 for lamp and occluder half-widths l = ±0.1, b = 0.25). The
/// critical segments lie on those eight lines; the CDT and the BSP meshes, solved at p = 0, and
/// the graded CDT as the hierarchical solver's top level, put element edges on them (artifact
/// E, scored on the segments that bound the shadow, ≈ 0), and the floor is dark under the
/// occluder and lit in the open.
#[test]
fn blender_shadow_scene_gets_its_critical_segments_meshed_and_solved() {
    use radlab::eval::artifacts::{ArtifactParams, measure};
    use radlab::eval::pointwise::{PiecewiseConstant, Reconstruction};
    use radlab::mesh::DEFAULT_SNAP;
    use radlab::mesh::discontinuity::scene_segments;
    use radlab::mesh::grade::GradeParams;
    use radlab::mesh::remesh::{MeshKind, RemeshParams};
    use radlab::solver::discontinuity::{self, DiscontinuityParams, solve_hierarchical};
    use radlab::solver::params::HierarchicalParams;
    for (label, scene) in both("shadow") {
        check_world_vertices(&label, &scene, "shadow");
        assert_eq!(scene.patches.len(), 3, "{label}: floor, occluder, lamp");
        let lamp = scene.patches.iter().find(|p| p.mesh == "Lamp").expect("the lamp");
        assert!(close(lamp.emission, Rgb::splat(10.0), F32_TOL), "{label}: E = {:?}", lamp.emission);
        assert!(lamp.normal.y < -0.99, "{label}: the lamp faces the floor");
        let floor = scene.patches.iter().position(|p| p.mesh == "Floor").unwrap();

        // The critical segments on the floor: every one of the eight lines carries some.
        let set = scene_segments(&scene.patches, floor, DEFAULT_SNAP).unwrap();
        let on_line = |s: &radlab::mesh::discontinuity::CriticalSegment, axis: usize, at: f64| {
            [s.a, s.b].iter().all(|p| (p.to_array()[axis] - at).abs() < POS_TOL)
        };
        for axis in [0, 2] {
            for at in [-0.425, -0.325, 0.325, 0.425] {
                assert!(
                    set.segments.iter().any(|s| on_line(s, axis, at)),
                    "{label}: no critical segment on {} = {at}",
                    ["x", "y", "z"][axis]
                );
            }
        }

        // Solved on each mesh: the shadow's segments on element edges, the shadow in B.
        let params = ArtifactParams { side: 32, ..ArtifactParams::quick() };
        let cdt = discontinuity::solve(&scene, &DiscontinuityParams::cdt(), &mut |_, _| {}).unwrap();
        let bsp = discontinuity::solve(&scene, &DiscontinuityParams::bsp(), &mut |_, _| {}).unwrap();
        // The mesh `radlab solve --method hierarchical --mesh discontinuity-cdt --dmesh-budget 300`
        // builds.
        let graded =
            RemeshParams::for_solve(MeshKind::Cdt, None, None, Some(GradeParams::with_budget(300)), 10_000)
                .unwrap();
        let top = solve_hierarchical(&scene, &graded, HierarchicalParams::quality(), &mut |_, _| {}).unwrap();
        for d in [cdt, bsp, top] {
            let sol = &d.solution;
            assert!(sol.is_physical(), "{label}: {}", sol.method);
            let flat = PiecewiseConstant::new(&scene, &sol.elements).unwrap();
            let e = measure(&scene, sol, &flat, &params).unwrap().unresolved;
            println!("{label}, {} ({} elements): E {e:?}", sol.method, sol.elements.len());
            assert!(e.segments >= 8 && e.fraction() < 0.01, "{label}, {}: {e:?}", sol.method);
            let b = |x: f64, z: f64| flat.radiosity_at(floor, DVec3::new(x, 0.0, z)).mean();
            assert!(
                b(0.0, 0.0) < 0.2 * b(0.7, 0.0),
                "{label}, {}: umbra {} lit {}",
                sol.method,
                b(0.0, 0.0),
                b(0.7, 0.0)
            );
        }
    }
}
