//! The top bar: the Lecture, View and Help menus, Open…, the Export baked glTF… menu (vertex
//! colours per element, or a lightmap of a chosen size: [`BakeChoice`]), the scene field and
//! Load, Screenshot, the Plots toggle, the Mesh menu ([`super::mesh_menu`]) and the name of the
//! scene shown.

use super::file_dialog::Purpose;
use super::help;
use super::history::RunHistory;
use super::lecture::Lecture;
use super::mesh_menu::MeshMenu;
use super::replay::Replay;
use super::split::SplitView;
use super::view::View;
use super::worker::DmeshOptions;
use crate::present::bake::LightmapParams;
use crate::present::figures::Figure;
use crate::scene::Scene;
use crate::solver::meshed::MeshSolveParams;
use eframe::egui;
use eframe::egui::PopupCloseBehavior;
use eframe::egui::containers::menu::{MenuButton, MenuConfig};

/// The top bar and the text of its scene field.
#[derive(Clone, Debug, Default)]
pub struct TopBar {
    /// The scene field: `builtin:NAME` or a path, opened by Load (or Enter).
    pub spec_edit: String,
    /// The Export menu's choice of bake form.
    pub bake: BakeChoice,
}

/// What the Export baked glTF menu bakes: vertex colours per element (the default), or the
/// original meshes with a lightmap of `size` (as `radlab solve --bake-lightmap SIZE`).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct BakeChoice {
    pub lightmap: bool,
    /// A power of two in [`LightmapParams::MIN_SIZE`]..=[`LightmapParams::MAX_SIZE`].
    pub size: u32,
}

impl Default for BakeChoice {
    fn default() -> Self {
        BakeChoice { lightmap: false, size: 1024 }
    }
}

impl BakeChoice {
    /// The lightmap size to bake, if a lightmap is chosen.
    #[must_use]
    pub fn lightmap_size(&self) -> Option<u32> {
        self.lightmap.then_some(self.size)
    }

    /// The menu's controls: the lightmap checkbox and its size.
    fn ui(&mut self, ui: &mut egui::Ui) {
        ui.checkbox(&mut self.lightmap, "lightmap").on_hover_text(
            "Bake the original meshes (one polygon per input patch) with a SIZE×SIZE lightmap on a \
             second UV set (TEXCOORD_1, an embedded PNG) instead of vertex colours per element: \
             radlab solve --bake-lightmap SIZE",
        );
        // The sizes as buttons, not a combo box: a popup inside the menu's popup would close it.
        ui.add_enabled_ui(self.lightmap, |ui| {
            ui.label("lightmap size (texels):");
            ui.horizontal_wrapped(|ui| {
                let mut size = LightmapParams::MIN_SIZE;
                while size <= LightmapParams::MAX_SIZE {
                    ui.selectable_value(&mut self.size, size, size.to_string())
                        .on_hover_text(format!("A {size}×{size} atlas"));
                    size *= 2;
                }
            });
        });
    }
}

/// What the top bar is lent for one frame: the panels its menus open and close, and what it
/// names.
pub struct TopBarInput<'a> {
    pub lecture: &'a mut Lecture,
    pub split: &'a mut SplitView,
    pub replay: &'a mut Replay,
    pub history: &'a mut RunHistory,
    pub show_help: &'a mut bool,
    pub show_plots: &'a mut bool,
    pub scene: Option<&'a Scene>,
    /// What the scene was opened from.
    pub scene_spec: &'a str,
    /// The mesh and the D-mesh options.
    pub mesh: (MeshSolveParams, DmeshOptions),
    /// What the hierarchical solver refines: "quadtree" on the input patches, "contact" on the
    /// contact mesh.
    pub top: &'static str,
}

/// What the top bar asks of the app.
#[derive(Clone, Debug)]
pub enum TopBarAction {
    OpenFigure(&'static Figure),
    /// Ask for a file (the desktop's dialog or the in-app one).
    ChooseFile(Purpose),
    /// Open this scene.
    Load(String),
    Screenshot,
    /// Solve on this mesh.
    SetMesh(MeshSolveParams, DmeshOptions),
}

impl View for TopBar {
    type Input<'a> = TopBarInput<'a>;
    type Action = TopBarAction;

    fn ui(&mut self, ui: &mut egui::Ui, input: TopBarInput<'_>) -> Option<TopBarAction> {
        let TopBarInput {
            lecture,
            split,
            replay,
            history,
            show_help,
            show_plots,
            scene,
            scene_spec,
            mesh,
            top,
        } = input;
        let mut action = None;
        ui.horizontal(|ui| {
            if let Some(f) = lecture.menu(ui) {
                action = Some(TopBarAction::OpenFigure(f));
            }
            view_menu(ui, split, replay, history);
            help::menu(ui, show_help);
            ui.separator();
            if ui
                .button("Open…")
                .on_hover_text("Open a .gltf/.glb file (or drop one on the window)")
                .clicked()
            {
                action = Some(TopBarAction::ChooseFile(Purpose::Open));
            }
            let bake = &mut self.bake;
            ui.add_enabled_ui(scene.is_some(), |ui| {
                // The menu stays open while its checkbox and size are set.
                let config = MenuConfig::new().close_behavior(PopupCloseBehavior::CloseOnClickOutside);
                MenuButton::new("Export baked glTF…")
                    .config(config)
                    .ui(ui, |ui| {
                        bake.ui(ui);
                        if ui.button("Choose file…").on_hover_text("Where to write the bake").clicked() {
                            let name = scene.map_or("radlab".to_owned(), |s| s.name.clone());
                            let suggested = format!("{name}.glb");
                            let lightmap = bake.lightmap_size();
                            action =
                                Some(TopBarAction::ChooseFile(Purpose::ExportBake { suggested, lightmap }));
                            ui.close();
                        }
                    })
                    .0
                    .on_hover_text(
                        "Write the solution shown as a .glb/.gltf at the viewer's exposure, unlit: \
                         radiosity as vertex colours, or a lightmap (docs/bake.md)",
                    );
            });
            let edit = ui
                .add(
                    egui::TextEdit::singleline(&mut self.spec_edit)
                        .desired_width(160.0)
                        .hint_text("builtin:NAME or path"),
                )
                .on_hover_text("builtin:NAME (radlab scenes lists them) or a .gltf/.glb path");
            let enter = edit.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
            if ui
                .button("Load")
                .on_hover_text("Open the scene named on the left (or press Enter there)")
                .clicked()
                || enter
            {
                let spec = self.spec_edit.trim().to_owned();
                if !spec.is_empty() {
                    action = Some(TopBarAction::Load(spec));
                }
            }
            if ui.button("Screenshot").on_hover_text("Save the viewport as a PNG").clicked() {
                action = Some(TopBarAction::Screenshot);
            }
            ui.toggle_value(show_plots, "Plots").on_hover_text(
                "Convergence plots under the inspector: residual per gather, links against elements \
                 (one point per solve), error against solver time",
            );
            if let Some((m, d)) = MeshMenu.ui(ui, (mesh.0, mesh.1, top)) {
                action = Some(TopBarAction::SetMesh(m, d));
            }
            ui.separator();
            let name = scene.map_or("(no scene)".to_owned(), |s| s.name.clone());
            // Cut at the window's edge ("…", the whole in the hover text) rather than run past it.
            ui.add(egui::Label::new(egui::RichText::new(name).strong()).truncate());
            ui.add(egui::Label::new(egui::RichText::new(scene_spec).weak()).truncate())
                .on_hover_text(scene_spec);
        });
        action
    }
}

/// The View menu: the split view, the run history and the refinement replay.
fn view_menu(ui: &mut egui::Ui, split: &mut SplitView, replay: &mut Replay, history: &mut RunHistory) {
    ui.menu_button("View", |ui| {
        if ui
            .checkbox(&mut split.on, "Split view (V)")
            .on_hover_text(
                "Two or three runs side by side with one camera and one exposure, each labelled \
                 with its settings, time and error: the runs picked in the run history, else the \
                 newest of this scene",
            )
            .changed()
        {
            replay.on &= !split.on;
        }
        ui.horizontal(|ui| {
            ui.label("panes");
            for n in [2, 3] {
                ui.selectable_value(&mut split.panes, n, n.to_string())
                    .on_hover_text(format!("Show the newest {n} runs when fewer than two are picked"));
            }
        });
        ui.checkbox(&mut history.open, "Run history (H)").on_hover_text(
            "Every solve of this window: settings, elements, links, time, error; pick the runs \
             of the split view there",
        );
        ui.separator();
        if ui
            .checkbox(&mut replay.on, "Refinement replay")
            .on_hover_text(
                "The last solve round by round (mesh, links, radiosity as they were), with a \
                 slider; and a depth slider that cuts the quadtrees at a level",
            )
            .changed()
        {
            split.on &= !replay.on;
        }
    })
    .response
    .on_hover_text("Split view, run history and refinement replay: compare solves, watch one form");
}
