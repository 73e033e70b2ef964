//! The `hil-host` command line: one subcommand enum, one module per command group.

use clap::{Parser, Subcommand};

pub mod lab;

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
    /// Zero-setup HIL demo: card + plant + supervisor on the in-process bus, summary, CSV, PNG.
    #[command(after_help = lab::DEMO_EXAMPLES)]
    Demo(lab::DemoArgs),
    /// Card, plant and supervisor as threads over a bus (vcan0, can0 or inproc).
    #[command(after_help = lab::RUN_EXAMPLES)]
    Run(lab::RunArgs),
    /// The card node alone on a bus (the controller crate, fed only by frames).
    #[command(after_help = lab::CARD_EXAMPLES)]
    Card(lab::CardArgs),
    /// The plant node alone on a bus (a thesis preset or a model file), recording.
    #[command(after_help = lab::PLANT_EXAMPLES)]
    Plant(lab::PlantArgs),
    /// The supervisor alone on a bus: gains in SI, arming, setpoint streams, live telemetry.
    #[command(after_help = lab::SUPERVISE_EXAMPLES)]
    Supervise(lab::SuperviseArgs),
    /// Decode a candump -L log, or put it back on a bus.
    #[command(after_help = lab::REPLAY_EXAMPLES)]
    Replay(lab::ReplayArgs),
    /// Lockstep cycles per second and bus load.
    #[command(after_help = lab::BENCH_EXAMPLES)]
    Bench(lab::BenchArgs),
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
        Command::Demo(a) => lab::demo(a),
        Command::Run(a) => lab::run(a),
        Command::Card(a) => lab::card(a),
        Command::Plant(a) => lab::plant(a),
        Command::Supervise(a) => lab::supervise(a),
        Command::Replay(a) => lab::replay(a),
        Command::Bench(a) => lab::bench(a),
    }
}
