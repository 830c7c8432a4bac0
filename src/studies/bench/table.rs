//! The report as Markdown: every measured row, then per scene each method's time to 5 % and
//! 1 % pointwise error (or where it stopped short, with the extrapolated estimate), the ratio of
//! the hierarchical solver's time to the best other's, and the convergence of the error oracle
//! on the contact mesh as its threshold halves.

use super::sweep::{CLUSTER_MARK, CONTACT_MARK, FAST_CAUSE_TAIL, TAIL_MARK};
use super::{BenchReport, Row, SceneSummary, TARGETS};
use crate::eval::pointwise::thousands;

fn pct(x: f64) -> String {
    if x.is_finite() { format!("{:.2} %", 100.0 * x) } else { "–".into() }
}

fn secs(t: Option<f64>) -> String {
    t.map_or_else(|| "not reached".into(), |t| format!("{t:.3} s"))
}

/// A ratio of times: two decimals, three below 0.1 (0.095×), two significant digits below 0.01 (1.2e-3×).
pub(super) fn times(r: f64) -> String {
    if r > 0.0 && r < 0.01 {
        format!("{r:.1e}×")
    } else if r > 0.0 && r < 0.1 {
        format!("{r:.3}×")
    } else {
        format!("{r:.2}×")
    }
}

/// An extrapolated time, to two significant digits (it is an estimate).
pub(super) fn secs_rough(t: f64) -> String {
    if t >= 1e7 {
        format!("{t:.1e} s")
    } else if t >= 100.0 {
        let p = 10f64.powi(t.log10().floor() as i32 - 1);
        format!("{} s", thousands(((t / p).round() * p) as usize))
    } else {
        format!("{t:.2} s")
    }
}

/// The report as Markdown: the full table, then per scene the time to 5 %, 2 % and 1 % and the
/// ratios.
#[must_use]
pub fn markdown(report: &BenchReport) -> String {
    let mut s = String::new();
    s.push_str(&format!(
        "Mode `{:?}`, median of {} run(s), {} thread(s). **Pointwise** errors of the reflected radiosity: each solution's piecewise-constant reconstruction at the points of the independent reference ({}; the enclosed points, inside a closed solid, left out), each point weighted by the area it stands for, relative to the RMS reflected radiosity (see `radlab::eval::pointwise`): rel L2 debiased (the reference's noise Σaσ² taken out; \"< x\" where below what the reference resolves); L∞ debiased, max (|ΔB| − kσ)₊ with k = √(2 ln(3N/0.05)) so that the reference's noise alone reads 0 with 95 % probability (the raw L∞ is in the JSON); p95, the level that 5 % of the area exceeds (robust, but not debiased). Beside them the element-average rel L2: element values against the reference averaged over each element's points.\n\n",
        report.mode,
        report.repeats,
        report.threads,
        report
            .scenes
            .iter()
            .map(|sc| format!(
                "{} {} points, noise {}",
                sc.scene.trim_start_matches("builtin:"),
                thousands(sc.reference_points),
                pct(sc.reference_noise)
            ))
            .collect::<Vec<_>>()
            .join("; ")
    ));
    s.push_str(&rows_table(&report.rows));
    s.push_str(
        "\n| scene | reference points / paths per point / noise / resolution | method | time to 5 % | time to 2 % | time to 1 % | least pointwise error reached (time) |\n|---|---:|---|---:|---:|---:|---:|\n",
    );
    for sc in &report.scenes {
        s.push_str(&scene_summary(report, sc));
    }
    s.push_str(&convergence_lines(report));
    s
}

/// The table of every measured row.
fn rows_table(rows: &[Row]) -> String {
    let mut s = String::new();
    s.push_str(
        "| scene | method | settings | elements | links | rays | time | pointwise rel L2 (debiased) | rel L∞ (debiased) | rel p95 | element-avg rel L2 | energy residual |\n",
    );
    s.push_str("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for r in rows {
        let time = if r.status == "ok" { format!("{:.3} s", r.time_s) } else { r.status.clone() };
        s.push_str(&format!(
            "| {} | {} | `{}` | {} | {} | {} | {} | {} | {} | {} | {} | {:.1e} |\n",
            r.scene.trim_start_matches("builtin:"),
            r.method,
            r.settings,
            r.elements,
            r.links,
            r.rays,
            time,
            if r.rel_l2_debiased < r.resolution {
                format!("< {}", pct(r.resolution))
            } else {
                pct(r.rel_l2_debiased)
            },
            pct(r.rel_linf_debiased),
            pct(r.rel_p95),
            pct(r.avg_rel_l2_debiased),
            r.energy_residual
        ));
    }
    s
}

/// The summary's targets, coarsest first (its columns).
const COLUMNS: [f64; 3] = [TARGETS[2], TARGETS[1], TARGETS[0]];

/// One summary row: `label` and one cell per target of [`COLUMNS`].
fn summary_row(name: &str, label: &str, cells: [String; 3]) -> String {
    format!("| {name} | | {label} | {} | {} | {} | |\n", cells[0], cells[1], cells[2])
}

/// One scene's rows of the summary table: each method's time to 5 %, 2 % and 1 % and the least
/// error it reached, then the hierarchical solver's time ratios.
fn scene_summary(report: &BenchReport, sc: &SceneSummary) -> String {
    let mut s = String::new();
    for m in ["uniform", "progressive", "hierarchical"] {
        let crossing =
            |target: f64| sc.crossings.iter().find(|c| c.method == m && (c.target - target).abs() < 1e-12);
        let cell = |target: f64| {
            let ok = sc.resolved.iter().any(|&(t, r)| (t - target).abs() < 1e-12 && r);
            let c = crossing(target);
            match (ok, c.and_then(|c| c.time_s), c.and_then(|c| c.extrapolated_s)) {
                (false, _, _) => "unresolved".to_string(),
                (true, None, Some(x)) => format!(
                    "not reached in {} (extrapolated ~{})",
                    c.and_then(|c| c.not_reached_in_s).map_or_else(|| "–".into(), |t| format!("{t:.3} s")),
                    secs_rough(x)
                ),
                (true, None, None) => match c.and_then(|c| c.not_reached_in_s) {
                    Some(t) => format!("not reached in {t:.3} s"),
                    None => "not reached".into(),
                },
                (true, t, _) => secs(t),
            }
        };
        let best = report
            .rows
            .iter()
            .filter(|r| r.scene == sc.scene && r.method == m && r.status == "ok")
            .min_by(|a, b| a.error().total_cmp(&b.error()))
            .map_or_else(|| "–".into(), |r| format!("{} ({:.3} s)", pct(r.error()), r.time_s));
        s.push_str(&format!(
            "| {} | {} / {} / {} / {} | {m} | {} | {} | {} | {best} |\n",
            sc.scene.trim_start_matches("builtin:"),
            thousands(sc.reference_points),
            sc.reference_samples,
            pct(sc.reference_noise),
            pct(sc.resolution),
            cell(COLUMNS[0]),
            cell(COLUMNS[1]),
            cell(COLUMNS[2])
        ));
    }
    let name = sc.scene.trim_start_matches("builtin:");
    let ratio = |target: f64| at(&sc.ratios, target).map_or_else(|| "n/a".into(), |r| format!("{r:.2}×"));
    s.push_str(&summary_row(name, "**hierarchical / best other**", COLUMNS.map(ratio)));
    // Rows shown only where a target has a value.
    let mut optional_row = |label: &str, cell: &dyn Fn(f64) -> Option<String>| {
        let cells = COLUMNS.map(cell);
        if cells.iter().any(Option::is_some) {
            s.push_str(&summary_row(name, label, cells.map(|c| c.unwrap_or_else(|| "n/a".to_string()))));
        }
    };
    optional_row("hierarchical / **uniform** (uniform had not reached it in its longest run)", &|t| {
        at(&sc.ratios_uniform_bound, t).map(|r| format!("< {} (measured)", times(r)))
    });
    optional_row("hierarchical / best other's **extrapolated** time", &|t| {
        at(&sc.ratios_extrapolated, t).map(|r| format!("{} (estimate)", times(r)))
    });
    s
}

/// The value of a per-target list ([`SceneSummary::ratios`] and the like) at `target`.
fn at(per_target: &[(f64, Option<f64>)], target: f64) -> Option<f64> {
    per_target.iter().find(|(t, _)| (t - target).abs() < 1e-12).and_then(|(_, r)| *r)
}

/// How many steps of `errors` rise by more than `resolution`.
fn rises_beyond(errors: &[f64], resolution: f64) -> usize {
    errors.windows(2).filter(|w| w[1] > w[0] + resolution).count()
}

/// The convergence check, per scene: the contact-mesh rows' errors in sweep order
/// (each halving the threshold), and whether each halving lowered the error — a rise counts only
/// above the reference's resolution; a run over budget ends the sequence.
fn convergence_lines(report: &BenchReport) -> String {
    let mut s = String::new();
    for sc in &report.scenes {
        for (clustered, tailed) in [(false, false), (true, false), (true, true)] {
            let rows: Vec<&Row> = report
                .rows
                .iter()
                .filter(|r| {
                    r.scene == sc.scene
                        && r.settings.contains(CONTACT_MARK)
                        && r.settings.contains(CLUSTER_MARK) == clustered
                        && r.settings.contains(TAIL_MARK) == tailed
                        && r.status == "ok"
                })
                .collect();
            if rows.len() < 2 {
                continue;
            }
            if s.is_empty() {
                s.push_str("\nConvergence of the error oracle on the contact mesh, each row halving the threshold (pointwise rel L2, debiased):\n\n");
            }
            let seq: Vec<String> = rows.iter().map(|r| pct(r.error())).collect();
            let errors: Vec<f64> = rows.iter().map(|r| r.error()).collect();
            let rises = rises_beyond(&errors, sc.resolution);
            s.push_str(&format!(
                "- {}{}: {} — {}\n",
                sc.scene.trim_start_matches("builtin:"),
                match (clustered, tailed) {
                    (true, true) => format!(" (clustered, tail share {FAST_CAUSE_TAIL})"),
                    (true, false) => " (clustered)".to_string(),
                    _ => String::new(),
                },
                seq.join(" → "),
                if rises == 0 {
                    "each halving lowered the error (within the resolution)".to_string()
                } else {
                    format!("{rises} halving(s) raised it beyond the resolution")
                }
            ));
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::studies::bench::Mode;

    /// The per-scene ratio rows: the measured bound and the estimate appear only where a target
    /// has one, as in docs/bench/table.md.
    #[test]
    fn ratio_rows_show_where_a_target_has_a_value() {
        let scene = |bound: Option<f64>| SceneSummary {
            scene: "builtin:splash_room".into(),
            patches: 219,
            reference_points: 65_536,
            reference_samples: 4096,
            reference_batches: 4,
            reference_noise: 0.02,
            resolution: 0.003,
            reference_cache: String::new(),
            resolved: vec![(0.01, false), (0.02, true), (0.05, true)],
            crossings: Vec::new(),
            ratios: vec![(0.01, None), (0.02, Some(0.5)), (0.05, None)],
            ratios_extrapolated: vec![(0.01, None), (0.02, None), (0.05, Some(0.0046))],
            ratios_uniform_bound: vec![(0.01, None), (0.02, None), (0.05, bound)],
        };
        let report = |bound| BenchReport {
            mode: Mode::Standard,
            repeats: 3,
            threads: 2,
            rows: Vec::new(),
            scenes: vec![scene(bound)],
        };
        let md = markdown(&report(Some(0.0601)));
        for line in [
            "| time to 5 % | time to 2 % | time to 1 % |",
            "| splash_room | | **hierarchical / best other** | n/a | 0.50× | n/a | |\n",
            "| splash_room | | hierarchical / **uniform** (uniform had not reached it in its longest run) | < 0.060× (measured) | n/a | n/a | |\n",
            "| splash_room | | hierarchical / best other's **extrapolated** time | 4.6e-3× (estimate) | n/a | n/a | |\n",
        ] {
            assert!(md.contains(line), "{line} in\n{md}");
        }
        assert!(!markdown(&report(None)).contains("(measured)"));
    }

    #[test]
    fn a_rise_counts_only_beyond_the_resolution() {
        assert_eq!(rises_beyond(&[0.05, 0.03, 0.031, 0.01], 0.002), 0);
        assert_eq!(rises_beyond(&[0.05, 0.03, 0.04, 0.01, 0.02], 0.002), 2);
        assert_eq!(rises_beyond(&[0.05], 0.0), 0);
    }
}
