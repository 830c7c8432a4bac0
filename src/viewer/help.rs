//! Keyboard shortcuts: the table the Help menu and window show, and the keys that act on the
//! solver, the overlays and the panels (the camera's keys are read by the viewport).

use crate::solver::hierarchical::StepKind;
use eframe::egui;

/// Every shortcut of the viewer: (keys, what they do). The Help menu and window list these.
pub const SHORTCUTS: &[(&str, &str)] = &[
    ("S", "Solve (the HSA91 loop until converged)"),
    ("Space", "Refine step"),
    ("G", "Gather step"),
    ("P", "Push-pull"),
    ("I", "Iterate (refine + gather + push-pull)"),
    ("Q", "quadtree overlay on / off"),
    ("L", "links overlay on / off"),
    ("E", "error heatmap on / off"),
    ("D", "critical edges (D0/D1/D2) on / off"),
    ("A", "artifact overlay: none, each of the five, all five, none again"),
    ("K", "cluster boxes on / off (clustered solves)"),
    ("C", "caption of the lecture figure shown / hidden"),
    ("V", "split view on / off (runs side by side, one camera)"),
    ("H", "run history window shown / hidden"),
    ("F1", "this help"),
    ("left drag, arrows", "orbit the camera"),
    ("right / middle drag, shift + left drag, shift + arrows", "pan"),
    ("wheel, + / −", "zoom"),
    ("F", "frame the whole scene"),
    ("R", "back to the scene's camera"),
    ("click", "pick an element: the inspector shows it and its links"),
    ("hover, matrix open", "a block: its link in 3-D; an element: its row and column in the matrix"),
];

/// What a key asks for.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Action {
    Step(StepKind),
    ToggleQuadtree,
    ToggleLinks,
    ToggleError,
    ToggleCritical,
    CycleArtifact,
    ToggleClusters,
    ToggleCaption,
    ToggleHelp,
    ToggleSplit,
    ToggleHistory,
}

/// The actions of the keys pressed this frame (none while a text field has the keyboard).
#[must_use]
pub fn pressed(ctx: &egui::Context) -> Vec<Action> {
    if ctx.egui_wants_keyboard_input() {
        return Vec::new();
    }
    let keys = [
        (egui::Key::S, Action::Step(StepKind::Solve)),
        (egui::Key::Space, Action::Step(StepKind::Refine)),
        (egui::Key::G, Action::Step(StepKind::Gather)),
        (egui::Key::P, Action::Step(StepKind::PushPull)),
        (egui::Key::I, Action::Step(StepKind::Iterate)),
        (egui::Key::Q, Action::ToggleQuadtree),
        (egui::Key::L, Action::ToggleLinks),
        (egui::Key::E, Action::ToggleError),
        (egui::Key::D, Action::ToggleCritical),
        (egui::Key::A, Action::CycleArtifact),
        (egui::Key::K, Action::ToggleClusters),
        (egui::Key::C, Action::ToggleCaption),
        (egui::Key::F1, Action::ToggleHelp),
        (egui::Key::V, Action::ToggleSplit),
        (egui::Key::H, Action::ToggleHistory),
    ];
    ctx.input(|i| {
        let plain = i.modifiers.is_none();
        keys.iter().filter(|(k, _)| plain && i.key_pressed(*k)).map(|&(_, a)| a).collect()
    })
}

/// The shortcut table.
pub fn table(ui: &mut egui::Ui) {
    egui::Grid::new("shortcuts").num_columns(2).striped(true).show(ui, |ui| {
        for (keys, what) in SHORTCUTS {
            ui.monospace(*keys);
            ui.label(*what);
            ui.end_row();
        }
    });
}

/// The Help menu in the top bar: the shortcut table and a button for the Help window.
pub fn menu(ui: &mut egui::Ui, window_open: &mut bool) {
    ui.menu_button("Help", |ui| {
        ui.strong("Keyboard shortcuts");
        table(ui);
        ui.separator();
        if ui
            .button("Open as a window (F1)")
            .on_hover_text("Keep the table open beside the viewport")
            .clicked()
        {
            *window_open = true;
            ui.close();
        }
    })
    .response
    .on_hover_text("Keyboard shortcuts");
}

/// The Help window (F1).
pub fn window(ctx: &egui::Context, open: &mut bool) {
    egui::Window::new("Keyboard shortcuts").open(open).resizable(false).collapsible(false).show(ctx, table);
}
