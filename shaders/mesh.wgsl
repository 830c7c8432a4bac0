// Radiosity mesh: one colour per vertex (flat: the element's B at every corner; smooth: Gouraud
// from vertex averages), exposure and tone mapping, back faces drawn distinctly, picked element
// highlighted. Output is display-encoded (sRGB or linear, per `tone`) into an Rgba8Unorm target.

struct Uniforms {
    view_proj: mat4x4<f32>,
    exposure: f32,
    // 0 = linear (clamp only), 1 = sRGB transfer curve.
    tone: u32,
    // 0 = vertex colour is radiosity (tone-mapped), 1 = vertex colour is a display colour.
    mode: u32,
    // Picked element id, 0xffffffff for none.
    selected: u32,
    back_color: vec4<f32>,
};

@group(0) @binding(0) var<uniform> u: Uniforms;

struct VsIn {
    @location(0) position: vec3<f32>,
    @location(1) element: u32,
    @location(2) color: vec3<f32>,
};

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) color: vec3<f32>,
    @location(1) @interpolate(flat) element: u32,
};

@vertex
fn vs_main(v: VsIn) -> VsOut {
    var o: VsOut;
    o.clip = u.view_proj * vec4<f32>(v.position, 1.0);
    o.color = v.color;
    o.element = v.element;
    return o;
}

fn srgb_encode(c: vec3<f32>) -> vec3<f32> {
    let lo = c * 12.92;
    let hi = 1.055 * pow(c, vec3<f32>(1.0 / 2.4)) - 0.055;
    return select(hi, lo, c <= vec3<f32>(0.0031308));
}

@fragment
fn fs_main(i: VsOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    var c: vec3<f32>;
    if (u.mode == 0u) {
        c = clamp(i.color * u.exposure, vec3<f32>(0.0), vec3<f32>(1.0));
        if (u.tone == 1u) {
            c = srgb_encode(c);
        }
    } else {
        c = i.color;
    }
    if (!front) {
        // Back faces: the back colour with diagonal stripes, so they never pass for lit surfaces.
        let s = (u32(i.clip.x + i.clip.y) / 6u) % 2u;
        c = u.back_color.rgb * select(0.6, 1.0, s == 0u);
    }
    if (i.element == u.selected) {
        c = mix(c, vec3<f32>(1.0, 0.55, 0.0), 0.55);
    }
    return vec4<f32>(c, 1.0);
}
