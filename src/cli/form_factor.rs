//! `radlab form-factor`: the form factor between two patches or groups of patches, or from a
//! differential element, by any of the kernels in [`radlab::geometry::form_factor`].
//!
//! A group (`mesh:NAME`) is area-weighted: `F_GH = Σ_{i∈G} A_i Σ_{j∈H} F_ij / Σ_{i∈G} A_i`.
//! With `--visibility`, each pair's F is multiplied by its visible fraction (shadow rays through
//! the scene's BVH, as the solvers do).

use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressStyle};
use radlab::geometry::accel::Accel;
use radlab::geometry::form_factor;
use radlab::geometry::visibility::{point_on_polygon, stratified, visible_fraction};
use radlab::math::{DVec3, Pcg32};
use radlab::scene::Scene;
use rayon::prelude::*;

/// Which kernel computes F.
#[derive(clap::ValueEnum, Copy, Clone, Debug, PartialEq, Eq)]
pub enum Method {
    /// Exact: Lambert's contour integral from a point; between polygons, adaptive quadrature of
    /// that exact kernel to --tolerance (relative).
    Exact,
    /// The disk approximation A cosθ cosθ' / (π r² + A) between centroids.
    Disk,
    /// Fixed --order × --order Gauss–Legendre quadrature of the exact kernel over the receiver
    /// (from a point: the exact kernel).
    Quadrature,
    /// Monte Carlo with --samples samples; prints the standard error.
    MonteCarlo,
}

impl Method {
    fn name(self) -> &'static str {
        match self {
            Method::Exact => "exact",
            Method::Disk => "disk",
            Method::Quadrature => "quadrature",
            Method::MonteCarlo => "monte-carlo",
        }
    }
}

/// Compute the form factor between two patches, two meshes, or from a point.
///
/// SEL is a patch index (as `radlab solve --json` numbers them) or `mesh:NAME` (all patches of
/// that mesh as one area-weighted group). F is printed in both directions. Patches are
/// one-sided (front = right-hand rule), so a pair facing away has F = 0.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene: a .gltf/.glb path or builtin:NAME.
    pub scene: String,
    /// The receiver (the "from" side of F_from→to): patch index or mesh:NAME.
    #[arg(long, required_unless_present = "from_point", conflicts_with = "from_point")]
    pub from: Option<String>,
    /// The source: patch index or mesh:NAME.
    #[arg(long)]
    pub to: String,
    /// A differential receiver at this point instead of --from: x,y,z.
    #[arg(long, value_parser = parse_vec3, requires = "from_normal", allow_hyphen_values = true)]
    pub from_point: Option<DVec3>,
    /// The differential receiver's normal (normalised here): x,y,z.
    #[arg(long, value_parser = parse_vec3, requires = "from_point", allow_hyphen_values = true)]
    pub from_normal: Option<DVec3>,
    /// Kernel: `exact` between two polygons is adaptive quadrature of the exact point kernel.
    #[arg(long, value_enum, default_value_t = Method::Exact)]
    pub method: Method,
    /// Multiply by the visible fraction (shadow rays against the rest of the scene).
    #[arg(long)]
    pub visibility: bool,
    /// Shadow rays per pair with --visibility.
    #[arg(long, default_value_t = 256)]
    pub rays: u32,
    /// Relative tolerance of `exact` between polygons.
    #[arg(long, default_value_t = 1e-9)]
    pub tolerance: f64,
    /// Gauss–Legendre points per direction for `quadrature`.
    #[arg(long, default_value_t = 4)]
    pub order: usize,
    /// Samples per pair for `monte-carlo`.
    #[arg(long, default_value_t = 100_000)]
    pub samples: u32,
    /// Seed of the Monte Carlo samples and the visibility rays.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Print {"from","to","method","F_from_to","F_to_from"} as JSON (F_to_from is null from a
    /// point; monte-carlo adds the standard errors).
    #[arg(long)]
    pub json: bool,
}

fn parse_vec3(s: &str) -> Result<DVec3, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("expected x,y,z (three comma-separated numbers), got {s:?}"));
    }
    let mut out = [0.0; 3];
    for (o, p) in out.iter_mut().zip(&parts) {
        *o = p.parse::<f64>().map_err(|e| format!("{p:?} in {s:?}: {e}"))?;
        if !o.is_finite() {
            return Err(format!("{p:?} in {s:?} is not finite"));
        }
    }
    Ok(DVec3::from_array(out))
}

/// Resolve a selector to patch indices.
fn select(scene: &Scene, sel: &str, flag: &str) -> anyhow::Result<Vec<usize>> {
    if let Some(name) = sel.strip_prefix("mesh:") {
        let idx: Vec<usize> = (0..scene.patches.len()).filter(|&i| scene.patches[i].mesh == name).collect();
        if idx.is_empty() {
            let mut meshes: Vec<&str> = scene.patches.iter().map(|p| p.mesh.as_str()).collect();
            meshes.dedup();
            meshes.sort_unstable();
            meshes.dedup();
            bail!("--{flag} {sel}: no mesh named {name:?} in the scene (meshes: {})", meshes.join(", "));
        }
        return Ok(idx);
    }
    let i: usize =
        sel.parse().map_err(|_| anyhow::anyhow!("--{flag} {sel:?}: expected a patch index or mesh:NAME"))?;
    if i >= scene.patches.len() {
        bail!(
            "--{flag} {i}: no such patch (the scene has {} patches, 0..{})",
            scene.patches.len(),
            scene.patches.len()
        );
    }
    Ok(vec![i])
}

/// A computed form factor with its standard error (Monte Carlo only).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Estimate {
    pub value: f64,
    pub std_error: Option<f64>,
}

/// What `form-factor` prints.
#[derive(Clone, Debug, PartialEq)]
pub struct Output {
    pub from: String,
    pub to: String,
    pub method: Method,
    pub from_to: Estimate,
    pub to_from: Option<Estimate>,
}

/// Settings of one computation (the numeric part of [`Args`]).
#[derive(Copy, Clone, Debug)]
struct Settings {
    method: Method,
    rays: u32,
    tolerance: f64,
    order: usize,
    samples: u32,
    seed: u64,
}

/// F from patch i to patch j (without visibility) and its variance (Monte Carlo).
fn pair(scene: &Scene, i: usize, j: usize, s: &Settings) -> (f64, f64) {
    if i == j {
        return (0.0, 0.0); // a planar patch does not see itself
    }
    let (a, b) = (&scene.patches[i], &scene.patches[j]);
    match s.method {
        Method::Exact => (form_factor::polygon_to_polygon(&a.vertices, &b.vertices, s.tolerance), 0.0),
        Method::Disk => (form_factor::disk(a.centroid, a.normal, b.centroid, b.normal, b.area), 0.0),
        Method::Quadrature => (form_factor::polygon_to_polygon_fixed(&a.vertices, &b.vertices, s.order), 0.0),
        Method::MonteCarlo => {
            let key = ((i as u64) << 32) | j as u64;
            let (f, se) =
                form_factor::polygon_to_polygon_mc(&a.vertices, &b.vertices, s.samples, s.seed ^ key);
            (f, se * se)
        }
    }
}

/// Area-weighted group form factor F_GH with its standard error. Pairs run in parallel and
/// are summed in order, so the result does not depend on the thread count.
fn group(
    scene: &Scene,
    accel: Option<&Accel>,
    from: &[usize],
    to: &[usize],
    s: &Settings,
    bar: &ProgressBar,
) -> Estimate {
    let area: f64 = from.iter().map(|&i| scene.patches[i].area).sum();
    let pairs: Vec<(usize, usize)> = from.iter().flat_map(|&i| to.iter().map(move |&j| (i, j))).collect();
    let terms: Vec<(f64, f64)> = pairs
        .par_iter()
        .map(|&(i, j)| {
            let w = scene.patches[i].area / area;
            let (mut f, mut v) = pair(scene, i, j, s);
            if let Some(accel) = accel
                && f > 0.0
            {
                // V_ij = V_ji: always sampled from the lower index's side, keyed by the pair.
                let (lo, hi) = (i.min(j), i.max(j));
                let vis = visible_fraction(
                    accel,
                    &scene.patches[lo].vertices,
                    lo as u32,
                    &scene.patches[hi].vertices,
                    hi as u32,
                    s.rays,
                    s.seed,
                    ((lo as u64) << 32) | hi as u64,
                );
                f *= vis;
                v *= vis * vis;
            }
            bar.inc(1);
            (w * f, w * w * v)
        })
        .collect();
    let (sum, var) = terms.iter().fold((0.0, 0.0), |(a, b), (f, v)| (a + f, b + v));
    Estimate { value: sum, std_error: (s.method == Method::MonteCarlo).then(|| var.sqrt()) }
}

/// Visible fraction from a point to patch j: stratified jittered points on j, seeded.
fn point_visibility(accel: &Accel, scene: &Scene, p: DVec3, j: usize, rays: u32, seed: u64) -> f64 {
    if rays == 0 {
        return 1.0;
    }
    let mut rng = Pcg32::keyed(seed, j as u64);
    let verts = &scene.patches[j].vertices;
    let visible = (0..rays)
        .filter(|&k| {
            let (u, v) = stratified(k, rays, 0, &mut rng);
            !accel.occluded(p, point_on_polygon(verts, u, v), [j as u32, j as u32])
        })
        .count();
    visible as f64 / f64::from(rays)
}

/// F from a differential element at `p` (unit normal `n`) to the group `to`.
fn from_point(
    scene: &Scene,
    accel: Option<&Accel>,
    p: DVec3,
    n: DVec3,
    to: &[usize],
    s: &Settings,
) -> Estimate {
    let (mut sum, mut var) = (0.0, 0.0);
    for &j in to {
        let b = &scene.patches[j];
        let (mut f, mut v) = match s.method {
            Method::Exact | Method::Quadrature => (form_factor::point_to_polygon(p, n, &b.vertices), 0.0),
            Method::Disk => (form_factor::disk(p, n, b.centroid, b.normal, b.area), 0.0),
            Method::MonteCarlo => {
                let (f, se) =
                    form_factor::point_to_polygon_mc(p, n, &b.vertices, s.samples, s.seed ^ j as u64);
                (f, se * se)
            }
        };
        if let Some(accel) = accel
            && f > 0.0
        {
            let vis = point_visibility(accel, scene, p, j, s.rays, s.seed);
            f *= vis;
            v *= vis * vis;
        }
        sum += f;
        var += v;
    }
    Estimate { value: sum, std_error: (s.method == Method::MonteCarlo).then(|| var.sqrt()) }
}

/// Compute what `form-factor` prints for an already loaded scene.
pub fn compute(scene: &Scene, args: &Args) -> anyhow::Result<Output> {
    if !(args.tolerance.is_finite() && args.tolerance > 0.0 && args.tolerance < 1.0) {
        bail!("--tolerance must be in (0, 1) (got {})", args.tolerance);
    }
    if args.order == 0 || args.order > 64 {
        bail!("--order must be in 1..=64 (got {})", args.order);
    }
    if args.method == Method::MonteCarlo && args.samples == 0 {
        bail!("--samples must be at least 1");
    }
    if args.visibility && (args.rays == 0 || args.rays > 1 << 20) {
        bail!("--rays must be in 1..=1048576 (got {})", args.rays);
    }
    let s = Settings {
        method: args.method,
        rays: args.rays,
        tolerance: args.tolerance,
        order: args.order,
        samples: args.samples,
        seed: args.seed,
    };
    let to = select(scene, &args.to, "to")?;
    let accel = args.visibility.then(|| Accel::build(scene));
    if let (Some(p), Some(n)) = (args.from_point, args.from_normal) {
        let nn = n.normalize_or_zero();
        if nn == DVec3::ZERO || !nn.is_finite() {
            bail!("--from-normal {n}: must be a non-zero vector");
        }
        let from_to = from_point(scene, accel.as_ref(), p, nn, &to, &s);
        let from = format!("point:{},{},{};normal:{},{},{}", p.x, p.y, p.z, nn.x, nn.y, nn.z);
        return Ok(Output { from, to: args.to.clone(), method: args.method, from_to, to_from: None });
    }
    let Some(from_sel) = &args.from else {
        bail!("give --from SEL or --from-point x,y,z --from-normal x,y,z")
    };
    let from = select(scene, from_sel, "from")?;
    // A bar on stderr for many pairs (indicatif hides it when stderr is not a terminal).
    let pairs = 2 * (from.len() * to.len()) as u64;
    let bar = if pairs >= 64 { ProgressBar::new(pairs) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("{msg} {bar:40} {pos}/{len} pairs {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_message("form factors");
    let from_to = group(scene, accel.as_ref(), &from, &to, &s, &bar);
    let to_from = group(scene, accel.as_ref(), &to, &from, &s, &bar);
    bar.finish_and_clear();
    Ok(Output {
        from: from_sel.clone(),
        to: args.to.clone(),
        method: args.method,
        from_to,
        to_from: Some(to_from),
    })
}

/// The JSON object `--json` prints.
#[must_use]
pub fn to_json(o: &Output) -> serde_json::Value {
    let mut v = serde_json::json!({
        "from": o.from,
        "to": o.to,
        "method": o.method.name(),
        "F_from_to": o.from_to.value,
        "F_to_from": o.to_from.map(|e| e.value),
    });
    if o.method == Method::MonteCarlo {
        v["F_from_to_std_error"] = o.from_to.std_error.into();
        v["F_to_from_std_error"] = o.to_from.and_then(|e| e.std_error).into();
    }
    v
}

fn describe(scene: &Scene, sel: &str) -> String {
    match sel.parse::<usize>().ok().and_then(|i| scene.patches.get(i)) {
        Some(p) => format!("patch {sel} ({})", p.name),
        None => sel.to_string(),
    }
}

fn fmt_estimate(e: Estimate) -> String {
    match e.std_error {
        Some(se) => format!("{:.9} ± {se:.2e} (1 standard error)", e.value),
        None => format!("{:.9}", e.value),
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let scene = Scene::load(&args.scene).with_context(|| format!("loading scene {}", args.scene))?;
    let out = compute(&scene, &args)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&to_json(&out))?);
        return Ok(());
    }
    let (from, to) = (describe(&scene, &out.from), describe(&scene, &out.to));
    let how = match out.method {
        Method::Exact if out.to_from.is_some() => {
            format!("exact kernel, adaptive quadrature to {:e} relative", args.tolerance)
        }
        Method::Exact => "exact kernel (Lambert's contour integral)".into(),
        Method::Disk => "disk approximation".into(),
        Method::Quadrature if out.to_from.is_some() => {
            format!("{0}×{0} Gauss–Legendre quadrature of the exact kernel", args.order)
        }
        Method::Quadrature => "exact kernel (a point needs no quadrature)".into(),
        Method::MonteCarlo => format!("Monte Carlo, {} samples per pair", args.samples),
    };
    let vis = if args.visibility {
        format!(", × visible fraction ({} rays per pair)", args.rays)
    } else {
        String::new()
    };
    println!("scene {} ({} patches); method: {how}{vis}", scene.source, scene.patches.len());
    println!("F({from} → {to}) = {}", fmt_estimate(out.from_to));
    match out.to_from {
        Some(e) => {
            println!("F({to} → {from}) = {}", fmt_estimate(e));
            let area = |sel: &str| -> anyhow::Result<f64> {
                Ok(select(&scene, sel, "from")?.iter().map(|&i| scene.patches[i].area).sum())
            };
            let (a_from, a_to) = (area(&out.from)?, area(&out.to)?);
            println!(
                "reciprocity: A_from·F = {:.9e}, A_to·F' = {:.9e} (areas {a_from:.6e}, {a_to:.6e})",
                a_from * out.from_to.value,
                a_to * e.value
            );
        }
        None => println!("F({to} → {from}) is undefined for a differential element"),
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;
    use radlab::math::Rgb;
    use radlab::scene::Patch;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        args: Args,
    }

    fn parse(line: &str) -> Args {
        Cli::try_parse_from(std::iter::once("ff").chain(line.split_whitespace())).unwrap().args
    }

    /// Unit cube, inward faces, as two meshes: "floor" (two triangles) and "walls" (5 quads).
    fn scene() -> Scene {
        let v = DVec3::new;
        let mk = |verts: Vec<DVec3>, mesh: &str| {
            Patch::new(verts, Rgb::splat(0.5), Rgb::ZERO, mesh, 0, mesh, "m").unwrap()
        };
        Scene::new(
            "cube",
            "test:cube",
            vec![
                mk(vec![v(0., 0., 0.), v(1., 0., 0.), v(1., 1., 0.)], "floor"),
                mk(vec![v(0., 0., 0.), v(1., 1., 0.), v(0., 1., 0.)], "floor"),
                mk(vec![v(0., 0., 1.), v(0., 1., 1.), v(1., 1., 1.), v(1., 0., 1.)], "walls"),
                mk(vec![v(0., 0., 0.), v(0., 0., 1.), v(1., 0., 1.), v(1., 0., 0.)], "walls"),
                mk(vec![v(0., 1., 0.), v(1., 1., 0.), v(1., 1., 1.), v(0., 1., 1.)], "walls"),
                mk(vec![v(0., 0., 0.), v(0., 1., 0.), v(0., 1., 1.), v(0., 0., 1.)], "walls"),
                mk(vec![v(1., 0., 0.), v(1., 0., 1.), v(1., 1., 1.), v(1., 1., 0.)], "walls"),
            ],
        )
    }

    /// Opposite faces of the unit cube [Howell C-11, X = Y = 1].
    const F_OPPOSITE: f64 = 0.199_824_895_698;
    /// The closed form is quoted to 12 digits; the exact method runs at 1e-9 relative.
    const QUOTED: f64 = 1e-9;

    #[test]
    fn groups_sum_and_directions_are_reciprocal() {
        let sc = scene();
        let o = compute(&sc, &parse("x --from mesh:floor --to mesh:walls")).unwrap();
        assert!((o.from_to.value - 1.0).abs() < 1e-8, "the floor sees only walls: {o:?}");
        // Reciprocity: A_floor F_fw = A_walls F_wf, A_walls = 5.
        assert!((o.to_from.unwrap().value * 5.0 - 1.0).abs() < 1e-8);
        let o = compute(&sc, &parse("x --from mesh:floor --to 2")).unwrap();
        assert!((o.from_to.value - F_OPPOSITE).abs() < QUOTED, "{o:?}");
        let j = to_json(&o);
        assert_eq!(j["from"], "mesh:floor");
        assert_eq!(j["method"], "exact");
        // Closed convex box: visibility changes nothing.
        let o2 = compute(&sc, &parse("x --from mesh:floor --to 2 --visibility --rays 16")).unwrap();
        assert!((o2.from_to.value - o.from_to.value).abs() < 1e-15);
    }

    #[test]
    fn builtin_scenes_through_the_loader() {
        /// Perpendicular unit squares sharing an edge [Howell C-14, W = H = 1].
        const F_ADJACENT: f64 = 0.200_043_776_075;
        let sc = Scene::load("builtin:perpendicular").unwrap();
        let o = compute(&sc, &parse("x --from 0 --to 1")).unwrap();
        assert!((o.from_to.value - F_ADJACENT).abs() < QUOTED, "{o:?}");
        assert!((o.to_from.unwrap().value - F_ADJACENT).abs() < QUOTED, "{o:?}");
        // With visibility (the Cornell blocks shadow the floor), both directions use the same V.
        let sc = Scene::load("builtin:cornell").unwrap();
        let o = compute(&sc, &parse("x --from mesh:floor --to mesh:light --visibility --rays 16")).unwrap();
        let area =
            |sel: &str| select(&sc, sel, "x").unwrap().iter().map(|&i| sc.patches[i].area).sum::<f64>();
        let (fwd, back) =
            (area("mesh:floor") * o.from_to.value, area("mesh:light") * o.to_from.unwrap().value);
        assert!(fwd > 0.0 && (fwd - back).abs() < 1e-8 * fwd, "reciprocity {fwd} vs {back}");
        let sc = Scene::load("builtin:parallel").unwrap();
        let o = compute(&sc, &parse("x --from 0 --to 1 --visibility --rays 16")).unwrap();
        assert!((o.from_to.value - F_OPPOSITE).abs() < QUOTED, "{o:?}");
    }

    #[test]
    fn every_method_is_close_to_exact() {
        let sc = scene();
        for (m, tol) in [("disk", 0.05), ("quadrature", 1e-4), ("monte-carlo", 0.01)] {
            let o = compute(&sc, &parse(&format!("x --from mesh:floor --to 2 --method {m} --samples 20000")))
                .unwrap();
            assert!((o.from_to.value - F_OPPOSITE).abs() < tol, "{m}: {o:?}");
            if m == "monte-carlo" {
                let se = o.from_to.std_error.unwrap();
                assert!((o.from_to.value - F_OPPOSITE).abs() < 4.0 * se, "{o:?}");
            }
        }
    }

    #[test]
    fn from_a_point_has_no_reverse() {
        let sc = scene();
        let o = compute(&sc, &parse("x --from-point 0.5,0.5,0 --from-normal 0,0,2 --to mesh:walls")).unwrap();
        assert!((o.from_to.value - 1.0).abs() < 1e-12);
        assert!(o.to_from.is_none() && to_json(&o)["F_to_from"].is_null());
        let neg = parse("x --from-point -0.5,0.5,1e-3 --from-normal 0,0,-1 --to 2");
        assert_eq!(compute(&sc, &neg).unwrap().from_to.value, 0.0);
    }

    #[test]
    fn bad_selectors_and_parameters_are_one_line_errors() {
        let sc = scene();
        for (line, needle) in [
            ("x --from 7 --to 2", "no such patch"),
            ("x --from mesh:roof --to 2", "no mesh named"),
            ("x --from abc --to 2", "patch index"),
            ("x --from 0 --to 2 --order 0", "--order"),
            ("x --from 0 --to 2 --tolerance 0", "--tolerance"),
            ("x --from-point 0,0,0 --from-normal 0,0,0 --to 2", "non-zero"),
        ] {
            let e = compute(&sc, &parse(line)).unwrap_err().to_string();
            assert!(e.contains(needle) && !e.contains('\n'), "{line}: {e}");
        }
        assert!(Cli::try_parse_from(["ff", "x", "--to", "1", "--from-point", "1,2"]).is_err());
        assert!(Cli::try_parse_from(["ff", "x", "--to", "1"]).is_err(), "needs --from or --from-point");
    }
}
