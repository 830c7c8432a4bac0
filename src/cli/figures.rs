//! `radlab figures [--json] [--screenshots DIR [NAME…]]`: the lecture's figures
//! ([`radlab::present::figures`]): list them, or write one PNG each by running `radlab view --figure NAME
//! --screenshot DIR/NAME.png` (needs a display, e.g. Xvfb, and the viewer).

use anyhow::{Context as _, bail};
use radlab::present::figures::{FIGURES, Figure, find};
use std::path::PathBuf;
use std::process::Command;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print every figure as JSON (name, slide, scene, preset, settings, overlays, camera,
    /// caption) instead of a table.
    #[arg(long, conflicts_with = "screenshots")]
    pub json: bool,
    /// Write one PNG per figure into this folder (DIR/NAME.png), each by a `radlab view
    /// --figure NAME --screenshot` run.
    #[arg(long, value_name = "DIR")]
    pub screenshots: Option<PathBuf>,
    /// With --screenshots: only these figures.
    #[arg(value_name = "NAME", requires = "screenshots")]
    pub names: Vec<String>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.json {
        println!("{}", serde_json::to_string_pretty(FIGURES)?);
        return Ok(());
    }
    let Some(dir) = args.screenshots else {
        let w = FIGURES.iter().map(|f| f.name.len()).max().unwrap_or(0);
        println!("{:<w$}  slide", "figure");
        for f in FIGURES {
            println!("{:<w$}  {}", f.name, f.slide);
        }
        println!("\nOpen one with `radlab view --figure NAME`, or from the viewer's Lecture menu.");
        return Ok(());
    };
    let figures: Vec<&Figure> = if args.names.is_empty() {
        FIGURES.iter().collect()
    } else {
        args.names.iter().map(|n| find(n)).collect::<Result<_, _>>()?
    };
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let exe = std::env::current_exe().context("finding the radlab executable")?;
    for f in figures {
        let png = dir.join(format!("{}.png", f.name));
        // One process per figure: a window's event loop can be created only once per process.
        let status = Command::new(&exe)
            .arg("view")
            .arg("--figure")
            .arg(f.name)
            .arg("--screenshot")
            .arg(&png)
            .status()
            .with_context(|| format!("running {} view --figure {}", exe.display(), f.name))?;
        if !status.success() {
            bail!("figure {}: the viewer failed ({status})", f.name);
        }
    }
    Ok(())
}
