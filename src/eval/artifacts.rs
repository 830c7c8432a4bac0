//! The five meshing artifacts of the lecture, measured: for a solution against a reference, one
//! number per artifact.
//!
//! The reference is anything that gives B at any point of any patch ([`Reconstruction`]): the
//! closed form of a single-bounce scene ([`crate::geometry::exact::SingleBounce::patch_radiosity_at`]), or
//! a fine solve's reconstruction. The solution is read through its piecewise-constant
//! reconstruction ([`PiecewiseConstant`]): B(x) = B_e of the leaf element e holding x;
//! [`measure_views`] reads it through given views instead (a p = 1 solution's own functions) and
//! also returns where each artifact lies ([`ArtifactMaps`], drawn by
//! [`crate::present::artifact_pictures`]; `radlab artifacts`). Only patches that reflect (ρ̄ > 0) are
//! examined: the rest hold B = E, constant by construction.
//!
//! Every patch is sampled on a grid of equal-area cells; A is the pointwise error in the penumbra
//! band, B the share of the reference's features (shadows, highlights) the solution does not
//! show, C the Mach bands of the Gouraud view at element edges, D the value jumps at element
//! edges where the reference is continuous, E the critical segments that bound a shadow left
//! inside elements. The exact definitions and thresholds, and what the five read on the built-in
//! scenes, are in docs/meshing.md, "The five artifacts".
//!
//! The lecture's artifacts: Lischinski, Tampieri & Greenberg 1992, "Discontinuity meshing for
//! accurate radiosity", IEEE CG&A 12(6), Fig. 1 (blocky shadows, missing features, Mach bands,
//! inappropriate shading discontinuities, unresolved discontinuities).

use crate::eval::metrics::MetricsError;
use crate::eval::penumbra::{BandParams, band};
use crate::eval::pointwise::{PiecewiseConstant, Reconstruction, compare_points_in};
use crate::eval::reference::{Cell, Estimate, RefPoint};
use crate::geometry::accel::Accel;
use crate::geometry::area_map::area_point;
use crate::math::{DVec3, Rgb};
use crate::mesh::DEFAULT_SNAP;
use crate::mesh::discontinuity::scene_segments;
use crate::mesh::grade::shadow_segments;
use crate::scene::Scene;
use crate::solver::Solution;
use rayon::prelude::*;
use serde::Serialize;

/// Settings of [`measure`] (module docs name each).
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct ArtifactParams {
    /// Grid points per side of every reflecting patch (A and B).
    pub side: u32,
    /// The penumbra band of A.
    pub band: BandParams,
    /// τ of B: a feature departs from its patch mean by more than this fraction of it.
    pub feature: f64,
    /// Features smaller than this many grid points are not counted (B).
    pub min_feature_points: usize,
    /// A jump in B̄ larger than this fraction of the patch mean is visible (D).
    pub jump: f64,
    /// Samples per element edge (D).
    pub edge_samples: u32,
    /// Samples per critical segment (E).
    pub segment_samples: u32,
    /// A segment sample this close to an element edge (× patch diameter) is resolved (E).
    pub on_edge: f64,
    /// Distance of E's error points from the segment (× patch diameter).
    pub near: f64,
    /// Side of the shadow-ray grid on the emitter that decides which critical segments bound a
    /// shadow and count for E ([`crate::mesh::grade::shadow_segments`]; side² rays a point).
    pub shadow_side: u32,
}

impl ArtifactParams {
    /// 64 × 64 points a patch, features at 25 % of the patch mean (a shadow a viewer sees at a
    /// glance) and at least 4 points, jumps at 2 % (about the Weber fraction of brightness),
    /// 8 samples an edge, 16 a segment, resolved within 10⁻⁴ of the patch's size (the D-mesh
    /// snaps far closer), error points 1 % of the patch's size from the segment, segments
    /// kept by an 8 × 8 shadow grid (the grading's, [`crate::mesh::grade::GradeParams`]).
    #[must_use]
    pub const fn standard() -> ArtifactParams {
        ArtifactParams {
            side: 64,
            band: BandParams::standard(),
            feature: 0.25,
            min_feature_points: 4,
            jump: 0.02,
            edge_samples: 8,
            segment_samples: 16,
            on_edge: 1e-4,
            near: 0.01,
            shadow_side: 8,
        }
    }

    /// [`Self::standard`] on a 32 × 32 grid (tests).
    #[must_use]
    pub const fn quick() -> ArtifactParams {
        ArtifactParams { side: 32, ..Self::standard() }
    }
}

impl Default for ArtifactParams {
    fn default() -> Self {
        Self::standard()
    }
}

/// B: features of the reference and how many the solution misses.
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize)]
pub struct MissingFeatures {
    pub features: usize,
    pub missing: usize,
    /// Missing features' area / all features' area.
    pub area_fraction: f64,
}

impl MissingFeatures {
    /// missing / features (0 without features).
    #[must_use]
    pub fn fraction(&self) -> f64 {
        if self.features == 0 { 0.0 } else { self.missing as f64 / self.features as f64 }
    }
}

/// D: interior element edges and the length of their inappropriate jumps.
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize)]
pub struct ShadingJumps {
    /// Interior edge length sampled (each interior edge once).
    pub edge_length: f64,
    /// Of which carries a visible jump where the reference is continuous.
    pub inappropriate_length: f64,
    /// Length-weighted mean of J / m_p over the inappropriate samples.
    pub mean_jump: f64,
}

impl ShadingJumps {
    /// inappropriate / interior edge length (0 without interior edges).
    #[must_use]
    pub fn fraction(&self) -> f64 {
        if self.edge_length > 0.0 { self.inappropriate_length / self.edge_length } else { 0.0 }
    }
}

/// C: interior element edges and the length where the Gouraud reconstruction kinks.
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize)]
pub struct MachBands {
    /// Interior edge length sampled (as D's).
    pub edge_length: f64,
    /// Of which the Gouraud reconstruction's slope jumps visibly where the reference's does not.
    pub band_length: f64,
}

impl MachBands {
    /// band / interior edge length (0 without interior edges).
    #[must_use]
    pub fn fraction(&self) -> f64 {
        if self.edge_length > 0.0 { self.band_length / self.edge_length } else { 0.0 }
    }
}

/// E: critical segments and how much of them falls inside elements.
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize)]
pub struct UnresolvedDiscontinuities {
    /// Segments that bound a shadow ([`crate::mesh::grade::shadow_segments`]), the ones scored.
    pub segments: usize,
    /// Segments found but not scored: no penumbra beside them (inside an umbra, in full light),
    /// so no discontinuity of B lies on them.
    pub dropped: usize,
    pub length: f64,
    pub unresolved_length: f64,
    /// Rel L2 error at the points beside unresolved samples; `None` when there are none.
    pub error_beside: Option<f64>,
}

impl UnresolvedDiscontinuities {
    /// unresolved / all segment length (0 without segments).
    #[must_use]
    pub fn fraction(&self) -> f64 {
        if self.length > 0.0 { self.unresolved_length / self.length } else { 0.0 }
    }
}

/// The five artifacts of one solution (module docs).
#[derive(Clone, Debug, Serialize)]
pub struct ArtifactReport {
    /// A: rel L2 in the penumbra band (`None`: no band), and the band's grid points.
    pub blocky_shadows: Option<f64>,
    pub band_points: usize,
    pub missing_features: MissingFeatures,
    pub mach_bands: MachBands,
    pub shading_jumps: ShadingJumps,
    pub unresolved: UnresolvedDiscontinuities,
}

/// Why [`measure`] failed.
#[derive(Debug, thiserror::Error)]
pub enum ArtifactError {
    #[error(transparent)]
    Metrics(#[from] MetricsError),
    #[error("critical segments: {0}")]
    Mesh(#[from] crate::mesh::MeshError),
}

/// Measure the artifacts of `solution` against `reference` (module docs).
pub fn measure<R: Reconstruction + ?Sized>(
    scene: &Scene,
    solution: &Solution,
    reference: &R,
    params: &ArtifactParams,
) -> Result<ArtifactReport, ArtifactError> {
    let pc = PiecewiseConstant::new(scene, &solution.elements)?;
    let gouraud = Gouraud::new(scene, solution)?;
    Ok(measure_all(scene, solution, &pc, None, &gouraud, reference, params)?.0)
}

/// [`measure`] with the solution read through given views, and where each artifact lies
/// ([`ArtifactMaps`], for pictures): `values` is what A, B, D and E read (the flat view of a
/// p = 0 solution, [`PiecewiseConstant`]; a p = 1 solution's own functions,
/// [`crate::eval::reconstruction::Nodal`]), `shaded` what C reads for kinks ([`Gouraud`] for p = 0, the
/// same p = 1 functions for p = 1). The elements of `solution` give the edges and locate the
/// points. D's jump is `values` on both sides of the edge ([`measure`] takes the two elements'
/// averages: the same for constant elements, not for leaves that carry a slope).
pub fn measure_views<R: Reconstruction + ?Sized>(
    scene: &Scene,
    solution: &Solution,
    values: &dyn Reconstruction,
    shaded: &dyn Reconstruction,
    reference: &R,
    params: &ArtifactParams,
) -> Result<(ArtifactReport, ArtifactMaps), ArtifactError> {
    measure_all(scene, solution, values, Some(values), shaded, reference, params)
}

/// [`measure_views`], D's jumps read on `jumps` (`None`: the element averages).
fn measure_all<R: Reconstruction + ?Sized>(
    scene: &Scene,
    solution: &Solution,
    values: &dyn Reconstruction,
    jumps: Option<&dyn Reconstruction>,
    shaded: &dyn Reconstruction,
    reference: &R,
    params: &ArtifactParams,
) -> Result<(ArtifactReport, ArtifactMaps), ArtifactError> {
    let pc = PiecewiseConstant::new(scene, &solution.elements)?;
    let points = grid_points(scene, params.side);
    let sol: Vec<Rgb> = crate::eval::pointwise::evaluate(values, &points);
    let refs: Vec<Rgb> = crate::eval::pointwise::evaluate(reference, &points);
    let means = patch_means(scene, &points, &refs, &sol);

    // A
    let accel = Accel::build(scene);
    let estimates: Vec<Estimate> =
        refs.iter().map(|&radiosity| Estimate { radiosity, std_error: Rgb::ZERO }).collect();
    let in_band = band(scene, &accel, &points, &estimates, &params.band);
    let band_points = in_band.iter().filter(|&&b| b).count();
    let blocky_shadows = compare_points_in(scene, &points, &sol, &estimates, &in_band, 0.0)?
        .map(|s| s.report.scene.l2_debiased);

    let samples = interior_edge_samples(scene, solution, &pc, &means, params);
    let (missing_features, features) = missing_features(&points, &refs, &sol, &means, params);
    let (mach_bands, mach) = mach_bands(solution, &samples, shaded, reference, &means, params);
    let (shading_jumps, jump_marks) = shading_jumps(solution, &samples, jumps, reference, &means, params);
    let (unresolved, segments) = unresolved(scene, &accel, solution, &pc, values, reference, params)?;
    let edges = samples
        .iter()
        .zip(mach.iter().zip(&jump_marks))
        .map(|(s, (&mach_band, &jump))| EdgeMark {
            patch: s.patch,
            x: s.x,
            along: s.n.cross(scene.patches[s.patch].normal),
            length: 2.0 * s.weight,
            mach_band,
            jump,
        })
        .collect();
    let report = ArtifactReport {
        blocky_shadows,
        band_points,
        missing_features,
        mach_bands,
        shading_jumps,
        unresolved,
    };
    let maps =
        ArtifactMaps { points, solution: sol, reference: refs, means, in_band, features, edges, segments };
    Ok((report, maps))
}

/// One interior element-edge sample (C, D): its point, the edge's direction, the length it
/// stands for, and whether it is a Mach band (C) or an inappropriate jump (D).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct EdgeMark {
    pub patch: usize,
    pub x: DVec3,
    pub along: DVec3,
    pub length: f64,
    pub mach_band: bool,
    pub jump: bool,
}

/// One critical-segment sample (E): its point, the segment's direction, the length it stands
/// for, and whether it lies inside an element.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct SegmentMark {
    pub patch: usize,
    pub x: DVec3,
    pub along: DVec3,
    pub length: f64,
    pub unresolved: bool,
}

/// Where the artifacts of [`measure_views`] lie.
#[derive(Clone, Debug)]
pub struct ArtifactMaps {
    /// The `side × side` grid of every reflecting patch, in patch order, row by row (A, B).
    pub points: Vec<RefPoint>,
    /// The solution's (`values`) and the reference's B at the grid points.
    pub solution: Vec<Rgb>,
    pub reference: Vec<Rgb>,
    /// Per patch: (m_p, s_p), the reference's and the solution's mean of B̄ over the grid.
    pub means: Vec<(f64, f64)>,
    /// Grid points in the penumbra band (A).
    pub in_band: Vec<bool>,
    /// Per grid point (B): 0 no counted feature, +1 a point of a feature shown, −1 of a missing one.
    pub features: Vec<i8>,
    /// Interior edge samples (C, D).
    pub edges: Vec<EdgeMark>,
    /// Critical-segment samples (E).
    pub segments: Vec<SegmentMark>,
}

/// A grid point of A or B, for an overlay.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct PointMark {
    pub patch: usize,
    pub x: DVec3,
    /// Side of the grid cell around it (√ of its area).
    pub size: f64,
    /// A: |B̄ − B̄_ref| / the band's RMS reflected radiosity; B: 0.
    pub value: f64,
    /// B: the feature holding this point is missing; A: always false.
    pub flagged: bool,
}

/// Where [`measure`] found each artifact, sample by sample (the viewer's overlays): the points,
/// edge samples and segment samples its numbers are sums over.
#[derive(Clone, Debug, Default)]
pub struct ArtifactSamples {
    /// A: the grid points in the penumbra band.
    pub band: Vec<PointMark>,
    /// B: the grid points of the reference's features (of at least `min_feature_points`).
    pub features: Vec<PointMark>,
    /// C and D: every interior edge sample (`x ± along · length / 2`).
    pub edges: Vec<EdgeMark>,
    /// E: every critical-segment sample (`x ± along · length / 2`).
    pub segments: Vec<SegmentMark>,
}

/// [`measure`], with the samples behind each number (the report is the same).
pub fn measure_samples<R: Reconstruction + ?Sized>(
    scene: &Scene,
    solution: &Solution,
    reference: &R,
    params: &ArtifactParams,
) -> Result<(ArtifactReport, ArtifactSamples), ArtifactError> {
    let pc = PiecewiseConstant::new(scene, &solution.elements)?;
    let gouraud = Gouraud::new(scene, solution)?;
    let (report, maps) = measure_all(scene, solution, &pc, None, &gouraud, reference, params)?;
    Ok((report, maps.samples(scene)))
}

impl ArtifactMaps {
    /// The maps as overlay samples ([`ArtifactSamples`]).
    #[must_use]
    pub fn samples(&self, scene: &Scene) -> ArtifactSamples {
        let pts = &self.points;
        let reflected = |k: usize| self.reference[k] - scene.patches[pts[k].patch].emission;
        let in_band = |k: &usize| self.in_band[*k];
        let band_area: f64 = (0..pts.len()).filter(in_band).map(|k| pts[k].area).sum();
        let band_rms = ((0..pts.len())
            .filter(in_band)
            .map(|k| pts[k].area * reflected(k).mul_rgb(reflected(k)).mean())
            .sum::<f64>()
            / band_area.max(f64::MIN_POSITIVE))
        .sqrt();
        let mark = |k: usize, value: f64, flagged: bool| PointMark {
            patch: pts[k].patch,
            x: pts[k].position,
            size: pts[k].area.sqrt(),
            value,
            flagged,
        };
        ArtifactSamples {
            band: (0..pts.len())
                .filter(in_band)
                .map(|k| {
                    let err = (self.solution[k] - self.reference[k]).map(f64::abs).mean();
                    mark(k, err / band_rms.max(f64::MIN_POSITIVE), false)
                })
                .collect(),
            features: (0..pts.len())
                .filter(|&k| self.features[k] != 0)
                .map(|k| mark(k, 0.0, self.features[k] < 0))
                .collect(),
            edges: self.edges.clone(),
            segments: self.segments.clone(),
        }
    }
}

/// Reflecting patches (ρ̄ > 0), in order.
fn reflecting(scene: &Scene) -> impl Iterator<Item = usize> + '_ {
    (0..scene.patches.len()).filter(|&p| scene.patches[p].reflectance.mean() > 0.0)
}

/// The `side × side` cell centres of every reflecting patch's area-uniform map, row by row.
fn grid_points(scene: &Scene, side: u32) -> Vec<RefPoint> {
    let n = f64::from(side);
    let mut out = Vec::new();
    for p in reflecting(scene) {
        let patch = &scene.patches[p];
        let area = patch.area / (n * n);
        for j in 0..side {
            for i in 0..side {
                let position =
                    area_point(&patch.vertices, (f64::from(i) + 0.5) / n, (f64::from(j) + 0.5) / n);
                let cell = Cell { patch: p as u32, level: 0, i, j };
                out.push(RefPoint { patch: p, position, area, cell });
            }
        }
    }
    out
}

/// Per patch: (m_p, s_p), the reference's and the solution's mean of B̄ over the grid.
fn patch_means(scene: &Scene, points: &[RefPoint], refs: &[Rgb], sol: &[Rgb]) -> Vec<(f64, f64)> {
    let mut acc = vec![(0.0, 0.0, 0.0); scene.patches.len()];
    for ((pt, r), s) in points.iter().zip(refs).zip(sol) {
        let a = &mut acc[pt.patch];
        a.0 += pt.area * r.mean();
        a.1 += pt.area * s.mean();
        a.2 += pt.area;
    }
    acc.iter().map(|&(r, s, a)| if a > 0.0 { (r / a, s / a) } else { (0.0, 0.0) }).collect()
}

/// B (module docs). `points` come `side²` per patch, row by row.
fn missing_features(
    points: &[RefPoint],
    refs: &[Rgb],
    sol: &[Rgb],
    means: &[(f64, f64)],
    params: &ArtifactParams,
) -> (MissingFeatures, Vec<i8>) {
    let side = params.side as usize;
    let mut out = MissingFeatures::default();
    let mut marks = vec![0i8; points.len()];
    let (mut area_all, mut area_missing) = (0.0, 0.0);
    for start in (0..points.len()).step_by(side * side) {
        let patch = points[start].patch;
        let (m, s) = means[patch];
        if m <= 0.0 {
            continue;
        }
        let tau = params.feature * m;
        // +1 highlight, −1 shadow, 0 neither; shown: the solution departs the same way.
        let sign: Vec<i8> = (0..side * side)
            .map(|k| {
                let d = refs[start + k].mean() - m;
                if d > tau {
                    1
                } else if d < -tau {
                    -1
                } else {
                    0
                }
            })
            .collect();
        let shown: Vec<bool> = (0..side * side)
            .map(|k| {
                let d = sol[start + k].mean() - s;
                d.abs() > 0.5 * tau && d.signum() as i8 == sign[k]
            })
            .collect();
        let mut seen = vec![false; side * side];
        for k0 in 0..side * side {
            if sign[k0] == 0 || seen[k0] {
                continue;
            }
            // Flood fill one 4-connected region of equal sign.
            let (mut size, mut shown_n) = (0usize, 0usize);
            let mut stack = vec![k0];
            let mut region = Vec::new();
            seen[k0] = true;
            while let Some(k) = stack.pop() {
                size += 1;
                region.push(k);
                shown_n += usize::from(shown[k]);
                let (i, j) = (k % side, k / side);
                let mut push = |q: usize| {
                    if !seen[q] && sign[q] == sign[k0] {
                        seen[q] = true;
                        stack.push(q);
                    }
                };
                if i > 0 {
                    push(k - 1);
                }
                if i + 1 < side {
                    push(k + 1);
                }
                if j > 0 {
                    push(k - side);
                }
                if j + 1 < side {
                    push(k + side);
                }
            }
            if size < params.min_feature_points {
                continue;
            }
            let area = size as f64 * points[start].area;
            out.features += 1;
            area_all += area;
            let missing = 2 * shown_n < size;
            if missing {
                out.missing += 1;
                area_missing += area;
            }
            for k in region {
                marks[start + k] = if missing { -1 } else { 1 };
            }
        }
    }
    out.area_fraction = if area_all > 0.0 { area_missing / area_all } else { 0.0 };
    (out, marks)
}

/// Distance from `x` to the boundary of the polygon `verts`.
fn boundary_distance(verts: &[DVec3], x: DVec3) -> f64 {
    (0..verts.len())
        .map(|k| {
            let (a, b) = (verts[k], verts[(k + 1) % verts.len()]);
            let ab = b - a;
            let t = ((x - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
            (a + ab * t).distance(x)
        })
        .fold(f64::INFINITY, f64::min)
}

/// True if `x` (on the polygon's plane) is inside the convex polygon `verts` of normal `normal`.
fn inside_convex(verts: &[DVec3], normal: DVec3, x: DVec3) -> bool {
    (0..verts.len()).all(|k| {
        let (a, b) = (verts[k], verts[(k + 1) % verts.len()]);
        (b - a).cross(x - a).dot(normal) >= 0.0
    })
}

/// One sample of an interior element edge (module docs, D): the point `x` on the edge of
/// element `inside`, the in-plane normal `n` pointing into element `outside`, its length weight.
struct EdgeSample {
    patch: usize,
    inside: usize,
    outside: usize,
    x: DVec3,
    n: DVec3,
    weight: f64,
    /// ε: the offset of the two located points x ± ε n.
    eps: f64,
}

/// Every interior edge sample of the solution's reflecting patches, in element order.
fn interior_edge_samples(
    scene: &Scene,
    solution: &Solution,
    pc: &PiecewiseConstant,
    means: &[(f64, f64)],
    params: &ArtifactParams,
) -> Vec<EdgeSample> {
    let m = params.edge_samples.max(1);
    solution
        .elements
        .par_iter()
        .enumerate()
        .filter(|(_, e)| scene.patches[e.patch].reflectance.mean() > 0.0 && means[e.patch].0 > 0.0)
        .flat_map_iter(|(index, e)| {
            let patch = &scene.patches[e.patch];
            let eps = 1e-6 * patch.diameter();
            let centre = crate::math::polygon_centroid(&e.vertices);
            let mut out = Vec::new();
            for k in 0..e.vertices.len() {
                let (a, b) = (e.vertices[k], e.vertices[(k + 1) % e.vertices.len()]);
                let mut n = (b - a).cross(patch.normal).normalize_or_zero();
                if n.dot((a + b) * 0.5 - centre) < 0.0 {
                    n = -n;
                }
                let weight = 0.5 * a.distance(b) / f64::from(m);
                for i in 0..m {
                    let x = a.lerp(b, (f64::from(i) + 0.5) / f64::from(m));
                    if boundary_distance(&patch.vertices, x) < 2.0 * eps {
                        continue;
                    }
                    let (o, s) = (pc.element_at(e.patch, x + n * eps), pc.element_at(e.patch, x - n * eps));
                    if let (Some(outside), Some(inside)) = (o, s)
                        && outside != inside
                        && inside == index
                    {
                        out.push(EdgeSample { patch: e.patch, inside, outside, x, n, weight, eps });
                    }
                }
            }
            out
        })
        .collect()
}

/// D (module docs), and which samples are inappropriate jumps: the jump of `values` across the
/// edge, or (`None`) of the two elements' average values.
fn shading_jumps<R: Reconstruction + ?Sized>(
    solution: &Solution,
    samples: &[EdgeSample],
    values: Option<&dyn Reconstruction>,
    reference: &R,
    means: &[(f64, f64)],
    params: &ArtifactParams,
) -> (ShadingJumps, Vec<bool>) {
    let mut out = ShadingJumps::default();
    let mut sum_jump = 0.0;
    let mut marks = Vec::with_capacity(samples.len());
    for s in samples {
        let mean = means[s.patch].0;
        out.edge_length += s.weight;
        let (out_x, in_x) = (s.x + s.n * s.eps, s.x - s.n * s.eps);
        let jump = match values {
            Some(v) => (v.radiosity_at(s.patch, out_x) - v.radiosity_at(s.patch, in_x)).mean().abs(),
            None => {
                (solution.elements[s.outside].radiosity - solution.elements[s.inside].radiosity).mean().abs()
            }
        };
        let jump_ref =
            (reference.radiosity_at(s.patch, out_x) - reference.radiosity_at(s.patch, in_x)).mean().abs();
        let flagged = jump > params.jump * mean && jump_ref < 0.1 * jump;
        if flagged {
            out.inappropriate_length += s.weight;
            sum_jump += s.weight * jump / mean;
        }
        marks.push(flagged);
    }
    out.mean_jump = if out.inappropriate_length > 0.0 { sum_jump / out.inappropriate_length } else { 0.0 };
    (out, marks)
}

/// The reconstruction a viewer draws from constant elements (Gouraud,
/// [`crate::eval::reconstruction::gouraud`]): each element corner takes the area-weighted mean of the
/// elements of its patch that share that corner (welded within 10⁻⁹ of the scene's diagonal; a
/// T-junction's corner is not shared by the long edge), and the value inside an element is the
/// linear (triangle) or bilinear (quad) interpolation of its corners' values.
pub struct Gouraud<'a>(crate::eval::reconstruction::Nodal<'a>);

impl<'a> Gouraud<'a> {
    /// Weld the corners of `solution`'s elements and average them.
    pub fn new(scene: &'a Scene, solution: &'a Solution) -> Result<Self, MetricsError> {
        let corners = crate::eval::reconstruction::gouraud(scene, &solution.elements);
        Ok(Gouraud(crate::eval::reconstruction::Nodal::new(scene, &solution.elements, corners)?))
    }
}

impl Reconstruction for Gouraud<'_> {
    fn radiosity_at(&self, patch: usize, x: DVec3) -> Rgb {
        self.0.radiosity_at(patch, x)
    }
}

/// C (module docs), read on `shaded`, and which samples are Mach bands.
fn mach_bands<R: Reconstruction + ?Sized>(
    solution: &Solution,
    samples: &[EdgeSample],
    shaded: &dyn Reconstruction,
    reference: &R,
    means: &[(f64, f64)],
    params: &ArtifactParams,
) -> (MachBands, Vec<bool>) {
    // The change of slope across the edge: outward slope on the far side plus the slope moving
    // away from the edge on the near side (zero where the function is smooth).
    let kink = |f: &dyn Fn(DVec3) -> Rgb, s: &EdgeSample| {
        let h = 10.0 * s.eps;
        let (x, n) = (s.x, s.n);
        ((f(x + n * (2.0 * h)) - f(x + n * h)) + (f(x - n * (2.0 * h)) - f(x - n * h))).mean().abs() / h
    };
    let mut out = MachBands::default();
    let mut marks = Vec::with_capacity(samples.len());
    for s in samples {
        let mean = means[s.patch].0;
        out.edge_length += s.weight;
        let k = kink(&|y| shaded.radiosity_at(s.patch, y), s);
        let k_ref = kink(&|y| reference.radiosity_at(s.patch, y), s);
        let flagged = k * solution.elements[s.inside].area.sqrt() > params.jump * mean && k_ref < 0.1 * k;
        if flagged {
            out.band_length += s.weight;
        }
        marks.push(flagged);
    }
    (out, marks)
}

/// E (module docs), and every segment sample.
fn unresolved<R: Reconstruction + ?Sized>(
    scene: &Scene,
    accel: &Accel,
    solution: &Solution,
    pc: &PiecewiseConstant,
    values: &dyn Reconstruction,
    reference: &R,
    params: &ArtifactParams,
) -> Result<(UnresolvedDiscontinuities, Vec<SegmentMark>), ArtifactError> {
    let m = params.segment_samples.max(1);
    let mut out = UnresolvedDiscontinuities::default();
    let mut marks = Vec::new();
    let (mut err2, mut ref2) = (0.0, 0.0);
    let mut by_patch = vec![Vec::new(); scene.patches.len()];
    for (i, e) in solution.elements.iter().enumerate() {
        by_patch[e.patch].push(i);
    }
    for p in reflecting(scene) {
        let patch = &scene.patches[p];
        let set = scene_segments(&scene.patches, p, DEFAULT_SNAP)?;
        // Only the segments that bound a shadow: the rest (inside an umbra, in full light) are
        // no discontinuity of B, and an element edge there would buy nothing.
        let kept = shadow_segments(scene, accel, p, &set, params.shadow_side.max(1));
        out.dropped += set.segments.len() - kept.len();
        let (tol, delta) = (params.on_edge * patch.diameter(), params.near * patch.diameter());
        for seg in &kept {
            let [a, b] = *seg;
            let len = a.distance(b);
            if len <= 0.0 {
                continue;
            }
            out.segments += 1;
            out.length += len;
            let n = (b - a).cross(patch.normal).normalize_or_zero();
            for i in 0..m {
                let x = a.lerp(b, (f64::from(i) + 0.5) / f64::from(m));
                let Some(owner) = pc.element_at(p, x) else { continue };
                let own = &solution.elements[owner].vertices;
                // A sample on an edge of a non-conforming mesh (a graded piece's T-vertex leaves
                // its neighbours' edges a rounding error apart) can lie outside every element;
                // the locator then returns the nearest centroid, which need not touch x. Such a
                // sample is on an element edge when one of the patch's elements has one at x.
                let resolved = boundary_distance(own, x) <= tol
                    || (!inside_convex(own, patch.normal, x)
                        && by_patch[p]
                            .iter()
                            .any(|&i| boundary_distance(&solution.elements[i].vertices, x) <= tol));
                let along = (b - a) / len;
                marks.push(SegmentMark {
                    patch: p,
                    x,
                    along,
                    length: len / f64::from(m),
                    unresolved: !resolved,
                });
                if resolved {
                    continue;
                }
                out.unresolved_length += len / f64::from(m);
                for y in [x + n * delta, x - n * delta] {
                    if inside_convex(&patch.vertices, patch.normal, y) {
                        let (b, r) = (values.radiosity_at(p, y), reference.radiosity_at(p, y));
                        let d = b - r;
                        err2 += d.mul_rgb(d).mean();
                        ref2 += r.mul_rgb(r).mean();
                    }
                }
            }
        }
    }
    out.error_beside = (ref2 > 0.0).then(|| (err2 / ref2).sqrt());
    Ok((out, marks))
}
