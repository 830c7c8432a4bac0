//! Offscreen tests of the viewport pipelines (CPU rasteriser: lavapipe or llvmpipe), with pixel
//! checks on known scenes, and the shaders parsed and validated with naga.
//!
//! One wgpu device is shared by every test in this binary (adapter creation costs 0.2–0.5 s).
#![cfg(feature = "gui")]

use eframe::egui_wgpu;
use eframe::wgpu;
use radlab::math::{DVec3, Rgb};
use radlab::present::overlay::{self, ElementCore, ElementView, LinkFilter, LinkView};
use radlab::render::geometry::{self, MeshColors};
use radlab::render::snapshot::{self, Thresholds};
use radlab::render::{
    FrameParams, Geometry, NO_SELECTION, OVERLAY_PICKED, OVERLAY_QUADTREE, RgbaImage, SceneRenderer, Uniforms,
};
use radlab::scene::Bounds;
use radlab::viewer::camera::OrbitCamera;
use std::sync::{Mutex, OnceLock};

/// 8-bit rounding of the rasteriser and of the sRGB curve in f32: ±2 levels.
const LEVEL_TOL: i32 = 2;
const W: u32 = 96;
const H: u32 = 64;

fn render_state() -> &'static Mutex<egui_wgpu::RenderState> {
    static RS: OnceLock<Mutex<egui_wgpu::RenderState>> = OnceLock::new();
    RS.get_or_init(|| {
        Mutex::new(egui_kittest::wgpu::create_render_state(
            egui_kittest::wgpu::default_wgpu_setup(),
            egui_wgpu::RendererOptions::PREDICTABLE,
        ))
    })
}

/// A square element of side 2 centred at (0, 0, z) facing +z (or −z when `flip`).
fn square(id: u32, z: f64, b: Rgb, flip: bool) -> ElementView {
    let mut v = [
        DVec3::new(-1.0, -1.0, z),
        DVec3::new(1.0, -1.0, z),
        DVec3::new(1.0, 1.0, z),
        DVec3::new(-1.0, 1.0, z),
    ];
    if flip {
        v.reverse();
    }
    ElementView {
        core: ElementCore {
            id,
            patch: id,
            parent: None,
            depth: 0,
            vertices: v,
            n_vertices: 4,
            area: 4.0,
            reflectance: Rgb::splat(0.5),
            emission: Rgb::ZERO,
            radiosity: b,
            error_estimate: 0.0,
        },
        leaf: true,
        stop: "",
    }
}

/// Camera on +z looking at the origin, the unit box in view.
fn camera() -> OrbitCamera {
    let mut c = OrbitCamera::frame_all(&Bounds { min: DVec3::splat(-1.0), max: DVec3::splat(1.0) });
    c.pitch = 0.0;
    c.distance = 4.0;
    c
}

fn uniforms(srgb: bool, mode: u32, selected: u32) -> Uniforms {
    let m = camera().view_proj(f64::from(W) / f64::from(H), DVec3::ZERO).to_cols_array_2d();
    Uniforms {
        view_proj: m.map(|c| c.map(|x| x as f32)),
        exposure: 1.0,
        tone: u32::from(srgb),
        mode,
        selected,
        back_color: [0.0, 0.0, 1.0, 1.0],
        overlay: if selected == NO_SELECTION { 0 } else { OVERLAY_PICKED },
        line_px: 0.75,
        _pad: [0; 2],
        background: [0.0, 0.0, 0.0, 1.0],
    }
}

fn draw(g: &Geometry, u: Uniforms) -> RgbaImage {
    draw_sized(g, u, [W, H])
}

fn draw_sized(g: &Geometry, u: Uniforms, size: [u32; 2]) -> RgbaImage {
    let rs = render_state().lock().unwrap();
    let mut r = SceneRenderer::new(&rs.device, wgpu::TextureFormat::Rgba8Unorm, None);
    r.set_geometry(&rs.device, g);
    let mut enc = rs.device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    r.render(&rs.device, &rs.queue, &mut enc, &FrameParams { uniforms: u, size });
    rs.queue.submit([enc.finish()]);
    r.read_pixels(&rs.device, &rs.queue).unwrap()
}

fn close(px: [u8; 4], want: [u8; 3]) -> bool {
    (0..3).all(|c| (i32::from(px[c]) - i32::from(want[c])).abs() <= LEVEL_TOL)
}

#[test]
fn flat_radiosity_linear_and_srgb_tone_mapping() {
    let els = vec![square(0, 0.0, Rgb::new(0.5, 0.25, 0.0), false)];
    let g =
        Geometry { mesh: geometry::mesh(&els, &[0], MeshColors::Flat, DVec3::ZERO), ..Geometry::default() };
    let img = draw(&g, uniforms(false, 0, NO_SELECTION));
    assert_eq!((img.width, img.height), (W, H));
    let c = img.pixel(W / 2, H / 2);
    assert!(close(c, [128, 64, 0]), "linear: {c:?}");
    assert!(close(img.pixel(1, 1), [0, 0, 0]), "background stays clear");
    // sRGB: 0.5 → 188, 0.25 → 137.
    let c = draw(&g, uniforms(true, 0, NO_SELECTION)).pixel(W / 2, H / 2);
    assert!(close(c, [188, 137, 0]), "sRGB: {c:?}");
}

#[test]
fn depth_test_keeps_the_nearer_surface_whatever_the_order() {
    let near = square(0, 0.5, Rgb::new(1.0, 0.0, 0.0), false);
    let far = square(1, -0.5, Rgb::new(0.0, 1.0, 0.0), false);
    for els in [vec![near.clone(), far.clone()], vec![far.clone(), near.clone()]] {
        let leaves: Vec<u32> = (0..2).collect();
        let mut els = els;
        for (i, e) in els.iter_mut().enumerate() {
            e.id = i as u32;
        }
        let g = Geometry {
            mesh: geometry::mesh(&els, &leaves, MeshColors::Flat, DVec3::ZERO),
            ..Geometry::default()
        };
        let c = draw(&g, uniforms(false, 0, NO_SELECTION)).pixel(W / 2, H / 2);
        assert!(close(c, [255, 0, 0]), "{c:?}");
    }
}

#[test]
fn back_faces_are_distinct_and_selection_is_highlighted() {
    let els = vec![square(0, 0.0, Rgb::new(0.0, 1.0, 0.0), true)];
    let g =
        Geometry { mesh: geometry::mesh(&els, &[0], MeshColors::Flat, DVec3::ZERO), ..Geometry::default() };
    let img = draw(&g, uniforms(false, 0, NO_SELECTION));
    // The back colour (blue) or its darker stripe, never the radiosity (green).
    for (x, y) in [(W / 2, H / 2), (W / 2 + 3, H / 2), (W / 2 + 6, H / 2 + 1)] {
        let c = img.pixel(x, y);
        assert!(c[1] < 10 && c[2] > 140, "back face at ({x},{y}): {c:?}");
    }
    let front = vec![square(0, 0.0, Rgb::new(0.0, 0.0, 0.0), false)];
    let g =
        Geometry { mesh: geometry::mesh(&front, &[0], MeshColors::Flat, DVec3::ZERO), ..Geometry::default() };
    let img = draw(&g, uniforms(false, 0, 0));
    let c = img.pixel(W / 2, H / 2);
    // Black mixed 55 % with orange (1, 0.55, 0).
    assert!(close(c, [140, 77, 0]), "highlight: {c:?}");
    // And outlined in white along its boundary.
    let row: Vec<[u8; 4]> = (0..W).map(|x| img.pixel(x, H / 2)).collect();
    assert!(row.iter().any(|p| p[0] > 200 && p[1] > 200 && p[2] > 200), "white outline: {row:?}");
}

#[test]
fn smooth_shading_interpolates_and_heatmap_passes_through() {
    // Two half-squares: left B = 0, right B = 1 (linear tone map). Smooth: the vertices on the
    // shared edge average to 0.5, so the centre column is mid-grey; flat: a hard step.
    let mut l = square(0, 0.0, Rgb::splat(0.0), false);
    l.vertices = [
        DVec3::new(-1.0, -1.0, 0.0),
        DVec3::new(0.0, -1.0, 0.0),
        DVec3::new(0.0, 1.0, 0.0),
        DVec3::new(-1.0, 1.0, 0.0),
    ];
    let mut r = square(1, 0.0, Rgb::splat(1.0), false);
    r.patch = 0;
    l.patch = 0;
    r.vertices = [
        DVec3::new(0.0, -1.0, 0.0),
        DVec3::new(1.0, -1.0, 0.0),
        DVec3::new(1.0, 1.0, 0.0),
        DVec3::new(0.0, 1.0, 0.0),
    ];
    let els = vec![l, r];
    let g = Geometry {
        mesh: geometry::mesh(&els, &[0, 1], MeshColors::Smooth, DVec3::ZERO),
        ..Geometry::default()
    };
    let img = draw(&g, uniforms(false, 0, NO_SELECTION));
    let mid = img.pixel(W / 2, H / 2)[0];
    assert!((100..=156).contains(&mid), "smooth centre {mid}");
    let g = Geometry {
        mesh: geometry::mesh(&els, &[0, 1], MeshColors::Flat, DVec3::ZERO),
        ..Geometry::default()
    };
    let img = draw(&g, uniforms(false, 0, NO_SELECTION));
    assert!(img.pixel(W / 2 - 4, H / 2)[0] < 5 && img.pixel(W / 2 + 4, H / 2)[0] > 250);
    let heat = [[0.2f32, 0.4, 0.6], [0.2, 0.4, 0.6]];
    let g = Geometry {
        mesh: geometry::mesh(&els, &[0, 1], MeshColors::Display(&heat), DVec3::ZERO),
        ..Geometry::default()
    };
    let c = draw(&g, uniforms(false, 1, NO_SELECTION)).pixel(W / 2 + 4, H / 2);
    assert!(close(c, [51, 102, 153]), "heatmap colour untouched: {c:?}");
}

#[test]
fn lines_are_depth_tested_unless_xray() {
    // A wall at z = 0.5 hides a link between two points behind it at z = −0.5.
    let wall = square(0, 0.5, Rgb::splat(0.0), false);
    let mut a = square(1, -0.5, Rgb::splat(0.0), false);
    let mut b = a.clone();
    for v in &mut a.vertices {
        *v = DVec3::new(v.x * 0.1 - 0.8, v.y * 0.1, -0.5);
    }
    for v in &mut b.vertices {
        *v = DVec3::new(v.x * 0.1 + 0.8, v.y * 0.1, -0.5);
    }
    b.id = 2;
    let els = vec![wall.clone(), a, b];
    let links = [LinkView { receiver: 1, source: 2, ff: 0.1, vis: 1.0 }];
    let ll = overlay::link_lines(&els, &links, &LinkFilter::default(), 1.0);
    assert_eq!(ll.shown, 1);
    let mesh = geometry::mesh(&els, &[0], MeshColors::Flat, DVec3::ZERO);
    let line = geometry::lines(&ll.lines, DVec3::ZERO);
    let hidden = draw(
        &Geometry { mesh: mesh.clone(), links: line.clone(), ..Geometry::default() },
        uniforms(false, 0, NO_SELECTION),
    );
    let shown = draw(
        &Geometry { mesh: mesh.clone(), links: line.clone(), links_xray: true, ..Geometry::default() },
        uniforms(false, 0, NO_SELECTION),
    );
    let row_max = |img: &RgbaImage| (0..img.height).map(|y| img.pixel(W / 2, y)[1]).max().unwrap();
    assert!(row_max(&hidden) < 5, "link behind the wall is hidden");
    assert!(row_max(&shown) > 100, "x-ray link is drawn (viridis top is bright)");
    // Overlay lines (critical edges, artifact samples) are always depth-tested.
    let overlay_hidden = draw(
        &Geometry { mesh, overlay: line.clone(), links_xray: true, ..Geometry::default() },
        uniforms(false, 0, NO_SELECTION),
    );
    assert!(row_max(&overlay_hidden) < 5, "an overlay line behind the wall is hidden");
    let unhidden = geometry::mesh(&els, &[1], MeshColors::Flat, DVec3::ZERO);
    let overlay_shown = draw(
        &Geometry { mesh: unhidden, overlay: line, ..Geometry::default() },
        uniforms(false, 0, NO_SELECTION),
    );
    assert!(row_max(&overlay_shown) > 100, "without the wall it is drawn");
}

#[test]
fn quadtree_edges_are_drawn_by_the_mesh_shader() {
    // One black wall: its depth-0 edges (white) appear only with the overlay bit.
    let wall = square(0, 0.0, Rgb::splat(0.0), false);
    let g = Geometry {
        mesh: geometry::mesh(&[wall], &[0], MeshColors::Flat, DVec3::ZERO),
        ..Geometry::default()
    };
    // Edge pixels: at least 40 % covered by the (anti-aliased) white edge.
    let white = |img: &RgbaImage| img.pixels.chunks_exact(4).filter(|p| p[0] > 100 && p[1] > 100).count();
    let mut u = uniforms(false, 0, NO_SELECTION);
    assert_eq!(white(&draw(&g, u)), 0);
    u.overlay = OVERLAY_QUADTREE;
    let img = draw(&g, u);
    assert!(white(&img) > 100, "edges drawn: {}", white(&img));
    assert!(close(img.pixel(W / 2, H / 2), [0, 0, 0]), "the interior stays the element's colour");
}

#[test]
fn a_triangles_third_edge_is_as_thin_as_the_others() {
    // A long, thin triangle whose third edge (u + v = 1, from corner 1 to corner 2) is its short
    // base: u and v both change fast across the triangle, in opposite directions, while u + v
    // changes slowly. Measuring that edge with fwidth(u) + fwidth(v) instead of fwidth(u + v)
    // drew it as a band ~12× too wide (the green streaks on Cornell's triangulated left wall).
    const SIZE: u32 = 240;
    // Rows below the base checked for the interior colour: from just past the edge's width
    // (line_px = 0.75 on each side, plus anti-aliasing) to where the side edges come near.
    const ROWS: std::ops::RangeInclusive<u32> = 3..=12;
    let half_base = 0.15;
    let mut tri = square(0, 0.0, Rgb::splat(0.0), false);
    tri.n_vertices = 3;
    tri.vertices = [
        DVec3::new(0.0, -1.0, 0.0),
        DVec3::new(half_base, 0.6, 0.0),
        DVec3::new(-half_base, 0.6, 0.0),
        DVec3::ZERO,
    ];
    let g =
        Geometry { mesh: geometry::mesh(&[tri], &[0], MeshColors::Flat, DVec3::ZERO), ..Geometry::default() };
    let vp = camera().view_proj(1.0, DVec3::ZERO);
    let mut u = uniforms(false, 0, NO_SELECTION);
    u.view_proj = vp.to_cols_array_2d().map(|c| c.map(|x| x as f32));
    u.overlay = OVERLAY_QUADTREE;
    let img = draw_sized(&g, u, [SIZE, SIZE]);
    let c = vp * DVec3::new(0.0, 0.6, 0.0).extend(1.0);
    let x = ((c.x / c.w + 1.0) * 0.5 * f64::from(SIZE)) as u32;
    let base = ((1.0 - c.y / c.w) * 0.5 * f64::from(SIZE)) as u32;
    // Edge colour (white) mixed in: the base row is partly covered, so its pixels are grey.
    let bright = |y: u32| img.pixel(x, y)[0] > 40;
    assert!((base.saturating_sub(2)..=base + 2).any(bright), "the base edge is drawn at row {base}");
    let wide: Vec<u32> = ROWS.map(|r| base + r).filter(|&y| bright(y)).collect();
    assert!(wide.is_empty(), "edge colour {wide:?} rows inside the triangle, below its base at row {base}");
    assert!(close(img.pixel(x, base + 40), [0, 0, 0]), "the interior is the element's colour");
}

/// The patch of [`t_junction_patch`]: parameter (x, y) ∈ [−1, 1]² → a rotated, scaled, shifted
/// square in the z = 0 plane. Each vertex is mapped from its own parameters, so (as in the
/// solver) a T-vertex is not bit-for-bit the average of its edge's end points.
fn patch_point(x: f64, y: f64) -> DVec3 {
    let (s, c) = 0.37f64.sin_cos();
    DVec3::new(0.93 * (c * x - s * y) + 0.0137, 0.93 * (s * x + c * y) - 0.0211, 0.0)
}

/// A square patch refined to depth `max_depth` along its diagonal and left coarse elsewhere:
/// dozens of T-junctions where big leaves meet finer ones. All leaves have B = 1.
fn t_junction_patch(max_depth: u8) -> (Vec<ElementView>, Vec<u32>) {
    fn cell(out: &mut Vec<ElementView>, x0: f64, y0: f64, s: f64, depth: u8, max_depth: u8) {
        let on_diagonal = (x0 - y0).abs() < s;
        if depth < max_depth && on_diagonal {
            let h = s / 2.0;
            for (dx, dy) in [(0.0, 0.0), (h, 0.0), (h, h), (0.0, h)] {
                cell(out, x0 + dx, y0 + dy, h, depth + 1, max_depth);
            }
            return;
        }
        let id = out.len() as u32;
        let mut e = square(id, 0.0, Rgb::splat(1.0), false);
        e.patch = 0;
        e.depth = depth;
        e.vertices = [
            patch_point(x0, y0),
            patch_point(x0 + s, y0),
            patch_point(x0 + s, y0 + s),
            patch_point(x0, y0 + s),
        ];
        e.area = s * s;
        out.push(e);
    }
    let mut els = Vec::new();
    cell(&mut els, -1.0, -1.0, 2.0, 0, max_depth);
    let leaves = (0..els.len() as u32).collect();
    (els, leaves)
}

/// Render white `leaves` on black, seen obliquely (so that shared edges are not pixel-aligned),
/// and return the dark pixels well inside the square `patch_point([−1, 1]²)`: cracks.
fn crack_pixels(
    els: &[ElementView],
    leaves: &[u32],
    colors: MeshColors<'_>,
    (yaw, pitch): (f64, f64),
) -> (usize, Vec<(u32, u32)>) {
    const SIZE: [u32; 2] = [480, 480];
    // Pixels closer than this to the silhouette are not checked (edge coverage rules).
    const SILHOUETTE_MARGIN_PX: f64 = 2.0;
    let mut cam = OrbitCamera::frame_all(&Bounds { min: DVec3::splat(-1.0), max: DVec3::splat(1.0) });
    cam.pitch = pitch;
    cam.yaw = yaw;
    cam.distance = 3.2;
    let vp = cam.view_proj(1.0, DVec3::ZERO);
    let to_px = |p: DVec3| {
        let c = vp * p.extend(1.0);
        [(c.x / c.w + 1.0) * 0.5 * f64::from(SIZE[0]), (1.0 - c.y / c.w) * 0.5 * f64::from(SIZE[1])]
    };
    let corners: Vec<[f64; 2]> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .iter()
        .map(|&(x, y)| to_px(patch_point(x, y)))
        .collect();
    // Signed distance (pixels) from each edge of the projected quad, positive inside.
    let orient = {
        let [a, b, c] = [corners[0], corners[1], corners[2]];
        ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])).signum()
    };
    let inside = |x: f64, y: f64| {
        (0..4).all(|i| {
            let (a, b) = (corners[i], corners[(i + 1) % 4]);
            let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
            orient * (ex * (y - a[1]) - ey * (x - a[0])) / ex.hypot(ey) > SILHOUETTE_MARGIN_PX
        })
    };
    let g = Geometry { mesh: geometry::mesh(els, leaves, colors, DVec3::ZERO), ..Geometry::default() };
    let mut u = uniforms(false, 0, NO_SELECTION);
    u.view_proj = vp.to_cols_array_2d().map(|c| c.map(|x| x as f32));
    let img = draw_sized(&g, u, SIZE);
    let mut checked = 0;
    let mut cracks = Vec::new();
    for y in 0..SIZE[1] {
        for x in 0..SIZE[0] {
            if inside(f64::from(x) + 0.5, f64::from(y) + 0.5) {
                checked += 1;
                if img.pixel(x, y)[0] < 250 {
                    cracks.push((x, y));
                }
            }
        }
    }
    (checked, cracks)
}

#[test]
fn t_junctions_leave_no_cracks() {
    let (els, leaves) = t_junction_patch(7);
    assert!(els.len() > 40, "{} leaves", els.len());
    for colors in [MeshColors::Flat, MeshColors::Smooth] {
        let (checked, cracks) = crack_pixels(&els, &leaves, colors, (0.4, 0.35));
        assert!(checked > 20_000, "the patch fills much of the image: {checked}");
        assert!(
            cracks.is_empty(),
            "{colors:?}: {} crack pixels, first {:?}",
            cracks.len(),
            &cracks[..cracks.len().min(8)]
        );
    }
}

/// Patch `patch` over the parameter rectangle [x0, x0 + w] × [−1, 1] of [`patch_point`], as the
/// solver keeps it: the root (not a leaf) and a quadtree below it, each vertex mapped from its own
/// parameters. Cells for which `refine(x, y, size, depth)` holds are split.
fn quadtree_patch(
    els: &mut Vec<ElementView>,
    patch: u32,
    x0: f64,
    w: f64,
    refine: &dyn Fn(f64, f64, f64, u8) -> bool,
) -> Vec<u32> {
    fn cell(
        els: &mut Vec<ElementView>,
        leaves: &mut Vec<u32>,
        parent: Option<u32>,
        patch: u32,
        [x, y, w, h]: [f64; 4],
        depth: u8,
        refine: &dyn Fn(f64, f64, f64, u8) -> bool,
    ) {
        let id = els.len() as u32;
        let mut e = square(id, 0.0, Rgb::splat(1.0), false);
        e.patch = patch;
        e.parent = parent;
        e.depth = depth;
        e.vertices =
            [patch_point(x, y), patch_point(x + w, y), patch_point(x + w, y + h), patch_point(x, y + h)];
        e.area = w * h;
        let split = refine(x, y, w, depth);
        e.leaf = !split;
        els.push(e);
        if split {
            let (hw, hh) = (w / 2.0, h / 2.0);
            for (dx, dy) in [(0.0, 0.0), (hw, 0.0), (hw, hh), (0.0, hh)] {
                cell(els, leaves, Some(id), patch, [x + dx, y + dy, hw, hh], depth + 1, refine);
            }
        } else {
            leaves.push(id);
        }
    }
    let mut leaves = Vec::new();
    cell(els, &mut leaves, None, patch, [x0, -1.0, w, 2.0], 0, refine);
    leaves
}

/// Camera (yaw, pitch) of the seam test: a crack shows only where a pixel centre falls in the
/// sliver between the two sides' edges, so several views make a missed one unlikely.
const SEAM_VIEWS: [(f64, f64); 8] =
    [(0.4, 0.35), (-0.3, 0.5), (0.9, 0.2), (-0.8, 0.7), (0.15, 0.9), (1.1, 0.45), (-1.2, 0.3), (0.6, 1.0)];

#[test]
fn seams_between_patches_leave_no_cracks() {
    // Two patches side by side sharing the edge x = 0 (a wall meeting the next wall, a box face
    // meeting the next), each refined along it differently: the left finely, the right in a band
    // at the bottom. The rasteriser leaves background pixels where one side's corner sits on the
    // other side's edge (a T-junction across patches), unless both sides share those vertices.
    let mut els = Vec::new();
    let mut leaves = quadtree_patch(&mut els, 0, -1.0, 1.0, &|x, _, w, d| d < 7 && x + w > -1e-9);
    leaves.extend(quadtree_patch(&mut els, 1, 0.0, 1.0, &|_, y, _, d| d < 4 && y < -0.6));
    let patches: std::collections::HashSet<u32> = leaves.iter().map(|&l| els[l as usize].patch).collect();
    assert_eq!(patches.len(), 2);
    for colors in [MeshColors::Flat, MeshColors::Smooth] {
        for view in SEAM_VIEWS {
            let (checked, cracks) = crack_pixels(&els, &leaves, colors, view);
            eprintln!("{view:?} {} cracks", cracks.len());
            assert!(checked > 20_000, "the patches fill much of the image: {checked}");
            assert!(
                cracks.is_empty(),
                "{colors:?}, view {view:?}: {} crack pixels along the seam, first {:?}",
                cracks.len(),
                &cracks[..cracks.len().min(8)]
            );
        }
    }
}

/// A box of five coloured faces seen from the open side: a golden image of the mesh pipeline.
#[test]
fn golden_box() {
    // Faces listed outward-wound; reversed so they face the inside, except the floor, left as
    // seen from its back (striped).
    let face = |id: u32, mut v: [DVec3; 4], b: Rgb| {
        if id != 0 {
            v.reverse();
        }
        let s = square(id, 0.0, b, false);
        ElementView { core: ElementCore { id, patch: id, vertices: v, radiosity: b, ..s.core }, ..s }
    };
    let (l, h) = (-1.0, 1.0);
    let p = DVec3::new;
    let els = vec![
        face(0, [p(l, l, l), p(h, l, l), p(h, l, h), p(l, l, h)], Rgb::splat(0.6)), // floor
        face(1, [p(l, h, l), p(l, h, h), p(h, h, h), p(h, h, l)], Rgb::splat(0.9)), // ceiling
        face(2, [p(l, l, l), p(l, h, l), p(h, h, l), p(h, l, l)], Rgb::splat(0.5)), // back
        face(3, [p(l, l, l), p(l, l, h), p(l, h, h), p(l, h, l)], Rgb::new(0.6, 0.1, 0.1)), // left
        face(4, [p(h, l, l), p(h, h, l), p(h, h, h), p(h, l, h)], Rgb::new(0.1, 0.6, 0.1)), // right
    ];
    let leaves: Vec<u32> = (0..5).collect();
    let g = Geometry {
        mesh: geometry::mesh(&els, &leaves, MeshColors::Flat, DVec3::ZERO),
        ..Geometry::default()
    };
    let mut u = uniforms(true, 0, 4);
    u.overlay |= OVERLAY_QUADTREE;
    let mut cam = camera();
    cam.distance = 3.5;
    cam.orbit(0.3, 0.2);
    u.view_proj = cam
        .view_proj(f64::from(W) / f64::from(H), DVec3::ZERO)
        .to_cols_array_2d()
        .map(|c| c.map(|x| x as f32));
    let img = draw(&g, u);
    // Golden image set on lavapipe (Mesa 22.3.6, Vulkan, device type Cpu); passes on llvmpipe
    // (WGPU_BACKEND=gl) too. The limits allow edge pixels to move by one position.
    let limits = Thresholds { mean: 2.0, p95: 1.0 };
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/snapshots");
    if let Err(e) = snapshot::check(&dir, "render_golden_box", &img, limits) {
        panic!("{e}");
    }
    assert!(
        img.distinct_colors() >= 6,
        "faces, back faces, highlight and edges all show: {}",
        img.distinct_colors()
    );
}

/// Draw `g` the way the native viewer does: straight into a host pass (egui's) with a
/// Depth32Float depth buffer cleared to 1, the viewport set to `rect` inside a larger target
/// cleared to `panel`. Returns the whole target.
fn draw_direct(
    g: &Geometry,
    u: Uniforms,
    format: wgpu::TextureFormat,
    target: [u32; 2],
    rect: [u32; 4],
    panel: wgpu::Color,
) -> RgbaImage {
    let rs = render_state().lock().unwrap();
    let mut r = SceneRenderer::new(&rs.device, format, Some(radlab::render::DEPTH_FORMAT));
    assert!(r.draws_direct());
    r.set_geometry(&rs.device, g);
    let frame = FrameParams { uniforms: u, size: [rect[2], rect[3]] };
    r.prepare_direct(&rs.queue, &frame);
    let texture = |format, usage| {
        rs.device.create_texture(&wgpu::TextureDescriptor {
            label: None,
            size: wgpu::Extent3d { width: target[0], height: target[1], depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
    };
    let color = texture(format, wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC);
    let depth = texture(radlab::render::DEPTH_FORMAT, wgpu::TextureUsages::RENDER_ATTACHMENT);
    let color_view = color.create_view(&wgpu::TextureViewDescriptor::default());
    let depth_view = depth.create_view(&wgpu::TextureViewDescriptor::default());
    let mut enc = rs.device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    {
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("host pass"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(panel), store: wgpu::StoreOp::Store },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        let [x, y, w, h] = rect.map(|v| v as f32);
        pass.set_viewport(x, y, w, h, 0.0, 1.0);
        pass.set_scissor_rect(rect[0], rect[1], rect[2], rect[3]);
        assert!(r.paint_direct(&mut pass));
    }
    rs.queue.submit([enc.finish()]);
    radlab::render::read_texture(&rs.device, &rs.queue, &color).unwrap()
}

#[test]
fn direct_drawing_into_the_host_pass_matches_the_offscreen_image() {
    // The golden box with every feature on (back faces, quadtree, selection, links, background)
    // drawn offscreen and, as the native viewer does, straight into a larger host pass at an
    // offset: the viewport must be the same image, and the host's pixels around it untouched.
    let (l, h) = (-1.0, 1.0);
    let p = DVec3::new;
    let face = |id: u32, mut v: [DVec3; 4], b: Rgb| {
        if id != 0 {
            v.reverse();
        }
        let s = square(id, 0.0, b, false);
        ElementView { core: ElementCore { id, patch: id, vertices: v, radiosity: b, ..s.core }, ..s }
    };
    let els = vec![
        face(0, [p(l, l, l), p(h, l, l), p(h, l, h), p(l, l, h)], Rgb::splat(0.6)),
        face(1, [p(l, h, l), p(l, h, h), p(h, h, h), p(h, h, l)], Rgb::splat(0.9)),
        face(2, [p(l, l, l), p(l, h, l), p(h, h, l), p(h, l, l)], Rgb::splat(0.5)),
        face(3, [p(l, l, l), p(l, l, h), p(l, h, h), p(l, h, l)], Rgb::new(0.6, 0.1, 0.1)),
    ];
    let leaves: Vec<u32> = (0..4).collect();
    let links = [
        LinkView { receiver: 0, source: 1, ff: 0.2, vis: 1.0 },
        LinkView { receiver: 3, source: 2, ff: 0.1, vis: 0.5 },
    ];
    let list = overlay::link_lines(&els, &links, &LinkFilter::default(), 0.8).lines;
    let g = Geometry {
        mesh: geometry::mesh(&els, &leaves, MeshColors::Smooth, DVec3::ZERO),
        links: geometry::lines(&list, DVec3::ZERO),
        links_xray: false,
        overlay: Vec::new(),
    };
    assert!(!g.links.is_empty());
    let mut u = uniforms(true, 0, 3);
    u.overlay |= OVERLAY_QUADTREE;
    u.background = [0.08, 0.08, 0.1, 1.0];
    let mut cam = camera();
    cam.distance = 3.5;
    cam.orbit(0.3, 0.2);
    u.view_proj = cam
        .view_proj(f64::from(W) / f64::from(H), DVec3::ZERO)
        .to_cols_array_2d()
        .map(|c| c.map(|x| x as f32));
    let offscreen = draw(&g, u);
    // The background shows (the box is open), so the background pass is exercised.
    let bg = [20, 20, 26];
    assert!(offscreen.pixels.chunks_exact(4).any(|q| close([q[0], q[1], q[2], q[3]], bg)));
    // Back-face stripes follow window pixels, 12 to a period along x + y: an offset that is a
    // multiple of it keeps them where the offscreen image has them; even, it keeps the 2×2 pixel
    // quads of the derivatives (quadtree edge widths) aligned too.
    let (x0, y0) = (14, 10);
    let panel = wgpu::Color { r: 0.2, g: 0.4, b: 0.6, a: 1.0 };
    for format in [wgpu::TextureFormat::Rgba8Unorm, wgpu::TextureFormat::Rgba8UnormSrgb] {
        let host = draw_direct(&g, u, format, [W + 30, H + 20], [x0, y0, W, H], panel);
        let viewport = host.crop(x0, y0, W, H);
        // An sRGB target stores the same display values after its decode-then-encode round trip
        // (±1 level), and the panel's linear clear colour encoded.
        let (stats, _) = snapshot::diff(&viewport, &offscreen).unwrap();
        if format.is_srgb() {
            // The link lines blend in linear light on an sRGB target (a few pixels differ more).
            assert!(
                stats.p95 <= f64::from(DIRECT_MAX_DIFF) && stats.mean <= SRGB_MEAN_DIFF,
                "{format:?}: {stats:?}"
            );
        } else {
            assert!(stats.max <= DIRECT_MAX_DIFF, "{format:?}: {stats:?}");
        }
        let want_panel: [u8; 3] = if format.is_srgb() { [124, 170, 203] } else { [51, 102, 153] };
        for (x, y) in [(0, 0), (x0 - 1, y0 + 5), (x0 + W, y0 + H - 1), (W + 29, H + 19)] {
            assert!(close(host.pixel(x, y), want_panel), "{format:?} ({x}, {y}): {:?}", host.pixel(x, y));
        }
    }
}

/// Direct and offscreen drawing run the same shaders on the same rasteriser: equal, up to one
/// level (interpolation rounding at another window offset; the sRGB target's decode-encode round
/// trip).
const DIRECT_MAX_DIFF: u8 = 1;
/// Mean difference allowed on an sRGB target, where the few link-line pixels blend differently.
const SRGB_MEAN_DIFF: f64 = 1.0;

#[test]
fn every_shader_parses_and_validates() {
    use wgpu::naga;
    for (name, src) in radlab::render::SHADERS {
        let module =
            naga::front::wgsl::parse_str(src).unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(src)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::default(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name}: {e:?}"));
        // The WGSL Uniforms struct has the Rust struct's size.
        if let Some((_, ty)) = module.types.iter().find(|(_, t)| t.name.as_deref() == Some("Uniforms")) {
            let layouter_size = match &ty.inner {
                naga::TypeInner::Struct { span, .. } => *span as usize,
                _ => 0,
            };
            assert_eq!(layouter_size, size_of::<Uniforms>(), "{name}: Uniforms size");
        }
    }
    // And the files on disk are the ones compiled in.
    for (name, src) in radlab::render::SHADERS {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders").join(name);
        assert_eq!(std::fs::read_to_string(&path).unwrap(), src, "{name}");
    }
}
