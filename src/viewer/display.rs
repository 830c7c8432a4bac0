//! What is shown, as data ([`Display`]: shading, exposure, overlays; no solver state), and the
//! side panel's Display and Overlays sections that edit it ([`DisplayPanel`]).

use super::view::View;
use super::widgets::log_slider;
use super::worker::{CLUSTER_LINKS_KEPT, ViewData};
use crate::present::mesh_overlay::Artifact;
use crate::present::overlay::{Decimation, LinkFilter};
use crate::solver::meshed::DisplayReconstruction;
use eframe::egui;

/// Levels of the cluster tree the clusters overlay draws at once.
pub const CLUSTER_LEVELS: u8 = 3;

/// Shading of the radiosity mesh (the display reconstruction).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Shading {
    Flat,
    /// Gouraud from vertex averages.
    Smooth,
    /// The element's own function, what the solver computed and the rulers score: a p = 1
    /// solve's vertex values, or a leaf's value with its slope; else its constant.
    Nodal,
}

impl Shading {
    /// The shading that draws a display reconstruction.
    #[must_use]
    pub fn of(r: DisplayReconstruction) -> Shading {
        match r {
            DisplayReconstruction::Flat => Shading::Flat,
            DisplayReconstruction::Gouraud => Shading::Smooth,
            DisplayReconstruction::Nodal => Shading::Nodal,
        }
    }
}

/// What is shown (no solver state).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Display {
    pub shading: Shading,
    /// Exposure in stops: radiosity × 2^EV before tone mapping.
    pub exposure_ev: f32,
    /// Set the exposure from the solution after every step (see [`super::builder::auto_exposure`]).
    pub auto_exposure: bool,
    pub srgb: bool,
    pub quadtree: bool,
    pub links: bool,
    pub error: bool,
    /// The critical edges: every receiver's D0/D1/D2 segments, coloured by kind.
    pub critical: bool,
    /// An artifact overlay (measured against the best reference there is).
    pub artifact: Option<Artifact>,
    /// The cluster tree's bounding boxes, from depth `clusters_from` down `CLUSTER_LEVELS` levels.
    pub clusters: bool,
    pub clusters_from: u8,
    pub link_filter: LinkFilter,
    /// With the links overlay, a clustered solve's cluster links too (dashed).
    pub cluster_links: bool,
    /// Links of the picked element only.
    pub selected_links_only: bool,
    pub links_xray: bool,
    pub link_alpha: f32,
}

impl Default for Display {
    fn default() -> Self {
        Display {
            shading: Shading::Nodal,
            exposure_ev: 0.0,
            auto_exposure: true,
            srgb: true,
            quadtree: false,
            links: false,
            error: false,
            critical: false,
            artifact: None,
            clusters: false,
            clusters_from: 0,
            link_filter: LinkFilter::default(),
            cluster_links: true,
            selected_links_only: false,
            links_xray: false,
            link_alpha: 0.35,
        }
    }
}

/// The artifact overlay after `a` in the order the A key steps through: none, each of the
/// five, all five, none again.
#[must_use]
pub fn next_artifact(a: Option<Artifact>) -> Option<Artifact> {
    let order: Vec<Option<Artifact>> =
        std::iter::once(None).chain(Artifact::ALL.map(Some)).chain([Some(Artifact::All)]).collect();
    let at = order.iter().position(|&o| o == a).unwrap_or(0);
    order[(at + 1) % order.len()]
}

/// The artifact overlay's box (none, one of the five, all).
fn artifact_box(ui: &mut egui::Ui, d: &mut Display) {
    egui::ComboBox::from_label("artifact")
        .width(ARTIFACT_BOX_W)
        .selected_text(d.artifact.map_or("none", Artifact::name))
        .show_ui(ui, |ui| {
            ui.selectable_value(&mut d.artifact, None, "none").on_hover_text("No artifact overlay");
            for a in Artifact::ALL.into_iter().chain([Artifact::All]) {
                ui.selectable_value(&mut d.artifact, Some(a), a.name()).on_hover_text(a.description());
            }
        })
        .response
        .on_hover_text(
            "The lecture's five meshing artifacts, where they are: measured against the closed \
             form (single-bounce scenes) or the scene's reference, on a background thread (A \
             steps through them)",
        );
}

/// Width of the artifact box (beside the Overlays heading).
const ARTIFACT_BOX_W: f32 = 110.0;

/// Width of the cluster depth slider (beside the clusters box).
const CLUSTER_SLIDER_W: f32 = 64.0;

/// What the Display and Overlays sections are lent for one frame.
pub struct DisplayInput<'a> {
    /// The settings edited.
    pub display: &'a mut Display,
    /// The solver state shown (a mesh solve or the quadtree's; p = 1 values; clusters).
    pub view: &'a ViewData,
    /// The error heatmap has something to show ([`super::RadlabApp::error_applies`]).
    pub error_applies: bool,
}

/// The side panel's Display and Overlays sections (shading, exposure, tone map; quadtree or
/// mesh edges, links and their filter, error heatmap, artifacts, critical edges, clusters).
#[derive(Copy, Clone, Debug, Default)]
pub struct DisplayPanel;

impl View for DisplayPanel {
    type Input<'a> = DisplayInput<'a>;
    type Action = ();

    fn ui(&mut self, ui: &mut egui::Ui, input: DisplayInput<'_>) -> Option<()> {
        let DisplayInput { display: d, view, error_applies } = input;
        let mesh_view = view.mesh.is_some();
        display_section(ui, d);
        ui.separator();
        ui.horizontal(|ui| {
            ui.heading("Overlays");
            ui.add_space(8.0);
            artifact_box(ui, d);
        });
        main_overlays_row(ui, d, mesh_view, error_applies);
        if !mesh_view && (d.links || d.selected_links_only) {
            ui.indent("links", |ui| link_options(ui, d, view));
        }
        ui.checkbox(&mut d.critical, "critical edges (D0/D1/D2)").on_hover_text(
            "Where the radiosity is discontinuous: D0 where surfaces touch (a jump in value), D1 / D2 \
             where a shadow's umbra or penumbra begins (a jump in the first / second derivative), \
             from the emitters' EV and VE events; on any mesh (D)",
        );
        clusters_row(ui, d, view);
        None
    }
}

/// The Display section: shading (its heading's row), exposure, tone map.
fn display_section(ui: &mut egui::Ui, d: &mut Display) {
    // Headings share their row with the section's first control, and the three main overlays
    // share one: the side panel fits a 1280 × 800 screen unscrolled with a caption open.
    ui.horizontal(|ui| {
        ui.heading("Display");
        ui.add_space(8.0);
        ui.selectable_value(&mut d.shading, Shading::Nodal, "solved").on_hover_text(
            "Each element's own function, what the solver computed and the rulers score: its \
             value with its slope (the hierarchical solver's leaves), its p = 1 vertex values \
             (a Galerkin solve), else its constant",
        );
        ui.selectable_value(&mut d.shading, Shading::Flat, "flat")
            .on_hover_text("Each element one colour (its average): the mesh's resolution shows");
        ui.selectable_value(&mut d.shading, Shading::Smooth, "Gouraud").on_hover_text(
            "Gouraud from vertex averages, what most systems show; T-vertices take their big \
             neighbour's edge value",
        );
    });
    // One row each for exposure and tone map: the side panel fits a lecture screen unscrolled.
    ui.horizontal(|ui| {
        let ev = ui
            .add(egui::Slider::new(&mut d.exposure_ev, -12.0..=12.0).step_by(0.1).text("EV"))
            .on_hover_text(
                "Exposure: radiosity × 2^EV before tone mapping; moving it turns auto exposure off",
            );
        if ev.changed() {
            d.auto_exposure = false;
        }
        ui.checkbox(&mut d.auto_exposure, "auto").on_hover_text(
            "Auto exposure: map the 95th percentile of the lit surfaces' radiosity to 80 % white",
        );
    });
    ui.horizontal(|ui| {
        ui.label("tone map");
        ui.selectable_value(&mut d.srgb, true, "sRGB").on_hover_text("Display values sRGB-encoded");
        ui.selectable_value(&mut d.srgb, false, "linear")
            .on_hover_text("Radiosity shown as is, clamped at 1 (dark mid-tones)");
        ui.label(egui::RichText::new("back faces: magenta").small().weak())
            .on_hover_text("Back faces are drawn in striped magenta");
    });
}

/// The three main overlays' row: quadtree (or mesh edges), links, error heatmap.
fn main_overlays_row(ui: &mut egui::Ui, d: &mut Display, mesh_view: bool, error_applies: bool) {
    ui.horizontal(|ui| {
        if mesh_view {
            ui.checkbox(&mut d.quadtree, "mesh edges").on_hover_text("The elements' edges; depth-tested (Q)");
        } else {
            ui.checkbox(&mut d.quadtree, "quadtree")
                .on_hover_text("Leaf edges coloured by depth; depth-tested (Q)");
        }
        ui.add_enabled(!mesh_view, egui::Checkbox::new(&mut d.links, "links"))
            .on_hover_text("Element-centre lines coloured by log F (L)")
            .on_disabled_hover_text(
                "A mesh solve keeps no links: every pair of its elements is coupled (n² interactions)",
            );
        ui.add_enabled(error_applies, egui::Checkbox::new(&mut d.error, "error heatmap"))
            .on_hover_text("Per-element error on a log colour scale (E)")
            .on_disabled_hover_text(if mesh_view {
                "A mesh solve has no error estimate of its own: Compute reference (above) gives \
                 the true error, then the heatmap shows it"
            } else {
                "The solver's error estimates of this state were given up (a newer command came \
                 first): Solve again, or Compute reference (above) for the true error"
            });
    });
}

/// Under the links overlay: the picked element's links only, the cluster links, and the
/// folded filter.
fn link_options(ui: &mut egui::Ui, d: &mut Display, view: &ViewData) {
    ui.checkbox(&mut d.selected_links_only, "picked element only")
        .on_hover_text("Only the links the picked element gathers through (click an element)");
    let clustered = view.stats.cluster_links > 0;
    ui.add_enabled(clustered, egui::Checkbox::new(&mut d.cluster_links, "cluster links (dashed)"))
        .on_hover_text(format!(
            "Also the links between clusters (or a cluster and a patch), dashed between \
                 the two ends' centres, coloured by F on the same scale: {} in this solve, \
                 the {CLUSTER_LINKS_KEPT} with the largest F kept for drawing, at most \
                 \"max lines\" of them drawn; with \"picked element only\", those of the \
                 picked element's patch and of the clusters holding it",
            view.stats.cluster_links
        ))
        .on_disabled_hover_text("This solve does not cluster: it has no cluster links");
    // Folded by default: the filter's eight controls would push the panel past the screen; its
    // header says what it holds.
    egui::CollapsingHeader::new("filter, sample, opacity")
        .id_salt("link filter")
        .default_open(false)
        .show(ui, |ui| link_filter(ui, d))
        .header_response
        .on_hover_text(
            "Which links are drawn (minimum F, visibility classes), how many (max lines \
             and the sample beyond them) and how (opacity, x-ray)",
        );
}

/// The links filter: minimum F, visibility classes, max lines and the sample beyond them,
/// opacity, x-ray.
fn link_filter(ui: &mut egui::Ui, d: &mut Display) {
    let mut min_ff = f64::from(d.link_filter.min_ff).max(1e-9);
    log_slider(ui, "min F", &mut min_ff, 1e-9, 1.0, "Hide links with a smaller form factor");
    d.link_filter.min_ff = if min_ff <= 1e-9 { 0.0 } else { min_ff as f32 };
    ui.horizontal(|ui| {
        ui.label("visibility");
        ui.checkbox(&mut d.link_filter.full, "full").on_hover_text("Links whose shadow rays all passed");
        ui.checkbox(&mut d.link_filter.partial, "partial")
            .on_hover_text("Links whose shadow rays were partly blocked: the penumbra's");
        ui.checkbox(&mut d.link_filter.none, "none")
            .on_hover_text("Links whose shadow rays were all blocked (they carry no light)");
    });
    ui.add(
        egui::Slider::new(&mut d.link_filter.max_lines, 100..=200_000).logarithmic(true).text("max lines"),
    )
    .on_hover_text("Decimation: beyond this many, a sample is drawn");
    ui.horizontal(|ui| {
        ui.label("sample");
        ui.selectable_value(&mut d.link_filter.decimation, Decimation::Strided, "every k-th")
            .on_hover_text("An even sample of the links");
        ui.selectable_value(&mut d.link_filter.decimation, Decimation::LargestF, "largest F")
            .on_hover_text("The links with the largest form factors");
    });
    ui.add(egui::Slider::new(&mut d.link_alpha, 0.05..=1.0).text("opacity"))
        .on_hover_text("Opacity of the link lines");
    ui.checkbox(&mut d.links_xray, "x-ray (no depth test)")
        .on_hover_text("Draw links through surfaces instead of hiding those behind them");
}

/// The clusters overlay's row (greyed out when the solve does not cluster): the box and the
/// shallowest level drawn.
fn clusters_row(ui: &mut egui::Ui, d: &mut Display, view: &ViewData) {
    let max_depth = view.clusters.iter().map(|c| c.depth).max();
    ui.add_enabled_ui(max_depth.is_some(), |ui| {
        ui.horizontal(|ui| {
            ui.checkbox(&mut d.clusters, "clusters").on_hover_text(format!(
                "The cluster tree above the input patches: bounding boxes of {CLUSTER_LEVELS} levels from \
                 the depth chosen, coloured by depth. Clusters link groups of patches, so links grow \
                 as n, not n² (K). While they are drawn, a click picks the smallest box drawn around \
                 the element too (orange; the inspector walks up and down from it)"
            ));
            if let Some(m) = max_depth {
                d.clusters_from = d.clusters_from.min(m);
                // A short slider: the row (box, slider, value, label) fits the side panel.
                ui.spacing_mut().slider_width = CLUSTER_SLIDER_W;
                ui.add(egui::Slider::new(&mut d.clusters_from, 0..=m).text("from depth"))
                    .on_hover_text("The shallowest cluster level drawn");
            }
        });
    })
    .response
    .on_disabled_hover_text(
        "This solve does not cluster: scenes of 3 000 patches or more do (the furnished rooms), \
         or --cluster on",
    );
}
