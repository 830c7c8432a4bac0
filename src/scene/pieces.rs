//! What the generated interiors (the furnished room, [`super::furnished`], and the scene
//! families, [`super::families`]) are built from: seeded draws, pieces placed in an object's
//! frame turned about +y, the materials of common interior surfaces, boxes and parallelograms
//! cut into quads, and rows of books on a board.
//!
//! A piece's frame: x to the object's right, y up, −z its front. A box face of sides u, v faces
//! u × v; a quad a b c d is counter-clockwise seen from its front.

use crate::math::{DVec3, Pcg32, Rgb};
use crate::scene::Mat;

/// Faces of a box, in its own frame: −x +x −y +y −z +z.
pub(super) const NX: u8 = 1;
pub(super) const PX: u8 = 2;
pub(super) const NY: u8 = 4;
pub(super) const PY: u8 = 8;
pub(super) const NZ: u8 = 16;
pub(super) const PZ: u8 = 32;
pub(super) const ALL: u8 = 63;
/// The four vertical faces.
pub(super) const SIDES: u8 = NX | PX | NZ | PZ;

// ---------------------------------------------------------------------------------------------
// Materials (ρ of common interior surfaces, 0.2–0.8)

pub(super) const fn mat(name: &'static str, r: f64, g: f64, b: f64) -> Mat {
    Mat { name, rho: Rgb::new(r, g, b), emission: Rgb::ZERO }
}

pub(super) const WALL: Mat = mat("wall", 0.75, 0.72, 0.66);
pub(super) const CEILING: Mat = mat("ceiling", 0.8, 0.8, 0.78);
pub(super) const WOODS: [Mat; 3] = [
    mat("wood_light", 0.62, 0.48, 0.32),
    mat("wood_dark", 0.38, 0.26, 0.2),
    mat("wood_white", 0.78, 0.76, 0.72),
];
pub(super) const BOOKS: [Mat; 6] = [
    mat("book_red", 0.65, 0.2, 0.2),
    mat("book_blue", 0.2, 0.28, 0.55),
    mat("book_green", 0.22, 0.45, 0.28),
    mat("book_cream", 0.78, 0.74, 0.62),
    mat("book_black", 0.2, 0.2, 0.22),
    mat("book_orange", 0.75, 0.42, 0.2),
];
pub(super) const METAL: Mat = mat("metal", 0.3, 0.3, 0.32);

// ---------------------------------------------------------------------------------------------
// Frames

/// A turn by `yaw` about +y, then a translation: piece frame → room.
#[derive(Clone, Copy, Debug)]
pub(super) struct Xf {
    cos: f64,
    sin: f64,
    at: DVec3,
}

impl Xf {
    pub(super) fn at(at: DVec3) -> Xf {
        Xf { cos: 1.0, sin: 0.0, at }
    }
    /// Turned by `yaw` radians (counter-clockwise seen from above) about +y, then moved to `at`.
    /// Quarter turns are exact (cos and sin within 1e-15 of 0 or ±1 are snapped), so their
    /// faces stay axis-aligned.
    pub(super) fn turned(yaw: f64, at: DVec3) -> Xf {
        let snap = |c: f64| if (c - c.round()).abs() < 1e-15 { c.round() } else { c };
        Xf { cos: snap(yaw.cos()), sin: snap(yaw.sin()), at }
    }
    /// The object's −z (its front) turned to point along `front` (horizontal).
    pub(super) fn facing(at: DVec3, front: DVec3) -> Xf {
        let f = DVec3::new(front.x, 0.0, front.z).normalize();
        Xf { cos: -f.z, sin: -f.x, at }
    }
    /// A turn by `yaw` radians about +y, no translation (not snapped).
    pub(super) fn turn(yaw: f64) -> Xf {
        Xf { cos: yaw.cos(), sin: yaw.sin(), at: DVec3::ZERO }
    }
    /// The same turn, moved to `at`.
    pub(super) fn moved_to(self, at: DVec3) -> Xf {
        Xf { at, ..self }
    }
    pub(super) fn rotate(&self, p: DVec3) -> DVec3 {
        DVec3::new(self.cos * p.x + self.sin * p.z, p.y, -self.sin * p.x + self.cos * p.z)
    }
    pub(super) fn apply(&self, p: DVec3) -> DVec3 {
        self.rotate(p) + self.at
    }
}

// ---------------------------------------------------------------------------------------------
// Seeded draws

/// A planner's random draws, all from one PCG32 stream.
pub(super) trait Draw {
    fn rng(&mut self) -> &mut Pcg32;

    /// Uniform in [lo, hi).
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.rng().next_f64()
    }
    /// True with probability `p`.
    fn chance(&mut self, p: f64) -> bool {
        self.rng().next_f64() < p
    }
    /// One of 0..n (0 when n is 0).
    fn below(&mut self, n: usize) -> usize {
        (self.rng().next_u32() as usize) % n.max(1)
    }
    /// One of `from` (not empty).
    fn pick<T: Copy>(&mut self, from: &[T]) -> T {
        from[self.below(from.len())]
    }
}

/// How a row of books fills a board: the share of its width drawn from `fill`, book
/// thicknesses from `thickness`, `margin` clear at each end, and a wider gap after a book with
/// probability `gap_chance`.
pub(super) struct BookRow {
    pub(super) fill: (f64, f64),
    pub(super) margin: f64,
    pub(super) thickness: (f64, f64),
    pub(super) gap_chance: f64,
}

impl BookRow {
    /// The books standing on a board from x = −`inner` to `inner` at height `y`, left to right,
    /// 2 mm apart or now and then 2–8 cm, at most `max_h` tall, their backs at z = `back`:
    /// each box's (lo, hi) and cover.
    pub(super) fn books(
        &self,
        draw: &mut impl Draw,
        inner: f64,
        y: f64,
        max_h: f64,
        back: f64,
    ) -> Vec<(DVec3, DVec3, Mat)> {
        let fill = draw.uniform(self.fill.0, self.fill.1);
        let mut x = -inner + self.margin;
        let mut out = Vec::new();
        while x < -inner + 2.0 * inner * fill {
            let bw = draw.uniform(self.thickness.0, self.thickness.1);
            let bh = max_h.min(draw.uniform(0.17, 0.3));
            let bd = draw.uniform(0.14, 0.24);
            if x + bw > inner - self.margin {
                break;
            }
            let book = draw.pick(&BOOKS);
            out.push((DVec3::new(x, y, back - bd), DVec3::new(x + bw, y + bh, back), book));
            x += bw + if draw.chance(self.gap_chance) { draw.uniform(0.02, 0.08) } else { 0.002 };
        }
        out
    }
}

// ---------------------------------------------------------------------------------------------
// Tessellation

/// Turns parallelograms and boxes into quads; what a quad becomes is the implementor's.
pub(super) trait Quads {
    /// The quad a b c d (counter-clockwise from the front), in the current piece's frame.
    fn quad(&mut self, a: DVec3, b: DVec3, c: DVec3, d: DVec3);

    /// The cells (along u, along v) a box face of sides `u`, `v` is cut into.
    fn face_cells(&self, u: DVec3, v: DVec3) -> (usize, usize);

    /// The parallelogram o + a u + b v cut into nu × nv cells, facing u × v.
    fn grid(&mut self, o: DVec3, u: DVec3, v: DVec3, nu: usize, nv: usize) {
        let at = |i: usize, j: usize| o + u * (i as f64 / nu as f64) + v * (j as f64 / nv as f64);
        for i in 0..nu {
            for j in 0..nv {
                self.quad(at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            }
        }
    }

    /// The faces of the box [lo, hi] in the mask, facing out, each cut as [`Quads::face_cells`] says.
    fn cuboid(&mut self, lo: DVec3, hi: DVec3, faces: u8) {
        let d = hi - lo;
        let (x, y, z) = (DVec3::new(d.x, 0.0, 0.0), DVec3::new(0.0, d.y, 0.0), DVec3::new(0.0, 0.0, d.z));
        // (corner, u, v) with u × v pointing out of the box, in the mask's bit order.
        let sides = [(lo, z, y), (lo + x, y, z), (lo, x, z), (lo + y, z, x), (lo, y, x), (lo + z, x, y)];
        for (bit, (o, u, v)) in sides.into_iter().enumerate() {
            if faces & (1 << bit) != 0 {
                let (nu, nv) = self.face_cells(u, v);
                self.grid(o, u, v, nu, nv);
            }
        }
    }
}
