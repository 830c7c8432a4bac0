//! The solver thread: owns the [`HierarchicalSolver`], runs one command at a time and sends back
//! a read-only [`ViewData`] after each, so the UI thread never waits on the solver. This module
//! holds what the UI sees of it (the commands, the replies, the [`Worker`] handle, [`ViewData`]);
//! the thread's own side is [`super::solver_thread`].
//!
//! ```text
//!  UI ── Command (mpsc) ──► "radlab-solver" thread ── Reply (mpsc) + request_repaint ──► UI
//!  UI ── cancel flag (Arc<AtomicBool>, the solver's own cancel_handle) ──► running step
//!  UI ── give way (GiveWay: a command's number, a stop flag) ──► error estimates being computed
//!  "radlab-solver" ── a mesh solve ──► "radlab-mesh-solve" thread (no cancel hook: the
//!                     solver thread watches the flag and drops it on Cancel)
//! ```

use crate::math::Rgb;
use crate::present::overlay::{ElementView, LinkView};
use crate::scene::Scene;
use crate::solver::Solution;
use crate::solver::hierarchical::{
    ClusterLinkView, HierarchicalSolver, HierarchicalStats, Snapshot, StepKind, StepReport,
};
use crate::solver::meshed::{MeshMethod, MeshSolution, MeshSolveParams};
use crate::solver::params::HierarchicalParams;
use crate::solver::spec::TopLevel;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, Sender, TryRecvError};

/// The solver's state as the viewer shows it.
#[derive(Clone, Debug, Default)]
pub struct ViewData {
    /// All elements, `id` = index.
    pub elements: Vec<ElementView>,
    /// Ids of the leaves, ascending.
    pub leaves: Vec<u32>,
    pub links: Vec<LinkView>,
    pub stats: HierarchicalStats,
    /// Residual after each gather.
    pub residuals: Vec<f64>,
    /// The radiosity shown is what push-pull will give (`push_pull_preview`): the solver has
    /// gathered but its own state waits for a Push-pull step.
    pub pushed_for_display: bool,
    /// The settings of the solver that produced this state (the run history records them).
    pub params: HierarchicalParams,
    /// Set when this state is a solve on a uniform or discontinuity mesh (not the quadtree):
    /// its settings, p = 1 vertex values and times ([`ViewData::of_mesh_solution`]).
    pub mesh: Option<MeshInfo>,
    /// The cluster tree's nodes (empty when the solve does not cluster).
    pub clusters: Vec<crate::solver::hierarchical::ClusterInfo>,
    /// Per input patch, the smallest cluster holding it (index into `clusters`).
    pub patch_cluster: Vec<u32>,
    /// The cluster links with the largest form factors, largest first, at most
    /// [`CLUSTER_LINKS_KEPT`] of the solver's `stats.cluster_links` (the links overlay draws
    /// them dashed); [`REPLAY_CLUSTER_LINKS`] in a refinement replay's frames.
    pub cluster_links: Vec<ClusterLinkView>,
    /// Each element's slope, by id, where it has one (empty: no element has one): the leaves'
    /// linear reconstruction, B(x) = B + d · (x − centroid), that the viewer draws by default.
    pub slopes: Vec<Option<crate::solver::Slope>>,
    /// Where the solver's error estimates of this state stand: in the elements'
    /// `error_estimate`s, or (every one 0) still to come or given up.
    pub estimates: Estimates,
}

/// Where a state's error estimates stand ([`ViewData::estimates`]).
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub enum Estimates {
    /// In the elements' `error_estimate`s (or the state has none of its own: a mesh solve, a
    /// replay's frame, a reference).
    #[default]
    Included,
    /// Not computed yet: a step's answer, whose estimates follow in a [`Reply::Estimates`] of
    /// their own ([`ViewData::with_estimates`]).
    Pending,
    /// Given up: a newer command came first ([`Reply::EstimatesDropped`]); the state is shown
    /// "not estimated".
    Dropped,
}

/// Most cluster links a [`ViewData`] carries: a 100 k-triangle room has 4 M (64 bytes each),
/// and the overlay draws a few thousand at most.
pub const CLUSTER_LINKS_KEPT: usize = 50_000;

/// Most cluster links a refinement replay frame carries (a frame a round, within
/// `REPLAY_BUDGET_BYTES`): the strongest 5 000, a few hundred kB a frame.
pub const REPLAY_CLUSTER_LINKS: usize = 5_000;

/// What the viewer adds to a discontinuity-mesh solve (docs/meshing.md): the D-mesh
/// as the hierarchical solver's top level, at p = 0 only (the Mesh menu greys it out at p = 1);
/// ignored on the uniform mesh. Grading is the mesh's own setting
/// ([`MeshSolveParams::grade`], built as `radlab solve --dmesh-budget` builds it).
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub struct DmeshOptions {
    /// Solve the D-mesh's pieces as the top level of hierarchical refinement, with the Solver
    /// panel's settings (`--method hierarchical`, [`crate::solver::discontinuity::solve_hierarchical`]).
    pub hierarchical: bool,
}

impl DmeshOptions {
    /// Whether these options change a solve on `m` (a discontinuity mesh at p = 0).
    #[must_use]
    pub fn apply_to(self, m: &MeshSolveParams) -> bool {
        self.hierarchical
            && matches!(m.method, MeshMethod::DiscontinuityCdt | MeshMethod::DiscontinuityBsp)
            && m.order == crate::geometry::basis::Order::Constant
    }

    /// What the label of a solve on `m` adds: " top of hierarchy".
    #[must_use]
    pub fn label(self, m: &MeshSolveParams) -> String {
        if self.apply_to(m) { " top of hierarchy".into() } else { String::new() }
    }
}

/// What a mesh solve adds to its [`ViewData`].
#[derive(Clone, Debug)]
pub struct MeshInfo {
    pub params: MeshSolveParams,
    /// The D-mesh options it was solved with.
    pub dmesh: DmeshOptions,
    /// At p = 1: each element's vertex values (indexed like the elements), drawn by the
    /// display's "solved" reconstruction (each element's own function).
    pub coefficients: Option<Arc<Vec<Vec<Rgb>>>>,
    /// Wall time of meshing (discontinuity meshes) and of the whole solve, seconds.
    pub meshing_s: f64,
    pub solve_s: f64,
    /// The solution as the solver returned it (elements on the input patches).
    pub solution: Arc<Solution>,
}

impl MeshInfo {
    /// "discontinuity-cdt p0 graded 2000 top of hierarchy", "discontinuity-bsp p1-discontinuous
    /// graded 700", …
    #[must_use]
    pub fn label(&self) -> String {
        format!("{}{}", self.params.label(), self.dmesh.label(&self.params))
    }
}

impl ViewData {
    /// Convert a solver snapshot.
    #[must_use]
    pub fn from_snapshot(s: Snapshot) -> ViewData {
        let elements: Vec<ElementView> = s.elements.iter().map(ElementView::from_info).collect();
        let leaves = elements.iter().filter(|e| e.leaf).map(|e| e.id).collect();
        let links = s.links.iter().map(LinkView::from_info).collect();
        let slopes = if s.elements.iter().any(|e| e.slope.is_some()) {
            s.elements.iter().map(|e| e.slope).collect()
        } else {
            Vec::new()
        };
        ViewData {
            elements,
            leaves,
            links,
            stats: s.stats,
            residuals: s.residuals,
            pushed_for_display: false,
            params: HierarchicalParams::default(),
            mesh: None,
            clusters: s.clusters,
            patch_cluster: s.patch_cluster,
            cluster_links: Vec::new(),
            slopes,
            estimates: Estimates::Included,
        }
    }

    /// This state with the solver's error estimates (`estimates`, indexed by element id, as
    /// [`HierarchicalSolver::error_estimates`] gives them) in place of the pending zeros.
    #[must_use]
    pub fn with_estimates(&self, estimates: &[f64]) -> ViewData {
        let mut v = self.clone();
        for e in &mut v.elements {
            e.error_estimate = estimates.get(e.id as usize).copied().unwrap_or(0.0);
        }
        v.estimates = Estimates::Included;
        v
    }

    /// This state, its pending estimates given up ([`Reply::EstimatesDropped`]).
    #[must_use]
    pub fn without_estimates(&self) -> ViewData {
        ViewData { estimates: Estimates::Dropped, ..self.clone() }
    }

    /// Whether the error estimates of this state are still to come ([`Estimates::Pending`]).
    #[must_use]
    pub fn estimates_pending(&self) -> bool {
        self.estimates == Estimates::Pending
    }

    /// The state of a solve on a uniform or discontinuity mesh: every element a leaf on its
    /// input patch (depth 0 where it is the whole patch, 1 where it is a piece) (materials from `scene`), no links (every pair was coupled), no error
    /// estimate.
    #[must_use]
    pub fn of_mesh_solution(
        scene: &Scene,
        params: MeshSolveParams,
        m: MeshSolution,
        solve_s: f64,
    ) -> ViewData {
        let elements = m
            .solution
            .elements
            .iter()
            .enumerate()
            .map(|(i, e)| {
                let patch = &scene.patches[e.patch];
                ElementView::flat_leaf(
                    i as u32,
                    e.patch,
                    patch,
                    &e.vertices,
                    e.area,
                    e.radiosity,
                    0.0,
                    "mesh element",
                )
            })
            .collect();
        let mut view = ViewData::of_flat_leaves(elements);
        // A patch cut into pieces: its pieces are one level below it (their edges draw in the
        // quadtree overlay's depth-1 colour, apart from whole patches' white).
        let mut per_patch = vec![0usize; scene.patches.len()];
        for e in &view.elements {
            per_patch[e.patch as usize] += 1;
        }
        for e in &mut view.elements {
            e.depth = u8::from(per_patch[e.patch as usize] > 1);
        }
        let pieces = view.elements.iter().filter(|e| e.depth == 1).count();
        view.stats.depth_histogram = vec![view.elements.len() - pieces, pieces];
        view.stats.links = m.solution.stats.links;
        if m.solution.elements.iter().any(|e| e.slope.is_some()) {
            view.slopes = m.solution.elements.iter().map(|e| e.slope).collect();
        }
        view.mesh = Some(MeshInfo {
            params,
            dmesh: DmeshOptions::default(),
            coefficients: m.coefficients.map(Arc::new),
            meshing_s: m.meshing_s,
            solve_s,
            solution: Arc::new(m.solution),
        });
        view
    }

    /// The unknowns of the solution: a p = 1 continuous mesh solve's shared vertices, else one
    /// value per leaf (p = 1 discontinuous: per element vertex).
    #[must_use]
    pub fn unknowns(&self) -> usize {
        let stated = self.mesh.as_ref().and_then(|m| {
            let extra = m.solution.stats.extra.as_ref()?;
            extra.get("unknowns")?.as_u64()
        });
        stated.map_or(self.stats.leaves, |n| n as usize)
    }

    /// The leaves as solved elements (the metrics' and the artifacts' input).
    #[must_use]
    pub fn solved_leaves(&self) -> Vec<crate::solver::SolvedElement> {
        self.leaves
            .iter()
            .map(|&l| {
                let e = &self.elements[l as usize];
                crate::solver::SolvedElement {
                    patch: e.patch as usize,
                    vertices: e.verts().to_vec(),
                    area: e.area,
                    radiosity: e.radiosity,
                    error_estimate: None,
                    slope: self.slope(l),
                }
            })
            .collect()
    }

    /// Element `id`'s slope, if it has one.
    #[must_use]
    pub fn slope(&self, id: u32) -> Option<crate::solver::Slope> {
        self.slopes.get(id as usize).copied().flatten()
    }

    /// Every element's own reconstruction as vertex values (indexed like `elements`, in vertex
    /// order): a p = 1 solve's coefficients, or each element's value with its slope at its
    /// corners (one value: constant). `None` when every element is constant.
    #[must_use]
    pub fn own_coefficients(&self) -> Option<std::borrow::Cow<'_, [Vec<Rgb>]>> {
        if let Some(c) = self.mesh.as_ref().and_then(|m| m.coefficients.as_deref()) {
            return Some(std::borrow::Cow::Borrowed(c.as_slice()));
        }
        if self.slopes.is_empty() {
            return None;
        }
        let values = self
            .elements
            .iter()
            .map(|e| match self.slope(e.id) {
                Some(s) => e.verts().iter().map(|&v| s.at(e.radiosity, v)).collect(),
                None => vec![e.radiosity],
            })
            .collect::<Vec<_>>();
        Some(std::borrow::Cow::Owned(values))
    }

    /// A state whose elements are all leaves of depth 0 (`elements[i].id == i`): a mesh solve,
    /// a reference.
    #[must_use]
    pub fn of_flat_leaves(elements: Vec<ElementView>) -> ViewData {
        let n = elements.len();
        let mut view = ViewData { leaves: (0..n as u32).collect(), elements, ..ViewData::default() };
        view.stats.elements = n;
        view.stats.leaves = n;
        view.stats.depth_histogram = vec![n];
        view
    }

    /// The state of a solver (pushed and pulled for display when it has gathered since its last
    /// push-pull, `unpushed`), with its settings and its strongest cluster links.
    #[must_use]
    pub fn of_solver(s: &HierarchicalSolver, unpushed: bool) -> Arc<ViewData> {
        Self::of_solver_with(s, unpushed, true, CLUSTER_LINKS_KEPT)
    }

    /// [`ViewData::of_solver`] with at most `cluster_links` cluster links (the strongest) and
    /// without the error estimates (every estimate 0) when `estimates` is false: the refinement
    /// replay's frames, which show radiosity only and keep [`REPLAY_CLUSTER_LINKS`].
    #[must_use]
    pub fn of_solver_with(
        s: &HierarchicalSolver,
        unpushed: bool,
        estimates: bool,
        cluster_links: usize,
    ) -> Arc<ViewData> {
        let snapshot = s.snapshot_with(estimates);
        let view = if unpushed {
            ViewData::from_gathered_snapshot(snapshot, &s.push_pull_preview())
        } else {
            ViewData::from_snapshot(snapshot)
        };
        // The solver builds only the strongest, largest first.
        let cluster_links = s.cluster_link_views(cluster_links);
        Arc::new(ViewData { params: s.params(), cluster_links, ..view })
    }

    /// [`ViewData::of_solver_with`] for a solver on a mesh of the input scene: `origin[i]` is the
    /// input patch the solver's patch `i` was cut from, and the view's elements (and its
    /// patch-to-cluster table) are on the input patches, as every view of the viewer is.
    #[must_use]
    pub fn of_solver_on(
        s: &HierarchicalSolver,
        unpushed: bool,
        estimates: bool,
        cluster_links: usize,
        origin: Option<&[usize]>,
    ) -> Arc<ViewData> {
        let view = Self::of_solver_with(s, unpushed, estimates, cluster_links);
        let Some(origin) = origin else { return view };
        let mut view = Arc::unwrap_or_clone(view);
        for e in &mut view.elements {
            if let Some(&o) = origin.get(e.patch as usize) {
                e.patch = o as u32;
            }
        }
        if !view.patch_cluster.is_empty() {
            let inputs = origin.iter().copied().max().map_or(0, |m| m + 1);
            let mut per_input = vec![u32::MAX; inputs];
            for (piece, &c) in view.patch_cluster.iter().enumerate() {
                if let Some(&o) = origin.get(piece)
                    && per_input[o] == u32::MAX
                {
                    per_input[o] = c;
                }
            }
            view.patch_cluster = per_input;
        }
        Arc::new(view)
    }

    /// Bytes this state holds (elements and links), about.
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.elements.len() * size_of::<ElementView>()
            + self.links.len() * size_of::<LinkView>()
            + self.cluster_links.len() * size_of::<ClusterLinkView>()
    }

    /// Convert a snapshot taken between a gather and its push-pull, showing the radiosity the
    /// push-pull will give (`pushed`: [`HierarchicalSolver::push_pull_preview`], by element id),
    /// so a Gather step shows its result at once. Its residuals end with that gather's
    /// ([`gather_residual`]), the value the push-pull will record.
    #[must_use]
    pub fn from_gathered_snapshot(mut s: Snapshot, pushed: &[Rgb]) -> ViewData {
        let residual = gather_residual(&s.elements, pushed);
        for (e, &b) in s.elements.iter_mut().zip(pushed) {
            e.radiosity = b;
        }
        s.residuals.push(residual);
        ViewData { pushed_for_display: true, ..ViewData::from_snapshot(s) }
    }
}

/// The residual of a Jacobi gather, as the solver's push-pull measures it: the largest change of
/// a leaf's radiosity, `max |B_new − B_old|` over leaves and channels, relative to the largest
/// reflected radiosity `max (B_new − E)`. A gather computes B_new = E + ρ F B_old, so the change
/// is the residual r = E + ρ F B − B of the radiosity it read [Cohen & Wallace 1993, sec. 5.3]: 1
/// after the first gather (all light is new), then falling about as the reflectance per bounce.
#[must_use]
pub fn gather_residual(before: &[crate::solver::hierarchical::ElementInfo], pushed: &[Rgb]) -> f64 {
    let (mut change, mut reflected) = (0.0f64, 0.0f64);
    for (e, &b) in before.iter().zip(pushed).filter(|(e, _)| e.children.is_none()) {
        change = change.max(b.abs_diff_max(e.radiosity));
        reflected = reflected.max((b - e.emission).max_channel());
    }
    if reflected > 0.0 { change / reflected } else { change }
}

/// What the UI asks of the solver thread.
#[derive(Clone, Debug)]
pub enum Command {
    /// Replace the solver (new scene, or a scene reloaded) on `top`: the input patches, or a
    /// mesh of them (the preset ladder's contact mesh, [`TopLevel::Auto`] resolved by the scene's
    /// size). On a mesh, the views' elements are on the input patches the pieces were cut from.
    Load {
        scene: Arc<Scene>,
        params: HierarchicalParams,
        top: TopLevel,
    },
    /// Restart with new parameters (keeps the BVH).
    SetParams(HierarchicalParams),
    /// New parameters, keeping what is solved where only the thresholds changed
    /// ([`HierarchicalSolver::retarget`]): answers [`Reply::Retargeted`] when a solved state
    /// was kept (the current one, or one solved earlier at a coarser threshold; the next Solve
    /// refines and gathers from it: a warm re-solve), else restarts as `SetParams` does and
    /// answers as it does.
    Retarget(HierarchicalParams),
    Reset,
    Step(StepKind),
    /// Solve the loaded scene on a uniform or discontinuity mesh ([`crate::solver::meshed`]);
    /// answers `Done` with a [`StepKind::Solve`] report and the mesh's state. The hierarchical
    /// solver is left as it was.
    SolveMesh(MeshSolveParams, DmeshOptions),
    /// Write the current solution as a baked glTF ([`crate::present::bake`]) to `path` (.glb/.gltf), in
    /// `form` (per-element vertex colours, or the original meshes with a lightmap).
    Bake {
        path: std::path::PathBuf,
        options: crate::present::bake::BakeOptions,
        form: crate::present::bake::BakeForm,
    },
}

impl Command {
    /// Whether this command's answer replaces the state shown (every command but a bake, which
    /// writes the state as it is): the error estimates still owed for that state are given up
    /// when it runs, and when it is sent ([`Worker::send`]) the estimates being computed give
    /// way to it.
    #[must_use]
    pub fn replaces_the_state(&self) -> bool {
        !matches!(self, Command::Bake { .. })
    }
}

/// What the solver thread answers.
pub enum Reply {
    /// A scene was loaded: its cancel flag and the initial state, and the scene the Load named
    /// (the UI drops the answer to a Load it has since replaced).
    Loaded {
        cancel: Arc<AtomicBool>,
        view: Arc<ViewData>,
        scene: Arc<Scene>,
    },
    /// A command finished (`report` is `None` for `SetParams` / `Reset` and a `Retarget` that
    /// restarted).
    Done {
        report: Option<StepReport>,
        view: Arc<ViewData>,
    },
    Progress {
        done: u64,
        total: u64,
    },
    /// The picture of a solve in progress (after a round's gathers); the solve goes on.
    Partial {
        view: Arc<ViewData>,
    },
    /// A solve's states as it went, for the refinement replay: the state it started from, then
    /// the state after each round but the last (whose state is the `Done` that follows), without
    /// error estimates, while they fit in [`REPLAY_BUDGET_BYTES`]. Sent just before that `Done`.
    Replay {
        frames: Vec<Arc<ViewData>>,
    },
    /// A bake was written (what, in one line) or not (why, in one line).
    Baked(Result<String, String>),
    Failed(String),
    /// A command queued before [`Worker::cancel_all`] was dropped unrun.
    Skipped,
    /// A `Retarget` kept the solver's state: only its settings changed (no new picture: the
    /// state is the one shown, its thresholds finer).
    Retargeted,
    /// A mesh solve was cancelled: its thread was left to finish on its own and its result will
    /// be dropped; the state shown stays (`report.cancelled` is set).
    Cancelled {
        report: StepReport,
    },
    /// The error estimates of the state a step answered with (`of`, the `view` of that `Done`,
    /// sent with [`Estimates::Pending`]): `view` is that state with them. Computed after the
    /// `Done` (see `super::solver_thread::run` for when). The UI applies them only to the very
    /// state they belong to (`Arc::ptr_eq` with `of`).
    Estimates {
        of: Arc<ViewData>,
        view: Arc<ViewData>,
    },
    /// The error estimates of state `of` (as in [`Reply::Estimates`]) are given up: a newer
    /// command that replaces the state came first, or a cancel of everything queued. Every state
    /// that owes estimates gets one of the two replies; the UI marks this one "not estimated"
    /// ([`ViewData::without_estimates`]).
    EstimatesDropped {
        of: Arc<ViewData>,
    },
}

impl Reply {
    /// Whether error estimates are still owed after this reply, `owed` before it
    /// ([`Reply::Estimates`]): a new state owes its own (a step's answer) or none; the
    /// estimates, or word that they were given up, settle what is owed; the other replies leave
    /// it (the thread settles what is owed before it runs a command that replaces the state).
    /// The solver thread and [`Worker`] both follow it.
    #[must_use]
    pub fn estimates_owed_after(&self, owed: bool) -> bool {
        match self {
            Reply::Loaded { view, .. } | Reply::Done { view, .. } => view.estimates_pending(),
            Reply::Estimates { .. } | Reply::EstimatesDropped { .. } => false,
            Reply::Retargeted
            | Reply::Progress { .. }
            | Reply::Partial { .. }
            | Reply::Replay { .. }
            | Reply::Baked(_)
            | Reply::Failed(_)
            | Reply::Skipped
            | Reply::Cancelled { .. } => owed,
        }
    }

    /// Whether this reply answers a command (the others come on the way, or after the answer).
    /// An answer whose error estimates follow it (counted alike on both sides of the channel:
    /// [`Pictures`]).
    pub(super) fn owes_estimates(&self) -> bool {
        matches!(self, Reply::Done { view, .. } if view.estimates_pending())
    }

    fn answers_a_command(&self) -> bool {
        match self {
            Reply::Loaded { .. }
            | Reply::Done { .. }
            | Reply::Cancelled { .. }
            | Reply::Baked(_)
            | Reply::Failed(_)
            | Reply::Skipped
            | Reply::Retargeted => true,
            Reply::Progress { .. }
            | Reply::Partial { .. }
            | Reply::Replay { .. }
            | Reply::Estimates { .. }
            | Reply::EstimatesDropped { .. } => false,
        }
    }
}

/// A solve sends its picture after a round at most this often (`Reply::Partial`): each one is
/// built for display and drawn while the solve goes on, on the same cores (on a 2-core machine,
/// pictures every 250 ms made the Cornell box's default solve take about 0.2 s longer).
pub const PARTIAL_EVERY: std::time::Duration = std::time::Duration::from_millis(1000);

/// How long the error estimates owed for an answer wait for its picture to be on screen
/// ([`Worker::pictures_shown`]) before they start anyway (a window that draws no frames).
pub const PICTURE_WAIT: std::time::Duration = std::time::Duration::from_millis(1000);

/// Most memory the frames of one refinement replay take (`Reply::Replay`); past it a solve
/// records no more frames (a 2 000-element Cornell box takes about 0.5 MB a frame).
pub const REPLAY_BUDGET_BYTES: usize = 64 << 20;

/// Handle of the solver thread (the thread ends when this is dropped).
/// Started by [`Worker::spawn`], which `super::solver_thread` holds beside the thread's loop.
pub struct Worker {
    pub(super) tx: Sender<(u64, Command)>,
    pub(super) rx: Receiver<Reply>,
    pub(super) cancel: Option<Arc<AtomicBool>>,
    /// Commands sent but not answered yet.
    pub(super) in_flight: usize,
    /// Commands sent so far (each goes with its number).
    pub(super) sent: u64,
    /// Commands numbered up to this one are dropped unrun ([`Worker::cancel_all`]).
    pub(super) skip_through: Arc<AtomicU64>,
    /// Whether the pictures a solve sends as it goes carry the solver's error estimates
    /// ([`Worker::set_partial_estimates`]).
    pub(super) partial_estimates: Arc<AtomicBool>,
    /// Which estimates give way to a newer command ([`Worker::send`], [`Worker::cancel_all`]).
    pub(super) give_way: Arc<GiveWay>,
    /// The last state answered still waits for its error estimates ([`Reply::Estimates`]).
    pub(super) estimates_owed: bool,
    /// Answers received whose error estimates follow them (`Reply::Done` with estimates pending).
    pub(super) answers_owing: u64,
    /// [`Pictures`], shared with the solver thread.
    pub(super) pictures: Arc<Pictures>,
}

/// How the UI tells the solver thread which answers' pictures are on screen: the error
/// estimates owed for an answer wait until its picture is (at most [`PICTURE_WAIT`]), so that
/// computing them does not slow down the display build and the frames that show it.
#[derive(Debug)]
pub struct Pictures {
    /// How many of the answers whose estimates follow them have their picture on screen (or
    /// will not be shown); `u64::MAX` while the UI does not say ([`Worker::waits_for_pictures`]):
    /// the estimates then start at once.
    shown: AtomicU64,
    /// How long, in milliseconds, the estimates wait for a picture at most.
    wait_ms: AtomicU64,
}

impl Default for Pictures {
    fn default() -> Pictures {
        Pictures { shown: AtomicU64::new(u64::MAX), wait_ms: AtomicU64::new(0) }
    }
}

impl Pictures {
    /// Whether the estimates owed for the `n`-th answer that owes them, sent `since`, still
    /// wait for its picture.
    pub(super) fn pending(&self, n: u64, since: std::time::Instant) -> bool {
        self.shown.load(Ordering::SeqCst) < n
            && since.elapsed().as_millis() < u128::from(self.wait_ms.load(Ordering::SeqCst))
    }
}

/// How the UI tells the solver thread that the error estimates it owes give way to a newer
/// command: the number of that command, and a flag that stops the estimates being computed
/// ([`HierarchicalSolver::error_estimates_until`]).
///
/// ```text
///  UI:     below ← max(below, n)  then  stop ← true     (before command n is queued)
///  thread: stop ← false  then  below > seq ? give up : error_estimates_until(stop)
/// ```
/// Either the thread reads the new `below`, or the UI's `stop` lands after the thread cleared
/// it and stops the computation (both sequentially consistent).
#[derive(Debug, Default)]
pub struct GiveWay {
    /// The estimates of the states answered by commands numbered below this one are given up.
    below: AtomicU64,
    /// Set with every raise of `below`.
    stop: AtomicBool,
}

impl GiveWay {
    /// Give up the estimates of the states answered by the commands numbered below `seq` (the
    /// UI's side).
    pub(super) fn from(&self, seq: u64) {
        self.below.fetch_max(seq, Ordering::SeqCst);
        self.stop.store(true, Ordering::SeqCst);
    }

    /// Whether the estimates of the state command `seq` answered are given up.
    pub(super) fn gives_way(&self, seq: u64) -> bool {
        seq < self.below.load(Ordering::SeqCst)
    }

    /// The error estimates of solver `s`, in the state command `seq` answered with; `None` when
    /// they give way to a newer command, before or while they are computed (the solver thread's
    /// side).
    pub(super) fn estimates(&self, seq: u64, s: &HierarchicalSolver) -> Option<Vec<f64>> {
        self.stop.store(false, Ordering::SeqCst);
        if self.gives_way(seq) {
            return None;
        }
        s.error_estimates_until(&self.stop)
    }
}

impl Worker {
    /// Whether the pictures a solve sends as it goes ([`Reply::Partial`]) carry the solver's
    /// error estimates: only while something shows them (the error overlay, the inspector).
    /// Each costs about as much as the solve's work so far, so without them a solve in the
    /// viewer takes what it takes on the command line. A step's answer is followed by them
    /// ([`Reply::Estimates`]).
    pub fn set_partial_estimates(&self, on: bool) {
        self.partial_estimates.store(on, Ordering::Relaxed);
    }

    /// From now on the UI says when the pictures of the answers it received are on screen
    /// ([`Worker::pictures_shown`]), and the error estimates owed for an answer wait for its
    /// picture, `at_most` this long (the viewer: [`PICTURE_WAIT`]).
    pub fn waits_for_pictures(&self, at_most: std::time::Duration) {
        let ms = u64::try_from(at_most.as_millis()).unwrap_or(u64::MAX);
        self.pictures.wait_ms.store(ms, Ordering::SeqCst);
        self.pictures.shown.store(self.answers_owing, Ordering::SeqCst);
    }

    /// The pictures of every answer received so far are on screen (or will not be shown): the
    /// error estimates owed for them may start. Nothing changes unless [`Worker::waits_for_pictures`]
    /// was called.
    pub fn pictures_shown(&self) {
        let shown = &self.pictures.shown;
        if shown.load(Ordering::SeqCst) != u64::MAX {
            shown.store(self.answers_owing, Ordering::SeqCst);
        }
    }

    /// Send a command the user asked for: where it replaces the state
    /// ([`Command::replaces_the_state`]), the error estimates still owed for the states
    /// answered before it give way to it (their computation stops; the UI hears
    /// [`Reply::EstimatesDropped`]), a finished Solve's included.
    pub fn send(&mut self, cmd: Command) {
        if cmd.replaces_the_state() {
            self.give_way.from(self.sent + 1);
        }
        self.queue(cmd);
    }

    /// Queue a command behind those sent, the estimates owed before it not giving way: a
    /// finished Solve's (a run of the history) are computed before it runs. A figure's sweep
    /// queues its solves so, as every run of it and the captions that quote them need their
    /// estimates. (The estimates of any other step are computed only while nothing is queued.)
    pub fn queue(&mut self, cmd: Command) {
        if self.tx.send((self.sent + 1, cmd)).is_ok() {
            self.sent += 1;
            self.in_flight += 1;
        }
    }

    /// Stop the running step and the error estimates being computed, and drop the commands
    /// still queued (a new scene replaces the old one: a figure's queued solves of the previous
    /// scene are not run).
    pub fn cancel_all(&self) {
        self.skip_through.store(self.sent, Ordering::Relaxed);
        self.give_way.from(self.sent + 1);
        self.cancel();
    }

    /// True while a command is queued or running.
    #[must_use]
    pub fn busy(&self) -> bool {
        self.in_flight > 0
    }

    /// Ask the running step to stop early.
    pub fn cancel(&self) {
        if let Some(c) = &self.cancel {
            c.store(true, Ordering::Relaxed);
        }
    }

    /// True while the last state answered waits for its error estimates: they come
    /// ([`Reply::Estimates`]) or word that they were given up ([`Reply::EstimatesDropped`]).
    #[must_use]
    pub fn estimates_owed(&self) -> bool {
        self.estimates_owed
    }

    /// Count reply `r` in: a command answered, the scene's cancel flag, estimates owed.
    fn received(&mut self, r: &Reply) {
        if let Reply::Loaded { cancel, .. } = r {
            self.cancel = Some(Arc::clone(cancel));
        }
        if r.answers_a_command() {
            self.in_flight = self.in_flight.saturating_sub(1);
        }
        if r.owes_estimates() {
            self.answers_owing += 1;
        }
        self.estimates_owed = r.estimates_owed_after(self.estimates_owed);
    }

    /// The solver thread is gone: nothing more will come.
    fn stopped(&mut self) -> Option<Reply> {
        self.estimates_owed = false;
        if self.in_flight > 0 {
            self.in_flight = 0;
            return Some(Reply::Failed("the solver thread stopped".into()));
        }
        None
    }

    /// Next reply, if any (never blocks).
    pub fn poll(&mut self) -> Option<Reply> {
        match self.rx.try_recv() {
            Ok(r) => {
                self.received(&r);
                Some(r)
            }
            Err(TryRecvError::Empty) => None,
            Err(TryRecvError::Disconnected) => self.stopped(),
        }
    }

    /// Block until every command sent is answered and the estimates owed have come (tests and
    /// scripted runs only; never in `ui`).
    pub fn wait_idle(&mut self, on_reply: impl FnMut(Reply)) {
        self.wait_until(true, on_reply);
    }

    /// Block until every command sent is answered, not for the estimates that follow (tests
    /// only).
    pub fn wait_answered(&mut self, on_reply: impl FnMut(Reply)) {
        self.wait_until(false, on_reply);
    }

    fn wait_until(&mut self, estimates: bool, mut on_reply: impl FnMut(Reply)) {
        while self.in_flight > 0 || (estimates && self.estimates_owed) {
            match self.rx.recv() {
                Ok(r) => {
                    self.received(&r);
                    on_reply(r);
                }
                Err(_) => {
                    if let Some(r) = self.stopped() {
                        on_reply(r);
                    }
                    return;
                }
            }
        }
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        // Stop a running step; the thread ends when it sees the closed channel.
        self.cancel();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc::channel;

    fn load(w: &mut Worker, spec: &str, params: HierarchicalParams) -> Arc<ViewData> {
        w.send(Command::Load { scene: Arc::new(Scene::load(spec).unwrap()), params, top: TopLevel::Patches });
        let mut view = None;
        w.wait_idle(|r| {
            if let Reply::Loaded { view: v, .. } = r {
                view = Some(v);
            }
        });
        view.expect("loaded")
    }

    #[test]
    fn steps_run_on_the_named_thread_and_report_back() {
        let (tx, rx) = channel::<String>();
        let tx = std::sync::Mutex::new(tx);
        let mut w = Worker::spawn(move || {
            let name = std::thread::current().name().unwrap_or("").to_owned();
            let _ = tx.lock().map(|t| t.send(name));
        })
        .unwrap();
        let v = load(&mut w, "builtin:cube-one-light", HierarchicalParams::interactive());
        assert_eq!(v.leaves.len(), 6);
        assert!(v.links.is_empty());
        assert_eq!(rx.recv().unwrap(), "radlab-solver");
        w.send(Command::Step(StepKind::Iterate));
        let mut report = None;
        let mut view = None;
        w.wait_idle(|r| {
            if let Reply::Done { report: r, view: v } = r {
                report = r;
                view = Some(v);
            }
        });
        let (report, view) = (report.unwrap(), view.unwrap());
        assert_eq!(report.kind, StepKind::Iterate);
        assert!(!view.links.is_empty());
        assert!(!w.busy());
        // Commands without a scene fail with a message, they do not panic the thread.
        let mut w2 = Worker::spawn(|| {}).unwrap();
        w2.send(Command::Reset);
        let mut failed = false;
        w2.wait_idle(|r| failed |= matches!(r, Reply::Failed(_)));
        assert!(failed);
    }

    #[test]
    fn pictures_on_the_way_carry_estimates_only_when_asked() {
        let mut w = Worker::spawn(|| {}).unwrap();
        load(&mut w, "builtin:cornell", HierarchicalParams::interactive());
        // Per solve: (the largest estimate of its pictures on the way, that of its answer, that
        // of the estimates that follow it).
        let solve = |w: &mut Worker, estimates: bool| {
            w.set_partial_estimates(estimates);
            w.send(Command::Reset);
            w.send(Command::Step(StepKind::Solve));
            let (mut partial, mut done, mut followed, mut pictures) = (0.0f64, None, None, 0);
            let most = |v: &ViewData| v.elements.iter().map(|e| e.error_estimate).fold(0.0, f64::max);
            w.wait_idle(|r| match r {
                Reply::Partial { view } => {
                    pictures += 1;
                    partial = partial.max(most(&view));
                }
                Reply::Done { report: Some(_), view } => {
                    assert!(view.estimates_pending(), "a step answers before its estimates");
                    done = Some(most(&view));
                }
                Reply::Estimates { view, .. } => followed = Some(most(&view)),
                _ => {}
            });
            assert!(pictures > 0, "a solve shows its first round at once");
            (partial, done.expect("the solve answers"), followed.expect("its estimates follow"))
        };
        let (partial, done, followed) = solve(&mut w, false);
        assert!(partial == 0.0 && done == 0.0 && followed > 0.0, "not asked: {partial}, {done}, {followed}");
        let (partial, done, followed) = solve(&mut w, true);
        assert!(partial > 0.0 && done == 0.0 && followed > 0.0, "asked: {partial}, {done}, {followed}");
    }

    /// A step answers with its state without error estimates, marked pending, and the estimates
    /// follow: that state, with the estimates `snapshot_with(true)` gives (a gather's state
    /// shown pushed and pulled, as its answer showed it).
    #[test]
    fn a_steps_estimates_follow_its_answer_and_are_the_solvers() {
        let mut w = Worker::spawn(|| {}).unwrap();
        let p = HierarchicalParams::interactive();
        load(&mut w, "builtin:cornell", p);
        let mut s = HierarchicalSolver::new(Arc::new(Scene::load("builtin:cornell").unwrap()), p).unwrap();
        for kind in [StepKind::Refine, StepKind::Gather, StepKind::Iterate] {
            w.send(Command::Step(kind));
            let mut answers = Vec::new();
            w.wait_idle(|r| answers.push(r));
            let [Reply::Done { report: Some(_), view: done }, Reply::Estimates { of, view }] = &answers[..]
            else {
                panic!("{kind:?}: a step's answer, then its estimates")
            };
            assert!(Arc::ptr_eq(done, of), "{kind:?}: the estimates name the state answered");
            assert!(done.estimates_pending() && view.estimates == Estimates::Included);
            assert!(done.elements.iter().all(|e| e.error_estimate == 0.0), "{kind:?}: none in the answer");
            // The same step here: the worker pushes and pulls a gather before the next step.
            let unpushed = kind == StepKind::Gather;
            let _report = match kind {
                StepKind::Refine => s.refine_step(),
                StepKind::Gather => s.gather_step(),
                _ => {
                    s.push_pull_step();
                    s.iterate()
                }
            };
            let expected = ViewData::of_solver(&s, unpushed);
            assert_eq!(view.elements.len(), expected.elements.len());
            for (got, want) in view.elements.iter().zip(&expected.elements) {
                assert_eq!(got.error_estimate, want.error_estimate, "{kind:?}: element {}", got.id);
                assert_eq!(got.radiosity, want.radiosity, "{kind:?}: element {}", got.id);
            }
            assert!(view.elements.iter().any(|e| e.error_estimate > 0.0) || kind == StepKind::Refine);
            assert_eq!(view.links, done.links, "the state answered, nothing else changed");
        }
    }

    #[test]
    fn a_solves_estimates_wait_until_its_picture_is_shown() {
        let mut w = Worker::spawn(|| {}).unwrap();
        // A wait far longer than the test's: only the UI's word starts the estimates.
        w.waits_for_pictures(std::time::Duration::from_secs(60));
        load(&mut w, "builtin:cornell", HierarchicalParams::interactive());
        w.pictures_shown();
        w.send(Command::Step(StepKind::Solve));
        let mut answers = Vec::new();
        w.wait_answered(|r| answers.push(r));
        assert!(
            answers.iter().any(|r| matches!(r, Reply::Done { view, .. } if view.estimates_pending())),
            "the solve's answer, its estimates owed"
        );
        assert!(w.estimates_owed());
        // Long enough for cornell's estimates at `interactive` (well under a second here).
        std::thread::sleep(std::time::Duration::from_millis(1500));
        while let Some(r) = w.poll() {
            assert!(!matches!(r, Reply::Estimates { .. }), "estimates before the picture was shown");
        }
        assert!(w.estimates_owed(), "still owed while the picture is not shown");
        w.pictures_shown();
        let mut after = Vec::new();
        w.wait_idle(|r| after.push(r));
        assert!(matches!(after[..], [Reply::Estimates { .. }]), "the estimates once it is");
        // A newer command does not wait for a picture: it gives the estimates up at once.
        w.send(Command::Step(StepKind::Solve));
        w.wait_answered(|_| {});
        let t = std::time::Instant::now();
        w.send(Command::Reset);
        let mut last = Vec::new();
        w.wait_answered(|r| last.push(r));
        assert!(last.iter().any(|r| matches!(r, Reply::EstimatesDropped { .. })));
        assert!(t.elapsed() < std::time::Duration::from_secs(30), "answered without the wait");
    }

    /// What a worker's replies say of the error estimates: (the answers, the answers whose
    /// estimates came, the answers whose estimates were given up), each `Estimates` and
    /// `EstimatesDropped` checked to name the last state answered, and every state that owes
    /// estimates checked to get one of the two before the next answer.
    fn estimates_of_answers(w: &mut Worker) -> (usize, Vec<usize>, Vec<usize>) {
        let (mut answered, mut estimated, mut dropped) =
            (Vec::<Arc<ViewData>>::new(), Vec::new(), Vec::new());
        let mut owed = false;
        w.wait_idle(|r| {
            match &r {
                Reply::Done { view, .. } => {
                    assert!(!owed, "an answer while the last one's estimates are owed");
                    answered.push(Arc::clone(view));
                }
                Reply::Estimates { of, .. } | Reply::EstimatesDropped { of } => {
                    let last = answered.last().expect("estimates follow an answer");
                    assert!(Arc::ptr_eq(last, of), "estimates of the last state answered only");
                    let list =
                        if matches!(r, Reply::Estimates { .. }) { &mut estimated } else { &mut dropped };
                    list.push(answered.len() - 1);
                }
                _ => {}
            }
            owed = r.estimates_owed_after(owed);
        });
        assert!(!owed && !w.estimates_owed(), "nothing owed once idle");
        (answered.len(), estimated, dropped)
    }

    /// Estimates never name a state other than the last one answered, and each state that owes
    /// them gets them or word that they were given up: a command sent behind a step gives up
    /// that step's (and a finished Solve's, a run of the history); one queued behind a finished
    /// Solve ([`Worker::queue`], a figure's sweep) waits for the run's, not for a step's; a
    /// cancel of everything queued gives them up.
    #[test]
    fn a_queued_command_drops_the_estimates_of_the_state_it_replaces() {
        let mut w = Worker::spawn(|| {}).unwrap();
        load(&mut w, "builtin:cornell", HierarchicalParams::interactive());
        let iterate = || Command::Step(StepKind::Iterate);
        let solve = || Command::Step(StepKind::Solve);
        // Both sent at once: an iteration takes far longer than the second send.
        w.send(iterate());
        w.send(iterate());
        assert_eq!(estimates_of_answers(&mut w), (2, vec![1], vec![0]), "the first step's given up");
        // Sent behind a solve, before it answers: the run's given up before they start.
        for c in [Command::Reset, solve(), iterate()] {
            w.send(c);
        }
        assert_eq!(estimates_of_answers(&mut w), (3, vec![2], vec![1]), "the run's given up");
        // Queued behind it: the run's kept, a step's not.
        for c in [Command::Reset, solve(), iterate(), iterate()] {
            w.queue(c);
        }
        assert_eq!(estimates_of_answers(&mut w), (4, vec![1, 3], vec![2]), "the run's kept");
        // A restart answers with its own estimates: nothing is owed after it.
        w.send(iterate());
        w.send(Command::Reset);
        assert_eq!(estimates_of_answers(&mut w), (2, vec![], vec![0]), "replaced by the reset");
        // A bake writes the state as it is: the estimates follow it (this one fails at once, on
        // its file's extension, and writes nothing).
        w.send(iterate());
        let options = crate::present::bake::BakeOptions {
            exposure: 1.0,
            exposure_rule: String::new(),
            scene_label: "builtin:cornell".into(),
            params: None,
        };
        let (path, form) = ("not-a-bake.txt".into(), crate::present::bake::BakeForm::Elements);
        w.send(Command::Bake { path, options, form });
        assert_eq!(estimates_of_answers(&mut w), (1, vec![0], vec![]), "kept through the bake");
        // A solve dropped by a cancel of everything queued (unrun, or stopped early), or a
        // finished one whose estimates had not started: given up, the restart queued after it
        // runs first.
        w.send(Command::Reset);
        w.send(solve());
        w.cancel_all();
        w.send(Command::Reset);
        let (answered, estimated, dropped) = estimates_of_answers(&mut w);
        assert!(estimated.is_empty() && dropped.len() <= 1, "{answered} answers: {dropped:?}");
    }

    /// A finished Solve's estimates give way to a command sent while they are computed: it is
    /// answered without waiting for them, and the run is told they were given up (never left
    /// owed). A kept `Retarget` gives them up the same way. The estimates take about the solve's
    /// own time (about a second at `quality`): they are still running when the next command is
    /// sent, as soon as the solve's answer comes.
    #[test]
    fn a_newer_command_stops_a_runs_estimates_and_is_answered_at_once() {
        let mut w = Worker::spawn(|| {}).unwrap();
        let p = HierarchicalParams::quality();
        load(&mut w, "builtin:cornell", p);
        let kinds = |answers: &[Reply]| -> Vec<&'static str> {
            answers
                .iter()
                .filter_map(|r| match r {
                    Reply::Done { report: Some(r), .. } => {
                        Some(if r.kind == StepKind::Solve { "solve" } else { "step" })
                    }
                    Reply::Done { report: None, .. } => Some("restart"),
                    Reply::Estimates { .. } => Some("estimates"),
                    Reply::EstimatesDropped { .. } => Some("dropped"),
                    Reply::Retargeted => Some("retargeted"),
                    _ => None,
                })
                .collect()
        };
        for then in [
            Command::Step(StepKind::Refine),
            Command::Retarget(HierarchicalParams { bf_eps: p.bf_eps / 2.0, ..p }),
        ] {
            w.send(Command::Reset);
            w.send(Command::Step(StepKind::Solve));
            let mut answers = Vec::new();
            w.wait_answered(|r| answers.push(r));
            let Some(Reply::Done { view: solved, .. }) = answers.last() else { panic!("the solve answers") };
            let solved = Arc::clone(solved);
            assert!(solved.estimates_pending() && w.estimates_owed(), "its estimates are being computed");
            let retarget = matches!(then, Command::Retarget(_));
            w.send(then);
            let mut after = Vec::new();
            w.wait_idle(|r| after.push(r));
            let Some(Reply::EstimatesDropped { of }) =
                after.iter().find(|r| !matches!(r, Reply::Progress { .. }))
            else {
                panic!("the run's estimates are given up first: {:?}", kinds(&after))
            };
            assert!(Arc::ptr_eq(of, &solved), "they name the run");
            let expected: &[&str] =
                if retarget { &["dropped", "retargeted"] } else { &["dropped", "step", "estimates"] };
            assert_eq!(kinds(&after), expected);
            assert!(!w.estimates_owed());
        }
    }

    #[test]
    fn each_gather_moves_one_bounce() {
        let mut w = Worker::spawn(|| {}).unwrap();
        load(&mut w, "builtin:cornell", HierarchicalParams::interactive());
        let mut step = |kind| {
            w.send(Command::Step(kind));
            let mut view = None;
            w.wait_idle(|r| {
                if let Reply::Done { view: v, .. } = r {
                    view = Some(v);
                }
            });
            view.expect("a step answers")
        };
        step(StepKind::Refine);
        // The light the leaves reflect, area-weighted: each bounce adds to it.
        let reflected = |v: &ViewData| -> f64 {
            v.leaves
                .iter()
                .map(|&l| &v.elements[l as usize])
                .map(|e| (e.radiosity - e.emission).mean() * e.area)
                .sum()
        };
        let first = reflected(&step(StepKind::Gather));
        let second = reflected(&step(StepKind::Gather));
        let third = reflected(&step(StepKind::Gather));
        assert!(first > 0.0, "the first gather lights the room");
        assert!(second > first * 1.01, "the second gather adds the second bounce: {first} then {second}");
        assert!(third > second, "and the third the third: {second} then {third}");
    }

    /// The residual a step reports and the view's residual list say what each step did: one
    /// entry per gather, the first 1 (all light new), then falling; a push-pull records the
    /// gather's residual (the one already shown), and one with nothing gathered changes nothing.
    #[test]
    fn each_gather_reports_its_own_residual() {
        let mut w = Worker::spawn(|| {}).unwrap();
        load(&mut w, "builtin:cornell", HierarchicalParams::interactive());
        let mut step = |kind| {
            w.send(Command::Step(kind));
            let mut done = None;
            w.wait_idle(|r| {
                if let Reply::Done { report, view } = r {
                    done = Some((report.expect("a step's report"), view));
                }
            });
            done.expect("a step answers")
        };
        let (refined, v) = step(StepKind::Refine);
        assert!(v.residuals.is_empty() && refined.residual == 0.0, "nothing gathered yet");
        let (first, v1) = step(StepKind::Gather);
        assert_eq!(v1.residuals.len(), 1);
        assert!((first.residual - 1.0).abs() < 1e-9, "the first bounce is all new light: {}", first.residual);
        let (second, v2) = step(StepKind::Gather);
        assert_eq!(v2.residuals.len(), 2, "{:?}", v2.residuals);
        assert_eq!(v2.residuals[0], v1.residuals[0], "the push-pull recorded the residual shown");
        assert_eq!(second.residual, v2.residuals[1]);
        assert!(
            second.residual < 0.9 && second.residual > 0.0,
            "the second bounce adds less: {}",
            second.residual
        );
        let (pushed, v3) = step(StepKind::PushPull);
        assert_eq!(v3.residuals, v2.residuals, "the push-pull records what the gather showed");
        assert!((pushed.residual - second.residual).abs() < 1e-12 * second.residual.max(1.0));
        let (again, v4) = step(StepKind::PushPull);
        assert_eq!(v4.residuals, v2.residuals, "nothing gathered: no residual recorded");
        assert_eq!(again.residual, pushed.residual);
        assert!(!again.converged, "a push-pull without a gather does not converge the solve");
        let (_, v5) = step(StepKind::Refine);
        assert_eq!(v5.residuals, v2.residuals, "a refinement keeps the gathers' residuals");
    }

    /// A threshold made finer keeps the solved state: the Solve that follows refines on from the
    /// last one's hierarchy and gathers from its radiosity (its residuals follow the last
    /// solve's). Made coarser again it goes back to the state solved there; coarser than every
    /// solved state, it restarts from the input patches.
    #[test]
    fn a_finer_threshold_retargets_warm_and_a_coarser_one_goes_back_or_restarts() {
        let mut w = Worker::spawn(|| {}).unwrap();
        let p = HierarchicalParams::interactive();
        load(&mut w, "builtin:cornell", p);
        let run = |w: &mut Worker, cmd: Command| {
            w.send(cmd);
            let mut answers = Vec::new();
            w.wait_answered(|r| answers.push(r));
            answers.pop().expect("an answer")
        };
        let Reply::Done { view: solved, .. } = run(&mut w, Command::Step(StepKind::Solve)) else {
            panic!("the solve answers")
        };
        let finer = HierarchicalParams { bf_eps: p.bf_eps / 4.0, ..p };
        assert!(matches!(run(&mut w, Command::Retarget(finer)), Reply::Retargeted), "kept");
        let Reply::Done { report: Some(report), view } = run(&mut w, Command::Step(StepKind::Solve)) else {
            panic!("the warm solve answers")
        };
        assert!(report.converged && report.refined > 0, "it refines on: {report:?}");
        assert!(
            view.stats.leaves > solved.stats.leaves,
            "{} then {}",
            solved.stats.leaves,
            view.stats.leaves
        );
        assert_eq!(view.params, finer);
        assert!(
            view.residuals.len() > solved.residuals.len() && view.residuals.starts_with(&solved.residuals),
            "the warm solve's gathers follow the last solve's"
        );
        assert!(matches!(run(&mut w, Command::Retarget(p)), Reply::Retargeted), "back to the first solve");
        let Reply::Done { view, .. } = run(&mut w, Command::Step(StepKind::Solve)) else {
            panic!("the solve answers")
        };
        assert_eq!(view.stats.leaves, solved.stats.leaves, "the first solve's mesh");
        let coarser = HierarchicalParams { bf_eps: p.bf_eps * 4.0, ..p };
        let Reply::Done { report: None, view } = run(&mut w, Command::Retarget(coarser)) else {
            panic!("a threshold coarser than every solve restarts")
        };
        assert!(view.links.is_empty() && view.residuals.is_empty(), "back to the input patches");
    }

    #[test]
    fn the_display_push_pull_matches_the_solvers() {
        let scene = Arc::new(Scene::load("builtin:cornell").unwrap());
        let mut s = HierarchicalSolver::new(scene, HierarchicalParams::interactive()).unwrap();
        s.refine_step();
        s.gather_step();
        let stale = ViewData::from_snapshot(s.snapshot());
        let shown = ViewData::from_gathered_snapshot(s.snapshot(), &s.push_pull_preview());
        assert!(shown.pushed_for_display && !stale.pushed_for_display);
        s.push_pull_step();
        let pushed = ViewData::from_snapshot(s.snapshot());
        let (mut moved, mut worst) = (0, 0.0f64);
        for ((a, b), old) in shown.elements.iter().zip(&pushed.elements).zip(&stale.elements) {
            let scale = b.radiosity.max_channel().max(1e-300);
            worst = worst.max(a.radiosity.abs_diff_max(b.radiosity) / scale);
            moved += usize::from(old.radiosity.abs_diff_max(b.radiosity) > 1e-9 * scale);
        }
        assert!(moved > 0, "the gather changed what push-pull gives");
        // Different summation order (the solver splits the sums by visibility class).
        assert!(worst < 1e-12, "display push-pull off by {worst:e} relative");
    }

    #[test]
    fn cancel_all_stops_the_running_solve_and_drops_the_queued_commands() {
        let mut w = Worker::spawn(|| {}).unwrap();
        load(&mut w, "builtin:splash_room", HierarchicalParams::quality());
        for _ in 0..3 {
            w.send(Command::Step(StepKind::Solve));
        }
        loop {
            if let Reply::Progress { .. } = w.rx.recv().unwrap() {
                break;
            }
        }
        w.cancel_all();
        let (mut done, mut skipped) = (Vec::new(), 0);
        w.wait_idle(|r| match r {
            Reply::Done { report, .. } => done.push(report.expect("a step's report")),
            Reply::Skipped => skipped += 1,
            _ => {}
        });
        assert_eq!((done.len(), skipped), (1, 2), "the running solve answers, the queued ones are dropped");
        assert!(done[0].cancelled, "the running solve stopped early");
        // What is sent afterwards runs.
        w.send(Command::Step(StepKind::Gather));
        let mut gathered = false;
        w.wait_idle(|r| gathered |= matches!(r, Reply::Done { report: Some(_), .. }));
        assert!(gathered);
    }

    #[test]
    fn a_running_mesh_solve_is_dropped_on_cancel_and_the_next_command_runs_at_once() {
        use crate::solver::meshed::MeshMethod;
        let mut w = Worker::spawn(|| {}).unwrap();
        load(&mut w, "builtin:table-room", HierarchicalParams::interactive());
        // A p = 1 solve on 1 500 unknowns or so: seconds even optimised.
        let params = MeshSolveParams {
            element_size_rel: 0.04,
            ..MeshSolveParams::new(MeshMethod::Uniform).linear(false)
        };
        w.send(Command::SolveMesh(params, DmeshOptions::default()));
        loop {
            match w.rx.recv().unwrap() {
                Reply::Progress { .. } => break,
                Reply::Done { .. } => panic!("the solve ended before its first progress"),
                Reply::Failed(e) => panic!("{e}"),
                _ => {}
            }
        }
        let pressed = std::time::Instant::now();
        w.cancel();
        let mut answers = Vec::new();
        w.wait_idle(|r| answers.push(r));
        let waited = pressed.elapsed();
        assert!(
            matches!(answers.last(), Some(Reply::Cancelled { report }) if report.cancelled),
            "the solve answers Cancelled"
        );
        assert!(waited < std::time::Duration::from_secs(2), "answered in {waited:?}");
        // The next command runs while the dropped solve finishes in the background, and the
        // dropped solve's progress is no longer forwarded.
        w.send(Command::Step(StepKind::Iterate));
        let mut answers = Vec::new();
        w.wait_answered(|r| answers.push(r));
        assert!(matches!(answers.last(), Some(Reply::Done { report: Some(_), .. })));
        assert!(!answers.iter().any(|r| matches!(r, Reply::Progress { .. })), "no stray progress");
    }

    #[test]
    fn a_running_solve_can_be_cancelled() {
        let mut w = Worker::spawn(|| {}).unwrap();
        load(&mut w, "builtin:splash_room", HierarchicalParams::quality());
        w.send(Command::Step(StepKind::Solve));
        // Wait until the solve reports its first round, then cancel it. The solver clears its
        // flag when each sub-step starts, so one press can land in the gap between two
        // sub-steps; keep pressing until the answer comes (as a user would).
        loop {
            if let Reply::Progress { .. } = w.rx.recv().unwrap() {
                break;
            }
        }
        let report = loop {
            w.cancel();
            match w.poll() {
                Some(Reply::Done { report, .. }) => break report,
                Some(Reply::Failed(e)) => panic!("{e}"),
                _ => std::thread::sleep(std::time::Duration::from_millis(20)),
            }
        };
        assert!(
            report.expect("the solve answers").cancelled,
            "the quality solve of splash_room stopped early"
        );
    }
}
