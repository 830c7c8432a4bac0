//! Fixed Gauss–Legendre rules: the n-point rule on [0, 1] (Newton on Legendre polynomials), and
//! F from→to by an n×n product rule of the exact point kernel over each piece of the receiver —
//! cheap and smooth, accurate when the polygons are far apart compared with their size.

use super::pair::{pieces, prepare};
use super::point::point_to_polygon_unit;
use crate::math::DVec3;
use std::f64::consts::PI;

/// Nodes and weights of the n-point Gauss–Legendre rule on [0, 1] (Newton on Pₙ; n ≥ 1).
#[must_use]
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let n = n.max(1);
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        // Tricomi's initial guess, then Newton.
        let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let kf = k as f64;
                let p2 = ((2.0 * kf - 1.0) * x * p1 - (kf - 1.0) * p0) / kf;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let dx = p1 / dp;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        out.push((0.5 * (1.0 - x), 0.5 * w));
    }
    out.reverse();
    out
}

/// Form factor F from→to with a fixed n×n Gauss–Legendre rule over each piece of `from`
/// (n² kernel evaluations per piece). Cheap and smooth; accurate when the polygons are far
/// apart compared with their size, not near contact (use [`super::polygon_to_polygon`] there).
#[must_use]
pub fn polygon_to_polygon_fixed(from: &[DVec3], to: &[DVec3], n: usize) -> f64 {
    polygon_to_polygon_rule(from, to, &gauss_legendre(n))
}

/// [`polygon_to_polygon_fixed`] with the rule given (nodes and weights on [0, 1], as
/// [`gauss_legendre`] makes them), for callers that keep the rules instead of computing one
/// per pair.
#[must_use]
pub fn polygon_to_polygon_rule(from: &[DVec3], to: &[DVec3], rule: &[(f64, f64)]) -> f64 {
    let Some(p) = prepare(from, to) else { return 0.0 };
    let mut sum = 0.0;
    for pc in pieces(&p.front) {
        for &(u, wu) in rule {
            for &(v, wv) in rule {
                let j = pc.jacobian(u, v, p.normal_from);
                if j > 0.0 {
                    sum +=
                        wu * wv * j * point_to_polygon_unit(pc.point(u, v), p.normal_from, to, p.normal_to);
                }
            }
        }
    }
    (sum / p.area).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_integrates_polynomials_exactly() {
        for n in 1..=12 {
            let rule = gauss_legendre(n);
            assert!((rule.iter().map(|r| r.1).sum::<f64>() - 1.0).abs() < 1e-14);
            for deg in 0..2 * n {
                let s: f64 = rule.iter().map(|(x, w)| w * x.powi(deg as i32)).sum();
                assert!((s - 1.0 / (deg as f64 + 1.0)).abs() < 1e-13, "n={n} deg={deg}: {s}");
            }
        }
    }
}
