//! `stacked-boxes`: a store room of box stacks — boxes resting on boxes, each turned against
//! the one below, some standing in pairs side by side — under a grid of ceiling panels.
//!
//! ```text
//!            ┌──┐                 each level: 60–100 % of the one below in each direction,
//!          ┌─┴──┴─┐ ◄ turned      turned by up to ±0.7 rad, moved by up to 15 % of it, so
//!         ┌┴──────┴┐  ±0.7 rad    it may overhang (its bottom face is kept: it lies on the
//!         │ ┌────┬─┴─┐           top below, a contact)
//!   floor ┴─┴────┴───┴──         the base: one box, or two of one height side by side
//! ```
//! k stacks on a 1.8 m grid, each turned as a whole by a random angle; 0–3 boxes on the base.
//! A box is 10 triangles on the floor, 12 on another box; a stack about 30. Cardboard colours
//! (ρ 0.55–0.8); panels 1.2 × 0.6 (E = 40) on a 3 m grid, the room 4 m high.

use super::kit::{ALL, Draw, Kit, Layout, NY, Xf, light, mat};
use crate::math::DVec3;
use crate::scene::Mat;
use crate::scene::Viewpoint;
use std::f64::consts::FRAC_PI_2;

const PITCH: f64 = 1.8;
const MARGIN: f64 = 1.5;
const HEIGHT: f64 = 4.0;
const PANEL: Mat = light("panel_light", 40.0);

/// The room with `k` stacks.
pub(super) fn layout(k: usize, seed: u64) -> Layout {
    let mut kit = Kit::new(seed, 0x57AC_B0E5);
    let nx = (k as f64).sqrt().ceil() as usize;
    let nz = k.div_ceil(nx);
    let (w, d) = (nx as f64 * PITCH + 2.0 * MARGIN - 0.6, nz as f64 * PITCH + 2.0 * MARGIN - 0.6);
    kit.room(w, d, HEIGHT, 1.0);
    kit.panel_grid(PANEL, (w, d), 3.0, HEIGHT - 0.03, (1.2, 0.6));
    for s in 0..k {
        let (i, j) = (s % nx, s / nx);
        let at = DVec3::new(
            MARGIN - 0.3 + (i as f64 + 0.5) * PITCH + kit.uniform(-0.1, 0.1),
            0.0,
            MARGIN - 0.3 + (j as f64 + 0.5) * PITCH + kit.uniform(-0.1, 0.1),
        );
        stack(&mut kit, &format!("stack{s}"), at);
    }
    kit.layout(Viewpoint {
        eye: DVec3::new(0.4, 2.6, 0.4),
        target: DVec3::new(w / 2.0, 0.5, d / 2.0),
        up: DVec3::Y,
        fov_y_deg: 65.0,
    })
}

/// One stack standing at `at` on the floor.
fn stack(kit: &mut Kit, mesh: &str, at: DVec3) {
    /// The boxes' cardboards.
    const CARDBOARD: [Mat; 3] = [
        mat("cardboard", 0.55, 0.42, 0.28),
        mat("cardboard_light", 0.68, 0.56, 0.4),
        mat("cardboard_white", 0.8, 0.78, 0.74),
    ];
    let mut yaw = kit.uniform(0.0, FRAC_PI_2);
    let (a, b, h) = (kit.uniform(0.5, 0.8), kit.uniform(0.4, 0.7), kit.uniform(0.3, 0.6));
    let xf = Xf::turned(yaw, at);
    // The base: one box, or two of one height touching side by side (along the stack's x).
    let (mut sa, mut sb) = (a, b);
    if kit.chance(0.3) {
        let (a2, b2) = (kit.uniform(0.3, 0.6), kit.uniform(0.4, 0.7));
        let c1 = kit.pick(&CARDBOARD);
        let c2 = kit.pick(&CARDBOARD);
        kit.cuboid(mesh, c1, xf, DVec3::new(-a, 0.0, -b / 2.0), DVec3::new(0.0, h, b / 2.0), ALL ^ NY);
        kit.cuboid(mesh, c2, xf, DVec3::new(0.0, 0.0, -b2 / 2.0), DVec3::new(a2, h, b2 / 2.0), ALL ^ NY);
        // What rests on the pair stays within the narrower box's depth.
        (sa, sb) = (a.min(a2) * 2.0, b.min(b2));
    } else {
        let c = kit.pick(&CARDBOARD);
        let half = DVec3::new(a / 2.0, 0.0, b / 2.0);
        kit.cuboid(mesh, c, xf, -half, half + DVec3::Y * h, ALL ^ NY);
    }
    let (mut centre, mut y) = (at, h);
    let mut below = xf;
    for _ in 0..kit.below(4) {
        let (na, nb) = (sa * kit.uniform(0.6, 1.0), sb * kit.uniform(0.6, 1.0));
        let nh = kit.uniform(0.2, 0.5);
        let offset = DVec3::new(sa * kit.uniform(-0.15, 0.15), 0.0, sb * kit.uniform(-0.15, 0.15));
        centre += below.rotate(offset);
        yaw += kit.uniform(-0.7, 0.7);
        let xf = Xf::turned(yaw, centre);
        let c = kit.pick(&CARDBOARD);
        let half = DVec3::new(na / 2.0, 0.0, nb / 2.0);
        kit.cuboid(mesh, c, xf, -half + DVec3::Y * y, half + DVec3::Y * (y + nh), ALL);
        (sa, sb, y, below) = (na, nb, y + nh, xf);
    }
}
