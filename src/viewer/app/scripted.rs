//! Files and the scripted runs: the file dialog's answers (open a scene, export a bake), the
//! screenshot once egui has taken it, and each frame of a scripted run (`--screenshot`,
//! `--bench-frames`): wait for the solve, let the display settle, then shoot or measure.

use super::RadlabApp;
use crate::viewer::file_dialog::{Answer, Purpose};
use crate::viewer::geometry::ShownGeometry;
use crate::viewer::script::{self, BenchScene, Script};
use crate::viewer::worker::{Command, ViewData};
use eframe::egui;
use std::path::PathBuf;
use std::time::Instant;

impl RadlabApp {
    /// What the file dialog answered: a scene to open, a file to export to, or nothing chosen.
    pub(super) fn file_answer(&mut self, answer: Answer) {
        match answer {
            Answer::Chosen(Purpose::Open, path) => self.load_spec(&path.to_string_lossy()),
            Answer::Chosen(Purpose::ExportBake { lightmap, .. }, path) => self.export_bake(path, lightmap),
            Answer::Cancelled(_) => self.status_bar.message = "no file chosen".into(),
            Answer::FellBack(note) => self.status_bar.message = note,
        }
    }

    /// Write the solution shown as a baked glTF (on the solver thread), at the display's
    /// exposure: vertex colours per element, or with `lightmap` the original meshes with a
    /// lightmap of that size (the CLI's `--bake-lightmap SIZE`); the answer is one line in the
    /// status bar, or an error.
    pub fn export_bake(&mut self, path: PathBuf, lightmap: Option<u32>) {
        let Some(scene) = &self.scene else { return };
        let overwrites_input = std::fs::canonicalize(&path)
            .is_ok_and(|p| std::fs::canonicalize(&scene.source).is_ok_and(|s| s == p));
        if overwrites_input {
            self.errors.push(format!(
                "export {}: that is the scene shown; refusing to overwrite it",
                path.display()
            ));
            return;
        }
        let ev = self.display.exposure_ev;
        let options = crate::present::bake::BakeOptions {
            exposure: 2f64.powf(f64::from(ev)),
            exposure_rule: format!(
                "the viewer's exposure 2^EV, EV = {ev:.1}{}",
                if self.display.auto_exposure {
                    " (auto: the 95th percentile of the lit surfaces' luminance at 0.8)"
                } else {
                    ""
                }
            ),
            scene_label: self.scene_spec.clone(),
            params: serde_json::to_value(self.solve.params).ok(),
        };
        let form = lightmap.map_or(crate::present::bake::BakeForm::Elements, |size| {
            crate::present::bake::BakeForm::Lightmap(crate::present::bake::LightmapParams::new(size))
        });
        self.solve.send(Command::Bake { path, options, form }, "baking");
    }

    /// Save the screenshot asked for, once egui has taken it: the viewport (or, for a scripted
    /// run that asks for it, the whole window) to the path asked for, else to a name of the
    /// scene's. A scripted run is over once it is saved.
    pub(super) fn handle_screenshot(&mut self, ctx: &egui::Context) {
        let Some(img) = self.script.take_screenshot(ctx) else { return };
        let waiting = self.script.script == Script::WaitingShot;
        let whole = self.opts.screenshot_window && waiting;
        let shot = script::crop(&img, self.framing.rect, whole, ctx.pixels_per_point());
        let path = self.opts.screenshot.clone().unwrap_or_else(|| {
            let name = self.scene.as_ref().map_or("radlab".to_owned(), |s| s.name.clone());
            PathBuf::from(format!("{name}-{}.png", self.geometry.generation))
        });
        let saved = match shot.save_png(&path) {
            Ok(()) => {
                self.status_bar.message = format!("saved {}", path.display());
                true
            }
            Err(e) => {
                self.errors.push(format!("screenshot: {e}"));
                self.script_failed(format!("screenshot: {e}"));
                false
            }
        };
        if waiting {
            if saved {
                println!("radlab: wrote {}", path.display());
                // A figure's caption quotes the state shown: printed with its picture, so that
                // documentation quoting it can be checked against the program.
                if let Some(caption) = self.lecture.caption().filter(|_| self.lecture.figure().is_some()) {
                    println!("radlab: caption: {caption}");
                }
            }
            self.script.finish();
        }
    }

    /// A scripted run's frame: keep drawing while the solve runs (a benchmark measures those
    /// frames), let the display settle and ask for the screenshot, or measure the benchmark's
    /// frames and print its report.
    pub(super) fn run_script(&mut self, ctx: &egui::Context) {
        // The solver's error estimates are on their way and something shown reads them: no
        // frames until they come (their reply asks for one), drawing would slow them down.
        if self.shows_pending_estimates()
            && matches!(self.script.script, Script::Settle(_) | Script::Bench { .. })
        {
            return;
        }
        // The display is final when the newest build is shown and the reference thread has
        // nothing left to report (its look-up or a score changes the error overlay).
        let current = self.geometry.current()
            && !self.split.building()
            && !self.replay.building()
            && !self.comparison.reference.busy()
            && !self.artifacts.busy();
        if let Script::Thresholds { .. } = self.script.script {
            self.bench_thresholds(ctx, current);
            return;
        }
        let run = &mut self.script;
        match &mut run.script {
            Script::None | Script::Done | Script::WaitingShot | Script::Thresholds { .. } => {}
            Script::Solving => {
                if self.opts.bench_frames.is_some() {
                    // Keep drawing while the solver runs: the UI must not wait on it.
                    run.solve_frames.tick(Instant::now(), run.last_ui_s, run.last_ui_cpu_s);
                    self.framing.camera.orbit(0.002, 0.0);
                    ctx.request_repaint();
                }
            }
            Script::Settle(n) => {
                let n = *n;
                if n == 0 {
                    // The display thread may still be building the last change.
                    if current {
                        run.script = Script::WaitingShot;
                        run.request_screenshot(ctx);
                    }
                } else {
                    run.script = Script::Settle(n - 1);
                }
                ctx.request_repaint();
            }
            Script::Bench { warmup, bench } => {
                if *warmup > 0 || !current {
                    *warmup -= usize::from(current && *warmup > 0);
                } else {
                    bench.tick(Instant::now(), run.last_ui_s, run.last_ui_cpu_s);
                }
                // Spin the camera a little so every frame really redraws.
                self.framing.camera.orbit(0.002, 0.0);
                if bench.frames() >= self.opts.bench_frames.unwrap_or(0) {
                    let scene = bench_scene(
                        &self.shown.view,
                        &self.geometry,
                        self.display.quadtree,
                        run.max_upload_s,
                    );
                    script::print_bench(bench, &run.solve_frames, &scene);
                    run.finish();
                }
                ctx.request_repaint();
            }
        }
    }

    /// `--bench-thresholds`: once the last picture is on screen, set the next threshold as the
    /// Solver panel's slider does; once that change's picture is on screen (its solve answered,
    /// nothing held back, its display built), print the time it took. `current`: the display
    /// shows the newest build asked for.
    fn bench_thresholds(&mut self, ctx: &egui::Context, current: bool) {
        let Script::Thresholds { left, waiting } = &self.script.script else { return };
        let (next, waiting) = (left.first().copied(), *waiting);
        let shown = current && !self.solve.busy() && !self.solve.resolve_pending && !self.shown.hold;
        match waiting {
            None if shown => {
                let Some(to) = next else {
                    self.script.finish();
                    return;
                };
                let from = self.solve.params.bf_eps;
                if let Script::Thresholds { left, waiting } = &mut self.script.script {
                    left.remove(0);
                    *waiting = Some((from, to, Instant::now()));
                }
                self.set_params(crate::viewer::solver_panel::slide_threshold(self.solve.params, to));
            }
            Some((from, to, at)) if shown && self.shown.view.params.bf_eps.to_bits() == to.to_bits() => {
                let s = at.elapsed().as_secs_f64();
                if let Script::Thresholds { waiting, .. } = &mut self.script.script {
                    *waiting = None;
                }
                let how = self.log.last_solve.map_or_else(|| "not solved".to_owned(), |n| n.text());
                let st = &self.shown.view.stats;
                println!(
                    "radlab: threshold {from} -> {to}: picture on screen in {s:.3} s ({how}; {} leaves, {} links)",
                    st.leaves, st.links
                );
            }
            _ => {}
        }
        ctx.request_repaint();
    }
}

/// What the benchmark's report says about the scene drawn: the solution `view` as `geometry`
/// draws it (with the quadtree overlay or not), and the largest geometry upload seen.
fn bench_scene(view: &ViewData, geometry: &ShownGeometry, quadtree: bool, max_upload_s: f64) -> BenchScene {
    BenchScene {
        elements: view.stats.elements,
        leaves: view.leaves.len(),
        triangles: geometry.geometry.mesh.triangles(),
        links: view.links.len(),
        links_drawn: geometry.geometry.links.len() / 2,
        quadtree,
        rebuild_s: geometry.rebuild_s,
        max_upload_s,
    }
}
