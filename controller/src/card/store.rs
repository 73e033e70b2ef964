//! The card's parameter memory: one raw `i32` per id of the protocol's parameter table
//! (`proto::params::TABLE` is the single source of truth for ids, ranges and defaults). The
//! staging area a `ParamWrite` fills and a `ParamCommit` applies is `proto::staging`.
//!
//! Why raw values: the wire carries raw integers already in machine units, so the store is a
//! flat array the runtime can range-check against the table, read back for `ParamRead`, and
//! turn into typed law configurations ([`super::config`]) only at commit time.

use crate::proto::params::{self, ParamDef, TABLE};
use crate::proto::ParamStatus;

/// Number of raw slots: the sum of all table rows' `count`.
pub const SLOTS: usize = slot_count();

// Evaluated only at compile time (it initialises a `const`): an overflow or a bad index here
// is a compile error, never a runtime panic, so the firmware lints do not apply.
#[allow(clippy::arithmetic_side_effects, clippy::indexing_slicing)]
const fn slot_count() -> usize {
    let mut n = 0usize;
    let mut i = 0usize;
    while i < TABLE.len() {
        n += TABLE[i].count as usize;
        i += 1;
    }
    n
}

/// Index of `id` in the flat store, with its definition.
fn slot_of(id: u16) -> Result<(usize, &'static ParamDef), ParamStatus> {
    let mut base = 0usize;
    for d in TABLE {
        if d.contains(id) {
            let off = usize::from(id.wrapping_sub(d.id));
            return Ok((base.saturating_add(off), d));
        }
        base = base.saturating_add(usize::from(d.count));
    }
    Err(ParamStatus::UnknownId)
}

/// All parameter values, raw.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParamStore {
    values: [i32; SLOTS],
}

impl Default for ParamStore {
    fn default() -> Self {
        Self::new()
    }
}

impl ParamStore {
    /// Every parameter at its table default.
    pub fn new() -> Self {
        let mut values = [0i32; SLOTS];
        let mut base = 0usize;
        for d in TABLE {
            for k in 0..usize::from(d.count) {
                if let Some(v) = values.get_mut(base.saturating_add(k)) {
                    *v = d.default;
                }
            }
            base = base.saturating_add(usize::from(d.count));
        }
        ParamStore { values }
    }

    /// Raw value of `id`.
    pub fn get(&self, id: u16) -> Result<i32, ParamStatus> {
        let (slot, _) = slot_of(id)?;
        self.values.get(slot).copied().ok_or(ParamStatus::UnknownId)
    }

    /// Raw value of a table id known to exist (constants from `proto::params`); the table
    /// default if it somehow does not (cannot happen for the constants, tested).
    pub fn raw(&self, id: u16) -> i32 {
        self.get(id)
            .unwrap_or_else(|_| params::lookup(id).map(|d| d.default).unwrap_or(0))
    }

    /// Sets a value without any checks (read-only system values maintained by the card).
    pub(crate) fn set_unchecked(&mut self, id: u16, value: i32) {
        if let Ok((slot, _)) = slot_of(id) {
            if let Some(v) = self.values.get_mut(slot) {
                *v = value;
            }
        }
    }

    /// Overlays `entries` (in order, so a later write of the same id wins). Values are not
    /// checked here: entries come from a staging that checked them.
    pub fn apply(&mut self, entries: &[(u16, i32)]) {
        for &(id, v) in entries {
            self.set_unchecked(id, v);
        }
    }

    /// `n` consecutive raw values starting at `id` (the ripple table), into `out`.
    pub fn run(&self, id: u16, out: &mut [i32]) {
        for (k, o) in out.iter_mut().enumerate() {
            let id_k = u16::try_from(k).ok().and_then(|k| id.checked_add(k));
            *o = id_k.and_then(|i| self.get(i).ok()).unwrap_or(0);
        }
    }
}

/// Checks one write against the table: known id, writable in this state, in range.
pub fn check_write(id: u16, value: i32, driving: bool) -> Result<(), ParamStatus> {
    let (_, def) = slot_of(id)?;
    match def.access {
        params::Access::ReadOnly => return Err(ParamStatus::ReadOnly),
        params::Access::Idle if driving => return Err(ParamStatus::NotAllowedInState),
        _ => {}
    }
    def.check(value)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::proto::params::*;

    #[test]
    fn defaults_and_table_runs() {
        let s = ParamStore::new();
        assert_eq!(s.get(SUPERVISOR_TIMEOUT), Ok(200));
        assert_eq!(s.get(RIPPLE_TABLE + 63), Ok(0));
        assert_eq!(s.get(RIPPLE_TABLE + 64), Err(ParamStatus::UnknownId));
        assert_eq!(
            SLOTS,
            TABLE.iter().map(|d| usize::from(d.count)).sum::<usize>()
        );
        for d in TABLE {
            assert_eq!(s.raw(d.id), d.default, "{}", d.name);
        }
    }

    #[test]
    fn write_checks() {
        assert_eq!(check_write(KE, 5, true), Ok(()));
        assert_eq!(check_write(KE, -1, false), Err(ParamStatus::OutOfRange));
        assert_eq!(
            check_write(COMMIT_COUNT, 0, false),
            Err(ParamStatus::ReadOnly)
        );
        assert_eq!(
            check_write(ROTOR_INERTIA, 5, true),
            Err(ParamStatus::NotAllowedInState)
        );
        assert_eq!(check_write(0x7777, 0, false), Err(ParamStatus::UnknownId));
    }
}
