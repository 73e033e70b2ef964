//! SI gains → machine gains, and the discrete stability guard (notes §1 "gain scaling", §2.9).
//!
//! Runs at **configuration time** (supervisor before sending, or the card at commit), never
//! in the 1 kHz path, so `f64` is used for the conversions (a [`Gain`] mantissa has 31 bits,
//! more than `f32` carries) and `micromath` for the one transcendental (`exp` of the low-pass
//! coefficient), called by UFCS (`micromath::F32Ext::exp(x)`) so host tests run the same
//! approximation as the firmware (toolchain.md §0). The card-side commit check
//! [`pd_stability_int`] uses integers only.
//!
//! Conventions (see `fixed_math` for the machine units):
//! * Colocated position/impedance gains are given **motor side** (N·m/rad, N·m·s/rad of the
//!   motor shaft). For an output-side behaviour use [`motor_gain_from_output`]: motor gain =
//!   output gain / N² (thesis: 8.41 = (29/10)² "resulting in 3 times the bandwidth").
//! * Non-colocated gains are given **output side** (N·m/rad of the output, output torque);
//!   the motor delivers 1/N of it.
//! * Force gains follow the thesis (notes §2): everything reflected to the motor, so a
//!   dimensionless Ke means motor torque = Ke·(τD − τenv)/N; force-rate Be is in seconds.
//! * Integral gains Ki: motor N·m per (rad·s) (position) or 1/s (force).

// `!(x >= 0.0)` is used on purpose: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::nonminimal_bool)]

use crate::fixed_math::{Alpha, Gain, Torque, GAIN_MAX_SHIFT, VEL_FRAC_BITS};
use crate::proto::scale::MOTOR_TORQUE_NM_PER_LSB;

use crate::laws::{
    DamperConfig, Feedback, ForceConfig, ForceDamping, FrictionConfig, ImpCompConfig,
    ImpedanceConfig, InputDamping, PidConfig, PositionConfig, RippleError, RippleTable, RIPPLE_MAX,
};
use crate::sensing::ObserverConfig;

const TWO_PI: f64 = core::f64::consts::TAU;

/// Why a conversion was refused. `what` names the parameter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum UnitsError {
    /// NaN or infinite input.
    NotFinite {
        /// Parameter name.
        what: &'static str,
    },
    /// The value does not fit its machine format (`value` in machine units).
    Overflow {
        /// Parameter name.
        what: &'static str,
        /// Machine-unit value that did not fit.
        value: f64,
    },
    /// A non-zero value rounds to zero (or loses more than 0.1 % to rounding) in its format.
    RoundsToZero {
        /// Parameter name.
        what: &'static str,
        /// Machine-unit value that was too small.
        value: f64,
    },
    /// A value is outside its documented range (e.g. negative Coulomb torque).
    OutOfRange {
        /// Parameter name.
        what: &'static str,
    },
    /// The scale itself is invalid (zero cpr, non-positive T or N).
    BadScale {
        /// Parameter name.
        what: &'static str,
    },
    /// The ripple table was refused.
    Ripple(RippleError),
    /// The velocity observer would be unstable or mis-sized.
    Observer,
}

impl core::fmt::Display for UnitsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            UnitsError::NotFinite { what } => write!(f, "{what}: not a finite number"),
            UnitsError::Overflow { what, value } => {
                write!(f, "{what}: {value:e} machine units does not fit its format")
            }
            UnitsError::RoundsToZero { what, value } => {
                write!(
                    f,
                    "{what}: {value:e} machine units rounds to zero / loses precision"
                )
            }
            UnitsError::OutOfRange { what } => write!(f, "{what}: out of range"),
            UnitsError::BadScale { what } => write!(f, "scale: {what} invalid"),
            UnitsError::Ripple(e) => write!(f, "ripple table: {e:?}"),
            UnitsError::Observer => write!(f, "velocity observer: unstable or invalid"),
        }
    }
}

/// Relative rounding error above which a gain is refused as imprecise.
pub const MAX_REL_ROUNDING: f64 = 1.0e-3;

/// Represent a real gain as a [`Gain`] with the largest shift that keeps the mantissa in
/// `i32` (relative error ≤ 2⁻³⁰ for any value in [2⁻³¹, 2³¹)). Errors: not finite;
/// |v| ≥ 2³¹ (`Overflow`); non-zero v that rounds to zero or loses more than
/// [`MAX_REL_ROUNDING`] (`RoundsToZero`). Exactly 0.0 gives `Gain::ZERO`.
pub fn gain_from_f64(what: &'static str, v: f64) -> Result<Gain, UnitsError> {
    if !v.is_finite() {
        return Err(UnitsError::NotFinite { what });
    }
    if v == 0.0 {
        return Ok(Gain::ZERO);
    }
    let lim = 2147483647.0; // i32::MAX
    if v.abs() >= lim {
        return Err(UnitsError::Overflow { what, value: v });
    }
    let mut shift: u8 = 0;
    let mut scaled = v;
    // Bounded loop: at most 62 doublings.
    while shift < GAIN_MAX_SHIFT && (scaled * 2.0).abs() < lim {
        scaled *= 2.0;
        shift = shift.saturating_add(1);
    }
    let m = round_half_away(scaled);
    if m == 0.0 || ((m - scaled) / scaled).abs() > MAX_REL_ROUNDING {
        return Err(UnitsError::RoundsToZero { what, value: v });
    }
    Gain::from_parts(m as i32, shift).ok_or(UnitsError::Overflow { what, value: v })
}

/// Round half away from zero (core has no `f64::round` without std). Every SI → machine
/// conversion of the crate rounds here, so the card and a supervisor round alike.
pub(crate) fn round_half_away(x: f64) -> f64 {
    let t = x as i64 as f64; // trunc for |x| < 2⁶³
    let r = x - t;
    if r >= 0.5 {
        t + 1.0
    } else if r <= -0.5 {
        t - 1.0
    } else {
        t
    }
}

/// N·m → torque LSB of the scale (`i32`).
pub fn torque_lsb(s: &Scale, what: &'static str, nm: f64) -> Result<Torque, UnitsError> {
    s.check()?;
    if !nm.is_finite() {
        return Err(UnitsError::NotFinite { what });
    }
    let v = round_half_away(nm / s.torque_lsb_nm);
    if v.abs() > 2147483647.0 {
        return Err(UnitsError::Overflow { what, value: v });
    }
    Ok(v as i32)
}

/// A torque limit that reaches the `i16` command: 0 < LSB ≤ 32767.
pub fn torque_limit(s: &Scale, what: &'static str, nm: f64) -> Result<Torque, UnitsError> {
    let t = torque_lsb(s, what, nm)?;
    if t > i32::from(i16::MAX) {
        return Err(UnitsError::Overflow {
            what,
            value: f64::from(t),
        });
    }
    if t <= 0 {
        return Err(UnitsError::OutOfRange { what });
    }
    Ok(t)
}

/// The thesis's gain-scaling rule: the motor gain giving the same output behaviour is the
/// output gain divided by N² (notes §1, §2.10).
pub fn motor_gain_from_output(k_out: f64, gear_ratio: f64) -> f64 {
    k_out / (gear_ratio * gear_ratio)
}

/// Km = 1 − Ia/Id (notes §2.8): actual and desired output inertia.
pub fn km_from_inertia(actual: f64, desired: f64) -> f64 {
    1.0 - actual / desired
}

/// Loop period, encoders and transmission.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scale {
    /// Card period T, s (1 ms).
    pub period_s: f64,
    /// Motor encoder counts per motor revolution.
    pub motor_cpr: u32,
    /// Output encoder counts per output revolution (0 if none).
    pub output_cpr: u32,
    /// Gear ratio N (motor rev per output rev).
    pub gear_ratio: f64,
    /// Size of one torque LSB in N·m (the card's: the wire's [`MOTOR_TORQUE_NM_PER_LSB`] =
    /// 0.1 mN·m). All torque-valued machine quantities (commands, limits, sensor values) are in
    /// this LSB. The parameter table ([`crate::card::si`]) is always in the wire's LSB.
    pub torque_lsb_nm: f64,
}

impl Scale {
    /// The thesis card: T = 1 ms, 2304 cpr, no output encoder, N as given, 0.1 mN·m LSB.
    pub fn thesis(gear_ratio: f64) -> Self {
        Scale {
            period_s: 1.0e-3,
            motor_cpr: 2304,
            output_cpr: 0,
            gear_ratio,
            torque_lsb_nm: MOTOR_TORQUE_NM_PER_LSB,
        }
    }

    fn check(&self) -> Result<(), UnitsError> {
        if !(self.period_s.is_finite() && self.period_s > 0.0) {
            return Err(UnitsError::BadScale { what: "period_s" });
        }
        if self.motor_cpr == 0 {
            return Err(UnitsError::BadScale { what: "motor_cpr" });
        }
        if !(self.gear_ratio.is_finite() && self.gear_ratio > 0.0) {
            return Err(UnitsError::BadScale { what: "gear_ratio" });
        }
        if !(self.torque_lsb_nm.is_finite() && self.torque_lsb_nm > 0.0) {
            return Err(UnitsError::BadScale {
                what: "torque_lsb_nm",
            });
        }
        Ok(())
    }

    /// Loop rate in Hz (rounded).
    pub fn rate_hz(&self) -> u16 {
        round_half_away(1.0 / self.period_s).clamp(1.0, 65535.0) as u16
    }

    /// Radians per motor-encoder count (no check: a zero cpr gives infinity, which the
    /// conversions that use it refuse as not finite or out of range).
    pub fn motor_rad_per_count(&self) -> f64 {
        TWO_PI / f64::from(self.motor_cpr)
    }

    /// Radians per count of the encoder a law feeds back.
    fn rad_per_count(&self, fb: Feedback) -> Result<f64, UnitsError> {
        self.check()?;
        match fb {
            Feedback::Colocated => Ok(self.motor_rad_per_count()),
            Feedback::NonColocated => {
                if self.output_cpr == 0 {
                    Err(UnitsError::BadScale { what: "output_cpr" })
                } else {
                    Ok(TWO_PI / f64::from(self.output_cpr))
                }
            }
        }
    }

    /// Motor torque per unit of SI torque at the fed-back side (1 motor side, 1/N output side).
    fn torque_factor(&self, fb: Feedback) -> f64 {
        match fb {
            Feedback::Colocated => 1.0,
            Feedback::NonColocated => 1.0 / self.gear_ratio,
        }
    }

    /// Rad/s per `Vel` LSB (1/16 count/s) of the encoder.
    fn rad_s_per_vel_lsb(&self, fb: Feedback) -> Result<f64, UnitsError> {
        Ok(self.rad_per_count(fb)? / f64::from(1u32 << VEL_FRAC_BITS))
    }
}

/// Stiffness N·m/rad → torque LSB per count.
pub fn stiffness_gain(
    s: &Scale,
    fb: Feedback,
    what: &'static str,
    k: f64,
) -> Result<Gain, UnitsError> {
    gain_from_f64(
        what,
        k * s.torque_factor(fb) * s.rad_per_count(fb)? / s.torque_lsb_nm,
    )
}

/// Damping N·m·s/rad → torque LSB per `Vel` LSB.
pub fn damping_gain(
    s: &Scale,
    fb: Feedback,
    what: &'static str,
    b: f64,
) -> Result<Gain, UnitsError> {
    gain_from_f64(
        what,
        b * s.torque_factor(fb) * s.rad_s_per_vel_lsb(fb)? / s.torque_lsb_nm,
    )
}

/// Position PD/PID gains in SI (side given by `feedback`, see module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionSi {
    /// Ke, N·m/rad.
    pub ke: f64,
    /// Be, N·m·s/rad.
    pub be: f64,
    /// Ki, N·m/(rad·s).
    pub ki: f64,
    /// Integrator limit, motor N·m.
    pub i_limit_nm: f64,
    /// Output limit, motor N·m.
    pub tau_max_nm: f64,
    /// Encoder fed back.
    pub feedback: Feedback,
}

/// Build a [`PositionConfig`] (backward difference: Ki·T per tick, integrator in Q16 torque).
pub fn position_config(s: &Scale, g: &PositionSi) -> Result<PositionConfig, UnitsError> {
    let fb = g.feedback;
    let kp = stiffness_gain(s, fb, "ke", g.ke)?;
    let kd = damping_gain(s, fb, "be", g.be)?;
    let ki_t = gain_from_f64(
        "ki",
        g.ki * s.period_s * s.torque_factor(fb) * s.rad_per_count(fb)? / s.torque_lsb_nm * 65536.0,
    )?;
    let i_limit = if g.ki == 0.0 {
        0
    } else {
        torque_limit(s, "i_limit", g.i_limit_nm)?
    };
    Ok(PositionConfig {
        pid: PidConfig {
            kp,
            kd,
            ki_t,
            i_limit,
            tau_max: torque_limit(s, "tau_max", g.tau_max_nm)?,
        },
        feedback: fb,
    })
}

/// Damper mode −Bdes·ω (motor N·m·s/rad).
pub fn damper_config(s: &Scale, b: f64, tau_max_nm: f64) -> Result<DamperConfig, UnitsError> {
    Ok(DamperConfig {
        b: damping_gain(s, Feedback::Colocated, "b_des", b)?,
        tau_max: torque_limit(s, "tau_max", tau_max_nm)?,
    })
}

/// Input damping −B1e·ẋ1 (motor N·m·s/rad).
pub fn input_damping(s: &Scale, b1e: f64) -> Result<InputDamping, UnitsError> {
    Ok(InputDamping {
        b1e: damping_gain(s, Feedback::Colocated, "b1e", b1e)?,
    })
}

/// D source of the force law, SI.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ForceDampingSi {
    /// No D term.
    None,
    /// Be on the force rate, seconds, low-passed at `cutoff_hz`.
    ForceRate {
        /// Be, s.
        be_s: f64,
        /// Low-pass cutoff, Hz (≥ rate: unfiltered).
        cutoff_hz: f64,
    },
    /// Be on the motor velocity, motor N·m·s/rad.
    InputVelocity {
        /// Be, N·m·s/rad.
        be: f64,
    },
}

/// Force P/PD/PI/PID in SI (thesis convention: reflected to the motor).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceSi {
    /// Ke, dimensionless.
    pub ke: f64,
    /// Ki, 1/s.
    pub ki: f64,
    /// D source.
    pub damping: ForceDampingSi,
    /// Integrator limit, motor N·m.
    pub i_limit_nm: f64,
    /// Output limit, motor N·m.
    pub tau_max_nm: f64,
}

/// Build a [`ForceConfig`].
pub fn force_config(s: &Scale, g: &ForceSi) -> Result<ForceConfig, UnitsError> {
    s.check()?;
    let n = s.gear_ratio;
    let kp = gain_from_f64("ke", g.ke / n)?;
    let ki_t = gain_from_f64("ki", g.ki * s.period_s / n * 65536.0)?;
    let (kd, damping) = match g.damping {
        ForceDampingSi::None => (Gain::ZERO, ForceDamping::None),
        ForceDampingSi::ForceRate { be_s, cutoff_hz } => (
            gain_from_f64("be", be_s / (n * s.period_s))?,
            ForceDamping::ForceRate {
                alpha: lowpass_alpha(s, cutoff_hz)?,
            },
        ),
        ForceDampingSi::InputVelocity { be } => (
            damping_gain(s, Feedback::Colocated, "be", be)?,
            ForceDamping::InputVelocity,
        ),
    };
    let i_limit = if g.ki == 0.0 {
        0
    } else {
        torque_limit(s, "i_limit", g.i_limit_nm)?
    };
    Ok(ForceConfig {
        pid: PidConfig {
            kp,
            kd,
            ki_t,
            i_limit,
            tau_max: torque_limit(s, "tau_max", g.tau_max_nm)?,
        },
        damping,
    })
}

/// First-order low-pass coefficient α = 1 − e^{−2π·fc·T} (U1F15). `micromath` exp, UFCS.
pub fn lowpass_alpha(s: &Scale, cutoff_hz: f64) -> Result<Alpha, UnitsError> {
    if !(cutoff_hz.is_finite() && cutoff_hz > 0.0) {
        return Err(UnitsError::OutOfRange { what: "cutoff_hz" });
    }
    let x = (TWO_PI * cutoff_hz * s.period_s) as f32;
    let a = 1.0 - micromath::F32Ext::exp(-x);
    let bits = round_half_away(f64::from(a) * 32768.0).clamp(0.0, 32768.0) as u16;
    if bits == 0 {
        return Err(UnitsError::RoundsToZero {
            what: "cutoff_hz",
            value: f64::from(a),
        });
    }
    Ok(Alpha::from_bits(bits))
}

/// Impedance law in SI: Ke, Be at the fed-back side (see module docs), Km dimensionless.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImpedanceSi {
    /// Ke, N·m/rad.
    pub ke: f64,
    /// Be, N·m·s/rad.
    pub be: f64,
    /// Km = 1 − Ia/Id, < 1.
    pub km: f64,
    /// Output limit, motor N·m.
    pub tau_max_nm: f64,
    /// Encoder fed back.
    pub feedback: Feedback,
}

/// Build an [`ImpedanceConfig`]. Km must be < 1 (notes §2.8).
pub fn impedance_config(s: &Scale, g: &ImpedanceSi) -> Result<ImpedanceConfig, UnitsError> {
    if g.km.is_nan() || g.km >= 1.0 {
        return Err(UnitsError::OutOfRange { what: "km" });
    }
    s.check()?;
    Ok(ImpedanceConfig {
        ke: stiffness_gain(s, g.feedback, "ke", g.ke)?,
        be: damping_gain(s, g.feedback, "be", g.be)?,
        km: gain_from_f64("km", g.km / s.gear_ratio)?,
        tau_max: torque_limit(s, "tau_max", g.tau_max_nm)?,
        feedback: g.feedback,
    })
}

/// Friction compensation in SI (motor side).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrictionSi {
    /// τc⁺, N·m (≥ 0).
    pub tau_c_pos: f64,
    /// τc⁻ magnitude, N·m (≥ 0).
    pub tau_c_neg: f64,
    /// Ramp half-width ω_r, motor rad/s (> 0).
    pub ramp_rad_s: f64,
    /// Viscous compensation, N·m·s/rad (≥ 0).
    pub viscous: f64,
    /// Under-compensation factor in [0, 1.5] (default 0.8).
    pub undercomp: f64,
    /// Output limit, N·m.
    pub limit_nm: f64,
}

/// Build a [`FrictionConfig`].
pub fn friction_config(s: &Scale, g: &FrictionSi) -> Result<FrictionConfig, UnitsError> {
    if !(g.tau_c_pos >= 0.0) {
        return Err(UnitsError::OutOfRange { what: "tau_c_pos" });
    }
    if !(g.tau_c_neg >= 0.0) {
        return Err(UnitsError::OutOfRange { what: "tau_c_neg" });
    }
    if !(g.ramp_rad_s > 0.0) {
        return Err(UnitsError::OutOfRange { what: "ramp_rad_s" });
    }
    if !(g.viscous >= 0.0) {
        return Err(UnitsError::OutOfRange { what: "viscous" });
    }
    if !(0.0..=1.5).contains(&g.undercomp) {
        return Err(UnitsError::OutOfRange { what: "undercomp" });
    }
    let ramp_vel = g.ramp_rad_s / s.rad_s_per_vel_lsb(Feedback::Colocated)?;
    let pos = torque_lsb(s, "tau_c_pos", g.tau_c_pos)?;
    let neg = torque_lsb(s, "tau_c_neg", g.tau_c_neg)?;
    Ok(FrictionConfig {
        tau_c_pos: pos,
        tau_c_neg: neg,
        slope_pos: gain_from_f64("tau_c_pos/ramp", f64::from(pos) / ramp_vel)?,
        slope_neg: gain_from_f64("tau_c_neg/ramp", f64::from(neg) / ramp_vel)?,
        viscous: damping_gain(s, Feedback::Colocated, "viscous", g.viscous)?,
        undercomp: Alpha::from_bits(round_half_away(g.undercomp * 32768.0) as u16),
        limit: torque_limit(s, "limit", g.limit_nm)?,
        alpha: Alpha::ONE,
    })
}

/// Impedance compensation in SI.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImpCompSi {
    /// Kd, desired output stiffness N·m/rad (output side).
    pub kd_out: f64,
    /// Kc, dimensionless compensation gain (motor torque reflected per output torque).
    pub kc: f64,
    /// Low-pass cutoff, Hz.
    pub cutoff_hz: f64,
    /// Output limit, motor N·m.
    pub limit_nm: f64,
    /// Encoder the main law feeds back (Δx is measured there).
    pub feedback: Feedback,
}

/// Build an [`ImpCompConfig`]. With colocated feedback Δx is in motor counts, i.e. N× the
/// output angle, which the gain accounts for.
pub fn imp_comp_config(s: &Scale, g: &ImpCompSi) -> Result<ImpCompConfig, UnitsError> {
    let rad_out_per_count = match g.feedback {
        Feedback::Colocated => s.rad_per_count(Feedback::Colocated)? / s.gear_ratio,
        Feedback::NonColocated => s.rad_per_count(Feedback::NonColocated)?,
    };
    Ok(ImpCompConfig {
        kd: gain_from_f64("kd_out", g.kd_out * rad_out_per_count / s.torque_lsb_nm)?,
        gain: gain_from_f64("kc", g.kc / s.gear_ratio)?,
        alpha: lowpass_alpha(s, g.cutoff_hz)?,
        limit: torque_limit(s, "limit", g.limit_nm)?,
    })
}

/// Ripple table from corrections in N·m (motor side) over `period_counts` motor counts.
pub fn ripple_table(s: &Scale, period_counts: u32, nm: &[f64]) -> Result<RippleTable, UnitsError> {
    if nm.len() > RIPPLE_MAX {
        return Err(UnitsError::Ripple(RippleError::Length));
    }
    let mut buf = [0i16; RIPPLE_MAX];
    for (slot, v) in buf.iter_mut().zip(nm.iter()) {
        let t = torque_lsb(s, "ripple", *v)?;
        *slot = i16::try_from(t).map_err(|_| UnitsError::Overflow {
            what: "ripple",
            value: f64::from(t),
        })?;
    }
    let entries = buf.get(..nm.len()).unwrap_or(&[]);
    RippleTable::new(period_counts, entries).map_err(UnitsError::Ripple)
}

/// Velocity observer from a bandwidth ω = 2π·f (Hz) and damping ζ: α = 2ζωT, β = (ωT)²
/// (see `sensing::ObserverConfig`). `max_jump` in counts.
pub fn observer_config(
    s: &Scale,
    bandwidth_hz: f64,
    zeta: f64,
    max_jump: i32,
) -> Result<ObserverConfig, UnitsError> {
    s.check()?;
    if !(bandwidth_hz > 0.0 && zeta > 0.0 && bandwidth_hz.is_finite() && zeta.is_finite()) {
        return Err(UnitsError::Observer);
    }
    let wt = TWO_PI * bandwidth_hz * s.period_s;
    let one = f64::from(1u32 << 24);
    let a = round_half_away(2.0 * zeta * wt * one);
    let b = round_half_away(wt * wt * one);
    if !(a >= 1.0 && b >= 1.0 && a < 4.0 * one && b < 4.0 * one) {
        return Err(UnitsError::Observer);
    }
    ObserverConfig::new(a as u32, b as u32, s.rate_hz(), max_jump).map_err(|_| UnitsError::Observer)
}

/// Rotor inertia (kg·m², motor side incl. reflected load you want to count on) as the machine
/// inertia J: torque LSB per (count/tick²). Used by [`pd_stability_int`].
pub fn inertia_gain(s: &Scale, inertia: f64) -> Result<Gain, UnitsError> {
    if !(inertia > 0.0) {
        return Err(UnitsError::OutOfRange { what: "inertia" });
    }
    let rad = s.rad_per_count(Feedback::Colocated)?;
    gain_from_f64(
        "inertia",
        inertia * rad / (s.period_s * s.period_s) / s.torque_lsb_nm,
    )
}

// ----------------------------------------------------------------------------------------
// Stability guard (notes §2.9)
// ----------------------------------------------------------------------------------------

/// Default safety margin of the stability guard: gains must stay within 80 % of the
/// theoretical bounds (kd ≤ 0.8·2 and kp ≤ 0.8·kp_max(kd)). 20 % covers the model's
/// optimism: the §2.9 closed form assumes a rigid rotor with no passive damping and no
/// computation delay, and the thesis reports its own predictions agree "to within small error
/// margins (less than 20%)" (§2.7).
pub const DEFAULT_MARGIN: f64 = 0.2;

/// Result of the stability guard.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PdStability {
    /// kp = Ke·T²/I.
    pub kp: f64,
    /// kd = Be·T/I.
    pub kd: f64,
    /// Theoretical bound kp_max(kd) = 2kd(2−kd)/(2+kd).
    pub kp_max: f64,
}

/// Why the stability guard refused a gain pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StabilityError {
    /// Inputs not finite / not positive where required (I, T).
    BadInput,
    /// kd ≤ 0: a rigid rotor under pure P control with backward difference is unstable.
    NoDamping,
    /// kd beyond (1 − margin)·2: the velocity loop overshoots every sample.
    TooMuchDamping,
    /// kp < 0.
    NegativeStiffness,
    /// kp beyond (1 − margin)·kp_max(kd).
    TooStiff,
}

/// The §2.9 discrete stability guard for motor-side PD with backward-difference D on a rigid
/// rotor (I·θ̈ = τ, zero-order hold, period T): with kp = Ke·T²/I and kd = Be·T/I the loop is
/// stable iff 0 < kd < 2 and 0 < kp < 2kd(2−kd)/(2+kd) (max kp ≈ 0.686 at kd ≈ 0.83: with
/// I = 10⁻⁵ kg·m², T = 1 ms, Ke < 6.9 N·m/rad). Refused with `margin` (fraction, e.g.
/// [`DEFAULT_MARGIN`]). kp = 0 (damper mode) is accepted. Passive damping only helps, so the
/// guard is conservative; a low-bandwidth velocity observer adds lag and is *not* covered —
/// keep the observer bandwidth well above the loop's (e.g. ≥ 5×).
pub fn pd_stability(
    ke: f64,
    be: f64,
    inertia: f64,
    period_s: f64,
    margin: f64,
) -> Result<PdStability, StabilityError> {
    if !(inertia > 0.0 && period_s > 0.0 && ke.is_finite() && be.is_finite())
        || !(0.0..1.0).contains(&margin)
    {
        return Err(StabilityError::BadInput);
    }
    let kp = ke * period_s * period_s / inertia;
    let kd = be * period_s / inertia;
    let f = 1.0 - margin;
    if !(kd > 0.0) {
        return Err(StabilityError::NoDamping);
    }
    if kd >= 2.0 * f {
        return Err(StabilityError::TooMuchDamping);
    }
    if kp < 0.0 {
        return Err(StabilityError::NegativeStiffness);
    }
    let kp_max = 2.0 * kd * (2.0 - kd) / (2.0 + kd);
    if kp > f * kp_max {
        return Err(StabilityError::TooStiff);
    }
    Ok(PdStability { kp, kd, kp_max })
}

/// `num/den · 2^(32 + e)` as a Q32 value (both ≥ 0), `None` if it exceeds 2⁹⁶.
fn q32_ratio(num: u64, num_shift: u8, den: u64, den_shift: u8) -> Option<u128> {
    // value = (num / 2^ns) / (den / 2^ds) · 2^32 = num·2^(32+ds) / (den·2^ns)
    if den == 0 {
        return None;
    }
    let up = 32u32.checked_add(u32::from(den_shift))?;
    let down = u32::from(num_shift);
    let (n, d) = if up >= down {
        let sh = up.checked_sub(down)?;
        if sh > 64 {
            // num < 2⁶³ ⇒ the shifted value would exceed 2¹²⁷; treat as "huge".
            return None;
        }
        (u128::from(num).checked_shl(sh)?, u128::from(den))
    } else {
        let sh = down.checked_sub(up)?;
        (u128::from(num), u128::from(den).checked_shl(sh)?)
    };
    let q = n.checked_div(d)?;
    if q > (1u128 << 96) {
        None
    } else {
        Some(q)
    }
}

/// Integer version of [`pd_stability`] for the card at commit (no floats): `ke` (torque LSB
/// per count), `be` (torque LSB per 1/16 count/s), `inertia` J from [`inertia_gain`] (torque
/// LSB per count/tick²), `rate_hz`, margin in percent (e.g. 20). kp = ke/J, kd = be·16·rate/J,
/// evaluated exactly in Q32 with `u128` intermediates.
pub fn pd_stability_int(
    ke: Gain,
    be: Gain,
    inertia: Gain,
    rate_hz: u16,
    margin_pct: u8,
) -> Result<(), StabilityError> {
    if inertia.mant() <= 0 || rate_hz == 0 || margin_pct >= 100 {
        return Err(StabilityError::BadInput);
    }
    if be.mant() <= 0 {
        return Err(StabilityError::NoDamping);
    }
    if ke.mant() < 0 {
        return Err(StabilityError::NegativeStiffness);
    }
    let one: u128 = 1 << 32;
    let j = u64::from(inertia.mant().unsigned_abs());
    let be_num = u64::from(be.mant().unsigned_abs())
        .checked_mul(
            u64::from(rate_hz)
                .checked_mul(16)
                .ok_or(StabilityError::BadInput)?,
        )
        .ok_or(StabilityError::BadInput)?;
    let kd =
        q32_ratio(be_num, be.shift(), j, inertia.shift()).ok_or(StabilityError::TooMuchDamping)?;
    let kp = q32_ratio(
        u64::from(ke.mant().unsigned_abs()),
        ke.shift(),
        j,
        inertia.shift(),
    )
    .ok_or(StabilityError::TooStiff)?;
    let f = u128::from(
        100u8
            .checked_sub(margin_pct)
            .ok_or(StabilityError::BadInput)?,
    );
    // kd·100 < f·2·ONE
    let two = one.checked_mul(2).ok_or(StabilityError::BadInput)?;
    if kd.checked_mul(100).ok_or(StabilityError::TooMuchDamping)?
        >= f.checked_mul(two).ok_or(StabilityError::BadInput)?
    {
        return Err(StabilityError::TooMuchDamping);
    }
    if kd == 0 {
        return Err(StabilityError::NoDamping);
    }
    // kp·(2 + kd)·100 ≤ f·2·kd·(2 − kd), all in Q32 (products < 2⁹⁶·2³⁴·2⁷ … bounded: kd < 2³³).
    if kp > one.checked_mul(4).ok_or(StabilityError::BadInput)? {
        return Err(StabilityError::TooStiff);
    }
    let lhs = kp
        .checked_mul(two.checked_add(kd).ok_or(StabilityError::BadInput)?)
        .and_then(|v| v.checked_mul(100))
        .ok_or(StabilityError::TooStiff)?;
    let rhs = f
        .checked_mul(2)
        .and_then(|v| v.checked_mul(kd))
        .and_then(|v| v.checked_mul(two.checked_sub(kd)?))
        .ok_or(StabilityError::BadInput)?;
    if lhs > rhs {
        return Err(StabilityError::TooStiff);
    }
    Ok(())
}
