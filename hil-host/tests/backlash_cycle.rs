//! The thesis's backlash limit cycle on the lab (`demo --scenario backlash-cycle`): with the
//! thesis's light rotor alone before the gap, the high-gain hold cycles on cyclo-29 and
//! kamo-ball-10, more the wider the gap, not at all without one (the cable), and a preload
//! of the order of τb = Kd·ε holds the load on one flank and stops it. The figures come from
//! the plant's motor encoder over the hold's last second.

mod common;

use common::{demo_json, dir};
use serde_json::Value;

fn f(v: &Value, k: &str) -> f64 {
    v[k].as_f64().unwrap_or_else(|| panic!("{k} in {v}"))
}

#[test]
fn the_cycle_grows_with_the_gap_and_a_preload_stops_it() {
    let out = dir("backlash_cycle", "demo");
    let j = demo_json(&["--scenario", "backlash-cycle"], &out);
    for png in ["width", "preload"] {
        assert!(out.join(format!("backlash-cycle-{png}.png")).exists());
    }
    let presets = j["presets"].as_array().unwrap();
    assert_eq!(presets.len(), 2);
    for p in presets {
        let name = p["preset"].as_str().unwrap();
        let widths = p["widths"].as_array().unwrap();
        // No gap, no cycle: the encoder's count or two.
        assert_eq!(f(&widths[0], "gap_deg"), 0.0);
        assert!(f(&widths[0], "counts") <= 3.0, "{name}: {}", widths[0]);
        // With one it cycles, and a wider gap cycles wider.
        let pp: Vec<f64> = widths.iter().map(|c| f(c, "motor_pp_deg")).collect();
        let gap: Vec<f64> = widths.iter().map(|c| f(c, "gap_deg")).collect();
        assert!(
            widths[1..].iter().all(|c| f(c, "counts") >= 10.0),
            "{name}: {pp:?}"
        );
        let at = |g: f64| pp[gap.iter().position(|x| (x - g).abs() < 1e-9).unwrap()];
        assert!(at(0.8) > 3.0 * at(0.1), "{name}: {pp:?}");
        // On its own gap, the thesis's "about the size of the zone of lost motion".
        let own = &p["own"];
        assert!(
            f(own, "motor_pp_deg") > 0.5 * f(own, "gap_deg"),
            "{name}: {own}"
        );
        // A preload stops it, within a few τb.
        let pre = p["preloads"].as_array().unwrap();
        assert!(f(&pre[0], "counts") >= 10.0, "{name}: {}", pre[0]);
        let tau_b = f(p, "tau_b");
        let stops = pre
            .iter()
            .find(|c| f(c, "counts") <= 2.0)
            .unwrap_or_else(|| panic!("{name}: no preload stops it: {pre:?}"));
        assert!(f(stops, "preload_nm") <= 3.0 * tau_b, "{name}: {stops}");
    }
    // The cable has no gap: nothing to cycle in.
    assert!(f(&j["no_gap"]["cycle"], "counts") <= 3.0, "{}", j["no_gap"]);
}
