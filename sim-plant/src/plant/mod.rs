//! The plant: motor + transmission + load, integrated at a fixed substep between 1 kHz
//! samples.
//!
//! ## Coordinates
//! Every mechanical quantity inside is referred to the **output** (thesis Tables 4.1/4.2 are
//! output-side; §4 notes: "to motor side divide K and B by N², torques by N"): the motor node
//! has inertia N²·I1, damping N²·B1, position θm/N and receives N·τm. Sensors convert back.
//!
//! ## Structures (thesis §3.1)
//! * rigid: `J·q̈ = N·τm − R(q, q̇) + τ_env`, J = N²I1 + I2;
//! * 2-mass: motor | spring τT(δ, δ̇) with soft zone and backlash | output, friction on the
//!   output (Table 4.1 was measured backdriving the output);
//! * 3-mass (Eqn 3.3.26): motor | Ks | middle | τT | output.
//!
//! ## Integration
//! Störmer–Verlet in its position ("drift–kick–drift") form at a fixed substep h (default
//! 10 kHz, configurable): positions advance half a step with the old velocities, the forces are
//! evaluated once there, velocities take a full kick, positions advance the second half. Why
//! this and not RK4: the right-hand side is non-smooth — stick/slip switches, backlash contact,
//! piecewise-linear soft zones — so RK4's stages straddle discontinuities and its order is
//! lost while it costs four force evaluations per step. Verlet costs one, is symplectic (no
//! energy drift on the lossless plant; energy error bounded at O((ω·h)²)), second-order
//! accurate in frequency, and the single velocity kick is where the friction node can clamp its
//! velocity to exactly zero for a proper stick state ([`friction`]). Consecutive half-drifts
//! are merged (the leapfrog form): one drift per substep, plus a half at each end of a step.
//! Stability needs ω·h < 2 for the stiffest mode; the constructor refuses anything above
//! ω·h = 1 and says which rate would do.
//!
//! The state (positions, velocities, stick flag, phase trackers) lives in a local `Core` for
//! the substep loop and every law is inlined, so the loop runs out of registers.
//!
//! ## Determinism
//! Pure f64 arithmetic in a fixed order plus a seeded ChaCha8 noise stream: the same model,
//! seed and inputs give bit-identical outputs.

pub mod environment;
pub mod friction;
pub mod sensors;
pub mod state;

pub use environment::Environment;
pub use sensors::{SensorConfig, Sensors};
pub use state::TrueState;

use crate::effects::{compliance, EffectLaws, Node};
use crate::fastmath::Rotor;
use crate::model::{Model, PlantKind};

/// Options that are not part of the joint model: integration, noise seed, set-up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantOptions {
    /// Internal substep rate (Hz), ≥ 10 kHz recommended.
    pub substep_rate: f64,
    /// Seed of the sensor-noise stream.
    pub seed: u64,
    /// Initial environment.
    pub environment: Environment,
}

impl Default for PlantOptions {
    fn default() -> Self {
        Self {
            substep_rate: 10_000.0,
            seed: 0,
            environment: Environment::Free,
        }
    }
}

/// Why a plant could not be built or stepped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlantError {
    /// The stiffest mode is too fast for the substep.
    #[error(
        "substep rate {rate} Hz is too low for a mode at {omega:.1} rad/s \
         (ω·h = {wh:.2} > 1); use at least {needed:.0} Hz"
    )]
    TooStiff {
        /// Requested rate (Hz).
        rate: f64,
        /// Fastest mode estimate (rad/s).
        omega: f64,
        /// ω·h.
        wh: f64,
        /// A rate that satisfies ω·h ≤ 1.
        needed: f64,
    },
    /// Bad option or model (message says which).
    #[error("{0}")]
    Invalid(String),
    /// Unknown preset name.
    #[error("unknown preset `{0}` (see preset_names())")]
    UnknownPreset(String),
}

/// Resolved mechanical constants (output-referred).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Mech {
    kind: PlantKind,
    n: f64,
    /// Motor node inertia (rigid: total J).
    i1: f64,
    /// Motor node damping (rigid: B1' + B2).
    b1: f64,
    im: f64,
    ks: f64,
    cs: f64,
    i2: f64,
    b2: f64,
    max_torque: f64,
    /// Reciprocals, so the substep loop multiplies instead of dividing.
    inv_i1: f64,
    inv_im: f64,
    inv_i2: f64,
}

/// 1/x, or 0 for a node that does not exist (x = 0).
fn recip(x: f64) -> f64 {
    if x > 0.0 {
        1.0 / x
    } else {
        0.0
    }
}

/// A simulated joint. Build with [`Plant::new`] or [`Plant::from_preset`], drive with
/// [`Plant::step`].
#[derive(Clone, Debug)]
pub struct Plant {
    model: Model,
    mech: Mech,
    laws: EffectLaws,
    dry: bool,
    env: Environment,
    rate: f64,
    /// Positions: motor node, middle node, output node (output-referred; rigid uses [0]).
    x: [f64; 3],
    v: [f64; 3],
    stuck: bool,
    /// Actuator delay line (output-referred commands, one slot per substep).
    delay_line: Vec<f64>,
    delay_pos: usize,
    sensors: sensors::SensorModel,
    last: TrueState,
}

impl Plant {
    /// Build a plant from a model.
    pub fn new(model: &Model, opts: PlantOptions) -> Result<Self, PlantError> {
        if !(opts.substep_rate.is_finite() && opts.substep_rate > 0.0) {
            return Err(PlantError::Invalid(format!(
                "substep_rate must be positive, got {}",
                opts.substep_rate
            )));
        }
        model
            .check_consistency()
            .map_err(|(_, m)| PlantError::Invalid(m))?;
        let mut laws = EffectLaws::default();
        model.effects.install(&mut laws);
        let n = model.plant.gear_ratio.value;
        let kind = model.kind();
        let i1m = n * n * model.motor.inertia.value;
        let b1m = n * n * model.motor.damping.value;
        let p = &model.plant;
        let mech = match kind {
            PlantKind::Rigid => Mech {
                kind,
                n,
                i1: i1m + p.output_inertia.value + p.middle_inertia.value,
                b1: b1m + p.output_damping.value,
                im: 0.0,
                ks: 0.0,
                cs: 0.0,
                i2: 0.0,
                b2: 0.0,
                max_torque: model.motor.max_torque.value,
                inv_i1: 0.0,
                inv_im: 0.0,
                inv_i2: 0.0,
            },
            PlantKind::TwoMass | PlantKind::ThreeMass => Mech {
                kind,
                n,
                i1: i1m,
                b1: b1m,
                im: p.middle_inertia.value,
                ks: p.proximal_stiffness.value,
                cs: p.proximal_damping.value,
                i2: p.output_inertia.value,
                b2: p.output_damping.value,
                max_torque: model.motor.max_torque.value,
                inv_i1: 0.0,
                inv_im: 0.0,
                inv_i2: 0.0,
            },
        };
        let mech = Mech {
            inv_i1: recip(mech.i1),
            inv_im: recip(mech.im),
            inv_i2: recip(mech.i2),
            ..mech
        };
        let h = 1.0 / opts.substep_rate;
        let delay_slots = (laws.actuator.delay / h).round() as usize;
        let cfg = SensorConfig {
            motor_cpr: model.motor.counts_per_rev.value,
            output_cpr: model.sensors.output_counts_per_rev.value,
            torque_resolution: model.sensors.torque_resolution.value,
            torque_noise: model.sensors.torque_noise.value,
            velocity_resolution: model.sensors.velocity_resolution.value,
            delay: model.sensors.delay.value.round() as usize,
        };
        let plant = Plant {
            model: model.clone(),
            mech,
            dry: laws.friction.has_dry(),
            laws,
            env: opts.environment,
            rate: opts.substep_rate,
            x: [0.0; 3],
            v: [0.0; 3],
            stuck: true,
            delay_line: vec![0.0; delay_slots],
            delay_pos: 0,
            sensors: sensors::SensorModel::new(cfg, opts.seed),
            last: TrueState::default(),
        };
        plant.check_step_size(&opts.environment)?;
        Ok(plant)
    }

    /// Build a named preset (see [`crate::presets::preset_names`]).
    pub fn from_preset(name: &str, opts: PlantOptions) -> Result<Self, PlantError> {
        let model =
            crate::presets::preset(name).ok_or_else(|| PlantError::UnknownPreset(name.into()))?;
        Self::new(&model, opts)
    }

    /// Fastest mode / damping rate estimate against the substep.
    fn check_step_size(&self, env: &Environment) -> Result<(), PlantError> {
        let m = &self.mech;
        let s = &self.laws.spring;
        let (ke, ce) = env.stiffness_damping();
        let visc = self
            .laws
            .friction
            .viscous_pos
            .max(self.laws.friction.viscous_neg);
        // Gershgorin-style bound: for each node, Σ(stiffness)/inertia·(1 + neighbour ratio).
        let (w2, c_rate) = match m.kind {
            PlantKind::Rigid => (ke / m.i1, (m.b1 + ce + visc) / m.i1),
            PlantKind::TwoMass => {
                let k = s.max_stiffness();
                (
                    (k * (1.0 / m.i1 + 1.0 / m.i2)).max((k + ke) / m.i2),
                    ((s.damping + m.b1) / m.i1).max((s.damping + m.b2 + ce + visc) / m.i2)
                        + s.damping / m.i2,
                )
            }
            PlantKind::ThreeMass => {
                let k = s.max_stiffness();
                let w2 = (2.0 * m.ks / m.i1)
                    .max(2.0 * (m.ks + k) / m.im)
                    .max(2.0 * k / m.i2 + ke / m.i2);
                let c = ((m.cs + m.b1) / m.i1)
                    .max((m.cs + s.damping) / m.im)
                    .max((s.damping + m.b2 + ce + visc) / m.i2);
                (w2, 2.0 * c)
            }
        };
        let omega = w2.sqrt().max(c_rate);
        let h = 1.0 / self.rate;
        if omega * h > 1.0 {
            return Err(PlantError::TooStiff {
                rate: self.rate,
                omega,
                wh: omega * h,
                needed: omega.ceil(),
            });
        }
        Ok(())
    }

    /// Change the environment (checked against the substep like at construction). Switching
    /// to [`Environment::Locked`] clamps the output where it is; [`Environment::Crank`] drives
    /// it from where it is.
    pub fn set_environment(&mut self, env: Environment) -> Result<(), PlantError> {
        self.check_step_size(&env)?;
        self.env = env;
        Ok(())
    }

    /// Current environment.
    pub fn environment(&self) -> Environment {
        self.env
    }

    /// The model the plant was built from.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The installed effect laws (resolved numbers).
    pub fn laws(&self) -> &EffectLaws {
        &self.laws
    }

    /// Substep rate (Hz).
    pub fn substep_rate(&self) -> f64 {
        self.rate
    }

    /// Place the joint: motor angle (rad at the motor) and output angle (rad); velocities are
    /// zeroed and the friction node starts stuck. In a rigid plant the output angle is
    /// motor/N and `output_angle` is ignored; the 3-mass middle node starts at motor/N.
    pub fn set_positions(&mut self, motor_angle: f64, output_angle: f64) {
        let xm = motor_angle / self.mech.n;
        self.x = match self.mech.kind {
            PlantKind::Rigid => [xm, xm, xm],
            _ => [xm, xm, output_angle],
        };
        self.v = [0.0; 3];
        self.stuck = true;
        self.last = self.true_state_now(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, false);
    }

    /// The true state after the last step.
    pub fn state(&self) -> TrueState {
        self.last
    }

    /// Mechanical energy: kinetic + transmission/stage springs + environment spring (J).
    /// Dissipative effects are not included; with no losses and no input it is conserved up
    /// to the integrator's O((ω·h)²) oscillation.
    pub fn energy(&self) -> f64 {
        let m = &self.mech;
        let [x0, x1, x2] = self.x;
        let [v0, v1, v2] = self.v;
        let s = &self.laws.spring;
        match m.kind {
            PlantKind::Rigid => 0.5 * m.i1 * v0 * v0 + self.env.potential(x0),
            PlantKind::TwoMass => {
                0.5 * m.i1 * v0 * v0
                    + 0.5 * m.i2 * v2 * v2
                    + compliance::potential(s.engaged(x0 - x2), s.k_soft, s.k_hard, s.knee_torque)
                    + self.env.potential(x2)
            }
            PlantKind::ThreeMass => {
                0.5 * m.i1 * v0 * v0
                    + 0.5 * m.im * v1 * v1
                    + 0.5 * m.i2 * v2 * v2
                    + 0.5 * m.ks * (x0 - x1) * (x0 - x1)
                    + compliance::potential(s.engaged(x1 - x2), s.k_soft, s.k_hard, s.knee_torque)
                    + self.env.potential(x2)
            }
        }
    }

    /// Apply `torque_cmd` (N·m at the motor, held for `dt`), advance `dt` seconds in
    /// substeps, and read the sensors. The HIL plant node calls this at 1 kHz with
    /// dt = 1 ms. The number of substeps is round(dt·rate) (at least 1), each dt/count long.
    pub fn step(&mut self, torque_cmd: f64, dt: f64) -> Sensors {
        self.advance(torque_cmd, dt);
        self.read_sensors()
    }

    /// Advance without reading the sensors (no noise drawn).
    pub fn advance(&mut self, torque_cmd: f64, dt: f64) {
        let count = ((dt * self.rate).round() as usize).max(1);
        let h = dt / count as f64;
        let inv_h = count as f64 / dt;
        let m = self.mech;
        let cmd = if torque_cmd.is_nan() { 0.0 } else { torque_cmd };
        let sat = cmd.clamp(-m.max_torque, m.max_torque);
        let u_cmd = m.n * sat;
        let mut out = Substep::default();
        // The state lives in a local for the loop so it can stay in registers.
        let mut core = Core {
            x: self.x,
            v: self.v,
            stuck: self.stuck,
            ripple: Rotor::new(),
            cogging: Rotor::new(),
            gravity: Rotor::new(),
        };
        // Leapfrog form of drift–kick–drift: the second half-drift of one substep and the first
        // half-drift of the next are one full drift, so positions are synchronised with
        // velocities only at the ends of the step.
        let mut before = self.begin_substeps(&mut core, h);
        let memoryless = self.delay_line.is_empty();
        // The actuator chain is memoryless without a delay: shape once per step.
        let shaped = self.laws.actuator.shape(u_cmd);
        for k in 0..count {
            let u = if memoryless {
                shaped
            } else {
                self.actuate(u_cmd)
            };
            out = self.kick(&mut core, u, h, inv_h, before);
            before = core.v[self.friction_node_index()];
            let d = if k + 1 == count { 0.5 * h } else { h };
            for i in 0..3 {
                core.x[i] += d * core.v[i];
            }
        }
        self.x = core.x;
        self.v = core.v;
        self.stuck = core.stuck;
        self.last = self.true_state_now(
            torque_cmd,
            out.motor_accel,
            out.applied / m.n,
            out.transmission,
            out.friction,
            out.env,
            out.accel,
            self.last.time + dt,
            sat != cmd,
        );
    }

    /// Read the sensors for the current state (draws noise, advances the delay line).
    pub fn read_sensors(&mut self) -> Sensors {
        let s = self.last;
        self.sensors.sample(
            s.motor_angle,
            s.motor_velocity,
            s.output_angle,
            s.environment_torque,
        )
    }

    /// Actuator chain for one substep: delay line, then the shaping effects.
    #[inline(always)]
    fn actuate(&mut self, u: f64) -> f64 {
        let delayed = if self.delay_line.is_empty() {
            u
        } else {
            let old = self.delay_line[self.delay_pos];
            self.delay_line[self.delay_pos] = u;
            self.delay_pos = (self.delay_pos + 1) % self.delay_line.len();
            old
        };
        self.laws.actuator.shape(delayed)
    }

    /// Resisting torques at the output that are not friction or spring: offset, ripple,
    /// gravity, additive torques (the rigid plant's output is its only node).
    #[inline(always)]
    fn output_load(&self, c: &mut Core, q: f64, v: f64, load: f64) -> f64 {
        let l = &self.laws;
        let mut r = 0.0;
        if !l.additive.is_empty() {
            r += l.additive_on(Node::Output, q, v, load);
        }
        if !l.ripple.is_zero() {
            r += l.ripple.torque_tracked(&mut c.ripple, q, load);
        }
        if !l.gravity.is_zero() {
            r += l.gravity.torque_tracked(&mut c.gravity, q, 0.0);
        }
        r
    }

    /// Resisting torques on the motor node: cogging at output-referred position `xm` (motor
    /// angle = N·xm) and additive torques.
    #[inline(always)]
    fn motor_load(&self, c: &mut Core, xm: f64, vm: f64, load: f64) -> f64 {
        let l = &self.laws;
        let mut r = 0.0;
        if !l.cogging.is_zero() {
            r += l
                .cogging
                .torque_tracked(&mut c.cogging, xm * self.mech.n, 0.0);
        }
        if !l.additive.is_empty() {
            r += l.additive_on(Node::Motor, xm, vm, load);
        }
        r
    }

    /// Update the friction node (index `i`, inertia `inertia`) given its non-friction,
    /// non-environment torque `tau` and its velocity at the start of the substep; returns
    /// (friction, environment torque on the node, acceleration).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn friction_node(
        &self,
        c: &mut Core,
        i: usize,
        inertia: f64,
        inv_inertia: f64,
        tau: f64,
        h: f64,
        inv_h: f64,
        v_old: f64,
    ) -> (f64, f64, f64) {
        if let Some(vp) = self.env.prescribed_velocity() {
            // Kinematic: the environment imposes the motion and carries the reaction.
            let f = if vp == 0.0 {
                0.0
            } else {
                self.laws.friction.sliding(vp)
            };
            let a = (vp - v_old) * inv_h;
            c.v[i] = vp;
            c.stuck = vp == 0.0;
            let env = inertia * a - tau + f;
            return (f, env, a);
        }
        let env = self.env.torque(c.x[i], v_old);
        let (vn, f) = friction::advance(
            v_old,
            &mut c.stuck,
            tau + env,
            h * inv_inertia,
            &self.laws.friction,
            self.dry,
        );
        c.v[i] = vn;
        (f, env, (vn - v_old) * inv_h)
    }

    /// Index of the friction (and environment) node: the output, or the only node.
    #[inline(always)]
    fn friction_node_index(&self) -> usize {
        if self.mech.kind == PlantKind::Rigid {
            0
        } else {
            2
        }
    }

    /// Start of a step: impose a kinematic environment's velocity and drift half a substep.
    /// Returns the friction node's velocity before the imposition (for the reaction's I·a).
    ///
    /// A kinematic environment (lock, crank) imposes the output velocity for the whole step,
    /// every drift included, so a locked output does not creep and a crank's angle is exactly
    /// speed·t.
    #[inline(always)]
    fn begin_substeps(&self, c: &mut Core, h: f64) -> f64 {
        let node = self.friction_node_index();
        let before = c.v[node];
        if let Some(vp) = self.env.prescribed_velocity() {
            c.v[node] = vp;
            if node == 0 {
                c.v = [vp; 3];
            }
        }
        for i in 0..3 {
            c.x[i] += 0.5 * h * c.v[i];
        }
        before
    }

    /// Forces at the current (mid-step) positions, full velocity update.
    #[inline(always)]
    fn kick(&self, c: &mut Core, u: f64, h: f64, inv_h: f64, before: f64) -> Substep {
        let m = self.mech;
        match m.kind {
            PlantKind::Rigid => {
                let x = c.x[0];
                let v = c.v[0];
                let tau = u - m.b1 * v - self.output_load(c, x, v, u) - self.motor_load(c, x, v, u);
                let (f, env, a) = self.friction_node(c, 0, m.i1, m.inv_i1, tau, h, inv_h, before);
                c.v[1] = c.v[0];
                c.v[2] = c.v[0];
                Substep {
                    applied: u,
                    motor_accel: a,
                    transmission: u,
                    friction: f,
                    env,
                    accel: a,
                }
            }
            PlantKind::TwoMass => {
                let [x0, _, x2] = c.x;
                let [v0, _, v2] = c.v;
                let tt = self.laws.spring.torque(x0 - x2, v0 - v2);
                let a0 = (u - tt - m.b1 * v0 - self.motor_load(c, x0, v0, tt)) * m.inv_i1;
                c.v[0] = v0 + h * a0;
                let tau = tt - m.b2 * v2 - self.output_load(c, x2, v2, tt);
                let (f, env, a) = self.friction_node(c, 2, m.i2, m.inv_i2, tau, h, inv_h, before);
                c.v[1] = c.v[0];
                Substep {
                    applied: u,
                    motor_accel: a0,
                    transmission: tt,
                    friction: f,
                    env,
                    accel: a,
                }
            }
            PlantKind::ThreeMass => {
                let [x0, x1, x2] = c.x;
                let [v0, v1, v2] = c.v;
                let ts = m.ks * (x0 - x1) + m.cs * (v0 - v1);
                let tt = self.laws.spring.torque(x1 - x2, v1 - v2);
                let a0 = (u - ts - m.b1 * v0 - self.motor_load(c, x0, v0, ts)) * m.inv_i1;
                let a1 = (ts - tt) * m.inv_im;
                c.v[0] = v0 + h * a0;
                c.v[1] = v1 + h * a1;
                let tau = tt - m.b2 * v2 - self.output_load(c, x2, v2, tt);
                let (f, env, a) = self.friction_node(c, 2, m.i2, m.inv_i2, tau, h, inv_h, before);
                Substep {
                    applied: u,
                    motor_accel: a0,
                    transmission: tt,
                    friction: f,
                    env,
                    accel: a,
                }
            }
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn true_state_now(
        &self,
        command: f64,
        motor_accel: f64,
        applied: f64,
        transmission: f64,
        friction: f64,
        env_on_output: f64,
        accel: f64,
        time: f64,
        saturated: bool,
    ) -> TrueState {
        let n = self.mech.n;
        let (xi, xo) = match self.mech.kind {
            PlantKind::ThreeMass => (self.x[1], self.x[2]),
            _ => (self.x[0], self.x[2]),
        };
        TrueState {
            time,
            motor_angle: self.x[0] * n,
            motor_velocity: self.v[0] * n,
            motor_acceleration: motor_accel * n,
            middle_angle: self.x[1],
            output_angle: self.x[2],
            output_velocity: self.v[2],
            output_acceleration: accel,
            deflection: xi - xo,
            transmission_torque: transmission,
            friction_torque: friction,
            environment_torque: -env_on_output,
            command,
            applied_torque: applied,
            stuck: self.stuck && self.dry,
            saturated,
        }
    }
}

/// The integrated state, held in a local during the substep loop.
#[derive(Clone, Copy, Debug)]
struct Core {
    x: [f64; 3],
    v: [f64; 3],
    stuck: bool,
    /// Phase trackers of the ripple, cogging and gravity angles.
    ripple: Rotor,
    cogging: Rotor,
    gravity: Rotor,
}

/// Quantities of the last substep, for the true-state record.
#[derive(Clone, Copy, Debug, Default)]
struct Substep {
    applied: f64,
    /// Motor node acceleration (output-referred).
    motor_accel: f64,
    transmission: f64,
    friction: f64,
    env: f64,
    accel: f64,
}
