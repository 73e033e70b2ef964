//! Impedance compensation (notes §2.12, Fig 4.20): feed-forward
//! `τff = Kc · LPF( Kd·Δx − F_measured )` — the desired output torque from the position error
//! minus the measured output torque, i.e. the torque deficit the transmission (friction,
//! ripple) is eating. The thesis ran it at 10 Hz with one sample of delay and it destabilised
//! with backlash + high gain; here it runs at 1 kHz with its own gain Kc and a first-order
//! low-pass (α = 1 − e^{−ωc·T}) against sensor noise. Useful for quasi-static tasks only
//! (§2.12); the limit bounds what it can inject.

use crate::fixed_math::{
    clamp_sym, pos_error, sat_i32, Alpha, Counts, Flags, Gain, LowPass, Output, Torque,
};

/// Impedance compensation configuration.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImpCompConfig {
    /// Kd: desired *output-side* torque LSB per count of the fed-back encoder.
    pub kd: Gain,
    /// Kc/N: motor LSB per output torque LSB.
    pub gain: Gain,
    /// Low-pass α in (0, 1].
    pub alpha: Alpha,
    /// |output| limit, motor torque LSB.
    pub limit: Torque,
}

/// Impedance compensation state (the low-pass).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImpComp {
    lp: LowPass,
}

impl ImpComp {
    /// Fresh state.
    pub const NEW: ImpComp = ImpComp { lp: LowPass::NEW };

    fn deficit(cfg: &ImpCompConfig, x_d: Counts, x: Counts, tau_env: Torque) -> (i32, bool) {
        let (e, c1) = pos_error(x_d, x);
        let (df, c2) = sat_i32(cfg.kd.apply(e).saturating_sub(i64::from(tau_env)));
        (df, c1 || c2)
    }

    /// Set the filter to the current unfiltered deficit (no transient on enable).
    pub fn prime(&mut self, cfg: &ImpCompConfig, x_d: Counts, x: Counts, tau_env: Torque) {
        let (df, _) = Self::deficit(cfg, x_d, x, tau_env);
        self.lp.reset(df);
    }

    /// One step: setpoint, measured position (same encoder as `kd`), output torque sensor.
    #[inline]
    pub fn step(&mut self, cfg: &ImpCompConfig, x_d: Counts, x: Counts, tau_env: Torque) -> Output {
        let mut flags = Flags::NONE;
        let (df, c) = Self::deficit(cfg, x_d, x, tau_env);
        flags.set_if(c, Flags::INPUT_CLAMPED);
        let f = self.lp.step(df, cfg.alpha);
        let (tau, sat) = clamp_sym(cfg.gain.apply(f), cfg.limit);
        flags.set_if(sat, Flags::OUTPUT_SATURATED);
        Output { tau, flags }
    }
}
