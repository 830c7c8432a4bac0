//! `radlab solve SCENE`: solve a scene, print statistics and the energy balance, optionally write
//! JSON (`--json`), an image (`--png`), the whole hierarchy (`--dump-hierarchy`) and a baked glTF
//! with the radiosity as vertex colours (`--bake`, [`radlab::present::bake`]).

use anyhow::{Context as _, bail};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use radlab::geometry::accel::Accel;
use radlab::geometry::basis::Order;
use radlab::mesh::remesh::{MeshKind, RemeshParams};
use radlab::scene::Scene;
use radlab::solver::PhaseTimes;
use radlab::solver::discontinuity::{self, DiscontinuityParams};
use radlab::solver::linear::LinearParams;
use radlab::solver::params::{AreaEps, HierarchicalParams, Oracle};
use radlab::solver::progressive::ProgressiveParams;
pub use radlab::solver::spec::Solved;
use radlab::solver::spec::{self, Plan as SpecPlan, Preset, SolveSpec};
use radlab::solver::uniform::UniformParams;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

mod output;

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Every patch meshed to --element-size, full form-factor matrix, Gauss–Seidel.
    Uniform,
    /// Southwell shooting of unshot power (progressive refinement).
    Progressive,
    /// Hanrahan–Salzman–Aupperle hierarchical radiosity.
    Hierarchical,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum OracleArg {
    Feps,
    Bf,
    Error,
}

impl From<OracleArg> for Oracle {
    fn from(o: OracleArg) -> Oracle {
        match o {
            OracleArg::Feps => Oracle::Feps,
            OracleArg::Bf => Oracle::Bf,
            OracleArg::Error => Oracle::Error,
        }
    }
}

/// The mesh a solve runs on (`--mesh`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum MeshArg {
    /// The hierarchical solver's adaptive quadtree of the input patches (--method hierarchical).
    Quadtree,
    /// Every patch cut into elements of --element-size (--method uniform or progressive).
    Uniform,
    /// Heckbert's constrained Delaunay discontinuity mesh, one element per piece.
    DiscontinuityCdt,
    /// Campbell & Fussell's BSP discontinuity mesh, one element per piece.
    DiscontinuityBsp,
    /// The input patches cut along their contacts with other patches (D0 lines: an object
    /// standing on a floor, a panel hung on a wall), the top level that the hierarchical solver
    /// then refines as its oracle asks (`RemeshParams::contacts`); with the error oracle its
    /// area floor follows the threshold (6e-4 × --bf-eps-rel) unless --aeps/--aeps-rel is given.
    Contact,
}

impl MeshArg {
    /// The flag's spelling.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            MeshArg::Quadtree => "quadtree",
            MeshArg::Uniform => "uniform",
            MeshArg::DiscontinuityCdt => "discontinuity-cdt",
            MeshArg::DiscontinuityBsp => "discontinuity-bsp",
            MeshArg::Contact => "contact",
        }
    }
}

/// What solves a scene: method, mesh, order and their settings — shared by `radlab solve` and
/// `radlab artifacts`.
/// `--dmesh-budget N|auto|off`: grade the discontinuity mesh to N patches, to a budget chosen
/// from the scene ([`radlab::mesh::grade::auto_budget`]), or not at all.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum BudgetArg {
    Patches(usize),
    Auto,
    Off,
}

impl std::str::FromStr for BudgetArg {
    type Err = String;
    fn from_str(s: &str) -> Result<BudgetArg, String> {
        match s {
            "auto" => Ok(BudgetArg::Auto),
            "off" => Ok(BudgetArg::Off),
            // 0 parses, and grading's validation refuses it in one line.
            n => n
                .parse::<usize>()
                .map(BudgetArg::Patches)
                .map_err(|_| format!("expected a number of patches, auto or off (got {n:?})")),
        }
    }
}

impl BudgetArg {
    /// The grading it asks for (`default` when the flag is absent): `None` ungraded.
    #[must_use]
    pub fn grading(arg: Option<BudgetArg>, default: BudgetArg) -> Option<radlab::mesh::grade::Budget> {
        use radlab::mesh::grade::Budget;
        match arg.unwrap_or(default) {
            BudgetArg::Patches(n) => Some(Budget::Patches(n)),
            BudgetArg::Auto => Some(Budget::Auto),
            BudgetArg::Off => None,
        }
    }

    /// The grading the flags ask for on a D-mesh solved by `plan` (hierarchical: `auto` unless
    /// told; the uniform solver and the contact mesh: `off`).
    fn for_plan(a: &SolverArgs, plan: Route, mesh: MeshArg) -> Option<radlab::mesh::grade::Budget> {
        let default = if matches!(plan, Route::DiscontinuityHierarchical(_)) && mesh != MeshArg::Contact {
            BudgetArg::Auto
        } else {
            BudgetArg::Off
        };
        match plan {
            Route::Discontinuity(_) | Route::DiscontinuityHierarchical(_) => {
                BudgetArg::grading(a.dmesh_budget, default)
            }
            _ => None,
        }
    }
}

#[derive(clap::Args, Debug)]
pub struct SolverArgs {
    /// Solver; default: hierarchical, or the one --mesh implies (uniform for the uniform and the
    /// discontinuity meshes). With --mesh discontinuity-*, hierarchical makes the mesh's pieces
    /// the top level of hierarchical refinement.
    #[arg(long, value_enum)]
    pub method: Option<Method>,
    /// Mesh: quadtree (the hierarchical solver's, the default), uniform, discontinuity-cdt or
    /// discontinuity-bsp (docs/meshing.md).
    #[arg(long, value_enum)]
    pub mesh: Option<MeshArg>,
    /// Smallest angle of the CDT refinement, degrees, 0..=34 (--mesh discontinuity-cdt;
    /// default 20, 0: the unrefined CDT).
    #[arg(long)]
    pub dmesh_min_angle: Option<f64>,
    /// Largest CDT triangle as a fraction of its receiver's area (--mesh discontinuity-cdt;
    /// default: no limit).
    #[arg(long)]
    pub dmesh_max_area: Option<f64>,
    /// Grade the discontinuity mesh to N patches for the whole scene: only the critical segments
    /// that bound a penumbra kept, then pieces split where the direct light varies (the
    /// penumbrae) and by area elsewhere, every patch included (src/mesh/grade.rs; the CDT's
    /// refinement then defaults to none). `auto` chooses N from the scene (the segments' pieces
    /// plus about one piece per (diagonal / 17)² of reflecting area), the default with
    /// --method hierarchical; `off` keeps the ungraded mesh, the default of the uniform solver.
    #[arg(long, value_name = "N|auto|off")]
    pub dmesh_budget: Option<BudgetArg>,
    /// When the mesh is graded: the assumed smooth gradient that sizes elements away from the
    /// shadows, in mean direct radiosities per scene diagonal (default 4; 0: split only where the
    /// direct light varies).
    #[arg(long)]
    pub dmesh_smooth: Option<f64>,
    /// When the mesh is graded: how much more a penumbra's variation counts than elsewhere
    /// (default 100; 1: plain L2 allocation).
    #[arg(long)]
    pub dmesh_penumbra_weight: Option<f64>,
    /// After a p = 0 solve on a discontinuity mesh, re-gather the partly shadowed pieces' direct
    /// light with more rays and give every piece a slope (`solver::discontinuity::gather`;
    /// default true; false: the solve's plain constants).
    #[arg(long)]
    pub dmesh_gather: Option<bool>,

    /// Preset the flags below modify. The ladder, each step halving the error oracle's threshold
    /// on the contact mesh: draft (0.2), interactive (0.1), quality (0.05, the default), fine
    /// (0.025), reference (0.0125). On the quadtree, for teaching and comparison: bf (the BF
    /// oracle), lecture (the lecture's Feps Refine), splash2 (the SPLASH-2 program's settings).
    #[arg(long, default_value = "quality")]
    pub preset: String,
    /// The oracle's threshold, whatever the oracle: the error oracle's ε (an error of B relative
    /// to the scene's mean reflected radiosity; its area floor, 6e-4 × ε of the scene's area,
    /// and the ladder's link budget follow it unless --aeps/--aeps-rel is given), the BF
    /// oracle's BFeps (relative to the
    /// brightest emission) or Feps (hierarchical).
    ///
    /// A list (`0.1,0.05,0.025`) solves at each threshold in turn, each finer step refining from
    /// where the last one stopped and gathering from its radiosity (a warm re-solve); the summary
    /// and the JSON's `walk` give every step's time, size and rays, the rest the last step's.
    #[arg(long, value_delimiter = ',', num_args = 1)]
    pub threshold: Vec<f64>,
    /// Refinement oracle (hierarchical): error (the ladder's), bf or feps.
    #[arg(long, value_enum)]
    pub oracle: Option<OracleArg>,
    /// Form-factor threshold of Refine (hierarchical).
    #[arg(long)]
    pub feps: Option<f64>,
    /// Minimum element area, scene units² (hierarchical).
    #[arg(long, conflicts_with = "aeps_rel")]
    pub aeps: Option<f64>,
    /// Minimum element area as a fraction of the scene's total area (hierarchical). With the
    /// error oracle, shrink it with the threshold, e.g. 6e-4 × --bf-eps-rel as `radlab bench`'s
    /// contact-mesh rows do: at the `quality` preset's fixed 1e-4 the floor, not the threshold,
    /// ends the refinement below --bf-eps-rel ≈ 0.15.
    #[arg(long)]
    pub aeps_rel: Option<f64>,
    /// BF oracle threshold, absolute, units of B (hierarchical).
    #[arg(long, conflicts_with = "bf_eps_rel")]
    pub bf_eps: Option<f64>,
    /// Oracle threshold, relative (hierarchical): BF, a fraction of the scene's largest
    /// emission; the error oracle (`quality`), of its mean reflected radiosity, about the
    /// pointwise error it allows (see --aeps-rel).
    #[arg(long)]
    pub bf_eps_rel: Option<f64>,
    /// Maximum subdivision depth below an input patch (hierarchical).
    #[arg(long)]
    pub max_depth: Option<u8>,
    /// Stop refining once this many links exist (hierarchical).
    #[arg(long)]
    pub max_links: Option<usize>,
    /// Gauss–Seidel instead of Jacobi gathering (hierarchical).
    #[arg(long)]
    pub gauss_seidel: bool,
    /// Gathers between refinements while the mesh still changes (hierarchical; the settled
    /// mesh is gathered to convergence).
    #[arg(long)]
    pub round_iterations: Option<u32>,
    /// Refinement ends when a refinement of the converged solution adds at most this fraction
    /// of the links; 0: until no link changes (hierarchical).
    #[arg(long)]
    pub settle: Option<f64>,
    /// Relative accuracy of each link's Galerkin coefficient (hierarchical; 0: one point at the
    /// smaller element's centroid, SPLASH-2's rule; presets: 1e-3 interactive, 1e-4 quality
    /// and lecture, 0 splash2).
    #[arg(long)]
    pub link_tol: Option<f64>,

    /// Target element size, scene units (uniform, progressive); default: 1/8 of the scene's
    /// bounding-box diagonal.
    #[arg(long)]
    pub element_size: Option<f64>,
    /// Element order (uniform and discontinuity meshes): 0 constant elements, 1 linear triangles /
    /// bilinear quads with a Galerkin solve (src/solver/linear.rs).
    #[arg(long, default_value_t = 0)]
    pub order: u32,
    /// With --order 1: one value per mesh vertex shared by the elements of a patch (continuous
    /// basis) instead of per-element vertex values.
    #[arg(long)]
    pub continuous: bool,
    /// Largest number of shots (progressive).
    #[arg(long)]
    pub max_shots: Option<u32>,
    /// Relative accuracy asked of each form factor's adaptive quadrature (uniform, progressive;
    /// default 1e-9: one element per face of a closed box then matches the exact solution to
    /// 1e-9; 1e-4 is far faster and enough for a picture: docs/solver.md).
    #[arg(long)]
    pub ff_tol: Option<f64>,

    /// Shadow rays per link / element pair.
    #[arg(long)]
    pub rays: Option<u32>,
    /// Convergence tolerance (relative change of radiosity; progressive: unshot/emitted power).
    #[arg(long)]
    pub tolerance: Option<f64>,
    /// Re-test a zero visibility estimate, on a link that would be refined at any other
    /// visibility, with up to this many times the rays before accepting it; 0 never (hierarchical).
    #[arg(long)]
    pub zero_confirm: Option<u32>,
    /// Partially visible links refine at this fraction of BFeps, in (0, 1] (hierarchical, BF
    /// oracle; 1 is SPLASH-2's criterion).
    #[arg(long)]
    pub partial_bf_factor: Option<f64>,
    /// Push each link's variation across its receiver (and its source's radiosity moment)
    /// instead of constants: true in every preset but splash2 (hierarchical; see README,
    /// "Push-pull with slopes").
    #[arg(long)]
    pub push_slopes: Option<bool>,
    /// With push-slopes: a partially visible link's slope reads the visibility at the
    /// receiver's child points where its penumbra matters (a shadow's ramp across a leaf, not a
    /// step between leaves): true in the ladder's presets (hierarchical, error oracle).
    #[arg(long)]
    pub vis_slopes: Option<bool>,
    /// Closed rows: balance the rows of form factors of the leaves of enclosed patches to exactly
    /// 1 by a symmetric scaling, so the white furnace is exact under every oracle and no enclosed
    /// leaf loses or creates light: true in every preset (hierarchical, not clustered, Jacobi;
    /// see docs/solver.md, "Closed rows").
    #[arg(long)]
    pub close_rows: Option<bool>,
    /// Row check: push down the links above a leaf whose row of form factors exceeds 1 (which
    /// creates light) where that adds more than this fraction of the mean reflected radiosity
    /// to its answer; 0 off. 0.05 in interactive, 0.1 in quality, off in lecture and splash2
    /// (hierarchical; see README, "Row check").
    #[arg(long)]
    pub row_tol: Option<f64>,
    /// The error oracle's tail share: a wrong receiver's links are split, largest variation
    /// first, until the others add up to at most this fraction of the threshold; in (0, 1],
    /// 0.25 in every preset. Larger: fewer links and a higher error at a given threshold
    /// (hierarchical, error oracle).
    #[arg(long)]
    pub cause_tail: Option<f64>,
    /// How the error oracle counts a wrong receiver's unsplit links against the tail share:
    /// linear (every preset: the sum of their shares) or signed (what they add to its error,
    /// kernels with signs, penumbras in quadrature: fewer links in cluttered scenes)
    /// (hierarchical, error oracle).
    #[arg(long, value_enum)]
    pub error_tail: Option<radlab::solver::params::ErrorTail>,
    /// Cluster the input patches, so links grow as n, not n² (hierarchical; auto: scenes of
    /// 3000 patches or more; see README, "Clustering").
    #[arg(long, value_enum)]
    pub cluster: Option<radlab::solver::params::Clustering>,
    /// Seed of the visibility jitter.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Worker threads (default: all cores). Results are identical for any count.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Refuse scenes with more triangles than this.
    #[arg(long, default_value_t = 5_000_000)]
    pub max_triangles: usize,

    /// Add the hierarchical solver's own error estimate to the JSON (`error_estimate`: its
    /// global relative L2, no reference needed); costs about as much again as the solve.
    #[arg(long)]
    pub estimate: bool,
    /// End the hierarchical solve after about this many seconds of solving: refinement stops
    /// early enough to leave the solver's estimate of the converging gathers' time, then it
    /// gathers to convergence on the mesh reached (said on stderr and in the JSON's `cancelled`
    /// and `notes`). The gathers stop at the budget's end, converged or not (the note then gives
    /// the residual); linking the input patches is not stopped. Hierarchical solves only.
    #[arg(long, value_name = "SECONDS")]
    pub time_budget: Option<f64>,
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene: a .gltf/.glb path or builtin:NAME (see `radlab scenes`).
    pub scene: String,
    #[command(flatten)]
    pub solver: SolverArgs,

    /// Write the JSON result to PATH (`-` for stdout).
    #[arg(long)]
    pub json: Option<String>,
    /// Write an image of the solution from the scene's default camera.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Image size for --png.
    #[arg(long, default_value_t = 640)]
    pub width: usize,
    #[arg(long, default_value_t = 480)]
    pub height: usize,
    /// Write every element (vertices, radiosity) and link (receiver, source, F, visibility) as JSON.
    #[arg(long)]
    pub dump_hierarchy: Option<PathBuf>,
    /// Write the solved mesh with its radiosity as vertex colours, unlit (COLOR_0, linear; the
    /// exposure and units in `extras`): PATH.glb, or PATH.gltf with the buffer embedded.
    #[arg(long, value_name = "PATH")]
    pub bake: Option<PathBuf>,
    /// COLOR_0 (or a lightmap texel) = clamp(B × this, 0, 1) in the bake; default: the --png
    /// image's exposure (the 99th percentile of the luminance the default camera sees at --width ×
    /// --height maps to 1).
    #[arg(long, requires = "bake")]
    pub bake_exposure: Option<f64>,
    /// Bake the original meshes (one polygon per input patch) with a SIZE×SIZE lightmap instead
    /// of the refined elements: TEXCOORD_1 into one atlas, embedded as an sRGB PNG, unlit. SIZE is
    /// a power of two from 64 to 8192.
    #[arg(long, value_name = "SIZE", requires = "bake")]
    pub bake_lightmap: Option<u32>,
    /// No progress bar, no summary (errors still go to stderr).
    #[arg(long, short)]
    pub quiet: bool,
}

/// Load a scene spec with a triangle cap, with the file named in any error.
pub fn load_scene(spec: &str, max_triangles: usize) -> anyhow::Result<radlab::scene::Scene> {
    let scene = if let Some(name) = spec.strip_prefix("builtin:") {
        radlab::scene::builtin::load(name)?
    } else {
        let opts = radlab::scene::gltf::LoadOptions { max_triangles, ..Default::default() };
        radlab::scene::gltf::load(std::path::Path::new(spec), &opts)?
    };
    Ok(scene)
}

/// Configure the global rayon pool once.
pub fn set_threads(threads: Option<usize>) -> anyhow::Result<()> {
    if let Some(t) = threads {
        if t == 0 {
            bail!("--threads must be at least 1");
        }
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build_global()
            .context("configuring the thread pool")?;
    }
    Ok(())
}

/// A progress bar on stderr that appears only once work has taken more than a second.
pub struct LazyBar {
    bar: ProgressBar,
    start: Instant,
    shown: bool,
    quiet: bool,
}

impl LazyBar {
    pub fn new(msg: &str, quiet: bool) -> LazyBar {
        let bar = ProgressBar::with_draw_target(Some(1), ProgressDrawTarget::hidden());
        bar.set_style(
            ProgressStyle::with_template("{msg:12} [{elapsed_precise}] {bar:40} {pos}/{len}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar.set_message(msg.to_string());
        LazyBar { bar, start: Instant::now(), shown: false, quiet }
    }
    pub fn update(&mut self, done: u64, total: u64) {
        if !self.shown && !self.quiet && self.start.elapsed() > Duration::from_secs(1) {
            self.bar.set_draw_target(ProgressDrawTarget::stderr());
            self.shown = true;
        }
        self.bar.set_length(total.max(1));
        self.bar.set_position(done);
    }
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

/// The preset `--preset` names.
pub fn preset(args: &SolverArgs) -> anyhow::Result<Preset> {
    Preset::from_name(&args.preset)
        .with_context(|| format!("unknown preset {:?} (one of {})", args.preset, Preset::names()))
}

/// The hierarchical solver's settings: the preset's, modified by the flags. The one threshold
/// (`--threshold`, or the oracle's own flag) is resolved by [`spec::with_threshold`]; with the
/// error oracle the area floor and the ladder's link budget follow it unless `--aeps`/`--aeps-rel`
/// is given.
pub fn hierarchical_params(args: &SolverArgs) -> anyhow::Result<HierarchicalParams> {
    let mut p = preset(args)?.hierarchical();
    if let Some(o) = args.oracle {
        p.oracle = o.into();
    }
    let floor_follows = args.aeps.is_none() && args.aeps_rel.is_none();
    if let Some(&v) = args.threshold.last() {
        p = spec::with_threshold(p, v, floor_follows);
    }
    if let Some(v) = args.feps {
        p.feps = v;
    }
    if let Some(v) = args.bf_eps {
        p.bf_eps = v;
        p.bf_relative = false;
    }
    if let Some(v) = args.bf_eps_rel {
        p = HierarchicalParams { bf_eps: v, bf_relative: true, ..p };
        if p.oracle == Oracle::Error && floor_follows {
            p = discontinuity::contact_area_floor(p);
        }
    }
    if let Some(v) = args.aeps {
        p.aeps = AreaEps::Absolute(v);
    }
    if let Some(v) = args.aeps_rel {
        p.aeps = AreaEps::Relative(v);
    }
    if let Some(v) = args.max_depth {
        p.max_depth = v;
    }
    if let Some(v) = args.max_links {
        p.max_links = v;
    }
    if let Some(v) = args.rays {
        p.rays = v;
    }
    if let Some(v) = args.tolerance {
        p.tolerance = v;
    }
    if let Some(v) = args.zero_confirm {
        p.zero_confirm = v;
    }
    if let Some(v) = args.partial_bf_factor {
        p.partial_bf_factor = v;
    }
    if let Some(v) = args.row_tol {
        p.row_tol = v;
    }
    if let Some(v) = args.cause_tail {
        p.cause_tail = v;
    }
    if let Some(v) = args.error_tail {
        p.error_tail = v;
    }
    if let Some(v) = args.vis_slopes {
        p.vis_slopes = v;
    }
    if let Some(v) = args.push_slopes {
        p.push_slopes = v;
    }
    if let Some(v) = args.close_rows {
        p.close_rows = v;
    }
    if let Some(v) = args.cluster {
        p.cluster = v;
    }
    if let Some(v) = args.round_iterations {
        p.round_iterations = v;
    }
    if let Some(v) = args.settle {
        p.settle = v;
    }
    if let Some(v) = args.link_tol {
        p.link_tol = v;
    }
    p.gauss_seidel = args.gauss_seidel;
    p.seed = args.seed;
    p.validate().map_err(anyhow::Error::msg).context("invalid parameters")?;
    Ok(p)
}

/// What `--method` and `--mesh` resolve to.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Route {
    Hierarchical,
    Uniform,
    Progressive,
    /// The uniform (p = 0) or Galerkin (p = 1) solve on a discontinuity mesh.
    Discontinuity(MeshKind),
    /// A mesh (the contact mesh, or a discontinuity mesh) as the top level of the hierarchical
    /// solver.
    DiscontinuityHierarchical(MeshKind),
}

/// Resolve `--method`, `--mesh`, `--order` and the mesh flags, refusing the combinations that
/// make no sense with a one-line reason. Without `--mesh`, the hierarchical solver runs on the
/// preset's top level (the contact mesh on the ladder, the quadtree for bf, lecture, splash2).
pub fn plan(a: &SolverArgs) -> anyhow::Result<(Route, MeshArg)> {
    let preset_mesh = match preset(a)?.top() {
        spec::TopLevel::Patches => MeshArg::Quadtree,
        spec::TopLevel::Mesh(_) | spec::TopLevel::Auto => MeshArg::Contact,
    };
    let mesh = a.mesh.unwrap_or(match a.method {
        None | Some(Method::Hierarchical) => preset_mesh,
        Some(Method::Uniform | Method::Progressive) => MeshArg::Uniform,
    });
    let plan = match (mesh, a.method) {
        (MeshArg::Quadtree, None | Some(Method::Hierarchical)) => Route::Hierarchical,
        (MeshArg::Uniform, None | Some(Method::Uniform)) => Route::Uniform,
        (MeshArg::Uniform, Some(Method::Progressive)) => Route::Progressive,
        (MeshArg::DiscontinuityCdt, None | Some(Method::Uniform)) => Route::Discontinuity(MeshKind::Cdt),
        (MeshArg::DiscontinuityBsp, None | Some(Method::Uniform)) => Route::Discontinuity(MeshKind::Bsp),
        (MeshArg::DiscontinuityCdt, Some(Method::Hierarchical)) => {
            Route::DiscontinuityHierarchical(MeshKind::Cdt)
        }
        (MeshArg::DiscontinuityBsp | MeshArg::Contact, Some(Method::Hierarchical)) => {
            Route::DiscontinuityHierarchical(MeshKind::Bsp)
        }
        (MeshArg::Contact, None) => Route::DiscontinuityHierarchical(MeshKind::Bsp),
        (MeshArg::Contact, Some(m)) => bail!(
            "--mesh contact is the top level of the hierarchical solver (--method hierarchical), not of --method {}",
            format!("{m:?}").to_lowercase()
        ),
        (MeshArg::Quadtree, Some(m)) => bail!(
            "--mesh quadtree is the hierarchical solver's own mesh; --method {} meshes uniformly (use --mesh uniform)",
            format!("{m:?}").to_lowercase()
        ),
        (MeshArg::Uniform, Some(Method::Hierarchical)) => bail!(
            "--method hierarchical refines its own quadtree (--mesh quadtree); --mesh uniform needs --method uniform or progressive"
        ),
        (m, Some(other)) => bail!(
            "--mesh {} is solved by the uniform solver (one element per piece) or, as its top level, by --method hierarchical; not by --method {}",
            m.name(),
            format!("{other:?}").to_lowercase()
        ),
    };
    let discontinuity = matches!(plan, Route::Discontinuity(_) | Route::DiscontinuityHierarchical(_));
    let hierarchical = matches!(plan, Route::Hierarchical | Route::DiscontinuityHierarchical(_));
    if a.element_size.is_some() && !matches!(plan, Route::Uniform | Route::Progressive) {
        bail!(
            "--element-size applies to --mesh uniform; --mesh {} sizes its own elements{}",
            mesh.name(),
            if discontinuity { " (one per piece; refine the CDT with --dmesh-max-area)" } else { "" }
        );
    }
    if (a.dmesh_min_angle.is_some() || a.dmesh_max_area.is_some()) && mesh != MeshArg::DiscontinuityCdt {
        bail!(
            "--dmesh-min-angle and --dmesh-max-area apply to --mesh discontinuity-cdt (not {})",
            mesh.name()
        );
    }
    if a.dmesh_budget.is_some() && !discontinuity {
        bail!(
            "--dmesh-budget applies to --mesh discontinuity-cdt, discontinuity-bsp and contact (not {})",
            mesh.name()
        );
    }
    if (a.dmesh_smooth.is_some() || a.dmesh_penumbra_weight.is_some())
        && BudgetArg::for_plan(a, plan, mesh).is_none()
    {
        bail!(
            "--dmesh-smooth and --dmesh-penumbra-weight tune a graded discontinuity mesh (--dmesh-budget N|auto; auto is the default with --method hierarchical)"
        );
    }
    if a.continuous && BudgetArg::for_plan(a, plan, mesh).is_some() {
        bail!(
            "--dmesh-budget grades the mesh with cuts that end on a neighbour's edge (T-vertices): a continuous basis needs a conforming mesh"
        );
    }
    if a.ff_tol.is_some() && hierarchical {
        bail!(
            "--ff-tol applies to --mesh uniform and the discontinuity meshes (the hierarchical solver's links use their own kernel)"
        );
    }
    if !hierarchical && !a.threshold.is_empty() {
        bail!("--threshold sets the hierarchical solver's oracle; --mesh {} has no oracle", mesh.name());
    }
    match a.order {
        0 if a.continuous => bail!("--continuous needs --order 1 (constant elements share no values)"),
        0 => {}
        1 if plan == Route::Hierarchical => bail!(
            "--order 1 is not implemented on --mesh quadtree (the hierarchical solver's elements are constant); use --mesh uniform, discontinuity-cdt or discontinuity-bsp"
        ),
        1 if hierarchical => bail!(
            "--order 1 is not implemented on the hierarchical solver (its elements are constant); use --mesh uniform, discontinuity-cdt or discontinuity-bsp"
        ),
        1 if plan == Route::Progressive => {
            bail!(
                "--order 1 needs the Galerkin solver (--method uniform); progressive shoots constant elements"
            )
        }
        1 if a.ff_tol.is_some() => bail!(
            "--ff-tol applies to the order-0 solver; --order 1 integrates its couplings with a fixed Gauss rule (src/solver/linear.rs)"
        ),
        1 => {}
        p => bail!("--order {p}: supported orders are 0 (constant) and 1 (linear / bilinear)"),
    }
    Ok((plan, mesh))
}

/// Grading to `budget` with `--dmesh-smooth` and `--dmesh-penumbra-weight` where given
/// ([`radlab::mesh::grade::GradeParams::auto`]'s otherwise).
pub fn grade_params(
    budget: radlab::mesh::grade::Budget,
    smooth: Option<f64>,
    penumbra_weight: Option<f64>,
) -> radlab::mesh::grade::GradeParams {
    let g = radlab::mesh::grade::GradeParams { budget, ..radlab::mesh::grade::GradeParams::auto() };
    radlab::mesh::grade::GradeParams {
        smooth: smooth.unwrap_or(g.smooth),
        penumbra_weight: penumbra_weight.unwrap_or(g.penumbra_weight),
        ..g
    }
}

/// The discontinuity mesh `--dmesh-*` asks for (kind from `--mesh`, grading by the plan:
/// [`BudgetArg::for_plan`]).
fn remesh_params(a: &SolverArgs, plan: Route, mesh: MeshArg, kind: MeshKind) -> anyhow::Result<RemeshParams> {
    let max_patches = if matches!(plan, Route::DiscontinuityHierarchical(_)) {
        radlab::mesh::remesh::HIERARCHICAL_MAX_PIECES
    } else {
        RemeshParams::cdt().max_patches
    };
    let grade =
        BudgetArg::for_plan(a, plan, mesh).map(|b| grade_params(b, a.dmesh_smooth, a.dmesh_penumbra_weight));
    if mesh == MeshArg::Contact {
        return Ok(RemeshParams { grade, ..RemeshParams::contacts() });
    }
    RemeshParams::for_solve(kind, a.dmesh_min_angle, a.dmesh_max_area, grade, max_patches)
        .context("invalid --dmesh-min-angle / --dmesh-max-area / --dmesh-budget / --dmesh-smooth / --dmesh-penumbra-weight")
}

/// The [`SolveSpec`] the flags ask for ([`plan`], the preset and the flags that modify it).
pub fn solve_spec(a: &SolverArgs, scene: &Scene) -> anyhow::Result<SolveSpec> {
    let (route, mesh) = plan(a)?;
    let default_size = scene.bounds().diagonal() / 8.0;
    let invalid = |e: String| anyhow::Error::msg(e).context("invalid parameters");
    let linear = |element_size: f64| -> anyhow::Result<LinearParams> {
        let mut p = LinearParams {
            seed: a.seed,
            element_size,
            order: Order::Linear,
            continuous: a.continuous,
            ..LinearParams::default()
        };
        if let Some(v) = a.rays {
            p.rays = v;
        }
        if let Some(v) = a.tolerance {
            p.tolerance = v;
        }
        p.validate().map_err(invalid)?;
        Ok(p)
    };
    let plan = match route {
        Route::Hierarchical => {
            SpecPlan::Hierarchical { params: hierarchical_params(a)?, top: spec::TopLevel::Patches }
        }
        // The preset's own top level (the ladder's contact mesh below a size, the patches above).
        Route::DiscontinuityHierarchical(_) if a.mesh.is_none() && a.dmesh_budget.is_none() => {
            SpecPlan::Hierarchical { params: hierarchical_params(a)?, top: preset(a)?.top() }
        }
        Route::DiscontinuityHierarchical(kind) => {
            let remesh = remesh_params(a, route, mesh, kind)?;
            SpecPlan::Hierarchical { params: hierarchical_params(a)?, top: spec::TopLevel::Mesh(remesh) }
        }
        Route::Uniform if a.order == 1 => SpecPlan::Linear(linear(a.element_size.unwrap_or(default_size))?),
        Route::Uniform => {
            let mut p = UniformParams {
                seed: a.seed,
                element_size: a.element_size.unwrap_or(default_size),
                ..UniformParams::default()
            };
            if let Some(v) = a.rays {
                p.rays = v;
            }
            if let Some(v) = a.tolerance {
                p.tolerance = v;
            }
            if let Some(v) = a.ff_tol {
                p.ff_tolerance = v;
            }
            p.validate().map_err(invalid)?;
            SpecPlan::Uniform(p)
        }
        Route::Progressive => {
            let mut p = ProgressiveParams {
                seed: a.seed,
                element_size: a.element_size.unwrap_or(default_size),
                ..ProgressiveParams::default()
            };
            if let Some(v) = a.rays {
                p.rays = v;
            }
            if let Some(v) = a.tolerance {
                p.tolerance = v;
            }
            if let Some(v) = a.max_shots {
                p.max_shots = v;
            }
            if let Some(v) = a.ff_tol {
                p.ff_tolerance = v;
            }
            p.validate().map_err(invalid)?;
            SpecPlan::Progressive(p)
        }
        Route::Discontinuity(kind) => {
            let mut p = DiscontinuityParams::with_mesh(remesh_params(a, route, mesh, kind)?);
            p.solve.seed = a.seed;
            if let Some(g) = a.dmesh_gather {
                p.gather = g;
            }
            if let Some(v) = a.rays {
                p.solve.rays = v;
            }
            if let Some(v) = a.tolerance {
                p.solve.tolerance = v;
            }
            if let Some(v) = a.ff_tol {
                p.solve.ff_tolerance = v;
            }
            p.solve.validate().map_err(invalid)?;
            let linear = if a.order == 1 { Some(linear(f64::INFINITY)?) } else { None };
            SpecPlan::Discontinuity { params: p, linear }
        }
    };
    Ok(SolveSpec { plan, estimate: a.estimate })
}

/// Solve `scene` as `a` says ([`solve_spec`], [`radlab::solver::spec::solve`]; with several
/// `--threshold` values, [`radlab::solver::spec::solve_walk`] and its steps); `spec` names the
/// scene in errors.
pub fn solve_scene(
    a: &SolverArgs,
    spec: &str,
    scene: &Arc<Scene>,
    accel: &Arc<Accel>,
    bvh_s: f64,
    progress: radlab::solver::Progress,
) -> anyhow::Result<(Solved, Vec<spec::WalkStep>)> {
    let s = solve_spec(a, scene)?;
    solve_with(a, spec, &s, scene, accel, bvh_s, progress)
}

/// Solve `scene` by `s` with the rest of `a` (the thresholds of a walk, the time budget), and
/// print the solve's notes on stderr; `spec` names the scene in errors.
pub fn solve_with(
    a: &SolverArgs,
    spec: &str,
    s: &SolveSpec,
    scene: &Arc<Scene>,
    accel: &Arc<Accel>,
    bvh_s: f64,
    progress: radlab::solver::Progress,
) -> anyhow::Result<(Solved, Vec<spec::WalkStep>)> {
    if let Some(secs) = a.time_budget {
        if !(secs > 0.0 && secs <= MAX_TIME_BUDGET_S) {
            bail!("--time-budget {secs}: a number of seconds in (0, {MAX_TIME_BUDGET_S}]");
        }
        if s.hierarchical().is_none() {
            bail!("--time-budget stops the hierarchical solver only; --mesh {} runs another", s.mesh_name());
        }
    }
    // The budget ends the solve: its refinement, and the gathers that converge the mesh reached.
    let stopped = match a.time_budget {
        Some(secs) => spec::Stopped::ConvergedBy(Instant::now() + Duration::from_secs_f64(secs)),
        None => spec::Stopped::Converged,
    };
    let (mut solved, walk) = if a.threshold.len() > 1 {
        let floor_follows = a.aeps.is_none() && a.aeps_rel.is_none();
        spec::solve_walk(scene, accel, bvh_s, s, &a.threshold, floor_follows, progress, None, stopped)
            .with_context(|| format!("solving {spec}"))?
    } else {
        let solved = spec::solve_stopping(scene, accel, bvh_s, s, progress, None, stopped)
            .with_context(|| format!("solving {spec}"))?;
        (solved, Vec::new())
    };
    if let (true, Some(secs)) = (solved.cancelled, a.time_budget) {
        solved.notes.push(match solved.gathers_cut {
            None => format!(
                "refinement stopped at the time budget of {secs} s: the answer is the converged solution on the mesh reached, coarser than asked"
            ),
            Some(residual) => format!(
                "refinement stopped at the time budget of {secs} s and the gathers stopped at its end before converging (residual {residual:.1e}, power balance residual {:.1e}): the answer is unconverged, on a mesh coarser than asked; raise --time-budget",
                solved.solution.energy.relative_residual()
            ),
        });
    }
    for note in &solved.notes {
        eprintln!("radlab: {spec}: {note}");
    }
    Ok((solved, walk))
}

/// The longest `--time-budget`: a week.
const MAX_TIME_BUDGET_S: f64 = 7.0 * 24.0 * 3600.0;

/// `radlab solve`: load the scene, solve it, then write what `args` asks for ([`output::write`]).
pub fn run(args: Args) -> anyhow::Result<()> {
    let a = &args.solver;
    set_threads(a.threads)?;
    let bake_format = match &args.bake {
        Some(out) => Some(output::check_bake_path(out, &args.scene, args.bake_exposure, args.bake_lightmap)?),
        None => None,
    };
    plan(a)?;
    let t_total = Instant::now();
    let t = Instant::now();
    let scene = Arc::new(load_scene(&args.scene, a.max_triangles)?);
    let load_s = t.elapsed().as_secs_f64();
    if !args.quiet {
        for w in &scene.warnings {
            eprintln!("radlab: warning: {}: {w}", args.scene);
        }
    }
    let t = Instant::now();
    let accel = Arc::new(Accel::build(&scene));
    let bvh_s = t.elapsed().as_secs_f64();

    let (route, mesh) = plan(a)?;
    let label = match route {
        Route::Discontinuity(_) | Route::DiscontinuityHierarchical(_) => mesh.name().to_string(),
        _ => format!("{route:?}").to_lowercase(),
    };
    let mut bar = LazyBar::new(&label, args.quiet);
    let (mut solved, walk) =
        solve_scene(a, &args.scene, &scene, &accel, bvh_s, &mut |d, n| bar.update(d, n))?;
    bar.finish();
    let solution = &mut solved.solution;
    solution.stats.time_s = PhaseTimes {
        load: load_s,
        bvh: bvh_s,
        total: t_total.elapsed().as_secs_f64(),
        ..solution.stats.time_s
    };
    output::write(&args, &scene, &accel, &solved, &walk, bake_format)
}
