//! Names a user types (a column, an effect) and the "did you mean" when one is misspelled:
//! the nearest known name by edit distance, or one that differs only in case.

use sim_plant::effects::EffectKind;
use thiserror::Error;

/// The known name closest to `word`, if one is close enough to be what was meant: equal but
/// for case, or within a third of the word's length in edits (at least 1, at most 3).
pub fn closest<'a>(word: &str, known: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    let limit = (word.chars().count() / 3).clamp(1, 3);
    known
        .into_iter()
        .filter(|k| *k != word)
        .map(|k| {
            let d = if k.eq_ignore_ascii_case(word) {
                0
            } else {
                strsim::osa_distance(&k.to_ascii_lowercase(), &word.to_ascii_lowercase())
            };
            (d, k)
        })
        .filter(|&(d, _)| d <= limit)
        .min_by_key(|&(d, _)| d)
        .map(|(_, k)| k)
}

/// ` (did you mean `x`?)`, or nothing.
pub fn did_you_mean<'a>(word: &str, known: impl IntoIterator<Item = &'a str>) -> String {
    closest(word, known)
        .map(|k| format!(" (did you mean `{k}`?)"))
        .unwrap_or_default()
}

/// An effect name the library does not know.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("unknown effect `{name}`{hint}; known: {known}")]
pub struct UnknownEffect {
    /// What was asked for.
    pub name: String,
    /// ` (did you mean …?)` or empty.
    pub hint: String,
    /// The known names, comma-separated.
    pub known: String,
}

/// The effect called `name` (`coulomb`, `ripple`, …).
pub fn effect(name: &str) -> Result<EffectKind, UnknownEffect> {
    EffectKind::from_name(name).ok_or_else(|| {
        let names = EffectKind::ALL.map(|k| k.name());
        UnknownEffect {
            name: name.to_string(),
            hint: did_you_mean(name, names),
            known: names.join(", "),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn near_misses_are_suggested_and_strangers_are_not() {
        let cols = ["time_s", "torque_Nm", "q_rad"];
        assert_eq!(closest("torqe_Nm", cols), Some("torque_Nm"));
        assert_eq!(closest("TIME_S", cols), Some("time_s"));
        assert_eq!(closest("q_deg", cols), None);
        assert_eq!(closest("velocity", cols), None);
        assert_eq!(
            closest("q_rad", cols),
            None,
            "an exact match is no suggestion"
        );
    }

    #[test]
    fn a_misspelled_effect_names_the_one_meant() {
        let e = effect("coulmb").unwrap_err();
        assert_eq!(e.hint, " (did you mean `coulomb`?)");
        assert!(e.to_string().contains("known: "), "{e}");
        assert_eq!(effect("ripple"), Ok(EffectKind::Ripple));
        assert!(effect("banana").unwrap_err().hint.is_empty());
    }
}
