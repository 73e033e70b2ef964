//! Force (torque) control P / PD / PI / PID on `τD − τsensor` (notes §2.3–2.6):
//!
//! `τm = Ke(τD − τenv) − Be·ṙ + Ki·T·Σ(τD − τenv)` where the damping signal `ṙ` is one of
//! * force rate `τ̇env` by backward difference (LSB per tick) through a first-order low-pass —
//!   the thesis's implementation ("digital differentiation plus low-pass filtering", §2.3);
//!   usable only with small Be, too much force-rate D destabilises;
//! * input (motor) velocity ẋ1 — the thesis's recommended fix (Eqn 3.3.16, Eqn 5.2):
//!   "no hard limit on electronic damping", stability no longer eroded by sensor stiffness Kf.
//!
//! Units: τD and τenv are output-side torque in 0.1 mN·m; the gains carry the 1/N of the
//! transmission (`units::force_gains`), so the output is motor torque.

use super::pid::{PidConfig, PidState};
use crate::fixed_math::{sat_i32, Alpha, Flags, LowPass, Output, Torque, Vel};

/// Where the force law's D term comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ForceDamping {
    /// No D term (P or PI force control).
    #[default]
    None,
    /// D on the force rate (backward difference, low-passed with `alpha`); `kd` in torque LSB
    /// per (sensor LSB per tick).
    ForceRate {
        /// Low-pass coefficient α in (0, 1] (1 = unfiltered).
        alpha: Alpha,
    },
    /// D on the motor velocity ẋ1; `kd` in torque LSB per (1/16 count/s).
    InputVelocity,
}

/// Force law configuration.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ForceConfig {
    /// Gains and limits: `kp` dimensionless (motor LSB per sensor LSB, includes 1/N), `ki_t` in
    /// 2⁻¹⁶ motor LSB per sensor LSB per tick, `kd` per [`ForceDamping`].
    pub pid: PidConfig,
    /// D source.
    pub damping: ForceDamping,
}

/// Force law state: integrator, force-rate differentiator and its filter.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ForceLaw {
    /// PID core state.
    pub pid: PidState,
    last_tau: Torque,
    primed: bool,
    rate_lp: LowPass,
}

impl ForceLaw {
    /// Fresh state.
    pub const NEW: ForceLaw = ForceLaw {
        pid: PidState::ZERO,
        last_tau: 0,
        primed: false,
        rate_lp: LowPass::NEW,
    };

    /// Prime the force-rate differentiator with the current sensor value (zero rate), so that
    /// entering force mode does not see a stale difference.
    pub fn prime(&mut self, tau_env: Torque) {
        self.last_tau = tau_env;
        self.primed = true;
        self.rate_lp.reset(0);
    }

    /// The damping signal this step would use, *without* updating the differentiator.
    fn rate(&self, cfg: &ForceConfig, tau_env: Torque, v1: Vel) -> (i32, LowPass) {
        match cfg.damping {
            ForceDamping::None => (0, self.rate_lp),
            ForceDamping::InputVelocity => (v1.to_bits(), self.rate_lp),
            ForceDamping::ForceRate { alpha } => {
                let d = if self.primed {
                    sat_i32(i64::from(tau_env).saturating_sub(i64::from(self.last_tau))).0
                } else {
                    0
                };
                let mut lp = self.rate_lp;
                let r = lp.step(d, alpha);
                (r, lp)
            }
        }
    }

    /// One step: desired output torque `tau_d`, sensor torque `tau_env`, motor velocity `v1`.
    #[inline]
    pub fn step(&mut self, cfg: &ForceConfig, tau_d: Torque, tau_env: Torque, v1: Vel) -> Output {
        let (e, clamped) = sat_i32(i64::from(tau_d).saturating_sub(i64::from(tau_env)));
        let (r, lp) = self.rate(cfg, tau_env, v1);
        self.rate_lp = lp;
        self.last_tau = tau_env;
        self.primed = true;
        let mut out = self.pid.step(&cfg.pid, e, r);
        out.flags.set_if(clamped, Flags::INPUT_CLAMPED);
        out
    }
}
