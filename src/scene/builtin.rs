//! Built-in scenes: geometry written in code ([`build`]), shipped as glTF under `assets/scenes/`
//! and loaded through the same glTF loader as any file ([`load`], source `builtin:NAME`).
//!
//! Every scene is y-up (the glTF convention), front faces by the right-hand rule, closed rooms
//! facing inward.
//!
//! - `cornell`: the Cornell box as published by the Cornell Program of Computer Graphics
//!   ("Cornell Box Data", <https://www.graphics.cornell.edu/online/box/data.html>): walls, short
//!   and tall block and ceiling light in its millimetre coordinates; camera at (278, 273, −800)
//!   looking down +z, 35 mm focal length on a 25 mm film (fov_y = 2·atan(12.5/35) = 39.31°).
//!   The ceiling is cut into four quads around the 130 × 105 light so the light sits *in* the
//!   ceiling without overlapping it. The published left wall is not planar (its vertices are off
//!   one plane by millimetres), so it is two triangles. Reflectances are the widely used RGB fits
//!   of the measured spectra from Benedikt Bitterli's "Rendering resources" Cornell box
//!   (white 0.725 0.71 0.68, red 0.63 0.065 0.05, green 0.14 0.45 0.091); the light's
//!   exitance is 10 × π × its radiance there (17, 12, 4) — π turns the radiance of a Lambertian
//!   emitter into exitance, 10 puts the walls' radiosity at O(1..10) — i.e. E = (534, 377, 126);
//!   the light's ρ is the published 0.78.
//! - `perpendicular`: two unit squares sharing an edge at 90° (the lecture's example); the
//!   vertical one emits E = 1; both ρ = 0.5.
//! - `parallel`: two directly opposed unit squares at distance 1; the top one emits E = 1; both ρ = 0.5.
//! - `furnace`: the closed unit cube facing inward, every face E = 1, ρ = 0.5: B = E/(1−ρ) = 2.
//! - `cube-one-light`: the closed unit cube facing inward; the top face emits E = 1 with ρ = 0
//!   (a pure emitter), the other five have ρ = 0.5.
//! - `table-room`: a 4 × 3 × 4 room with a table (top slab + four legs, all boxes) under a
//!   0.5 × 0.5 ceiling light set into the ceiling: sharp shadows under the table, the classic
//!   meshing example. Walls ρ = 0.6, floor 0.4, table 0.5, light E = 50 (B of the walls O(1)).
//! - `shadow-wide`, `shadow-narrow`: single-bounce scenes with an exact answer
//!   ([`crate::geometry::exact`]): one emitter with ρ = 0 facing down, black occluders (ρ = 0, E = 0),
//!   one 2 × 2 receiver on the floor (ρ = 0.5), nothing else, so the receiver's radiosity is
//!   ρ E F(x → visible part of the lamp) in closed form. `shadow-wide`: a 1 × 1 lamp (E = 10) at
//!   height 2 and two overlapping occluders at heights 1 and 0.6: penumbrae about a unit wide,
//!   overlapping shadows (inclusion–exclusion). `shadow-narrow`: a 0.2 × 0.2 lamp (E = 250) at
//!   height 2 and one occluder at height 0.25, near the receiver: a penumbra about 0.03 wide.
//! - `thin-pole`: a single-bounce scene with a thin occluder: the 2 × 2 receiver,
//!   a 0.06 × 0.06 lamp (E = 3 000) at height 2 over its centre, and a black pole 0.02 × 0.02 ×
//!   1.2 standing on the floor at x = 0.35 (four sides and a top). Its shadow is a dark streak
//!   from the foot outward, about 0.02–0.05 wide and 0.4 long, with narrow penumbrae: a
//!   feature one or two cells of a 64 × 64 grid wide that a mesh must place edges on to see.
//! - `splash_room`, `splash_largeroom`: the HSA91 / SPLASH-2 `radiosity` test rooms (216 and
//!   305 polygons) converted to glTF, shipped unchanged; their lamps have ρ = 1.0, clamped by the
//!   loader with a warning. They have no code version (`build` returns `None`).
//!
//! ## Regenerating the assets
//! `RADLAB_WRITE_ASSETS=1 cargo test --no-default-features --test builtin_scenes` rewrites
//! `assets/scenes/NAME.gltf` from [`build`] (run it once more without the variable: the first
//! run's other tests still see the previously embedded copies); without the variable that test
//! checks that every asset equals what the writer produces now.

use super::gltf::{LoadOptions, load_slice};
use super::{Mat, Patch, Scene, SceneError, Viewpoint};
use crate::math::{DVec3, Rgb, polygon_centroid, polygon_normal};
use std::path::Path;

/// Built-in scene names with a one-line description.
pub const BUILTINS: &[(&str, &str)] = &[
    ("cornell", "the published Cornell box: two blocks, coloured walls, light in the ceiling"),
    ("perpendicular", "two unit squares sharing an edge at 90 degrees, one emitting"),
    ("parallel", "two directly opposed unit squares at distance 1, one emitting"),
    ("furnace", "closed unit cube, every face E = 1 and rho = 0.5 (B = 2 everywhere)"),
    ("cube-one-light", "closed unit cube, top face emitting, rho = 0.5 elsewhere"),
    ("table-room", "a table under a small ceiling light in a room: sharp shadows"),
    ("shadow-wide", "single bounce with an exact answer: a large lamp, two occluders, broad penumbrae"),
    ("shadow-narrow", "single bounce with an exact answer: a small lamp, an occluder near the floor"),
    ("thin-pole", "single bounce with an exact answer: a small lamp, a thin pole standing on the floor"),
    ("splash_room", "the HSA91 / SPLASH-2 test room (216 polygons, lamps rho = 1 clamped)"),
    ("splash_largeroom", "the larger SPLASH-2 room (305 polygons, lamps rho = 1 clamped)"),
];

/// The glTF text of each built-in, embedded in the binary.
fn asset(name: &str) -> Option<&'static [u8]> {
    Some(match name {
        "cornell" => include_bytes!("../../assets/scenes/cornell.gltf"),
        "perpendicular" => include_bytes!("../../assets/scenes/perpendicular.gltf"),
        "parallel" => include_bytes!("../../assets/scenes/parallel.gltf"),
        "furnace" => include_bytes!("../../assets/scenes/furnace.gltf"),
        "cube-one-light" => include_bytes!("../../assets/scenes/cube-one-light.gltf"),
        "table-room" => include_bytes!("../../assets/scenes/table-room.gltf"),
        "shadow-wide" => include_bytes!("../../assets/scenes/shadow-wide.gltf"),
        "shadow-narrow" => include_bytes!("../../assets/scenes/shadow-narrow.gltf"),
        "thin-pole" => include_bytes!("../../assets/scenes/thin-pole.gltf"),
        "splash_room" => include_bytes!("../../assets/scenes/splash_room.gltf"),
        "splash_largeroom" => include_bytes!("../../assets/scenes/splash_largeroom.gltf"),
        _ => return None,
    })
}

/// Load a built-in scene by name from its embedded glTF (the same loader as files use), or
/// generate a furnished room (`furnished-SIZE[-sSEED]`, [`super::furnished`]) or a family's
/// scene (`FAMILY-SIZE[-sSEED]`, [`super::families`]).
pub fn load(name: &str) -> Result<Scene, SceneError> {
    if let Some(params) = super::furnished::parse(name) {
        return super::furnished::load(name, params);
    }
    if let Some(params) = super::families::parse(name) {
        return super::families::load(name, params);
    }
    let bytes = asset(name).ok_or_else(|| SceneError::UnknownBuiltin { name: name.into() })?;
    let label = format!("builtin:{name}");
    let mut scene = load_slice(bytes, None, Path::new(&label), &LoadOptions::default())?;
    scene.name = name.to_string();
    scene.source = label;
    Ok(scene)
}

/// Build a built-in scene's geometry in code (`None` for unknown names and for the SPLASH-2 rooms,
/// which exist only as files). Patch names follow the loader's `mesh/primitive/triangle` scheme,
/// so `load(name)` gives the same names, order and (to f32 precision) values.
#[must_use]
pub fn build(name: &str) -> Option<Scene> {
    let mut b = Builder { patches: Vec::new() };
    let camera = match name {
        "cornell" => cornell(&mut b),
        "perpendicular" => perpendicular(&mut b),
        "parallel" => parallel(&mut b),
        "furnace" => furnace(&mut b),
        "cube-one-light" => cube_one_light(&mut b),
        "table-room" => table_room(&mut b),
        "shadow-wide" => shadow_wide(&mut b),
        "shadow-narrow" => shadow_narrow(&mut b),
        "thin-pole" => thin_pole(&mut b),
        _ => return None,
    };
    let mut scene = Scene::new(name, format!("builtin:{name}"), b.patches);
    scene.camera = camera;
    Some(scene)
}

/// Accumulates patches with loader-compatible names.
struct Builder {
    patches: Vec<Patch>,
}

const fn grey(name: &'static str, rho: f64) -> Mat {
    Mat { name, rho: Rgb::splat(rho), emission: Rgb::ZERO }
}

impl Builder {
    /// One mesh (one primitive, one material): its polygons (3 or 4 vertices, already oriented).
    fn mesh(&mut self, mesh: &str, mat: Mat, polys: Vec<Vec<DVec3>>) {
        let mut triangle = 0;
        for verts in polys {
            let n = verts.len();
            let name = format!("{mesh}/0/{triangle}");
            let patch = Patch::new(verts, mat.rho, mat.emission, mesh, 0, name, mat.name)
                .expect("built-in geometry is valid by construction");
            self.patches.push(patch);
            triangle += n - 2;
        }
    }
}

fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

/// The polygon with its front facing `toward` (reversed if it faces away).
fn facing(mut verts: Vec<DVec3>, toward: DVec3) -> Vec<DVec3> {
    if polygon_normal(&verts).dot(toward - polygon_centroid(&verts)) < 0.0 {
        verts.reverse();
    }
    verts
}

/// The polygon with its front facing away from `from`.
fn away(verts: Vec<DVec3>, from: DVec3) -> Vec<DVec3> {
    let c = polygon_centroid(&verts);
    facing(verts, 2.0 * c - from)
}

/// A quad if its four vertices are planar (as `Scene::validate` requires), else two triangles
/// `(0 1 2)(0 2 3)`.
fn quad_or_tris(verts: Vec<DVec3>) -> Vec<Vec<DVec3>> {
    let n = polygon_normal(&verts);
    let c = polygon_centroid(&verts);
    let diam = verts.iter().flat_map(|a| verts.iter().map(move |b| a.distance(*b))).fold(0.0, f64::max);
    if verts.iter().all(|p| (n.dot(*p - c)).abs() <= super::PLANARITY_TOL * diam) {
        vec![verts]
    } else {
        vec![vec![verts[0], verts[1], verts[2]], vec![verts[0], verts[2], verts[3]]]
    }
}

/// The six faces of an axis-aligned box, in the order −x +x −y +y −z +z, facing outward
/// (`inward = false`) or inward.
fn box_faces(lo: DVec3, hi: DVec3, inward: bool) -> Vec<Vec<DVec3>> {
    let c = 0.5 * (lo + hi);
    let (a, b) = (lo, hi);
    let faces = vec![
        vec![v(a.x, a.y, a.z), v(a.x, a.y, b.z), v(a.x, b.y, b.z), v(a.x, b.y, a.z)],
        vec![v(b.x, a.y, a.z), v(b.x, b.y, a.z), v(b.x, b.y, b.z), v(b.x, a.y, b.z)],
        vec![v(a.x, a.y, a.z), v(b.x, a.y, a.z), v(b.x, a.y, b.z), v(a.x, a.y, b.z)],
        vec![v(a.x, b.y, a.z), v(a.x, b.y, b.z), v(b.x, b.y, b.z), v(b.x, b.y, a.z)],
        vec![v(a.x, a.y, a.z), v(a.x, b.y, a.z), v(b.x, b.y, a.z), v(b.x, a.y, a.z)],
        vec![v(a.x, a.y, b.z), v(b.x, a.y, b.z), v(b.x, b.y, b.z), v(a.x, b.y, b.z)],
    ];
    faces.into_iter().map(|f| if inward { facing(f, c) } else { away(f, c) }).collect()
}

/// The rectangle [x0,x1]×[z0,z1] at height y minus the hole [hx0,hx1]×[hz0,hz1], as four quads
/// (front strip, back strip, the two sides of the hole), facing `toward`.
fn plane_with_hole(y: f64, outer: [f64; 4], hole: [f64; 4], toward: DVec3) -> Vec<Vec<DVec3>> {
    let [x0, x1, z0, z1] = outer;
    let [hx0, hx1, hz0, hz1] = hole;
    let rect = |xa: f64, xb: f64, za: f64, zb: f64| {
        facing(vec![v(xa, y, za), v(xb, y, za), v(xb, y, zb), v(xa, y, zb)], toward)
    };
    vec![rect(x0, x1, z0, hz0), rect(x0, x1, hz1, z1), rect(x0, hx0, hz0, hz1), rect(hx1, x1, hz0, hz1)]
}

fn cornell(b: &mut Builder) -> Option<Viewpoint> {
    let white = Mat { name: "white", rho: Rgb::new(0.725, 0.71, 0.68), emission: Rgb::ZERO };
    let red = Mat { name: "red", rho: Rgb::new(0.63, 0.065, 0.05), emission: Rgb::ZERO };
    let green = Mat { name: "green", rho: Rgb::new(0.14, 0.45, 0.091), emission: Rgb::ZERO };
    let pi = std::f64::consts::PI;
    let light =
        Mat { name: "light", rho: Rgb::splat(0.78), emission: Rgb::new(170.0 * pi, 120.0 * pi, 40.0 * pi) };
    let inside = v(278.0, 274.4, 279.6);

    b.mesh(
        "floor",
        white,
        vec![facing(
            vec![v(552.8, 0.0, 0.0), v(0.0, 0.0, 0.0), v(0.0, 0.0, 559.2), v(549.6, 0.0, 559.2)],
            inside,
        )],
    );
    b.mesh(
        "ceiling",
        white,
        plane_with_hole(548.8, [0.0, 556.0, 0.0, 559.2], [213.0, 343.0, 227.0, 332.0], inside),
    );
    b.mesh(
        "light",
        light,
        vec![facing(
            vec![
                v(343.0, 548.8, 227.0),
                v(343.0, 548.8, 332.0),
                v(213.0, 548.8, 332.0),
                v(213.0, 548.8, 227.0),
            ],
            inside,
        )],
    );
    b.mesh(
        "back_wall",
        white,
        vec![facing(
            vec![v(549.6, 0.0, 559.2), v(0.0, 0.0, 559.2), v(0.0, 548.8, 559.2), v(556.0, 548.8, 559.2)],
            inside,
        )],
    );
    b.mesh(
        "right_wall",
        green,
        vec![facing(
            vec![v(0.0, 0.0, 559.2), v(0.0, 0.0, 0.0), v(0.0, 548.8, 0.0), v(0.0, 548.8, 559.2)],
            inside,
        )],
    );
    b.mesh(
        "left_wall",
        red,
        quad_or_tris(facing(
            vec![v(552.8, 0.0, 0.0), v(549.6, 0.0, 559.2), v(556.0, 548.8, 559.2), v(556.0, 548.8, 0.0)],
            inside,
        )),
    );

    let block = |top: [(f64, f64); 4], h: f64| -> Vec<Vec<DVec3>> {
        let cx = top.iter().map(|p| p.0).sum::<f64>() / 4.0;
        let cz = top.iter().map(|p| p.1).sum::<f64>() / 4.0;
        let centre = v(cx, 0.5 * h, cz);
        let mut faces = vec![away(top.iter().map(|&(x, z)| v(x, h, z)).collect(), centre)];
        for k in 0..4 {
            let (p, q) = (top[k], top[(k + 1) % 4]);
            faces
                .push(away(vec![v(p.0, 0.0, p.1), v(p.0, h, p.1), v(q.0, h, q.1), v(q.0, 0.0, q.1)], centre));
        }
        faces
    };
    b.mesh(
        "short_block",
        white,
        block([(130.0, 65.0), (82.0, 225.0), (240.0, 272.0), (290.0, 114.0)], 165.0),
    );
    b.mesh(
        "tall_block",
        white,
        block([(423.0, 247.0), (265.0, 296.0), (314.0, 456.0), (472.0, 406.0)], 330.0),
    );

    Some(Viewpoint {
        eye: v(278.0, 273.0, -800.0),
        target: v(278.0, 273.0, 0.0),
        up: DVec3::Y,
        fov_y_deg: 2.0 * (12.5f64 / 35.0).atan().to_degrees(),
    })
}

fn perpendicular(b: &mut Builder) -> Option<Viewpoint> {
    let floor = vec![v(0.0, 0.0, 0.0), v(0.0, 0.0, 1.0), v(1.0, 0.0, 1.0), v(1.0, 0.0, 0.0)];
    let wall = vec![v(0.0, 0.0, 0.0), v(0.0, 1.0, 0.0), v(0.0, 1.0, 1.0), v(0.0, 0.0, 1.0)];
    b.mesh("receiver", grey("grey", 0.5), vec![facing(floor, v(0.5, 1.0, 0.5))]);
    let emitter = Mat { name: "emitter", rho: Rgb::splat(0.5), emission: Rgb::ONE };
    b.mesh("emitter", emitter, vec![facing(wall, v(1.0, 0.5, 0.5))]);
    None
}

fn parallel(b: &mut Builder) -> Option<Viewpoint> {
    let sq = |y: f64| vec![v(0.0, y, 0.0), v(1.0, y, 0.0), v(1.0, y, 1.0), v(0.0, y, 1.0)];
    b.mesh("receiver", grey("grey", 0.5), vec![facing(sq(0.0), v(0.5, 1.0, 0.5))]);
    let emitter = Mat { name: "emitter", rho: Rgb::splat(0.5), emission: Rgb::ONE };
    b.mesh("emitter", emitter, vec![facing(sq(1.0), v(0.5, 0.0, 0.5))]);
    None
}

fn furnace(b: &mut Builder) -> Option<Viewpoint> {
    let m = Mat { name: "furnace", rho: Rgb::splat(0.5), emission: Rgb::ONE };
    b.mesh("cube", m, box_faces(DVec3::ZERO, DVec3::ONE, true));
    None
}

fn cube_one_light(b: &mut Builder) -> Option<Viewpoint> {
    let mut faces = box_faces(DVec3::ZERO, DVec3::ONE, true);
    let top = faces.remove(3);
    b.mesh("walls", grey("grey", 0.5), faces);
    b.mesh("light", Mat { name: "light", rho: Rgb::ZERO, emission: Rgb::ONE }, vec![top]);
    None
}

fn table_room(b: &mut Builder) -> Option<Viewpoint> {
    let (w, h, d) = (4.0, 3.0, 4.0);
    let inside = v(0.5 * w, 0.5 * h, 0.5 * d);
    let mut room = box_faces(DVec3::ZERO, v(w, h, d), true);
    let floor = room.remove(2);
    room.remove(2); // the ceiling, replaced by a ceiling with a hole for the light
    b.mesh("floor", grey("floor", 0.4), vec![floor]);
    b.mesh("walls", grey("wall", 0.6), room);
    let (l0, l1) = (1.75, 2.25);
    b.mesh("ceiling", grey("wall", 0.6), plane_with_hole(h, [0.0, w, 0.0, d], [l0, l1, l0, l1], inside));
    let light = Mat { name: "light", rho: Rgb::ZERO, emission: Rgb::splat(50.0) };
    b.mesh(
        "light",
        light,
        vec![facing(vec![v(l0, h, l0), v(l1, h, l0), v(l1, h, l1), v(l0, h, l1)], inside)],
    );

    let table = grey("table", 0.5);
    let (tx0, tx1, tz0, tz1) = (1.25, 2.75, 1.5, 2.5);
    let (leg_h, top_t, leg_w, inset) = (0.75, 0.05, 0.06, 0.05);
    b.mesh("table_top", table, box_faces(v(tx0, leg_h, tz0), v(tx1, leg_h + top_t, tz1), false));
    for (k, (x, z)) in [
        (tx0 + inset, tz0 + inset),
        (tx1 - inset - leg_w, tz0 + inset),
        (tx1 - inset - leg_w, tz1 - inset - leg_w),
        (tx0 + inset, tz1 - inset - leg_w),
    ]
    .into_iter()
    .enumerate()
    {
        // The four sides only: the bottom rests on the floor and the top touches the table top.
        let mut faces = box_faces(v(x, 0.0, z), v(x + leg_w, leg_h, z + leg_w), false);
        faces.drain(2..4);
        b.mesh(&format!("leg{k}"), table, faces);
    }
    Some(Viewpoint { eye: v(3.7, 2.2, 3.7), target: v(2.0, 0.6, 2.0), up: DVec3::Y, fov_y_deg: 60.0 })
}

/// The horizontal rectangle [x0,x1]×[z0,z1] at height y, facing up (`up`) or down.
fn level_rect(y: f64, [x0, x1, z0, z1]: [f64; 4], up: bool) -> Vec<DVec3> {
    let r = vec![v(x0, y, z0), v(x1, y, z0), v(x1, y, z1), v(x0, y, z1)];
    facing(r, v(0.5 * (x0 + x1), if up { y + 1.0 } else { y - 1.0 }, 0.5 * (z0 + z1)))
}

/// A single-bounce scene: a 2 × 2 floor receiver (ρ = 0.5), a lamp facing down (ρ = 0), black
/// occluders (listed as rectangles at a height).
fn single_bounce(
    b: &mut Builder,
    lamp: (f64, [f64; 4], f64),
    occluders: &[(f64, [f64; 4])],
) -> Option<Viewpoint> {
    b.mesh("receiver", grey("grey", 0.5), vec![level_rect(0.0, [-1.0, 1.0, -1.0, 1.0], true)]);
    let (y, rect, e) = lamp;
    let light = Mat { name: "light", rho: Rgb::ZERO, emission: Rgb::splat(e) };
    b.mesh("light", light, vec![level_rect(y, rect, false)]);
    let black = grey("black", 0.0);
    if !occluders.is_empty() {
        b.mesh("occluders", black, occluders.iter().map(|&(y, r)| level_rect(y, r, true)).collect());
    }
    Some(Viewpoint { eye: v(2.2, 2.4, 2.8), target: v(0.0, 0.4, 0.0), up: DVec3::Y, fov_y_deg: 50.0 })
}

fn shadow_wide(b: &mut Builder) -> Option<Viewpoint> {
    single_bounce(
        b,
        (2.0, [-0.5, 0.5, -0.5, 0.5], 10.0),
        &[(1.0, [-0.6, 0.2, -0.4, 0.4]), (0.6, [0.0, 0.7, -0.2, 0.6])],
    )
}

fn thin_pole(b: &mut Builder) -> Option<Viewpoint> {
    let camera = single_bounce(b, (2.0, [-0.03, 0.03, -0.03, 0.03], 3000.0), &[]);
    let (x, z, w, h) = (0.34, -0.01, 0.02, 1.2);
    let mut pole = box_faces(v(x, 0.0, z), v(x + w, h, z + w), false);
    pole.remove(2); // the bottom rests on the floor
    b.mesh("pole", grey("black", 0.0), pole);
    camera
}

fn shadow_narrow(b: &mut Builder) -> Option<Viewpoint> {
    single_bounce(b, (2.0, [-0.1, 0.1, -0.1, 0.1], 250.0), &[(0.25, [-0.4, 0.2, -0.2, 0.4])])
}
