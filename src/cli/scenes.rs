//! `radlab scenes`: list the built-in scenes (name, patch count after loading, description).
//! Each is used as `builtin:NAME` wherever a scene is expected. The generated furnished rooms
//! follow (their listed sizes; any `furnished-SIZE[-sSEED]` works): generating the 1 M room
//! takes a few seconds, so `--no-generated` leaves them out.

use anyhow::Context as _;
use radlab::scene::builtin::{BUILTINS, load};
use radlab::scene::furnished::{MAX_TRIANGLES, MIN_TRIANGLES, SIZES};
use serde::Serialize;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print a JSON array `[{"name", "source", "patches", "emitters", "description"}]` instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Leave out the generated furnished rooms (which are generated to be counted).
    #[arg(long)]
    pub no_generated: bool,
}

#[derive(Serialize)]
struct Row {
    name: String,
    source: String,
    patches: usize,
    emitters: usize,
    description: String,
}

fn row(name: &str, description: String) -> anyhow::Result<Row> {
    let scene = load(name).with_context(|| format!("loading builtin:{name}"))?;
    Ok(Row {
        name: name.to_string(),
        source: format!("builtin:{name}"),
        patches: scene.patches.len(),
        emitters: scene.patches.iter().filter(|p| p.is_emitter()).count(),
        description,
    })
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut rows = Vec::new();
    for &(name, description) in BUILTINS {
        rows.push(row(name, description.to_string())?);
    }
    if !args.no_generated {
        for &(name, target) in SIZES {
            let description = format!(
                "generated furnished room, {target} triangles targeted (furnished-SIZE[-sSEED], SIZE {MIN_TRIANGLES}..={MAX_TRIANGLES})"
            );
            rows.push(row(name, description)?);
        }
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
