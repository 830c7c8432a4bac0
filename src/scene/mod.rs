//! The scene: planar convex polygons (triangles and quads), one-sided, each with an RGB
//! reflectance ρ ∈ [0, 1) and an RGB emission E ≥ 0 (radiant exitance, the unit of B).
//!
//! Front = right-hand rule on the vertex order. A patch radiates and receives only on its
//! front side; `doubleSided` glTF materials become two back-to-back patches.
//!
//! Submodules: [`gltf`] (import), [`builtin`] (the built-in scenes), [`furnished`] (generated
//! furnished rooms), [`families`] (generated scene families), [`texture`]; validation lives here.

pub mod builtin;
pub mod decal;
pub mod families;
pub mod furnished;
pub mod gltf;
mod pieces;
pub mod texture;

use crate::math::{DVec3, Rgb, polygon_area, polygon_centroid, polygon_normal};
use serde::Serialize;
use std::path::PathBuf;

/// Largest reflectance a patch may have. ρ = 1 makes an enclosure's radiosity equation singular
/// (nothing is ever absorbed); the loader clamps ρ ∈ [RHO_MAX, 1] to `RHO_MAX` with a warning
/// (the SPLASH-2 room's lamps are ρ = 1.0) and rejects ρ > 1 or ρ < 0 as an error.
pub const RHO_MAX: f64 = 0.999;

/// Relative tolerance on a quad's distance from its plane (as a fraction of its diameter) for it
/// to count as planar.
pub const PLANARITY_TOL: f64 = 1e-6;

/// Errors building or loading a scene. Each names the file (or built-in) and the cause.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{file}: cannot read: {source}")]
    Io {
        file: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: cannot write: {source}")]
    Write {
        file: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: invalid glTF: {cause}")]
    InvalidGltf { file: PathBuf, cause: String },
    #[error("{file}: buffer {index} is missing or too short: {cause}")]
    Buffer { file: PathBuf, index: usize, cause: String },
    #[error(
        "{file}: URI {uri:?} leaves the scene's folder or uses an unsupported scheme (only relative file paths and data: URIs are read)"
    )]
    UriOutsideScene { file: PathBuf, uri: String },
    #[error("{file}: mesh {mesh:?} primitive {primitive}: non-finite vertex position")]
    NonFinitePosition { file: PathBuf, mesh: String, primitive: usize },
    #[error("{file}: material {material:?}: reflectance {value} is outside [0, 1]")]
    ReflectanceOutOfRange { file: PathBuf, material: String, value: f64 },
    #[error("{file}: material {material:?}: negative or non-finite emission {value}")]
    BadEmission { file: PathBuf, material: String, value: f64 },
    #[error("{file}: image {index}: {cause}")]
    Image { file: PathBuf, index: usize, cause: String },
    #[error("{file}: cannot read: it is {kind}, not a regular file")]
    NotRegularFile { file: PathBuf, kind: &'static str },
    #[error("{file}: the scene has no patches")]
    Empty { file: PathBuf },
    #[error("{file}: more than {cap} triangles (the size cap; raise it with --max-triangles)")]
    TooLarge { file: PathBuf, cap: usize },
    #[error("{file}: patch {index}: {cause}")]
    BadPatch { file: PathBuf, index: usize, cause: String },
    #[error("builtin:{name}: {cause}")]
    BadGenerated { name: String, cause: String },
    #[error("unknown built-in scene {name:?} (try `radlab scenes`)")]
    UnknownBuiltin { name: String },
}

/// One input polygon.
#[derive(Clone, Debug, Serialize)]
pub struct Patch {
    /// 3 or 4 vertices, counter-clockwise seen from the front.
    pub vertices: Vec<DVec3>,
    pub reflectance: Rgb,
    pub emission: Rgb,
    /// Name of the glTF mesh (or built-in part) this patch comes from.
    pub mesh: String,
    /// Index of the primitive within its mesh.
    pub primitive: usize,
    /// Human-readable name: `mesh/primitive/triangle` or the built-in part's name.
    pub name: String,
    /// Name of the material.
    pub material: String,
    // Derived, filled by `Patch::new`.
    pub normal: DVec3,
    pub area: f64,
    pub centroid: DVec3,
}

impl Patch {
    /// Build a patch, computing normal, area and centroid. Checks only what makes the geometry
    /// unusable (vertex count, non-finite values, zero area); see [`Scene::validate`] for more.
    pub fn new(
        vertices: Vec<DVec3>,
        reflectance: Rgb,
        emission: Rgb,
        mesh: impl Into<String>,
        primitive: usize,
        name: impl Into<String>,
        material: impl Into<String>,
    ) -> Result<Patch, String> {
        if !(3..=4).contains(&vertices.len()) {
            return Err(format!("{} vertices (a patch has 3 or 4)", vertices.len()));
        }
        if vertices.iter().any(|v| !v.is_finite()) {
            return Err("non-finite vertex position".into());
        }
        let area = polygon_area(&vertices);
        let normal = polygon_normal(&vertices);
        if !(area > 0.0) || normal == DVec3::ZERO {
            return Err("zero area".into());
        }
        let centroid = polygon_centroid(&vertices);
        Ok(Patch {
            vertices,
            reflectance,
            emission,
            mesh: mesh.into(),
            primitive,
            name: name.into(),
            material: material.into(),
            normal,
            area,
            centroid,
        })
    }

    /// A piece of this patch: the same material, mesh and primitive, with its own vertices and
    /// name (a remeshed or cut piece). Errors as [`Patch::new`].
    pub fn piece(&self, vertices: Vec<DVec3>, name: impl Into<String>) -> Result<Patch, String> {
        Patch::new(
            vertices,
            self.reflectance,
            self.emission,
            self.mesh.clone(),
            self.primitive,
            name,
            self.material.clone(),
        )
    }

    #[must_use]
    pub fn is_emitter(&self) -> bool {
        self.emission.max_channel() > 0.0
    }

    /// Emitted power Φ = E · A (per channel).
    #[must_use]
    pub fn power(&self) -> Rgb {
        self.emission * self.area
    }

    /// The patch's plane offset d in n·x = d.
    #[must_use]
    pub fn plane_d(&self) -> f64 {
        self.normal.dot(self.centroid)
    }

    /// Largest distance between two vertices.
    #[must_use]
    pub fn diameter(&self) -> f64 {
        let mut d: f64 = 0.0;
        for (i, a) in self.vertices.iter().enumerate() {
            for b in &self.vertices[i + 1..] {
                d = d.max(a.distance(*b));
            }
        }
        d
    }
}

/// Axis-aligned bounds.
#[derive(Copy, Clone, Debug, Serialize)]
pub struct Bounds {
    pub min: DVec3,
    pub max: DVec3,
}

impl Bounds {
    #[must_use]
    pub fn center(&self) -> DVec3 {
        0.5 * (self.min + self.max)
    }
    #[must_use]
    pub fn diagonal(&self) -> f64 {
        (self.max - self.min).length()
    }
}

/// A loaded scene: patches in the documented order, plus what the loader noticed.
#[derive(Clone, Debug, Serialize)]
pub struct Scene {
    /// Display name (file stem or built-in name).
    pub name: String,
    /// Where it came from: a path, or `builtin:NAME`.
    pub source: String,
    pub patches: Vec<Patch>,
    /// Non-fatal notes from loading (clamped ρ, skipped primitives, no emitter, …).
    pub warnings: Vec<String>,
    /// The scene's own viewpoint (a glTF camera node), if it has one.
    pub camera: Option<Viewpoint>,
}

/// A camera placement: where from, where to, which way is up, vertical field of view.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct Viewpoint {
    pub eye: DVec3,
    pub target: DVec3,
    pub up: DVec3,
    pub fov_y_deg: f64,
}

impl Scene {
    /// A scene from patches, with the "no emitter" warning filled in.
    #[must_use]
    pub fn new(name: impl Into<String>, source: impl Into<String>, patches: Vec<Patch>) -> Scene {
        let mut s =
            Scene { name: name.into(), source: source.into(), patches, warnings: Vec::new(), camera: None };
        if !s.patches.iter().any(Patch::is_emitter) {
            s.warnings.push("no patch emits light: the solution will be black".into());
        }
        s
    }

    /// Load a scene from `builtin:NAME` or a .gltf/.glb path with default options.
    pub fn load(spec: &str) -> Result<Scene, SceneError> {
        if let Some(name) = spec.strip_prefix("builtin:") {
            builtin::load(name)
        } else {
            gltf::load(std::path::Path::new(spec), &gltf::LoadOptions::default())
        }
    }

    #[must_use]
    pub fn bounds(&self) -> Bounds {
        let mut min = DVec3::splat(f64::INFINITY);
        let mut max = DVec3::splat(f64::NEG_INFINITY);
        for p in &self.patches {
            for v in &p.vertices {
                min = min.min(*v);
                max = max.max(*v);
            }
        }
        Bounds { min, max }
    }

    #[must_use]
    pub fn total_area(&self) -> f64 {
        self.patches.iter().map(|p| p.area).sum()
    }

    /// Total emitted power Σ E·A.
    #[must_use]
    pub fn emitted_power(&self) -> Rgb {
        self.patches.iter().map(Patch::power).sum()
    }

    /// Check the scene's invariants; returns a report of everything wrong (empty = valid).
    #[must_use]
    pub fn validate(&self) -> Vec<String> {
        let mut report = Vec::new();
        if self.patches.is_empty() {
            report.push("no patches".into());
        }
        for (i, p) in self.patches.iter().enumerate() {
            if !(3..=4).contains(&p.vertices.len()) {
                report.push(format!("patch {i}: {} vertices", p.vertices.len()));
                continue;
            }
            if p.vertices.iter().any(|v| !v.is_finite()) {
                report.push(format!("patch {i}: non-finite vertex"));
            }
            if !(p.area > 0.0) {
                report.push(format!("patch {i}: zero area"));
            }
            for c in p.reflectance.0 {
                if !(0.0..=RHO_MAX).contains(&c) {
                    report.push(format!("patch {i}: reflectance {c} outside [0, {RHO_MAX}]"));
                }
            }
            for c in p.emission.0 {
                if !(c >= 0.0 && c.is_finite()) {
                    report.push(format!("patch {i}: emission {c}"));
                }
            }
            let diam = p.diameter();
            for v in &p.vertices {
                let off = (p.normal.dot(*v) - p.plane_d()).abs();
                if off > PLANARITY_TOL * diam.max(f64::MIN_POSITIVE) {
                    report.push(format!("patch {i}: not planar (vertex {off:e} off its plane)"));
                    break;
                }
            }
            if !is_convex(&p.vertices, p.normal) {
                report.push(format!("patch {i}: not convex"));
            }
        }
        report
    }
}

/// True if a planar polygon turns the same way at every vertex (strictly convex or degenerate
/// straight angles allowed).
#[must_use]
pub fn is_convex(verts: &[DVec3], normal: DVec3) -> bool {
    let n = verts.len();
    if n == 3 {
        return true;
    }
    let scale = verts.iter().map(|v| (*v - verts[0]).length_squared()).fold(0.0, f64::max);
    (0..n).all(|i| {
        let a = verts[i];
        let b = verts[(i + 1) % n];
        let c = verts[(i + 2) % n];
        (b - a).cross(c - b).dot(normal) >= -1e-12 * scale
    })
}

/// A material of a scene built in code (the built-in and generated scenes): name, ρ, E.
#[derive(Clone, Copy, Debug)]
struct Mat {
    name: &'static str,
    rho: Rgb,
    emission: Rgb,
}
