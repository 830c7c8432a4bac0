//! Classical radiosity on a uniform mesh: every patch split into elements no larger than a target
//! size, the full form-factor matrix, and Gauss–Seidel [Goral et al. 1984; Cohen & Greenberg
//! 1985; Cohen & Wallace 1993, sec. 5.3]:
//!
//! ```text
//! B_i = E_i + ρ_i Σ_j F_ij V_ij B_j          (per RGB channel)
//! ```
//!
//! ## How it works
//! - **Mesh** ([`mesh_patch`]): a quad becomes an n×m grid of its bilinear map, a triangle 4^k
//!   midpoint-split triangles; no element side is longer than `element_size`.
//! - **Form factors** ([`pair_coupling`]): for each unordered pair {i, j} the form factor is
//!   integrated once, over the smaller element, by adaptive quadrature of the exact
//!   point-to-polygon kernel ([`crate::geometry::form_factor::polygon_to_polygon_adaptive`]); the other
//!   direction follows from reciprocity `A_i F_ij = A_j F_ji`, so the matrix is exactly
//!   reciprocal and the energy balance below is a real check. The visible fraction V_ij = V_ji
//!   comes from [`crate::geometry::visibility::visible_fraction`] keyed by the pair. Pairs on one patch
//!   (coplanar) and pairs facing away are skipped. Rows are computed in parallel (rayon); every
//!   pair's value depends only on the pair, so the result is identical for any thread count.
//! - **Solve**: Gauss–Seidel sweeps until the largest change of any element's radiosity is below
//!   `tolerance` × the largest radiosity.
//! - **Energy**: `absorbed = Σ A_i (1−ρ_i) H_i` with `H_i = Σ_j F_ij V_ij B_j`, and
//!   `escaped = Σ A_i B_i (1 − Σ_j F_ij V_ij)`; with a reciprocal matrix these add up to the
//!   emitted power exactly when B solves the system.
//!
//! Known limitation (the classical one): V_ij is the unweighted fraction of unblocked point
//! pairs, so `F_ij V_ij` is exact only for no or full occlusion. In a closed room the row sums
//! then miss 1 and `escaped` shows it, most on coarse meshes of rooms (docs/solver.md#the-solvers;
//! coplanar overlapping polygons are both seen, so rows can also sum past 1).
//!
//! Memory is O(n²) (sparse rows of the non-zero entries): the element count is capped
//! (`max_elements`), and the solver refuses larger meshes with a message.

use super::{EnergyBalance, PhaseTimes, Progress, Solution, SolveStats, SolvedElement};
use crate::geometry::accel::Accel;
use crate::geometry::form_factor::polygon_to_polygon_adaptive;
use crate::geometry::visibility::visible_fraction;
use crate::math::{DVec3, Rgb, polygon_area};
use crate::scene::{Patch, Scene};
use rayon::prelude::*;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Default relative accuracy of each form factor's quadrature (`--ff-tol`): tight enough that a
/// closed box with one element per face (`builtin:furnace`, `builtin:cube-one-light`) matches the
/// exact 6×6 solution from the catalog form factors to 1e-9 (tests/classical_solvers.rs);
/// 1e-8 is not. It costs time against [`COARSE_FF_TOLERANCE`] for no visible change: chosen by
/// measurement, see docs/solver.md#the-solvers.
pub const DEFAULT_FF_TOLERANCE: f64 = 1e-9;

/// The former fixed tolerance: for comparisons at the percent level (the bench, `reference
/// --compare`, tests against a reference), where the quadrature error (≤ 1e-4 relative per form
/// factor) is far below what is measured and the tight default would
/// only cost time.
pub const COARSE_FF_TOLERANCE: f64 = 1e-4;

/// Largest subdivision of one patch side (quads) — 4096² elements; a triangle's depth is capped
/// at the same resolution. Callers check [`element_count`] against their cap first.
const MAX_SPLITS_PER_SIDE: f64 = 4096.0;

/// Settings of the uniform-mesh solver.
#[derive(Copy, Clone, Debug, PartialEq, serde::Serialize)]
pub struct UniformParams {
    /// Longest element side, in scene units (`f64::INFINITY`: one element per patch).
    pub element_size: f64,
    /// Shadow rays per element pair for the visible fraction (0: no occlusion test, V = 1).
    pub rays: u32,
    /// Gauss–Seidel stops when the largest change of any element's radiosity in a sweep is at
    /// most this fraction of the largest radiosity.
    pub tolerance: f64,
    /// Cap on Gauss–Seidel sweeps.
    pub max_iterations: u32,
    /// Seed of the visibility jitter.
    pub seed: u64,
    /// Relative accuracy asked of each form factor's quadrature (each row's absolute accuracy is
    /// about twice this); the CLI's `--ff-tol`, default [`DEFAULT_FF_TOLERANCE`].
    pub ff_tolerance: f64,
    /// Refuse meshes with more elements than this (the matrix needs O(n²) memory and time).
    pub max_elements: usize,
}

impl Default for UniformParams {
    fn default() -> Self {
        UniformParams {
            element_size: f64::INFINITY,
            rays: 16,
            tolerance: 1e-10,
            max_iterations: 1000,
            seed: 0,
            ff_tolerance: DEFAULT_FF_TOLERANCE,
            max_elements: 10_000,
        }
    }
}

impl UniformParams {
    /// The mesh and coupling settings ([`start`]).
    pub(crate) fn mesh(&self) -> MeshSettings {
        let (element_size, max_elements, rays, seed) =
            (self.element_size, self.max_elements, self.rays, self.seed);
        MeshSettings { element_size, max_elements, rays, seed, ff_tolerance: self.ff_tolerance }
    }
}

/// Checks shared by the classical solvers' parameters.
pub(crate) fn validate_common(
    element_size: f64,
    rays: u32,
    ff_tolerance: f64,
    max_elements: usize,
) -> Result<(), String> {
    if element_size.is_nan() || element_size <= 0.0 {
        return Err(format!("element-size must be > 0 (got {element_size})"));
    }
    if rays > 4096 {
        return Err(format!("rays must be in 0..=4096 (got {rays})"));
    }
    if !(ff_tolerance.is_finite() && ff_tolerance > 0.0 && ff_tolerance < 1.0) {
        return Err(format!("ff-tol (form-factor tolerance) must be in (0, 1) (got {ff_tolerance})"));
    }
    if max_elements == 0 {
        return Err("max-elements must be at least 1".into());
    }
    Ok(())
}

impl UniformParams {
    /// Reject absurd values with a message naming the parameter.
    pub fn validate(&self) -> Result<(), String> {
        validate_common(self.element_size, self.rays, self.ff_tolerance, self.max_elements)?;
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            return Err(format!("tolerance must be > 0 (got {})", self.tolerance));
        }
        if self.max_iterations == 0 {
            return Err("max-iterations must be at least 1".into());
        }
        Ok(())
    }
}

/// Grid resolution of a patch: (n, m) splits of a quad's two directions, or (2^k, 2^k) for a
/// triangle split k times.
fn splits(patch: &Patch, element_size: f64) -> (u32, u32, bool) {
    let v = &patch.vertices;
    let count = |len: f64| (len / element_size).ceil().clamp(1.0, MAX_SPLITS_PER_SIDE);
    if v.len() == 4 {
        let nu = count((v[1] - v[0]).length().max((v[2] - v[3]).length()));
        let nv = count((v[3] - v[0]).length().max((v[2] - v[1]).length()));
        (nu as u32, nv as u32, false)
    } else {
        let longest = (0..v.len()).map(|i| (v[(i + 1) % v.len()] - v[i]).length()).fold(0.0, f64::max);
        let k = count(longest).log2().ceil() as u32;
        (1 << k, 1 << k, true)
    }
}

/// Number of elements [`mesh_patch`] makes of `patch` (as f64: it can be astronomically large
/// for a tiny size, which is what callers check before meshing).
#[must_use]
pub fn element_count(patch: &Patch, element_size: f64) -> f64 {
    let v = &patch.vertices;
    let raw = |len: f64| (len / element_size).ceil().max(1.0);
    if v.len() == 4 {
        raw((v[1] - v[0]).length().max((v[2] - v[3]).length()))
            * raw((v[3] - v[0]).length().max((v[2] - v[1]).length()))
    } else {
        let longest = (0..v.len()).map(|i| (v[(i + 1) % v.len()] - v[i]).length()).fold(0.0, f64::max);
        4f64.powf(raw(longest).log2().ceil())
    }
}

/// Split a patch into elements no longer than `element_size` on any side, same orientation as
/// the patch: a quad into an n×m grid of its bilinear map, a triangle into 4^k triangles by
/// midpoint subdivision. (At most 4096 splits per side; see [`element_count`].)
#[must_use]
pub fn mesh_patch(patch: &Patch, element_size: f64) -> Vec<Vec<DVec3>> {
    let v = &patch.vertices;
    let (nu, nv, triangle) = splits(patch, element_size);
    if !triangle {
        let at = |i: u32, j: u32| {
            let (s, t) = (f64::from(i) / f64::from(nu), f64::from(j) / f64::from(nv));
            let a = v[0].lerp(v[1], s);
            let b = v[3].lerp(v[2], s);
            a.lerp(b, t)
        };
        let mut out = Vec::with_capacity((nu * nv) as usize);
        for j in 0..nv {
            for i in 0..nu {
                out.push(vec![at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        return out;
    }
    let mut tris = vec![[v[0], v[1], v[2]]];
    let mut n = 1;
    while n < nu {
        tris = tris
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) = ((a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5);
                [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
            })
            .collect();
        n *= 2;
    }
    tris.into_iter().map(|t| t.to_vec()).collect()
}

/// The largest element size (to 0.1 %) at which the scene meshes into at most
/// `target_elements` elements — a scene-independent way to pick `element_size`.
/// `f64::INFINITY` (one element per patch, the coarsest mesh there is) when the scene has at
/// least `target_elements` patches.
#[must_use]
pub fn element_size_for(scene: &Scene, target_elements: usize) -> f64 {
    let count = |size: f64| scene.patches.iter().map(|p| element_count(p, size)).sum::<f64>();
    let target = target_elements as f64;
    let diam = scene.bounds().diagonal();
    if scene.patches.is_empty() || diam.is_nan() || diam <= 0.0 || count(diam) >= target {
        return f64::INFINITY;
    }
    // count(size) is non-increasing in size: bisect in log space between a size that is too
    // fine and the scene's diagonal (one element per patch).
    let (mut lo, mut hi) = (diam * 1e-6, diam);
    if count(lo) <= target {
        return lo;
    }
    while hi / lo > 1.001 {
        let mid = (lo * hi).sqrt();
        if count(mid) <= target { hi = mid } else { lo = mid }
    }
    hi
}

/// One element of a classical solver's mesh.
#[derive(Clone, Debug)]
pub struct Element {
    pub patch: usize,
    pub vertices: Vec<DVec3>,
    pub area: f64,
}

/// Mesh every patch of the scene, refusing more than `max_elements` elements.
pub fn mesh_scene(scene: &Scene, element_size: f64, max_elements: usize) -> Result<Vec<Element>, String> {
    let total: f64 = scene.patches.iter().map(|p| element_count(p, element_size)).sum();
    if total > max_elements as f64 {
        return Err(format!(
            "element-size {element_size} gives {total:.0} elements, more than the cap of {max_elements} \
             (the form-factor matrix needs O(n²) memory and time): use a larger element size"
        ));
    }
    let mut out = Vec::with_capacity(total as usize);
    for (i, p) in scene.patches.iter().enumerate() {
        for verts in mesh_patch(p, element_size) {
            let area = polygon_area(&verts);
            if area > 0.0 {
                out.push(Element { patch: i, vertices: verts, area });
            }
        }
    }
    Ok(out)
}

/// What a classical solver's parameters say of its mesh and of its pairs' couplings.
pub(crate) struct MeshSettings {
    pub element_size: f64,
    pub max_elements: usize,
    pub rays: u32,
    pub seed: u64,
    pub ff_tolerance: f64,
}

/// The start every classical solver makes: its parameters' check (`valid`), the clock, the
/// mesh ([`mesh_scene`]) and its couplings' settings.
pub(crate) fn start(
    scene: &Scene,
    valid: Result<(), String>,
    m: MeshSettings,
) -> Result<(Instant, Vec<Element>, CouplingSettings), String> {
    valid?;
    let t_start = Instant::now();
    let elems = mesh_scene(scene, m.element_size, m.max_elements)?;
    let settings = CouplingSettings::new(m.rays, m.seed, m.ff_tolerance, elems.len());
    Ok((t_start, elems, settings))
}

/// What the classical solvers need to compute a pair's coupling.
#[derive(Copy, Clone, Debug)]
pub struct CouplingSettings {
    pub rays: u32,
    pub seed: u64,
    pub ff_tolerance: f64,
    /// Absolute floor of each form factor's quadrature accuracy.
    pub ff_abs_tolerance: f64,
}

impl CouplingSettings {
    /// The settings for a mesh of `n` elements: each form factor's absolute accuracy is
    /// `ff_tolerance / n`, so a row of n of them sums to `ff_tolerance`.
    #[must_use]
    pub fn new(rays: u32, seed: u64, ff_tolerance: f64, n: usize) -> Self {
        CouplingSettings { rays, seed, ff_tolerance, ff_abs_tolerance: ff_tolerance / n.max(1) as f64 }
    }
}

/// The coupling of one unordered pair (i < j): `(F_ij V_ij, F_ji V_ji, rays cast, kernel
/// evaluations)`, or `None` when it is zero without a ray cast (same patch, facing away).
///
/// F is integrated over the smaller element (the lower index on a tie) and the other direction
/// follows by reciprocity ([`pair_form_factors`]); V is keyed by the pair, so it is the same in
/// both directions and for every solver that uses this function ([`pair_visibility`]).
#[must_use]
pub fn pair_coupling(
    accel: &Accel,
    elems: &[Element],
    i: usize,
    j: usize,
    s: &CouplingSettings,
) -> Option<(f64, f64, u64, u64)> {
    let (fij, fji, evaluations) = pair_form_factors(elems, i, j, s)?;
    let vis = if s.rays == 0 { 1.0 } else { pair_visibility(accel, elems, i, j, s.rays, s.seed) };
    Some((fij * vis, fji * vis, u64::from(s.rays), evaluations))
}

/// The unoccluded form factors `(F_ij, F_ji, kernel evaluations)` of a pair, or `None` when
/// they are zero (same patch, facing away): F integrated over the smaller element (the lower
/// index on a tie) to `s`'s accuracy, the other direction by reciprocity.
#[must_use]
pub fn pair_form_factors(
    elems: &[Element],
    i: usize,
    j: usize,
    s: &CouplingSettings,
) -> Option<(f64, f64, u64)> {
    let (ei, ej) = (&elems[i], &elems[j]);
    if ei.patch == ej.patch || i == j {
        return None;
    }
    let i_small = ei.area <= ej.area;
    let (from, to) = if i_small { (ei, ej) } else { (ej, ei) };
    let q = polygon_to_polygon_adaptive(&from.vertices, &to.vertices, s.ff_tolerance, s.ff_abs_tolerance);
    if q.value.is_nan() || q.value <= 0.0 {
        return None;
    }
    let back = q.value * from.area / to.area;
    let (fij, fji) = if i_small { (q.value, back) } else { (back, q.value) };
    Some((fij, fji, q.evaluations))
}

/// The visible fraction of the pair (i, j) with `rays` rays and `seed`, keyed by the unordered
/// pair: the same estimate for (j, i).
#[must_use]
pub fn pair_visibility(accel: &Accel, elems: &[Element], i: usize, j: usize, rays: u32, seed: u64) -> f64 {
    let (a, b) = (i.min(j), i.max(j));
    let (ea, eb) = (&elems[a], &elems[b]);
    visible_fraction(
        accel,
        &ea.vertices,
        ea.patch as u32,
        &eb.vertices,
        eb.patch as u32,
        rays,
        seed,
        ((a as u64) << 32) | b as u64,
    )
}

/// Wrap a progress callback so rayon workers can report through it (monotone: a report never
/// goes back, whatever order the workers reach the lock in).
pub(crate) struct SharedProgress<'a> {
    inner: Mutex<(Progress<'a>, u64)>,
    done: AtomicU64,
    total: u64,
}

impl<'a> SharedProgress<'a> {
    pub(crate) fn new(p: Progress<'a>, total: u64) -> Self {
        SharedProgress { inner: Mutex::new((p, 0)), done: AtomicU64::new(0), total }
    }
    /// Add `n` units of work done; reports unless another thread is reporting.
    pub(crate) fn add(&self, n: u64) {
        let done = self.done.fetch_add(n, Ordering::Relaxed) + n;
        if let Ok(mut guard) = self.inner.try_lock() {
            let (p, last) = &mut *guard;
            if done > *last {
                *last = done;
                (*p)(done, self.total);
            }
        }
    }
    pub(crate) fn finish(self) {
        let (p, _) = self.inner.into_inner().unwrap_or_else(std::sync::PoisonError::into_inner);
        (*p)(self.total, self.total);
    }
}

/// One row of the form-factor matrix: the non-zero F_ij V_ij, by increasing j.
#[derive(Default)]
struct Row {
    index: Vec<u32>,
    value: Vec<f64>,
}

impl Row {
    fn push(&mut self, j: u32, f: f64) {
        self.index.push(j);
        self.value.push(f);
    }
}

/// Pairs (i, j > i) of one row: (j, F_ij V, F_ji V), with the rays and kernel evaluations spent.
type UpperRow = (Vec<(u32, f64, f64)>, u64, u64);

/// Solve the scene on a uniform mesh. Errors: invalid parameters, or a mesh over the cap.
pub fn solve(
    scene: &Scene,
    accel: &Accel,
    params: &UniformParams,
    progress: Progress,
) -> Result<Solution, String> {
    let (t_start, elems, settings) = start(scene, params.validate(), params.mesh())?;
    let n = elems.len();

    // Form factors: upper triangle in parallel, rows in order.
    let total_pairs = (n as u64) * (n as u64).saturating_sub(1) / 2;
    let shared = SharedProgress::new(progress, total_pairs);
    let upper: Vec<UpperRow> = (0..n)
        .into_par_iter()
        .map(|i| {
            let mut row = Vec::new();
            let (mut rays, mut evals) = (0u64, 0u64);
            for j in i + 1..n {
                if let Some((fij, fji, r, e)) = pair_coupling(accel, &elems, i, j, &settings) {
                    rays += r;
                    evals += e;
                    if fij > 0.0 || fji > 0.0 {
                        row.push((j as u32, fij, fji));
                    }
                }
            }
            shared.add((n - 1 - i) as u64);
            (row, rays, evals)
        })
        .collect();
    shared.finish();
    // Full rows as index and value arrays (12 bytes per entry). Row r receives its entries
    // j < r while rows j are consumed in order, then its own j > r: already sorted by j.
    let mut rows: Vec<Row> = (0..n).map(|_| Row::default()).collect();
    let (mut rays, mut evaluations) = (0u64, 0u64);
    for (i, (row, r, e)) in upper.into_iter().enumerate() {
        rays += r;
        evaluations += e;
        for (j, fij, fji) in row {
            rows[i].push(j, fij);
            rows[j as usize].push(i as u32, fji);
        }
    }
    debug_assert!(rows.iter().all(|r| r.index.windows(2).all(|w| w[0] < w[1])), "rows sorted");
    let links: usize = rows.iter().map(|r| r.index.len()).sum();
    let t_ff = t_start.elapsed().as_secs_f64();

    // Gauss–Seidel.
    let t_solve = Instant::now();
    let rho: Vec<Rgb> = elems.iter().map(|e| scene.patches[e.patch].reflectance).collect();
    let emis: Vec<Rgb> = elems.iter().map(|e| scene.patches[e.patch].emission).collect();
    let mut b = emis.clone();
    let gather = |b: &[Rgb], row: &Row| {
        row.index.iter().zip(&row.value).map(|(&j, &f)| b[j as usize] * f).sum::<Rgb>()
    };
    let (mut iterations, mut converged, mut last_change) = (0usize, false, f64::INFINITY);
    for _ in 0..params.max_iterations {
        iterations += 1;
        let mut change: f64 = 0.0;
        for i in 0..n {
            let new = emis[i] + rho[i].mul_rgb(gather(&b, &rows[i]));
            change = change.max(new.abs_diff_max(b[i]));
            b[i] = new;
        }
        let scale = b.iter().map(|x| x.max_channel()).fold(0.0, f64::max);
        last_change = if scale > 0.0 { change / scale } else { 0.0 };
        if last_change <= params.tolerance {
            converged = true;
            break;
        }
    }

    // Energy balance from the solver's own quantities.
    let mut energy = EnergyBalance::default();
    for (i, e) in elems.iter().enumerate() {
        let h = gather(&b, &rows[i]);
        let row_sum: f64 = rows[i].value.iter().sum();
        energy.emitted += emis[i] * e.area;
        energy.absorbed += (Rgb::ONE - rho[i]).mul_rgb(h) * e.area;
        energy.escaped += b[i] * (e.area * (1.0 - row_sum));
    }
    let t_solve = t_solve.elapsed().as_secs_f64();

    Ok(mesh_solution(
        scene,
        "uniform".into(),
        constant_elements(elems, &b),
        energy,
        SolveStats {
            links,
            iterations,
            rays,
            time_s: PhaseTimes::of_solve(t_ff, t_solve),
            extra: Some(serde_json::json!({
                "converged": converged,
                "final_change": last_change,
                "kernel_evaluations": evaluations,
                "params": params,
            })),
            ..SolveStats::default()
        },
    ))
}

/// The elements of a mesh with one radiosity each (`b`, in element order): constant, no error
/// estimate, no slope.
pub(super) fn constant_elements(elems: Vec<Element>, b: &[Rgb]) -> Vec<SolvedElement> {
    elems
        .into_iter()
        .zip(b)
        .map(|(e, &radiosity)| SolvedElement::constant(e.patch, e.vertices, e.area, radiosity))
        .collect()
}

/// The [`Solution`] of a solver on a mesh of the input patches: its elements, each patch's
/// area-weighted average of them, the energy balance, and `stats` with the patch and element
/// counts filled in.
pub(super) fn mesh_solution(
    scene: &Scene,
    method: String,
    elements: Vec<SolvedElement>,
    energy: EnergyBalance,
    stats: SolveStats,
) -> Solution {
    let patch_radiosity = Solution::patch_averages(scene.patches.len(), &elements);
    Solution {
        method,
        stats: SolveStats { patches: scene.patches.len(), elements: elements.len(), ..stats },
        elements,
        patch_radiosity,
        energy,
    }
}
