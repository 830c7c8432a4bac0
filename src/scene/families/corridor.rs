//! `corridor`: a long corridor with a row of rooms on each side, each behind a door in the
//! corridor wall — shut, ajar or open — most of the building out of sight of most of the rest.
//!
//! ```text
//!    z = 10 ┌──────┬──────┬──────┬──────┐   rooms 3.6 × 4 m, 2.6 m high, walls 12 cm
//!           │ ▄▄ ▪ │ ▪ ▄▄ │  ▄▄  │ ▪ ▄▄ │   a table and a cabinet in each (clear of the door)
//!           │      │      │      │      │
//!           └──╱ ──┴─ ── ─┴──  ──┴─╲ ───┘   doors 0.9 × 2.1 m: shut (30 %) or swung into the
//!             corridor 2 m wide   ▀▀         room by 0.3–1.55 rad
//!           ┌── ╲──┬─ ── ─┬──  ──┬── ╱──┐
//!           │  ▄▄  │ ▪ ▄▄ │ ▄▄ ▪ │  ▄▄  │
//!    z = 0  └──────┴──────┴──────┴──────┘   x →  k bays of two rooms each
//! ```
//! Lights: a 0.6 × 0.6 ceiling panel (E = 30) in 60 % of the rooms, a 1.2 × 0.3 panel (E = 25) over
//! the corridor in half the bays (always the first). Walls are boxes without the faces that touch
//! the floor, the ceiling or another wall; a bay is about 200 triangles, the building's
//! ceiling and outer walls are cut into 1 m panels.

use super::kit::{ALL, Draw, Kit, Layout, METAL, NX, NY, NZ, PX, PY, PZ, SIDES, WALL, WOODS, Xf, light};
use crate::math::DVec3;
use crate::scene::Mat;
use crate::scene::Viewpoint;

const ROOM_W: f64 = 3.6;
const ROOM_D: f64 = 4.0;
const CORRIDOR: f64 = 2.0;
const HEIGHT: f64 = 2.6;
const T: f64 = 0.12;
const DOOR_W: f64 = 0.9;
const DOOR_H: f64 = 2.1;
const ROOM_LIGHT: Mat = light("room_light", 30.0);
const CORRIDOR_LIGHT: Mat = light("corridor_light", 25.0);

/// The building with `k` bays (a room on each side of the corridor).
pub(super) fn layout(k: usize, seed: u64) -> Layout {
    let mut kit = Kit::new(seed, 0xC0DD_1D02);
    let (l, d) = (k as f64 * ROOM_W, 2.0 * ROOM_D + CORRIDOR);
    kit.room(l, d, HEIGHT, 1.0);
    let origin = Xf::at(DVec3::ZERO);
    for i in 0..k {
        let x0 = i as f64 * ROOM_W;
        if i == 0 || kit.chance(0.5) {
            let at = DVec3::new(x0 + ROOM_W / 2.0, HEIGHT - 0.02, ROOM_D + CORRIDOR / 2.0);
            kit.panel(&format!("corridor_light{i}"), CORRIDOR_LIGHT, at, 1.2, 0.3);
        }
        for south in [true, false] {
            let side = if south { "s" } else { "n" };
            let mesh = format!("room{i}{side}");
            // The corridor wall with its door opening (the room at −z for the south row).
            let zc = if south { ROOM_D } else { ROOM_D + CORRIDOR };
            let (z0, z1) = (zc - T / 2.0, zc + T / 2.0);
            let xd0 = x0 + kit.uniform(0.4, ROOM_W - DOOR_W - 0.4);
            let xd1 = xd0 + DOOR_W;
            let x1 = x0 + ROOM_W;
            let wall = format!("{mesh}_wall");
            kit.cuboid(
                &wall,
                WALL,
                origin,
                DVec3::new(x0, 0.0, z0),
                DVec3::new(xd0, HEIGHT, z1),
                NZ | PZ | PX,
            );
            kit.cuboid(
                &wall,
                WALL,
                origin,
                DVec3::new(xd1, 0.0, z0),
                DVec3::new(x1, HEIGHT, z1),
                NZ | PZ | NX,
            );
            let lintel = (DVec3::new(xd0, DOOR_H, z0), DVec3::new(xd1, HEIGHT, z1));
            kit.cuboid(&wall, WALL, origin, lintel.0, lintel.1, NZ | PZ | NY);
            // The wall to the next room, from the outer wall to this corridor wall.
            if i > 0 {
                let (za, zb) = if south { (0.0, z0) } else { (z1, d) };
                let (lo, hi) = (DVec3::new(x0 - T / 2.0, 0.0, za), DVec3::new(x0 + T / 2.0, HEIGHT, zb));
                kit.cuboid(&wall, WALL, origin, lo, hi, NX | PX);
            }
            // The door, hinged at the opening's low-x side on the room's face of the wall.
            let inward = if south { -1.0 } else { 1.0 };
            let angle = if kit.chance(0.3) { 0.0 } else { kit.uniform(0.3, 1.55) };
            let hinge = DVec3::new(xd0 + 0.005, 0.0, if south { z0 } else { z1 });
            let leaf = Xf::turned(-inward * angle, hinge);
            let (lz0, lz1) = if south { (-0.04, 0.0) } else { (0.0, 0.04) };
            let door = kit.pick(&WOODS);
            let (lo, hi) = (DVec3::new(0.0, 0.01, lz0), DVec3::new(DOOR_W - 0.01, DOOR_H - 0.01, lz1));
            kit.cuboid(&format!("{mesh}_door"), door, leaf, lo, hi, ALL);
            // Furniture in the half of the room away from the corridor.
            let far = |t: f64| if south { t } else { d - t };
            furnish(&mut kit, &mesh, x0, far);
            if kit.chance(0.6) {
                let at = DVec3::new(x0 + ROOM_W / 2.0, HEIGHT - 0.02, far(ROOM_D / 2.0));
                kit.panel(&format!("{mesh}_light"), ROOM_LIGHT, at, 0.6, 0.6);
            }
        }
    }
    kit.layout(Viewpoint {
        eye: DVec3::new(0.3, 1.6, ROOM_D + CORRIDOR / 2.0),
        target: DVec3::new(l, 1.0, ROOM_D + CORRIDOR / 2.0),
        up: DVec3::Y,
        fov_y_deg: 60.0,
    })
}

/// A table and a cabinet in the room spanning x0..x0 + ROOM_W, `far(t)` the z at distance t
/// from the outer wall.
fn furnish(kit: &mut Kit, mesh: &str, x0: f64, far: impl Fn(f64) -> f64) {
    let wood = kit.pick(&WOODS);
    let table = format!("{mesh}_table");
    let (tw, td) = (kit.uniform(1.0, 1.4), kit.uniform(0.6, 0.8));
    let centre = DVec3::new(x0 + kit.uniform(1.0, ROOM_W - 1.0), 0.0, far(kit.uniform(1.2, 1.8)));
    let xf = Xf::turned(kit.uniform(-0.2, 0.2), centre);
    let top = (DVec3::new(-tw / 2.0, 0.71, -td / 2.0), DVec3::new(tw / 2.0, 0.74, td / 2.0));
    kit.cuboid(&table, wood, xf, top.0, top.1, ALL);
    for (sx, sz) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        let (x, z) = (sx * (tw / 2.0 - 0.06), sz * (td / 2.0 - 0.06));
        kit.cuboid(
            &table,
            wood,
            xf,
            DVec3::new(x - 0.02, 0.0, z - 0.02),
            DVec3::new(x + 0.02, 0.71, z + 0.02),
            SIDES,
        );
    }
    // The cabinet stands against the outer wall (its back touching it).
    let (cw, ch) = (kit.uniform(0.6, 1.0), kit.uniform(1.2, 2.0));
    let cx = x0 + kit.uniform(0.2 + cw / 2.0, ROOM_W - 0.2 - cw / 2.0);
    let (za, zb) = (far(0.0), far(0.45));
    let (lo, hi) = (DVec3::new(cx - cw / 2.0, 0.0, za.min(zb)), DVec3::new(cx + cw / 2.0, ch, za.max(zb)));
    let front = if za < zb { PZ } else { NZ };
    kit.cuboid(&format!("{mesh}_cabinet"), METAL, Xf::at(DVec3::ZERO), lo, hi, NX | PX | PY | front);
}
