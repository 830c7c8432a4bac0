//! The viewport's picture: the 3-D view drawn through the renderer's paint callback (slot 0), or
//! a note where there is no wgpu renderer, then what is drawn over it — the matrix window's
//! highlight and the overlays' legends ([`super::legends`]). The app handles the viewport's
//! input (camera, picking) before, so that a click shows in the same frame.

use super::geometry::ShownGeometry;
use super::legends::{self, Legends};
use super::worker::ViewData;
use crate::math::DVec3;
use crate::present::overlay::Highlight;
use crate::render::{
    FrameParams, NO_SELECTION, OVERLAY_PICKED, OVERLAY_QUADTREE, Uniforms, ViewportCallback,
};
use eframe::egui::{self, Color32, Rect};
use eframe::egui_wgpu;
use glam::DMat4;
use std::sync::Arc;

/// Background of the viewport (display space).
const BACKGROUND: [f32; 4] = [0.08, 0.08, 0.1, 1.0];
/// Back faces: dull magenta, striped in the shader.
const BACK_COLOR: [f32; 4] = [0.55, 0.1, 0.45, 1.0];
/// Width of the quadtree edges drawn by the mesh shader, pixels on each side of an edge (a
/// shared edge shows both sides' depth colours, 1.5 px together).
const QUADTREE_LINE_PX: f32 = 0.75;

/// How the mesh shader draws, besides the camera.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Shade {
    /// Exposure in stops.
    pub exposure_ev: f32,
    pub srgb: bool,
    /// Colour by the error heatmap.
    pub error: bool,
    /// Edges of the quadtree (or mesh) drawn.
    pub quadtree: bool,
    /// The picked element, outlined.
    pub picked: Option<u32>,
}

/// The renderer's uniforms for `view_proj` and `shade`.
#[must_use]
pub fn uniforms(view_proj: DMat4, shade: Shade, pixels_per_point: f32) -> Uniforms {
    let m = view_proj.to_cols_array_2d();
    Uniforms {
        view_proj: m.map(|c| c.map(|x| x as f32)),
        exposure: 2f32.powf(shade.exposure_ev),
        tone: u32::from(shade.srgb),
        mode: u32::from(shade.error),
        selected: shade.picked.unwrap_or(NO_SELECTION),
        back_color: BACK_COLOR,
        overlay: if shade.quadtree { OVERLAY_QUADTREE } else { 0 }
            | if shade.picked.is_some() { OVERLAY_PICKED } else { 0 },
        line_px: QUADTREE_LINE_PX * pixels_per_point,
        _pad: [0; 2],
        background: BACKGROUND,
    }
}

/// What the viewport's picture is drawn from, for one frame.
pub struct Picture<'a> {
    pub geometry: &'a ShownGeometry,
    /// The camera's view-projection for the viewport's aspect, and the scene centre.
    pub view_proj: DMat4,
    pub origin: DVec3,
    pub shade: Shade,
    /// A wgpu renderer is there to draw with.
    pub has_wgpu: bool,
    /// The solution shown (for the highlight's outlines and label).
    pub view: &'a ViewData,
    /// What the matrix window asks to highlight.
    pub highlight: Option<Highlight>,
    pub legends: Legends<'a>,
}

/// Draw the viewport's picture into `rect`.
pub fn paint(ui: &egui::Ui, rect: Rect, p: &Picture<'_>) {
    let painter = ui.painter_at(rect);
    if p.has_wgpu {
        let ppp = ui.ctx().pixels_per_point();
        let size =
            [(rect.width() * ppp).round().max(1.0) as u32, (rect.height() * ppp).round().max(1.0) as u32];
        painter.add(egui_wgpu::Callback::new_paint_callback(
            rect,
            ViewportCallback {
                frame: FrameParams { uniforms: uniforms(p.view_proj, p.shade, ppp), size },
                geometry: Arc::clone(&p.geometry.geometry),
                generation: p.geometry.generation,
                slot: 0,
            },
        ));
    } else {
        painter.rect_filled(rect, 0.0, Color32::from_gray(20));
        painter.text(
            rect.center(),
            egui::Align2::CENTER_CENTER,
            "no wgpu renderer",
            egui::FontId::proportional(16.0),
            Color32::GRAY,
        );
    }
    if let Some(h) = p.highlight {
        legends::highlight(&painter, rect, p.view, h, p.view_proj, p.origin);
    }
    p.legends.draw(&painter, rect);
}
