//! Instruction counts of the card under QEMU (`-icount shift=0` + SysTick, calibrated
//! against a counted loop): every law, the full joint pipeline, one whole card tick and one
//! configuration build, on a Cortex-M4F (mps2-an386) and a Cortex-M0 (microbit). Prints the
//! table the README quotes. `cargo bench -p firmware --bench insn` (CI prints the same
//! table from `tests/insn_table.rs`, which needs no release build of the host crates).

use firmware::host;

fn main() {
    if host::skip_without_qemu("instruction-count bench") {
        return;
    }
    match host::instruction_table() {
        Ok(t) => print!("{}", host::format_table(&t)),
        Err(e) => {
            eprintln!("insn bench failed: {e}");
            std::process::exit(1);
        }
    }
}
