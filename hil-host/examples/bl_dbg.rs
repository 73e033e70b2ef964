use hil_host::lab::recorder::read_rows;
use hil_host::lab::scenario::{Scenario, ScenarioKind};
use hil_host::lab::{Lab, LabOptions};
use sim_plant::{Environment, Param};
fn main() {
    let a: Vec<f64> = std::env::args()
        .skip(1)
        .map(|x| x.parse().unwrap())
        .collect();
    // args: i1 kc_out ratio_inertia gap_deg preload substep zeta
    let mut m =
        sim_plant::presets::preset(&std::env::var("P").unwrap_or("kamo-ball-10".into())).unwrap();
    let n = m.plant.gear_ratio.value;
    m.motor.inertia = Param::fixed(a[0]);
    m.plant.output_inertia = Param::fixed((a[2] - 1.0) * a[0] * n * n);
    let c = m.effects.compliance.as_mut().unwrap();
    c.stiffness = Param::fixed(a[1]);
    c.soft_stiffness = Param::fixed(0.0);
    c.knee = Param::fixed(0.0);
    // ζ of the contact mode (rotor on the contact)
    c.damping = Param::fixed(2.0 * a[6] * (a[1] / (n * n) * a[0]).sqrt() * n * n);
    m.effects.backlash.as_mut().unwrap().width = Param::fixed(a[3].to_radians());
    if a[1] == 0.0 {
        m.effects.compliance = None;
        m.effects.backlash = None;
    }
    m.effects.coulomb = None;
    m.effects.stribeck = None;
    m.effects.viscous = None;
    m.effects.asymmetry = None;
    m.effects.ripple = None;
    m.effects.cogging = None;
    let mut sc = Scenario::new(ScenarioKind::Backlash, &m).unwrap();
    let pre = std::env::var("PRE")
        .map(|v| v.parse::<f64>().unwrap())
        .unwrap_or(-1.0);
    if pre >= 0.0 {
        sc.kind = ScenarioKind::Wall;
        sc.set_wall(Some(Environment::Torque { torque: pre }));
    }
    sc.gains.stiffness *= a[4];
    println!(
        "k {:.1} N·m/deg out, b {:.3}",
        sc.gains.stiffness.to_radians(),
        sc.gains.damping
    );
    let _ = Environment::Free;
    let opts = LabOptions {
        seed: 1,
        substep_rate: a[5],
        ..LabOptions::default()
    };
    let mut lab = Lab::new(&m, sc, &opts).unwrap();
    let csv = std::path::Path::new("/tmp/bl_dbg.csv");
    lab.recorder.write_csv(csv).unwrap();
    lab.run(|_, _| {}).unwrap();
    let rows: Vec<_> = read_rows(csv).unwrap().map(|r| r.unwrap()).collect();
    let late: Vec<_> = rows.iter().filter(|r| r.time_s > 2.2).collect();
    let mx = late
        .iter()
        .map(|r| r.motor_pos_rad / n)
        .fold(f64::MIN, f64::max);
    let mn = late
        .iter()
        .map(|r| r.motor_pos_rad / n)
        .fold(f64::MAX, f64::min);
    let tmax = late
        .iter()
        .map(|r| r.torque_cmd_nm.abs())
        .fold(0.0, f64::max);
    println!(
        "motor p-p {:.4} deg (gap {} deg), max |τ| {:.3} N·m",
        (mx - mn).to_degrees(),
        a[3],
        tmax
    );
    let _ = a[4];
}
