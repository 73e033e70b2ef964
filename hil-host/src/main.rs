//! `hil-host` command-line interface (see `hil_host::cli`).
fn main() -> std::process::ExitCode {
    hil_host::cli::main()
}
