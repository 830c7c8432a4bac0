//! Speed against error: sweep every solver over its settings on a few scenes, time each run
//! (median of repeats), measure its error against the cached independent reference, and
//! summarise when each method first reaches 1 %, 2 % and 5 % relative L2 error.
//!
//! ```text
//! for scene:   pointwise reference R at N adaptive points (crate::eval::reference::points, cached on disk)
//!   for method ∈ {uniform(h), progressive(shots), hierarchical(Feps/Aeps, BFeps, rays; quadtree
//!                 or contact mesh)}:
//!     t   = median wall time of `repeats` solves (BVH built once, outside the timing)
//!     err = pointwise::score_solution(solution, R)       pointwise rel L1/L2/L∞/p95, energy
//!                                                        residual; element-average rel L2 beside it
//!   curve(method) = lower envelope of (t, err) — the least error reached by time t
//!   t(1 %), t(5 %) = log-log interpolation on the curve; ratio = t_hier / min t_other
//!   uniform missed a target hierarchical reached → finer uniform rows (d/32, d/40, d/48) until
//!     it reaches it or has run 10 × t_hier (each only if its predicted time fits the budget):
//!     then t_hier / t_uniform < t_hier / (longest uniform run) is measured, not extrapolated
//! ```
//!
//! The reference is computed in independent batches (each cached on disk) merged by
//! [`crate::eval::reference::merge_batches`], leaving out the batch that placed the points once
//! another exists ([`crate::eval::reference::scoring_batches`]: its estimates are not independent
//! of where it put them); batches are added until it resolves half the smallest target:
//!
//! ```text
//! noise      = √(Σ a σ²) / √(Σ a (B̂ − E)²)             ≤ REFERENCE_TARGET = 0.5 %   (a: point weights)
//! resolution = 2 · noise · (2/N)^¼                      ≤ REFERENCE_TARGET
//! ```
//!
//! Half the target, not a tenth, because the reported error is the **debiased** L2 (the
//! reference's noise Σaσ² taken out, [`crate::eval::metrics`]), which a misestimated σ² moves far
//! less than noise moves a raw L2. The error is **pointwise** ([`crate::eval::pointwise`]): the
//! solution's own reconstruction at the reference's points, area-weighted, shadow edges included;
//! the element-average error is reported beside it. Every run has a wall-clock budget: a
//! hierarchical run is cancelled through its cancel handle and reported as `over budget`; the
//! classical solvers are bounded by their element caps and shot counts. The rule's figures and
//! the results: docs/performance.md.

mod envelope;
mod measure;
mod plot;
mod sweep;
mod table;

pub use envelope::{EXTRAPOLATE_POINTS, extrapolate_time, pareto, time_to_reach};
pub use plot::plot_png;
pub(crate) use plot::{register_font, write_png_rgb};
pub use sweep::{
    CLUSTER_ROWS_MIN_PATCHES, CONTACT_AEPS_PER_EPS, EXTEND_FACTOR, FAST_CAUSE_TAIL, Method, extension_wanted,
    predict_uniform_time, sweep, uniform_divisions, uniform_extension,
};
pub use table::markdown;

use crate::eval::pointwise::thousands;
use crate::eval::reference::{Cache, Estimate, PointParams, ReferenceParams};
use crate::geometry::accel::Accel;
use crate::scene::Scene;
use crate::studies::hard_cases;
use measure::{curve, extend_uniform, measure, reference_batches, reference_quality, row_line};
use serde::Serialize;
use std::sync::Arc;

/// The scenes `radlab bench` runs by default.
pub const DEFAULT_SCENES: [&str; 4] =
    ["builtin:cornell", "builtin:table-room", "builtin:perpendicular", "builtin:splash_room"];

/// Error targets of the summary (relative L2).
pub const TARGETS: [f64; 3] = [0.01, 0.02, 0.05];

/// A reference resolves an error target when its noise and its resolution are both at most this
/// fraction of the target (the rule in the module docs).
pub const RESOLVE_FRACTION: f64 = 0.5;

/// The standard and full runs add reference batches until it resolves the smallest target.
pub const REFERENCE_TARGET: f64 = RESOLVE_FRACTION * TARGETS[0];

/// Errors of the bench.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error("bench: scene {spec}: {source}")]
    Scene {
        spec: String,
        #[source]
        source: crate::scene::SceneError,
    },
    #[error("bench: scene {spec}: reference: {source}")]
    Reference {
        spec: String,
        #[source]
        source: crate::eval::reference::ReferenceError,
    },
    #[error("bench: scene {spec}: metrics: {source}")]
    Metrics {
        spec: String,
        #[source]
        source: crate::eval::metrics::MetricsError,
    },
    #[error("bench: {0}")]
    Output(String),
}

/// How much to sweep.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// One or two settings per method, one repeat, a rough reference: a CI smoke run.
    Quick,
    Standard,
    /// Finer sweeps, more repeats, a better reference.
    Full,
}

/// Settings of a bench run.
#[derive(Clone, Debug)]
pub struct BenchConfig {
    pub scenes: Vec<String>,
    pub mode: Mode,
    /// Repeats per setting (the median time is reported).
    pub repeats: usize,
    /// Paths per point of one reference batch (batch b uses seed `reference.seed + b`; batch 0
    /// places the points).
    pub reference: ReferenceParams,
    /// The pointwise reference has at least this many points.
    pub reference_points: u32,
    /// Add reference batches until both the reference's noise and its resolution are at most this
    /// relative L2 (see the module docs); `None`: one batch.
    pub reference_target: Option<f64>,
    /// At most this many reference batches.
    pub reference_max_batches: u32,
    /// Wall-clock budget of one solve, seconds.
    pub budget_s: f64,
    pub cache: Cache,
}

impl BenchConfig {
    #[must_use]
    pub fn new(mode: Mode) -> Self {
        // Quick: 4096 points, 64 paths each (a smoke run; the table says how many points).
        let (repeats, samples, reference_points, budget_s) = match mode {
            Mode::Quick => (1, 64, PointParams::quick().points, 5.0),
            Mode::Standard => (3, 1024, PointParams::standard().points, 60.0),
            Mode::Full => (5, 1024, 4 * PointParams::standard().points, 300.0),
        };
        let (reference_target, reference_max_batches) = match mode {
            Mode::Quick => (None, 1),
            Mode::Standard => (Some(REFERENCE_TARGET), 64),
            Mode::Full => (Some(REFERENCE_TARGET), 256),
        };
        BenchConfig {
            scenes: DEFAULT_SCENES.iter().map(|s| (*s).to_string()).collect(),
            mode,
            repeats,
            reference: ReferenceParams { samples, ..ReferenceParams::standard() },
            reference_points,
            reference_target,
            reference_max_batches,
            budget_s,
            cache: Cache::default_location(),
        }
    }
}

/// One measured (scene, method, settings) point.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub scene: String,
    pub method: String,
    pub settings: String,
    /// `ok`, `over budget`, or the solver's error.
    pub status: String,
    pub elements: usize,
    pub links: usize,
    pub rays: u64,
    /// Median wall time of the repeats, seconds.
    pub time_s: f64,
    pub times_s: Vec<f64>,
    /// Pointwise error (the solution's reconstruction at the reference's points), relative L1.
    pub rel_l1: f64,
    /// Pointwise relative L2, raw (includes the reference's noise).
    pub rel_l2: f64,
    /// Pointwise relative L2 with the reference's noise taken out: the bench's error.
    pub rel_l2_debiased: f64,
    /// Raw L∞ (includes the reference's noise).
    pub rel_linf: f64,
    /// L∞ with the reference's noise taken out: max (|ΔB| − kσ)₊ / R (see `metrics`).
    pub rel_linf_debiased: f64,
    /// Area-weighted 95th percentile of the pointwise error / R.
    pub rel_p95: f64,
    /// Area-weighted 99th percentile of the pointwise error / R.
    pub rel_p99: f64,
    /// Element-average error: the element values against the reference averaged over each
    /// element's points, relative L2 debiased (`pointwise::compare_element_averages`).
    pub avg_rel_l2_debiased: f64,
    pub energy_residual: f64,
    /// Smallest L2 error the reference resolves (see `metrics::Norms::resolution`).
    pub resolution: f64,
}

impl Row {
    /// The error used for curves and crossings: the debiased L2, but never below the resolution
    /// (a smaller figure would be a measurement of the reference's noise).
    #[must_use]
    pub fn error(&self) -> f64 {
        self.rel_l2_debiased.max(self.resolution)
    }
}

/// Time a method needs to reach an error target, interpolated on its curve.
#[derive(Clone, Debug, Serialize)]
pub struct Crossing {
    pub method: String,
    pub target: f64,
    /// `None`: not reached by any setting of the sweep.
    pub time_s: Option<f64>,
    /// When the uniform rows did not reach the target: where the power law through their last
    /// rows reaches it ([`extrapolate_time`]), an estimate beyond what was measured. `None` when
    /// reached, for the other methods (progressive refinement converges to its fixed mesh's
    /// answer: its error floors), or when the rows do not fall with time.
    pub extrapolated_s: Option<f64>,
    /// When not reached: the longest time any of the method's rows ran, all with a larger error.
    /// A measured lower bound on its time to the target (for uniform: finer meshes take longer).
    pub not_reached_in_s: Option<f64>,
}

/// The per-scene summary.
#[derive(Clone, Debug, Serialize)]
pub struct SceneSummary {
    pub scene: String,
    pub patches: usize,
    /// Points of the pointwise reference.
    pub reference_points: usize,
    /// Paths per reference point of the batches scored against (`reference::scoring_batches`:
    /// all but the one that placed the points, when there are others).
    pub reference_samples: u32,
    /// Reference batches computed (the first places the points).
    pub reference_batches: u32,
    /// Relative L2 a perfect solver would show against this reference.
    pub reference_noise: f64,
    /// Smallest relative L2 the reference resolves: targets below it read "unresolved".
    pub resolution: f64,
    pub reference_cache: String,
    /// Per target: whether this reference resolves it (noise and resolution both at most
    /// [`RESOLVE_FRACTION`] × the target); crossings of unresolved targets read "unresolved".
    pub resolved: Vec<(f64, bool)>,
    pub crossings: Vec<Crossing>,
    /// Per target: t(hierarchical) / min t(other methods), when both reached it.
    pub ratios: Vec<(f64, Option<f64>)>,
    /// Per target, when hierarchical reached it and no other method did: t(hierarchical) /
    /// min of the others' extrapolated times (an estimate, labelled as such in the report).
    pub ratios_extrapolated: Vec<(f64, Option<f64>)>,
    /// Per target, when hierarchical reached it and the uniform rows did not: t(hierarchical) /
    /// the longest uniform run, all of whose errors were above the target. A measured upper bound
    /// on hierarchical / uniform time to the target (the uniform rows are extended,
    /// [`uniform_extension`], until it is at most 1 / [`EXTEND_FACTOR`]).
    pub ratios_uniform_bound: Vec<(f64, Option<f64>)>,
}

/// Everything a bench run measured.
#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    pub mode: Mode,
    pub repeats: usize,
    pub threads: usize,
    pub rows: Vec<Row>,
    pub scenes: Vec<SceneSummary>,
}

/// Load `builtin:NAME`, `hard:NAME` or a path.
fn load(spec: &str) -> Result<Scene, BenchError> {
    hard_cases::load_scene(spec).map_err(|source| BenchError::Scene { spec: spec.into(), source })
}

/// Run the bench. `log` receives one line per step (scene, reference, each measured point).
pub fn run(config: &BenchConfig, log: &mut dyn FnMut(&str)) -> Result<BenchReport, BenchError> {
    let mut rows = Vec::new();
    let mut scenes = Vec::new();
    for spec in &config.scenes {
        let (summary, scene_rows) = bench_scene(config, spec, log)?;
        scenes.push(summary);
        rows.extend(scene_rows);
    }
    Ok(BenchReport {
        mode: config.mode,
        repeats: config.repeats,
        threads: rayon::current_num_threads(),
        rows,
        scenes,
    })
}

/// One scene of [`run`]: its reference, every setting of its sweep measured (the uniform rows
/// extended where they fell short), and its summary.
fn bench_scene(
    config: &BenchConfig,
    spec: &String,
    log: &mut dyn FnMut(&str),
) -> Result<(SceneSummary, Vec<Row>), BenchError> {
    let scene = Arc::new(load(spec)?);
    let accel = Arc::new(Accel::build(&scene));
    log(&format!(
        "{spec}: {} patches; pointwise reference at ≥ {} points, batches of {} paths per point{}",
        scene.patches.len(),
        thousands(config.reference_points as usize),
        config.reference.samples,
        config.reference_target.map_or_else(String::new, |t| format!(
            " until noise and resolution ≤ {:.2} % (at most {} batches)",
            100.0 * t,
            config.reference_max_batches
        ))
    ));
    let measure::ReferenceBatches { points, estimates, file: cache_file, computed: batches, scoring } =
        reference_batches(config, spec, &scene, &accel, log)?;
    let reference: &[Estimate] = &estimates;
    let (noise, resolution) = reference_quality(&scene, &points, reference)
        .map_err(|e| BenchError::Output(format!("{spec}: {e}")))?;
    let resolves =
        |target: f64| noise <= RESOLVE_FRACTION * target && resolution <= RESOLVE_FRACTION * target;
    let mut scene_rows: Vec<Row> = Vec::new();
    for method in sweep(&scene, config.mode) {
        let r = measure(config, spec, &scene, &accel, &method, &points, reference)?;
        log(&row_line(&r));
        scene_rows.push(r);
    }
    extend_uniform(config, spec, &scene, &accel, &points, reference, resolves, &mut scene_rows, log)?;
    let mut summary = SceneSummary {
        scene: spec.clone(),
        patches: scene.patches.len(),
        reference_points: points.len(),
        reference_samples: config.reference.samples * scoring,
        reference_batches: batches,
        reference_noise: noise,
        resolution,
        reference_cache: cache_file,
        resolved: Vec::new(),
        crossings: Vec::new(),
        ratios: Vec::new(),
        ratios_extrapolated: Vec::new(),
        ratios_uniform_bound: Vec::new(),
    };
    for &target in &TARGETS {
        summarise_target(&mut summary, &scene_rows, target, resolves(target));
    }
    Ok((summary, scene_rows))
}

/// Add to `summary` each method's crossing of `target` and the hierarchical solver's time ratios
/// at it (`None` where the reference does not resolve the target, `resolved` false).
fn summarise_target(summary: &mut SceneSummary, rows: &[Row], target: f64, resolved: bool) {
    let mut hier = None;
    let mut best_other: Option<f64> = None;
    let mut best_extrapolated: Option<f64> = None;
    let mut uniform_not_reached_in: Option<f64> = None;
    for m in ["uniform", "progressive", "hierarchical"] {
        let pts = curve(rows, m);
        let t = time_to_reach(&pts, target);
        let not_reached_in = if t.is_none() { pts.iter().map(|p| p.0).reduce(f64::max) } else { None };
        if m == "uniform" {
            uniform_not_reached_in = not_reached_in;
        }
        // Only the uniform rows refine their mesh; progressive refinement converges to its
        // fixed mesh's answer, whose error floors above the targets (no power law).
        let extrapolated = if t.is_none() && m == "uniform" { extrapolate_time(&pts, target) } else { None };
        if m == "hierarchical" {
            hier = t;
        } else if let Some(t) = t {
            best_other = Some(best_other.map_or(t, |b: f64| b.min(t)));
        } else if let Some(t) = extrapolated {
            best_extrapolated = Some(best_extrapolated.map_or(t, |b: f64| b.min(t)));
        }
        summary.crossings.push(Crossing {
            method: m.into(),
            target,
            time_s: t,
            extrapolated_s: extrapolated,
            not_reached_in_s: not_reached_in,
        });
    }
    summary
        .ratios_uniform_bound
        .push((target, hier.zip(uniform_not_reached_in).filter(|_| resolved).map(|(h, u)| h / u)));
    summary.ratios.push((target, hier.zip(best_other).map(|(h, o)| h / o).filter(|_| resolved)));
    summary.ratios_extrapolated.push((
        target,
        hier.zip(best_extrapolated).filter(|_| best_other.is_none() && resolved).map(|(h, o)| h / o),
    ));
    summary.resolved.push((target, resolved));
}
