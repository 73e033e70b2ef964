//! Where a validation record leaves the positions the estimation record covered. A term
//! periodic in the position (ripple, cogging, gravity) is fitted on the arc it saw; beyond
//! it, a relative error δ of its period slips its phase by 2π·δ per period travelled, so a
//! period that fits the estimation record well can mispredict a validation record that sits
//! a few periods away, with nothing wrong in the model's form.

use crate::model::Model;
use crate::residual::Prepared;

/// One note per position-periodic effect of `model` whose period the validation record
/// `val` extrapolates over at least one period beyond the estimation record `est`'s range
/// (none without a validation record).
pub fn extrapolation_notes(model: &Model, est: &Prepared, val: Option<&Prepared>) -> Vec<String> {
    let Some(val) = val else {
        return Vec::new();
    };
    let range = |x: &[f64]| {
        x.iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
                (l.min(v), h.max(v))
            })
    };
    let (lo, hi) = range(&est.position);
    let (vlo, vhi) = range(&val.position);
    let beyond = (lo - vlo).max(vhi - hi).max(0.0);
    if !(beyond.is_finite() && hi > lo) {
        return Vec::new();
    }
    let unit = est.axis.unit("rad");
    model
        .effects
        .iter()
        .filter_map(|e| {
            let period = (e.kind.fit_traits().position_period?)(&e.shape, est.gear_ratio);
            let periods = beyond / period;
            (period > 0.0 && periods >= 1.0).then(|| {
                // The fitted period's own 1σ, where the refit estimated it, as a phase there.
                let slip = e
                    .shape_sigma
                    .map(|s| {
                        format!(
                            " (its 1σ, {:.2} %, is {:.2} rad of phase)",
                            100.0 * s / period,
                            std::f64::consts::TAU * periods * s / period
                        )
                    })
                    .unwrap_or_default();
                format!(
                    "{}: the validation record reaches {beyond:.3} {unit} beyond the positions \
                     the estimation record covered ({vlo:.3}…{vhi:.3} against {lo:.3}…{hi:.3} \
                     {unit}): {periods:.1} periods of {period:.4} {unit} past the {:.1} it was \
                     fitted on, where an error δ in the period slips the phase by \
                     2π·{periods:.1}·δ{slip}. Record the estimation over the positions the \
                     joint will use.",
                    e.kind.name(),
                    (hi - lo) / period,
                )
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::{Columns, Recording};

    fn prepared(from: f64, to: f64) -> Prepared {
        let n = 4000;
        let dt = 1e-3;
        let output: Vec<f64> = (0..n)
            .map(|k| from + (to - from) * 0.5 * (1.0 - (k as f64 * 3e-3).cos()))
            .collect();
        let rec = Recording {
            path: "synthetic".into(),
            time: (0..n).map(|k| k as f64 * dt).collect(),
            input: (0..n).map(|k| (k as f64 * 0.01).sin()).collect(),
            output,
            load_output: None,
            dt,
            units: ("N·m".into(), "rad".into()),
            columns: Columns::new("u", "q"),
            resampled: None,
            recorded: None,
        };
        Prepared::new(&rec, Some(40.0))
    }

    /// A ripple of period 0.4 fitted on 0.2…0.9 rad: a validation record on −1.5…0.1 rad
    /// lies 1.7 rad = 4.25 periods beyond and gets a note; one inside the arc does not, nor
    /// does a model without a position-periodic term.
    #[test]
    fn a_ripple_validated_periods_away_gets_a_note() {
        let mut m = super::super::tests::with_ripple(0.4);
        let est = prepared(0.2, 0.9);
        let notes = extrapolation_notes(&m, &est, Some(&prepared(0.1, -1.5)));
        assert_eq!(notes.len(), 1, "{notes:?}");
        let n = &notes[0];
        assert!(
            n.starts_with("ripple:") && n.contains("reaches 1.700 rad beyond"),
            "{n}"
        );
        assert!(!n.contains("1σ"), "{n}");
        m.effects[1].shape_sigma = Some(0.004);
        let n = &extrapolation_notes(&m, &est, Some(&prepared(0.1, -1.5)))[0];
        assert!(n.contains("its 1σ, 1.00 %, is 0.27 rad of phase"), "{n}");
        assert!(extrapolation_notes(&m, &est, Some(&prepared(0.3, 0.8))).is_empty());
        assert!(extrapolation_notes(&m, &est, None).is_empty());
        let plain = Model::baseline();
        assert!(extrapolation_notes(&plain, &est, Some(&prepared(0.1, -1.5))).is_empty());
    }
}
