//! The drive's position loop: PD (or PID) on the measured motor position, plus the plan's
//! feed-forward and dither.
//!
//! Gains are placed for the rigid plant: Kp = J·ω², Kd = 2ζ·J·ω, Ki = Kp·(ratio·ω), a loop
//! bandwidth of a few Hz. The derivative acts on the tracking error through a first-order
//! low-pass (at most 30 Hz and a tenth of the sample rate) so the encoder steps do not turn
//! into torque spikes.

use super::plant::Plant;
use std::f64::consts::TAU;

#[derive(Debug, Clone)]
pub struct Controller {
    kp: f64,
    kd: f64,
    ki: f64,
    dt: f64,
    /// Pole of the derivative filter (per sample).
    pole: f64,
    last_error: Option<f64>,
    rate: f64,
    integral: f64,
}

impl Controller {
    pub fn new(plant: &Plant, dt: f64, integral: bool) -> Controller {
        let j = plant.joint.total_inertia();
        let w = TAU * plant.loop_hz;
        let kp = j * w * w;
        let filter_hz = (0.1 / dt).min(30.0);
        Controller {
            kp,
            kd: 2.0 * plant.loop_zeta * j * w,
            ki: if integral {
                kp * plant.integral_ratio * w
            } else {
                0.0
            },
            dt,
            pole: (-TAU * filter_hz * dt).exp(),
            last_error: None,
            rate: 0.0,
            integral: 0.0,
        }
    }

    /// Proportional gain, N·m/rad.
    pub fn kp(&self) -> f64 {
        self.kp
    }

    /// Feedback torque for reference `r` and measured position `y`.
    pub fn feedback(&mut self, r: f64, y: f64) -> f64 {
        let e = r - y;
        let de = (e - self.last_error.unwrap_or(e)) / self.dt;
        self.last_error = Some(e);
        self.rate = self.pole * self.rate + (1.0 - self.pole) * de;
        self.integral += e * self.dt;
        self.kp * e + self.kd * self.rate + self.ki * self.integral
    }
}
