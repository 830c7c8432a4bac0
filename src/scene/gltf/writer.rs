//! The glTF writer, the loader's inverse: one buffer (a data URI, or the .glb's BIN chunk
//! [glTF 2.0, sec. 4.4]), one mesh per run of patches with the same mesh name, one material per
//! distinct (ρ, E) (E above 1 as `KHR_materials_emissive_strength`), quads as two triangles
//! `(0 1 2)(0 2 3)` that the loader merges back, and the scene camera as a camera node.
//! Deterministic: the same scene gives the same bytes.

use crate::math::DVec3;
use crate::scene::{Patch, Scene, SceneError, Viewpoint};
use base64::Engine as _;
use glam::{DMat3, DQuat, DVec4};
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(Serialize)]
struct OutRoot {
    asset: OutAsset,
    #[serde(rename = "extensionsUsed", skip_serializing_if = "Vec::is_empty")]
    extensions_used: Vec<&'static str>,
    scene: usize,
    scenes: Vec<OutScene>,
    nodes: Vec<OutNode>,
    meshes: Vec<OutMesh>,
    materials: Vec<OutMaterial>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    cameras: Vec<OutCamera>,
    accessors: Vec<OutAccessor>,
    #[serde(rename = "bufferViews")]
    buffer_views: Vec<OutView>,
    buffers: Vec<OutBuffer>,
}
#[derive(Serialize)]
struct OutAsset {
    version: &'static str,
    generator: &'static str,
}
#[derive(Serialize)]
struct OutScene {
    nodes: Vec<usize>,
}
#[derive(Serialize)]
struct OutNode {
    name: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    mesh: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    camera: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    translation: Option<[f32; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    rotation: Option<[f32; 4]>,
}
#[derive(Serialize)]
struct OutMesh {
    name: String,
    primitives: Vec<OutPrimitive>,
}
#[derive(Serialize)]
struct OutPrimitive {
    attributes: OutAttributes,
    indices: usize,
    material: usize,
    mode: u32,
}
#[derive(Serialize)]
struct OutAttributes {
    #[serde(rename = "POSITION")]
    position: usize,
}
#[derive(Serialize)]
struct OutMaterial {
    name: String,
    #[serde(rename = "pbrMetallicRoughness")]
    pbr: OutPbr,
    #[serde(rename = "emissiveFactor")]
    emissive_factor: [f32; 3],
    #[serde(skip_serializing_if = "Option::is_none")]
    extensions: Option<OutMatExt>,
}
#[derive(Serialize)]
struct OutPbr {
    #[serde(rename = "baseColorFactor")]
    base_color_factor: [f32; 4],
    #[serde(rename = "metallicFactor")]
    metallic_factor: f32,
    #[serde(rename = "roughnessFactor")]
    roughness_factor: f32,
}
#[derive(Serialize)]
struct OutMatExt {
    #[serde(rename = "KHR_materials_emissive_strength")]
    strength: OutStrength,
}
#[derive(Serialize)]
struct OutStrength {
    #[serde(rename = "emissiveStrength")]
    emissive_strength: f32,
}
#[derive(Serialize)]
struct OutCamera {
    #[serde(rename = "type")]
    kind: &'static str,
    perspective: OutPerspective,
}
#[derive(Serialize)]
struct OutPerspective {
    yfov: f32,
    znear: f32,
}
#[derive(Serialize)]
struct OutAccessor {
    #[serde(rename = "bufferView")]
    buffer_view: usize,
    #[serde(rename = "componentType")]
    component_type: u32,
    count: usize,
    #[serde(rename = "type")]
    kind: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    min: Option<[f32; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    max: Option<[f32; 3]>,
}
#[derive(Serialize)]
struct OutView {
    buffer: usize,
    #[serde(rename = "byteOffset")]
    byte_offset: usize,
    #[serde(rename = "byteLength")]
    byte_length: usize,
    target: u32,
}
#[derive(Serialize)]
struct OutBuffer {
    #[serde(rename = "byteLength")]
    byte_length: usize,
    /// A data: URI in a .gltf; none in a .glb, whose buffer is its BIN chunk.
    #[serde(skip_serializing_if = "Option::is_none")]
    uri: Option<String>,
}

const GL_FLOAT: u32 = 5126;
const GL_UNSIGNED_INT: u32 = 5125;
const GL_ARRAY_BUFFER: u32 = 34962;
const GL_ELEMENT_ARRAY_BUFFER: u32 = 34963;
const GL_TRIANGLES: u32 = 4;

/// The glTF JSON text for a scene (see [`write_gltf`]); deterministic.
pub fn gltf_string(scene: &Scene) -> Result<String, SceneError> {
    let (mut root, bin) = out_root(scene)?;
    root.buffers.push(OutBuffer {
        byte_length: bin.len(),
        uri: Some(format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&bin)
        )),
    });
    let mut s = serde_json::to_string_pretty(&root).map_err(|e| out_error(scene, &e))?;
    s.push('\n');
    Ok(s)
}

/// The scene as binary glTF (.glb): the JSON of [`gltf_string`] with the one buffer in the BIN
/// chunk instead of a data URI [Khronos glTF 2.0 specification, sec. 4.4 (GLB file format)].
/// A 12-byte header, the JSON chunk padded with spaces and the BIN chunk padded with zeros to
/// 4 bytes; deterministic.
pub fn glb_bytes(scene: &Scene) -> Result<Vec<u8>, SceneError> {
    const MAGIC: &[u8; 4] = b"glTF";
    const CHUNK_JSON: u32 = 0x4E4F_534A;
    const CHUNK_BIN: u32 = 0x004E_4942;
    let (mut root, mut bin) = out_root(scene)?;
    root.buffers.push(OutBuffer { byte_length: bin.len(), uri: None });
    let mut json = serde_json::to_vec(&root).map_err(|e| out_error(scene, &e))?;
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let length = u32::try_from(total)
        .map_err(|_| out_error(scene, &format!("{total} bytes is more than a .glb can hold (4 GiB)")))?;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&length.to_le_bytes());
    for (kind, chunk) in [(CHUNK_JSON, &json), (CHUNK_BIN, &bin)] {
        out.extend_from_slice(&(chunk.len() as u32).to_le_bytes());
        out.extend_from_slice(&kind.to_le_bytes());
        out.extend_from_slice(chunk);
    }
    Ok(out)
}

fn out_error(scene: &Scene, cause: &dyn std::fmt::Display) -> SceneError {
    SceneError::InvalidGltf { file: PathBuf::from(&scene.source), cause: cause.to_string() }
}

/// The document without its buffer, and the buffer's bytes: one mesh per run of patches with one
/// mesh name, one material per distinct (ρ, E), the camera.
fn out_root(scene: &Scene) -> Result<(OutRoot, Vec<u8>), SceneError> {
    let mut root = OutRoot {
        asset: OutAsset { version: "2.0", generator: "radlab" },
        extensions_used: Vec::new(),
        scene: 0,
        scenes: vec![OutScene { nodes: Vec::new() }],
        nodes: Vec::new(),
        meshes: Vec::new(),
        materials: Vec::new(),
        cameras: Vec::new(),
        accessors: Vec::new(),
        buffer_views: Vec::new(),
        buffers: Vec::new(),
    };
    let mut bin: Vec<u8> = Vec::new();
    let mut mat_of: Vec<MaterialKey> = Vec::new();

    let mut i = 0;
    while i < scene.patches.len() {
        // A run of patches with one mesh name → one mesh; sub-runs of (primitive, material) → primitives.
        let mesh_name = &scene.patches[i].mesh;
        let mut mesh = OutMesh { name: mesh_name.clone(), primitives: Vec::new() };
        while i < scene.patches.len() && &scene.patches[i].mesh == mesh_name {
            let material = material_index(&mut root, &mut mat_of, scene, i)?;
            let (positions, indices, next) = primitive_run(scene, i);
            i = next;
            mesh.primitives.push(push_primitive(&mut root, &mut bin, &positions, &indices, material));
        }
        root.scenes[0].nodes.push(root.nodes.len());
        root.nodes.push(OutNode {
            name: mesh.name.clone(),
            mesh: Some(root.meshes.len()),
            camera: None,
            translation: None,
            rotation: None,
        });
        root.meshes.push(mesh);
    }
    if let Some(cam) = scene.camera {
        push_camera(&mut root, cam, scene.bounds().diagonal()).map_err(|cause| out_error(scene, &cause))?;
    }
    Ok((root, bin))
}

/// A patch's material as the writer tells materials apart: the bits of ρ and E.
type MaterialKey = ([u64; 3], [u64; 3]);

fn material_key(p: &Patch) -> MaterialKey {
    (p.reflectance.0.map(f64::to_bits), p.emission.0.map(f64::to_bits))
}

/// The index of patch `i`'s material, added to `root` (and its key to `mat_of`) the first time it
/// is seen: ρ as the base colour, E as the emissive factor, scaled into [0, 1] by
/// `KHR_materials_emissive_strength` when a channel is above 1.
fn material_index(
    root: &mut OutRoot,
    mat_of: &mut Vec<MaterialKey>,
    scene: &Scene,
    i: usize,
) -> Result<usize, SceneError> {
    let first = &scene.patches[i];
    let key = material_key(first);
    if let Some(m) = mat_of.iter().position(|k| *k == key) {
        return Ok(m);
    }
    if !first.reflectance.is_finite() || !first.emission.is_finite() {
        return Err(out_error(scene, &format!("patch {i}: non-finite material")));
    }
    let e = first.emission;
    let strength = e.max_channel().max(1.0);
    let ext = (strength > 1.0)
        .then_some(OutMatExt { strength: OutStrength { emissive_strength: strength as f32 } });
    if ext.is_some() && root.extensions_used.is_empty() {
        root.extensions_used.push("KHR_materials_emissive_strength");
    }
    let r = first.reflectance;
    root.materials.push(OutMaterial {
        name: first.material.clone(),
        pbr: OutPbr {
            base_color_factor: [r.0[0] as f32, r.0[1] as f32, r.0[2] as f32, 1.0],
            metallic_factor: 0.0,
            roughness_factor: 1.0,
        },
        emissive_factor: (e / strength).0.map(|c| c as f32),
        extensions: ext,
    });
    mat_of.push(key);
    Ok(mat_of.len() - 1)
}

/// The run of patches from `first` with its mesh name, primitive and material, as f32 positions
/// and triangle indices (a quad as `(0 1 2)(0 2 3)`), and the index after the run.
fn primitive_run(scene: &Scene, first: usize) -> (Vec<[f32; 3]>, Vec<u32>, usize) {
    let head = &scene.patches[first];
    let key = material_key(head);
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut indices: Vec<u32> = Vec::new();
    let mut i = first;
    while i < scene.patches.len() {
        let p = &scene.patches[i];
        if p.mesh != head.mesh || p.primitive != head.primitive || material_key(p) != key {
            break;
        }
        let base = positions.len() as u32;
        positions.extend(p.vertices.iter().map(|v| v.to_array().map(|c| c as f32)));
        indices.extend([base, base + 1, base + 2]);
        if p.vertices.len() == 4 {
            indices.extend([base, base + 2, base + 3]);
        }
        i += 1;
    }
    (positions, indices, i)
}

/// One primitive: its positions (with their bounds, as the spec requires) and indices appended to
/// the buffer, each with its view and accessor.
fn push_primitive(
    root: &mut OutRoot,
    bin: &mut Vec<u8>,
    positions: &[[f32; 3]],
    indices: &[u32],
    material: usize,
) -> OutPrimitive {
    let mut mn = [f32::INFINITY; 3];
    let mut mx = [f32::NEG_INFINITY; 3];
    for p in positions {
        for c in 0..3 {
            mn[c] = mn[c].min(p[c]);
            mx[c] = mx[c].max(p[c]);
        }
    }
    let pos_view =
        push_view(root, bin, positions.iter().flatten().flat_map(|f| f.to_le_bytes()), GL_ARRAY_BUFFER);
    root.accessors.push(OutAccessor {
        buffer_view: pos_view,
        component_type: GL_FLOAT,
        count: positions.len(),
        kind: "VEC3",
        min: Some(mn),
        max: Some(mx),
    });
    let idx_view =
        push_view(root, bin, indices.iter().flat_map(|i| i.to_le_bytes()), GL_ELEMENT_ARRAY_BUFFER);
    root.accessors.push(OutAccessor {
        buffer_view: idx_view,
        component_type: GL_UNSIGNED_INT,
        count: indices.len(),
        kind: "SCALAR",
        min: None,
        max: None,
    });
    OutPrimitive {
        attributes: OutAttributes { position: root.accessors.len() - 2 },
        indices: root.accessors.len() - 1,
        material,
        mode: GL_TRIANGLES,
    }
}

/// The scene camera as a perspective camera node: eye as the translation, the view frame
/// (right, up, −forward) as the rotation [glTF 2.0, sec. 3.10]; the near plane at 1e-3 of the
/// scene's diagonal `diag`.
fn push_camera(root: &mut OutRoot, cam: Viewpoint, diag: f64) -> Result<(), String> {
    let forward = (cam.target - cam.eye).normalize_or_zero();
    let right = forward.cross(cam.up).normalize_or_zero();
    if right == DVec3::ZERO {
        return Err("camera: up is parallel to the view direction".into());
    }
    let up = right.cross(forward);
    let rot = DQuat::from_mat3(&DMat3::from_cols(right, up, -forward)).normalize();
    root.scenes[0].nodes.push(root.nodes.len());
    root.nodes.push(OutNode {
        name: "camera".into(),
        mesh: None,
        camera: Some(0),
        translation: Some(cam.eye.to_array().map(|c| c as f32)),
        rotation: Some(DVec4::from(rot).to_array().map(|c| c as f32)),
    });
    root.cameras.push(OutCamera {
        kind: "perspective",
        perspective: OutPerspective { yfov: cam.fov_y_deg.to_radians() as f32, znear: (1e-3 * diag) as f32 },
    });
    Ok(())
}

fn push_view(root: &mut OutRoot, bin: &mut Vec<u8>, bytes: impl Iterator<Item = u8>, target: u32) -> usize {
    let start = bin.len();
    bin.extend(bytes);
    root.buffer_views.push(OutView { buffer: 0, byte_offset: start, byte_length: bin.len() - start, target });
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    root.buffer_views.len() - 1
}

/// Write a scene as a self-contained .gltf (one data-URI buffer). Loading the file gives back the
/// same patches in the same order (f32 precision), quads included.
pub fn write_gltf(scene: &Scene, path: &Path) -> Result<(), SceneError> {
    let text = gltf_string(scene)?;
    std::fs::write(path, text).map_err(|source| SceneError::Write { file: path.to_path_buf(), source })
}

/// Write a scene as binary glTF (.glb, [`glb_bytes`]). Loading the file gives back the same
/// patches in the same order (f32 precision), quads included.
pub fn write_glb(scene: &Scene, path: &Path) -> Result<(), SceneError> {
    let bytes = glb_bytes(scene)?;
    std::fs::write(path, bytes).map_err(|source| SceneError::Write { file: path.to_path_buf(), source })
}
