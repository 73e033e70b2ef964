//! End-to-end HIL scenarios on the in-process bus, in lockstep: card + plant + supervisor
//! exchanging real protocol frames.

use hil_host::lab::scenario::{Scenario, ScenarioKind};
use hil_host::lab::{Lab, LabOptions};

fn run(kind: ScenarioKind, preset: &str) -> Lab {
    let model = sim_plant::preset(preset).expect("preset");
    let sc = Scenario::new(kind, &model).expect("scenario");
    let mut lab = Lab::new(&model, sc, &LabOptions::default()).expect("lab");
    lab.run(|_, _| {}).expect("run");
    println!("== {} on {preset}\n{}", kind.name(), lab.summary().table());
    println!("events: {:?}", lab.supervisor.events);
    lab
}

#[test]
fn print_all() {
    for k in ScenarioKind::ALL {
        run(k, "whoi-cable-30");
    }
    run(ScenarioKind::Backlash, "kamo-ball-10");
    panic!("show");
}
