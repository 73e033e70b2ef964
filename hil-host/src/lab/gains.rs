//! Gains in SI units, as a control engineer states them (output side, like the thesis's
//! "desired output stiffness 1.1 N·m/deg"), and their translation into the card's parameter
//! table with the thesis's motor-gain = output-gain / N² rule. The same §2.9 stability guard
//! the card applies at commit ([`controller::card::config`]) runs here before anything is
//! sent, so the supervisor refuses an unstable set (unless forced) and can say why.

use anyhow::{anyhow, Result};
use controller::card::config;
use controller::card::si;
use controller::card::ParamStore;
use controller::proto::params::{self as p, WatchdogReaction};
use controller::proto::scale::MOTOR_TORQUE_NM_PER_LSB;
use controller::proto::Mode;
use controller::units::{motor_gain_from_output, Scale};

/// The joint the gains are for: the card's own scale (period, encoders, transmission, torque
/// LSB, which [`si`] converts with) and the rotor inertia its stability guard needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointScale {
    /// The card's scale.
    pub card: Scale,
    /// Rotor (input) inertia at the motor, kg·m² (the stability guard's I).
    pub rotor_inertia: f64,
}

impl JointScale {
    /// A card at `period_s` with the wire's torque LSB. Counts per revolution are whole on a
    /// card, as the parameter table sends them: a model's are rounded here.
    pub fn new(
        period_s: f64,
        motor_cpr: f64,
        output_cpr: f64,
        gear_ratio: f64,
        rotor_inertia: f64,
    ) -> Self {
        JointScale {
            card: Scale {
                period_s,
                motor_cpr: motor_cpr.round() as u32,
                output_cpr: output_cpr.round() as u32,
                gear_ratio,
                torque_lsb_nm: MOTOR_TORQUE_NM_PER_LSB,
            },
            rotor_inertia,
        }
    }

    /// Gear ratio N (motor rev per output rev).
    pub fn gear_ratio(&self) -> f64 {
        self.card.gear_ratio
    }

    /// Control period, s.
    pub fn period_s(&self) -> f64 {
        self.card.period_s
    }

    /// Motor encoder counts per motor revolution.
    pub fn motor_cpr(&self) -> f64 {
        f64::from(self.card.motor_cpr)
    }

    /// Motor counts per output radian.
    pub fn motor_counts_per_output_rad(&self) -> f64 {
        self.motor_cpr() * self.gear_ratio() / std::f64::consts::TAU
    }

    /// Counts per output radian of the encoder `mode` feeds back: the output encoder's in
    /// the non-colocated modes (their setpoints and Ke, Be are per output count, protocol
    /// §"Modes"), the motor's otherwise, and the motor's when there is no output encoder (the
    /// card refuses such a mode itself, and says why).
    pub fn counts_per_output_rad(&self, mode: Mode) -> f64 {
        if mode.needs_output_encoder() && self.card.output_cpr > 0 {
            f64::from(self.card.output_cpr) / std::f64::consts::TAU
        } else {
            self.motor_counts_per_output_rad()
        }
    }
}

/// Friction feed-forward (output side, N·m and N·m·s/rad).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrictionComp {
    /// τc⁺.
    pub coulomb_pos: f64,
    /// τc⁻ (magnitude).
    pub coulomb_neg: f64,
    /// Viscous compensation.
    pub viscous: f64,
    /// Under-compensation factor (thesis: "slightly below"; default 0.8).
    pub under: f64,
    /// Half-width of the ramp through zero velocity, output rad/s.
    pub ramp_velocity: f64,
    /// Cut-off of the low-pass on the velocity it acts on, Hz (0 = none): well below the
    /// rotor's mode against the transmission (see `controller::laws::friction`).
    pub filter_hz: f64,
    /// Act on the setpoint's velocity (a feed-forward on the reference: the supervisor must
    /// send it) instead of the measured one.
    pub on_setpoint: bool,
}

/// Entries of the card's ripple table.
pub const RIPPLE_ENTRIES: usize = p::RIPPLE_TABLE_LEN as usize;

/// Position-periodic feed-forward through the card's ripple table: `len` corrections
/// (output-referred N·m) spread evenly over `period_counts` motor counts from count 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RippleFf {
    /// Motor counts per period.
    pub period_counts: u32,
    /// Entries used (2..=64).
    pub len: usize,
    /// The corrections, output N·m.
    pub table: [f64; RIPPLE_ENTRIES],
}

/// Feed-forward of loads that depend on position alone (output-referred N·m): they are
/// what they are at any speed, so unlike friction they are given in full.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Feedforward {
    /// Constant torque (an offset the model measured).
    pub offset: f64,
    /// Gravity: `sin·sin θ + cos·cos θ`, θ the output angle from motor count 0.
    pub gravity_sin: f64,
    /// See `gravity_sin`.
    pub gravity_cos: f64,
    /// Ripple / cogging table.
    pub ripple: Option<RippleFf>,
}

/// A gain set, output-side SI. Zero means "term off".
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GainSet {
    /// Desired output stiffness Ke, N·m/rad.
    pub stiffness: f64,
    /// Desired output damping Be, N·m·s/rad.
    pub damping: f64,
    /// Integral gain, N·m/(rad·s).
    pub integral: f64,
    /// Integrator limit, N·m at the motor.
    pub integrator_limit: f64,
    /// Input-velocity damping B1e, output-referred N·m·s/rad.
    pub input_damping: f64,
    /// Force P gain (motor N·m per output N·m of error).
    pub force_kp: f64,
    /// Force-rate gain, s.
    pub force_kd: f64,
    /// Force integral gain, 1/s.
    pub force_ki: f64,
    /// Impedance Km = 1 − Ia/Id.
    pub km: f64,
    /// Motor torque limit, N·m.
    pub torque_limit: f64,
    /// Output velocity limit, rad/s.
    pub velocity_limit: f64,
    /// Quick-stop damping, output N·m·s/rad.
    pub quick_stop_damping: f64,
    /// Friction compensation.
    pub friction: Option<FrictionComp>,
    /// Offset, gravity and ripple feed-forward.
    pub feedforward: Feedforward,
    /// Supervisor watchdog timeout, ms.
    pub watchdog_ms: u32,
    /// Watchdog reaction.
    pub watchdog_reaction: WatchdogReaction,
    /// The card's sensor timeout, µs (`None`: the card's default, 3000 µs). A card that
    /// drives the motor and hears no sensor frame for longer faults with `SensorTimeout`;
    /// in real time on a machine that stalls, this is what such a stall runs into.
    pub sensor_timeout_us: Option<u32>,
    /// Telemetry every N ticks.
    pub telemetry_divider: u16,
    /// Fraction of the §2.9 discrete PD bound the card admits (its `stability_margin`).
    pub stability_fraction: f64,
}

impl Default for GainSet {
    fn default() -> Self {
        GainSet {
            stiffness: 0.0,
            damping: 0.0,
            integral: 0.0,
            integrator_limit: 0.5,
            input_damping: 0.0,
            force_kp: 0.0,
            force_kd: 0.0,
            force_ki: 0.0,
            km: 0.0,
            torque_limit: 2.0,
            velocity_limit: 20.0,
            quick_stop_damping: 0.0,
            friction: None,
            feedforward: Feedforward::default(),
            watchdog_ms: 200,
            watchdog_reaction: WatchdogReaction::QuickStop,
            sensor_timeout_us: None,
            telemetry_divider: 1,
            stability_fraction: 0.5,
        }
    }
}

fn si_err(e: si::SiError) -> anyhow::Error {
    let (what, param) = match e {
        si::SiError::NotFinite { param } => ("is not finite", param),
        si::SiError::OutOfRange { param } => ("is out of range for its wire format", param),
        si::SiError::RoundsToZero { param } => ("is too small for its wire format", param),
    };
    let name = p::lookup(param).map(|d| d.name).unwrap_or("?");
    anyhow!("gain `{name}` (param {param:#06x}) {what}")
}

/// The low-pass coefficient 1 − e^(−2πfT) of a cut-off `hz` (0 = none: 1).
fn lowpass_fraction(hz: f64, period_s: f64) -> f64 {
    if hz > 0.0 {
        1.0 - (-std::f64::consts::TAU * hz * period_s).exp()
    } else {
        1.0
    }
}

/// A feed-forward torque (motor N·m) in τLSB: one below half an LSB is 0, not an error (a
/// table's entries pass through zero).
fn ff_torque(param: u16, nm: f64) -> Result<i32, si::SiError> {
    if nm.abs() < 0.5 * MOTOR_TORQUE_NM_PER_LSB {
        return Ok(0);
    }
    si::torque(param, nm)
}

impl GainSet {
    /// The parameter entries for this set on `joint` (plant constants included), for `mode`.
    pub fn entries(&self, j: &JointScale, mode: Mode) -> Result<Vec<(u16, i32)>> {
        let n = j.gear_ratio();
        let m = j.card;
        let mg = |k: f64| motor_gain_from_output(k, n);
        // Ke and Be act on the fed-back encoder's counts: `si` scales per motor count, so a
        // non-colocated gain goes in as the motor gain giving the same torque per output count.
        let law_gain =
            |k: f64| mg(k) * j.motor_counts_per_output_rad() / j.counts_per_output_rad(mode);
        let mut e = vec![
            (
                p::ROTOR_INERTIA,
                si::inertia(j.rotor_inertia).map_err(si_err)?,
            ),
            (p::MOTOR_COUNTS_PER_REV, m.motor_cpr as i32),
            (p::OUTPUT_COUNTS_PER_REV, m.output_cpr as i32),
            (p::GEAR_RATIO, (n * 65536.0).round() as i32),
            (
                p::KE,
                si::stiffness(&m, law_gain(self.stiffness)).map_err(si_err)?,
            ),
            (
                p::BE,
                si::damping(p::BE, &m, law_gain(self.damping)).map_err(si_err)?,
            ),
            (p::KI, si::integral(&m, mg(self.integral)).map_err(si_err)?),
            (
                p::INTEGRATOR_LIMIT,
                si::torque(p::INTEGRATOR_LIMIT, self.integrator_limit).map_err(si_err)?,
            ),
            (
                p::FORCE_INTEGRATOR_LIMIT,
                si::torque(p::FORCE_INTEGRATOR_LIMIT, self.integrator_limit).map_err(si_err)?,
            ),
            (
                p::B1E,
                si::damping(p::B1E, &m, mg(self.input_damping)).map_err(si_err)?,
            ),
            (
                p::FORCE_KP,
                si::torque_ratio(p::FORCE_KP, self.force_kp).map_err(si_err)?,
            ),
            (
                p::FORCE_KD,
                si::force_rate(&m, self.force_kd).map_err(si_err)?,
            ),
            (
                p::FORCE_KI,
                si::force_integral(&m, self.force_ki).map_err(si_err)?,
            ),
            (p::KM, si::torque_ratio(p::KM, self.km / n).map_err(si_err)?),
            (
                p::TORQUE_LIMIT,
                si::torque(p::TORQUE_LIMIT, self.torque_limit).map_err(si_err)?,
            ),
            (
                p::VELOCITY_LIMIT,
                si::velocity(p::VELOCITY_LIMIT, &m, self.velocity_limit * n).map_err(si_err)?,
            ),
            (
                p::QUICK_STOP_DAMPING,
                si::damping(p::QUICK_STOP_DAMPING, &m, mg(self.quick_stop_damping))
                    .map_err(si_err)?,
            ),
            (p::SUPERVISOR_TIMEOUT, self.watchdog_ms as i32),
            (p::WATCHDOG_REACTION, self.watchdog_reaction.as_u8().into()),
            (p::TELEMETRY_DIVIDER, self.telemetry_divider.into()),
            (
                p::STABILITY_MARGIN,
                si::fraction(p::STABILITY_MARGIN, self.stability_fraction).map_err(si_err)?,
            ),
        ];
        if let Some(us) = self.sensor_timeout_us {
            e.push((p::SENSOR_TIMEOUT, i32::try_from(us).unwrap_or(i32::MAX)));
        }
        match self.friction {
            Some(f) => e.extend([
                (p::FRICTION_ENABLE, 1),
                (
                    p::COULOMB_POS,
                    si::torque(p::COULOMB_POS, f.coulomb_pos / n).map_err(si_err)?,
                ),
                (
                    p::COULOMB_NEG,
                    si::torque(p::COULOMB_NEG, f.coulomb_neg / n).map_err(si_err)?,
                ),
                (
                    p::VISCOUS_POS,
                    si::damping(p::VISCOUS_POS, &m, mg(f.viscous)).map_err(si_err)?,
                ),
                (
                    p::VISCOUS_NEG,
                    si::damping(p::VISCOUS_NEG, &m, mg(f.viscous)).map_err(si_err)?,
                ),
                (
                    p::UNDER_COMPENSATION,
                    si::fraction(p::UNDER_COMPENSATION, f.under).map_err(si_err)?,
                ),
                (
                    p::FRICTION_DEADBAND,
                    si::velocity(p::FRICTION_DEADBAND, &m, f.ramp_velocity * n).map_err(si_err)?,
                ),
                (p::FRICTION_SOURCE, i32::from(f.on_setpoint)),
                (
                    p::FRICTION_FILTER,
                    si::fraction(
                        p::FRICTION_FILTER,
                        lowpass_fraction(f.filter_hz, m.period_s),
                    )
                    .map_err(si_err)?,
                ),
            ]),
            None => e.push((p::FRICTION_ENABLE, 0)),
        }
        let ff = &self.feedforward;
        e.extend([
            (
                p::TORQUE_OFFSET,
                ff_torque(p::TORQUE_OFFSET, ff.offset / n).map_err(si_err)?,
            ),
            (
                p::GRAVITY_SIN,
                ff_torque(p::GRAVITY_SIN, ff.gravity_sin / n).map_err(si_err)?,
            ),
            (
                p::GRAVITY_COS,
                ff_torque(p::GRAVITY_COS, ff.gravity_cos / n).map_err(si_err)?,
            ),
        ]);
        match &ff.ripple {
            Some(r) => {
                let period = i32::try_from(r.period_counts).map_err(|_| {
                    anyhow!("ripple period of {} counts is too long", r.period_counts)
                })?;
                e.extend([
                    (p::RIPPLE_ENABLE, 1),
                    (p::RIPPLE_PERIOD, period),
                    (p::RIPPLE_LENGTH, r.len as i32),
                    (p::RIPPLE_PHASE, 0),
                ]);
                for (i, v) in r.table.iter().take(r.len).enumerate() {
                    e.push((
                        p::RIPPLE_TABLE + i as u16,
                        ff_torque(p::RIPPLE_TABLE, v / n).map_err(si_err)?,
                    ));
                }
            }
            None => e.push((p::RIPPLE_ENABLE, 0)),
        }
        Ok(e)
    }
}

/// Runs the card's own configuration check (conversion + §2.9 stability guard) on the card
/// defaults overlaid with `entries`, for `mode`. `Err` says what the card would refuse.
pub fn check(entries: &[(u16, i32)], mode: Mode) -> Result<()> {
    if entries.len() > p::STAGING_CAPACITY {
        return Err(anyhow!(
            "the gain set has {} parameters and the card stages {} at a time: use a shorter \
             ripple table",
            entries.len(),
            p::STAGING_CAPACITY
        ));
    }
    for &(id, v) in entries {
        if let Err(s) = controller::card::store::check_write(id, v, false) {
            let name = p::lookup(id).map(|d| d.name).unwrap_or("?");
            return Err(anyhow!("param `{name}` = {v}: {}", s.name()));
        }
    }
    let mut store = ParamStore::new();
    store.apply(entries);
    config::build(&store, Some(mode))
        .map(|_| ())
        .map_err(|e| match e {
            config::ConfigError::Unstable { why } => anyhow!(
                "the stability guard refuses these gains ({why:?}): outside the discrete \
             rigid-rotor PD region of thesis §2.9 with the configured rotor inertia and period \
             (use --force to send anyway)"
            ),
            other => anyhow!("the card would refuse this set: {other:?}"),
        })
}

/// A gains file (`--gains FILE.toml`): any field of [`GainSet`] in the same output-side SI
/// units, the rest kept from the scenario. Unknown keys are refused, so a misspelt gain is an
/// error rather than a gain left at its default.
#[derive(Clone, Debug, Default, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GainsFile {
    /// N·m/rad.
    pub stiffness: Option<f64>,
    /// N·m·s/rad.
    pub damping: Option<f64>,
    /// N·m/(rad·s).
    pub integral: Option<f64>,
    /// N·m at the motor.
    pub integrator_limit: Option<f64>,
    /// N·m·s/rad (output-referred).
    pub input_damping: Option<f64>,
    /// Motor N·m per output N·m.
    pub force_kp: Option<f64>,
    /// s.
    pub force_kd: Option<f64>,
    /// 1/s.
    pub force_ki: Option<f64>,
    /// 1 − Ia/Id.
    pub km: Option<f64>,
    /// N·m at the motor.
    pub torque_limit: Option<f64>,
    /// rad/s at the output.
    pub velocity_limit: Option<f64>,
    /// N·m·s/rad.
    pub quick_stop_damping: Option<f64>,
    /// Fraction of the §2.9 bound the card admits.
    pub stability_fraction: Option<f64>,
    /// `[friction]`: friction compensation.
    pub friction: Option<FrictionFile>,
    /// `[feedforward]`: offset, gravity, ripple table.
    pub feedforward: Option<FeedforwardFile>,
}

/// `[friction]` of a gains file (output side).
#[derive(Clone, Copy, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrictionFile {
    /// N·m.
    pub coulomb_pos: f64,
    /// N·m (magnitude).
    pub coulomb_neg: f64,
    /// N·m·s/rad.
    #[serde(default)]
    pub viscous: f64,
    /// Under-compensation factor.
    #[serde(default = "default_under")]
    pub under: f64,
    /// Half-width of the ramp through zero, output rad/s.
    pub ramp_velocity: f64,
    /// Cut-off of the velocity low-pass, Hz (0 = none).
    #[serde(default)]
    pub filter_hz: f64,
    /// Act on the setpoint's velocity (the supervisor's reference) instead of the measured.
    #[serde(default)]
    pub on_setpoint: bool,
}

fn default_under() -> f64 {
    0.8
}

/// `[feedforward]` of a gains file (output N·m).
#[derive(Clone, Debug, Default, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FeedforwardFile {
    /// Constant.
    #[serde(default)]
    pub offset: f64,
    /// × sin of the output angle.
    #[serde(default)]
    pub gravity_sin: f64,
    /// × cos of the output angle.
    #[serde(default)]
    pub gravity_cos: f64,
    /// `[feedforward.ripple]`.
    pub ripple: Option<RippleFile>,
}

/// `[feedforward.ripple]`: 2..=64 corrections (output N·m) over `period_counts` motor counts.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RippleFile {
    /// Motor counts per period.
    pub period_counts: u32,
    /// The corrections.
    pub table: Vec<f64>,
}

impl GainsFile {
    /// Reads and checks `path`.
    pub fn load(path: &std::path::Path) -> Result<GainsFile> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| anyhow!("cannot read the gains file {}: {e}", path.display()))?;
        let g: GainsFile =
            toml::from_str(&text).map_err(|e| anyhow!("gains file {}: {e}", path.display()))?;
        g.check()
            .map_err(|e| anyhow!("gains file {}: {e}", path.display()))?;
        Ok(g)
    }

    fn check(&self) -> Result<()> {
        let mut all = vec![
            ("stiffness", self.stiffness),
            ("damping", self.damping),
            ("integral", self.integral),
            ("integrator_limit", self.integrator_limit),
            ("input_damping", self.input_damping),
            ("force_kp", self.force_kp),
            ("force_kd", self.force_kd),
            ("force_ki", self.force_ki),
            ("km", self.km),
            ("torque_limit", self.torque_limit),
            ("velocity_limit", self.velocity_limit),
            ("quick_stop_damping", self.quick_stop_damping),
            ("stability_fraction", self.stability_fraction),
        ];
        if let Some(f) = &self.friction {
            all.extend([
                ("friction.coulomb_pos", Some(f.coulomb_pos)),
                ("friction.coulomb_neg", Some(f.coulomb_neg)),
                ("friction.viscous", Some(f.viscous)),
                ("friction.ramp_velocity", Some(f.ramp_velocity)),
                ("friction.filter_hz", Some(f.filter_hz)),
            ]);
            if !(f.under > 0.0 && f.under <= 1.0) {
                return Err(anyhow!("friction.under must be in (0, 1], got {}", f.under));
            }
        }
        for (name, v) in all {
            match v {
                Some(x) if !x.is_finite() => return Err(anyhow!("`{name}` is not a number")),
                Some(x) if x < 0.0 && name != "km" => {
                    return Err(anyhow!("`{name}` = {x} must not be negative"))
                }
                _ => {}
            }
        }
        if let Some(r) = self.feedforward.as_ref().and_then(|f| f.ripple.as_ref()) {
            if !(2..=RIPPLE_ENTRIES).contains(&r.table.len()) {
                return Err(anyhow!(
                    "feedforward.ripple.table has {} entries; the card takes 2 to {RIPPLE_ENTRIES}",
                    r.table.len()
                ));
            }
            if (r.period_counts as usize) < r.table.len() {
                return Err(anyhow!(
                    "feedforward.ripple.period_counts {} is shorter than its table",
                    r.period_counts
                ));
            }
            if r.table.iter().any(|v| !v.is_finite()) {
                return Err(anyhow!(
                    "feedforward.ripple.table holds a value that is not a number"
                ));
            }
        }
        Ok(())
    }

    /// Overlays the file on `g`.
    pub fn apply(&self, g: &mut GainSet) {
        let set = |dst: &mut f64, v: Option<f64>| {
            if let Some(v) = v {
                *dst = v;
            }
        };
        set(&mut g.stiffness, self.stiffness);
        set(&mut g.damping, self.damping);
        set(&mut g.integral, self.integral);
        set(&mut g.integrator_limit, self.integrator_limit);
        set(&mut g.input_damping, self.input_damping);
        set(&mut g.force_kp, self.force_kp);
        set(&mut g.force_kd, self.force_kd);
        set(&mut g.force_ki, self.force_ki);
        set(&mut g.km, self.km);
        set(&mut g.torque_limit, self.torque_limit);
        set(&mut g.velocity_limit, self.velocity_limit);
        set(&mut g.quick_stop_damping, self.quick_stop_damping);
        set(&mut g.stability_fraction, self.stability_fraction);
        if let Some(f) = self.friction {
            g.friction = Some(FrictionComp {
                coulomb_pos: f.coulomb_pos,
                coulomb_neg: f.coulomb_neg,
                viscous: f.viscous,
                under: f.under,
                ramp_velocity: f.ramp_velocity,
                filter_hz: f.filter_hz,
                on_setpoint: f.on_setpoint,
            });
        }
        if let Some(ff) = &self.feedforward {
            g.feedforward = Feedforward {
                offset: ff.offset,
                gravity_sin: ff.gravity_sin,
                gravity_cos: ff.gravity_cos,
                ripple: ff.ripple.as_ref().map(|r| {
                    let mut table = [0.0; RIPPLE_ENTRIES];
                    for (d, s) in table.iter_mut().zip(&r.table) {
                        *d = *s;
                    }
                    RippleFf {
                        period_counts: r.period_counts,
                        len: r.table.len(),
                        table,
                    }
                }),
            };
        }
    }
}
