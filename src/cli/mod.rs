//! Command-line interface. Each subcommand lives in its own file with its `Args` and `run`.

pub mod artifacts;
pub mod bench;
pub mod figures;
pub mod form_factor;
pub mod h_vs_p;
pub mod mesh;
pub mod reference;
pub mod scenes;
pub mod solve;
pub mod speed;
pub mod view;

use clap::{Parser, Subcommand};

/// radlab — a lab for hierarchical radiosity.
///
/// With no subcommand, opens the viewer on builtin:cornell.
#[derive(Parser, Debug)]
#[command(name = "radlab", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Open the interactive viewer on a scene.
    View(view::Args),
    /// Solve a scene and report statistics, energy balance, JSON and an image.
    Solve(solve::Args),
    /// Compute the form factor between two patches (or from a point).
    FormFactor(form_factor::Args),
    /// List the built-in scenes.
    Scenes(scenes::Args),
    /// The lecture's figures: list them, or write one screenshot each.
    Figures(figures::Args),
    /// Independent Monte Carlo reference solution (cached on disk).
    Reference(reference::Args),
    /// Speed-against-error report over methods and settings.
    Bench(bench::Args),
    /// Discontinuity mesh of a scene (critical segments, CDT or BSP): counts and meshing time.
    Mesh(mesh::Args),
    /// h- against p-refinement: Galerkin p = 0 / p = 1 on exact single-bounce scenes (table,
    /// slopes, log-log plot).
    HVsP(h_vs_p::Args),
    /// The five meshing artifacts (A–E) of a solution against the scene's reference: table,
    /// pictures, JSON.
    Artifacts(artifacts::Args),
    /// Hierarchical solver speed benchmark (default: the SPLASH-2 room at SPLASH-2 settings).
    Speed(speed::Args),
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        None => view::run(view::Args::default_scene()),
        Some(Command::View(a)) => view::run(a),
        Some(Command::Solve(a)) => solve::run(a),
        Some(Command::FormFactor(a)) => form_factor::run(a),
        Some(Command::Scenes(a)) => scenes::run(a),
        Some(Command::Figures(a)) => figures::run(a),
        Some(Command::Reference(a)) => reference::run(a),
        Some(Command::Bench(a)) => bench::run(a),
        Some(Command::Speed(a)) => speed::run(a),
        Some(Command::Mesh(a)) => mesh::run(a),
        Some(Command::HVsP(a)) => h_vs_p::run(a),
        Some(Command::Artifacts(a)) => artifacts::run(a),
    }
}
