//! The `hil-host` command line: one subcommand enum, one module per command group.
//!
//! To add a command group, add a module here with its `Args` structs and a `run`, then one
//! variant per command in [`Command`] and one arm in [`run`]. Nothing in the workbench modules needs to change.

use clap::{Parser, Subcommand};

pub mod console;
pub mod lab;
pub mod replay;
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
    /// Zero-setup HIL demo: card + plant + supervisor on the in-process bus, summary, CSV, PNG.
    #[command(after_help = format!("{}\n\n{}", lab::DEMO_EXAMPLES, lab::INJECT_HELP))]
    Demo(lab::DemoArgs),
    /// Card, plant and supervisor as threads over a bus (vcan0, can0 or inproc).
    #[command(after_help = format!("{}\n\n{}", lab::RUN_EXAMPLES, lab::INJECT_HELP))]
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
    /// Decode a candump -L log (signals with units), convert it to a recording, or put it back on a bus.
    #[command(after_help = replay::REPLAY_EXAMPLES)]
    Replay(replay::ReplayArgs),
    /// A card's parameters: the table, active values, a set committed atomically.
    #[command(after_help = console::PARAM_EXAMPLES)]
    Param(console::ParamArgs),
    /// A card's health: state, mode, fault, limits, frame rates and bus load.
    #[command(after_help = console::STATUS_EXAMPLES)]
    Status(console::StatusArgs),
    /// Lockstep cycles per second and bus load.
    #[command(after_help = lab::BENCH_EXAMPLES)]
    Bench(lab::BenchArgs),
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
    quiet_on_closed_stdout();
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // A run that did not end clean has printed its report; say how it ended and
            // exit with its code (1, or 130 when interrupted). Anything else is an error:
            // see `exit_code`.
            if let Some(f) = e.downcast_ref::<crate::lab::report::RunFailed>() {
                eprintln!("hil-host: the run ended {}", f.verdict.word());
                return std::process::ExitCode::from(f.verdict.exit_code());
            }
            eprintln!("error: {}", error_text(&e));
            std::process::ExitCode::from(exit_code(&e))
        }
    }
}

/// 1 for an error in what a file holds (a recording, a model file, a candump log, or a fit
/// that cannot be made on them), 2 for everything else — a usage error, as clap's own exit
/// code for a bad flag: a script can tell "fix the command" from "fix the data".
fn exit_code(e: &anyhow::Error) -> u8 {
    let data = e.chain().any(|c| {
        c.is::<jointlab_workbench::data::DataError>()
            || c.is::<jointlab_workbench::dataset::DatasetError>()
            || c.is::<jointlab_workbench::model::ModelError>()
            || c.is::<jointlab_workbench::fit::FitError>()
            || c.is::<sim_plant::model::ModelError>()
            || c.is::<jointlab_can::candump::LogError>()
    });
    if data {
        1
    } else {
        2
    }
}

/// An error and its causes on one line, each cause once: several of the library's errors
/// already name their cause in their own message (an I/O error after the file it concerns),
/// and anyhow's `{:#}` would repeat it.
fn error_text(e: &anyhow::Error) -> String {
    let mut s = e.to_string();
    for cause in e.chain().skip(1) {
        let c = cause.to_string();
        if !s.contains(&c) {
            s.push_str(": ");
            s.push_str(&c);
        }
    }
    s
}

impl Command {
    /// The plant a lab command runs (`None` for commands without one).
    fn plant(&self) -> Option<&lab::PlantChoice> {
        match self {
            Command::Demo(a) => Some(&a.plant),
            Command::Run(a) => Some(&a.sup.plant),
            Command::Plant(a) => Some(&a.plant),
            Command::Supervise(a) => Some(&a.plant),
            Command::Bench(a) => Some(&a.plant),
            _ => None,
        }
    }
}

/// Run a parsed command. `--preset list` is a question, answered here for every command
/// that takes a plant: the names on stdout, one per line, and nothing run.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    if cli
        .command
        .plant()
        .is_some_and(lab::PlantChoice::lists_presets)
    {
        for name in sim_plant::preset_names() {
            println!("{name}");
        }
        return Ok(());
    }
    match cli.command {
        Command::Demo(a) => lab::demo(a),
        Command::Run(a) => lab::run(a),
        Command::Card(a) => lab::card(a),
        Command::Plant(a) => lab::plant(a),
        Command::Supervise(a) => lab::supervise(a),
        Command::Replay(a) => replay::replay(a),
        Command::Param(a) => console::param(a),
        Command::Status(a) => console::status(a),
        Command::Bench(a) => lab::bench(a),
        Command::Compare(a) => workbench::compare(a),
        Command::Diagnose(a) => workbench::diagnose(a),
        Command::Fit(a) => workbench::fit(a),
    }
}

/// `hil-host diagnose … | head` closes stdout early; Rust ignores SIGPIPE, so the next
/// `println!` panics with "failed printing to stdout: Broken pipe". Like a C tool killed by
/// SIGPIPE, end quietly then (the demo writes its files before it prints; the workbench
/// writes a model only when asked, before its report); every other panic keeps the default
/// report.
fn quiet_on_closed_stdout() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let msg = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if msg.contains("failed printing to stdout") && msg.contains("Broken pipe") {
            std::process::exit(141); // 128 + SIGPIPE, what a shell reports for `head`
        }
        default(info);
    }));
}
