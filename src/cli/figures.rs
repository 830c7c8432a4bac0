//! `radlab figures [--json] [--screenshots DIR [NAME…]]`: the lecture's figures
//! ([`radlab::present::figures`]): list them, or write one PNG each by running `radlab view --figure NAME
//! --screenshot DIR/NAME.png` (needs a display, e.g. Xvfb, and the viewer).

use anyhow::{Context as _, bail};
use radlab::present::figures::{FIGURES, Figure, find, placeholders};
use std::path::PathBuf;
use std::process::Command;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print every figure as JSON (name, slide, scene, preset, settings, overlays, camera, and
    /// its caption as a template: `caption_template`, whose names in braces, listed in
    /// `caption_fills`, the viewer fills from the state it shows) instead of a table.
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
        let figures = FIGURES.iter().map(figure_json).collect::<anyhow::Result<Vec<_>>>()?;
        println!("{}", serde_json::to_string_pretty(&figures)?);
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

/// A figure as JSON. Its caption's numbers depend on the state a solve reaches when the figure
/// opens, so the caption is given as what it is, a template (`caption_template`), with the
/// names it quotes (`caption_fills`, see `radlab::present::figures::PLACEHOLDERS`); `radlab view
/// --figure NAME` shows it filled.
fn figure_json(f: &Figure) -> anyhow::Result<serde_json::Value> {
    let mut v = serde_json::to_value(f)?;
    let object = v.as_object_mut().context("a figure serialises to an object")?;
    let caption = object.remove("caption").unwrap_or_default();
    object.insert("caption_template".to_owned(), caption);
    object.insert("caption_fills".to_owned(), serde_json::json!(placeholders(f.caption)));
    Ok(v)
}
