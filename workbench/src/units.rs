//! Units from a column name's suffix: `time_s`, `q_deg`, `torque_cmd_Nm`, `motor_vel_rad_s`.
//!
//! [`SUFFIXES`] is the one table of the suffixes a recording may use, with the unit plots and
//! reports label the column with and the factor that brings its values to SI. The HIL
//! recorder (`hil-host`) names its columns from this table, so a lab recording loads with its
//! units.
//!
//! A suffix is the part after the last `_`, or after the last two for the per-second units
//! (`_rad_s`): the longest one the table knows wins, so `motor_vel_rad_s` is rad/s and
//! `time_s` is seconds. A name without a known suffix is unitless (factor 1) unless its last
//! `_`-part *looks like a unit* ([`looks_like_unit`]: an SI prefix on a unit symbol, such as
//! `km`, `nm`, `mA`, `kNm`, `mrad`): that is an [`UnknownUnit`] error naming the column, not a
//! silent factor of 1. Ordinary names (`q`, `pos`, `tau_motor`, `force_cmd`) carry no such
//! part and read as unitless. Case matters: `_nm` is nanometres, not `_Nm`.

use thiserror::Error;

/// One suffix the workbench reads: the unit it stands for and the factor to SI.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Suffix {
    /// The text after the column name's `_` (`"Nm"`, `"rad_s"`).
    pub suffix: &'static str,
    /// The SI unit the column holds after scaling, as plots label it.
    pub unit: &'static str,
    /// Factor from the column's values to `unit`.
    pub factor: f64,
}

const fn s(suffix: &'static str, unit: &'static str, factor: f64) -> Suffix {
    Suffix {
        suffix,
        unit,
        factor,
    }
}

const DEG: f64 = std::f64::consts::PI / 180.0;

/// The suffixes a recording's columns may carry.
pub const SUFFIXES: &[Suffix] = &[
    s("s", "s", 1.0),
    s("ms", "s", 1e-3),
    s("us", "s", 1e-6),
    s("m", "m", 1.0),
    s("mm", "m", 1e-3),
    s("rad", "rad", 1.0),
    s("deg", "rad", DEG),
    s("N", "N", 1.0),
    s("Nm", "N·m", 1.0),
    s("V", "V", 1.0),
    s("A", "A", 1.0),
    s("mps", "m/s", 1.0),
    s("radps", "rad/s", 1.0),
    s("rad_s", "rad/s", 1.0),
    s("deg_s", "rad/s", DEG),
];

/// SI prefixes [`looks_like_unit`] recognises in front of a unit symbol.
const PREFIXES: &[&str] = &["", "n", "u", "µ", "m", "c", "d", "k", "M", "G"];
/// Unit symbols [`looks_like_unit`] recognises after a prefix.
const SYMBOLS: &[&str] = &[
    "m", "s", "g", "N", "Nm", "rad", "deg", "V", "A", "W", "Hz", "mps", "radps",
];

/// A selected column whose name ends in a unit-like suffix the table does not know.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error(
    "column `{column}`: unknown unit suffix `_{suffix}`{}; known suffixes: {}",
    did_you_mean(.suffix),
    known_suffixes()
)]
pub struct UnknownUnit {
    /// The column.
    pub column: String,
    /// Its unit-like suffix.
    pub suffix: String,
}

/// `, did you mean `_Nm`?` when a known suffix differs from `suffix` only in case.
fn did_you_mean(suffix: &str) -> String {
    SUFFIXES
        .iter()
        .find(|k| k.suffix.eq_ignore_ascii_case(suffix))
        .map(|k| format!(" (did you mean `_{}`?)", k.suffix))
        .unwrap_or_default()
}

/// The table's suffixes with their units, for error messages.
pub fn known_suffixes() -> String {
    SUFFIXES
        .iter()
        .map(|k| format!("_{} ({})", k.suffix, k.unit))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Whether `part` reads as a unit symbol: one of a few SI prefixes (or none) on one of a few
/// symbols. Words a column name ends in (`cmd`, `pos`, `motor`, `est`, `true`) do not.
pub fn looks_like_unit(part: &str) -> bool {
    PREFIXES.iter().any(|p| {
        part.strip_prefix(p)
            .is_some_and(|rest| SYMBOLS.contains(&rest))
    })
}

/// The table's row for `column`'s suffix, `None` for a unitless name; an error for a
/// unit-like suffix the table does not know (see the module docs for the rule).
pub fn suffix_of(column: &str) -> Result<Option<&'static Suffix>, UnknownUnit> {
    let known = SUFFIXES
        .iter()
        .filter(|k| {
            column
                .strip_suffix(k.suffix)
                .is_some_and(|head| head.ends_with('_'))
        })
        .max_by_key(|k| k.suffix.len());
    if known.is_some() {
        return Ok(known);
    }
    match column.rsplit_once('_') {
        Some((_, part)) if looks_like_unit(part) => Err(UnknownUnit {
            column: column.to_string(),
            suffix: part.to_string(),
        }),
        _ => Ok(None),
    }
}

/// Unit label and SI factor of `column` (`("", 1.0)` for a unitless name).
pub fn unit_of(column: &str) -> Result<(&'static str, f64), UnknownUnit> {
    Ok(suffix_of(column)?.map_or(("", 1.0), |k| (k.unit, k.factor)))
}

/// A number in engineering form for people: 4 significant digits, plain between 10⁻³ and
/// 10⁵ (`9.735`, `0.01234`, `12350`), else with an exponent that is a multiple of 3
/// (`1.235e6`, `4.5e-9`).
pub fn eng(x: f64) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x == 0.0 {
        return "0".into();
    }
    let trim = |s: String| {
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    };
    // Four significant digits of x, in scientific form: rounding first decides the decade
    // (9.99996e5 is 1.000e6, not 1000e3).
    let sci = format!("{x:.3e}");
    let (mantissa, exp) = sci.split_once('e').unwrap_or((&sci, "0"));
    let exp: i32 = exp.parse().unwrap_or(0);
    let m: f64 = mantissa.parse().unwrap_or(x);
    if (-3..5).contains(&exp) {
        let digits = (3 - exp).max(0) as usize;
        return trim(format!("{:.digits$}", m * 10f64.powi(exp)));
    }
    let e3 = exp.div_euclid(3) * 3;
    let digits = (3 - (exp - e3)) as usize;
    format!(
        "{}e{e3}",
        trim(format!("{:.digits$}", m * 10f64.powi(exp - e3)))
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_suffixes_scale_to_si_and_the_longest_wins() {
        assert_eq!(unit_of("time_s"), Ok(("s", 1.0)));
        assert_eq!(unit_of("t_ms"), Ok(("s", 1e-3)));
        assert_eq!(unit_of("torque_cmd_Nm"), Ok(("N·m", 1.0)));
        assert_eq!(unit_of("motor_vel_rad_s"), Ok(("rad/s", 1.0)));
        assert_eq!(unit_of("q_deg_s"), Ok(("rad/s", DEG)));
        assert_eq!(unit_of("q_deg"), Ok(("rad", DEG)));
    }

    #[test]
    fn ordinary_names_are_unitless() {
        for name in [
            "q",
            "pos",
            "t",
            "u",
            "tau_motor",
            "force_cmd",
            "cmd_missing",
            "seq",
            "vel_est",
            "x_true",
            "state",
            "_",
        ] {
            assert_eq!(unit_of(name), Ok(("", 1.0)), "{name}");
        }
    }

    #[test]
    fn an_unknown_unit_suffix_is_an_error_naming_the_column_and_the_known_ones() {
        let e = unit_of("x_km").unwrap_err();
        assert_eq!(e.column, "x_km");
        assert_eq!(e.suffix, "km");
        let msg = e.to_string();
        assert!(msg.contains("column `x_km`"), "{msg}");
        assert!(
            msg.contains("_Nm (N·m)") && msg.contains("_rad_s (rad/s)"),
            "{msg}"
        );
        for name in ["torque_nm", "i_mA", "f_kN", "q_mrad", "t_ns", "tau_kNm"] {
            assert!(unit_of(name).is_err(), "{name}");
        }
        let nm = unit_of("torque_cmd_nm").unwrap_err().to_string();
        assert!(nm.contains("did you mean `_Nm`?"), "{nm}");
    }

    #[test]
    fn engineering_numbers() {
        for (x, s) in [
            (9.7351, "9.735"),
            (0.012346, "0.01235"),
            (12346.0, "12350"),
            (95.0, "95"),
            (-3.179, "-3.179"),
            (1.2346e6, "1.235e6"),
            (4.5e-9, "4.5e-9"),
            (0.0, "0"),
            (f64::NAN, "NaN"),
            (999_999.0, "1e6"),
            (0.00099999, "0.001"),
            (99_999.9, "100e3"),
            (-2.5e-7, "-250e-9"),
        ] {
            assert_eq!(eng(x), s, "{x}");
        }
    }
}
