//! The instruction-count benchmark's set-ups, shared by the `qemu-bench` image and its host
//! tests: one configuration per law, the full joint pipeline of `controller`'s host bench
//! (position PID + input damping + friction comp + impedance comp + ripple table), two
//! input sets, a configured card for one whole tick, and the parameter set whose commit is
//! the configuration path.
//!
//! Configurations are built from SI values with `controller::units` (f64, configuration
//! time); what is measured is only the integer step.
// Set-up arithmetic on small constant ranges (sample index < 64), outside the measured step.
#![allow(clippy::arithmetic_side_effects)]

use controller::card::Card;
use controller::fixed_math::{Alpha, Vel};
use controller::laws::{Feedback, ForceConfig, ForceLaw, Gravity};
use controller::laws::{
    FrictionComp, FrictionConfig, ImpComp, ImpCompConfig, ImpedanceConfig, ImpedanceLaw,
    InputDamping, JointConfig, JointState, Measurements, Mode, PositionConfig, PositionLaw,
    RippleTable, Setpoint,
};
use controller::proto::params as p;
use controller::proto::{
    ControlWord, Message, Mode as WireMode, NodeId, ParamCommit, ParamWrite, SetChecksum,
    SetpointMotion,
};
use controller::units::{self, ForceDampingSi, Scale};

/// Samples per input set (the loop cycles through them).
pub const SAMPLES: usize = 64;

/// Which inputs the laws see.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Inputs {
    /// The host bench's inputs: errors of thousands of counts, velocities of ±2000
    /// counts/s, output torques of ±0.1 N·m — the PID often saturates.
    Bench,
    /// A joint tracking its setpoint: errors of a few counts, small velocities and torques.
    Tracking,
}

/// One measured case.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Case {
    /// Loop overhead alone (subtracted from every other case).
    Baseline,
    /// Position PD.
    Pd,
    /// Position PID.
    Pid,
    /// Input-velocity damping −B1e·ẋ1.
    InputDamping,
    /// Impedance with Km ≠ 0.
    Impedance,
    /// Force PI.
    ForcePi,
    /// Friction compensation.
    Friction,
    /// Impedance compensation.
    ImpComp,
    /// Ripple table.
    Ripple,
    /// The full joint pipeline through `JointState::step`.
    Full,
}

impl Case {
    /// Every case, baseline first.
    pub const ALL: [Case; 10] = [
        Case::Baseline,
        Case::Pd,
        Case::Pid,
        Case::InputDamping,
        Case::Impedance,
        Case::ForcePi,
        Case::Friction,
        Case::ImpComp,
        Case::Ripple,
        Case::Full,
    ];

    /// Short name for the table.
    pub const fn name(self) -> &'static str {
        match self {
            Case::Baseline => "baseline",
            Case::Pd => "position PD",
            Case::Pid => "position PID",
            Case::InputDamping => "input damping",
            Case::Impedance => "impedance (Km != 0)",
            Case::ForcePi => "force PI",
            Case::Friction => "friction comp",
            Case::ImpComp => "impedance comp",
            Case::Ripple => "ripple table",
            Case::Full => "full pipeline",
        }
    }
}

/// Every configuration and the samples.
#[derive(Debug)]
pub struct Bench {
    full: JointConfig,
    pd: PositionConfig,
    pid: PositionConfig,
    b1e: InputDamping,
    imp: ImpedanceConfig,
    force: ForceConfig,
    fric: FrictionConfig,
    ic: ImpCompConfig,
    rip: RippleTable,
    samples: [(Setpoint, Measurements); SAMPLES],
}

/// Ripple corrections (N·m) of the bench: a triangle of ±0.03 N·m over 64 entries.
fn ripple_nm() -> [f64; 64] {
    let mut t = [0.0f64; 64];
    let mut v = 0.0f64;
    for (i, e) in t.iter_mut().enumerate() {
        *e = v;
        v += if (16..48).contains(&i) {
            -0.001875
        } else {
            0.001875
        };
    }
    t
}

fn sample(inputs: Inputs, k: usize) -> (Setpoint, Measurements) {
    let k = k as i64;
    match inputs {
        Inputs::Bench => {
            let x = (k * 37) % 5000 - 2500;
            (
                Setpoint {
                    x_d: (k * 13) % 3000,
                    tau_d: 0,
                    ..Default::default()
                },
                Measurements {
                    x1: x,
                    v1: Vel::from_bits(((((k * 7919) % 4001) - 2000) * 16) as i32),
                    x2: 0,
                    v2: Vel::ZERO,
                    tau_env: (((k * 104_729) % 2001) - 1000) as i32,
                },
            )
        }
        Inputs::Tracking => {
            let x_d = 1_000_000 + k * 3;
            (
                Setpoint {
                    x_d,
                    tau_d: 5000 + (k % 7) as i32 * 10,
                    ..Default::default()
                },
                Measurements {
                    x1: x_d + (k % 9) - 4,
                    v1: Vel::from_bits((((k % 11) - 5) * 40) as i32),
                    x2: 0,
                    v2: Vel::ZERO,
                    tau_env: 4600 + ((k * 5) % 41) as i32 * 10,
                },
            )
        }
    }
}

impl Bench {
    /// Builds every configuration (`None` only if the units conversion refuses a value:
    /// a bench bug, tested on the host).
    pub fn new(inputs: Inputs) -> Option<Bench> {
        let s = Scale::thesis(30.0);
        let pos = |ki: f64| {
            units::position_config(
                &s,
                &units::PositionSi {
                    ke: 0.4,
                    be: 0.009,
                    ki,
                    i_limit_nm: 1.0,
                    tau_max_nm: 2.0,
                    feedback: Feedback::Colocated,
                },
            )
            .ok()
        };
        let pid = pos(5.0)?;
        let b1e = units::input_damping(&s, 0.002).ok()?;
        let fric = units::friction_config(
            &s,
            &units::FrictionSi {
                tau_c_pos: 0.03,
                tau_c_neg: 0.02,
                ramp_rad_s: 0.3,
                viscous: 0.001,
                undercomp: 0.8,
                limit_nm: 0.5,
            },
        )
        .ok()?;
        let ic = ImpCompConfig {
            alpha: Alpha::from_bits(983), // 0.03
            ..units::imp_comp_config(
                &s,
                &units::ImpCompSi {
                    kd_out: 300.0,
                    kc: 1.0,
                    cutoff_hz: 5.0,
                    limit_nm: 0.5,
                    feedback: Feedback::Colocated,
                },
            )
            .ok()?
        };
        let rip = units::ripple_table(&s, 128, &ripple_nm()).ok()?;
        let imp = units::impedance_config(
            &s,
            &units::ImpedanceSi {
                ke: 0.4,
                be: 0.009,
                km: 0.3,
                tau_max_nm: 2.0,
                feedback: Feedback::Colocated,
            },
        )
        .ok()?;
        let force = units::force_config(
            &s,
            &units::ForceSi {
                ke: 0.5,
                ki: 20.0,
                damping: ForceDampingSi::None,
                i_limit_nm: 1.0,
                tau_max_nm: 2.0,
            },
        )
        .ok()?;
        let mut samples = [(Setpoint::default(), Measurements::default()); SAMPLES];
        for (k, s) in samples.iter_mut().enumerate() {
            *s = sample(inputs, k);
        }
        Some(Bench {
            full: JointConfig {
                mode: Mode::Position(pid),
                input_damping: b1e,
                friction: Some(fric),
                imp_comp: Some(ic),
                ripple: Some(rip.clone()),
                friction_on_setpoint: false,
                offset: 120,
                gravity: Gravity::new(138_240, 900, -400),
                tau_max: 20000,
                transfer_shift: 6,
            },
            pd: pos(0.0)?,
            pid,
            b1e,
            imp,
            force,
            fric,
            ic,
            rip,
            samples,
        })
    }

    /// Runs `steps` steps of `case` and returns a checksum of the outputs (so nothing is
    /// optimised away). Each case is its own loop; `Baseline` runs the same loop around a
    /// trivial body.
    #[inline(never)]
    pub fn run(&mut self, case: Case, steps: u32) -> i64 {
        match case {
            Case::Baseline => self.lp(steps, |_, _, m| m.tau_env),
            Case::Pd => {
                let (c, mut st) = (self.pd, PositionLaw::default());
                self.lp(steps, move |_, sp, m| st.step(&c, sp.x_d, m.x1, m.v1).tau)
            }
            Case::Pid => {
                let (c, mut st) = (self.pid, PositionLaw::default());
                self.lp(steps, move |_, sp, m| st.step(&c, sp.x_d, m.x1, m.v1).tau)
            }
            Case::InputDamping => {
                let c = self.b1e;
                self.lp(steps, move |_, _, m| c.torque(m.v1) as i32)
            }
            Case::Impedance => {
                let c = self.imp;
                self.lp(steps, move |_, sp, m| {
                    ImpedanceLaw.step(&c, sp.x_d, m.x1, m.v1, m.tau_env).tau
                })
            }
            Case::ForcePi => {
                let (c, mut st) = (self.force, ForceLaw::NEW);
                self.lp(steps, move |_, sp, m| {
                    st.step(&c, sp.tau_d, m.tau_env, m.v1).tau
                })
            }
            Case::Friction => {
                let (c, mut st) = (self.fric, FrictionComp::NEW);
                self.lp(steps, move |_, _, m| st.step(&c, m.v1).tau)
            }
            Case::ImpComp => {
                let (c, mut st) = (self.ic, ImpComp::NEW);
                self.lp(steps, move |_, sp, m| {
                    st.step(&c, sp.x_d, m.x1, m.tau_env).tau
                })
            }
            Case::Ripple => {
                let t = self.rip.clone();
                self.lp(steps, move |_, _, m| t.torque(m.x1))
            }
            Case::Full => {
                let c = self.full.clone();
                let mut st = JointState::new();
                self.lp(steps, move |_, sp, m| st.step(&c, sp, m).out.tau)
            }
        }
    }

    #[inline(always)]
    fn lp(&self, steps: u32, mut f: impl FnMut(u32, &Setpoint, &Measurements) -> i32) -> i64 {
        let mut acc = 0i64;
        let mut k = 0usize;
        for i in 0..steps {
            if let Some((sp, m)) = self.samples.get(k) {
                let (sp, m) = core::hint::black_box((sp, m));
                acc = acc.wrapping_add(i64::from(f(i, sp, m)));
            }
            k = if k + 1 >= SAMPLES {
                0
            } else {
                k.wrapping_add(1)
            };
        }
        acc
    }
}

/// The bench's node number.
pub const NODE: u8 = 1;

/// The parameter set of the configuration benchmark and the card tick: position PID with
/// input damping, friction compensation, impedance compensation and a 64-entry ripple
/// table, telemetry every tick — every branch of `config::build` that does arithmetic.
/// The gains are the host bench's (Ke 0.4 N·m/rad, Be 0.009 N·m·s/rad, Ki 5 N·m/(rad·s),
/// B1e 0.002 N·m·s/rad on the thesis card), converted with `card::si`.
pub fn full_param_set() -> heapless::Vec<(u16, i32), 96> {
    use controller::card::si;
    let s = Scale::thesis(1.0);
    let mut v: heapless::Vec<(u16, i32), 96> = heapless::Vec::new();
    let fixed = [
        (p::KE, si::stiffness(&s, 0.4).unwrap_or(0)),
        (p::BE, si::damping(p::BE, &s, 0.009).unwrap_or(0)),
        (p::KI, si::integral(&s, 5.0).unwrap_or(0)),
        (p::INTEGRATOR_LIMIT, 10_000),
        (p::B1E, si::damping(p::B1E, &s, 0.002).unwrap_or(0)),
        (p::TORQUE_LIMIT, 20_000),
        (p::FRICTION_ENABLE, 1),
        (p::COULOMB_POS, 300),
        (p::COULOMB_NEG, 200),
        (
            p::VISCOUS_POS,
            si::damping(p::VISCOUS_POS, &s, 0.001).unwrap_or(0),
        ),
        (p::FRICTION_DEADBAND, 100),
        (p::IMPEDANCE_COMP_ENABLE, 1),
        (p::IMPEDANCE_COMP_STIFFNESS, 9_000),
        (p::IMPEDANCE_COMP_GAIN, 2_184),
        (p::IMPEDANCE_COMP_FILTER, 2_000),
        (p::RIPPLE_ENABLE, 1),
        (p::RIPPLE_PERIOD, 128),
        (p::RIPPLE_LENGTH, 64),
        (p::TELEMETRY_DIVIDER, 1),
    ];
    for e in fixed {
        let _ = v.push(e);
    }
    for i in 0..64u16 {
        let tri = i32::from(if i < 32 { i } else { 64 - i }) * 20 - 320;
        let _ = v.push((p::RIPPLE_TABLE.wrapping_add(i), tri));
    }
    v
}

/// [`full_param_set`] without the parameters that may change only while the card is idle:
/// what a commit while enabled may carry.
pub fn driving_param_set() -> heapless::Vec<(u16, i32), 96> {
    let mut v = full_param_set();
    v.retain(|(id, _)| p::lookup(*id).map(|d| d.access) == Ok(p::Access::Any));
    v
}

/// The commit that applies `entries` as set `set_seq`, after its writes.
pub fn writes_and_commit(
    entries: &[(u16, i32)],
    set_seq: u8,
    mut send: impl FnMut(Message),
) -> ParamCommit {
    let mut sum = SetChecksum::new();
    for &(param_id, value) in entries {
        sum.push(param_id, value);
        send(Message::ParamWrite(ParamWrite {
            param_id,
            value,
            set_seq,
        }));
    }
    ParamCommit {
        set_seq,
        count: sum.count(),
        crc: sum.crc(),
    }
}

/// A card configured with [`full_param_set`] and enabled in position PID at `x` counts,
/// with a setpoint 50 counts away: what one tick of the firmware runs.
pub fn configured_card(x: u32) -> Option<Card> {
    let mut card = Card::new(NodeId::new(NODE)?).ok()?;
    configure(&mut card, x).then_some(card)
}

/// Configures a fresh `card` in place as [`configured_card`] describes (in place: a card
/// is 3 KiB, and the M0 image has 16 KiB of RAM). False if it did not end up enabled.
pub fn configure(card: &mut Card, x: u32) -> bool {
    let node = card.node();
    let card = &mut *card;
    let mut t = 0u64;
    let tick = |card: &mut Card, seq: u8, t: &mut u64| {
        *t = t.wrapping_add(1000);
        let s = controller::card::Sensors {
            motor_counts: x,
            output_torque: Some(0),
            output_counts: None,
            seq,
            encoder_error: false,
        };
        card.step(*t, &s);
    };
    tick(card, 0, &mut t);
    let entries = full_param_set();
    let commit = writes_and_commit(&entries, 1, |m| {
        card.handle_message(t, node, m);
    });
    card.handle_message(t, node, Message::ParamCommit(commit));
    tick(card, 1, &mut t);
    for cw in [
        ControlWord::Shutdown,
        ControlWord::Enable(WireMode::PositionPid),
    ] {
        card.handle_message(t, node, Message::ControlWord(cw));
    }
    tick(card, 2, &mut t);
    card.handle_message(
        t,
        node,
        Message::SetpointMotion(SetpointMotion {
            position: (x as i32).wrapping_add(50),
            velocity_ff: 0,
            torque_ff: 0,
        }),
    );
    while card.poll_transmit().is_some() {}
    card.state() == controller::proto::State::Enabled
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller::proto::State;

    #[test]
    fn every_case_builds_and_runs() {
        for inputs in [Inputs::Bench, Inputs::Tracking] {
            let mut b = Bench::new(inputs).expect("bench configs build");
            let mut sums = std::vec::Vec::new();
            for c in Case::ALL {
                sums.push(b.run(c, 200));
            }
            // Each law produces torque on these inputs (a case that returned zero every
            // step would measure nothing).
            for (c, s) in Case::ALL.iter().zip(&sums).skip(1) {
                assert_ne!(*s, 0, "{:?} {inputs:?}", c);
            }
        }
    }

    #[test]
    fn the_parameter_sets_build_and_commit_while_enabled() {
        let mut st = controller::card::ParamStore::new();
        st.apply(&full_param_set());
        assert!(controller::card::config::build(&st, Some(WireMode::PositionPid)).is_ok());
        let mut card = configured_card(1_000_000).expect("card");
        let node = card.node();
        let c = writes_and_commit(&driving_param_set(), 9, |m| {
            card.handle_message(0, node, m);
        });
        while card.poll_transmit().is_some() {}
        card.handle_message(0, node, Message::ParamCommit(c));
        assert!(matches!(
            card.poll_transmit(),
            Some(Message::ParamResponse(r)) if r.status == controller::proto::ParamStatus::Ok
        ));
    }

    #[test]
    fn configured_card_runs_pid_with_every_term() {
        let mut card = configured_card(100_000).expect("card");
        assert_eq!(card.state(), State::Enabled);
        let cfg = card.config().joint.clone();
        assert!(matches!(cfg.mode, Mode::Position(c) if c.pid.has_integrator()));
        assert!(cfg.friction.is_some() && cfg.imp_comp.is_some() && cfg.ripple.is_some());
        assert!(!cfg.input_damping.b1e.is_zero());
        let s = controller::card::Sensors {
            motor_counts: 100_000,
            output_torque: Some(0),
            output_counts: None,
            seq: 3,
            encoder_error: false,
        };
        let a = card.step(10_000, &s);
        assert!(a.drive && a.torque > 0, "{a:?}");
    }
}
