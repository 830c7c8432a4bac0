//! A cluster of a clustered solve, picked: which cluster a click picks, the walk
//! up and down the cluster tree from the picked element, and the inspector's section on the
//! picked cluster — its depth, patches, area, box and the cluster links it holds.
//!
//! A click picks an element; while the cluster boxes are drawn it picks the cluster around
//! that element's patch too, at the levels shown: the smallest cluster holding the patch whose
//! depth is at most the deepest level drawn. From there "up" walks to the parent and "down"
//! back down the same chain towards the element:
//!
//! ```text
//!   root (depth 0) ─ … ─ cluster (depth d) ─ … ─ smallest cluster of the patch ─ patch ─ element
//!                    up: parent            down: child towards the element
//! ```
//!
//! Everything is read from the solver's read-only views carried in [`ViewData`] (`clusters`,
//! `patch_cluster`, `cluster_links`); nothing here changes the solver.

use super::view::View;
use super::widgets::grid_row;
use super::worker::ViewData;
use crate::scene::Scene;
use crate::solver::hierarchical::ClusterEnd;
use eframe::egui;
use std::sync::Arc;

/// The clusters holding input patch `patch`, smallest first, up to the root (indices into
/// `view.clusters`; empty when the solve does not cluster).
#[must_use]
pub fn chain(view: &ViewData, patch: u32) -> Vec<u32> {
    let mut out = Vec::new();
    let mut at = view.patch_cluster.get(patch as usize).copied().filter(|&c| c != u32::MAX);
    while let Some(i) = at {
        out.push(i);
        at = view.clusters.get(i as usize).and_then(|c| c.parent);
    }
    out
}

/// The clusters holding `element`'s patch, smallest first (empty: no such element, or no
/// clusters).
#[must_use]
pub fn chain_of_element(view: &ViewData, element: u32) -> Vec<u32> {
    view.elements.get(element as usize).map_or_else(Vec::new, |e| chain(view, e.patch))
}

/// The cluster a click on `element` picks while the boxes down to depth `deepest` are drawn:
/// the smallest cluster holding its patch whose depth is at most `deepest` (the smallest box
/// drawn around it, when its depth is among those drawn).
#[must_use]
pub fn at_shown_level(view: &ViewData, element: u32, deepest: u8) -> Option<u32> {
    chain_of_element(view, element).into_iter().find(|&c| view.clusters[c as usize].depth <= deepest)
}

/// The cluster one level below `cluster` on the way to `element` (`None`: `cluster` is the
/// smallest holding the element's patch, or does not hold it).
#[must_use]
pub fn child_towards(view: &ViewData, element: u32, cluster: u32) -> Option<u32> {
    let chain = chain_of_element(view, element);
    let at = chain.iter().position(|&c| c == cluster)?;
    at.checked_sub(1).map(|i| chain[i])
}

/// The input patches in `cluster` (those whose chain passes through it), in patch order.
#[must_use]
pub fn members(view: &ViewData, cluster: u32) -> Vec<u32> {
    let Some(depth) = view.clusters.get(cluster as usize).map(|c| c.depth) else { return Vec::new() };
    (0..view.patch_cluster.len() as u32)
        .filter(|&p| {
            let mut at = view.patch_cluster[p as usize];
            // Depths fall towards the root: stop at the picked cluster's depth.
            while let Some(c) = view.clusters.get(at as usize).filter(|c| c.depth >= depth) {
                if at == cluster {
                    return true;
                }
                at = c.parent.unwrap_or(u32::MAX);
            }
            false
        })
        .collect()
}

/// A cluster end in words: "cluster 12 (depth 3)" or "patch 7".
#[must_use]
pub fn end_label(view: &ViewData, end: ClusterEnd) -> String {
    match end {
        ClusterEnd::Cluster(i) => match view.clusters.get(i as usize) {
            Some(c) => format!("cluster {i} (depth {})", c.depth),
            None => format!("cluster {i}"),
        },
        ClusterEnd::Patch(p) => format!("patch {p}"),
    }
}

/// The inspector's first line on a picked cluster (tests look for it).
#[must_use]
pub fn title(view: &ViewData, cluster: u32) -> String {
    let c = &view.clusters[cluster as usize];
    format!("Cluster {cluster}: depth {}, {} patches", c.depth, c.patches)
}

/// What the picked cluster's section works out once per solution and cluster.
#[derive(Clone, Debug)]
struct Summary {
    /// Its patches (counted from `patch_cluster`) and their total area (without a scene: none).
    patches: usize,
    area: Option<f64>,
    /// The kept cluster links with the cluster at one end: the other end, F, V (largest F
    /// first, as kept).
    links: Vec<(ClusterEnd, f64, f32)>,
}

/// The inspector's section on the picked cluster, with its cached summary.
#[derive(Clone, Debug, Default)]
pub struct ClusterSection {
    cache: Option<(Arc<ViewData>, u32, Arc<Summary>)>,
}

/// What the cluster section is lent for one frame.
pub struct ClusterInput<'a> {
    pub view: &'a Arc<ViewData>,
    /// The picked cluster (an index into `view.clusters`) and the element it was reached from.
    pub cluster: u32,
    pub element: u32,
    pub scene: Option<&'a Scene>,
    /// "Picked element only": draw only the picked cluster's links.
    pub selected_links_only: &'a mut bool,
}

/// What the cluster section asks: pick this cluster instead (`None`: the element alone).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct PickCluster(pub Option<u32>);

impl ClusterSection {
    fn summary(&mut self, view: &Arc<ViewData>, cluster: u32, scene: Option<&Scene>) -> Arc<Summary> {
        if let Some((v, c, s)) = &self.cache
            && Arc::ptr_eq(v, view)
            && *c == cluster
        {
            return Arc::clone(s);
        }
        let members = members(view, cluster);
        let area =
            scene.map(|s| members.iter().filter_map(|&p| s.patches.get(p as usize)).map(|p| p.area).sum());
        let me = ClusterEnd::Cluster(cluster);
        let links = view
            .cluster_links
            .iter()
            .filter_map(|l| match l.ends {
                [a, b] if a == me => Some((b, l.ff, l.vis)),
                [a, b] if b == me => Some((a, l.ff, l.vis)),
                _ => None,
            })
            .collect();
        let s = Arc::new(Summary { patches: members.len(), area, links });
        self.cache = Some((Arc::clone(view), cluster, Arc::clone(&s)));
        s
    }
}

impl View for ClusterSection {
    type Input<'a> = ClusterInput<'a>;
    type Action = PickCluster;

    fn ui(&mut self, ui: &mut egui::Ui, input: ClusterInput<'_>) -> Option<PickCluster> {
        let ClusterInput { view, cluster, element, scene, selected_links_only } = input;
        let info = *view.clusters.get(cluster as usize)?;
        let s = self.summary(view, cluster, scene);
        let mut action = None;
        ui.strong(title(view, cluster));
        egui::Grid::new("picked cluster").num_columns(2).striped(true).show(ui, |ui| {
            grid_row(ui, "patches", format!("{} (counted: {})", info.patches, s.patches));
            if let Some(a) = s.area {
                grid_row(ui, "area", format!("{a:.4e}"));
            }
            let size = info.bmax - info.bmin;
            grid_row(ui, "box", format!("{:.3} × {:.3} × {:.3}", size.x, size.y, size.z));
            grid_row(ui, "cluster links", info.links.to_string());
            grid_row(ui, "kept to draw", format!("{} of its {}", s.links.len(), info.links));
            grid_row(
                ui,
                "parent",
                info.parent.map_or("none (the root)".to_owned(), |p| format!("cluster {p}")),
            );
        });
        ui.horizontal(|ui| {
            let parent = info.parent;
            if ui
                .add_enabled(parent.is_some(), egui::Button::new("up: parent"))
                .on_hover_text("Pick the cluster one level up")
                .clicked()
            {
                action = Some(PickCluster(parent));
            }
            let child = child_towards(view, element, cluster);
            if ui
                .add_enabled(child.is_some(), egui::Button::new("down: child"))
                .on_hover_text("Pick the cluster one level down, towards the picked element")
                .clicked()
            {
                action = Some(PickCluster(child));
            }
            if ui.button("to element").on_hover_text("Drop the cluster: the picked element alone").clicked() {
                action = Some(PickCluster(None));
            }
        });
        ui.checkbox(selected_links_only, "show its cluster links in the viewport")
            .on_hover_text("Draw only this cluster's cluster links (of those kept to draw)");
        egui::ScrollArea::vertical().max_height(160.0).id_salt("cluster links").show(ui, |ui| {
            egui::Grid::new("cluster link rows").num_columns(3).striped(true).show(ui, |ui| {
                for h in ["other end", "F", "V"] {
                    ui.strong(h);
                }
                ui.end_row();
                for &(other, ff, vis) in s.links.iter().take(200) {
                    ui.monospace(end_label(view, other));
                    ui.monospace(format!("{ff:.3e}"));
                    ui.monospace(format!("{vis:.2}"));
                    ui.end_row();
                }
            });
        });
        action
    }
}
