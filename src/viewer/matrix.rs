//! The blocking form-factor matrix window ([`crate::present::block_matrix`]): every link of the current
//! solution drawn as the block of leaf-to-leaf entries it stands for, coloured by log F.
//!
//! It is linked to the 3-D viewport both ways. Hovering a block names its link and asks the app
//! to highlight that link and its two elements in the viewport
//! ([`crate::present::overlay::Highlight::Link`]); clicking it picks the receiver. The element hovered
//! (or else picked) in the viewport comes back as [`MatrixInput::element`]: its row (as
//! receiver, orange) and column (as source, cyan) are tinted and the blocks it gathers or shoots
//! through (its own links and its ancestors') outlined.
//!
//! It is docked at the top of the inspector column, beside the viewport, never over it: the
//! outlines it asks the viewport to draw stay in sight. What the pointer is over (a block's
//! link, else the highlighted element) is written in a box of fixed height under the matrix, not
//! in a tooltip, so nothing covers the colour scale and the legend below it.

use super::view::View;
use super::widgets::rgb32;
use super::worker::ViewData;
use crate::present::block_matrix::BlockMatrix;
use crate::present::overlay::{Highlight, LogScale, Palette, ancestors};
use eframe::egui::{self, Color32, Pos2, Rect, Sense, Vec2};
use std::sync::Arc;

/// Largest side of the matrix drawing, points (it takes the column's width up to this).
const MAX_SIDE: f32 = 360.0;
/// Lines of text the hover box keeps room for (the layout below it does not jump).
const INFO_LINES: f32 = 4.0;
/// Most blocks drawn (the largest first, so the coarse structure always shows).
const MAX_BLOCKS: usize = 40_000;
/// Most blocks of a highlighted element outlined.
const MAX_OUTLINED: usize = 4_000;
/// Thinnest highlighted row or column band, points (a leaf's row of a fine mesh is sub-pixel).
const MIN_BAND: f32 = 2.0;
/// Tint of a highlighted element's row (as receiver; the viewport's receiver orange).
const ROW_TINT: Color32 = Color32::from_rgba_premultiplied(90, 50, 9, 90);
/// Tint of a highlighted element's column (as source; the viewport's source cyan).
const COL_TINT: Color32 = Color32::from_rgba_premultiplied(18, 77, 90, 90);

/// What the app lends the matrix for one frame.
pub struct MatrixInput<'a> {
    /// The solution shown.
    pub view: &'a Arc<ViewData>,
    /// The element to highlight (hovered or picked in the viewport).
    pub element: Option<u32>,
}

/// What the matrix asks of the app.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum MatrixAction {
    /// A block is hovered: highlight this link and its two elements in the viewport.
    Hover(Highlight),
    /// A block was clicked: pick its receiver.
    Pick(u32),
}

/// The row and column highlighted last frame (for tests and the status line).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct RowHighlight {
    pub element: u32,
    /// The element's leaf run: its rows and its columns.
    pub run: (u32, u32),
    /// Blocks of its own links and its ancestors'.
    pub blocks: usize,
}

/// The window's state: open or not, and the matrix of the solution last shown.
#[derive(Clone, Debug, Default)]
pub struct MatrixWindow {
    pub open: bool,
    /// (address of the `ViewData` it was built from, the matrix, its colour scale).
    cache: Option<(usize, Arc<BlockMatrix>, Option<LogScale>)>,
    highlighted: Option<RowHighlight>,
    /// Where the matrix itself was drawn in the last frame (screen points).
    drawn: Option<Rect>,
}

impl MatrixWindow {
    /// The matrix section at the top of the inspector column (when open): its title and close
    /// button, then the matrix.
    pub fn panel(&mut self, ui: &mut egui::Ui, input: MatrixInput<'_>) -> Option<MatrixAction> {
        ui.horizontal(|ui| {
            ui.heading("Blocking form-factor matrix");
            ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
                if ui.button("×").on_hover_text("Close the matrix (Lecture menu opens it)").clicked() {
                    self.open = false;
                }
            });
        });
        if !self.open {
            self.highlighted = None;
            self.drawn = None;
            return None;
        }
        self.ui(ui, input)
    }

    /// Where the matrix was drawn in the last frame (`None`: not drawn).
    #[must_use]
    pub fn matrix_rect(&self) -> Option<Rect> {
        self.drawn.filter(|_| self.open)
    }

    /// The element whose row and column were highlighted in the last frame drawn.
    #[must_use]
    pub fn highlighted(&self) -> Option<RowHighlight> {
        self.highlighted
    }
}

impl View for MatrixWindow {
    type Input<'a> = MatrixInput<'a>;
    type Action = MatrixAction;

    fn ui(&mut self, ui: &mut egui::Ui, input: MatrixInput<'_>) -> Option<MatrixAction> {
        let view = input.view;
        if view.mesh.is_some() {
            // Nothing stale: a mesh solve has no links to draw as blocks.
            ui.label(format!(
                "A mesh solve keeps no links: every pair of its {} elements is coupled, the full \
                 n × n matrix. Pick the quadtree in the Mesh menu to see the blocks.",
                view.leaves.len()
            ));
            self.highlighted = None;
            self.drawn = None;
            return None;
        }
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
        let chain = input
            .element
            .filter(|&id| (id as usize) < view.elements.len() && (id as usize) < m.runs.len())
            .map(|id| (id, ancestors(&view.elements, id)));
        let drawn = draw(ui, &m, scale, chain.as_ref());
        self.highlighted = drawn.highlighted;
        self.drawn = Some(drawn.rect);
        drawn.action
    }
}

/// What one frame's drawing of the matrix gave.
struct Drawn {
    action: Option<MatrixAction>,
    highlighted: Option<RowHighlight>,
    /// Where the matrix itself is.
    rect: Rect,
}

fn draw(
    ui: &mut egui::Ui,
    m: &BlockMatrix,
    scale: Option<LogScale>,
    element: Option<&(u32, Vec<u32>)>,
) -> Drawn {
    let n = m.n.max(1) as f32;
    ui.label(format!(
        "{} leaves: n² = {} entries; {} links (blocks) cover {:.0} % of them",
        m.n,
        u64::from(m.n) * u64::from(m.n),
        m.blocks.len(),
        100.0 * m.covered()
    ));
    let side = ui.available_width().clamp(64.0, MAX_SIDE);
    let (rect, response) = ui.allocate_exact_size(Vec2::splat(side), Sense::click());
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 0.0, Color32::from_gray(16));
    let cell = side / n;
    let to_rect = |rows: (u32, u32), cols: (u32, u32)| {
        Rect::from_min_max(
            Pos2::new(rect.left() + cols.0 as f32 * cell, rect.top() + rows.0 as f32 * cell),
            Pos2::new(rect.left() + cols.1 as f32 * cell, rect.top() + rows.1 as f32 * cell),
        )
    };
    for b in m.blocks.iter().take(MAX_BLOCKS) {
        let t = scale.map_or(0.5, |s| s.t(f64::from(b.ff)));
        painter.rect_filled(to_rect(b.rows, b.cols), 0.0, rgb32(Palette::Viridis.at(t)));
    }
    let highlighted = element.map(|(id, chain)| {
        let run = m.runs[*id as usize];
        let band = |r: Rect| {
            let grow = Vec2::new((MIN_BAND - r.width()).max(0.0), (MIN_BAND - r.height()).max(0.0)) * 0.5;
            r.expand2(grow)
        };
        painter.rect_filled(band(to_rect(run, (0, m.n))), 0.0, ROW_TINT);
        painter.rect_filled(band(to_rect((0, m.n), run)), 0.0, COL_TINT);
        let mut blocks = 0;
        for b in m.blocks.iter().filter(|b| chain.contains(&b.receiver) || chain.contains(&b.source)) {
            if blocks < MAX_OUTLINED {
                let stroke = egui::Stroke::new(1.0, Color32::from_rgb(255, 230, 120));
                painter.rect_stroke(band(to_rect(b.rows, b.cols)), 0.0, stroke, egui::StrokeKind::Inside);
            }
            blocks += 1;
        }
        RowHighlight { element: *id, run, blocks }
    });
    // The block under the pointer: outlined, and named in the box below.
    let hovered = response.hover_pos().and_then(|pos| {
        let row = ((pos.y - rect.top()) / cell).floor().clamp(0.0, n - 1.0) as u32;
        let col = ((pos.x - rect.left()) / cell).floor().clamp(0.0, n - 1.0) as u32;
        m.at(row, col)
    });
    if let Some(b) = hovered {
        painter.rect_stroke(
            to_rect(b.rows, b.cols),
            0.0,
            egui::Stroke::new(1.5, Color32::WHITE),
            egui::StrokeKind::Outside,
        );
    }
    let info = match (hovered, highlighted) {
        (Some(b), _) => format!(
            "link: receiver {} gathers from source {}, F = {:.3e}, V = {:.2}; {} × {} leaf \
             entries share this one number. Click: pick the receiver.",
            b.receiver,
            b.source,
            b.ff,
            b.vis,
            b.rows.1 - b.rows.0,
            b.cols.1 - b.cols.0
        ),
        (None, Some(h)) => format!(
            "element {}: its row (receiving) and column (shooting) tinted, its {} blocks outlined",
            h.element, h.blocks
        ),
        (None, None) => "Hover a block: the viewport outlines its receiver (orange) and source (cyan) \
                         and draws the link. Hover an element in the viewport: its row and column \
                         are tinted here."
            .to_owned(),
    };
    info_box(ui, &info);
    if m.blocks.len() > MAX_BLOCKS {
        ui.weak(format!("the {MAX_BLOCKS} largest of {} blocks drawn", m.blocks.len()));
    }
    colour_scale(ui, scale, side);
    ui.weak("rows: receiver leaves, columns: source leaves, in quadtree order; colour: log F; dark: no link");
    let action = hovered.map(|b| {
        if response.clicked() {
            MatrixAction::Pick(b.receiver)
        } else {
            MatrixAction::Hover(Highlight::Link { receiver: b.receiver, source: b.source })
        }
    });
    Drawn { action, highlighted, rect }
}

/// `text` in a box of [`INFO_LINES`] lines' height, whatever its length (wrapped to the
/// column; a longer text is cut at the box).
fn info_box(ui: &mut egui::Ui, text: &str) {
    let line = ui.text_style_height(&egui::TextStyle::Body);
    let size = Vec2::new(ui.available_width(), INFO_LINES * line + 8.0);
    let (r, _) = ui.allocate_exact_size(size, Sense::hover());
    ui.painter().rect_filled(r, 3.0, Color32::from_black_alpha(90));
    let mut child = ui.new_child(
        egui::UiBuilder::new().max_rect(r.shrink(4.0)).layout(egui::Layout::top_down(egui::Align::Min)),
    );
    child.set_clip_rect(r);
    child.add(egui::Label::new(text).wrap());
}

/// The colour scale of the blocks: log F from the smallest to the largest link's.
fn colour_scale(ui: &mut egui::Ui, scale: Option<LogScale>, width: f32) {
    let (bar, _) = ui.allocate_exact_size(Vec2::new(width, 10.0), Sense::hover());
    let steps = 48;
    for i in 0..steps {
        let t = f64::from(i) / f64::from(steps - 1);
        let x = |k: i32| bar.left() + bar.width() * k as f32 / steps as f32;
        let r = Rect::from_x_y_ranges(x(i)..=x(i + 1) + 0.5, bar.y_range());
        ui.painter().rect_filled(r, 0.0, rgb32(Palette::Viridis.at(t)));
    }
    let (lo, hi) = scale.map_or(("–".to_owned(), "–".to_owned()), |s| {
        (format!("F {:.1e}", s.lo), format!("{:.1e}", s.hi))
    });
    ui.horizontal(|ui| {
        ui.weak(lo);
        ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| ui.weak(hi));
    });
}
