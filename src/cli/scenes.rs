//! `radlab scenes`: list the built-in scenes (name, patch count after loading, description).
//! Each is used as `builtin:NAME` wherever a scene is expected. The generated furnished rooms
//! and scene families follow (their listed sizes; any `FAMILY-SIZE[-sSEED]` works): generating
//! the 1 M room takes a few seconds, so `--no-generated` leaves them out.
//!
//! `radlab scenes --generate FAMILY --triangles N --out PATH.glb [--seed S]` writes a family's
//! scene ([`radlab::scene::families`]) as binary glTF (or glTF with an embedded buffer when
//! PATH ends in `.gltf`); the file loads back as `builtin:FAMILY-N[-sS]` generates it.

use anyhow::{Context as _, bail};
use radlab::scene::builtin::{BUILTINS, load};
use radlab::scene::families::{self, Family, FamilyParams};
use radlab::scene::furnished::{MAX_TRIANGLES, MIN_TRIANGLES, SIZES};
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print a JSON array `[{"name", "source", "patches", "emitters", "description"}]` instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Leave out the generated furnished rooms and families (which are generated to be counted).
    #[arg(long)]
    pub no_generated: bool,
    /// Generate a scene of this family and write it to --out (furnished, box-grid, shelves,
    /// chairs, stacked-boxes, corridor) instead of listing.
    #[arg(long, value_name = "FAMILY", requires_all = ["triangles", "out"])]
    pub generate: Option<String>,
    /// The generated scene's size in triangles, as a glTF file counts them (10k, 30000, 1m).
    #[arg(long, value_name = "N", requires = "generate")]
    pub triangles: Option<String>,
    /// Picks another scene of the same family and size.
    #[arg(long, default_value_t = 0, requires = "generate")]
    pub seed: u64,
    /// Where to write the generated scene (.glb, or .gltf with the buffer embedded).
    #[arg(long, value_name = "PATH", requires = "generate")]
    pub out: Option<PathBuf>,
    /// Replace --out if it exists.
    #[arg(long, requires = "generate")]
    pub force: bool,
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
    if let Some(family) = &args.generate {
        let (Some(triangles), Some(out)) = (&args.triangles, &args.out) else {
            bail!("--generate needs --triangles N and --out PATH.glb");
        };
        return generate(family, triangles, args.seed, out, args.force);
    }
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
        for family in Family::ALL.into_iter().filter(|f| *f != Family::Furnished) {
            let (min, max) = family.range();
            let description = format!(
                "generated: {}, 10000 triangles targeted ({}-SIZE[-sSEED], SIZE {min}..={max})",
                family.description(),
                family.name()
            );
            rows.push(row(&format!("{}-10k", family.name()), description)?);
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

/// `--generate`: check everything before generating, write, say what was written.
fn generate(family: &str, triangles: &str, seed: u64, out: &Path, force: bool) -> anyhow::Result<()> {
    let family = Family::from_name(family)
        .with_context(|| format!("unknown scene family {family:?} (the families: {})", Family::names()))?;
    let n = families::parse_triangles(family, triangles)
        .map_err(|cause| anyhow::anyhow!("--triangles: {cause}"))?;
    let params =
        FamilyParams::new(family, n, seed).map_err(|cause| anyhow::anyhow!("--triangles: {cause}"))?;
    let glb = match out.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("glb") => true,
        Some("gltf") => false,
        _ => bail!("{}: the output must end in .glb or .gltf", out.display()),
    };
    if !force && out.exists() {
        bail!("{}: exists; not overwriting it (pass --force to replace it)", out.display());
    }
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty())
        && !dir.is_dir()
    {
        bail!("{}: cannot write: folder {} does not exist", out.display(), dir.display());
    }
    let scene = families::generate(params);
    let written = if glb {
        radlab::scene::gltf::write_glb(&scene, out)
    } else {
        radlab::scene::gltf::write_gltf(&scene, out)
    };
    written.with_context(|| format!("writing {}", out.display()))?;
    let emitters = scene.patches.iter().filter(|p| p.is_emitter()).count();
    println!(
        "{}: {} ({} triangles, {} patches, {emitters} emitting), builtin:{}-{n}-s{seed}",
        out.display(),
        family.name(),
        families::triangles(&scene),
        scene.patches.len(),
        family.name()
    );
    Ok(())
}
