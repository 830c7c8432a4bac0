//! Form-factor kernels: pure functions of geometry, `f64` inside.
//!
//! - [`point_to_polygon`]: exact differential-area → polygon form factor by Lambert's contour
//!   integral  `F = 1/(2π) Σ_i β_i n·γ_i`, with β_i the angle subtended by edge i and γ_i the unit
//!   normal of the plane through the point and that edge [Cohen & Wallace 1993, eq. 4.17;
//!   Baum, Rushmeier, Winget 1989]. Angles by `atan2` (accurate for tiny and near-π angles).
//! - [`disk`]: the lecture's disk approximation `F ≈ A cosθ cosθ' / (π r² + A)`.

use crate::math::DVec3;

/// Exact form factor from a differential area at `p` with unit normal `n` to a convex polygon
/// (counter-clockwise seen from its front).
///
/// One-sided: 0 when `p` is on or behind the polygon's plane (it radiates only from its front).
/// The polygon is first clipped against the receiver's tangent plane, so only the part in front
/// of `p` counts. Never NaN: a point on the polygon's edge or vertex gives the limit value.
#[must_use]
pub fn point_to_polygon(p: DVec3, n: DVec3, verts: &[DVec3]) -> f64 {
    let src_n = crate::math::newell_normal(verts);
    // One-sided source: p must be strictly in front of the source plane.
    let src_n_unit = src_n.normalize_or_zero();
    let dist_to_plane = src_n_unit.dot(p - verts[0]);
    let scale = verts.iter().map(|v| (*v - p).length()).fold(0.0, f64::max);
    if !(dist_to_plane > 1e-12 * scale) {
        return 0.0;
    }
    // Clip against the receiver's tangent plane: keep n·(v − p) ≥ 0.
    // A convex polygon clipped by one plane gains at most one vertex.
    let k = verts.len();
    let mut small = [DVec3::ZERO; 8];
    let mut large = Vec::new();
    let clipped: &mut [DVec3] = if k < 8 {
        &mut small
    } else {
        large.resize(k + 1, DVec3::ZERO);
        &mut large
    };
    let mut m = 0usize;
    for i in 0..k {
        let a = verts[i] - p;
        let b = verts[(i + 1) % k] - p;
        let da = n.dot(a);
        let db = n.dot(b);
        if da >= 0.0 {
            clipped[m] = a;
            m += 1;
        }
        if (da >= 0.0) != (db >= 0.0) {
            let t = da / (da - db);
            clipped[m] = a + (b - a) * t;
            m += 1;
        }
    }
    if m < 3 {
        return 0.0;
    }
    let mut sum = 0.0;
    for i in 0..m {
        let a = clipped[i];
        let b = clipped[(i + 1) % m];
        let c = a.cross(b);
        let cl = c.length();
        if cl <= 0.0 {
            continue;
        }
        let beta = cl.atan2(a.dot(b));
        sum += beta * n.dot(c) / cl;
    }
    (sum.abs() / (2.0 * std::f64::consts::PI)).min(1.0)
}

/// Disk approximation of the form factor from a differential area at `p` (unit normal `n`) to a
/// source of area `src_area` at `src_centroid` facing `src_normal`:
/// `F ≈ A cosθ cosθ' / (π r² + A)` (the lecture; exact for a coaxial disk). Cosines clamped at 0.
#[must_use]
pub fn disk(p: DVec3, n: DVec3, src_centroid: DVec3, src_normal: DVec3, src_area: f64) -> f64 {
    let d = src_centroid - p;
    let r2 = d.length_squared();
    if r2 <= 0.0 {
        return 1.0;
    }
    let r = r2.sqrt();
    let cos_r = (n.dot(d) / r).max(0.0);
    let cos_s = (-src_normal.dot(d) / r).max(0.0);
    src_area * cos_r * cos_s / (std::f64::consts::PI * r2 + src_area)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Closed form for a point under a coaxial disk: r²/(r²+h²); a 512-gon inscribed in the disk
    /// differs by O(1/512²) relative.
    #[test]
    fn point_to_many_sided_polygon_matches_disk_closed_form() {
        let (r, h) = (0.7, 1.3);
        let n_sides = 512;
        let verts: Vec<DVec3> = (0..n_sides)
            .rev() // clockwise from above = counter-clockwise seen from below (the front)
            .map(|i| {
                let a = 2.0 * std::f64::consts::PI * f64::from(i) / f64::from(n_sides);
                DVec3::new(r * a.cos(), r * a.sin(), h)
            })
            .collect();
        // The inscribed polygon lies between the disk of its apothem r·cos(π/n) and the disk of r.
        let t = 2.0 * std::f64::consts::PI / f64::from(n_sides);
        let f = point_to_polygon(DVec3::ZERO, DVec3::Z, &verts[..]);
        let f_in = r * r * (t / 2.0).cos().powi(2) / (r * r * (t / 2.0).cos().powi(2) + h * h);
        let f_out = r * r / (r * r + h * h);
        assert!(f > f_in - 1e-12 && f < f_out + 1e-12, "{f_in} <= {f} <= {f_out}");
    }

    #[test]
    fn behind_is_zero_and_clipping_halves_a_symmetric_polygon() {
        let sq = [
            DVec3::new(-1.0, -1.0, 1.0),
            DVec3::new(-1.0, 1.0, 1.0),
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(1.0, -1.0, 1.0),
        ];
        assert!(point_to_polygon(DVec3::ZERO, DVec3::Z, &sq) > 0.0);
        assert_eq!(point_to_polygon(DVec3::new(0.0, 0.0, 2.0), -DVec3::Z, &sq), 0.0);
        // Receivers facing +x and −x see mirror-image halves of the square: equal form factors.
        let fx = point_to_polygon(DVec3::ZERO, DVec3::X, &sq);
        let fmx = point_to_polygon(DVec3::ZERO, -DVec3::X, &sq);
        assert!((fx - fmx).abs() < 1e-14 && fx > 0.0);
    }

    #[test]
    fn closed_cube_sums_to_one_from_any_interior_point() {
        // Unit cube with inward-facing faces (CCW seen from inside).
        let c = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        let faces = [
            [c(0., 0., 0.), c(1., 0., 0.), c(1., 1., 0.), c(0., 1., 0.)], // floor z=0, normal +z
            [c(0., 0., 1.), c(0., 1., 1.), c(1., 1., 1.), c(1., 0., 1.)], // ceiling, normal −z
            [c(0., 0., 0.), c(0., 0., 1.), c(1., 0., 1.), c(1., 0., 0.)], // y=0, normal +y
            [c(0., 1., 0.), c(1., 1., 0.), c(1., 1., 1.), c(0., 1., 1.)], // y=1, normal −y
            [c(0., 0., 0.), c(0., 1., 0.), c(0., 1., 1.), c(0., 0., 1.)], // x=0, normal +x
            [c(1., 0., 0.), c(1., 0., 1.), c(1., 1., 1.), c(1., 1., 0.)], // x=1, normal −x
        ];
        for f in &faces {
            let n = crate::math::polygon_normal(f);
            assert!((n.dot(DVec3::splat(0.5) - f[0])) > 0.0, "face must point inward");
        }
        for (p, n) in
            [(c(0.3, 0.6, 0.0), DVec3::Z), (c(0.5, 0.5, 1.0), -DVec3::Z), (c(0.0, 0.2, 0.9), DVec3::X)]
        {
            let s: f64 = faces.iter().map(|f| point_to_polygon(p, n, f)).sum();
            assert!((s - 1.0).abs() < 1e-12, "sum {s}");
        }
    }

    #[test]
    fn disk_is_exact_for_coaxial_disk() {
        let (r, h) = (0.5_f64, 2.0_f64);
        let a = std::f64::consts::PI * r * r;
        let f = disk(DVec3::ZERO, DVec3::Z, DVec3::new(0.0, 0.0, h), -DVec3::Z, a);
        assert!((f - r * r / (r * r + h * h)).abs() < 1e-15);
    }
}
