//! `chairs`: a lecture room — rows of chairs on thin legs facing a board and a desk, under a
//! grid of ceiling panels.
//!
//! ```text
//!   ┌────────── board ──────────┐  z = 0 (the front wall)
//!   │          ▄▄desk▄▄          │
//!   │  h h h h h h   h h h h h h │  rows 0.95 m apart, chairs 0.6 m apart, an aisle in the
//!   │  h h h h h h   h h h h h h │  middle of rows of six or more
//!   └────────────────────────────┘
//! ```
//! k chairs fill rows of ⌈√(1.5 k)⌉; each is pulled a little out of line and turned by up to
//! ±0.08 rad. A chair is a seat, four legs 22 mm square, two back posts and a back rest: 72
//! triangles. Frames are metal or wood, seats fabric. Panels 0.6 × 0.6 (E = 30) on a 2.4 m grid.

use super::kit::{ALL, Draw, Kit, Layout, METAL, NY, NZ, PY, PZ, SIDES, WOODS, Xf, light, mat};
use crate::math::DVec3;
use crate::scene::Mat;
use crate::scene::Viewpoint;

const PITCH_X: f64 = 0.6;
const PITCH_Z: f64 = 0.95;
const AISLE: f64 = 1.2;
const MARGIN: f64 = 1.2;
const FRONT: f64 = 3.0;
const HEIGHT: f64 = 3.0;
const PANEL: Mat = light("panel_light", 30.0);

/// The room for `k` chairs.
pub(super) fn layout(k: usize, seed: u64) -> Layout {
    /// The seats' fabrics.
    const FABRICS: [Mat; 4] = [
        mat("fabric_red", 0.6, 0.22, 0.2),
        mat("fabric_blue", 0.22, 0.3, 0.6),
        mat("fabric_green", 0.25, 0.5, 0.3),
        mat("fabric_grey", 0.5, 0.5, 0.5),
    ];
    let mut kit = Kit::new(seed, 0xC4A1_125E);
    let cols = ((1.5 * k as f64).sqrt().ceil() as usize).max(1);
    let rows = k.div_ceil(cols);
    let aisle = if cols >= 6 { AISLE } else { 0.0 };
    let w = cols as f64 * PITCH_X + aisle + 2.0 * MARGIN;
    let d = FRONT + rows as f64 * PITCH_Z + MARGIN;
    kit.room(w, d, HEIGHT, 1.0);
    kit.panel_grid(PANEL, (w, d), 2.4, HEIGHT - 0.02, (0.6, 0.6));
    // The board on the front wall and a desk before it.
    let board = (w - 2.0).clamp(0.8, 4.0);
    let (bx0, bx1) = (w / 2.0 - board / 2.0, w / 2.0 + board / 2.0);
    let white = mat("board_white", 0.82, 0.82, 0.8);
    let origin = Xf::at(DVec3::ZERO);
    kit.cuboid("board", white, origin, DVec3::new(bx0, 0.9, 0.0), DVec3::new(bx1, 2.1, 0.02), ALL ^ NZ);
    let wood = kit.pick(&WOODS);
    let desk = Xf::at(DVec3::new(w / 2.0, 0.0, 1.4));
    kit.cuboid("desk", wood, desk, DVec3::new(-0.7, 0.72, -0.35), DVec3::new(0.7, 0.75, 0.35), ALL);
    for sx in [-1.0, 1.0] {
        let x = sx * 0.66;
        kit.cuboid(
            "desk",
            wood,
            desk,
            DVec3::new(x - 0.02, 0.0, -0.33),
            DVec3::new(x + 0.02, 0.72, 0.33),
            SIDES,
        );
    }

    let frame = if kit.chance(0.5) { METAL } else { kit.pick(&WOODS) };
    let fabric = kit.pick(&FABRICS);
    for c in 0..k {
        let (row, col) = (c / cols, c % cols);
        let gap = if 2 * col >= cols { aisle } else { 0.0 };
        let x = MARGIN + (col as f64 + 0.5) * PITCH_X + gap + kit.uniform(-0.02, 0.02);
        let z = FRONT + (row as f64 + 0.5) * PITCH_Z + kit.uniform(-0.03, 0.03);
        let xf = Xf::turned(kit.uniform(-0.08, 0.08), DVec3::new(x, 0.0, z));
        chair(&mut kit, &format!("row{row}"), xf, frame, fabric);
    }
    kit.layout(Viewpoint {
        eye: DVec3::new(w / 2.0, 2.2, d - 0.3),
        target: DVec3::new(w / 2.0, 0.8, 0.0),
        up: DVec3::Y,
        fov_y_deg: 65.0,
    })
}

/// A chair centred on the origin of `xf`, its sitter facing −z.
fn chair(kit: &mut Kit, mesh: &str, xf: Xf, frame: Mat, seat: Mat) {
    let (w, d) = (kit.uniform(0.44, 0.48), 0.42);
    let (sy, st, leg) = (0.46, 0.03, 0.011);
    let (hw, hd) = (w / 2.0, d / 2.0);
    kit.cuboid(mesh, seat, xf, DVec3::new(-hw, sy - st, -hd), DVec3::new(hw, sy, hd), ALL);
    let (lx, lz) = (hw - 0.03, hd - 0.03);
    for (sx, sz) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        let (x, z) = (sx * lx, sz * lz);
        let (lo, hi) = (DVec3::new(x - leg, 0.0, z - leg), DVec3::new(x + leg, sy - st, z + leg));
        kit.cuboid(mesh, frame, xf, lo, hi, SIDES);
    }
    // Two posts rising from the seat over the back legs, a rest between them.
    let back = kit.uniform(0.4, 0.46);
    for sx in [-1.0, 1.0] {
        let x = sx * lx;
        let (lo, hi) = (DVec3::new(x - leg, sy, lz - leg), DVec3::new(x + leg, sy + back, lz + leg));
        kit.cuboid(mesh, frame, xf, lo, hi, SIDES | PY);
    }
    let (lo, hi) =
        (DVec3::new(-lx + leg, sy + 0.2, lz - 0.01), DVec3::new(lx - leg, sy + back - 0.02, lz + 0.01));
    kit.cuboid(mesh, seat, xf, lo, hi, NY | PY | NZ | PZ);
}
