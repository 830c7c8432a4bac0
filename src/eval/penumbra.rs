//! The **penumbra band** of a pointwise reference: the points that see part, but not all, of
//! the direct light — where a shadow's value is strictly between umbra and fully lit, and where
//! constant elements show as blocky shadows (the lecture's artifact A).
//!
//! For a point x of patch p (normal n) and each emitter e ≠ p (E_e ≠ 0), with F_e(x) the
//! unoccluded point-to-polygon form factor (Lambert's closed form,
//! [`crate::geometry::form_factor::point_to_polygon`]) and the emitter sampled at the centres y_k of a
//! `side × side` grid of its area-uniform map ([`crate::geometry::area_map::area_point`]):
//!
//! ```text
//! v_e(x)  = Σ_k K(x, y_k) V(x, y_k) / Σ_k K(x, y_k)      K = cosθ_x cosθ_y / r⁴ (∝ the kernel per area)
//! lit(x)  = Σ_e Ē_e F_e(x) v_e(x) / Σ_e Ē_e F_e(x)        Ē_e: mean of E_e over channels
//! D(x)    = ρ̄_p Σ_e Ē_e F_e(x)                             the direct light x gets unoccluded
//!
//! x ∈ band  ⇔  lo < lit(x) < hi   and   D(x) ≥ min_direct · B̂(x)
//! ```
//!
//! i.e. the fraction of the unoccluded direct light that reaches x lies strictly between the
//! umbra (0) and fully lit (1), by margins `lo` and `1 − hi`; and that direct light matters at x
//! (it is at least `min_direct` of the reference value B̂(x), mean over channels), so grazing
//! points that receive almost nothing directly do not count. V is a shadow ray
//! ([`crate::geometry::accel::Accel::occluded`]), the grid is fixed (no randomness), so the band depends
//! only on the scene, the points and the reference values — not on any solution — and works on
//! any scene (table-room, cornell) as well as on the exact single-bounce scenes, where lit(x) is
//! the fraction [`crate::geometry::exact`] computes in closed form (up to the grid's quadrature error).
//! [`crate::eval::pointwise::score_solution_in_band`] scores a solution over the band.

use crate::eval::reference::{Estimate, RefPoint};
use crate::geometry::accel::Accel;
use crate::geometry::lit::{FULLY_LIT_ABOVE, MIN_DIRECT_SHARE, UMBRA_BELOW, lit_fraction};
use crate::scene::Scene;
use rayon::prelude::*;

/// Settings of [`band`].
#[derive(Copy, Clone, Debug, PartialEq, serde::Serialize)]
pub struct BandParams {
    /// Emitter samples per side (`side²` shadow rays per point and emitter).
    pub side: u32,
    /// lit(x) must exceed this (not umbra).
    pub lo: f64,
    /// lit(x) must stay below this (not fully lit).
    pub hi: f64,
    /// The unoccluded direct light D(x) must be at least this fraction of B̂(x).
    pub min_direct: f64,
}

impl BandParams {
    /// 16 × 16 rays per emitter, lit strictly between 2 % and 98 %, direct light ≥ 10 % of B̂:
    /// a ray grid of 256 resolves lit to ~0.4 %, far inside the margins, and an emitter's
    /// shadow that changes B by less than a tenth is not counted as a shadow.
    #[must_use]
    pub const fn standard() -> BandParams {
        BandParams { side: 16, lo: UMBRA_BELOW, hi: FULLY_LIT_ABOVE, min_direct: MIN_DIRECT_SHARE }
    }
}

impl Default for BandParams {
    fn default() -> Self {
        Self::standard()
    }
}

/// Which points are in the penumbra band (module docs), in point order (parallel; identical for
/// any thread count).
#[must_use]
pub fn band(
    scene: &Scene,
    accel: &Accel,
    points: &[RefPoint],
    reference: &[Estimate],
    params: &BandParams,
) -> Vec<bool> {
    points
        .par_iter()
        .zip(reference)
        .map(|(pt, r)| {
            lit_fraction(scene, accel, pt.patch, pt.position, params.side).is_some_and(|(lit, direct)| {
                lit > params.lo && lit < params.hi && direct >= params.min_direct * r.radiosity.mean()
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::exact::SingleBounce;
    use crate::geometry::form_factor::point_to_polygon;
    use crate::math::{DVec3, Rgb};

    /// lit(x) against the closed form on shadow-wide (two overlapping occluders): a 16 × 16 grid
    /// of a unit lamp is a midpoint rule whose error is the cells a shadow edge cuts, ~16 of 256,
    /// each off by up to half its weight: ≤ 1/32 ≈ 3 % (measured worst 2.6 %).
    #[test]
    fn lit_fraction_matches_the_exact_answer() {
        const GRID_QUADRATURE: f64 = 0.04;
        let scene = Scene::load("builtin:shadow-wide").unwrap();
        let sb = SingleBounce::new(&scene).unwrap();
        let accel = Accel::build(&scene);
        let r = &scene.patches[sb.receiver];
        let (mut inside, mut checked) = (0, 0);
        for j in 0..12 {
            for i in 0..12 {
                let (s, t) = ((f64::from(i) + 0.5) / 12.0, (f64::from(j) + 0.5) / 12.0);
                let v = &r.vertices;
                let x: DVec3 = v[0].lerp(v[1], s).lerp(v[3].lerp(v[2], s), t);
                let (lit, direct) = lit_fraction(&scene, &accel, sb.receiver, x, 16).unwrap();
                let f_all = point_to_polygon(x, r.normal, &scene.patches[sb.emitter].vertices);
                let exact = sb.visible_form_factor(x) / f_all;
                assert!((lit - exact).abs() < GRID_QUADRATURE, "at {x}: {lit} vs exact {exact}");
                let e = scene.patches[sb.emitter].emission.mean();
                assert!((direct - r.reflectance.mean() * e * f_all).abs() < 1e-12);
                inside += usize::from(exact > 0.1 && exact < 0.9);
                checked += 1;
            }
        }
        assert!(inside > 10, "the grid crosses the penumbrae ({inside} of {checked})");
    }

    /// The band holds the points strictly between umbra and fully lit, and none where the
    /// reference value dwarfs the direct light.
    #[test]
    fn band_selects_the_penumbra() {
        let scene = Scene::load("builtin:shadow-narrow").unwrap();
        let sb = SingleBounce::new(&scene).unwrap();
        let accel = Accel::build(&scene);
        let r = &scene.patches[sb.receiver];
        let points: Vec<RefPoint> = (0..200u32)
            .map(|k| {
                let s = (f64::from(k) + 0.5) / 200.0;
                let v = &r.vertices;
                let x = v[0].lerp(v[1], s).lerp(v[3].lerp(v[2], s), 0.5);
                let cell = crate::eval::reference::Cell { patch: sb.receiver as u32, level: 0, i: k, j: 0 };
                RefPoint { patch: sb.receiver, position: x, area: 1.0, cell }
            })
            .collect();
        let exact: Vec<Estimate> = points
            .iter()
            .map(|p| Estimate { radiosity: sb.radiosity_at(p.position), std_error: Rgb::ZERO })
            .collect();
        let b = band(&scene, &accel, &points, &exact, &BandParams::standard());
        let n = b.iter().filter(|&&x| x).count();
        assert!(n > 0 && n < points.len() / 4, "a narrow penumbra: {n} of {}", points.len());
        for (p, &inb) in points.iter().zip(&b) {
            let f = sb.visible_form_factor(p.position)
                / point_to_polygon(p.position, r.normal, &scene.patches[sb.emitter].vertices);
            if !(0.01..=0.99).contains(&f) {
                assert!(!inb, "at {}: lit {f} is umbra or fully lit", p.position);
            }
            if f > 0.05 && f < 0.95 {
                assert!(inb, "at {}: lit {f} is penumbra", p.position);
            }
        }
        // A reference that is ten times the direct light everywhere: nothing counts.
        let bright: Vec<Estimate> =
            points.iter().map(|_| Estimate { radiosity: Rgb::splat(1e6), std_error: Rgb::ZERO }).collect();
        assert!(band(&scene, &accel, &points, &bright, &BandParams::standard()).iter().all(|&x| !x));
    }
}
