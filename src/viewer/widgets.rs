//! Small widgets and colour helpers the panels share.

use eframe::egui::{self, Color32};

/// An overlay colour (0..1 RGB) as an egui colour.
#[must_use]
pub fn rgb32(c: [f32; 3]) -> Color32 {
    Color32::from_rgb((c[0] * 255.0) as u8, (c[1] * 255.0) as u8, (c[2] * 255.0) as u8)
}

/// A radiosity triple as the inspector prints it.
#[must_use]
pub fn rgb_text(c: crate::math::Rgb) -> String {
    format!("{:.4} {:.4} {:.4}", c.r(), c.g(), c.b())
}

/// One row of a two-column inspector grid: a name, and its value in monospace, wrapped at the
/// column's edge (never cut, never widening the panel).
pub fn grid_row(ui: &mut egui::Ui, name: &str, value: String) {
    ui.label(name);
    ui.add(egui::Label::new(egui::RichText::new(value).monospace()).wrap());
    ui.end_row();
}

/// A log slider with a typed value next to it.
pub fn log_slider(ui: &mut egui::Ui, label: &str, v: &mut f64, lo: f64, hi: f64, tip: &str) {
    ui.horizontal(|ui| {
        // Only what the user enters is clamped: a preset's value outside the range (the lecture
        // preset's BFeps 0, a uniform mesh's Feps 0) stays as it is, and nothing restarts.
        ui.add(
            egui::Slider::new(v, lo..=hi)
                .logarithmic(true)
                .clamping(egui::SliderClamping::Edits)
                .show_value(false)
                .text(label),
        )
        .on_hover_text(tip);
        let typed = ui
            .add(
                egui::DragValue::new(v)
                    .speed(0.0)
                    .range(lo..=hi)
                    .clamp_existing_to_range(false)
                    .custom_formatter(|x, _| format!("{x:.2e}")),
            )
            .on_hover_text(format!("{label}: type a value ({lo:.0e} to {hi:.0e})"));
        // The typed field's accessible name (screen readers, UI tests).
        let name = format!("{label} value");
        ui.ctx().accesskit_node_builder(typed.id, |b| b.set_label(name));
    });
}
