//! The p = 0 Galerkin solve on a discontinuity mesh, reported on the **input** scene.
//!
//! [`crate::mesh::remesh::discontinuity_scene`] replaces every receiver with critical segments by
//! its mesh pieces (Heckbert's CDT or Campbell & Fussell's BSP), each a patch; the uniform solver
//! with one element per patch then solves
//!
//! ```text
//! B_i = E_i + ρ_i Σ_j F_ij V_ij B_j          over the pieces i, j   [Heckbert 1992, sec. 3]
//! ```
//!
//! then [`gather`] re-integrates the direct light of the pieces that see an emitter partly (more
//! shadow rays where the solve's V is strictly between 0 and 1) and gives every piece a slope
//! from the irradiance gathered at its points (a constant element with a slope, as the
//! hierarchical solver's leaves; `DiscontinuityParams::gather`, on by default), and [`pull_back`]
//! hands every solved element back to the input patch it was cut from (the
//! remeshed scene's `origin`), so the solution is a [`Solution`] **of the input scene**: its
//! elements are the pieces, its patch indices the input's. Anything that scores a solution of the
//! input scene — the pointwise ruler ([`crate::eval::pointwise`]) at points placed on the input
//! patches, images, the element-average comparison — then reads it like any other method's:
//!
//! ```text
//! input scene ──remesh──▶ pieces (patch q, origin[q] = p) ──uniform, p = 0──▶ B_q
//!      ▲                                                                       │
//!      └─────────────── element (patch p, piece q's polygon, B_q) ◀── pull_back ┘
//! ```
//!
//! [`solve_galerkin`] does the same with the Galerkin solver of [`super::linear`] (p = 0 or
//! p = 1, continuous across the pieces of one input patch) and returns the coefficients too.
//!
//! [`solve_hierarchical`] makes the discontinuity mesh the **top level of hierarchical
//! refinement** [Lischinski, Tampieri & Greenberg 1993, "Combining hierarchical radiosity and
//! discontinuity meshing"]: the pieces are the input patches of the hierarchical solver
//! ([`super::hierarchical`], HSA91), which links them, subdivides them as its oracle asks (each
//! piece a quadtree of triangles or quads below it) and pushes slopes to its leaves; every leaf
//! is pulled back onto the input patch its piece was cut from. Shadow boundaries then lie on
//! top-level edges, which no subdivision has to find.

use super::hierarchical::HierarchicalSolver;
use super::linear::LinearParams;
use super::params::HierarchicalParams;
use super::uniform::{
    self, COARSE_FF_TOLERANCE, CouplingSettings, Element, UniformParams, mesh_scene, pair_form_factors,
    pair_visibility,
};
use super::{Progress, Slope, Solution};
use crate::geometry::accel::Accel;
use crate::geometry::form_factor::point_to_polygon;
use crate::geometry::visibility::point_on_polygon;
use crate::math::{DVec3, Rgb, orthonormal_basis, polygon_area, polygon_centroid};
use crate::mesh::MeshError;
use crate::mesh::remesh::{MeshKind, RemeshParams, RemeshStats, conform, discontinuity_scene};
use crate::scene::Scene;
use rayon::prelude::*;
use std::sync::Arc;
use std::time::Instant;

/// The contact mesh's area floor per unit of the error oracle's relative threshold: Aeps =
/// 6e-4 · X of the scene's area ([`contact_area_floor`]; `radlab bench`'s contact rows).
pub const CONTACT_AEPS_PER_EPS: f64 = 6e-4;

/// `p` with its area floor shrinking with the error oracle's relative threshold X, Aeps =
/// [`CONTACT_AEPS_PER_EPS`] · X of the scene's area (unchanged for the other oracles or an
/// absolute threshold). What `radlab solve --mesh contact` and `radlab reference --compare
/// hierarchical-contact` use unless told an Aeps: on the contact mesh the error then falls at
/// each halving of X, where the `quality` preset's fixed 1e-4 stops the refinement below
/// X ≈ 0.15 (docs/meshing.md).
#[must_use]
pub const fn contact_area_floor(p: HierarchicalParams) -> HierarchicalParams {
    use super::params::{AreaEps, Oracle};
    if matches!(p.oracle, Oracle::Error) && p.bf_relative {
        HierarchicalParams { aeps: AreaEps::Relative(CONTACT_AEPS_PER_EPS * p.bf_eps), ..p }
    } else {
        p
    }
}

/// Settings of [`solve`]: the mesh, and the uniform solve on it (`element_size` is forced to ∞,
/// one element per piece).
#[derive(Copy, Clone, Debug, PartialEq, serde::Serialize)]
pub struct DiscontinuityParams {
    pub mesh: RemeshParams,
    /// Rays, tolerances, seed and element cap of the uniform solve.
    pub solve: UniformParams,
    /// After the solve, [`gather`]: the direct light of partly shadowed pieces re-integrated
    /// with more rays, and a slope per piece from a gather at its points.
    pub gather: bool,
}

impl DiscontinuityParams {
    /// The uniform solve's settings used by `radlab mesh --solve` and `reference --compare
    /// dmesh-*`: 16 rays per pair, form factors to [`COARSE_FF_TOLERANCE`].
    #[must_use]
    pub fn with_mesh(mesh: RemeshParams) -> DiscontinuityParams {
        DiscontinuityParams {
            mesh,
            solve: UniformParams {
                element_size: f64::INFINITY,
                ff_tolerance: COARSE_FF_TOLERANCE,
                max_elements: mesh.max_patches,
                ..UniformParams::default()
            },
            gather: true,
        }
    }

    /// Heckbert's constrained Delaunay mesh ([`RemeshParams::cdt`]).
    #[must_use]
    pub fn cdt() -> DiscontinuityParams {
        Self::with_mesh(RemeshParams::cdt())
    }

    /// Campbell & Fussell's BSP mesh ([`RemeshParams::bsp`]).
    #[must_use]
    pub fn bsp() -> DiscontinuityParams {
        Self::with_mesh(RemeshParams::bsp())
    }
}

/// Why [`solve`] failed.
#[derive(Debug, thiserror::Error)]
pub enum DiscontinuityError {
    /// The mesh's message is part of this one (not a separate source, which `{:#}` would print
    /// a second time).
    #[error("discontinuity mesh: {0}")]
    Mesh(MeshError),
    #[error("solve on the discontinuity mesh: {0}")]
    Solve(String),
}

impl From<MeshError> for DiscontinuityError {
    fn from(e: MeshError) -> Self {
        DiscontinuityError::Mesh(e)
    }
}

/// A solve on a discontinuity mesh: the solution on the input scene, the mesh's statistics and
/// the two times (meshing is in `mesh.total_s`).
#[derive(Clone, Debug)]
pub struct DiscontinuitySolution {
    /// Elements on the input scene's patches ([`pull_back`]).
    pub solution: Solution,
    pub mesh: RemeshStats,
    /// Wall time of the solve on the mesh (BVH build and [`gather`] included), seconds.
    pub solve_s: f64,
    /// What [`gather`] did (p = 0 solves with [`DiscontinuityParams::gather`]).
    pub gather: Option<GatherStats>,
}

/// Remesh `scene` and solve on the pieces (module docs).
pub fn solve(
    scene: &Scene,
    params: &DiscontinuityParams,
    progress: Progress,
) -> Result<DiscontinuitySolution, DiscontinuityError> {
    let meshed = discontinuity_scene(scene, &params.mesh)?;
    let t = Instant::now();
    let accel = Accel::build(&meshed.scene);
    let solve = UniformParams { element_size: f64::INFINITY, ..params.solve };
    let mut on_mesh =
        uniform::solve(&meshed.scene, &accel, &solve, progress).map_err(DiscontinuityError::Solve)?;
    let gathered = params.gather.then(|| gather(&meshed.scene, &accel, &solve, &mut on_mesh));
    let solve_s = t.elapsed().as_secs_f64();
    let mut solution = pull_back(on_mesh, &meshed.origin, scene.patches.len());
    solution.method = match params.mesh.kind {
        MeshKind::Cdt => "discontinuity-cdt",
        MeshKind::Bsp => "discontinuity-bsp",
    }
    .into();
    Ok(DiscontinuitySolution { solution, mesh: meshed.stats, solve_s, gather: gathered })
}

/// [`solve`] with the Galerkin solver of [`super::linear`] on the pieces (order and continuity
/// from `linear`; its element size is not used: one element per piece). Continuous coefficients
/// are shared between the pieces of one input patch (the CDT is conforming). Returns the solution
/// on the input scene and each element's coefficients ([`crate::eval::reconstruction::Nodal`]). A
/// continuous basis on the (ungraded) BSP mesh runs on its pieces made conforming first
/// ([`crate::mesh::remesh::conform`]: the T-vertices inserted, pieces that gained corners fanned
/// into triangles). An ungraded mesh whose pieces need more unknowns than `linear.max_unknowns`
/// (the matrix is O(n²)) is graded to the most pieces that fit ([`crate::mesh::grade`]: small in
/// the penumbrae, larger elsewhere; the stats' `graded` says so) instead of refused; a continuous
/// basis needs the conforming ungraded mesh and keeps the cap's error.
pub fn solve_galerkin(
    scene: &Scene,
    params: &DiscontinuityParams,
    linear: &LinearParams,
    progress: Progress,
) -> Result<(DiscontinuitySolution, Vec<Vec<Rgb>>), DiscontinuityError> {
    let mut meshed = discontinuity_scene(scene, &params.mesh)?;
    let fits = linear.max_unknowns / linear.order.functions(4).max(1);
    if params.mesh.grade.is_none() && !linear.continuous && meshed.scene.patches.len() > fits {
        let mesh = RemeshParams {
            grade: Some(crate::mesh::grade::GradeParams::with_budget(fits)),
            cdt: crate::mesh::cdt::CdtParams::unrefined(),
            max_patches: params.mesh.max_patches.max(fits),
            ..params.mesh
        };
        meshed = discontinuity_scene(scene, &mesh)?;
    }
    if linear.continuous && params.mesh.kind == MeshKind::Bsp && params.mesh.grade.is_none() {
        // Shared vertex values need the pieces to meet corner to corner.
        conform(&mut meshed, scene);
    }
    let t = Instant::now();
    let accel = Accel::build(&meshed.scene);
    let per_element = linear.order.functions(4);
    let elems = mesh_scene(&meshed.scene, f64::INFINITY, linear.max_unknowns / per_element.max(1))
        .map_err(DiscontinuityError::Solve)?;
    let groups: Vec<usize> = elems.iter().map(|e| meshed.origin[e.patch]).collect();
    let on_mesh = super::linear::solve_mesh(&meshed.scene, &accel, elems, &groups, linear, progress)
        .map_err(DiscontinuityError::Solve)?;
    let solve_s = t.elapsed().as_secs_f64();
    let mut solution = pull_back(on_mesh.solution, &meshed.origin, scene.patches.len());
    solution.method = match params.mesh.kind {
        MeshKind::Cdt => "discontinuity-cdt",
        MeshKind::Bsp => "discontinuity-bsp",
    }
    .into();
    Ok((DiscontinuitySolution { solution, mesh: meshed.stats, solve_s, gather: None }, on_mesh.coefficients))
}

/// The discontinuity mesh of `mesh` as the top level of the hierarchical solver with `params`
/// (module docs): the solution's elements are the hierarchy's leaves, pulled back onto the input
/// patches; `solve_s` is the hierarchical solve's (BVH of the pieces included).
pub fn solve_hierarchical(
    scene: &Scene,
    mesh: &RemeshParams,
    params: HierarchicalParams,
    progress: Progress,
) -> Result<DiscontinuitySolution, DiscontinuityError> {
    let mut on_mesh = HierarchicalOnMesh::new(scene, mesh, params)?;
    on_mesh.solver.solve(progress);
    Ok(on_mesh.finish(false))
}

/// [`solve_hierarchical`] in its steps, for a caller that needs the solver between them (its
/// cancel handle, as `radlab bench` uses it): the mesh and the solver on its pieces, not yet
/// solved.
pub struct HierarchicalOnMesh {
    pub solver: HierarchicalSolver,
    origin: Vec<usize>,
    input_patches: usize,
    stats: RemeshStats,
    kind: MeshKind,
    events: crate::mesh::remesh::Events,
    started: Instant,
}

impl HierarchicalOnMesh {
    /// Mesh `scene` and set the hierarchical solver up on the pieces (BVH built).
    pub fn new(
        scene: &Scene,
        mesh: &RemeshParams,
        params: HierarchicalParams,
    ) -> Result<HierarchicalOnMesh, DiscontinuityError> {
        params.validate().map_err(DiscontinuityError::Solve)?;
        let meshed = discontinuity_scene(scene, mesh)?;
        let started = Instant::now();
        let pieces = Arc::new(meshed.scene);
        let accel = Arc::new(Accel::build(&pieces));
        let bvh_s = started.elapsed().as_secs_f64();
        let solver = HierarchicalSolver::with_accel(Arc::clone(&pieces), accel, params, bvh_s);
        Ok(HierarchicalOnMesh {
            solver,
            origin: meshed.origin,
            input_patches: scene.patches.len(),
            stats: meshed.stats,
            kind: mesh.kind,
            events: mesh.events,
            started,
        })
    }

    /// The solver on the pieces, and each piece's input patch.
    #[must_use]
    pub fn into_parts(self) -> (HierarchicalSolver, Vec<usize>) {
        (self.solver, self.origin)
    }

    /// The solved hierarchy's leaves pulled back onto the input scene, with the solver's own
    /// per-element error estimates if `estimates` ([`HierarchicalSolver::solution_with`]; they
    /// are computed on the pieces, which carry their input patch's material); `solve_s` counts
    /// from [`Self::new`]'s BVH on, the estimates not included.
    #[must_use]
    pub fn finish(self, estimates: bool) -> DiscontinuitySolution {
        use crate::mesh::remesh::Events;
        let solve_s = self.started.elapsed().as_secs_f64();
        let on_mesh = self.solver.solution_with(estimates);
        let mut solution = pull_back(on_mesh, &self.origin, self.input_patches);
        solution.method = match (self.events, self.kind) {
            (Events::Contacts, _) => "hierarchical on contact mesh",
            (Events::All, MeshKind::Cdt) => "hierarchical on discontinuity-cdt",
            (Events::All, MeshKind::Bsp) => "hierarchical on discontinuity-bsp",
        }
        .into();
        DiscontinuitySolution { solution, mesh: self.stats, solve_s, gather: None }
    }
}

/// Shadow rays of a piece–emitter pair whose solve estimate is partly visible ([`gather`]).
pub const PARTIAL_RAYS: u32 = 256;
/// Emitter samples per side at each gather point (`side²` shadow rays per point and emitter).
pub const GATHER_EMITTER_SIDE: u32 = 8;
/// Shadow rays of a piece–piece pair for the gather's indirect part.
pub const GATHER_PAIR_RAYS: u32 = 4;

/// What [`gather`] did.
#[derive(Copy, Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct GatherStats {
    /// Piece–emitter pairs re-integrated with [`PARTIAL_RAYS`] rays.
    pub partial_pairs: usize,
    /// Pieces given a slope.
    pub slopes: usize,
    pub seconds: f64,
}

/// Two corrections of a p = 0 solve on the pieces of a discontinuity mesh (`solution`: the
/// uniform solve of `scene` with `solve`, one element per piece, not yet pulled back), both
/// aimed at what constant elements with 16 shadow rays per pair leave in a penumbra:
///
/// 1. **The direct light of partly shadowed pieces, re-integrated.** A piece whose coupling to
///    an emitter piece came out partly visible in the solve (0 < V < 1 with `solve.rays` rays)
///    gets that coupling again with [`PARTIAL_RAYS`] rays (the solve's own estimate is
///    recomputed: [`uniform::pair_visibility`] is keyed by the pair; F once), and
///    `B_i += ρ_i (F_ij V_ij⁽²⁵⁶⁾ − F_ij V_ij⁽ⁿ⁾) B_j`. Adaptive sampling where V ∈ (0, 1) only:
///    fully lit and umbra pieces, where every ray agreed, keep the solve's value.
/// 2. **A slope per piece** (`SolvedElement::slope`, as the hierarchical solver's leaves carry
///    one): the gathered irradiance `H(x) = Σ_j B_j F(x → j) v_j(x)` at the piece's points
///    `x_k = c + (v_k − c) / 2` (the 3-point Gauss rule on a triangle), F the unoccluded
///    point-to-polygon form factor (closed form), v_j the visible fraction from x of an emitter
///    piece (a [`GATHER_EMITTER_SIDE`]² grid, kernel-weighted) and of any other piece the
///    pair's ([`GATHER_PAIR_RAYS`] rays); the slope is ρ_i times the least-squares gradient of
///    H in the piece's plane. The piece's average B_i is kept, so the slope moves light within
///    the piece, not between pieces.
///
/// The energy balance is the solve's (before step 1). A solve without shadow rays (`rays` 0: no
/// occlusion) is left as it is.
pub fn gather(scene: &Scene, accel: &Accel, solve: &UniformParams, solution: &mut Solution) -> GatherStats {
    let t = Instant::now();
    let elems: Vec<Element> = solution
        .elements
        .iter()
        .map(|e| Element { patch: e.patch, vertices: e.vertices.clone(), area: e.area })
        .collect();
    let n = elems.len();
    let settings = CouplingSettings::new(solve.rays, solve.seed, solve.ff_tolerance, n);
    let emitters: Vec<usize> =
        (0..n).filter(|&j| scene.patches[elems[j].patch].emission != Rgb::ZERO).collect();
    let b: Vec<Rgb> = solution.elements.iter().map(|e| e.radiosity).collect();
    let normals: Vec<DVec3> = elems.iter().map(|e| scene.patches[e.patch].normal).collect();
    let per_piece: Vec<(Rgb, Option<Slope>, usize)> = (0..n)
        .into_par_iter()
        .map(|i| {
            let rho = scene.patches[elems[i].patch].reflectance;
            if rho == Rgb::ZERO || solve.rays == 0 {
                return (Rgb::ZERO, None, 0);
            }
            // 1. Partly visible emitter couplings, again with more rays.
            let mut delta = Rgb::ZERO;
            let mut partial = 0;
            for &j in &emitters {
                // The solve's estimate of the pair's V (same rays, seed and key), then, where it
                // is partial, a better one; F (the costly cubature) once.
                let Some((f, ..)) = pair_form_factors(&elems, i, j, &settings) else { continue };
                let v = pair_visibility(accel, &elems, i, j, settings.rays, settings.seed);
                if v > 0.0 && v < 1.0 - 1e-12 {
                    let good = pair_visibility(accel, &elems, i, j, PARTIAL_RAYS, settings.seed);
                    delta += b[j] * (f * good - f * v);
                    partial += 1;
                }
            }
            // 2. The gathered irradiance at the piece's points, and its gradient.
            let c = polygon_centroid(&elems[i].vertices);
            let points: Vec<DVec3> = elems[i].vertices.iter().map(|&v| c.lerp(v, 0.5)).collect();
            let n_i = normals[i];
            let mut h = vec![Rgb::ZERO; points.len()];
            let mut ff = vec![0.0; points.len()];
            for j in 0..n {
                if elems[j].patch == elems[i].patch || b[j] == Rgb::ZERO {
                    continue;
                }
                let mut any = false;
                for (k, &x) in points.iter().enumerate() {
                    ff[k] = point_to_polygon(x, n_i, &elems[j].vertices).max(0.0);
                    any |= ff[k] > 0.0;
                }
                if !any {
                    continue;
                }
                if emitters.binary_search(&j).is_ok() {
                    for (k, &x) in points.iter().enumerate() {
                        if ff[k] > 0.0 {
                            let v = point_visible(accel, (x, n_i, elems[i].patch), (&elems[j], normals[j]));
                            h[k] += b[j] * (ff[k] * v);
                        }
                    }
                } else {
                    let v = pair_visibility(
                        accel,
                        &elems,
                        i,
                        j,
                        GATHER_PAIR_RAYS,
                        solve.seed ^ 0x9a7e_5105_0000_0001,
                    );
                    for k in 0..points.len() {
                        h[k] += b[j] * (ff[k] * v);
                    }
                }
            }
            let slope =
                plane_gradient(&points, &h, n_i).map(|g| Slope { centroid: c, d: g.map(|d| rho.mul_rgb(d)) });
            (rho.mul_rgb(delta), slope, partial)
        })
        .collect();
    let mut stats = GatherStats::default();
    for (e, (delta, slope, partial)) in solution.elements.iter_mut().zip(per_piece) {
        e.radiosity = (e.radiosity + delta).map(|v| v.max(0.0));
        stats.partial_pairs += partial;
        stats.slopes += usize::from(slope.is_some());
        e.slope = slope;
    }
    solution.patch_radiosity = Solution::patch_averages(solution.patch_radiosity.len(), &solution.elements);
    stats.seconds = t.elapsed().as_secs_f64();
    stats
}

/// The kernel-weighted fraction of `emitter` (a convex piece, normal `n_e`) that `x` (on patch
/// `patch`, normal `n`) sees: a [`GATHER_EMITTER_SIDE`]² grid on each triangle of its fan, area
/// weighted, each ray weighted by cos θ_x cos θ_y / r² (so ∫ K V / ∫ K, the factor of the point's
/// form factor that is visible). 1 when no sample faces `x`.
fn point_visible(
    accel: &Accel,
    (x, n, patch): (DVec3, DVec3, usize),
    (emitter, n_e): (&Element, DVec3),
) -> f64 {
    let side = GATHER_EMITTER_SIDE;
    let s = f64::from(side);
    let v = &emitter.vertices;
    let mut last = crate::geometry::accel::NO_HIT;
    let (mut seen, mut all) = (0.0, 0.0);
    for t in 1..v.len() - 1 {
        let tri = [v[0], v[t], v[t + 1]];
        let w = polygon_area(&tri) / (s * s);
        for q in 0..side * side {
            let (u, r) = ((f64::from(q % side) + 0.5) / s, (f64::from(q / side) + 0.5) / s);
            let y = point_on_polygon(&tri, u, r);
            let d = y - x;
            let r2 = d.length_squared();
            let k = w * n.dot(d).max(0.0) * (-n_e.dot(d)).max(0.0) / (r2 * r2);
            if k <= 0.0 {
                continue;
            }
            all += k;
            if !accel.occluded_cached(x, y, [patch as u32, emitter.patch as u32], &mut last) {
                seen += k;
            }
        }
    }
    if all > 0.0 { seen / all } else { 1.0 }
}

/// The least-squares gradient, in the plane of normal `n`, of the values `h` at `points` (≥ 3,
/// not collinear), per channel, as world-axis components; `None` when the points do not span
/// the plane.
fn plane_gradient(points: &[DVec3], h: &[Rgb], n: DVec3) -> Option<[Rgb; 3]> {
    let (t, b) = orthonormal_basis(n);
    let m = points.len() as f64;
    let c = points.iter().copied().sum::<DVec3>() / m;
    let hm = h.iter().copied().sum::<Rgb>() * (1.0 / m);
    let (mut uu, mut uw, mut ww) = (0.0, 0.0, 0.0);
    let (mut uh, mut wh) = (Rgb::ZERO, Rgb::ZERO);
    for (&x, &hk) in points.iter().zip(h) {
        let (u, w) = ((x - c).dot(t), (x - c).dot(b));
        uu += u * u;
        uw += u * w;
        ww += w * w;
        uh += (hk - hm) * u;
        wh += (hk - hm) * w;
    }
    let det = uu * ww - uw * uw;
    if !(det > 1e-12 * (uu + ww) * (uu + ww)) {
        return None;
    }
    let gu = (uh * ww - wh * uw) * (1.0 / det);
    let gw = (wh * uu - uh * uw) * (1.0 / det);
    Some([0, 1, 2].map(|a| gu * t[a] + gw * b[a]))
}

/// A solution of a remeshed scene as a solution of its input scene: each element's patch `q`
/// becomes `origin[q]` (the input patch piece `q` was cut from), and the per-patch averages are
/// taken over the input's `input_patches` patches. Elements, values, energy and statistics are
/// kept (`stats.patches` becomes the input's count).
#[must_use]
pub fn pull_back(mut solution: Solution, origin: &[usize], input_patches: usize) -> Solution {
    for e in &mut solution.elements {
        e.patch = origin[e.patch];
    }
    solution.patch_radiosity = Solution::patch_averages(input_patches, &solution.elements);
    solution.stats.patches = input_patches;
    solution
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pull_back_maps_pieces_to_their_input_patch() {
        let scene = Scene::load("builtin:shadow-narrow").unwrap();
        let meshed = discontinuity_scene(&scene, &RemeshParams::bsp()).unwrap();
        assert!(meshed.scene.patches.len() > scene.patches.len());
        let d = solve(&scene, &DiscontinuityParams::bsp(), &mut |_, _| {}).unwrap();
        let sol = &d.solution;
        assert_eq!(sol.method, "discontinuity-bsp");
        assert_eq!(sol.elements.len(), meshed.scene.patches.len(), "one element per piece");
        assert_eq!(sol.patch_radiosity.len(), scene.patches.len());
        // Every input patch is covered by its pieces exactly (area).
        for (p, patch) in scene.patches.iter().enumerate() {
            let area: f64 = sol.elements.iter().filter(|e| e.patch == p).map(|e| e.area).sum();
            assert!((area - patch.area).abs() < 1e-9 * patch.area, "patch {p}: {area} vs {}", patch.area);
        }
        // The emitter keeps its emission; the lit receiver is positive.
        let emitter = scene.patches.iter().position(|p| p.emission != Rgb::ZERO).unwrap();
        assert!(sol.patch_radiosity[emitter].g() >= scene.patches[emitter].emission.g());
        assert!(sol.is_physical());
    }

    /// The hierarchical solver on the pieces: every leaf lies on (and is pulled back to) an input
    /// patch, the leaves cover each input patch, at least one piece is subdivided further, and
    /// the lit receiver's average agrees with the p = 0 solve on the same pieces.
    #[test]
    fn hierarchical_on_the_pieces_covers_the_input_patches() {
        let scene = Scene::load("builtin:shadow-narrow").unwrap();
        let mesh = RemeshParams::bsp();
        let pieces = discontinuity_scene(&scene, &mesh).unwrap().scene.patches.len();
        let h = solve_hierarchical(&scene, &mesh, HierarchicalParams::quality(), &mut |_, _| {}).unwrap();
        let sol = &h.solution;
        assert_eq!(sol.method, "hierarchical on discontinuity-bsp");
        assert!(sol.elements.len() > pieces, "{} leaves on {pieces} pieces", sol.elements.len());
        for (p, patch) in scene.patches.iter().enumerate() {
            let area: f64 = sol.elements.iter().filter(|e| e.patch == p).map(|e| e.area).sum();
            assert!((area - patch.area).abs() < 1e-9 * patch.area, "patch {p}: {area} vs {}", patch.area);
        }
        assert!(sol.is_physical());
        let flat = solve(&scene, &DiscontinuityParams::bsp(), &mut |_, _| {}).unwrap().solution;
        let lit = scene
            .patches
            .iter()
            .enumerate()
            .filter(|(_, p)| p.emission == Rgb::ZERO)
            .map(|(i, _)| i)
            .max_by(|&a, &b| flat.patch_radiosity[a].mean().total_cmp(&flat.patch_radiosity[b].mean()))
            .unwrap();
        let (hb, fb) = (sol.patch_radiosity[lit].mean(), flat.patch_radiosity[lit].mean());
        assert!((hb - fb).abs() < 0.05 * fb, "lit receiver: hierarchical {hb} vs p = 0 {fb}");
    }

    /// The gradient of an affine field is recovered exactly from three or more points in any
    /// plane; collinear points give none.
    #[test]
    fn plane_gradient_recovers_an_affine_field() {
        let n = DVec3::new(1.0, 2.0, -0.5).normalize();
        let (t, b) = orthonormal_basis(n);
        let g = t * 0.7 - b * 1.3; // in the plane
        let field = |x: DVec3| Rgb::new(2.0 + g.dot(x), 1.0 - 2.0 * g.dot(x), 0.5);
        let points = [DVec3::ZERO, t, b, t + b * 0.3];
        let h: Vec<Rgb> = points.iter().map(|&x| field(x)).collect();
        let d = plane_gradient(&points, &h, n).unwrap();
        for a in 0..3 {
            assert!((d[a].r() - g[a]).abs() < 1e-12 && (d[a].g() + 2.0 * g[a]).abs() < 1e-12, "{d:?}");
            assert!(d[a].b().abs() < 1e-12);
        }
        assert!(plane_gradient(&[DVec3::ZERO, t, t * 2.0], &h[..3], n).is_none());
    }

    /// The gather on shadow-narrow's BSP: every lit piece gets a slope, the pieces the solve saw
    /// partly shadowed from the lamp are re-integrated, and each receiver's average stays within
    /// a few percent of the ungathered solve's (the gather moves light within pieces, and only
    /// the partial pieces' averages change).
    #[test]
    fn gather_gives_slopes_and_keeps_the_averages() {
        let scene = Scene::load("builtin:shadow-narrow").unwrap();
        let off = solve(
            &scene,
            &DiscontinuityParams { gather: false, ..DiscontinuityParams::bsp() },
            &mut |_, _| {},
        )
        .unwrap();
        let on = solve(&scene, &DiscontinuityParams::bsp(), &mut |_, _| {}).unwrap();
        let g = on.gather.unwrap();
        assert!(off.gather.is_none() && off.solution.elements.iter().all(|e| e.slope.is_none()));
        assert!(g.partial_pairs > 0 && g.slopes > 0, "{g:?}");
        let receiver = crate::geometry::exact::SingleBounce::new(&scene).unwrap().receiver;
        let (a, b) = (off.solution.patch_radiosity[receiver].g(), on.solution.patch_radiosity[receiver].g());
        assert!((a - b).abs() < 0.05 * a, "receiver average {a} → {b}");
        assert!(on.solution.is_physical());
    }

    #[test]
    fn a_mesh_error_reads_once_in_the_one_line_chain() {
        let e: DiscontinuityError = MeshError::TooManyPatches { count: 20, cap: 10 }.into();
        let line = format!("{:#}", anyhow::Error::from(e));
        assert_eq!(line.matches("more than the cap").count(), 1, "{line}");
        assert!(line.starts_with("discontinuity mesh: the discontinuity mesh has 20 patches"), "{line}");
    }
}
