//! Hidden-effect trial bench: ≥ 200 trials per family (default), confusion matrix, hit rates,
//! null false-alarm rate, refit-to-noise-floor rate, pair (`--auto`) rate.
//!
//! ```sh
//! cargo run --release -p jointlab-tests --bin hidden-trials -- [TRIALS_PER_FAMILY] [SEED]
//!     [--family a,b | --pairs-only | --nulls-only] [--fails] [--load-encoder]
//! cargo run --release -p jointlab-tests --bin hidden-trials -- one FAMILY SEED RHO
//! ```
//! (`--help` lists the options.) The quick-iteration filters keep every trial's seed as in a
//! full run. Trials alternate target strengths ρ ∈ {0.5, 1, 2, 4}; rates are reported per
//! measured-ρ bin. `--load-encoder` records a load-side encoder too and passes it to the
//! workbench (see `TrialOptions::load_encoder`; same seeds, draws and floors).

use std::collections::BTreeMap;
use std::time::Instant;

use clap::{Args, Parser, Subcommand};
use jointlab_tests::hidden::{run_with, Family, Outcome, TrialOptions};

/// Hidden-effect trials of the workbench: confusion matrix, hit rates per strength bin, null
/// false-alarm rate, refit-to-floor rate, `--auto` pairs.
#[derive(Parser)]
#[command(args_conflicts_with_subcommands = true)]
struct Cli {
    #[command(subcommand)]
    one: Option<One>,
    #[command(flatten)]
    bench: Bench,
}

#[derive(Args)]
struct Bench {
    /// Trials per single-effect family (and null trials; half as many pairs).
    #[arg(default_value_t = 200)]
    trials: usize,
    /// Seed of the whole run (each trial's seed derives from it, family and index).
    #[arg(default_value_t = 1)]
    seed: u64,
    /// Run only these single-effect families (comma-separated; no nulls, no pairs).
    #[arg(long, value_delimiter = ',', conflicts_with_all = ["pairs_only", "nulls_only"])]
    family: Option<Vec<String>>,
    /// Run only the `--auto` pairs.
    #[arg(long, conflicts_with = "nulls_only")]
    pairs_only: bool,
    /// Run only the null trials.
    #[arg(long)]
    nulls_only: bool,
    /// List (on stderr) the single-effect trials at ρ ≥ 1 that missed rank 1 or the refit bound.
    #[arg(long)]
    fails: bool,
    /// Record a load-side encoder too and pass it to the workbench.
    #[arg(long)]
    load_encoder: bool,
}

#[derive(Subcommand)]
enum One {
    /// Run and print one trial (replay a miss from `--fails`; `HIDDEN_DEBUG=1` for detail).
    One {
        /// Hidden effect(s), `+`-separated (e.g. `gravity+asymmetry`).
        families: String,
        /// The trial's seed (as `--fails` prints it).
        seed: u64,
        /// Target strength ρ.
        rho: f64,
        /// Record a load-side encoder too.
        #[arg(long)]
        load_encoder: bool,
    },
}

fn main() {
    let cli = Cli::parse();
    if let Some(One::One {
        families,
        seed,
        rho,
        load_encoder,
    }) = cli.one
    {
        let fam: Vec<Family> = Family::ALL
            .iter()
            .copied()
            .filter(|f| families.split('+').any(|n| n == f.name()))
            .collect();
        if fam.is_empty() {
            let names: Vec<&str> = Family::ALL.iter().map(|f| f.name()).collect();
            eprintln!("no family in {families:?}; known: {}", names.join(", "));
            std::process::exit(2);
        }
        match run_with(seed, &fam, rho, TrialOptions { load_encoder }) {
            None => println!(
                "unstable: the drawn loop diverges with the effect or on its effect-free twin \
                 (the bench skips such a draw)"
            ),
            Some(o) => {
                let names: Vec<&str> = o.families.iter().map(|f| f.name()).collect();
                println!("hidden:     {}", names.join(" + "));
                println!("measured ρ: {:.3} (target {rho})", o.rho);
                println!("rank 1:     {}", o.top.as_deref().unwrap_or("(none)"));
                println!(
                    "verdict:    {}",
                    o.verdict
                        .as_deref()
                        .unwrap_or("no significant missing effect")
                );
                if o.families.len() == 1 {
                    println!(
                        "refit:      validation RMS {:.3}× the noise floor after fit --add {} \
                         (bar 1.1)",
                        o.val_ratio,
                        names.join("")
                    );
                }
                if o.families.len() == 2 {
                    println!("--auto added: {}", o.auto_added.join(", "));
                }
            }
        }
        return;
    }
    let Bench {
        trials,
        seed: seed0,
        family: only,
        pairs_only,
        nulls_only,
        fails: show_fails,
        load_encoder,
    } = cli.bench;
    if let Some(names) = &only {
        for n in names {
            if !Family::ALL.iter().any(|f| f.name() == n) {
                eprintln!("--family: unknown family {n:?}");
                std::process::exit(2);
            }
        }
    }
    let singles = !pairs_only && !nulls_only;
    let with_nulls = only.is_none() && !pairs_only;
    let with_pairs = only.is_none() && !nulls_only;
    let opts = TrialOptions { load_encoder };
    let rhos = [0.5, 1.0, 2.0, 4.0];
    let t0 = Instant::now();
    let pair_fams = [
        (Family::Coulomb, Family::Offset),
        (Family::Coulomb, Family::Ripple),
        (Family::Gravity, Family::Asymmetry),
        (Family::Offset, Family::Delay),
        (Family::Asymmetry, Family::Ripple),
    ];
    // Jobs: (group 0 = single, 1 = null, 2 = pair; seed; families; target ρ)
    let mut jobs: Vec<(u8, u64, Vec<Family>, f64)> = Vec::new();
    for (fi, f) in Family::ALL.iter().enumerate() {
        if !singles
            || only
                .as_ref()
                .is_some_and(|o| !o.iter().any(|n| n == f.name()))
        {
            continue;
        }
        for i in 0..trials {
            jobs.push((
                0,
                seed0 * 1_000_003 + (fi as u64) * 100_000 + i as u64,
                vec![*f],
                rhos[i % rhos.len()],
            ));
        }
    }
    for i in 0..if with_nulls { trials } else { 0 } {
        jobs.push((1, seed0 * 7_000_003 + i as u64, vec![], 1.0));
    }
    for i in 0..if with_pairs { trials / 2 } else { 0 } {
        let (a, b) = pair_fams[i % pair_fams.len()];
        jobs.push((2, seed0 * 9_000_011 + i as u64, vec![a, b], 2.0));
    }
    let workers = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results: Vec<(usize, Option<Outcome>)> = std::thread::scope(|sc| {
        let hs: Vec<_> = (0..workers)
            .map(|_| {
                sc.spawn(|| {
                    let mut out = Vec::new();
                    loop {
                        let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        if k >= jobs.len() {
                            break;
                        }
                        let (_, seed, fams, rho) = &jobs[k];
                        out.push((k, run_with(*seed, fams, *rho, opts)));
                        if k.is_multiple_of(50) {
                            eprintln!(
                                "{k}/{} trials ({:.0} s)",
                                jobs.len(),
                                t0.elapsed().as_secs_f64()
                            );
                        }
                    }
                    out
                })
            })
            .collect();
        hs.into_iter()
            .flat_map(|h| h.join().expect("worker"))
            .collect()
    });
    let mut all: Vec<Outcome> = Vec::new();
    let mut nulls = Vec::new();
    let mut pairs = Vec::new();
    let mut unstable = 0usize;
    let mut sorted = results;
    sorted.sort_by_key(|(k, _)| *k);
    let list = std::env::var_os("HIDDEN_LIST").is_some();
    for (k, o) in sorted {
        if list {
            // One line per trial (`HIDDEN_LIST=1`): the seed and ρ to re-run it with `one`.
            if let Some(o) = &o {
                let (_, seed, fams, rho) = &jobs[k];
                let names: Vec<&str> = fams.iter().map(|f| f.name()).collect();
                println!(
                    "trial {} {seed} {rho}: ρ {:.2} top {:?} val/floor {:.3}",
                    names.join("+"),
                    o.rho,
                    o.top,
                    o.val_ratio
                );
            }
        }
        match (jobs[k].0, o) {
            (_, None) => unstable += 1,
            (0, Some(o)) => {
                if show_fails
                    && o.rho >= 1.0
                    && (!o.rank1_ok() || o.val_ratio.is_nan() || o.val_ratio > 1.1)
                {
                    eprintln!(
                        "fail: {} seed {} target ρ {} (measured {:.2}): rank 1 {:?}, val/floor {:.3}",
                        o.families[0].name(),
                        jobs[k].1,
                        jobs[k].3,
                        o.rho,
                        o.top,
                        o.val_ratio
                    );
                }
                all.push(o)
            }
            (1, Some(o)) => nulls.push(o),
            (_, Some(o)) => pairs.push(o),
        }
    }

    // Confusion matrix: rows = hidden family, columns = rank-1 candidate.
    let names: Vec<&str> = Family::ALL.iter().map(|f| f.name()).collect();
    let mut cols: Vec<String> = names.iter().map(|s| s.to_string()).collect();
    for o in &all {
        if let Some(t) = &o.top {
            if !cols.contains(t) {
                cols.push(t.clone());
            }
        }
    }
    println!("\nconfusion matrix, measured ρ ≥ 1 (rows: hidden effect, columns: rank-1 candidate)");
    print!("{:<13}", "");
    for c in &cols {
        print!("{:>7}", &c[..c.len().min(6)]);
    }
    println!();
    for f in Family::ALL {
        print!("{:<13}", f.name());
        for c in &cols {
            let n = all
                .iter()
                .filter(|o| {
                    o.families[0] == f && o.rho >= 1.0 && o.top.as_deref() == Some(c.as_str())
                })
                .count();
            print!("{:>7}", n);
        }
        println!();
    }
    println!(
        "\n{:<13} {:>14} {:>16} {:>16} {:>18}",
        "family", "rank1 ρ≥1", "rank1 0.5≤ρ<1", "verdict ρ≥1", "val≤1.1·floor ρ≥1"
    );
    let mut summary = BTreeMap::new();
    for f in Family::ALL {
        let hi: Vec<&Outcome> = all
            .iter()
            .filter(|o| o.families[0] == f && o.rho >= 1.0)
            .collect();
        let mid: Vec<&Outcome> = all
            .iter()
            .filter(|o| o.families[0] == f && o.rho >= 0.5 && o.rho < 1.0)
            .collect();
        let rate = |v: &[&Outcome], p: &dyn Fn(&Outcome) -> bool| -> String {
            if v.is_empty() {
                "–".into()
            } else {
                format!(
                    "{:.1}% ({}/{})",
                    100.0 * v.iter().filter(|o| p(o)).count() as f64 / v.len() as f64,
                    v.iter().filter(|o| p(o)).count(),
                    v.len()
                )
            }
        };
        let r1 = rate(&hi, &|o| o.rank1_ok());
        println!(
            "{:<13} {:>14} {:>16} {:>16} {:>18}",
            f.name(),
            r1,
            rate(&mid, &|o| o.rank1_ok()),
            rate(&hi, &|o| o.verdict.as_deref() == Some(o.families[0].name())),
            rate(&hi, &|o| o.val_ratio <= 1.1)
        );
        summary.insert(f.name(), r1);
    }
    // How far the refits miss: quartiles of validation RMS / floor at ρ ≥ 1.
    println!("\nvalidation RMS / floor after fit --add, ρ ≥ 1: quartiles (25 / 50 / 75 / 95 %)");
    for f in Family::ALL {
        let mut v: Vec<f64> = all
            .iter()
            .filter(|o| o.families[0] == f && o.rho >= 1.0 && o.val_ratio.is_finite())
            .map(|o| o.val_ratio)
            .collect();
        if v.is_empty() {
            continue;
        }
        v.sort_by(f64::total_cmp);
        let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
        println!(
            "{:<13} {:>6.3} {:>6.3} {:>6.3} {:>6.3}",
            f.name(),
            q(0.25),
            q(0.5),
            q(0.75),
            q(0.95)
        );
    }
    let fa = nulls.iter().filter(|o| !o.null_ok()).count();
    println!(
        "\nnull trials: {} of {} flagged a missing effect (false-alarm rate {:.1} %)",
        fa,
        nulls.len(),
        100.0 * fa as f64 / nulls.len().max(1) as f64
    );
    let mut fa_by: BTreeMap<String, usize> = BTreeMap::new();
    for o in nulls.iter().filter(|o| !o.null_ok()) {
        *fa_by
            .entry(o.verdict.clone().unwrap_or_default())
            .or_default() += 1;
    }
    if !fa_by.is_empty() {
        println!("  false alarms by effect: {fa_by:?}");
    }
    let pok = pairs.iter().filter(|o| o.pair_ok()).count();
    println!(
        "pairs (--auto, ρ≈2 each): both found in {} of {} ({:.1} %)",
        pok,
        pairs.len(),
        100.0 * pok as f64 / pairs.len().max(1) as f64
    );
    for o in pairs.iter().filter(|o| !o.pair_ok()).take(10) {
        println!(
            "  missed: hidden {:?}, added {:?}",
            o.families.iter().map(|f| f.name()).collect::<Vec<_>>(),
            o.auto_added
        );
    }
    println!("unstable (skipped) trials: {unstable}");
    println!(
        "trials per family: {trials}; workers: {workers}; load encoder: {}",
        if opts.load_encoder { "yes" } else { "no" }
    );
    println!("total {:.1} s", t0.elapsed().as_secs_f64());
}
