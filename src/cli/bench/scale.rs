//! `radlab bench --scale`: the generated scene families solved at growing sizes, one row per
//! family and size: wall time, peak memory, links per element and where the light went.
//!
//! Each row is one `radlab solve builtin:FAMILY-SIZE --preset P --json …` run as a child process
//! of this one, so that its peak memory is its own (the child reads its own `getrusage` high-water
//! mark) and a row that runs out of memory or time fails alone. The scenes are generated in the
//! child ([`radlab::scene::families`]), never written to disk. Rows run one at a time, smallest
//! size first, so that the machine's cores all go to the row being timed.

use anyhow::Context;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// The sizes solved by default, in triangles (every family of `radlab scenes --generate` is).
pub const SIZES: [&str; 3] = ["10k", "100k", "1m"];

/// Check the families' names and sizes before any solve: one line naming what is wrong.
pub fn check(config: &ScaleConfig) -> anyhow::Result<()> {
    use radlab::scene::families::{Family, parse_triangles};
    anyhow::ensure!(
        !config.families.is_empty() && !config.sizes.is_empty(),
        "--families and --sizes need at least one each"
    );
    for name in &config.families {
        let family = Family::from_name(name)
            .with_context(|| format!("--families: unknown family {name:?} (one of {})", Family::names()))?;
        for size in &config.sizes {
            parse_triangles(family, size).map_err(|e| anyhow::anyhow!("--sizes: {name} at {size}: {e}"))?;
        }
    }
    anyhow::ensure!(
        radlab::solver::spec::Preset::from_name(&config.preset).is_some(),
        "--preset: unknown preset {:?} (one of {})",
        config.preset,
        radlab::solver::spec::Preset::names()
    );
    Ok(())
}

/// What the study runs.
#[derive(Clone, Debug)]
pub struct ScaleConfig {
    pub families: Vec<String>,
    pub sizes: Vec<String>,
    pub preset: String,
    /// Wall-clock budget of one solve (`radlab solve --time-budget`), seconds.
    pub budget_s: Option<f64>,
    /// Solver threads (`--threads`; `None`: all cores).
    pub threads: Option<usize>,
}

/// One family at one size.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ScaleRow {
    pub scene: String,
    pub preset: String,
    /// "ok", or why the row has no figures (the child's last line of stderr).
    pub status: String,
    pub patches: u64,
    pub elements: u64,
    pub links: u64,
    pub cluster_links: u64,
    pub links_per_element: f64,
    /// Refinement stopped at the link budget, or the time budget cancelled the solve.
    pub budget_hit: bool,
    pub cancelled: bool,
    /// Wall time of the child process: generation, BVH, meshing, solve and writing its JSON
    /// (which lists every patch).
    pub wall_s: f64,
    /// The solve's own total time (`stats.time_s.total`).
    pub solve_s: f64,
    pub peak_rss_bytes: u64,
    /// Channel means of the power balance.
    pub emitted: f64,
    pub absorbed: f64,
    pub absorbed_by_back_faces: f64,
    pub not_gathered: f64,
    pub closed: bool,
    pub light_created: bool,
    pub relative_residual: f64,
}

/// Solve every family at every size; `log` gets one line per row as it finishes.
pub fn run(config: &ScaleConfig, dir: &Path, log: &mut dyn FnMut(&str)) -> anyhow::Result<Vec<ScaleRow>> {
    let exe = std::env::current_exe().context("finding the radlab executable")?;
    let mut rows = Vec::new();
    for size in &config.sizes {
        for family in &config.families {
            let scene = format!("builtin:{family}-{size}");
            log(&format!("{scene} at {} …", config.preset));
            let row = solve_row(&exe, config, &scene, dir)?;
            log(&row_line(&row));
            rows.push(row);
        }
    }
    Ok(rows)
}

/// One row: the child solve and its JSON read back.
fn solve_row(exe: &Path, config: &ScaleConfig, scene: &str, dir: &Path) -> anyhow::Result<ScaleRow> {
    let json = dir.join("solve.json");
    let _ = std::fs::remove_file(&json);
    let mut cmd = Command::new(exe);
    cmd.args(["solve", scene, "--preset", &config.preset, "-q", "--json"]).arg(&json);
    if let Some(b) = config.budget_s {
        cmd.args(["--time-budget", &b.to_string()]);
    }
    if let Some(t) = config.threads {
        cmd.args(["--threads", &t.to_string()]);
    }
    let t = Instant::now();
    let out = cmd.output().with_context(|| format!("running {}", exe.display()))?;
    let wall_s = t.elapsed().as_secs_f64();
    let mut row =
        ScaleRow { scene: scene.into(), preset: config.preset.clone(), wall_s, ..ScaleRow::default() };
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        row.status = err.lines().last().unwrap_or("failed").to_string();
        return Ok(row);
    }
    let text = std::fs::read_to_string(&json).with_context(|| format!("reading {}", json.display()))?;
    let doc: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("parsing {}", json.display()))?;
    fill(&mut row, &doc);
    Ok(row)
}

/// The row's figures from `radlab solve --json`'s document.
fn fill(row: &mut ScaleRow, doc: &serde_json::Value) {
    let stats = &doc["stats"];
    let u = |v: &serde_json::Value| v.as_u64().unwrap_or(0);
    let mean = |v: &serde_json::Value| {
        v.as_array().map_or(0.0, |c| {
            c.iter().filter_map(serde_json::Value::as_f64).sum::<f64>() / c.len().max(1) as f64
        })
    };
    row.status = "ok".into();
    row.patches = u(&stats["patches"]);
    row.elements = u(&stats["elements"]);
    row.links = u(&stats["links"]);
    row.cluster_links = u(&stats["cluster_links"]);
    row.links_per_element = stats["links_per_element"].as_f64().unwrap_or(0.0);
    row.budget_hit = stats["budget_hit"].as_bool().unwrap_or(false);
    row.cancelled = doc["cancelled"].as_bool().unwrap_or(false);
    row.solve_s = stats["time_s"]["total"].as_f64().unwrap_or(0.0);
    row.peak_rss_bytes = u(&stats["peak_rss_bytes"]);
    let e = &doc["energy"];
    row.emitted = mean(&e["emitted"]);
    row.absorbed = mean(&e["absorbed"]);
    row.absorbed_by_back_faces = mean(&e["absorbed_by_back_faces"]);
    row.not_gathered = mean(&e["not_gathered"]);
    row.closed = e["closed"].as_bool().unwrap_or(false);
    row.light_created = e["light_created"].as_bool().unwrap_or(false);
    row.relative_residual = e["relative_residual"].as_f64().unwrap_or(0.0);
}

/// A row as one log line.
fn row_line(r: &ScaleRow) -> String {
    if r.status != "ok" {
        return format!("  {}: {} ({:.1} s)", r.scene, r.status, r.wall_s);
    }
    format!(
        "  {}: {} patches, {} elements, {} links ({} cluster), {:.1} links per element{}, {:.1} s wall, {:.0} MB peak, not gathered {:.2} % of emitted{}",
        r.scene,
        r.patches,
        r.elements,
        r.links,
        r.cluster_links,
        r.links_per_element,
        if r.budget_hit { " (link budget hit)" } else { "" },
        r.wall_s,
        r.peak_rss_bytes as f64 / 1e6,
        100.0 * share(r.not_gathered, r.emitted),
        if r.light_created { ", LIGHT CREATED" } else { "" }
    )
}

fn share(part: f64, whole: f64) -> f64 {
    if whole > 0.0 { part / whole } else { 0.0 }
}

/// The rows as a Markdown table.
#[must_use]
pub fn markdown(rows: &[ScaleRow], config: &ScaleConfig) -> String {
    let mut s = format!(
        "`radlab bench --scale`, preset `{}`, {} thread(s){}: each row one `radlab solve` in a process of its own (wall time from start to exit, generation included; peak memory its own). Energy as channel means; \"not gathered\" is the power no front face gathers (back faces, rows' shortfall, and in an open scene what leaves it).\n\n",
        config.preset,
        config.threads.map_or_else(|| "all".to_string(), |t| t.to_string()),
        config.budget_s.map_or_else(String::new, |b| format!(", time budget {b} s a solve"))
    );
    s.push_str("| scene | patches | elements | links | cluster links | links per element | solve (s) | wall (s) | peak memory | emitted | absorbed | absorbed by back faces | not gathered | light created | residual |\n");
    s.push_str("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|\n");
    for r in rows {
        let name = r.scene.trim_start_matches("builtin:");
        if r.status != "ok" {
            s.push_str(&format!("| `{name}` | {} | | | | | | {:.1} | | | | | | | |\n", r.status, r.wall_s));
            continue;
        }
        let budget = match (r.budget_hit, r.cancelled) {
            (_, true) => " (time budget)",
            (true, false) => " (link budget)",
            _ => "",
        };
        s.push_str(&format!(
            "| `{name}` | {} | {} | {} | {} | {:.1}{budget} | {:.1} | {:.1} | {:.0} MB | {:.4} | {:.4} | {:.2} % | {:.2} % | {} | {:.1e} |\n",
            r.patches,
            r.elements,
            r.links,
            r.cluster_links,
            r.links_per_element,
            r.solve_s,
            r.wall_s,
            r.peak_rss_bytes as f64 / 1e6,
            r.emitted,
            r.absorbed,
            100.0 * share(r.absorbed_by_back_faces, r.emitted),
            100.0 * share(r.not_gathered, r.emitted),
            if r.light_created { "**yes**" } else { "no" },
            r.relative_residual
        ));
    }
    s
}

/// The study's scratch folder (the children's JSON), removed when dropped.
pub struct Scratch(pub PathBuf);

impl Scratch {
    pub fn new() -> anyhow::Result<Scratch> {
        let dir = std::env::temp_dir().join(format!("radlab-bench-scale-{}", std::process::id()));
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        Ok(Scratch(dir))
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
