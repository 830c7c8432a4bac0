//! How the viewport frames the scene ([`Framing`]): the orbit camera, the scene's own camera to
//! go back to, the origin the geometry is drawn around, and where the viewport was drawn.

use super::camera::OrbitCamera;
use crate::math::DVec3;
use crate::present::figures::CameraPreset;
use crate::scene::{Bounds, Scene};
use eframe::egui::{self, Pos2, Rect};
use glam::DMat4;
use std::sync::Arc;

/// The camera and the viewport's place.
pub struct Framing {
    pub(super) camera: OrbitCamera,
    /// The scene's own camera (R goes back to it; a figure's camera turns from it).
    pub(super) home: OrbitCamera,
    /// The scene's centre: the geometry is built relative to it (f32 precision near it).
    pub(super) origin: DVec3,
    /// Where the viewport (or the pane view in its place) was drawn in the last frame, points.
    pub(super) rect: Rect,
}

impl Default for Framing {
    /// Until a scene is loaded: framing the unit cube around the origin.
    fn default() -> Framing {
        let start = OrbitCamera::frame_all(&Bounds { min: DVec3::splat(-1.0), max: DVec3::splat(1.0) });
        Framing { camera: start, home: start, origin: DVec3::ZERO, rect: Rect::NOTHING }
    }
}

impl Framing {
    /// Frame `scene` with its own camera, else the CPU renderer's default (inside closed rooms,
    /// the most front-facing direction outside open scenes).
    pub fn frame_scene(&mut self, scene: &Scene) {
        let b = scene.bounds();
        self.origin = b.center();
        let c = crate::present::image::Camera::for_scene(scene);
        let v = crate::scene::Viewpoint { eye: c.eye, target: c.target, up: c.up, fov_y_deg: c.fov_y_deg };
        self.home = OrbitCamera::from_viewpoint(&v, &b);
        self.camera = self.home;
    }

    /// A figure's camera: the scene's own, turned and zoomed as `c` says.
    pub fn figure_camera(&mut self, c: CameraPreset) {
        self.camera = self.home;
        self.camera.orbit(-c.yaw_deg.to_radians(), c.pitch_deg.to_radians());
        self.camera.zoom(c.zoom);
    }

    /// The camera's keys ([`OrbitCamera::keys`]; F frames the scene, R goes back to its camera).
    pub fn keys(&mut self, ui: &egui::Ui, scene: Option<&Arc<Scene>>) {
        self.camera.keys(ui, &self.home, || scene.map(|s| s.bounds()));
    }

    /// The camera's view-projection at `aspect`, around the origin.
    #[must_use]
    pub fn view_proj(&self, aspect: f64) -> DMat4 {
        self.camera.view_proj(aspect, self.origin)
    }

    /// The point of the viewport at fractions (x, y) of its width and height (y down), once it
    /// has been drawn.
    #[must_use]
    pub fn at_fraction(&self, x: f32, y: f32) -> Option<Pos2> {
        let r = self.rect;
        r.is_positive().then(|| Pos2::new(r.left() + x * r.width(), r.top() + y * r.height()))
    }
}
