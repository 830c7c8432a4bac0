//! The pointwise reference: Monte Carlo estimates of B at **points**, each with its standard
//! error, placed densely enough to resolve a penumbra.
//!
//! Each point stands for a **cell** of its patch, and carries the cell's area a_k as its weight,
//! so a sum over points is a quadrature over the surfaces (the midpoint rule on the cells):
//!
//! ```text
//! ∫_S f(x) dA  ≈  Σ_k a_k f(x_k)          (x_k the centre of cell k, Σ_k a_k = area of S)
//! ```
//!
//! ## How the points are placed
//! Cells live in a patch's parameter square (s, t) ∈ [0,1)²: a quad is the bilinear map
//! x = lerp(lerp(v0, v1, s), lerp(v3, v2, s), t); a triangle the collapsed map
//! x = v0 + u (v1 − v0) + u t (v2 − v1) with u = √s, which is area-uniform in (s, t). In both
//! maps lines of constant s and of constant t are straight, so every cell is a planar quad (a
//! triangle at the apex) and its area is exact.
//!
//! ```text
//!   level 0 grid (nu × nv)          a cell split where its estimate differs from a neighbour's
//!   ┌───┬───┬───┬───┐               ┌───┬───┬─┬─┬───┐
//!   │ · │ · │ · │ · │               │ · │ · │·│·│ · │     |B̂_a − B̂_b| > K √(σ_a² + σ_b²),  K = 3
//!   ├───┼───┼───┼───┤      →        │   │   ├─┼─┤   │     (any channel): ranked by a · excess²
//!   │ · │ · │ · │ · │               │ · │ · │·│·│ · │
//!   └───┴───┴───┴───┘               └───┴───┴─┴─┴───┘
//! ```
//!
//! 1. **Coarse pass**: half of the requested points, spread over the patches in proportion to
//!    area (at least [`MIN_CELLS_PER_PATCH`] per patch), on near-square grids; each estimated.
//! 2. **Refinement rounds** ([`PointParams::rounds`]): each leaf cell is compared with its
//!    edge neighbours in the same patch (at its own level or coarser); a pair whose estimates
//!    differ by more than K = [`SPLIT_SIGMAS`] times their combined standard error flags both
//!    cells. The flagged cells with the largest a · excess² are split into 4 (their point
//!    replaced by 4 new ones), up to the round's share of the remaining budget.
//! 3. **Fill**: if the set is still below [`PointParams::points`], the largest cells are split
//!    until it is not; so every set has at least that many points.
//!
//! Every cell has its own random stream `Pcg32::keyed(seed, hash(patch, level, i, j))`, cells
//! are estimated in parallel (rayon) and ties are broken by the cell, so the layout and every
//! estimate are identical for any thread count. A later batch with another seed re-estimates
//! the same points ([`estimate_at`]); [`crate::eval::reference::merge_batches`] merges them. The cells
//! left unsplit were chosen on their first estimates (a small selection effect on batch 0's
//! noise); later batches are independent of the layout.

use super::{Control, Emitters, Estimate, Hasher64, RefElement, ReferenceError, ReferenceParams, Tracer};
use crate::geometry::accel::Accel;
use crate::math::{DVec3, Pcg32, Rgb, polygon_area};
use crate::scene::Scene;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::sync::atomic::Ordering;

/// Fewest level-0 cells on any patch (a 4 × 4 grid).
pub const MIN_CELLS_PER_PATCH: u32 = 16;

/// Two neighbouring estimates differ significantly when they differ by more than this many
/// combined standard errors (one channel is enough).
pub const SPLIT_SIGMAS: f64 = 3.0;

/// Fraction of the requested points placed by the uniform first pass.
pub const COARSE_FRACTION: f64 = 0.5;

/// Settings of the pointwise reference.
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PointParams {
    /// The set has at least this many points.
    pub points: u32,
    /// Refinement rounds after the coarse pass (a cell's side halves at most once per round).
    pub rounds: u32,
    /// Paths per point, bounces, and the seed of these estimates.
    pub paths: ReferenceParams,
    /// Seed of the pass that placed the points (batch 0). Equal to `paths.seed` for that batch;
    /// other batches re-estimate the same points with their own `paths.seed`.
    pub layout_seed: u64,
}

impl PointParams {
    /// The default of `radlab reference` and of the standard bench: 65 536 points, 1024 paths each.
    #[must_use]
    pub const fn standard() -> Self {
        PointParams { points: 65_536, rounds: 3, paths: ReferenceParams::standard(), layout_seed: 0 }
    }
    /// Rough and fast (tests, `bench --quick`): 4096 points, 64 paths each.
    #[must_use]
    pub const fn quick() -> Self {
        PointParams { points: 4096, rounds: 3, paths: ReferenceParams::quick(), layout_seed: 0 }
    }
    /// The same points, estimated with another seed (a further batch).
    #[must_use]
    pub const fn batch(self, seed: u64) -> Self {
        PointParams { paths: ReferenceParams { seed, ..self.paths }, ..self }
    }
    fn validate(&self) -> Result<(), ReferenceError> {
        if self.points == 0 {
            return Err(ReferenceError::ZeroSamples("points"));
        }
        if self.paths.samples == 0 {
            return Err(ReferenceError::ZeroSamples("samples"));
        }
        if self.paths.max_bounces == 0 {
            return Err(ReferenceError::ZeroSamples("max-bounces"));
        }
        Ok(())
    }
}

impl Default for PointParams {
    fn default() -> Self {
        Self::standard()
    }
}

/// A cell of a patch's parameter square: level L splits the patch's level-0 grid (nu × nv) into
/// (nu·2^L) × (nv·2^L); (i, j) is the cell's column (s) and row (t).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Cell {
    pub patch: u32,
    pub level: u8,
    pub i: u32,
    pub j: u32,
}

impl Cell {
    /// The key of this cell's random stream.
    fn key(&self) -> u64 {
        Hasher64::default()
            .u64(u64::from(self.patch))
            .u64(u64::from(self.level))
            .u64(u64::from(self.i))
            .u64(u64::from(self.j))
            .finish()
    }
    fn children(&self) -> [Cell; 4] {
        let (l, i, j) = (self.level + 1, 2 * self.i, 2 * self.j);
        let c = |i, j| Cell { patch: self.patch, level: l, i, j };
        [c(i, j), c(i + 1, j), c(i, j + 1), c(i + 1, j + 1)]
    }
}

/// One reference point: where it is and the area it stands for.
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RefPoint {
    pub patch: usize,
    pub position: DVec3,
    /// Area of the cell the point stands for (its quadrature weight).
    pub area: f64,
    pub cell: Cell,
}

/// A set of points with their estimates (same order), and the level-0 grid of every patch (so
/// a point's cell can be drawn, see [`PointSet::cell_region`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PointSet {
    /// (nu, nv) of each patch's level-0 grid, in patch order.
    pub grids: Vec<(u32, u32)>,
    pub points: Vec<RefPoint>,
}

impl PointSet {
    /// The cell of point `k` as a region (a quad; at a triangle's apex two corners coincide).
    #[must_use]
    pub fn cell_region(&self, scene: &Scene, k: usize) -> RefElement {
        let p = &self.points[k];
        RefElement {
            patch: p.patch,
            vertices: cell_corners(&scene.patches[p.patch].vertices, self.grids[p.patch], &p.cell).to_vec(),
        }
    }
    /// Every point's cell as a region, in point order.
    #[must_use]
    pub fn cell_regions(&self, scene: &Scene) -> Vec<RefElement> {
        (0..self.points.len()).map(|k| self.cell_region(scene, k)).collect()
    }
    /// (patch, area) of every point: the regions [`crate::eval::metrics::compare_regions`] weighs.
    #[must_use]
    pub fn weights(&self) -> Vec<(usize, f64)> {
        self.points.iter().map(|p| (p.patch, p.area)).collect()
    }
}

/// The patch's parameter map (module docs): bilinear on quads, the collapsed area-uniform map on
/// triangles.
fn param_point(v: &[DVec3], s: f64, t: f64) -> DVec3 {
    if v.len() == 4 {
        v[0].lerp(v[1], s).lerp(v[3].lerp(v[2], s), t)
    } else {
        let u = s.max(0.0).sqrt();
        v[0] + (v[1] - v[0]) * u + (v[2] - v[1]) * (u * t)
    }
}

/// Parameter rectangle of a cell: (s0, s1, t0, t1).
fn cell_rect(grid: (u32, u32), c: &Cell) -> (f64, f64, f64, f64) {
    let scale = f64::from(1u32 << c.level);
    let (nu, nv) = (f64::from(grid.0) * scale, f64::from(grid.1) * scale);
    (f64::from(c.i) / nu, f64::from(c.i + 1) / nu, f64::from(c.j) / nv, f64::from(c.j + 1) / nv)
}

fn cell_corners(v: &[DVec3], grid: (u32, u32), c: &Cell) -> [DVec3; 4] {
    let (s0, s1, t0, t1) = cell_rect(grid, c);
    [param_point(v, s0, t0), param_point(v, s1, t0), param_point(v, s1, t1), param_point(v, s0, t1)]
}

fn make_point(scene: &Scene, grids: &[(u32, u32)], c: Cell) -> RefPoint {
    let patch = c.patch as usize;
    let v = &scene.patches[patch].vertices;
    let (s0, s1, t0, t1) = cell_rect(grids[patch], &c);
    RefPoint {
        patch,
        position: param_point(v, 0.5 * (s0 + s1), 0.5 * (t0 + t1)),
        area: polygon_area(&cell_corners(v, grids[patch], &c)),
        cell: c,
    }
}

/// Level-0 grids: `total` cells spread over the patches in proportion to area, near-square cells.
fn level0_grids(scene: &Scene, total: f64) -> Vec<(u32, u32)> {
    let area: f64 = scene.patches.iter().map(|p| p.area).sum();
    // Grids finer than this per patch side would only follow a degenerate input (slivers).
    const MAX_SIDE: f64 = 4096.0;
    scene
        .patches
        .iter()
        .map(|p| {
            let n = (total * p.area / area.max(f64::MIN_POSITIVE)).max(f64::from(MIN_CELLS_PER_PATCH));
            let v = &p.vertices;
            if v.len() == 4 {
                let lu = v[0].distance(v[1]).max(v[3].distance(v[2]));
                let lv = v[0].distance(v[3]).max(v[1].distance(v[2]));
                let ratio = if lv > 0.0 { lu / lv } else { 1.0 };
                let nu = (n * ratio).sqrt().round().clamp(1.0, MAX_SIDE);
                let nv = (n / nu).ceil().clamp(1.0, MAX_SIDE);
                (nu as u32, nv as u32)
            } else {
                let k = n.sqrt().ceil().clamp(1.0, MAX_SIDE) as u32;
                (k, k)
            }
        })
        .collect()
}

impl Tracer<'_> {
    /// `samples` paths from the point: mean and standard error.
    fn point(&self, x: DVec3, patch: usize, key: u64) -> Estimate {
        let mut rng = Pcg32::keyed(self.params.seed, key);
        let n = f64::from(self.params.samples);
        let mut sum = Rgb::ZERO;
        let mut sum2 = Rgb::ZERO;
        for _ in 0..self.params.samples {
            let b = self.radiosity_at(x, patch, &mut rng);
            sum += b;
            sum2 += b.mul_rgb(b);
        }
        let mean = sum / n;
        let var = (sum2 / n - mean.mul_rgb(mean)).map(|v| v.max(0.0)) * (n / (n - 1.0).max(1.0));
        Estimate { radiosity: mean, std_error: (var / n).map(f64::sqrt) }
    }

    fn points(&self, points: &[RefPoint], control: &Control) -> Result<Vec<Estimate>, ReferenceError> {
        points
            .par_iter()
            .map(|p| {
                if control.cancelled() {
                    return None;
                }
                let e = self.point(p.position, p.patch, p.cell.key());
                control.done.fetch_add(1, Ordering::Relaxed);
                Some(e)
            })
            .collect::<Option<Vec<Estimate>>>()
            .ok_or(ReferenceError::Cancelled)
    }
}

/// At least `points` points on level-0 grids alone (cells spread over the patches in proportion
/// to area, near-square), without estimates: the layout where B is known in closed form and
/// nothing needs placing by its noise ([`crate::geometry::exact`]).
#[must_use]
pub fn uniform_points(scene: &Scene, points: u32) -> PointSet {
    let grids = level0_grids(scene, f64::from(points));
    let mut set = PointSet { points: Vec::new(), grids };
    for (p, &(nu, nv)) in set.grids.iter().enumerate() {
        for j in 0..nv {
            for i in 0..nu {
                set.points.push(make_point(scene, &set.grids, Cell { patch: p as u32, level: 0, i, j }));
            }
        }
    }
    set
}

/// Place at least `params.points` points (module docs) and estimate B at each with
/// `params.paths` (seed `params.layout_seed`): the points in (patch, level, i, j) order and
/// their estimates.
pub fn reference_points(
    scene: &Scene,
    accel: &Accel,
    params: &PointParams,
    control: &Control,
) -> Result<(PointSet, Vec<Estimate>), ReferenceError> {
    params.validate()?;
    let paths = ReferenceParams { seed: params.layout_seed, ..params.paths };
    let tracer = Tracer { scene, accel, emitters: Emitters::new(scene), params: paths };
    let target = params.points as usize;
    let grids = level0_grids(scene, f64::from(params.points) * COARSE_FRACTION);
    let mut cells: Vec<Cell> = Vec::new();
    for (p, &(nu, nv)) in grids.iter().enumerate() {
        for j in 0..nv {
            for i in 0..nu {
                cells.push(Cell { patch: p as u32, level: 0, i, j });
            }
        }
    }
    let mut points: Vec<RefPoint> = cells.iter().map(|&c| make_point(scene, &grids, c)).collect();
    control.done.store(0, Ordering::Relaxed);
    control
        .total
        .store(points.len() + 4 * target.saturating_sub(points.len()).div_ceil(3), Ordering::Relaxed);
    let mut estimates = tracer.points(&points, control)?;
    let rounds = params.rounds as usize;
    for round in 0..=rounds {
        let remaining = target.saturating_sub(points.len());
        if remaining == 0 {
            break;
        }
        let chosen: Vec<usize> = if round < rounds {
            let budget = remaining.div_ceil(3).div_ceil(rounds - round);
            let mut flagged = significant_differences(&grids, &points, &estimates);
            flagged.sort_by(|a, b| b.1.total_cmp(&a.1).then(points[a.0].cell.cmp(&points[b.0].cell)));
            flagged.truncate(budget);
            flagged.into_iter().map(|(k, _)| k).collect()
        } else {
            // Fill: split the largest cells until the set has enough points.
            let mut order: Vec<usize> = (0..points.len()).collect();
            order.sort_by(|&a, &b| {
                points[b].area.total_cmp(&points[a].area).then(points[a].cell.cmp(&points[b].cell))
            });
            order.truncate(remaining.div_ceil(3));
            order
        };
        if chosen.is_empty() {
            continue;
        }
        let new: Vec<RefPoint> = chosen
            .iter()
            .flat_map(|&k| points[k].cell.children())
            .map(|c| make_point(scene, &grids, c))
            .collect();
        let new_est = tracer.points(&new, control)?;
        let mut drop = vec![false; points.len()];
        for &k in &chosen {
            drop[k] = true;
        }
        let (mut p2, mut e2): (Vec<RefPoint>, Vec<Estimate>) = points
            .iter()
            .zip(&estimates)
            .zip(&drop)
            .filter(|(_, d)| !**d)
            .map(|((p, e), _)| (*p, *e))
            .unzip();
        p2.extend(new);
        e2.extend(new_est);
        (points, estimates) = (p2, e2);
    }
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by_key(|&k| points[k].cell);
    let set = PointSet { grids, points: order.iter().map(|&k| points[k]).collect() };
    let estimates = order.iter().map(|&k| estimates[k]).collect();
    control.total.store(control.done.load(Ordering::Relaxed), Ordering::Relaxed);
    Ok((set, estimates))
}

/// Leaf cells whose estimate differs significantly from an edge neighbour's (same patch, same
/// or coarser level): (index, a · excess²), each index once with its largest score.
fn significant_differences(grids: &[(u32, u32)], points: &[RefPoint], est: &[Estimate]) -> Vec<(usize, f64)> {
    let index: HashMap<Cell, usize> = points.iter().enumerate().map(|(k, p)| (p.cell, k)).collect();
    let mut score = vec![0.0f64; points.len()];
    for (a, p) in points.iter().enumerate() {
        let c = p.cell;
        let (nu, nv) = grids[c.patch as usize];
        let (nu, nv) = (i64::from(nu) << c.level, i64::from(nv) << c.level);
        for (di, dj) in [(1i64, 0i64), (-1, 0), (0, 1), (0, -1)] {
            let (ni, nj) = (i64::from(c.i) + di, i64::from(c.j) + dj);
            if ni < 0 || nj < 0 || ni >= nu || nj >= nv {
                continue;
            }
            // The leaf covering the neighbour position at this level or coarser; none: it is
            // split finer, and its own children find this cell.
            let Some(b) = (0..=c.level).rev().find_map(|l| {
                let shift = c.level - l;
                index
                    .get(&Cell { patch: c.patch, level: l, i: (ni >> shift) as u32, j: (nj >> shift) as u32 })
                    .copied()
            }) else {
                continue;
            };
            let (ea, eb) = (&est[a], &est[b]);
            let excess = (0..3)
                .map(|ch| {
                    let d = (ea.radiosity.0[ch] - eb.radiosity.0[ch]).abs();
                    let s = ea.std_error.0[ch].hypot(eb.std_error.0[ch]);
                    d - SPLIT_SIGMAS * s
                })
                .fold(f64::NEG_INFINITY, f64::max);
            if excess > 0.0 {
                score[a] = score[a].max(points[a].area * excess * excess);
                score[b] = score[b].max(points[b].area * excess * excess);
            }
        }
    }
    score.into_iter().enumerate().filter(|(_, s)| *s > 0.0).collect()
}

/// Estimate B at the points of a set with `paths` (its own seed): the estimates of one further
/// batch, in point order, with each cell's own stream (so `paths.seed == layout_seed` reproduces
/// [`reference_points`]'s estimates).
pub fn estimate_at(
    scene: &Scene,
    accel: &Accel,
    set: &PointSet,
    paths: &ReferenceParams,
    control: &Control,
) -> Result<Vec<Estimate>, ReferenceError> {
    if paths.samples == 0 {
        return Err(ReferenceError::ZeroSamples("samples"));
    }
    if paths.max_bounces == 0 {
        return Err(ReferenceError::ZeroSamples("max-bounces"));
    }
    for (index, p) in set.points.iter().enumerate() {
        if p.patch >= scene.patches.len() {
            return Err(ReferenceError::BadElement { index, patch: p.patch, patches: scene.patches.len() });
        }
    }
    let tracer = Tracer { scene, accel, emitters: Emitters::new(scene), params: *paths };
    control.done.store(0, Ordering::Relaxed);
    control.total.store(set.points.len(), Ordering::Relaxed);
    tracer.points(&set.points, control)
}

/// Hash of everything a pointwise reference depends on: the patches, the settings, the format.
#[must_use]
pub fn points_cache_key(scene: &Scene, params: &PointParams) -> u64 {
    let mut h = Hasher64::default();
    h.bytes(b"points").u64(u64::from(super::FORMAT_VERSION));
    super::hash_scene(&mut h, scene);
    h.u64(u64::from(params.points))
        .u64(u64::from(params.rounds))
        .u64(u64::from(params.paths.samples))
        .u64(u64::from(params.paths.min_bounces))
        .u64(u64::from(params.paths.max_bounces))
        .u64(params.paths.seed)
        .u64(params.layout_seed);
    h.finish()
}

/// What the cache stores for a pointwise reference.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CachedPoints {
    pub format_version: u32,
    /// [`points_cache_key`] as 16 hex digits.
    pub key: String,
    pub scene: String,
    pub params: PointParams,
    /// The points (in the file: empty for a further batch, whose points are the layout's).
    pub set: PointSet,
    pub estimates: Vec<Estimate>,
    /// Seconds the computation took (this batch; not the layout it reused).
    pub compute_s: f64,
}

/// Hemisphere directions per point that [`enclosed`] traces.
pub const ENCLOSED_RAYS: usize = 64;

/// Per point, whether it is **enclosed**: each of [`ENCLOSED_RAYS`] fixed directions of its
/// hemisphere (cosine-distributed, on a golden-angle spiral) meets the back of a surface, as
/// the floor under a box that stands on it without a bottom does. No light reaches such a point
/// (a path from it ends on a back face at its first bounce), and no viewer in the scene sees it;
/// the pointwise rulers leave enclosed points out of the reference and the solution alike, as
/// the floor under a decal is left out (the loader drops it), since what a solver puts there is
/// shown to no one. A point that sees a front face or open sky in any of the directions is kept.
/// Deterministic, and identical for any thread count.
pub fn enclosed(scene: &Scene, accel: &Accel, points: &[RefPoint]) -> Vec<bool> {
    // (u, v) of the reference's own cosine sampling: u stratified, v turned by the golden ratio.
    let golden = (3.0 - 5f64.sqrt()) / 2.0;
    let uv: Vec<(f64, f64)> = (0..ENCLOSED_RAYS)
        .map(|k| ((k as f64 + 0.5) / ENCLOSED_RAYS as f64, (golden * k as f64).fract()))
        .collect();
    points
        .par_iter()
        .map(|p| {
            let n = scene.patches[p.patch].normal;
            uv.iter().all(|&(u, v)| {
                let d = super::cosine_direction(n, u, v);
                accel
                    .first_hit(p.position, d, p.patch as u32)
                    .is_some_and(|(q, _)| scene.patches[q as usize].normal.dot(d) > 0.0)
            })
        })
        .collect()
}

/// `points` and their `estimates` without the enclosed points ([`enclosed`]), and how many
/// were left out.
#[must_use]
pub fn without_enclosed(
    scene: &Scene,
    accel: &Accel,
    points: &[RefPoint],
    estimates: &[Estimate],
) -> (Vec<RefPoint>, Vec<Estimate>, usize) {
    let inside = enclosed(scene, accel, points);
    let kept = |i: usize| !inside.get(i).copied().unwrap_or(false);
    let p: Vec<RefPoint> = points.iter().enumerate().filter(|(i, _)| kept(*i)).map(|(_, x)| *x).collect();
    let e: Vec<Estimate> = estimates.iter().enumerate().filter(|(i, _)| kept(*i)).map(|(_, x)| *x).collect();
    let dropped = points.len() - p.len();
    (p, e, dropped)
}

impl CachedPoints {
    /// Leave out the enclosed points ([`enclosed`]) and their estimates; returns how many.
    pub fn drop_enclosed(&mut self, scene: &Scene, accel: &Accel) -> usize {
        let (p, e, n) = without_enclosed(scene, accel, &self.set.points, &self.estimates);
        self.set.points = p;
        self.estimates = e;
        n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_tile_their_patch_and_points_lie_inside() {
        let scene = Scene::load("builtin:cornell").unwrap();
        let grids = level0_grids(&scene, 500.0);
        for (p, patch) in scene.patches.iter().enumerate() {
            let (nu, nv) = grids[p];
            let mut area = 0.0;
            for j in 0..2 * nv {
                for i in 0..2 * nu {
                    let pt = make_point(&scene, &grids, Cell { patch: p as u32, level: 1, i, j });
                    area += pt.area;
                    assert!((patch.normal.dot(pt.position) - patch.plane_d()).abs() < 1e-9);
                }
            }
            assert!((area - patch.area).abs() < 1e-9 * patch.area, "patch {p}: {area} vs {}", patch.area);
        }
    }

    /// The floor under a box of box-grid (which has no bottom) is enclosed; the floor between
    /// boxes, a box's top and the room's walls are not.
    #[test]
    fn the_floor_under_a_box_is_enclosed_and_beside_it_not() {
        let scene = Scene::load("builtin:box-grid-1000").unwrap();
        let accel = Accel::build(&scene);
        let on = |name: &str, x: DVec3| {
            let patch = scene
                .patches
                .iter()
                .position(|p| {
                    let (lo, hi) =
                        p.vertices.iter().fold((DVec3::MAX, DVec3::MIN), |(l, h), v| (l.min(*v), h.max(*v)));
                    p.name.starts_with(name) && (x.cmpge(lo - 1e-9) & x.cmple(hi + 1e-9)).all()
                })
                .unwrap_or_else(|| panic!("no {name} patch holds {x}"));
            RefPoint {
                patch,
                position: x,
                area: 1.0,
                cell: Cell { patch: patch as u32, level: 0, i: 0, j: 0 },
            }
        };
        let tops: Vec<DVec3> = scene
            .patches
            .iter()
            .filter(|p| p.name.starts_with("boxes") && p.normal.y > 0.99)
            .map(|p| p.vertices.iter().copied().sum::<DVec3>() / p.vertices.len() as f64)
            .take(5)
            .collect();
        assert_eq!(tops.len(), 5);
        let mut points = Vec::new();
        for c in &tops {
            points.push(on("floor", DVec3::new(c.x, 0.0, c.z)));
            // Half the grid's pitch (0.25) along both axes: between four boxes at most 0.2 wide.
            points.push(on("floor", DVec3::new(c.x + 0.125, 0.0, c.z + 0.125)));
            points.push(on("boxes", *c));
        }
        let got = enclosed(&scene, &accel, &points);
        for (k, c) in tops.iter().enumerate() {
            assert_eq!(&got[3 * k..3 * k + 3], &[true, false, false], "box with its top at {c}");
        }
    }

    #[test]
    fn triangle_cells_are_area_uniform_in_s_and_t() {
        let v = [DVec3::ZERO, DVec3::new(2.0, 0.0, 0.0), DVec3::new(0.0, 1.0, 0.0)];
        let c = Cell { patch: 0, level: 0, i: 0, j: 0 };
        let a = polygon_area(&cell_corners(&v, (4, 3), &c));
        let d = polygon_area(&cell_corners(&v, (4, 3), &Cell { i: 3, j: 2, ..c }));
        // Each of the 12 cells holds 1/12 of the area 1.
        assert!((a - 1.0 / 12.0).abs() < 1e-12 && (d - 1.0 / 12.0).abs() < 1e-12, "{a} {d}");
    }
}
