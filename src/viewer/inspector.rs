//! The inspector (right panel): the errors so far, then the picked cluster when there is one
//! ([`super::clusters`]), then the picked element — its numbers, the clusters above its patch
//! (each can be picked), and the links it gathers through (its own and its ancestors'), largest
//! B·F·V first.

use super::clusters::{ClusterInput, ClusterSection, PickCluster};
use super::history::Ruler;
use super::view::View;
use super::widgets::{grid_row, rgb_text};
use super::worker::{Estimates, ViewData};
use crate::present::overlay;
use crate::scene::Scene;
use eframe::egui::{self, Color32};
use std::sync::Arc;

/// One row of the inspector's link table: (receiver, source, F, V, B·F·V).
type LinkRow = (u32, u32, f32, f32, f64);

/// Rows of the link table listed (the strongest by B·F·V).
pub const TABLE_ROWS: usize = 200;

/// The inspector and its cached link table.
#[derive(Clone, Debug, Default)]
pub struct Inspector {
    /// (solution, element, rows): computed once per solution and element, not every frame.
    rows: Option<(Arc<ViewData>, u32, Arc<Vec<LinkRow>>)>,
    /// The picked cluster's section.
    cluster: ClusterSection,
}

/// What the inspector is lent for one frame.
pub struct InspectorInput<'a> {
    /// Errors shown above the inspector (a "clear" button empties the list).
    pub errors: &'a mut Vec<String>,
    /// The picked element and the solution it is an element of.
    pub picked: Option<(u32, &'a Arc<ViewData>)>,
    /// The picked cluster (an index into the picked solution's clusters), if any.
    pub cluster: Option<u32>,
    pub scene: Option<&'a Scene>,
    /// Per-element true error against the reference, when it belongs to the picked solution.
    pub true_error: Option<&'a [f64]>,
    /// What the true error is measured against.
    pub ruler: Ruler,
    /// "show these links in the viewport".
    pub selected_links_only: &'a mut bool,
}

/// What the error heatmap and the inspector's error show: the true error against the reference
/// or the closed form (`true_error`), else the solver's estimate.
#[must_use]
pub fn error_label(true_error: Option<Ruler>) -> &'static str {
    match true_error {
        Some(Ruler::Reference) => "true error |B − B_ref|",
        Some(Ruler::ClosedForm) => "true error |B − B_exact| (vs closed form)",
        None => "solver's error estimate",
    }
}

impl View for Inspector {
    type Input<'a> = InspectorInput<'a>;
    type Action = PickCluster;

    fn ui(&mut self, ui: &mut egui::Ui, input: InspectorInput<'_>) -> Option<PickCluster> {
        let InspectorInput { errors, picked, cluster, scene, true_error, ruler, selected_links_only } = input;
        errors_section(ui, errors);
        ui.heading("Inspect");
        let Some((id, v)) = picked else {
            ui.label("Click an element in the viewport.");
            return None;
        };
        let e = v.elements.get(id as usize)?;
        let mut action = None;
        if let Some(c) = cluster {
            let input = ClusterInput { view: v, cluster: c, element: id, scene, selected_links_only };
            action = self.cluster.ui(ui, input);
            ui.separator();
        }
        let error = match true_error {
            Some(t) => t.get(id as usize).copied().unwrap_or(0.0),
            None => e.error_estimate,
        };
        let err_label = error_label(true_error.map(|_| ruler));
        egui::Grid::new("element").num_columns(2).striped(true).show(ui, |ui| {
            grid_row(ui, "element", format!("{} (patch {})", e.id, e.patch));
            if let Some(p) = scene.and_then(|s| s.patches.get(e.patch as usize)) {
                grid_row(ui, "patch name", p.name.clone());
            }
            grid_row(ui, "depth", e.depth.to_string());
            grid_row(ui, "area", format!("{:.4e}", e.area));
            grid_row(ui, "E", rgb_text(e.emission));
            grid_row(ui, "ρ", rgb_text(e.reflectance));
            grid_row(ui, "B", rgb_text(e.radiosity));
            if v.mesh.is_some() && true_error.is_none() {
                grid_row(ui, "error", "none (a mesh solve has no estimate)".to_owned());
            } else if v.estimates != Estimates::Included && true_error.is_none() {
                let not_yet = if v.estimates_pending() { "estimating…" } else { "not estimated" };
                grid_row(ui, "error", format!("{not_yet} ({err_label})"));
            } else {
                grid_row(ui, "error", format!("{error:.3e} ({err_label})"));
            }
            grid_row(ui, "stopped", e.stop.to_owned());
        });
        if let Some(pick) = patch_clusters(ui, v, e.patch, cluster) {
            action = Some(pick);
        }
        ui.separator();
        if let Some(m) = &v.mesh {
            ui.label(format!(
                "{}: no links — this element is coupled to every element it sees ({} form-factor \
                 entries in all).",
                m.label(),
                v.stats.links
            ));
            return action;
        }
        let rows = self.link_rows(v, id);
        link_table(ui, &rows, id);
        if cluster.is_none() {
            ui.checkbox(selected_links_only, "show these links in the viewport")
                .on_hover_text("Draw only these links, from the element and its ancestors");
        }
        action
    }
}

impl Inspector {
    /// The links through which element `id` of `v` gathers: its own and its ancestors', largest
    /// B·F·V first (computed once per solver state and element, not every frame).
    fn link_rows(&mut self, v: &Arc<ViewData>, id: u32) -> Arc<Vec<LinkRow>> {
        match &self.rows {
            Some((seen, sel, rows)) if Arc::ptr_eq(seen, v) && *sel == id => Arc::clone(rows),
            _ => {
                let chain = overlay::ancestors(&v.elements, id);
                let mut rows: Vec<LinkRow> = v
                    .links
                    .iter()
                    .filter(|l| chain.contains(&l.receiver))
                    .map(|l| {
                        let b = v.elements.get(l.source as usize).map_or(0.0, |s| s.radiosity.mean());
                        (l.receiver, l.source, l.ff, l.vis, b * f64::from(l.ff) * f64::from(l.vis))
                    })
                    .collect();
                rows.sort_by(|a, b| b.4.total_cmp(&a.4).then(a.1.cmp(&b.1)));
                let rows = Arc::new(rows);
                self.rows = Some((Arc::clone(v), id, Arc::clone(&rows)));
                rows
            }
        }
    }
}

/// The errors so far, newest first (five at most), with a button that forgets them.
fn errors_section(ui: &mut egui::Ui, errors: &mut Vec<String>) {
    if errors.is_empty() {
        return;
    }
    ui.colored_label(Color32::from_rgb(255, 110, 90), "Errors");
    for e in errors.iter().rev().take(5) {
        ui.label(egui::RichText::new(e).color(Color32::from_rgb(255, 150, 130)));
    }
    if ui.small_button("clear").on_hover_text("Forget these errors").clicked() {
        errors.clear();
    }
    ui.separator();
}

/// Clustered solves: the clusters holding `patch`, smallest first, each with a button that
/// picks it (`picked`: the cluster picked now). Answers the cluster picked this frame. (A patch
/// that is the whole tree, a one-patch scene, has no cluster: u32::MAX.)
fn patch_clusters(ui: &mut egui::Ui, v: &ViewData, patch: u32, picked: Option<u32>) -> Option<PickCluster> {
    let &first = v.patch_cluster.get(patch as usize).filter(|&&c| c != u32::MAX)?;
    let mut chain = Vec::new();
    let mut at = Some(first);
    while let Some((i, c)) = at.and_then(|i| v.clusters.get(i as usize).map(|c| (i, c))) {
        chain.push((i, *c));
        at = c.parent;
    }
    let cluster_links: u32 = chain.iter().map(|(_, c)| c.links).sum();
    let mut action = None;
    egui::CollapsingHeader::new(format!("in {} clusters · {cluster_links} cluster links", chain.len()))
        .id_salt("clusters of the patch")
        .show(ui, |ui| {
            egui::Grid::new("clusters").num_columns(4).striped(true).show(ui, |ui| {
                for h in ["depth", "patches", "cluster links", ""] {
                    ui.strong(h);
                }
                ui.end_row();
                for &(i, c) in &chain {
                    ui.monospace(c.depth.to_string());
                    ui.monospace(c.patches.to_string());
                    ui.monospace(c.links.to_string());
                    if ui
                        .selectable_label(picked == Some(i), "pick")
                        .on_hover_text(format!("Pick cluster {i}: its box, numbers and links"))
                        .clicked()
                    {
                        action = Some(PickCluster(Some(i)));
                    }
                    ui.end_row();
                }
            });
        })
        .header_response
        .on_hover_text(
            "The cluster tree above this element's patch, from the smallest cluster up to \
                 the root: how many patches each holds and how many cluster links it has (the \
                 header sums them); pick one to see its box and its links",
        );
    action
}

/// The link table of element `id`: a line that counts its links (the blocked ones too), then
/// the strongest [`TABLE_ROWS`] of `rows`.
fn link_table(ui: &mut egui::Ui, rows: &[LinkRow], id: u32) {
    // The same links the viewport draws for this element ("picked element only"), less the
    // links filter's (by default the blocked ones, V = 0, which carry no light).
    let blocked = rows.iter().filter(|r| r.3 <= overlay::VIS_CLASS_EPS).count();
    let blocked = if blocked > 0 { format!(", {blocked} of them blocked (V = 0)") } else { String::new() };
    // The table lists the strongest TABLE_ROWS; the line says so when there are more.
    let listed = if rows.len() > TABLE_ROWS {
        format!(" ({TABLE_ROWS} of {} shown)", rows.len())
    } else {
        String::new()
    };
    ui.label(format!("{} links gathered through (own + ancestors'){blocked}, by B·F·V{listed}:", rows.len()))
        .on_hover_text(
            "The links this element gathers through: its own and its ancestors'. The viewport \
                 draws the same links with \"show these links\" (the links filter's visibility \
                 classes apply: blocked links are hidden unless \"none\" is ticked)",
        );
    egui::ScrollArea::both().max_height(220.0).auto_shrink([false, true]).id_salt("links").show(ui, |ui| {
        egui::Grid::new("links").num_columns(5).striped(true).show(ui, |ui| {
            for h in ["at", "source", "F", "V", "B·F·V"] {
                ui.strong(h);
            }
            ui.end_row();
            for (r, s, f, vis, c) in rows.iter().take(TABLE_ROWS) {
                ui.monospace(if *r == id { "self".to_owned() } else { format!("↑{r}") });
                ui.monospace(s.to_string());
                ui.monospace(format!("{f:.3e}"));
                ui.monospace(format!("{vis:.2}"));
                ui.monospace(format!("{c:.3e}"));
                ui.end_row();
            }
        });
    });
}
