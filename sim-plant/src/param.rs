//! Model parameters: a value that is either fixed or free (for the fitter), with its spec.
//!
//! In a model file a parameter is written as
//! * a bare number — fixed, in the canonical unit of the spec (`torque = 1.38`);
//! * a string with a unit suffix — fixed, converted (`backlash = "0.8 deg"`);
//! * an inline table — `{ value = 1.38, free = true, unit = "N·m", min = 0.0, max = 5.0 }`
//!   (all keys but `value` optional; unknown keys are errors).
//!
//! The span of the written value is kept so that a wrong unit or an out-of-range number can be
//! reported with file, line and column after parsing (see [`crate::model`]).

use std::fmt;
use std::ops::Range;

use serde::de::{self, MapAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::units;

/// How a parameter enters the fingerprint of its effect.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// Linear amplitude of fingerprint column `n` of the effect (see
    /// [`crate::effects::fingerprint`]); the fitter can solve for it by least squares.
    Amplitude(usize),
    /// Shape parameter: the fingerprint is nonlinear in it; searched on a grid
    /// ([`crate::effects::shape_grid`]).
    Shape,
    /// A dynamics-only setting that the equation-error fingerprint does not see.
    Setting,
}

/// Description of one parameter: name, canonical unit, default, physical bounds, meaning.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    /// Key in the model file.
    pub name: &'static str,
    /// Canonical unit (SI, output-referred); see [`crate::units`].
    pub unit: &'static str,
    /// Value used when the key is absent.
    pub default: f64,
    /// Smallest physically meaningful value.
    pub min: f64,
    /// Largest physically meaningful value.
    pub max: f64,
    /// How the parameter relates to the effect's fingerprint.
    pub role: Role,
    /// What it is (the doc comment of the declaration; may start with a space).
    pub doc: &'static str,
}

/// A parameter value, fixed or free.
#[derive(Clone, Debug)]
pub struct Param {
    /// Value in the canonical unit of the parameter's spec.
    pub value: f64,
    /// Whether the fitter may change it.
    pub free: bool,
    /// Optional fitting bounds (canonical unit).
    pub min: Option<f64>,
    /// Optional fitting bounds (canonical unit).
    pub max: Option<f64>,
    /// Unit as written in the file, pending conversion by [`Param::resolve`].
    written_unit: Option<String>,
    /// Byte range of the value in the source text, if parsed.
    span: Option<Range<usize>>,
}

impl PartialEq for Param {
    /// Equality of meaning: value, freedom and bounds (not where it was written).
    fn eq(&self, other: &Self) -> bool {
        self.value == other.value
            && self.free == other.free
            && self.min == other.min
            && self.max == other.max
            && self.written_unit == other.written_unit
    }
}

impl Param {
    /// A fixed parameter.
    pub fn fixed(value: f64) -> Self {
        Self {
            value,
            free: false,
            min: None,
            max: None,
            written_unit: None,
            span: None,
        }
    }

    /// A free parameter (to be fitted), starting at `value`.
    pub fn free(value: f64) -> Self {
        Self {
            free: true,
            ..Self::fixed(value)
        }
    }

    /// Where the value was written (byte range in the source), if it came from a file.
    pub fn span(&self) -> Option<Range<usize>> {
        self.span.clone()
    }

    /// Convert a written unit to the canonical unit of `spec` (spelled as `axis` spells it)
    /// and check the physical range. On error returns the message; the caller attaches the
    /// position from [`Param::span`].
    pub fn resolve(&mut self, spec: &ParamSpec, axis: units::Axis) -> Result<(), String> {
        if let Some(unit) = self.written_unit.take() {
            let factor = units::conversion_on(&unit, spec.unit, axis)
                .map_err(|e| format!("parameter `{}`: {e}", spec.name))?;
            self.value *= factor;
            self.min = self.min.map(|m| m * factor);
            self.max = self.max.map(|m| m * factor);
        }
        if !self.value.is_finite() {
            return Err(format!("parameter `{}` is not a finite number", spec.name));
        }
        if self.value < spec.min || self.value > spec.max {
            return Err(format!(
                "parameter `{}` = {} {} is outside its physical range [{}, {}]",
                spec.name,
                self.value,
                axis.unit(spec.unit),
                spec.min,
                spec.max
            ));
        }
        // The fitting bounds: a NaN bound compares false with everything, so it would pass
        // every check below and be written back; a start outside the box has no fit to start.
        for (key, bound) in [("min", self.min), ("max", self.max)] {
            if bound.is_some_and(f64::is_nan) {
                return Err(format!(
                    "parameter `{}`: {key} is NaN; a bound must be a number",
                    spec.name
                ));
            }
        }
        if let (Some(lo), Some(hi)) = (self.min, self.max) {
            if lo > hi {
                return Err(format!(
                    "parameter `{}`: min {lo} is above max {hi}",
                    spec.name
                ));
            }
        }
        if let Some(lo) = self.min.filter(|lo| self.value < *lo) {
            return Err(format!(
                "parameter `{}` = {} {} is below its min {lo}",
                spec.name, self.value, spec.unit
            ));
        }
        if let Some(hi) = self.max.filter(|hi| self.value > *hi) {
            return Err(format!(
                "parameter `{}` = {} {} is above its max {hi}",
                spec.name, self.value, spec.unit
            ));
        }
        Ok(())
    }

    /// Whether the value is written as a bare number (fixed, no bounds).
    pub fn is_plain(&self) -> bool {
        !self.free && self.min.is_none() && self.max.is_none()
    }

    /// TOML text for this value (bare number or inline table), used by the model writer.
    pub fn to_toml_value(&self) -> String {
        if self.is_plain() {
            return fmt_f64(self.value);
        }
        let mut s = format!("{{ value = {}", fmt_f64(self.value));
        if self.free {
            s.push_str(", free = true");
        }
        if let Some(m) = self.min {
            s.push_str(&format!(", min = {}", fmt_f64(m)));
        }
        if let Some(m) = self.max {
            s.push_str(&format!(", max = {}", fmt_f64(m)));
        }
        s.push_str(" }");
        s
    }
}

/// Shortest text that reads back to the same `f64` and is a valid TOML float.
pub fn fmt_f64(v: f64) -> String {
    if v.is_nan() {
        return "nan".into();
    }
    if v.is_infinite() {
        return if v > 0.0 { "inf".into() } else { "-inf".into() };
    }
    let s = format!("{v:?}");
    if s.contains('.') || s.contains('e') || s.contains("inf") || s.contains("nan") {
        s
    } else {
        format!("{s}.0")
    }
}

impl Serialize for Param {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        if self.is_plain() {
            return serializer.serialize_f64(self.value);
        }
        #[derive(Serialize)]
        struct Table {
            value: f64,
            free: bool,
            #[serde(skip_serializing_if = "Option::is_none")]
            min: Option<f64>,
            #[serde(skip_serializing_if = "Option::is_none")]
            max: Option<f64>,
        }
        Table {
            value: self.value,
            free: self.free,
            min: self.min,
            max: self.max,
        }
        .serialize(serializer)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ParamTable {
    value: f64,
    #[serde(default)]
    free: bool,
    unit: Option<String>,
    min: Option<f64>,
    max: Option<f64>,
}

/// The written forms, before we know where they were.
struct Written(Param);

impl<'de> Deserialize<'de> for Written {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Param;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str(
                    "a number, a string such as \"0.8 deg\", or a table { value = …, free = … }",
                )
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Param, E> {
                Ok(Param::fixed(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Param, E> {
                Ok(Param::fixed(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Param, E> {
                Ok(Param::fixed(v as f64))
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<Param, E> {
                let (value, unit) = units::split_number_unit(v).map_err(E::custom)?;
                let mut p = Param::fixed(value);
                p.written_unit = Some(unit.to_string());
                Ok(p)
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<Param, A::Error> {
                let t = ParamTable::deserialize(de::value::MapAccessDeserializer::new(map))?;
                Ok(Param {
                    value: t.value,
                    free: t.free,
                    min: t.min,
                    max: t.max,
                    written_unit: t.unit,
                    span: None,
                })
            }
        }
        deserializer.deserialize_any(V).map(Written)
    }
}

impl<'de> Deserialize<'de> for Param {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let spanned = toml::Spanned::<Written>::deserialize(deserializer)?;
        let span = spanned.span();
        let mut p = spanned.into_inner().0;
        // A zero-length span means the deserializer was not toml (e.g. JSON): no position.
        p.span = (!span.is_empty()).then_some(span);
        Ok(p)
    }
}

/// Declare an effect's parameter struct, its [`ParamSpec`] list and accessors, from one table.
///
/// ```text
/// define_params! {
///     /// doc
///     torque: "N·m" = 0.0, [0.0, 1e6], Amplitude(0);
/// }
/// ```
#[macro_export]
#[doc(hidden)]
macro_rules! define_params {
    ($( $(#[doc = $doc:literal])+ $name:ident : $unit:literal = $default:expr, [$min:expr, $max:expr], $role:expr ;)*) => {
        /// Parameters of this effect as written in a model file (output-referred SI units).
        #[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
        #[serde(deny_unknown_fields, default)]
        pub struct Params {
            $( $(#[doc = $doc])+ pub $name: $crate::param::Param, )*
        }
        impl Default for Params {
            fn default() -> Self {
                Self { $( $name: $crate::param::Param::fixed($default), )* }
            }
        }
        /// Names, units, defaults and roles of this effect's parameters.
        pub const PARAMS: &[$crate::param::ParamSpec] = &[
            $( $crate::param::ParamSpec {
                name: stringify!($name),
                unit: $unit,
                default: $default,
                min: $min,
                max: $max,
                role: { #[allow(unused_imports)] use $crate::param::Role::*; $role },
                doc: concat!($($doc),+),
            }, )*
        ];
        impl Params {
            /// Parameters paired with their specs, in [`PARAMS`] order.
            pub fn entries(&self) -> Vec<(&'static $crate::param::ParamSpec, &$crate::param::Param)> {
                let mut v = Vec::new();
                let mut _i = 0;
                $( v.push((&PARAMS[_i], &self.$name)); _i += 1; )*
                v
            }
            /// Mutable access, in [`PARAMS`] order (the fitter writes values back through this).
            pub fn entries_mut(&mut self) -> Vec<(&'static $crate::param::ParamSpec, &mut $crate::param::Param)> {
                let mut v = Vec::new();
                let mut _i = 0;
                $( v.push((&PARAMS[_i], &mut self.$name)); _i += 1; )*
                v
            }
        }
    };
}
