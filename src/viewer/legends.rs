//! What is drawn over the viewport's picture: the legends of the overlays shown (quadtree
//! depth or mesh edges, links' F scale, critical edges, artifacts, error scale), a note when
//! there is nothing to see yet, and the highlight the matrix window asks for (an element's
//! outline, or a link and its two elements, with a label).

use super::artifacts::Measured;
use super::display::Display;
use super::widgets::rgb32;
use super::worker::ViewData;
use crate::math::DVec3;
use crate::mesh::discontinuity::SegmentCounts;
use crate::present::mesh_overlay::Artifact;
use crate::present::overlay::{self, Decimation, Highlight, LogScale, Palette};
use eframe::egui::{self, Color32, Pos2, Rect, Vec2};
use glam::DMat4;

/// What the legends describe, lent for one frame.
pub struct Legends<'a> {
    pub display: &'a Display,
    /// The solution shown.
    pub view: &'a ViewData,
    /// An element of the solution shown is picked (its links may be drawn).
    pub picked: bool,
    /// The cluster picked (its cluster links are drawn instead of the element's).
    pub picked_cluster: Option<u32>,
    /// (links drawn, links that pass the filter).
    pub link_stats: (usize, usize),
    /// (cluster links drawn, carried ones that pass the filter), when they are drawn.
    pub cluster_link_stats: Option<(usize, usize)>,
    pub link_scale: Option<LogScale>,
    pub error_scale: Option<LogScale>,
    /// The critical edges drawn, by kind (while that overlay is on).
    pub critical: Option<SegmentCounts>,
    /// The artifact measurement of the solution shown (`None`: not answered yet).
    pub artifacts: Option<&'a Result<Measured, String>>,
    /// What the error heatmap shows, while it is drawn.
    pub error: Option<&'static str>,
    /// The solver thread has work.
    pub busy: bool,
    /// The split view is on (but shows the viewport: fewer than two runs).
    pub split_on: bool,
    /// The picture is the last finished solve's while a settings change is re-solved: why, in
    /// one line (it is framed and the line shown at the bottom).
    pub stale: Option<String>,
}

impl Legends<'_> {
    /// Draw the legends in the viewport's upper-left corner, and a note at the bottom.
    pub fn draw(&self, painter: &egui::Painter, rect: Rect) {
        let x = rect.left() + 8.0;
        let mut y = rect.top() + 8.0;
        if self.display.quadtree {
            y = self.edges_legend(painter, Pos2::new(x, y));
        }
        if self.links_shown() {
            y = self.links_legend(painter, Pos2::new(x, y));
        }
        if let Some(c) = self.critical {
            y = critical_legend(painter, Pos2::new(x, y), c) + 6.0;
        }
        if let Some(which) = self.display.artifact {
            y = self.artifact_legend(painter, Pos2::new(x, y), which) + 6.0;
        }
        if let Some(what) = self.error {
            self.error_legend(painter, Pos2::new(x, y), what);
        }
        self.note(painter, rect);
    }

    /// The element links are drawn: the links overlay, or the picked element's links.
    fn links_shown(&self) -> bool {
        let mesh_view = self.view.mesh.is_some();
        !mesh_view && (self.display.links || (self.display.selected_links_only && self.picked))
    }

    /// The edges overlay's legend at `at`: a mesh solve's mesh and times, else the quadtree's
    /// depth colours; returns where the next legend goes.
    fn edges_legend(&self, painter: &egui::Painter, at: Pos2) -> f32 {
        let Pos2 { x, y } = at;
        let font = egui::FontId::proportional(12.0);
        if let Some(m) = &self.view.mesh {
            let text = format!(
                "mesh edges: {} · {} elements · solve {:.2} s{}",
                m.label(),
                self.view.leaves.len(),
                m.solve_s,
                if m.meshing_s > 0.0 {
                    format!(" (meshing {:.0} ms)", m.meshing_s * 1e3)
                } else {
                    String::new()
                }
            );
            let galley = painter.layout_no_wrap(text, font, Color32::WHITE);
            let box_r = Rect::from_min_size(Pos2::new(x, y), galley.size() + Vec2::new(8.0, 4.0));
            painter.rect_filled(box_r, 4.0, LEGEND_BG);
            painter.galley(box_r.min + Vec2::new(4.0, 2.0), galley, Color32::WHITE);
            return box_r.bottom() + 6.0;
        }
        let max_depth = self.view.stats.depth_histogram.len().max(1);
        let shown = max_depth.min(12);
        let box_r =
            Rect::from_min_size(Pos2::new(x, y), Vec2::new((8.0 + 18.0 * shown as f32).max(100.0), 36.0));
        painter.rect_filled(box_r, 4.0, LEGEND_BG);
        painter.text(
            Pos2::new(x + 4.0, y + 2.0),
            egui::Align2::LEFT_TOP,
            "quadtree depth",
            font,
            Color32::WHITE,
        );
        for dpt in 0..shown {
            let c = overlay::depth_color(dpt as u8);
            let r = Rect::from_min_size(Pos2::new(x + 4.0 + 18.0 * dpt as f32, y + 18.0), Vec2::splat(14.0));
            painter.rect_filled(r, 2.0, rgb32(c));
            painter.text(
                r.center(),
                egui::Align2::CENTER_CENTER,
                dpt.to_string(),
                egui::FontId::proportional(9.0),
                if dpt == 0 { Color32::BLACK } else { Color32::WHITE },
            );
        }
        box_r.bottom() + 6.0
    }

    /// The links' legend at `at`: their F scale and how many are drawn, how they are drawn, and
    /// the cluster links' line; returns where the next legend goes.
    fn links_legend(&self, painter: &egui::Painter, at: Pos2) -> f32 {
        let Pos2 { x, mut y } = at;
        // With "picked element only", the links counted are the ones the picked element
        // gathers through: the inspector's table lists the same links.
        let whose = if self.display.selected_links_only && self.picked_cluster.is_none() {
            " the picked element gathers through"
        } else {
            ""
        };
        let title = format!(
            "links{whose}: F (log), {} of {} shown{}",
            self.link_stats.0,
            self.link_stats.1,
            match (self.link_stats.0 < self.link_stats.1, self.display.link_filter.decimation) {
                (false, _) => "",
                (true, Decimation::Strided) => " (every k-th)",
                (true, Decimation::LargestF) => " (largest F)",
            }
        );
        let bar = ColourBar { title: &title, scale: self.link_scale, palette: Palette::Viridis, unit: "" };
        y = bar.draw(painter, Pos2::new(x, y), None) + 6.0;
        painter.text(
            Pos2::new(x + 4.0, y),
            egui::Align2::LEFT_TOP,
            if self.display.links_xray {
                "x-ray: links drawn through surfaces"
            } else {
                "depth-tested, alpha-blended"
            },
            egui::FontId::proportional(10.0),
            Color32::LIGHT_GRAY,
        );
        y += 18.0;
        if let Some(note) =
            cluster_link_note(self.display, self.view, self.cluster_link_stats, self.picked_cluster)
        {
            let galley = painter.layout_no_wrap(note, egui::FontId::proportional(11.0), Color32::WHITE);
            let box_r = Rect::from_min_size(Pos2::new(x, y), galley.size() + Vec2::new(8.0, 4.0));
            painter.rect_filled(box_r, 4.0, LEGEND_BG);
            painter.galley(box_r.min + Vec2::new(4.0, 2.0), galley, Color32::WHITE);
            y = box_r.bottom() + 6.0;
        }
        y
    }

    /// The error heatmap's legend at `at`: its scale, and what its black foot stands for.
    fn error_legend(&self, painter: &egui::Painter, at: Pos2, what: &str) {
        let title = format!("error: {what} (log scale, ends at the 10th / 99th percentile)");
        let bar = ColourBar {
            title: &title,
            scale: self.error_scale,
            palette: Palette::Heat,
            unit: " (units of B)",
        };
        // The scale's foot is black: the lowest tenth, and the elements with no error.
        let floor = match self.error_scale {
            Some(s) => format!("black: at or below {:.1e}, or zero", s.lo),
            None => "black: zero (no error to show)".to_owned(),
        };
        bar.draw(painter, at, Some(&floor));
    }

    /// The note over the picture: why it is stale (framed), that there is nothing yet, what to
    /// do next on a scene only lit by its lamps, or why the split view shows one picture.
    fn note(&self, painter: &egui::Painter, rect: Rect) {
        if let Some(why) = &self.stale {
            painter.rect_stroke(
                rect.shrink(1.0),
                0.0,
                egui::Stroke::new(2.0, STALE),
                egui::StrokeKind::Inside,
            );
            bottom_note(painter, rect, why);
        } else if self.view.elements.is_empty() {
            let msg = if self.busy {
                "loading…"
            } else {
                "No scene. Open… a .gltf/.glb, drop one here, or type builtin:NAME above and press Load."
            };
            let font = egui::FontId::proportional(12.0);
            painter.text(rect.center(), egui::Align2::CENTER_CENTER, msg, font, Color32::LIGHT_GRAY);
        } else if self.view.links.is_empty() && !self.busy && self.view.mesh.is_none() {
            // A freshly loaded scene: only the lamps are lit. Say what to do next.
            bottom_note(
                painter,
                rect,
                "Only the lamps are lit: press Solve, or Refine step then Gather step to watch it converge.",
            );
        } else if self.split_on {
            bottom_note(painter, rect, SPLIT_NOTE);
        }
    }

    /// The artifact overlay's legend: what it shows, its numbers and what it was measured
    /// against (or that it is being measured, or why it cannot be); returns the bottom y.
    fn artifact_legend(&self, painter: &egui::Painter, at: Pos2, which: Artifact) -> f32 {
        let font = egui::FontId::proportional(12.0);
        let mut rows: Vec<(Option<[f32; 4]>, String)> = Vec::new();
        match self.artifacts {
            None => rows.push((None, format!("artifact {}: measuring…", which.name()))),
            Some(Err(e)) => rows.push((None, e.clone())),
            Some(Ok(m)) => {
                rows.push((None, format!("artifacts against {} ({:.1} s)", m.against, m.time_s)));
                let shown: Vec<Artifact> =
                    if which == Artifact::All { Artifact::ALL.to_vec() } else { vec![which] };
                for a in shown {
                    rows.push((Some(a.color()), a.summary(&m.report)));
                }
            }
        }
        let galleys: Vec<_> = rows
            .into_iter()
            .map(|(c, t)| (c, painter.layout_no_wrap(t, font.clone(), Color32::WHITE)))
            .collect();
        let w = galleys.iter().map(|(_, g)| g.size().x).fold(0.0, f32::max) + 36.0;
        let box_r = Rect::from_min_size(at, Vec2::new(w, 4.0 + 18.0 * galleys.len() as f32));
        painter.rect_filled(box_r, 4.0, Color32::from_black_alpha(170));
        for (i, (color, galley)) in galleys.into_iter().enumerate() {
            let top = at.y + 2.0 + 18.0 * i as f32;
            if let Some(c) = color {
                let swatch = Rect::from_min_size(Pos2::new(at.x + 6.0, top + 6.0), Vec2::new(18.0, 4.0));
                painter.rect_filled(swatch, 0.0, rgb32([c[0], c[1], c[2]]));
            }
            painter.galley(Pos2::new(at.x + 30.0, top), galley, Color32::WHITE);
        }
        box_r.bottom()
    }
}

/// Draw a highlight over the viewport `rect` seen through `view_proj` (positions relative to
/// `origin`): the elements' outlines and the link's line ([`overlay::highlight_lines`], not
/// depth-tested, so they show through surfaces) and a label naming them.
pub fn highlight(
    painter: &egui::Painter,
    rect: Rect,
    view: &ViewData,
    h: Highlight,
    view_proj: DMat4,
    origin: DVec3,
) {
    let lines = overlay::highlight_lines(&view.elements, h);
    if lines.points.is_empty() {
        return;
    }
    let vp = view_proj;
    let project = |p: DVec3| {
        let c = vp * (p - origin).extend(1.0);
        (c.w > 1e-9).then(|| {
            let (x, y) = ((c.x / c.w) as f32, (c.y / c.w) as f32);
            Pos2::new(
                rect.left() + (0.5 + 0.5 * x) * rect.width(),
                rect.top() + (0.5 - 0.5 * y) * rect.height(),
            )
        })
    };
    for (p, c) in lines.points.chunks_exact(2).zip(lines.colors.chunks_exact(2)) {
        if let (Some(a), Some(b)) = (project(p[0]), project(p[1])) {
            let [r, g, bl, al] = c[0].map(|x| (x.clamp(0.0, 1.0) * 255.0) as u8);
            painter
                .line_segment([a, b], egui::Stroke::new(2.0, Color32::from_rgba_unmultiplied(r, g, bl, al)));
        }
    }
    // The label sits in the viewport's lower-left corner, off the link's middle and the
    // outlines.
    let text = match h {
        Highlight::Link { receiver, source } => {
            let l = view.links.iter().find(|l| l.receiver == receiver && l.source == source);
            let fv = l.map_or(String::new(), |l| format!(" · F = {:.3e} · V = {:.2}", l.ff, l.vis));
            format!("receiver {receiver} (orange) gathers from source {source} (cyan){fv}")
        }
        Highlight::Element(id) => format!("element {id} (orange): its row and column in the matrix"),
    };
    let galley = painter.layout_no_wrap(text, egui::FontId::proportional(12.0), Color32::WHITE);
    let box_r = Rect::from_min_size(
        Pos2::new(rect.left() + 8.0, rect.bottom() - 56.0),
        galley.size() + Vec2::new(8.0, 4.0),
    );
    painter.rect_filled(box_r, 3.0, Color32::from_black_alpha(190));
    painter.galley(box_r.min + Vec2::new(4.0, 2.0), galley, Color32::WHITE);
}

/// The links legend's line on a clustered solve's cluster links: how many are drawn (dashed) of
/// how many there are, or why none are; `stats`: (drawn, carried ones that pass the filter) of
/// the geometry shown, when it drew them; `picked_cluster`: the cluster whose links "picked
/// element only" draws instead of the element's. `None` when the solve has no cluster links.
#[must_use]
pub fn cluster_link_note(
    d: &Display,
    view: &ViewData,
    stats: Option<(usize, usize)>,
    picked_cluster: Option<u32>,
) -> Option<String> {
    let total = view.stats.cluster_links;
    if total == 0 {
        return None;
    }
    Some(match stats {
        _ if !d.cluster_links => format!("cluster links: {total} (not drawn)"),
        None if view.cluster_links.is_empty() => format!("cluster links: {total} (none kept to draw)"),
        None => format!("cluster links: {total}"),
        Some((shown, matched)) if d.selected_links_only => {
            let kept = view.cluster_links.len();
            let whose =
                picked_cluster.map_or("the picked element's".to_owned(), |c| format!("cluster {c}'s"));
            format!("- - cluster links (dashed): {shown} drawn, {whose} ({matched} of {kept} kept)")
        }
        Some((shown, matched)) => {
            let mut s = format!("- - cluster links (dashed): {shown} drawn of {total}");
            if shown < total {
                let kept = view.cluster_links.len();
                s += &format!(" (largest F; {matched} of the {kept} kept pass the filter)");
            }
            s
        }
    })
}

/// The legends' boxes.
const LEGEND_BG: Color32 = Color32::from_black_alpha(170);

/// The frame around a stale picture (amber).
const STALE: Color32 = Color32::from_rgb(230, 170, 60);

/// What the viewport says while the split view is on but has fewer than two runs to show.
const SPLIT_NOTE: &str = "Split view: it needs two solved runs. Solve again with other settings \
                          (auto-run re-solves on every change), or pick runs in the View menu's Run \
                          history.";

/// A bottom note's text laid out for the viewport `rect`: wrapped 20 points inside each side.
fn note_galley(painter: &egui::Painter, rect: Rect, msg: &str) -> std::sync::Arc<egui::Galley> {
    let wrap = (rect.width() - 40.0).max(80.0);
    painter.layout(msg.to_owned(), egui::FontId::proportional(12.0), Color32::WHITE, wrap)
}

/// A note in a dark box at the bottom centre of the viewport, wrapped to its width (a narrow
/// split pane or window cuts no words off); its last line sits where a one-line note does.
fn bottom_note(painter: &egui::Painter, rect: Rect, msg: &str) {
    let galley = note_galley(painter, rect, msg);
    let size = galley.size() + Vec2::new(16.0, 8.0);
    let box_r =
        Rect::from_min_size(Pos2::new(rect.center().x - size.x / 2.0, rect.bottom() - 18.0 - size.y), size);
    painter.rect_filled(box_r, 4.0, Color32::from_black_alpha(170));
    painter.galley(box_r.min + Vec2::new(8.0, 4.0), galley, Color32::WHITE);
}

/// The critical edges' legend: a swatch and a count per kind; returns the bottom y.
fn critical_legend(painter: &egui::Painter, at: Pos2, c: crate::mesh::discontinuity::SegmentCounts) -> f32 {
    use crate::present::mesh_overlay::CRITICAL_COLORS;
    let font = egui::FontId::proportional(12.0);
    let rows = [
        (CRITICAL_COLORS[0], format!("D0 value jumps (contact): {}", c.d0)),
        (CRITICAL_COLORS[1], format!("D1 slope jumps: {}", c.d1)),
        (CRITICAL_COLORS[2], format!("D2 curvature jumps: {}", c.d2)),
    ];
    let box_r = Rect::from_min_size(at, Vec2::new(230.0, 20.0 + 18.0 * rows.len() as f32));
    painter.rect_filled(box_r, 4.0, Color32::from_black_alpha(170));
    painter.text(
        at + Vec2::new(4.0, 2.0),
        egui::Align2::LEFT_TOP,
        "critical edges",
        font.clone(),
        Color32::WHITE,
    );
    for (i, (color, text)) in rows.into_iter().enumerate() {
        let top = at.y + 20.0 + 18.0 * i as f32;
        let swatch = Rect::from_min_size(Pos2::new(at.x + 6.0, top + 6.0), Vec2::new(18.0, 4.0));
        painter.rect_filled(swatch, 0.0, rgb32([color[0], color[1], color[2]]));
        painter.text(Pos2::new(at.x + 30.0, top), egui::Align2::LEFT_TOP, text, font.clone(), Color32::WHITE);
    }
    box_r.bottom()
}

/// A horizontal colour bar with its title and end values.
struct ColourBar<'a> {
    title: &'a str,
    scale: Option<LogScale>,
    palette: Palette,
    /// Unit written after the top value.
    unit: &'a str,
}

impl ColourBar<'_> {
    /// Draw the bar at `at`, with a swatch of the palette's foot and `floor` saying what it
    /// stands for when given; returns the bottom y.
    fn draw(&self, painter: &egui::Painter, at: Pos2, floor: Option<&str>) -> f32 {
        let w = 200.0;
        let font = egui::FontId::proportional(11.0);
        let galley = painter.layout_no_wrap(self.title.to_owned(), font.clone(), Color32::WHITE);
        let floor_h = if floor.is_some() { 16.0 } else { 0.0 };
        let box_r = Rect::from_min_size(at, Vec2::new(galley.size().x.max(w) + 8.0, 50.0 + floor_h));
        painter.rect_filled(box_r, 4.0, Color32::from_black_alpha(170));
        painter.galley(at + Vec2::new(4.0, 2.0), galley, Color32::WHITE);
        let bar_y = at.y + 18.0;
        let n = 64;
        for i in 0..n {
            let t = i as f64 / f64::from(n - 1);
            let r = Rect::from_min_size(
                Pos2::new(at.x + 4.0 + w * i as f32 / n as f32, bar_y),
                Vec2::new(w / n as f32 + 0.5, 12.0),
            );
            painter.rect_filled(r, 0.0, rgb32(self.palette.at(t)));
        }
        let (lo, hi) = self.scale.map_or(("–".to_owned(), "–".to_owned()), |s| {
            (format!("{:.1e}", s.lo), format!("{:.1e}{}", s.hi, self.unit))
        });
        painter.text(
            Pos2::new(at.x + 4.0, bar_y + 14.0),
            egui::Align2::LEFT_TOP,
            lo,
            font.clone(),
            Color32::WHITE,
        );
        painter.text(
            Pos2::new(at.x + 4.0 + w, bar_y + 14.0),
            egui::Align2::RIGHT_TOP,
            hi,
            font.clone(),
            Color32::WHITE,
        );
        if let Some(text) = floor {
            let y = bar_y + 31.0;
            let swatch = Rect::from_min_size(Pos2::new(at.x + 4.0, y + 1.0), Vec2::new(12.0, 10.0));
            painter.rect_filled(swatch, 0.0, rgb32(self.palette.at(0.0)));
            painter.rect_stroke(swatch, 0.0, (1.0, Color32::GRAY), egui::StrokeKind::Outside);
            painter.text(
                Pos2::new(swatch.right() + 6.0, y),
                egui::Align2::LEFT_TOP,
                text,
                font,
                Color32::WHITE,
            );
        }
        box_r.bottom()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The split view's note used to be one line wider than a 600-point viewport (cut off at
    /// both ends); it wraps to the viewport's width now.
    #[test]
    fn the_split_views_note_wraps_inside_a_narrow_viewport() {
        let ctx = egui::Context::default();
        let rect = Rect::from_min_size(Pos2::ZERO, Vec2::new(560.0, 400.0));
        let (mut wrapped, mut one_line) = (Vec2::ZERO, Vec2::ZERO);
        let mut out = ctx.run_ui(egui::RawInput::default(), |ui| {
            let painter = ui.painter().clone();
            wrapped = note_galley(&painter, rect, SPLIT_NOTE).size();
            one_line = painter
                .layout_no_wrap(SPLIT_NOTE.to_owned(), egui::FontId::proportional(12.0), Color32::WHITE)
                .size();
        });
        out.textures_delta.clear();
        assert!(one_line.x > rect.width(), "the note is longer than the viewport: {one_line:?}");
        assert!(wrapped.x + 16.0 <= rect.width(), "its box fits: {wrapped:?}");
        assert!(wrapped.y > 1.5 * one_line.y, "on two lines or more: {wrapped:?}");
    }
}
