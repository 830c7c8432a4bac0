//! The fraction of the direct light a point sees: for a point x of patch p (normal n) and each
//! emitter e ≠ p, with F_e(x) the unoccluded point-to-polygon form factor (Lambert's closed form)
//! and the emitter sampled at the centres y_k of a `side × side` grid of its area-uniform map:
//!
//! ```text
//! v_e(x)  = Σ_k K(x, y_k) V(x, y_k) / Σ_k K(x, y_k)      K = cosθ_x cosθ_y / r⁴ (∝ the kernel per area)
//! lit(x)  = Σ_e Ē_e F_e(x) v_e(x) / Σ_e Ē_e F_e(x)        Ē_e: mean of E_e over channels
//! D(x)    = ρ̄_p Σ_e Ē_e F_e(x)                             the direct light x gets unoccluded
//! ```
//!
//! lit is 0 in the umbra and 1 fully lit; between, x is in a penumbra. The grid is fixed (no
//! randomness), so lit depends only on the scene. The graded mesh spends its budget where lit
//! varies; the penumbra band of the rulers (`eval::penumbra`) is the points strictly between the
//! two margins below.

use crate::geometry::accel::Accel;
use crate::geometry::area_map::area_point;
use crate::geometry::form_factor::point_to_polygon;
use crate::scene::Scene;

/// Below this lit fraction a point is in the umbra.
pub const UMBRA_BELOW: f64 = 0.02;
/// Above this lit fraction a point is fully lit.
pub const FULLY_LIT_ABOVE: f64 = 0.98;
/// A shadow counts only where the direct light is at least this share of the point's value.
pub const MIN_DIRECT_SHARE: f64 = 0.1;

/// lit(x) and D(x) at point `x` of `patch` (module docs), from a `side × side` grid of shadow rays per
/// emitter; `None` when no emitter faces it (D = 0).
#[must_use]
pub fn lit_fraction(
    scene: &Scene,
    accel: &Accel,
    patch: usize,
    x: crate::math::DVec3,
    side: u32,
) -> Option<(f64, f64)> {
    let p = &scene.patches[patch];
    let (mut seen, mut total) = (0.0, 0.0);
    let mut last = crate::geometry::accel::NO_HIT;
    let n = f64::from(side);
    for (e, emitter) in scene.patches.iter().enumerate() {
        let power = emitter.emission.mean();
        if e == patch || power <= 0.0 {
            continue;
        }
        let f = point_to_polygon(x, p.normal, &emitter.vertices);
        if f <= 0.0 {
            continue;
        }
        let (mut k_all, mut k_vis) = (0.0, 0.0);
        for j in 0..side {
            for i in 0..side {
                let y = area_point(&emitter.vertices, (f64::from(i) + 0.5) / n, (f64::from(j) + 0.5) / n);
                let d = y - x;
                let r2 = d.length_squared();
                let k = (p.normal.dot(d).max(0.0) * (-emitter.normal.dot(d)).max(0.0)) / (r2 * r2);
                if k <= 0.0 {
                    continue;
                }
                k_all += k;
                if !accel.occluded_cached(x, y, [patch as u32, e as u32], &mut last) {
                    k_vis += k;
                }
            }
        }
        if k_all > 0.0 {
            total += power * f;
            seen += power * f * (k_vis / k_all);
        }
    }
    (total > 0.0).then(|| (seen / total, p.reflectance.mean() * total))
}
