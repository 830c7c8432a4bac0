//! The Mesh menu of the top bar: what the solution is computed on (the hierarchical quadtree, a
//! uniform mesh, a discontinuity mesh) and a mesh solve's settings (order, continuity, element
//! size, CDT angle, rays), greyed out on the quadtree, whose settings are the Solver section's.

use super::view::View;
use super::widgets::log_slider;
use crate::solver::meshed::{MeshMethod, MeshSolveParams};
use eframe::egui;

/// The Mesh menu (its state is the app's [`MeshSolveParams`]).
#[derive(Copy, Clone, Debug, Default)]
pub struct MeshMenu;

impl View for MeshMenu {
    /// The mesh solved on now.
    type Input<'a> = MeshSolveParams;
    /// The mesh and settings chosen, when they changed.
    type Action = MeshSolveParams;

    fn ui(&mut self, ui: &mut egui::Ui, mesh: MeshSolveParams) -> Option<MeshSolveParams> {
        let title = match mesh.method {
            MeshMethod::Quadtree => "Mesh: quadtree".to_owned(),
            _ => format!("Mesh: {}", mesh.label()),
        };
        let mut chosen = None;
        ui.menu_button(title, |ui| chosen = controls(ui, mesh)).response.on_hover_text(
            "What the solution is computed on: the hierarchical quadtree, a uniform mesh, or a \
             discontinuity mesh whose edges follow the shadow boundaries; element order p = 0 / 1",
        );
        chosen
    }
}

fn controls(ui: &mut egui::Ui, mesh: MeshSolveParams) -> Option<MeshSolveParams> {
    let mut m = mesh;
    for method in MeshMethod::ALL {
        ui.radio_value(&mut m.method, method, method.name()).on_hover_text(method.description());
    }
    ui.separator();
    let on_mesh = m.method != MeshMethod::Quadtree;
    ui.add_enabled_ui(on_mesh, |ui| {
        ui.horizontal(|ui| {
            ui.label("order");
            ui.selectable_value(&mut m.order, crate::basis::Order::Constant, "p = 0")
                .on_hover_text("Constant elements: one value each")
                .on_disabled_hover_text("The quadtree's elements are constant (p = 0)");
            ui.selectable_value(&mut m.order, crate::basis::Order::Linear, "p = 1")
                .on_hover_text(
                    "Linear (triangles) / bilinear (quads) elements, a Galerkin solve of their \
                     vertex values: follows a smooth ramp inside an element, but 20-60 times \
                     slower than p = 0 (a minute or more on table-room; Cancel drops it)",
                )
                .on_disabled_hover_text("p = 1 exists on the uniform and discontinuity meshes");
        });
        ui.add_enabled_ui(m.order == crate::basis::Order::Linear, |ui| {
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
    })
    .response
    .on_disabled_hover_text("Mesh settings: pick a uniform or discontinuity mesh above");
    (m != mesh).then_some(m)
}
