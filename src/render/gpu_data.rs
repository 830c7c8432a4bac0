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
}
const _: () = assert!(size_of::<Uniforms>() == 96);

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
}
const _: () = assert!(size_of::<MeshVertex>() == 28);

/// A line vertex (lines.wgsl `VsIn`).
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Pod, Zeroable)]
pub struct LineVertex {
    pub position: [f32; 3],
    /// RGBA display colour, alpha-blended.
    pub color: [f32; 4],
}
const _: () = assert!(size_of::<LineVertex>() == 28);
