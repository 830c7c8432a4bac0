//! Solver settings as data: `Copy` structs with named `const fn` presets.
//!
//! Parameters, mutable solver state and statistics are three separate types; nothing is global.

use serde::Serialize;

/// The error oracle's tail share in every preset (`HierarchicalParams::cause_tail`; why this
/// value: `solver::hierarchical::oracle`).
pub const DEFAULT_CAUSE_TAIL: f64 = 0.25;

/// Which test decides that a link is accurate enough (HSA91, sec. 4; SPLASH-2 `radiosity`).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Oracle {
    /// Link when both form-factor estimates F_pq, F_qp are below `feps` (the lecture's Refine).
    Feps,
    /// Link when B_source · F · (error bound) is below `bf_eps` (error-driven; re-applied after
    /// each gather so the mesh follows the light).
    Bf,
    /// Split where a receiver's answer is wrong: the variation of its total gathered radiosity
    /// across it (own and inherited links at its would-be children's centroids) and the
    /// visibility uncertainty of its partially visible links, against `bf_eps`
    /// (`solver::hierarchical::oracle`).
    Error,
}

/// Whether the solver builds a cluster hierarchy above the input patches
/// (`solver::hierarchical::cluster`): links between groups of patches instead of every pair.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Clustering {
    /// Link every pair of input patches (HSA91: the hierarchy only subdivides).
    Off,
    /// Cluster scenes of at least `AUTO_PATCHES` (3000) input patches.
    Auto,
    /// Always cluster.
    On,
}

/// How the error oracle counts the rest of a wrong receiver's links, those it leaves unsplit
/// (`HierarchicalParams::error_tail`; `solver::hierarchical::oracle`, "the tail").
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum ErrorTail {
    /// The sum of their shares c_rq (each link's own variation, taken alone): every preset.
    Linear,
    /// What they add to the receiver's error as e_r sums it: their kernels' variation with
    /// signs (links that vary in opposite ways across the receiver cancel), their penumbra terms
    /// in quadrature (the shadows of independent occluders are not all at their worst at once),
    /// as the receiver's own e_r then takes them too.
    Signed,
}

impl Clustering {
    /// `Auto` clusters from this many input patches: below it, linking every pair costs less
    /// than a second (the built-in scenes have at most a few hundred patches).
    pub const AUTO_PATCHES: usize = 3000;

    /// Cluster a scene of `patches` input patches?
    #[must_use]
    pub fn applies(self, patches: usize) -> bool {
        match self {
            Clustering::Off => false,
            Clustering::Auto => patches >= Self::AUTO_PATCHES,
            Clustering::On => true,
        }
    }
}

/// Minimum element area: absolute (scene units²) or a fraction of the scene's total area.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "lowercase", tag = "kind", content = "value")]
pub enum AreaEps {
    Absolute(f64),
    Relative(f64),
}

impl AreaEps {
    /// The absolute floor for a scene of total area `scene_area`.
    #[must_use]
    pub fn resolve(self, scene_area: f64) -> f64 {
        match self {
            AreaEps::Absolute(a) => a,
            AreaEps::Relative(r) => r * scene_area,
        }
    }
}

/// Settings of the hierarchical solver.
///
/// | field | speed | error |
/// |---|---|---|
/// | `feps` ↓ | more links, slower | smaller form-factor error per link |
/// | `aeps` ↓ | deeper trees where light changes | sharper shadows, Mach bands shrink |
/// | `bf_eps` ↓ | more refinement where B·F is large | smaller energy error per link |
/// | `rays` ↑ | linear in link cost | smoother penumbrae, better V estimates |
/// | `max_depth` | caps the tree | a hard floor on resolution |
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct HierarchicalParams {
    pub oracle: Oracle,
    /// Form-factor threshold of the lecture's Refine (the `feps` oracle).
    pub feps: f64,
    /// Elements of area at or below this are never subdivided.
    pub aeps: AreaEps,
    /// Threshold of the BF oracle, in units of B (radiosity × form factor) when
    /// `bf_relative` is false, else as a fraction of the scene's largest emission E_max
    /// (so one setting behaves the same whatever the scene's radiometric units).
    pub bf_eps: f64,
    /// Interpret `bf_eps` relative to the scene's largest emission (BF oracle), or to the
    /// area-weighted mean reflected radiosity of the current solution (error oracle, whose
    /// threshold is an error of B: 0.01 = one percent of the scene's mean reflected light; the
    /// largest emission until anything has been gathered).
    pub bf_relative: bool,
    /// Shadow rays per link for the visible fraction.
    pub rays: u32,
    /// Maximum quadtree depth below an input patch.
    pub max_depth: u8,
    /// Convergence: stop iterating when the largest change of any element's radiosity, relative
    /// to the largest radiosity in the scene, is below this.
    pub tolerance: f64,
    /// Refinement stops splitting once this many links exist (a hard memory and time budget;
    /// `stats.budget_hit` says when it bound). Under the error oracle, the pass that would
    /// overrun it splits the pairs of the largest receiver errors only, and is the last.
    pub max_links: usize,
    /// Safety cap on gather iterations per solve.
    pub max_iterations: u32,
    /// Safety cap on refine→gather rounds (the HSA91 outer loop).
    pub max_rounds: u32,
    /// Gathers per round while the mesh is still changing: the next refinement comes after this
    /// many gathers, not after convergence (a refinement that adds at most `settle` of the
    /// links, and the last allowed round, converge fully). `max_iterations`: converge every round.
    pub round_iterations: u32,
    /// The mesh has settled, and refinement ends, when a refinement after the first adds at
    /// most this fraction of the links (its few links are gathered to convergence, and no
    /// refinement follows); 0: refine until a refinement of the converged solution changes no
    /// link.
    pub settle: f64,
    /// Gauss–Seidel (use new radiosities as soon as a patch is gathered) instead of Jacobi.
    pub gauss_seidel: bool,
    /// When the element with the larger form-factor estimate is at the Aeps floor, split the other
    /// one instead (off: the lecture's Refine links them).
    pub split_fallback: bool,
    /// A new link whose visibility estimate is 0 but that the oracle would refine whatever its
    /// visibility (unless it is 0) is re-tested with up to `zero_confirm × rays` more rays before
    /// the zero is accepted (0: never). For such a link a zero is the only way refinement stops,
    /// so without the test each level of refinement loses the expected P(zero) · V of the
    /// link's light, and the losses compound over the levels (a floor lit through many small
    /// links comes out dark; docs/solver.md, "Visibility"). With `conservative`, links the
    /// oracle would refine only were they partially visible are re-tested too.
    pub zero_confirm: u32,
    /// Partially visible links refine at this fraction of BFeps (BF oracle; in (0, 1]). 1 is the
    /// SPLASH-2 program's criterion (its error term counts a partially visible link's whole
    /// form factor); below 1, shadow boundaries refine further than light variation does.
    pub partial_bf_factor: f64,
    /// Conservative BF oracle: straddling pairs are also estimated at four interior points (a
    /// lamp standing on a floor is otherwise never refined), and a partially visible link's
    /// source term is its brightest leaf rather than its average (B_avg · V_avg counts a hidden
    /// dark part twice); zero visibility estimates of links it would refine were they partially
    /// visible are re-tested (`zero_confirm`). Off in `splash2`, which follows the SPLASH-2
    /// program's centroid estimates.
    pub conservative: bool,
    /// The lecture's five-times rule for link form factors: a pair whose larger element is at
    /// least five of its diameters from the smaller one's centroid, and wholly in front of it,
    /// gets the disk estimate instead of the exact point-to-polygon kernel (see
    /// `solver::hierarchical`). Cheaper; changes F by about a percent on those links.
    pub five_times: bool,
    /// Relative accuracy of a refined link's Galerkin coefficient (`solver::hierarchical::transfer`:
    /// the Gauss order grows as the pair gets closer until it meets it, adaptive cubature
    /// beyond); 0: the kernel at the smaller element's centroid, SPLASH-2's one-point rule.
    /// Input patch pairs are always integrated to 1e-7 where they are near. Exactness in
    /// closed scenes (Σ F = 1 per element) needs this at 1e-7 once the mesh is refined.
    /// With the error oracle at a relative ε (`bf_relative`), the adaptive cubature of touching
    /// and near pairs runs to `max(link_tol, transfer::LINK_TOL_PER_EPS · ε)`: no finer than the
    /// answer is asked for.
    pub link_tol: f64,
    /// Push each link's variation across its receiver down with the irradiance (`Link::slope`):
    /// a descendant gathers a coarse link's transfer at its own centroid, not the receiver's
    /// average. Without it an element inherits the average of every coarse link above it, its
    /// row of form factors no longer sums to its own (it exceeds 1 near corners), and as its
    /// radiosity follows that row, the solve creates light. Off in `splash2` (SPLASH-2 pushes
    /// constants).
    pub push_slopes: bool,
    /// With `push_slopes`: a partially visible link's slope reads V at the receiver's child
    /// points (`solver::hierarchical::oracle::kernel_slope`), where the link's penumbra can
    /// make the receiver's answer wrong (ρ F B 2 min(V, 1 − V) above `cause_tail` · ε), instead
    /// of the unoccluded kernel's slope times the link's average V. A penumbra across a leaf at
    /// the area floor is then a ramp, not a step between two flat leaves. On in the ladder's
    /// presets, off in the teaching presets and `splash2`.
    pub vis_slopes: bool,
    /// Row check (`solver::hierarchical::refine`): no point receives more than all of its
    /// hemisphere, so a leaf whose row of F·V over its own and inherited links (with their
    /// slopes, as push-pull hands them down) exceeds 1 holds a coarse link's average where its
    /// own share is smaller; as its radiosity follows that row, the solve creates light. Where
    /// that excess adds more than `row_tol` times the scene's mean reflected radiosity to a
    /// leaf's answer, the largest links of its ancestors are pushed down a level at each
    /// refinement. 0: off (`lecture`, the lecture's Refine alone; `splash2`, SPLASH-2's
    /// criterion); off too in a solve with cluster links. Smaller values push more links down for
    /// little more balance (docs/solver.md, "The row check").
    pub row_tol: f64,
    /// Closed rows (`solver::hierarchical::closure`): on the leaves of the patches that front
    /// faces enclose (no hemisphere ray leaves the scene or meets a back face), gather through
    /// the symmetric scaling of the leaves' operator whose rows sum to exactly 1, as a point's
    /// form factors do in an enclosure. The white furnace then comes out exact under every
    /// oracle (without it, refined by the BF or Feps oracle, B is off by the rows' error, ρ/(1 −
    /// ρ) times it), and an enclosed leaf's row neither loses nor creates light. Off in
    /// clustered solves and with `gauss_seidel`.
    pub close_rows: bool,
    /// The error oracle's tail share (`solver::hierarchical::oracle`): of a receiver whose
    /// answer is wrong, the links with the largest variation are split until the others add up
    /// to at most this fraction of ε. Larger: fewer links per threshold, a higher error at a
    /// given ε; [`DEFAULT_CAUSE_TAIL`] in every preset. In (0, 1].
    pub cause_tail: f64,
    /// How the error oracle counts the links a wrong receiver leaves unsplit against
    /// `cause_tail` · ε ([`ErrorTail`]; `Linear` in every preset).
    pub error_tail: ErrorTail,
    /// Clustering above the input patches (`Auto` in every preset).
    pub cluster: Clustering,
    /// Seed of the visibility jitter.
    pub seed: u64,
}

impl HierarchicalParams {
    /// Fast enough to drag sliders: coarse floor, few rays. [`Self::quality`] with the BF oracle
    /// and a looser threshold and tolerance.
    #[must_use]
    pub const fn interactive() -> Self {
        HierarchicalParams {
            oracle: Oracle::Bf,
            feps: 0.05,
            bf_eps: 2e-3,
            rays: 4,
            max_depth: 12,
            // Room for the BF oracle to finish a closed box: it refines for the light that flows,
            // and a refinement the budget stops half-way, before the first gather, leaves leaves
            // whose rows of F·V exceed 1 before the row check can act. The built-in scenes and
            // figures stay far below it.
            max_links: 2_000_000,
            // The energy balance's residual is the last gather's change: 3e-4 keeps it under 1e-3.
            tolerance: 3e-4,
            max_iterations: 100,
            max_rounds: 16,
            link_tol: 1e-3,
            row_tol: 0.05,
            vis_slopes: false,
            ..Self::quality()
        }
    }

    /// The error oracle's settings: each element's answer allowed to vary by 10 % of the scene's
    /// mean reflected radiosity across it, slopes pushed down (`push_slopes`). The ladder's
    /// steps (`spec::Preset`) start from these and set the threshold and the area floor; their
    /// measured error and time: README, "Presets". The other presets start from these too.
    #[must_use]
    pub const fn quality() -> Self {
        HierarchicalParams {
            oracle: Oracle::Error,
            feps: 0.02,
            aeps: AreaEps::Relative(1e-4),
            bf_eps: 0.1,
            bf_relative: true,
            rays: 16,
            max_depth: 14,
            max_links: 4_000_000,
            tolerance: 1e-4,
            max_iterations: 200,
            max_rounds: 24,
            round_iterations: 3,
            settle: 0.02,
            gauss_seidel: false,
            split_fallback: false,
            zero_confirm: 4,
            partial_bf_factor: 0.25,
            conservative: true,
            five_times: false,
            link_tol: 1e-4,
            push_slopes: true,
            vis_slopes: true,
            row_tol: 0.05,
            close_rows: true,
            cause_tail: DEFAULT_CAUSE_TAIL,
            error_tail: ErrorTail::Linear,
            cluster: Clustering::Auto,
            seed: 0,
        }
    }

    /// The lecture's Refine: the form-factor oracle alone, one round.
    #[must_use]
    pub const fn lecture() -> Self {
        HierarchicalParams {
            oracle: Oracle::Feps,
            bf_eps: 0.0,
            rays: 8,
            max_depth: 12,
            max_rounds: 1,
            row_tol: 0.0,
            vis_slopes: false,
            ..Self::quality()
        }
    }

    /// Equivalent of the SPLASH-2 `radiosity` defaults on its room scene: minimum element area
    /// 2000 (scene units), BF epsilon 0.015, energy tolerance 0.005. Partially visible links
    /// refine at BFeps, as in the SPLASH-2 program; zero estimates of links refined at any other
    /// visibility are confirmed with 2 × rays more rays (without, the room comes out dark, its
    /// floor most: `zero_confirm`).
    #[must_use]
    pub const fn splash2() -> Self {
        HierarchicalParams {
            oracle: Oracle::Bf,
            feps: 0.5,
            aeps: AreaEps::Absolute(2000.0),
            bf_eps: 0.015,
            bf_relative: false,
            rays: 4,
            max_depth: 16,
            tolerance: 0.005,
            max_iterations: 100,
            zero_confirm: 2,
            partial_bf_factor: 1.0,
            conservative: false,
            five_times: true,
            link_tol: 0.0,
            push_slopes: false,
            vis_slopes: false,
            row_tol: 0.0,
            settle: 1e-3,
            ..Self::quality()
        }
    }

    /// Look up a preset by name (`interactive`, `quality`, `lecture`, `splash2`).
    #[must_use]
    pub fn preset(name: &str) -> Option<Self> {
        Some(match name {
            "interactive" => Self::interactive(),
            "quality" => Self::quality(),
            "lecture" => Self::lecture(),
            "splash2" => Self::splash2(),
            _ => return None,
        })
    }

    pub const PRESETS: [&'static str; 4] = ["interactive", "quality", "lecture", "splash2"];

    /// Reject absurd values with a message naming the parameter.
    pub fn validate(&self) -> Result<(), String> {
        let pos = |name: &str, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(format!("{name} must be a finite number >= 0 (got {v})"))
            }
        };
        pos("feps", self.feps)?;
        pos("bf-eps", self.bf_eps)?;
        match self.aeps {
            AreaEps::Absolute(a) => pos("aeps", a)?,
            AreaEps::Relative(a) => {
                pos("aeps-rel", a)?;
                if a > 1.0 {
                    return Err(format!("aeps-rel is a fraction of the scene's area, at most 1 (got {a})"));
                }
            }
        }
        if !(self.row_tol.is_finite() && (0.0..1.0).contains(&self.row_tol)) {
            return Err(format!("row-tol must be in [0, 1) (got {})", self.row_tol));
        }
        if !(self.cause_tail > 0.0 && self.cause_tail <= 1.0) {
            return Err(format!("cause-tail must be in (0, 1] (got {})", self.cause_tail));
        }
        if !(self.link_tol.is_finite() && (0.0..1.0).contains(&self.link_tol)) {
            return Err(format!("link_tol must be in [0, 1) (got {})", self.link_tol));
        }
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            return Err(format!("tolerance must be > 0 (got {})", self.tolerance));
        }
        if self.rays == 0 || self.rays > 4096 {
            return Err(format!("rays must be in 1..=4096 (got {})", self.rays));
        }
        if self.zero_confirm > 64 {
            return Err(format!("zero-confirm must be in 0..=64 (got {})", self.zero_confirm));
        }
        if !(self.partial_bf_factor > 0.0 && self.partial_bf_factor <= 1.0) {
            return Err(format!("partial-bf-factor must be in (0, 1] (got {})", self.partial_bf_factor));
        }
        if self.max_depth > 30 {
            return Err(format!("max-depth must be at most 30 (got {})", self.max_depth));
        }
        if self.max_links == 0 {
            return Err("max-links must be at least 1".into());
        }
        if self.max_iterations == 0 {
            return Err("max-iterations must be at least 1".into());
        }
        if self.round_iterations == 0 {
            return Err("round-iterations must be at least 1".into());
        }
        if !(self.settle.is_finite() && (0.0..=1.0).contains(&self.settle)) {
            return Err(format!("settle is a fraction of the links, in 0..=1 (got {})", self.settle));
        }
        Ok(())
    }
}

impl Default for HierarchicalParams {
    fn default() -> Self {
        Self::quality()
    }
}
