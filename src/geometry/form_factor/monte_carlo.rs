//! Monte Carlo form factors with their standard error: uniform points on the receiver scored
//! with the exact point kernel (bounded in [0, 1], so the variance stays finite for touching
//! polygons), and uniform points on the source scored with `A cosθ cosθ' / (π r²)`.

use super::pair::prepare;
use super::point::point_to_polygon_unit;
use crate::math::{DVec3, Pcg32, newell_normal, polygon_area};
use std::f64::consts::PI;

/// Uniformly distributed point on a convex polygon (fan triangles chosen by area, then the
/// square-root map).
fn sample_polygon(verts: &[DVec3], cumulative: &[f64], rng: &mut Pcg32) -> DVec3 {
    let total = *cumulative.last().unwrap_or(&0.0);
    let x = rng.next_f64() * total;
    let t = cumulative.partition_point(|&c| c <= x).min(cumulative.len() - 1);
    let (a, b, c) = (verts[0], verts[t + 1], verts[t + 2]);
    let su = rng.next_f64().sqrt();
    let v = rng.next_f64();
    a * (1.0 - su) + b * (su * (1.0 - v)) + c * (su * v)
}

/// Cumulative areas of the fan triangles of a convex polygon.
fn fan_cumulative(verts: &[DVec3]) -> Vec<f64> {
    let mut acc = 0.0;
    (1..verts.len() - 1)
        .map(|i| {
            acc += polygon_area(&[verts[0], verts[i], verts[i + 1]]);
            acc
        })
        .collect()
}

/// Mean and standard error of a sample sum.
fn mean_and_error(sum: f64, sum_sq: f64, n: u32) -> (f64, f64) {
    let nf = f64::from(n);
    let mean = sum / nf;
    let var = if n > 1 { ((sum_sq - sum * mean) / (nf - 1.0)).max(0.0) } else { f64::INFINITY };
    (mean, (var / nf).sqrt())
}

/// Monte Carlo estimate of F from→to and its standard error: `samples` independent uniform
/// points on `from`, each scored with the exact point kernel to `to`. The score is bounded in
/// [0, 1], so the variance is finite even for touching polygons (unlike the 1/r² area–area
/// estimator). `samples = 0` gives (0, ∞).
#[must_use]
pub fn polygon_to_polygon_mc(from: &[DVec3], to: &[DVec3], samples: u32, seed: u64) -> (f64, f64) {
    if samples == 0 {
        return (0.0, f64::INFINITY);
    }
    let Some(p) = prepare(from, to) else { return (0.0, 0.0) };
    // Sample the front part only; the rest scores 0, which the area ratio accounts for.
    let cumulative = fan_cumulative(&p.front);
    let ratio = cumulative.last().copied().unwrap_or(0.0) / p.area;
    let mut rng = Pcg32::keyed(seed, 0x0f0f_f0f0);
    let (mut s, mut s2) = (0.0, 0.0);
    for _ in 0..samples {
        let x = sample_polygon(&p.front, &cumulative, &mut rng);
        let f = point_to_polygon_unit(x, p.normal_from, to, p.normal_to);
        s += f;
        s2 += f * f;
    }
    let (mean, se) = mean_and_error(s, s2, samples);
    (mean * ratio, se * ratio)
}

/// Monte Carlo estimate of the point-to-polygon form factor and its standard error: `samples`
/// uniform points y on the polygon scored with `A cosθ cosθ' / (π r²)` (cosines clamped at 0,
/// the source one-sided). `samples = 0` gives (0, ∞).
#[must_use]
pub fn point_to_polygon_mc(p: DVec3, n: DVec3, verts: &[DVec3], samples: u32, seed: u64) -> (f64, f64) {
    if samples == 0 || verts.len() < 3 {
        return (0.0, if samples == 0 { f64::INFINITY } else { 0.0 });
    }
    let src = newell_normal(verts);
    let area = 0.5 * src.length();
    let src = src.normalize_or_zero();
    let cumulative = fan_cumulative(verts);
    let mut rng = Pcg32::keyed(seed, 0xf0f0_0f0f);
    let (mut s, mut s2) = (0.0, 0.0);
    for _ in 0..samples {
        let y = sample_polygon(verts, &cumulative, &mut rng);
        let d = y - p;
        let r2 = d.length_squared();
        let f = if r2 > 0.0 {
            let r = r2.sqrt();
            let cr = (n.dot(d) / r).max(0.0);
            let cs = (-src.dot(d) / r).max(0.0);
            area * cr * cs / (PI * r2)
        } else {
            0.0
        };
        if f.is_finite() {
            s += f;
            s2 += f * f;
        }
    }
    mean_and_error(s, s2, samples)
}
