//! `shelves`: a library — rows of bookcases standing back to back, their boards full of thin
//! books, under ceiling panels over the aisles.
//!
//! ```text
//!   seen from above            one bookcase (0.9 m wide, 1.8–2.1 m tall, 0.32 m deep)
//!   ▀▀▀ panel  ▀▀▀ panel       ┌──────────────┐
//!   ┌──┬──┬──┬──┐  ← faces −z  │▌▌▐▌ ▌▐▌▌▌▌  │ books 1.2–4 cm thick, 17–30 cm tall,
//!   ├──┼──┼──┼──┤  backs touch │▌▌▌▐▌▌▌ ▌▌▌▌▌│ 2 mm apart (now and then a gap)
//!   └──┴──┴──┴──┘  ← faces +z  │▐▌▌▌▌▌▌  ▌▌▐▌│ 4–5 boards, the bottom one on the floor
//!   ▀▀▀ aisle 1.4 m ▀▀▀        └──────────────┘
//! ```
//! k counts the boards that hold books: bookcases are added (side by side, a row of them
//! against the next back to back) until k boards are filled; the last one's upper boards stay
//! empty. A board with books is about 230 triangles. Every book is its top and sides and
//! faces (10 triangles: it stands on the board); cases touch their neighbours side to side and
//! back to back. Panels 1.2 × 0.6 emit E = 30 over every aisle, one every 2.5 m.

use super::kit::{ALL, Draw, Kit, Layout, NX, NY, NZ, PX, PY, PZ, WOODS, Xf, light};
use crate::math::DVec3;
use crate::scene::Mat;
use crate::scene::Viewpoint;
use crate::scene::pieces::BookRow;
use std::f64::consts::PI;

const WIDTH: f64 = 0.9;
const DEPTH: f64 = 0.32;
const BOARD: f64 = 0.02;
const AISLE: f64 = 1.4;
const MARGIN: f64 = 1.2;
const HEIGHT: f64 = 2.8;
const PANEL: Mat = light("panel_light", 30.0);

/// The library with `k` boards of books.
pub(super) fn layout(k: usize, seed: u64) -> Layout {
    let mut kit = Kit::new(seed, 0x5E1F_B00C);
    // Boards per case, drawn first: the number of cases sizes the room.
    let mut boards = Vec::new();
    while boards.iter().sum::<usize>() < k {
        boards.push(4 + kit.below(2));
    }
    let cases = boards.len();
    let cols = ((1.13 * cases as f64).sqrt().ceil() as usize).max(1);
    let lines = cases.div_ceil(cols);
    let rows = lines.div_ceil(2);
    let row_depth = 2.0 * DEPTH + AISLE;
    let w = cols as f64 * WIDTH + 2.0 * MARGIN;
    let d = rows as f64 * row_depth - AISLE + 2.0 * MARGIN;
    kit.room(w, d, HEIGHT, 1.0);

    // Panels over the aisles: the two margins and between the rows.
    let per_aisle = ((w / 2.5).round() as usize).max(1);
    for a in 0..=rows {
        let z = if a == 0 { MARGIN / 2.0 } else { MARGIN + a as f64 * row_depth - AISLE / 2.0 };
        let z = if a == rows { d - MARGIN / 2.0 } else { z };
        for i in 0..per_aisle {
            let x = w * (i as f64 + 0.5) / per_aisle as f64;
            kit.panel(&format!("panel{a}_{i}"), PANEL, DVec3::new(x, HEIGHT - 0.02, z), 1.2, 0.6);
        }
    }

    let mut left = k;
    for (c, &n) in boards.iter().enumerate() {
        let (line, i) = (c / cols, c % cols);
        let (row, back) = (line / 2, line % 2 == 1);
        let x = MARGIN + (i as f64 + 0.5) * WIDTH;
        let z0 = MARGIN + row as f64 * row_depth;
        // A case faces −z in its own frame; the second line of a row is turned to face +z, the
        // two backs touching at z0 + DEPTH.
        let xf = if back {
            Xf::turned(PI, DVec3::new(x, 0.0, z0 + 1.5 * DEPTH))
        } else {
            Xf::at(DVec3::new(x, 0.0, z0 + 0.5 * DEPTH))
        };
        let filled = n.min(left);
        left -= filled;
        bookcase(&mut kit, &format!("case{c}"), xf, n, filled);
    }
    kit.layout(Viewpoint {
        eye: DVec3::new(0.3, 1.9, 0.3),
        target: DVec3::new(w / 2.0, 0.8, d / 2.0),
        up: DVec3::Y,
        fov_y_deg: 65.0,
    })
}

/// A bookcase facing −z, centred on the origin of `xf`, `n` boards of which the lowest
/// `filled` hold books.
fn bookcase(kit: &mut Kit, mesh: &str, xf: Xf, n: usize, filled: usize) {
    let wood = kit.pick(&WOODS);
    let h = kit.uniform(1.8, 2.1);
    let (hw, hd, t) = (WIDTH / 2.0, DEPTH / 2.0, BOARD);
    let inner = hw - t;
    // Sides, top, back; the boards (the bottom one on the floor).
    for sx in [-1.0, 1.0] {
        let x = sx * (hw - t / 2.0);
        kit.cuboid(
            mesh,
            wood,
            xf,
            DVec3::new(x - t / 2.0, 0.0, -hd),
            DVec3::new(x + t / 2.0, h, hd),
            ALL ^ NY,
        );
    }
    let top = (DVec3::new(-inner, h - t, -hd), DVec3::new(inner, h, hd));
    kit.cuboid(mesh, wood, xf, top.0, top.1, ALL ^ NX ^ PX);
    kit.cuboid(mesh, wood, xf, DVec3::new(-inner, 0.0, hd - t), DVec3::new(inner, h - t, hd), NZ | PZ);
    let pitch = (h - t) / n as f64;
    for s in 0..n {
        let y = s as f64 * pitch;
        let faces = if s == 0 { PY | NZ } else { NY | PY | NZ };
        kit.cuboid(mesh, wood, xf, DVec3::new(-inner, y, -hd), DVec3::new(inner, y + t, hd - t), faces);
    }
    // Books standing on the boards, left to right, 2 mm apart, a gap now and then.
    let row = BookRow { fill: (0.6, 0.97), margin: 0.005, thickness: (0.012, 0.04), gap_chance: 0.08 };
    for s in 0..filled {
        let books = row.books(kit, inner, s as f64 * pitch + t, pitch - t - 0.03, hd - t - 0.005);
        debug_assert!(!books.is_empty(), "a board holds at least one book");
        for (lo, hi, book) in books {
            kit.cuboid(&format!("{mesh}_books{s}"), book, xf, lo, hi, ALL ^ NY);
        }
    }
}
