//! The thesis's stiffness-fidelity ranking (Ch. 4), asserted on the lab: at each of its three
//! desired stiffnesses, the cable and KAMO 30:1 lose the least work per crank cycle, DOJEN and
//! REDEX come next, the harmonic drive and SUMITOMO lose the most.

mod common;

use std::collections::HashSet;

use common::{demo_json, dir};
use hil_host::lab::fidelity::{ranking, sweep, SIX, STIFFNESSES};

#[test]
fn the_six_transmissions_rank_as_in_the_thesis_at_every_stiffness() {
    let cells = sweep(1, &dir("fidelity", "sweep"), || {}).unwrap();
    assert_eq!(cells.len(), SIX.len() * STIFFNESSES.len());
    for c in &cells {
        assert!(c.loop_area_j.is_finite() && c.loop_area_j > 0.0, "{c:?}");
    }
    let set = |names: &[&str]| names.iter().map(|s| s.to_string()).collect::<HashSet<_>>();
    for k in STIFFNESSES {
        let r: Vec<String> = ranking(&cells, k)
            .iter()
            .map(|c| c.preset.clone())
            .collect();
        let group = |a: usize, b: usize| r[a..b].iter().cloned().collect::<HashSet<_>>();
        assert_eq!(
            group(0, 2),
            set(&["whoi-cable-30", "kamo-ball-30"]),
            "at {k}: {r:?}"
        );
        assert_eq!(
            group(2, 4),
            set(&["dojen-cam-33", "redex-corbac-30"]),
            "at {k}: {r:?}"
        );
        assert_eq!(
            group(4, 6),
            set(&["harmonic-drive-60", "sumitomo-59"]),
            "at {k}: {r:?}"
        );
    }
}

#[test]
fn the_scenario_prints_json_and_writes_the_loops() {
    let out = dir("fidelity", "cli");
    let j = demo_json(&["--scenario", "fidelity"], &out);
    assert_eq!(j["ranking"].as_array().unwrap().len(), STIFFNESSES.len());
    assert!(out.join("fidelity.png").exists());
}
