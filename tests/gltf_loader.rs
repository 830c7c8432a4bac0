//! The glTF loader on good and bad input, one test per case. Every bad file is
//! built in a fresh temporary folder; every error must be a `SceneError` whose message names the
//! file, never a panic.

use base64::Engine as _;
use radlab::math::DVec3;
use radlab::scene::gltf::{LoadOptions, load, load_slice};
use radlab::scene::{RHO_MAX, Scene, SceneError};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Positions pass through f32: comparisons of unit-size coordinates allow f32 round-off.
const F32_TOL: f64 = 1e-6;

static COUNTER: AtomicUsize = AtomicUsize::new(0);

/// A fresh, empty folder under the system temp dir, removed when dropped.
struct TmpDir(PathBuf);

impl Drop for TmpDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

impl std::ops::Deref for TmpDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

fn tmpdir(tag: &str) -> TmpDir {
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let d = std::env::temp_dir().join(format!("radlab-gltf-{tag}-{}-{n}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    TmpDir(d)
}

fn bytes_of(positions: &[[f32; 3]], indices: &[u32]) -> Vec<u8> {
    let mut b: Vec<u8> = positions.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
    b.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    b
}

fn data_uri(bytes: &[u8]) -> String {
    format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

/// A document with one mesh "m" of one primitive (positions + u32 indices in one data-URI
/// buffer), one node, and `material` as material 0 (if given).
fn doc(positions: &[[f32; 3]], indices: &[u32], material: Option<Value>) -> Value {
    let bytes = bytes_of(positions, indices);
    let pos_len = positions.len() * 12;
    let mut prim = json!({"attributes": {"POSITION": 0}, "indices": 1});
    let mut d = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "n"}],
        "meshes": [{"name": "m", "primitives": []}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": positions.len(), "type": "VEC3"},
            {"bufferView": 1, "componentType": 5125, "count": indices.len(), "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": pos_len},
            {"buffer": 0, "byteOffset": pos_len, "byteLength": indices.len() * 4}
        ],
        "buffers": [{"byteLength": bytes.len(), "uri": data_uri(&bytes)}]
    });
    if let Some(m) = material {
        prim["material"] = json!(0);
        d["materials"] = json!([m]);
    }
    d["meshes"][0]["primitives"] = json!([prim]);
    d
}

/// A unit square in z = 0 facing +z, as two triangles sharing the diagonal 0–2.
fn square() -> (Vec<[f32; 3]>, Vec<u32>) {
    (vec![[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]], vec![0, 1, 2, 0, 2, 3])
}

fn emissive(rho: f64, e: f64) -> Value {
    json!({"name": "mat", "pbrMetallicRoughness": {"baseColorFactor": [rho, rho, rho, 1.0]}, "emissiveFactor": [e, e, e]})
}

fn lit_square() -> Value {
    let (p, i) = square();
    doc(&p, &i, Some(emissive(0.5, 1.0)))
}

fn write(dir: &Path, name: &str, text: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A file in its own temporary folder (both removed when dropped).
struct TmpFile {
    _dir: TmpDir,
    path: PathBuf,
}

impl std::ops::Deref for TmpFile {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.path
    }
}

fn write_doc(tag: &str, d: &Value) -> TmpFile {
    let dir = tmpdir(tag);
    let path = write(&dir, &format!("{tag}.gltf"), serde_json::to_string(d).unwrap().as_bytes());
    TmpFile { _dir: dir, path }
}

fn load_ok(path: &Path) -> Scene {
    load(path, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"))
}

/// Load, expect an error, check the message names the file, return the error.
fn load_err(path: &Path) -> SceneError {
    load_err_with(path, &LoadOptions::default())
}

fn load_err_with(path: &Path, opts: &LoadOptions) -> SceneError {
    let e = match load(path, opts) {
        Ok(s) => panic!("{} loaded ({} patches) but should fail", path.display(), s.patches.len()),
        Err(e) => e,
    };
    let msg = e.to_string();
    let fname = path.file_name().unwrap().to_string_lossy();
    assert!(msg.contains(&*fname), "error does not name the file: {msg}");
    assert!(!msg.contains('\n'), "error is not one line: {msg}");
    e
}

// ------------------------------------------------------------------ good input

#[test]
fn square_loads_as_one_quad_with_material() {
    let s = load_ok(&write_doc("good", &lit_square()));
    assert_eq!(s.name, "good");
    assert_eq!(s.patches.len(), 1);
    let p = &s.patches[0];
    assert_eq!(p.vertices.len(), 4);
    assert!((p.area - 1.0).abs() < F32_TOL);
    assert!(p.normal.dot(DVec3::Z) > 1.0 - F32_TOL);
    assert_eq!(p.reflectance.0, [0.5; 3]);
    assert_eq!(p.emission.0, [1.0; 3]);
    assert_eq!(
        (p.mesh.as_str(), p.primitive, p.name.as_str(), p.material.as_str()),
        ("m", 0, "m/0/0", "mat")
    );
    assert!(s.validate().is_empty());
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
}

#[test]
fn missing_material_is_grey_and_no_emitter_warns() {
    let (p, i) = square();
    let s = load_ok(&write_doc("nomat", &doc(&p, &i, None)));
    assert_eq!(s.patches[0].reflectance.0, [0.5; 3]);
    assert!(s.patches[0].emission.is_zero());
    assert!(s.warnings.iter().any(|w| w.contains("no patch emits")), "{:?}", s.warnings);
}

#[test]
fn emissive_strength_multiplies_the_factor() {
    let mut d = lit_square();
    d["materials"][0]["emissiveFactor"] = json!([1.0, 0.5, 0.25]);
    d["materials"][0]["extensions"] = json!({"KHR_materials_emissive_strength": {"emissiveStrength": 8.0}});
    d["extensionsUsed"] = json!(["KHR_materials_emissive_strength"]);
    let s = load_ok(&write_doc("strength", &d));
    assert_eq!(s.patches[0].emission.0, [8.0, 4.0, 2.0]);
}

#[test]
fn external_relative_buffer_loads() {
    let (p, i) = square();
    let mut d = doc(&p, &i, Some(emissive(0.5, 1.0)));
    let dir = tmpdir("external");
    std::fs::create_dir_all(dir.join("bin")).unwrap();
    write(&dir, "bin/data.bin", &bytes_of(&p, &i));
    d["buffers"][0]["uri"] = json!("bin/data.bin");
    let path = write(&dir, "external.gltf", serde_json::to_string(&d).unwrap().as_bytes());
    assert_eq!(load_ok(&path).patches.len(), 1);
    // `a/../b` stays inside the folder and is accepted.
    d["buffers"][0]["uri"] = json!("bin/../bin/data.bin");
    let path = write(&dir, "external2.gltf", serde_json::to_string(&d).unwrap().as_bytes());
    assert_eq!(load_ok(&path).patches.len(), 1);
}

/// GLB container: 12-byte header, JSON chunk, BIN chunk, each padded to 4 bytes.
fn glb(json_doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut j = serde_json::to_vec(json_doc).unwrap();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((j.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(j);
    out.extend((b.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(b);
    out
}

fn glb_square() -> Vec<u8> {
    let (p, i) = square();
    let mut d = doc(&p, &i, Some(emissive(0.5, 1.0)));
    let bin = bytes_of(&p, &i);
    d["buffers"] = json!([{"byteLength": bin.len()}]);
    glb(&d, &bin)
}

#[test]
fn glb_loads() {
    let dir = tmpdir("glb");
    let s = load_ok(&write(&dir, "square.glb", &glb_square()));
    assert_eq!(s.patches.len(), 1);
    assert_eq!(s.patches[0].vertices.len(), 4);
}

#[test]
fn load_slice_reads_data_uris_without_a_folder() {
    let text = serde_json::to_vec(&lit_square()).unwrap();
    let s = load_slice(&text, None, Path::new("mem.gltf"), &LoadOptions::default()).unwrap();
    assert_eq!(s.patches.len(), 1);
    // …but a relative file URI cannot be resolved without a folder.
    let mut d = lit_square();
    d["buffers"][0]["uri"] = json!("data.bin");
    let e =
        load_slice(&serde_json::to_vec(&d).unwrap(), None, Path::new("mem.gltf"), &LoadOptions::default())
            .unwrap_err();
    assert!(matches!(e, SceneError::Buffer { .. }), "{e}");
    assert!(e.to_string().contains("mem.gltf"));
}

#[test]
fn camera_node_becomes_the_scene_viewpoint() {
    let mut d = lit_square();
    d["cameras"] = json!([{"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.01}}]);
    // Camera at (0.5, 0.5, 3) looking down −z (the glTF default orientation), up +y.
    d["nodes"] = json!([{"mesh": 0}, {"camera": 0, "translation": [0.5, 0.5, 3.0]}]);
    d["scenes"] = json!([{"nodes": [0, 1]}]);
    let s = load_ok(&write_doc("camera", &d));
    let cam = s.camera.unwrap();
    assert!(cam.eye.distance(DVec3::new(0.5, 0.5, 3.0)) < F32_TOL);
    assert!((cam.target - cam.eye).normalize().dot(-DVec3::Z) > 1.0 - F32_TOL);
    assert!(cam.up.dot(DVec3::Y) > 1.0 - F32_TOL);
    assert!((cam.fov_y_deg - 0.5f64.to_degrees()).abs() < 1e-4);
}

// ------------------------------------------------------------------ geometry rules

#[test]
fn quad_merge_numbering_and_non_mergeable_pairs() {
    // t0 = first half of a unit square, t1 = an unrelated triangle, t2 = second half of the square,
    // t3/t4 = a pair sharing an edge but folded (not planar), t5/t6 = a pair forming a non-convex quad.
    let positions: Vec<[f32; 3]> = vec![
        [0., 0., 0.],
        [1., 0., 0.],
        [1., 1., 0.],
        [0., 1., 0.], // square 0..3
        [5., 0., 0.],
        [6., 0., 0.],
        [5., 1., 0.], // lone triangle 4..6
        [0., 0., 2.],
        [1., 0., 2.],
        [1., 1., 2.],
        [0., 1., 2.5], // folded pair 7..10
        [0., 0., 4.],
        [2., 0., 4.],
        [0.5, 0.5, 4.],
        [0., 2., 4.], // dart 11..14
    ];
    let indices = [0, 1, 2, 4, 5, 6, 0, 2, 3, 7, 8, 9, 7, 9, 10, 11, 12, 13, 11, 13, 14];
    let mut d = doc(&positions, &indices, Some(emissive(0.5, 1.0)));
    d["materials"][0]["emissiveFactor"] = json!([1.0, 1.0, 1.0]);
    let s = load_ok(&write_doc("merge", &d));
    let names: Vec<&str> = s.patches.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["m/0/0", "m/0/1", "m/0/3", "m/0/4", "m/0/5", "m/0/6"]);
    let sizes: Vec<usize> = s.patches.iter().map(|p| p.vertices.len()).collect();
    assert_eq!(sizes, [4, 3, 3, 3, 3, 3]);
    // The merged quad starts at the first triangle's first vertex and keeps its orientation.
    let q = &s.patches[0].vertices;
    assert_eq!(q[0], DVec3::ZERO);
    assert_eq!(q[2], DVec3::new(1.0, 1.0, 0.0));
    assert!(s.patches[0].normal.dot(DVec3::Z) > 1.0 - F32_TOL);
    assert!(s.validate().is_empty(), "{:?}", s.validate());
}

#[test]
fn merged_quad_works_without_shared_indices() {
    // Same square, six separate vertices (no index sharing): merged by position.
    let p: Vec<[f32; 3]> =
        vec![[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
    let s = load_ok(&write_doc("unshared", &doc(&p, &[0, 1, 2, 3, 4, 5], Some(emissive(0.5, 1.0)))));
    assert_eq!(s.patches.len(), 1);
    assert_eq!(s.patches[0].vertices.len(), 4);
}

#[test]
fn zero_area_triangles_are_dropped_and_counted() {
    let (mut p, mut i) = square();
    p.extend([[3., 0., 0.], [4., 0., 0.], [5., 0., 0.]]); // collinear
    i.extend([4, 5, 6, 4, 4, 5]); // collinear, and a repeated vertex
    let s = load_ok(&write_doc("zero", &doc(&p, &i, Some(emissive(0.5, 1.0)))));
    assert_eq!(s.patches.len(), 1);
    assert!(s.warnings.iter().any(|w| w.contains("2 zero-area")), "{:?}", s.warnings);
}

#[test]
fn negative_determinant_transform_flips_winding() {
    let (p, i) = square();
    let mut d = doc(&p, &i, Some(emissive(0.5, 1.0)));
    d["nodes"][0]["scale"] = json!([-1.0, 1.0, 1.0]);
    d["nodes"][0]["translation"] = json!([10.0, 0.0, 0.0]);
    let s = load_ok(&write_doc("mirror", &d));
    assert_eq!(s.patches.len(), 1);
    let patch = &s.patches[0];
    // Mirrored in x: it covers x ∈ [9, 10] and still faces +z (winding reversed with the mirror).
    assert!(patch.normal.dot(DVec3::Z) > 1.0 - F32_TOL, "normal {}", patch.normal);
    let b = s.bounds();
    assert!((b.min.x - 9.0).abs() < F32_TOL && (b.max.x - 10.0).abs() < F32_TOL);
    assert!(s.validate().is_empty());

    // A positive-determinant rotation (180° about y) turns it to face −z without reversing.
    let mut d = doc(&p, &i, Some(emissive(0.5, 1.0)));
    d["nodes"][0]["rotation"] = json!([0.0, 1.0, 0.0, 0.0]);
    let s = load_ok(&write_doc("rotate", &d));
    assert!(s.patches[0].normal.dot(-DVec3::Z) > 1.0 - F32_TOL);
}

#[test]
fn nested_nodes_compose_in_depth_first_order() {
    let (p, i) = square();
    let mut d = doc(&p, &i, Some(emissive(0.5, 1.0)));
    // Root 0 (translate x+10) has children 2 then 1; node 1 = mesh at +y 5, node 2 = mesh at origin.
    d["nodes"] = json!([
        {"translation": [10.0, 0.0, 0.0], "children": [2, 1]},
        {"mesh": 0, "translation": [0.0, 5.0, 0.0]},
        {"mesh": 0}
    ]);
    let s = load_ok(&write_doc("nested", &d));
    assert_eq!(s.patches.len(), 2);
    assert!(s.patches[0].centroid.distance(DVec3::new(10.5, 0.5, 0.0)) < F32_TOL);
    assert!(s.patches[1].centroid.distance(DVec3::new(10.5, 5.5, 0.0)) < F32_TOL);
}

#[test]
fn node_cycle_is_an_error_not_a_hang() {
    let mut d = lit_square();
    d["nodes"] = json!([{"mesh": 0, "children": [1]}, {"children": [0]}]);
    let e = load_err(&write_doc("cycle", &d));
    assert!(matches!(e, SceneError::InvalidGltf { .. }), "{e}");
}

#[test]
fn double_sided_gives_back_to_back_patches() {
    let mut d = lit_square();
    d["materials"][0]["doubleSided"] = json!(true);
    let s = load_ok(&write_doc("double", &d));
    assert_eq!(s.patches.len(), 2);
    let (a, b) = (&s.patches[0], &s.patches[1]);
    assert!(a.normal.dot(b.normal) < -1.0 + F32_TOL);
    assert!((a.area - b.area).abs() < F32_TOL);
    assert_eq!((a.name.as_str(), b.name.as_str()), ("m/0/0", "m/0/0/back"));
    assert!(s.validate().is_empty());
}

#[test]
fn non_triangle_mode_is_skipped_with_a_warning() {
    let mut d = lit_square();
    let tri = d["meshes"][0]["primitives"][0].clone();
    let mut lines = tri.clone();
    lines["mode"] = json!(1);
    d["meshes"][0]["primitives"] = json!([lines, tri]);
    let s = load_ok(&write_doc("lines", &d));
    assert_eq!(s.patches.len(), 1);
    assert_eq!(s.patches[0].primitive, 1, "primitive numbering keeps the skipped one");
    assert!(s.warnings.iter().any(|w| w.contains("non-triangle")), "{:?}", s.warnings);
}

// ------------------------------------------------------------------ materials

#[test]
fn reflectance_above_one_is_an_error() {
    let (p, i) = square();
    let e = load_err(&write_doc("rho_big", &doc(&p, &i, Some(emissive(1.2, 1.0)))));
    assert!(matches!(e, SceneError::ReflectanceOutOfRange { .. }), "{e}");
}

#[test]
fn reflectance_one_is_clamped_with_a_warning() {
    let (p, i) = square();
    let s = load_ok(&write_doc("rho_one", &doc(&p, &i, Some(emissive(1.0, 1.0)))));
    assert_eq!(s.patches[0].reflectance.0, [RHO_MAX; 3]);
    assert!(s.warnings.iter().any(|w| w.contains("clamped")), "{:?}", s.warnings);
    assert!(s.validate().is_empty());
}

#[test]
fn negative_emission_is_an_error() {
    let mut d = lit_square();
    d["materials"][0]["emissiveFactor"] = json!([1.0, 1.0, 1.0]);
    d["materials"][0]["extensions"] = json!({"KHR_materials_emissive_strength": {"emissiveStrength": -2.0}});
    let e = load_err(&write_doc("neg_emission", &d));
    assert!(matches!(e, SceneError::BadEmission { .. }), "{e}");
}

// ------------------------------------------------------------------ malformed files

#[test]
fn invalid_json_is_an_error() {
    let dir = tmpdir("badjson");
    let e = load_err(&write(&dir, "bad.gltf", b"{ \"asset\": { \"version\": \"2.0\" }, nope }"));
    assert!(matches!(e, SceneError::InvalidGltf { .. }), "{e}");
}

#[test]
fn truncated_json_is_an_error() {
    let text = serde_json::to_vec(&lit_square()).unwrap();
    let dir = tmpdir("truncjson");
    for cut in [0, 1, text.len() / 3, text.len() - 1] {
        let e = load_err(&write(&dir, "trunc.gltf", &text[..cut]));
        assert!(matches!(e, SceneError::InvalidGltf { .. }), "cut {cut}: {e}");
    }
}

#[test]
fn truncated_glb_is_an_error() {
    let full = glb_square();
    let dir = tmpdir("truncglb");
    // Every prefix, including the ones that cut the 12-byte header and each chunk header.
    for cut in (0..full.len()).filter(|c| *c < 40 || c % 7 == 0) {
        let bytes = &full[..cut];
        if !bytes.starts_with(b"glTF") {
            continue;
        }
        let e = load_err(&write(&dir, "trunc.glb", bytes));
        assert!(matches!(e, SceneError::InvalidGltf { .. } | SceneError::Buffer { .. }), "cut {cut}: {e}");
    }
    // A header whose length field is smaller than the header itself.
    let mut bad = full.clone();
    bad[8..12].copy_from_slice(&4u32.to_le_bytes());
    load_err(&write(&dir, "tiny.glb", &bad));
    // A chunk length pointing past the end.
    let mut bad = full;
    bad[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
    load_err(&write(&dir, "chunk.glb", &bad));
}

#[test]
fn missing_buffer_file_is_an_error() {
    let mut d = lit_square();
    d["buffers"][0]["uri"] = json!("missing.bin");
    let e = load_err(&write_doc("missing", &d));
    assert!(matches!(e, SceneError::Buffer { .. }), "{e}");
}

#[test]
fn short_buffer_is_an_error() {
    let (p, i) = square();
    // The data URI holds fewer bytes than byteLength declares.
    let mut d = doc(&p, &i, Some(emissive(0.5, 1.0)));
    d["buffers"][0]["byteLength"] = json!(4096);
    let e = load_err(&write_doc("short", &d));
    assert!(matches!(e, SceneError::Buffer { .. }), "{e}");
    // An external file shorter than byteLength.
    let dir = tmpdir("shortfile");
    write(&dir, "data.bin", &bytes_of(&p, &i)[..20]);
    let mut d = doc(&p, &i, Some(emissive(0.5, 1.0)));
    d["buffers"][0]["uri"] = json!("data.bin");
    let e = load_err(&write(&dir, "shortfile.gltf", serde_json::to_string(&d).unwrap().as_bytes()));
    assert!(matches!(e, SceneError::Buffer { .. }), "{e}");
}

#[test]
fn accessor_or_view_out_of_range_is_an_error() {
    // A bufferView running past its buffer.
    let mut d = lit_square();
    d["bufferViews"][1]["byteLength"] = json!(1 << 30);
    let e = load_err(&write_doc("view_range", &d));
    assert!(matches!(e, SceneError::Buffer { .. }), "{e}");
    // An accessor with a huge count inside a small view (no allocation of `count` elements).
    let mut d = lit_square();
    d["accessors"][0]["count"] = json!(1_000_000_000u64);
    let e = load_err_with(
        &write_doc("acc_range", &d),
        &LoadOptions { max_triangles: usize::MAX, ..Default::default() },
    );
    assert!(matches!(e, SceneError::Buffer { .. }), "{e}");
    // An index referring past the vertex list.
    let (p, _) = square();
    let e = load_err(&write_doc("bad_index", &doc(&p, &[0, 1, 9], Some(emissive(0.5, 1.0)))));
    assert!(matches!(e, SceneError::InvalidGltf { .. }), "{e}");
}

#[test]
fn dotdot_uri_is_rejected() {
    let mut d = lit_square();
    d["buffers"][0]["uri"] = json!("../outside.bin");
    let e = load_err(&write_doc("dotdot", &d));
    assert!(matches!(e, SceneError::UriOutsideScene { .. }), "{e}");
    d["buffers"][0]["uri"] = json!("sub/../../outside.bin");
    assert!(matches!(load_err(&write_doc("dotdot2", &d)), SceneError::UriOutsideScene { .. }));
    d["buffers"][0]["uri"] = json!("%2E%2E/outside.bin");
    assert!(matches!(load_err(&write_doc("dotdot3", &d)), SceneError::UriOutsideScene { .. }));
}

#[test]
fn absolute_uri_is_rejected() {
    for uri in ["/etc/passwd", "\\\\server\\share\\x.bin", "C:/x.bin"] {
        let mut d = lit_square();
        d["buffers"][0]["uri"] = json!(uri);
        let e = load_err(&write_doc("absolute", &d));
        assert!(matches!(e, SceneError::UriOutsideScene { .. }), "{uri}: {e}");
    }
}

#[test]
fn other_scheme_uri_is_rejected() {
    for uri in ["http://example.com/x.bin", "file:///etc/passwd", "https:x.bin"] {
        let mut d = lit_square();
        d["buffers"][0]["uri"] = json!(uri);
        let e = load_err(&write_doc("scheme", &d));
        assert!(matches!(e, SceneError::UriOutsideScene { .. }), "{uri}: {e}");
    }
}

#[test]
fn image_uri_escaping_is_rejected() {
    for uri in ["../texture.png", "/tmp/texture.png", "http://example.com/t.png"] {
        let mut d = lit_square();
        d["images"] = json!([{"uri": uri}]);
        let e = load_err(&write_doc("image", &d));
        assert!(matches!(e, SceneError::UriOutsideScene { .. }), "{uri}: {e}");
    }
}

#[test]
fn nan_position_is_an_error() {
    let (mut p, i) = square();
    p[2][1] = f32::NAN;
    let e = load_err(&write_doc("nan", &doc(&p, &i, Some(emissive(0.5, 1.0)))));
    assert!(matches!(e, SceneError::NonFinitePosition { .. }), "{e}");
    let (mut p, i) = square();
    p[0][0] = f32::INFINITY;
    let e = load_err(&write_doc("inf", &doc(&p, &i, Some(emissive(0.5, 1.0)))));
    assert!(matches!(e, SceneError::NonFinitePosition { .. }), "{e}");
}

#[test]
fn no_patches_is_an_error() {
    // Only degenerate triangles.
    let p: Vec<[f32; 3]> = vec![[0., 0., 0.], [1., 0., 0.], [2., 0., 0.]];
    let e = load_err(&write_doc("empty", &doc(&p, &[0, 1, 2], Some(emissive(0.5, 1.0)))));
    assert!(matches!(e, SceneError::Empty { .. }), "{e}");
    // No meshes at all.
    let d = json!({"asset": {"version": "2.0"}, "scenes": [{"nodes": []}], "scene": 0});
    let e = load_err(&write_doc("nothing", &d));
    assert!(matches!(e, SceneError::Empty { .. }), "{e}");
}

#[test]
fn size_cap_is_checked_before_reading() {
    let opts = LoadOptions { max_triangles: 1, ..Default::default() };
    let e = load_err_with(&write_doc("cap", &lit_square()), &opts);
    assert!(matches!(e, SceneError::TooLarge { cap: 1, .. }), "{e}");
    // The check uses declared counts: a file claiming 10^9 triangles with no data is refused as
    // too large, before its (short) buffer is ever looked at.
    let mut d = lit_square();
    d["accessors"][1]["count"] = json!(3_000_000_000u64);
    let e = load_err(&write_doc("cap_claim", &d));
    assert!(matches!(e, SceneError::TooLarge { .. }), "{e}");
}

#[test]
fn unreadable_file_is_an_io_error() {
    let dir = tmpdir("io");
    let e = load_err(&dir.join("does_not_exist.gltf"));
    assert!(matches!(e, SceneError::Io { .. }), "{e}");
}

// ------------------------------------------------------------------ writer

#[test]
fn write_gltf_round_trips_patches_materials_and_camera() {
    use radlab::math::Rgb;
    use radlab::scene::gltf::write_gltf;
    use radlab::scene::{Patch, Viewpoint};
    let v = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let quad = vec![v(0., 0., 0.), v(2., 0., 0.), v(2., 1., 0.), v(0., 1., 0.)];
    let tri = vec![v(0., 0., 1.), v(0., 1., 1.), v(1., 0., 1.)];
    let far = vec![v(5., 0., 0.), v(6., 0., 0.), v(6., 0., -1.), v(5., 0., -1.)];
    let patch = |verts: Vec<DVec3>, rho: f64, e: Rgb, mesh: &str| {
        Patch::new(verts, Rgb::splat(rho), e, mesh, 0, mesh, format!("{mesh}-mat")).unwrap()
    };
    let mut scene = Scene::new(
        "w",
        "test:w",
        vec![
            patch(quad, 0.25, Rgb::ZERO, "a"),
            patch(tri, 0.5, Rgb::new(40.0, 20.0, 10.0), "b"),
            patch(far, 0.75, Rgb::ZERO, "a"),
        ],
    );
    scene.camera =
        Some(Viewpoint { eye: v(1., 2., 8.), target: v(1., 0.5, 0.), up: DVec3::Y, fov_y_deg: 50.0 });
    let dir = tmpdir("writer");
    let path = dir.join("w.gltf");
    write_gltf(&scene, &path).unwrap();
    let back = load_ok(&path);
    assert_eq!(back.patches.len(), 3);
    for (a, b) in scene.patches.iter().zip(&back.patches) {
        assert_eq!(a.vertices.len(), b.vertices.len());
        for (p, q) in a.vertices.iter().zip(&b.vertices) {
            assert!(p.distance(*q) < F32_TOL, "{p} vs {q}");
        }
        assert_eq!(a.mesh, b.mesh);
        assert_eq!(a.material, b.material);
        assert!(a.reflectance.abs_diff_max(b.reflectance) < F32_TOL);
        assert!(a.emission.abs_diff_max(b.emission) < F32_TOL * a.emission.max_channel().max(1.0));
    }
    let (a, b) = (scene.camera.unwrap(), back.camera.unwrap());
    assert!(a.eye.distance(b.eye) < F32_TOL * 10.0);
    assert!((a.target - a.eye).normalize().dot((b.target - b.eye).normalize()) > 1.0 - F32_TOL);
    assert!((a.fov_y_deg - b.fov_y_deg).abs() < 1e-4);
}

// ------------------------------------------------------------------ robustness

/// Seeded random corruption of a valid .glb and .gltf: every result is `Ok` or a one-line error
/// naming the file, never a panic.
#[test]
fn corrupted_files_never_panic() {
    use radlab::math::Pcg32;
    let glb_bytes = glb_square();
    let mut d = lit_square();
    d["nodes"] = json!([{"mesh": 0, "children": [1]}, {"mesh": 0, "scale": [-1.0, 2.0, 1.0]}]);
    let gltf_bytes = serde_json::to_vec(&d).unwrap();
    let opts = LoadOptions::default();
    let label = Path::new("fuzz.glb");
    for (k, base) in [&glb_bytes, &gltf_bytes].into_iter().enumerate() {
        let mut rng = Pcg32::keyed(7, k as u64);
        for round in 0..1500 {
            let mut bytes = base.clone();
            let edits = 1 + (rng.next_u32() % 4) as usize;
            for _ in 0..edits {
                let at = rng.next_u32() as usize % bytes.len();
                match rng.next_u32() % 3 {
                    0 => bytes[at] = rng.next_u32() as u8,
                    1 => bytes.truncate(at.max(1)),
                    _ => bytes[at] = b"0123456789-.,:[]{}\"e"[rng.next_u32() as usize % 20],
                }
            }
            check_no_panic(&bytes, label, &opts, round);
        }
    }
    // Structural: replace numbers in the JSON (indices, counts, offsets, strides, factors) with
    // hostile values, so the corruption reaches the accessor, node and material checks.
    let text = String::from_utf8(gltf_bytes).unwrap();
    let data_start = text.find("data:").unwrap();
    let numbers: Vec<(usize, usize)> = {
        let b = text.as_bytes();
        let mut v = Vec::new();
        let mut i = 0;
        while i < b.len() {
            let in_data = i >= data_start && i < data_start + text[data_start..].find('"').unwrap();
            if b[i].is_ascii_digit() && !in_data {
                let j = (i..b.len()).find(|&j| !(b[j].is_ascii_digit() || b[j] == b'.')).unwrap_or(b.len());
                v.push((i, j));
                i = j;
            } else {
                i += 1;
            }
        }
        v
    };
    let hostile =
        ["0", "1", "2", "3", "4", "7", "12", "255", "65536", "2147483648", "4294967301", "1e30", "0.5", "-1"];
    let mut rng = Pcg32::keyed(7, 99);
    for round in 0..3000 {
        let mut picks: Vec<usize> =
            (0..1 + rng.next_u32() % 3).map(|_| rng.next_u32() as usize % numbers.len()).collect();
        picks.sort_unstable();
        picks.dedup();
        let mut out = text.clone();
        for &k in picks.iter().rev() {
            let (a, b) = numbers[k];
            out.replace_range(a..b, hostile[rng.next_u32() as usize % hostile.len()]);
        }
        check_no_panic(out.as_bytes(), label, &opts, round);
    }
}

fn check_no_panic(bytes: &[u8], label: &Path, opts: &LoadOptions, round: usize) {
    match load_slice(bytes, None, label, opts) {
        Ok(s) => assert!(!s.patches.is_empty(), "round {round}"),
        Err(e) => {
            let msg = e.to_string();
            assert!(msg.contains("fuzz.glb") && !msg.contains('\n'), "round {round}: {msg}");
        }
    }
}

// ------------------------------------------------------------------ hostile files

/// The fuzz findings kept as files (tests/fuzz_regressions/): each was a panic or work out of
/// proportion to the file, and each is now a one-line error naming the file and the cause. Each
/// file is loaded from its path and from bytes (as the fuzz target does).
#[test]
fn fuzz_regression_files_are_one_line_errors() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions");
    let cases = [
        // gltf's `Image::source` unwrapped both: a panic.
        ("image_without_source.gltf", "image 0 has neither uri nor bufferView"),
        ("image_view_without_mime.gltf", "image 0 has a bufferView but no mimeType"),
        // gltf's `Camera::projection` unwraps the projection its type names: a panic.
        ("camera_without_projection.gltf", "camera 0 lacks the projection its type names"),
        // 19 nodes, each the next one's parent twice over: 2^18 mesh instances from 1 KB.
        ("node_dag.gltf", "node 1 has two parents (0 and 0)"),
        // A truncated JPEG in the BIN chunk: the image crate's error spans two lines.
        ("truncated_jpeg.glb", "bad image header: Format error decoding Jpeg"),
    ];
    for (name, cause) in cases {
        let path = dir.join(name);
        let e = load_err(&path);
        assert!(e.to_string().contains(cause), "{name}: {e}");
        let bytes = std::fs::read(&path).unwrap();
        let e = load_slice(&bytes, None, Path::new(name), &LoadOptions::default()).unwrap_err();
        assert!(e.to_string().contains(cause) && !e.to_string().contains('\n'), "{name}: {e}");
    }
    // The same files made well-formed load: the errors come from the defect, not the rest.
    let mut d: Value =
        serde_json::from_slice(&std::fs::read(dir.join("image_without_source.gltf")).unwrap()).unwrap();
    d["images"][0]["uri"] = json!("data:image/png;base64,AAAA");
    assert_eq!(load_ok(&write_doc("image_ok", &d)).patches.len(), 1);
    d["images"][0] = json!({"bufferView": 0, "mimeType": "image/png"});
    assert_eq!(load_ok(&write_doc("image_view_ok", &d)).patches.len(), 1);
    let mut d: Value =
        serde_json::from_slice(&std::fs::read(dir.join("camera_without_projection.gltf")).unwrap()).unwrap();
    d["cameras"][0]["type"] = json!("orthographic");
    assert_eq!(load_ok(&write_doc("camera_ok", &d)).patches.len(), 1);
}

/// glTF nodes form disjoint trees [glTF 2.0, sec. 3.5.3]; a scene that lists a node twice or lists a
/// child as a root would walk a subtree many times.
#[test]
fn scene_roots_must_be_distinct_root_nodes() {
    let mut d = lit_square();
    d["scenes"] = json!([{"nodes": [0, 0]}]);
    let e = load_err(&write_doc("root_twice", &d));
    assert!(e.to_string().contains("scene 0 lists node 0 twice"), "{e}");
    d["nodes"] = json!([{"children": [1]}, {"mesh": 0}]);
    d["scenes"] = json!([{"nodes": [0, 1]}]);
    let e = load_err(&write_doc("root_child", &d));
    assert!(e.to_string().contains("scene 0: root node 1 has a parent (0)"), "{e}");
    d["scenes"] = json!([{"nodes": [0]}]);
    assert_eq!(load_ok(&write_doc("root_ok", &d)).patches.len(), 1);
}

/// A file of tests/fuzz_regressions/ that loads: loaded from its path and from its bytes (as
/// the fuzz target does), the two scenes the same; the scene and the seconds the path load took.
fn load_regression_file(name: &str) -> (Scene, f64) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions").join(name);
    let t = std::time::Instant::now();
    let s = load_ok(&path);
    let secs = t.elapsed().as_secs_f64();
    let bytes = std::fs::read(&path).unwrap();
    let from_bytes = load_slice(&bytes, None, Path::new(name), &LoadOptions::default()).unwrap();
    assert_eq!(from_bytes.patches.len(), s.patches.len(), "{name}");
    assert!(s.patches.iter().zip(&from_bytes.patches).all(|(a, b)| a.vertices == b.vertices), "{name}");
    (s, secs)
}

/// Time limit for the linear-work tests below: each takes well under a second here, and the
/// quadratic versions they guard against took minutes on the same input.
const LINEAR_WORK_SECONDS: f64 = 20.0;

/// Many nodes instancing one primitive whose POSITION accessor is large but whose triangles use
/// three of its vertices: the primitive is decoded once and each instance transforms only the
/// vertices its triangles use. (Decoding the accessor again per instance was 4000 × 100 000
/// vertex reads and hash inserts from a 1.6 MB file.) The finding's shape is kept as a file,
/// `tests/fuzz_regressions/many_instances.gltf` (40 KB: 600 nodes, each translated by its index
/// along z, instancing one triangle of a 1000-vertex accessor); the timing needs the larger
/// version built here.
#[test]
fn instancing_is_linear_in_the_triangles_it_adds() {
    let (s, secs) = load_regression_file("many_instances.gltf");
    assert_eq!(s.patches.len(), 600);
    for (k, p) in s.patches.iter().enumerate() {
        assert_eq!(p.vertices.len(), 3);
        assert!(p.centroid.distance(DVec3::new(1.0 / 3.0, 1.0 / 3.0, k as f64)) < 1e-4, "{k}");
    }
    assert!(secs < LINEAR_WORK_SECONDS, "many_instances.gltf took {secs:.1} s");
    let mut positions = vec![[0.0f32; 3]; 100_000];
    for (k, p) in positions.iter_mut().enumerate() {
        *p = [k as f32, 1.0, 2.0];
    }
    positions[0] = [0.0, 0.0, 0.0];
    positions[1] = [1.0, 0.0, 0.0];
    positions[2] = [0.0, 1.0, 0.0];
    let mut d = doc(&positions, &[0, 1, 2], Some(emissive(0.5, 1.0)));
    let nodes: Vec<Value> =
        (0..4000).map(|k| json!({"mesh": 0, "translation": [0.0, 0.0, k as f64]})).collect();
    d["nodes"] = json!(nodes);
    d["scenes"] = json!([{"nodes": (0..4000).collect::<Vec<_>>()}]);
    let bytes = serde_json::to_vec(&d).unwrap();
    let t = std::time::Instant::now();
    let s = load_slice(&bytes, None, Path::new("instances.gltf"), &LoadOptions::default()).unwrap();
    let secs = t.elapsed().as_secs_f64();
    assert_eq!(s.patches.len(), 4000);
    assert!(s.patches[3999].centroid.distance(DVec3::new(1.0 / 3.0, 1.0 / 3.0, 3999.0)) < 1e-4);
    assert!(secs < LINEAR_WORK_SECONDS, "4000 instances of one triangle took {secs:.1} s");
}

/// A fan: n triangles on the directed edge a→b and n on b→a, no two forming a planar quad. Each
/// triangle looks at no more than a few merge partners per edge (all n of them made merging n²).
/// The finding's shape is kept as a file, `tests/fuzz_regressions/triangle_fan.glb` (37 KB:
/// n = 1000, u16 indices); the timing needs the larger fan built here.
#[test]
fn quad_merging_is_linear_on_shared_edges() {
    let (s, secs) = load_regression_file("triangle_fan.glb");
    assert_eq!(s.patches.len(), 2000);
    assert!(s.patches.iter().all(|p| p.vertices.len() == 3));
    assert!(secs < LINEAR_WORK_SECONDS, "triangle_fan.glb took {secs:.1} s");
    let n = 20_000;
    let mut positions = vec![[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0]];
    let mut indices = Vec::new();
    for k in 0..n {
        // c_k on one side (angles in (0.1, 1.5)), d_k on the other ((1.7, 3.0)): c and d are never
        // opposite (angle π apart), so no quad (a d b c) is planar.
        let (tc, td) = (0.1 + 1.4 * k as f64 / n as f64, 1.7 + 1.3 * k as f64 / n as f64);
        let c = positions.len() as u32;
        positions.push([0.5, tc.cos() as f32, tc.sin() as f32]);
        positions.push([0.5, td.cos() as f32, td.sin() as f32]);
        indices.extend([0, 1, c, 1, 0, c + 1]);
    }
    let bytes = serde_json::to_vec(&doc(&positions, &indices, Some(emissive(0.5, 1.0)))).unwrap();
    let t = std::time::Instant::now();
    let s = load_slice(&bytes, None, Path::new("fan.gltf"), &LoadOptions::default()).unwrap();
    let secs = t.elapsed().as_secs_f64();
    assert_eq!(s.patches.len(), 2 * n);
    assert!(s.patches.iter().all(|p| p.vertices.len() == 3));
    assert!(secs < LINEAR_WORK_SECONDS, "a fan of {n} triangle pairs took {secs:.1} s");
    // A quad on a shared edge is still found among the first candidates: a square whose diagonal
    // is shared with two extra (non-planar) triangles still merges.
    let (mut p, mut i) = square();
    p.push([0.5, 0.5, 1.0]);
    i.extend([2, 0, 4]);
    let s = load_slice(
        &serde_json::to_vec(&doc(&p, &i, Some(emissive(0.5, 1.0)))).unwrap(),
        None,
        Path::new("fan.gltf"),
        &LoadOptions::default(),
    )
    .unwrap();
    assert_eq!(s.patches.iter().map(|p| p.vertices.len()).collect::<Vec<_>>(), [4, 3]);
}

/// Every patch carries its mesh and material names: a long name is shortened once, not copied
/// at full length into every triangle.
#[test]
fn long_names_are_shortened() {
    let mut d = lit_square();
    d["meshes"][0]["name"] = json!("m".repeat(100_000));
    d["materials"][0]["name"] = json!("é".repeat(50_000));
    let s = load_ok(&write_doc("long_names", &d));
    let p = &s.patches[0];
    assert!(p.mesh.len() <= 256 + 3 && p.mesh.starts_with("mmm"), "{}", p.mesh.len());
    assert!(p.material.len() <= 256 + 3 && p.material.starts_with('é'), "{}", p.material.len());
    assert!(p.name.len() < 300);
    assert!(
        s.warnings.iter().any(|w| w.contains("2 mesh or material name(s) longer than 256 bytes")),
        "{:?}",
        s.warnings
    );
}

/// Buffers' declared byteLengths are summed and capped before any is read; many buffers naming
/// the one GLB binary chunk share it.
#[test]
fn declared_buffer_lengths_are_capped_and_the_glb_chunk_is_shared() {
    let mut d = lit_square();
    d["buffers"] = json!([d["buffers"][0].clone(), {"byteLength": 3u64 << 30, "uri": "a.bin"}, {"byteLength": 3u64 << 30, "uri": "b.bin"}]);
    let e = load_err(&write_doc("declared", &d));
    assert!(
        e.to_string()
            .contains("buffers declare 6442451016 bytes in all, more than the 4294967296 byte limit"),
        "{e}"
    );

    let (p, i) = square();
    let bin = bytes_of(&p, &i);
    let mut d = doc(&p, &i, Some(emissive(0.5, 1.0)));
    let buffers: Vec<Value> = (0..2000).map(|_| json!({"byteLength": bin.len()})).collect();
    d["buffers"] = json!(buffers);
    d["bufferViews"][1]["buffer"] = json!(1999);
    let s = load_slice(&glb(&d, &bin), None, Path::new("shared.glb"), &LoadOptions::default()).unwrap();
    assert_eq!(s.patches.len(), 1);
}

/// Run `f` on a thread and wait at most `secs` for it: a refusal that regresses into a blocking
/// open or an endless read fails the test instead of hanging it.
#[cfg(unix)]
fn within<T: Send + 'static>(secs: u64, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(std::time::Duration::from_secs(secs))
        .expect("did not return: blocked on a FIFO or device?")
}

#[cfg(unix)]
fn mkfifo(path: &Path) {
    let ok = std::process::Command::new("mkfifo").arg(path).status().unwrap().success();
    assert!(ok, "mkfifo {}", path.display());
}

/// A FIFO as a buffer would block the loader until a writer came (and then read what it
/// wrote); a FIFO as an image is refused the same way, before anything opens it.
#[cfg(unix)]
#[test]
fn fifo_buffer_or_image_is_refused() {
    let dir = tmpdir("fifo");
    mkfifo(&dir.join("pipe.bin"));
    let mut d = lit_square();
    d["buffers"][0] = json!({"byteLength": 72, "uri": "pipe.bin"});
    let path = write(&dir, "fifo_buffer.gltf", serde_json::to_string(&d).unwrap().as_bytes());
    let e = within(30, move || load_err(&path));
    assert!(matches!(e, SceneError::Buffer { index: 0, .. }), "{e}");
    assert!(e.to_string().contains("pipe.bin is a FIFO, not a regular file"), "{e}");

    let mut d = lit_square();
    d["images"] = json!([{"uri": "pipe.bin"}]);
    let path = write(&dir, "fifo_image.gltf", serde_json::to_string(&d).unwrap().as_bytes());
    let e = within(30, move || load_err(&path));
    assert!(e.to_string().contains("image 0: ") && e.to_string().contains("is a FIFO"), "{e}");
    // A missing image is only a warning (its texture is not used; the factor is).
    d["images"] = json!([{"uri": "missing.png"}]);
    let s = load_ok(&write(&dir, "missing_image.gltf", serde_json::to_string(&d).unwrap().as_bytes()));
    assert!(s.warnings.iter().any(|w| w.contains("image 0") && w.contains("not found")), "{:?}", s.warnings);
}

/// The scene file itself must be a regular file: a device never ends (`/dev/zero` was read until
/// memory ran out) and a FIFO blocks.
#[cfg(unix)]
#[test]
fn device_or_fifo_as_the_scene_file_is_refused() {
    let e = within(30, || load_err(Path::new("/dev/zero")));
    assert!(matches!(e, SceneError::NotRegularFile { kind: "a character device", .. }), "{e}");
    let dir = tmpdir("fifo_scene");
    let path = dir.join("scene.gltf");
    mkfifo(&path);
    let e = within(30, move || load_err(&path));
    assert!(e.to_string().contains("it is a FIFO, not a regular file"), "{e}");
    let e = load_err(&dir);
    assert!(matches!(e, SceneError::NotRegularFile { kind: "a folder", .. }), "{e}");
}

/// A device given as a buffer or image URI is refused before it is opened (`/dev/zero` would be
/// read until the byte limit, `/dev/tty` could block). A symbolic link to a device resolves
/// outside the scene's folder; a device node inside the folder (made where `mknod` is
/// permitted, as root in CI's container) is not a regular file.
#[cfg(unix)]
#[test]
fn device_as_buffer_or_image_is_refused() {
    let dir = tmpdir("device");
    std::os::unix::fs::symlink("/dev/zero", dir.join("zero.bin")).unwrap();
    let node = std::process::Command::new("mknod")
        .arg(dir.join("node.bin"))
        .args(["c", "1", "5"])
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    let mut uris = vec![("zero.bin", "resolves outside the scene's folder")];
    if node {
        uris.push(("node.bin", "node.bin is a character device, not a regular file"));
    } else {
        eprintln!("mknod not permitted here: only the symbolic link to /dev/zero is tested");
    }
    for (uri, cause) in uris {
        let mut d = lit_square();
        d["buffers"][0] = json!({"byteLength": 72, "uri": uri});
        let path = write(&dir, "device_buffer.gltf", serde_json::to_string(&d).unwrap().as_bytes());
        let e = within(30, move || load_err(&path));
        assert!(
            matches!(e, SceneError::Buffer { index: 0, .. }) && e.to_string().contains(cause),
            "{uri}: {e}"
        );

        let mut d = lit_square();
        d["images"] = json!([{"uri": uri}]);
        let path = write(&dir, "device_image.gltf", serde_json::to_string(&d).unwrap().as_bytes());
        let e = within(30, move || load_err(&path));
        assert!(
            matches!(e, SceneError::Image { index: 0, .. }) && e.to_string().contains(cause),
            "{uri}: {e}"
        );
    }
}

/// A texture whose header declares a huge image (PNG 100 000 × 100 000, JPEG 65 500 × 65 500:
/// 30 and 12.9 GB as 8-bit RGB), in a file of 1–2 KB, is refused from its header, before any
/// pixel buffer is allocated: a one-line error naming the file, the image and the size. The
/// files are in tests/fuzz_regressions/ (a textured square; the JPEG is the Blender scene's
/// wall.jpg with its frame header's size rewritten). The fuzz target's lower pixel cap gives the
/// same refusal.
#[test]
fn huge_texture_headers_are_refused_before_decoding() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions");
    let fuzz_caps = LoadOptions { max_texture_pixels: 1 << 20, ..LoadOptions::default() };
    for (name, size) in [("huge_png_header.gltf", "100000×100000"), ("huge_jpeg_header.gltf", "65500×65500")]
    {
        let path = dir.join(name);
        for opts in [LoadOptions::default(), fuzz_caps.clone()] {
            let (p, o) = (path.clone(), opts.clone());
            let e = within(30, move || load_err_with(&p, &o));
            let msg = e.to_string();
            assert!(matches!(e, SceneError::Image { index: 0, .. }), "{name}: {msg}");
            assert!(msg.contains(&format!("image is {size}, more than the limit")), "{name}: {msg}");
            let bytes = std::fs::read(&path).unwrap();
            let e = load_slice(&bytes, None, Path::new(name), &opts).unwrap_err().to_string();
            assert!(e.contains(name) && e.contains(size) && !e.contains('\n'), "{name}: {e}");
        }
    }
}

/// A file's textures may decode to 4 × `max_texture_pixels` in all, and that total is summed
/// from the headers before any texture is decoded: `texture_budget_headers.gltf` (3 KB) has five
/// data-URI images whose headers each declare 8192 × 8192 (four PNGs, one JPEG), each within the
/// per-image cap, none with pixel data. The fifth takes the total over the budget and the file
/// is refused naming it; were the images decoded first, the first one's missing data would be
/// the error. With the cap raised so the five fit, the first image is decoded and fails.
#[test]
fn texture_budget_is_checked_from_the_headers_before_decoding() {
    let name = "texture_budget_headers.gltf";
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions").join(name);
    let (p, o) = (path.clone(), LoadOptions::default());
    let e = within(30, move || load_err_with(&p, &o));
    let msg = e.to_string();
    assert!(matches!(e, SceneError::Image { index: 4, .. }), "{msg}");
    assert!(msg.contains(name) && !msg.contains('\n'), "{msg}");
    assert!(msg.contains("8192×8192 takes the textures' headers to 335544320 pixels"), "{msg}");
    assert!(msg.contains("more than the limit of 268435456") && msg.contains("nothing decoded"), "{msg}");
    let bytes = std::fs::read(&path).unwrap();
    let e = load_slice(&bytes, None, Path::new(name), &LoadOptions::default()).unwrap_err();
    assert_eq!(e.to_string(), msg.replacen(&path.display().to_string(), name, 1));
    // Five 8192² images are exactly the budget of a cap of 5/4 × 8192²: the headers pass, and
    // decoding the first (a header without pixels) is the error.
    let roomy = LoadOptions { max_texture_pixels: 5 << 24, ..LoadOptions::default() };
    let e = load_slice(&bytes, None, Path::new(name), &roomy).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, SceneError::Image { index: 0, .. }) && msg.contains("cannot decode"), "{msg}");
}

/// Loading reads and never writes: the file's bytes and modification time are unchanged, and a
/// read-only file loads.
#[test]
fn the_input_file_is_never_written() {
    let f = write_doc("readonly", &lit_square());
    let before = std::fs::read(&*f).unwrap();
    let mut perms = std::fs::metadata(&*f).unwrap().permissions();
    perms.set_readonly(true);
    std::fs::set_permissions(&*f, perms).unwrap();
    let mtime = std::fs::metadata(&*f).unwrap().modified().unwrap();
    assert_eq!(load_ok(&f).patches.len(), 1);
    assert_eq!(std::fs::read(&*f).unwrap(), before);
    assert_eq!(std::fs::metadata(&*f).unwrap().modified().unwrap(), mtime);
}

/// The fuzz target's seed corpus (fuzz/seeds/loader, made by fuzz/make_seeds.py) loads: the
/// fuzzer starts from files that reach the geometry, not from early errors.
#[test]
fn fuzz_seeds_load_from_bytes() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/seeds/loader");
    let mut names: Vec<PathBuf> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
    names.sort();
    assert!(names.len() >= 8, "{names:?}");
    assert!(names.iter().any(|p| p.extension().is_some_and(|e| e == "glb")));
    for path in &names {
        let bytes = std::fs::read(path).unwrap();
        let s = load_slice(&bytes, None, path, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        assert!(!s.patches.is_empty() && s.validate().is_empty(), "{}", path.display());
    }
    // features.glb: two meshes under a node tree, u8 and u16 indices, a double-sided floor, a
    // camera, and both image sources.
    let bytes = std::fs::read(dir.join("features.glb")).unwrap();
    let s = load_slice(&bytes, None, Path::new("features.glb"), &LoadOptions::default()).unwrap();
    assert_eq!(s.patches.len(), 3);
    assert!(s.camera.is_some());
    assert!(s.patches.iter().any(|p| p.emission.max_channel() > 4.0));
}
