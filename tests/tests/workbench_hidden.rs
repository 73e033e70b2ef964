//! Hidden-effect trials, reduced for CI: on every truth and every logging convention it
//! records, one trial per family at target ρ = 2 (rank 1 and the refit to the referee's
//! floor), three null trials (quiet), and one `--auto` pair (both found). Seeds are fixed and
//! consecutive (never picked); each group allows the misses stated in its assertion, set from
//! the bench's rates (`cargo run --release -p jointlab-tests --bin hidden-trials`,
//! docs/design/workbench-validation.md).
//!
//! Run in release for speed: `cargo test --release -p jointlab-tests --test workbench_hidden`

use jointlab_tests::hidden::{self, refit_bar, Family, Logging, Outcome, Truth, PAIRS};
use rayon::prelude::*;

/// Outcomes of `families` at ρ on consecutive seeds from `seed0`, on `truth` logged `logging`
/// (draws whose truth diverges do not count and are replaced by the next seed).
fn trials(
    truth: &dyn Truth,
    logging: Logging,
    families: &[Family],
    rho: f64,
    seed0: u64,
    count: usize,
) -> Vec<Outcome> {
    (seed0..seed0 + 4 * count as u64)
        .filter_map(|s| hidden::run(truth, s, families, rho, logging).ok())
        .take(count)
        .collect()
}

/// One truth, one convention: every family once, two nulls, one pair (zoh).
fn check(truth: &dyn Truth, logging: Logging, misses_allowed: usize) {
    let name = format!("{}/{}", truth.name(), logging.name());
    let singles: Vec<Outcome> = Family::ALL
        .par_iter()
        .enumerate()
        .flat_map(|(i, f)| trials(truth, logging, &[*f], 2.0, 60_000 + 1000 * i as u64, 1))
        .collect();
    let mut rank_miss = 0;
    let mut fit_miss = 0;
    for o in &singles {
        println!(
            "{name} {:<12} ρ {:.2} {} Hz 2^{} {:<14} top {:?} verdict {:?} val/floor {:.3?} {}",
            o.families[0],
            o.rho,
            o.rate_hz,
            o.encoder_bits,
            o.excitation,
            o.top,
            o.verdict,
            o.val_ratio,
            o.error.as_deref().unwrap_or("")
        );
        assert!(o.error.is_none(), "{name}: workbench error {:?}", o.error);
        rank_miss += usize::from(!o.rank1_ok());
        let bar = refit_bar(&o.families[0]);
        fit_miss += usize::from(o.refit_judgeable(bar) && !o.refit_ok(bar));
    }
    assert_eq!(
        singles.len(),
        Family::ALL.len(),
        "{name}: a family never drew a stable trial"
    );
    assert!(
        rank_miss <= misses_allowed,
        "{name}: rank 1 missed on {rank_miss} of 10"
    );
    assert!(
        fit_miss <= misses_allowed,
        "{name}: refit above its bar on {fit_miss} of 10"
    );
    let nulls = trials(truth, logging, &[], 1.0, 70_000, 3);
    for o in &nulls {
        println!(
            "{name} null: verdict {:?} {}",
            o.verdict,
            o.error.as_deref().unwrap_or("")
        );
    }
    let loud = nulls.iter().filter(|o| !o.null_ok()).count();
    assert!(loud <= 1, "{name}: {loud} of 3 null trials named an effect");
    let (a, b) = PAIRS[0];
    for o in trials(truth, logging, &[a, b], 2.0, 80_000, 1) {
        println!(
            "{name} pair {:?}: --auto added {:?}",
            o.families, o.auto_added
        );
        assert!(o.error.is_none(), "{name}: workbench error {:?}", o.error);
        // Both found (an extra effect is counted against the bench's pair rate, not here).
        assert!(
            o.families.iter().all(|f| o.auto_added.contains(f)),
            "{name}: --auto added {:?} for {:?}",
            o.auto_added,
            o.families
        );
    }
}

#[test]
fn rk4_truth() {
    let t = hidden::truth("rk4").expect("rk4 truth");
    for &lg in t.loggings() {
        check(t.as_ref(), lg, 2);
    }
}

#[test]
fn physicist_truth() {
    let t = hidden::truth("physicist").expect("physicist truth");
    for &lg in t.loggings() {
        check(t.as_ref(), lg, 2);
    }
}

#[test]
fn lab_truth() {
    let t = hidden::truth("lab").expect("lab truth");
    for &lg in t.loggings() {
        check(t.as_ref(), lg, 3);
    }
}
