//! The Mesh menu of the top bar: what the solution is computed on (the hierarchical quadtree, a
//! uniform mesh, a discontinuity mesh) and a mesh solve's settings (order, continuity, element
//! size, CDT angle, rays), greyed out on the quadtree, whose settings are the Solver section's;
//! on a discontinuity mesh, grading to a budget of patches ([`MeshSolveParams::grade`], at p = 0
//! and p = 1 discontinuous) and, at p = 0, the D-mesh as the top level of hierarchical refinement
//! ([`DmeshOptions`]).

use super::view::View;
use super::widgets::log_slider;
use super::worker::DmeshOptions;
use crate::solver::meshed::{MeshMethod, MeshSolveParams};
use eframe::egui;

/// The Mesh menu (its state is the app's [`MeshSolveParams`]).
#[derive(Copy, Clone, Debug, Default)]
pub struct MeshMenu;

impl View for MeshMenu {
    /// The mesh solved on now, the D-mesh options, and what the hierarchical solver refines
    /// ("quadtree", or "contact" for the contact mesh under its quadtrees).
    type Input<'a> = (MeshSolveParams, DmeshOptions, &'static str);
    /// The mesh and settings chosen, when they changed.
    type Action = (MeshSolveParams, DmeshOptions);

    fn ui(
        &mut self,
        ui: &mut egui::Ui,
        (mesh, dmesh, top): (MeshSolveParams, DmeshOptions, &'static str),
    ) -> Option<(MeshSolveParams, DmeshOptions)> {
        let title = match mesh.method {
            MeshMethod::Quadtree if top == "contact" => "Mesh: contact mesh + quadtree".to_owned(),
            MeshMethod::Quadtree => "Mesh: quadtree".to_owned(),
            _ => format!("Mesh: {}{}", mesh.label(), dmesh.label(&mesh)),
        };
        let mut chosen = None;
        ui.menu_button(title, |ui| chosen = controls(ui, (mesh, dmesh))).response.on_hover_text(
            "What the solution is computed on: the hierarchical quadtree, a uniform mesh, or a \
             discontinuity mesh whose edges follow the shadow boundaries; element order p = 0 / 1",
        );
        chosen
    }
}

fn controls(
    ui: &mut egui::Ui,
    (mesh, dmesh): (MeshSolveParams, DmeshOptions),
) -> Option<(MeshSolveParams, DmeshOptions)> {
    let (mut m, mut d) = (mesh, dmesh);
    for method in MeshMethod::ALL {
        ui.radio_value(&mut m.method, method, method.name()).on_hover_text(method.description());
    }
    ui.separator();
    let on_mesh = m.method != MeshMethod::Quadtree;
    ui.add_enabled_ui(on_mesh, |ui| {
        ui.horizontal(|ui| {
            ui.label("order");
            ui.selectable_value(&mut m.order, crate::geometry::basis::Order::Constant, "p = 0")
                .on_hover_text("Constant elements: one value each")
                .on_disabled_hover_text("The quadtree's elements are constant (p = 0)");
            ui.selectable_value(&mut m.order, crate::geometry::basis::Order::Linear, "p = 1")
                .on_hover_text(
                    "Linear (triangles) / bilinear (quads) elements, a Galerkin solve of their \
                     vertex values: follows a smooth ramp inside an element, but 20-60 times \
                     slower than p = 0 (a minute or more on table-room; Cancel drops it)",
                )
                .on_disabled_hover_text("p = 1 exists on the uniform and discontinuity meshes");
        });
        ui.add_enabled_ui(m.order == crate::geometry::basis::Order::Linear, |ui| {
            ui.horizontal(|ui| {
                ui.selectable_value(&mut m.continuous, false, "discontinuous")
                    .on_hover_text("Each element its own vertex values: jumps can remain at element edges");
                ui.selectable_value(&mut m.continuous, true, "continuous").on_hover_text(
                    "One value per mesh vertex, shared by the elements around it: no jumps, \
                     fewer unknowns",
                );
            })
            .response
            .on_disabled_hover_text("Continuity applies to p = 1 elements");
        });
        ui.add_enabled_ui(m.method == MeshMethod::Uniform, |ui| {
            log_slider(
                ui,
                "size",
                &mut m.element_size_rel,
                1e-3,
                1.0,
                "Uniform mesh: longest element side, as a fraction of the scene's diagonal",
            );
        });
        ui.add_enabled_ui(m.method == MeshMethod::DiscontinuityCdt, |ui| {
            ui.add(
                egui::Slider::new(&mut m.cdt_min_angle_deg, 0.0..=30.0).step_by(5.0).text("CDT min angle"),
            )
            .on_hover_text(
                "Delaunay refinement of the constrained triangulation to this smallest angle \
                     (degrees; 0: the constraints' triangulation as it is, fewest elements)",
            );
        });
        ui.add(egui::Slider::new(&mut m.rays, 1..=64).logarithmic(true).text("rays / pair"))
            .on_hover_text("Shadow rays per element pair (the visible fraction)");
        let discontinuity = matches!(m.method, MeshMethod::DiscontinuityCdt | MeshMethod::DiscontinuityBsp);
        ui.add_enabled_ui(discontinuity && !m.continuous, |ui| grade_controls(ui, &mut m))
            .response
            .on_disabled_hover_text(
                "Grading: a discontinuity mesh at p = 0 or p = 1 discontinuous (its cuts leave \
                 T-vertices, which a continuous basis cannot share values across)",
            );
        if !discontinuity || m.continuous {
            m.grade = None;
        }
        ui.add_enabled_ui(discontinuity && m.order == crate::geometry::basis::Order::Constant, |ui| {
            top_level_control(ui, &mut d);
        })
        .response
        .on_disabled_hover_text("The hierarchical top level: a discontinuity mesh at p = 0");
    })
    .response
    .on_disabled_hover_text("Mesh settings: pick a uniform or discontinuity mesh above");
    (m != mesh || d != dmesh).then_some((m, d))
}

/// Default budget when grading is turned on: table-room's unrefined CDT has 592 shadow-bounding
/// pieces, so twice that gives the penumbrae room.
const DEFAULT_BUDGET: usize = 2_000;

/// Grading to a budget (docs/meshing.md, "A graded discontinuity mesh").
fn grade_controls(ui: &mut egui::Ui, m: &mut MeshSolveParams) {
    ui.horizontal(|ui| {
        let budget_now = match m.grade.map(|g| g.budget) {
            Some(crate::mesh::grade::Budget::Patches(n)) => Some(n),
            Some(crate::mesh::grade::Budget::Auto) => Some(DEFAULT_BUDGET),
            None => None,
        };
        let mut graded = budget_now.is_some();
        ui.checkbox(&mut graded, "graded").on_hover_text(
            "Keep only the segments that bound a shadow, then cut the piece with the largest \
             error estimate in two (across a penumbra, along its isolines) until the scene has \
             this many patches (radlab solve --dmesh-budget N)",
        );
        let mut budget = budget_now.unwrap_or(DEFAULT_BUDGET);
        ui.add_enabled(graded, egui::Slider::new(&mut budget, 100..=6_000).logarithmic(true).text("patches"))
            .on_hover_text("The budget: patches for the whole scene after grading");
        if budget_now != graded.then_some(budget) {
            *m = if graded { m.graded(budget) } else { MeshSolveParams { grade: None, ..*m } };
        }
    });
}

/// The D-mesh as the top level of hierarchical refinement (docs/meshing.md, "The D-mesh as the
/// top level").
fn top_level_control(ui: &mut egui::Ui, d: &mut DmeshOptions) {
    ui.checkbox(&mut d.hierarchical, "top of hierarchical refinement").on_hover_text(
        "Hand the D-mesh's pieces to the hierarchical solver as its top level (the Solver \
         panel's settings): shadow boundaries are top-level edges, the oracle refines the smooth \
         parts below them (radlab solve --method hierarchical)",
    );
}
