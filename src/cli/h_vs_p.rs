//! `radlab h-vs-p`: the h- against p-refinement study ([`radlab::studies::order_study`]) — Galerkin
//! p = 0 and p = 1 on a sequence of uniform meshes of the parallel squares and of
//! `builtin:shadow-narrow`, scored against the exact single-bounce answer: the table (Markdown),
//! the fitted log-log slopes and a log-log plot (PNG).

use anyhow::Context as _;
use radlab::studies::order_study::{self, StudyParams, StudyScene};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Receiver elements per side, one mesh each (comma-separated; default 2,4,8,16,32,64,128).
    #[arg(long, value_delimiter = ',')]
    pub divisions: Option<Vec<u32>>,
    /// Evaluation lattice: GRID × GRID points on the receiver.
    #[arg(long, default_value_t = StudyParams::docs().grid)]
    pub grid: usize,
    /// Rays that classify each element pair as hidden, unoccluded or partly occluded.
    #[arg(long, default_value_t = StudyParams::docs().rays)]
    pub rays: u32,
    /// Write the log-log plot here.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Write every row (scene, method, h, unknowns, errors, time) as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut params = StudyParams::docs();
    if let Some(d) = args.divisions {
        anyhow::ensure!(
            d.len() >= 2 && d.iter().all(|&n| (1..=256).contains(&n)),
            "--divisions: at least two values in 1..=256"
        );
        params.divisions = d;
    }
    anyhow::ensure!((2..=2048).contains(&args.grid), "--grid must be in 2..=2048");
    params.grid = args.grid;
    params.rays = args.rays;
    let mut rows = Vec::new();
    for scene in [StudyScene::ParallelSquares, StudyScene::ShadowNarrow] {
        rows.extend(
            order_study::run(scene, &params).map_err(anyhow::Error::msg).with_context(|| scene.name())?,
        );
    }
    print!("{}", order_study::markdown(&rows));
    if let Some(path) = &args.png {
        order_study::plot_png(&rows, path).map_err(anyhow::Error::msg)?;
        println!("wrote {}", path.display());
    }
    if let Some(path) = &args.json {
        let doc = serde_json::json!({ "params": params, "rows": rows, "fits": order_study::fits(&rows) });
        std::fs::write(path, serde_json::to_string_pretty(&doc)? + "\n")
            .with_context(|| format!("writing {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
