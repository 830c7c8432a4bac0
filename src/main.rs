//! `radlab` — the command line: `view` (default), `solve`, `form-factor`, `scenes`, `figures`, `reference`, `bench`, `speed`, `mesh`.

mod cli;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // One line: the outermost context and its causes, joined.
            eprintln!("radlab: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
