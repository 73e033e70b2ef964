//! The parameter table: every id the card accepts in `ParamWrite`/`ParamRead`, with its
//! access rule, unit / Q format, range and default. This table is the single source of
//! truth: `docs/protocol.md` § "Parameter table" must list exactly these rows (checked by
//! `controller/tests/proto_spec.rs`), and the card runtime range-checks staged values with
//! [`lookup`] and [`ParamDef::check`].
//!
//! Numbering: the high byte is the group, so a new parameter lands in its group without
//! renumbering, and a `candump` reader can tell the group at a glance.
//!
//! | range | group |
//! |---|---|
//! | 0x0001–0x00FF | system (read-only) |
//! | 0x0100–0x01FF | position / impedance law gains |
//! | 0x0200–0x02FF | force law gains |
//! | 0x0300–0x03FF | limits and quick stop |
//! | 0x0400–0x04FF | friction compensation |
//! | 0x0500–0x05FF | impedance compensation |
//! | 0x0600–0x06FF | position-periodic ripple compensation (table at 0x0640–0x067F) |
//! | 0x0700–0x07FF | watchdogs and fault reaction |
//! | 0x0800–0x08FF | telemetry and heartbeat |
//! | 0x0900–0x09FF | plant constants (stability guard, encoders) |
//! | 0x0A00–0x0AFF | feed-forward of position-dependent loads (offset, gravity) |
//!
//! Machine units (all integers, so the 1 kHz loop never converts): "τLSB" = motor torque LSB
//! = 0.1 mN·m; "τoLSB" = output torque LSB = 0.01 N·m; "tick" = one control period (nominal
//! 1 ms); Q16.16 = raw / 65536; Q0.16 = raw / 65536 in [0, 1]. Gains use the backward
//! difference (thesis §2.9): the D gain multiplies the per-tick difference (that is Be/T),
//! the I gain is added per tick (that is Ki·T). `controller::units` converts SI gains to
//! these units at configuration time.

use super::field::wire_enum;
use super::ParamStatus;

/// Entries the card must be able to stage in one set: a gain set with friction, feed-forward
/// and a 32-entry ripple table is about 80.
pub const STAGING_CAPACITY: usize = 96;

/// Number of ripple-table entries (ids `RIPPLE_TABLE ..= RIPPLE_TABLE + 63`).
pub const RIPPLE_TABLE_LEN: u16 = 64;

/// Who may write a parameter, and when.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Access {
    /// Read-only (`ParamStatus::ReadOnly` on write).
    ReadOnly,
    /// Writable in any state; applied at a cycle boundary (gains: bumpless switching is the
    /// card's job).
    Any,
    /// Writable only while the card is not driving (`Disabled`, `Ready`, `Fault`); otherwise
    /// `ParamStatus::NotAllowedInState`. For constants the stability guard and sensor
    /// handling depend on.
    Idle,
}

impl Access {
    /// Name used in the spec table.
    pub const fn name(self) -> &'static str {
        match self {
            Access::ReadOnly => "ro",
            Access::Any => "any",
            Access::Idle => "idle",
        }
    }
}

wire_enum! {
    /// Value of [`WATCHDOG_REACTION`]: what the card does when the supervisor goes quiet.
    pub enum WatchdogReaction {
        /// Torque to zero at once (the joint coasts).
        ZeroTorque = 0,
        /// Brake with quick-stop damping (0x0307) to standstill, then zero torque.
        QuickStop = 1,
        /// Hold the position where the watchdog fired, with the active Ke/Be on the motor
        /// encoder, until `ClearFault` (a vertical axis must not drop).
        HoldPosition = 2,
    }
}

/// One row of the parameter table (or a run of `count` consecutive ids, for tables).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ParamDef {
    /// First id.
    pub id: u16,
    /// Number of consecutive ids sharing this definition (1, or the table length).
    pub count: u16,
    /// Short name (snake_case; the supervisor's TOML keys use it).
    pub name: &'static str,
    /// Access rule.
    pub access: Access,
    /// Unit / Q format of the raw i32.
    pub unit: &'static str,
    /// Smallest accepted raw value.
    pub min: i32,
    /// Largest accepted raw value.
    pub max: i32,
    /// Value after reset.
    pub default: i32,
}

impl ParamDef {
    /// Whether `id` falls in this row.
    pub fn contains(&self, id: u16) -> bool {
        id >= self.id && u32::from(id) < u32::from(self.id).saturating_add(u32::from(self.count))
    }

    /// Range check of a raw value.
    pub fn check(&self, value: i32) -> Result<(), ParamStatus> {
        if (self.min..=self.max).contains(&value) {
            Ok(())
        } else {
            Err(ParamStatus::OutOfRange)
        }
    }
}

macro_rules! params {
    ($( $konst:ident = $id:literal $(x $count:literal)?, $name:literal, $access:ident, $unit:literal, $min:expr, $max:expr, $default:expr; )+) => {
        $(
            #[doc = concat!("`", $name, "` — ", $unit)]
            pub const $konst: u16 = $id;
        )+
        /// The whole table, in id order.
        pub const TABLE: &[ParamDef] = &[
            $( ParamDef {
                id: $id,
                count: params!(@count $($count)?),
                name: $name,
                access: Access::$access,
                unit: $unit,
                min: $min,
                max: $max,
                default: $default,
            }, )+
        ];
    };
    (@count) => { 1 };
    (@count $c:literal) => { $c };
}

const MAX: i32 = i32::MAX;
const MIN: i32 = i32::MIN;
const TQ: i32 = i16::MAX as i32;

params! {
    // --- 0x00xx system (read-only) ---
    PROTOCOL_VERSION = 0x0001, "protocol_version", ReadOnly, "integer", 1, 255, super::PROTOCOL_VERSION as i32;
    NODE_ID = 0x0002, "node_id", ReadOnly, "integer (set by the card's boot configuration)", 1, 127, 1;
    COMMIT_COUNT = 0x0003, "commit_count", ReadOnly, "commits applied since boot", 0, MAX, 0;
    LAST_SET_SEQ = 0x0004, "last_set_seq", ReadOnly, "set_seq of the last applied commit", 0, 255, 0;
    // --- 0x01xx position / impedance gains ---
    KE = 0x0101, "ke", Any, "Q16.16 τLSB per count", 0, MAX, 0;
    BE = 0x0102, "be", Any, "Q16.16 τLSB per (count/tick)", 0, MAX, 0;
    KI = 0x0103, "ki", Any, "Q16.16 τLSB per (count·tick)", 0, MAX, 0;
    B1E = 0x0104, "b1e", Any, "Q16.16 τLSB per (motor count/tick)", 0, MAX, 0;
    KM = 0x0105, "km", Any, "Q16.16 τLSB per τoLSB", MIN, MAX, 0;
    INTEGRATOR_LIMIT = 0x0106, "integrator_limit", Any, "τLSB", 0, TQ, 0;
    // --- 0x02xx force gains ---
    FORCE_KP = 0x0201, "force_kp", Any, "Q16.16 τLSB per τoLSB", 0, MAX, 0;
    FORCE_KD = 0x0202, "force_kd", Any, "Q16.16 τLSB per (τoLSB/tick)", 0, MAX, 0;
    FORCE_KI = 0x0203, "force_ki", Any, "Q16.16 τLSB per (τoLSB·tick)", 0, MAX, 0;
    FORCE_INTEGRATOR_LIMIT = 0x0204, "force_integrator_limit", Any, "τLSB", 0, TQ, 0;
    FORCE_RATE_FILTER = 0x0205, "force_rate_filter", Any, "Q0.16 low-pass α (65536 = none)", 1, 65536, 65536;
    // --- 0x03xx limits ---
    TORQUE_LIMIT = 0x0301, "torque_limit", Any, "τLSB", 0, TQ, 0;
    VELOCITY_LIMIT = 0x0302, "velocity_limit", Any, "counts/s", 1, MAX, 100_000;
    POSITION_MIN = 0x0303, "position_min", Any, "counts", MIN, MAX, MIN;
    POSITION_MAX = 0x0304, "position_max", Any, "counts", MIN, MAX, MAX;
    OUTPUT_TORQUE_LIMIT = 0x0305, "output_torque_limit", Any, "τoLSB", 1, TQ, TQ;
    SOFT_LIMITS_ENABLE = 0x0306, "soft_limits_enable", Idle, "bool (0/1)", 0, 1, 0;
    QUICK_STOP_DAMPING = 0x0307, "quick_stop_damping", Any, "Q16.16 τLSB per (count/tick)", 0, MAX, 0;
    STANDSTILL_VELOCITY = 0x0308, "standstill_velocity", Any, "counts/s", 0, MAX, 1_000;
    // --- 0x04xx friction compensation ---
    FRICTION_ENABLE = 0x0400, "friction_enable", Any, "bool (0/1)", 0, 1, 0;
    COULOMB_POS = 0x0401, "coulomb_pos", Any, "τLSB (τc⁺, applied for v > 0)", 0, TQ, 0;
    COULOMB_NEG = 0x0402, "coulomb_neg", Any, "τLSB (τc⁻ magnitude, applied for v < 0)", 0, TQ, 0;
    VISCOUS_POS = 0x0403, "viscous_pos", Any, "Q16.16 τLSB per (count/tick)", 0, MAX, 0;
    VISCOUS_NEG = 0x0404, "viscous_neg", Any, "Q16.16 τLSB per (count/tick)", 0, MAX, 0;
    UNDER_COMPENSATION = 0x0405, "under_compensation", Any, "factor × 65536 (65536 = 1.0)", 0, 98_304, 58_982;
    FRICTION_DEADBAND = 0x0406, "friction_deadband", Any, "counts/s", 0, MAX, 1_000;
    FRICTION_SAME_SIGN_TICKS = 0x0407, "friction_same_sign_ticks", Any, "ticks", 1, 1_000, 3;
    FRICTION_FILTER = 0x0408, "friction_filter", Any, "Q0.16 low-pass α of the velocity it acts on (65536 = none)", 1, 65536, 65536;
    FRICTION_SOURCE = 0x0409, "friction_source", Any, "0 = the measured velocity, 1 = the setpoint's velocity_ff", 0, 1, 0;
    // --- 0x05xx impedance compensation ---
    IMPEDANCE_COMP_ENABLE = 0x0500, "impedance_comp_enable", Any, "bool (0/1)", 0, 1, 0;
    IMPEDANCE_COMP_STIFFNESS = 0x0501, "impedance_comp_stiffness", Any, "Q16.16 τoLSB per count", 0, MAX, 0;
    IMPEDANCE_COMP_GAIN = 0x0502, "impedance_comp_gain", Any, "Q16.16 τLSB per τoLSB", MIN, MAX, 0;
    IMPEDANCE_COMP_FILTER = 0x0503, "impedance_comp_filter", Any, "Q0.16 low-pass α (65536 = none)", 1, 65536, 65536;
    // --- 0x06xx ripple compensation ---
    RIPPLE_ENABLE = 0x0600, "ripple_enable", Any, "bool (0/1)", 0, 1, 0;
    RIPPLE_PERIOD = 0x0601, "ripple_period", Idle, "counts per ripple period", 1, MAX, 2_304;
    RIPPLE_LENGTH = 0x0602, "ripple_length", Idle, "table entries used (≤ 64)", 1, 64, 64;
    RIPPLE_PHASE = 0x0603, "ripple_phase", Any, "counts", 0, MAX, 0;
    RIPPLE_TABLE = 0x0640 x 64, "ripple_table", Any, "τLSB (entry i at 0x0640 + i)", i16::MIN as i32, TQ, 0;
    // --- 0x07xx watchdogs ---
    SUPERVISOR_TIMEOUT = 0x0700, "supervisor_timeout", Any, "ms", 1, 60_000, 200;
    WATCHDOG_REACTION = 0x0701, "watchdog_reaction", Any, "enum WatchdogReaction", 0, 2, 1;
    SENSOR_TIMEOUT = 0x0702, "sensor_timeout", Any, "µs", 1_100, 100_000, 3_000;
    MAX_SEQ_SKIP = 0x0703, "max_seq_skip", Any, "lost sensor frames tolerated in a row", 0, 255, 2;
    // --- 0x08xx telemetry ---
    TELEMETRY_DIVIDER = 0x0800, "telemetry_divider", Any, "ticks per telemetry frame (0 = off)", 0, 1_000, 10;
    HEARTBEAT_PERIOD = 0x0801, "heartbeat_period", Any, "ms", 10, 10_000, 100;
    // --- 0x09xx plant constants ---
    ROTOR_INERTIA = 0x0900, "rotor_inertia", Idle, "1e-9 kg·m²", 1, MAX, 10_000;
    CONTROL_PERIOD = 0x0901, "control_period", Idle, "µs", 100, 10_000, 1_000;
    MOTOR_COUNTS_PER_REV = 0x0902, "motor_counts_per_rev", Idle, "counts", 1, MAX, 2_304;
    GEAR_RATIO = 0x0903, "gear_ratio", Idle, "Q16.16 (motor rev per output rev)", 1, MAX, 30 * 65_536;
    OUTPUT_COUNTS_PER_REV = 0x0904, "output_counts_per_rev", Idle, "counts (0 = no output encoder)", 0, MAX, 0;
    STABILITY_MARGIN = 0x0905, "stability_margin", Idle, "Q0.16 fraction of the discrete PD bound", 1, 65536, 32_768;
    // --- 0x0Axx feed-forward ---
    TORQUE_OFFSET = 0x0A00, "torque_offset", Any, "τLSB (constant, added in every mode)", -TQ, TQ, 0;
    GRAVITY_SIN = 0x0A01, "gravity_sin", Any, "τLSB (× sin of the output angle)", -TQ, TQ, 0;
    GRAVITY_COS = 0x0A02, "gravity_cos", Any, "τLSB (× cos of the output angle)", -TQ, TQ, 0;
}

/// Finds the definition of `id` (`Err(UnknownId)` if none).
pub fn lookup(id: u16) -> Result<&'static ParamDef, ParamStatus> {
    TABLE
        .iter()
        .find(|d| d.contains(id))
        .ok_or(ParamStatus::UnknownId)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_sorted_disjoint_and_defaults_in_range() {
        for w in TABLE.windows(2) {
            let (a, b) = (&w[0], &w[1]);
            assert!(
                u32::from(a.id) + u32::from(a.count) <= u32::from(b.id),
                "{a:?} {b:?}"
            );
        }
        for d in TABLE {
            assert!(d.min <= d.max, "{}", d.name);
            assert!(d.check(d.default).is_ok(), "{} default", d.name);
            assert_ne!(d.id, 0, "id 0 is reserved");
        }
    }

    #[test]
    fn lookup_finds_table_entries_and_rejects_gaps() {
        assert_eq!(
            lookup(RIPPLE_TABLE + 63).map(|d| d.name),
            Ok("ripple_table")
        );
        assert_eq!(lookup(RIPPLE_TABLE + 64), Err(ParamStatus::UnknownId));
        assert_eq!(lookup(0x0100), Err(ParamStatus::UnknownId));
        assert_eq!(lookup(KE).map(|d| d.access), Ok(Access::Any));
        assert_eq!(
            lookup(TORQUE_LIMIT).and_then(|d| d.check(40_000)),
            Err(ParamStatus::OutOfRange)
        );
    }
}
