//! `radlab bench`: speed against error over methods and settings (see [`radlab::studies::bench`]).

use anyhow::Context;
use radlab::eval::reference::Cache;
use radlab::studies::bench::{self, BenchConfig, Mode};
use std::path::PathBuf;

pub mod scale;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Comma-separated scenes (`builtin:NAME`, `hard:NAME` or paths; a bare NAME means builtin:NAME).
    /// Default: cornell, table-room, perpendicular, splash_room.
    #[arg(long, value_delimiter = ',')]
    pub scenes: Vec<String>,
    /// A smoke run: two settings per method, one repeat, a rough reference (4096 points, 64 paths
    /// each; under a minute).
    #[arg(long, conflicts_with = "full")]
    pub quick: bool,
    /// Finer sweeps, five repeats, a better reference.
    #[arg(long)]
    pub full: bool,
    /// Repeats per setting (default: 1 quick, 3 standard, 5 full); the median time is reported.
    #[arg(long)]
    pub repeats: Option<usize>,
    /// Paths per reference point in each reference batch (default: 64 quick, 1024 standard and full).
    #[arg(long)]
    pub reference_samples: Option<u32>,
    /// Points of the pointwise reference, at least (default: 4096 quick, 65536 standard, 262144 full).
    #[arg(long)]
    pub reference_points: Option<u32>,
    /// Add reference batches until the reference's noise and resolution are at most this relative
    /// L2, e.g. 0.005 (default: 0.005 standard and full; quick: one batch). 0: one batch.
    #[arg(long)]
    pub reference_target: Option<f64>,
    /// At most this many reference batches (default: 1 quick, 64 standard, 256 full).
    #[arg(long)]
    pub reference_batches: Option<u32>,
    /// Wall-clock budget of one solve in seconds (default: 5 quick, 60 standard, 300 full).
    #[arg(long)]
    pub budget: Option<f64>,
    /// Write the full result as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the log-log speed-vs-error plot (PNG).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write the Markdown table (for the README).
    #[arg(long)]
    pub table: Option<PathBuf>,
    /// Reference cache folder (default: $RADLAB_CACHE, else .radlab-cache/).
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
    /// The scale study instead: the generated scene families (`radlab scenes --generate`) solved
    /// at growing sizes, one `radlab solve` process a row (wall time, peak memory, links per
    /// element, energy; docs/scale.md). `--budget` then sets each solve's `--time-budget`.
    #[arg(long, conflicts_with_all = ["quick", "full", "scenes", "plot"])]
    pub scale: bool,
    /// With --scale: the families (default: all of them).
    #[arg(long, value_delimiter = ',', requires = "scale")]
    pub families: Vec<String>,
    /// With --scale: the sizes in triangles (default: 10k,100k,1m).
    #[arg(long, value_delimiter = ',', requires = "scale")]
    pub sizes: Vec<String>,
    /// With --scale: the preset each row solves at (default: the default preset).
    #[arg(long, requires = "scale")]
    pub preset: Option<String>,
    /// With --scale: solver threads of each row (default: all cores).
    #[arg(long, requires = "scale")]
    pub threads: Option<usize>,
}

/// `radlab bench --scale`.
fn run_scale(args: &Args) -> anyhow::Result<()> {
    let config = scale::ScaleConfig {
        families: if args.families.is_empty() {
            radlab::scene::families::Family::ALL.map(|f| f.name().to_string()).to_vec()
        } else {
            args.families.clone()
        },
        sizes: if args.sizes.is_empty() {
            scale::SIZES.map(String::from).to_vec()
        } else {
            args.sizes.clone()
        },
        preset: args
            .preset
            .clone()
            .unwrap_or_else(|| radlab::solver::spec::Preset::Quality.name().to_string()),
        budget_s: args.budget,
        threads: args.threads,
    };
    scale::check(&config)?;
    if let Some(b) = config.budget_s {
        anyhow::ensure!(b.is_finite() && b > 0.0, "--budget must be a number of seconds > 0 (got {b})");
    }
    if let Some(t) = config.threads {
        anyhow::ensure!(t >= 1, "--threads must be at least 1");
    }
    let scratch = scale::Scratch::new()?;
    let rows = scale::run(&config, &scratch.0, &mut |line| eprintln!("{line}"))?;
    let table = scale::markdown(&rows, &config);
    println!("{table}");
    write_outputs(args, &serde_json::to_string_pretty(&rows)?, &table, &mut |l| eprintln!("{l}"))
}

/// Write `--json` and `--table` where asked, saying so through `say`.
fn write_outputs(args: &Args, json: &str, table: &str, say: &mut dyn FnMut(&str)) -> anyhow::Result<()> {
    for (path, text) in [(&args.json, json), (&args.table, table)] {
        if let Some(p) = path {
            std::fs::write(p, text).with_context(|| format!("writing {}", p.display()))?;
            say(&format!("wrote {}", p.display()));
        }
    }
    Ok(())
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.scale {
        return run_scale(&args);
    }
    let mode = if args.quick {
        Mode::Quick
    } else if args.full {
        Mode::Full
    } else {
        Mode::Standard
    };
    let mut config = BenchConfig::new(mode);
    if !args.scenes.is_empty() {
        config.scenes = args
            .scenes
            .iter()
            .map(|s| {
                if s.contains(':') || s.contains('.') || s.contains('/') {
                    s.clone()
                } else {
                    format!("builtin:{s}")
                }
            })
            .collect();
    }
    if let Some(r) = args.repeats {
        anyhow::ensure!(r >= 1, "--repeats must be at least 1");
        config.repeats = r;
    }
    if let Some(n) = args.reference_samples {
        anyhow::ensure!(n >= 1, "--reference-samples must be at least 1");
        config.reference.samples = n;
    }
    if let Some(n) = args.reference_points {
        anyhow::ensure!(n >= 1, "--reference-points must be at least 1");
        config.reference_points = n;
    }
    if let Some(t) = args.reference_target {
        anyhow::ensure!(t.is_finite() && t >= 0.0, "--reference-target must be a number >= 0 (got {t})");
        config.reference_target = (t > 0.0).then_some(t);
    }
    if let Some(n) = args.reference_batches {
        anyhow::ensure!(n >= 1, "--reference-batches must be at least 1");
        config.reference_max_batches = n;
    }
    if let Some(b) = args.budget {
        anyhow::ensure!(b.is_finite() && b > 0.0, "--budget must be a number of seconds > 0 (got {b})");
        config.budget_s = b;
    }
    if let Some(dir) = &args.cache_dir {
        config.cache = Cache::at(dir.clone());
    }
    println!("reference cache: {}", config.cache.dir.display());
    let report = bench::run(&config, &mut |line| println!("{line}"))?;
    let table = bench::markdown(&report);
    println!("\n{table}");
    write_outputs(&args, &serde_json::to_string_pretty(&report)?, &table, &mut |l| println!("{l}"))?;
    if let Some(p) = &args.plot {
        bench::plot_png(&report, p)?;
        println!("wrote {}", p.display());
    }
    Ok(())
}
