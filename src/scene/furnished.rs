//! Generated furnished rooms: the scenes clustering is measured on.
//!
//! `builtin:furnished-SIZE[-sSEED]`: a room of `SIZE` triangles (within 2 %), made
//! the way rooms modelled in Blender are: tables with chairs, desks with desk lamps, lounge
//! corners, bookcases full of books, floor lamps, ceiling light panels, all of many small
//! triangles. `SIZE` is a number of triangles with an optional `k` (10³) or `m` (10⁶) suffix,
//! from [`MIN_TRIANGLES`] to [`MAX_TRIANGLES`]; `SEED` (default 0) picks another room of the
//! same size. The same name always gives the same scene, patch for patch. Nothing is read or
//! written: the scene is generated in memory (its time and size: docs/scale.md#the-rooms).
//!
//! ## How it works
//! Two phases, so that the triangle count can be aimed at without changing the room:
//!
//! ```text
//!  plan (seeded):  bays × (dining set | desk | lounge) + bookcases along the walls
//!                  + floor lamps in the corners + a light panel above each bay
//!                  → a list of primitive pieces (cuboid, cylinder, frustum, rectangle)
//!  tessellate(h):  every piece cut into cells of side ≤ h (cylinders into ⌈2πr/h⌉ segments)
//!                  count(h) is non-increasing in h: bisect log h until count(h) ≈ SIZE
//!                  (a miss over 2 %: the coarser step, and floor boards cut into planks)
//! ```
//!
//! The bays (3.2 m squares) are a ⌈√B⌉ × ⌈B/⌈√B⌉⌉ grid, B = round((SIZE/6000)^0.75): one bay
//! up to 10 k, 2 × 2 at 30 k, 3 × 3 at 100 k, 7 × 7 at 1 M, with a 0.7 m strip along the walls
//! for bookcases (rooms under 8 000 triangles have fewer); the tessellation makes up the rest.
//! The room shell is tiled at fixed sizes (0.5 m floor boards in two woods, 1 m wall and
//! ceiling panels) whatever SIZE is. Every patch is a triangle (a cut quad's two halves),
//! one-sided, facing out of its piece; the room faces inward. Reflectances are 0.2–0.8 (woods,
//! fabrics, book covers, metal); the emitters are the ceiling panels (facing down) and the lamp
//! shades (glowing outward, lined with a non-emitting inner layer 2 mm in).

use super::Mat;
use super::pieces::{
    ALL, BOOKS, BookRow, CEILING, Draw, METAL, NX, NY, NZ, PX, PY, PZ, Quads, SIDES, WALL, WOODS, Xf, mat,
};
use super::{Patch, Scene, SceneError, Viewpoint};
use crate::math::{DVec3, Pcg32, Rgb};
use std::f64::consts::PI;

/// The smallest room: one bay with its lamps, shell and (below 8 000 triangles, fewer)
/// bookcases at the coarsest tessellation is about 1 300 triangles.
pub const MIN_TRIANGLES: usize = 2_000;
/// The largest room (the loader's default triangle cap).
pub const MAX_TRIANGLES: usize = 5_000_000;

/// The sizes listed by `radlab scenes`: name and target triangle count.
pub const SIZES: &[(&str, usize)] = &[
    ("furnished-10k", 10_000),
    ("furnished-30k", 30_000),
    ("furnished-100k", 100_000),
    ("furnished-1m", 1_000_000),
];

/// What a `furnished-…` name asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FurnishedParams {
    /// Target number of triangles (= patches).
    pub triangles: usize,
    /// Picks the room's layout, sizes and colours.
    pub seed: u64,
}

/// Parse `furnished-SIZE[-sSEED]` (the part after `builtin:`). `None` if the name is not a
/// furnished room; `Some(Err(cause))` if it is one with a bad size or seed.
#[must_use]
pub fn parse(name: &str) -> Option<Result<FurnishedParams, String>> {
    let rest = name.strip_prefix("furnished-")?;
    Some(parse_rest(rest))
}

fn parse_rest(rest: &str) -> Result<FurnishedParams, String> {
    let (triangles, seed) = parse_size_seed(rest, MIN_TRIANGLES, MAX_TRIANGLES)?;
    Ok(FurnishedParams { triangles, seed })
}

/// Parse `SIZE[-sSEED]`: a triangle count with an optional `k` (10³) or `m` (10⁶) suffix in
/// `min..=max`, and a seed (default 0).
pub(super) fn parse_size_seed(rest: &str, min: usize, max: usize) -> Result<(usize, u64), String> {
    let (size, seed) = match rest.split_once("-s") {
        Some((size, seed)) => {
            let seed = seed.parse::<u64>().map_err(|_| format!("seed {seed:?} is not a whole number"))?;
            (size, seed)
        }
        None => (rest, 0),
    };
    Ok((parse_triangles(size, min, max)?, seed))
}

/// Parse a triangle count such as `10k`, `30000` or `1m` in `min..=max`.
pub(super) fn parse_triangles(size: &str, min: usize, max: usize) -> Result<usize, String> {
    let (digits, scale) = match size.as_bytes().last() {
        Some(b'k' | b'K') => (&size[..size.len() - 1], 1_000),
        Some(b'm' | b'M') => (&size[..size.len() - 1], 1_000_000),
        _ => (size, 1),
    };
    let bad = || format!("size {size:?} is not a triangle count such as 10k, 30000 or 1m");
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return Err(bad());
    }
    let triangles = digits.parse::<usize>().ok().and_then(|n| n.checked_mul(scale)).ok_or_else(bad)?;
    if !(min..=max).contains(&triangles) {
        return Err(format!("{triangles} triangles is outside the generator's range {min}..={max}"));
    }
    Ok(triangles)
}

/// Load `builtin:NAME` for a furnished-room name: parse it and generate the room.
pub fn load(name: &str, params: Result<FurnishedParams, String>) -> Result<Scene, SceneError> {
    load_generated(name, params, generate)
}

/// The scene `generate` makes from the parsed `params`, named `name` and sourced
/// `builtin:NAME` (a generator's own name spells the size out); a parse error as
/// [`SceneError::BadGenerated`].
pub(super) fn load_generated<P>(
    name: &str,
    params: Result<P, String>,
    generate: impl FnOnce(P) -> Scene,
) -> Result<Scene, SceneError> {
    let params = params.map_err(|cause| SceneError::BadGenerated { name: name.into(), cause })?;
    let mut scene = generate(params);
    scene.name = name.to_string();
    scene.source = format!("builtin:{name}");
    Ok(scene)
}

/// The room for these parameters (deterministic).
#[must_use]
pub fn generate(params: FurnishedParams) -> Scene {
    let mut plan = plan(params);
    let h = cell_size(&mut plan, params.triangles);
    let mut tess = Tess::new(h, Some(Vec::with_capacity(plan.count(h))));
    for piece in &plan.pieces {
        tess.piece(piece);
    }
    let name = format!("furnished-{}-s{}", params.triangles, params.seed);
    let mut scene = Scene::new(name.clone(), format!("builtin:{name}"), tess.out.unwrap_or_default());
    scene.camera = Some(plan.camera);
    scene
}

/// A miss of the target by more than 1/`CLOSE_ENOUGH` is made up with floor planks.
const CLOSE_ENOUGH: usize = 50;

/// The cell size whose triangle count is nearest `target` (bisection on log h; the count is a
/// non-increasing step function of h). Where many like pieces cross a step together the
/// nearest count can miss by several per cent: then the coarser step is taken and the floor
/// boards are cut into planks for the difference.
fn cell_size(plan: &mut Plan, target: usize) -> f64 {
    let (mut fine, mut coarse) = (1e-3f64, 10.0f64);
    if plan.count(coarse) >= target {
        return coarse;
    }
    if plan.count(fine) <= target {
        return fine;
    }
    for _ in 0..50 {
        let mid = (fine * coarse).sqrt();
        if plan.count(mid) >= target {
            fine = mid;
        } else {
            coarse = mid;
        }
    }
    let miss = |plan: &Plan, h: f64| plan.count(h).abs_diff(target);
    let nearest = if miss(plan, fine) <= miss(plan, coarse) { fine } else { coarse };
    if miss(plan, nearest) * CLOSE_ENOUGH > target {
        let short = target - plan.count(coarse);
        plan.add_planks(short / 2);
        return coarse;
    }
    nearest
}

// ---------------------------------------------------------------------------------------------
// Materials

const FLOOR: [Mat; 2] = [mat("floor_oak", 0.5, 0.36, 0.23), mat("floor_walnut", 0.42, 0.3, 0.2)];
const FABRICS: [Mat; 5] = [
    mat("fabric_red", 0.6, 0.22, 0.2),
    mat("fabric_blue", 0.22, 0.3, 0.6),
    mat("fabric_green", 0.25, 0.5, 0.3),
    mat("fabric_grey", 0.5, 0.5, 0.5),
    mat("fabric_mustard", 0.7, 0.55, 0.2),
];
const CERAMIC: Mat = mat("ceramic", 0.8, 0.8, 0.78);
const SHADE_INSIDE: Mat = mat("shade_inside", 0.7, 0.65, 0.55);
const PANEL_LIGHT: Mat =
    Mat { name: "panel_light", rho: Rgb::new(0.8, 0.8, 0.8), emission: Rgb::new(30.0, 28.5, 25.5) };
const SHADE_LIGHT: Mat =
    Mat { name: "shade_light", rho: Rgb::new(0.7, 0.65, 0.55), emission: Rgb::new(12.0, 10.2, 7.2) };

// ---------------------------------------------------------------------------------------------
// The plan: primitive pieces, each in its object's frame

#[derive(Clone, Copy, Debug)]
enum Shape {
    /// The parallelogram `o + a u + b v`, a, b ∈ [0, 1], facing u × v, cut into `cells` of side
    /// ≤ that length (`None`: ≤ h).
    Rect { o: DVec3, u: DVec3, v: DVec3, cell: Option<f64> },
    /// The parallelogram `o + a u + b v` cut into `n` planks across `v` (a floor board).
    Planks { o: DVec3, u: DVec3, v: DVec3, n: usize },
    /// Axis-aligned box, the faces in the mask, facing out.
    Cuboid { lo: DVec3, hi: DVec3, faces: u8 },
    /// Vertical cylinder from `base` up `len`, facing out, with optional bottom/top discs.
    Cylinder { base: DVec3, r: f64, len: f64, bottom: bool, top: bool },
    /// Vertical truncated cone from radius `r0` at `base` to `r1` at `base + len·y`, facing out
    /// (`outward`) or in.
    Frustum { base: DVec3, r0: f64, r1: f64, len: f64, outward: bool },
}

struct Piece {
    mesh: String,
    mat: Mat,
    xf: Xf,
    shape: Shape,
}

struct Plan {
    pieces: Vec<Piece>,
    camera: Viewpoint,
}

impl Plan {
    /// Triangles at cell size `h` (what tessellation would emit, without emitting it).
    fn count(&self, h: f64) -> usize {
        self.pieces.iter().map(|p| shape_triangles(&p.shape, h)).sum()
    }

    /// Cut the floor boards into `extra` more planks in all (two triangles each), spread
    /// evenly, the first boards one more.
    fn add_planks(&mut self, extra: usize) {
        let boards = self.pieces.iter().filter(|p| matches!(p.shape, Shape::Planks { .. })).count();
        if boards == 0 {
            return;
        }
        let (each, first) = (extra / boards, extra % boards);
        let planks = self.pieces.iter_mut().filter_map(|p| match &mut p.shape {
            Shape::Planks { n, .. } => Some(n),
            _ => None,
        });
        for (k, n) in planks.enumerate() {
            *n += each + usize::from(k < first);
        }
    }
}

/// Cells along a length (at least 1, at most `MAX_CELLS`).
fn cells(len: f64, h: f64) -> usize {
    const MAX_CELLS: f64 = 400.0;
    (len / h).ceil().clamp(1.0, MAX_CELLS) as usize
}

/// Segments around a circle of radius `r`.
fn segments(r: f64, h: f64) -> usize {
    (2.0 * PI * r / h).ceil().clamp(6.0, 64.0) as usize
}

/// Triangles in a disc of radius `r` cut into `k` segments: a fan in the middle, quads outside.
fn disc_triangles(r: f64, k: usize, h: f64) -> usize {
    k * (2 * cells(r, h) - 1)
}

fn shape_triangles(shape: &Shape, h: f64) -> usize {
    match *shape {
        Shape::Rect { u, v, cell, .. } => {
            let c = cell.unwrap_or(h);
            2 * cells(u.length(), c) * cells(v.length(), c)
        }
        Shape::Planks { n, .. } => 2 * n,
        Shape::Cuboid { lo, hi, faces } => {
            let d = hi - lo;
            let (x, y, z) = (cells(d.x, h), cells(d.y, h), cells(d.z, h));
            let per_face = [y * z, y * z, x * z, x * z, x * y, x * y];
            (0..6).filter(|i| faces & (1 << i) != 0).map(|i| 2 * per_face[i]).sum()
        }
        Shape::Cylinder { r, len, bottom, top, .. } => {
            let k = segments(r, h);
            2 * k * cells(len, h) + (usize::from(bottom) + usize::from(top)) * disc_triangles(r, k, h)
        }
        Shape::Frustum { r0, r1, len, .. } => {
            let k = segments(r0.max(r1), h);
            2 * k * cells(len.hypot(r1 - r0), h)
        }
    }
}

/// The seeded layout.
struct Planner {
    rng: Pcg32,
    pieces: Vec<Piece>,
}

impl Draw for Planner {
    fn rng(&mut self) -> &mut Pcg32 {
        &mut self.rng
    }
}

impl Planner {
    fn add(&mut self, mesh: &str, mat: Mat, xf: Xf, shape: Shape) {
        self.pieces.push(Piece { mesh: mesh.to_string(), mat, xf, shape });
    }
    fn cuboid(&mut self, mesh: &str, mat: Mat, xf: Xf, lo: DVec3, hi: DVec3, faces: u8) {
        self.add(mesh, mat, xf, Shape::Cuboid { lo, hi, faces });
    }

    /// A table centred on the origin of `xf`, top `w × d` at height `top_y`; returns its top height.
    fn table(&mut self, mesh: &str, xf: Xf, w: f64, d: f64, top_y: f64, wood: Mat, round_legs: bool) -> f64 {
        let t = 0.04;
        self.cuboid(
            mesh,
            wood,
            xf,
            DVec3::new(-w / 2.0, top_y - t, -d / 2.0),
            DVec3::new(w / 2.0, top_y, d / 2.0),
            ALL,
        );
        let inset = 0.08;
        for (sx, sz) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            let (x, z) = (sx * (w / 2.0 - inset), sz * (d / 2.0 - inset));
            if round_legs {
                let shape = Shape::Cylinder {
                    base: DVec3::new(x, 0.0, z),
                    r: 0.03,
                    len: top_y - t,
                    bottom: false,
                    top: false,
                };
                self.add(mesh, wood, xf, shape);
            } else {
                let s = 0.025;
                self.cuboid(
                    mesh,
                    wood,
                    xf,
                    DVec3::new(x - s, 0.0, z - s),
                    DVec3::new(x + s, top_y - t, z + s),
                    SIDES,
                );
            }
        }
        top_y
    }

    /// A chair whose sitter faces the object's −z; the seat centred on the origin of `xf`.
    fn chair(&mut self, mesh: &str, xf: Xf, frame: Mat, seat: Mat) {
        let (w, d) = (self.uniform(0.42, 0.48), self.uniform(0.4, 0.45));
        let (sy, st, leg) = (0.45, 0.04, 0.018);
        self.cuboid(
            mesh,
            seat,
            xf,
            DVec3::new(-w / 2.0, sy - st, -d / 2.0),
            DVec3::new(w / 2.0, sy, d / 2.0),
            ALL,
        );
        for (sx, sz) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            let (x, z) = (sx * (w / 2.0 - leg - 0.01), sz * (d / 2.0 - leg - 0.01));
            self.cuboid(
                mesh,
                frame,
                xf,
                DVec3::new(x - leg, 0.0, z - leg),
                DVec3::new(x + leg, sy - st, z + leg),
                SIDES,
            );
        }
        // The back: two posts rising from the back legs' line and horizontal slats between them.
        let back_h = self.uniform(0.38, 0.5);
        let zb = d / 2.0 - leg - 0.01;
        for sx in [-1.0, 1.0] {
            let x = sx * (w / 2.0 - leg - 0.01);
            let lo = DVec3::new(x - leg, sy, zb - leg);
            self.cuboid(mesh, frame, xf, lo, DVec3::new(x + leg, sy + back_h, zb + leg), SIDES | PY);
        }
        let slats = 2 + (self.rng.next_u32() % 3) as usize;
        let x0 = -(w / 2.0 - 2.0 * leg - 0.01);
        for k in 0..slats {
            let y = sy + back_h * (0.35 + 0.6 * (k as f64 + 0.5) / slats as f64);
            let lo = DVec3::new(x0, y - 0.025, zb - 0.012);
            self.cuboid(mesh, frame, xf, lo, DVec3::new(-x0, y + 0.025, zb + 0.012), NY | PY | NZ | PZ);
        }
    }

    /// A lamp: a base disc, a pole and a glowing shade (outer emitter + inner lining).
    fn lamp(&mut self, mesh: &str, xf: Xf, base_r: f64, pole_h: f64, shade: (f64, f64, f64), stand: Mat) {
        let (r0, r1, len) = shade;
        self.add(
            mesh,
            stand,
            xf,
            Shape::Cylinder { base: DVec3::ZERO, r: base_r, len: 0.03, bottom: false, top: true },
        );
        let pole = Shape::Cylinder {
            base: DVec3::new(0.0, 0.03, 0.0),
            r: 0.012,
            len: pole_h,
            bottom: false,
            top: true,
        };
        self.add(mesh, stand, xf, pole);
        let base = DVec3::new(0.0, 0.03 + pole_h - 0.6 * len, 0.0);
        let shade_mesh = format!("{mesh}_shade");
        self.add(&shade_mesh, SHADE_LIGHT, xf, Shape::Frustum { base, r0, r1, len, outward: true });
        let lining = Shape::Frustum { base, r0: r0 - 0.002, r1: r1 - 0.002, len, outward: false };
        self.add(&format!("{mesh}_lining"), SHADE_INSIDE, xf, lining);
    }

    /// Small things on a table top at height `y` within `w × d`: cups, bowls, books.
    fn tabletop(&mut self, mesh: &str, xf: Xf, y: f64, w: f64, d: f64) {
        let n = self.rng.next_u32() % 4;
        for k in 0..n {
            let x = self.uniform(-0.4, 0.4) * w;
            let z = self.uniform(-0.35, 0.35) * d;
            let m = format!("{mesh}_item{k}");
            if self.chance(0.6) {
                let r = self.uniform(0.035, 0.09);
                let len = self.uniform(0.05, 0.11);
                self.add(
                    &m,
                    CERAMIC,
                    xf,
                    Shape::Cylinder { base: DVec3::new(x, y, z), r, len, bottom: false, top: true },
                );
            } else {
                let book = self.pick(&BOOKS);
                let (bw, bd, bh) =
                    (self.uniform(0.15, 0.22), self.uniform(0.2, 0.28), self.uniform(0.02, 0.05));
                self.cuboid(
                    &m,
                    book,
                    xf,
                    DVec3::new(x - bw / 2.0, y, z - bd / 2.0),
                    DVec3::new(x + bw / 2.0, y + bh, z + bd / 2.0),
                    SIDES | PY,
                );
            }
        }
    }

    /// A dining table with chairs around it, centred in the bay (turned 0° or 90°).
    fn dining(&mut self, bay: &str, centre: DVec3) {
        let wood = self.pick(&WOODS);
        let fabric = self.pick(&FABRICS);
        let (w, d) = (self.uniform(1.4, 1.9), self.uniform(0.8, 1.0));
        let xf = if self.chance(0.5) { Xf::at(centre) } else { Xf::facing(centre, DVec3::X) };
        let round = self.chance(0.5);
        let top = self.table(&format!("{bay}_table"), xf, w, d, 0.74, wood, round);
        self.tabletop(&format!("{bay}_table"), xf, top, w, d);
        // In the table's frame: chairs along the long sides (two each on a long table), one at
        // each end now and then, each facing the table.
        let per_side = if w >= 1.6 { 2 } else { 1 };
        let mut seats = Vec::new();
        for side in [-1.0, 1.0] {
            for k in 0..per_side {
                let along = (k as f64 + 0.5) / per_side as f64 - 0.5;
                seats
                    .push((DVec3::new(along * w, 0.0, side * (d / 2.0 + 0.28)), DVec3::new(0.0, 0.0, -side)));
            }
            if self.chance(0.7) {
                seats.push((DVec3::new(side * (w / 2.0 + 0.28), 0.0, 0.0), DVec3::new(-side, 0.0, 0.0)));
            }
        }
        for (k, (at, front)) in seats.into_iter().enumerate() {
            // A chair pulled out a little and turned a little.
            let jitter = DVec3::new(self.uniform(-0.03, 0.03), 0.0, self.uniform(-0.03, 0.03));
            let turn = Xf::turn(self.uniform(-0.15, 0.15));
            let front = xf.rotate(turn.rotate(front));
            self.chair(&format!("{bay}_chair{k}"), Xf::facing(xf.apply(at + jitter), front), wood, fabric);
        }
    }

    /// A desk with a chair, a desk lamp and a few books.
    fn desk(&mut self, bay: &str, centre: DVec3) {
        let wood = self.pick(&WOODS);
        let fabric = self.pick(&FABRICS);
        let front = self.pick(&[DVec3::X, -DVec3::X, DVec3::Z, -DVec3::Z]);
        let xf = Xf::facing(centre, front);
        let (w, d, top_y) = (self.uniform(1.1, 1.5), self.uniform(0.6, 0.75), 0.74);
        let mesh = format!("{bay}_desk");
        self.cuboid(
            &mesh,
            wood,
            xf,
            DVec3::new(-w / 2.0, top_y - 0.03, -d / 2.0),
            DVec3::new(w / 2.0, top_y, d / 2.0),
            ALL,
        );
        // Two side panels, a drawer block under the right half.
        for sx in [-1.0, 1.0] {
            let x = sx * (w / 2.0 - 0.02);
            self.cuboid(
                &mesh,
                wood,
                xf,
                DVec3::new(x - 0.02, 0.0, -d / 2.0 + 0.02),
                DVec3::new(x + 0.02, top_y - 0.03, d / 2.0 - 0.02),
                SIDES,
            );
        }
        let lo = DVec3::new(w / 2.0 - 0.45, 0.35, -d / 2.0 + 0.04);
        self.cuboid(
            &mesh,
            wood,
            xf,
            lo,
            DVec3::new(w / 2.0 - 0.04, top_y - 0.03, d / 2.0 - 0.04),
            NX | NY | NZ | PZ,
        );
        // The lamp at the back left corner, the books on the right.
        let lamp_xf = xf.moved_to(xf.apply(DVec3::new(-w / 2.0 + 0.2, top_y, d / 2.0 - 0.18)));
        self.lamp(&format!("{bay}_desklamp"), lamp_xf, 0.08, 0.35, (0.12, 0.08, 0.14), METAL);
        self.tabletop(&mesh, xf.moved_to(xf.apply(DVec3::new(0.15 * w, 0.0, 0.0))), top_y, 0.5 * w, d);
        // The chair in front (the desk's −z side), facing the desk.
        let chair_at = xf.apply(DVec3::new(0.0, 0.0, -d / 2.0 - 0.3));
        self.chair(&format!("{bay}_chair"), Xf::facing(chair_at, -front), wood, fabric);
    }

    /// Two armchairs at a low table, a floor lamp beside them.
    fn lounge(&mut self, bay: &str, centre: DVec3) {
        let wood = self.pick(&WOODS);
        let fabric = self.pick(&FABRICS);
        let (w, d) = (self.uniform(0.8, 1.1), self.uniform(0.5, 0.6));
        let top = self.table(&format!("{bay}_lowtable"), Xf::at(centre), w, d, 0.42, wood, false);
        self.tabletop(&format!("{bay}_lowtable"), Xf::at(centre), top, w, d);
        for (k, side) in [-1.0, 1.0].into_iter().enumerate() {
            let at = centre + DVec3::new(0.0, 0.0, side * (d / 2.0 + 0.55));
            let xf = Xf::facing(at, DVec3::new(0.0, 0.0, -side));
            let mesh = format!("{bay}_armchair{k}");
            let (aw, ad) = (0.8, 0.75);
            self.cuboid(
                &mesh,
                fabric,
                xf,
                DVec3::new(-aw / 2.0 + 0.12, 0.0, -ad / 2.0),
                DVec3::new(aw / 2.0 - 0.12, 0.42, ad / 2.0 - 0.15),
                SIDES | PY,
            );
            self.cuboid(
                &mesh,
                fabric,
                xf,
                DVec3::new(-aw / 2.0, 0.0, ad / 2.0 - 0.15),
                DVec3::new(aw / 2.0, 0.85, ad / 2.0),
                ALL ^ NY,
            );
            for sx in [-1.0, 1.0] {
                let x = sx * (aw / 2.0 - 0.06);
                self.cuboid(
                    &mesh,
                    fabric,
                    xf,
                    DVec3::new(x - 0.06, 0.0, -ad / 2.0),
                    DVec3::new(x + 0.06, 0.6, ad / 2.0 - 0.15),
                    ALL ^ NY,
                );
            }
        }
        let lamp_at = centre + DVec3::new(w / 2.0 + 0.45, 0.0, 0.0);
        self.lamp(&format!("{bay}_floorlamp"), Xf::at(lamp_at), 0.15, 1.5, (0.22, 0.15, 0.26), METAL);
    }

    /// A bookcase against a wall: the object's −z faces into the room, its back at local z = d/2.
    fn bookcase(&mut self, mesh: &str, xf: Xf) {
        let wood = self.pick(&WOODS);
        let (w, h, d, t) = (0.9, self.uniform(1.8, 2.2), 0.34, 0.02);
        let shelves = 4 + (self.rng.next_u32() % 2) as usize;
        // Sides, top, back panel; then the shelf boards (the bottom board rests on the floor).
        for sx in [-1.0, 1.0] {
            let x = sx * (w / 2.0 - t / 2.0);
            self.cuboid(
                mesh,
                wood,
                xf,
                DVec3::new(x - t / 2.0, 0.0, -d / 2.0),
                DVec3::new(x + t / 2.0, h, d / 2.0),
                ALL ^ NY,
            );
        }
        let inner = w / 2.0 - t;
        self.cuboid(
            mesh,
            wood,
            xf,
            DVec3::new(-inner, h - t, -d / 2.0),
            DVec3::new(inner, h, d / 2.0),
            ALL ^ NX ^ PX,
        );
        let back = Shape::Rect {
            o: DVec3::new(inner, 0.0, d / 2.0 - t),
            u: DVec3::new(-2.0 * inner, 0.0, 0.0),
            v: DVec3::new(0.0, h - t, 0.0),
            cell: None,
        };
        self.add(mesh, wood, xf, back);
        let pitch = (h - t) / shelves as f64;
        for s in 0..shelves {
            let y = s as f64 * pitch;
            let faces = if s == 0 { PY | NZ } else { NY | PY | NZ };
            self.cuboid(
                mesh,
                wood,
                xf,
                DVec3::new(-inner, y, -d / 2.0),
                DVec3::new(inner, y + t, d / 2.0 - t),
                faces,
            );
        }
        // Books standing on each board, left to right, a gap now and then.
        let row = BookRow { fill: (0.4, 0.95), margin: 0.01, thickness: (0.018, 0.05), gap_chance: 0.1 };
        for s in 0..shelves {
            let books = row.books(self, inner, s as f64 * pitch + t, pitch - t - 0.03, d / 2.0 - t - 0.005);
            for (k, (lo, hi, book)) in books.into_iter().enumerate() {
                self.cuboid(&format!("{mesh}_s{s}b{k}"), book, xf, lo, hi, ALL ^ NY);
            }
        }
    }
}

/// Bays, their furniture, the bookcases, lamps and light panels, the room shell.
fn plan(params: FurnishedParams) -> Plan {
    const BAY: f64 = 3.2;
    const STRIP: f64 = 0.7;
    const HEIGHT: f64 = 2.8;
    let bays = ((params.triangles as f64 / 6000.0).powf(0.75).round() as usize).max(1);
    let nx = (bays as f64).sqrt().ceil() as usize;
    let nz = bays.div_ceil(nx);
    let (w, d) = (nx as f64 * BAY + 2.0 * STRIP, nz as f64 * BAY + 2.0 * STRIP);
    let mut p = Planner { rng: Pcg32::new(params.seed, 0x5EED_F00D), pieces: Vec::new() };

    shell(&mut p, w, d, HEIGHT);
    for i in 0..nx {
        for j in 0..nz {
            let centre = DVec3::new(STRIP + (i as f64 + 0.5) * BAY, 0.0, STRIP + (j as f64 + 0.5) * BAY);
            let bay = format!("bay{i}_{j}");
            match p.rng.next_u32() % 10 {
                0..=5 => p.dining(&bay, centre),
                6..=7 => p.desk(&bay, centre),
                _ => p.lounge(&bay, centre),
            }
            // A light panel in the ceiling above the bay, 2 cm below it, facing down.
            let (pw, pd) = (0.6, 1.2);
            let o = DVec3::new(centre.x - pw / 2.0, HEIGHT - 0.02, centre.z - pd / 2.0);
            let panel =
                Shape::Rect { o, u: DVec3::new(pw, 0.0, 0.0), v: DVec3::new(0.0, 0.0, pd), cell: None };
            p.add(&format!("{bay}_panel"), PANEL_LIGHT, Xf::at(DVec3::ZERO), panel);
        }
    }
    // Bookcases along the walls, in 1 m slots clear of the corners; each wall's front faces in.
    // A bookcase is about 700 triangles at the coarsest: small rooms get fewer.
    let case_chance = 0.45 * (params.triangles as f64 / 8000.0).min(1.0).powi(2);
    let walls = [
        (DVec3::new(0.0, 0.0, d), DVec3::X, w, -DVec3::Z),
        (DVec3::new(w, 0.0, 0.0), -DVec3::X, w, DVec3::Z),
        (DVec3::ZERO, DVec3::Z, d, DVec3::X),
        (DVec3::new(w, 0.0, d), -DVec3::Z, d, -DVec3::X),
    ];
    let mut case = 0;
    for (start, along, len, inward) in walls {
        let slots = ((len - 1.6) / 1.0).floor().max(0.0) as usize;
        for s in 0..slots {
            if p.chance(case_chance) {
                let at = start + along * (0.8 + s as f64 + 0.5) + inward * (0.17 + 0.01);
                p.bookcase(&format!("case{case}"), Xf::facing(at, inward));
                case += 1;
            }
        }
    }
    // Floor lamps in the corners.
    for (k, (x, z)) in
        [(0.4, 0.4), (w - 0.4, 0.4), (w - 0.4, d - 0.4), (0.4, d - 0.4)].into_iter().enumerate()
    {
        p.lamp(
            &format!("cornerlamp{k}"),
            Xf::at(DVec3::new(x, 0.0, z)),
            0.15,
            1.5,
            (0.22, 0.15, 0.26),
            METAL,
        );
    }
    let camera = Viewpoint {
        eye: DVec3::new(0.9, 2.3, 0.9),
        target: DVec3::new(0.5 * w, 0.7, 0.5 * d),
        up: DVec3::Y,
        fov_y_deg: 65.0,
    };
    Plan { pieces: p.pieces, camera }
}

/// The room's floor (0.5 m boards in two woods, alternating), walls and ceiling (1 m panels),
/// all facing in.
fn shell(p: &mut Planner, w: f64, d: f64, h: f64) {
    let origin = Xf::at(DVec3::ZERO);
    // Boards of 0.5 m, the last in each row shorter and ending at the wall (a room 11 m wide,
    // 11.000000000000002 in floating point, has 22 boards, not a 23rd of width 2e-15).
    let board = 0.5;
    let count = |len: f64| ((len / board - 1e-6).ceil() as usize).max(1);
    let edge = |k: usize, n: usize, len: f64| if k == n { len } else { k as f64 * board };
    let (nx, nz) = (count(w), count(d));
    for i in 0..nx {
        for j in 0..nz {
            let (x0, z0) = (i as f64 * board, j as f64 * board);
            let (x1, z1) = (edge(i + 1, nx, w), edge(j + 1, nz, d));
            let o = DVec3::new(x0, 0.0, z0);
            let planks =
                Shape::Planks { o, u: DVec3::new(0.0, 0.0, z1 - z0), v: DVec3::new(x1 - x0, 0.0, 0.0), n: 1 };
            p.add("floor", FLOOR[(i + j) % 2], origin, planks);
        }
    }
    let panel = Some(1.0);
    let rect = |o: DVec3, u: DVec3, v: DVec3| Shape::Rect { o, u, v, cell: panel };
    p.add(
        "ceiling",
        CEILING,
        origin,
        rect(DVec3::new(0.0, h, 0.0), DVec3::new(w, 0.0, 0.0), DVec3::new(0.0, 0.0, d)),
    );
    let up = DVec3::new(0.0, h, 0.0);
    p.add("walls", WALL, origin, rect(DVec3::ZERO, DVec3::new(w, 0.0, 0.0), up));
    p.add("walls", WALL, origin, rect(DVec3::new(w, 0.0, d), DVec3::new(-w, 0.0, 0.0), up));
    p.add("walls", WALL, origin, rect(DVec3::new(0.0, 0.0, d), DVec3::new(0.0, 0.0, -d), up));
    p.add("walls", WALL, origin, rect(DVec3::new(w, 0.0, 0.0), DVec3::new(0.0, 0.0, d), up));
}

// ---------------------------------------------------------------------------------------------
// Tessellation

/// Emits (or, without an output, only counts) the triangles of pieces at cell size `h`.
struct Tess {
    h: f64,
    out: Option<Vec<Patch>>,
    mesh: String,
    mat: Mat,
    xf: Xf,
    triangle: usize,
}

impl Tess {
    fn new(h: f64, out: Option<Vec<Patch>>) -> Tess {
        Tess { h, out, mesh: String::new(), mat: WALL, xf: Xf::at(DVec3::ZERO), triangle: 0 }
    }

    fn piece(&mut self, piece: &Piece) {
        if piece.mesh != self.mesh {
            self.mesh.clone_from(&piece.mesh);
            self.triangle = 0;
        }
        self.mat = piece.mat;
        self.xf = piece.xf;
        let h = self.h;
        match piece.shape {
            Shape::Rect { o, u, v, cell } => {
                let cell = cell.unwrap_or(h);
                self.grid(o, u, v, cells(u.length(), cell), cells(v.length(), cell));
            }
            Shape::Planks { o, u, v, n } => self.grid(o, u, v, 1, n),
            Shape::Cuboid { lo, hi, faces } => self.cuboid(lo, hi, faces),
            Shape::Cylinder { base, r, len, bottom, top } => {
                let k = segments(r, h);
                self.band(base, r, r, len, k, true);
                if bottom {
                    self.disc(base, r, k, false);
                }
                if top {
                    self.disc(base + DVec3::new(0.0, len, 0.0), r, k, true);
                }
            }
            Shape::Frustum { base, r0, r1, len, outward } => {
                self.band(base, r0, r1, len, segments(r0.max(r1), h), outward);
            }
        }
    }

    fn tri(&mut self, a: DVec3, b: DVec3, c: DVec3) {
        let Some(out) = self.out.as_mut() else { return };
        let verts = vec![self.xf.apply(a), self.xf.apply(b), self.xf.apply(c)];
        let name = format!("{}/0/{}", self.mesh, self.triangle);
        let m = self.mat;
        let patch = Patch::new(verts, m.rho, m.emission, self.mesh.as_str(), 0, name, m.name)
            .expect("generated triangles have positive area by construction");
        out.push(patch);
        self.triangle += 1;
    }

    /// The side of a vertical (truncated) cone, `k` segments, rows of height ≤ h along its slant.
    fn band(&mut self, base: DVec3, r0: f64, r1: f64, len: f64, k: usize, outward: bool) {
        let rows = cells(len.hypot(r1 - r0), self.h);
        let at = |i: usize, j: usize| {
            let t = j as f64 / rows as f64;
            let a = 2.0 * PI * (i % k) as f64 / k as f64;
            let r = r0 + (r1 - r0) * t;
            base + DVec3::new(r * a.cos(), len * t, -r * a.sin())
        };
        for i in 0..k {
            for j in 0..rows {
                // Counter-clockwise seen from outside: around +y by the right-hand rule, then up.
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                if outward {
                    self.quad(a, b, c, d);
                } else {
                    self.quad(a, d, c, b);
                }
            }
        }
    }

    /// A horizontal disc at `centre`, facing up or down: a fan of `k` triangles in the middle,
    /// rings of `k` quads around it.
    fn disc(&mut self, centre: DVec3, r: f64, k: usize, up: bool) {
        let rings = cells(r, self.h);
        let at = |i: usize, ring: usize| {
            let a = 2.0 * PI * (i % k) as f64 / k as f64;
            let rr = r * ring as f64 / rings as f64;
            centre + DVec3::new(rr * a.cos(), 0.0, -rr * a.sin())
        };
        for i in 0..k {
            let (a, b) = (at(i, 1), at(i + 1, 1));
            if up {
                self.tri(centre, a, b)
            } else {
                self.tri(centre, b, a)
            }
            for ring in 1..rings {
                let (a, b, c, d) = (at(i, ring), at(i, ring + 1), at(i + 1, ring + 1), at(i + 1, ring));
                if up { self.quad(a, b, c, d) } else { self.quad(a, d, c, b) }
            }
        }
    }
}

impl Quads for Tess {
    /// The quad a b c d as two triangles.
    fn quad(&mut self, a: DVec3, b: DVec3, c: DVec3, d: DVec3) {
        self.tri(a, b, c);
        self.tri(a, c, d);
    }

    /// Cells of side ≤ h.
    fn face_cells(&self, u: DVec3, v: DVec3) -> (usize, usize) {
        (cells(u.length(), self.h), cells(v.length(), self.h))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse() {
        let p = |s: &str| parse(s).map(|r| r.map(|f| (f.triangles, f.seed)));
        assert_eq!(p("furnished-10k"), Some(Ok((10_000, 0))));
        assert_eq!(p("furnished-1m-s7"), Some(Ok((1_000_000, 7))));
        assert_eq!(p("furnished-25000"), Some(Ok((25_000, 0))));
        assert_eq!(p("cornell"), None);
        for bad in [
            "furnished-",
            "furnished-10q",
            "furnished-k",
            "furnished-1k",
            "furnished-10k-sx",
            "furnished-99999999999999999999m",
        ] {
            assert!(matches!(p(bad), Some(Err(_))), "{bad}");
        }
    }

    #[test]
    fn every_shape_counts_what_it_emits() {
        let shapes = [
            Shape::Rect { o: DVec3::ZERO, u: DVec3::X * 0.7, v: DVec3::Z * 0.3, cell: None },
            Shape::Planks { o: DVec3::ZERO, u: DVec3::Z * 0.5, v: DVec3::X * 0.5, n: 7 },
            Shape::Cuboid { lo: DVec3::ZERO, hi: DVec3::new(0.3, 0.5, 0.2), faces: ALL ^ NY },
            Shape::Cylinder { base: DVec3::ZERO, r: 0.2, len: 0.5, bottom: true, top: true },
            Shape::Frustum { base: DVec3::ZERO, r0: 0.2, r1: 0.1, len: 0.3, outward: false },
        ];
        for h in [0.01, 0.07, 1.0] {
            for shape in shapes {
                let mut t = Tess::new(h, Some(Vec::new()));
                t.piece(&Piece { mesh: "m".into(), mat: WALL, xf: Xf::at(DVec3::ZERO), shape });
                assert_eq!(t.out.unwrap().len(), shape_triangles(&shape, h), "{shape:?} at h = {h}");
            }
        }
    }

    /// Each closed piece faces out: its patches' normals point away from its centre.
    #[test]
    fn closed_shapes_face_out() {
        let c = DVec3::new(0.15, 0.25, 0.1);
        for (shape, centre) in [
            (Shape::Cuboid { lo: DVec3::ZERO, hi: 2.0 * c, faces: ALL }, c),
            (
                Shape::Cylinder { base: DVec3::ZERO, r: 0.2, len: 0.5, bottom: true, top: true },
                DVec3::new(0.0, 0.25, 0.0),
            ),
        ] {
            let mut t = Tess::new(0.05, Some(Vec::new()));
            t.piece(&Piece { mesh: "m".into(), mat: WALL, xf: Xf::at(DVec3::ZERO), shape });
            for p in t.out.unwrap() {
                assert!(p.normal.dot(p.centroid - centre) > 0.0, "{shape:?}: {} faces in", p.name);
            }
        }
    }
}
