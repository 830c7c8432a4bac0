//! One entry point for the solves on a mesh that is not the hierarchical quadtree — the uniform
//! mesh and the two discontinuity meshes — at element order p = 0 or p = 1, as the viewer and the
//! lecture figures pick them ([`MeshMethod`], [`MeshSolveParams`]).
//!
//! ```text
//! p = 0   uniform            → uniform::solve (classical, one value per element)
//!         discontinuity-*    → discontinuity::solve (remesh, uniform solve on the pieces; constant
//!                               elements, without `discontinuity::gather`'s slopes)
//! p = 1   uniform            → linear::solve (Galerkin, vertex values)
//!         discontinuity-*    → discontinuity::solve_galerkin (Galerkin on the pieces)
//! ```
//!
//! Each returns a [`Solution`] of the **input** scene (a discontinuity mesh's pieces are pulled
//! back onto the patch they were cut from) and, at p = 1, every element's vertex values, which a
//! display draws as the element's own function ([`DisplayReconstruction::Nodal`]).

use super::discontinuity::{self, DiscontinuityParams};
use super::linear::{self, LinearParams};
use super::uniform::{self, COARSE_FF_TOLERANCE, UniformParams};
use super::{Progress, Solution};
use crate::geometry::accel::Accel;
use crate::geometry::basis::Order;
use crate::math::Rgb;
use crate::mesh::grade::{Budget, GradeParams};
use crate::mesh::remesh::{MeshKind, RemeshParams};
use crate::scene::Scene;
use serde::Serialize;

/// The mesh a solve runs on.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Serialize, clap::ValueEnum)]
pub enum MeshMethod {
    /// The hierarchical solver's adaptive quadtree (HSA91), refined by its oracle.
    #[default]
    Quadtree,
    /// Every patch cut into a grid of elements of one size.
    Uniform,
    /// Receivers replaced by Heckbert's constrained Delaunay mesh of their critical segments.
    DiscontinuityCdt,
    /// Receivers split by Campbell & Fussell's BSP of their critical segments.
    DiscontinuityBsp,
}

impl MeshMethod {
    /// Every method, in menu order.
    pub const ALL: [MeshMethod; 4] = [
        MeshMethod::Quadtree,
        MeshMethod::Uniform,
        MeshMethod::DiscontinuityCdt,
        MeshMethod::DiscontinuityBsp,
    ];

    /// The CLI's spelling.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            MeshMethod::Quadtree => "quadtree",
            MeshMethod::Uniform => "uniform",
            MeshMethod::DiscontinuityCdt => "discontinuity-cdt",
            MeshMethod::DiscontinuityBsp => "discontinuity-bsp",
        }
    }

    /// One line on what the mesh is (tooltips).
    #[must_use]
    pub fn description(self) -> &'static str {
        match self {
            MeshMethod::Quadtree => {
                "Hierarchical radiosity: each patch a quadtree refined where the oracle asks, links at many levels"
            }
            MeshMethod::Uniform => {
                "Every patch cut into equal elements (element size below), every pair of elements coupled: n² interactions"
            }
            MeshMethod::DiscontinuityCdt => {
                "Receivers meshed by Heckbert's constrained Delaunay triangulation with the critical \
                 segments (D0/D1/D2) as constraints, so shadow boundaries fall on element edges"
            }
            MeshMethod::DiscontinuityBsp => {
                "Receivers split into convex pieces by the critical segments' lines (Campbell & Fussell's BSP)"
            }
        }
    }
}

/// How a solution is drawn (and read) between its element values.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Serialize, clap::ValueEnum)]
pub enum DisplayReconstruction {
    /// Each element one colour: its average.
    Flat,
    /// Vertex values averaged from the elements around each vertex, interpolated (what most
    /// systems show).
    Gouraud,
    /// The element's own function, what the solver computed and every ruler scores: a p = 1
    /// solve's vertex values, or its average with its slope (the hierarchical solver's leaves,
    /// a discontinuity mesh's gathered pieces), else its constant; discontinuous across element
    /// edges where the basis is. Spelled `solved` (`nodal` is accepted).
    #[default]
    #[value(name = "solved", alias = "nodal")]
    Nodal,
}

impl DisplayReconstruction {
    /// The CLI's spelling.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            DisplayReconstruction::Flat => "flat",
            DisplayReconstruction::Gouraud => "gouraud",
            DisplayReconstruction::Nodal => "solved",
        }
    }
}

/// Settings of a solve on a uniform or discontinuity mesh.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct MeshSolveParams {
    pub method: MeshMethod,
    pub order: Order,
    /// p = 1: one value per mesh vertex of a patch, shared by its elements.
    pub continuous: bool,
    /// Uniform mesh: longest element side as a fraction of the scene's bounding-box diagonal.
    pub element_size_rel: f64,
    /// Constrained Delaunay refinement: smallest angle, degrees (0: the unrefined CDT).
    pub cdt_min_angle_deg: f64,
    /// Shadow rays per element pair.
    pub rays: u32,
    /// Refuse meshes with more unknowns than this (the matrices are O(n²)); a graded mesh
    /// raises it to its budget (times the functions per element at p = 1).
    pub max_unknowns: usize,
    /// A discontinuity mesh graded to a budget of patches ([`crate::mesh::grade`], `radlab solve
    /// --dmesh-budget`); `None`: the pieces as they are. Not with a continuous basis (grading
    /// leaves T-vertices).
    pub grade: Option<GradeParams>,
}

impl MeshSolveParams {
    /// p = 0 on `method`, elements of 1/16 of the diagonal (uniform), the CDT refined to 20°,
    /// 16 rays, at most 6 000 unknowns, not graded.
    #[must_use]
    pub const fn new(method: MeshMethod) -> MeshSolveParams {
        MeshSolveParams {
            method,
            order: Order::Constant,
            continuous: false,
            element_size_rel: 1.0 / 16.0,
            cdt_min_angle_deg: 20.0,
            rays: 16,
            max_unknowns: 6_000,
            grade: None,
        }
    }

    /// The same graded to `budget` patches ([`GradeParams::with_budget`]).
    #[must_use]
    pub const fn graded(self, budget: usize) -> MeshSolveParams {
        MeshSolveParams { grade: Some(GradeParams::with_budget(budget)), ..self }
    }

    /// The same at p = 1, continuous or not.
    #[must_use]
    pub const fn linear(self, continuous: bool) -> MeshSolveParams {
        MeshSolveParams { order: Order::Linear, continuous, ..self }
    }

    /// Reject what cannot be solved, with one line naming the setting.
    pub fn validate(&self) -> Result<(), String> {
        if self.method == MeshMethod::Quadtree {
            return Err("the quadtree is solved by the hierarchical solver, not a mesh solve".into());
        }
        if self.continuous && self.order == Order::Constant {
            return Err("a continuous basis needs order 1 (constant elements share no values)".into());
        }
        if !(self.element_size_rel.is_finite() && self.element_size_rel > 0.0) {
            return Err(format!("element size must be > 0 (got {})", self.element_size_rel));
        }
        if !(0.0..=34.0).contains(&self.cdt_min_angle_deg) {
            return Err(format!("CDT min angle must be in [0, 34] degrees (got {})", self.cdt_min_angle_deg));
        }
        if self.rays == 0 || self.max_unknowns == 0 {
            return Err("rays and max unknowns must be at least 1".into());
        }
        if self.grade.is_some() {
            if !matches!(self.method, MeshMethod::DiscontinuityCdt | MeshMethod::DiscontinuityBsp) {
                return Err(format!(
                    "grading applies to the discontinuity meshes (not {})",
                    self.method.name()
                ));
            }
            if self.continuous {
                return Err(
                    "grading cuts pieces with T-vertices: a continuous basis needs a conforming mesh".into(),
                );
            }
        }
        self.remesh().map(|_| ())
    }

    /// "uniform p0", "discontinuity-cdt p1-continuous", …
    #[must_use]
    pub fn label(&self) -> String {
        let order = match (self.order, self.continuous) {
            (Order::Constant, _) => "p0",
            (Order::Linear, false) => "p1-discontinuous",
            (Order::Linear, true) => "p1-continuous",
        };
        let graded = match self.grade.map(|g| g.budget) {
            None => String::new(),
            Some(Budget::Patches(n)) => format!(" graded {n}"),
            Some(Budget::Auto) => " graded auto".into(),
        };
        format!("{} {order}{graded}", self.method.name())
    }

    /// The discontinuity mesh, built as `radlab solve` builds it ([`RemeshParams::for_solve`]);
    /// graded, the CDT starts unrefined (grading sizes the elements) whatever the angle here.
    pub fn remesh(&self) -> Result<RemeshParams, String> {
        let kind = if self.method == MeshMethod::DiscontinuityBsp { MeshKind::Bsp } else { MeshKind::Cdt };
        let angle = self.grade.is_none().then_some(self.cdt_min_angle_deg);
        RemeshParams::for_solve(kind, angle, None, self.grade, self.max_unknowns).map_err(|e| e.to_string())
    }
}

/// A solve on a mesh: the solution on the input scene, p = 1 vertex values per element (`None`
/// at p = 0), and the meshing time of a discontinuity mesh.
#[derive(Clone, Debug)]
pub struct MeshSolution {
    pub solution: Solution,
    pub coefficients: Option<Vec<Vec<Rgb>>>,
    pub meshing_s: f64,
}

/// Solve `scene` on the mesh of `params` (module docs).
pub fn solve(scene: &Scene, params: &MeshSolveParams, progress: Progress) -> Result<MeshSolution, String> {
    params.validate()?;
    let element_size = params.element_size_rel * scene.bounds().diagonal().max(f64::MIN_POSITIVE);
    let uniform_params = UniformParams {
        element_size,
        rays: params.rays,
        ff_tolerance: COARSE_FF_TOLERANCE,
        max_elements: params.max_unknowns,
        ..UniformParams::default()
    };
    let linear_params = LinearParams {
        element_size,
        order: params.order,
        continuous: params.continuous,
        rays: params.rays,
        max_unknowns: params.max_unknowns,
        ..LinearParams::default()
    };
    let mesh = params.remesh()?;
    let uniform_params = UniformParams { max_elements: mesh.max_patches, ..uniform_params };
    // Graded: the budget of patches, each up to 4 functions at p = 1.
    let linear_params = match mesh.grade {
        Some(_) => LinearParams {
            max_unknowns: params.max_unknowns.max(mesh.max_patches * params.order.functions(4)),
            ..linear_params
        },
        None => linear_params,
    };
    // p = 0 here is the lecture's constant element (the h vs p figures set it beside p = 1), so
    // without the gather's slopes, which `radlab solve`/`reference`/`artifacts` apply.
    let dmesh =
        DiscontinuityParams { solve: uniform_params, gather: false, ..DiscontinuityParams::with_mesh(mesh) };
    let (solution, coefficients, meshing_s) = match (params.method, params.order) {
        // `validate` refused it already; an error, not a panic, if that ever changes.
        (MeshMethod::Quadtree, _) => return Err("the quadtree is not a mesh solve".into()),
        (MeshMethod::Uniform, Order::Constant) => {
            (uniform::solve(scene, &Accel::build(scene), &uniform_params, progress)?, None, 0.0)
        }
        (MeshMethod::Uniform, Order::Linear) => {
            let s = linear::solve(scene, &Accel::build(scene), &linear_params, progress)?;
            (s.solution, Some(s.coefficients), 0.0)
        }
        (_, Order::Constant) => {
            let d = discontinuity::solve(scene, &dmesh, progress).map_err(|e| e.to_string())?;
            (d.solution, None, d.mesh.total_s)
        }
        (_, Order::Linear) => {
            let (d, c) = discontinuity::solve_galerkin(scene, &dmesh, &linear_params, progress)
                .map_err(|e| e.to_string())?;
            (d.solution, Some(c), d.mesh.total_s)
        }
    };
    Ok(MeshSolution { solution, coefficients, meshing_s })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shadow() -> Scene {
        Scene::load("builtin:shadow-narrow").unwrap()
    }

    #[test]
    fn every_mesh_and_order_solves_shadow_narrow() {
        let scene = shadow();
        for method in [MeshMethod::Uniform, MeshMethod::DiscontinuityCdt, MeshMethod::DiscontinuityBsp] {
            let p0 = MeshSolveParams {
                element_size_rel: 0.2,
                cdt_min_angle_deg: 0.0,
                ..MeshSolveParams::new(method)
            };
            for p in [p0, p0.linear(false), p0.linear(true)] {
                let s = solve(&scene, &p, &mut |_, _| {}).unwrap_or_else(|e| panic!("{}: {e}", p.label()));
                assert!(s.solution.is_physical(), "{}", p.label());
                assert_eq!(s.solution.patch_radiosity.len(), scene.patches.len(), "{}", p.label());
                match (p.order, &s.coefficients) {
                    (Order::Constant, None) => {}
                    (Order::Linear, Some(c)) => {
                        assert_eq!(c.len(), s.solution.elements.len());
                        assert!(c.iter().zip(&s.solution.elements).all(|(c, e)| c.len() == e.vertices.len()));
                    }
                    _ => panic!("{}: coefficients at the wrong order", p.label()),
                }
            }
        }
    }

    /// Graded, at p = 0 and p = 1 (discontinuous): exactly the budget's elements, built as the
    /// CLI builds them ([`RemeshParams::for_solve`]: the CDT unrefined under grading).
    #[test]
    fn graded_meshes_solve_at_both_orders() {
        let scene = shadow();
        let p0 = MeshSolveParams::new(MeshMethod::DiscontinuityBsp).graded(60);
        let mesh = p0.remesh().unwrap();
        assert_eq!(mesh.grade, Some(GradeParams::with_budget(60)));
        let cdt = MeshSolveParams::new(MeshMethod::DiscontinuityCdt).graded(60).remesh().unwrap();
        assert_eq!(cdt.cdt.min_angle_deg, 0.0, "grading sizes the elements");
        for p in [p0, p0.linear(false)] {
            let s = solve(&scene, &p, &mut |_, _| {}).unwrap_or_else(|e| panic!("{}: {e}", p.label()));
            assert_eq!(s.solution.elements.len(), 60, "{}", p.label());
            assert_eq!(s.coefficients.is_some(), p.order == Order::Linear, "{}", p.label());
        }
        assert_eq!(p0.linear(false).label(), "discontinuity-bsp p1-discontinuous graded 60");
    }

    #[test]
    fn bad_settings_are_one_line_errors() {
        let scene = shadow();
        let refuse = |p: MeshSolveParams| {
            let e = solve(&scene, &p, &mut |_, _| {}).unwrap_err();
            assert!(!e.contains('\n') && !e.is_empty(), "{e}");
            e
        };
        assert!(refuse(MeshSolveParams::new(MeshMethod::Quadtree)).contains("hierarchical"));
        let u = MeshSolveParams::new(MeshMethod::Uniform);
        assert!(refuse(MeshSolveParams { continuous: true, ..u }).contains("order 1"));
        assert!(refuse(MeshSolveParams { element_size_rel: f64::NAN, ..u }).contains("element size"));
        assert!(refuse(MeshSolveParams { element_size_rel: 1e-4, max_unknowns: 50, ..u }).contains("50"));
        // Grading: discontinuity meshes only, not with a continuous basis, a valid budget.
        assert!(refuse(u.graded(100)).contains("discontinuity meshes"));
        let cdt = MeshSolveParams::new(MeshMethod::DiscontinuityCdt);
        assert!(refuse(cdt.linear(true).graded(100)).contains("conforming"));
        assert!(refuse(cdt.graded(0)).contains("budget"));
    }
}
