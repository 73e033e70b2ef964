//! Power-stage adapter (embedded-hal 1.0): the card's `i16` torque command → PWM duty
//! (`SetDutyCycle`) + direction, enable and brake pins (`OutputPin`).
//!
//! The thesis card drove a D/A converter into an analogue current servo (notes §1); a
//! sign/magnitude PWM H-bridge with a current loop in hardware is today's equivalent: duty ∝
//! |τ| (torque ∝ current), direction pin = sign. Safety rules (design.md: the card never
//! exceeds its torque limit):
//! * **Disabled or fault → duty 0, enable low, brake on**, in that order (remove drive first,
//!   then engage the brake), and this path is attempted completely even if one write fails
//!   (the first error is returned).
//! * Drive: brake off, direction, duty, then enable — the bridge is never enabled with a stale
//!   duty or direction.
//! * |τ| ≥ `full_scale` gives full duty (the limit itself lives in the law/runtime); the duty
//!   is rounded, so the quantisation is ≤ ½ duty step.
//!
//! Pin polarity: direction high = positive torque, enable high = bridge on, brake high =
//! brake engaged (wrap an inverting pin type if the board differs).

use embedded_hal::digital::{Error as _, ErrorKind as PinErrorKind, OutputPin};
use embedded_hal::pwm::{Error as _, ErrorKind as PwmErrorKind, SetDutyCycle};

use crate::fixed_math::TorqueCmd;

/// What the stage should do this tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StageCommand {
    /// Drive this torque (0.1 mN·m, motor side).
    Drive(TorqueCmd),
    /// Outputs off, brake on (normal disabled state).
    Disabled,
    /// Outputs off, brake on (a fault is latched by the runtime).
    Fault,
}

/// Which output failed. (`defmt::Format` is implemented by hand: embedded-hal's error kinds
/// only support defmt 0.3.)
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PowerStageError {
    /// The PWM channel.
    Pwm(PwmErrorKind),
    /// The direction pin.
    Direction(PinErrorKind),
    /// The enable pin.
    Enable(PinErrorKind),
    /// The brake pin.
    Brake(PinErrorKind),
    /// `full_scale` was not positive.
    BadFullScale,
}

#[cfg(feature = "defmt")]
impl defmt::Format for PowerStageError {
    fn format(&self, f: defmt::Formatter) {
        match self {
            PowerStageError::Pwm(_) => defmt::write!(f, "PowerStageError::Pwm"),
            PowerStageError::Direction(_) => defmt::write!(f, "PowerStageError::Direction"),
            PowerStageError::Enable(_) => defmt::write!(f, "PowerStageError::Enable"),
            PowerStageError::Brake(_) => defmt::write!(f, "PowerStageError::Brake"),
            PowerStageError::BadFullScale => defmt::write!(f, "PowerStageError::BadFullScale"),
        }
    }
}

/// The adapter. `full_scale` is the torque (LSB) that corresponds to 100 % duty.
#[derive(Debug)]
pub struct PowerStage<P, D, E, B> {
    pwm: P,
    dir: D,
    enable: E,
    brake: B,
    max_duty: u16,
    full_scale: u16,
}

impl<P, D, E, B> PowerStage<P, D, E, B>
where
    P: SetDutyCycle,
    D: OutputPin,
    E: OutputPin,
    B: OutputPin,
{
    /// Take the peripherals, read the PWM's maximum duty once, and put the stage in the safe
    /// state (duty 0, enable low, brake on).
    pub fn new(
        pwm: P,
        dir: D,
        enable: E,
        brake: B,
        full_scale: u16,
    ) -> Result<Self, (Self, PowerStageError)> {
        let max_duty = pwm.max_duty_cycle();
        let mut s = PowerStage {
            pwm,
            dir,
            enable,
            brake,
            max_duty,
            full_scale,
        };
        if full_scale == 0 {
            let _ = s.safe();
            return Err((s, PowerStageError::BadFullScale));
        }
        match s.safe() {
            Ok(()) => Ok(s),
            Err(e) => Err((s, e)),
        }
    }

    /// Duty for a torque command: round(|τ|·max / full_scale), saturated at max.
    pub fn duty_for(&self, tau: TorqueCmd) -> u16 {
        let mag = u32::from(tau.unsigned_abs());
        let fs = u32::from(self.full_scale.max(1));
        if mag >= fs {
            return self.max_duty;
        }
        // mag < fs ≤ 65535, max ≤ 65535 ⇒ product < 2³², + fs/2 < 2³² + 2¹⁶ — use u64.
        let num = u64::from(mag)
            .wrapping_mul(u64::from(self.max_duty))
            .wrapping_add(u64::from(fs).wrapping_shr(1));
        let d = num.checked_div(u64::from(fs)).unwrap_or(0);
        u16::try_from(d).unwrap_or(self.max_duty).min(self.max_duty)
    }

    /// Safe state: duty 0, enable low, brake on. Every write is attempted; first error wins.
    fn safe(&mut self) -> Result<(), PowerStageError> {
        let r1 = self
            .pwm
            .set_duty_cycle(0)
            .map_err(|e| PowerStageError::Pwm(e.kind()));
        let r2 = self
            .enable
            .set_low()
            .map_err(|e| PowerStageError::Enable(e.kind()));
        let r3 = self
            .brake
            .set_high()
            .map_err(|e| PowerStageError::Brake(e.kind()));
        r1.and(r2).and(r3)
    }

    /// Apply one tick's command. On a write error while driving, the stage falls back to the
    /// safe state (best effort) and returns the error.
    pub fn apply(&mut self, cmd: StageCommand) -> Result<(), PowerStageError> {
        match cmd {
            StageCommand::Disabled | StageCommand::Fault => self.safe(),
            StageCommand::Drive(tau) => {
                let r = self.drive(tau);
                if r.is_err() {
                    let _ = self.safe();
                }
                r
            }
        }
    }

    fn drive(&mut self, tau: TorqueCmd) -> Result<(), PowerStageError> {
        self.brake
            .set_low()
            .map_err(|e| PowerStageError::Brake(e.kind()))?;
        if tau >= 0 {
            self.dir.set_high()
        } else {
            self.dir.set_low()
        }
        .map_err(|e| PowerStageError::Direction(e.kind()))?;
        let duty = self.duty_for(tau);
        self.pwm
            .set_duty_cycle(duty)
            .map_err(|e| PowerStageError::Pwm(e.kind()))?;
        self.enable
            .set_high()
            .map_err(|e| PowerStageError::Enable(e.kind()))
    }

    /// Maximum duty read at construction.
    pub fn max_duty(&self) -> u16 {
        self.max_duty
    }

    /// Give the peripherals back.
    pub fn release(self) -> (P, D, E, B) {
        (self.pwm, self.dir, self.enable, self.brake)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use embedded_hal_mock::eh1::digital::{Mock as Pin, State, Transaction as PinT};
    use embedded_hal_mock::eh1::pwm::{Mock as Pwm, Transaction as PwmT};
    use embedded_hal_mock::eh1::MockError;
    use std::vec;
    use std::vec::Vec;

    fn safe_pwm() -> Vec<PwmT> {
        vec![PwmT::set_duty_cycle(0)]
    }

    #[allow(clippy::type_complexity)]
    fn stage(
        pwm: Vec<PwmT>,
        dir: Vec<PinT>,
        en: Vec<PinT>,
        br: Vec<PinT>,
    ) -> PowerStage<Pwm, Pin, Pin, Pin> {
        let mut p = vec![PwmT::max_duty_cycle(1000)];
        p.extend(pwm);
        PowerStage::new(
            Pwm::new(&p),
            Pin::new(&dir),
            Pin::new(&en),
            Pin::new(&br),
            20000,
        )
        .map_err(|(_, e)| e)
        .unwrap()
    }

    fn done(s: PowerStage<Pwm, Pin, Pin, Pin>) {
        let (mut p, mut d, mut e, mut b) = s.release();
        p.done();
        d.done();
        e.done();
        b.done();
    }

    #[test]
    fn new_is_safe_then_drives_both_directions() {
        let mut pwm = safe_pwm();
        pwm.extend([
            PwmT::set_duty_cycle(500),
            PwmT::set_duty_cycle(1000),
            PwmT::set_duty_cycle(1),
        ]);
        let dir = vec![
            PinT::set(State::High),
            PinT::set(State::Low),
            PinT::set(State::High),
        ];
        let en = vec![
            PinT::set(State::Low),
            PinT::set(State::High),
            PinT::set(State::High),
            PinT::set(State::High),
        ];
        let br = vec![
            PinT::set(State::High),
            PinT::set(State::Low),
            PinT::set(State::Low),
            PinT::set(State::Low),
        ];
        let mut s = stage(pwm, dir, en, br);
        s.apply(StageCommand::Drive(10000)).unwrap(); // 50 %
        s.apply(StageCommand::Drive(i16::MIN)).unwrap(); // beyond full scale, negative
        s.apply(StageCommand::Drive(10)).unwrap(); // 10·1000/20000 = 0.5 → rounds to 1
        done(s);
    }

    #[test]
    fn disable_and_fault_turn_off_and_brake() {
        let mut pwm = safe_pwm();
        pwm.extend([
            PwmT::set_duty_cycle(250),
            PwmT::set_duty_cycle(0),
            PwmT::set_duty_cycle(0),
        ]);
        let dir = vec![PinT::set(State::Low)];
        let en = vec![
            PinT::set(State::Low),
            PinT::set(State::High),
            PinT::set(State::Low),
            PinT::set(State::Low),
        ];
        let br = vec![
            PinT::set(State::High),
            PinT::set(State::Low),
            PinT::set(State::High),
            PinT::set(State::High),
        ];
        let mut s = stage(pwm, dir, en, br);
        s.apply(StageCommand::Drive(-5000)).unwrap();
        s.apply(StageCommand::Disabled).unwrap();
        s.apply(StageCommand::Fault).unwrap();
        done(s);
    }

    #[test]
    fn pwm_error_while_driving_falls_back_to_safe() {
        let mut pwm = safe_pwm();
        pwm.extend([
            PwmT::set_duty_cycle(100).with_error(MockError::Io(std::io::ErrorKind::Other)),
            PwmT::set_duty_cycle(0),
        ]);
        let dir = vec![PinT::set(State::High)];
        let en = vec![PinT::set(State::Low), PinT::set(State::Low)];
        let br = vec![
            PinT::set(State::High),
            PinT::set(State::Low),
            PinT::set(State::High),
        ];
        let mut s = stage(pwm, dir, en, br);
        let e = s.apply(StageCommand::Drive(2000)).unwrap_err();
        assert_eq!(e, PowerStageError::Pwm(PwmErrorKind::Other));
        done(s);
    }

    #[test]
    fn pin_error_in_safe_path_still_tries_the_rest() {
        let mut pwm = safe_pwm();
        pwm.push(PwmT::set_duty_cycle(0));
        let dir = vec![];
        let en = vec![
            PinT::set(State::Low),
            PinT::set(State::Low).with_error(MockError::Io(std::io::ErrorKind::Other)),
        ];
        let br = vec![PinT::set(State::High), PinT::set(State::High)];
        let mut s = stage(pwm, dir, en, br);
        let e = s.apply(StageCommand::Fault).unwrap_err();
        assert_eq!(e, PowerStageError::Enable(PinErrorKind::Other));
        done(s);
    }

    #[test]
    fn duty_rounding_and_zero_full_scale() {
        let s = stage(
            safe_pwm(),
            vec![],
            vec![PinT::set(State::Low)],
            vec![PinT::set(State::High)],
        );
        assert_eq!(s.duty_for(0), 0);
        assert_eq!(s.duty_for(19999), 1000);
        assert_eq!(s.duty_for(-19989), 999);
        assert_eq!(s.duty_for(i16::MAX), 1000);
        done(s);
        let p = [PwmT::max_duty_cycle(10), PwmT::set_duty_cycle(0)];
        let r = PowerStage::new(
            Pwm::new(&p),
            Pin::new(&[]),
            Pin::new(&[PinT::set(State::Low)]),
            Pin::new(&[PinT::set(State::High)]),
            0,
        );
        let (s, e) = r.err().unwrap();
        assert_eq!(e, PowerStageError::BadFullScale);
        done(s);
    }
}
