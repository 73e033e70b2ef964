//! The instruction-count table (see `benches/insn.rs`): every row measured on both cores.
//! Speed goals are not asserted here; the figures are printed (`--nocapture`) and quoted
//! in the README.

use firmware::host;

#[test]
fn instruction_counts_on_m4_and_m0() {
    if host::skip_without_qemu("instruction_counts_on_m4_and_m0") {
        return;
    }
    let table = host::instruction_table().expect("qemu-bench runs on both machines");
    print!("{}", host::format_table(&table));
    let want = [
        "Pd",
        "Pid",
        "InputDamping",
        "Impedance",
        "ForcePi",
        "Friction",
        "ImpComp",
        "Ripple",
        "Full",
        "card tick (mean)",
        "card tick (max)",
        "config::build",
        "commit (card, while enabled)",
    ];
    for w in want {
        let r = table
            .iter()
            .find(|r| r.what == w)
            .unwrap_or_else(|| panic!("row {w} missing"));
        for v in r.bench.iter().chain(&r.tracking) {
            assert!(v.is_finite() && *v > 0.0, "{w}: {v}");
        }
    }
    // The M0 has no long multiply and soft-float only: it never needs fewer instructions.
    let full = table.iter().find(|r| r.what == "Full").expect("full");
    assert!(full.bench[1] > full.bench[0], "{full:?}");
}
