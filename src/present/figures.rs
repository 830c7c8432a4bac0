//! The lecture's figures as data: each [`Figure`] is a named preset — scene, solver settings,
//! the steps to run, overlays, camera — with a caption that says what to look at and why (the
//! slide's point, in our words). The viewer's Lecture menu and `radlab view --figure NAME` open
//! them; `radlab figures` lists them and writes one screenshot each.
//!
//! The slides follow the radiosity lecture (CS348b lecture 17, after Hanrahan, Salzman and
//! Aupperle 1991). The meshing slides — irradiance discontinuities, Campbell's BSP mesh,
//! Heckbert's constrained Delaunay mesh, h vs p, meshing options, the five artifacts — solve on
//! a uniform or discontinuity mesh ([`Figure::mesh`], [`crate::solver::meshed`]) and sit in the
//! Lecture menu's [`MESHING`] submenu.
//!
//! ## Uniform meshes
//! The viewer runs the hierarchical solver only. A uniform mesh is that solver with the
//! form-factor oracle at Feps = 0 ([`uniform`]): no pair is ever accurate enough, so every
//! element is split down to the area floor Aeps and every pair of floor-sized elements that see
//! each other gets a link — the classical method's full n × n matrix, on a mesh whose elements
//! all have about the same area (within a factor of four: a quadtree halves sides).

use crate::present::mesh_overlay::Artifact;
use crate::solver::hierarchical::StepKind;
use crate::solver::meshed::{DisplayReconstruction, MeshMethod, MeshSolveParams};
use crate::solver::params::{AreaEps, HierarchicalParams, Oracle};
use serde::Serialize;

/// Overlays drawn over the shaded scene.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Overlays {
    /// Leaf edges coloured by quadtree depth.
    pub quadtree: bool,
    /// Link lines coloured by log F.
    pub links: bool,
    /// Links overlay: only the partially visible links (those crossing a shadow boundary).
    pub partial_links_only: bool,
    /// Per-element error heatmap instead of the radiosity.
    pub error: bool,
    /// Flat shading (each element one colour) instead of Gouraud.
    pub flat: bool,
    /// The critical edges (D0/D1/D2 segments).
    pub critical: bool,
    /// An artifact overlay.
    pub artifact: Option<Artifact>,
}

impl Overlays {
    const NONE: Overlays = Overlays {
        quadtree: false,
        links: false,
        partial_links_only: false,
        error: false,
        flat: false,
        critical: false,
        artifact: None,
    };
}

/// The view, relative to the scene's own camera (the viewer's home view): orbit by `yaw_deg`
/// (positive: the eye moves left around the target) and `pitch_deg` (positive: up), then dolly
/// by `zoom` (< 1 moves closer).
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct CameraPreset {
    pub yaw_deg: f64,
    pub pitch_deg: f64,
    pub zoom: f64,
}

impl CameraPreset {
    /// The scene's own camera.
    pub const HOME: CameraPreset = CameraPreset { yaw_deg: 0.0, pitch_deg: 0.0, zoom: 1.0 };
}

/// One lecture figure.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct Figure {
    /// Short kebab-case name: `radlab view --figure NAME`.
    pub name: &'static str,
    /// The slide's title, as the Lecture menu lists it.
    pub slide: &'static str,
    /// `builtin:NAME`.
    pub scene: &'static str,
    /// The solver preset the settings start from (shown in the viewer's preset box).
    pub preset: &'static str,
    /// What the method is, in a few words (uniform mesh, Feps refinement, BF oracle…).
    pub method: &'static str,
    /// The solver settings (of the hierarchical solver: the quadtree mesh).
    pub params: HierarchicalParams,
    /// The mesh solved on: the quadtree (`params`) or a uniform / discontinuity mesh.
    pub mesh: MeshSolveParams,
    /// How the solution is drawn (unless `overlays.flat`).
    pub reconstruction: DisplayReconstruction,
    /// Steps run after loading: `[Solve]` for a solved figure, `[Refine]` for the first step of
    /// a stepped one, `[]` for the input patches.
    pub steps: &'static [StepKind],
    /// Before the figure's own solve, solve once at each of these BFeps values (the runs show
    /// as points in the plots panel's links-against-elements plot).
    pub sweep_bf_eps: &'static [f64],
    pub overlays: Overlays,
    pub camera: CameraPreset,
    /// Once solved, pick the element under this viewport point (fractions, y down) and show
    /// only its links; the inspector lists them.
    pub pick: Option<[f32; 2]>,
    /// Open the plots panel.
    pub plots: bool,
    /// Open the blocking form-factor matrix window.
    pub matrix: bool,
    /// The screenshot shows the whole window (inspector, plots), not only the viewport.
    pub window_shot: bool,
    /// The Lecture menu's submenu that lists the figure (`None`: the menu itself).
    pub submenu: Option<&'static str>,
    /// Before the figure's own solve, solve on each of these meshes (runs of the history).
    pub mesh_sweep: &'static [MeshSolveParams],
    /// Open the split view: the newest two runs of the scene side by side (the sweep's and the
    /// figure's own).
    pub split: bool,
    /// Two to five sentences: what to look at and why. Its numbers are names in braces
    /// (`{leaves}`, `{error_value}`, [`PLACEHOLDERS`]) that [`Figure::caption_text`] fills from the
    /// state shown, so a caption never quotes a number the screen does not show.
    pub caption: &'static str,
}

impl Figure {
    /// The figure's defaults: the scene solved with a preset, no overlay, the scene's camera.
    const fn base(
        name: &'static str,
        slide: &'static str,
        scene: &'static str,
        preset: &'static str,
        params: HierarchicalParams,
    ) -> Figure {
        Figure {
            name,
            slide,
            scene,
            preset,
            method: "hierarchical",
            params,
            mesh: MeshSolveParams::new(MeshMethod::Quadtree),
            reconstruction: DisplayReconstruction::Gouraud,
            steps: &[StepKind::Solve],
            sweep_bf_eps: &[],
            overlays: Overlays::NONE,
            camera: CameraPreset::HOME,
            pick: None,
            plots: false,
            matrix: false,
            window_shot: false,
            submenu: None,
            mesh_sweep: &[],
            split: false,
            caption: "",
        }
    }

    /// The scene's name without the `builtin:` prefix.
    #[must_use]
    pub fn builtin_name(&self) -> &'static str {
        self.scene.strip_prefix("builtin:").unwrap_or(self.scene)
    }

    /// Whether a step run after the figure's own keeps the state the caption describes: a
    /// stepped figure (one that does not solve) goes on with Refine, Gather, Push-pull and
    /// Iterate, a solved figure with a Solve (the same settings give the same solution);
    /// anything else leaves it.
    #[must_use]
    pub fn follows(&self, kind: StepKind) -> bool {
        let solved = self.steps.contains(&StepKind::Solve) || self.mesh.method != MeshMethod::Quadtree;
        if solved { kind == StepKind::Solve } else { kind != StepKind::Solve }
    }

    /// The caption with "…" for its numbers (the Lecture menu's tooltip: no state yet).
    #[must_use]
    pub fn caption_outline(&self) -> String {
        fill(self.caption, |_| None)
    }

    /// The caption with its numbers filled from `facts` (the state shown); a number not known
    /// yet (a reference still scoring) reads "…".
    #[must_use]
    pub fn caption_text(&self, facts: &CaptionFacts) -> String {
        fill(self.caption, |name| facts.value(name))
    }
}

/// The numbers captions quote, read from the state a figure shows (the viewer fills them in).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CaptionFacts {
    /// Leaves (the elements that carry radiosity) and links of the solution shown (a mesh
    /// solve's links are its form-factor entries); the links whose visibility is partial.
    pub leaves: usize,
    pub links: usize,
    pub links_partial: usize,
    /// Unknowns of the solution: p = 1 continuous, its shared vertices; else its leaves.
    pub unknowns: usize,
    /// Gathers of the state since its last restart, and the last one's residual.
    pub gathers: usize,
    pub residual: Option<f64>,
    /// The state's pointwise relative L2 error against the closed form or the reference, and
    /// over the penumbra band (where the closed form gives the band).
    pub error: Option<f64>,
    pub band_error: Option<f64>,
    /// The run beside it in the split view: its unknowns and errors.
    pub other_unknowns: Option<usize>,
    pub other_error: Option<f64>,
    pub other_band_error: Option<f64>,
    /// The largest leaf's diameter, and the links whose two elements' centres are five
    /// diameters (each's) apart: the five-times rule's disk links.
    pub largest_diameter: Option<f64>,
    pub disk_links: Option<usize>,
    /// The disk and the exact form factor between the scene's first two patches.
    pub ff_disk: Option<f64>,
    pub ff_exact: Option<f64>,
    /// (leaves, links) of each run in the state's plot series (the scene and oracle).
    pub series: Vec<(usize, usize)>,
}

/// The names a caption may quote in braces (see [`CaptionFacts`]).
pub const PLACEHOLDERS: &[&str] = &[
    "leaves",
    "links",
    "links_partial",
    "links_per_leaf",
    "leaves_squared",
    "unknowns",
    "bounces",
    "residual",
    "error_value",
    "band_error",
    "other_unknowns",
    "other_error",
    "other_band_error",
    "largest_diameter",
    "disk_links",
    "ff_disk",
    "ff_exact",
    "series_runs",
    "series_links_per_leaf",
];

/// A relative error as captions, run labels and the status bar write it: "12.34 %".
#[must_use]
pub fn percent(e: f64) -> String {
    format!("{:.2} %", 100.0 * e)
}

impl CaptionFacts {
    /// The text of placeholder `name` (`None`: not known yet, or not a placeholder).
    #[must_use]
    pub fn value(&self, name: &str) -> Option<String> {
        let per_leaf = |links: usize, leaves: usize| format!("{:.1}", links as f64 / leaves.max(1) as f64);
        Some(match name {
            "leaves" => self.leaves.to_string(),
            "links" => self.links.to_string(),
            "links_partial" => self.links_partial.to_string(),
            "links_per_leaf" => per_leaf(self.links, self.leaves),
            "leaves_squared" => (self.leaves as u128 * self.leaves as u128).to_string(),
            "unknowns" => self.unknowns.to_string(),
            "bounces" => match self.gathers {
                1 => "one bounce of light".to_owned(),
                n => format!("{n} bounces of light"),
            },
            "residual" => format!("{:.2e}", self.residual?),
            "error_value" => percent(self.error?),
            "band_error" => percent(self.band_error?),
            "other_unknowns" => self.other_unknowns?.to_string(),
            "other_error" => percent(self.other_error?),
            "other_band_error" => percent(self.other_band_error?),
            "largest_diameter" => format!("{:.3}", self.largest_diameter?),
            "disk_links" => self.disk_links?.to_string(),
            "ff_disk" => format!("{:.3}", self.ff_disk?),
            "ff_exact" => format!("{:.3}", self.ff_exact?),
            "series_runs" => self.series.len().to_string(),
            "series_links_per_leaf" => {
                let per: Vec<f64> = self.series.iter().map(|&(n, l)| l as f64 / n.max(1) as f64).collect();
                let lo = per.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = per.iter().copied().fold(0.0, f64::max);
                if per.is_empty() {
                    return None;
                }
                format!("{lo:.1} to {hi:.1} links per leaf")
            }
            _ => return None,
        })
    }
}

/// `template` with every `{name}` replaced by `value(name)`, "…" where that is `None`.
fn fill(template: &str, value: impl Fn(&str) -> Option<String>) -> String {
    let mut out = String::with_capacity(template.len());
    let mut rest = template;
    while let Some(open) = rest.find('{') {
        out.push_str(&rest[..open]);
        let Some(close) = rest[open..].find('}') else { break };
        let name = &rest[open + 1..open + close];
        out.push_str(&value(name).unwrap_or_else(|| "…".to_owned()));
        rest = &rest[open + close + 1..];
    }
    out.push_str(rest);
    out
}

/// The names quoted in a caption, in order.
#[must_use]
pub fn placeholders(template: &str) -> Vec<&str> {
    template.split('{').skip(1).filter_map(|t| t.split_once('}').map(|(name, _)| name)).collect()
}

/// The Lecture menu's submenu of the meshing slides.
pub const MESHING: &str = "Meshing given shadows";

/// A meshing figure's defaults: `scene` solved on `mesh`, listed in the [`MESHING`] submenu.
const fn meshing(
    name: &'static str,
    slide: &'static str,
    scene: &'static str,
    mesh: MeshSolveParams,
) -> Figure {
    Figure {
        method: mesh.method.name(),
        mesh,
        submenu: Some(MESHING),
        ..Figure::base(name, slide, scene, "bf", HierarchicalParams::interactive())
    }
}

/// Heckbert's constrained Delaunay mesh refined to 20°.
const CDT: MeshSolveParams = MeshSolveParams::new(MeshMethod::DiscontinuityCdt);
/// The narrow penumbra seen from above, close.
const NARROW_CLOSE: CameraPreset = CameraPreset { yaw_deg: 20.0, pitch_deg: 10.0, zoom: 0.55 };

/// A uniform mesh with the hierarchical solver (see the module docs): the form-factor oracle at
/// Feps = 0 refines every pair down to elements of at most `aeps_rel` of the scene's area, and
/// links every pair of those.
#[must_use]
pub const fn uniform(aeps_rel: f64) -> HierarchicalParams {
    HierarchicalParams {
        oracle: Oracle::Feps,
        feps: 0.0,
        aeps: AreaEps::Relative(aeps_rel),
        // At the floor, split the other element of the pair, so every link joins two
        // floor-sized elements (no link between a floor element and a whole patch).
        split_fallback: true,
        rays: 4,
        max_depth: 16,
        max_rounds: 1,
        ..HierarchicalParams::lecture()
    }
}

/// Area floor of the coarse uniform mesh: about 300 elements on table-room.
const UNIFORM_COARSE: f64 = 1.0 / 256.0;
/// Area floor of the fine uniform mesh: four times as many elements as the coarse one.
const UNIFORM_FINE: f64 = 1.0 / 1024.0;

/// The table room seen a little from above, so the floor under the table shows.
const TABLE_FROM_ABOVE: CameraPreset = CameraPreset { yaw_deg: 0.0, pitch_deg: 12.0, zoom: 1.0 };

/// Every figure, in the lecture's order.
pub const FIGURES: &[Figure] = &[
    Figure {
        method: "hierarchical, form-factor oracle (Feps), one step",
        params: HierarchicalParams { feps: 0.05, ..HierarchicalParams::lecture() },
        steps: &[StepKind::Refine],
        camera: CameraPreset { yaw_deg: 35.0, pitch_deg: 20.0, zoom: 1.0 },
        overlays: Overlays { quadtree: true, links: true, ..Overlays::NONE },
        caption: "Two squares meet at a right angle; the vertical one emits. A Refine step \
                  splits, in each pair whose form-factor estimates are not both below Feps, the \
                  element that looks larger from the other (F_pq > F_qp: split q): {leaves} \
                  leaves and {links} links so far. The mesh is finest along the shared edge, where \
                  the elements are closest and F varies fastest. Press G to gather, P to \
                  push-pull, Space to refine again.",
        ..Figure::base(
            "perpendicular-refine",
            "Basic refinement: two perpendicular polygons",
            "builtin:perpendicular",
            "lecture",
            HierarchicalParams::lecture(),
        )
    },
    Figure {
        method: "hierarchical, form-factor oracle (Feps)",
        overlays: Overlays { quadtree: true, ..Overlays::NONE },
        caption: "Refine with the form-factor oracle alone: a pair is linked once both of its \
                  form-factor estimates are below Feps. The mesh follows the geometry, not the \
                  light: it is finest in the corners and where the blocks stand on the floor, where \
                  elements are close to each other, and a shadow edge is not refined for being one.",
        ..Figure::base(
            "feps-refinement",
            "Refine: the form-factor oracle",
            "builtin:cornell",
            "lecture",
            HierarchicalParams::lecture(),
        )
    },
    Figure {
        method: "hierarchical, BF oracle",
        overlays: Overlays { quadtree: true, ..Overlays::NONE },
        caption: "The same room refined by B·F: a link is split when the light it carries, the \
                  source's radiosity times the form factor, is above BFeps. Fine elements go where \
                  much light arrives and changes: the floor around the blocks' shadows, the back \
                  wall under the light. The ceiling, which the light does not reach directly, \
                  stays coarse.",
        ..Figure::base(
            "bf-refinement",
            "Refining by B·F instead of F",
            "builtin:cornell",
            "bf",
            HierarchicalParams::interactive(),
        )
    },
    Figure {
        method: "hierarchical on the contact mesh, error oracle (quality preset)",
        camera: TABLE_FROM_ABOVE,
        caption: "A converged, finely refined solution of the table room: the reference the \
                  uniform meshes of the next figures are measured against. The shadow under the \
                  table has a sharp umbra and soft penumbrae from the small ceiling light. The \
                  Reference panel's Compute reference gives an independent Monte Carlo answer, \
                  and the error heatmap then shows |B − B_ref|.",
        ..Figure::base(
            "reference-table",
            "Reference solution vs. a uniform mesh",
            "builtin:table-room",
            "quality",
            crate::solver::spec::Preset::Quality.hierarchical(),
        )
    },
    Figure {
        method: "uniform mesh (Feps = 0, coarse area floor)",
        overlays: Overlays { quadtree: true, flat: true, ..Overlays::NONE },
        camera: TABLE_FROM_ABOVE,
        caption: "A uniform mesh of {leaves} elements, flat shaded: every element is one \
                  colour. The shadow under the table comes out as a few blocky elements and \
                  the legs' shadows are missing, because no element boundary follows them. \
                  Every pair of elements that see each other is linked: {links} links, of the \
                  n² = {leaves_squared} pairs.",
        ..Figure::base(
            "uniform-coarse",
            "Increasing resolution: a coarse uniform mesh",
            "builtin:table-room",
            "lecture",
            uniform(UNIFORM_COARSE),
        )
    },
    Figure {
        method: "uniform mesh (Feps = 0, fine area floor)",
        overlays: Overlays { quadtree: true, flat: true, ..Overlays::NONE },
        camera: TABLE_FROM_ABOVE,
        caption: "A quarter of the area floor: {leaves} elements and {links} links, \
                  {links_per_leaf} per element. The shadow's outline is sharper, but the error \
                  falls only about in proportion to the element size, while the links grow as n²: \
                  four times the elements, sixteen times the links. Most of the new elements sit \
                  on walls where the light was already smooth.",
        ..Figure::base(
            "uniform-fine",
            "Increasing resolution: a finer uniform mesh",
            "builtin:table-room",
            "lecture",
            uniform(UNIFORM_FINE),
        )
    },
    Figure {
        method: "uniform mesh (Feps = 0, coarse area floor)",
        overlays: Overlays { error: true, ..Overlays::NONE },
        camera: TABLE_FROM_ABOVE,
        caption: "The coarse uniform mesh coloured by its error on a log scale. The error \
                  gathers where the light changes within an element — the shadow edges under \
                  the table and the floor near the legs — and those are the blocky \
                  shadows and missing features of the shaded image. Without a reference this is \
                  the solver's own estimate; Compute reference turns it into the true error.",
        ..Figure::base(
            "error-image",
            "The error image: blocky shadows, missing features",
            "builtin:table-room",
            "lecture",
            uniform(UNIFORM_COARSE),
        )
    },
    Figure {
        method: "hierarchical, BF oracle",
        overlays: Overlays { quadtree: true, ..Overlays::NONE },
        camera: TABLE_FROM_ABOVE,
        caption: "Adaptive meshing puts the elements where the light changes: the quadtree is \
                  deep along the table's shadow and under the light, and coarse on the walls. \
                  The status bar says {leaves} leaves and {links} links, {links_per_leaf} per \
                  leaf: a uniform mesh of as many leaves links every pair that see each other, up \
                  to {leaves_squared}, and spends its leaves where the light is smooth too.",
        ..Figure::base(
            "adaptive-meshing",
            "Adaptive meshing",
            "builtin:table-room",
            "bf",
            HierarchicalParams::interactive(),
        )
    },
    Figure {
        method: "hierarchical, BF oracle",
        overlays: Overlays { links: true, partial_links_only: true, ..Overlays::NONE },
        camera: TABLE_FROM_ABOVE,
        caption: "Only the partially visible links are drawn: those whose shadow rays were \
                  partly blocked. Their receivers straddle a shadow boundary, in the penumbra, \
                  where part of the light is seen; in the umbra and in full light every ray \
                  agrees: here {links_partial} of the {links} links. Refinement splits these links \
                  first, which is why the mesh follows the shadow.",
        ..Figure::base(
            "penumbra-links",
            "Penumbras and umbras",
            "builtin:table-room",
            "bf",
            HierarchicalParams::interactive(),
        )
    },
    Figure {
        method: "hierarchical, BF oracle",
        overlays: Overlays { quadtree: true, ..Overlays::NONE },
        camera: CameraPreset { yaw_deg: 20.0, pitch_deg: -15.0, zoom: 0.5 },
        caption: "A small lamp high above and an occluder just over the floor: the penumbra is \
                  a thin ring around the umbra. The quadtree is deepest exactly there, because only \
                  the links that straddle the ring are partly visible. This scene's answer is known \
                  in closed form: the solution's pointwise error against it is {error_value}, \
                  {band_error} in the penumbra band.",
        ..Figure::base(
            "narrow-penumbra",
            "Penumbras and umbras: a narrow penumbra",
            "builtin:shadow-narrow",
            "bf",
            HierarchicalParams::interactive(),
        )
    },
    Figure {
        overlays: Overlays { critical: true, quadtree: true, ..Overlays::NONE },
        camera: TABLE_FROM_ABOVE,
        method: "hierarchical, BF oracle, critical edges",
        caption: "Where the radiosity is not smooth: D0 (red) where the legs stand on the floor and \
                  the value jumps, D1 (amber) and D2 (cyan) where a shadow's umbra or penumbra \
                  begins, found from the lamp's vertices and edges against the occluders' (EV and \
                  VE events). The quadtree cuts the floor along its own axes and crosses these \
                  lines instead of following them. The legend counts each kind.",
        ..meshing(
            "irradiance-discontinuities",
            "Irradiance discontinuities: D0, D1, D2",
            "builtin:table-room",
            MeshSolveParams::new(MeshMethod::Quadtree),
        )
    },
    Figure {
        overlays: Overlays { quadtree: true, critical: true, flat: true, ..Overlays::NONE },
        camera: TABLE_FROM_ABOVE,
        caption: "Campbell and Fussell split each receiver by the lines of its critical segments, \
                  recursively, into convex pieces: the scene becomes {leaves} pieces whose edges \
                  lie on every shadow boundary, solved with one value a piece (p = 0, drawn \
                  flat). A line runs on past the shadow it bounds, so pieces are long and thin \
                  and the floor is cut where nothing changes.",
        ..meshing(
            "bsp-mesh",
            "Campbell's BSP mesh",
            "builtin:table-room",
            MeshSolveParams::new(MeshMethod::DiscontinuityBsp),
        )
    },
    Figure {
        overlays: Overlays { quadtree: true, critical: true, ..Overlays::NONE },
        camera: TABLE_FROM_ABOVE,
        caption: "Heckbert triangulates each receiver with its critical segments as constraints, \
                  so every shadow boundary (the critical edges, drawn over it) is an edge of the \
                  mesh and between them the triangles are as fat as Delaunay allows. The Mesh menu's CDT \
                  min angle adds points until no angle is smaller (here none: the \
                  constraints' own triangulation). Unlike the BSP mesh it is conforming, so vertex \
                  values can be shared (continuous p = 1).",
        ..meshing(
            "cdt-mesh",
            "Heckbert's constrained Delaunay mesh with its critical edges",
            "builtin:table-room",
            MeshSolveParams { cdt_min_angle_deg: 0.0, ..CDT },
        )
    },
    Figure {
        overlays: Overlays { quadtree: true, flat: true, ..Overlays::NONE },
        camera: NARROW_CLOSE,
        caption: "The narrow penumbra on Heckbert's mesh with constant elements, drawn flat: the \
                  mesh's edges bound each penumbra strip, but one value a triangle cannot follow \
                  the ramp from umbra to light across it: with {unknowns} unknowns the pointwise \
                  error against the closed form is {band_error} in the penumbra band \
                  ({error_value} over the scene). Subdividing (h) helps only once elements are \
                  narrower than the penumbra.",
        ..meshing(
            "h-vs-p-constant",
            "h vs p: constant elements on a discontinuity mesh",
            "builtin:shadow-narrow",
            CDT,
        )
    },
    Figure {
        reconstruction: DisplayReconstruction::Nodal,
        camera: NARROW_CLOSE,
        mesh_sweep: &[CDT],
        split: true,
        caption: "The same mesh solved twice, side by side, each drawn as its elements' own \
                  functions: left constant elements, right linear ones, continuous across edges. \
                  Inside each strip the radiosity is a smooth ramp, which a linear element follows: \
                  against the closed form, the penumbra band's pointwise error is \
                  {other_band_error} with {other_unknowns} constant unknowns and {band_error} with \
                  {unknowns} linear ones. Raising p pays near a shadow once the mesh's edges follow its \
                  discontinuities.",
        ..meshing(
            "h-vs-p-linear",
            "h vs p: constant beside linear elements on the same mesh",
            "builtin:shadow-narrow",
            CDT.linear(true),
        )
    },
    Figure {
        overlays: Overlays { quadtree: true, ..Overlays::NONE },
        reconstruction: DisplayReconstruction::Nodal,
        camera: NARROW_CLOSE,
        caption: "A uniform mesh of quadrilaterals with bilinear, discontinuous elements, each drawn \
                  as its own function: the steps at element edges show where neighbours disagree. \
                  The Mesh menu sets the element type (quads of the quadtree and the uniform mesh, \
                  the Delaunay mesh's triangles, the BSP's convex pieces), their size and their \
                  order (p = 0 or 1, continuous or not). The Display panel's flat, Gouraud and true p = 1 \
                  draw one solution three ways.",
        ..meshing(
            "meshing-options",
            "Meshing options: element type, size, order",
            "builtin:shadow-narrow",
            MeshSolveParams {
                element_size_rel: 0.08,
                ..MeshSolveParams::new(MeshMethod::Uniform).linear(false)
            },
        )
    },
    Figure {
        overlays: Overlays { flat: true, artifact: Some(Artifact::All), ..Overlays::NONE },
        camera: NARROW_CLOSE,
        caption: "A coarse uniform mesh of the narrow shadow against its closed form, each artifact \
                  marked where it lies: A the penumbra band's error, B missing features (blue), C \
                  Mach bands (magenta) and D inappropriate jumps (orange) on element edges where \
                  the exact answer is smooth, E shadow boundaries inside elements (lime). The \
                  legend gives each as a number. On a discontinuity mesh (Mesh menu) E drops to \
                  zero, while D stays until p = 1.",
        ..meshing(
            "five-artifacts",
            "The five artifacts, labelled on the error image",
            "builtin:shadow-narrow",
            MeshSolveParams { element_size_rel: 0.1, ..MeshSolveParams::new(MeshMethod::Uniform) },
        )
    },
    Figure {
        method: "hierarchical, Feps oracle with the five-times rule",
        params: HierarchicalParams { five_times: true, feps: 0.005, ..HierarchicalParams::lecture() },
        overlays: Overlays { quadtree: true, ..Overlays::NONE },
        camera: CameraPreset { yaw_deg: 30.0, pitch_deg: 0.0, zoom: 1.0 },
        caption: "Two opposed squares one unit apart. The disk formula A cos θ cos θ' / (πr² + A) \
                  is good only for elements small against their distance: for the two whole \
                  squares it gives {ff_disk} against the exact {ff_exact} (radlab form-factor \
                  builtin:parallel --from 0 --to 1 --method disk). With the five-times rule on, \
                  a link's form factor is the disk formula only for pairs whose centres are at \
                  least five diameters apart, else the exact kernel: here the largest element's \
                  diameter is {largest_diameter}, and {disk_links} of the {links} links take the \
                  disk. The Lecture menu's five-times explorer shows how the error falls with \
                  distance.",
        ..Figure::base(
            "five-times",
            "The disk form factor and the five-times rule",
            "builtin:parallel",
            "lecture",
            HierarchicalParams::lecture(),
        )
    },
    Figure {
        method: "hierarchical, form-factor oracle (Feps)",
        params: HierarchicalParams { feps: 0.05, ..HierarchicalParams::lecture() },
        matrix: true,
        window_shot: true,
        caption: "The two perpendicular squares refined with Feps, and every link drawn as the \
                  block of the leaf-to-leaf form-factor matrix it stands for (rows receive, columns \
                  send, leaves in quadtree order). Large blocks are far pairs of large elements \
                  linked once; the blocks shrink towards the shared edge, where near elements \
                  must be small. Hover a block to name its link, click it to pick the receiver.",
        ..Figure::base(
            "block-matrix",
            "The blocking form-factor matrix",
            "builtin:perpendicular",
            "lecture",
            HierarchicalParams::lecture(),
        )
    },
    Figure {
        method: "hierarchical, BF oracle, solved at four BFeps",
        sweep_bf_eps: &[0.05, 0.02, 0.01],
        plots: true,
        window_shot: true,
        caption: "The room solved at {series_runs} thresholds, coarse to fine; each solve is a \
                  point in the plots panel's links-against-elements plot (log-log), between the \
                  dashed n and n² guides. The finest has {links} links for {leaves} leaves \
                  ({series_links_per_leaf} across the thresholds), where a uniform mesh of as many \
                  leaves links every pair that see each other, up to {leaves_squared}. \
                  Hierarchical radiosity bounds the links per element as the mesh is refined: O(n) \
                  links, against the uniform mesh's O(n²). Move BFeps to add points.",
        ..Figure::base(
            "linear-links",
            "O(n) interactions",
            "builtin:cornell",
            "bf",
            HierarchicalParams::interactive(),
        )
    },
    Figure {
        method: "hierarchical, BF oracle, Refine then one Gather",
        steps: &[StepKind::Refine, StepKind::Gather],
        caption: "Refine, then Gather: {bounces} so far, residual {residual}. Each Gather moves \
                  the light one bounce further, so after the first every element holds only the \
                  light that reaches it straight from the lamp: the ceiling is dark and the shadows \
                  are black. Press G again to gather the next bounce (the residual is how much it \
                  changed the radiosity), or S to solve to convergence.",
        ..Figure::base(
            "one-gather",
            "Gather: the first bounce",
            "builtin:cornell",
            "bf",
            HierarchicalParams::interactive(),
        )
    },
    Figure {
        method: "hierarchical, BF oracle",
        pick: Some([0.25, 0.93]),
        window_shot: true,
        caption: "One floor element is picked and its links drawn. Gather is recursive: an \
                  element collects light through its own links and through those of every \
                  ancestor in its quadtree (the inspector's rows not marked self), then push-pull \
                  hands the ancestors' irradiance down and area-averages radiosity back up. Click any \
                  element to see its links.",
        ..Figure::base(
            "recursive-gather",
            "Recursive gather and push-pull",
            "builtin:cornell",
            "bf",
            HierarchicalParams::interactive(),
        )
    },
    Figure {
        method: "hierarchical, BF oracle (SPLASH-2 settings)",
        caption: "The test room of Hanrahan, Salzman and Aupperle (the SPLASH-2 radiosity \
                  program's input), solved with that program's settings. Shadows under the \
                  tables and chairs and the light pools under the lamps come from a mesh that is \
                  fine only where they are; press Q for the quadtree.",
        ..Figure::base(
            "hsa91-room",
            "Results: the HSA91 room",
            "builtin:splash_room",
            "splash2",
            HierarchicalParams::splash2(),
        )
    },
];

/// Why a figure name was not found.
#[derive(Debug, thiserror::Error)]
#[error("unknown figure {name:?} (one of {})", names().join(", "))]
pub struct UnknownFigure {
    pub name: String,
}

/// The figures' names, in order.
#[must_use]
pub fn names() -> Vec<&'static str> {
    FIGURES.iter().map(|f| f.name).collect()
}

/// Look a figure up by name.
pub fn find(name: &str) -> Result<&'static Figure, UnknownFigure> {
    FIGURES.iter().find(|f| f.name == name).ok_or_else(|| UnknownFigure { name: name.to_owned() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_figure_loads_and_its_settings_are_valid() {
        for f in FIGURES {
            let scene = crate::scene::builtin::load(f.builtin_name())
                .unwrap_or_else(|e| panic!("{}: {} does not load: {e}", f.name, f.scene));
            assert!(!scene.patches.is_empty(), "{}", f.name);
            assert!(f.scene.starts_with("builtin:"), "{}: figures use built-in scenes", f.name);
            f.params.validate().unwrap_or_else(|e| panic!("{}: {e}", f.name));
            assert!(
                crate::solver::spec::Preset::from_name(f.preset).is_some(),
                "{}: preset {}",
                f.name,
                f.preset
            );
            for &b in f.sweep_bf_eps {
                HierarchicalParams { bf_eps: b, ..f.params }.validate().unwrap();
            }
            if f.mesh.method != MeshMethod::Quadtree {
                f.mesh.validate().unwrap_or_else(|e| panic!("{}: {e}", f.name));
                assert_eq!(f.submenu, Some(MESHING), "{}: a mesh figure is a meshing slide", f.name);
            }
            if f.reconstruction == DisplayReconstruction::Nodal {
                assert_eq!(
                    f.mesh.order,
                    crate::geometry::basis::Order::Linear,
                    "{}: true p = 1 needs p = 1",
                    f.name
                );
            }
        }
        // The meshing slides of the lecture.
        for name in [
            "irradiance-discontinuities",
            "bsp-mesh",
            "cdt-mesh",
            "h-vs-p-constant",
            "h-vs-p-linear",
            "meshing-options",
            "five-artifacts",
        ] {
            assert_eq!(find(name).unwrap().submenu, Some(MESHING), "{name}");
        }
    }

    #[test]
    fn names_are_unique_kebab_case_and_captions_are_two_to_five_sentences() {
        let mut seen = std::collections::HashSet::new();
        for f in FIGURES {
            assert!(seen.insert(f.name), "{} twice", f.name);
            assert!(f.name.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-'));
            let sentences = f.caption.matches(". ").count() + usize::from(f.caption.ends_with('.'));
            assert!((2..=5).contains(&sentences), "{}: {sentences} sentences", f.name);
            assert!(!f.slide.is_empty());
        }
        assert!(FIGURES.len() >= 10);
    }

    #[test]
    fn captions_quote_only_known_numbers_and_fill_them() {
        let facts = CaptionFacts {
            leaves: 812,
            links: 7230,
            links_partial: 310,
            unknowns: 231,
            gathers: 2,
            residual: Some(0.31),
            error: Some(0.0412),
            band_error: Some(0.04),
            other_unknowns: Some(428),
            other_error: Some(0.1),
            other_band_error: Some(0.44),
            largest_diameter: Some(0.177),
            disk_links: Some(512),
            ff_disk: Some(0.24),
            ff_exact: Some(0.2),
            series: vec![(100, 500), (400, 2400)],
        };
        for f in FIGURES {
            for name in placeholders(f.caption) {
                assert!(PLACEHOLDERS.contains(&name), "{}: unknown {{{name}}}", f.name);
                assert!(facts.value(name).is_some(), "{}: {{{name}}} has no value", f.name);
            }
            let text = f.caption_text(&facts);
            assert!(!text.contains('{') && !text.contains('…'), "{}: {text}", f.name);
        }
        let f = find("adaptive-meshing").unwrap();
        let text = f.caption_text(&facts);
        assert!(text.contains("812 leaves and 7230 links, 8.9 per leaf"), "{text}");
        assert!(text.contains("up to 659344"), "{text}");
        let text = find("h-vs-p-linear").unwrap().caption_text(&facts);
        assert!(text.contains("44.00 % with 428 constant unknowns and 4.00 % with 231 linear"), "{text}");
        assert!(
            find("one-gather")
                .unwrap()
                .caption_text(&facts)
                .contains("2 bounces of light so far, residual 3.10e-1")
        );
        // Not known yet: "…", never a stale number.
        let text = find("h-vs-p-constant").unwrap().caption_text(&CaptionFacts::default());
        assert!(text.contains("closed form is … in the penumbra band (… over"), "{text}");
    }

    #[test]
    fn stepped_figures_follow_steps_and_solved_ones_a_solve() {
        let one_gather = find("one-gather").unwrap();
        assert!(one_gather.follows(StepKind::Gather) && one_gather.follows(StepKind::PushPull));
        assert!(!one_gather.follows(StepKind::Solve), "a solve is no longer the first bounces");
        let solved = find("adaptive-meshing").unwrap();
        assert!(solved.follows(StepKind::Solve) && !solved.follows(StepKind::Refine));
        assert!(find("h-vs-p-linear").unwrap().follows(StepKind::Solve));
    }

    #[test]
    fn unknown_names_list_the_valid_ones() {
        let e = find("nope").unwrap_err().to_string();
        assert!(e.contains("\"nope\"") && e.contains("adaptive-meshing") && !e.contains('\n'), "{e}");
        assert_eq!(find("hsa91-room").unwrap().scene, "builtin:splash_room");
    }

    #[test]
    fn a_uniform_mesh_links_every_pair_of_floor_sized_leaves() {
        use crate::solver::hierarchical::HierarchicalSolver;
        let scene = std::sync::Arc::new(crate::scene::builtin::load("parallel").unwrap());
        // A floor of 1/12 (1/24 of the two squares' area): each square splits into 16 of 1/16.
        let mut s = HierarchicalSolver::new(scene, uniform(1.0 / 24.0)).unwrap();
        s.solve(&mut |_, _| {});
        let snap = s.snapshot();
        let leaves: Vec<_> = snap.elements.iter().filter(|e| e.children.is_none()).collect();
        assert_eq!(leaves.len(), 32);
        assert!(leaves.iter().all(|e| (e.area - 1.0 / 16.0).abs() < 1e-12));
        let is_leaf = |id: u32| snap.elements[id as usize].children.is_none();
        assert!(snap.links.iter().all(|l| is_leaf(l.receiver) && is_leaf(l.source)));
        // Every leaf of one square gathers from every leaf of the other: 2 × 16 × 16.
        assert_eq!(snap.links.len(), 2 * 16 * 16);
    }
}
