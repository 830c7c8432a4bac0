// Radiosity mesh: one colour per vertex (flat: the element's B at every corner; smooth: Gouraud
// from vertex averages), exposure and tone mapping (per vertex), back faces drawn distinctly,
// picked element highlighted and outlined, quadtree edges drawn from each fragment's distance to its leaf's
// boundary (no line geometry: "single-pass wireframe", Bærentzen et al. 2006). Output is
// display-encoded (sRGB or linear, per `tone`): into the Rgba8Unorm offscreen target, or straight
// into egui's pass, whose *Srgb target formats re-encode on write (then `DECODE_OUTPUT` undoes
// the encoding first). `vs_background`/`fs_background` fill the pixels the mesh left empty.

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
    // Bit 0: quadtree edges; bit 1: something is picked (its outline needs the edge distance).
    overlay: u32,
    // Edge width in pixels, on each side of a shared edge.
    line_px: f32,
    pad0: u32,
    pad1: u32,
    background: vec4<f32>,
};

@group(0) @binding(0) var<uniform> u: Uniforms;

// True when the colour target is an *Srgb format (the hardware encodes what we write).
override DECODE_OUTPUT: bool = false;

fn srgb_decode(c: vec3<f32>) -> vec3<f32> {
    let lo = c / 12.92;
    let hi = pow((c + 0.055) / 1.055, vec3<f32>(2.4));
    return select(hi, lo, c <= vec3<f32>(0.04045));
}

// A display-encoded colour as the colour target wants it.
fn to_target(c: vec3<f32>) -> vec4<f32> {
    if (DECODE_OUTPUT) {
        return vec4<f32>(srgb_decode(c), 1.0);
    }
    return vec4<f32>(c, 1.0);
}

struct VsIn {
    @location(0) position: vec3<f32>,
    @location(1) element: u32,
    @location(2) color: vec3<f32>,
    // Position in the leaf's parameter square (quads: unit square; triangles: u, v ≥ 0, u + v ≤ 1).
    @location(3) uv: vec2<f32>,
    // Quadtree-depth colour of the leaf; alpha 1 for a quad, 0 for a triangle.
    @location(4) line_color: vec4<f32>,
};

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) color: vec3<f32>,
    @location(1) @interpolate(flat) element: u32,
    @location(2) uv: vec2<f32>,
    @location(3) @interpolate(flat) line_color: vec4<f32>,
};

@vertex
fn vs_main(v: VsIn) -> VsOut {
    var o: VsOut;
    o.clip = u.view_proj * vec4<f32>(v.position, 1.0);
    o.color = display(v.color);
    o.element = v.element;
    o.uv = v.uv;
    o.line_color = v.line_color;
    return o;
}

// The sRGB transfer curve with 1.055 c^(1/2.4) − 0.055 approximated from three square roots
// (I. Taylor, "sRGB approximations for HLSL", 2010): within one 8-bit level of the exact curve
// on [0, 1], and several times cheaper than pow() on a CPU rasteriser.
fn srgb_encode(c: vec3<f32>) -> vec3<f32> {
    let lo = c * 12.92;
    let s1 = sqrt(c);
    let s2 = sqrt(s1);
    let s3 = sqrt(s2);
    let hi = 0.662002687 * s1 + 0.684122060 * s2 - 0.323583601 * s3 - 0.0225411470 * c;
    return select(hi, lo, c <= vec3<f32>(0.0031308));
}

// A vertex colour as displayed: radiosity (mode 0) exposed, clamped and tone-mapped; a display
// colour (mode 1, heatmap) as it is. Done per vertex, so smooth shading interpolates display
// values (as Gouraud shading on a display does); the fragment shader, which runs for every pixel
// of the viewport on a CPU rasteriser, only adds the overlays.
fn display(color: vec3<f32>) -> vec3<f32> {
    if (u.mode != 0u) {
        return color;
    }
    let c = clamp(color * u.exposure, vec3<f32>(0.0), vec3<f32>(1.0));
    if (u.tone == 1u) {
        return srgb_encode(c);
    }
    return c;
}

@fragment
fn fs_main(i: VsOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    // Distance to the leaf's boundary in pixels, only when an overlay needs it (the branch is
    // on a uniform, so the derivatives stay in uniform control flow).
    var d = 1e6;
    if ((u.overlay & 3u) != 0u) {
        // Each edge's own coordinate divided by that coordinate's screen-space rate of change:
        // u = 0 and v = 0 (both shapes), u = 1 and v = 1 (quads), s = 1 − u − v = 0 (a
        // triangle's third edge). The third edge needs fwidth(s) itself: fwidth(u) + fwidth(v)
        // overestimates it without bound where u and v change fast in opposite directions (a
        // sheared parameterisation, e.g. long triangles seen at a grazing angle), which drew
        // that edge as a wide, blurred band.
        let s = 1.0 - i.uv.x - i.uv.y;
        let inv = 1.0 / max(fwidth(vec3<f32>(i.uv, s)), vec3<f32>(1e-6));
        let near = min(i.uv.x * inv.x, i.uv.y * inv.y);
        let far = min((1.0 - i.uv.x) * inv.x, (1.0 - i.uv.y) * inv.y);
        d = min(near, select(s * inv.z, far, i.line_color.a > 0.5));
    }
    var c = i.color;
    if (!front) {
        // Back faces: the back colour with diagonal stripes, so they never pass for lit surfaces.
        let s = (u32(i.clip.x + i.clip.y) / 6u) % 2u;
        c = u.back_color.rgb * select(0.6, 1.0, s == 0u);
    }
    if ((u.overlay & 1u) != 0u) {
        c = mix(c, i.line_color.rgb, clamp(u.line_px + 0.5 - d, 0.0, 1.0));
    }
    if (i.element == u.selected) {
        c = mix(c, vec3<f32>(1.0, 0.55, 0.0), 0.55);
        // A white outline twice the quadtree's width.
        c = mix(c, vec3<f32>(1.0), clamp(2.0 * u.line_px + 0.5 - d, 0.0, 1.0));
    }
    return to_target(c);
}

// The background: one triangle over the viewport at the far plane (depth 1). Drawn after the
// mesh with the depth test "less or equal" against a depth buffer cleared to 1, it shades only the
// pixels the mesh left empty.
@vertex
fn vs_background(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let x = f32((i << 1u) & 2u);
    let y = f32(i & 2u);
    return vec4<f32>(x * 2.0 - 1.0, 1.0 - y * 2.0, 1.0, 1.0);
}

@fragment
fn fs_background() -> @location(0) vec4<f32> {
    return to_target(u.background.rgb);
}
