//! `radlab speed [SCENE] [--preset P] [--rays 4,10] [--threads 1,2] [--repeats N] [--seeds K] [--json PATH]`:
//! the hierarchical solver's speed benchmark.
//!
//! Runs the preset's full hierarchical solve, set up as `radlab solve` sets it up
//! (`solver::spec::setup`: on the input patches with the BVH reused, or on the preset's mesh,
//! whose meshing and BVH are then timed too), for every rays × threads
//! combination, `repeats` times after one untimed warm-up, and prints the median wall time per
//! phase, the element and link counts, and the link-creation rate (links created by refinement,
//! including replaced ones, per second of refinement). With `--seeds K` the timed runs cycle
//! through K visibility seeds: the mesh depends on which links a few rays find partially
//! visible, so one seed can be lucky; the row then gives the median time over all runs, the
//! counts of the run with the median link count, and the range of links. Defaults: the SPLASH-2 room at settings
//! equivalent to the SPLASH-2 `radiosity` program's defaults (preset `splash2`: minimum element
//! area 2000, BF epsilon 0.015, energy tolerance 0.005).

use anyhow::{Context, bail};
use radlab::geometry::accel::Accel;
use radlab::solver::hierarchical::HierarchicalStats;
use radlab::solver::params::HierarchicalParams;
use radlab::solver::spec::{Plan, SolveSpec, TopLevel, setup};
use serde::Serialize;
use std::sync::Arc;
use std::time::Instant;

/// The SPLASH-2 program's figures on this class of machine (from the issue text): one thread,
/// 10 rays per link through a BSP tree.
const SPLASH2_CPU_S: f64 = 0.83;
const SPLASH2_ELEMENTS: usize = 17_112;
const SPLASH2_LINKS: usize = 168_919;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene (.gltf/.glb or builtin:NAME)
    #[arg(default_value = "builtin:splash_room")]
    pub scene: String,
    /// Preset whose hierarchical settings are timed on the quadtree of the input patches (the
    /// solver SPLASH-2's program runs): splash2 (default), bf, lecture, or a step of the ladder
    /// (draft, interactive, quality, fine, reference: its error oracle, here on the quadtree).
    #[arg(long, default_value = "splash2")]
    pub preset: String,
    /// Rays per link, comma-separated
    #[arg(long, value_delimiter = ',', default_value = "4,10")]
    pub rays: Vec<u32>,
    /// Thread counts, comma-separated
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    pub threads: Vec<usize>,
    /// Timed runs per combination (the median is reported)
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// Visibility seeds the timed runs cycle through (run i uses the preset's seed + i mod N).
    /// The mesh depends on the seed (which links look partially visible to a few rays), so one
    /// seed can be lucky; several give a fair median.
    #[arg(long, default_value_t = 1)]
    pub seeds: u64,
    /// Write the rows as JSON to this file
    #[arg(long)]
    pub json: Option<std::path::PathBuf>,
}

/// One rays × threads combination (phase times from the run with the median total).
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub rays: u32,
    pub threads: usize,
    pub elements: usize,
    pub leaves: usize,
    pub links: usize,
    pub links_created: u64,
    pub rays_cast: u64,
    /// The median-time run's phase times, under their names in [`HierarchicalStats`].
    #[serde(flatten)]
    pub phases: Phases,
    pub total_s: f64,
    pub totals_s: Vec<f64>,
    /// Seeds cycled through, and the fewest and most links over the timed runs.
    pub seeds: u64,
    pub links_min: usize,
    pub links_max: usize,
    pub links_per_s: f64,
    pub rays_per_s: f64,
}

/// The statistics of one solve, of which a [`Row`] shows the phase times: refinement
/// (`refine_s`) and its parts — initial linking, the oracle (parallel), splitting (serial), new
/// links (parallel), installing them (serial) — then gather and push-pull.
#[derive(Clone, Debug)]
pub struct Phases(pub HierarchicalStats);

impl Serialize for Phases {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap as _;
        let st = &self.0;
        let times = [
            ("refine_s", st.refine_s),
            ("refine_initial_s", st.refine_initial_s),
            ("refine_decide_s", st.refine_decide_s),
            ("refine_split_s", st.refine_split_s),
            ("refine_links_s", st.refine_links_s),
            ("refine_install_s", st.refine_install_s),
            ("gather_s", st.gather_s),
            ("push_pull_s", st.push_pull_s),
        ];
        let mut map = serializer.serialize_map(Some(times.len()))?;
        for (name, seconds) in times {
            map.serialize_entry(name, &seconds)?;
        }
        map.end()
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    check(&args)?;
    let ladder = radlab::solver::spec::Preset::from_name(&args.preset).with_context(|| {
        format!("unknown preset {:?} (one of {})", args.preset, radlab::solver::spec::Preset::names())
    })?;
    let (preset, top) = (ladder.hierarchical(), ladder.top());
    let scene = Arc::new(super::solve::load_scene(&args.scene, 5_000_000)?);
    let accel = Arc::new(Accel::build(&scene));
    println!(
        "{}: {} patches, preset {}, {} timed run(s) per row after a warm-up, seeds {}..{}",
        args.scene,
        scene.patches.len(),
        args.preset,
        args.repeats,
        preset.seed,
        preset.seed.wrapping_add(args.seeds - 1)
    );
    println!(
        "| rays | threads | elements (leaves) | links | links created | rays cast | refine | gather + push-pull | total (median) | links/s | rays/s |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let mut rows = Vec::new();
    for &rays in &args.rays {
        for &threads in &args.threads {
            let row = measure(&args, &scene, &accel, (preset, top), rays, threads)?;
            let ph = &row.phases.0;
            println!(
                "| {} | {} | {} ({}) | {} | {} | {} | {:.3} s | {:.3} s | {:.3} s | {:.2} M | {:.2} M |",
                row.rays,
                row.threads,
                row.elements,
                row.leaves,
                row.links,
                row.links_created,
                row.rays_cast,
                ph.refine_s,
                ph.gather_s + ph.push_pull_s,
                row.total_s,
                row.links_per_s / 1e6,
                row.rays_per_s / 1e6
            );
            rows.push(row);
        }
    }
    print_phases(&rows, args.seeds);
    println!(
        "SPLASH-2 radiosity on this class of machine (issue figure): {SPLASH2_CPU_S} s CPU on one thread, \
         {SPLASH2_ELEMENTS} elements, {SPLASH2_LINKS} links, 10 rays per link."
    );
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&rows).context("serialising the rows")?;
        std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// Refuse counts outside what the benchmark can run.
fn check(args: &Args) -> anyhow::Result<()> {
    if args.repeats == 0 || args.repeats > 1000 {
        bail!("--repeats must be between 1 and 1000 (got {})", args.repeats);
    }
    if args.seeds == 0 || args.seeds > 1000 {
        bail!("--seeds must be between 1 and 1000 (got {})", args.seeds);
    }
    if args.rays.iter().any(|&r| r == 0 || r > 4096) {
        bail!("--rays must be between 1 and 4096");
    }
    if args.threads.iter().any(|&t| t == 0 || t > 1024) {
        bail!("--threads must be between 1 and 1024");
    }
    Ok(())
}

/// One row: a warm-up and `args.repeats` timed solves at `rays` per link on `threads` threads,
/// cycling through the seeds.
fn measure(
    args: &Args,
    scene: &Arc<radlab::scene::Scene>,
    accel: &Arc<Accel>,
    (preset, top): (HierarchicalParams, TopLevel),
    rays: u32,
    threads: usize,
) -> anyhow::Result<Row> {
    let pool =
        rayon::ThreadPoolBuilder::new().num_threads(threads).build().context("building the thread pool")?;
    let mut runs = Vec::new();
    for i in 0..=args.repeats {
        // The warm-up (i = 0) uses the last seed; run i the preset's seed + (i - 1) mod N.
        let k = (i as u64 + args.seeds - 1) % args.seeds;
        let params = HierarchicalParams { rays, seed: preset.seed.wrapping_add(k), ..preset };
        let (total, stats) = pool.install(|| {
            let t = Instant::now();
            let spec = SolveSpec { plan: Plan::Hierarchical { params, top }, estimate: false };
            let mut s = setup(scene, Some((accel, 0.0)), &spec)?;
            s.solver_mut().solve(&mut |_, _| {});
            anyhow::Ok((t.elapsed().as_secs_f64(), s.solver().stats()))
        })?;
        if i > 0 {
            runs.push((total, stats));
        }
    }
    runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let totals: Vec<f64> = runs.iter().map(|r| r.0).collect();
    let (total, st) = runs[runs.len() / 2].clone();
    // Counts from the run with the median link count (they depend on the seed only, so they
    // agree across thread counts; times come from the median-time run).
    let mut by_links: Vec<&HierarchicalStats> = runs.iter().map(|r| &r.1).collect();
    by_links.sort_by_key(|s| (s.links, s.elements, s.rays));
    let counts = by_links[by_links.len() / 2].clone();
    let links_min = runs.iter().map(|r| r.1.links).min().unwrap_or(0);
    let links_max = runs.iter().map(|r| r.1.links).max().unwrap_or(0);
    Ok(Row {
        rays,
        threads,
        elements: counts.elements,
        leaves: counts.leaves,
        links: counts.links,
        links_created: counts.links_created,
        rays_cast: counts.rays,
        total_s: total,
        totals_s: totals,
        seeds: args.seeds,
        links_min,
        links_max,
        links_per_s: st.links_created as f64 / st.refine_s.max(1e-9),
        rays_per_s: st.rays as f64 / st.refine_s.max(1e-9),
        phases: Phases(st),
    })
}

/// Refinement by phase, row by row, and with several seeds the range of links.
fn print_phases(rows: &[Row], seeds: u64) {
    println!();
    println!("Refinement by phase (same runs; install is mostly serial):");
    println!("| rays | threads | initial linking | oracle | split | new links | install | other |");
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in rows {
        let ph = &r.phases.0;
        let parts = ph.refine_initial_s
            + ph.refine_decide_s
            + ph.refine_split_s
            + ph.refine_links_s
            + ph.refine_install_s;
        println!(
            "| {} | {} | {:.3} s | {:.3} s | {:.3} s | {:.3} s | {:.3} s | {:.3} s |",
            r.rays,
            r.threads,
            ph.refine_initial_s,
            ph.refine_decide_s,
            ph.refine_split_s,
            ph.refine_links_s,
            ph.refine_install_s,
            ph.refine_s - parts
        );
    }
    if seeds > 1 {
        println!("Links over the seeds (row: fewest to most):");
        for r in rows {
            println!("  {} rays, {} threads: {} to {}", r.rays, r.threads, r.links_min, r.links_max);
        }
    }
}
