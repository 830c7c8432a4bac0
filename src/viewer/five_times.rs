//! The five-times explorer: a square source of side s facing a differential receiver at a
//! distance d (and a sideways offset); the exact form factor (Lambert's contour integral,
//! [`form_factor::point_to_polygon`]) against the disk approximation
//! `F ≈ A cosθ cosθ' / (πr² + A)` ([`form_factor::disk`]) and the point-source one
//! `A cosθ cosθ' / (πr²)`, with the lecture's rule of thumb: once the distance is at least five
//! times the source's diameter, the approximations are within about a percent.

use crate::geometry::form_factor;
use crate::math::DVec3;
use eframe::egui;
use std::f64::consts::PI;

/// Distance in diameters beyond which the lecture's rule says a source may be taken as a point.
pub const FIVE: f64 = 5.0;

/// The explorer's settings.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct FiveTimes {
    pub open: bool,
    /// Side of the square source.
    pub side: f64,
    /// Height of the source's centre above the receiver.
    pub distance: f64,
    /// Sideways offset of the source's centre.
    pub offset: f64,
}

impl Default for FiveTimes {
    fn default() -> Self {
        FiveTimes { open: false, side: 1.0, distance: 2.0, offset: 0.0 }
    }
}

/// Exact, disk and point-source form factors from a receiver at the origin facing +y to a
/// square of side `side` centred at (`offset`, `distance`, 0) facing −y.
#[must_use]
pub fn form_factors(side: f64, distance: f64, offset: f64) -> [f64; 3] {
    let h = 0.5 * side;
    let c = DVec3::new(offset, distance, 0.0);
    // Counter-clockwise seen from below (its front faces −y).
    let verts = [
        c + DVec3::new(-h, 0.0, -h),
        c + DVec3::new(h, 0.0, -h),
        c + DVec3::new(h, 0.0, h),
        c + DVec3::new(-h, 0.0, h),
    ];
    let (p, n, src_n, area) = (DVec3::ZERO, DVec3::Y, -DVec3::Y, side * side);
    let exact = form_factor::point_to_polygon(p, n, &verts);
    let disk = form_factor::disk(p, n, c, src_n, area);
    let r2 = c.length_squared();
    let cos = c.y / r2.sqrt();
    // Not clamped at 1: close up the point-source formula runs past 1, which is the point.
    let point = area * cos * cos / (PI * r2);
    [exact, disk, point]
}

impl FiveTimes {
    /// The explorer window (when open).
    pub fn window(&mut self, ctx: &egui::Context) {
        let mut open = self.open;
        egui::Window::new("Five-times explorer").open(&mut open).resizable(false).show(ctx, |ui| {
            self.contents(ui);
        });
        self.open = open;
    }

    fn contents(&mut self, ui: &mut egui::Ui) {
        use egui_plot::{Legend, Line, Plot, PlotPoints, VLine};
        ui.add(egui::Slider::new(&mut self.side, 0.05..=4.0).text("source side s"))
            .on_hover_text("Side of the square source (its diameter is s√2)");
        ui.add(egui::Slider::new(&mut self.distance, 0.05..=20.0).logarithmic(true).text("distance d"))
            .on_hover_text("Height of the source's centre above the receiver");
        ui.add(egui::Slider::new(&mut self.offset, 0.0..=10.0).text("offset"))
            .on_hover_text("Sideways shift of the source: both cosines fall");
        let [exact, disk, point] = form_factors(self.side, self.distance, self.offset);
        let diam = self.side * 2f64.sqrt();
        let dist = (self.distance * self.distance + self.offset * self.offset).sqrt();
        let ratio = dist / diam;
        egui::Grid::new("five_times").num_columns(3).striped(true).show(ui, |ui| {
            for (name, f) in [("exact", exact), ("disk", disk), ("point source", point)] {
                ui.label(name);
                ui.monospace(format!("F = {f:.5}"));
                if exact > 0.0 {
                    ui.monospace(format!("{:+.2} %", 100.0 * (f / exact - 1.0)));
                }
                ui.end_row();
            }
        });
        let verdict = if ratio >= FIVE {
            "at least five diameters: a point will do"
        } else {
            "closer than five diameters"
        };
        ui.label(format!("distance / diameter = {ratio:.2}: {verdict}"));
        // Error of the approximations on axis against distance in diameters.
        let curve = |k: usize| -> Vec<[f64; 2]> {
            (0..=120)
                .map(|i| {
                    let x = 0.1 * 200f64.powf(f64::from(i) / 120.0); // 0.1 … 20 diameters
                    let f = form_factors(1.0, x * 2f64.sqrt(), 0.0);
                    [x.log10(), (f[k] / f[0] - 1.0).abs().max(1e-9).log10()]
                })
                .collect()
        };
        Plot::new("five_times_plot")
            .height(160.0)
            .width(360.0)
            .legend(Legend::default())
            .x_axis_label("log₁₀ distance / diameter")
            .y_axis_label("log₁₀ relative error")
            .show(ui, |p| {
                p.line(Line::new("disk", PlotPoints::from(curve(1))));
                p.line(Line::new("point source", PlotPoints::from(curve(2))));
                p.vline(VLine::new("five diameters", FIVE.log10()));
            });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn far_away_the_approximations_agree_with_the_exact_form_factor() {
        // On axis at five diameters both are within a percent; at half a diameter the point
        // source is far off.
        let side = 1.0;
        let [e, d, p] = form_factors(side, FIVE * side * 2f64.sqrt(), 0.0);
        assert!((d / e - 1.0).abs() < 0.01 && (p / e - 1.0).abs() < 0.01, "{e} {d} {p}");
        let [e, _, p] = form_factors(side, 0.5 * side * 2f64.sqrt(), 0.0);
        assert!(p / e > 1.5, "{e} {p}");
        // The unit square one unit up: exact 0.2395 (the catalog's square-to-point value).
        let [e, _, _] = form_factors(1.0, 1.0, 0.0);
        assert!((e - 0.239_465).abs() < 1e-4, "{e}");
    }
}
