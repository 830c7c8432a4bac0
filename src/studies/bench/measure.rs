//! Measuring the rows: the reference in independent batches (seeds s, s + 1, …, each cached)
//! merged until its noise and resolution meet the target, each setting solved `repeats` times
//! under its budget (median wall time) and scored pointwise against the reference, and the
//! uniform rows extended where they missed a target the hierarchical rows reached.

use super::sweep::{
    Method, extension_wanted, predict_uniform_time, uniform_divisions, uniform_extension, uniform_row,
};
use super::{BenchConfig, BenchError, Row, TARGETS};
use crate::eval::pointwise::{self, thousands};
use crate::eval::reference::{Control, Estimate, PointParams, RefPoint};
use crate::geometry::accel::Accel;
use crate::scene::Scene;
use crate::solver::Solution;
use std::sync::Arc;
use std::time::{Duration, Instant};

fn median(xs: &mut [f64]) -> f64 {
    xs.sort_by(f64::total_cmp);
    let n = xs.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        xs[n / 2]
    } else {
        0.5 * (xs[n / 2 - 1] + xs[n / 2])
    }
}

/// A measured row as the bench's log shows it.
pub(super) fn row_line(r: &Row) -> String {
    format!(
        "  {:<12} {:<46} {:>7} el {:>9} links {:>8.3} s  pointwise L2 {:>7.3} %  {}",
        r.method,
        r.settings,
        r.elements,
        r.links,
        r.time_s,
        100.0 * r.error(),
        r.status
    )
}

/// Points (time, error) of the rows of one method that ran.
pub(super) fn curve(rows: &[Row], method: &str) -> Vec<(f64, f64)> {
    rows.iter().filter(|r| r.method == method && r.status == "ok").map(|r| (r.time_s, r.error())).collect()
}

/// Add finer uniform rows ([`uniform_extension`]) after the last uniform row while, for some
/// resolved target that the hierarchical rows reached, the uniform rows have neither reached it
/// nor run [`EXTEND_FACTOR`] × the hierarchical time to it, and the next size's predicted time
/// ([`predict_uniform_time`]) fits the budget.
#[allow(clippy::too_many_arguments)]
pub(super) fn extend_uniform(
    config: &BenchConfig,
    spec: &str,
    scene: &Arc<Scene>,
    accel: &Arc<Accel>,
    points: &[RefPoint],
    reference: &[Estimate],
    resolves: impl Fn(f64) -> bool,
    rows: &mut Vec<Row>,
    log: &mut dyn FnMut(&str),
) -> Result<(), BenchError> {
    let d = scene.bounds().diagonal();
    // The last uniform row's size, diagonal / k.
    let mut k_last = uniform_divisions(config.mode).last().copied().unwrap_or(f64::NAN);
    for &k_next in uniform_extension(config.mode) {
        debug_assert!(k_next > k_last, "the extension refines the sweep's sizes");
        let (hier, uni) = (curve(rows, "hierarchical"), curve(rows, "uniform"));
        if !TARGETS.iter().any(|&target| resolves(target) && extension_wanted(&hier, &uni, target)) {
            return Ok(());
        }
        let Some(last) = rows.iter().rposition(|r| r.method == "uniform") else { return Ok(()) };
        if rows[last].status != "ok" {
            return Ok(());
        }
        let predicted = predict_uniform_time(rows[last].time_s, k_last, k_next);
        if predicted > config.budget_s {
            log(&format!(
                "  uniform h = d/{k_next}: not run, predicted {predicted:.0} s exceeds the budget of {} s",
                config.budget_s
            ));
            return Ok(());
        }
        let method = uniform_row(d / k_next);
        let r = measure(config, spec, scene, accel, &method, points, reference)?;
        log(&format!(
            "{} (extended: uniform had not reached a target the hierarchical rows reached)",
            row_line(&r)
        ));
        rows.insert(last + 1, r);
        k_last = k_next;
    }
    Ok(())
}

/// The reference's (noise, resolution) as relative L2 (a perfect solver's comparison with it).
pub(super) fn reference_quality(
    scene: &Scene,
    points: &[RefPoint],
    estimates: &[Estimate],
) -> Result<(f64, f64), String> {
    let values: Vec<_> = estimates.iter().map(|e| e.radiosity).collect();
    let r = pointwise::compare_points(scene, points, &values, estimates, 0.0).map_err(|e| e.to_string())?;
    Ok((r.scene.reference_noise, r.scene.resolution))
}

/// The pointwise reference a scene's rows are scored against ([`reference_batches`]).
pub(super) struct ReferenceBatches {
    pub(super) points: Vec<RefPoint>,
    /// The scoring estimates (`reference::scoring_batches`).
    pub(super) estimates: Vec<Estimate>,
    /// The last batch's cache file.
    pub(super) file: String,
    /// Batches computed, and merged into `estimates`.
    pub(super) computed: u32,
    pub(super) scoring: u32,
}

/// Compute (or read from the cache) reference batches with seeds seed, seed + 1, … until the
/// merged reference meets `config.reference_target` or `reference_max_batches` is reached,
/// logging each batch. Batch 0 places the points; the others re-estimate them, and once there
/// are any they alone are the reference (`reference::scoring_batches`). Returns the points, the
/// scoring estimates, the last batch's cache file, the batches computed and the batches merged.
pub(super) fn reference_batches(
    config: &BenchConfig,
    spec: &str,
    scene: &Scene,
    accel: &Accel,
    log: &mut dyn FnMut(&str),
) -> Result<ReferenceBatches, BenchError> {
    let ref_err = |source| BenchError::Reference { spec: spec.into(), source };
    let mut batches: Vec<Vec<Estimate>> = Vec::new();
    let max = config.reference_max_batches.max(1);
    let t0 = Instant::now();
    let layout = PointParams {
        points: config.reference_points,
        paths: config.reference,
        layout_seed: config.reference.seed,
        ..PointParams::standard()
    };
    loop {
        let b = batches.len() as u32;
        let params = layout.batch(config.reference.seed.wrapping_add(u64::from(b)));
        let (entry, status) = config
            .cache
            .get_or_compute_points(scene, accel, &params, &Control::default())
            .map_err(ref_err)?;
        let (how, file) = status.describe(entry.compute_s);
        let file = file.display().to_string();
        batches.push(entry.estimates);
        let points = entry.set.points;
        let (merged, scoring) = crate::eval::reference::scoring_batches(&batches)
            .expect("batches of one point set have equal length");
        let (noise, res) = reference_quality(scene, &points, &merged)
            .map_err(|e| BenchError::Output(format!("{spec}: {e}")))?;
        log(&format!(
            "  reference batch {}/{max} ({how}; {:.0} s so far): {} points, {} paths per point scored, noise {:.3} %, resolution {:.3} %  [{file}]",
            b + 1,
            t0.elapsed().as_secs_f64(),
            thousands(points.len()),
            u64::from(config.reference.samples) * scoring as u64,
            100.0 * noise,
            100.0 * res
        ));
        let done = config.reference_target.is_none_or(|t| noise <= t && res <= t);
        if done || b + 1 >= max {
            if !done {
                log(&format!(
                    "  reference: target not met after {max} batches; the table marks what it cannot resolve"
                ));
            }
            // The enclosed points are left out of the scores (`points::enclosed`).
            let (points, merged, enclosed) =
                crate::eval::reference::points::without_enclosed(scene, accel, &points, &merged);
            if enclosed > 0 {
                log(&format!("  reference: {} enclosed points left out of the scores", thousands(enclosed)));
            }
            return Ok(ReferenceBatches {
                points,
                estimates: merged,
                file,
                computed: b + 1,
                scoring: scoring as u32,
            });
        }
    }
}

/// Measure one setting.
pub(super) fn measure(
    config: &BenchConfig,
    spec: &str,
    scene: &Arc<Scene>,
    accel: &Arc<Accel>,
    method: &Method,
    points: &[RefPoint],
    reference: &[Estimate],
) -> Result<Row, BenchError> {
    let budget = Duration::from_secs_f64(config.budget_s);
    let mut times = Vec::new();
    let mut last: Option<Solution> = None;
    let mut status = "ok".to_string();
    for _ in 0..config.repeats.max(1) {
        match method.run(scene, accel, budget) {
            Ok(Some((sol, secs))) => {
                times.push(secs);
                last = Some(sol);
            }
            Ok(None) => {
                status = "over budget".into();
                break;
            }
            Err(e) => {
                status = e;
                break;
            }
        }
    }
    let mut row = Row {
        scene: spec.into(),
        method: method.name().into(),
        settings: method.settings(),
        status,
        elements: 0,
        links: 0,
        rays: 0,
        time_s: f64::NAN,
        times_s: times.clone(),
        rel_l1: f64::NAN,
        rel_l2: f64::NAN,
        rel_l2_debiased: f64::NAN,
        rel_linf: f64::NAN,
        rel_linf_debiased: f64::NAN,
        rel_p95: f64::NAN,
        rel_p99: f64::NAN,
        avg_rel_l2_debiased: f64::NAN,
        energy_residual: f64::NAN,
        resolution: f64::NAN,
    };
    let Some(sol) = last.filter(|_| row.status == "ok") else { return Ok(row) };
    let score = pointwise::score_solution(scene, &sol, points, reference)
        .map_err(|source| BenchError::Metrics { spec: spec.into(), source })?;
    let rep = &score.pointwise;
    row.elements = sol.elements.len();
    row.links = sol.stats.links;
    row.rays = sol.stats.rays;
    row.time_s = median(&mut times);
    row.rel_l1 = rep.scene.l1;
    row.rel_l2 = rep.scene.l2;
    row.rel_l2_debiased = rep.scene.l2_debiased;
    row.rel_linf = rep.scene.linf;
    row.rel_linf_debiased = rep.scene.linf_debiased;
    row.rel_p95 = rep.scene.p95;
    row.rel_p99 = rep.scene.p99;
    row.avg_rel_l2_debiased = score.element_average.scene.l2_debiased;
    row.energy_residual = rep.energy_residual;
    row.resolution = rep.scene.resolution;
    Ok(row)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_even_and_odd() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), 2.5);
    }
}
