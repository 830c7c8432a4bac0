// Copies the offscreen viewport image (display-encoded Rgba8Unorm) into egui's render pass.
// `fs_decode` is used when egui's target is an *Srgb format, which re-encodes on write.

@group(0) @binding(0) var img: texture_2d<f32>;
@group(0) @binding(1) var smp: sampler;

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

// One triangle covering the viewport.
@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> VsOut {
    let x = f32((i << 1u) & 2u);
    let y = f32(i & 2u);
    var o: VsOut;
    o.clip = vec4<f32>(x * 2.0 - 1.0, 1.0 - y * 2.0, 0.0, 1.0);
    o.uv = vec2<f32>(x, y);
    return o;
}

@fragment
fn fs_copy(i: VsOut) -> @location(0) vec4<f32> {
    return textureSample(img, smp, i.uv);
}

fn srgb_decode(c: vec3<f32>) -> vec3<f32> {
    let lo = c / 12.92;
    let hi = pow((c + 0.055) / 1.055, vec3<f32>(2.4));
    return select(hi, lo, c <= vec3<f32>(0.04045));
}

@fragment
fn fs_decode(i: VsOut) -> @location(0) vec4<f32> {
    let c = textureSample(img, smp, i.uv);
    return vec4<f32>(srgb_decode(c.rgb), c.a);
}
