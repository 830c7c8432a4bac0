//! glTF 2.0 import and export of radiosity scenes.
//!
//! A glTF file [Khronos glTF 2.0 specification, sec. 3.7 (meshes), sec. 3.9 (materials)] becomes
//! a list of planar convex patches:
//!
//! - **Geometry**: every `TRIANGLES` primitive of every mesh instance, with the node's world
//!   transform applied (`M = M_root · … · M_node`, f64); where det(M) < 0 the winding is reversed
//!   to keep each triangle's front side. Two triangles of one primitive that share an edge and
//!   form a planar, strictly convex quadrilateral are merged into one quad patch, so a quadtree
//!   can subdivide imported quads.
//! - **Material**: `baseColorFactor.rgb` → ρ (linear RGB), times the base-colour texture's mean
//!   over the patch ([`super::texture`]); `emissiveFactor × KHR_materials_emissive_strength` → E
//!   (radiant exitance, the unit of B). No material → ρ = 0.5, E = 0. `doubleSided` → two
//!   back-to-back patches. ρ ∈ [[`RHO_MAX`](crate::scene::RHO_MAX), 1] is clamped with a warning
//!   (the SPLASH-2 lamps' ρ = 1 would make an enclosure's system singular); ρ outside [0, 1] or a
//!   negative or non-finite E is an error. `KHR_lights_punctual` is skipped with a warning
//!   (radlab is lit by emissive surfaces); an unread extension in `extensionsRequired` is an error.
//!
//! Patches are numbered (for the CLI and tests) by scene node depth-first in document order, then
//! primitive, then triangle index; a merged quad takes its first triangle's place, its partner is
//! the earliest later triangle that qualifies; zero-area triangles are dropped with a warning.
//!
//! ```text
//!   tri i = (p0 p1 p2), shared edge p2→p0, tri j = (p0 p2 q)      p2 ──── q
//!   quad  = (p0 p1 p2 q)   (starts at p0, keeps i's orientation)   │ i   ╱ │
//!                                                                  │   ╱ j │
//!                                                                  p1 ── p0
//! ```
//!
//! **Untrusted input.** Buffers and images are read by this module, not by the `gltf` crate: only
//! `data:` URIs and relative paths to regular files inside the scene's folder
//! ([`SceneError::UriOutsideScene`]), every range checked with overflow-safe arithmetic and every
//! size against [`LoadOptions`] before a byte is read or a texture decoded; what the `gltf` crate
//! assumes and does not validate (disjoint node trees, one source per image) is checked first;
//! work is linear in the input plus the output. A hostile file can neither panic the loader nor
//! make it allocate without bound (`tests/gltf_loader.rs`, the fuzz target; each case:
//! docs/fuzzing.md).
//!
//! The writer ([`write_gltf`], [`write_glb`]) produces the inverse: one buffer, one mesh per run
//! of patches with the same mesh name, one material per distinct (ρ, E), quads as two triangles
//! `(0 1 2)(0 2 3)` that the loader merges back, and the scene camera as a camera node.
//!
//! ## Files
//! `loader` walks the document (nodes, meshes, materials, camera); `validate` checks the JSON
//! before the `gltf` crate reads it; `io` is the sandboxed input (files, URIs, GLB chunks,
//! buffers); `primitive` turns one primitive's accessors into patches (quads merged);
//! `base_color` averages base-colour textures into ρ; `writer` writes .gltf and .glb.

mod base_color;
mod io;
mod loader;
mod primitive;
mod validate;
mod writer;

pub(crate) use primitive::mergeable;
pub use writer::{glb_bytes, gltf_string, write_glb, write_gltf};

use super::texture::{Texture, Wrap};
use super::{Scene, SceneError};
use crate::math::{DVec3, Rgb};
use glam::DMat4;
use io::{ReadError, read_regular};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
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

/// A material's base-colour texture: which image, which `TEXCOORD_n`, how uv wraps.
#[derive(Clone, Copy)]
struct TextureRef {
    image: usize,
    tex_coord: u32,
    wrap: [Wrap; 2],
}

impl Loader<'_> {
    /// The file is not valid glTF, for `cause`.
    fn invalid(&self, cause: impl Into<String>) -> SceneError {
        SceneError::InvalidGltf { file: self.file.clone(), cause: cause.into() }
    }
}
