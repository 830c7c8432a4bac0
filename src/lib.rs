//! # radlab — a lab for hierarchical radiosity
//!
//! A solver for diffuse global illumination that is fast and honest about its error, and an
//! interactive tool that shows how radiosity works and where it goes wrong.
//!
//! The radiosity equation for a diffuse scene of patches i, RGB per channel:
//!
//! ```text
//! B_i = E_i + ρ_i Σ_j F_ij V_ij B_j          [Goral et al. 1984; Cohen & Wallace 1993, ch. 2]
//! ```
//!
//! solved here by classical methods (a uniform mesh with Gauss–Seidel, progressive refinement)
//! and by hierarchical radiosity [Hanrahan, Salzman, Aupperle 1991, "A Rapid Hierarchical
//! Radiosity Algorithm", SIGGRAPH '91] — quadtree elements, `Refine` with Feps/Aeps or a BF
//! oracle, links, recursive `Gather`, push-pull — which needs O(n) interactions instead of n².
//!
//! ## Module map (dependencies point one way; see ARCHITECTURE.md)
//! - [`math`]: `Rgb`, polygon area/normal/centroid, seeded RNG.
//! - [`scene`]: patches, materials, glTF import, built-in scenes, validation.
//! - [`form_factor`]: pure kernels — point→polygon (Lambert), disk, quadrature, Monte Carlo.
//! - [`accel`]: obvhs BVH over the input polygons; `occluded(a, b)`.
//! - [`visibility`]: visible fraction between two elements with seeded jittered rays.
//! - [`hierarchy`]: element arena (`ElementId`), quad/triangle 1→4 split.
//! - [`link`]: compact link store.
//! - [`solver`]: parameters, uniform / progressive / hierarchical solvers, statistics, where the
//!   light goes (absorbed, on back faces, out of the scene).
//! - [`reference`](mod@reference): an independent Monte Carlo estimator that shares no kernel with `solver`.
//! - [`metrics`]: per-element error, L1/L2/L∞, energy balance.
//! - [`mesh`]: meshing given shadows — critical segments (D0, EV/VE → D1/D2) on each receiver,
//!   Heckbert's constrained Delaunay mesh and Campbell & Fussell's BSP mesh, a scene remeshed.
//! - [`figures`]: the lecture's figures as presets (scene, settings, overlays, camera, caption).
//! - [`exact`]: exact single-bounce radiosity (one emitter, black occluders, one receiver):
//!   a closed-form ruler with no reference noise.
//! - [`pointwise`]: the pointwise ruler — a solution's reconstruction at the reference's points.
//! - [`basis`]: element basis functions (p = 0 constant, p = 1 linear / bilinear), quadrature on an element.
//! - [`order_study`]: h- against p-refinement measured on exact single-bounce scenes (slopes, table, plot).
//! - [`reconstruction`]: flat, Gouraud-from-vertex-averages and nodal p = 1 reconstructions.
//! - [`penumbra`]: the penumbra band of a point set (points that see part of the direct light).
//! - [`artifacts`]: the five meshing artifacts of the lecture, one number each, against a reference.
//! - [`artifact_pictures`]: one picture per artifact, every reflecting patch drawn in its plane.
//! - [`bench`](mod@bench): the speed-against-error sweep behind `radlab bench`.
//! - [`hard_cases`]: generated numerically hard scenes (assets/scenes/hard/).
//! - [`image`]: a CPU renderer of solutions (PNG) from a default camera.
//! - [`bake`]: a solution as a glTF asset (vertex colours, unlit) that any viewer shows as solved.
//! - [`overlay`]: CPU-side line/colour lists for quadtree, links and error overlays.
//! - [`mesh_overlay`]: the meshing overlays' lines: critical edges (D0/D1/D2), artifact samples.
//! - [`block_matrix`]: links as the blocks of the leaf-to-leaf form-factor matrix they stand for.
//! - `render`, `viewer` (feature `gui`): wgpu pipelines and the eframe app.

pub mod accel;
pub mod artifact_pictures;
pub mod artifacts;
pub mod bake;
pub mod basis;
pub mod bench;
pub mod block_matrix;
pub mod exact;
pub mod figures;
pub mod form_factor;
pub mod hard_cases;
pub mod hierarchy;
pub mod image;
pub mod link;
pub mod math;
pub mod mesh;
pub mod mesh_overlay;
pub mod metrics;
pub mod order_study;
pub mod overlay;
pub mod penumbra;
pub mod pointwise;
pub mod reconstruction;
pub mod reference;
pub mod scene;
pub mod solver;
pub mod visibility;

#[cfg(feature = "gui")]
pub mod render;
#[cfg(feature = "gui")]
pub mod viewer;
