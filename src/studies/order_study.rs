//! h- against p-refinement, measured (the lecture's "element order and
//! continuity"): the pointwise error of Galerkin solutions ([`crate::solver::linear`]) of order
//! p = 0 and p = 1 on a sequence of uniform meshes, against the exact single-bounce answer
//! ([`crate::geometry::exact`]: no reference noise).
//!
//! For a smooth solution the error of the best approximation by degree-p pieces of size h is
//! O(h^(p+1)) [Ciarlet 1978; for radiosity Heckbert & Winget 1991, Zatz 1993]:
//!
//! ```text
//! ‖B − B_h‖ ≤ C h^(p+1) |B|_(p+1)          log ‖B − B_h‖ ≈ log C + (p + 1) log h
//! ```
//!
//! so the log-log slope of the error against h is the order of convergence ([`slope`]: least
//! squares over the sizes). Where B is not smooth — across a penumbra narrower than the
//! elements, B has a ramp of width w ≪ h — no polynomial of any degree fits it inside one
//! element, and the error falls only as the elements shrink: raising p buys at best a constant.
//!
//! Two scenes ([`StudyScene`]): **parallel squares** (unit squares at distance 1, the lower one
//! the receiver, ρ = 0.5, E = 1: B = ρE·F(x → square), smooth) and **`builtin:shadow-narrow`**
//! (a 0.2-wide lamp 2 above a 2 × 2 floor, an occluder 0.25 above it: a penumbra ~0.03 wide).
//! Only the receiver is refined (n × n elements, h = side / n); the emitter is meshed once (it
//! emits a constant, which every order represents exactly; on shadow-narrow 4 × 4 pieces, so the
//! per-point-pair visibility sees the lamp at 256 points), the occluder is one black element.
//! The error is the relative L2 over a `grid` × `grid` lattice of cell centres on the receiver,
//! and over the points of that lattice in the penumbra band (2 % … 98 % of the lamp visible).
//! Methods: p = 0 shown flat, p = 0 shown Gouraud from vertex averages (the common display),
//! p = 1 discontinuous and continuous.

use crate::eval::pointwise::{PiecewiseConstant, Reconstruction};
use crate::eval::reconstruction::{Nodal, gouraud};
use crate::geometry::accel::Accel;
use crate::geometry::basis::Order;
use crate::geometry::exact::SingleBounce;
use crate::geometry::form_factor::point_to_polygon;
use crate::math::{DVec3, Rgb, polygon_area};
use crate::scene::{Patch, Scene};
use crate::solver::linear::{self, LinearParams};
use crate::solver::uniform::{Element, mesh_patch};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// Lit fraction bounds of the penumbra band (as in tests/exact.rs).
const PENUMBRA: (f64, f64) = (0.02, 0.98);

/// The scenes of the study (module docs).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize)]
pub enum StudyScene {
    ParallelSquares,
    ShadowNarrow,
}

impl StudyScene {
    /// Name in tables and plots.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            StudyScene::ParallelSquares => "parallel-squares",
            StudyScene::ShadowNarrow => "shadow-narrow",
        }
    }

    /// The scene.
    #[must_use]
    pub fn scene(self) -> Scene {
        match self {
            StudyScene::ParallelSquares => {
                let v = DVec3::new;
                let up = vec![v(0., 0., 0.), v(0., 0., 1.), v(1., 0., 1.), v(1., 0., 0.)];
                let down = vec![v(0., 1., 0.), v(1., 1., 0.), v(1., 1., 1.), v(0., 1., 1.)];
                let patch = |verts, rho: f64, e: f64, name: &str| {
                    Patch::new(verts, Rgb::splat(rho), Rgb::splat(e), name, 0, name, "m")
                        .expect("a valid unit square")
                };
                Scene::new(
                    "parallel-squares",
                    "order-study",
                    vec![patch(up, 0.5, 0.0, "receiver"), patch(down, 0.0, 1.0, "emitter")],
                )
            }
            StudyScene::ShadowNarrow => {
                Scene::load("builtin:shadow-narrow").expect("the built-in scene shadow-narrow exists")
            }
        }
    }

    /// The width of the narrowest feature of B on the receiver, where there is one: the penumbra
    /// of shadow-narrow, lamp width × occluder height / (lamp height − occluder height) =
    /// 0.2 × 0.25 / 1.75.
    #[must_use]
    pub fn feature_width(self) -> Option<f64> {
        match self {
            StudyScene::ParallelSquares => None,
            StudyScene::ShadowNarrow => Some(0.2 * 0.25 / 1.75),
        }
    }

    /// Elements per side of the emitter (module docs).
    fn emitter_divisions(self) -> u32 {
        match self {
            StudyScene::ParallelSquares => 1,
            StudyScene::ShadowNarrow => 4,
        }
    }
}

/// One way of computing and showing a solution.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize)]
pub enum Method {
    /// Galerkin p = 0, each element's value.
    P0Flat,
    /// Galerkin p = 0, Gouraud from vertex averages.
    P0Gouraud,
    /// Galerkin p = 1, per-element vertex values.
    P1Discontinuous,
    /// Galerkin p = 1, shared vertex values.
    P1Continuous,
}

impl Method {
    pub const ALL: [Method; 4] =
        [Method::P0Flat, Method::P0Gouraud, Method::P1Discontinuous, Method::P1Continuous];

    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Method::P0Flat => "p0 flat",
            Method::P0Gouraud => "p0 Gouraud",
            Method::P1Discontinuous => "p1 discontinuous",
            Method::P1Continuous => "p1 continuous",
        }
    }
}

/// Settings of [`run`].
#[derive(Clone, Debug, Serialize)]
pub struct StudyParams {
    /// Receiver elements per side, one size each (h = side / n).
    pub divisions: Vec<u32>,
    /// Evaluation lattice: grid × grid cell centres on the receiver.
    pub grid: usize,
    /// Rays of each pair's visibility class ([`LinearParams::rays`]).
    pub rays: u32,
}

impl StudyParams {
    /// The settings of docs/meshing.md's table: n = 2 … 128 (h = side/2 … side/128); 257² points
    /// (a prime, so the lattice never lines up with the element edges: on an aligned lattice
    /// every element is sampled at the same local points, and at 2 × 2 points an element those
    /// are near the Gauss points of the L2 projection, where its error is superconvergent);
    /// 64 rays to classify a pair (fewer let a pair near the penumbra pass as unoccluded, the
    /// error floor of the finest meshes).
    #[must_use]
    pub fn docs() -> StudyParams {
        StudyParams { divisions: vec![2, 4, 8, 16, 32, 64, 128], grid: 257, rays: 64 }
    }
}

/// One solve, scored.
#[derive(Clone, Debug, Serialize)]
pub struct StudyRow {
    pub scene: &'static str,
    pub method: &'static str,
    pub divisions: u32,
    /// Receiver element side.
    pub h: f64,
    /// Receiver elements, and unknowns of the whole system.
    pub elements: usize,
    pub unknowns: usize,
    /// Relative L2 error over the receiver's lattice.
    pub l2: f64,
    /// Relative L2 error over the lattice points in the penumbra band (`None` without a shadow).
    pub band_l2: Option<f64>,
    /// Wall time of the solve, seconds.
    pub time_s: f64,
}

/// The exact answer on the receiver's lattice, and which points are in the penumbra band.
struct Lattice {
    points: Vec<DVec3>,
    exact: Vec<f64>,
    band: Vec<bool>,
}

fn lattice(scene: &Scene, sb: &SingleBounce, grid: usize) -> Lattice {
    let r = &scene.patches[sb.receiver];
    let e = &scene.patches[sb.emitter];
    let mut out = Lattice { points: Vec::new(), exact: Vec::new(), band: Vec::new() };
    for j in 0..grid {
        for i in 0..grid {
            let (s, t) = ((i as f64 + 0.5) / grid as f64, (j as f64 + 0.5) / grid as f64);
            let x = crate::geometry::basis::position(&r.vertices, crate::geometry::basis::Local(s, t));
            let visible = sb.visible_form_factor(x);
            let open = point_to_polygon(x, r.normal, &e.vertices);
            let lit = if open > 0.0 { visible / open } else { 0.0 };
            out.points.push(x);
            out.exact.push(sb.radiosity_at(x).g());
            out.band.push(lit > PENUMBRA.0 && lit < PENUMBRA.1);
        }
    }
    out
}

/// Relative L2 of `values` against the exact lattice over the points where `keep` holds (equal
/// cell areas); `None` when no point is kept.
fn rel_l2(lat: &Lattice, values: &[f64], keep: impl Fn(usize) -> bool) -> Option<f64> {
    let (mut num, mut den) = (0.0, 0.0);
    for k in (0..values.len()).filter(|&k| keep(k)) {
        num += (values[k] - lat.exact[k]).powi(2);
        den += lat.exact[k].powi(2);
    }
    (den > 0.0).then(|| (num / den).sqrt())
}

/// The study's mesh: the receiver in n × n, the emitter in its fixed divisions, the rest whole.
fn mesh(scene: &Scene, sb: &SingleBounce, study: StudyScene, n: u32) -> Vec<Element> {
    let mut out = Vec::new();
    for (i, p) in scene.patches.iter().enumerate() {
        let side = (p.vertices[1] - p.vertices[0]).length().max((p.vertices[3] - p.vertices[0]).length());
        let divisions = if i == sb.receiver {
            n
        } else if i == sb.emitter {
            study.emitter_divisions()
        } else {
            1
        };
        // 1e-9 below the exact division, so rounding never adds a row of slivers.
        let size = side / f64::from(divisions) * (1.0 + 1e-9);
        for verts in mesh_patch(p, size) {
            let area = polygon_area(&verts);
            out.push(Element { patch: i, vertices: verts, area });
        }
    }
    out
}

/// Solve and score every method at every size on one scene. Errors: the solver's.
pub fn run(study: StudyScene, params: &StudyParams) -> Result<Vec<StudyRow>, String> {
    let scene = study.scene();
    let sb = SingleBounce::new(&scene).map_err(|e| e.to_string())?;
    let accel = Accel::build(&scene);
    let lat = lattice(&scene, &sb, params.grid);
    let has_band = lat.band.iter().any(|&b| b);
    let side = (scene.patches[sb.receiver].vertices[1] - scene.patches[sb.receiver].vertices[0]).length();
    let mut rows = Vec::new();
    for &n in &params.divisions {
        let elems = mesh(&scene, &sb, study, n);
        let groups: Vec<usize> = elems.iter().map(|e| e.patch).collect();
        for (order, continuous) in [(Order::Constant, false), (Order::Linear, false), (Order::Linear, true)] {
            let p = LinearParams {
                order,
                continuous,
                rays: params.rays,
                max_unknowns: 100_000,
                ..LinearParams::default()
            };
            let t = Instant::now();
            let sol = linear::solve_mesh(&scene, &accel, elems.clone(), &groups, &p, &mut |_, _| {})?;
            let time_s = t.elapsed().as_secs_f64();
            let unknowns =
                sol.solution.stats.extra.as_ref().and_then(|x| x["unknowns"].as_u64()).unwrap_or(0) as usize;
            let methods: Vec<(Method, Vec<Vec<Rgb>>)> = match (order, continuous) {
                (Order::Constant, _) => vec![
                    (Method::P0Flat, sol.coefficients.clone()),
                    (Method::P0Gouraud, gouraud(&scene, &sol.solution.elements)),
                ],
                (Order::Linear, false) => vec![(Method::P1Discontinuous, sol.coefficients.clone())],
                (Order::Linear, true) => vec![(Method::P1Continuous, sol.coefficients.clone())],
            };
            for (method, coef) in methods {
                let values: Vec<f64> = if method == Method::P0Flat {
                    let flat =
                        PiecewiseConstant::new(&scene, &sol.solution.elements).map_err(|e| e.to_string())?;
                    lat.points.iter().map(|x| flat.radiosity_at(sb.receiver, *x).g()).collect()
                } else {
                    let nodal =
                        Nodal::new(&scene, &sol.solution.elements, coef).map_err(|e| e.to_string())?;
                    lat.points.iter().map(|x| nodal.radiosity_at(sb.receiver, *x).g()).collect()
                };
                rows.push(StudyRow {
                    scene: study.name(),
                    method: method.name(),
                    divisions: n,
                    h: side / f64::from(n),
                    elements: (n * n) as usize,
                    unknowns,
                    l2: rel_l2(&lat, &values, |_| true).unwrap_or(0.0),
                    band_l2: if has_band { rel_l2(&lat, &values, |k| lat.band[k]) } else { None },
                    time_s,
                });
            }
        }
    }
    Ok(rows)
}

/// Least-squares slope of log y against log x (NaN for fewer than two points).
#[must_use]
pub fn slope(points: &[(f64, f64)]) -> f64 {
    let pts: Vec<(f64, f64)> = points.iter().map(|&(x, y)| (x.ln(), y.ln())).collect();
    let n = pts.len() as f64;
    let (mx, my) = (pts.iter().map(|p| p.0).sum::<f64>() / n, pts.iter().map(|p| p.1).sum::<f64>() / n);
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    sxy / sxx
}

/// The fitted slopes of one scene and method: over the whole receiver and over the band.
#[derive(Clone, Debug, Serialize)]
pub struct Fit {
    pub scene: &'static str,
    pub method: &'static str,
    pub slope: f64,
    pub band_slope: Option<f64>,
}

/// [`slope`] of every (scene, method) in `rows`, in row order.
#[must_use]
pub fn fits(rows: &[StudyRow]) -> Vec<Fit> {
    let mut out: Vec<Fit> = Vec::new();
    for r in rows {
        if out.iter().any(|f| f.scene == r.scene && f.method == r.method) {
            continue;
        }
        let mine: Vec<&StudyRow> =
            rows.iter().filter(|s| s.scene == r.scene && s.method == r.method).collect();
        let whole: Vec<(f64, f64)> = mine.iter().map(|s| (s.h, s.l2)).collect();
        let band: Option<Vec<(f64, f64)>> = mine.iter().map(|s| s.band_l2.map(|b| (s.h, b))).collect();
        out.push(Fit {
            scene: r.scene,
            method: r.method,
            slope: slope(&whole),
            band_slope: band.map(|b| slope(&b)),
        });
    }
    out
}

/// Markdown: one table per scene (rows: sizes; columns: unknowns and error of each method),
/// then the fitted slopes.
#[must_use]
pub fn markdown(rows: &[StudyRow]) -> String {
    let mut s = String::new();
    let mut scenes: Vec<&str> = rows.iter().map(|r| r.scene).collect();
    scenes.dedup();
    for scene in scenes {
        let mine: Vec<&StudyRow> = rows.iter().filter(|r| r.scene == scene).collect();
        let band = mine.iter().any(|r| r.band_l2.is_some());
        s.push_str(&format!("**{scene}** — relative L2 error over the receiver"));
        s.push_str(if band { " (in brackets: over the penumbra band)\n\n" } else { "\n\n" });
        s.push_str("| n × n | h |");
        for m in Method::ALL {
            s.push_str(&format!(" {} (unknowns) |", m.name()));
        }
        s.push_str("\n|---|---|");
        s.push_str(&"---|".repeat(Method::ALL.len()));
        s.push('\n');
        let mut sizes: Vec<u32> = mine.iter().map(|r| r.divisions).collect();
        sizes.dedup();
        for n in sizes {
            let h = mine.iter().find(|r| r.divisions == n).map_or(0.0, |r| r.h);
            s.push_str(&format!("| {n} × {n} | {h:.4} |"));
            for m in Method::ALL {
                match mine.iter().find(|r| r.divisions == n && r.method == m.name()) {
                    Some(r) => {
                        s.push_str(&format!(" {} %", percent(r.l2)));
                        if let Some(b) = r.band_l2 {
                            s.push_str(&format!(" [{:.1} %]", 100.0 * b));
                        }
                        s.push_str(&format!(" ({}) |", r.unknowns));
                    }
                    None => s.push_str(" |"),
                }
            }
            s.push('\n');
        }
        s.push_str("\n| method | slope of log error / log h | in the penumbra band |\n|---|---|---|\n");
        for f in fits(rows).iter().filter(|f| f.scene == scene) {
            let band = f.band_slope.map_or_else(|| "—".to_string(), |b| format!("{b:.2}"));
            s.push_str(&format!("| {} | {:.2} | {band} |\n", f.method, f.slope));
        }
        s.push('\n');
    }
    s
}

/// A fraction in percent with three significant digits (at least one decimal).
fn percent(x: f64) -> String {
    let p = 100.0 * x;
    let decimals = if p > 0.0 { (2.0 - p.abs().log10().floor()).clamp(1.0, 8.0) as usize } else { 1 };
    format!("{p:.decimals$}")
}

/// One plotted point: method, h, error.
type Point = (&'static str, f64, f64);

/// Log-log PNG: error against h, one panel per scene (and one for the penumbra band where there
/// is one), one line per method, its fitted slope in the legend.
pub fn plot_png(rows: &[StudyRow], path: &Path) -> Result<(), String> {
    use plotters::prelude::*;
    crate::studies::bench::register_font();
    let mut panels: Vec<(String, Vec<Point>, Option<f64>)> = Vec::new();
    let mut scenes: Vec<&str> = rows.iter().map(|r| r.scene).collect();
    scenes.dedup();
    for scene in &scenes {
        let mine: Vec<&StudyRow> = rows.iter().filter(|r| r.scene == *scene).collect();
        let width = [StudyScene::ParallelSquares, StudyScene::ShadowNarrow]
            .into_iter()
            .find(|s| s.name() == *scene)
            .and_then(StudyScene::feature_width);
        panels.push((
            format!("{scene}: whole receiver"),
            mine.iter().map(|r| (r.method, r.h, r.l2)).collect(),
            width,
        ));
        if mine.iter().all(|r| r.band_l2.is_some()) {
            panels.push((
                format!("{scene}: penumbra band"),
                mine.iter().map(|r| (r.method, r.h, r.band_l2.unwrap_or(0.0))).collect(),
                width,
            ));
        }
    }
    let (pw, ph) = (560u32, 460u32);
    let (w, h) = (pw * panels.len().max(1) as u32, ph);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    let err = |e: &dyn std::fmt::Display| format!("plot {}: {e}", path.display());
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let areas = root.split_evenly((1, panels.len().max(1)));
        let colours =
            [RGBColor(31, 119, 180), RGBColor(148, 103, 189), RGBColor(255, 127, 14), RGBColor(44, 160, 44)];
        for ((title, pts, width), area) in panels.iter().zip(areas) {
            let pos: Vec<&(&str, f64, f64)> = pts.iter().filter(|p| p.2 > 0.0 && p.1 > 0.0).collect();
            let (h0, h1) = pos.iter().fold((f64::INFINITY, 0.0f64), |a, p| (a.0.min(p.1), a.1.max(p.1)));
            let (h0, h1) = width.map_or((h0, h1), |w| (h0.min(w), h1.max(w)));
            let (e0, e1) = pos.iter().fold((f64::INFINITY, 0.0f64), |a, p| (a.0.min(p.2), a.1.max(p.2)));
            if pos.is_empty() {
                continue;
            }
            let mut chart = ChartBuilder::on(&area)
                .caption(title, ("sans-serif", 20))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(64)
                .build_cartesian_2d((h0 / 1.4..h1 * 1.4).log_scale(), (e0 / 2.0..e1 * 2.0).log_scale())
                .map_err(|e| err(&e))?;
            chart
                .configure_mesh()
                .x_desc("element size h")
                .y_desc("pointwise relative L2 error")
                .light_line_style(WHITE.mix(0.0))
                .y_label_formatter(&|y| format!("{}%", percent(*y)))
                .x_label_formatter(&|x| format!("{x:.3}"))
                .y_labels(8)
                .label_style(("sans-serif", 13))
                .draw()
                .map_err(|e| err(&e))?;
            if let Some(w) = *width {
                chart
                    .draw_series(DashedLineSeries::new(
                        [(w, e0 / 2.0), (w, e1 * 2.0)],
                        6,
                        4,
                        BLACK.mix(0.5).stroke_width(1),
                    ))
                    .map_err(|e| err(&e))?
                    .label(format!("h = penumbra width {w:.3}"))
                    .legend(|(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], BLACK.mix(0.5).stroke_width(1))
                    });
            }
            for (m, col) in Method::ALL.iter().zip(colours) {
                let line: Vec<(f64, f64)> =
                    pos.iter().filter(|p| p.0 == m.name()).map(|p| (p.1, p.2)).collect();
                if line.is_empty() {
                    continue;
                }
                let label = format!("{} (slope {:.2})", m.name(), slope(&line));
                chart
                    .draw_series(LineSeries::new(line.clone(), col.stroke_width(2)))
                    .map_err(|e| err(&e))?
                    .label(label)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2)));
                chart
                    .draw_series(line.iter().map(|&p| Circle::new(p, 4, col.filled())))
                    .map_err(|e| err(&e))?;
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK.mix(0.3))
                .label_font(("sans-serif", 13))
                .position(SeriesLabelPosition::LowerRight)
                .draw()
                .map_err(|e| err(&e))?;
        }
        root.present().map_err(|e| err(&e))?;
    }
    crate::studies::bench::write_png_rgb(path, w, h, &buf).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_of_a_power_law() {
        let pts: Vec<(f64, f64)> =
            [1.0, 0.5, 0.25, 0.125].iter().map(|&h: &f64| (h, 3.0 * h.powi(2))).collect();
        assert!((slope(&pts) - 2.0).abs() < 1e-12);
    }
}
