//! What solves a scene, said once: a [`SolveSpec`] (the solver, the mesh it runs on, the element
//! order and every setting) and one [`solve`] that runs it. `radlab solve`, the benchmarks and
//! the studies build a spec, from a [`Preset`] and their flags, and call [`solve`].
//!
//! ```text
//!  Preset ──► SolveSpec { plan, estimate } ──► solve(scene, accel, spec, progress, cancel)
//!                 │
//!                 ├─ Hierarchical { params, top: Patches }      HSA91 on the input patches
//!                 ├─ Hierarchical { params, top: Mesh(remesh) } the contact or a discontinuity
//!                 │                                             mesh as the top level
//!                 ├─ Uniform / Linear / Progressive            a uniform mesh, p = 0 or 1
//!                 └─ Discontinuity { params, linear }          a discontinuity mesh, p = 0 or 1
//! ```
//!
//! ## The preset ladder
//! The default path is hierarchical radiosity [Hanrahan, Salzman, Aupperle 1991] on the contact
//! mesh (each input patch cut where other patches touch it, `RemeshParams::contacts`), refined
//! by the error oracle: a receiver is split where its gathered radiosity varies across it by more
//! than ε times the scene's mean reflected radiosity (`solver::hierarchical::oracle`). Each step of
//! the ladder halves ε, and the area floor follows it (`discontinuity::contact_area_floor`):
//!
//! ```text
//!   draft 0.2 ─► interactive 0.1 ─► quality 0.05 (default) ─► fine 0.025 ─► reference 0.0125
//! ```
//!
//! The teaching presets keep the lecture's and SPLASH-2's oracles on the quadtree: `bf` (the
//! BF oracle), `lecture` (Refine with Feps alone) and `splash2` (the SPLASH-2 program's settings).

use super::discontinuity::{self, DiscontinuityParams, HierarchicalOnMesh};
use super::hierarchical::HierarchicalSolver;
use super::linear::{self, LinearParams};
use super::params::{AreaEps, HierarchicalParams, Oracle};
use super::progressive::{self, ProgressiveParams};
use super::uniform::{self, UniformParams};
use super::{Progress, Solution};
use crate::geometry::accel::Accel;
use crate::math::Rgb;
use crate::mesh::remesh::{Events, MeshKind, RemeshParams, RemeshStats};
use crate::scene::Scene;
use serde::Serialize;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// A named starting point for a solve.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// The ladder's coarsest step: ε = 0.2.
    Draft,
    /// ε = 0.1: fast enough to drag a slider on the built-in rooms.
    Interactive,
    /// ε = 0.05: the default.
    Quality,
    /// ε = 0.025.
    Fine,
    /// ε = 0.0125: the ladder's finest step.
    Reference,
    /// The BF oracle on the quadtree (HSA91's B·F criterion, with the row check).
    Bf,
    /// The lecture's Refine: the Feps oracle alone, on the quadtree.
    Lecture,
    /// The SPLASH-2 `radiosity` program's settings on the quadtree.
    Splash2,
}

impl Preset {
    /// Every preset: the ladder, coarse to fine, then the teaching presets.
    pub const ALL: [Preset; 8] = [
        Preset::Draft,
        Preset::Interactive,
        Preset::Quality,
        Preset::Fine,
        Preset::Reference,
        Preset::Bf,
        Preset::Lecture,
        Preset::Splash2,
    ];

    /// The ladder, coarse to fine: each step halves the previous one's threshold.
    pub const LADDER: [Preset; 5] =
        [Preset::Draft, Preset::Interactive, Preset::Quality, Preset::Fine, Preset::Reference];

    /// The preset of `radlab solve` and the viewer.
    pub const DEFAULT: Preset = Preset::Quality;

    /// The name the CLI and the viewer use.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Preset::Draft => "draft",
            Preset::Interactive => "interactive",
            Preset::Quality => "quality",
            Preset::Fine => "fine",
            Preset::Reference => "reference",
            Preset::Bf => "bf",
            Preset::Lecture => "lecture",
            Preset::Splash2 => "splash2",
        }
    }

    /// The preset named `name`.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Preset> {
        Preset::ALL.into_iter().find(|p| p.name() == name)
    }

    /// Every name, comma-separated (error messages).
    #[must_use]
    pub fn names() -> String {
        Preset::ALL.map(Preset::name).join(", ")
    }

    /// One line on what the preset does (help texts, tooltips).
    #[must_use]
    pub fn description(self) -> String {
        match self.threshold_rel() {
            Some(eps) => format!(
                "contact mesh, error oracle at {eps} of the mean reflected radiosity{}",
                if self == Preset::DEFAULT { " (default)" } else { "" }
            ),
            None => match self {
                Preset::Bf => "quadtree, BF oracle (B·F against 2e-3 of the brightest emission)".into(),
                Preset::Lecture => "quadtree, the lecture's Refine (Feps 0.02 alone)".into(),
                _ => "quadtree, the SPLASH-2 radiosity program's settings (BFeps 0.015, Aeps 2000)".into(),
            },
        }
    }

    /// The error oracle's relative threshold ε of a ladder step; `None` for the teaching presets.
    #[must_use]
    pub const fn threshold_rel(self) -> Option<f64> {
        match self {
            Preset::Draft => Some(0.2),
            Preset::Interactive => Some(0.1),
            Preset::Quality => Some(0.05),
            Preset::Fine => Some(0.025),
            Preset::Reference => Some(0.0125),
            Preset::Bf | Preset::Lecture | Preset::Splash2 => None,
        }
    }

    /// The hierarchical solver's settings of this preset.
    #[must_use]
    pub const fn hierarchical(self) -> HierarchicalParams {
        match self.threshold_rel() {
            Some(eps) => ladder_params(eps),
            None => match self {
                Preset::Bf => HierarchicalParams::interactive(),
                Preset::Lecture => HierarchicalParams::lecture(),
                _ => HierarchicalParams::splash2(),
            },
        }
    }

    /// The top level the preset refines: the contact mesh on the ladder (below
    /// [`CONTACT_AUTO_PATCHES`] input patches, [`TopLevel::Auto`]), the input patches (the
    /// quadtree) for the teaching presets.
    #[must_use]
    pub fn top(self) -> TopLevel {
        if self.threshold_rel().is_some() { TopLevel::Auto } else { TopLevel::Patches }
    }

    /// The whole solve of this preset.
    #[must_use]
    pub fn spec(self) -> SolveSpec {
        SolveSpec {
            plan: Plan::Hierarchical { params: self.hierarchical(), top: self.top() },
            estimate: false,
        }
    }
}

/// The hierarchical settings of a ladder step at relative threshold `eps`: the error oracle, its
/// area floor following the threshold (`discontinuity::contact_area_floor`), clustered where it
/// pays (`Clustering::Auto`), the row check at [`ladder_row_tol`], a link budget that grows
/// as the threshold shrinks ([`ladder_max_links`]) and the rays per link of [`ladder_rays`].
#[must_use]
pub const fn ladder_params(eps: f64) -> HierarchicalParams {
    discontinuity::contact_area_floor(HierarchicalParams {
        oracle: Oracle::Error,
        bf_eps: eps,
        bf_relative: true,
        row_tol: ladder_row_tol(eps),
        max_links: ladder_max_links(eps),
        rays: ladder_rays(eps),
        ..HierarchicalParams::quality()
    })
}

/// The row check's tolerance on the ladder (`HierarchicalParams::row_tol`): a leaf whose row of
/// F·V exceeds 1 has its ancestors' largest links pushed down where the excess adds more than
/// this fraction of the mean reflected radiosity to its answer. The excess of a leaf creates
/// light in proportion to its area, so the coarse steps, whose leaves are large, check tighter:
/// 0.05 from ε = 0.2 up (at 0.1, table-room's draft created 2e-3 of the emitted power), 0.1
/// below, where it creates none on the contact mesh of the built-in scenes. On the quadtree
/// (`--mesh quadtree`) table-room's floor is not enclosed under the table's legs, so its rows
/// are not closed, and at 0.1 `interactive` creates 7e-4 of the emitted power there; 0.05 at
/// every step would stop that, and costs the contact mesh up to 80 % more time for a little
/// less error (table-room `quality` 0.73 s against 0.40 s for 1.23 % against 1.49 %,
/// splash_room `interactive` 5.4 s against 4.4 s for 3.69 % against 3.78 %; measured with
/// `--vis-slopes false`, whose refinement is nearly the same).
#[must_use]
pub const fn ladder_row_tol(eps: f64) -> f64 {
    if eps >= 0.2 { 0.05 } else { 0.1 }
}

/// The ladder's link budget: 4 M at ε = 0.05 and above, growing as ε^−1.5 below (11.3 M at
/// 0.025, 32 M at 0.0125; at most 64 M). A finer step refines further, and a budget that stopped
/// it half-way would leave it less accurate than it should be: with the budget growing as 1/ε
/// (8 and 16 M), splash_room's `fine` and `reference` read 2.29 and 2.07 %, with these budgets
/// 2.18 and 1.70 % (docs/solver.md, "Presets").
#[must_use]
pub const fn ladder_max_links(eps: f64) -> usize {
    let r = 0.05 / eps.max(1e-6);
    // r^1.5 = r √r, √r by Newton's iteration (a const fn has no `sqrt`).
    let mut s = if r > 1.0 { r } else { 1.0 };
    let mut k = 0;
    while k < 64 {
        s = 0.5 * (s + r / s);
        k += 1;
    }
    (4.0e6 * r * s).clamp(4.0e6, 64.0e6) as usize
}

/// Shadow rays per link on the ladder: 16, and 64 at the finest step (ε < 0.025). A link's
/// visible fraction is an estimate whose noise does not shrink with ε, so at the finest step it,
/// not the threshold, bounds the pointwise error: the edge of a shadow whose links all drew 16
/// rays can read a band of its receiver far too dark however fine ε is. The coarser steps keep
/// 16, where the threshold bounds the error, and the default's time stays as it is
/// (docs/solver.md, "How the tolerances were chosen").
#[must_use]
pub const fn ladder_rays(eps: f64) -> u32 {
    if eps >= 0.025 { 16 } else { 64 }
}

/// The one threshold of an oracle, resolved in one place: Feps for the form-factor oracle, BFeps
/// for the BF oracle, ε (an error of B, relative to the mean reflected radiosity) for the error
/// oracle. Relative thresholds are read as the oracle reads them (`HierarchicalParams::bf_relative`).
#[must_use]
pub fn threshold(p: &HierarchicalParams) -> f64 {
    match p.oracle {
        Oracle::Feps => p.feps,
        Oracle::Bf | Oracle::Error => p.bf_eps,
    }
}

/// `p` with its oracle's threshold set to `value` (relative where the oracle reads it so: BF to the
/// brightest emission, the error oracle to the mean reflected radiosity). With the error oracle
/// and `floor_follows`, the area floor follows the threshold as on the ladder, and so does the
/// link budget where it is the ladder's for the old threshold ([`follow_ladder_budget`]).
#[must_use]
pub fn with_threshold(p: HierarchicalParams, value: f64, floor_follows: bool) -> HierarchicalParams {
    match p.oracle {
        Oracle::Feps => HierarchicalParams { feps: value, ..p },
        Oracle::Bf => HierarchicalParams { bf_eps: value, bf_relative: true, ..p },
        Oracle::Error => {
            let q = HierarchicalParams { bf_eps: value, bf_relative: true, ..p };
            if floor_follows {
                follow_ladder_budget(discontinuity::contact_area_floor(q), p.bf_eps)
            } else {
                q
            }
        }
    }
}

/// `p`, whose error threshold was `old_eps`, with the ladder's link budget for its threshold
/// ([`ladder_max_links`]) if its budget was the ladder's for `old_eps`; a budget set by hand
/// stays. A finer threshold then refines further, as the ladder's finer step does, instead of
/// stopping at the coarser threshold's budget.
#[must_use]
pub fn follow_ladder_budget(p: HierarchicalParams, old_eps: f64) -> HierarchicalParams {
    if p.oracle == Oracle::Error && p.max_links == ladder_max_links(old_eps) {
        HierarchicalParams { max_links: ladder_max_links(p.bf_eps), ..p }
    } else {
        p
    }
}

/// What the hierarchical solver refines.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub enum TopLevel {
    /// The input patches, each the root of a quadtree (HSA91).
    Patches,
    /// A mesh of the input patches (the contact mesh, or a discontinuity mesh) as the top level.
    Mesh(RemeshParams),
    /// The contact mesh on a scene of fewer than [`CONTACT_AUTO_PATCHES`] input patches, the
    /// input patches above ([`SolveSpec::resolved`]).
    Auto,
}

/// [`TopLevel::Auto`] meshes contacts below this many input patches. Above it the scene is
/// clustered, and the contact mesh's pieces (about three per patch on a furnished room) cost
/// more time than they return: there the clustered links, not the mesh, bound the error
/// (docs/scale.md).
pub const CONTACT_AUTO_PATCHES: usize = super::params::Clustering::AUTO_PATCHES;

/// The solver and its settings.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub enum Plan {
    /// Hierarchical radiosity on `top`.
    Hierarchical { params: HierarchicalParams, top: TopLevel },
    /// A uniform mesh with constant elements, the full matrix, Gauss–Seidel.
    Uniform(UniformParams),
    /// A uniform mesh with linear / bilinear elements, Galerkin (`LinearParams::order`).
    Linear(LinearParams),
    /// Southwell shooting on a uniform mesh (progressive refinement).
    Progressive(ProgressiveParams),
    /// The uniform solver on a discontinuity mesh, one element per piece; with `linear`, the
    /// Galerkin solve at p = 1 on its pieces.
    Discontinuity { params: DiscontinuityParams, linear: Option<LinearParams> },
}

/// A whole solve: the plan, and whether the hierarchical solver adds its per-element error
/// estimates to the solution (about as costly again as the solve).
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct SolveSpec {
    pub plan: Plan,
    pub estimate: bool,
}

impl Default for SolveSpec {
    fn default() -> Self {
        Preset::DEFAULT.spec()
    }
}

impl SolveSpec {
    /// The preset named `name` ([`Preset::from_name`]).
    #[must_use]
    pub fn preset(name: &str) -> Option<SolveSpec> {
        Preset::from_name(name).map(Preset::spec)
    }

    /// The hierarchical settings, if the plan is hierarchical.
    #[must_use]
    pub fn hierarchical(&self) -> Option<&HierarchicalParams> {
        match &self.plan {
            Plan::Hierarchical { params, .. } => Some(params),
            _ => None,
        }
    }

    /// The name of the mesh the solve runs on: quadtree, contact, uniform, discontinuity-cdt,
    /// discontinuity-bsp.
    #[must_use]
    pub fn mesh_name(&self) -> &'static str {
        let dmesh = |m: &RemeshParams| match (m.events, m.kind) {
            (Events::Contacts, _) => "contact",
            (Events::All, MeshKind::Cdt) => "discontinuity-cdt",
            (Events::All, MeshKind::Bsp) => "discontinuity-bsp",
        };
        match &self.plan {
            Plan::Hierarchical { top: TopLevel::Patches, .. } => "quadtree",
            Plan::Hierarchical { top: TopLevel::Mesh(m), .. } => dmesh(m),
            Plan::Hierarchical { top: TopLevel::Auto, .. } => "contact",
            Plan::Uniform(_) | Plan::Linear(_) | Plan::Progressive(_) => "uniform",
            Plan::Discontinuity { params, .. } => dmesh(&params.mesh),
        }
    }

    /// The element order (0 or 1) and whether a p = 1 basis is continuous.
    #[must_use]
    pub fn order(&self) -> (u32, bool) {
        match &self.plan {
            Plan::Linear(l) | Plan::Discontinuity { linear: Some(l), .. } => {
                (u32::from(l.order == crate::geometry::basis::Order::Linear), l.continuous)
            }
            _ => (0, false),
        }
    }

    /// The settings as JSON (`radlab solve --json`'s `params`).
    #[must_use]
    pub fn params_json(&self) -> serde_json::Value {
        use serde_json::json;
        match &self.plan {
            Plan::Hierarchical { params, top: TopLevel::Patches | TopLevel::Auto } => json!(params),
            Plan::Hierarchical { params, top: TopLevel::Mesh(m) } => json!({ "mesh": m, "solve": params }),
            Plan::Uniform(p) => json!(p),
            Plan::Linear(p) => json!(p),
            Plan::Progressive(p) => json!(p),
            Plan::Discontinuity { params, linear: None } => json!(params),
            Plan::Discontinuity { params, linear: Some(l) } => json!({ "mesh": params.mesh, "solve": l }),
        }
    }

    /// The spec as it runs on `scene`: [`TopLevel::Auto`] made the contact mesh or the patches.
    #[must_use]
    pub fn resolved(&self, scene: &Scene) -> SolveSpec {
        match self.plan {
            Plan::Hierarchical { params, top: TopLevel::Auto } => {
                let top = if scene.patches.len() < CONTACT_AUTO_PATCHES {
                    TopLevel::Mesh(RemeshParams::contacts())
                } else {
                    TopLevel::Patches
                };
                SolveSpec { plan: Plan::Hierarchical { params, top }, ..*self }
            }
            _ => *self,
        }
    }

    /// Reject what cannot be solved, with one line naming the setting.
    pub fn validate(&self) -> Result<(), SolveError> {
        let invalid = |e: String| SolveError::Invalid(e);
        match &self.plan {
            Plan::Hierarchical { params, .. } => params.validate().map_err(invalid),
            Plan::Uniform(p) => p.validate().map_err(invalid),
            Plan::Linear(p) => p.validate().map_err(invalid),
            Plan::Progressive(p) => p.validate().map_err(invalid),
            Plan::Discontinuity { params, linear } => {
                params.solve.validate().map_err(invalid)?;
                linear.as_ref().map_or(Ok(()), |l| l.validate().map_err(invalid))
            }
        }
    }
}

/// Why a solve did not run.
#[derive(Debug, thiserror::Error)]
pub enum SolveError {
    #[error("invalid parameters: {0}")]
    Invalid(String),
    #[error("{0}")]
    Failed(String),
}

/// A solved scene and what made it.
pub struct Solved {
    pub solution: Solution,
    pub spec: SolveSpec,
    /// The hierarchical solver on the input patches, for its hierarchy and links (`None` on a
    /// mesh top level, whose elements lie on the mesh's pieces).
    pub hierarchical: Option<HierarchicalSolver>,
    /// Each element's basis coefficients at order 1 (vertex values, in vertex order); `None` at
    /// order 0 (one coefficient per element: its radiosity).
    pub coefficients: Option<Vec<Vec<Rgb>>>,
    /// On a contact or discontinuity mesh: what meshing did (its times) and the solve's wall
    /// time (s).
    pub remesh: Option<(RemeshStats, f64)>,
    /// What the solve changed in the spec to run, one line each (a discontinuity mesh graded to
    /// fit the p = 1 solver's cap): the CLI prints them on stderr.
    pub notes: Vec<String>,
    /// Whether `cancel` or a deadline stopped a hierarchical solve before it converged (the
    /// solution is then the state reached, or with [`Stopped`]'s `Converged` its mesh gathered to
    /// convergence).
    pub cancelled: bool,
    /// Where the deadline ([`Stopped::ConvergedBy`]) stopped the converging gathers before they
    /// converged: the residual of the last gather.
    pub gathers_cut: Option<f64>,
}

impl Solved {
    /// Every element's basis coefficients: its order-1 vertex values; at order 0 its values at
    /// its vertices where it has a slope ([`crate::solver::SolvedElement::corner_values`]), else
    /// its one constant.
    #[must_use]
    pub fn element_coefficients(&self) -> Vec<Vec<Rgb>> {
        self.coefficients.clone().unwrap_or_else(|| {
            self.solution
                .elements
                .iter()
                .map(|e| if e.slope.is_some() { e.corner_values() } else { vec![e.radiosity] })
                .collect()
        })
    }

    /// Whether some element varies linearly through a slope at order 0 (the dump's `p0-slope`
    /// basis).
    #[must_use]
    pub fn has_slopes(&self) -> bool {
        self.coefficients.is_none() && self.solution.elements.iter().any(|e| e.slope.is_some())
    }
}

/// A hierarchical solve set up as its spec says, before it runs: on the input patches, or on
/// the pieces of a mesh (the contact mesh of the ladder) with each piece's input patch. What
/// [`solve`] runs to the end, and what the viewer steps.
pub enum Setup {
    Patches(Box<HierarchicalSolver>),
    Mesh(Box<HierarchicalOnMesh>),
}

impl Setup {
    #[must_use]
    pub fn solver(&self) -> &HierarchicalSolver {
        match self {
            Setup::Patches(s) => s,
            Setup::Mesh(m) => &m.solver,
        }
    }

    pub fn solver_mut(&mut self) -> &mut HierarchicalSolver {
        match self {
            Setup::Patches(s) => s,
            Setup::Mesh(m) => &mut m.solver,
        }
    }

    /// The solver, and on a mesh each of its patches' input patch.
    #[must_use]
    pub fn into_parts(self) -> (HierarchicalSolver, Option<Vec<usize>>) {
        match self {
            Setup::Patches(s) => (*s, None),
            Setup::Mesh(m) => {
                let (s, origin) = m.into_parts();
                (s, Some(origin))
            }
        }
    }
}

/// Set up the hierarchical solve of `spec` on `scene` ([`TopLevel::Auto`] resolved by the
/// scene's size): `accel`, the scene's BVH and the seconds it took, if built (a mesh builds its
/// own). An error if the spec is invalid or not hierarchical, or the mesh fails.
pub fn setup(
    scene: &Arc<Scene>,
    accel: Option<(&Arc<Accel>, f64)>,
    spec: &SolveSpec,
) -> Result<Setup, SolveError> {
    spec.validate()?;
    let failed = SolveError::Failed;
    match &spec.resolved(scene).plan {
        Plan::Hierarchical { params, top: TopLevel::Patches | TopLevel::Auto } => {
            Ok(Setup::Patches(Box::new(match accel {
                Some((accel, bvh_s)) => {
                    HierarchicalSolver::with_accel(Arc::clone(scene), Arc::clone(accel), *params, bvh_s)
                }
                None => HierarchicalSolver::new(Arc::clone(scene), *params).map_err(failed)?,
            })))
        }
        Plan::Hierarchical { params, top: TopLevel::Mesh(mesh) } => Ok(Setup::Mesh(Box::new(
            HierarchicalOnMesh::new(scene, mesh, *params)
                .map_err(|e| failed(format!("{}: {e}", scene.name)))?,
        ))),
        _ => Err(failed(format!("{}: the {} solver has no hierarchy to step", scene.name, spec.mesh_name()))),
    }
}

/// Solve `scene` (with its BVH `accel`, built in `bvh_s` seconds) as `spec` says. Setting
/// `cancel` makes a hierarchical solve stop at its next sub-step (the mesh solvers run to the
/// end); the solution is then the state reached.
pub fn solve(
    scene: &Arc<Scene>,
    accel: &Arc<Accel>,
    bvh_s: f64,
    spec: &SolveSpec,
    progress: Progress,
    cancel: Option<&Arc<AtomicBool>>,
) -> Result<Solved, SolveError> {
    solve_stopping(scene, accel, bvh_s, spec, progress, cancel, Stopped::AsReached)
}

/// What a hierarchical solve stopped by its flag gives: the state reached, or that state's mesh
/// gathered, without refining, to convergence ([`HierarchicalSolver::converge`]: a time budget's
/// answer, converged if coarser than asked); `ConvergedBy` also ends the solve, refinement and
/// converging gathers, by a deadline (a time budget's end: [`HierarchicalSolver::set_deadline`];
/// `Solved::gathers_cut` says whether the gathers stopped before converging).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stopped {
    AsReached,
    Converged,
    ConvergedBy(Instant),
}

/// [`solve`], with `stopped` saying what a hierarchical solve stopped by `cancel` gives
/// (`Solved::cancelled` says whether it was stopped).
pub fn solve_stopping(
    scene: &Arc<Scene>,
    accel: &Arc<Accel>,
    bvh_s: f64,
    spec: &SolveSpec,
    progress: Progress,
    cancel: Option<&Arc<AtomicBool>>,
    stopped: Stopped,
) -> Result<Solved, SolveError> {
    spec.validate()?;
    let spec = &spec.resolved(scene);
    let failed = SolveError::Failed;
    let (mut hierarchical, mut coefficients, mut remesh) = (None, None, None);
    let mut notes = Vec::new();
    let (mut cancelled, mut gathers_cut) = (false, None);
    let solution = match &spec.plan {
        Plan::Hierarchical { .. } => match setup(scene, Some((accel, bvh_s)), spec)? {
            Setup::Patches(mut s) => {
                (cancelled, gathers_cut) = forward_solve(&mut s, cancel, progress, stopped);
                let sol = s.solution_with(spec.estimate);
                hierarchical = Some(*s);
                sol
            }
            Setup::Mesh(mut on_mesh) => {
                (cancelled, gathers_cut) = forward_solve(&mut on_mesh.solver, cancel, progress, stopped);
                let d = on_mesh.finish(spec.estimate);
                remesh = Some((d.mesh, d.solve_s));
                d.solution
            }
        },
        Plan::Uniform(p) => uniform::solve(scene, accel, p, progress).map_err(failed)?,
        Plan::Linear(p) => {
            let s = linear::solve(scene, accel, p, progress).map_err(failed)?;
            coefficients = Some(s.coefficients);
            s.solution
        }
        Plan::Progressive(p) => progressive::solve(scene, accel, p, progress).map_err(failed)?,
        Plan::Discontinuity { params, linear: None } => {
            let d = discontinuity::solve(scene, params, progress).map_err(|e| failed(e.to_string()))?;
            remesh = Some((d.mesh, d.solve_s));
            d.solution
        }
        Plan::Discontinuity { params, linear: Some(l) } => {
            let (d, c) = discontinuity::solve_galerkin(scene, params, l, progress)
                .map_err(|e| failed(e.to_string()))?;
            if let (None, Some(g)) = (params.mesh.grade, &d.mesh.graded) {
                notes.push(format!(
                    "the {} mesh has more pieces than p = 1's cap of {} unknowns holds: graded to {}",
                    spec.mesh_name(),
                    l.max_unknowns,
                    g.budget
                ));
            }
            coefficients = Some(c);
            remesh = Some((d.mesh, d.solve_s));
            d.solution
        }
    };
    notes.extend(budget_note(&solution, &spec.plan));
    Ok(Solved { solution, spec: *spec, hierarchical, coefficients, remesh, notes, cancelled, gathers_cut })
}

/// A line for the user when the link budget stopped a hierarchical refinement before its oracle
/// was satisfied: the solution is coarser than the threshold asks, and its error estimate reads
/// low (the unrefined links' error is not in it).
fn budget_note(solution: &Solution, plan: &Plan) -> Option<String> {
    let Plan::Hierarchical { params, .. } = plan else { return None };
    let hit = solution.stats.extra.as_ref()?.get("budget_hit")?.as_bool()?;
    hit.then(|| {
        format!(
            "refinement stopped at the link budget ({} links) before the threshold was met: the \
             answer is coarser than asked; raise --max-links or coarsen the threshold",
            params.max_links
        )
    })
}

/// One step of a walk down thresholds ([`solve_walk`]).
#[derive(Copy, Clone, Debug, Serialize)]
pub struct WalkStep {
    /// The oracle's threshold of this step ([`with_threshold`]).
    pub threshold: f64,
    /// Whether the step started from a solved state ([`HierarchicalSolver::retarget`]): the last
    /// step's, for a finer threshold, or an earlier step's no finer than it, for a coarser one.
    /// The first step, and a coarser threshold than every step before, start cold.
    pub warm: bool,
    /// Wall time of the step's solve (s).
    pub solve_s: f64,
    pub elements: usize,
    pub leaves: usize,
    pub links: usize,
    /// Shadow rays cast in this step alone.
    pub rays: u64,
}

/// Solve a hierarchical `spec` at each of `thresholds` in turn ([`with_threshold`]; the area floor
/// follows the threshold when `floor_follows`), each step refining from where the last stopped
/// and gathering from its radiosity when its threshold is finer ([`HierarchicalSolver::retarget`]):
/// a warm re-solve, as a threshold slider moves. A coarser threshold goes back to the finest
/// earlier step no finer than it and refines on from there. Returns the last step's solve and
/// every step's figures. Refinement at a finer threshold only adds to what a coarser one built,
/// so the result is a solve at the last threshold that started from the earlier ones' mesh. `stopped` says
/// what a step stopped by `cancel` gives (and the walk ends there).
pub fn solve_walk(
    scene: &Arc<Scene>,
    accel: &Arc<Accel>,
    bvh_s: f64,
    spec: &SolveSpec,
    thresholds: &[f64],
    floor_follows: bool,
    progress: Progress,
    cancel: Option<&Arc<AtomicBool>>,
    stopped: Stopped,
) -> Result<(Solved, Vec<WalkStep>), SolveError> {
    let failed = SolveError::Failed;
    spec.validate()?;
    let spec = spec.resolved(scene);
    let (Plan::Hierarchical { params, top }, Some(&first)) = (spec.plan, thresholds.first()) else {
        return Err(failed("a walk down thresholds needs the hierarchical solver and a threshold".into()));
    };
    let at = |t: f64| with_threshold(params, t, floor_follows);
    let mut steps = Vec::with_capacity(thresholds.len());
    let (mut cancelled, mut gathers_cut) = (false, None);
    // A walk that never turns coarser has no state to go back to: keep none (no copies).
    let turns_coarser = thresholds.windows(2).any(|w| w[1] > w[0]);
    let mut walk = |s: &mut HierarchicalSolver| -> Result<(), SolveError> {
        s.keep_solved_states(turns_coarser);
        for (k, &t) in thresholds.iter().enumerate() {
            let warm = if k == 0 { false } else { s.retarget(at(t)).map_err(failed)? };
            let rays_before = if warm { s.stats().rays } else { 0 };
            let started = std::time::Instant::now();
            (cancelled, gathers_cut) = forward_solve(s, cancel, &mut *progress, stopped);
            let st = s.stats();
            steps.push(WalkStep {
                threshold: t,
                warm,
                solve_s: started.elapsed().as_secs_f64(),
                elements: st.elements,
                leaves: st.leaves,
                links: st.links,
                rays: st.rays.saturating_sub(rays_before),
            });
            if cancelled {
                break;
            }
        }
        Ok(())
    };
    let (solution, hierarchical, remesh) = match &top {
        TopLevel::Patches | TopLevel::Auto => {
            let mut s =
                HierarchicalSolver::with_accel(Arc::clone(scene), Arc::clone(accel), at(first), bvh_s);
            walk(&mut s)?;
            (s.solution_with(spec.estimate), Some(s), None)
        }
        TopLevel::Mesh(mesh) => {
            let mut on_mesh =
                HierarchicalOnMesh::new(scene, mesh, at(first)).map_err(|e| failed(e.to_string()))?;
            walk(&mut on_mesh.solver)?;
            let d = on_mesh.finish(spec.estimate);
            (d.solution, None, Some((d.mesh, d.solve_s)))
        }
    };
    let last = thresholds.get(steps.len().saturating_sub(1)).copied().unwrap_or(first);
    let spec = SolveSpec { plan: Plan::Hierarchical { params: at(last), top }, ..spec };
    let notes = budget_note(&solution, &spec.plan).into_iter().collect();
    let solved =
        Solved { solution, spec, hierarchical, coefficients: None, remesh, notes, cancelled, gathers_cut };
    Ok((solved, steps))
}

/// Run `s.solve`, stopping it when `cancel` is set (the solver looks at its flag between
/// refinement passes and between gathers) or by [`Stopped::ConvergedBy`]'s deadline; with
/// [`Stopped::Converged`] or `ConvergedBy` a stopped solve then gathers to convergence on the
/// mesh it reached (by the deadline). Returns whether the solve was stopped, and where the
/// deadline stopped the gathers before they converged, their residual.
fn forward_solve(
    s: &mut HierarchicalSolver,
    cancel: Option<&Arc<AtomicBool>>,
    progress: Progress,
    stopped: Stopped,
) -> (bool, Option<f64>) {
    let deadline = match stopped {
        Stopped::ConvergedBy(deadline) => Some(deadline),
        Stopped::AsReached | Stopped::Converged => None,
    };
    s.set_deadline(deadline);
    let cancelled = match cancel {
        None => s.solve(progress).cancelled,
        // Set before the solve starts: nothing to run.
        Some(outer) if outer.load(Ordering::Relaxed) => true,
        Some(outer) => {
            // A relay thread hands the caller's flag to the solver's own within milliseconds,
            // whether or not the solver reports progress meanwhile (a refinement pass may not).
            // It keeps handing it on until the solve ends: the solve clears its own flag as it
            // starts, which would drop a cancel relayed before that.
            let inner = s.cancel_handle();
            let done = Arc::new(AtomicBool::new(false));
            let relay = {
                let (outer, done) = (Arc::clone(outer), Arc::clone(&done));
                std::thread::spawn(move || {
                    while !done.load(Ordering::Relaxed) {
                        if outer.load(Ordering::Relaxed) {
                            inner.store(true, Ordering::Relaxed);
                        }
                        std::thread::sleep(std::time::Duration::from_millis(2));
                    }
                })
            };
            let cancelled = s.solve(progress).cancelled;
            done.store(true, Ordering::Relaxed);
            let _ = relay.join();
            cancelled
        }
    };
    if cancelled && stopped != Stopped::AsReached {
        s.converge();
    }
    let gathers_cut = s.gathers_cut();
    s.set_deadline(None);
    (cancelled, gathers_cut)
}

/// The relative area floor of `p`, if it is relative.
#[must_use]
pub fn area_floor_rel(p: &HierarchicalParams) -> Option<f64> {
    match p.aeps {
        AreaEps::Relative(a) => Some(a),
        AreaEps::Absolute(_) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::remesh::RemeshParams;

    fn load(name: &str) -> (Arc<Scene>, Arc<Accel>) {
        let scene = Arc::new(Scene::load(&format!("builtin:{name}")).unwrap());
        let accel = Arc::new(Accel::build(&scene));
        (scene, accel)
    }

    #[test]
    fn the_ladder_halves_its_threshold_on_the_contact_mesh() {
        let eps: Vec<f64> = Preset::LADDER.iter().map(|p| p.threshold_rel().unwrap()).collect();
        for w in eps.windows(2) {
            assert!((w[1] - w[0] / 2.0).abs() < 1e-15, "{eps:?}");
        }
        for p in Preset::LADDER {
            let spec = p.spec();
            let h = spec.hierarchical().unwrap();
            assert_eq!(h.oracle, Oracle::Error, "{}", p.name());
            assert_eq!(threshold(h), p.threshold_rel().unwrap());
            assert_eq!(spec.mesh_name(), "contact", "{}", p.name());
            assert_eq!(spec.hierarchical().map(|_| ()), Some(()));
            // The area floor follows the threshold.
            let floor = area_floor_rel(h).unwrap();
            assert!((floor - discontinuity::CONTACT_AEPS_PER_EPS * threshold(h)).abs() < 1e-18);
            assert!(h.validate().is_ok());
        }
        // The finest step draws more rays per link; the default keeps the quality preset's.
        assert_eq!(Preset::DEFAULT.hierarchical().rays, HierarchicalParams::quality().rays);
        assert!(Preset::Reference.hierarchical().rays > Preset::Fine.hierarchical().rays);
        for p in [Preset::Bf, Preset::Lecture, Preset::Splash2] {
            assert_eq!(p.spec().mesh_name(), "quadtree", "{}", p.name());
            assert_eq!(p.threshold_rel(), None);
        }
        assert_eq!(SolveSpec::default(), SolveSpec::preset("quality").unwrap());
        for p in Preset::ALL {
            assert_eq!(Preset::from_name(p.name()), Some(p));
        }
        assert_eq!(Preset::from_name("ultra"), None);
    }

    /// The ladder meshes contacts on a scene below the clustering size, and refines the patches
    /// of a larger one.
    #[test]
    fn the_ladder_meshes_contacts_below_the_clustering_size() {
        let small = Scene::load("builtin:cornell").unwrap();
        let large = Scene::load("builtin:furnished-4k").unwrap();
        assert!(large.patches.len() >= CONTACT_AUTO_PATCHES, "{}", large.patches.len());
        let spec = Preset::Quality.spec();
        assert_eq!(spec.resolved(&small).mesh_name(), "contact");
        assert!(matches!(
            spec.resolved(&small).plan,
            Plan::Hierarchical { top: TopLevel::Mesh(m), .. } if m == RemeshParams::contacts()
        ));
        assert_eq!(spec.resolved(&large).mesh_name(), "quadtree");
        assert_eq!(Preset::Bf.spec().resolved(&small).mesh_name(), "quadtree");
    }

    #[test]
    fn one_threshold_whatever_the_oracle() {
        let e = with_threshold(Preset::Quality.hierarchical(), 0.2, true);
        assert_eq!(threshold(&e), 0.2);
        assert_eq!(area_floor_rel(&e), Some(discontinuity::CONTACT_AEPS_PER_EPS * 0.2));
        let kept = with_threshold(Preset::Quality.hierarchical(), 0.2, false);
        assert_eq!(area_floor_rel(&kept), area_floor_rel(&Preset::Quality.hierarchical()));
        // The ladder's budget follows the threshold; one set by hand stays.
        let finer = with_threshold(Preset::Quality.hierarchical(), 0.0125, true);
        assert_eq!(finer.max_links, Preset::Reference.hierarchical().max_links);
        let own = HierarchicalParams { max_links: 123_456, ..Preset::Quality.hierarchical() };
        assert_eq!(with_threshold(own, 0.0125, true).max_links, 123_456);
        assert_eq!(with_threshold(Preset::Quality.hierarchical(), 0.0125, false).max_links, 4_000_000);
        let f = with_threshold(Preset::Lecture.hierarchical(), 0.05, true);
        assert_eq!((f.feps, threshold(&f)), (0.05, 0.05));
        let b = with_threshold(Preset::Splash2.hierarchical(), 1e-3, true);
        assert!(b.bf_relative && threshold(&b) == 1e-3);
    }

    /// Every plan runs through the one entry, and each reports the mesh it ran on.
    #[test]
    fn every_plan_solves_through_one_entry() {
        let (scene, accel) = load("shadow-narrow");
        let coarse = |eps| SolveSpec {
            plan: Plan::Hierarchical { params: ladder_params(eps), top: Preset::Draft.top() },
            estimate: false,
        };
        let size = scene.bounds().diagonal() / 4.0;
        let plans = [
            (coarse(0.4), "contact"),
            (Preset::Draft.spec(), "contact"),
            (Preset::Bf.spec(), "quadtree"),
            (
                SolveSpec {
                    plan: Plan::Uniform(UniformParams { element_size: size, ..UniformParams::default() }),
                    estimate: false,
                },
                "uniform",
            ),
            (
                SolveSpec {
                    plan: Plan::Linear(LinearParams {
                        element_size: size,
                        order: crate::geometry::basis::Order::Linear,
                        ..LinearParams::default()
                    }),
                    estimate: false,
                },
                "uniform",
            ),
            (
                SolveSpec {
                    plan: Plan::Discontinuity { params: DiscontinuityParams::bsp(), linear: None },
                    estimate: false,
                },
                "discontinuity-bsp",
            ),
        ];
        for (spec, mesh) in plans {
            assert_eq!(spec.mesh_name(), mesh);
            let s = solve(&scene, &accel, 0.0, &spec, &mut |_, _| {}, None).unwrap();
            assert!(s.solution.is_physical(), "{mesh}");
            assert_eq!(s.solution.patch_radiosity.len(), scene.patches.len(), "{mesh}");
            assert_eq!(s.coefficients.is_some(), spec.order().0 == 1, "{mesh}");
            assert_eq!(s.remesh.is_some(), mesh.starts_with("discontinuity") || mesh == "contact", "{mesh}");
        }
    }

    /// A refinement the link budget stops says so; one that ends on its own says nothing.
    #[test]
    fn a_solve_stopped_by_the_link_budget_says_so() {
        let (scene, accel) = load("shadow-narrow");
        let run = |max_links| {
            let params = HierarchicalParams { max_links, ..ladder_params(0.1) };
            let spec =
                SolveSpec { plan: Plan::Hierarchical { params, top: TopLevel::Auto }, estimate: false };
            solve(&scene, &accel, 0.0, &spec.resolved(&scene), &mut |_, _| {}, None).unwrap()
        };
        let free = run(HierarchicalParams::quality().max_links);
        assert!(free.notes.is_empty(), "{:?}", free.notes);
        let links = free.solution.stats.links;
        let bound = run(links / 4);
        assert!(
            bound.notes.iter().any(|n| n.contains("link budget") && n.contains(&format!("{}", links / 4))),
            "{:?} ({links} links unbounded)",
            bound.notes
        );
    }

    /// A p = 1 solve on a discontinuity mesh with more pieces than the cap's unknowns is graded
    /// to fit, and says so, instead of refusing.
    #[test]
    fn a_p1_discontinuity_mesh_over_the_cap_is_graded_to_fit() {
        let (scene, accel) = load("shadow-narrow");
        let params = DiscontinuityParams::with_mesh(RemeshParams::cdt());
        let pieces =
            crate::mesh::remesh::discontinuity_scene(&scene, &params.mesh).unwrap().scene.patches.len();
        // A cap that holds a third of the pieces' four unknowns each.
        let fits = pieces / 3;
        let linear = LinearParams {
            order: crate::geometry::basis::Order::Linear,
            max_unknowns: 4 * fits,
            element_size: f64::INFINITY,
            ..LinearParams::default()
        };
        let spec = SolveSpec { plan: Plan::Discontinuity { params, linear: Some(linear) }, estimate: false };
        let s = solve(&scene, &accel, 0.0, &spec, &mut |_, _| {}, None).unwrap();
        assert_eq!(s.notes.len(), 1, "{:?}", s.notes);
        assert!(s.notes[0].contains(&format!("graded to {fits}")), "{}", s.notes[0]);
        assert!(s.solution.elements.len() <= fits, "{} elements, {fits} fit", s.solution.elements.len());
        assert!(s.solution.is_physical());
        // Continuous: grading would leave T-vertices, so the cap's refusal stands.
        let continuous = LinearParams { continuous: true, ..linear };
        let spec =
            SolveSpec { plan: Plan::Discontinuity { params, linear: Some(continuous) }, estimate: false };
        assert!(solve(&scene, &accel, 0.0, &spec, &mut |_, _| {}, None).is_err());
    }

    /// A cancel flag set before the solve stops the hierarchical solve before it refines.
    #[test]
    fn a_set_cancel_flag_stops_the_solve() {
        let (scene, accel) = load("cornell");
        let cancel = Arc::new(AtomicBool::new(true));
        let full = solve(&scene, &accel, 0.0, &Preset::Draft.spec(), &mut |_, _| {}, None).unwrap();
        let stopped =
            solve(&scene, &accel, 0.0, &Preset::Draft.spec(), &mut |_, _| {}, Some(&cancel)).unwrap();
        assert!(
            stopped.solution.stats.elements < full.solution.stats.elements,
            "cancelled {} against {} elements",
            stopped.solution.stats.elements,
            full.solution.stats.elements
        );
    }

    /// A deadline ends the solve: one that has passed before the solve stops the refinement
    /// before its first pass, and the gathers after the one that any answer needs, and the
    /// solve says where they stopped; one far off changes nothing.
    #[test]
    fn a_deadline_bounds_the_refinement_and_the_converging_gathers() {
        let (scene, accel) = load("cornell");
        let spec = Preset::Reference.spec();
        let run =
            |stopped| solve_stopping(&scene, &accel, 0.0, &spec, &mut |_, _| {}, None, stopped).unwrap();
        let passed = run(Stopped::ConvergedBy(Instant::now()));
        assert!(passed.cancelled);
        let st = &passed.solution.stats;
        assert_eq!(st.iterations, 1, "one gather");
        let residual = passed.gathers_cut.expect("the gathers stopped before converging");
        assert!(residual > 1e-3, "one gather is far from converged: {residual}");

        let spec = Preset::Draft.spec();
        let run =
            |stopped| solve_stopping(&scene, &accel, 0.0, &spec, &mut |_, _| {}, None, stopped).unwrap();
        let free = run(Stopped::Converged);
        let far = run(Stopped::ConvergedBy(Instant::now() + std::time::Duration::from_secs(3600)));
        assert!(!far.cancelled && far.gathers_cut.is_none());
        assert_eq!(far.solution.patch_radiosity, free.solution.patch_radiosity);
    }
}
