//! `radlab artifacts SCENE [solve flags]`: solve as `radlab solve` would, measure the five
//! meshing artifacts ([`radlab::eval::artifacts`]) against the scene's best ruler, print the table,
//! write one picture per artifact ([`radlab::present::artifact_pictures`]) and optionally JSON.
//!
//! The ruler (the reference B at any point): on a single-bounce scene ([`radlab::geometry::exact`]) the
//! closed form; otherwise the cached path-traced pointwise reference ([`radlab::eval::reference`],
//! `radlab reference SCENE`, computed and cached on first use) read through its piecewise-linear
//! interpolant ([`radlab::eval::pointwise::PointInterpolant`]). With the cached reference the pointwise
//! error at its own points (debiased by its noise) is printed too.

use super::solve::{LazyBar, Solved, SolverArgs, load_scene, set_threads, solve_scene};
use anyhow::Context as _;
use radlab::eval::artifacts::{ArtifactMaps, ArtifactParams, ArtifactReport, Gouraud, measure_views};
use radlab::eval::pointwise::{PiecewiseConstant, PointInterpolant, Reconstruction, thousands};
use radlab::eval::reference::{Cache, CachedPoints, Control, PointParams, ReferenceParams};
use radlab::geometry::accel::Accel;
use radlab::math::{DVec3, Rgb};
use serde_json::json;
use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene: a .gltf/.glb path or builtin:NAME (see `radlab scenes`).
    pub scene: String,
    #[command(flatten)]
    pub solver: SolverArgs,
    /// Folder for the five pictures (A-blocky-shadows.png … E-unresolved-discontinuities.png).
    #[arg(long, default_value = "artifacts")]
    pub out: PathBuf,
    /// Write the table and the settings as JSON to PATH (`-` for stdout).
    #[arg(long)]
    pub json: Option<String>,
    /// Grid points per side of every reflecting patch (A, B; default 64).
    #[arg(long, default_value_t = ArtifactParams::standard().side)]
    pub side: u32,
    /// Reference cache folder (scenes without a closed form; default: $RADLAB_CACHE, else
    /// .radlab-cache/).
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
    /// Paths per reference point, when the reference must be computed or looked up (default:
    /// `radlab reference`'s, 1 024).
    #[arg(long, default_value_t = PointParams::standard().paths.samples)]
    pub samples: u32,
    /// Score against the cached path-traced reference even on a single-bounce scene.
    #[arg(long)]
    pub path_traced: bool,
    /// Read every element as its constant (drop the slopes the hierarchical solver pushes to
    /// its leaves): how much of a quadtree's smaller D is the slopes' (docs/meshing.md).
    #[arg(long)]
    pub drop_slopes: bool,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// The reference of the measurement and how to name it.
enum Ruler {
    Exact(radlab::geometry::exact::SingleBounce),
    Points { interpolant: PointInterpolant, label: String },
}

impl Reconstruction for Ruler {
    fn radiosity_at(&self, patch: usize, x: DVec3) -> Rgb {
        match self {
            Ruler::Exact(sb) => sb.patch_radiosity_at(patch, x),
            Ruler::Points { interpolant, .. } => interpolant.radiosity_at(patch, x),
        }
    }
}

impl Ruler {
    /// How the report names the ruler.
    fn label(&self) -> String {
        match self {
            Ruler::Exact(_) => "the closed form (exact single-bounce scene)".to_string(),
            Ruler::Points { label, .. } => label.clone(),
        }
    }
}

/// The pointwise error of the solution at the cached reference's own points, debiased by its
/// noise: the scene's, its noise, the penumbra band's, and per patch (JSON rows).
struct Pointwise {
    rel_l2: f64,
    noise: f64,
    band: Option<f64>,
    per_patch: Vec<serde_json::Value>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let a = &args.solver;
    set_threads(a.threads)?;
    anyhow::ensure!((4..=1024).contains(&args.side), "--side {}: must be in 4..=1024", args.side);
    super::solve::plan(a)?;
    anyhow::ensure!(!args.drop_slopes || a.order == 0, "--drop-slopes reads p = 0 elements (not --order 1)");
    // The output folder first: a bad --out fails before the reference and the solve.
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("--out {}: cannot create the folder", args.out.display()))?;
    let scene = Arc::new(load_scene(&args.scene, a.max_triangles)?);
    let to_stdout = args.json.as_deref() == Some("-");
    let mut log: Box<dyn Write> =
        if to_stdout { Box::new(std::io::stderr()) } else { Box::new(std::io::stdout()) };
    let t = Instant::now();
    let accel = Arc::new(Accel::build(&scene));
    let bvh_s = t.elapsed().as_secs_f64();

    // The ruler first: a missing cache fails before the solve.
    let exact = if args.path_traced { None } else { radlab::geometry::exact::SingleBounce::new(&scene).ok() };
    let cached = match exact {
        Some(_) => None,
        None => Some(cached_reference(&args, &scene, &accel, &mut log)?),
    };

    let mut bar = LazyBar::new("solve", args.quiet);
    let t = Instant::now();
    let (solved, _) = solve_scene(a, &args.scene, &scene, &accel, bvh_s, &mut |d, n| bar.update(d, n))?;
    bar.finish();
    let solve_s = t.elapsed().as_secs_f64();
    let mut solved = solved;
    if args.drop_slopes {
        solved.solution.elements.iter_mut().for_each(|e| e.slope = None);
    }

    let t = Instant::now();
    let ruler = ruler(&scene, exact, cached.as_ref())?;
    let params = ArtifactParams { side: args.side, ..ArtifactParams::standard() };
    let (report, maps, pointwise) = measure(&scene, &accel, &solved, &ruler, cached.as_ref(), &params)?;
    let measure_s = t.elapsed().as_secs_f64();
    let pictures = radlab::present::artifact_pictures::write_pictures(&scene, &maps, &args.out)
        .with_context(|| format!("writing the pictures into {}", args.out.display()))?;

    let measured = Measured { ruler_label: ruler.label(), report, pointwise, pictures, solve_s, measure_s };
    print_measured(&args, &solved, &measured, &mut log)?;
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&measured_json(&args, &solved, &params, measured))?;
        if to_stdout {
            println!("{text}");
        } else {
            std::fs::write(path, text + "\n").with_context(|| format!("writing {path}"))?;
        }
    }
    Ok(())
}

/// The cached path-traced pointwise reference of the scene, computed and cached first when
/// missing (`radlab reference`'s, at `--samples` paths a point).
fn cached_reference(
    args: &Args,
    scene: &radlab::scene::Scene,
    accel: &Accel,
    log: &mut dyn Write,
) -> anyhow::Result<CachedPoints> {
    let params = PointParams {
        paths: ReferenceParams { samples: args.samples, ..ReferenceParams::standard() },
        ..PointParams::standard()
    };
    let cache = args.cache_dir.clone().map_or_else(Cache::default_location, Cache::at);
    writeln!(log, "reference: looking up (or computing) the pointwise reference of {}", args.scene)?;
    let (entry, status) = cache
        .get_or_compute_points(scene, accel, &params, &Control::default())
        .with_context(|| format!("reference of {}", args.scene))?;
    if let radlab::eval::reference::CacheStatus::Computed(f) = &status {
        writeln!(log, "reference: computed in {:.1} s, cached in {}", entry.compute_s, f.display())?;
    }
    Ok(entry)
}

/// The ruler: the closed form where there is one, else the cached reference's interpolant.
fn ruler(
    scene: &radlab::scene::Scene,
    exact: Option<radlab::geometry::exact::SingleBounce>,
    cached: Option<&CachedPoints>,
) -> anyhow::Result<Ruler> {
    Ok(match (exact, cached) {
        (Some(sb), _) => Ruler::Exact(sb),
        (None, Some(entry)) => {
            let values: Vec<Rgb> = entry.estimates.iter().map(|e| e.radiosity).collect();
            let interpolant = PointInterpolant::new(scene, &entry.set.points, &values)?;
            let label = format!(
                "the cached path-traced reference ({} points, {} paths each), linearly interpolated",
                thousands(entry.set.points.len()),
                thousands(entry.params.paths.samples as usize)
            );
            Ruler::Points { interpolant, label }
        }
        (None, None) => unreachable!("a reference is looked up when there is no closed form"),
    })
}

/// The five artifacts of the solution against `ruler` (values read as the solution's
/// reconstruction; shading as a p = 1 solution's own, else Gouraud over the element averages),
/// and the pointwise error at the cached reference's points when there is one.
fn measure(
    scene: &radlab::scene::Scene,
    accel: &Accel,
    solved: &Solved,
    ruler: &Ruler,
    cached: Option<&CachedPoints>,
    params: &ArtifactParams,
) -> anyhow::Result<(ArtifactReport, ArtifactMaps, Option<Pointwise>)> {
    let sol = &solved.solution;
    let nodal = match &solved.coefficients {
        Some(c) => Some(radlab::eval::reconstruction::Nodal::new(scene, &sol.elements, c.clone())?),
        None => None,
    };
    let flat = PiecewiseConstant::new(scene, &sol.elements)?;
    let gouraud = Gouraud::new(scene, sol)?;
    let (values, shaded): (&dyn Reconstruction, &dyn Reconstruction) = match &nodal {
        Some(n) => (n, n),
        None => (&flat, &gouraud),
    };
    let (report, maps) = measure_views(scene, sol, values, shaded, ruler, params)?;
    let pointwise = match cached {
        Some(entry) => Some(pointwise_at_reference(scene, accel, sol, values, entry)?),
        None => None,
    };
    Ok((report, maps, pointwise))
}

/// The pointwise error where the reference was estimated (debiased by its noise), over the
/// scene, its penumbra band and per patch.
fn pointwise_at_reference(
    scene: &radlab::scene::Scene,
    accel: &Accel,
    sol: &radlab::solver::Solution,
    values: &dyn Reconstruction,
    entry: &CachedPoints,
) -> anyhow::Result<Pointwise> {
    let band = radlab::eval::penumbra::band(
        scene,
        accel,
        &entry.set.points,
        &entry.estimates,
        &radlab::eval::penumbra::BandParams::standard(),
    );
    let s = radlab::eval::pointwise::score_reconstruction_in_band(
        scene,
        sol,
        values,
        &entry.set.points,
        &entry.estimates,
        Some(&band),
    )?;
    let per_patch: Vec<serde_json::Value> = s
        .pointwise
        .per_patch
        .iter()
        .map(|p| {
            json!({"patch": p.patch, "name": p.name, "area": p.norms.area,
                   "rel_l2": p.norms.l2_debiased, "reference_mean": p.reference.mean(),
                   "solution_mean": p.solution.mean()})
        })
        .collect();
    Ok(Pointwise {
        rel_l2: s.pointwise.scene.l2_debiased,
        noise: s.pointwise.scene.reference_noise,
        band: s.penumbra.map(|b| b.report.scene.l2_debiased),
        per_patch,
    })
}

/// What a run measured, for the printed report and the JSON.
struct Measured {
    ruler_label: String,
    report: ArtifactReport,
    pointwise: Option<Pointwise>,
    pictures: Vec<PathBuf>,
    solve_s: f64,
    measure_s: f64,
}

/// The solution's order as the report names it, with its number (0 or 1).
fn basis(solved: &Solved) -> (String, u32) {
    let (order_n, continuous) = solved.spec.order();
    let order = match (order_n, continuous) {
        (0, _) => "p0".to_string(),
        (_, true) => "p1-continuous".to_string(),
        _ => "p1-discontinuous".to_string(),
    };
    (order, order_n)
}

/// The solution's unknowns, where its solver counts them.
fn unknowns(sol: &radlab::solver::Solution) -> Option<u64> {
    sol.stats.extra.as_ref().and_then(|x| x.get("unknowns")).and_then(serde_json::Value::as_u64)
}

/// The report on `log`: what was solved and measured against what, the pointwise error, the
/// table, the times and the pictures written.
fn print_measured(args: &Args, solved: &Solved, m: &Measured, log: &mut dyn Write) -> anyhow::Result<()> {
    let sol = &solved.solution;
    let (order, _) = basis(solved);
    let ruler_label = &m.ruler_label;
    writeln!(
        log,
        "{}: {} on the {} mesh, {order}, {} elements{}; ruler: {ruler_label}",
        args.scene,
        sol.method,
        solved.spec.mesh_name(),
        thousands(sol.elements.len()),
        unknowns(sol).map_or_else(String::new, |u| format!(", {} unknowns", thousands(u as usize)))
    )?;
    if let Some(p) = &m.pointwise {
        writeln!(
            log,
            "pointwise rel L2 at the reference's points {:.2} % (noise {:.2} %), penumbra band {}",
            100.0 * p.rel_l2,
            100.0 * p.noise,
            p.band.map_or_else(|| "none".into(), |b| format!("{:.2} %", 100.0 * b))
        )?;
    }
    print_table(&m.report, args.side, log)?;
    let meshing_s = solved.remesh.as_ref().map(|(r, _)| r.total_s);
    let (solve_s, measure_s) = (m.solve_s, m.measure_s);
    writeln!(
        log,
        "times: {}solve {solve_s:.3} s, artifacts {measure_s:.3} s",
        meshing_s.map_or_else(String::new, |x| format!("meshing {x:.4} s (inside the solve), "))
    )?;
    for p in &m.pictures {
        writeln!(log, "wrote {}", p.display())?;
    }
    Ok(())
}

/// The `--json` document: the table, the settings, the pointwise error, the times and the
/// pictures.
fn measured_json(args: &Args, solved: &Solved, params: &ArtifactParams, m: Measured) -> serde_json::Value {
    let sol = &solved.solution;
    let (order, order_n) = basis(solved);
    let report = &m.report;
    json!({
        "scene": args.scene,
        "method": sol.method,
        "mesh": solved.spec.mesh_name(),
        "order": order_n,
        "basis": order,
        "elements": sol.elements.len(),
        "unknowns": unknowns(sol),
        "ruler": m.ruler_label,
        "params": params,
        "solver_params": solved.spec.params_json(),
        "pointwise": m.pointwise.map(|p| json!({"rel_l2": p.rel_l2, "noise": p.noise, "penumbra_band_rel_l2": p.band, "per_patch": p.per_patch})),
        "artifacts": report,
        "fractions": {
            "A": report.blocky_shadows,
            "B": report.missing_features.fraction(),
            "C": report.mach_bands.fraction(),
            "D": report.shading_jumps.fraction(),
            "E": report.unresolved.fraction(),
        },
        "times_s": {"solve": m.solve_s, "meshing": solved.remesh.as_ref().map(|(r, _)| r.total_s), "artifacts": m.measure_s},
        "pictures": m.pictures,
    })
}

/// The five-artifact table, one row each (shared with `radlab reference --exact --compare`).
pub fn print_table(r: &ArtifactReport, side: u32, log: &mut dyn Write) -> anyhow::Result<()> {
    let pct = |x: f64| format!("{:.1} %", 100.0 * x);
    writeln!(log, "artifacts ({side}² grid points a patch):")?;
    let (b, d, e) = (&r.missing_features, &r.shading_jumps, &r.unresolved);
    let rows = [
        (
            "A blocky shadows",
            r.blocky_shadows.map_or_else(|| "no penumbra".into(), pct),
            format!("rel L2 in the penumbra band, {} points", r.band_points),
        ),
        (
            "B missing features",
            pct(b.fraction()),
            format!("{} of {} features, {} of their area", b.missing, b.features, pct(b.area_fraction)),
        ),
        (
            "C Mach bands",
            pct(r.mach_bands.fraction()),
            format!("of the interior edge length ({:.3})", r.mach_bands.edge_length),
        ),
        (
            "D shading discontinuities",
            pct(d.fraction()),
            format!(
                "of {:.3} interior edge length; mean jump {} of the patch mean",
                d.edge_length,
                pct(d.mean_jump)
            ),
        ),
        (
            "E unresolved",
            pct(e.fraction()),
            format!(
                "of {:.3} critical-segment length in {} segments that bound a shadow, {} others not scored; rel L2 beside them {}",
                e.length,
                e.segments,
                e.dropped,
                e.error_beside.map_or_else(|| "none".into(), pct)
            ),
        ),
    ];
    for (name, value, detail) in rows {
        writeln!(log, "  {name:<25} {value}  ({detail})")?;
    }
    Ok(())
}
