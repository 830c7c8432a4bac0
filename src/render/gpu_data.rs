//! GPU-side structs: `#[repr(C)]` + `bytemuck::Pod`, each with a `const` size assertion and a WGSL
//! struct of the same name and layout in `shaders/` (`Uniforms` in mesh.wgsl and lines.wgsl;
//! vertex layouts match the `VsIn` structs).

use bytemuck::{Pod, Zeroable};

/// Per-frame uniforms (mesh.wgsl, lines.wgsl `Uniforms`).
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Pod, Zeroable)]
pub struct Uniforms {
    /// Column-major view-projection from the scene's local frame (wgpu clip space, depth 0..1).
    pub view_proj: [[f32; 4]; 4],
    /// Multiplier on radiosity before tone mapping (2^EV).
    pub exposure: f32,
    /// 0 = linear (clamp only), 1 = sRGB transfer curve.
    pub tone: u32,
    /// 0 = vertex colours are radiosity, 1 = vertex colours are display colours (heatmap).
    pub mode: u32,
    /// Picked element id, [`NO_SELECTION`] for none.
    pub selected: u32,
    /// Colour of back faces (display space, alpha unused).
    pub back_color: [f32; 4],
    /// Bit set of [`OVERLAY_QUADTREE`], [`OVERLAY_PICKED`].
    pub overlay: u32,
    /// Width of the quadtree edges in pixels (on each side of a shared edge).
    pub line_px: f32,
    pub _pad: [u32; 2],
    /// Background of the viewport (display space; alpha unused): the clear colour of the
    /// offscreen target, drawn behind the mesh when drawing straight into egui's pass.
    pub background: [f32; 4],
}
const _: () = assert!(size_of::<Uniforms>() == 128);

/// `Uniforms::overlay` bit: draw every leaf's edges in its quadtree-depth colour.
pub const OVERLAY_QUADTREE: u32 = 1;
/// `Uniforms::overlay` bit: an element is picked (the shader outlines it).
pub const OVERLAY_PICKED: u32 = 2;

/// `Uniforms::selected` when nothing is picked.
pub const NO_SELECTION: u32 = u32::MAX;

/// A mesh vertex (mesh.wgsl `VsIn`).
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Pod, Zeroable)]
pub struct MeshVertex {
    /// Position in the scene's local frame (world minus the scene's centre).
    pub position: [f32; 3],
    /// Element id (for the highlight).
    pub element: u32,
    /// Radiosity (mode 0) or display colour (mode 1).
    pub color: [f32; 3],
    /// Position in the leaf's parameter square (quads: corners (0,0), (1,0), (1,1), (0,1);
    /// triangles: (0,0), (1,0), (0,1)); the shader turns it into a distance to the leaf's
    /// boundary in pixels for the quadtree and the outline.
    pub uv: [f32; 2],
    /// Quadtree-depth colour of the leaf (RGB, unorm8); alpha 255 for a quad, 0 for a triangle
    /// (which edges bound the parameter domain).
    pub line_color: [u8; 4],
}
const _: () = assert!(size_of::<MeshVertex>() == 40);

/// A line vertex (lines.wgsl `VsIn`).
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Pod, Zeroable)]
pub struct LineVertex {
    pub position: [f32; 3],
    /// RGBA display colour, alpha-blended.
    pub color: [f32; 4],
}
const _: () = assert!(size_of::<LineVertex>() == 28);
