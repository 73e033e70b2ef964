//! Units accepted in model files.
//!
//! Every number inside the simulator is SI and referred to the **output shaft** (the convention
//! of the thesis's Tables 4.1/4.2, Schempf 1990 §4). A model file may write a parameter as a
//! bare number (already in the canonical unit), as `{ value = …, unit = "…" }`, or as a string
//! with a unit suffix (`"0.8 deg"`). Units are checked against the parameter's canonical unit
//! and converted; anything else is an error that names the file position.

use std::f64::consts::PI;

/// One accepted spelling of a unit: its canonical unit and the factor to that canonical unit.
struct Alias {
    spelling: &'static str,
    canonical: &'static str,
    factor: f64,
}

const DEG: f64 = PI / 180.0;

/// The table of spellings. Canonical units are the ones parameter specs use.
const ALIASES: &[Alias] = &[
    a("1", "1", 1.0),
    a("", "1", 1.0),
    a("%", "1", 0.01),
    a("N·m", "N·m", 1.0),
    a("Nm", "N·m", 1.0),
    a("N*m", "N·m", 1.0),
    a("N.m", "N·m", 1.0),
    a("rad", "rad", 1.0),
    a("deg", "rad", DEG),
    a("°", "rad", DEG),
    a("arcmin", "rad", DEG / 60.0),
    a("rad/s", "rad/s", 1.0),
    a("deg/s", "rad/s", DEG),
    a("N·m·s/rad", "N·m·s/rad", 1.0),
    a("Nms/rad", "N·m·s/rad", 1.0),
    a("N*m*s/rad", "N·m·s/rad", 1.0),
    a("N·m/(deg/s)", "N·m·s/rad", 1.0 / DEG),
    a("Nm/(deg/s)", "N·m·s/rad", 1.0 / DEG),
    a("N·m/rad", "N·m/rad", 1.0),
    a("Nm/rad", "N·m/rad", 1.0),
    a("N*m/rad", "N·m/rad", 1.0),
    a("N·m/deg", "N·m/rad", 1.0 / DEG),
    a("Nm/deg", "N·m/rad", 1.0 / DEG),
    a("kg·m²", "kg·m²", 1.0),
    a("kg*m^2", "kg·m²", 1.0),
    a("kgm2", "kg·m²", 1.0),
    a("s", "s", 1.0),
    a("ms", "s", 1e-3),
    a("us", "s", 1e-6),
    a("µs", "s", 1e-6),
    a("Hz", "Hz", 1.0),
    a("kHz", "Hz", 1e3),
    a("1/(N·m)", "1/(N·m)", 1.0),
    a("1/Nm", "1/(N·m)", 1.0),
    a("kg·m²·s²", "kg·m²·s²", 1.0),
    a("counts/rev", "counts/rev", 1.0),
    a("cycles/rev", "cycles/rev", 1.0),
    a("samples", "samples", 1.0),
];

const fn a(spelling: &'static str, canonical: &'static str, factor: f64) -> Alias {
    Alias {
        spelling,
        canonical,
        factor,
    }
}

/// What the model's coordinate measures. The equations of a rigid joint and of a linear axis
/// are the same with force for torque, metres for radians and kilograms for kg·m² (a ball
/// screw's carriage, the EMPS benchmark): the numbers are stored alike, and only the names of
/// their units differ, in files, reports and the spellings a file may use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Axis {
    /// A joint: N·m, rad, kg·m².
    #[default]
    Rotary,
    /// A linear axis: N, m, kg.
    Linear,
}

impl Axis {
    /// The axis whose position is measured in `unit` (`m` → linear, anything else rotary).
    pub fn of_position_unit(unit: &str) -> Axis {
        if unit == "m" {
            Axis::Linear
        } else {
            Axis::Rotary
        }
    }

    /// Its name in files (`rotary`, `linear`).
    pub const fn name(self) -> &'static str {
        match self {
            Axis::Rotary => "rotary",
            Axis::Linear => "linear",
        }
    }

    /// A canonical (rotary) unit as this axis names it: `N·m·s/rad` → `N·s/m` on a linear
    /// axis.
    pub fn unit(self, canonical: &str) -> String {
        match self {
            Axis::Rotary => canonical.to_string(),
            Axis::Linear => canonical
                .replace("(N·m)", "N")
                .replace("kg·m²", "kg")
                .replace("N·m", "N")
                .replace("rad", "m"),
        }
    }
}

/// Spellings on a linear axis, to the canonical (rotary-named) unit of the same number.
const LINEAR: &[Alias] = &[
    a("N", "N·m", 1.0),
    a("kN", "N·m", 1e3),
    a("m", "rad", 1.0),
    a("mm", "rad", 1e-3),
    a("um", "rad", 1e-6),
    a("µm", "rad", 1e-6),
    a("m/s", "rad/s", 1.0),
    a("mm/s", "rad/s", 1e-3),
    a("N·s/m", "N·m·s/rad", 1.0),
    a("Ns/m", "N·m·s/rad", 1.0),
    a("N*s/m", "N·m·s/rad", 1.0),
    a("N/m", "N·m/rad", 1.0),
    a("N/mm", "N·m/rad", 1e3),
    a("kg", "kg·m²", 1.0),
    a("1/N", "1/(N·m)", 1.0),
    a("kg·s²", "kg·m²·s²", 1.0),
];

/// [`conversion`] on `axis`: a linear axis's file writes N, m, kg (and their multiples), and
/// a rotary spelling of a linear quantity there is an error, not a silent factor of 1.
pub fn conversion_on(unit: &str, canonical: &str, axis: Axis) -> Result<f64, String> {
    if axis == Axis::Rotary {
        return conversion(unit, canonical);
    }
    let unit = unit.trim();
    if let Some(al) = LINEAR.iter().find(|al| al.spelling == unit) {
        return if al.canonical == canonical {
            Ok(al.factor)
        } else {
            Err(format!(
                "unit `{unit}` measures {}, but this parameter is in {}",
                Axis::Linear.unit(al.canonical),
                Axis::Linear.unit(canonical)
            ))
        };
    }
    let linear = Axis::Linear.unit(canonical);
    if linear != canonical && !unit.is_empty() && conversion(unit, canonical).is_ok() {
        return Err(format!(
            "unit `{unit}` is a rotary unit, and this model's axis is linear: this parameter \
             is in {linear}"
        ));
    }
    conversion(unit, canonical).map_err(|e| e.replace(canonical, &linear))
}

/// Factor converting a value written in `unit` to `canonical`, or an explanation.
pub fn conversion(unit: &str, canonical: &str) -> Result<f64, String> {
    let unit = unit.trim();
    match ALIASES.iter().find(|al| al.spelling == unit) {
        Some(al) if al.canonical == canonical => Ok(al.factor),
        Some(al) => Err(format!(
            "unit `{unit}` measures {}, but this parameter is in {canonical}",
            al.canonical
        )),
        None => Err(format!(
            "unknown unit `{unit}` (this parameter is in {canonical}; accepted: {})",
            accepted(canonical)
        )),
    }
}

/// Accepted spellings for a canonical unit, for error messages.
pub fn accepted(canonical: &str) -> String {
    ALIASES
        .iter()
        .filter(|al| al.canonical == canonical && !al.spelling.is_empty())
        .map(|al| format!("`{}`", al.spelling))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Split `"0.8 deg"` into (0.8, "deg"). The number must come first.
pub fn split_number_unit(s: &str) -> Result<(f64, &str), String> {
    let s = s.trim();
    let end = s
        .char_indices()
        .find(|&(i, c)| {
            !(c.is_ascii_digit()
                || c == '.'
                || c == '+'
                || c == '-'
                || ((c == 'e' || c == 'E')
                    && s[i + 1..]
                        .starts_with(|d: char| d.is_ascii_digit() || d == '-' || d == '+')))
        })
        .map(|(i, _)| i)
        .unwrap_or(s.len());
    let number: f64 = s[..end]
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` does not start with a number"))?;
    Ok((number, s[end..].trim()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn converts_degrees_and_rejects_wrong_dimension() {
        assert!((conversion("deg", "rad").unwrap() - PI / 180.0).abs() < 1e-15);
        assert!(conversion("N·m", "rad")
            .unwrap_err()
            .contains("measures N·m"));
        assert!(conversion("furlong", "rad")
            .unwrap_err()
            .contains("unknown unit"));
        assert_eq!(split_number_unit("0.8 deg").unwrap(), (0.8, "deg"));
        assert_eq!(split_number_unit("-1.5e-3 s").unwrap(), (-1.5e-3, "s"));
        assert_eq!(split_number_unit("2.5").unwrap(), (2.5, ""));
        assert!(split_number_unit("deg").is_err());
    }

    #[test]
    fn a_linear_axis_speaks_newtons_and_metres() {
        let lin = Axis::Linear;
        assert_eq!(lin.unit("N·m·s/rad"), "N·s/m");
        assert_eq!(lin.unit("kg·m²"), "kg");
        assert_eq!(lin.unit("1/(N·m)"), "1/N");
        assert_eq!(Axis::Rotary.unit("N·m"), "N·m");
        assert_eq!(conversion_on("mm", "rad", lin).unwrap(), 1e-3);
        assert_eq!(conversion_on("N/mm", "N·m/rad", lin).unwrap(), 1e3);
        assert_eq!(conversion_on("ms", "s", lin).unwrap(), 1e-3);
        let e = conversion_on("N·m", "N·m", lin).unwrap_err();
        assert!(e.contains("rotary") && e.contains("in N"), "{e}");
        let e = conversion_on("N", "rad", lin).unwrap_err();
        assert!(e.contains("measures N") && e.contains("in m"), "{e}");
        assert!(conversion_on("N", "N·m", Axis::Rotary).is_err());
    }
}
