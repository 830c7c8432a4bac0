//! The solver's named parts: what each pass reads and writes, so that a pass can take the
//! parts it needs beside the mesh ([`Hierarchy`]) instead of the whole solver.
//!
//! ```text
//!  Setup ─ fixed inputs, read by every pass       LinkGraph ─ refine writes, gather reads
//!  GatherState ─ gather's plan of the links       PushPullState ─ push-pull's sums, the moments
//!  OracleState ─ refine's per-element cache       ClusterState ─ links above the input patches
//!  RunLog ─ what the steps report
//! ```

use super::HierarchicalStats;
use super::cluster::{ClusterLink, ClusterTransfer, ClusterTree};
use super::deadline::Pace;
use super::gather::GatherPlan;
use super::linking::InitialLinks;
use super::oracle::Kernels;
use super::push_pull::{Chain, FlatChain, Pushed};
use super::refine::{PairMemo, resolve_bf_eps};
use crate::geometry::accel::Accel;
use crate::math::Rgb;
use crate::scene::Scene;
use crate::solver::EnergyBalance;
use crate::solver::hierarchy::Hierarchy;
use crate::solver::link::LinkStore;
use crate::solver::params::HierarchicalParams;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// The fixed setup: the scene, its BVH, the parameters and their resolved thresholds, the
/// cancel flag and the switches that exist only to check that a shortcut changes nothing.
pub(super) struct Setup {
    pub(super) scene: Arc<Scene>,
    pub(super) accel: Arc<Accel>,
    pub(super) params: HierarchicalParams,
    /// Aeps in scene units² (resolved from a relative setting).
    pub(super) aeps: f64,
    /// BFeps in units of B (resolved from a relative setting).
    pub(super) bf_eps: f64,
    pub(super) cancel: Arc<AtomicBool>,
    /// A time budget's end (`HierarchicalSolver::set_deadline`; `None`: none).
    pub(super) deadline: Option<Instant>,
    /// Time the BVH took to build.
    pub(super) bvh_s: f64,
    /// Stop casting a new link's rays once they settle what the next refinement pass does
    /// with it (on by default; off only to check that it changes nothing).
    pub(super) early_exit: bool,
    /// Recompute the error oracle's whole field every pass instead of updating it (off; only to
    /// check that the update changes nothing).
    pub(super) full_error_passes: bool,
}

impl Setup {
    /// The setup of a solve of `scene` with BVH `accel` (built in `bvh_s` seconds).
    pub(super) fn new(scene: Arc<Scene>, accel: Arc<Accel>, params: HierarchicalParams, bvh_s: f64) -> Self {
        let mut s = Setup {
            aeps: 0.0,
            bf_eps: 0.0,
            scene,
            accel,
            params,
            cancel: Arc::new(AtomicBool::new(false)),
            deadline: None,
            bvh_s,
            early_exit: true,
            full_error_passes: false,
        };
        s.set_params(params);
        s
    }

    /// Take new parameters and resolve their thresholds against the scene.
    pub(super) fn set_params(&mut self, p: HierarchicalParams) {
        self.params = p;
        self.aeps = p.aeps.resolve(self.scene.total_area());
        self.bf_eps = resolve_bf_eps(&p, &self.scene);
    }

    pub(super) fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }

    /// Whether the deadline has passed.
    pub(super) fn past_deadline(&self) -> bool {
        self.deadline.is_some_and(|d| Instant::now() >= d)
    }
}

/// The link graph: every element's links (by receiver), whether the input patches are linked yet,
/// and the caches that make linking and refinement cheaper.
#[derive(Default)]
pub(super) struct LinkGraph {
    pub(super) links: LinkStore,
    pub(super) linked: bool,
    /// Initial links of the input patch pairs, reusable while `rays` and `seed` are unchanged.
    pub(super) initial_cache: Option<InitialLinks>,
    /// The new pairs of the current refinement pass (see `make_link`).
    pub(super) pair_memo: PairMemo,
}

/// The gather's state: the links flattened into a plan, which receivers changed since, and the
/// radiosities of the previous iteration.
#[derive(Default)]
pub(super) struct GatherState {
    /// The links flattened for gathering (buffers kept between rebuilds).
    pub(super) plan: GatherPlan,
    /// `plan` matches the current links but for the receivers in `plan_changed` (false: rebuild
    /// it whole).
    pub(super) plan_valid: bool,
    /// Receivers whose link lists changed since `plan` was made (refinements record them; the
    /// next gather updates their entries).
    pub(super) plan_changed: Vec<u32>,
    /// Scratch for Jacobi gathers: every element's radiosity before the gather (kept between
    /// gathers, so no large allocation per iteration).
    pub(super) b_prev: Vec<Rgb>,
}

impl GatherState {
    /// The links changed wholesale: rebuild the plan at the next gather.
    pub(super) fn invalidate(&mut self) {
        self.plan_valid = false;
        self.plan_changed.clear();
    }
}

/// Push-pull's state: the per-element sums pushed down (scratch kept between passes) and the
/// first moments of radiosity that the next gather reads.
#[derive(Default)]
pub(super) struct PushPullState {
    /// Scratch for `push_pull_flat`.
    pub(super) chain: Vec<Chain>,
    /// The same without slopes.
    pub(super) flat_chain: Vec<FlatChain>,
    /// Each element's first moment of radiosity about its centroid, Σ_leaves A B (c − c_e) / A_e,
    /// in its tangent basis (u, v), from the last push-pull (empty without `push_slopes`).
    pub(super) moment: Vec<[Rgb; 2]>,
    /// Scratch: the same moments in world coordinates (x, y, z), while pulling.
    pub(super) moment_world: Vec<[Rgb; 3]>,
}

/// The oracle's per-element cache during and between refinements.
#[derive(Default)]
pub(super) struct OracleState {
    /// The oracle's compact copy of every element's (b_max, max channel of B) during
    /// refinement; cleared afterwards, as B changes.
    pub(super) b: Vec<[f64; 2]>,
    /// The row check's floor per element during refinement (`refine::row_floors`): the smallest
    /// F·V of its links that `refine::row_split` pushes down, 0 for none; empty when off.
    pub(super) row_floor: Vec<f32>,
    /// The error oracle's kernels at each element's child points per linked source, from the
    /// last refinement (`oracle::ErrorField::kernels`): the next one evaluates only new pairs.
    pub(super) error_kernels: Vec<Kernels>,
}

/// The clusters above the input patches ([`super::cluster`]): the tree, its links and transfer.
#[derive(Clone, Default)]
pub(super) struct ClusterState {
    /// The cluster tree (built at the first linking, when `params.cluster` applies).
    pub(super) tree: Option<Arc<ClusterTree>>,
    /// Links with a cluster at one end at least.
    pub(super) links: Vec<ClusterLink>,
    /// Scratch of the cluster transfer.
    pub(super) xfer: ClusterTransfer,
    /// Each input patch's Σ F·V through cluster links (its energy row's share).
    pub(super) fv: Vec<f64>,
}

/// What the input patches gather through cluster links: per patch the irradiance, and (with
/// slopes) its gradient in the patch's tangent basis.
pub(super) type ClusterIrradiance = (Vec<Rgb>, Vec<[Rgb; 2]>);

impl ClusterState {
    /// What the input patches of `hier` gather through the cluster links from the current
    /// radiosities (None when there are none); `slopes`: with the gradients.
    pub(super) fn irradiance(&mut self, hier: &Hierarchy, slopes: bool) -> Option<ClusterIrradiance> {
        let tree = self.tree.as_ref()?;
        if self.links.is_empty() {
            return None;
        }
        let b = |p: u32| hier.get(p).radiosity;
        Some(if slopes {
            self.xfer.irradiance_and_slopes(tree, hier, &b)
        } else {
            (self.xfer.irradiance(tree, hier, &b), Vec::new())
        })
    }
}

/// The run log: statistics, the residual of every gather, convergence and the power balance.
#[derive(Clone, Default)]
pub(super) struct RunLog {
    pub(super) stats: HierarchicalStats,
    /// Residual after each gather, in order.
    pub(super) residuals: Vec<f64>,
    pub(super) converged: bool,
    pub(super) energy: EnergyBalance,
    pub(super) gathered_once: bool,
    /// The solver's measured speed, for a deadline's estimates.
    pub(super) pace: Pace,
    /// The deadline stopped the last solve's or convergence's gathers before they converged
    /// and closed the power balance.
    pub(super) gathers_cut: bool,
    /// The last solve ended as a solve ends when it is done (its mesh settled, its gathers
    /// converged), and nothing was refined or retargeted since: another solve under the same
    /// parameters has nothing to do (a kept state restored at its own parameters, whose log
    /// this is, is that solve's answer again).
    pub(super) settled: bool,
}

impl RunLog {
    /// Record a push-pull: its residual, whether it is below `tolerance`, and its power sums.
    pub(super) fn record_push(&mut self, pushed: Pushed, tolerance: f64) {
        self.residuals.push(pushed.residual);
        self.converged = pushed.residual < tolerance;
        if let Some((absorbed, escaped)) = pushed.energy {
            self.energy.absorbed = absorbed;
            self.energy.escaped = escaped;
        }
    }

    /// Nothing run yet: all emitted power still to be gathered.
    pub(super) fn new(scene: &Scene) -> Self {
        RunLog {
            energy: EnergyBalance { emitted: scene.emitted_power(), ..Default::default() },
            ..Default::default()
        }
    }
}
