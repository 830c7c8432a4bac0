//! The scripted runs (`radlab view --screenshot PATH`, `--bench-frames N`): what the run waits
//! for ([`Script`]) and what it keeps on the way ([`ScriptRun`]: the screenshot asked for, the
//! frame times, how it ends), the part of the window a screenshot keeps, and the benchmark's
//! report.

use super::bench::{FrameBench, load_average};
use crate::render::RgbaImage;
use eframe::egui::{self, Pos2, Rect, Vec2};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, channel};

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
    /// `--bench-thresholds`: the thresholds still to set, and the change waiting for its
    /// picture (from, to, when it was made).
    Thresholds {
        left: Vec<f64>,
        waiting: Option<(f64, f64, std::time::Instant)>,
    },
    Done,
}

impl Script {
    /// What follows the solve: the threshold changes (`thresholds`, when there are any), the
    /// benchmark's frames, or the frames before the screenshot.
    #[must_use]
    pub fn after_solve(bench: bool, thresholds: &[f64]) -> Script {
        if !thresholds.is_empty() {
            Script::Thresholds { left: thresholds.to_vec(), waiting: None }
        } else if bench {
            Script::Bench { warmup: BENCH_WARMUP_FRAMES, bench: FrameBench::default() }
        } else {
            Script::Settle(4)
        }
    }
}

/// A scripted run as it goes (also an interactive window's screenshot, asked for by the top
/// bar's button): what it waits for, the screenshot on its way, the frame times the benchmark
/// reports, and how the run ends.
pub struct ScriptRun {
    pub(super) script: Script,
    /// The screenshot asked for, until egui hands it over.
    shot_rx: Option<Receiver<Arc<egui::ColorImage>>>,
    /// Frame times while a scripted benchmark waits for its solve.
    pub(super) solve_frames: FrameBench,
    /// Longest geometry upload seen (seconds; read from the renderer).
    pub(super) max_upload_s: f64,
    /// Wall time of the last `ui` call (seconds).
    pub(super) last_ui_s: f64,
    /// On-CPU time of the last `ui` call (benchmarks only).
    pub(super) last_ui_cpu_s: Option<f64>,
    /// Set when the window should close (scripted runs); read by the runner.
    pub(super) exit_code: Option<i32>,
    /// Why a scripted run failed (its first failure, one line): the runner's error message.
    pub(super) exit_error: Option<String>,
}

impl Default for ScriptRun {
    fn default() -> ScriptRun {
        ScriptRun {
            script: Script::None,
            shot_rx: None,
            solve_frames: FrameBench::default(),
            max_upload_s: 0.0,
            last_ui_s: 0.0,
            last_ui_cpu_s: None,
            exit_code: None,
            exit_error: None,
        }
    }
}

impl ScriptRun {
    /// A scripted run cannot go on: it ends with an error, whose message is its first
    /// failure's (`message`, one line; nothing in a window: the error list shows it).
    pub fn failed(&mut self, message: String) {
        if self.script != Script::None {
            self.exit_code = Some(1);
            self.exit_error.get_or_insert(message);
        }
    }

    /// The solver thread finished a command and has nothing left (`idle`): a run waiting for
    /// its solve goes on to the benchmark's frames (`bench`) or the screenshot's.
    pub fn solver_answered(&mut self, idle: bool, bench: bool, thresholds: &[f64]) {
        if self.script == Script::Solving && idle {
            self.script = Script::after_solve(bench, thresholds);
        }
    }

    /// The run is over: the window closes with success unless it failed first.
    pub fn finish(&mut self) {
        self.script = Script::Done;
        self.exit_code.get_or_insert(0);
    }

    /// The window should close: the run is done, or it failed.
    #[must_use]
    pub fn should_close(&self) -> bool {
        self.exit_code.is_some_and(|code| self.script == Script::Done || code != 0)
    }

    /// Ask egui for a screenshot of the next frame.
    pub fn request_screenshot(&mut self, ctx: &egui::Context) {
        let (tx, rx) = channel();
        ctx.request_screenshot(move |img| {
            let _ = tx.send(img);
        });
        self.shot_rx = Some(rx);
        ctx.request_repaint();
    }

    /// The screenshot asked for, once egui has taken it (`None`: none asked for, or not taken
    /// yet; then another frame is asked for).
    pub fn take_screenshot(&mut self, ctx: &egui::Context) -> Option<Arc<egui::ColorImage>> {
        let rx = self.shot_rx.as_ref()?;
        let Ok(img) = rx.try_recv() else {
            ctx.request_repaint();
            return None;
        };
        self.shot_rx = None;
        Some(img)
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
