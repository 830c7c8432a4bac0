//! A solved scene baked into a glTF 2.0 asset that any viewer shows as solved.
//!
//! Radiosity is view-independent: a diffuse surface leaves radiance L = B/π in every direction
//! [Cohen & Wallace 1993, sec. 2.4], so the solution *is* a coloured mesh. Every leaf element of a
//! [`Solution`] becomes one polygon (a quad as two triangles) with per-vertex values of its own
//! reconstruction, B at the vertex (its average with its slope where it has one,
//! [`crate::solver::SolvedElement::corner_values`]):
//!
//! ```text
//!   COLOR_0    = clamp(B · exposure, 0, 1)   linear RGB, VEC3 float (glTF requires [0, 1])
//!   _RADIOSITY = B                           linear RGB, VEC3 float, unclamped, no exposure
//! ```
//!
//! and POSITION, NORMAL (the patch's plane) and indices, under one material with
//! `KHR_materials_unlit` and base colour 1, so a viewer shows COLOR_0 unlit: the lighting as
//! solved [Khronos glTF 2.0 specification, sec. 3.7.2 (attributes); KHR_materials_unlit]. The material
//! is single-sided, as radlab's patches are: a patch radiates and receives on its front only (a
//! `doubleSided` input material already became two back-to-back patches, each baked with its own
//! radiosity).
//!
//! B is radiant exitance (emitted + reflected power per unit area) in the scene's own unit of
//! emission ([`UNITS`]); the exposure, its rule, the units and where the solution came from are
//! written to `asset.extras.radlab` (and again to the scene's `extras`, which Blender keeps as
//! custom properties). The piecewise-constant solution is baked as it is: each element has its
//! own vertices (none shared), so colours do not blend across element edges.
//!
//! **The lightmap form** ([`BakeForm::Lightmap`], `--bake-lightmap SIZE`) bakes the original
//! meshes instead — one polygon per input patch — with `TEXCOORD_1` into one SIZE × SIZE atlas
//! of the solution's reconstruction, an sRGB PNG that the unlit material shows as its base
//! colour (`texCoord: 1`); `TEXCOORD_0` is each patch's planar map in scene units (glTF wants
//! texture coordinate sets numbered from 0). The atlas, its charts and its texels: [`lightmap`].
//!
//! ## Layout
//! ```text
//!   one node + mesh + primitive per input mesh name (patch.mesh, first-appearance order)
//!   accessors per primitive: POSITION, NORMAL, COLOR_0, _RADIOSITY (f32), indices (u32)
//!       lightmap form:       POSITION, NORMAL, TEXCOORD_0, TEXCOORD_1 (f32), indices (u32)
//!                            + sampler (LINEAR, no mipmaps, clamp), texture, image (PNG)
//!   .glb : 12-byte header ─ JSON chunk (space-padded) ─ BIN chunk (zero-padded; the PNG last)
//!   .gltf: JSON with the one buffer (and the PNG) as base64 data: URIs
//! ```
//! Output is deterministic: the same solution gives the same bytes.

pub mod lightmap;

pub use lightmap::{Lightmap, LightmapParams, TEXEL_RULE};

use crate::math::DVec3;
use crate::scene::Scene;
use crate::solver::Solution;
use base64::Engine as _;
use serde_json::{Value, json};
use std::collections::HashMap;
use std::path::Path;

/// What B (and `_RADIOSITY`) is measured in; written to the extras.
pub const UNITS: &str = "radiant exitance B (emitted + reflected power per unit area) in the scene's unit of \
emission: glTF emissiveFactor x KHR_materials_emissive_strength (W/m^2 for a scene authored in W/m^2)";

/// How COLOR_0 relates to B; written to the extras.
pub const COLOR_RULE: &str =
    "COLOR_0 = clamp(B * exposure, 0, 1), linear RGB; _RADIOSITY = B, linear RGB, unclamped";

/// What the two texture coordinate sets of the lightmap form hold; written to the extras.
pub const LIGHTMAP_TEXCOORD_RULE: &str = "TEXCOORD_1 = the vertex in the lightmap atlas (images[0]); TEXCOORD_0 = the \
vertex in its patch's own plane, in scene units from the corner of the patch's bounding box (a planar map for \
tiling textures; the baked material does not use it)";

const GL_FLOAT: u32 = 5126;
const GL_UNSIGNED_INT: u32 = 5125;
const GL_ARRAY_BUFFER: u32 = 34962;
const GL_ELEMENT_ARRAY_BUFFER: u32 = 34963;
const GL_TRIANGLES: u32 = 4;
const GL_LINEAR: u32 = 9729;
const GL_CLAMP_TO_EDGE: u32 = 33071;
const GLB_MAGIC: &[u8; 4] = b"glTF";
const GLB_CHUNK_JSON: u32 = 0x4E4F_534A;
const GLB_CHUNK_BIN: u32 = 0x004E_4942;

/// The two containers a bake can be written in, chosen by the output file's extension.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum BakeFormat {
    /// Binary glTF: one file, JSON and binary chunks.
    Glb,
    /// glTF JSON with the buffer embedded as a base64 `data:` URI.
    Gltf,
}

impl BakeFormat {
    /// `.glb` or `.gltf` (any case); anything else is [`BakeError::UnknownExtension`].
    pub fn from_path(path: &Path) -> Result<BakeFormat, BakeError> {
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("glb") => Ok(BakeFormat::Glb),
            Some("gltf") => Ok(BakeFormat::Gltf),
            _ => Err(BakeError::UnknownExtension { path: path.display().to_string() }),
        }
    }
}

/// What a bake records besides the geometry and colours.
#[derive(Clone, Debug)]
pub struct BakeOptions {
    /// COLOR_0 = clamp(B · exposure, 0, 1); finite and > 0.
    pub exposure: f64,
    /// How the exposure was chosen, in words (written to the extras).
    pub exposure_rule: String,
    /// The scene as the user named it (`builtin:cornell`, a path).
    pub scene_label: String,
    /// The solver's parameters, if the caller has them (written to the extras).
    pub params: Option<Value>,
}

/// Why a solution could not be baked.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    #[error("{path}: a bake is written as .glb or .gltf (the extension chooses which)")]
    UnknownExtension { path: String },
    #[error("exposure {0} is not a finite positive number")]
    BadExposure(f64),
    #[error("the solution has no elements")]
    Empty,
    #[error("element {element} lies on patch {patch}, which the scene does not have")]
    SceneMismatch { element: usize, patch: usize },
    #[error("element {element} (patch {patch}) has a non-finite vertex or radiosity")]
    NonFinite { element: usize, patch: usize },
    #[error("the bake would be {bytes} bytes, over the 4 GiB a glTF buffer or GLB file can hold")]
    TooLarge { bytes: u64 },
    #[error(
        "lightmap size {0}: must be a power of two from {min} to {max}",
        min = LightmapParams::MIN_SIZE,
        max = LightmapParams::MAX_SIZE
    )]
    BadLightmapSize(u32),
    #[error(
        "a {size}x{size} lightmap cannot hold {charts} charts of one texel each with their gutter; use a larger size"
    )]
    LightmapTooSmall { size: u32, charts: usize },
    #[error(transparent)]
    Locate(#[from] crate::eval::metrics::MetricsError),
}

/// What geometry a bake holds.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum BakeForm {
    /// Every leaf element as its own flat polygon coloured by `COLOR_0` (the default).
    Elements,
    /// The original meshes — one polygon per input patch — with `TEXCOORD_1` into one lightmap
    /// atlas, embedded as a PNG ([`lightmap`]).
    Lightmap(LightmapParams),
}

/// The solution as a GLB file's bytes (the element form).
pub fn glb(scene: &Scene, solution: &Solution, opts: &BakeOptions) -> Result<Vec<u8>, BakeError> {
    glb_as(scene, solution, opts, BakeForm::Elements)
}

/// The solution in `form` as a GLB file's bytes; a lightmap is a buffer view of the BIN chunk.
pub fn glb_as(
    scene: &Scene,
    solution: &Solution,
    opts: &BakeOptions,
    form: BakeForm,
) -> Result<Vec<u8>, BakeError> {
    let Document { json: mut doc, mut bin, image } = document(scene, solution, opts, form)?;
    if let Some(png) = image {
        let views = doc["bufferViews"].as_array_mut().expect("document() writes bufferViews as an array");
        views.push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": png.len()}));
        doc["images"][0]["bufferView"] = json!(views.len() - 1);
        doc["images"][0]["mimeType"] = json!("image/png");
        bin.extend_from_slice(&png);
        pad(&mut bin, 0);
        doc["buffers"][0]["byteLength"] = json!(bin.len());
    }
    let mut json = serde_json::to_vec(&doc).expect("a serde_json::Value always serialises");
    pad(&mut json, b' ');
    let total = 12 + 8 + json.len() as u64 + 8 + bin.len() as u64;
    let total32 = u32::try_from(total).map_err(|_| BakeError::TooLarge { bytes: total })?;
    let mut out = Vec::with_capacity(total as usize);
    out.extend_from_slice(GLB_MAGIC);
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total32.to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&GLB_CHUNK_JSON.to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(&GLB_CHUNK_BIN.to_le_bytes());
    out.extend_from_slice(&bin);
    Ok(out)
}

/// The solution as self-contained glTF JSON text (the buffer as a base64 `data:` URI; the
/// element form).
pub fn gltf(scene: &Scene, solution: &Solution, opts: &BakeOptions) -> Result<String, BakeError> {
    gltf_as(scene, solution, opts, BakeForm::Elements)
}

/// The solution in `form` as self-contained glTF JSON text: the buffer, and a lightmap, as
/// base64 `data:` URIs.
pub fn gltf_as(
    scene: &Scene,
    solution: &Solution,
    opts: &BakeOptions,
    form: BakeForm,
) -> Result<String, BakeError> {
    let Document { json: mut doc, bin, image } = document(scene, solution, opts, form)?;
    let b64 = |bytes: &[u8]| base64::engine::general_purpose::STANDARD.encode(bytes);
    doc["buffers"][0]["uri"] = Value::String(format!("data:application/octet-stream;base64,{}", b64(&bin)));
    if let Some(png) = image {
        doc["images"][0]["uri"] = Value::String(format!("data:image/png;base64,{}", b64(&png)));
    }
    let mut text = serde_json::to_string_pretty(&doc).expect("a serde_json::Value always serialises");
    text.push('\n');
    Ok(text)
}

/// The bytes of a bake in `format` (the element form).
pub fn bake(
    scene: &Scene,
    solution: &Solution,
    opts: &BakeOptions,
    format: BakeFormat,
) -> Result<Vec<u8>, BakeError> {
    bake_as(scene, solution, opts, BakeForm::Elements, format)
}

/// The bytes of a bake in `form` and `format`.
pub fn bake_as(
    scene: &Scene,
    solution: &Solution,
    opts: &BakeOptions,
    form: BakeForm,
    format: BakeFormat,
) -> Result<Vec<u8>, BakeError> {
    match format {
        BakeFormat::Glb => glb_as(scene, solution, opts, form),
        BakeFormat::Gltf => gltf_as(scene, solution, opts, form).map(String::into_bytes),
    }
}

/// One primitive's vertex streams, before packing: `colors` and `radiosity` in the element form,
/// `uv0` and `uv1` in the lightmap form.
#[derive(Default)]
struct Streams {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    colors: Vec<[f32; 3]>,
    radiosity: Vec<[f32; 3]>,
    uv0: Vec<[f32; 2]>,
    uv1: Vec<[f32; 2]>,
    indices: Vec<u32>,
}

impl Streams {
    /// A polygon's vertices (each vertex its own) and its fan: a triangle once, a quad (planar,
    /// convex) as two triangles.
    fn push_polygon(&mut self, vertices: &[DVec3], normal: [f32; 3]) {
        let base = self.positions.len() as u32;
        for v in vertices {
            self.positions.push(v.to_array().map(|c| c as f32));
            self.normals.push(normal);
        }
        for k in 1..vertices.len() as u32 - 1 {
            self.indices.extend([base, base + k, base + k + 1]);
        }
    }
}

/// A bake before its container places the buffer and the image.
struct Document {
    /// The glTF JSON, without the buffer's URI.
    json: Value,
    /// The binary buffer, 4-byte aligned.
    bin: Vec<u8>,
    /// The lightmap form's PNG, for the container to place (`images[0]` has no source yet).
    image: Option<Vec<u8>>,
}

/// The bake of `solution` in `form`, before its container.
fn document(
    scene: &Scene,
    solution: &Solution,
    opts: &BakeOptions,
    form: BakeForm,
) -> Result<Document, BakeError> {
    if !(opts.exposure.is_finite() && opts.exposure > 0.0) {
        return Err(BakeError::BadExposure(opts.exposure));
    }
    if solution.elements.is_empty() {
        return Err(BakeError::Empty);
    }
    let (mesh_names, mesh_of_patch) = mesh_groups(scene);
    let mut streams: Vec<Streams> = mesh_names.iter().map(|_| Streams::default()).collect();
    let (clipped, b_max) = element_streams(scene, solution, opts, form, &mesh_of_patch, &mut streams)?;
    let mut info = json!({
        "exposure": opts.exposure,
        "exposure_rule": opts.exposure_rule,
        "units": UNITS,
        "color": COLOR_RULE,
        "scene": opts.scene_label,
        "method": solution.method,
        "elements": solution.elements.len(),
        "patches": scene.patches.len(),
        "clipped_elements": clipped,
        "radiosity_max": b_max,
        "params": opts.params,
        "radlab_version": env!("CARGO_PKG_VERSION"),
    });
    let mut material = json!({
        "name": "radlab baked radiosity (unlit, COLOR_0)",
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
        "doubleSided": false,
        "extensions": {"KHR_materials_unlit": {}},
    });
    let lightmap = match form {
        BakeForm::Lightmap(params) => {
            let map = Lightmap::bake(scene, solution, opts.exposure, params)?;
            lightmap_streams(scene, &map, params, &mesh_of_patch, &mut streams);
            info["color"] = json!(lightmap::TEXEL_RULE);
            info["lightmap"] = json!({
                "size": params.size,
                "padding": params.padding,
                "texels_per_unit": map.texels_per_unit,
                "charts": map.charts.len(),
                "coverage": map.coverage(),
                "clipped_texels": map.clipped_texels,
                "texcoord": LIGHTMAP_TEXCOORD_RULE,
            });
            material["name"] = json!("radlab baked radiosity (unlit, lightmap on TEXCOORD_1)");
            material["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": 0, "texCoord": 1});
            Some(map)
        }
        BakeForm::Elements => None,
    };
    let mut b = Buffers::default();
    for (name, s) in mesh_names.iter().zip(&streams) {
        if s.indices.is_empty() {
            continue; // a mesh whose patches have no elements (none of radlab's solvers does this)
        }
        b.push_mesh(name, s);
    }
    let bytes = b.bin.len() as u64;
    if u32::try_from(bytes).is_err() {
        return Err(BakeError::TooLarge { bytes });
    }
    let mut doc = json!({
        "asset": {
            "version": "2.0",
            "generator": concat!("radlab ", env!("CARGO_PKG_VERSION"), " (baked radiosity)"),
            "extras": {"radlab": info},
        },
        "extensionsUsed": ["KHR_materials_unlit"],
        "scene": 0,
        "scenes": [{"name": scene.name, "nodes": (0..b.nodes.len()).collect::<Vec<_>>(), "extras": {"radlab": info}}],
        "nodes": b.nodes,
        "meshes": b.meshes,
        "materials": [material],
        "accessors": b.accessors,
        "bufferViews": b.views,
        "buffers": [{"byteLength": b.bin.len()}],
    });
    if lightmap.is_some() {
        doc["samplers"] = json!([{"magFilter": GL_LINEAR, "minFilter": GL_LINEAR, "wrapS": GL_CLAMP_TO_EDGE, "wrapT": GL_CLAMP_TO_EDGE}]);
        doc["textures"] = json!([{"name": "radlab lightmap", "sampler": 0, "source": 0}]);
        doc["images"] = json!([{"name": "radlab lightmap"}]);
    }
    Ok(Document { json: doc, bin: b.bin, image: lightmap.map(|m| m.png()) })
}

/// The meshes' names in patch order (first appearance) and each patch's mesh: elements are
/// grouped by their patch's mesh name.
fn mesh_groups(scene: &Scene) -> (Vec<&str>, Vec<usize>) {
    let mut mesh_names: Vec<&str> = Vec::new();
    let mut mesh_of_name: HashMap<&str, usize> = HashMap::new();
    let mesh_of_patch: Vec<usize> = scene
        .patches
        .iter()
        .map(|p| {
            *mesh_of_name.entry(p.mesh.as_str()).or_insert_with(|| {
                mesh_names.push(p.mesh.as_str());
                mesh_names.len() - 1
            })
        })
        .collect();
    (mesh_names, mesh_of_patch)
}

/// Check every element (its patch in the scene, finite values) and, in the elements form, add
/// its polygon with its own reconstruction at its vertices to its mesh's streams. Returns the
/// elements whose exposed colour leaves [0, 1], and the largest B per channel.
fn element_streams(
    scene: &Scene,
    solution: &Solution,
    opts: &BakeOptions,
    form: BakeForm,
    mesh_of_patch: &[usize],
    streams: &mut [Streams],
) -> Result<(usize, [f64; 3]), BakeError> {
    let mut clipped = 0usize;
    let mut b_max = [0.0f64; 3];
    for (i, e) in solution.elements.iter().enumerate() {
        let Some(patch) = scene.patches.get(e.patch) else {
            return Err(BakeError::SceneMismatch { element: i, patch: e.patch });
        };
        if !e.radiosity.is_finite() || e.vertices.iter().any(|v| !v.is_finite()) {
            return Err(BakeError::NonFinite { element: i, patch: e.patch });
        }
        let exposed = e.radiosity.0.map(|c| c * opts.exposure);
        if exposed.iter().any(|c| !(0.0..=1.0).contains(c)) {
            clipped += 1;
        }
        for (m, c) in b_max.iter_mut().zip(e.radiosity.0) {
            *m = m.max(c);
        }
        if form == BakeForm::Elements {
            let s = &mut streams[mesh_of_patch[e.patch]];
            let n = e.vertices.len();
            s.push_polygon(&e.vertices, unit_f32(patch.normal.to_array()));
            // The element's own reconstruction at its vertices: its value with its slope.
            for b in e.corner_values() {
                s.colors.push(b.0.map(|c| (c * opts.exposure).clamp(0.0, 1.0) as f32));
                s.radiosity.push(b.0.map(|c| c as f32));
            }
            debug_assert_eq!(e.corner_values().len(), n);
        }
    }
    Ok((clipped, b_max))
}

/// The lightmap form's polygons: each charted input patch whole, with its planar map
/// (TEXCOORD_0) and its place in the atlas (TEXCOORD_1).
fn lightmap_streams(
    scene: &Scene,
    map: &Lightmap,
    params: LightmapParams,
    mesh_of_patch: &[usize],
    streams: &mut [Streams],
) {
    for c in &map.charts {
        let patch = &scene.patches[c.patch];
        let s = &mut streams[mesh_of_patch[c.patch]];
        s.push_polygon(&patch.vertices, unit_f32(patch.normal.to_array()));
        s.uv0.extend(patch.vertices.iter().map(|&v| c.plane_uv(v)));
        s.uv1.extend(patch.vertices.iter().map(|&v| c.uv(v, params.size)));
    }
}

/// The binary buffer and the glTF arrays that point into it, filled mesh by mesh.
#[derive(Default)]
struct Buffers {
    bin: Vec<u8>,
    accessors: Vec<Value>,
    views: Vec<Value>,
    meshes: Vec<Value>,
    nodes: Vec<Value>,
}

impl Buffers {
    /// One mesh (and its node): its streams' accessors, the indices, one primitive.
    fn push_mesh(&mut self, name: &str, s: &Streams) {
        let mut floats = |data: &[_], min_max: bool| {
            push_floats(&mut self.accessors, &mut self.views, &mut self.bin, data, min_max)
        };
        let mut attributes = json!({
            "POSITION": floats(&s.positions, true),
            "NORMAL": floats(&s.normals, false),
        });
        if !s.colors.is_empty() {
            attributes["COLOR_0"] = json!(floats(&s.colors, false));
            attributes["_RADIOSITY"] = json!(floats(&s.radiosity, false));
        }
        if !s.uv0.is_empty() {
            attributes["TEXCOORD_0"] =
                json!(push_floats(&mut self.accessors, &mut self.views, &mut self.bin, &s.uv0, false));
            attributes["TEXCOORD_1"] =
                json!(push_floats(&mut self.accessors, &mut self.views, &mut self.bin, &s.uv1, false));
        }
        let view = push_view(
            &mut self.views,
            &mut self.bin,
            s.indices.iter().flat_map(|i| i.to_le_bytes()),
            GL_ELEMENT_ARRAY_BUFFER,
        );
        self.accessors.push(json!({"bufferView": view, "componentType": GL_UNSIGNED_INT, "count": s.indices.len(), "type": "SCALAR"}));
        let indices = self.accessors.len() - 1;
        self.nodes.push(json!({"name": name, "mesh": self.meshes.len()}));
        self.meshes.push(json!({
            "name": name,
            "primitives": [{
                "attributes": attributes,
                "indices": indices,
                "material": 0,
                "mode": GL_TRIANGLES,
            }],
        }));
    }
}

/// A unit vector in f32 (normalised again after rounding, for the validator's unit-length check).
fn unit_f32(n: [f64; 3]) -> [f32; 3] {
    let f = n.map(|c| c as f32);
    let len = f.iter().map(|c| c * c).sum::<f32>().sqrt();
    if len > 0.0 { f.map(|c| c / len) } else { [0.0, 0.0, 1.0] }
}

fn bounds<const N: usize>(points: &[[f32; N]]) -> ([f32; N], [f32; N]) {
    let mut lo = [f32::INFINITY; N];
    let mut hi = [f32::NEG_INFINITY; N];
    for p in points {
        for c in 0..N {
            lo[c] = lo[c].min(p[c]);
            hi[c] = hi[c].max(p[c]);
        }
    }
    (lo, hi)
}

/// Append a tightly packed f32 VEC2 or VEC3 accessor (with its min and max if `min_max`) and its
/// buffer view; its index.
fn push_floats<const N: usize>(
    accessors: &mut Vec<Value>,
    views: &mut Vec<Value>,
    bin: &mut Vec<u8>,
    data: &[[f32; N]],
    min_max: bool,
) -> usize {
    let view = push_view(views, bin, data.iter().flatten().flat_map(|f| f.to_le_bytes()), GL_ARRAY_BUFFER);
    let kind = if N == 2 { "VEC2" } else { "VEC3" };
    let mut acc = json!({"bufferView": view, "componentType": GL_FLOAT, "count": data.len(), "type": kind});
    if min_max {
        let (lo, hi) = bounds(data);
        // As f64 of the f32 values, so the JSON numbers equal the stored floats exactly.
        let numbers = |v: [f32; N]| v.map(f64::from).to_vec();
        acc["min"] = json!(numbers(lo));
        acc["max"] = json!(numbers(hi));
    }
    accessors.push(acc);
    accessors.len() - 1
}

/// Append a buffer view (4-byte aligned, as every accessor here is f32 or u32); its index.
fn push_view(
    views: &mut Vec<Value>,
    bin: &mut Vec<u8>,
    bytes: impl Iterator<Item = u8>,
    target: u32,
) -> usize {
    let start = bin.len();
    bin.extend(bytes);
    views.push(json!({"buffer": 0, "byteOffset": start, "byteLength": bin.len() - start, "target": target}));
    pad(bin, 0);
    views.len() - 1
}

fn pad(bytes: &mut Vec<u8>, with: u8) {
    while !bytes.len().is_multiple_of(4) {
        bytes.push(with);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rgb;
    use crate::scene::builtin;
    use crate::solver::SolvedElement;

    fn one_element_per_patch(scene: &Scene) -> Solution {
        let elements = SolvedElement::whole_patches(scene, |i| Rgb::new(0.5, 1.0, 3.0) * (i as f64 + 1.0));
        Solution::of_elements("test", scene.patches.len(), elements)
    }

    fn opts(exposure: f64) -> BakeOptions {
        BakeOptions {
            exposure,
            exposure_rule: "test".into(),
            scene_label: "builtin:furnace".into(),
            params: None,
        }
    }

    #[test]
    fn glb_header_and_chunks_are_aligned_and_sized() {
        let scene = builtin::build("furnace").unwrap();
        let bytes = glb(&scene, &one_element_per_patch(&scene), &opts(0.25)).unwrap();
        assert_eq!(&bytes[0..4], b"glTF");
        assert_eq!(u32::from_le_bytes(bytes[4..8].try_into().unwrap()), 2);
        assert_eq!(u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize, bytes.len());
        let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        assert_eq!(json_len % 4, 0);
        let bin_at = 20 + json_len;
        let bin_len = u32::from_le_bytes(bytes[bin_at..bin_at + 4].try_into().unwrap()) as usize;
        assert_eq!(bin_len % 4, 0);
        assert_eq!(bin_at + 8 + bin_len, bytes.len());
    }

    #[test]
    fn the_same_solution_gives_the_same_bytes() {
        let scene = builtin::build("cornell").unwrap();
        let sol = one_element_per_patch(&scene);
        assert_eq!(glb(&scene, &sol, &opts(0.1)).unwrap(), glb(&scene, &sol, &opts(0.1)).unwrap());
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        let scene = builtin::build("furnace").unwrap();
        let mut sol = one_element_per_patch(&scene);
        assert!(matches!(glb(&scene, &sol, &opts(0.0)), Err(BakeError::BadExposure(_))));
        assert!(matches!(glb(&scene, &sol, &opts(f64::NAN)), Err(BakeError::BadExposure(_))));
        sol.elements[2].radiosity = Rgb::new(f64::NAN, 0.0, 0.0);
        assert!(matches!(glb(&scene, &sol, &opts(1.0)), Err(BakeError::NonFinite { element: 2, .. })));
        sol.elements[2].patch = 99;
        assert!(matches!(glb(&scene, &sol, &opts(1.0)), Err(BakeError::SceneMismatch { patch: 99, .. })));
        sol.elements.clear();
        assert!(matches!(glb(&scene, &sol, &opts(1.0)), Err(BakeError::Empty)));
    }

    /// FNV-1a (64-bit): a hash whose value is fixed by its definition, for golden bytes.
    fn fnv1a(bytes: &[u8]) -> u64 {
        bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
    }

    /// The element bake (no lightmap) of a fixed solution, byte for byte as before the lightmap
    /// existed (the hash was taken from the element bake written before the lightmap was added).
    #[test]
    fn the_element_bake_bytes_are_unchanged() {
        let scene = builtin::build("cornell").unwrap();
        let sol = one_element_per_patch(&scene);
        let glb = glb(&scene, &sol, &opts(0.1)).unwrap();
        let text = gltf(&scene, &sol, &opts(0.1)).unwrap();
        assert_eq!((glb.len(), fnv1a(&glb)), (12_696, 0xd8f0_56ab_78c1_3150));
        assert_eq!((text.len(), fnv1a(text.as_bytes())), (20_464, 0xb70f_716f_d9fc_1be5));
    }

    #[test]
    fn the_extension_chooses_the_format() {
        assert_eq!(BakeFormat::from_path(Path::new("a/b.GLB")).unwrap(), BakeFormat::Glb);
        assert_eq!(BakeFormat::from_path(Path::new("b.gltf")).unwrap(), BakeFormat::Gltf);
        assert!(BakeFormat::from_path(Path::new("b.png")).is_err());
        assert!(BakeFormat::from_path(Path::new("glb")).is_err());
    }
}
