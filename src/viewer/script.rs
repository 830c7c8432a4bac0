//! The scripted runs (`radlab view --screenshot PATH`, `--bench-frames N`): what the run waits
//! for ([`Script`]), the part of the window a screenshot keeps, and the benchmark's report.

use super::bench::{FrameBench, load_average};
use crate::render::RgbaImage;
use eframe::egui::{self, Pos2, Rect, Vec2};

/// Frames drawn before `--bench-frames` starts measuring: the first uploads the geometry.
pub const BENCH_WARMUP_FRAMES: usize = 3;

/// What a scripted run (`--screenshot`, `--bench-frames`) is waiting for.
#[derive(Clone, Debug, PartialEq)]
pub enum Script {
    None,
    /// Waiting for the solve to finish.
    Solving,
    /// Frames left to draw before the screenshot (the geometry must reach the GPU first).
    Settle(u32),
    WaitingShot,
    Bench {
        /// Frames still to draw before measuring (the geometry upload happens in the first).
        warmup: usize,
        bench: FrameBench,
    },
    Done,
}

impl Script {
    /// What follows the solve: the benchmark's frames, or the frames before the screenshot.
    #[must_use]
    pub fn after_solve(bench: bool) -> Script {
        if bench {
            Script::Bench { warmup: BENCH_WARMUP_FRAMES, bench: FrameBench::default() }
        } else {
            Script::Settle(4)
        }
    }
}

/// The part of a window screenshot to keep: `rect` (points), or the whole window.
#[must_use]
pub fn crop(img: &egui::ColorImage, rect: Rect, whole_window: bool, pixels_per_point: f32) -> RgbaImage {
    let ppp = pixels_per_point;
    let full = RgbaImage {
        width: img.size[0] as u32,
        height: img.size[1] as u32,
        pixels: img.pixels.iter().flat_map(|c| c.to_array()).collect(),
    };
    let r = if whole_window {
        Rect::from_min_size(Pos2::ZERO, Vec2::new(full.width as f32, full.height as f32) / ppp)
    } else {
        rect
    };
    full.crop(
        (r.left() * ppp).round() as u32,
        (r.top() * ppp).round() as u32,
        (r.width() * ppp).round() as u32,
        (r.height() * ppp).round() as u32,
    )
}

/// What the benchmark's report says about the scene drawn.
#[derive(Copy, Clone, Debug)]
pub struct BenchScene {
    pub elements: usize,
    pub leaves: usize,
    pub triangles: usize,
    pub links: usize,
    pub links_drawn: usize,
    pub quadtree: bool,
    /// The last display build's time, seconds.
    pub rebuild_s: f64,
    /// The largest geometry upload seen, seconds.
    pub max_upload_s: f64,
}

/// Print the benchmark's two lines: the frames measured after the solve, and those drawn
/// while it ran.
pub fn print_bench(bench: &FrameBench, during_solve: &FrameBench, n: &BenchScene) {
    let s = bench.summary();
    let fmt_cpu = |c: Option<f64>| c.map_or("n/a".to_owned(), |c| format!("{c:.1} ms"));
    println!(
        "radlab: {} frames; {} elements ({} leaves, {} triangles), {} links ({} drawn); quadtree {}; frame time median {:.2} ms, p95 {:.2} ms, max {:.2} ms ({:.1} fps); CPU {} per frame (all threads); UI code median {:.2} ms; last display build {:.1} ms (display thread); load average {}",
        s.frames,
        n.elements,
        n.leaves,
        n.triangles,
        n.links,
        n.links_drawn,
        if n.quadtree { "on" } else { "off" },
        s.median_ms,
        s.p95_ms,
        s.max_ms,
        if s.median_ms > 0.0 { 1e3 / s.median_ms } else { 0.0 },
        fmt_cpu(s.cpu_ms_per_frame),
        s.ui_median_ms,
        n.rebuild_s * 1e3,
        load_average().map_or("n/a".to_owned(), |l| format!("{l:.2}")),
    );
    let d = during_solve.summary();
    let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max) * 1e3;
    println!(
        "radlab: during the solve: {} frames, frame time median {:.2} ms, p95 {:.2} ms, max {:.2} ms; UI code max {:.2} ms wall, {:.2} ms on-CPU; largest geometry upload {:.2} ms",
        d.frames,
        d.median_ms,
        d.p95_ms,
        d.max_ms,
        max(&during_solve.ui_s),
        max(&during_solve.ui_cpu_s),
        n.max_upload_s * 1e3
    );
}
