//! Where the power that no front face gathers goes. A solver's power balance reads
//!
//! ```text
//! emitted = absorbed + Σ_i A_i B_i (1 − Σ_j F_ij V_ij)          (EnergyBalance: absorbed + escaped)
//! ```
//!
//! and the second term mixes three things that a closed room must tell apart. Patches are
//! one-sided, so the cosine-weighted hemisphere above a point x splits, by what a ray from x
//! meets first, into the fractions f_front (a patch's front face: what the row Σ_j F_xj V_xj
//! stands for), f_back (a patch's back face, which absorbs it: a lamp's back facing the
//! ceiling, the inside of an open box) and f_out (nothing: the light leaves the scene). With
//! the fractions estimated by cosine-distributed rays from every element,
//!
//! ```text
//! Σ A B (1 − row) = Σ A B f_back  +  Σ A B f_out  +  Σ A B (f_front − row)
//!                   back faces       out of the scene   the rows' shortfall
//! ```
//!
//! The last term is the discretisation's: positive where the rows gather less than the front
//! faces they see, negative where they gather more (light created). A scene is **closed** when
//! no more than [`CLOSED_RAY_FRACTION`] of the rays leave it — decided from the geometry, not from
//! the solution: a room's walls, floor and ceiling stop every ray, an open box (Cornell) lets the
//! rays through its open side go. [Cohen & Wallace 1993, ch. 2 (the energy balance of the
//! radiosity equation); the estimator is the path tracer's first bounce, Kajiya 1986.]

use crate::geometry::accel::Accel;
use crate::geometry::visibility::point_on_polygon;
use crate::math::{DVec3, Pcg32, Rgb, newell_normal, orthonormal_basis, splitmix64};
use crate::scene::Scene;
use crate::solver::{EnergyBalance, SolvedElement};
use rayon::prelude::*;
use serde::Serialize;

/// Rays shared by the elements in proportion to the power each leaves with ([`split`]: the
/// split's standard error is then at most ½ / √RAY_BUDGET of the power leaving the surfaces),
/// beside [`MIN_RAYS`] each; at most [`MAX_RAYS`] an element.
pub const RAY_BUDGET: u64 = 1 << 20;
pub const MIN_RAYS: u32 = 4;
pub const MAX_RAYS: u32 = 4096;

/// A scene whose rays leave it at most this often is closed: a room's shell stops them all but
/// the few that slip through gaps where pieces meet (rays from just above a floor at the feet of
/// boxes standing on it); an open box lets a sizeable fraction go.
pub const CLOSED_RAY_FRACTION: f64 = 1e-3;

/// The cosine-weighted fractions of a hemisphere by what its rays meet first (they add to 1).
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize)]
pub struct Hemisphere {
    pub front: f64,
    pub back: f64,
    pub out: f64,
    /// Rays cast, and of them those that left the scene.
    pub rays: u32,
    pub rays_out: u32,
}

/// A region of a surface whose hemisphere is sampled: the polygon `verts`, its unit `normal`,
/// and the input patch it lies on (which the rays ignore).
#[derive(Copy, Clone, Debug)]
pub struct Region<'a> {
    pub verts: &'a [DVec3],
    pub normal: DVec3,
    pub patch: u32,
}

/// What a ray from a surface meets first.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Hit {
    /// The front face of this input patch (which gathers the light).
    Front(u32),
    /// The back face of this input patch (which absorbs it).
    Back(u32),
    /// Nothing: the ray leaves the scene.
    Out,
}

/// A set of hemisphere rays: `rays` cosine-distributed rays (stratified in sin²θ) from points
/// uniform on `region`, keyed by `key` and `seed` (the same rays on any thread).
#[derive(Copy, Clone, Debug)]
pub struct HemisphereRays<'a> {
    pub region: Region<'a>,
    pub rays: u32,
    pub key: u64,
    pub seed: u64,
}

/// Cast the ray set `set` and hand what each ray meets to `f`. `scene` and `accel` are the
/// input scene and its BVH.
pub fn cast_hemisphere(scene: &Scene, accel: &Accel, set: HemisphereRays, mut f: impl FnMut(Hit)) {
    let HemisphereRays { region: Region { verts, normal, patch }, rays, key, seed } = set;
    let mut rng = Pcg32::keyed(seed ^ 0xE5CA_9E00, key);
    let (t1, t2) = orthonormal_basis(normal);
    for k in 0..rays {
        // Malley's method: a point uniform on the unit disk, lifted to the hemisphere.
        let u = (f64::from(k) + rng.next_f64()) / f64::from(rays);
        let phi = std::f64::consts::TAU * rng.next_f64();
        let (r, z) = (u.sqrt(), (1.0 - u).max(0.0).sqrt());
        let dir = t1 * (r * phi.cos()) + t2 * (r * phi.sin()) + normal * z;
        let x = point_on_polygon(verts, 0.02 + 0.96 * rng.next_f64(), 0.02 + 0.96 * rng.next_f64());
        f(match accel.first_hit(x, dir, patch) {
            None => Hit::Out,
            Some((q, _)) if scene.patches[q as usize].normal.dot(dir) < 0.0 => Hit::Front(q),
            Some((q, _)) => Hit::Back(q),
        });
    }
}

/// The [`Hemisphere`] that the ray set `set` measures ([`cast_hemisphere`]).
#[must_use]
pub fn hemisphere(scene: &Scene, accel: &Accel, set: HemisphereRays) -> Hemisphere {
    let rays = set.rays;
    let mut h = Hemisphere { rays, ..Hemisphere::default() };
    cast_hemisphere(scene, accel, set, |hit| match hit {
        Hit::Front(_) => h.front += 1.0,
        Hit::Back(_) => h.back += 1.0,
        Hit::Out => {
            h.out += 1.0;
            h.rays_out += 1;
        }
    });
    if rays > 0 {
        let n = f64::from(rays);
        (h.front, h.back, h.out) = (h.front / n, h.back / n, h.out / n);
    }
    h
}

/// The escaped power of a solution split as the module docs say, per channel.
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize)]
pub struct EscapeSplit {
    /// Σ A B f_back: absorbed by the backs of one-sided patches.
    pub back_faces: Rgb,
    /// Σ A B f_out: leaves the scene (0 in a closed room).
    pub out_of_scene: Rgb,
    /// escaped − back faces − out of the scene: what the rows of F·V fall short of the front
    /// faces their elements see (negative: light created by rows that gather more).
    pub row_shortfall: Rgb,
    /// The standard error of `back_faces + out_of_scene` (and so of `row_shortfall`): the rays'
    /// noise, √(Σ (A B)² g (1 − g) / rays) with g the element's fraction not on a front face.
    pub noise: Rgb,
    /// At most [`CLOSED_RAY_FRACTION`] of the rays left the scene.
    pub closed: bool,
    pub rays: u64,
    pub rays_out: u64,
}

/// Rays for an element leaving `power` of the `total` power leaving all of them.
#[must_use]
pub fn rays_for(power: f64, total: f64) -> u32 {
    let share = if total > 0.0 { (RAY_BUDGET as f64 * power / total).ceil() } else { 0.0 };
    (f64::from(MIN_RAYS) + share).min(f64::from(MAX_RAYS)) as u32
}

/// Split a solution's `escaped` power (its energy balance's Σ A B (1 − row)) by the
/// hemispheres of its elements. `scene` and `accel` are the input scene and its BVH, whose patch
/// ids the elements' `patch` indices are. Deterministic for a seed, whatever the thread count.
#[must_use]
pub fn split(
    scene: &Scene,
    accel: &Accel,
    elements: &[SolvedElement],
    escaped: Rgb,
    seed: u64,
) -> EscapeSplit {
    let total: f64 = elements.iter().map(|e| e.radiosity.mean() * e.area).sum();
    let per: Vec<(Rgb, Rgb, Rgb, u32, u32)> = elements
        .par_iter()
        .enumerate()
        .with_min_len(64)
        .map(|(i, e)| {
            if e.vertices.len() < 3 || e.area <= 0.0 {
                return (Rgb::ZERO, Rgb::ZERO, Rgb::ZERO, 0, 0);
            }
            let n = newell_normal(&e.vertices).normalize_or_zero();
            let region = Region { verts: &e.vertices, normal: n, patch: e.patch as u32 };
            let power = e.radiosity * e.area;
            let rays = rays_for(power.mean(), total);
            let h =
                hemisphere(scene, accel, HemisphereRays { region, rays, key: splitmix64(i as u64), seed });
            let g = h.back + h.out;
            let var = power.mul_rgb(power) * (g * (1.0 - g) / f64::from(rays.max(1)));
            (power * h.back, power * h.out, var, h.rays, h.rays_out)
        })
        .collect();
    let mut s = EscapeSplit::default();
    let mut var = Rgb::ZERO;
    for (back, out, v, r, r_out) in per {
        s.back_faces += back;
        s.out_of_scene += out;
        var += v;
        s.rays += u64::from(r);
        s.rays_out += u64::from(r_out);
    }
    s.noise = var.map(f64::sqrt);
    s.closed = (s.rays_out as f64) <= CLOSED_RAY_FRACTION * s.rays as f64;
    s.row_shortfall = escaped - s.back_faces - s.out_of_scene;
    s
}

/// The power balance with the escaped power split, as `radlab solve --json` writes it: emitted,
/// absorbed (by front faces, Σ A (1 − ρ) H), absorbed by back faces, escaped (out of the scene: 0
/// in a closed one, where a ray lost through a crack between two patches counts as the rows'),
/// the rows' shortfall, their sum `not_gathered` (Σ A B (1 − Σ F·V), the balance's own term),
/// whether the scene is closed, the rays cast, their noise (the standard error of the split),
/// whether the rows create light beyond it ([`created`]) and the balance's relative residual.
#[must_use]
pub fn energy_json(e: &EnergyBalance, s: &EscapeSplit) -> serde_json::Value {
    let (escaped, shortfall) = reported(s);
    serde_json::json!({
        "emitted": e.emitted,
        "absorbed": e.absorbed,
        "absorbed_by_back_faces": s.back_faces,
        "escaped": escaped,
        "rows_shortfall": shortfall,
        "not_gathered": e.escaped,
        "closed": s.closed,
        "hemisphere_rays": s.rays,
        "split_noise": s.noise,
        "light_created": created(s),
        "relative_residual": e.relative_residual(),
    })
}

/// The same as one line of text (channel means), as `radlab solve` prints it.
#[must_use]
pub fn describe(e: &EnergyBalance, s: &EscapeSplit) -> String {
    let (escaped, shortfall) = reported(s);
    let scene = if s.closed { " (closed scene)" } else { "" };
    let created = if created(s) { " (light created)" } else { "" };
    format!(
        "emitted {:.4}  absorbed {:.4}  absorbed by back faces {:.4}  escaped {:.4}{scene}  rows' shortfall {:.4}{created}  residual {:.2e}",
        e.emitted.mean(),
        e.absorbed.mean(),
        s.back_faces.mean(),
        escaped.mean(),
        shortfall.mean(),
        e.relative_residual()
    )
}

/// Do the rows gather more than the front faces they see, beyond three standard errors of the
/// rays in some channel?
#[must_use]
pub fn created(s: &EscapeSplit) -> bool {
    let (_, shortfall) = reported(s);
    (0..3).any(|c| shortfall.0[c] < -3.0 * s.noise.0[c])
}

/// The escaped power and the rows' shortfall as reported: in a closed scene nothing escapes,
/// and the few rays lost through cracks count as the rows'.
fn reported(s: &EscapeSplit) -> (Rgb, Rgb) {
    if s.closed { (Rgb::ZERO, s.row_shortfall + s.out_of_scene) } else { (s.out_of_scene, s.row_shortfall) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Patch;

    /// The unit cube's faces facing in, but for those `skip` names (+x, −x, +y, −y, +z, −z).
    fn box_faces(skip: &[usize]) -> Vec<Patch> {
        let c = DVec3::splat(0.5);
        let mut out = Vec::new();
        for (k, n) in
            [DVec3::X, DVec3::NEG_X, DVec3::Y, DVec3::NEG_Y, DVec3::Z, DVec3::NEG_Z].into_iter().enumerate()
        {
            if skip.contains(&k) {
                continue;
            }
            let t1 = if n.x.abs() > 0.5 { DVec3::Y } else { DVec3::X };
            let t2 = n.cross(t1);
            // Counter-clockwise seen from inside (the normal −n faces in).
            let v = [(-1.0, -1.0), (-1.0, 1.0), (1.0, 1.0), (1.0, -1.0)]
                .map(|(a, b)| c + (n + t1 * a + t2 * b) * 0.5)
                .to_vec();
            out.push(Patch::new(v, Rgb::splat(0.5), Rgb::ZERO, "box", 0, "face", "m").expect("a face"));
        }
        out
    }

    /// Every patch one element with B = 1 where `lit`.
    fn elements(scene: &Scene, lit: impl Fn(usize) -> bool) -> Vec<SolvedElement> {
        SolvedElement::whole_patches(scene, |i| if lit(i) { Rgb::ONE } else { Rgb::ZERO })
    }

    /// A closed box keeps every ray; without its top it is open, and what leaves is the five
    /// faces' form factors to the opening (floor 0.19982, each wall 0.20004: 0.99998 with B = 1);
    /// a lamp hung 5 cm under the closed box's top, facing down, shows its back to the top.
    #[test]
    fn closed_open_and_back_faces_are_told_apart() {
        let closed = Scene::new("t", "closed", box_faces(&[]));
        assert!(closed.patches[0].normal.x < 0.0, "faces face in");
        let accel = Accel::build(&closed);
        let s = split(&closed, &accel, &elements(&closed, |_| true), Rgb::ZERO, 0);
        assert!(s.closed && s.rays_out == 0 && s.back_faces == Rgb::ZERO, "{s:?}");

        let open = Scene::new("t", "open", box_faces(&[2]));
        let accel = Accel::build(&open);
        let s = split(&open, &accel, &elements(&open, |_| true), Rgb::ZERO, 0);
        let out = s.out_of_scene.mean();
        assert!(!s.closed && (out - 0.99998).abs() <= 4.0 * s.noise.mean() + 1e-3, "{s:?}");
        // 20 480 rays over the box's elements: the split's standard error is about 0.014 of B·A
        // (each ray's share is a whole element's power); 0.02 keeps the 4σ check above tight.
        assert!(s.noise.mean() < 0.02, "{s:?}");

        let mut patches = box_faces(&[]);
        let lamp =
            [(0.4, 0.4), (0.6, 0.4), (0.6, 0.6), (0.4, 0.6)].map(|(x, z)| DVec3::new(x, 0.95, z)).to_vec();
        patches.push(
            Patch::new(lamp, Rgb::splat(0.5), Rgb::splat(10.0), "lamp", 0, "lamp", "m").expect("a lamp"),
        );
        let lamp_scene = Scene::new("t", "lamp", patches);
        assert!(lamp_scene.patches[6].normal.y < -0.99, "the lamp faces down");
        let accel = Accel::build(&lamp_scene);
        // The top (+y) face alone lit: what it sends to the lamp lands on the lamp's back.
        let s = split(&lamp_scene, &accel, &elements(&lamp_scene, |i| i == 2), Rgb::ZERO, 0);
        assert!(s.closed && s.out_of_scene == Rgb::ZERO, "{s:?}");
        assert!((0.02..0.06).contains(&s.back_faces.mean()), "{s:?}");
    }
}
