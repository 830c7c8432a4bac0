//! `box-grid`: a dense grid of small boxes of varying height standing on the floor of a closed
//! room, lit only by one 2 × 2 panel hung just below the ceiling, facing down.
//!
//! ```text
//!        ceiling ──────────────────────────────  y = 2.5
//!                          ▀▀▀▀ panel (E = 20, 2 × 2, 5 cm below)
//!
//!          ▄   █ ▄     █   ▄ █     ▄   █ ▄      boxes 0.12–0.2 m wide, 0.05–0.6 m tall,
//!        ▄ █ ▄ █ █ ▄ ▄ █ █ █ █ ▄ █ █ █ █ █ ▄    on a 0.25 m grid, 1 m from the walls
//!        floor ────────────────────────────────
//! ```
//! k boxes fill a ⌈√k⌉-wide grid row by row; each box is its top and four sides (10 triangles:
//! the bottom rests on the floor). The room is six quads and the floor a fill piece, so at
//! 100 k triangles the scene is a 100 × 100 grid in a 27 m room. Box colours are four greys
//! and browns (ρ 0.3–0.7); walls 0.75, floor 0.45, ceiling 0.8; the panel emits E = 20 (80 in
//! all), ρ 0.8.

use super::kit::{ALL, Draw, Kit, Layout, NY, Xf, light, mat};
use crate::math::DVec3;
use crate::scene::Mat;
use crate::scene::Viewpoint;

const PITCH: f64 = 0.25;
const MARGIN: f64 = 1.0;
const HEIGHT: f64 = 2.5;
const BOXES: [Mat; 4] = [
    mat("box_grey", 0.5, 0.5, 0.5),
    mat("box_light", 0.7, 0.68, 0.64),
    mat("box_brown", 0.45, 0.33, 0.22),
    mat("box_dark", 0.3, 0.3, 0.32),
];
const PANEL: Mat = light("panel_light", 20.0);

/// The room for `k` boxes.
pub(super) fn layout(k: usize, seed: u64) -> Layout {
    let mut kit = Kit::new(seed, 0xB0C5_6A1D);
    let nx = (k as f64).sqrt().ceil() as usize;
    let nz = k.div_ceil(nx);
    let (w, d) = (nx as f64 * PITCH + 2.0 * MARGIN, nz as f64 * PITCH + 2.0 * MARGIN);
    kit.room(w, d, HEIGHT, f64::INFINITY);
    kit.panel("panel", PANEL, DVec3::new(w / 2.0, HEIGHT - 0.05, d / 2.0), 2.0, 2.0);
    for b in 0..k {
        let (i, j) = (b % nx, b / nx);
        let centre = DVec3::new(MARGIN + (i as f64 + 0.5) * PITCH, 0.0, MARGIN + (j as f64 + 0.5) * PITCH);
        let (sx, sz) = (kit.uniform(0.12, 0.2), kit.uniform(0.12, 0.2));
        let h = kit.uniform(0.05, 0.6);
        let colour = kit.pick(&BOXES);
        let half = DVec3::new(sx / 2.0, 0.0, sz / 2.0);
        kit.cuboid(&format!("boxes{j}"), colour, Xf::at(centre), -half, half + DVec3::Y * h, ALL ^ NY);
    }
    kit.layout(Viewpoint {
        eye: DVec3::new(0.4, 2.0, 0.4),
        target: DVec3::new(w / 2.0, 0.3, d / 2.0),
        up: DVec3::Y,
        fov_y_deg: 65.0,
    })
}
