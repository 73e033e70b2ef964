//! SI values → the raw `i32`s of the parameter table (`proto::params`), for supervisors.
//!
//! The inverse of the scaling in [`super::config`]: a supervisor holding gains in N·m/rad,
//! N·m·s/rad, N·m, kg·m² calls these to fill `ParamWrite` frames, and gets a typed error
//! when a value does not fit its wire format (rather than a silently wrapped number). Runs on
//! the supervisor or at configuration time, never in the 1 kHz step.
//!
//! Of a [`Scale`] these read the period and the motor encoder only: the table's gains are per
//! motor count, and its torques are in the wire's LSBs (`proto::scale`), whatever
//! `Scale::torque_lsb_nm` says. The exception is Ke and Be in the non-colocated modes, which
//! act on output-encoder counts: for an output-side Ke pass Ke·cpr_motor/(N·cpr_output), the
//! motor gain giving the same torque per output count (Be likewise).

use crate::proto::params::{self as p, ParamDef};
use crate::proto::scale::{MOTOR_TORQUE_NM_PER_LSB, OUTPUT_TORQUE_NM_PER_LSB};
use crate::units::{round_half_away, Scale};

/// Why an SI value has no raw form.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SiError {
    /// NaN or infinite.
    NotFinite {
        /// Parameter id.
        param: u16,
    },
    /// Outside the table's range for the parameter after scaling.
    OutOfRange {
        /// Parameter id.
        param: u16,
    },
    /// Non-zero but rounds to raw 0 (a gain too small for its Q format).
    RoundsToZero {
        /// Parameter id.
        param: u16,
    },
}

/// Rounds `v` and range-checks it against the table row of `param`.
pub fn raw(param: u16, v: f64) -> Result<i32, SiError> {
    if !v.is_finite() {
        return Err(SiError::NotFinite { param });
    }
    let def: &ParamDef = p::lookup(param).map_err(|_| SiError::OutOfRange { param })?;
    let r = round_half_away(v);
    if v != 0.0 && r == 0.0 {
        return Err(SiError::RoundsToZero { param });
    }
    if r < f64::from(def.min) || r > f64::from(def.max) {
        return Err(SiError::OutOfRange { param });
    }
    Ok(r as i32)
}

/// Stiffness Ke [N·m/rad] → `KE` (Q16.16 τLSB per count).
pub fn stiffness(s: &Scale, ke: f64) -> Result<i32, SiError> {
    raw(
        p::KE,
        ke / MOTOR_TORQUE_NM_PER_LSB * s.motor_rad_per_count() * 65536.0,
    )
}

/// A damping [N·m·s/rad] → a "Q16.16 τLSB per (count/tick)" parameter (`BE`, `B1E`,
/// `VISCOUS_*`, `QUICK_STOP_DAMPING`).
pub fn damping(param: u16, s: &Scale, b: f64) -> Result<i32, SiError> {
    raw(
        param,
        b / MOTOR_TORQUE_NM_PER_LSB * s.motor_rad_per_count() / s.period_s * 65536.0,
    )
}

/// Integral gain Ki [N·m/(rad·s)] → `KI` (Q16.16 τLSB per count·tick).
pub fn integral(s: &Scale, ki: f64) -> Result<i32, SiError> {
    raw(
        p::KI,
        ki / MOTOR_TORQUE_NM_PER_LSB * s.motor_rad_per_count() * s.period_s * 65536.0,
    )
}

/// A motor torque [N·m] → τLSB parameter (`TORQUE_LIMIT`, `COULOMB_*`, ripple entries, …).
pub fn torque(param: u16, nm: f64) -> Result<i32, SiError> {
    raw(param, nm / MOTOR_TORQUE_NM_PER_LSB)
}

/// An output torque [N·m] → τoLSB parameter (`OUTPUT_TORQUE_LIMIT`).
pub fn output_torque(param: u16, nm: f64) -> Result<i32, SiError> {
    raw(param, nm / OUTPUT_TORQUE_NM_PER_LSB)
}

/// A dimensionless motor-per-output torque gain (force Kp, Km/N, impedance-comp gain) →
/// Q16.16 τLSB per τoLSB.
pub fn torque_ratio(param: u16, k: f64) -> Result<i32, SiError> {
    raw(
        param,
        k * OUTPUT_TORQUE_NM_PER_LSB / MOTOR_TORQUE_NM_PER_LSB * 65536.0,
    )
}

/// Force-rate gain [N·m per (N·m/s)] → `FORCE_KD` (Q16.16 τLSB per (τoLSB/tick)).
pub fn force_rate(s: &Scale, kd: f64) -> Result<i32, SiError> {
    raw(
        p::FORCE_KD,
        kd / s.period_s * OUTPUT_TORQUE_NM_PER_LSB / MOTOR_TORQUE_NM_PER_LSB * 65536.0,
    )
}

/// Force integral gain [N·m per (N·m·s)] → `FORCE_KI` (Q16.16 τLSB per (τoLSB·tick)).
pub fn force_integral(s: &Scale, ki: f64) -> Result<i32, SiError> {
    raw(
        p::FORCE_KI,
        ki * s.period_s * OUTPUT_TORQUE_NM_PER_LSB / MOTOR_TORQUE_NM_PER_LSB * 65536.0,
    )
}

/// Output-side stiffness for impedance compensation [N·m/rad] → `IMPEDANCE_COMP_STIFFNESS`
/// (Q16.16 τoLSB per count).
pub fn output_stiffness(s: &Scale, k: f64) -> Result<i32, SiError> {
    raw(
        p::IMPEDANCE_COMP_STIFFNESS,
        k / OUTPUT_TORQUE_NM_PER_LSB * s.motor_rad_per_count() * 65536.0,
    )
}

/// Rotor inertia [kg·m²] → `ROTOR_INERTIA` (1e-9 kg·m²).
pub fn inertia(j: f64) -> Result<i32, SiError> {
    raw(p::ROTOR_INERTIA, j * 1e9)
}

/// A velocity [rad/s] → counts/s parameter (`VELOCITY_LIMIT`, `STANDSTILL_VELOCITY`, …).
pub fn velocity(param: u16, s: &Scale, w: f64) -> Result<i32, SiError> {
    raw(param, w / s.motor_rad_per_count())
}

/// A fraction in [0, 1] → Q0.16 (`UNDER_COMPENSATION`, filters, margins).
pub fn fraction(param: u16, f: f64) -> Result<i32, SiError> {
    raw(param, f * 65536.0)
}

/// Inverse of [`stiffness`], for read-back and reports.
pub fn stiffness_si(s: &Scale, raw: i32) -> f64 {
    f64::from(raw) / 65536.0 * MOTOR_TORQUE_NM_PER_LSB / s.motor_rad_per_count()
}

/// Inverse of [`damping`].
pub fn damping_si(s: &Scale, raw: i32) -> f64 {
    f64::from(raw) / 65536.0 * MOTOR_TORQUE_NM_PER_LSB / s.motor_rad_per_count() * s.period_s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_gains_round_trip_within_one_lsb() {
        let s = Scale::thesis(1.0);
        let k = stiffness(&s, 2.0).unwrap();
        assert!(
            (stiffness_si(&s, k) - 2.0).abs()
                < 2.0 / 65536.0 * MOTOR_TORQUE_NM_PER_LSB / s.motor_rad_per_count() + 1e-9
        );
        let b = damping(p::BE, &s, 0.01).unwrap();
        assert!((damping_si(&s, b) - 0.01).abs() / 0.01 < 1e-6);
    }

    #[test]
    fn errors_name_the_parameter() {
        let s = Scale::thesis(1.0);
        assert_eq!(
            stiffness(&s, -1.0),
            Err(SiError::OutOfRange { param: p::KE })
        );
        assert_eq!(
            stiffness(&s, f64::NAN),
            Err(SiError::NotFinite { param: p::KE })
        );
        assert_eq!(
            torque(p::TORQUE_LIMIT, 5.0),
            Err(SiError::OutOfRange {
                param: p::TORQUE_LIMIT
            })
        );
        assert_eq!(
            stiffness(&s, 1e-12),
            Err(SiError::RoundsToZero { param: p::KE })
        );
    }
}
