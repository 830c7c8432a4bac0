// Overlay lines (links): positions in the scene's local frame, RGBA
// display colours, alpha-blended over the mesh.

struct Uniforms {
    view_proj: mat4x4<f32>,
    exposure: f32,
    tone: u32,
    mode: u32,
    selected: u32,
    back_color: vec4<f32>,
    overlay: u32,
    line_px: f32,
    pad0: u32,
    pad1: u32,
    background: vec4<f32>,
};

@group(0) @binding(0) var<uniform> u: Uniforms;

// True when the colour target is an *Srgb format (see mesh.wgsl).
override DECODE_OUTPUT: bool = false;

fn srgb_decode(c: vec3<f32>) -> vec3<f32> {
    let lo = c / 12.92;
    let hi = pow((c + 0.055) / 1.055, vec3<f32>(2.4));
    return select(hi, lo, c <= vec3<f32>(0.04045));
}

struct VsIn {
    @location(0) position: vec3<f32>,
    @location(1) color: vec4<f32>,
};

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) color: vec4<f32>,
};

@vertex
fn vs_main(v: VsIn) -> VsOut {
    var o: VsOut;
    o.clip = u.view_proj * vec4<f32>(v.position, 1.0);
    o.color = v.color;
    return o;
}

@fragment
fn fs_main(i: VsOut) -> @location(0) vec4<f32> {
    if (DECODE_OUTPUT) {
        return vec4<f32>(srgb_decode(i.color.rgb), i.color.a);
    }
    return i.color;
}
