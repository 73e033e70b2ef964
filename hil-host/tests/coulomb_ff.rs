//! The thesis's Coulomb feed-forward finding (§4, friction compensation), held against its
//! own words rather than against the lab's earlier runs: with backlash and a high gain the
//! feed-forward keeps a limit cycle "about the size of the zone of lost motion" going,
//! "slightly below" the friction is safe, over-compensation injects energy; a transmission
//! without backlash does not cycle.

mod common;

use common::{demo_json, dir};
use hil_host::lab::coulomb_ff::{sweep, UnderRow, UNDERS};

fn at(rows: &[UnderRow], u: f64) -> &UnderRow {
    rows.iter().find(|r| r.under == u).unwrap()
}

#[test]
fn over_compensation_cycles_the_cycloid_about_its_backlash_and_under_compensation_does_not() {
    let m = sim_plant::presets::preset("cyclo-29").unwrap();
    let s = sweep(&m, "cyclo-29", 1, &dir("coulomb_ff", "cyclo")).unwrap();
    assert_eq!(s.rows.len(), UNDERS.len());
    assert!(s.backlash_deg > 0.0);
    // Slightly below the friction: no cycle (one count of encoder jitter allowed each way).
    for u in [0.6, 0.8] {
        let r = at(&s.rows, u);
        assert!(r.limit_cycle_counts <= 2.0, "under {u}: {r:?}");
    }
    // Over the friction: a cycle of the backlash's order (within a factor of two of it).
    let over = at(&s.rows, 1.2);
    assert!(
        over.limit_cycle_deg > 0.5 * s.backlash_deg && over.limit_cycle_deg < 2.0 * s.backlash_deg,
        "{over:?} against {}°",
        s.backlash_deg
    );
    // The card feeds it: the power into the held joint is positive and far above the
    // under-compensated hold's.
    let safe = at(&s.rows, 0.8);
    assert!(over.hold_power_w > 0.0, "{over:?}");
    assert!(
        over.hold_power_w > 100.0 * safe.hold_power_w.abs(),
        "{over:?} {safe:?}"
    );
    // The feed-forward helps the tracking task at every factor below 1.
    let off = at(&s.rows, 0.0);
    for u in [0.6, 0.8] {
        assert!(at(&s.rows, u).tracking_rms_rad < off.tracking_rms_rad);
    }
}

#[test]
fn the_cable_without_backlash_never_cycles() {
    let m = sim_plant::presets::preset("whoi-cable-30").unwrap();
    let s = sweep(&m, "whoi-cable-30", 1, &dir("coulomb_ff", "cable")).unwrap();
    for r in &s.rows {
        assert!(r.limit_cycle_counts <= 2.0, "{r:?}");
    }
}

#[test]
fn the_scenario_prints_the_table_and_writes_the_plot() {
    let out = dir("coulomb_ff", "cli");
    let j = demo_json(&["--scenario", "coulomb-ff", "--preset", "cyclo-29"], &out);
    assert_eq!(j["rows"].as_array().unwrap().len(), UNDERS.len());
    assert!(out.join("coulomb-ff-cyclo-29.png").exists());
}
