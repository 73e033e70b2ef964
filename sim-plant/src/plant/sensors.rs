//! Sensors as the motor card sees them (thesis §1 sensor table): the motor encoder in raw
//! counts (2304 counts/rev, wrapping i32 — the card works on raw counts, §1), an optional
//! output encoder, the Sensorimotor velocity at its resolution, and the output torque sensor
//! (JR3) with resolution and Gaussian noise; all optionally delayed by whole samples.
//!
//! Noise comes from a ChaCha8 stream seeded by the plant's seed, so a run is bit-reproducible.

use std::collections::VecDeque;
use std::f64::consts::TAU;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// One sample of everything the card can read.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sensors {
    /// Motor encoder: floor(θm · cpr / 2π), wrapping modulo 2³² (two's complement), so a
    /// consumer differencing consecutive samples with `wrapping_sub` is correct across wrap.
    pub motor_counts: i32,
    /// Output encoder (same convention), if the model has one.
    pub output_counts: Option<i32>,
    /// Motor velocity (rad/s at the motor), quantised to the velocity resolution.
    pub motor_velocity: f64,
    /// Output torque sensor reading (N·m): torque the output exerts on its environment,
    /// quantised to `torque_resolution`, with noise.
    pub torque: f64,
    /// The same reading in sensor LSBs (saturating to the i32 range).
    pub torque_counts: i32,
}

/// Sensor configuration, resolved from the model's `[motor]` and `[sensors]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorConfig {
    /// Motor encoder counts per motor rev.
    pub motor_cpr: f64,
    /// Output encoder counts per output rev (0 = none).
    pub output_cpr: f64,
    /// Torque LSB (N·m).
    pub torque_resolution: f64,
    /// Torque noise σ (N·m).
    pub torque_noise: f64,
    /// Velocity LSB (rad/s at the motor).
    pub velocity_resolution: f64,
    /// Delay in samples.
    pub delay: usize,
}

/// Turns true quantities into readings; owns the noise stream and the delay line.
#[derive(Clone, Debug)]
pub struct SensorModel {
    cfg: SensorConfig,
    rng: ChaCha8Rng,
    queue: VecDeque<Sensors>,
}

/// Wrapping encoder count of an angle (rad): floor(angle·cpr/2π) mod 2³².
#[inline]
pub fn encoder_counts(angle: f64, cpr: f64) -> i32 {
    let c = angle * cpr / TAU;
    // floor by a truncating cast (f64::floor is a libm call on baseline x86-64). f64 → i64 is
    // exact for |c| < 2⁵³ (≈ 4·10¹² motor revs at 2304 cpr); i64 → i32 keeps the low 32 bits,
    // i.e. wraps like a hardware counter.
    let t = c as i64;
    let floor = if (t as f64) > c { t - 1 } else { t };
    floor as i32
}

impl SensorModel {
    /// A sensor model with its own noise stream.
    pub fn new(cfg: SensorConfig, seed: u64) -> Self {
        Self {
            cfg,
            rng: ChaCha8Rng::seed_from_u64(seed),
            queue: VecDeque::with_capacity(cfg.delay + 1),
        }
    }

    /// Configuration.
    pub fn config(&self) -> &SensorConfig {
        &self.cfg
    }

    /// Read the sensors for the true motor angle/velocity (motor side), output angle and the
    /// true output torque; returns the (possibly delayed) reading.
    pub fn sample(
        &mut self,
        motor_angle: f64,
        motor_velocity: f64,
        output_angle: f64,
        torque: f64,
    ) -> Sensors {
        let c = &self.cfg;
        let noisy = if c.torque_noise > 0.0 {
            let z: f64 = StandardNormal.sample(&mut self.rng);
            torque + c.torque_noise * z
        } else {
            torque
        };
        let torque_counts = (crate::fastmath::round(noisy / c.torque_resolution) as i64)
            .clamp(i32::MIN.into(), i32::MAX.into()) as i32;
        let now = Sensors {
            motor_counts: encoder_counts(motor_angle, c.motor_cpr),
            output_counts: (c.output_cpr > 0.0).then(|| encoder_counts(output_angle, c.output_cpr)),
            motor_velocity: crate::fastmath::round(motor_velocity / c.velocity_resolution)
                * c.velocity_resolution,
            torque: f64::from(torque_counts) * c.torque_resolution,
            torque_counts,
        };
        if c.delay == 0 {
            return now;
        }
        if self.queue.is_empty() {
            // Before the first delayed sample exists the line holds the first reading.
            self.queue.extend(std::iter::repeat_n(now, c.delay));
        }
        self.queue.push_back(now);
        self.queue.pop_front().unwrap_or(now)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encoder_quantises_and_wraps() {
        assert_eq!(encoder_counts(0.0, 2304.0), 0);
        assert_eq!(encoder_counts(TAU, 2304.0), 2304);
        assert_eq!(encoder_counts(-1e-9, 2304.0), -1);
        assert_eq!(encoder_counts(TAU / 2304.0 * 1.5, 2304.0), 1);
        // 2³¹ counts later the counter wraps to i32::MIN.
        let revs = (1u64 << 31) as f64 / 2304.0;
        assert_eq!(encoder_counts(revs * TAU + 1e-7, 2304.0), i32::MIN);
        let a = encoder_counts(revs * TAU - TAU / 2304.0 * 0.5, 2304.0);
        let b = encoder_counts(revs * TAU + TAU / 2304.0 * 0.5, 2304.0);
        assert_eq!(b.wrapping_sub(a), 1);
    }

    #[test]
    fn delay_line_delays_by_whole_samples() {
        let cfg = SensorConfig {
            motor_cpr: 2304.0,
            output_cpr: 0.0,
            torque_resolution: 0.01,
            torque_noise: 0.0,
            velocity_resolution: 1e-4,
            delay: 2,
        };
        let mut s = SensorModel::new(cfg, 1);
        let r: Vec<f64> = (0..5)
            .map(|i| s.sample(0.0, 0.0, 0.0, i as f64).torque)
            .collect();
        assert_eq!(r, vec![0.0, 0.0, 0.0, 1.0, 2.0]);
    }
}
