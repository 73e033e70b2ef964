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
//! The substep loop is compiled once per structure and environment kind; the state and every
//! loop-invariant constant live in locals and every law is inlined, so the loop runs out of
//! registers. Position-periodic torques (cogging, ripple, gravity) are table-plus-polynomial
//! [`Harmonic`]s built at construction; effects with zero amplitude are not evaluated.
//!
//! Speed: at 10 kHz the loop is bound by its dependency chain velocity → position → torques →
//! velocity, not by arithmetic, so the laws are written for a short chain. The periodic
//! torques' phase is reduced exactly once per step and then carried as a table index plus
//! fraction, advanced by each drift's increment with the index *predicted* from the previous
//! increment (`PhaseTrack`): the angle's multiply and rounding are off the chain and the
//! value is one Estrin polynomial of the fraction. The spring is `k·δ + c` per branch, the
//! Stribeck exp is inline and table-based, and in every sum the term that is ready last is
//! added last. All of it is deterministic; it differs from the plain formulas by rounding.
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

use crate::effects::{compliance, EffectLaws, Node, PeriodicTorque};
use crate::fastmath::{self, Harmonic, Phase};
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
    /// Positions: motor node, middle node, output node (output-referred; rigid uses index 0).
    x: [f64; 3],
    v: [f64; 3],
    stuck: bool,
    /// Actuator delay line (output-referred commands, one slot per substep).
    delay_line: Vec<f64>,
    delay_pos: usize,
    sensors: sensors::SensorModel,
    last: TrueState,
    /// The periodic torques of `laws`, precomputed for the substep loop.
    periodic: Periodics,
    /// The transmission spring of `laws` in the substep loop's form.
    spring: PiecewiseSpring,
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
        let periodic = Periodics::new(&laws, n);
        let spring = PiecewiseSpring::new(&laws.spring);
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
            periodic,
            spring,
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
        let count = (fastmath::round(dt * self.rate) as usize).max(1);
        let h = dt / count as f64;
        let inv_h = count as f64 / dt;
        let m = self.mech;
        let cmd = if torque_cmd.is_nan() { 0.0 } else { torque_cmd };
        let sat = cmd.clamp(-m.max_torque, m.max_torque);
        let u_cmd = m.n * sat;
        // One loop per structure and environment kind, so the substep has no dispatch left.
        let out = match m.kind {
            PlantKind::Rigid => self.substeps_in_env::<RIGID>(u_cmd, count, h, inv_h),
            PlantKind::TwoMass => self.substeps_in_env::<TWO_MASS>(u_cmd, count, h, inv_h),
            PlantKind::ThreeMass => self.substeps_in_env::<THREE_MASS>(u_cmd, count, h, inv_h),
        };
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
        let s = &self.last;
        self.sensors.sample(
            s.motor_angle,
            s.motor_velocity,
            s.output_angle,
            s.environment_torque,
        )
    }

    /// [`Plant::substeps`] for the current environment's kind.
    #[inline(always)]
    fn substeps_in_env<const KIND: u8>(
        &mut self,
        u_cmd: f64,
        count: usize,
        h: f64,
        inv_h: f64,
    ) -> Substep {
        match self.env {
            Environment::Free => self.substeps::<KIND, FREE>(u_cmd, count, h, inv_h),
            Environment::Spring { .. } => self.substeps::<KIND, SPRING>(u_cmd, count, h, inv_h),
            Environment::Torque { .. } => self.substeps::<KIND, TORQUE>(u_cmd, count, h, inv_h),
            Environment::Wall { .. } => self.substeps::<KIND, WALL>(u_cmd, count, h, inv_h),
            Environment::Locked | Environment::Crank { .. } => {
                self.substeps::<KIND, KINEMATIC>(u_cmd, count, h, inv_h)
            }
        }
    }

    /// `count` substeps of length `h` with the (output-referred, saturated) command `u_cmd`
    /// held; returns the last substep's quantities. `KIND` is the structure ([`RIGID`],
    /// [`TWO_MASS`], [`THREE_MASS`]) and `ENV` the environment's kind ([`FREE`], …): both are
    /// compile-time constants, so each combination is its own loop without dispatch.
    ///
    /// Leapfrog form of drift–kick–drift: the second half-drift of one substep and the first
    /// half-drift of the next are one full drift, so positions are synchronised with velocities
    /// only at the ends of the step. A kinematic environment (lock, crank) imposes the output
    /// velocity for the whole step, every drift included, so a locked output does not creep and
    /// a crank's angle is exactly speed·t.
    ///
    /// Everything loop-invariant is copied into locals first and every law is inlined, so the
    /// state and the constants live in registers; absent effects cost a predictable branch.
    #[inline(never)]
    fn substeps<const KIND: u8, const ENV: u8>(
        &mut self,
        u_cmd: f64,
        count: usize,
        h: f64,
        inv_h: f64,
    ) -> Substep {
        let m = self.mech;
        let laws = &self.laws;
        let fl = laws.friction;
        let spring = self.spring;
        let has_additive = !laws.additive.is_empty();
        let dry = self.dry;
        let env = self.env;
        let (env_k, env_d, env_rest, env_t, vp) = match env {
            Environment::Spring {
                stiffness,
                damping,
                rest,
            } => (stiffness, damping, rest, 0.0, 0.0),
            Environment::Torque { torque } => (0.0, 0.0, 0.0, torque, 0.0),
            Environment::Crank { speed } => (0.0, 0.0, 0.0, 0.0, speed),
            _ => (0.0, 0.0, 0.0, 0.0, 0.0),
        };
        let cogging = self.periodic.cogging.as_ref();
        let ripple = self.periodic.ripple.as_ref();
        let ripple_gain = self.periodic.ripple_load_gain;
        let gravity = self.periodic.gravity.as_ref();
        let delay = &mut self.delay_line[..];
        let mut delay_pos = self.delay_pos;
        // The friction (and environment) node: the output, or the only node.
        let node = if KIND == RIGID { 0 } else { 2 };
        let (inertia, inv_inertia) = if KIND == RIGID {
            (m.i1, m.inv_i1)
        } else {
            (m.i2, m.inv_i2)
        };
        let h_over_i = h * inv_inertia;
        // h/I folded into one factor per node (a reassociation of h·(τ/I)).
        let h_over_i1 = h * m.inv_i1;
        let h_over_im = h * m.inv_im;
        let mut x = self.x;
        let mut v = self.v;
        let mut stuck = self.stuck;

        // Resisting torques on the motor node: cogging (its value at the current phase) and
        // additive torques at output-referred position `xm`.
        // The sums start at −0.0, the identity of IEEE addition (0.0 is not: 0.0 + −0.0 = 0.0),
        // so the compiler drops the start instead of adding it on the dependency chain.
        let motor_load = |cog: f64, xm: f64, vm: f64, load: f64| -> f64 {
            let mut r = -0.0;
            if cogging.is_some() {
                r += cog;
            }
            if has_additive {
                r += laws.additive_on(Node::Motor, xm, vm, load);
            }
            r
        };
        // Resisting torques at the output that are not friction or spring: additive torques,
        // ripple, gravity (values at their current phases; the rigid plant's output is its
        // only node).
        let output_load = |rip: f64, grav: f64, q: f64, vq: f64, load: f64| -> f64 {
            let mut r = -0.0;
            if has_additive {
                r += laws.additive_on(Node::Output, q, vq, load);
            }
            if ripple.is_some() {
                r += rip * (1.0 + ripple_gain * load.abs());
            }
            if gravity.is_some() {
                r += grav;
            }
            r
        };
        // The friction node at position `q` with velocity `v_old` at the start of the substep
        // and non-friction, non-environment torque `drive − load` (the position-dependent
        // `load` last, which keeps it off the front of the dependency chain): (new velocity,
        // friction, environment torque on the node, acceleration).
        let friction_node = |q: f64, v_old: f64, drive: f64, load: f64, stuck: &mut bool| {
            if ENV == KINEMATIC {
                let tau = drive - load;
                // The environment imposes the motion and carries the reaction.
                let f = if vp == 0.0 { 0.0 } else { fl.sliding(vp) };
                let a = (vp - v_old) * inv_h;
                *stuck = vp == 0.0;
                return (vp, f, inertia * a - tau + f, a);
            }
            let e = match ENV {
                FREE => 0.0,
                SPRING => -env_k * (q - env_rest) - env_d * v_old,
                TORQUE => env_t,
                _ => env.torque(q, v_old),
            };
            // (Free: no `+ 0.0` on the dependency chain.)
            let drive = if ENV == FREE { drive } else { drive + e };
            let (vn, f) = friction::advance(v_old, stuck, drive, load, h_over_i, &fl, dry);
            (vn, f, e, (vn - v_old) * inv_h)
        };

        // Start of the step: impose a kinematic environment's velocity (keeping the velocity
        // before, for the reaction's I·a) and drift half a substep.
        let mut before = v[node];
        if ENV == KINEMATIC {
            v[node] = vp;
            if node == 0 {
                v = [vp; 3];
            }
        }
        drift::<KIND>(&mut x, &v, 0.5 * h);
        // Phases of the periodic torques: reduced exactly here, then advanced by each drift's
        // increment (see `Harmonic::predict`), re-anchored every step so rounding cannot
        // accumulate beyond one step's ten increments.
        let mut cog = PhaseTrack::start(cogging, x[0], v[0], h);
        let mut rip = PhaseTrack::start(ripple, x[node], v[node], h);
        let mut grav = PhaseTrack::start(gravity, x[node], v[node], h);
        // The actuator chain is memoryless without a delay: shape once per step.
        let shaped = laws.actuator.shape(u_cmd);
        let mut out = Substep::default();
        for k in 0..count {
            let u = if delay.is_empty() {
                shaped
            } else {
                let old = delay[delay_pos];
                delay[delay_pos] = u_cmd;
                delay_pos += 1;
                if delay_pos == delay.len() {
                    delay_pos = 0;
                }
                laws.actuator.shape(old)
            };
            // Forces at the current (mid-step) positions, full velocity update.
            let sub = match KIND {
                RIGID => {
                    let [q, _, _] = x;
                    let vq = v[0];
                    let load = output_load(rip.value, grav.value, q, vq, u)
                        + motor_load(cog.value, q, vq, u);
                    let (vn, f, e, a) = friction_node(q, before, u - m.b1 * vq, load, &mut stuck);
                    v = [vn; 3];
                    Substep {
                        applied: u,
                        motor_accel: a,
                        transmission: u,
                        friction: f,
                        env: e,
                        accel: a,
                    }
                }
                TWO_MASS => {
                    let [x0, _, x2] = x;
                    let [v0, _, v2] = v;
                    let tt = spring.torque(x0 - x2, v0 - v2);
                    // The spring torque arrives last (it depends on both positions): subtract it last.
                    let net0 = ((u - m.b1 * v0) - motor_load(cog.value, x0, v0, tt)) - tt;
                    let a0 = net0 * m.inv_i1;
                    let v0n = v0 + net0 * h_over_i1;
                    let load = output_load(rip.value, grav.value, x2, v2, tt);
                    let (vn, f, e, a) = friction_node(x2, before, tt - m.b2 * v2, load, &mut stuck);
                    v = [v0n, v0n, vn];
                    Substep {
                        applied: u,
                        motor_accel: a0,
                        transmission: tt,
                        friction: f,
                        env: e,
                        accel: a,
                    }
                }
                _ => {
                    let [x0, x1, x2] = x;
                    let [v0, v1, v2] = v;
                    let ts = m.ks * (x0 - x1) + m.cs * (v0 - v1);
                    let tt = spring.torque(x1 - x2, v1 - v2);
                    let net0 = ((u - m.b1 * v0) - motor_load(cog.value, x0, v0, ts)) - ts;
                    let a0 = net0 * m.inv_i1;
                    let net1 = ts - tt;
                    let load = output_load(rip.value, grav.value, x2, v2, tt);
                    let (vn, f, e, a) = friction_node(x2, before, tt - m.b2 * v2, load, &mut stuck);
                    v = [v0 + net0 * h_over_i1, v1 + net1 * h_over_im, vn];
                    Substep {
                        applied: u,
                        motor_accel: a0,
                        transmission: tt,
                        friction: f,
                        env: e,
                        accel: a,
                    }
                }
            };
            // Only the last substep's quantities are kept (kept out of registers meanwhile).
            if k + 1 == count {
                out = sub;
            }
            before = v[node];
            let d = if k + 1 == count { 0.5 * h } else { h };
            drift::<KIND>(&mut x, &v, d);
            if k + 1 < count {
                cog.advance(cogging, v[0]);
                rip.advance(ripple, v[node]);
                grav.advance(gravity, v[node]);
            }
        }
        // The nodes `drift` skipped move with the motor node (rigid: all three).
        self.x = match KIND {
            RIGID => [x[0]; 3],
            TWO_MASS => [x[0], x[0], x[2]],
            _ => x,
        };
        self.v = v;
        self.stuck = stuck;
        self.delay_pos = delay_pos;
        out
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

/// Positions advance by `d`·velocity. Only the nodes that exist move: in a rigid plant all
/// three positions are the one node's, in a 2-mass plant the middle node is the motor node
/// (same start, same velocity, hence bit-identical updates) — skipping them keeps the substep
/// loop's state in fewer registers.
#[inline(always)]
fn drift<const KIND: u8>(x: &mut [f64; 3], v: &[f64; 3], d: f64) {
    match KIND {
        RIGID => x[0] += d * v[0],
        TWO_MASS => {
            x[0] += d * v[0];
            x[2] += d * v[2];
        }
        _ => {
            for i in 0..3 {
                x[i] += d * v[i];
            }
        }
    }
}

/// [`Plant::substeps`]' structure kinds.
const RIGID: u8 = 0;
const TWO_MASS: u8 = 1;
const THREE_MASS: u8 = 2;
/// [`Plant::substeps`]' environment kinds.
const FREE: u8 = 0;
const SPRING: u8 = 1;
const TORQUE: u8 = 2;
const WALL: u8 = 3;
const KINEMATIC: u8 = 4;

/// The position-periodic torques in the integrator's form; `None` where the amplitude is
/// zero, so an absent effect costs nothing.
#[derive(Clone, Debug)]
struct Periodics {
    /// Motor cogging as a function of the output-referred motor node position (k·N).
    cogging: Option<Harmonic>,
    /// Transmission ripple at its zero-load amplitude.
    ripple: Option<Harmonic>,
    /// Ripple amplitude growth per N·m of transmitted torque.
    ripple_load_gain: f64,
    /// Gravity.
    gravity: Option<Harmonic>,
}

impl Periodics {
    fn new(laws: &EffectLaws, n: f64) -> Self {
        let make =
            |p: &PeriodicTorque, k: f64| (!p.is_zero()).then(|| Harmonic::new(p.sin, p.cos, k));
        Self {
            cogging: make(&laws.cogging, laws.cogging.wavenumber * n),
            ripple: make(&laws.ripple, laws.ripple.wavenumber),
            ripple_load_gain: laws.ripple.load_gain,
            gravity: make(&laws.gravity, laws.gravity.wavenumber),
        }
    }
}

/// The transmission spring ([`crate::effects::SpringLaw`]: backlash gap, soft zone, stiff
/// branch, damping while engaged) as a function of the raw deflection: on each branch the
/// torque is `k·δ + (c + damping·δ̇)` with the gap and the knee folded into `c`, so the
/// substep computes one multiply and one add after the deflection instead of subtracting the
/// gap, then the knee, then multiplying, adding the knee torque and the damping (four fewer
/// operations on the dependency chain; the branches are predictable). The same curve up to
/// rounding.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct PiecewiseSpring {
    /// Half the backlash gap: no torque for |δ| ≤ gap.
    gap: f64,
    /// Deflection where the stiff branch starts: gap + knee deflection.
    knee: f64,
    k_soft: f64,
    /// Soft branch offset, −k_soft·gap (for δ > 0; negated for δ < 0).
    c_soft: f64,
    k_hard: f64,
    /// Stiff branch offset, knee torque − k_hard·(gap + knee deflection).
    c_hard: f64,
    damping: f64,
}

impl PiecewiseSpring {
    fn new(s: &crate::effects::SpringLaw) -> Self {
        let gap = 0.5 * s.backlash;
        let knee = gap + s.knee_deflection;
        Self {
            gap,
            knee,
            k_soft: s.k_soft,
            c_soft: -s.k_soft * gap,
            k_hard: s.k_hard,
            c_hard: s.knee_torque - s.k_hard * knee,
            damping: s.damping,
        }
    }

    /// Transmitted torque at deflection `d` and deflection rate `dd` (as
    /// [`crate::effects::SpringLaw::torque`]).
    #[inline(always)]
    fn torque(&self, d: f64, dd: f64) -> f64 {
        let (k, c) = if d > self.knee {
            (self.k_hard, self.c_hard)
        } else if d < -self.knee {
            (self.k_hard, -self.c_hard)
        } else if d > self.gap {
            (self.k_soft, self.c_soft)
        } else if d < -self.gap {
            (self.k_soft, -self.c_soft)
        } else {
            return 0.0;
        };
        // The offset and the damping (from the velocities) are ready before the deflection.
        k * d + (c + self.damping * dd)
    }
}

/// A periodic torque's [`Phase`] carried through the substeps of one step. Only the torque
/// and the next anchor are kept between substeps (the phase itself is dead once both are
/// computed), which keeps the loop's state in registers.
#[derive(Clone, Copy, Debug, Default)]
struct PhaseTrack {
    /// The torque where this substep evaluates it (0 for an absent harmonic).
    value: f64,
    /// The phase re-centred for the next substep (computed from this one's phase, off the
    /// dependency chain through the velocity).
    anchor: Phase,
    /// Table steps per unit velocity over one substep: h·k·N/2π.
    per_velocity: f64,
}

impl PhaseTrack {
    /// Exact phase at `q`; the velocity `v` of the drift that led here guesses the next
    /// increment. Inert for an absent harmonic.
    #[inline(always)]
    fn start(harmonic: Option<&Harmonic>, q: f64, v: f64, h: f64) -> Self {
        match harmonic {
            Some(hm) => {
                let per_velocity = h * hm.steps_per_unit();
                let now = hm.phase(q);
                Self {
                    value: hm.at(now),
                    anchor: Harmonic::predict(now, per_velocity * v),
                    per_velocity,
                }
            }
            None => Self::default(),
        }
    }

    /// Move on by a full drift with velocity `v` and evaluate the torque there.
    #[inline(always)]
    fn advance(&mut self, harmonic: Option<&Harmonic>, v: f64) {
        if let Some(hm) = harmonic {
            let inc = self.per_velocity * v;
            let now = Harmonic::advance(self.anchor, inc);
            self.value = hm.at(now);
            self.anchor = Harmonic::predict(now, inc);
        }
    }
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
