//! The machine-tool paper's velocity pulse on the lab: the card's velocity loop holds the
//! pulse's speed on every transmission, and where there is a gap the load's response after
//! the start differs from the one after the stop (it waits while the motor crosses the gap,
//! then overshoots), where the cable's load follows its motor both ways.

mod common;

use common::{demo_json, dir};
use hil_host::lab::velocity_pulse::{run, Pulse, PULSE_SPEED};

fn pulse(preset: &str) -> Pulse {
    let m = sim_plant::presets::preset(preset).unwrap();
    run(&m, preset, 1, &dir("velocity_pulse", preset)).unwrap()
}

#[test]
fn the_velocity_loop_holds_the_pulse_on_every_transmission() {
    for preset in sim_plant::presets::preset_names() {
        let p = pulse(preset);
        assert!(
            (p.motor_mean - PULSE_SPEED).abs() < 0.03 * PULSE_SPEED.abs(),
            "{preset}: {}",
            p.motor_mean
        );
    }
}

#[test]
fn with_a_gap_the_load_waits_after_the_start_and_not_after_the_stop() {
    for preset in ["cyclo-29", "kamo-ball-10"] {
        let p = pulse(preset);
        assert!(p.backlash_rad > 0.0);
        // The motor crosses at most the whole gap before the load moves: at the pulse's
        // speed that takes backlash/|speed|; the load must lag by a part of it.
        let crossing = p.backlash_rad / PULSE_SPEED.abs();
        assert!(
            p.start.delay_s > p.motor_start.delay_s + 0.25 * crossing,
            "{preset}: {p:?}"
        );
        // Stopping, friction keeps the load on its flank: it follows the motor.
        assert!(
            p.stop.delay_s <= p.motor_stop.delay_s + 0.005,
            "{preset}: {p:?}"
        );
        assert!(p.start.overshoot > p.stop.overshoot, "{preset}: {p:?}");
    }
    let cable = pulse("whoi-cable-30");
    assert!(
        (cable.start.delay_s - cable.motor_start.delay_s).abs() <= 0.005,
        "{cable:?}"
    );
}

#[test]
fn the_scenario_prints_json_and_writes_the_plot() {
    let out = dir("velocity_pulse", "cli");
    let j = demo_json(
        &["--scenario", "velocity-pulse", "--preset", "cyclo-29"],
        &out,
    );
    assert_eq!(j["pulse"]["label"], "cyclo-29");
    assert!(j["pulse"]["backlash_rad"].as_f64().unwrap() > 0.0);
    assert!(out.join("velocity-pulse-cyclo-29.png").exists());
}
