//! What every generated family is built from: a seeded planner that places primitive pieces
//! (axis-aligned boxes turned about +y, parallelograms) in a room, and the tessellation that
//! turns the pieces into patches the way radlab's own glTF loader reads them back from a file.
//!
//! ## How it works
//! ```text
//!  pieces ── tessellate ──► quads (a b c d), counter-clockwise from the front
//!                             │ vertices rounded to f32 (what a .glb stores)
//!                             ├─ the loader would merge its two triangles → one quad patch
//!                             └─ it would not (a turned face, no longer planar in f32)
//!                                                                   → two triangle patches
//! ```
//! Every quad is written as the triangles `(a b c)(a c d)`; the loader merges exactly those
//! pairs that [`crate::scene::gltf`]'s `mergeable` accepts, so a generated scene and the same
//! scene loaded from its file have the same patches, in the same order, with the same names
//! (`mesh/primitive/triangle`, the primitive counted within a run of one mesh name, a new one
//! at each change of material, as the writer groups them).

use crate::math::{DVec3, Pcg32, Rgb};
use crate::scene::Mat;
use crate::scene::gltf::mergeable;
pub(super) use crate::scene::pieces::{
    ALL, CEILING, Draw, METAL, NX, NY, NZ, PX, PY, PZ, Quads, SIDES, WALL, WOODS, Xf, mat,
};
use crate::scene::{Patch, Viewpoint};

// ---------------------------------------------------------------------------------------------
// Materials the families share besides [`crate::scene::pieces`]'s.

/// An emitter: white-ish exitance `e` (the unit of B), ρ 0.8.
pub(super) const fn light(name: &'static str, e: f64) -> Mat {
    Mat { name, rho: Rgb::new(0.8, 0.8, 0.8), emission: Rgb::new(e, 0.95 * e, 0.85 * e) }
}

pub(super) const FLOOR: Mat = mat("floor", 0.45, 0.34, 0.24);

// ---------------------------------------------------------------------------------------------
// Pieces

#[derive(Clone, Copy, Debug)]
pub(super) enum Shape {
    /// The parallelogram `o + a u + b v`, a, b ∈ [0, 1], facing u × v, cut into cells of side
    /// ≤ `cell` (`f64::INFINITY`: one cell).
    Rect { o: DVec3, u: DVec3, v: DVec3, cell: f64 },
    /// A parallelogram like `Rect` that takes whatever the triangle budget leaves (the floor): cut
    /// into one cell while counting, into [`Layout::fill`] cells when emitted.
    Fill { o: DVec3, u: DVec3, v: DVec3 },
    /// A box in the piece's frame, the faces in the mask, facing out, one quad each.
    Cuboid { lo: DVec3, hi: DVec3, faces: u8 },
}

#[derive(Clone, Debug)]
pub(super) struct Piece {
    pub(super) mesh: String,
    pub(super) mat: Mat,
    pub(super) xf: Xf,
    pub(super) shape: Shape,
}

/// Cells along a length (at least 1, at most `MAX_CELLS`).
fn cells(len: f64, cell: f64) -> usize {
    const MAX_CELLS: f64 = 4096.0;
    (len / cell).ceil().clamp(1.0, MAX_CELLS) as usize
}

fn shape_triangles(shape: &Shape) -> usize {
    match *shape {
        Shape::Rect { u, v, cell, .. } => 2 * cells(u.length(), cell) * cells(v.length(), cell),
        Shape::Fill { .. } => 2,
        Shape::Cuboid { faces, .. } => 2 * faces.count_ones() as usize,
    }
}

/// A planned scene: its pieces and the viewpoint it is best seen from.
pub(super) struct Layout {
    pub(super) pieces: Vec<Piece>,
    pub(super) camera: Viewpoint,
}

impl Layout {
    /// Triangles the layout has with each fill piece as one cell.
    pub(super) fn triangles(&self) -> usize {
        self.pieces.iter().map(|p| shape_triangles(&p.shape)).sum()
    }

    /// The cells (along u, along v) of a fill piece that make up `extra` more triangles than its
    /// one cell (at least 1 × 1; the cells as square as the piece allows).
    pub(super) fn fill(u: DVec3, v: DVec3, extra: usize) -> (usize, usize) {
        let quads = (1 + extra / 2) as f64;
        let (lu, lv) = (u.length(), v.length());
        let nu = ((quads * lu / lv).sqrt().round() as usize).max(1);
        let nv = ((quads / nu as f64).floor() as usize).max(1);
        (nu, nv)
    }

    /// The patches, with the fill pieces sharing `extra` triangles (the first ones one more cell
    /// row where it does not divide).
    pub(super) fn patches(&self, extra: usize) -> Vec<Patch> {
        let fills = self.pieces.iter().filter(|p| matches!(p.shape, Shape::Fill { .. })).count();
        let mut out = Tess::new(self.triangles() + extra);
        let mut fill = 0;
        for piece in &self.pieces {
            out.start(piece);
            match piece.shape {
                Shape::Rect { o, u, v, cell } => {
                    out.grid(o, u, v, cells(u.length(), cell), cells(v.length(), cell))
                }
                Shape::Fill { o, u, v } => {
                    let share = extra / fills.max(1) + usize::from(fill < extra % fills.max(1));
                    let (nu, nv) = Layout::fill(u, v, share);
                    out.grid(o, u, v, nu, nv);
                    fill += 1;
                }
                Shape::Cuboid { lo, hi, faces } => out.cuboid(lo, hi, faces),
            }
        }
        out.patches
    }
}

/// Emits patches with loader-compatible names.
struct Tess {
    patches: Vec<Patch>,
    xf: Xf,
    mat: Mat,
    mesh: String,
    primitive: usize,
    triangle: usize,
}

impl Tess {
    fn new(capacity: usize) -> Tess {
        Tess {
            patches: Vec::with_capacity(capacity),
            xf: Xf::at(DVec3::ZERO),
            mat: WALL,
            mesh: String::new(),
            primitive: 0,
            triangle: 0,
        }
    }

    /// A new piece: the writer starts a new mesh at a new mesh name and a new primitive at a new
    /// material within one.
    fn start(&mut self, piece: &Piece) {
        let same_material = |a: &Mat, b: &Mat| a.rho.0 == b.rho.0 && a.emission.0 == b.emission.0;
        if piece.mesh != self.mesh || self.patches.is_empty() {
            self.mesh.clone_from(&piece.mesh);
            self.primitive = 0;
            self.triangle = 0;
        } else if !same_material(&piece.mat, &self.mat) {
            self.primitive += 1;
            self.triangle = 0;
        }
        self.mat = piece.mat;
        self.xf = piece.xf;
    }

    fn push(&mut self, verts: Vec<DVec3>) {
        let m = self.mat;
        let name = format!("{}/{}/{}", self.mesh, self.primitive, self.triangle);
        self.triangle += verts.len() - 2;
        let patch = Patch::new(verts, m.rho, m.emission, self.mesh.as_str(), self.primitive, name, m.name)
            .expect("generated pieces have positive area by construction");
        self.patches.push(patch);
    }
}

impl Quads for Tess {
    /// The quad a b c d (counter-clockwise from the front), in the room, at f32 precision: one
    /// patch where the loader would merge its two triangles, else the two triangles.
    fn quad(&mut self, a: DVec3, b: DVec3, c: DVec3, d: DVec3) {
        let f32_round = |p: DVec3| p.as_vec3().as_dvec3();
        let [a, b, c, d] = [a, b, c, d].map(|p| f32_round(self.xf.apply(p)));
        let quad = vec![a, b, c, d];
        if mergeable(&quad) {
            self.push(quad);
        } else {
            self.push(vec![a, b, c]);
            self.push(vec![a, c, d]);
        }
    }

    /// One quad a face.
    fn face_cells(&self, _u: DVec3, _v: DVec3) -> (usize, usize) {
        (1, 1)
    }
}

// ---------------------------------------------------------------------------------------------
// The planner

/// A seeded planner: random draws and the pieces placed so far.
pub(super) struct Kit {
    rng: Pcg32,
    pub(super) pieces: Vec<Piece>,
}

impl Draw for Kit {
    fn rng(&mut self) -> &mut Pcg32 {
        &mut self.rng
    }
}

impl Kit {
    /// A planner for one family (`stream` keeps families with the same seed apart).
    pub(super) fn new(seed: u64, stream: u64) -> Kit {
        Kit { rng: Pcg32::new(seed, stream), pieces: Vec::new() }
    }
    pub(super) fn add(&mut self, mesh: &str, mat: Mat, xf: Xf, shape: Shape) {
        self.pieces.push(Piece { mesh: mesh.to_string(), mat, xf, shape });
    }
    pub(super) fn cuboid(&mut self, mesh: &str, mat: Mat, xf: Xf, lo: DVec3, hi: DVec3, faces: u8) {
        self.add(mesh, mat, xf, Shape::Cuboid { lo, hi, faces });
    }

    /// A closed room [0, w] × [0, h] × [0, d] facing in: the floor a fill piece, the walls and
    /// the ceiling cut into panels of side ≤ `panel`.
    pub(super) fn room(&mut self, w: f64, d: f64, h: f64, panel: f64) {
        let origin = Xf::at(DVec3::ZERO);
        let (x, y, z) = (DVec3::new(w, 0.0, 0.0), DVec3::new(0.0, h, 0.0), DVec3::new(0.0, 0.0, d));
        self.add("floor", FLOOR, origin, Shape::Fill { o: DVec3::ZERO, u: z, v: x });
        let rect = |o: DVec3, u: DVec3, v: DVec3| Shape::Rect { o, u, v, cell: panel };
        self.add("ceiling", CEILING, origin, rect(y, x, z));
        self.add("walls", WALL, origin, rect(DVec3::ZERO, x, y));
        self.add("walls", WALL, origin, rect(x + z, -x, y));
        self.add("walls", WALL, origin, rect(z, -z, y));
        self.add("walls", WALL, origin, rect(x, z, y));
    }

    /// A `w × d` light panel centred at (x, y, z), facing down (one-sided: its back faces the
    /// ceiling it hangs under).
    pub(super) fn panel(&mut self, mesh: &str, mat: Mat, centre: DVec3, w: f64, d: f64) {
        let o = centre - DVec3::new(w / 2.0, 0.0, d / 2.0);
        let shape =
            Shape::Rect { o, u: DVec3::new(w, 0.0, 0.0), v: DVec3::new(0.0, 0.0, d), cell: f64::INFINITY };
        self.add(mesh, mat, Xf::at(DVec3::ZERO), shape);
    }

    /// Light panels `panel{i}_{j}` of `size` (along x, along z) over the floor [0, w] × [0, d],
    /// in a grid of cells about `spacing` on a side, one centred in each, at height `y`.
    pub(super) fn panel_grid(
        &mut self,
        mat: Mat,
        (w, d): (f64, f64),
        spacing: f64,
        y: f64,
        size: (f64, f64),
    ) {
        let (nx, nz) = (((w / spacing).round() as usize).max(1), ((d / spacing).round() as usize).max(1));
        for i in 0..nx {
            for j in 0..nz {
                let at = DVec3::new(w * (i as f64 + 0.5) / nx as f64, y, d * (j as f64 + 0.5) / nz as f64);
                self.panel(&format!("panel{i}_{j}"), mat, at, size.0, size.1);
            }
        }
    }

    /// The layout of the pieces placed.
    pub(super) fn layout(self, camera: Viewpoint) -> Layout {
        Layout { pieces: self.pieces, camera }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_shape_counts_what_it_emits() {
        let shapes = [
            Shape::Rect { o: DVec3::ZERO, u: DVec3::X * 0.7, v: DVec3::Z * 0.3, cell: 0.1 },
            Shape::Cuboid { lo: DVec3::ZERO, hi: DVec3::new(0.3, 0.5, 0.2), faces: ALL ^ NY },
            Shape::Fill { o: DVec3::ZERO, u: DVec3::Z * 2.0, v: DVec3::X * 3.0 },
        ];
        for (yaw, shape) in [0.0, 0.4].into_iter().flat_map(|y| shapes.map(|s| (y, s))) {
            let piece = Piece { mesh: "m".into(), mat: WALL, xf: Xf::turned(yaw, DVec3::ONE), shape };
            let layout = Layout { pieces: vec![piece], camera: test_camera() };
            let tris: usize = layout.patches(0).iter().map(|p| p.vertices.len() - 2).sum();
            assert_eq!(tris, layout.triangles(), "{shape:?} turned by {yaw}");
        }
    }

    #[test]
    fn fill_takes_the_extra_triangles() {
        let (u, v) = (DVec3::Z * 2.0, DVec3::X * 3.0);
        for extra in [0, 1, 2, 10, 99, 1000, 12_345] {
            let (nu, nv) = Layout::fill(u, v, extra);
            let got = 2 * nu * nv;
            assert!(got <= extra + 2 && got + 2 * nu.max(nv) + 2 >= extra, "{extra}: {nu} x {nv}");
        }
    }

    /// A box faces out: each patch's normal points away from its centre.
    #[test]
    fn boxes_face_out() {
        let (lo, hi) = (DVec3::new(-0.1, 0.0, -0.2), DVec3::new(0.1, 0.3, 0.2));
        let xf = Xf::turned(0.7, DVec3::new(2.0, 0.0, 1.0));
        let piece = Piece { mesh: "b".into(), mat: WALL, xf, shape: Shape::Cuboid { lo, hi, faces: ALL } };
        let layout = Layout { pieces: vec![piece], camera: test_camera() };
        let centre = xf.apply(0.5 * (lo + hi));
        for p in layout.patches(0) {
            assert!(p.normal.dot(p.centroid - centre) > 0.0, "{} faces in", p.name);
        }
    }

    fn test_camera() -> Viewpoint {
        Viewpoint { eye: DVec3::ONE, target: DVec3::ZERO, up: DVec3::Y, fov_y_deg: 60.0 }
    }
}
