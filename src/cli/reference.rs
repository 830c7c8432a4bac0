//! `radlab reference SCENE`: the independent Monte Carlo reference, cached on disk (see
//! [`radlab::eval::reference`]): at adaptive points by default (the pointwise ruler,
//! [`radlab::eval::reference::points`], [`radlab::eval::pointwise`]), or averaged over a uniform reference
//! mesh (`--ruler regions`).

use anyhow::Context;
use radlab::eval::metrics::ErrorReport;
use radlab::eval::pointwise::thousands;
use radlab::eval::reference::{
    Cache, CacheStatus, CachedPoints, Control, Estimate, PointParams, ReferenceParams, reference_mesh,
};
use radlab::geometry::accel::Accel;
use radlab::math::{Rgb, polygon_area};
use radlab::present::image::View;
use radlab::studies::hard_cases;
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
    /// Batches of `--samples` paths per point (points ruler): batch b uses seed `--seed + b` on
    /// batch 1's points, each cached on its own, as `radlab bench` computes them (its batches are
    /// reused). With two or more, the solution is scored against the merge of batches 2 … N,
    /// which are independent of where batch 1 put the points
    /// (`eval::reference::scoring_batches`); the noise falls as 1/√(N − 1).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=256))]
    pub batches: u32,
    /// Largest element side of the reference mesh, in scene units (regions ruler; default: scene
    /// diagonal / 16).
    #[arg(long)]
    pub region_size: Option<f64>,
    /// Seed of the reference's sampling (the solver's visibility seed is --seed).
    #[arg(long, default_value_t = 0)]
    pub ref_seed: u64,
    /// Write the estimates as JSON to this file (`-` for standard output).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Cache folder (default: $RADLAB_CACHE, else .radlab-cache/ in the current directory).
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
    /// Also solve the scene, as `radlab solve` does with the same solver flags (--preset,
    /// --threshold, --mesh, --method, --order, …; below), and print its error against the
    /// reference per patch, for the scene and, with the pointwise ruler, over the penumbra band
    /// ([`radlab::eval::penumbra`]).
    #[arg(long)]
    pub compare: bool,
    /// Pointwise ruler on a single-bounce scene (`builtin:shadow-wide`, `builtin:shadow-narrow`, `builtin:thin-pole`,
    /// [`radlab::geometry::exact`]): score against the closed-form answer at the reference's points (no
    /// noise) instead of their Monte Carlo estimates; the points are still placed by the cached
    /// reference (use a small --samples to place them quickly). With --compare, also prints the
    /// five meshing artifacts of the solution ([`radlab::eval::artifacts`]).
    #[arg(long)]
    pub exact: bool,
    /// How the pointwise ruler reads the --compare solution: `solved` (the default: each
    /// element's own function, its value with its slope or its p = 1 vertex values, what the
    /// viewer draws and the bake writes; `nodal` is the same), `flat` (element averages, slopes
    /// dropped), `gouraud` (vertex averages, interpolated).
    #[arg(long, value_parser = ["solved", "flat", "gouraud", "nodal"])]
    pub reconstruction: Option<String>,
    /// The solver --compare runs: the same flags as `radlab solve`.
    #[command(flatten, next_help_heading = "Solver (with --compare)")]
    pub solver: super::solve::SolverArgs,
    /// Estimate B at the points listed in this JSON file instead of over a mesh: an array of
    /// `{"patch": INDEX, "point": [x, y, z]}` (each point on its patch), `--samples` paths each;
    /// `--json` then writes `{"points": [{"patch", "point", "radiosity", "std_error"}]}`.
    /// Not cached.
    #[arg(long, conflicts_with_all = ["compare", "images", "region_size"])]
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

/// `--point-file`: B at listed points with standard errors (see [`radlab::eval::reference::estimate_points`]).
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
    let params =
        ReferenceParams { samples: args.samples, seed: args.ref_seed, ..ReferenceParams::standard() };
    let accel = Accel::build(scene);
    let t0 = std::time::Instant::now();
    let est = radlab::eval::reference::estimate_points(scene, &accel, &points, &params)?;
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
    super::solve::set_threads(args.solver.threads)?;
    if let Some(file) = &args.point_file {
        let scene = hard_cases::load_scene(&args.scene).with_context(|| format!("loading {}", args.scene))?;
        return run_point_file(&args, &scene, file);
    }
    if args.ruler == "points" {
        return run_points(&args);
    }
    anyhow::ensure!(!args.exact, "--exact needs the points ruler");
    let scene = hard_cases::load_scene(&args.scene).with_context(|| format!("loading {}", args.scene))?;
    let size = args.region_size.unwrap_or(scene.bounds().diagonal() / 16.0);
    let mesh = reference_mesh(&scene, size)?;
    let params =
        ReferenceParams { samples: args.samples, seed: args.ref_seed, ..ReferenceParams::standard() };
    let cache = args.cache_dir.clone().map_or_else(Cache::default_location, Cache::at);
    let accel = Accel::build(&scene);
    let mut log = log_stream(&args);
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
    if args.compare {
        let (sol, _) = solve(&args, &scene, &mut log)?;
        compare(&args, &sol, &scene, &accel, &mesh, &entry.estimates, &mut log)?;
    } else if args.images.is_some() {
        anyhow::bail!("--images needs --compare");
    }
    write_json(&args, &mut log, || {
        serde_json::json!({
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
        })
    })
}

/// Solve the scene as `radlab solve` would with the same solver flags ([`super::solve::solve_spec`]),
/// with the solver's own error estimate (printed beside the measured error); logs the size and
/// time. Returns the solution and, at order 1, each element's vertex coefficients.
fn solve(
    args: &Args,
    scene: &radlab::scene::Scene,
    log: &mut Box<dyn Write>,
) -> anyhow::Result<(radlab::solver::Solution, Option<Vec<Vec<Rgb>>>)> {
    use std::sync::Arc;
    let a = &args.solver;
    let scene = Arc::new(scene.clone());
    let t0 = std::time::Instant::now();
    let accel = Arc::new(Accel::build(&scene));
    let bvh_s = t0.elapsed().as_secs_f64();
    let mut spec = super::solve::solve_spec(a, &scene)?;
    spec.estimate = true;
    // With several thresholds, a walk down them, warm: scored at its last step.
    let (solved, walk) =
        super::solve::solve_with(a, &args.scene, &spec, &scene, &accel, bvh_s, &mut |_, _| {})?;
    for w in &walk {
        let how = if w.warm { "warm" } else { "cold" };
        writeln!(
            log,
            "threshold {} ({how}): {:.3} s, {} leaves, {} links",
            w.threshold, w.solve_s, w.leaves, w.links
        )?;
    }
    let secs = t0.elapsed().as_secs_f64();
    let sol = solved.solution;
    let (order, _) = solved.spec.order();
    writeln!(
        log,
        "\nsolved ({}, {}, order {order}): {} elements, {} links, {secs:.3} s",
        a.preset,
        solved.spec.mesh_name(),
        sol.elements.len(),
        sol.stats.links
    )?;
    if let Some((m, _)) = &solved.remesh {
        writeln!(log, "mesh: {}", m.describe())?;
    }
    if order == 1 {
        let unknowns = sol.stats.extra.as_ref().and_then(|x| x["unknowns"].as_u64()).unwrap_or(0);
        writeln!(log, "order 1, Galerkin: {unknowns} unknowns")?;
    }
    Ok((sol, solved.coefficients))
}

/// `--point-errors`: one CSV row per point (reference, its standard error, the solution there).
fn write_point_errors(
    path: &std::path::Path,
    points: &[radlab::eval::reference::points::RefPoint],
    reference: &[radlab::eval::reference::Estimate],
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

/// Print the error of a solution against the element-average reference per patch and for the scene.
fn compare(
    args: &Args,
    sol: &radlab::solver::Solution,
    scene: &radlab::scene::Scene,
    accel: &Accel,
    mesh: &[radlab::eval::reference::RefElement],
    estimates: &[radlab::eval::reference::Estimate],
    log: &mut Box<dyn Write>,
) -> anyhow::Result<()> {
    let rep = radlab::eval::metrics::compare_resampled(scene, sol, mesh, estimates)?;
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
    regions: &[radlab::eval::reference::RefElement],
    errors: &[f64],
    log: &mut Box<dyn Write>,
) -> anyhow::Result<()> {
    if let Some(prefix) = &args.images {
        let camera = radlab::present::image::Camera::for_scene(scene);
        let (w, h) = (640, 480);
        let sol_path = PathBuf::from(format!("{}_solution.png", prefix.display()));
        let err_path = PathBuf::from(format!("{}_error.png", prefix.display()));
        let view = View { scene, accel, elements: &sol.elements, camera, width: w, height: h };
        view.radiosity_image()
            .write_png(&sol_path)
            .with_context(|| format!("writing {}", sol_path.display()))?;
        radlab::present::image::error_image(scene, accel, regions, errors, &camera, w, h)
            .write_png(&err_path)
            .with_context(|| format!("writing {}", err_path.display()))?;
        writeln!(log, "wrote {} and {}", sol_path.display(), err_path.display())?;
    }
    Ok(())
}

/// `radlab reference` with the pointwise ruler (the default).
fn run_points(args: &Args) -> anyhow::Result<()> {
    let scene = hard_cases::load_scene(&args.scene).with_context(|| format!("loading {}", args.scene))?;
    anyhow::ensure!(args.region_size.is_none(), "--region-size needs --ruler regions");
    let params = PointParams {
        points: args.points,
        paths: ReferenceParams { samples: args.samples, seed: args.ref_seed, ..ReferenceParams::standard() },
        layout_seed: args.ref_seed,
        ..PointParams::standard()
    };
    let cache = args.cache_dir.clone().map_or_else(Cache::default_location, Cache::at);
    let accel = Accel::build(&scene);
    let mut log = log_stream(args);
    writeln!(
        log,
        "pointwise reference for {} ({} patches): at least {} points, {} paths each",
        scene.source,
        scene.patches.len(),
        thousands(params.points as usize),
        params.paths.samples
    )?;
    let (mut entry, file) = cached_points(args, &scene, &accel, &cache, &params, &mut log)?;
    if args.exact {
        let sb = radlab::geometry::exact::SingleBounce::new(&scene).context("--exact")?;
        entry.estimates = entry
            .set
            .points
            .iter()
            .map(|p| Estimate { radiosity: sb.patch_radiosity_at(p.patch, p.position), std_error: Rgb::ZERO })
            .collect();
        writeln!(
            log,
            "--exact: the reference values are the closed-form single-bounce answer at the points"
        )?;
    }
    print_point_quality(&scene, &entry, &mut log)?;
    let points = &entry.set.points;
    let cells = points.iter().zip(&entry.estimates).map(|(p, e)| (p.patch, p.area, e));
    let patches = patch_summaries(&scene, cells, "points", &mut log)?;
    if args.compare {
        compare_points(args, &scene, &accel, &entry, &mut log)?;
    } else if args.images.is_some() {
        anyhow::bail!("--images needs --compare");
    }
    write_json(args, &mut log, || {
        serde_json::json!({
            "scene": scene.source,
            "ruler": "points",
            "cache_file": file.display().to_string(),
            "params": entry.params,
            "patches": patches,
            "points": points.iter().zip(&entry.estimates).map(|(p, e)| serde_json::json!({
                "patch": p.patch, "position": p.position, "area": p.area, "level": p.cell.level,
                "radiosity": e.radiosity, "std_error": e.std_error,
            })).collect::<Vec<_>>(),
        })
    })
}

/// The reference at the points, from the cache (computed and cached when missing or invalid),
/// with `--batches` independent batches merged; and its cache file.
fn cached_points(
    args: &Args,
    scene: &radlab::scene::Scene,
    accel: &Accel,
    cache: &Cache,
    params: &PointParams,
    log: &mut Box<dyn Write>,
) -> anyhow::Result<(CachedPoints, PathBuf)> {
    let (mut entry, status) = cache.get_or_compute_points(scene, accel, params, &Control::default())?;
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
            let seed = args.ref_seed.wrapping_add(u64::from(b));
            let (more, status) =
                cache.get_or_compute_points(scene, accel, &params.batch(seed), &Control::default())?;
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
        let (scoring, n) = radlab::eval::reference::scoring_batches(&batches)
            .context("reference batches of different lengths")?;
        entry.estimates = scoring;
        let which =
            if n == 1 { "batch 2".to_string() } else { format!("batches 2–{} merged", args.batches) };
        writeln!(
            log,
            "scored against {which}: batch 1 placed the points, so its estimates are not independent of them"
        )?;
    } else {
        writeln!(
            log,
            "scored against batch 1, which placed the points: its debiased figures read low near the noise (`--batches 2` or more scores against batches that did not place them)"
        )?;
    }
    Ok((entry, file.clone()))
}

/// The point set's size and refinement, and the reference's own noise and resolution.
fn print_point_quality(
    scene: &radlab::scene::Scene,
    entry: &CachedPoints,
    log: &mut Box<dyn Write>,
) -> anyhow::Result<()> {
    let points = &entry.set.points;
    let regions = entry.set.weights();
    let values: Vec<Rgb> = entry.estimates.iter().map(|e| e.radiosity).collect();
    let quality = radlab::eval::metrics::compare_regions(scene, &regions, &values, &entry.estimates, 0.0)?;
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
    Ok(())
}

/// `--compare`: solve the scene and print its error against the reference at the points, in
/// the penumbra band and per element; the solver's own estimate checked against it; with
/// `--exact` the five artifacts; `--point-errors` and `--images` written.
fn compare_points(
    args: &Args,
    scene: &radlab::scene::Scene,
    accel: &Accel,
    entry: &CachedPoints,
    log: &mut Box<dyn Write>,
) -> anyhow::Result<()> {
    let mut entry = entry.clone();
    let enclosed = entry.drop_enclosed(scene, accel);
    if enclosed > 0 {
        writeln!(
            log,
            "{} points enclosed in solids (every direction from them meets the back of a surface: no light reaches them and no one sees them) are left out of the scores",
            thousands(enclosed)
        )?;
    }
    let entry = &entry;
    let points = &entry.set.points;
    let (sol, coefficients) = solve(args, scene, log)?;
    let band_params = radlab::eval::penumbra::BandParams::standard();
    // The band costs side² rays per point and facing emitter patch: skipped (and said so)
    // above BAND_RAY_BUDGET, as on a furnished room whose lamps are many small polygons.
    let emitters = scene.patches.iter().filter(|p| p.emission.mean() > 0.0).count();
    let band_rays = points.len() as f64 * emitters as f64 * f64::from(band_params.side).powi(2);
    let band = (band_rays <= BAND_RAY_BUDGET)
        .then(|| radlab::eval::penumbra::band(scene, accel, points, &entry.estimates, &band_params));
    let (sol, nodal_coefficients) = reconstruction(args, scene, sol, coefficients, log)?;
    let score = match &nodal_coefficients {
        Some(c) => {
            let r = radlab::eval::reconstruction::Nodal::new(scene, &sol.elements, c.clone())?;
            radlab::eval::pointwise::score_reconstruction_in_band(
                scene,
                &sol,
                &r,
                points,
                &entry.estimates,
                band.as_deref(),
            )?
        }
        None => radlab::eval::pointwise::score_solution_in_band(
            scene,
            &sol,
            points,
            &entry.estimates,
            band.as_deref(),
        )?,
    };
    writeln!(log, "{}:", radlab::eval::pointwise::label(&score.pointwise, points.len()))?;
    print_report(&score.pointwise, true, log)?;
    if let Some(path) = &args.point_errors {
        let values = match &nodal_coefficients {
            Some(c) => radlab::eval::pointwise::evaluate(
                &radlab::eval::reconstruction::Nodal::new(scene, &sol.elements, c.clone())?,
                points,
            ),
            None => radlab::eval::pointwise::evaluate(
                &radlab::eval::pointwise::PiecewiseConstant::new(scene, &sol.elements)?,
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
            print_report(&b.report, false, log)?;
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
    print_report(&score.element_average, false, log)?;
    print_estimate_check(scene, &sol, entry, score.pointwise.scene.l2_debiased, log)?;
    if args.exact {
        print_artifacts(scene, &sol, log)?;
    }
    let cells = entry.set.cell_regions(scene);
    write_images(args, &sol, scene, accel, &cells, &score.pointwise.per_element, log)
}

/// The solution as `--reconstruction` reads it: `nodal` (the default) the solver's own
/// coefficients where it has them, `gouraud` vertex values averaged from the elements, `flat`
/// each element's average alone (its slope dropped). Returns the solution and the nodal
/// coefficients to score, if any.
fn reconstruction(
    args: &Args,
    scene: &radlab::scene::Scene,
    mut sol: radlab::solver::Solution,
    coefficients: Option<Vec<Vec<Rgb>>>,
    log: &mut Box<dyn Write>,
) -> anyhow::Result<(radlab::solver::Solution, Option<Vec<Vec<Rgb>>>)> {
    let kind = match args.reconstruction.as_deref() {
        None | Some("nodal") => "solved",
        Some(k) => k,
    };
    let nodal_coefficients = match (kind, coefficients) {
        ("gouraud", _) => Some(radlab::eval::reconstruction::gouraud(scene, &sol.elements)),
        ("solved", c) => c,
        _ => {
            // Flat: each element's average alone.
            for e in &mut sol.elements {
                e.slope = None;
            }
            None
        }
    };
    writeln!(log, "reconstruction: {kind}")?;
    Ok((sol, nodal_coefficients))
}

/// The solver's own error estimate, where it made one, against the measured pointwise error
/// `measured` (globally and, per element, by rank).
fn print_estimate_check(
    scene: &radlab::scene::Scene,
    sol: &radlab::solver::Solution,
    entry: &CachedPoints,
    measured: f64,
    log: &mut Box<dyn Write>,
) -> anyhow::Result<()> {
    let Some(c) = radlab::eval::pointwise::check_estimate(scene, sol, &entry.set.points, &entry.estimates)?
    else {
        return Ok(());
    };
    writeln!(
        log,
        "the solver's own error estimate (no reference): pointwise rel L2 {:.2} %, measured/estimate {:.2}; per element: Spearman {:.3} against each element's own pointwise error, over the {} elements holding ≥ {} points",
        100.0 * c.global_estimate,
        measured / c.global_estimate,
        c.spearman,
        c.elements,
        radlab::eval::pointwise::ESTIMATE_CHECK_MIN_POINTS
    )?;
    let cluster_links = sol
        .stats
        .extra
        .as_ref()
        .and_then(|x| x.get("cluster_links"))
        .and_then(serde_json::Value::as_u64)
        .unwrap_or(0);
    if cluster_links > 0 {
        writeln!(log, "  (the estimate leaves out the error of the solve's {cluster_links} cluster links)")?;
    }
    Ok(())
}

/// Most rays `reference --compare` spends on the penumbra band (points × emitter patches ×
/// side²): about two minutes on 2 cores; above it the band is skipped and the output says so.
const BAND_RAY_BUDGET: f64 = 2e9;

/// With `--compare METHOD --exact`: the five meshing artifacts ([`radlab::eval::artifacts`]) of the
/// solution against the closed form, one row each.
fn print_artifacts(
    scene: &radlab::scene::Scene,
    sol: &radlab::solver::Solution,
    log: &mut dyn std::io::Write,
) -> anyhow::Result<()> {
    use radlab::eval::artifacts::{ArtifactParams, measure};
    let sb = radlab::geometry::exact::SingleBounce::new(scene).context("--exact")?;
    let exact = |p: usize, x: radlab::math::DVec3| sb.patch_radiosity_at(p, x);
    let r = measure(scene, sol, &exact, &ArtifactParams::standard())?;
    writeln!(log, "against the closed form:")?;
    super::artifacts::print_table(&r, ArtifactParams::standard().side, log)
}

/// `--json -`: the document goes to stdout.
fn json_to_stdout(args: &Args) -> bool {
    args.json.as_deref().is_some_and(|p| p.as_os_str() == "-")
}

/// Where the log goes: stderr when the `--json` document takes stdout, else stdout.
fn log_stream(args: &Args) -> Box<dyn Write> {
    if json_to_stdout(args) { Box::new(std::io::stderr()) } else { Box::new(std::io::stdout()) }
}

/// With `--json PATH`, write the document `doc` makes to PATH, or to stdout for `-`, saying so
/// in `log`; without, nothing.
fn write_json(
    args: &Args,
    log: &mut dyn Write,
    doc: impl FnOnce() -> serde_json::Value,
) -> anyhow::Result<()> {
    let Some(path) = &args.json else { return Ok(()) };
    let text = serde_json::to_string_pretty(&doc())?;
    if json_to_stdout(args) {
        println!("{text}");
    } else {
        std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
        writeln!(log, "wrote {}", path.display())?;
    }
    Ok(())
}
