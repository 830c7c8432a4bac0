//! `radlab view [SCENE] [--screenshot PATH] [--overlay none|quadtree|links|error|critical|artifacts|clusters,…] [--preset NAME]
//! [--bench-frames N] [--figure NAME] [--split N] [--history] [--replay FRAME [--depth-cut D]]
//! [--mesh KIND] [--order 0|1 [--continuous]] [--reconstruction flat|gouraud|nodal]`:
//! the interactive viewer (feature `gui`).
//!
//! Without the feature, or without a display, it fails with one line suggesting `radlab solve`.

use radlab::solver::meshed::{DisplayReconstruction, MeshMethod};
use std::path::PathBuf;

/// An overlay the viewer opens with (the one definition: under `gui` each names the
/// [`radlab::viewer::Display`] setting it turns on, [`Overlay::turn_on`]).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Overlay {
    #[default]
    None,
    Quadtree,
    Links,
    Error,
    /// The critical edges (D0/D1/D2 segments) coloured by kind.
    Critical,
    /// The five meshing artifacts' marked samples (against the closed form or the reference).
    Artifacts,
    /// The cluster tree's bounding boxes (clustered solves: the furnished rooms).
    Clusters,
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene: a .gltf/.glb path or builtin:NAME.
    #[arg(default_value = "builtin:cornell")]
    pub scene: String,
    /// Solve with the preset, write the viewport to this PNG and exit.
    #[arg(long, value_name = "PATH")]
    pub screenshot: Option<PathBuf>,
    /// Overlays to draw at start (with --screenshot or --bench-frames), comma-separated:
    /// e.g. `--overlay quadtree,links`.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "none")]
    pub overlay: Vec<Overlay>,
    /// Solver preset: the ladder draft, interactive, quality, fine, reference (the error oracle
    /// on the contact mesh); bf, lecture, splash2 (on the quadtree). Without it: quality, the
    /// default, shown first at interactive and then refined on warm to quality (with --replay:
    /// quality alone).
    #[arg(long)]
    pub preset: Option<String>,
    /// Benchmark: solve, draw N frames, print the median frame time and exit.
    #[arg(long, value_name = "N")]
    pub bench_frames: Option<usize>,
    /// Benchmark: solve, then set the threshold (ε of the ladder's presets, else BFeps) to each
    /// value in turn as the Solver panel's slider does, print the time from each change to its
    /// picture on screen, and exit.
    #[arg(long, value_name = "EPS,...", value_delimiter = ',', conflicts_with_all = ["bench_frames", "screenshot", "no_solve"])]
    pub bench_thresholds: Vec<f64>,
    /// Once solved, pick the element under this viewport point (fractions, y down: "0.5,0.8")
    /// and show its links.
    #[arg(long, value_name = "X,Y", value_parser = parse_point)]
    pub pick: Option<[f32; 2]>,
    /// --screenshot captures the whole window (panels, inspector, plots), not only the viewport.
    #[arg(long)]
    pub window: bool,
    /// Open the plots panel.
    #[arg(long)]
    pub plots: bool,
    /// Solve as soon as the scene is loaded (the default; kept for scripts that pass it).
    #[arg(long, conflicts_with = "no_solve")]
    pub solve: bool,
    /// Open on the input patches, unsolved (to step Refine / Gather / Push-pull by hand).
    #[arg(long)]
    pub no_solve: bool,
    /// Open a lecture figure (`radlab figures` lists them): its scene, settings, overlays,
    /// camera and caption replace SCENE, --preset and --overlay. Repeat to open several in
    /// turn, each once the solves before it are done, so that each leaves its runs in the
    /// history (`--figure reference-table --figure uniform-coarse --split 3`: the table room's
    /// reference, its quality solve and a coarse uniform mesh side by side).
    #[arg(long, value_name = "NAME")]
    pub figure: Vec<String>,
    /// Open the split view with N panes (2 or 3): the newest solves side by side, one camera,
    /// one exposure (with --figure, e.g. the solves of its threshold sweep).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(2..=3))]
    pub split: Option<u8>,
    /// Open the run history window (every solve: settings, elements, links, time, error).
    #[arg(long)]
    pub history: bool,
    /// Open the refinement replay of the first solve at this frame (0: where it starts, then
    /// one per round; past the last: the result).
    #[arg(long, value_name = "FRAME")]
    pub replay: Option<usize>,
    /// With --replay: draw the quadtrees down to this depth only (0: the input patches).
    #[arg(long, value_name = "D", requires = "replay")]
    pub depth_cut: Option<u8>,
    /// The mesh solved on: the hierarchical quadtree, a uniform mesh, or a discontinuity mesh
    /// (constrained Delaunay or BSP; docs/meshing.md).
    #[arg(long, value_enum, default_value = "quadtree")]
    pub mesh: MeshMethod,
    /// Element order on a uniform or discontinuity mesh: 0 constant, 1 linear / bilinear.
    #[arg(long, default_value_t = 0)]
    pub order: u32,
    /// With --order 1: one value per mesh vertex, shared by the elements around it.
    #[arg(long)]
    pub continuous: bool,
    /// How the solution is drawn: solved (each element's own function: its value with its slope,
    /// or its p = 1 vertex values; what the rulers score), flat (element averages) or gouraud
    /// (vertex averages).
    #[arg(long, value_enum, default_value = "solved")]
    pub reconstruction: DisplayReconstruction,
}

impl Args {
    #[must_use]
    pub fn default_scene() -> Args {
        Args {
            scene: "builtin:cornell".into(),
            screenshot: None,
            overlay: vec![Overlay::None],
            preset: None,
            bench_frames: None,
            bench_thresholds: Vec::new(),
            pick: None,
            window: false,
            plots: false,
            solve: false,
            no_solve: false,
            figure: Vec::new(),
            split: None,
            history: false,
            replay: None,
            depth_cut: None,
            mesh: MeshMethod::Quadtree,
            order: 0,
            continuous: false,
            reconstruction: DisplayReconstruction::Nodal,
        }
    }

    /// The mesh settings the flags ask for (`None`: the quadtree), or why they cannot be used.
    pub fn mesh_params(&self) -> anyhow::Result<Option<radlab::solver::meshed::MeshSolveParams>> {
        use radlab::geometry::basis::Order;
        use radlab::solver::meshed::MeshSolveParams;
        let Some(order) = Order::from_degree(self.order) else {
            anyhow::bail!(
                "--order {}: supported orders are 0 (constant) and 1 (linear / bilinear)",
                self.order
            );
        };
        if self.mesh == MeshMethod::Quadtree {
            if order != Order::Constant || self.continuous {
                anyhow::bail!(
                    "--order 1 and --continuous need --mesh uniform|discontinuity-cdt|discontinuity-bsp (the quadtree's elements are constant)"
                );
            }
            return Ok(None);
        }
        let p = MeshSolveParams { order, continuous: self.continuous, ..MeshSolveParams::new(self.mesh) };
        p.validate().map_err(|e| anyhow::anyhow!("--mesh {}: {e}", self.mesh.name()))?;
        Ok(Some(p))
    }
}

impl Overlay {
    /// Turn this overlay on in `d`.
    #[cfg(feature = "gui")]
    pub fn turn_on(self, d: &mut radlab::viewer::Display) {
        match self {
            Overlay::None => {}
            Overlay::Quadtree => d.quadtree = true,
            Overlay::Links => d.links = true,
            Overlay::Error => d.error = true,
            Overlay::Critical => d.critical = true,
            Overlay::Artifacts => d.artifact = Some(radlab::present::mesh_overlay::Artifact::All),
            Overlay::Clusters => d.clusters = true,
        }
    }
}

fn parse_point(s: &str) -> Result<[f32; 2], String> {
    let (x, y) = s.split_once(',').ok_or("expected X,Y (fractions of the viewport)")?;
    let f = |t: &str| -> Result<f32, String> {
        let v: f32 = t.trim().parse().map_err(|e| format!("{t:?}: {e}"))?;
        if (0.0..=1.0).contains(&v) { Ok(v) } else { Err(format!("{v} is outside 0..1")) }
    };
    Ok([f(x)?, f(y)?])
}

#[cfg(feature = "gui")]
pub fn run(args: Args) -> anyhow::Result<()> {
    use radlab::viewer::ViewerOptions;
    if let Some(name) = &args.preset
        && radlab::solver::spec::Preset::from_name(name).is_none()
    {
        anyhow::bail!("--preset {name:?}: unknown preset (one of {})", radlab::solver::spec::Preset::names());
    }
    if args.bench_frames == Some(0) {
        anyhow::bail!("--bench-frames must be at least 1");
    }
    if let Some(t) = args.bench_thresholds.iter().find(|t| !(t.is_finite() && **t > 0.0)) {
        anyhow::bail!("--bench-thresholds: {t} is not a threshold (each must be finite and above 0)");
    }
    let mut figures =
        args.figure.iter().map(|n| radlab::present::figures::find(n)).collect::<Result<Vec<_>, _>>()?;
    let figure = (!figures.is_empty()).then(|| figures.remove(0));
    let mesh = args.mesh_params()?;
    let mut display = radlab::viewer::Display::default();
    for o in &args.overlay {
        o.turn_on(&mut display);
    }
    radlab::viewer::run(ViewerOptions {
        scene: args.scene,
        preset: args.preset,
        display,
        solve_on_start: args.solve || !args.no_solve,
        screenshot: args.screenshot,
        bench_frames: args.bench_frames,
        bench_thresholds: args.bench_thresholds,
        pick: args.pick,
        screenshot_window: args.window || figure.is_some_and(|f| f.window_shot),
        show_plots: args.plots,
        figure,
        then_figures: figures,
        split: args.split.map(usize::from),
        show_history: args.history,
        replay: args.replay,
        depth_cut: args.depth_cut,
        mesh,
        reconstruction: Some(args.reconstruction),
        ..ViewerOptions::default()
    })?;
    Ok(())
}

#[cfg(not(feature = "gui"))]
pub fn run(args: Args) -> anyhow::Result<()> {
    for name in &args.figure {
        radlab::present::figures::find(name)?;
    }
    args.mesh_params()?;
    anyhow::bail!("this radlab was built without the viewer (feature `gui`); use `radlab solve SCENE`")
}
