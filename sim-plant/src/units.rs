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
}
