//! The card's state vocabulary shared by several messages: CiA-402-shaped [`State`],
//! control [`Mode`], [`FaultCode`] and [`LimitFlags`].

use super::field::wire_enum;

wire_enum! {
    /// Card state, shaped after CiA 402's power state machine (collapsed to what a torque
    /// card needs). Transitions (driven by [`ControlWord`](super::ControlWord) commands and faults):
    ///
    /// ```text
    ///  Disabled --Shutdown--> Ready --Enable(mode)--> Enabled(mode) --QuickStop--> QuickStop
    ///     ^  ^                  |                      |   ^ Enable(other mode): switch   |
    ///     |  +----Disable-------+----------------------+                    stopped ----+
    ///     +--ClearFault-- Fault <--reaction done-- FaultReaction <--any fault (any state)
    /// ```
    pub enum State {
        /// Power stage off, torque command 0. Parameters may be written and committed.
        Disabled = 0,
        /// Configuration valid and armed; power stage still off. Next step is `Enable`.
        Ready = 1,
        /// Control law of the selected mode running; torque commanded.
        Enabled = 2,
        /// Braking to standstill (configured quick-stop damping), then `Disabled`.
        QuickStop = 3,
        /// A fault was detected; the configured reaction (zero torque or damping) is running.
        FaultReaction = 4,
        /// Reaction done, torque 0. Only `ClearFault` leaves this state (to `Disabled`).
        Fault = 5,
    }
}

wire_enum! {
    /// Control mode, selected by `Enable(mode)`. On the wire, 0 means "no mode" (used in the
    /// heartbeat while none was ever selected); modes start at 1.
    /// The laws follow `thesis-notes.md` §2 (Schempf 1990 Ch. 3).
    pub enum Mode {
        /// τm = motor torque feed-forward from `SetpointMotion` (limits still apply).
        TorquePassthrough = 1,
        /// τm = Ke(xD − x1) − Be·ẋ1 on the motor encoder (colocated, robust).
        PositionPdColocated = 2,
        /// τm = Ke(xD − x2) − Be·ẋ2 on the output encoder (non-colocated; needs one).
        PositionPdNonColocated = 3,
        /// Colocated PD plus integral Ki∫e with anti-windup clamp.
        PositionPid = 4,
        /// Pure viscous motor behaviour τm = −Be·ẋ1 (spring/damper emulation, §2.10).
        Damper = 5,
        /// τm = Ke(τD − τenv) − B1e·ẋ1 (P force with input damping, Eqn 3.3.16).
        ForceP = 6,
        /// Adds force-rate damping −Bf·τ̇env (Eqn 3.3.12).
        ForcePd = 7,
        /// P force plus integral of the force error (Eqn 3.3.34 without D), input damping B1e.
        ForcePi = 8,
        /// τm = Ke(xD − x1) − Be·ẋ1 + Km·τenv (colocated impedance, Eqn 3.3.20).
        ImpedanceColocated = 9,
        /// τm = Ke(xD − x2) − Be·ẋ2 + Km·τenv (non-colocated impedance, Eqn 3.3.19).
        ImpedanceNonColocated = 10,
        /// τm = Be·(vD − ẋ1) + Ke·Σ(vD − ẋ1)·T with anti-windup clamp `integrator_limit`:
        /// velocity PI on the motor encoder, vD the setpoint's velocity_ff.
        Velocity = 11,
    }
}

impl Mode {
    /// Encodes an optional mode: `None` → 0.
    pub const fn opt_to_u8(m: Option<Mode>) -> u8 {
        match m {
            Some(m) => m.as_u8(),
            None => 0,
        }
    }

    /// Decodes an optional mode byte: 0 → `Some(None)`, unknown → `None`.
    pub const fn opt_from_u8(v: u8) -> Option<Option<Mode>> {
        if v == 0 {
            Some(None)
        } else {
            match Mode::from_u8(v) {
                Some(m) => Some(Some(m)),
                None => None,
            }
        }
    }

    /// True for modes that need the output encoder (`OutputEncoder` frames).
    pub const fn needs_output_encoder(self) -> bool {
        matches!(
            self,
            Mode::PositionPdNonColocated | Mode::ImpedanceNonColocated
        )
    }

    /// True for modes that use the output torque sensor.
    pub const fn needs_torque_sensor(self) -> bool {
        matches!(
            self,
            Mode::ForceP
                | Mode::ForcePd
                | Mode::ForcePi
                | Mode::ImpedanceColocated
                | Mode::ImpedanceNonColocated
        )
    }
}

wire_enum! {
    /// Why the card entered `FaultReaction`/`Fault`. 0 on the wire means "no fault"
    /// (heartbeat only; a `Fault` frame always carries a code).
    pub enum FaultCode {
        /// No `Sensor` frame within the sensor timeout (param 0x0702). detail = µs since last.
        SensorTimeout = 1,
        /// No supervisor frame within the watchdog timeout (0x0700). detail = ms since last.
        SupervisorWatchdog = 2,
        /// CAN controller reported bus-off / error-passive. detail = controller error code.
        BusError = 3,
        /// A saturating operation in the control path saturated for longer than allowed.
        /// detail = unsaturated value, saturated to i32.
        Overflow = 4,
        /// Position outside the soft limits (0x0303/0x0304). detail = position (counts).
        PositionLimit = 5,
        /// |velocity| above the velocity limit (0x0302). detail = velocity (counts/s).
        VelocityLimit = 6,
        /// |output torque| above the output torque limit (0x0305). detail = torque (0.01 N·m).
        OutputTorqueLimit = 7,
        /// Active configuration found invalid on `Shutdown`/`Enable`. detail = param id.
        ConfigRejected = 8,
        /// The sensor frame flagged an encoder error, or a needed sensor is missing
        /// (torque invalid in a force mode, no output encoder in a non-colocated mode).
        /// detail = sensor sequence number.
        SensorInvalid = 9,
        /// Sensor sequence numbers skipped more than allowed, or the `OutputEncoder` frame of
        /// a tick is missing. detail = expected seq << 8 | received seq.
        SequenceError = 10,
        /// The power stage reported a fault (over-current, over-temperature, under-voltage).
        /// detail = power-stage status word.
        PowerStage = 11,
        /// A condition that should be impossible (a bug). detail = location code.
        Internal = 12,
    }
}

impl FaultCode {
    /// Encodes an optional fault: `None` → 0.
    pub const fn opt_to_u8(f: Option<FaultCode>) -> u8 {
        match f {
            Some(f) => f.as_u8(),
            None => 0,
        }
    }

    /// Decodes an optional fault byte: 0 → `Some(None)`, unknown → `None`.
    pub const fn opt_from_u8(v: u8) -> Option<Option<FaultCode>> {
        if v == 0 {
            Some(None)
        } else {
            match FaultCode::from_u8(v) {
                Some(f) => Some(Some(f)),
                None => None,
            }
        }
    }
}

/// What limited the output this tick. One byte on the wire (bits 0..=5; 6..=7 reserved).
///
/// Flags rather than an enum because several limits can act at once, and the card must never
/// limit silently (design non-negotiable): every clamp sets its bit.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LimitFlags(u8);

impl LimitFlags {
    /// No limit active.
    pub const NONE: LimitFlags = LimitFlags(0);
    /// Torque command clamped to the torque limit (0x0301).
    pub const TORQUE: LimitFlags = LimitFlags(0x01);
    /// Velocity limiting active (0x0302).
    pub const VELOCITY: LimitFlags = LimitFlags(0x02);
    /// A position soft limit is active (0x0303/0x0304).
    pub const POSITION: LimitFlags = LimitFlags(0x04);
    /// Integrator clamped (anti-windup, 0x0106 / 0x0204).
    pub const INTEGRATOR: LimitFlags = LimitFlags(0x08);
    /// An intermediate product saturated in the control law this tick.
    pub const OVERFLOW: LimitFlags = LimitFlags(0x10);
    /// A value did not fit its wire field (e.g. telemetry velocity) and was saturated.
    pub const WIRE_SATURATED: LimitFlags = LimitFlags(0x20);
    /// Bits with a meaning; the rest are reserved and must be 0.
    pub const DEFINED: u8 = 0b0011_1111;
    /// (name, flag) pairs, in bit order; names match the DBC signal suffixes.
    pub const NAMED: [(&'static str, LimitFlags); 6] = [
        ("torque", Self::TORQUE),
        ("velocity", Self::VELOCITY),
        ("position", Self::POSITION),
        ("integrator", Self::INTEGRATOR),
        ("overflow", Self::OVERFLOW),
        ("wire_saturated", Self::WIRE_SATURATED),
    ];

    /// `None` if a reserved bit is set.
    pub const fn from_bits(b: u8) -> Option<LimitFlags> {
        if b & !Self::DEFINED == 0 {
            Some(LimitFlags(b))
        } else {
            None
        }
    }

    /// Drops reserved bits.
    pub const fn from_bits_truncate(b: u8) -> LimitFlags {
        LimitFlags(b & Self::DEFINED)
    }

    /// The wire byte.
    pub const fn bits(self) -> u8 {
        self.0
    }

    /// True if all of `other`'s bits are set.
    pub const fn contains(self, other: LimitFlags) -> bool {
        self.0 & other.0 == other.0
    }

    /// True if no bit is set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Sets `other`'s bits.
    pub fn insert(&mut self, other: LimitFlags) {
        self.0 |= other.0;
    }

    /// Sets or clears `other`'s bits.
    pub fn set(&mut self, other: LimitFlags, on: bool) {
        if on {
            self.0 |= other.0;
        } else {
            self.0 &= !other.0;
        }
    }
}

impl core::ops::BitOr for LimitFlags {
    type Output = LimitFlags;
    fn bitor(self, rhs: LimitFlags) -> LimitFlags {
        LimitFlags(self.0 | rhs.0)
    }
}

impl core::ops::BitOrAssign for LimitFlags {
    fn bitor_assign(&mut self, rhs: LimitFlags) {
        self.0 |= rhs.0;
    }
}
