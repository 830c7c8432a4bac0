//! The p = 0 Galerkin solve on a discontinuity mesh, reported on the **input** scene.
//!
//! [`crate::mesh::remesh::discontinuity_scene`] replaces every receiver with critical segments by
//! its mesh pieces (Heckbert's CDT or Campbell & Fussell's BSP), each a patch; the uniform solver
//! with one element per patch then solves
//!
//! ```text
//! B_i = E_i + ρ_i Σ_j F_ij V_ij B_j          over the pieces i, j   [Heckbert 1992, §3]
//! ```
//!
//! and [`pull_back`] hands every solved element back to the input patch it was cut from (the
//! remeshed scene's `origin`), so the solution is a [`Solution`] **of the input scene**: its
//! elements are the pieces, its patch indices the input's. Anything that scores a solution of the
//! input scene — the pointwise ruler ([`crate::pointwise`]) at points placed on the input
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
use super::uniform::{self, COARSE_FF_TOLERANCE, UniformParams, mesh_scene};
use super::{Progress, Solution};
use crate::accel::Accel;
use crate::math::Rgb;
use crate::mesh::MeshError;
use crate::mesh::remesh::{MeshKind, RemeshParams, RemeshStats, discontinuity_scene};
use crate::scene::Scene;
use std::sync::Arc;
use std::time::Instant;

/// The most pieces [`solve_hierarchical`]'s callers let a discontinuity mesh have (the CLI's cap
/// for the hierarchical top level): the hierarchical solver clusters a scene of more than 3 000
/// patches and links it in about linear memory (furnished-100k: 34 s, 1.3 GB, docs/scale.md),
/// where the uniform solver's n² couplings keep [`RemeshParams::cdt`]'s 10 000.
pub const HIERARCHICAL_MAX_PIECES: usize = 100_000;

/// Settings of [`solve`]: the mesh, and the uniform solve on it (`element_size` is forced to ∞,
/// one element per piece).
#[derive(Copy, Clone, Debug, PartialEq, serde::Serialize)]
pub struct DiscontinuityParams {
    pub mesh: RemeshParams,
    /// Rays, tolerances, seed and element cap of the uniform solve.
    pub solve: UniformParams,
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
    /// Wall time of the solve on the mesh (BVH build included), seconds.
    pub solve_s: f64,
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
    let on_mesh =
        uniform::solve(&meshed.scene, &accel, &solve, progress).map_err(DiscontinuityError::Solve)?;
    let solve_s = t.elapsed().as_secs_f64();
    let mut solution = pull_back(on_mesh, &meshed.origin, scene.patches.len());
    solution.method = match params.mesh.kind {
        MeshKind::Cdt => "discontinuity-cdt",
        MeshKind::Bsp => "discontinuity-bsp",
    }
    .into();
    Ok(DiscontinuitySolution { solution, mesh: meshed.stats, solve_s })
}

/// [`solve`] with the Galerkin solver of [`super::linear`] on the pieces (order and continuity
/// from `linear`; its element size is not used: one element per piece). Continuous coefficients
/// are shared between the pieces of one input patch (the CDT is conforming). Returns the solution
/// on the input scene and each element's coefficients ([`crate::reconstruction::Nodal`]).
pub fn solve_galerkin(
    scene: &Scene,
    params: &DiscontinuityParams,
    linear: &LinearParams,
    progress: Progress,
) -> Result<(DiscontinuitySolution, Vec<Vec<Rgb>>), DiscontinuityError> {
    let meshed = discontinuity_scene(scene, &params.mesh)?;
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
    Ok((DiscontinuitySolution { solution, mesh: meshed.stats, solve_s }, on_mesh.coefficients))
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
    params.validate().map_err(DiscontinuityError::Solve)?;
    let meshed = discontinuity_scene(scene, mesh)?;
    let t = Instant::now();
    let pieces = Arc::new(meshed.scene);
    let accel = Arc::new(Accel::build(&pieces));
    let bvh_s = t.elapsed().as_secs_f64();
    let mut solver = HierarchicalSolver::with_accel(Arc::clone(&pieces), accel, params, bvh_s);
    solver.solve(progress);
    let on_mesh = solver.solution_with(false);
    let solve_s = t.elapsed().as_secs_f64();
    let mut solution = pull_back(on_mesh, &meshed.origin, scene.patches.len());
    solution.method = match mesh.kind {
        MeshKind::Cdt => "hierarchical on discontinuity-cdt",
        MeshKind::Bsp => "hierarchical on discontinuity-bsp",
    }
    .into();
    Ok(DiscontinuitySolution { solution, mesh: meshed.stats, solve_s })
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

    #[test]
    fn a_mesh_error_reads_once_in_the_one_line_chain() {
        let e: DiscontinuityError = MeshError::TooManyPatches { count: 20, cap: 10 }.into();
        let line = format!("{:#}", anyhow::Error::from(e));
        assert_eq!(line.matches("more than the cap").count(), 1, "{line}");
        assert!(line.starts_with("discontinuity mesh: the discontinuity mesh has 20 patches"), "{line}");
    }
}
