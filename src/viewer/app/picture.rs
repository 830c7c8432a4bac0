//! The picture in the middle of the window: the viewport (camera, picking, the paint callback
//! and the legends over it) or a pane view in its place (the split view, the replay), and the
//! display builds they draw: what the display settings ask of a build, when one is asked for,
//! and how the mesh shader draws it.

use super::RadlabApp;
use crate::eval::artifacts::ArtifactSamples;
use crate::present::mesh_overlay::Artifact;
use crate::viewer::builder::{self, Coloring};
use crate::viewer::display::{CLUSTER_LEVELS, Shading};
use crate::viewer::geometry::BuildKey;
use crate::viewer::legends::Legends;
use crate::viewer::pane::{self, PaneStyle};
use crate::viewer::replay::ReplayInput;
use crate::viewer::split::{SplitAction, SplitInput};
use crate::viewer::view::View;
use crate::viewer::viewport::{self, Picture, Shade};
use eframe::egui::{self, Pos2, Rect, Sense};
use std::sync::Arc;

impl RadlabApp {
    /// The viewport: the camera's mouse and keys, a click picks, the pointer's leaf is tracked
    /// for the matrix window; the newest display build is drawn with the legends over it.
    pub(super) fn viewport(&mut self, ui: &mut egui::Ui) {
        let rect = ui.available_rect_before_wrap();
        self.framing.rect = rect;
        let response = ui.allocate_rect(rect, Sense::click_and_drag());
        let aspect = f64::from(rect.width() / rect.height().max(1.0));

        // Camera: left-drag orbit, right/middle-drag or shift-drag pan, wheel zoom, keys.
        self.framing.camera.interact(ui, &response, rect);
        self.framing.keys(ui, self.scene.as_ref());
        if response.clicked()
            && let Some(pos) = response.interact_pointer_pos()
        {
            self.pick_at(pos, rect);
        }
        // While the matrix is open, the leaf under the pointer is highlighted there.
        self.pick.viewport_hover = if self.lecture.matrix.open {
            response.hover_pos().and_then(|pos| self.pick_id(pos, rect))
        } else {
            None
        };

        self.request_geometry();
        self.poll_geometry(false);
        let picture = Picture {
            geometry: &self.geometry,
            view_proj: self.framing.view_proj(aspect),
            origin: self.framing.origin,
            shade: self.shade(),
            has_wgpu: self.has_wgpu,
            view: &self.shown.view,
            highlight: self.highlight(),
            legends: self.legends(),
        };
        viewport::paint(ui, rect, &picture);
        ui.horizontal(|_| {});
    }

    /// What the legends over the viewport describe this frame.
    fn legends(&self) -> Legends<'_> {
        Legends {
            display: &self.display,
            view: &self.shown.view,
            picked: self.pick.here().is_some(),
            picked_cluster: self.picked_cluster(),
            link_stats: self.geometry.link_stats,
            cluster_link_stats: self.geometry.cluster_link_stats,
            link_scale: self.geometry.link_scale,
            error_scale: self.geometry.error_scale,
            critical: self.critical_counts(),
            artifacts: self.artifacts(),
            error: self.shade().error.then(|| self.error_label()),
            busy: self.busy(),
            split_on: self.split.on,
            stale: self.stale_note(),
        }
    }

    /// Before a pane view (split, replay) draws in place of the viewport: the camera's keys, and
    /// the current solution's build, which sets the auto exposure every pane shares. Returns how
    /// the panes draw.
    fn pane_frame(&mut self, ui: &egui::Ui) -> PaneStyle {
        self.framing.rect = ui.available_rect_before_wrap();
        self.pick.viewport_hover = None;
        self.framing.keys(ui, self.scene.as_ref());
        self.request_geometry();
        self.poll_geometry(false);
        PaneStyle {
            uniforms: viewport::uniforms(
                self.framing.view_proj(1.0),
                self.shade(),
                ui.ctx().pixels_per_point(),
            ),
            origin: self.framing.origin,
            has_wgpu: self.has_wgpu,
        }
    }

    /// The split view in place of the viewport: the runs of the history side by side, with the
    /// viewport's camera (its keys too) and exposure.
    pub(super) fn split_view(&mut self, ui: &mut egui::Ui) {
        let style = self.pane_frame(ui);
        let settings = self.build_settings();
        let scene = self.scene.as_ref().map_or("", |s| s.name.as_str());
        let picked = self.pick.selected.zip(self.pick.selected_run).map(|(id, run)| (run, id));
        let camera = &mut self.framing.camera;
        let input = SplitInput { history: &self.history, scene, camera, settings, style, picked };
        match self.split.ui(ui, input) {
            Some(SplitAction::OpenHistory) => self.history.open = true,
            Some(SplitAction::Pick { run, element }) => {
                self.pick.in_run(run, element);
                // The panes were drawn before the pick: outline it in the next frame.
                ui.ctx().request_repaint();
            }
            None => {}
        }
    }

    /// The refinement replay in place of the viewport.
    pub(super) fn replay_view(&mut self, ui: &mut egui::Ui) {
        let style = self.pane_frame(ui);
        let settings = self.build_settings();
        self.replay.ui(ui, ReplayInput { camera: &mut self.framing.camera, settings, style });
    }

    /// The artifact overlay to draw and its samples, when they were measured on the state shown.
    fn artifact_samples(&self) -> Option<(Artifact, Arc<ArtifactSamples>)> {
        self.artifacts.samples(self.display.artifact, self.shown.seq)
    }

    /// What the display settings ask of a geometry build (the split view's panes use them too).
    fn build_settings(&self) -> builder::Settings {
        let d = &self.display;
        let mesh_view = self.mesh_view();
        let picked = self.pick.here();
        let picked_cluster = self.picked_cluster();
        let show_links = !mesh_view && (d.links || (picked.is_some() && d.selected_links_only));
        let links = show_links.then(|| {
            let mut filter = d.link_filter;
            filter.element = if d.selected_links_only {
                // Nothing picked: nothing to show; a cluster picked: its cluster links only.
                Some(picked.filter(|_| picked_cluster.is_none()).unwrap_or(u32::MAX))
            } else {
                None
            };
            filter
        });
        builder::Settings {
            coloring: if d.error && self.error_applies() {
                Coloring::Error
            } else {
                match d.shading {
                    Shading::Smooth => Coloring::Smooth,
                    Shading::Flat => Coloring::Flat,
                    Shading::Nodal => Coloring::Nodal,
                }
            },
            links,
            link_alpha: d.link_alpha,
            links_xray: d.links_xray,
            cluster_links: d.cluster_links,
            origin: self.framing.origin,
            depth_limit: None,
            critical: d.critical,
            clusters: d
                .clusters
                .then(|| (d.clusters_from, d.clusters_from.saturating_add(CLUSTER_LEVELS - 1))),
            picked_cluster,
        }
    }

    /// Ask for a display build when the solver state (its error estimates included) or a
    /// display setting it depends on changed. The build runs on the `radlab-display` thread; the
    /// UI keeps showing the previous geometry until [`RadlabApp::poll_geometry`] picks the new
    /// one up.
    pub(super) fn request_geometry(&mut self) {
        // The error overlay of a state whose estimates are on their way: the last build (the
        // last state's heatmap) stays until they come (the status bar says so).
        if self.overlay_waits_for_estimates() {
            return;
        }
        let settings = self.build_settings();
        let key = BuildKey {
            view_seq: self.shown.seq,
            // (Only the heatmap reads the estimates: their arrival rebuilds nothing else.)
            view: if settings.coloring == Coloring::Error {
                Arc::as_ptr(&self.shown.view) as usize
            } else {
                0
            },
            true_error: self.true_error().map(|e| Arc::as_ptr(e) as usize),
            artifacts: self.artifact_samples().map(|(a, s)| (a, Arc::as_ptr(&s) as usize)),
            settings,
        };
        let (view, view_seq, true_error) =
            (Arc::clone(&self.shown.view), self.shown.seq, self.true_error().cloned());
        let (scene, artifacts) = (self.scene.clone(), self.artifact_samples());
        let ev = self.geometry.request(key, self.display.auto_exposure, |seq| builder::Request {
            seq,
            view,
            view_seq,
            true_error,
            settings,
            scene,
            artifacts,
        });
        self.apply_exposure(ev);
    }

    /// Pick up a finished display build (`wait`: block for it).
    pub(super) fn poll_geometry(&mut self, wait: bool) {
        let ev = self.geometry.poll(wait, self.display.auto_exposure);
        self.apply_exposure(ev);
    }

    /// The auto exposure of a new build, if any.
    fn apply_exposure(&mut self, ev: Option<f32>) {
        if let Some(ev) = ev {
            self.display.exposure_ev = ev;
        }
    }

    /// How the mesh shader draws the current solution (the panes too, less the pick).
    fn shade(&self) -> Shade {
        let d = &self.display;
        // While the overlay waits for the estimates, the last build stays: drawn as it was built.
        let error = if self.overlay_waits_for_estimates() {
            self.geometry.coloring == Some(Coloring::Error)
        } else {
            d.error && self.error_applies()
        };
        Shade {
            exposure_ev: d.exposure_ev,
            srgb: d.srgb,
            error,
            quadtree: d.quadtree,
            picked: self.pick.here(),
        }
    }

    /// Frame the whole scene, keeping the view direction.
    pub fn frame_all(&mut self) {
        if let Some(s) = &self.scene {
            self.framing.camera.reframe(&s.bounds());
        }
    }

    /// Pick the element under a viewport point; while the cluster boxes are drawn, the cluster
    /// around it at the levels shown too ([`crate::viewer::clusters::at_shown_level`]).
    fn pick_at(&mut self, pos: Pos2, rect: Rect) {
        let id = self.pick_id(pos, rect);
        let deepest = self.display.clusters_from.saturating_add(CLUSTER_LEVELS - 1);
        self.pick.element(id, &self.shown.view, self.display.clusters.then_some(deepest));
    }

    /// Pick cluster `c` of the current solution (`None`: the element alone); ignored unless it
    /// holds the picked element's patch (the inspector's up / down walk that chain).
    pub fn pick_cluster(&mut self, c: Option<u32>) {
        self.pick.set_cluster(c, &self.shown.view);
    }

    /// The leaf under a viewport point.
    fn pick_id(&self, pos: Pos2, rect: Rect) -> Option<u32> {
        pane::pick(&self.shown.view, &self.framing.camera, pos, rect)
    }

    /// Pick the element under a point given in viewport-relative coordinates (0..1, y down).
    pub fn pick_relative(&mut self, x: f32, y: f32) {
        if let Some(pos) = self.framing.at_fraction(x, y) {
            self.pick_at(pos, self.framing.rect);
        }
    }
}
