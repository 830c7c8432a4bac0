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
//! ## Layers (dependencies point down the list; see ARCHITECTURE.md, kept by tests/layers.rs)
//! - [`math`]: `Rgb`, polygon area/normal/centroid, seeded RNG.
//! - [`scene`]: patches, materials, glTF import and export, built-in and generated scenes.
//! - [`geometry`]: form-factor kernels, exact single-bounce integrals, the BVH and visibility,
//!   element basis functions.
//! - [`mesh`]: meshing given shadows — critical segments, the discontinuity meshes, the graded mesh.
//! - [`solver`]: the element hierarchy and links, the hierarchical, uniform, progressive,
//!   discontinuity and Galerkin solvers, presets and the one solve path (`solver::spec`).
//! - [`eval`]: the rulers — the independent reference, the pointwise and element-average error,
//!   reconstructions, the penumbra band and the lecture's five meshing artifacts.
//! - [`present`]: what a solution looks like — images, overlays, figures, the bake, the matrix view.
//! - [`studies`]: measured sweeps — the speed-against-error bench, h against p, the hard cases.
//! - `render`, `viewer` (feature `gui`): wgpu pipelines and the eframe app.

pub mod eval;
pub mod geometry;
pub mod math;
pub mod mesh;
pub mod present;
pub mod scene;
pub mod solver;
pub mod studies;

#[cfg(feature = "gui")]
pub mod render;
#[cfg(feature = "gui")]
pub mod viewer;
