//! The viewport camera: orbit around a target, pan, zoom (dolly), frame-all and reset.
//! Y is up (glTF's convention). All math in f64; the GPU gets an `f32` view-projection in the
//! scene's local frame (world minus `origin`).
//!
//! ```text
//! eye = target + distance · (cos pitch · sin yaw, sin pitch, cos pitch · cos yaw)
//! ```

use crate::math::DVec3;
use crate::scene::{Bounds, Viewpoint};
use eframe::egui;
use glam::{DMat4, DVec4};

/// Closest the pitch gets to ±90° (radians), so the up vector never aligns with the view.
const PITCH_LIMIT: f64 = 1.55;

/// An orbit camera.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct OrbitCamera {
    pub target: DVec3,
    /// Radians around +Y, 0 = looking down −Z (eye on +Z).
    pub yaw: f64,
    /// Radians above the horizon.
    pub pitch: f64,
    pub distance: f64,
    pub fov_y_deg: f64,
    /// Scene diagonal, for near/far planes and pan speed.
    pub scale: f64,
}

impl OrbitCamera {
    /// A camera that sees all of `bounds` from the front (+Z side), slightly from above.
    #[must_use]
    pub fn frame_all(bounds: &Bounds) -> OrbitCamera {
        let fov_y_deg: f64 = 45.0;
        let diag =
            if bounds.diagonal().is_finite() && bounds.diagonal() > 0.0 { bounds.diagonal() } else { 1.0 };
        let half = (0.5 * fov_y_deg).to_radians();
        OrbitCamera {
            target: bounds.center(),
            yaw: 0.0,
            pitch: 0.15,
            distance: 0.5 * diag / half.sin() * 1.05,
            fov_y_deg,
            scale: diag,
        }
    }

    /// The scene's own viewpoint as an orbit camera (falls back to `frame_all` if degenerate).
    #[must_use]
    pub fn from_viewpoint(v: &Viewpoint, bounds: &Bounds) -> OrbitCamera {
        let d = v.eye - v.target;
        let distance = d.length();
        let mut cam = Self::frame_all(bounds);
        if !(distance > 0.0 && distance.is_finite()) {
            return cam;
        }
        cam.target = v.target;
        cam.distance = distance;
        cam.pitch = (d.y / distance).clamp(-1.0, 1.0).asin().clamp(-PITCH_LIMIT, PITCH_LIMIT);
        cam.yaw = d.x.atan2(d.z);
        if v.fov_y_deg > 1.0 && v.fov_y_deg < 170.0 {
            cam.fov_y_deg = v.fov_y_deg;
        }
        cam
    }

    #[must_use]
    pub fn eye(&self) -> DVec3 {
        self.target
            + self.distance
                * DVec3::new(
                    self.pitch.cos() * self.yaw.sin(),
                    self.pitch.sin(),
                    self.pitch.cos() * self.yaw.cos(),
                )
    }

    /// Rotate by screen-space deltas (radians).
    pub fn orbit(&mut self, d_yaw: f64, d_pitch: f64) {
        self.yaw = (self.yaw - d_yaw).rem_euclid(std::f64::consts::TAU);
        self.pitch = (self.pitch + d_pitch).clamp(-PITCH_LIMIT, PITCH_LIMIT);
    }

    /// Move the target in the view plane by a fraction of the view's height (dx right, dy up).
    pub fn pan(&mut self, dx: f64, dy: f64) {
        let (right, up, _) = self.basis();
        let h = 2.0 * self.distance * (0.5 * self.fov_y_deg.to_radians()).tan();
        self.target += (right * dx + up * dy) * h;
    }

    /// Dolly: multiply the distance by `factor` (< 1 zooms in).
    pub fn zoom(&mut self, factor: f64) {
        if factor.is_finite() && factor > 0.0 {
            self.distance = (self.distance * factor).clamp(self.scale * 1e-4, self.scale * 1e3);
        }
    }

    /// (right, up, forward) unit vectors.
    #[must_use]
    pub fn basis(&self) -> (DVec3, DVec3, DVec3) {
        let f = (self.target - self.eye()).normalize();
        let r = f.cross(DVec3::Y).normalize();
        (r, r.cross(f), f)
    }

    fn near_far(&self) -> (f64, f64) {
        let near = (self.distance - self.scale).max(self.distance * 1e-3).max(self.scale * 1e-5);
        (near, self.distance + 2.0 * self.scale)
    }

    /// View-projection from the local frame (world − `origin`) to wgpu clip space (depth 0..1).
    #[must_use]
    pub fn view_proj(&self, aspect: f64, origin: DVec3) -> DMat4 {
        let eye = self.eye() - origin;
        let (r, u, f) = self.basis();
        let view = DMat4::from_cols(
            DVec4::new(r.x, u.x, -f.x, 0.0),
            DVec4::new(r.y, u.y, -f.y, 0.0),
            DVec4::new(r.z, u.z, -f.z, 0.0),
            DVec4::new(-r.dot(eye), -u.dot(eye), f.dot(eye), 1.0),
        );
        let (n, fa) = self.near_far();
        let t = 1.0 / (0.5 * self.fov_y_deg.to_radians()).tan();
        let aspect = if aspect > 0.0 && aspect.is_finite() { aspect } else { 1.0 };
        let proj = DMat4::from_cols(
            DVec4::new(t / aspect, 0.0, 0.0, 0.0),
            DVec4::new(0.0, t, 0.0, 0.0),
            DVec4::new(0.0, 0.0, fa / (n - fa), -1.0),
            DVec4::new(0.0, 0.0, n * fa / (n - fa), 0.0),
        );
        proj * view
    }

    /// Frame `bounds`, keeping the view direction.
    pub fn reframe(&mut self, bounds: &Bounds) {
        let f = OrbitCamera::frame_all(bounds);
        self.target = f.target;
        self.distance = f.distance;
    }

    /// The camera's keys (arrows orbit, shift + arrows pan, + / − zoom, F frames `bounds()`, R
    /// goes back to `home`), unless a text field has the keyboard.
    pub fn keys(&mut self, ui: &egui::Ui, home: &OrbitCamera, bounds: impl FnOnce() -> Option<Bounds>) {
        if ui.ctx().egui_wants_keyboard_input() {
            return;
        }
        let (frame, reset) = ui.input(|i| {
            let step = 0.05;
            let pan = i.modifiers.shift;
            for (key, dx, dy) in [
                (egui::Key::ArrowLeft, -1.0, 0.0),
                (egui::Key::ArrowRight, 1.0, 0.0),
                (egui::Key::ArrowUp, 0.0, -1.0),
                (egui::Key::ArrowDown, 0.0, 1.0),
            ] {
                if i.key_down(key) {
                    if pan {
                        self.pan(dx * step * 0.5, -dy * step * 0.5);
                    } else {
                        self.orbit(dx * step, dy * step);
                    }
                }
            }
            if i.key_pressed(egui::Key::Plus) || i.key_pressed(egui::Key::Equals) {
                self.zoom(0.85);
            }
            if i.key_pressed(egui::Key::Minus) {
                self.zoom(1.0 / 0.85);
            }
            (i.key_pressed(egui::Key::F), i.key_pressed(egui::Key::R))
        });
        if frame && let Some(b) = bounds() {
            self.reframe(&b);
        }
        if reset {
            *self = *home;
        }
    }

    /// Drive the camera from a view's response: left-drag orbits, right/middle-drag or
    /// shift-drag pans, the wheel zooms (while hovered). The viewport and every split-view pane
    /// call this with the one camera they share.
    pub fn interact(&mut self, ui: &egui::Ui, response: &egui::Response, rect: egui::Rect) {
        let shift = ui.input(|i| i.modifiers.shift);
        let d = response.drag_delta();
        if response.dragged_by(egui::PointerButton::Primary) && !shift {
            self.orbit(f64::from(d.x) * 0.01, f64::from(d.y) * 0.01);
        } else if response.dragged_by(egui::PointerButton::Secondary)
            || response.dragged_by(egui::PointerButton::Middle)
            || (response.dragged_by(egui::PointerButton::Primary) && shift)
        {
            let h = f64::from(rect.height().max(1.0));
            self.pan(-f64::from(d.x) / h, f64::from(d.y) / h);
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.zoom((-f64::from(scroll) * 0.002).exp());
            }
        }
    }

    /// The world-space ray through normalised device coordinates (x right, y up, both −1..1).
    #[must_use]
    pub fn ray(&self, ndc_x: f64, ndc_y: f64, aspect: f64) -> (DVec3, DVec3) {
        let (r, u, f) = self.basis();
        let t = (0.5 * self.fov_y_deg.to_radians()).tan();
        let dir = (f + r * (ndc_x * t * aspect) + u * (ndc_y * t)).normalize();
        (self.eye(), dir)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Round trip through f64 matrices: only rounding remains.
    const TIGHT: f64 = 1e-9;

    fn unit_bounds() -> Bounds {
        Bounds { min: DVec3::splat(-1.0), max: DVec3::splat(1.0) }
    }

    #[test]
    fn target_projects_to_the_centre_and_ray_round_trips() {
        let mut c = OrbitCamera::frame_all(&unit_bounds());
        c.orbit(0.7, 0.3);
        let origin = DVec3::new(0.5, 0.0, 0.0);
        let m = c.view_proj(1.5, origin);
        let p = m * (c.target - origin).extend(1.0);
        assert!((p.x / p.w).abs() < TIGHT && (p.y / p.w).abs() < TIGHT);
        assert!((0.0..1.0).contains(&(p.z / p.w)));
        // A point along the ray through NDC (0.3, −0.4) projects back to (0.3, −0.4).
        let (o, d) = c.ray(0.3, -0.4, 1.5);
        let q = m * (o + d * c.distance - origin).extend(1.0);
        assert!((q.x / q.w - 0.3).abs() < TIGHT && (q.y / q.w + 0.4).abs() < TIGHT);
    }

    #[test]
    fn viewpoint_round_trip_and_controls() {
        let v = Viewpoint {
            eye: DVec3::new(0.0, 1.0, 5.0),
            target: DVec3::new(0.0, 1.0, 0.0),
            up: DVec3::Y,
            fov_y_deg: 40.0,
        };
        let c = OrbitCamera::from_viewpoint(&v, &unit_bounds());
        assert!((c.eye() - v.eye).length() < TIGHT);
        let mut z = c;
        z.zoom(0.5);
        assert!((z.distance - 2.5).abs() < TIGHT);
        let mut p = c;
        p.pan(0.1, 0.0);
        assert!(p.target.x > 0.0 && (p.target.y - 1.0).abs() < TIGHT);
        let mut o = c;
        o.orbit(0.0, 10.0);
        assert!(o.pitch <= PITCH_LIMIT);
    }
}
