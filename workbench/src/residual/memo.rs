//! A bounded memo of effect columns on one prepared record, for the shape searches: a search
//! varies one effect's shape over hundreds of refits while the other effects' columns stay
//! as they were, and building those (band-limited sign columns, the quantiser's blurred
//! sawtooth) was most of a refit's time.
//!
//! Keyed by the effect and its shape to the bit, so a hit returns exactly the columns a
//! rebuild would: results do not depend on what the memo holds. It lives no longer than one
//! refit of one record (see `refine::refit_all`), so the record cannot change under it.

use std::sync::{Arc, Mutex};

use sim_plant::effects::{EffectKind, Shape};

use super::design::model_columns;
use super::Prepared;

/// Entries kept: the model's other effects (a handful) stay, being used at every refit,
/// while the searched effect's passing shapes cycle through the rest. At 10⁵ samples and
/// three columns an entry is 2.4 MB.
const CAPACITY: usize = 24;

/// The memo (see the module's doc). Shared by the worker pool's refits.
#[derive(Debug, Default)]
pub struct ColumnMemo {
    entries: Mutex<Entries>,
}

#[derive(Debug, Default)]
struct Entries {
    list: Vec<Entry>,
    /// A counter that orders uses, for least-recently-used eviction.
    tick: u64,
}

#[derive(Debug)]
struct Entry {
    kind: EffectKind,
    /// The shape's fields to the bit (`{:?}` of an `f64` round-trips).
    shape: String,
    cols: Arc<Vec<Vec<f64>>>,
    used: u64,
}

impl ColumnMemo {
    /// An empty memo.
    pub fn new() -> Self {
        Self::default()
    }

    /// [`model_columns`] of `kind` at `shape` on `p`, from the memo when it holds them.
    /// `p` must be the record every earlier call gave.
    pub fn columns(&self, kind: EffectKind, p: &Prepared, shape: &Shape) -> Arc<Vec<Vec<f64>>> {
        let key = format!("{shape:?}");
        if let Some(c) = self.lookup(kind, &key) {
            return c;
        }
        let cols = Arc::new(model_columns(kind, p, shape));
        // A poisoned lock (a panic elsewhere) only costs the memo.
        if let Ok(mut e) = self.entries.lock() {
            e.tick += 1;
            let used = e.tick;
            if !e.list.iter().any(|x| x.kind == kind && x.shape == key) {
                if e.list.len() >= CAPACITY {
                    if let Some(oldest) = (0..e.list.len()).min_by_key(|&i| e.list[i].used) {
                        e.list.swap_remove(oldest);
                    }
                }
                e.list.push(Entry {
                    kind,
                    shape: key,
                    cols: Arc::clone(&cols),
                    used,
                });
            }
        }
        cols
    }

    fn lookup(&self, kind: EffectKind, key: &str) -> Option<Arc<Vec<Vec<f64>>>> {
        let mut e = self.entries.lock().ok()?;
        e.tick += 1;
        let tick = e.tick;
        let hit = e
            .list
            .iter_mut()
            .find(|x| x.kind == kind && x.shape == key)?;
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

    /// A shape is a hit only to the bit, and the memo stays within its capacity, keeping
    /// the entry in use.
    #[test]
    fn the_memo_is_exact_and_bounded() {
        let p = record();
        let memo = ColumnMemo::new();
        let kept = Shape {
            sign_epsilon: 1e-3,
            ..Shape::default()
        };
        let first = memo.columns(EffectKind::Coulomb, &p, &kept);
        for k in 0..3 * CAPACITY {
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
        let held = memo.entries.lock().unwrap().list.len();
        assert_eq!(held, CAPACITY);
        assert!(!Arc::ptr_eq(
            &memo.columns(EffectKind::Asymmetry, &p, &kept),
            &first
        ));
    }
}
