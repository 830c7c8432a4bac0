//! `radlab reference SCENE`: the independent Monte Carlo reference, cached on disk (see
//! [`radlab::reference`]): at adaptive points by default (the pointwise ruler,
//! [`radlab::reference::points`], [`radlab::pointwise`]), or averaged over a uniform reference
//! mesh (`--ruler regions`).

use anyhow::Context;
use radlab::accel::Accel;
use radlab::hard_cases;
use radlab::math::{Rgb, polygon_area};
use radlab::metrics::ErrorReport;
use radlab::pointwise::thousands;
use radlab::reference::{
    Cache, CacheStatus, Control, Estimate, PointParams, ReferenceParams, reference_mesh,
};
use std::io::Write;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene: `builtin:NAME`, `hard:NAME` (a generated hard case) or a .gltf/.glb path.
    pub scene: String,
    /// `points`: estimates at adaptive points, the pointwise ruler; `regions`: averages over a
    /// uniform reference mesh (the element-average reference).
    #[arg(long, default_value = "points", value_parser = ["points", "regions"])]
    pub ruler: String,
    /// Paths per point (points) or stratified paths per element (regions).
    #[arg(long, default_value_t = PointParams::standard().paths.samples)]
    pub samples: u32,
    /// At least this many points (points ruler).
    #[arg(long, default_value_t = PointParams::standard().points)]
    pub points: u32,
    /// Independent batches of `--samples` paths per point to merge (points ruler): batch b uses
    /// seed `--seed + b` on batch 0's points, each cached on its own, as `radlab bench` computes
    /// them (its batches are reused); the noise falls as 1/√batches.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=256))]
    pub batches: u32,
    /// Largest element side of the reference mesh, in scene units (regions ruler; default: scene
    /// diagonal / 16).
    #[arg(long)]
    pub element_size: Option<f64>,
    /// Seed of the sampling.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Write the estimates as JSON to this file (`-` for standard output).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Cache folder (default: $RADLAB_CACHE, else .radlab-cache/ in the current directory).
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
    /// Also solve the scene with this method (`preset`: as `--preset` solves it, on its own top
    /// level, as `radlab solve` does; `hierarchical`, `uniform`, `progressive`,
    /// `dmesh-cdt` / `dmesh-bsp`: the uniform solver at p = 0 on a discontinuity mesh, one element
    /// per piece, `hierarchical-dmesh-cdt` / `hierarchical-dmesh-bsp`: the discontinuity mesh
    /// as the top level of the hierarchical solver, or `hierarchical-contact`: the contact mesh
    /// as its top level (`radlab solve --mesh contact`); `--preset` and the `--solve-*` flags as
    /// for `hierarchical`) and print its error against the reference per patch, for the scene and,
    /// with the pointwise ruler, over the penumbra band ([`radlab::penumbra`]).
    #[arg(long)]
    pub compare: Option<String>,
    /// Smallest angle of the CDT refinement of --compare dmesh-cdt and hierarchical-dmesh-cdt,
    /// degrees (0: unrefined). Default 20, or 0 when the mesh is graded.
    #[arg(long)]
    pub dmesh_min_angle: Option<f64>,
    /// Grade the discontinuity mesh of --compare dmesh-* / hierarchical-dmesh-* to N patches,
    /// to a budget chosen from the scene (`auto`, the default of hierarchical-dmesh-*) or not at
    /// all (`off`, the default of dmesh-*), as `radlab solve --dmesh-budget`.
    #[arg(long, value_name = "N|auto|off")]
    pub dmesh_budget: Option<super::solve::BudgetArg>,
    /// The graded mesh's smooth gradient (as `radlab solve --dmesh-smooth`).
    #[arg(long)]
    pub dmesh_smooth: Option<f64>,
    /// dmesh-*: re-gather partly shadowed pieces and give every piece a slope after the p = 0
    /// solve (as `radlab solve --dmesh-gather`; default true).
    #[arg(long)]
    pub dmesh_gather: Option<bool>,
    /// The graded mesh's penumbra weight (as `radlab solve --dmesh-penumbra-weight`).
    #[arg(long)]
    pub dmesh_penumbra_weight: Option<f64>,
    /// Largest triangle of --compare dmesh-cdt, as a fraction of its receiver's area.
    #[arg(long, default_value_t = f64::INFINITY)]
    pub dmesh_max_area: f64,
    /// Pointwise ruler on a single-bounce scene (`builtin:shadow-wide`, `builtin:shadow-narrow`, `builtin:thin-pole`,
    /// [`radlab::exact`]): score against the closed-form answer at the reference's points (no
    /// noise) instead of their Monte Carlo estimates; the points are still placed by the cached
    /// reference (use a small --samples to place them quickly). With --compare, also prints the
    /// five meshing artifacts of the solution ([`radlab::artifacts`]).
    #[arg(long)]
    pub exact: bool,
    /// Preset for --compare (the ladder: draft, interactive, quality, fine, reference; on the
    /// quadtree: bf, lecture, splash2; see `radlab solve --preset`). `--compare preset` solves as
    /// the preset does, on its own top level; `--compare hierarchical` on the quadtree.
    #[arg(long, default_value = "interactive")]
    pub preset: String,
    /// Element order of --compare uniform / dmesh-cdt / dmesh-bsp: 0 constant (the classical
    /// solver), 1 linear / bilinear with a Galerkin solve (src/solver/linear.rs).
    #[arg(long, default_value_t = 0)]
    pub order: u32,
    /// With --order 1: vertex values shared by the elements of a patch (continuous basis).
    #[arg(long)]
    pub continuous: bool,
    /// How the pointwise ruler reads the --compare solution: `flat` (element values), `gouraud`
    /// (vertex averages, interpolated), `nodal` (the elements' own p = 1 functions; needs
    /// --order 1). Default: flat at order 0, nodal at order 1.
    #[arg(long, value_parser = ["flat", "gouraud", "nodal"])]
    pub reconstruction: Option<String>,
    /// Element size of --compare uniform/progressive (default: scene diagonal / 16).
    #[arg(long)]
    pub solve_element_size: Option<f64>,
    /// Shadow rays per link of --compare hierarchical (default: the preset's).
    #[arg(long)]
    pub solve_rays: Option<u32>,
    /// Visibility seed of --compare hierarchical (default: the preset's).
    #[arg(long)]
    pub solve_seed: Option<u64>,
    /// Oracle of --compare hierarchical (default: the preset's).
    #[arg(long, value_enum)]
    pub solve_oracle: Option<super::solve::OracleArg>,
    /// BFeps of --compare hierarchical, relative (BF: to the largest emission; error oracle: to
    /// the mean reflected radiosity). Default: the preset's.
    #[arg(long)]
    pub solve_bf_eps_rel: Option<f64>,
    /// Aeps of --compare hierarchical, a fraction of the scene's total area (as `radlab solve
    /// --aeps-rel`). Default: the preset's.
    #[arg(long)]
    pub solve_aeps_rel: Option<f64>,
    /// Link budget of --compare hierarchical (as `radlab solve --max-links`). Default: the preset's.
    #[arg(long)]
    pub solve_max_links: Option<usize>,
    /// Deepest quadtree level of --compare hierarchical (as `radlab solve --max-depth`). Default:
    /// the preset's.
    #[arg(long)]
    pub solve_max_depth: Option<u8>,
    /// Relative tolerance of --compare hierarchical's link coefficients (as `radlab solve
    /// --link-tol`). Default: the preset's.
    #[arg(long)]
    pub solve_link_tol: Option<f64>,
    /// The error oracle's tail share of --compare hierarchical (as `radlab solve
    /// --cause-tail`). Default: the preset's.
    #[arg(long)]
    pub solve_cause_tail: Option<f64>,
    /// Clustering of --compare hierarchical (off, auto, on). Default: the preset's (auto).
    #[arg(long, value_enum)]
    pub solve_cluster: Option<radlab::solver::params::Clustering>,
    /// Estimate B at the points listed in this JSON file instead of over a mesh: an array of
    /// `{"patch": INDEX, "point": [x, y, z]}` (each point on its patch), `--samples` paths each;
    /// `--json` then writes `{"points": [{"patch", "point", "radiosity", "std_error"}]}`.
    /// Not cached.
    #[arg(long, conflicts_with_all = ["compare", "images", "element_size"])]
    pub point_file: Option<PathBuf>,
    /// With --compare and the pointwise ruler: write every point's reference and solution as CSV
    /// (`patch,x,y,z,area,ref_r,ref_g,ref_b,sigma_r,sigma_g,sigma_b,sol_r,sol_g,sol_b`), to see
    /// where the error lies.
    #[arg(long, requires = "compare")]
    pub point_errors: Option<PathBuf>,
    /// With --compare: write PREFIX_solution.png and PREFIX_error.png (per-element relative error,
    /// colour bar) from the scene's default camera.
    #[arg(long)]
    pub images: Option<PathBuf>,
}

/// Per-patch summary printed and written to JSON.
#[derive(serde::Serialize)]
struct PatchSummary<'a> {
    patch: usize,
    name: &'a str,
    elements: usize,
    radiosity: Rgb,
    std_error: Rgb,
}

/// Per-patch area-weighted averages of reference estimates given as (patch, area, estimate)
/// (standard errors combine as √(Σ a² σ²) / Σ a), printed as a table whose count column is
/// headed `unit`.
fn patch_summaries<'a, 'e>(
    scene: &'a radlab::scene::Scene,
    items: impl Iterator<Item = (usize, f64, &'e Estimate)>,
    unit: &str,
    log: &mut impl std::io::Write,
) -> anyhow::Result<Vec<PatchSummary<'a>>> {
    let mut sums = vec![(0usize, 0.0, Rgb::ZERO, Rgb::ZERO); scene.patches.len()];
    for (patch, a, e) in items {
        let s = &mut sums[patch];
        s.0 += 1;
        s.1 += a;
        s.2 += e.radiosity * a;
        s.3 += e.std_error.mul_rgb(e.std_error) * (a * a);
    }
    let patches: Vec<PatchSummary> = sums
        .iter()
        .enumerate()
        .map(|(i, (n, a, b, v))| PatchSummary {
            patch: i,
            name: &scene.patches[i].name,
            elements: *n,
            radiosity: *b / *a,
            std_error: v.map(f64::sqrt) / *a,
        })
        .collect();
    writeln!(
        log,
        "{:>5}  {:<28} {:>6}  {:>30}  {:>10}",
        "patch", "name", unit, "radiosity (r, g, b)", "std err"
    )?;
    for p in &patches {
        let b = p.radiosity.0;
        writeln!(
            log,
            "{:>5}  {:<28} {:>6}  {:>9.4e} {:>9.4e} {:>9.4e}  {:>10.3e}",
            p.patch,
            p.name,
            p.elements,
            b[0],
            b[1],
            b[2],
            p.std_error.max_channel()
        )?;
    }
    Ok(patches)
}

/// One entry of a `--point-file` file.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct PointSpec {
    patch: usize,
    point: [f64; 3],
}

/// Largest distance of a `--point-file` point from its patch's plane, relative to the patch's size.
const POINT_OFF_PLANE_REL: f64 = 1e-6;

/// `--point-file`: B at listed points with standard errors (see [`radlab::reference::estimate_points`]).
fn run_point_file(args: &Args, scene: &radlab::scene::Scene, file: &std::path::Path) -> anyhow::Result<()> {
    let text = std::fs::read_to_string(file).with_context(|| format!("reading {}", file.display()))?;
    let specs: Vec<PointSpec> = serde_json::from_str(&text).with_context(|| {
        format!("{}: expected an array of {{\"patch\": N, \"point\": [x, y, z]}}", file.display())
    })?;
    let mut points = Vec::with_capacity(specs.len());
    for (i, s) in specs.iter().enumerate() {
        let Some(p) = scene.patches.get(s.patch) else {
            anyhow::bail!(
                "{}: point {i}: patch {} does not exist ({} patches)",
                file.display(),
                s.patch,
                scene.patches.len()
            );
        };
        let x = radlab::math::DVec3::from_array(s.point);
        let off = (p.normal.dot(x) - p.plane_d()).abs();
        if !x.is_finite() || off > POINT_OFF_PLANE_REL * p.diameter() {
            anyhow::bail!(
                "{}: point {i} {:?} is not on patch {} ({} off its plane)",
                file.display(),
                s.point,
                s.patch,
                off
            );
        }
        points.push((x, s.patch));
    }
    let params = ReferenceParams { samples: args.samples, seed: args.seed, ..ReferenceParams::standard() };
    let accel = Accel::build(scene);
    let t0 = std::time::Instant::now();
    let est = radlab::reference::estimate_points(scene, &accel, &points, &params)?;
    eprintln!(
        "reference for {}: {} points, {} paths each, {:.2} s",
        scene.source,
        points.len(),
        params.samples,
        t0.elapsed().as_secs_f64()
    );
    let doc = serde_json::json!({
        "scene": scene.source,
        "params": params,
        "points": specs.iter().zip(&est).map(|(s, e)| serde_json::json!({
            "patch": s.patch, "point": s.point, "radiosity": e.radiosity, "std_error": e.std_error,
        })).collect::<Vec<_>>(),
    });
    let text = serde_json::to_string_pretty(&doc)?;
    match args.json.as_deref() {
        Some(p) if p.as_os_str() != "-" => {
            std::fs::write(p, text + "\n").with_context(|| format!("writing {}", p.display()))?;
        }
        _ => println!("{text}"),
    }
    Ok(())
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if let Some(file) = &args.point_file {
        let scene = hard_cases::load_scene(&args.scene).with_context(|| format!("loading {}", args.scene))?;
        return run_point_file(&args, &scene, file);
    }
    if args.ruler == "points" {
        return run_points(&args);
    }
    anyhow::ensure!(!args.exact, "--exact needs the points ruler");
    let scene = hard_cases::load_scene(&args.scene).with_context(|| format!("loading {}", args.scene))?;
    let size = args.element_size.unwrap_or(scene.bounds().diagonal() / 16.0);
    let mesh = reference_mesh(&scene, size)?;
    let params = ReferenceParams { samples: args.samples, seed: args.seed, ..ReferenceParams::standard() };
    let cache = args.cache_dir.clone().map_or_else(Cache::default_location, Cache::at);
    let accel = Accel::build(&scene);
    let to_stdout = args.json.as_deref().is_some_and(|p| p.as_os_str() == "-");
    let mut log: Box<dyn Write> =
        if to_stdout { Box::new(std::io::stderr()) } else { Box::new(std::io::stdout()) };
    writeln!(
        log,
        "reference for {} ({} patches): {} elements of size ≤ {size:.4}, {} paths each",
        scene.source,
        scene.patches.len(),
        mesh.len(),
        params.samples
    )?;
    let (entry, status) = cache.get_or_compute(&scene, &accel, &mesh, &params)?;
    match &status {
        CacheStatus::Hit(f) => writeln!(log, "cache: read {}", f.display())?,
        CacheStatus::Computed(f) => {
            writeln!(log, "cache: computed in {:.2} s, wrote {}", entry.compute_s, f.display())?
        }
        CacheStatus::Recomputed { file, why } => {
            writeln!(log, "cache: entry {} was invalid ({why}); recomputed and rewrote it", file.display())?;
        }
    }
    // Per-patch area-weighted averages; standard errors combine as √(Σ a² σ²)/Σ a.
    let regions = mesh.iter().zip(&entry.estimates).map(|(m, e)| (m.patch, polygon_area(&m.vertices), e));
    let patches = patch_summaries(&scene, regions, "elems", &mut log)?;
    let rel: Vec<f64> = entry
        .estimates
        .iter()
        .filter(|e| e.radiosity.mean() > 0.0)
        .map(|e| e.std_error.mean() / e.radiosity.mean())
        .collect();
    if !rel.is_empty() {
        let mean = rel.iter().sum::<f64>() / rel.len() as f64;
        writeln!(log, "mean relative standard error per element: {:.2} %", 100.0 * mean)?;
    }
    if let Some(method) = &args.compare {
        let (sol, _) = solve(&args, method, &scene, &accel, &mut log)?;
        compare(&args, &sol, &scene, &accel, &mesh, &entry.estimates, &mut log)?;
    } else if args.images.is_some() {
        anyhow::bail!("--images needs --compare METHOD");
    }
    if let Some(path) = &args.json {
        let doc = serde_json::json!({
            "scene": scene.source,
            "element_size": size,
            "cache_file": match &status {
                CacheStatus::Hit(f) | CacheStatus::Computed(f) | CacheStatus::Recomputed { file: f, .. } => f.display().to_string(),
            },
            "params": entry.params,
            "patches": patches,
            "elements": entry.elements.iter().zip(&entry.estimates).map(|(m, e)| serde_json::json!({
                "patch": m.patch, "vertices": m.vertices, "radiosity": e.radiosity, "std_error": e.std_error,
            })).collect::<Vec<_>>(),
        });
        write_doc(&doc, path, to_stdout, &mut log)?;
    }
    Ok(())
}

/// Solve the scene with `--compare METHOD` and its settings; logs the size and time.
fn solve(
    args: &Args,
    method: &str,
    scene: &radlab::scene::Scene,
    accel: &Accel,
    log: &mut Box<dyn Write>,
) -> anyhow::Result<(radlab::solver::Solution, Option<Vec<Vec<Rgb>>>)> {
    use radlab::solver::{hierarchical::HierarchicalSolver, progressive, uniform};
    let h = args.solve_element_size.unwrap_or(scene.bounds().diagonal() / 16.0);
    let t0 = std::time::Instant::now();
    let linear = linear_params(args, method)?;
    let mut coefficients = None;
    let sol = match method {
        "hierarchical" => {
            let p = hierarchical_params(args)?;
            let mut s =
                HierarchicalSolver::new(std::sync::Arc::new(scene.clone()), p).map_err(anyhow::Error::msg)?;
            s.solve(&mut |_, _| {});
            s.solution()
        }
        "preset" => {
            use radlab::solver::spec::{self, Preset, SolveSpec};
            let top = Preset::from_name(&args.preset).map_or(spec::TopLevel::Patches, Preset::top);
            let plan = spec::Plan::Hierarchical { params: hierarchical_params(args)?, top };
            let solve_spec = SolveSpec { plan, estimate: true };
            let scene = std::sync::Arc::new(scene.clone());
            let accel = std::sync::Arc::new(Accel::build(&scene));
            let solved = spec::solve(&scene, &accel, 0.0, &solve_spec, &mut |_, _| {}, None)?;
            if let Some((m, solve_s)) = &solved.remesh {
                writeln!(
                    log,
                    "\n{method} {} ({}): {}, solve {solve_s:.3} s",
                    args.preset,
                    solved.spec.mesh_name(),
                    m.describe()
                )?;
            }
            solved.solution
        }
        "hierarchical-dmesh-cdt" | "hierarchical-dmesh-bsp" | "hierarchical-contact" => {
            let mut p = hierarchical_params(args)?;
            if method == "hierarchical-contact" && args.solve_aeps_rel.is_none() {
                p = radlab::solver::discontinuity::contact_area_floor(p);
            }
            let mesh = remesh_params(args, method)?;
            // With the solver's own estimates, as for --compare hierarchical.
            let mut on_mesh = radlab::solver::discontinuity::HierarchicalOnMesh::new(scene, &mesh, p)?;
            on_mesh.solver.solve(&mut |_, _| {});
            let d = on_mesh.finish(true);
            writeln!(log, "\n{method}: {}, solve {:.3} s", d.mesh.describe(), d.solve_s)?;
            d.solution
        }
        "uniform" if linear.is_some() => {
            let p = radlab::solver::linear::LinearParams { element_size: h, ..linear.unwrap_or_default() };
            let s = radlab::solver::linear::solve(scene, accel, &p, &mut |_, _| {})
                .map_err(anyhow::Error::msg)?;
            coefficients = Some(s.coefficients);
            s.solution
        }
        "uniform" => {
            let p = uniform::UniformParams {
                element_size: h,
                ff_tolerance: uniform::COARSE_FF_TOLERANCE,
                ..uniform::UniformParams::default()
            };
            uniform::solve(scene, accel, &p, &mut |_, _| {}).map_err(anyhow::Error::msg)?
        }
        "progressive" => {
            let p = progressive::ProgressiveParams {
                element_size: h,
                ff_tolerance: uniform::COARSE_FF_TOLERANCE,
                ..progressive::ProgressiveParams::default()
            };
            progressive::solve(scene, accel, &p, &mut |_, _| {}).map_err(anyhow::Error::msg)?
        }
        "dmesh-cdt" | "dmesh-bsp" => {
            use radlab::solver::discontinuity::{self, DiscontinuityParams};
            let mut p = DiscontinuityParams::with_mesh(remesh_params(args, method)?);
            p.gather = args.dmesh_gather.unwrap_or(p.gather);
            p.solve.rays = args.solve_rays.unwrap_or(p.solve.rays);
            p.solve.seed = args.solve_seed.unwrap_or(p.solve.seed);
            let d = match &linear {
                Some(lp) => {
                    let lp = radlab::solver::linear::LinearParams {
                        rays: p.solve.rays,
                        seed: p.solve.seed,
                        ..*lp
                    };
                    let (d, c) = discontinuity::solve_galerkin(scene, &p, &lp, &mut |_, _| {})?;
                    coefficients = Some(c);
                    d
                }
                None => discontinuity::solve(scene, &p, &mut |_, _| {})?,
            };
            writeln!(log, "\n{method}: {}, solve {:.3} s", d.mesh.describe(), d.solve_s)?;
            d.solution
        }
        other => anyhow::bail!(
            "--compare {other}: expected hierarchical, uniform, progressive, dmesh-cdt, dmesh-bsp, hierarchical-dmesh-cdt, hierarchical-dmesh-bsp or hierarchical-contact"
        ),
    };
    let secs = t0.elapsed().as_secs_f64();
    writeln!(log, "\n{method}: {} elements, {} links, {secs:.3} s", sol.elements.len(), sol.stats.links)?;
    if let Some(lp) = linear {
        let unknowns = sol.stats.extra.as_ref().and_then(|x| x["unknowns"].as_u64()).unwrap_or(0);
        writeln!(log, "order 1 ({}), Galerkin: {unknowns} unknowns", lp.label())?;
    }
    Ok((sol, coefficients))
}

/// `--point-errors`: one CSV row per point (reference, its standard error, the solution there).
fn write_point_errors(
    path: &std::path::Path,
    points: &[radlab::reference::points::RefPoint],
    reference: &[radlab::reference::Estimate],
    values: &[radlab::math::Rgb],
) -> anyhow::Result<()> {
    use std::io::Write as _;
    let file = std::fs::File::create(path).with_context(|| format!("{}: cannot create", path.display()))?;
    let mut out = std::io::BufWriter::new(file);
    let write = |out: &mut std::io::BufWriter<std::fs::File>| -> std::io::Result<()> {
        writeln!(out, "patch,x,y,z,area,ref_r,ref_g,ref_b,sigma_r,sigma_g,sigma_b,sol_r,sol_g,sol_b")?;
        for ((p, e), v) in points.iter().zip(reference).zip(values) {
            let (x, r, s) = (p.position, e.radiosity, e.std_error);
            writeln!(
                out,
                "{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                p.patch,
                x.x,
                x.y,
                x.z,
                p.area,
                r.0[0],
                r.0[1],
                r.0[2],
                s.0[0],
                s.0[1],
                s.0[2],
                v.0[0],
                v.0[1],
                v.0[2]
            )?;
        }
        out.flush()
    };
    write(&mut out).with_context(|| format!("{}: cannot write", path.display()))
}

/// The hierarchical solver's settings of --compare hierarchical and hierarchical-dmesh-*:
/// `--preset` modified by the `--solve-*` flags.
fn hierarchical_params(args: &Args) -> anyhow::Result<radlab::solver::params::HierarchicalParams> {
    use radlab::solver::spec::Preset;
    let mut p = Preset::from_name(&args.preset)
        .with_context(|| format!("--preset {}: one of {}", args.preset, Preset::names()))?
        .hierarchical();
    p.rays = args.solve_rays.unwrap_or(p.rays);
    p.seed = args.solve_seed.unwrap_or(p.seed);
    if let Some(o) = args.solve_oracle {
        p.oracle = o.into();
    }
    if let Some(e) = args.solve_bf_eps_rel {
        p.bf_eps = e;
        p.bf_relative = true;
    }
    if let Some(a) = args.solve_aeps_rel {
        p.aeps = radlab::solver::params::AreaEps::Relative(a);
    }
    p.max_links = args.solve_max_links.unwrap_or(p.max_links);
    p.max_depth = args.solve_max_depth.unwrap_or(p.max_depth);
    p.link_tol = args.solve_link_tol.unwrap_or(p.link_tol);
    p.cause_tail = args.solve_cause_tail.unwrap_or(p.cause_tail);
    p.cluster = args.solve_cluster.unwrap_or(p.cluster);
    p.validate().map_err(anyhow::Error::msg).context("invalid --solve-* flag")?;
    Ok(p)
}

/// The discontinuity mesh of --compare dmesh-* / hierarchical-dmesh-*: its kind, the CDT flags,
/// and grading (`--dmesh-budget`; `auto` by default on the hierarchical top level, `off` for the
/// uniform solver).
fn remesh_params(args: &Args, method: &str) -> anyhow::Result<radlab::mesh::remesh::RemeshParams> {
    use super::solve::BudgetArg;
    use radlab::mesh::remesh::RemeshParams;
    let hierarchical = method.starts_with("hierarchical-");
    if method == "hierarchical-contact" {
        anyhow::ensure!(
            args.dmesh_min_angle.is_none() && args.dmesh_budget.is_none(),
            "--compare hierarchical-contact: the contact mesh is an ungraded BSP (drop --dmesh-min-angle / --dmesh-budget)"
        );
        return Ok(RemeshParams::contacts());
    }
    let mut p = if method.ends_with("-cdt") { RemeshParams::cdt() } else { RemeshParams::bsp() };
    if hierarchical {
        p.max_patches = radlab::solver::discontinuity::HIERARCHICAL_MAX_PIECES;
    }
    let default = if hierarchical { BudgetArg::Auto } else { BudgetArg::Off };
    let budget = BudgetArg::grading(args.dmesh_budget, default);
    anyhow::ensure!(
        budget.is_some() || (args.dmesh_smooth.is_none() && args.dmesh_penumbra_weight.is_none()),
        "--dmesh-smooth and --dmesh-penumbra-weight tune a graded mesh (--dmesh-budget N|auto)"
    );
    anyhow::ensure!(
        budget.is_none() || !args.continuous,
        "--dmesh-budget grades the mesh with T-vertices: --continuous needs --dmesh-budget off"
    );
    let grade = budget.map(|b| super::solve::grade_params(b, args.dmesh_smooth, args.dmesh_penumbra_weight));
    RemeshParams::for_solve(p.kind, args.dmesh_min_angle, Some(args.dmesh_max_area), grade, p.max_patches)
        .context("invalid --dmesh-min-angle / --dmesh-max-area / --dmesh-budget / --dmesh-smooth / --dmesh-penumbra-weight")
}

/// The Galerkin settings of `--order 1` (None at order 0), refusing the unsupported combinations.
fn linear_params(args: &Args, method: &str) -> anyhow::Result<Option<radlab::solver::linear::LinearParams>> {
    use radlab::basis::Order;
    match args.order {
        0 => {
            anyhow::ensure!(!args.continuous, "--continuous needs --order 1");
            anyhow::ensure!(
                args.reconstruction.as_deref() != Some("nodal"),
                "--reconstruction nodal needs --order 1 (use flat or gouraud at order 0)"
            );
            Ok(None)
        }
        1 => {
            anyhow::ensure!(
                matches!(method, "uniform" | "dmesh-cdt" | "dmesh-bsp"),
                "--order 1 is implemented for --compare uniform, dmesh-cdt and dmesh-bsp (not {method})"
            );
            let p = radlab::solver::linear::LinearParams {
                order: Order::Linear,
                continuous: args.continuous,
                rays: args.solve_rays.unwrap_or(16),
                seed: args.solve_seed.unwrap_or(0),
                ..radlab::solver::linear::LinearParams::default()
            };
            Ok(Some(p))
        }
        p => anyhow::bail!("--order {p}: supported orders are 0 and 1"),
    }
}

/// Print the error of a solution against the element-average reference per patch and for the scene.
fn compare(
    args: &Args,
    sol: &radlab::solver::Solution,
    scene: &radlab::scene::Scene,
    accel: &Accel,
    mesh: &[radlab::reference::RefElement],
    estimates: &[radlab::reference::Estimate],
    log: &mut Box<dyn Write>,
) -> anyhow::Result<()> {
    let rep = radlab::metrics::compare_resampled(scene, sol, mesh, estimates)?;
    writeln!(log, "element-average error (the solution averaged over {} reference regions):", mesh.len())?;
    print_report(&rep, true, log)?;
    write_images(args, sol, scene, accel, mesh, &rep.per_element, log)
}

/// The per-patch table (when `per_patch`) and the scene line of an error report.
fn print_report(rep: &ErrorReport, per_patch: bool, log: &mut Box<dyn Write>) -> anyhow::Result<()> {
    if per_patch {
        writeln!(
            log,
            "{:>5}  {:<28} {:>9} {:>9} {:>9} {:>9} {:>9}",
            "patch", "name", "rel L1", "rel L2", "L∞ raw", "L∞ deb.", "p99"
        )?;
        for p in &rep.per_patch {
            writeln!(
                log,
                "{:>5}  {:<28} {:>8.2}% {:>8.2}% {:>8.2}% {:>8.2}% {:>8.2}%",
                p.patch,
                p.name,
                100.0 * p.norms.l1,
                100.0 * p.norms.l2_debiased,
                100.0 * p.norms.linf,
                100.0 * p.norms.linf_debiased,
                100.0 * p.norms.p99
            )?;
        }
    }
    let n = &rep.scene;
    writeln!(
        log,
        "scene: rel L1 {:.2} %, rel L2 {:.2} % (debiased; raw {:.2} %, reference noise {:.2} %, resolution {:.2} %), rel L∞ {:.2} % (debiased {:.2} %), p95 {:.2} %, p99 {:.2} %, energy residual {:.2e}",
        100.0 * n.l1,
        100.0 * n.l2_debiased,
        100.0 * n.l2,
        100.0 * n.reference_noise,
        100.0 * n.resolution,
        100.0 * n.linf,
        100.0 * n.linf_debiased,
        100.0 * n.p95,
        100.0 * n.p99,
        rep.energy_residual
    )?;
    Ok(())
}

/// With --images: the solution image and the error image over `regions` (one value each).
fn write_images(
    args: &Args,
    sol: &radlab::solver::Solution,
    scene: &radlab::scene::Scene,
    accel: &Accel,
    regions: &[radlab::reference::RefElement],
    errors: &[f64],
    log: &mut Box<dyn Write>,
) -> anyhow::Result<()> {
    if let Some(prefix) = &args.images {
        let camera = radlab::image::Camera::for_scene(scene);
        let (w, h) = (640, 480);
        let sol_path = PathBuf::from(format!("{}_solution.png", prefix.display()));
        let err_path = PathBuf::from(format!("{}_error.png", prefix.display()));
        radlab::image::radiosity_image(scene, accel, &sol.elements, &camera, w, h)
            .write_png(&sol_path)
            .with_context(|| format!("writing {}", sol_path.display()))?;
        radlab::metrics::error_image(scene, accel, regions, errors, &camera, w, h)
            .write_png(&err_path)
            .with_context(|| format!("writing {}", err_path.display()))?;
        writeln!(log, "wrote {} and {}", sol_path.display(), err_path.display())?;
    }
    Ok(())
}

/// `radlab reference` with the pointwise ruler (the default).
fn run_points(args: &Args) -> anyhow::Result<()> {
    let scene = hard_cases::load_scene(&args.scene).with_context(|| format!("loading {}", args.scene))?;
    anyhow::ensure!(args.element_size.is_none(), "--element-size needs --ruler regions");
    let params = PointParams {
        points: args.points,
        paths: ReferenceParams { samples: args.samples, seed: args.seed, ..ReferenceParams::standard() },
        layout_seed: args.seed,
        ..PointParams::standard()
    };
    let cache = args.cache_dir.clone().map_or_else(Cache::default_location, Cache::at);
    let accel = Accel::build(&scene);
    let to_stdout = args.json.as_deref().is_some_and(|p| p.as_os_str() == "-");
    let mut log: Box<dyn Write> =
        if to_stdout { Box::new(std::io::stderr()) } else { Box::new(std::io::stdout()) };
    writeln!(
        log,
        "pointwise reference for {} ({} patches): at least {} points, {} paths each",
        scene.source,
        scene.patches.len(),
        thousands(params.points as usize),
        params.paths.samples
    )?;
    let (mut entry, status) = cache.get_or_compute_points(&scene, &accel, &params, &Control::default())?;
    let file = match &status {
        CacheStatus::Hit(f) => {
            writeln!(log, "cache: read {}", f.display())?;
            f
        }
        CacheStatus::Computed(f) => {
            writeln!(log, "cache: computed in {:.2} s, wrote {}", entry.compute_s, f.display())?;
            f
        }
        CacheStatus::Recomputed { file, why } => {
            writeln!(log, "cache: entry {} was invalid ({why}); recomputed and rewrote it", file.display())?;
            file
        }
    };
    if args.batches > 1 {
        let mut batches = vec![std::mem::take(&mut entry.estimates)];
        for b in 1..args.batches {
            let seed = args.seed.wrapping_add(u64::from(b));
            let (more, status) =
                cache.get_or_compute_points(&scene, &accel, &params.batch(seed), &Control::default())?;
            let (how, f) = status.describe(more.compute_s);
            writeln!(log, "batch {}/{} (seed {seed}): {how}, {}", b + 1, args.batches, f.display())?;
            anyhow::ensure!(
                more.set.points == entry.set.points,
                "reference batch {} placed other points than batch 1 ({})",
                b + 1,
                f.display()
            );
            batches.push(more.estimates);
        }
        entry.estimates =
            radlab::reference::merge_batches(&batches).context("reference batches of different lengths")?;
    }
    let points = &entry.set.points;
    if args.exact {
        let sb = radlab::exact::SingleBounce::new(&scene).context("--exact")?;
        entry.estimates = points
            .iter()
            .map(|p| Estimate { radiosity: sb.patch_radiosity_at(p.patch, p.position), std_error: Rgb::ZERO })
            .collect();
        writeln!(
            log,
            "--exact: the reference values are the closed-form single-bounce answer at the points"
        )?;
    }
    let regions = entry.set.weights();
    let values: Vec<Rgb> = entry.estimates.iter().map(|e| e.radiosity).collect();
    let quality = radlab::metrics::compare_regions(&scene, &regions, &values, &entry.estimates, 0.0)?;
    let max_level = points.iter().map(|p| p.cell.level).max().unwrap_or(0);
    let refined = points.iter().filter(|p| p.cell.level > 0).count();
    writeln!(
        log,
        "{} points ({} in refined cells, down to level {max_level}); noise {:.2} % of the RMS reflected radiosity (the pointwise rel L2 a perfect solver would read), resolution {:.2} %",
        thousands(points.len()),
        thousands(refined),
        100.0 * quality.scene.reference_noise,
        100.0 * quality.scene.resolution
    )?;
    let cells = points.iter().zip(&entry.estimates).map(|(p, e)| (p.patch, p.area, e));
    let patches = patch_summaries(&scene, cells, "points", &mut log)?;
    if let Some(method) = &args.compare {
        let (sol, coefficients) = solve(args, method, &scene, &accel, &mut log)?;
        let band_params = radlab::penumbra::BandParams::standard();
        // The band costs side² rays per point and facing emitter patch: skipped (and said so)
        // above BAND_RAY_BUDGET, as on a furnished room whose lamps are many small polygons.
        let emitters = scene.patches.iter().filter(|p| p.emission.mean() > 0.0).count();
        let band_rays = points.len() as f64 * emitters as f64 * f64::from(band_params.side).powi(2);
        let band = (band_rays <= BAND_RAY_BUDGET)
            .then(|| radlab::penumbra::band(&scene, &accel, points, &entry.estimates, &band_params));
        let kind =
            args.reconstruction.as_deref().unwrap_or(if coefficients.is_some() { "nodal" } else { "flat" });
        let nodal_coefficients = match (kind, coefficients) {
            ("gouraud", _) => Some(radlab::reconstruction::gouraud(&scene, &sol.elements)),
            ("nodal", c) => c,
            _ => None,
        };
        writeln!(log, "reconstruction: {kind}")?;
        let score = match &nodal_coefficients {
            Some(c) => {
                let r = radlab::reconstruction::Nodal::new(&scene, &sol.elements, c.clone())?;
                radlab::pointwise::score_reconstruction_in_band(
                    &scene,
                    &sol,
                    &r,
                    points,
                    &entry.estimates,
                    band.as_deref(),
                )?
            }
            None => radlab::pointwise::score_solution_in_band(
                &scene,
                &sol,
                points,
                &entry.estimates,
                band.as_deref(),
            )?,
        };
        writeln!(log, "{}:", radlab::pointwise::label(&score.pointwise, points.len()))?;
        print_report(&score.pointwise, true, &mut log)?;
        if let Some(path) = &args.point_errors {
            let values = match &nodal_coefficients {
                Some(c) => radlab::pointwise::evaluate(
                    &radlab::reconstruction::Nodal::new(&scene, &sol.elements, c.clone())?,
                    points,
                ),
                None => radlab::pointwise::evaluate(
                    &radlab::pointwise::PiecewiseConstant::new(&scene, &sol.elements)?,
                    points,
                ),
            };
            write_point_errors(path, points, &entry.estimates, &values)?;
            writeln!(log, "wrote {} ({} points)", path.display(), thousands(points.len()))?;
        }
        match &score.penumbra {
            Some(b) => {
                let total: f64 = points.iter().map(|p| p.area).sum();
                writeln!(
                    log,
                    "penumbra band ({} points, {:.2} % of the area; lit strictly between {} and {} % of the unoccluded direct light):",
                    thousands(b.points),
                    100.0 * b.area / total,
                    100.0 * band_params.lo,
                    100.0 * band_params.hi
                )?;
                print_report(&b.report, false, &mut log)?;
            }
            None if band.is_none() => writeln!(
                log,
                "penumbra band: skipped ({} points × {emitters} emitter patches × {}² rays = {band_rays:.1e} rays, above the budget of {BAND_RAY_BUDGET:.0e})",
                thousands(points.len()),
                band_params.side
            )?,
            None => writeln!(log, "penumbra band: no point of the reference is in a penumbra")?,
        }
        writeln!(
            log,
            "element-average error (element values against the reference averaged over each element's points, {} elements):",
            score.element_average.per_element.len()
        )?;
        print_report(&score.element_average, false, &mut log)?;
        if let Some(c) = radlab::pointwise::check_estimate(&scene, &sol, points, &entry.estimates)? {
            writeln!(
                log,
                "the solver's own error estimate (no reference): pointwise rel L2 {:.2} %, measured/estimate {:.2}; per element: Spearman {:.3} against each element's own pointwise error, over the {} elements holding ≥ {} points",
                100.0 * c.global_estimate,
                score.pointwise.scene.l2_debiased / c.global_estimate,
                c.spearman,
                c.elements,
                radlab::pointwise::ESTIMATE_CHECK_MIN_POINTS
            )?;
            let cluster_links = sol
                .stats
                .extra
                .as_ref()
                .and_then(|x| x.get("cluster_links"))
                .and_then(serde_json::Value::as_u64)
                .unwrap_or(0);
            if cluster_links > 0 {
                writeln!(
                    log,
                    "  (the estimate leaves out the error of the solve's {cluster_links} cluster links)"
                )?;
            }
        }
        if args.exact {
            print_artifacts(&scene, &sol, &mut log)?;
        }
        let cells = entry.set.cell_regions(&scene);
        write_images(args, &sol, &scene, &accel, &cells, &score.pointwise.per_element, &mut log)?;
    } else if args.images.is_some() {
        anyhow::bail!("--images needs --compare METHOD");
    }
    if let Some(path) = &args.json {
        let doc = serde_json::json!({
            "scene": scene.source,
            "ruler": "points",
            "cache_file": file.display().to_string(),
            "params": entry.params,
            "patches": patches,
            "points": points.iter().zip(&entry.estimates).map(|(p, e)| serde_json::json!({
                "patch": p.patch, "position": p.position, "area": p.area, "level": p.cell.level,
                "radiosity": e.radiosity, "std_error": e.std_error,
            })).collect::<Vec<_>>(),
        });
        write_doc(&doc, path, to_stdout, &mut log)?;
    }
    Ok(())
}

/// Most rays `reference --compare` spends on the penumbra band (points × emitter patches ×
/// side²): about two minutes on 2 cores; above it the band is skipped and the output says so.
const BAND_RAY_BUDGET: f64 = 2e9;

/// With `--compare METHOD --exact`: the five meshing artifacts ([`radlab::artifacts`]) of the
/// solution against the closed form, one row each.
fn print_artifacts(
    scene: &radlab::scene::Scene,
    sol: &radlab::solver::Solution,
    log: &mut dyn std::io::Write,
) -> anyhow::Result<()> {
    use radlab::artifacts::{ArtifactParams, measure};
    let sb = radlab::exact::SingleBounce::new(scene).context("--exact")?;
    let exact = |p: usize, x: radlab::math::DVec3| sb.patch_radiosity_at(p, x);
    let r = measure(scene, sol, &exact, &ArtifactParams::standard())?;
    writeln!(log, "against the closed form:")?;
    super::artifacts::print_table(&r, ArtifactParams::standard().side, log)
}

/// Write a `--json` document to `path`, or to stdout when `to_stdout` (`--json -`), saying so in
/// `log`.
fn write_doc(
    doc: &serde_json::Value,
    path: &std::path::Path,
    to_stdout: bool,
    log: &mut dyn std::io::Write,
) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(doc)?;
    if to_stdout {
        println!("{text}");
    } else {
        std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
        writeln!(log, "wrote {}", path.display())?;
    }
    Ok(())
}
