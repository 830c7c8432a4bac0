//! What a solution looks like: images, overlays, the lecture's figures, the bake.

/// One picture per meshing artifact, every reflecting patch drawn in its plane.
pub mod artifact_pictures;
/// A solution as a glTF asset (vertex colours or a lightmap).
pub mod bake;
/// Links as the blocks of the leaf-to-leaf form-factor matrix they stand for.
pub mod block_matrix;
/// The lecture's figures as data: scene, settings, steps, overlays, camera, caption.
pub mod figures;
/// A CPU ray-cast renderer of solutions to PNG, the default camera, auto exposure.
pub mod image;
/// The meshing overlays' lines: critical edges (D0/D1/D2) and artifact samples.
pub mod mesh_overlay;
/// CPU-side vertex and colour lists for shading, quadtree, links and error; picking.
pub mod overlay;
