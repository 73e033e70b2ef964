//! A bounded memo of effect columns on one prepared record, for the shape searches and the
//! diagnosis: a search varies one effect's shape over hundreds of refits while the other
//! effects' columns stay as they were, and `--auto` diagnoses one record again after every
//! step over the same grid of candidate shapes. Building those columns (band-limited sign
//! columns, the quantiser's blurred sawtooth, a mode's filtered input) was most of a refit's
//! time and half of a diagnosis's.
//!
//! Keyed by what the columns are (a model's or a candidate's, on which window), the effect and
//! its shape to the bit, so a hit returns exactly the columns a rebuild would: results do not
//! depend on what the memo holds. It lives no longer than the record it was made for (one
//! refit, or one `--auto` run), so the record cannot change under it.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use sim_plant::effects::{EffectKind, Shape, Trajectory};

use super::design::{candidate_columns_on, model_columns};
use super::Prepared;

/// Bytes of columns a refit's memo keeps: the model's other effects beside the searched
/// effect's passing shapes (a few hundred columns of a 10⁴-sample record).
const REFIT_BUDGET: usize = 64 << 20;

/// Bytes of columns a diagnosis's memo keeps: its whole grid of candidate shapes on a long
/// record (about 85 MB on the 24 841-sample EMPS record, searched on at most 40 000 samples),
/// so that the next diagnosis finds it.
pub const DIAGNOSIS_BUDGET: usize = 192 << 20;

/// What a memo entry's columns are.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
struct Key {
    kind: EffectKind,
    /// `None`: the model's columns on the whole record ([`model_columns`]); `Some((offset,
    /// len))`: a candidate's ([`candidate_columns_on`]) on the trajectory that starts
    /// `offset` samples into the record and holds `len`.
    window: Option<(usize, usize)>,
    /// The shape's fields to the bit (`{:?}` of an `f64` round-trips).
    shape: String,
}

/// The memo (see the module's doc). Shared by the worker pool's refits.
#[derive(Debug)]
pub struct ColumnMemo {
    entries: Mutex<Entries>,
    /// Most bytes kept.
    budget: usize,
}

impl Default for ColumnMemo {
    fn default() -> Self {
        Self::with_budget(REFIT_BUDGET)
    }
}

#[derive(Debug, Default)]
struct Entries {
    map: HashMap<Key, Entry>,
    /// Bytes the entries hold.
    bytes: usize,
    /// A counter that orders uses, for least-recently-used eviction.
    tick: u64,
}

#[derive(Debug)]
struct Entry {
    cols: Arc<Vec<Vec<f64>>>,
    used: u64,
}

fn bytes_of(cols: &[Vec<f64>]) -> usize {
    cols.iter()
        .map(|c| c.len() * std::mem::size_of::<f64>())
        .sum()
}

impl ColumnMemo {
    /// An empty memo for a refit's shape searches.
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty memo that keeps at most `budget` bytes of columns (least recently used
    /// first out).
    pub fn with_budget(budget: usize) -> Self {
        ColumnMemo {
            entries: Mutex::default(),
            budget,
        }
    }

    /// [`model_columns`] of `kind` at `shape` on `p`, from the memo when it holds them.
    /// `p` must be the record every earlier call gave.
    pub fn columns(&self, kind: EffectKind, p: &Prepared, shape: &Shape) -> Arc<Vec<Vec<f64>>> {
        let key = Key {
            kind,
            window: None,
            shape: format!("{shape:?}"),
        };
        self.get_or(key, || model_columns(kind, p, shape))
    }

    /// [`candidate_columns_on`] of `kind` at `shape` on `t`, from the memo when it holds
    /// them. `t` must be the record every earlier call gave, or a window of it.
    pub fn candidate(&self, kind: EffectKind, t: &Trajectory, shape: &Shape) -> Arc<Vec<Vec<f64>>> {
        let key = Key {
            kind,
            window: Some((t.raw_offset, t.len())),
            shape: format!("{shape:?}"),
        };
        self.get_or(key, || candidate_columns_on(kind, t, shape))
    }

    fn get_or(&self, key: Key, build: impl FnOnce() -> Vec<Vec<f64>>) -> Arc<Vec<Vec<f64>>> {
        if let Some(c) = self.lookup(&key) {
            return c;
        }
        let cols = Arc::new(build());
        // A poisoned lock (a panic elsewhere) only costs the memo.
        if let Ok(mut e) = self.entries.lock() {
            e.tick += 1;
            let used = e.tick;
            let size = bytes_of(&cols);
            if size <= self.budget && !e.map.contains_key(&key) {
                while e.bytes + size > self.budget {
                    let Some(oldest) = e
                        .map
                        .iter()
                        .min_by_key(|(_, x)| x.used)
                        .map(|(k, _)| k.clone())
                    else {
                        break;
                    };
                    if let Some(gone) = e.map.remove(&oldest) {
                        e.bytes -= bytes_of(&gone.cols);
                    }
                }
                e.bytes += size;
                e.map.insert(
                    key,
                    Entry {
                        cols: Arc::clone(&cols),
                        used,
                    },
                );
            }
        }
        cols
    }

    fn lookup(&self, key: &Key) -> Option<Arc<Vec<Vec<f64>>>> {
        let mut e = self.entries.lock().ok()?;
        e.tick += 1;
        let tick = e.tick;
        let hit = e.map.get_mut(key)?;
        hit.used = tick;
        Some(Arc::clone(&hit.cols))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::{Columns, Recording};
    use crate::model::Model;
    use crate::residual::{refit, refit_with};

    fn record() -> Prepared {
        let n = 3000;
        let rec = Recording {
            path: "synthetic".into(),
            time: (0..n).map(|k| k as f64 * 1e-3).collect(),
            input: (0..n)
                .map(|k| {
                    let v = (k as f64 * 4e-3).cos();
                    0.01 * (k as f64 * 4e-3).sin() + 0.2 * v.signum()
                })
                .collect(),
            output: (0..n).map(|k| (k as f64 * 4e-3).sin()).collect(),
            load_output: None,
            dt: 1e-3,
            units: ("N·m".into(), "rad".into()),
            columns: Columns::new("u", "q"),
            resampled: None,
            recorded: None,
        };
        Prepared::new(&rec, Some(40.0))
    }

    fn with_coulomb(eps: f64) -> Model {
        let mut m = Model::baseline();
        let shape = Shape {
            sign_epsilon: eps,
            ..Shape::default()
        };
        m.add(EffectKind::Coulomb, shape);
        m
    }

    /// Through the memo, cold or warm, a refit is the plain refit to the bit.
    #[test]
    fn a_memoised_refit_is_the_plain_refit() {
        let p = record();
        let memo = ColumnMemo::new();
        for eps in [1e-3, 2e-3, 1e-3] {
            let (mut a, mut b) = (with_coulomb(eps), with_coulomb(eps));
            let fa = refit(&mut a, &p).unwrap();
            let fb = refit_with(&mut b, &p, Some(&memo)).unwrap();
            assert_eq!(fa.rss.to_bits(), fb.rss.to_bits());
            for (x, y) in a.params().iter().zip(b.params()) {
                assert_eq!(x.value.to_bits(), y.value.to_bits(), "{}", x.name);
            }
        }
    }

    /// A shape is a hit only to the bit, and the memo stays within its budget, keeping the
    /// entry in use; a candidate's columns on the record are not the model's.
    #[test]
    fn the_memo_is_exact_and_bounded() {
        let p = record();
        let entry = p.len() * std::mem::size_of::<f64>();
        let capacity = 24;
        let memo = ColumnMemo::with_budget(capacity * entry);
        let kept = Shape {
            sign_epsilon: 1e-3,
            ..Shape::default()
        };
        let first = memo.columns(EffectKind::Coulomb, &p, &kept);
        for k in 0..3 * capacity {
            let s = Shape {
                sign_epsilon: 1e-3 * (1.0 + f64::EPSILON * (k + 1) as f64),
                ..Shape::default()
            };
            let c = memo.columns(EffectKind::Coulomb, &p, &s);
            assert!(
                !Arc::ptr_eq(&c, &first),
                "shape {k} hit another shape's columns"
            );
            assert!(Arc::ptr_eq(
                &memo.columns(EffectKind::Coulomb, &p, &kept),
                &first
            ));
        }
        let (held, bytes) = {
            let e = memo.entries.lock().unwrap();
            (e.map.len(), e.bytes)
        };
        assert_eq!(held, capacity);
        assert_eq!(bytes, capacity * entry);
        assert!(!Arc::ptr_eq(
            &memo.columns(EffectKind::Asymmetry, &p, &kept),
            &first
        ));
        let t = p.trajectory();
        let candidate = memo.candidate(EffectKind::Coulomb, &t, &kept);
        assert!(!Arc::ptr_eq(&candidate, &first));
        assert!(Arc::ptr_eq(
            &memo.candidate(EffectKind::Coulomb, &t, &kept),
            &candidate
        ));
        assert_eq!(
            *candidate,
            super::super::design::candidate_columns_on(EffectKind::Coulomb, &t, &kept)
        );
    }
}
