//! Error of a solution against the independent reference, per element, per patch and per scene.
//!
//! For regions i (elements) of area a_i with solver radiosity B_i, reference B̂_i ± σ_i
//! (standard error) and emission E_i, per RGB channel c:
//!
//! ```text
//! rel L1  = Σ_i a_i Σ_c |B_ic − B̂_ic|  /  Σ_i a_i Σ_c |B̂_ic − E_ic|
//! rel L2  = √( Σ_i a_i Σ_c (B_ic − B̂_ic)²  /  Σ_i a_i Σ_c (B̂_ic − E_ic)² )          (RMS)
//! rel L∞  = max_i max_c |B_ic − B̂_ic|  /  R,   R = √( Σ a Σ_c (B̂ − E)² / (3 Σ a) )
//! ```
//!
//! Errors are relative to the **reflected** radiosity B − E: emission is exact in every method, and
//! a bright lamp would otherwise inflate the denominator and hide the error of everything else.
//! L∞ is relative to the RMS reflected radiosity R (not per element: a dark element's relative error
//! is unbounded and says nothing). The reference's own noise enters the L2 numerator as Σ a σ²;
//! [`Norms::l2_debiased`] subtracts it (E[(B − B̂)²] = (B − B)² + σ²), [`Norms::reference_noise`]
//! reports it, and a measured error below ~3× the noise is a measurement of the reference, not of
//! the solver.
//!
//! L∞ has the same problem, worse: the largest |ΔB| of a thousand elements is, for a perfect solver,
//! the largest of a thousand noise draws (≈ 3.5σ). So every comparison also reports
//!
//! ```text
//! debiased L∞ = max_i max_c (|B_ic − B̂_ic| − k σ_ic)₊ / R,    k = √(2 ln(3N / α)),  α = 0.05
//! ```
//!
//! over N regions (3N channel values): by the Gaussian tail bound P(|Z| > k) ≤ e^(−k²/2) and a
//! union bound, a perfect solver reads 0 with probability ≥ 95 % (when σ is right; below ~1000
//! paths per region σ runs low, see [`crate::eval::reference`]). k is 4.7 for 1000 regions, 5.1 for
//! 10 000. And the robust alternatives [`Norms::p95`] / [`Norms::p99`]: the area-weighted 95th /
//! 99th percentile of the per-region error |ΔB| (mean over channels) / R — the level that 5 % / 1 %
//! of the area exceeds; one noisy element cannot move them.
//!
//! **Pointwise**: [`crate::eval::pointwise`] evaluates a solution at the points of the pointwise
//! reference and takes the same norms with each point weighted by the area of its cell — the
//! default figure of `radlab bench` and `radlab reference --compare`; this module's
//! element-average comparisons stay beside it.
//!
//! When the reference was computed on other regions than the solution's elements (a fixed
//! reference mesh, cached once per scene), [`resample`] evaluates the solution's piecewise-constant
//! radiosity at a grid of area-uniform points in each reference region and averages them.
//!
//! Also: the energy-balance residual (`EnergyBalance::relative_residual`), Spearman's rank
//! correlation [Spearman 1904] (how well the solver's own error estimate ranks the true error),
//! and an image of the per-element error (see [`error_image`]).

use crate::eval::reference::{Estimate, RefElement};
use crate::geometry::area_map::area_point;
use crate::math::{DVec3, Rgb, orthonormal_basis};
use crate::scene::Scene;
use crate::solver::{Solution, SolvedElement};
use serde::Serialize;

/// Errors of the metrics.
#[derive(Debug, thiserror::Error)]
pub enum MetricsError {
    #[error("metrics: {solution} solution values for {reference} reference values")]
    LengthMismatch { solution: usize, reference: usize },
    #[error("metrics: region {index} lies on patch {patch}, but the scene has {patches} patches")]
    BadPatch { index: usize, patch: usize, patches: usize },
}

/// Relative error norms of a set of regions (see the module docs for the formulas).
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize)]
pub struct Norms {
    pub l1: f64,
    pub l2: f64,
    /// √(max(0, Σ a (ΔB² − σ²))) / denominator: the L2 with the reference's noise taken out.
    pub l2_debiased: f64,
    /// Not debiased: includes the reference's noise (see the module docs).
    pub linf: f64,
    /// max (|ΔB| − kσ)₊ / R: L∞ with the reference's noise taken out (module docs).
    pub linf_debiased: f64,
    /// Area-weighted 95th percentile of the per-region |ΔB| (mean over channels) / R.
    pub p95: f64,
    /// Area-weighted 99th percentile of the per-region |ΔB| (mean over channels) / R.
    pub p99: f64,
    /// √(Σ a σ²) / denominator: the L2 error a perfect solver would show against this reference.
    pub reference_noise: f64,
    /// The smallest L2 error this comparison resolves: 2 × the standard deviation of the
    /// debiased squared error, ≈ 2 · noise · (2/N)^¼ for N regions of similar area and noise
    /// (the debiased Σ a(ΔB² − σ²) still fluctuates by ≈ noise² √(2/N)). Below it, read "< resolution".
    pub resolution: f64,
    /// Area these norms cover.
    pub area: f64,
}

/// Error norms of one input patch.
#[derive(Clone, Debug, Serialize)]
pub struct PatchError {
    pub patch: usize,
    pub name: String,
    pub norms: Norms,
    /// Area-weighted mean radiosity, solution and reference.
    pub solution: Rgb,
    pub reference: Rgb,
}

/// The error of a solution against a reference.
#[derive(Clone, Debug, Serialize)]
pub struct ErrorReport {
    pub scene: Norms,
    pub per_patch: Vec<PatchError>,
    /// Per region: |ΔB| (mean over channels) / R, the quantity the error image shows.
    pub per_element: Vec<f64>,
    /// The solver's own energy-balance residual, |emitted − absorbed − escaped| / emitted.
    pub energy_residual: f64,
}

/// Accumulates the sums behind [`Norms`].
#[derive(Copy, Clone, Default)]
struct Sums {
    area: f64,
    abs: f64,
    sq: f64,
    noise: f64,
    ref_abs: f64,
    ref_sq: f64,
    max_abs: f64,
    max_debiased: f64,
}

impl Sums {
    /// One region: area a, solver value b, reference r, emission e; k: the noise multiple
    /// [`linf_sigmas`] for the debiased L∞.
    fn add(&mut self, a: f64, b: Rgb, r: &Estimate, e: Rgb, k: f64) {
        self.area += a;
        for c in 0..3 {
            let d = b.0[c] - r.radiosity.0[c];
            let refl = r.radiosity.0[c] - e.0[c];
            self.abs += a * d.abs();
            self.sq += a * d * d;
            self.noise += a * r.std_error.0[c] * r.std_error.0[c];
            self.ref_abs += a * refl.abs();
            self.ref_sq += a * refl * refl;
            self.max_abs = self.max_abs.max(d.abs());
            self.max_debiased = self.max_debiased.max(d.abs() - k * r.std_error.0[c]);
        }
    }
    /// RMS reflected radiosity R (per channel).
    fn rms(&self) -> f64 {
        if self.area > 0.0 { (self.ref_sq / (3.0 * self.area)).sqrt() } else { 0.0 }
    }
    /// `errors`: (area, |ΔB| mean over channels) of the regions, for the percentiles.
    fn norms(&self, regions: usize, errors: &mut [(f64, f64)]) -> Norms {
        let div = |n: f64, d: f64| {
            if d > 0.0 {
                n / d
            } else if n > 0.0 {
                f64::INFINITY
            } else {
                0.0
            }
        };
        Norms {
            l1: div(self.abs, self.ref_abs),
            l2: div(self.sq, self.ref_sq).sqrt(),
            l2_debiased: div((self.sq - self.noise).max(0.0), self.ref_sq).sqrt(),
            linf: div(self.max_abs, self.rms()),
            linf_debiased: div(self.max_debiased.max(0.0), self.rms()),
            p95: div(weighted_quantile(errors, 0.95), self.rms()),
            p99: div(weighted_quantile(errors, 0.99), self.rms()),
            reference_noise: div(self.noise, self.ref_sq).sqrt(),
            resolution: 2.0 * div(self.noise, self.ref_sq).sqrt() * (2.0 / regions.max(1) as f64).powf(0.25),
            area: self.area,
        }
    }
}

/// Probability that a perfect solver's debiased L∞ is nonzero (module docs).
pub const LINF_FALSE_ALARM: f64 = 0.05;

/// The noise multiple k of the debiased L∞ for `regions` regions: √(2 ln(3N/α)), α = [`LINF_FALSE_ALARM`].
#[must_use]
pub fn linf_sigmas(regions: usize) -> f64 {
    (2.0 * (3.0 * regions.max(1) as f64 / LINF_FALSE_ALARM).ln()).sqrt()
}

/// The area-weighted q-quantile of (area, value) pairs: the smallest value v such that regions
/// with value ≤ v hold at least a fraction q of the area. Sorts `xs`; 0 when empty.
#[must_use]
pub fn weighted_quantile(xs: &mut [(f64, f64)], q: f64) -> f64 {
    xs.sort_by(|a, b| a.1.total_cmp(&b.1));
    let total: f64 = xs.iter().map(|x| x.0).sum();
    let mut acc = 0.0;
    for &(a, v) in xs.iter() {
        acc += a;
        if acc >= q * total {
            return v;
        }
    }
    xs.last().map_or(0.0, |x| x.1)
}

/// Compare solver values on regions (patch, area, emission) with reference estimates on the
/// same regions, in the same order.
pub fn compare_regions(
    scene: &Scene,
    regions: &[(usize, f64)],
    values: &[Rgb],
    reference: &[Estimate],
    energy_residual: f64,
) -> Result<ErrorReport, MetricsError> {
    if values.len() != reference.len() || regions.len() != reference.len() {
        return Err(MetricsError::LengthMismatch { solution: values.len(), reference: reference.len() });
    }
    let np = scene.patches.len();
    let mut scene_sums = Sums::default();
    let mut patch_sums = vec![Sums::default(); np];
    let mut patch_n = vec![0usize; np];
    let mut patch_b = vec![(Rgb::ZERO, Rgb::ZERO); np];
    let k = linf_sigmas(regions.len());
    for (index, (&(patch, area), (b, r))) in regions.iter().zip(values.iter().zip(reference)).enumerate() {
        if patch >= np {
            return Err(MetricsError::BadPatch { index, patch, patches: np });
        }
        let e = scene.patches[patch].emission;
        scene_sums.add(area, *b, r, e, k);
        patch_sums[patch].add(area, *b, r, e, k);
        patch_n[patch] += 1;
        patch_b[patch].0 += *b * area;
        patch_b[patch].1 += r.radiosity * area;
    }
    let rms = scene_sums.rms();
    let abs_err: Vec<f64> =
        values.iter().zip(reference).map(|(b, r)| (*b - r.radiosity).map(f64::abs).mean()).collect();
    let per_element = abs_err.iter().map(|&d| if rms > 0.0 { d / rms } else { d }).collect();
    // (area, |ΔB|) per region, and grouped by patch, for the percentiles.
    let mut patch_errors: Vec<Vec<(f64, f64)>> = vec![Vec::new(); np];
    for (&(patch, area), &d) in regions.iter().zip(&abs_err) {
        patch_errors[patch].push((area, d));
    }
    let mut all: Vec<(f64, f64)> = regions.iter().zip(&abs_err).map(|(r, &d)| (r.1, d)).collect();
    let per_patch = patch_sums
        .iter()
        .enumerate()
        .filter(|(_, s)| s.area > 0.0)
        .map(|(i, s)| PatchError {
            patch: i,
            name: scene.patches[i].name.clone(),
            norms: s.norms(patch_n[i], &mut patch_errors[i]),
            solution: patch_b[i].0 / s.area,
            reference: patch_b[i].1 / s.area,
        })
        .collect();
    Ok(ErrorReport {
        scene: scene_sums.norms(regions.len(), &mut all),
        per_patch,
        per_element,
        energy_residual,
    })
}

/// Compare a solution with a reference computed on its own elements (same order).
pub fn compare_solution(
    scene: &Scene,
    solution: &Solution,
    reference: &[Estimate],
) -> Result<ErrorReport, MetricsError> {
    let regions: Vec<(usize, f64)> = solution.elements.iter().map(|e| (e.patch, e.area)).collect();
    let values: Vec<Rgb> = solution.elements.iter().map(|e| e.radiosity).collect();
    compare_regions(scene, &regions, &values, reference, solution.energy.relative_residual())
}

/// Compare a solution with a reference computed on other regions (e.g. [`crate::eval::reference::reference_mesh`]):
/// the solution is first [`resample`]d onto them.
pub fn compare_resampled(
    scene: &Scene,
    solution: &Solution,
    ref_elements: &[RefElement],
    reference: &[Estimate],
) -> Result<ErrorReport, MetricsError> {
    let values = resample(scene, &solution.elements, ref_elements)?;
    let regions: Vec<(usize, f64)> =
        ref_elements.iter().map(|e| (e.patch, crate::math::polygon_area(&e.vertices))).collect();
    compare_regions(scene, &regions, &values, reference, solution.energy.relative_residual())
}

/// Points per side of the grid at which [`resample`] evaluates a solution inside each region.
pub const RESAMPLE_GRID: u32 = 6;

/// A [`Locator`] per patch over the elements that lie on it (`None` for a patch without
/// elements). Errors if an element names a patch the scene lacks.
pub(crate) fn patch_locators(
    scene: &Scene,
    elements: &[SolvedElement],
) -> Result<Vec<Option<Locator>>, MetricsError> {
    let np = scene.patches.len();
    let mut by_patch: Vec<Vec<usize>> = vec![Vec::new(); np];
    for (i, e) in elements.iter().enumerate() {
        if e.patch >= np {
            return Err(MetricsError::BadPatch { index: i, patch: e.patch, patches: np });
        }
        by_patch[e.patch].push(i);
    }
    Ok(by_patch
        .iter()
        .enumerate()
        .map(|(p, ids)| (!ids.is_empty()).then(|| Locator::new(scene.patches[p].normal, elements, ids)))
        .collect())
}

/// Average of a solution's piecewise-constant radiosity over each region: the area-weighted mean
/// over a RESAMPLE_GRID² grid of points (see `grid_point`). A point that falls in no element
/// (a gap of rounding size along an edge) takes the nearest element's value on the same patch.
pub fn resample(
    scene: &Scene,
    elements: &[SolvedElement],
    regions: &[RefElement],
) -> Result<Vec<Rgb>, MetricsError> {
    let np = scene.patches.len();
    let locators = patch_locators(scene, elements)?;
    let g = RESAMPLE_GRID;
    regions
        .iter()
        .enumerate()
        .map(|(index, r)| {
            let Some(Some(loc)) = locators.get(r.patch) else {
                return if r.patch < np {
                    Ok(scene.patches[r.patch].emission) // no element on this patch: nothing solved
                } else {
                    Err(MetricsError::BadPatch { index, patch: r.patch, patches: np })
                };
            };
            let mut sum = Rgb::ZERO;
            let mut wsum = 0.0;
            for j in 0..g {
                for i in 0..g {
                    let u = (f64::from(i) + 0.5) / f64::from(g);
                    let v = (f64::from(j) + 0.5) / f64::from(g);
                    let (x, w) = grid_point(&r.vertices, u, v);
                    sum += elements[loc.locate(x, elements)].radiosity * w;
                    wsum += w;
                }
            }
            Ok(if wsum > 0.0 { sum / wsum } else { Rgb::ZERO })
        })
        .collect()
}

/// A quadrature point of a region and its weight: bilinear on quads (weight = the map's Jacobian,
/// so a grid of cell centres is the midpoint rule and splits evenly into sub-quads), the
/// area-uniform map on triangles (weight 1).
fn grid_point(verts: &[DVec3], u: f64, v: f64) -> (DVec3, f64) {
    if verts.len() == 4 {
        let x = verts[0].lerp(verts[1], u).lerp(verts[3].lerp(verts[2], u), v);
        let du = (verts[1] - verts[0]).lerp(verts[2] - verts[3], v);
        let dv = (verts[3] - verts[0]).lerp(verts[2] - verts[1], u);
        (x, du.cross(dv).length())
    } else {
        (area_point(verts, u, v), 1.0)
    }
}

/// Point location among the elements of one patch: a uniform 2-D bucket grid in the patch plane.
pub(crate) struct Locator {
    t: DVec3,
    b: DVec3,
    min: [f64; 2],
    cell: [f64; 2],
    n: usize,
    buckets: Vec<Vec<usize>>,
    ids: Vec<usize>,
}

impl Locator {
    pub(crate) fn new(normal: DVec3, elements: &[SolvedElement], ids: &[usize]) -> Self {
        let (t, b) = orthonormal_basis(normal);
        let proj = |x: DVec3| [x.dot(t), x.dot(b)];
        let mut min = [f64::INFINITY; 2];
        let mut max = [f64::NEG_INFINITY; 2];
        for &i in ids {
            for v in &elements[i].vertices {
                let p = proj(*v);
                for k in 0..2 {
                    min[k] = min[k].min(p[k]);
                    max[k] = max[k].max(p[k]);
                }
            }
        }
        let n = ((ids.len() as f64).sqrt().ceil() as usize).clamp(1, 256);
        let cell = [
            ((max[0] - min[0]) / n as f64).max(f64::MIN_POSITIVE),
            ((max[1] - min[1]) / n as f64).max(f64::MIN_POSITIVE),
        ];
        let mut buckets = vec![Vec::new(); n * n];
        for &i in ids {
            let mut lo = [f64::INFINITY; 2];
            let mut hi = [f64::NEG_INFINITY; 2];
            for v in &elements[i].vertices {
                let p = proj(*v);
                for k in 0..2 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
            let c0 = |k: usize, x: f64| (((x - min[k]) / cell[k]).floor().max(0.0) as usize).min(n - 1);
            for cy in c0(1, lo[1])..=c0(1, hi[1]) {
                for cx in c0(0, lo[0])..=c0(0, hi[0]) {
                    buckets[cy * n + cx].push(i);
                }
            }
        }
        Locator { t, b, min, cell, n, buckets, ids: ids.to_vec() }
    }

    /// The element containing x (or the nearest by centroid among the bucket's, else the patch's).
    pub(crate) fn locate(&self, x: DVec3, elements: &[SolvedElement]) -> usize {
        let p = [x.dot(self.t), x.dot(self.b)];
        let c = |k: usize| (((p[k] - self.min[k]) / self.cell[k]).floor().max(0.0) as usize).min(self.n - 1);
        let bucket = &self.buckets[c(1) * self.n + c(0)];
        let proj = |v: DVec3| [v.dot(self.t) - p[0], v.dot(self.b) - p[1]];
        let inside = |i: usize| {
            let vs = &elements[i].vertices;
            let mut sign = 0.0f64;
            for k in 0..vs.len() {
                let a = proj(vs[k]);
                let b = proj(vs[(k + 1) % vs.len()]);
                let cross = a[0] * b[1] - a[1] * b[0];
                if cross != 0.0 {
                    if sign == 0.0 {
                        sign = cross.signum();
                    } else if cross.signum() != sign {
                        return false;
                    }
                }
            }
            true
        };
        if let Some(&i) = bucket.iter().find(|&&i| inside(i)) {
            return i;
        }
        let candidates: &[usize] = if bucket.is_empty() { &self.ids } else { bucket };
        let dist = |i: usize| {
            let vs = &elements[i].vertices;
            let c = vs.iter().copied().sum::<DVec3>() / vs.len() as f64;
            let q = proj(c);
            q[0] * q[0] + q[1] * q[1]
        };
        *candidates.iter().min_by(|&&a, &&b| dist(a).total_cmp(&dist(b))).expect("a locator has elements")
    }
}

/// Ranks with ties averaged (1-based), for Spearman's correlation.
#[must_use]
pub fn ranks(xs: &[f64]) -> Vec<f64> {
    let mut idx: Vec<usize> = (0..xs.len()).collect();
    idx.sort_by(|&a, &b| xs[a].total_cmp(&xs[b]));
    let mut r = vec![0.0; xs.len()];
    let mut i = 0;
    while i < idx.len() {
        let mut j = i;
        while j + 1 < idx.len() && xs[idx[j + 1]] == xs[idx[i]] {
            j += 1;
        }
        let avg = (i + j) as f64 / 2.0 + 1.0;
        for &k in &idx[i..=j] {
            r[k] = avg;
        }
        i = j + 1;
    }
    r
}

/// Pearson correlation of two equally long series (0 when either is constant or they are shorter than 2).
#[must_use]
pub fn pearson(xs: &[f64], ys: &[f64]) -> f64 {
    let n = xs.len().min(ys.len());
    if n < 2 {
        return 0.0;
    }
    let mx = xs[..n].iter().sum::<f64>() / n as f64;
    let my = ys[..n].iter().sum::<f64>() / n as f64;
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let (dx, dy) = (xs[i] - mx, ys[i] - my);
        sxy += dx * dy;
        sxx += dx * dx;
        syy += dy * dy;
    }
    if sxx > 0.0 && syy > 0.0 { sxy / (sxx * syy).sqrt() } else { 0.0 }
}

/// Spearman's rank correlation ρ_s: the Pearson correlation of the ranks (ties averaged).
#[must_use]
pub fn spearman(xs: &[f64], ys: &[f64]) -> f64 {
    pearson(&ranks(xs), &ranks(ys))
}

/// How well a solution's own per-element error estimates rank the true error against a reference
/// on its elements: Spearman's ρ between `error_estimate` and |ΔB| (mean over channels), over
/// the elements that have an estimate. `None` when fewer than 3 have one.
#[must_use]
pub fn estimate_rank_correlation(solution: &Solution, reference: &[Estimate]) -> Option<f64> {
    let (est, err): (Vec<f64>, Vec<f64>) = solution
        .elements
        .iter()
        .zip(reference)
        .filter_map(|(e, r)| e.error_estimate.map(|x| (x, (e.radiosity - r.radiosity).map(f64::abs).mean())))
        .unzip();
    (est.len() >= 3).then(|| spearman(&est, &err))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weighted_quantile_counts_area() {
        // Areas 1, 1, 8: the value 3 holds 80 % of the area.
        let mut xs = [(8.0, 3.0), (1.0, 1.0), (1.0, 2.0)];
        assert_eq!(weighted_quantile(&mut xs, 0.1), 1.0);
        assert_eq!(weighted_quantile(&mut xs, 0.2), 2.0);
        assert_eq!(weighted_quantile(&mut xs, 0.21), 3.0);
        assert_eq!(weighted_quantile(&mut xs, 0.99), 3.0);
        assert_eq!(weighted_quantile(&mut [], 0.5), 0.0);
    }

    #[test]
    fn linf_sigmas_bound_the_false_alarm_rate() {
        // 3N · e^(−k²/2) = α by construction (the Gaussian tail bound P(|Z| > k) ≤ e^(−k²/2)).
        for n in [1usize, 100, 1000, 100_000] {
            let k = linf_sigmas(n);
            assert!((3.0 * n as f64 * (-k * k / 2.0).exp() - LINF_FALSE_ALARM).abs() < 1e-12);
        }
        assert!((linf_sigmas(1000) - 4.69).abs() < 0.01);
    }

    #[test]
    fn ranks_average_ties() {
        assert_eq!(ranks(&[10.0, 30.0, 20.0, 20.0]), vec![1.0, 4.0, 2.5, 2.5]);
    }

    #[test]
    fn spearman_is_one_for_monotone_and_minus_one_for_reversed() {
        let x: Vec<f64> = (0..20).map(f64::from).collect();
        let y: Vec<f64> = x.iter().map(|v| v.powi(3) + 1.0).collect();
        let z: Vec<f64> = x.iter().map(|v| (-v).exp()).collect();
        assert!((spearman(&x, &y) - 1.0).abs() < 1e-12);
        assert!((spearman(&x, &z) + 1.0).abs() < 1e-12);
        assert_eq!(spearman(&x, &[1.0; 20]), 0.0);
    }
}
