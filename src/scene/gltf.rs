//! glTF 2.0 import and export of radiosity scenes.
//!
//! A glTF file [Khronos glTF 2.0 specification, sec. 3.7 (meshes), sec. 3.9 (materials)] becomes
//! a list of planar convex patches:
//!
//! - **Geometry**: every `TRIANGLES` primitive of every mesh instance, with the node's world
//!   transform applied (`M = M_root · … · M_node`, f64). A transform with det(M) < 0 mirrors the
//!   geometry, so each triangle's winding is reversed to keep its front side where it was.
//! - **Material**: `baseColorFactor.rgb` → ρ (linear RGB), times the mean of the base-colour
//!   texture (PNG or JPEG, sRGB decoded to linear) over each patch when there is one
//!   ([`super::texture`]: 16 stratified samples per triangle, a merged quad's two triangles
//!   weighted by area; the product clamped to `RHO_MAX`), `emissiveFactor ×
//!   KHR_materials_emissive_strength` → E (radiant exitance, the unit of B). No material → ρ = 0.5,
//!   E = 0. `doubleSided` → two back-to-back patches (the back one right after the front one).
//!   ρ ∈ [`RHO_MAX`], 1] is clamped to `RHO_MAX` with a warning (the SPLASH-2 lamps have ρ = 1.0,
//!   which would make an enclosure's system singular); ρ < 0, ρ > 1, or E < 0 / non-finite are
//!   errors.
//! - **Extensions**: `KHR_materials_emissive_strength` is read. `KHR_lights_punctual` lights are
//!   skipped with a one-line warning (radlab is lit by emissive surfaces; a point has no area).
//!   Every other extension in `extensionsUsed` is named in one warning and ignored; one in
//!   `extensionsRequired` that is not read is an error.
//! - **Quads**: two triangles of one primitive that share an edge (same positions, opposite
//!   directions) and form a planar, strictly convex quadrilateral are merged into one quad patch,
//!   so a quadtree can subdivide imported quads.
//!
//! ## Patch numbering (used by the CLI and tests)
//! Scene nodes depth-first in document order; each mesh's primitives in order; triangles in index
//! order. A merged quad takes its first triangle's place; the partner is the earliest later
//! triangle that qualifies. Zero-area triangles are dropped (and counted in a warning).
//!
//! ```text
//!   tri i = (p0 p1 p2), shared edge p2→p0, tri j = (p0 p2 q)      p2 ──── q
//!   quad  = (p0 p1 p2 q)   (starts at p0, keeps i's orientation)   │ i   ╱ │
//!                                                                  │   ╱ j │
//!                                                                  p1 ── p0
//! ```
//!
//! ## Untrusted input
//! Buffers are read by this module, not by the `gltf` crate: only `data:` URIs (base64) and
//! relative file paths that stay inside the scene's folder are accepted
//! ([`SceneError::UriOutsideScene`] otherwise, for image URIs too). GLB containers are parsed
//! here as well. Every buffer, buffer view and accessor range is checked with overflow-safe
//! arithmetic before any byte is read, and the triangle count is checked against
//! [`LoadOptions::max_triangles`] before any geometry is read, so a hostile file can neither panic
//! the loader nor make it allocate without bound. `tests/gltf_loader.rs` and the fuzz target
//! (`fuzz/`, docs/fuzzing.md) hold it to that. In detail:
//!
//! - **Files**: the scene file and buffer files are read only if they are regular files (a FIFO
//!   would block, a device never end), opened read-only, and read up to
//!   [`LoadOptions::max_file_bytes`]; the sum of the buffers' declared byteLengths is capped
//!   the same way before any is read. Image files are read the same way when a material uses
//!   them as its base-colour texture, and one that exists must be a regular file inside the
//!   folder in any case; a texture's size is read from its header and refused above
//!   [`LoadOptions::max_texture_pixels`] (8192 × 8192) before it is decoded, and a file's
//!   textures may have `TEXTURE_BUDGET` (4) times that in all (kept at 3 bytes a pixel),
//!   summed from all their headers before any is decoded. Nothing is ever written.
//! - **Structure the `gltf` crate assumes** and does not validate is checked first: an image has
//!   one source (and a MIME type with a buffer view), a camera has the projection its type
//!   names, and the nodes form disjoint trees, so the walk visits each node once (a node reused
//!   as a child would describe exponentially many instances).
//! - **Work linear in the input plus the output**: each primitive is decoded once however many
//!   nodes instance it, and an instance transforms only the vertices its triangles use; quad
//!   merging looks at no more than `MAX_EDGE_CANDIDATES` partners per edge; names longer than
//!   `MAX_NAME_BYTES` are shortened, since every patch carries them. The output is bounded by
//!   the triangle cap.
//!
//! The writer ([`write_gltf`], [`write_glb`]) produces the inverse: one buffer (a data URI, or
//! the .glb's BIN chunk), one mesh per run of patches with the same mesh name, one material per
//! distinct (ρ, E), quads as two triangles `(0 1 2)(0 2 3)` that the loader merges back, and the
//! scene camera as a camera node.

use super::texture::{Texture, Wrap};
use super::{PLANARITY_TOL, Patch, RHO_MAX, Scene, SceneError, Viewpoint, is_convex};
use crate::math::{DVec3, Rgb};
use base64::Engine as _;
use glam::{DMat3, DMat4, DQuat, DVec4};
use gltf::accessor::{DataType, Dimensions};
use serde::Serialize;
use std::borrow::Cow;
use std::collections::{BTreeSet, HashMap};
use std::io::Read;
use std::path::{Component, Path, PathBuf};
use std::rc::Rc;

/// Extensions the loader reads. `KHR_lights_punctual` is parsed too, but its lights are skipped
/// with a warning (radlab lights scenes by emissive surfaces only).
const READ_EXTENSIONS: &[&str] = &["KHR_materials_emissive_strength"];

/// Options for loading a glTF file.
#[derive(Clone, Debug)]
pub struct LoadOptions {
    /// Refuse files with more triangles than this (counted over all mesh instances before any
    /// geometry is read). Default 5 M.
    pub max_triangles: usize,
    /// Refuse a .gltf/.glb file or an external buffer file larger than this many bytes.
    /// Default 4 GiB.
    pub max_file_bytes: u64,
    /// Refuse base-colour textures with more pixels than this (and wider or taller than
    /// [`texture::MAX_SIDE`](super::texture::MAX_SIDE)), before decoding them. Default 2^26
    /// (8192 × 8192).
    pub max_texture_pixels: u64,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions { max_triangles: 5_000_000, max_file_bytes: 4 << 30, max_texture_pixels: 1 << 26 }
    }
}

/// A triangle with area below this fraction of its longest edge squared is numerically
/// collinear (f32 input carries ~1e-7 relative noise; its square bounds honest slivers far above).
const DEGENERATE_REL_AREA: f64 = 1e-14;

/// Two triangles merge into a quad only if every corner turns by more than this (relative
/// to the quad's size squared): a quad with a ~straight corner is really a triangle.
const MERGE_CONVEX_REL: f64 = 1e-9;

/// A merge partner is looked for among at most this many later triangles on each edge. A
/// surface edge has one (two triangles share it); more is a fan of overlapping triangles, and
/// looking at all of them would make merging quadratic in the primitive's size.
const MAX_EDGE_CANDIDATES: usize = 8;

/// Mesh and material names longer than this are shortened (with a warning): every patch carries
/// its names, so a long name would otherwise cost its length once per triangle instance.
const MAX_NAME_BYTES: usize = 256;

/// The decoded textures of one file may have at most this many times
/// [`LoadOptions::max_texture_pixels`] in all (each is 3 bytes a pixel in memory).
const TEXTURE_BUDGET: u64 = 4;

/// Load a .gltf or .glb file. Relative buffer URIs are resolved in the file's folder. The file
/// is opened for reading only, and only if it is a regular file (see [`read_regular`]).
pub fn load(path: &Path, opts: &LoadOptions) -> Result<Scene, SceneError> {
    let bytes = read_regular(path, opts.max_file_bytes, None).map_err(|e| match e {
        ReadError::Io(source) => SceneError::Io { file: path.to_path_buf(), source },
        ReadError::NotRegular(kind) => SceneError::NotRegularFile { file: path.to_path_buf(), kind },
        ReadError::TooLarge(len) => SceneError::InvalidGltf {
            file: path.to_path_buf(),
            cause: format!("file has {len} bytes, more than the {} byte limit", opts.max_file_bytes),
        },
    })?;
    let base = path.parent().map(|p| if p.as_os_str().is_empty() { Path::new(".") } else { p });
    let mut scene = load_slice(&bytes, base, path, opts)?;
    scene.source = path.display().to_string();
    Ok(scene)
}

/// Why [`read_regular`] refused or failed.
enum ReadError {
    Io(std::io::Error),
    /// What the path is instead of a regular file ("a FIFO", "a character device", …).
    NotRegular(&'static str),
    /// The file's size in bytes, above the limit.
    TooLarge(u64),
}

/// What a non-regular file is, for the error message.
fn file_kind(ft: std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt as _;
        if ft.is_fifo() {
            return "a FIFO";
        }
        if ft.is_char_device() {
            return "a character device";
        }
        if ft.is_block_device() {
            return "a block device";
        }
        if ft.is_socket() {
            return "a socket";
        }
    }
    if ft.is_dir() { "a folder" } else { "not a regular file" }
}

/// Read a regular file of at most `max_bytes` bytes (at most `want` of them, if given).
///
/// A FIFO, device, socket or folder is refused before it is opened: opening a FIFO blocks until
/// a writer comes, and a device such as `/dev/zero` never ends. The file is then opened read-only
/// and non-blocking (so a FIFO swapped in after the check cannot block either), checked again
/// through the open handle, and read through `take`, so the allocation is bounded by the limit
/// even if the file grows meanwhile.
fn read_regular(path: &Path, max_bytes: u64, want: Option<u64>) -> Result<Vec<u8>, ReadError> {
    let check = |meta: &std::fs::Metadata| -> Result<u64, ReadError> {
        if !meta.is_file() {
            return Err(ReadError::NotRegular(file_kind(meta.file_type())));
        }
        if meta.len() > max_bytes {
            return Err(ReadError::TooLarge(meta.len()));
        }
        Ok(meta.len())
    };
    check(&std::fs::metadata(path).map_err(ReadError::Io)?)?;
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt as _;
        options.custom_flags(libc::O_NONBLOCK);
    }
    let file = options.open(path).map_err(ReadError::Io)?;
    let len = check(&file.metadata().map_err(ReadError::Io)?)?;
    let limit = want.map_or(max_bytes.saturating_add(1), |w| w.min(max_bytes.saturating_add(1)));
    let mut data = Vec::with_capacity(len.min(limit) as usize);
    file.take(limit).read_to_end(&mut data).map_err(ReadError::Io)?;
    if data.len() as u64 > max_bytes {
        return Err(ReadError::TooLarge(data.len() as u64));
    }
    Ok(data)
}

/// Load glTF from memory. `base_dir` is the folder relative buffer URIs are resolved in (`None`:
/// only `data:` URIs and the GLB binary chunk are available); `file_label` names the file in
/// errors and gives the scene its name (file stem).
pub fn load_slice(
    bytes: &[u8],
    base_dir: Option<&Path>,
    file_label: &Path,
    opts: &LoadOptions,
) -> Result<Scene, SceneError> {
    Loader {
        file: file_label.to_path_buf(),
        base_dir,
        opts,
        warnings: Vec::new(),
        shortened_names: 0,
        textures: HashMap::new(),
    }
    .run(bytes)
}

struct Loader<'a> {
    file: PathBuf,
    base_dir: Option<&'a Path>,
    opts: &'a LoadOptions,
    warnings: Vec<String>,
    /// How many names [`Loader::short_name`] shortened (one warning for all).
    shortened_names: usize,
    /// Decoded base-colour textures by image index (`None`: unavailable, warned once).
    textures: HashMap<usize, Option<Rc<Texture>>>,
}

/// What an instance of a mesh adds, found once per mesh.
struct MeshInfo {
    name: String,
    /// Triangles over its triangle primitives (from the accessors' counts, before reading them).
    triangles: usize,
    /// The primitives with at least one triangle: (primitive index, material index).
    primitives: Vec<(usize, Option<usize>)>,
    skipped_modes: usize,
    missing_positions: usize,
}

/// One primitive's geometry, decoded once however many nodes instance its mesh.
struct PrimGeometry {
    /// The vertices the triangles use, in order of first use (the mesh's own frame).
    vertices: Vec<DVec3>,
    /// Canonical id of each vertex: equal positions share one, so unindexed duplicates still
    /// share edges.
    ids: Vec<u32>,
    /// Every triangle in index order (degenerate ones too: their number names the others).
    triangles: Vec<[u32; 3]>,
    /// The base-colour texture's mean over each triangle (linear), if the material has one.
    texture_means: Option<Vec<Rgb>>,
}

/// One mesh instance found while walking the node graph.
struct Instance {
    mesh: usize,
    world: DMat4,
}

/// A material as the solver sees it.
#[derive(Clone)]
struct Mat {
    name: String,
    rho: Rgb,
    emission: Rgb,
    double_sided: bool,
    texture: Option<TextureRef>,
}

/// An image's encoded bytes and where they came from (for errors).
type ImageBytes<'b> = (Cow<'b, [u8]>, String);

/// A material's base-colour texture: which image, which `TEXCOORD_n`, how uv wraps.
#[derive(Clone, Copy)]
struct TextureRef {
    image: usize,
    tex_coord: u32,
    wrap: [Wrap; 2],
}

impl Loader<'_> {
    fn invalid(&self, cause: impl Into<String>) -> SceneError {
        SceneError::InvalidGltf { file: self.file.clone(), cause: cause.into() }
    }

    fn run(mut self, bytes: &[u8]) -> Result<Scene, SceneError> {
        let (json, blob) = if bytes.starts_with(b"glTF") { self.split_glb(bytes)? } else { (bytes, None) };
        let document = self.parse(json)?;
        let doc = &document;
        self.extension_warnings(doc.as_json());

        for image in doc.images() {
            // `parse` checked that every image has exactly one source (the crate panics otherwise).
            if let gltf::image::Source::Uri { uri, .. } = image.source()
                && let Some(rel) = self.check_uri(uri)?
            {
                self.check_image_file(image.index(), &rel, uri)?;
            }
        }

        // Walk the graph first: instances, camera, and the triangle count before reading geometry.
        let (instances, camera_node) = self.walk(doc)?;
        let meshes: Vec<MeshInfo> = doc.meshes().map(|m| self.mesh_info(&m)).collect();
        let mut triangles: usize = 0;
        for inst in &instances {
            let mesh = meshes.get(inst.mesh).ok_or_else(|| self.invalid("mesh index out of range"))?;
            triangles = triangles.saturating_add(mesh.triangles);
            if triangles > self.opts.max_triangles {
                return Err(SceneError::TooLarge { file: self.file.clone(), cap: self.opts.max_triangles });
            }
        }

        let buffers = self.read_buffers(doc, blob)?;
        let materials = self.materials(doc)?;
        self.check_texture_budget(doc, &instances, &meshes, &materials, &buffers)?;
        let default_mat = Mat {
            name: "default".into(),
            rho: Rgb::splat(0.5),
            emission: Rgb::ZERO,
            double_sided: false,
            texture: None,
        };

        // Each primitive is decoded once, however many nodes instance its mesh: the work per
        // instance is then linear in the triangles it adds (which the cap above bounds).
        let mut geometry: HashMap<(usize, usize), PrimGeometry> = HashMap::new();
        let mut patches = Vec::new();
        let (mut skipped_modes, mut missing_positions, mut dropped) = (0usize, 0usize, 0usize);
        for inst in &instances {
            let mesh = &meshes[inst.mesh];
            skipped_modes += mesh.skipped_modes;
            missing_positions += mesh.missing_positions;
            for &(primitive, material) in &mesh.primitives {
                let mat = material.map_or(&default_mat, |i| &materials[i]);
                let geom = match geometry.entry((inst.mesh, primitive)) {
                    std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
                    std::collections::hash_map::Entry::Vacant(e) => {
                        let g =
                            self.decode_primitive(doc, inst.mesh, primitive, &mesh.name, mat, &buffers)?;
                        e.insert(g)
                    }
                };
                let (prim_patches, d) = self.primitive_patches(geom, inst, mat, &mesh.name, primitive)?;
                dropped += d;
                patches.extend(prim_patches);
            }
        }
        if skipped_modes > 0 {
            self.warnings.push(format!(
                "{skipped_modes} primitive(s) with a non-triangle mode (points, lines, strips, fans) skipped"
            ));
        }
        if missing_positions > 0 {
            self.warnings.push(format!("{missing_positions} primitive(s) without POSITION skipped"));
        }
        if dropped > 0 {
            self.warnings.push(format!("{dropped} zero-area triangle(s) dropped"));
        }
        if self.shortened_names > 0 {
            self.warnings.push(format!(
                "{} mesh or material name(s) longer than {MAX_NAME_BYTES} bytes shortened",
                self.shortened_names
            ));
        }
        if patches.is_empty() {
            return Err(SceneError::Empty { file: self.file.clone() });
        }

        let name = self.file.file_stem().map_or_else(|| "scene".into(), |s| s.to_string_lossy().into_owned());
        let mut scene = Scene::new(name, self.file.display().to_string(), patches);
        super::decal::cut_under_decals(&mut scene);
        if let Some((node, world)) = camera_node {
            scene.camera = self.viewpoint(doc, node, world, &scene);
        }
        let mut warnings = self.warnings;
        warnings.append(&mut scene.warnings);
        scene.warnings = warnings;
        Ok(scene)
    }

    /// One line naming the extensions the file uses that are not read (their data is ignored;
    /// an unsupported one in `extensionsRequired` was refused by `parse`), and one for the
    /// punctual lights skipped: radlab's light comes from emissive surfaces, and a point has no
    /// area to emit from.
    fn extension_warnings(&mut self, root: &gltf::json::Root) {
        let mut ignored: Vec<&str> = root
            .extensions_used
            .iter()
            .map(String::as_str)
            .filter(|e| !READ_EXTENSIONS.contains(e) && *e != "KHR_lights_punctual")
            .collect();
        ignored.sort_unstable();
        ignored.dedup();
        if !ignored.is_empty() {
            let shown: Vec<String> = ignored.iter().take(8).map(|e| self.short_name(e)).collect();
            let more =
                if ignored.len() > 8 { format!(" and {} more", ignored.len() - 8) } else { String::new() };
            self.warnings.push(format!("extensions not supported (ignored): {}{more}", shown.join(", ")));
        }
        let lights = root
            .nodes
            .iter()
            .filter(|n| n.extensions.as_ref().is_some_and(|e| e.khr_lights_punctual.is_some()))
            .count();
        if lights > 0 {
            self.warnings.push(format!(
                "KHR_lights_punctual: {lights} light(s) skipped (radlab is lit by emissive surfaces only; model the lamp as an emissive mesh)"
            ));
        }
    }

    /// `name`, cut to at most [`MAX_NAME_BYTES`] (at a character boundary, marked with "…").
    fn short_name(&mut self, name: &str) -> String {
        if name.len() <= MAX_NAME_BYTES {
            return name.to_string();
        }
        self.shortened_names += 1;
        let cut = (0..=MAX_NAME_BYTES).rev().find(|&i| name.is_char_boundary(i)).unwrap_or(0);
        format!("{}…", &name[..cut])
    }

    /// A mesh's name (shortened) and the primitives an instance of it makes triangles from.
    fn mesh_info(&mut self, mesh: &gltf::Mesh) -> MeshInfo {
        let name = match mesh.name() {
            Some(n) => self.short_name(n),
            None => format!("mesh{}", mesh.index()),
        };
        let mut info =
            MeshInfo { name, triangles: 0, primitives: Vec::new(), skipped_modes: 0, missing_positions: 0 };
        for prim in mesh.primitives() {
            if prim.mode() != gltf::mesh::Mode::Triangles {
                info.skipped_modes += 1;
                continue;
            }
            let Some(positions) = prim.get(&gltf::Semantic::Positions) else {
                info.missing_positions += 1;
                continue;
            };
            let n = prim.indices().map_or(positions.count(), |ix| ix.count()) / 3;
            if n > 0 {
                info.triangles = info.triangles.saturating_add(n);
                info.primitives.push((prim.index(), prim.material().index()));
            }
        }
        info
    }

    /// Read one primitive's positions and indices and keep the vertices its triangles use.
    fn decode_primitive(
        &mut self,
        doc: &gltf::Document,
        mesh_index: usize,
        primitive: usize,
        mesh_name: &str,
        mat: &Mat,
        buffers: &[Cow<[u8]>],
    ) -> Result<PrimGeometry, SceneError> {
        let prim = doc
            .meshes()
            .nth(mesh_index)
            .and_then(|m| m.primitives().nth(primitive))
            .ok_or_else(|| self.invalid("primitive index out of range"))?;
        let pos_acc =
            prim.get(&gltf::Semantic::Positions).ok_or_else(|| self.invalid("primitive without POSITION"))?;
        let positions = self.read_positions(&pos_acc, buffers, mesh_name, primitive)?;
        let indices = match prim.indices() {
            Some(acc) => {
                if acc.count() % 3 != 0 {
                    self.warnings.push(format!(
                        "mesh {mesh_name:?} primitive {primitive}: index count is not a multiple of 3 (the rest is ignored)"
                    ));
                }
                self.read_indices(&acc, buffers, positions.len())?
            }
            None => (0..positions.len() as u32).collect(),
        };
        // Compact: only the vertices the triangles use, numbered in order of first use, so an
        // instance transforms at most 3 vertices per triangle whatever the accessor's size.
        let mut compact = vec![u32::MAX; positions.len()];
        let mut vertices = Vec::new();
        let mut ids = Vec::new();
        let mut canon: HashMap<[u32; 3], u32> = HashMap::new();
        let mut triangles = Vec::with_capacity(indices.len() / 3);
        for tri in indices.chunks_exact(3) {
            triangles.push([tri[0], tri[1], tri[2]].map(|i| {
                let slot = &mut compact[i as usize];
                if *slot == u32::MAX {
                    *slot = vertices.len() as u32;
                    let p = positions[i as usize];
                    vertices.push(DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])));
                    // Canonical ids by exact position, so unindexed duplicates still share edges.
                    let next = canon.len() as u32;
                    ids.push(*canon.entry(p.map(f32::to_bits)).or_insert(next));
                }
                *slot
            }));
        }
        let texture_means = match mat.texture {
            Some(tex) => {
                self.texture_means(doc, &prim, tex, &mat.name, &indices, positions.len(), buffers)?
            }
            None => None,
        };
        Ok(PrimGeometry { vertices, ids, triangles, texture_means })
    }

    /// Parse and validate the JSON. Every index must be in range (the `gltf` crate's iterators
    /// rely on it); the accessor `min`/`max` the spec requires for POSITION are not needed here
    /// and many exporters omit them, so their absence is tolerated.
    fn parse(&self, json: &[u8]) -> Result<gltf::Document, SceneError> {
        use gltf::json::validation::{Error as VError, Validate};
        let root: gltf::json::Root =
            gltf::json::deserialize::from_slice(json).map_err(|e| self.invalid(e.to_string()))?;
        // gltf-json's own validation indexes `accessors[POSITION]` unchecked (it panics on a
        // dangling index), so attribute indices are checked first.
        for (m, mesh) in root.meshes.iter().enumerate() {
            for (p, prim) in mesh.primitives.iter().enumerate() {
                if let Some(bad) = prim.attributes.values().find(|i| i.value() >= root.accessors.len()) {
                    return Err(self.invalid(format!(
                        "meshes[{m}].primitives[{p}].attributes: accessor {} does not exist",
                        bad.value()
                    )));
                }
            }
        }
        let mut errors = Vec::new();
        root.validate(&root, gltf::json::Path::new, &mut |path, error| {
            let path = path();
            let min_max = path.as_str().ends_with(".min") || path.as_str().ends_with(".max");
            if !(min_max && error == VError::Missing) {
                errors.push(format!("{path}: {error}"));
            }
        });
        if let Some(first) = errors.first() {
            let more =
                if errors.len() > 1 { format!(" (and {} more)", errors.len() - 1) } else { String::new() };
            return Err(self.invalid(format!("{first}{more}")));
        }
        self.check_structure(&root)?;
        Ok(gltf::Document::from_json_without_validation(root))
    }

    /// What the spec requires, gltf-json does not validate, and the `gltf` crate (or a linear
    /// walk of the scene) relies on:
    /// - an image has a `uri` or a `bufferView`, not both, and a `bufferView` image has a
    ///   `mimeType` [glTF 2.0, sec. 5.18] (`Image::source` unwraps them);
    /// - a camera has the projection its `type` names (`Camera::projection` unwraps it);
    /// - the nodes form disjoint trees [glTF 2.0, sec. 3.5.3]: no node has two parents, a
    ///   scene's root nodes have none and are listed once. A node reused as a child of several
    ///   nodes (or listed many times) would describe exponentially many instances from a few
    ///   bytes; as trees, the walk visits each node at most once.
    fn check_structure(&self, root: &gltf::json::Root) -> Result<(), SceneError> {
        for (i, image) in root.images.iter().enumerate() {
            match (&image.uri, &image.buffer_view, &image.mime_type) {
                (Some(_), None, _) | (None, Some(_), Some(_)) => {}
                (None, None, _) => {
                    return Err(self.invalid(format!("image {i} has neither uri nor bufferView")));
                }
                (Some(_), Some(_), _) => {
                    return Err(self.invalid(format!("image {i} has both uri and bufferView")));
                }
                (None, Some(_), None) => {
                    return Err(self.invalid(format!("image {i} has a bufferView but no mimeType")));
                }
            }
        }
        for (i, camera) in root.cameras.iter().enumerate() {
            use gltf::json::camera::Type;
            use gltf::json::validation::Checked;
            let ok = match camera.type_ {
                Checked::Valid(Type::Perspective) => camera.perspective.is_some(),
                Checked::Valid(Type::Orthographic) => camera.orthographic.is_some(),
                Checked::Invalid => false,
            };
            if !ok {
                return Err(self.invalid(format!("camera {i} lacks the projection its type names")));
            }
        }
        let mut parent: Vec<Option<usize>> = vec![None; root.nodes.len()];
        for (i, node) in root.nodes.iter().enumerate() {
            for c in node.children.iter().flatten() {
                let slot = parent
                    .get_mut(c.value())
                    .ok_or_else(|| self.invalid(format!("node {i}: child {} does not exist", c.value())))?;
                if let Some(p) = slot.replace(i) {
                    return Err(self.invalid(format!(
                        "node {} has two parents ({p} and {i}); glTF nodes form disjoint trees",
                        c.value()
                    )));
                }
            }
        }
        for (s, scene) in root.scenes.iter().enumerate() {
            let mut listed = vec![false; root.nodes.len()];
            for n in &scene.nodes {
                let i = n.value();
                let seen = listed
                    .get_mut(i)
                    .ok_or_else(|| self.invalid(format!("scene {s}: node {i} does not exist")))?;
                if std::mem::replace(seen, true) {
                    return Err(self.invalid(format!("scene {s} lists node {i} twice")));
                }
                if let Some(p) = parent[i] {
                    return Err(self.invalid(format!("scene {s}: root node {i} has a parent ({p})")));
                }
            }
        }
        Ok(())
    }

    /// Split a GLB container into its JSON chunk and optional BIN chunk [glTF 2.0, sec. 4.4].
    fn split_glb<'b>(&self, bytes: &'b [u8]) -> Result<(&'b [u8], Option<&'b [u8]>), SceneError> {
        fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
            bytes.get(at..at.checked_add(4)?).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        }
        let truncated = |what: &str| self.invalid(format!("truncated GLB: {what}"));
        let version = u32_at(bytes, 4).ok_or_else(|| truncated("header"))?;
        if version != 2 {
            return Err(self.invalid(format!("GLB version {version} (only 2 is supported)")));
        }
        let total = u32_at(bytes, 8).ok_or_else(|| truncated("header"))? as usize;
        if total > bytes.len() {
            return Err(truncated(&format!("header says {total} bytes, file has {}", bytes.len())));
        }
        if total < 12 {
            return Err(self.invalid(format!("GLB header says {total} bytes, less than the header itself")));
        }
        let bytes = &bytes[..total];
        let chunk = |at: usize| -> Result<Option<(&'b [u8], u32)>, SceneError> {
            if at >= bytes.len() {
                return Ok(None);
            }
            let len = u32_at(bytes, at).ok_or_else(|| truncated("chunk header"))? as usize;
            let ty = u32_at(bytes, at + 4).ok_or_else(|| truncated("chunk header"))?;
            let data = at
                .checked_add(8)
                .and_then(|s| s.checked_add(len).map(|e| (s, e)))
                .and_then(|(s, e)| bytes.get(s..e))
                .ok_or_else(|| truncated(&format!("chunk at byte {at} claims {len} bytes")))?;
            Ok(Some((data, ty)))
        };
        const JSON: u32 = 0x4E4F_534A;
        const BIN: u32 = 0x004E_4942;
        let (json, ty) = chunk(12)?.ok_or_else(|| truncated("no JSON chunk"))?;
        if ty != JSON {
            return Err(self.invalid("GLB's first chunk is not JSON"));
        }
        let next = 12 + 8 + json.len().next_multiple_of(4);
        let bin = match chunk(next)? {
            Some((data, BIN)) => Some(data),
            _ => None,
        };
        Ok((json, bin))
    }

    /// Resolve a URI to a file inside the scene's folder, or reject it.
    fn check_uri(&self, uri: &str) -> Result<Option<PathBuf>, SceneError> {
        let reject = || SceneError::UriOutsideScene { file: self.file.clone(), uri: uri.to_string() };
        if uri.starts_with("data:") {
            return Ok(None);
        }
        let decoded = percent_decode(uri).ok_or_else(reject)?;
        // A scheme (`http:`, `file:`, a drive letter `C:`) appears before the first separator.
        let first_sep = decoded.find(['/', '\\']).unwrap_or(decoded.len());
        if decoded[..first_sep].contains(':') || decoded.contains('\0') {
            return Err(reject());
        }
        let rel = Path::new(&decoded);
        let mut depth = 0usize;
        for comp in decoded.split(['/', '\\']) {
            match comp {
                "" if depth == 0 && decoded.starts_with(['/', '\\']) => return Err(reject()),
                "" | "." => {}
                ".." => depth = depth.checked_sub(1).ok_or_else(reject)?,
                _ => depth += 1,
            }
        }
        if rel.is_absolute()
            || rel.components().any(|c| matches!(c, Component::Prefix(_) | Component::RootDir))
        {
            return Err(reject());
        }
        Ok(Some(PathBuf::from(decoded.replace('\\', "/"))))
    }

    /// Read every buffer: data URIs, relative files, or the GLB binary chunk.
    /// Read every buffer: data URIs, relative files, or the GLB binary chunk (borrowed, not
    /// copied: however many buffers name it, it is in memory once). The declared byteLengths are
    /// summed and capped by [`LoadOptions::max_file_bytes`] before any buffer is read.
    fn read_buffers<'b>(
        &self,
        doc: &gltf::Document,
        blob: Option<&'b [u8]>,
    ) -> Result<Vec<Cow<'b, [u8]>>, SceneError> {
        let declared = doc.buffers().fold(0u64, |sum, b| sum.saturating_add(b.length() as u64));
        if declared > self.opts.max_file_bytes {
            return Err(self.invalid(format!(
                "buffers declare {declared} bytes in all, more than the {} byte limit",
                self.opts.max_file_bytes
            )));
        }
        let mut out = Vec::new();
        for buf in doc.buffers() {
            let index = buf.index();
            let err = |cause: String| SceneError::Buffer { file: self.file.clone(), index, cause };
            let want = buf.length();
            let data = match buf.source() {
                gltf::buffer::Source::Bin => {
                    Cow::Borrowed(blob.ok_or_else(|| err("no GLB binary chunk and no uri".into()))?)
                }
                gltf::buffer::Source::Uri(uri) => match self.check_uri(uri)? {
                    None => Cow::Owned(decode_data_uri(uri).map_err(err)?),
                    Some(rel) => Cow::Owned(self.read_relative(&rel, uri, want).map_err(err)?),
                },
            };
            if data.len() < want {
                return Err(err(format!("has {} bytes, byteLength says {want}", data.len())));
            }
            out.push(data);
        }
        Ok(out)
    }

    /// The file a relative URI names, if it stays inside the scene's folder (symbolic links
    /// included).
    fn resolve(&self, rel: &Path, uri: &str) -> Result<PathBuf, String> {
        let base = self.base_dir.ok_or_else(|| format!("{uri:?}: no folder to resolve a relative URI in"))?;
        let path = base.join(rel);
        let canon_base = base.canonicalize().map_err(|e| format!("{}: {e}", base.display()))?;
        let canon = path.canonicalize().map_err(|e| format!("{}: {e}", path.display()))?;
        if !canon.starts_with(&canon_base) {
            return Err(format!("{uri:?} resolves outside the scene's folder"));
        }
        Ok(canon)
    }

    /// Read at most `want` bytes (the buffer's byteLength) of a regular file inside the folder.
    fn read_relative(&self, rel: &Path, uri: &str, want: usize) -> Result<Vec<u8>, String> {
        let canon = self.resolve(rel, uri)?;
        let shown = self.base_dir.map_or_else(|| rel.to_path_buf(), |b| b.join(rel));
        read_regular(&canon, self.opts.max_file_bytes, Some(want as u64)).map_err(|e| match e {
            ReadError::Io(e) => format!("{}: {e}", shown.display()),
            ReadError::NotRegular(kind) => format!("{} is {kind}, not a regular file", shown.display()),
            ReadError::TooLarge(len) => format!(
                "{} has {len} bytes, more than the {} byte limit",
                shown.display(),
                self.opts.max_file_bytes
            ),
        })
    }

    /// Every image file that exists must be a regular file inside the folder, as a buffer must
    /// (used as a texture or not): a FIFO or device is refused here, before anything could open
    /// it. A missing image is a warning (materials using it keep their factor).
    fn check_image_file(&mut self, index: usize, rel: &Path, uri: &str) -> Result<(), SceneError> {
        let Some(base) = self.base_dir else { return Ok(()) };
        let shown = base.join(rel);
        if std::fs::metadata(&shown).is_err_and(|e| e.kind() == std::io::ErrorKind::NotFound) {
            self.warnings
                .push(format!("image {index}: {} not found (its texture is not used)", shown.display()));
            return Ok(());
        }
        let err = |cause: String| SceneError::Image { file: self.file.clone(), index, cause };
        let canon = self.resolve(rel, uri).map_err(err)?;
        let meta = std::fs::metadata(&canon).map_err(|e| err(format!("{}: {e}", shown.display())))?;
        if !meta.is_file() {
            return Err(err(format!(
                "{} is {}, not a regular file",
                shown.display(),
                file_kind(meta.file_type())
            )));
        }
        Ok(())
    }

    /// The base-colour texture's mean over each triangle (`indices` in threes) of a primitive,
    /// or `None` with a warning when the texture or the texture coordinates are unavailable.
    fn texture_means(
        &mut self,
        doc: &gltf::Document,
        prim: &gltf::Primitive,
        tex: TextureRef,
        material: &str,
        indices: &[u32],
        n_vertices: usize,
        buffers: &[Cow<[u8]>],
    ) -> Result<Option<Vec<Rgb>>, SceneError> {
        let Some(acc) = prim.get(&gltf::Semantic::TexCoords(tex.tex_coord)) else {
            self.warnings.push(format!(
                "material {material:?}: a primitive has no TEXCOORD_{} (texture not used, factor used)",
                tex.tex_coord
            ));
            return Ok(None);
        };
        if acc.count() != n_vertices {
            return Err(self.invalid(format!(
                "accessor {}: TEXCOORD_{} has {} elements, POSITION has {n_vertices}",
                acc.index(),
                tex.tex_coord,
                acc.count()
            )));
        }
        let uvs = self.read_uvs(&acc, buffers)?;
        let Some(texture) = self.texture(doc, tex.image, buffers)? else { return Ok(None) };
        Ok(Some(
            indices
                .chunks_exact(3)
                .map(|t| {
                    texture
                        .triangle_mean([uvs[t[0] as usize], uvs[t[1] as usize], uvs[t[2] as usize]], tex.wrap)
                })
                .collect(),
        ))
    }

    /// Texture coordinates: float, or normalized unsigned byte/short VEC2 [glTF 2.0, sec. 3.7.2.1].
    fn read_uvs(&self, acc: &gltf::Accessor, buffers: &[Cow<[u8]>]) -> Result<Vec<[f64; 2]>, SceneError> {
        let size = match acc.data_type() {
            DataType::F32 => 4,
            DataType::U8 if acc.normalized() => 1,
            DataType::U16 if acc.normalized() => 2,
            _ => 0,
        };
        if size == 0 || acc.dimensions() != Dimensions::Vec2 {
            return Err(self.invalid(format!(
                "accessor {}: TEXCOORD must be float or normalized unsigned byte/short VEC2",
                acc.index()
            )));
        }
        let (bytes, stride) = self.accessor_bytes(acc, buffers, 2 * size)?;
        let comp = |e: &[u8], k: usize| -> f64 {
            match size {
                4 => f64::from(f32::from_le_bytes([e[4 * k], e[4 * k + 1], e[4 * k + 2], e[4 * k + 3]])),
                2 => f64::from(u16::from_le_bytes([e[2 * k], e[2 * k + 1]])) / 65535.0,
                _ => f64::from(e[k]) / 255.0,
            }
        };
        Ok((0..acc.count())
            .map(|i| {
                let e = &bytes[i * stride..i * stride + 2 * size];
                [comp(e, 0), comp(e, 1)]
            })
            .collect())
    }

    /// Refuse a file whose base-colour textures would decode to more than `TEXTURE_BUDGET` ×
    /// [`LoadOptions::max_texture_pixels`] pixels in all, from their headers, before any is
    /// decoded. Only the images of materials that instanced primitives use are counted; an
    /// image whose header is unreadable or over the per-image cap is left to [`Loader::texture`],
    /// which refuses it with its own cause when it is used.
    fn check_texture_budget(
        &mut self,
        doc: &gltf::Document,
        instances: &[Instance],
        meshes: &[MeshInfo],
        materials: &[Mat],
        buffers: &[Cow<[u8]>],
    ) -> Result<(), SceneError> {
        let images: BTreeSet<usize> = instances
            .iter()
            .filter_map(|inst| meshes.get(inst.mesh))
            .flat_map(|mesh| &mesh.primitives)
            .filter_map(|&(_, material)| materials.get(material?)?.texture)
            .map(|t| t.image)
            .collect();
        let budget = self.opts.max_texture_pixels.saturating_mul(TEXTURE_BUDGET);
        let warnings = self.warnings.len();
        let mut pixels: u64 = 0;
        for image in images {
            let Some((bytes, label)) = self.image_bytes(doc, image, buffers)? else { continue };
            let Ok((w, h)) = Texture::header(&bytes, self.opts.max_texture_pixels) else { continue };
            pixels = pixels.saturating_add(u64::from(w) * u64::from(h));
            if pixels > budget {
                return Err(SceneError::Image {
                    file: self.file.clone(),
                    index: image,
                    cause: format!(
                        "{label}: {w}×{h} takes the textures' headers to {pixels} pixels in all, \
                         more than the limit of {budget} ({TEXTURE_BUDGET} × {}) (nothing decoded)",
                        self.opts.max_texture_pixels
                    ),
                });
            }
        }
        // `texture` warns about an image it cannot read when a primitive uses it.
        self.warnings.truncate(warnings);
        Ok(())
    }

    /// An image decoded as a texture, once per image; `None` (warned) if it cannot be read
    /// here: a missing file, or a relative URI with no folder to resolve it in.
    fn texture(
        &mut self,
        doc: &gltf::Document,
        image: usize,
        buffers: &[Cow<[u8]>],
    ) -> Result<Option<Rc<Texture>>, SceneError> {
        if let Some(t) = self.textures.get(&image) {
            return Ok(t.clone());
        }
        let decoded = match self.image_bytes(doc, image, buffers)? {
            None => None,
            Some((bytes, label)) => {
                let t = Texture::decode(&bytes, self.opts.max_texture_pixels).map_err(|cause| {
                    SceneError::Image {
                        file: self.file.clone(),
                        index: image,
                        cause: format!("{label}: {cause}"),
                    }
                })?;
                Some(Rc::new(t))
            }
        };
        self.textures.insert(image, decoded.clone());
        Ok(decoded)
    }

    /// An image's encoded bytes and a label naming where they came from (its file, a data
    /// URI, a buffer view).
    fn image_bytes<'b>(
        &mut self,
        doc: &gltf::Document,
        image: usize,
        buffers: &'b [Cow<[u8]>],
    ) -> Result<Option<ImageBytes<'b>>, SceneError> {
        let err = |cause: String| SceneError::Image { file: self.file.clone(), index: image, cause };
        let img = doc.images().nth(image).ok_or_else(|| err("does not exist".into()))?;
        // `parse` checked that every image has exactly one source (the crate panics otherwise).
        match img.source() {
            gltf::image::Source::Uri { uri, .. } => match self.check_uri(uri)? {
                None => Ok(Some((Cow::Owned(decode_data_uri(uri).map_err(err)?), "data: URI".into()))),
                Some(rel) => {
                    let Some(base) = self.base_dir else {
                        self.warnings.push(format!(
                            "image {image}: {uri:?} not read (no folder to resolve it in; its texture is not used)"
                        ));
                        return Ok(None);
                    };
                    let shown = base.join(&rel);
                    if std::fs::metadata(&shown).is_err_and(|e| e.kind() == std::io::ErrorKind::NotFound) {
                        return Ok(None); // warned by `check_image_file`
                    }
                    let bytes = self.read_relative(&rel, uri, usize::MAX).map_err(err)?;
                    Ok(Some((Cow::Owned(bytes), shown.display().to_string())))
                }
            },
            gltf::image::Source::View { view, .. } => {
                let buf = buffers.get(view.buffer().index()).ok_or_else(|| err("bad buffer".into()))?;
                let range = view
                    .offset()
                    .checked_add(view.length())
                    .filter(|&end| end <= buf.len())
                    .map(|end| view.offset()..end)
                    .ok_or_else(|| err(format!("bufferView {} runs past its buffer", view.index())))?;
                Ok(Some((Cow::Borrowed(&buf[range]), format!("bufferView {}", view.index()))))
            }
        }
    }

    fn materials(&mut self, doc: &gltf::Document) -> Result<Vec<Mat>, SceneError> {
        let mut out = Vec::new();
        for m in doc.materials() {
            let index = m.index().unwrap_or(0);
            let name = match m.name() {
                Some(n) => self.short_name(n),
                None => format!("material{index}"),
            };
            let pbr = m.pbr_metallic_roughness();
            let base = pbr.base_color_factor();
            let mut rho = Rgb::new(f64::from(base[0]), f64::from(base[1]), f64::from(base[2]));
            for c in rho.0 {
                if !(0.0..=1.0).contains(&c) {
                    return Err(SceneError::ReflectanceOutOfRange {
                        file: self.file.clone(),
                        material: name,
                        value: c,
                    });
                }
            }
            let json = m.index().and_then(|i| doc.as_json().materials.get(i));
            let texture = json
                .and_then(|j| j.pbr_metallic_roughness.base_color_texture.as_ref())
                .and_then(|info| texture_ref(doc.as_json(), info.index.value(), info.tex_coord));
            // With a texture the factor is a multiplier (1 is the usual value): the product is
            // clamped per patch instead (`primitive_patches`).
            if texture.is_none() && rho.max_channel() > RHO_MAX {
                self.warnings.push(format!(
                    "material {name:?}: reflectance {:?} clamped to {RHO_MAX} (ρ = 1 absorbs nothing: the system would be singular)",
                    rho.0
                ));
                rho = rho.map(|c| c.min(RHO_MAX));
            }
            if json.is_some_and(|j| j.emissive_texture.is_some()) {
                self.warnings.push(format!("material {name:?}: emissive texture ignored (factor used)"));
            }
            let strength = f64::from(m.emissive_strength().unwrap_or(1.0));
            let ef = m.emissive_factor();
            let emission = Rgb::new(f64::from(ef[0]), f64::from(ef[1]), f64::from(ef[2])) * strength;
            for c in emission.0 {
                if !(c >= 0.0 && c.is_finite()) {
                    return Err(SceneError::BadEmission {
                        file: self.file.clone(),
                        material: name,
                        value: c,
                    });
                }
            }
            out.push(Mat { name, rho, emission, double_sided: m.double_sided(), texture });
        }
        Ok(out)
    }

    /// Depth-first walk of the default scene (or, without scenes, of every root node), in document
    /// order. Returns the mesh instances and the first perspective camera node.
    #[allow(clippy::type_complexity)]
    fn walk(&self, doc: &gltf::Document) -> Result<(Vec<Instance>, Option<(usize, DMat4)>), SceneError> {
        let roots: Vec<usize> = if let Some(s) = doc.default_scene().or_else(|| doc.scenes().next()) {
            s.nodes().map(|n| n.index()).collect()
        } else {
            let mut is_child = vec![false; doc.nodes().len()];
            for n in doc.nodes() {
                for c in n.children() {
                    is_child[c.index()] = true;
                }
            }
            (0..is_child.len()).filter(|&i| !is_child[i]).collect()
        };
        let nodes: Vec<gltf::Node> = doc.nodes().collect();
        let mut instances = Vec::new();
        let mut camera = None;
        // `check_structure` made the nodes disjoint trees, so no node is reached twice; the
        // check stays as the walk's own guarantee of linear work.
        let mut visited = vec![false; nodes.len()];
        // Explicit stack: (node, parent world matrix) so deep trees cannot overflow.
        let mut stack: Vec<(usize, DMat4)> = roots.iter().rev().map(|&r| (r, DMat4::IDENTITY)).collect();
        while let Some((i, parent)) = stack.pop() {
            let node = nodes.get(i).ok_or_else(|| self.invalid(format!("node {i} does not exist")))?;
            if std::mem::replace(&mut visited[i], true) {
                return Err(self.invalid(format!("node {i} is reached twice (the nodes are not trees)")));
            }
            let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)));
            if !local.is_finite() {
                return Err(self.invalid(format!("node {i}: non-finite transform")));
            }
            let world = parent * local;
            if let Some(m) = node.mesh() {
                instances.push(Instance { mesh: m.index(), world });
            }
            if camera.is_none() && node.camera().is_some() {
                camera = Some((i, world));
            }
            let children: Vec<usize> = node.children().map(|c| c.index()).collect();
            for &c in children.iter().rev() {
                stack.push((c, world));
            }
        }
        Ok((instances, camera))
    }

    /// Check an accessor's range against its view and buffer; return (bytes, offset, stride).
    fn accessor_bytes<'b>(
        &self,
        acc: &gltf::Accessor,
        buffers: &'b [Cow<'_, [u8]>],
        elem: usize,
    ) -> Result<(&'b [u8], usize), SceneError> {
        let ai = acc.index();
        if acc.sparse().is_some() {
            return Err(self.invalid(format!("accessor {ai}: sparse accessors are not supported")));
        }
        let view = acc.view().ok_or_else(|| self.invalid(format!("accessor {ai} has no bufferView")))?;
        let buf = buffers
            .get(view.buffer().index())
            .ok_or_else(|| self.invalid(format!("accessor {ai}: bad buffer")))?;
        let declared = view.buffer().length();
        let view_end = view.offset().checked_add(view.length());
        let Some(view_end) = view_end.filter(|&e| e <= declared && e <= buf.len()) else {
            return Err(SceneError::Buffer {
                file: self.file.clone(),
                index: view.buffer().index(),
                cause: format!(
                    "bufferView {} (offset {}, length {}) runs past the buffer's {} bytes",
                    view.index(),
                    view.offset(),
                    view.length(),
                    buf.len().min(declared)
                ),
            });
        };
        let view_bytes = &buf[view.offset()..view_end];
        let stride = view.stride().unwrap_or(elem);
        if stride < elem {
            return Err(
                self.invalid(format!("bufferView {}: stride {stride} < element size {elem}", view.index()))
            );
        }
        let count = acc.count();
        let end = count
            .checked_sub(1)
            .and_then(|n| n.checked_mul(stride))
            .and_then(|x| x.checked_add(acc.offset()))
            .and_then(|x| x.checked_add(elem));
        match end {
            Some(end) if end <= view_bytes.len() => Ok((&view_bytes[acc.offset()..end], stride)),
            _ if count == 0 => Ok((&view_bytes[..0], stride)),
            _ => Err(SceneError::Buffer {
                file: self.file.clone(),
                index: view.buffer().index(),
                cause: format!(
                    "accessor {ai} ({count} elements, stride {stride}, offset {}) runs past bufferView {}'s {} bytes",
                    acc.offset(),
                    view.index(),
                    view_bytes.len()
                ),
            }),
        }
    }

    fn read_positions(
        &self,
        acc: &gltf::Accessor,
        buffers: &[Cow<[u8]>],
        mesh: &str,
        primitive: usize,
    ) -> Result<Vec<[f32; 3]>, SceneError> {
        if acc.data_type() != DataType::F32 || acc.dimensions() != Dimensions::Vec3 {
            return Err(self.invalid(format!("accessor {}: POSITION must be float VEC3", acc.index())));
        }
        let (bytes, stride) = self.accessor_bytes(acc, buffers, 12)?;
        let f = |b: &[u8], k: usize| f32::from_le_bytes([b[4 * k], b[4 * k + 1], b[4 * k + 2], b[4 * k + 3]]);
        let mut out = Vec::with_capacity(acc.count());
        for i in 0..acc.count() {
            let e = &bytes[i * stride..i * stride + 12];
            let p = [f(e, 0), f(e, 1), f(e, 2)];
            if !p.iter().all(|c| c.is_finite()) {
                return Err(SceneError::NonFinitePosition {
                    file: self.file.clone(),
                    mesh: mesh.into(),
                    primitive,
                });
            }
            out.push(p);
        }
        Ok(out)
    }

    fn read_indices(
        &self,
        acc: &gltf::Accessor,
        buffers: &[Cow<[u8]>],
        n_vertices: usize,
    ) -> Result<Vec<u32>, SceneError> {
        let size = match acc.data_type() {
            DataType::U8 => 1,
            DataType::U16 => 2,
            DataType::U32 => 4,
            t => return Err(self.invalid(format!("accessor {}: index type {t:?}", acc.index()))),
        };
        if acc.dimensions() != Dimensions::Scalar {
            return Err(self.invalid(format!("accessor {}: indices must be SCALAR", acc.index())));
        }
        let (bytes, stride) = self.accessor_bytes(acc, buffers, size)?;
        let mut out = Vec::with_capacity(acc.count());
        for i in 0..acc.count() {
            let e = &bytes[i * stride..i * stride + size];
            let v = match size {
                1 => u32::from(e[0]),
                2 => u32::from(u16::from_le_bytes([e[0], e[1]])),
                _ => u32::from_le_bytes([e[0], e[1], e[2], e[3]]),
            };
            if v as usize >= n_vertices {
                return Err(
                    self.invalid(format!("accessor {}: index {v} ≥ vertex count {n_vertices}", acc.index()))
                );
            }
            out.push(v);
        }
        Ok(out)
    }

    /// Triangles of one primitive instance → patches (merged quads, double-sided copies).
    /// Returns the patches and the number of zero-area triangles dropped.
    fn primitive_patches(
        &self,
        geom: &PrimGeometry,
        inst: &Instance,
        mat: &Mat,
        mesh: &str,
        primitive: usize,
    ) -> Result<(Vec<Patch>, usize), SceneError> {
        let flip = DMat3::from_mat4(inst.world).determinant() < 0.0;
        let ids = &geom.ids;
        let world: Vec<DVec3> = geom.vertices.iter().map(|&p| inst.world.transform_point3(p)).collect();
        if world.iter().any(|v| !v.is_finite()) {
            return Err(SceneError::NonFinitePosition {
                file: self.file.clone(),
                mesh: mesh.into(),
                primitive,
            });
        }

        // Valid triangles: (index-order number, vertex indices in front-facing order).
        let mut tris: Vec<(usize, [u32; 3])> = Vec::new();
        let mut dropped = 0;
        for (t, c) in geom.triangles.iter().enumerate() {
            let v = if flip { [c[0], c[2], c[1]] } else { [c[0], c[1], c[2]] };
            let [a, b, cc] = v.map(|i| world[i as usize]);
            let longest =
                (b - a).length_squared().max((cc - b).length_squared()).max((a - cc).length_squared());
            let area2 = (b - a).cross(cc - a).length();
            let has_area = area2 > DEGENERATE_REL_AREA * longest; // false for NaN too
            if !has_area {
                dropped += 1;
                continue;
            }
            tris.push((t, v));
        }
        // Directed edges (canonical ids) → triangles having them, in order.
        let mut edges: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
        for (k, (_, v)) in tris.iter().enumerate() {
            for e in 0..3 {
                edges.entry((ids[v[e] as usize], ids[v[(e + 1) % 3] as usize])).or_default().push(k);
            }
        }
        let mut used = vec![false; tris.len()];
        let mut out = Vec::new();
        for k in 0..tris.len() {
            if used[k] {
                continue;
            }
            used[k] = true;
            let (t, v) = tris[k];
            let p = v.map(|i| world[i as usize]);
            let mut best: Option<(usize, Vec<DVec3>)> = None;
            for e in 0..3 {
                let key = (ids[v[(e + 1) % 3] as usize], ids[v[e] as usize]);
                // The list is in triangle order: skip to the triangles after k, and look at no
                // more than MAX_EDGE_CANDIDATES of them (an edge that many triangles share is not
                // a surface a quad belongs to; without the bound a fan of n triangles on one edge
                // costs n² merge tests).
                let list = edges.get(&key).map_or(&[][..], Vec::as_slice);
                let later = &list[list.partition_point(|&j| j <= k)..];
                for &j in later.iter().take(MAX_EDGE_CANDIDATES) {
                    if best.as_ref().is_some_and(|(b, _)| *b <= j) {
                        break;
                    }
                    if used[j] {
                        continue;
                    }
                    let w = tris[j].1;
                    let shared = [ids[v[e] as usize], ids[v[(e + 1) % 3] as usize]];
                    let Some(q) = w.iter().find(|&&i| !shared.contains(&ids[i as usize])) else { continue };
                    let q = world[*q as usize];
                    let quad = match e {
                        0 => vec![p[0], q, p[1], p[2]],
                        1 => vec![p[0], p[1], q, p[2]],
                        _ => vec![p[0], p[1], p[2], q],
                    };
                    if mergeable(&quad) {
                        best = Some((j, quad));
                    }
                }
            }
            // ρ = baseColorFactor × the texture's mean over the patch (area-weighted over a
            // merged quad's two triangles).
            let tex_mean = |t: usize| geom.texture_means.as_ref().and_then(|m| m.get(t)).copied();
            let area = |v: &[u32; 3]| {
                let [a, b, c] = v.map(|i| world[i as usize]);
                (b - a).cross(c - a).length()
            };
            let (verts, texel) = match best {
                Some((j, quad)) => {
                    used[j] = true;
                    let (tj, vj) = tris[j];
                    let texel = tex_mean(t).zip(tex_mean(tj)).map(|(ci, cj)| {
                        let (ai, aj) = (area(&v), area(&vj));
                        (ci * ai + cj * aj) / (ai + aj)
                    });
                    (quad, texel)
                }
                None => (p.to_vec(), tex_mean(t)),
            };
            let r = mat.rho.0;
            let rho = texel
                .map_or(mat.rho, |c| Rgb::new(r[0] * c.0[0], r[1] * c.0[1], r[2] * c.0[2]))
                .map(|c| c.min(RHO_MAX));
            let name = format!("{mesh}/{primitive}/{t}");
            let mut push = |verts: Vec<DVec3>, name: String| -> Result<(), SceneError> {
                let index = out.len();
                let patch = Patch::new(verts, rho, mat.emission, mesh, primitive, name, mat.name.clone())
                    .map_err(|cause| SceneError::BadPatch { file: self.file.clone(), index, cause })?;
                out.push(patch);
                Ok(())
            };
            if mat.double_sided {
                let back: Vec<DVec3> = verts.iter().rev().copied().collect();
                push(verts, name.clone())?;
                push(back, format!("{name}/back"))?;
            } else {
                push(verts, name)?;
            }
        }
        Ok((out, dropped))
    }

    /// The camera node's placement: eye = node origin, looking down its −z, up = its +y
    /// [glTF 2.0, sec. 3.10]. glTF has no target; it is put at the distance of the scene's centre.
    fn viewpoint(
        &mut self,
        doc: &gltf::Document,
        node: usize,
        world: DMat4,
        scene: &Scene,
    ) -> Option<Viewpoint> {
        let cam = doc.nodes().nth(node)?.camera()?;
        let gltf::camera::Projection::Perspective(p) = cam.projection() else {
            self.warnings.push("orthographic camera ignored (a default view is used)".into());
            return None;
        };
        let eye = world.transform_point3(DVec3::ZERO);
        let forward = world.transform_vector3(-DVec3::Z).normalize_or_zero();
        let up = world.transform_vector3(DVec3::Y).normalize_or_zero();
        let fov = f64::from(p.yfov()).to_degrees();
        if forward == DVec3::ZERO || up == DVec3::ZERO || !(fov > 0.0 && fov < 180.0) {
            self.warnings.push("degenerate camera ignored (a default view is used)".into());
            return None;
        }
        let b = scene.bounds();
        let dist = (b.center() - eye).length();
        let dist = if dist > 0.0 { dist } else { 0.5 * b.diagonal().max(1.0) };
        Some(Viewpoint { eye, target: eye + forward * dist, up, fov_y_deg: fov })
    }
}

/// Is this quad (from two triangles) planar and strictly convex, as `Scene::validate` requires?
/// (Generated scenes use it to emit as quads exactly the triangle pairs this loader merges.)
pub(crate) fn mergeable(quad: &[DVec3]) -> bool {
    let Ok(p) = Patch::new(quad.to_vec(), Rgb::ZERO, Rgb::ZERO, "", 0, "", "") else { return false };
    let diam = p.diameter();
    if quad.iter().any(|v| (p.normal.dot(*v) - p.plane_d()).abs() > PLANARITY_TOL * diam) {
        return false;
    }
    if !is_convex(quad, p.normal) {
        return false;
    }
    (0..4).all(|i| {
        let (a, b, c) = (quad[i], quad[(i + 1) % 4], quad[(i + 2) % 4]);
        (b - a).cross(c - b).dot(p.normal) > MERGE_CONVEX_REL * diam * diam
    })
}

/// A material's base-colour texture from the JSON (indices were validated by `parse`).
fn texture_ref(root: &gltf::json::Root, texture: usize, tex_coord: u32) -> Option<TextureRef> {
    use gltf::json::validation::Checked;
    let t = root.textures.get(texture)?;
    let wrap = |w: &Checked<gltf::json::texture::WrappingMode>| match w {
        Checked::Valid(w) => Wrap::from_gl(w.as_gl_enum()),
        Checked::Invalid => Wrap::Repeat,
    };
    let sampler = t.sampler.and_then(|s| root.samplers.get(s.value()));
    let wrap = sampler.map_or([Wrap::Repeat; 2], |s| [wrap(&s.wrap_s), wrap(&s.wrap_t)]);
    Some(TextureRef { image: t.source.value(), tex_coord, wrap })
}

/// Decode `%XX` escapes; `None` on a malformed escape or invalid UTF-8.
fn percent_decode(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = std::str::from_utf8(b.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// Decode `data:[<mime>];base64,<payload>`.
fn decode_data_uri(uri: &str) -> Result<Vec<u8>, String> {
    let rest = &uri["data:".len()..];
    let (header, payload) = rest.split_once(',').ok_or("data: URI without a comma")?;
    if !header.ends_with(";base64") {
        return Err("data: URI is not base64".into());
    }
    base64::engine::general_purpose::STANDARD
        .decode(payload.trim())
        .map_err(|e| format!("bad base64 in data: URI: {e}"))
}

// ---------------------------------------------------------------------------------------------
// Writer
// ---------------------------------------------------------------------------------------------

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
    let bad = |cause: String| out_error(scene, &cause);
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
    let mut mat_of: Vec<([u64; 3], [u64; 3])> = Vec::new();

    let mut i = 0;
    while i < scene.patches.len() {
        // A run of patches with one mesh name → one mesh; sub-runs of (primitive, material) → primitives.
        let mesh_name = &scene.patches[i].mesh;
        let mut mesh = OutMesh { name: mesh_name.clone(), primitives: Vec::new() };
        while i < scene.patches.len() && &scene.patches[i].mesh == mesh_name {
            let first = &scene.patches[i];
            let key = (first.reflectance.0.map(f64::to_bits), first.emission.0.map(f64::to_bits));
            let material = match mat_of.iter().position(|k| *k == key) {
                Some(m) => m,
                None => {
                    if !first.reflectance.is_finite() || !first.emission.is_finite() {
                        return Err(bad(format!("patch {i}: non-finite material")));
                    }
                    let e = first.emission;
                    let strength = e.max_channel().max(1.0);
                    let ext = (strength > 1.0).then_some(OutMatExt {
                        strength: OutStrength { emissive_strength: strength as f32 },
                    });
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
                    mat_of.len() - 1
                }
            };
            let mut positions: Vec<[f32; 3]> = Vec::new();
            let mut indices: Vec<u32> = Vec::new();
            let prim = first.primitive;
            while i < scene.patches.len() {
                let p = &scene.patches[i];
                let k = (p.reflectance.0.map(f64::to_bits), p.emission.0.map(f64::to_bits));
                if &p.mesh != mesh_name || p.primitive != prim || k != key {
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
            let mut mn = [f32::INFINITY; 3];
            let mut mx = [f32::NEG_INFINITY; 3];
            for p in &positions {
                for c in 0..3 {
                    mn[c] = mn[c].min(p[c]);
                    mx[c] = mx[c].max(p[c]);
                }
            }
            let pos_view = push_view(
                &mut root,
                &mut bin,
                positions.iter().flatten().flat_map(|f| f.to_le_bytes()),
                GL_ARRAY_BUFFER,
            );
            root.accessors.push(OutAccessor {
                buffer_view: pos_view,
                component_type: GL_FLOAT,
                count: positions.len(),
                kind: "VEC3",
                min: Some(mn),
                max: Some(mx),
            });
            let idx_view = push_view(
                &mut root,
                &mut bin,
                indices.iter().flat_map(|i| i.to_le_bytes()),
                GL_ELEMENT_ARRAY_BUFFER,
            );
            root.accessors.push(OutAccessor {
                buffer_view: idx_view,
                component_type: GL_UNSIGNED_INT,
                count: indices.len(),
                kind: "SCALAR",
                min: None,
                max: None,
            });
            mesh.primitives.push(OutPrimitive {
                attributes: OutAttributes { position: root.accessors.len() - 2 },
                indices: root.accessors.len() - 1,
                material,
                mode: GL_TRIANGLES,
            });
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
        let forward = (cam.target - cam.eye).normalize_or_zero();
        let right = forward.cross(cam.up).normalize_or_zero();
        if right == DVec3::ZERO {
            return Err(bad("camera: up is parallel to the view direction".into()));
        }
        let up = right.cross(forward);
        let rot = DQuat::from_mat3(&DMat3::from_cols(right, up, -forward)).normalize();
        let diag = scene.bounds().diagonal();
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
            perspective: OutPerspective {
                yfov: cam.fov_y_deg.to_radians() as f32,
                znear: (1e-3 * diag) as f32,
            },
        });
    }

    Ok((root, bin))
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
