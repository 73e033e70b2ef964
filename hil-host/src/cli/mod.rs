//! The `hil-host` command line: one subcommand enum, one module per command group.
//!
//! To add a command group (e.g. the HIL commands `demo/run/card/plant/supervise/replay`),
//! add a module here with its `Args` structs and a `run`, then one variant per command in
//! [`Command`] and one arm in [`run`]. Nothing in the workbench modules needs to change.

use clap::{Parser, Subcommand};

pub mod workbench;

/// jointlab host: HIL lab and model-vs-measurement workbench.
#[derive(Debug, Parser)]
#[command(name = "hil-host", version, about, long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// All subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Compare a model with a recording: fit %, RMS, noise floor, where the error lives, plots, HTML.
    #[command(after_help = workbench::COMPARE_EXAMPLES)]
    Compare(workbench::CompareArgs),
    /// Rank the library effects the model is missing (statistical tests, Holm), or `--auto` add them.
    #[command(after_help = workbench::DIAGNOSE_EXAMPLES)]
    Diagnose(workbench::DiagnoseArgs),
    /// Add an effect, refit all free parameters (±1σ), report the error before/after, write the model.
    #[command(after_help = workbench::FIT_EXAMPLES)]
    Fit(workbench::FitArgs),
}

/// Parse the command line and run; the process exit code.
pub fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::from(2)
        }
    }
}

/// Run a parsed command.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Compare(a) => workbench::compare(a),
        Command::Diagnose(a) => workbench::diagnose(a),
        Command::Fit(a) => workbench::fit(a),
    }
}
