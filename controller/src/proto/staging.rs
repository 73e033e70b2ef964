//! The staged-configuration rules of `docs/protocol.md` § "Configuration: staging and atomic
//! commit", as one small state machine both the card and tests use, so "what makes a commit
//! valid" has a single implementation.
//!
//! The card feeds every `ParamWrite` addressed to it into [`Staging::write`] (answering an
//! `Err` with a `ParamResponse{reply_to: Write}`), and at a tick boundary passes a
//! `ParamCommit` to [`Staging::commit`] with a closure that cross-checks and applies the
//! entries. Whatever happens, the staging is empty afterwards, and the active configuration
//! changes only if every check — including the closure's — passed.

use super::params::{lookup, Access};
use super::{ParamCommit, ParamResponse, ParamStatus, ParamWrite, ReplyTo, SetChecksum};

/// One staged set (up to `N` accepted entries, `N` ≥ [`super::params::STAGING_CAPACITY`]
/// for a conforming card).
#[derive(Debug, Clone)]
pub struct Staging<const N: usize> {
    set_seq: Option<u8>,
    entries: heapless::Vec<(u16, i32), N>,
    /// Over every write received in the set, accepted or not, exactly as the supervisor
    /// computes it over every write it sent.
    received: SetChecksum,
    /// First rejected write of the set: (status, param id).
    poisoned: Option<(ParamStatus, u16)>,
}

impl<const N: usize> Default for Staging<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Staging<N> {
    /// Nothing staged.
    pub const fn new() -> Self {
        Staging {
            set_seq: None,
            entries: heapless::Vec::new(),
            received: SetChecksum::new(),
            poisoned: None,
        }
    }

    /// Discards the staging.
    pub fn clear(&mut self) {
        *self = Self::new();
    }

    /// The set being staged, if any.
    pub fn set_seq(&self) -> Option<u8> {
        self.set_seq
    }

    /// Accepted entries so far, in arrival order.
    pub fn entries(&self) -> &[(u16, i32)] {
        &self.entries
    }

    /// Stages one write. `driving` is true while the card drives the motor (`Enabled`,
    /// `QuickStop`, `FaultReaction`), when `idle` parameters may not change. A write for a
    /// different `set_seq` first discards the current staging. A rejected write poisons the
    /// set; the error is the status the card answers with.
    pub fn write(&mut self, w: &ParamWrite, driving: bool) -> Result<(), ParamStatus> {
        if self.set_seq != Some(w.set_seq) {
            self.clear();
            self.set_seq = Some(w.set_seq);
        }
        self.received.push(w.param_id, w.value);
        let verdict = lookup(w.param_id).and_then(|d| {
            match d.access {
                Access::ReadOnly => return Err(ParamStatus::ReadOnly),
                Access::Idle if driving => return Err(ParamStatus::NotAllowedInState),
                Access::Idle | Access::Any => {}
            }
            d.check(w.value)?;
            self.entries
                .push((w.param_id, w.value))
                .map_err(|_| ParamStatus::StagingFull)
        });
        if let Err(status) = verdict {
            if self.poisoned.is_none() {
                self.poisoned = Some((status, w.param_id));
            }
        }
        verdict
    }

    /// Checks a commit against the staging and, if it matches, hands the entries (in arrival
    /// order; a later write to the same id must win) to `apply`, which cross-checks the set
    /// and applies it — or returns `(InconsistentSet, offending id)` and changes nothing.
    /// Returns the `ParamResponse` to send. The staging is empty afterwards in every case.
    pub fn commit<F>(&mut self, c: &ParamCommit, apply: F) -> ParamResponse
    where
        F: FnOnce(&[(u16, i32)]) -> Result<(), (ParamStatus, u16)>,
    {
        let staged = u8::try_from(self.entries.len()).unwrap_or(u8::MAX);
        let verdict = match self.set_seq {
            None => Err((ParamStatus::NothingStaged, 0)),
            Some(s) if s != c.set_seq => Err((ParamStatus::SequenceMismatch, 0)),
            Some(_) => match self.poisoned {
                Some(p) => Err(p),
                None if self.received.count() != c.count => Err((ParamStatus::CountMismatch, 0)),
                None if self.received.crc() != c.crc => Err((ParamStatus::ChecksumMismatch, 0)),
                None if self.entries.is_empty() => Err((ParamStatus::NothingStaged, 0)),
                None => apply(&self.entries),
            },
        };
        self.clear();
        let (status, param_id) = match verdict {
            Ok(()) => (ParamStatus::Ok, 0),
            Err(e) => e,
        };
        ParamResponse {
            reply_to: ReplyTo::Commit,
            status,
            set_seq: c.set_seq,
            param_id,
            value: i32::from(staged),
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::proto::params::{CONTROL_PERIOD, KE, PROTOCOL_VERSION, TORQUE_LIMIT};

    fn w(param_id: u16, value: i32, set_seq: u8) -> ParamWrite {
        ParamWrite {
            param_id,
            value,
            set_seq,
        }
    }

    fn commit_for(set_seq: u8, entries: &[(u16, i32)]) -> ParamCommit {
        let s = SetChecksum::of(entries);
        ParamCommit {
            set_seq,
            count: s.count(),
            crc: s.crc(),
        }
    }

    #[test]
    fn good_set_is_applied_in_order() {
        let mut st = Staging::<8>::new();
        let set = [(KE, 65_536), (TORQUE_LIMIT, 20_000), (KE, 131_072)];
        for &(id, v) in &set {
            assert_eq!(st.write(&w(id, v, 7), false), Ok(()));
        }
        let mut applied = std::vec::Vec::new();
        let r = st.commit(&commit_for(7, &set), |e| {
            applied.extend_from_slice(e);
            Ok(())
        });
        assert_eq!((r.status, r.set_seq, r.value), (ParamStatus::Ok, 7, 3));
        assert_eq!(applied, set);
        assert_eq!(st.set_seq(), None, "staging is cleared after a commit");
    }

    #[test]
    fn every_commit_rejection() {
        let set = [(KE, 1), (TORQUE_LIMIT, 2)];
        let never =
            |_: &[(u16, i32)]| -> Result<(), (ParamStatus, u16)> { panic!("must not apply") };
        let status = |st: &mut Staging<8>, c: ParamCommit| {
            let r = st.commit(&c, never);
            (r.status, r.param_id)
        };
        let fill = |st: &mut Staging<8>, entries: &[(u16, i32)], seq: u8| {
            for &(id, v) in entries {
                let _ = st.write(&w(id, v, seq), false);
            }
        };

        let mut st = Staging::<8>::new();
        assert_eq!(
            status(&mut st, commit_for(1, &set)),
            (ParamStatus::NothingStaged, 0)
        );

        fill(&mut st, &set, 1);
        assert_eq!(
            status(&mut st, commit_for(2, &set)),
            (ParamStatus::SequenceMismatch, 0)
        );

        fill(&mut st, &set[..1], 1); // a write lost on the bus
        assert_eq!(
            status(&mut st, commit_for(1, &set)),
            (ParamStatus::CountMismatch, 0)
        );

        fill(&mut st, &[(KE, 1), (TORQUE_LIMIT, 3)], 1); // a value corrupted
        assert_eq!(
            status(&mut st, commit_for(1, &set)),
            (ParamStatus::ChecksumMismatch, 0)
        );

        fill(&mut st, &[(TORQUE_LIMIT, 2), (KE, 1)], 1); // reordered
        assert_eq!(
            status(&mut st, commit_for(1, &set)),
            (ParamStatus::ChecksumMismatch, 0)
        );

        let bad = [(KE, 1), (TORQUE_LIMIT, 40_000)];
        fill(&mut st, &bad, 1);
        assert_eq!(
            status(&mut st, commit_for(1, &bad)),
            (ParamStatus::OutOfRange, TORQUE_LIMIT)
        );

        let ro = [(PROTOCOL_VERSION, 1)];
        fill(&mut st, &ro, 1);
        assert_eq!(
            status(&mut st, commit_for(1, &ro)),
            (ParamStatus::ReadOnly, PROTOCOL_VERSION)
        );

        let unknown = [(0x0100, 1)];
        fill(&mut st, &unknown, 1);
        assert_eq!(
            status(&mut st, commit_for(1, &unknown)),
            (ParamStatus::UnknownId, 0x0100)
        );

        let idle = [(CONTROL_PERIOD, 1000)];
        assert_eq!(
            st.write(&w(CONTROL_PERIOD, 1000, 1), true),
            Err(ParamStatus::NotAllowedInState)
        );
        assert_eq!(
            status(&mut st, commit_for(1, &idle)),
            (ParamStatus::NotAllowedInState, CONTROL_PERIOD)
        );

        let many: std::vec::Vec<(u16, i32)> = (0..9).map(|i| (KE, i)).collect();
        fill(&mut st, &many, 1);
        assert_eq!(
            status(&mut st, commit_for(1, &many)),
            (ParamStatus::StagingFull, KE)
        );

        // The closure's own verdict (cross-checks) rejects the whole set.
        fill(&mut st, &set, 1);
        let r = st.commit(&commit_for(1, &set), |_| {
            Err((ParamStatus::InconsistentSet, KE))
        });
        assert_eq!(
            (r.status, r.param_id, r.value),
            (ParamStatus::InconsistentSet, KE, 2)
        );
    }

    #[test]
    fn a_new_set_seq_discards_the_old_staging() {
        let mut st = Staging::<8>::new();
        assert_eq!(st.write(&w(KE, 5, 1), false), Ok(()));
        assert_eq!(st.write(&w(TORQUE_LIMIT, 6, 2), false), Ok(()));
        assert_eq!(st.entries(), &[(TORQUE_LIMIT, 6)]);
        let r = st.commit(&commit_for(2, &[(TORQUE_LIMIT, 6)]), |_| Ok(()));
        assert_eq!(r.status, ParamStatus::Ok);
    }
}
