//! The settings each method is swept over, relative to the scene's diagonal d: uniform meshes
//! h = d/k, progressive refinement by shot count, the hierarchical solver over its oracles'
//! thresholds (BF, error, the lecture's Feps) on the quadtree and on the contact mesh (clustered
//! on scenes of many patches); and the finer uniform rows added after the sweep where uniform
//! missed a target the hierarchical rows reached, predicted as t(k) ∝ k⁴ (all pairs of k² elements).

use super::Mode;
use super::envelope::time_to_reach;
use crate::geometry::accel::Accel;
use crate::scene::Scene;
use crate::solver::Solution;
use crate::solver::params::{AreaEps, Clustering, DEFAULT_CAUSE_TAIL, HierarchicalParams};
use crate::solver::progressive::ProgressiveParams;
use crate::solver::spec::{Plan, SolveSpec, TopLevel};
use crate::solver::uniform::{self, UniformParams};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, mpsc};
use std::time::{Duration, Instant};

/// One solver configuration.
#[derive(Clone, Debug)]
pub enum Method {
    Uniform(UniformParams),
    Progressive(ProgressiveParams),
    Hierarchical(HierarchicalParams),
    /// The hierarchical solver with the contact mesh as its top level
    /// ([`crate::mesh::remesh::RemeshParams::contacts`]); its rows are hierarchical rows
    /// (`mesh=contact` in their settings).
    HierarchicalContact(HierarchicalParams),
}

impl Method {
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Method::Uniform(_) => "uniform",
            Method::Progressive(_) => "progressive",
            Method::Hierarchical(_) | Method::HierarchicalContact(_) => "hierarchical",
        }
    }

    /// The settings that vary in the sweep, as `key=value` words.
    #[must_use]
    pub fn settings(&self) -> String {
        match self {
            Method::Uniform(p) => format!("h={} rays={}", g3(p.element_size), p.rays),
            Method::Progressive(p) => {
                format!("h={} shots={} rays={}", g3(p.element_size), p.max_shots, p.rays)
            }
            Method::Hierarchical(p) | Method::HierarchicalContact(p) => {
                let aeps = match p.aeps {
                    AreaEps::Absolute(a) => g3(a),
                    AreaEps::Relative(r) => format!("{r:.1e}A").replace(".0e", "e"),
                };
                let mut mesh = if matches!(self, Method::HierarchicalContact(_)) {
                    format!(" {CONTACT_MARK}")
                } else {
                    String::new()
                };
                if p.cluster == Clustering::On {
                    mesh.push_str(&format!(" {CLUSTER_MARK}"));
                }
                if p.cause_tail != DEFAULT_CAUSE_TAIL {
                    mesh.push_str(&format!(" {TAIL_MARK}{}", p.cause_tail));
                }
                format!("{:?} feps={} aeps={aeps} bfeps={} rays={}{mesh}", p.oracle, p.feps, p.bf_eps, p.rays)
                    .to_lowercase()
            }
        }
    }

    /// What the row solves, as [`crate::solver::spec::solve`] takes it.
    #[must_use]
    pub fn plan(&self) -> Plan {
        match self {
            Method::Uniform(p) => Plan::Uniform(*p),
            Method::Progressive(p) => Plan::Progressive(*p),
            Method::Hierarchical(p) => Plan::Hierarchical { params: *p, top: TopLevel::Patches },
            Method::HierarchicalContact(p) => Plan::Hierarchical {
                params: *p,
                top: TopLevel::Mesh(crate::mesh::remesh::RemeshParams::contacts()),
            },
        }
    }

    /// Solve through [`crate::solver::spec::solve`] (no error estimate), cancelling a
    /// hierarchical run after `budget`: the solution and the solve's wall time. `Ok(None)` when
    /// over budget.
    pub(super) fn run(
        &self,
        scene: &Arc<Scene>,
        accel: &Arc<Accel>,
        budget: Duration,
    ) -> Result<Option<(Solution, f64)>, String> {
        let spec = SolveSpec { plan: self.plan(), estimate: false };
        let cancel = Arc::new(AtomicBool::new(false));
        let (done_tx, done_rx) = mpsc::channel::<()>();
        let watchdog = {
            let cancel = Arc::clone(&cancel);
            std::thread::spawn(move || {
                if done_rx.recv_timeout(budget) == Err(mpsc::RecvTimeoutError::Timeout) {
                    cancel.store(true, Ordering::Relaxed);
                }
            })
        };
        let t0 = Instant::now();
        let solved = crate::solver::spec::solve(scene, accel, 0.0, &spec, &mut |_, _| {}, Some(&cancel));
        let secs = t0.elapsed().as_secs_f64();
        let _ = done_tx.send(());
        let _ = watchdog.join();
        let solved = solved.map_err(|e| e.to_string())?;
        Ok((!solved.cancelled).then_some((solved.solution, secs)))
    }
}

/// Three significant digits, without trailing zeros.
fn g3(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let digits = (2 - x.abs().log10().floor() as i32).max(0) as usize;
    let s = format!("{x:.digits$}");
    if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s }
}

/// The sweep of one scene for a mode, sizes relative to the scene's diagonal.
#[must_use]
pub fn sweep(scene: &Scene, mode: Mode) -> Vec<Method> {
    let d = scene.bounds().diagonal();
    let mut out = Vec::new();
    for &k in uniform_divisions(mode) {
        out.push(uniform_row(d / k));
    }
    let shots: &[u32] = match mode {
        Mode::Quick => &[100, 1000],
        Mode::Standard => &[30, 100, 300, 1000, 3000, 10_000],
        Mode::Full => &[30, 100, 300, 1000, 3000, 10_000, 30_000],
    };
    let prog_h = match mode {
        Mode::Quick => d / 8.0,
        Mode::Standard => d / 16.0,
        Mode::Full => d / 24.0,
    };
    for &n in shots {
        out.push(Method::Progressive(ProgressiveParams {
            element_size: prog_h,
            max_shots: n,
            tolerance: 1e-9,
            rays: 16,
            ff_tolerance: uniform::COARSE_FF_TOLERANCE,
            ..ProgressiveParams::default()
        }));
    }
    out.extend(hierarchical_rows(mode).into_iter().map(Method::Hierarchical));
    if mode != Mode::Quick {
        out.extend(contact_rows(scene));
    }
    out
}

/// The hierarchical rows on the quadtree of the input patches: the BF oracle over BFeps × Aeps,
/// the error oracle halving its threshold, the lecture's Feps oracle.
fn hierarchical_rows(mode: Mode) -> Vec<HierarchicalParams> {
    let base = HierarchicalParams::interactive();
    match mode {
        Mode::Quick => vec![HierarchicalParams { aeps: AreaEps::Relative(1e-3), ..base }, base],
        Mode::Standard | Mode::Full => {
            let mut v = Vec::new();
            // BF oracle: BFeps (relative to the brightest emission, as the presets use it) × Aeps,
            // at 4 and 16 rays per link.
            for (bf, a) in [(1e-2, 1e-3), (5e-3, 3e-4), (2e-3, 1e-4), (1e-3, 5e-5), (5e-4, 2e-5)] {
                v.push(HierarchicalParams { bf_eps: bf, aeps: AreaEps::Relative(a), ..base });
            }
            for (bf, a) in [(2e-3, 1e-4), (5e-4, 2e-5)] {
                v.push(HierarchicalParams { bf_eps: bf, aeps: AreaEps::Relative(a), rays: 16, ..base });
            }
            // The error oracle (the quality preset's), halving its threshold, at 16 rays.
            for eps in [0.4, 0.2, 0.1, 0.05] {
                v.push(HierarchicalParams { bf_eps: eps, ..HierarchicalParams::quality() });
            }
            // The lecture's Feps oracle.
            for (f, a) in [(0.1, 1e-3), (0.05, 3e-4), (0.02, 1e-4)] {
                v.push(HierarchicalParams {
                    feps: f,
                    aeps: AreaEps::Relative(a),
                    ..HierarchicalParams::lecture()
                });
            }
            if mode == Mode::Full {
                v.push(HierarchicalParams {
                    bf_eps: 0.025,
                    aeps: AreaEps::Relative(5e-5),
                    ..HierarchicalParams::quality()
                });
                v.push(HierarchicalParams { bf_eps: 2e-4, aeps: AreaEps::Relative(1e-5), rays: 16, ..base });
            }
            v
        }
    }
}

/// The hierarchical rows on the contact mesh: the error oracle halving its threshold, and on
/// scenes of [`CLUSTER_ROWS_MIN_PATCHES`] patches or more the same clustered, also with the fast
/// tail share.
fn contact_rows(scene: &Scene) -> Vec<Method> {
    let contact = |p: HierarchicalParams| {
        Method::HierarchicalContact(crate::solver::discontinuity::contact_area_floor(p))
    };
    let quality = HierarchicalParams::quality();
    // The error oracle on the contact mesh, halving its threshold with the area floor shrinking
    // in step (6e-4 · eps of the scene's area; at the quadtree rows' fixed 1e-4 the floor, not
    // the threshold, ends the refinement).
    let mut out: Vec<Method> =
        [0.4, 0.2, 0.1, 0.05, 0.025].map(|eps| contact(HierarchicalParams { bf_eps: eps, ..quality })).into();
    // The same, clustered above the contact mesh's patches, on scenes with enough patches for
    // clusters to stand for many of them (splash_room's 527 pieces are linked pair by pair
    // otherwise).
    if scene.patches.len() >= CLUSTER_ROWS_MIN_PATCHES {
        let clustered = HierarchicalParams { cluster: Clustering::On, ..quality };
        for eps in [0.4, 0.2, 0.1, 0.05] {
            out.push(contact(HierarchicalParams { bf_eps: eps, ..clustered }));
        }
        // And with the oracle's tail share at [`FAST_CAUSE_TAIL`]: fewer links per threshold, a
        // better error against time.
        for eps in [0.34, 0.17] {
            out.push(contact(HierarchicalParams { bf_eps: eps, cause_tail: FAST_CAUSE_TAIL, ..clustered }));
        }
    }
    out
}

/// The uniform rows of the sweep: element sizes scene diagonal / k.
#[must_use]
pub fn uniform_divisions(mode: Mode) -> &'static [f64] {
    match mode {
        Mode::Quick => &[4.0, 8.0],
        Mode::Standard => &[4.0, 8.0, 12.0, 16.0, 24.0],
        Mode::Full => &[4.0, 8.0, 12.0, 16.0, 24.0, 32.0],
    }
}

/// The uniform solver at element size `h`, as the sweep runs it.
pub(super) fn uniform_row(h: f64) -> Method {
    Method::Uniform(UniformParams {
        element_size: h,
        rays: 16,
        ff_tolerance: uniform::COARSE_FF_TOLERANCE,
        ..UniformParams::default()
    })
}

/// Finer uniform sizes (scene diagonal / k) that [`super::run`] adds after the sweep where the
/// uniform rows missed a target that the hierarchical rows reached, until uniform reaches it or has
/// run [`EXTEND_FACTOR`] times the hierarchical time to it (so that "uniform needs more than 10×
/// the time" is measured, not extrapolated), each only if its predicted time fits the budget.
#[must_use]
pub fn uniform_extension(mode: Mode) -> &'static [f64] {
    match mode {
        Mode::Quick => &[],
        Mode::Standard => &[32.0, 40.0, 48.0],
        Mode::Full => &[40.0, 48.0, 64.0],
    }
}

/// The uniform rows are extended until their slowest one has run this many times the
/// hierarchical time to the target (the "≤ 1/10 of uniform's time").
pub const EXTEND_FACTOR: f64 = 10.0;

/// Predicted time of a uniform row at diagonal / `k_next` from one at diagonal / `k`: elements
/// grow as k², links (all pairs) and rays as k⁴.
#[must_use]
pub fn predict_uniform_time(t: f64, k: f64, k_next: f64) -> f64 {
    t * (k_next / k).powi(4)
}

/// Scenes with fewer input patches get no clustered rows in [`sweep`].
pub const CLUSTER_ROWS_MIN_PATCHES: usize = 100;

/// The tail share of [`sweep`]'s fast clustered rows (`HierarchicalParams::cause_tail`; the
/// presets' is [`DEFAULT_CAUSE_TAIL`]): fewer links for about the same error on a clustered
/// contact mesh at a coarse threshold, so the bench shows the fastest route to 5 %. Chosen by
/// measurement, see docs/solver.md#oracles.
pub const FAST_CAUSE_TAIL: f64 = 0.5;

/// The contact-mesh rows' area floor per unit of error threshold (see [`sweep`]).
pub use crate::solver::discontinuity::CONTACT_AEPS_PER_EPS;

/// Whether the uniform rows (`uni`, (time, error) points) need a finer row for `target`: the
/// hierarchical rows reached it, the uniform rows did not, and the slowest uniform row ran less
/// than [`EXTEND_FACTOR`] × the hierarchical time to it.
#[must_use]
pub fn extension_wanted(hier: &[(f64, f64)], uni: &[(f64, f64)], target: f64) -> bool {
    let slowest = uni.iter().map(|p| p.0).fold(0.0, f64::max);
    time_to_reach(uni, target).is_none()
        && time_to_reach(hier, target).is_some_and(|h| slowest < EXTEND_FACTOR * h)
}

/// The settings word that marks the contact-mesh rows ([`Method::HierarchicalContact`]).
pub(super) const CONTACT_MARK: &str = "mesh=contact";
/// The settings word that marks clustered rows.
pub(super) const CLUSTER_MARK: &str = "cluster=on";
/// The settings word (before its value) that marks rows with another tail share than the
/// presets'.
pub(super) const TAIL_MARK: &str = "tail=";

#[cfg(test)]
mod tests {
    use super::*;

    /// Clustered contact-mesh rows on scenes with many patches only, marked in their settings
    /// (the convergence lines keep them apart from the unclustered ones).
    #[test]
    fn clustered_rows_only_where_clusters_can_stand_for_many_patches() {
        let clustered = |name: &str| {
            let scene = crate::scene::builtin::load(name).unwrap();
            sweep(&scene, Mode::Standard)
                .iter()
                .filter(|m| matches!(m, Method::HierarchicalContact(p) if p.cluster == Clustering::On))
                .map(Method::settings)
                .collect::<Vec<_>>()
        };
        assert!(clustered("cornell").is_empty());
        let rows = clustered("splash_room");
        assert_eq!(rows.len(), 6, "{rows:?}");
        assert!(rows.iter().all(|s| s.contains(CONTACT_MARK) && s.contains(CLUSTER_MARK)), "{rows:?}");
        // The last two take the fast tail share, and say so.
        let tailed: Vec<bool> =
            rows.iter().map(|s| s.contains(&format!("{TAIL_MARK}{FAST_CAUSE_TAIL}"))).collect();
        assert_eq!(tailed, [false, false, false, false, true, true], "{rows:?}");
    }

    #[test]
    fn uniform_rows_extend_until_ten_times_the_hierarchical_time() {
        // Hierarchical reaches 5 % at 2 s (log-log between its rows).
        let hier = [(0.5, 0.08), (2.0, 0.05), (8.0, 0.03)];
        let uni = [(1.0, 0.20), (6.0, 0.12)];
        assert!(extension_wanted(&hier, &uni, 0.05), "6 s < 10 × 2 s");
        let longer = [(1.0, 0.20), (6.0, 0.12), (21.0, 0.10)];
        assert!(!extension_wanted(&hier, &longer, 0.05), "21 s ≥ 10 × 2 s: the bound is measured");
        let reached = [(1.0, 0.20), (6.0, 0.04)];
        assert!(!extension_wanted(&hier, &reached, 0.05), "uniform reached it");
        assert!(!extension_wanted(&hier, &uni, 0.01), "hierarchical did not reach 1 %");
        // Elements grow as k², pairs as k⁴.
        assert!((predict_uniform_time(6.0, 24.0, 48.0) - 96.0).abs() < 1e-12);
        // The extension continues where the sweep's sizes end.
        for mode in [Mode::Standard, Mode::Full] {
            let (sweep_last, ext) = (uniform_divisions(mode).last().unwrap(), uniform_extension(mode));
            assert!(ext.first().is_some_and(|k| k > sweep_last) && ext.windows(2).all(|w| w[1] > w[0]));
        }
    }
}
