//! The blocking form-factor matrix window ([`crate::block_matrix`]): every link of the current
//! solution drawn as the block of leaf-to-leaf entries it stands for, coloured by log F.
//! Hovering a block names its link; clicking it picks the receiver in the viewport and shows its
//! links there.

use super::worker::ViewData;
use crate::block_matrix::BlockMatrix;
use crate::overlay::{LogScale, Palette};
use eframe::egui::{self, Color32, Pos2, Rect, Sense, Vec2};
use std::sync::Arc;

/// Side of the matrix drawing, points.
const SIDE: f32 = 360.0;
/// Most blocks drawn (the largest first, so the coarse structure always shows).
const MAX_BLOCKS: usize = 40_000;

/// The window's state: open or not, and the matrix of the solution last shown.
#[derive(Clone, Debug, Default)]
pub struct MatrixWindow {
    pub open: bool,
    /// (address of the `ViewData` it was built from, the matrix, its colour scale).
    cache: Option<(usize, Arc<BlockMatrix>, Option<LogScale>)>,
}

impl MatrixWindow {
    /// The window (when open); returns the receiver element of a clicked block.
    pub fn window(&mut self, ctx: &egui::Context, view: &Arc<ViewData>) -> Option<u32> {
        let key = Arc::as_ptr(view) as usize;
        if self.cache.as_ref().is_none_or(|c| c.0 != key) {
            let mut m = BlockMatrix::build(&view.elements, &view.links);
            // Largest blocks first: drawn first, and kept when the count is capped.
            m.blocks.sort_by_key(|b| {
                std::cmp::Reverse(u64::from(b.rows.1 - b.rows.0) * u64::from(b.cols.1 - b.cols.0))
            });
            let scale = LogScale::spanning(m.blocks.iter().map(|b| f64::from(b.ff)));
            self.cache = Some((key, Arc::new(m), scale));
        }
        let (m, scale) = self.cache.as_ref().map(|c| (Arc::clone(&c.1), c.2))?;
        let mut open = self.open;
        let mut clicked = None;
        egui::Window::new("Blocking form-factor matrix")
            .open(&mut open)
            .resizable(false)
            .default_pos([560.0, 60.0])
            .show(ctx, |ui| clicked = draw(ui, &m, scale));
        self.open = open;
        clicked
    }
}

fn draw(ui: &mut egui::Ui, m: &BlockMatrix, scale: Option<LogScale>) -> Option<u32> {
    let n = m.n.max(1) as f32;
    ui.label(format!(
        "{} leaves: n² = {} entries; {} links (blocks) cover {:.0} % of them",
        m.n,
        u64::from(m.n) * u64::from(m.n),
        m.blocks.len(),
        100.0 * m.covered()
    ));
    let (rect, response) = ui.allocate_exact_size(Vec2::splat(SIDE), Sense::click());
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 0.0, Color32::from_gray(16));
    let cell = SIDE / n;
    let to_rect = |rows: (u32, u32), cols: (u32, u32)| {
        Rect::from_min_max(
            Pos2::new(rect.left() + cols.0 as f32 * cell, rect.top() + rows.0 as f32 * cell),
            Pos2::new(rect.left() + cols.1 as f32 * cell, rect.top() + rows.1 as f32 * cell),
        )
    };
    for b in m.blocks.iter().take(MAX_BLOCKS) {
        let t = scale.map_or(0.5, |s| s.t(f64::from(b.ff)));
        let [r, g, bl] = Palette::Viridis.at(t);
        let c = Color32::from_rgb((r * 255.0) as u8, (g * 255.0) as u8, (bl * 255.0) as u8);
        painter.rect_filled(to_rect(b.rows, b.cols).expand(0.0), 0.0, c);
    }
    if m.blocks.len() > MAX_BLOCKS {
        ui.weak(format!("the {MAX_BLOCKS} largest of {} blocks drawn", m.blocks.len()));
    }
    ui.weak("rows: receiver leaves, columns: source leaves, in quadtree order; colour: log F");
    let pos = response.hover_pos()?;
    let row = ((pos.y - rect.top()) / cell).floor().clamp(0.0, n - 1.0) as u32;
    let col = ((pos.x - rect.left()) / cell).floor().clamp(0.0, n - 1.0) as u32;
    let b = m.at(row, col)?;
    painter.rect_stroke(
        to_rect(b.rows, b.cols),
        0.0,
        egui::Stroke::new(1.5, Color32::WHITE),
        egui::StrokeKind::Outside,
    );
    let clicked = response.clicked();
    response.on_hover_text(format!(
        "link: receiver {} ← source {}, F = {:.3e}; {} × {} leaf entries share this one number. \
         Click: pick the receiver in the viewport.",
        b.receiver,
        b.source,
        b.ff,
        b.rows.1 - b.rows.0,
        b.cols.1 - b.cols.0
    ));
    clicked.then_some(b.receiver)
}
