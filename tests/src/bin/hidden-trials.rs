//! Hidden-effect trial bench: per truth and per logging convention, the rank-1 confusion
//! matrix, rank-1 rates per strength bin, null false alarms, the refit to the referee's floor,
//! `--auto` pairs — each truth and convention reported on its own, never pooled.
//!
//! ```sh
//! cargo run --release -p jointlab-tests --bin hidden-trials -- [TRIALS_PER_FAMILY] [--seed S]
//!     [--truth rk4,physicist] [--logging zoh,mid] [--family a,b | --nulls-only | --pairs-only]
//!     [--state FILE] [--fails]
//! cargo run --release -p jointlab-tests --bin hidden-trials -- one TRUTH FAMILIES SEED RHO [--logging mid]
//! ```
//! Trials run in parallel and each finished one is appended to the state file (JSON lines):
//! an interrupted run resumes where it stopped, and a finished one reprints its report.
//! Targets alternate ρ ∈ {0.5, 1, 2, 4}; rates are per measured-ρ bin. A workbench error or
//! panic counts as a failed trial; a draw whose truth diverges does not count (listed).

use std::collections::{BTreeMap, BTreeSet};
use std::io::{BufRead, Write};
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

use clap::{Args, Parser, Subcommand};
use jointlab_tests::hidden::{self, refit_bar, Family, Logging, Outcome, Skip, INDISTINCT, PAIRS};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Hidden-effect trials of the workbench on every truth.
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
    #[arg(default_value_t = 100)]
    trials: usize,
    /// Seed of the whole run (each trial's seed derives from it, family and index).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Truths to run (comma-separated; default all).
    #[arg(long, value_delimiter = ',')]
    truth: Option<Vec<String>>,
    /// Logging conventions (zoh, mid; default both).
    #[arg(long, value_delimiter = ',')]
    logging: Option<Vec<String>>,
    /// Run only these single-effect families (comma-separated; no nulls, no pairs).
    #[arg(long, value_delimiter = ',', conflicts_with_all = ["pairs_only", "nulls_only"])]
    family: Option<Vec<String>>,
    /// Run only the `--auto` pairs.
    #[arg(long, conflicts_with = "nulls_only")]
    pairs_only: bool,
    /// Run only the null trials.
    #[arg(long)]
    nulls_only: bool,
    /// State file (JSON lines) that makes the run resumable (default
    /// `target/hidden-trials-seed<S>.jsonl`).
    #[arg(long)]
    state: Option<PathBuf>,
    /// List the failed trials (on stderr) with their conditions.
    #[arg(long)]
    fails: bool,
    /// Only report what the state file holds (run nothing).
    #[arg(long)]
    report_only: bool,
}

#[derive(Subcommand)]
enum One {
    /// Run and print one trial (`HIDDEN_DEBUG=1` for detail; `HIDDEN_DUMP=FILE.csv` writes
    /// its estimation record there and its validation record to FILE.val.csv, CSVs for
    /// `hil-host diagnose`).
    One {
        /// Truth's name.
        truth: String,
        /// Hidden effect(s), `+`-separated (`none` for a null trial).
        families: String,
        /// The trial's seed.
        seed: u64,
        /// Target strength ρ.
        rho: f64,
        /// Logging convention.
        #[arg(long, default_value = "zoh")]
        logging: String,
    },
}

/// One job of the bench.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
struct Job {
    truth: String,
    logging: String,
    families: Vec<String>,
    seed: u64,
    /// Target ρ × 1000 (an integer key).
    target_milli: u32,
}

/// A finished job as the state file holds it.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Done {
    job: Job,
    outcome: Option<Outcome>,
    skipped: Option<String>,
}

fn logging_of(name: &str) -> Option<Logging> {
    Logging::ALL.into_iter().find(|l| l.name() == name)
}

fn families_of(spec: &str) -> Option<Vec<Family>> {
    if spec == "none" {
        return Some(Vec::new());
    }
    spec.split('+').map(Family::from_name).collect()
}

fn fail(msg: String) -> ! {
    eprintln!("{msg}");
    std::process::exit(2);
}

fn run_job(job: &Job) -> Done {
    let truth = hidden::truth(&job.truth).expect("job truth exists");
    let logging = logging_of(&job.logging).expect("job logging exists");
    let fams: Vec<Family> = job
        .families
        .iter()
        .map(|n| Family::from_name(n).expect("job family exists"))
        .collect();
    let rho = f64::from(job.target_milli) / 1000.0;
    match hidden::run(truth.as_ref(), job.seed, &fams, rho, logging) {
        Ok(o) => Done {
            job: job.clone(),
            outcome: Some(o),
            skipped: None,
        },
        Err(s) => Done {
            job: job.clone(),
            outcome: None,
            skipped: Some(match s {
                Skip::Diverged(why) => format!("diverged: {why}"),
                Skip::Strength(r) => format!("strength ρ = {r:.3} far from its target"),
                Skip::Stuck(c) => format!("stuck: the joint moved {c:.0} counts"),
            }),
        },
    }
}

fn main() {
    let cli = Cli::parse();
    if let Some(One::One {
        truth,
        families,
        seed,
        rho,
        logging,
    }) = cli.one
    {
        let t = hidden::truth(&truth).unwrap_or_else(|| fail(format!("unknown truth {truth:?}")));
        let fams = families_of(&families)
            .unwrap_or_else(|| fail(format!("unknown family in {families:?}")));
        let lg =
            logging_of(&logging).unwrap_or_else(|| fail(format!("unknown logging {logging:?}")));
        match hidden::run(t.as_ref(), seed, &fams, rho, lg) {
            Err(s) => println!("does not count: {s:?}"),
            Ok(o) => println!("{}", serde_json::to_string_pretty(&o).unwrap_or_default()),
        }
        return;
    }
    let b = cli.bench;
    let all_truths: Vec<String> = hidden::truths()
        .iter()
        .map(|t| t.name().to_string())
        .collect();
    let truths = b.truth.clone().unwrap_or(all_truths.clone());
    for t in &truths {
        if !all_truths.contains(t) {
            fail(format!(
                "--truth: unknown {t:?} (have {})",
                all_truths.join(", ")
            ));
        }
    }
    let loggings: Vec<String> = b
        .logging
        .clone()
        .unwrap_or(Logging::ALL.iter().map(|l| l.name().to_string()).collect());
    for l in &loggings {
        if logging_of(l).is_none() {
            fail(format!("--logging: unknown {l:?} (zoh, mid)"));
        }
    }
    if let Some(names) = &b.family {
        for n in names {
            if Family::from_name(n).is_none() {
                fail(format!("--family: unknown family {n:?}"));
            }
        }
    }
    let singles = !b.pairs_only && !b.nulls_only;
    let with_nulls = b.family.is_none() && !b.pairs_only;
    let with_pairs = b.family.is_none() && !b.nulls_only;
    let rhos = [500u32, 1000, 2000, 4000];
    let mut jobs: Vec<Job> = Vec::new();
    for truth in &truths {
        let t = hidden::truth(truth).expect("checked");
        for lg in t.loggings() {
            if !loggings.iter().any(|l| l == lg.name()) {
                continue;
            }
            let job = |families: Vec<String>, seed: u64, target_milli: u32| Job {
                truth: truth.clone(),
                logging: lg.name().to_string(),
                families,
                seed,
                target_milli,
            };
            for (fi, f) in Family::ALL.iter().enumerate() {
                if !singles
                    || b.family
                        .as_ref()
                        .is_some_and(|o| !o.iter().any(|n| n == f.name()))
                {
                    continue;
                }
                for i in 0..b.trials {
                    let seed = b.seed * 1_000_003 + (fi as u64) * 100_000 + i as u64;
                    jobs.push(job(vec![f.name().into()], seed, rhos[i % rhos.len()]));
                }
            }
            for i in 0..if with_nulls { b.trials } else { 0 } {
                jobs.push(job(Vec::new(), b.seed * 7_000_003 + i as u64, 1000));
            }
            for i in 0..if with_pairs { b.trials / 2 } else { 0 } {
                let (x, y) = PAIRS[i % PAIRS.len()];
                let names = vec![x.name().into(), y.name().into()];
                jobs.push(job(names, b.seed * 9_000_011 + i as u64, 2000));
            }
        }
    }
    let state = b
        .state
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("target/hidden-trials-seed{}.jsonl", b.seed)));
    let mut done: BTreeMap<Job, Done> = BTreeMap::new();
    if let Ok(f) = std::fs::File::open(&state) {
        for line in std::io::BufReader::new(f).lines().map_while(Result::ok) {
            if let Ok(d) = serde_json::from_str::<Done>(&line) {
                done.insert(d.job.clone(), d);
            }
        }
    }
    let todo: Vec<&Job> = if b.report_only {
        Vec::new()
    } else {
        jobs.iter().filter(|j| !done.contains_key(j)).collect()
    };
    eprintln!(
        "{} trials, {} already in {} — running {}",
        jobs.len(),
        jobs.iter().filter(|j| done.contains_key(j)).count(),
        state.display(),
        todo.len()
    );
    if let Some(dir) = state.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).unwrap_or_else(|e| fail(format!("{}: {e}", dir.display())));
    }
    let file = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&state)
        .unwrap_or_else(|e| fail(format!("{}: {e}", state.display())));
    let file = Mutex::new(file);
    let t0 = Instant::now();
    let count = std::sync::atomic::AtomicUsize::new(0);
    let new: Vec<Done> = todo
        .par_iter()
        .map(|j| {
            let d = run_job(j);
            if let Ok(line) = serde_json::to_string(&d) {
                if let Ok(mut f) = file.lock() {
                    let _ = writeln!(f, "{line}");
                    let _ = f.flush();
                }
            }
            let k = count.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            if k.is_multiple_of(25) {
                eprintln!("{k}/{} ({:.0} s)", todo.len(), t0.elapsed().as_secs_f64());
            }
            d
        })
        .collect();
    for d in new {
        done.insert(d.job.clone(), d);
    }
    let wanted: BTreeSet<&Job> = jobs.iter().collect();
    let results: Vec<&Done> = done.values().filter(|d| wanted.contains(&d.job)).collect();
    report(&results, b.fails);
    println!("elapsed {:.0} s this run", t0.elapsed().as_secs_f64());
}

fn pct(k: usize, n: usize) -> String {
    if n == 0 {
        "—".into()
    } else {
        format!("{:5.1} % ({k}/{n})", 100.0 * k as f64 / n as f64)
    }
}

fn describe(o: &Outcome) -> String {
    format!(
        "seed {} ρ {:.2}{}{}{} {} Hz 2^{} {} — top {:?} verdict {:?} val/floor {:.3?}{}{}",
        o.seed,
        o.rho,
        o.rho_beyond_offset
            .map_or(String::new(), |r| format!(" (beyond an offset {r:.2})")),
        o.rho_beyond_spring
            .map_or(String::new(), |r| format!(" (beyond a spring {r:.2})")),
        o.base_val
            .filter(|b| *b > 0.0)
            .map_or(String::new(), |b| format!(" (base joint on val {b:.2})")),
        o.rate_hz,
        o.encoder_bits,
        o.excitation,
        o.top,
        o.verdict,
        o.val_ratio,
        if o.auto_added.is_empty() {
            String::new()
        } else {
            format!(" auto {:?}", o.auto_added)
        },
        o.error
            .as_ref()
            .map(|e| format!(" ERROR {e}"))
            .unwrap_or_default()
    )
}

fn report(results: &[&Done], fails: bool) {
    let mut groups: BTreeMap<(String, String), Vec<&Done>> = BTreeMap::new();
    for d in results {
        groups
            .entry((d.job.truth.clone(), d.job.logging.clone()))
            .or_default()
            .push(d);
    }
    let names: Vec<&str> = Family::ALL.iter().map(|f| f.name()).collect();
    for ((truth, logging), ds) in &groups {
        println!("\n=== truth {truth}, logging {logging} ===");
        let outs: Vec<&Outcome> = ds.iter().filter_map(|d| d.outcome.as_ref()).collect();
        let skipped: Vec<&&Done> = ds.iter().filter(|d| d.outcome.is_none()).collect();
        let singles: Vec<&&Outcome> = outs.iter().filter(|o| o.families.len() == 1).collect();
        let nulls: Vec<&&Outcome> = outs.iter().filter(|o| o.families.is_empty()).collect();
        let pairs: Vec<&&Outcome> = outs.iter().filter(|o| o.families.len() == 2).collect();
        let errors = outs.iter().filter(|o| o.error.is_some()).count();
        println!(
            "counted {} trials ({} single, {} null, {} pair); workbench errors {errors}; not counted (truth diverged / strength) {}",
            outs.len(),
            singles.len(),
            nulls.len(),
            pairs.len(),
            skipped.len()
        );
        if !singles.is_empty() {
            // Rank-1 confusion at ρ ≥ 1: rows hidden, columns the rank-1 candidate.
            let mut cols: BTreeSet<String> = names.iter().map(|s| s.to_string()).collect();
            for o in &singles {
                cols.insert(o.top.clone().unwrap_or_else(|| "(none)".into()));
            }
            let cols: Vec<String> = cols.into_iter().collect();
            println!("rank-1 confusion at ρ ≥ 1 (rows hidden, columns rank 1):");
            print!("{:>13}", "");
            for c in &cols {
                print!(" {:>5}", &c[..c.len().min(5)]);
            }
            println!();
            for f in &names {
                print!("{f:>13}");
                for c in &cols {
                    let k = singles
                        .iter()
                        .filter(|o| o.families[0] == *f && o.rho >= 1.0)
                        .filter(|o| o.top.as_deref().unwrap_or("(none)") == c)
                        .count();
                    print!(" {k:>5}");
                }
                println!();
            }
            println!(
                "{:>13}  {:>18} {:>18} {:>18} {:>18}",
                "family", "rank 1 ρ≥1", "rank 1 0.5≤ρ<1", "verdict ρ≥1", "refit ≤ bar, judged"
            );
            let (mut a1, mut n1, mut a2, mut n2, mut rf, mut nf) = (0, 0, 0, 0, 0, 0);
            for f in &names {
                let of: Vec<&&&Outcome> = singles.iter().filter(|o| o.families[0] == *f).collect();
                let hi: Vec<_> = of.iter().filter(|o| o.rho >= 1.0).collect();
                let mid: Vec<_> = of.iter().filter(|o| o.rho >= 0.5 && o.rho < 1.0).collect();
                let r1 = hi.iter().filter(|o| o.rank1_ok()).count();
                let r2 = mid.iter().filter(|o| o.rank1_ok()).count();
                let vd = hi.iter().filter(|o| o.verdict_ok()).count();
                let judged: Vec<_> = of
                    .iter()
                    .filter(|o| o.refit_judgeable(refit_bar(f)))
                    .collect();
                let fit = judged.iter().filter(|o| o.refit_ok(refit_bar(f))).count();
                (a1, n1, a2, n2, rf, nf) = (
                    a1 + r1,
                    n1 + hi.len(),
                    a2 + r2,
                    n2 + mid.len(),
                    rf + fit,
                    nf + judged.len(),
                );
                println!(
                    "{f:>13}  {:>18} {:>18} {:>18} {:>18}",
                    pct(r1, hi.len()),
                    pct(r2, mid.len()),
                    pct(vd, hi.len()),
                    pct(fit, judged.len())
                );
            }
            println!(
                "{:>13}  {:>18} {:>18} {:>18} {:>18}",
                "all",
                pct(a1, n1),
                pct(a2, n2),
                "",
                pct(rf, nf)
            );
            // How many of those passes name a simpler effect the truth says stands in.
            let stand_ins: BTreeMap<&str, usize> = singles
                .iter()
                .filter(|o| o.rho >= 0.5 && o.stands_in(o.top.as_deref()))
                .fold(BTreeMap::new(), |mut m, o| {
                    *m.entry(o.families[0].as_str()).or_default() += 1;
                    m
                });
            if !stand_ins.is_empty() {
                let list: Vec<String> = stand_ins.iter().map(|(f, k)| format!("{f} {k}")).collect();
                println!(
                    "rank 1 a stand-in the truth allows at ρ ≥ 0.5 (offset for gravity, spring for a gap, beyond-simpler ρ < {INDISTINCT}): {}",
                    list.join(", ")
                );
            }
            // Refits judged against a floor the base joint raised (what the start model
            // leaves of the joint without the effect, on the validation record).
            let raised = singles
                .iter()
                .filter(|o| o.base_val.is_some_and(|b| b >= INDISTINCT))
                .count();
            let unjudged = singles
                .iter()
                .filter(|o| !o.refit_judgeable(refit_bar(&o.families[0])))
                .count();
            if unjudged > 0 {
                println!(
                    "refits not counted (the start model alone would pass the bar, by the truth): {unjudged}/{}",
                    singles.len()
                );
            }
            let unphysical = singles
                .iter()
                .filter(|o| o.refit_unphysical.is_some())
                .count();
            if unphysical > 0 {
                println!(
                    "refits `fit` would not write (a parameter outside its physical range), failed: {unphysical}/{}",
                    singles.len()
                );
            }
            if raised > 0 {
                println!(
                    "refit floors raised by the base joint (≥ {INDISTINCT} floors beyond the start model): {raised}/{}",
                    singles.len()
                );
            }
            // Where the rank-1 misses at ρ ≥ 0.5 fall, by recording condition.
            let misses: Vec<&&&Outcome> = singles
                .iter()
                .filter(|o| o.rho >= 0.5 && !o.rank1_ok())
                .collect();
            if !misses.is_empty() {
                let tally = |key: &dyn Fn(&Outcome) -> String| {
                    let mut t: BTreeMap<String, (usize, usize)> = BTreeMap::new();
                    for o in singles.iter().filter(|o| o.rho >= 0.5) {
                        let e = t.entry(key(o)).or_default();
                        e.1 += 1;
                        e.0 += usize::from(!o.rank1_ok());
                    }
                    t.iter()
                        .map(|(k, (m, n))| format!("{k} {m}/{n}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                };
                println!("rank-1 misses at ρ ≥ 0.5 by condition:");
                println!("  rate: {}", tally(&|o| format!("{} Hz", o.rate_hz)));
                println!("  encoder: {}", tally(&|o| format!("2^{}", o.encoder_bits)));
                println!("  excitation: {}", tally(&|o| o.excitation.clone()));
            }
            if fails {
                for o in &singles {
                    let f = &o.families[0];
                    let miss_rank = o.rho >= 0.5 && !o.rank1_ok();
                    let miss_fit = o.refit_judgeable(refit_bar(f)) && !o.refit_ok(refit_bar(f));
                    if miss_rank || miss_fit {
                        eprintln!("[{truth}/{logging}] {f}: {}", describe(o));
                    }
                }
            }
        }
        if !nulls.is_empty() {
            let q = nulls.iter().filter(|o| o.null_ok()).count();
            println!("nulls quiet: {}", pct(q, nulls.len()));
            let mut said: BTreeMap<String, usize> = BTreeMap::new();
            for o in nulls.iter().filter(|o| !o.null_ok()) {
                *said
                    .entry(o.verdict.clone().or(o.error.clone()).unwrap_or_default())
                    .or_default() += 1;
            }
            if !said.is_empty() {
                println!("  null verdicts: {said:?}");
            }
            if fails {
                for o in nulls.iter().filter(|o| !o.null_ok()) {
                    eprintln!("[{truth}/{logging}] null: {}", describe(o));
                }
            }
        }
        if !pairs.is_empty() {
            let q = pairs.iter().filter(|o| o.pair_ok()).count();
            println!("pairs (--auto, exactly both): {}", pct(q, pairs.len()));
            if fails {
                for o in pairs.iter().filter(|o| !o.pair_ok()) {
                    eprintln!("[{truth}/{logging}] pair {:?}: {}", o.families, describe(o));
                }
            }
        }
        for d in skipped.iter().take(5) {
            println!(
                "  not counted: {:?} seed {}: {}",
                d.job.families,
                d.job.seed,
                d.skipped.as_deref().unwrap_or("")
            );
        }
    }
}
