//! `radlab scenes`: list the built-in scenes (name, patch count after loading, description).
//! Each is used as `builtin:NAME` wherever a scene is expected.

use anyhow::Context as _;
use radlab::scene::builtin::{BUILTINS, load};
use serde::Serialize;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print a JSON array `[{"name", "source", "patches", "emitters", "description"}]` instead of a table.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct Row {
    name: &'static str,
    source: String,
    patches: usize,
    emitters: usize,
    description: &'static str,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut rows = Vec::new();
    for &(name, description) in BUILTINS {
        let scene = load(name).with_context(|| format!("loading builtin:{name}"))?;
        rows.push(Row {
            name,
            source: format!("builtin:{name}"),
            patches: scene.patches.len(),
            emitters: scene.patches.iter().filter(|p| p.is_emitter()).count(),
            description,
        });
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
        return Ok(());
    }
    let w = rows.iter().map(|r| r.source.len()).max().unwrap_or(0);
    println!("{:<w$}  {:>7}  description", "scene", "patches");
    for r in &rows {
        println!("{:<w$}  {:>7}  {}", r.source, r.patches, r.description);
    }
    Ok(())
}
