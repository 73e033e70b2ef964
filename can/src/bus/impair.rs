//! A node's receive side with injected losses and delays, on any [`CanBus`].
//!
//! [`Impaired`] wraps one node's bus handle and, while a [`LinkFault`] is active, drops each
//! received data frame with a probability (seeded: a lockstep run stays bit-reproducible) and
//! holds the others back by a fixed delay plus a uniform jitter. Frames leave the hold in the
//! order they came (a controller's receive FIFO does not reorder). Error frames are never
//! dropped or delayed: every node sees them when they happen.
//!
//! Time comes from a [`LinkClock`]: the lab's simulated ticks (lockstep) or the wall clock
//! (real time). Delays are rounded up to whole ticks in lockstep.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{BusError, CanBus, ClassicFrame};

/// Where an impaired link reads the time.
#[derive(Clone, Debug)]
pub enum LinkClock {
    /// Simulated ticks of 1 ms, advanced by whoever runs the lab.
    Ticks(Arc<AtomicU64>),
    /// Wall time since the given instant.
    Wall(Instant),
}

impl LinkClock {
    /// Now, µs since the start of the run.
    pub fn now_us(&self) -> u64 {
        match self {
            LinkClock::Ticks(t) => t.load(Ordering::Relaxed).saturating_mul(1000),
            LinkClock::Wall(t0) => u64::try_from(t0.elapsed().as_micros()).unwrap_or(u64::MAX),
        }
    }
}

/// One impairment of a receive side, active from `from_us` until `until_us` (µs of run
/// time; `None` = to the end).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkFault {
    /// Probability (0..=1) that a received data frame is lost.
    pub drop: f64,
    /// Fixed delay of every received data frame.
    pub delay: Duration,
    /// Extra delay, uniform in `0..jitter`.
    pub jitter: Duration,
    /// Start, µs of run time.
    pub from_us: u64,
    /// End, µs of run time.
    pub until_us: Option<u64>,
}

impl LinkFault {
    fn active(&self, now_us: u64) -> bool {
        now_us >= self.from_us && self.until_us.is_none_or(|u| now_us < u)
    }
}

/// What an impaired link did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Data frames that reached the link.
    pub received: u64,
    /// Of those, dropped.
    pub dropped: u64,
    /// Of those, held back by a delay.
    pub delayed: u64,
}

/// A bus handle whose receive side drops and delays frames. See the module docs.
#[derive(Debug)]
pub struct Impaired<B> {
    inner: B,
    clock: LinkClock,
    faults: Vec<LinkFault>,
    rng: ChaCha8Rng,
    held: VecDeque<(u64, ClassicFrame)>,
    stats: LinkStats,
}

impl<B: CanBus> Impaired<B> {
    /// Wraps `inner`; no impairment until [`Impaired::add`]. `seed` makes the drops
    /// reproducible.
    pub fn new(inner: B, clock: LinkClock, seed: u64) -> Self {
        Impaired {
            inner,
            clock,
            faults: Vec::new(),
            rng: ChaCha8Rng::seed_from_u64(seed),
            held: VecDeque::new(),
            stats: LinkStats::default(),
        }
    }

    /// Adds an impairment.
    pub fn add(&mut self, f: LinkFault) {
        self.faults.push(f);
    }

    /// What the link did so far.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// The wrapped handle.
    pub fn inner(&self) -> &B {
        &self.inner
    }

    /// Frames held back right now.
    pub fn held(&self) -> usize {
        self.held.len()
    }

    /// Drop probability and delay (µs, jitter drawn) for a frame arriving at `now_us`.
    fn impairment(&mut self, now_us: u64) -> (bool, u64) {
        let mut keep = 1.0;
        let mut delay = Duration::ZERO;
        let mut jitter = Duration::ZERO;
        for f in self.faults.iter().filter(|f| f.active(now_us)) {
            keep *= 1.0 - f.drop.clamp(0.0, 1.0);
            delay += f.delay;
            jitter += f.jitter;
        }
        let lost = keep < 1.0 && self.rng.random::<f64>() >= keep;
        let extra = if jitter > Duration::ZERO {
            jitter.mul_f64(self.rng.random::<f64>())
        } else {
            Duration::ZERO
        };
        let d = u64::try_from((delay + extra).as_micros()).unwrap_or(u64::MAX);
        (lost, d)
    }

    fn arrive(&mut self, f: ClassicFrame) -> Option<ClassicFrame> {
        let now = self.clock.now_us();
        self.stats.received += 1;
        let (lost, delay_us) = self.impairment(now);
        if lost {
            self.stats.dropped += 1;
            return None;
        }
        if delay_us == 0 && self.held.is_empty() {
            return Some(f);
        }
        if delay_us > 0 {
            self.stats.delayed += 1;
        }
        let last = self.held.back().map_or(0, |h| h.0);
        self.held
            .push_back((now.saturating_add(delay_us).max(last), f));
        None
    }
}

impl<B: CanBus> CanBus for Impaired<B> {
    fn send(&mut self, frame: &ClassicFrame) -> Result<(), BusError> {
        self.inner.send(frame)
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<ClassicFrame>, BusError> {
        let deadline = Instant::now() + timeout;
        loop {
            let now = self.clock.now_us();
            if let Some(&(due, f)) = self.held.front() {
                if due <= now {
                    self.held.pop_front();
                    return Ok(Some(f));
                }
            }
            let left = deadline.saturating_duration_since(Instant::now());
            // With frames on hold, wake up when the first is due (wall clock) or poll in
            // steps of a tick (simulated ticks advance elsewhere).
            let wait = match (self.held.front(), &self.clock) {
                (None, _) => left,
                (Some(&(due, _)), LinkClock::Wall(_)) => {
                    left.min(Duration::from_micros(due.saturating_sub(now)))
                }
                (Some(_), LinkClock::Ticks(_)) => left.min(Duration::from_millis(1)),
            };
            match self.inner.recv_timeout(wait)? {
                Some(f) => {
                    if let Some(f) = self.arrive(f) {
                        return Ok(Some(f));
                    }
                }
                None => {
                    let due = self
                        .held
                        .front()
                        .is_some_and(|h| h.0 <= self.clock.now_us());
                    if Instant::now() >= deadline && !due {
                        return Ok(None);
                    }
                }
            }
        }
    }

    fn name(&self) -> &str {
        self.inner.name()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::{BusFault, InprocHub};

    fn f(id: u16) -> ClassicFrame {
        ClassicFrame::std(id, &[]).unwrap()
    }

    #[test]
    fn drops_at_the_rate_and_reproducibly() {
        let run = |seed| {
            let hub = InprocHub::new("impair-drop");
            let mut tx = hub.attach("tx");
            let ticks = Arc::new(AtomicU64::new(0));
            let mut rx = Impaired::new(hub.attach("rx"), LinkClock::Ticks(ticks), seed);
            rx.add(LinkFault {
                drop: 0.25,
                delay: Duration::ZERO,
                jitter: Duration::ZERO,
                from_us: 0,
                until_us: None,
            });
            let mut got = vec![];
            for i in 0..4000 {
                tx.send(&f(i % 0x7FF)).unwrap();
                while let Some(g) = rx.try_recv().unwrap() {
                    got.push(g.raw_id());
                }
            }
            (got, rx.stats())
        };
        let (a, sa) = run(1);
        let (b, _) = run(1);
        let (c, _) = run(2);
        assert_eq!(a, b, "same seed, same losses");
        assert_ne!(a, c);
        assert_eq!(sa.received, 4000);
        assert_eq!(sa.dropped + a.len() as u64, 4000);
        assert!((800..1200).contains(&sa.dropped), "{sa:?}");
    }

    #[test]
    fn delays_in_ticks_keep_order_and_let_error_frames_through() {
        let hub = InprocHub::new("impair-delay");
        let mut tx = hub.attach("tx");
        let ticks = Arc::new(AtomicU64::new(0));
        let mut rx = Impaired::new(hub.attach("rx"), LinkClock::Ticks(ticks.clone()), 3);
        rx.add(LinkFault {
            drop: 0.0,
            delay: Duration::from_micros(1500),
            jitter: Duration::from_micros(900),
            from_us: 1000,
            until_us: Some(5000),
        });
        // tick 0: not active yet
        tx.send(&f(1)).unwrap();
        assert_eq!(rx.try_recv().unwrap(), Some(f(1)));
        ticks.store(1, Ordering::Relaxed);
        tx.send(&f(2)).unwrap();
        tx.send(&f(3)).unwrap();
        hub.inject_fault(BusFault::no_ack());
        // the error frame is not held back
        assert!(rx.try_recv().unwrap_err().fault().is_some());
        assert_eq!(rx.try_recv().unwrap(), None);
        assert_eq!(rx.held(), 2);
        ticks.store(2, Ordering::Relaxed);
        assert_eq!(
            rx.try_recv().unwrap(),
            None,
            "1.5 ms is not up after 1 tick"
        );
        ticks.store(4, Ordering::Relaxed);
        assert_eq!(rx.try_recv().unwrap(), Some(f(2)));
        assert_eq!(rx.try_recv().unwrap(), Some(f(3)));
        ticks.store(6, Ordering::Relaxed);
        tx.send(&f(4)).unwrap();
        assert_eq!(rx.try_recv().unwrap(), Some(f(4)), "window over");
        assert_eq!(rx.stats().delayed, 2);
    }

    #[test]
    fn wall_clock_delay_holds_a_frame_back() {
        let hub = InprocHub::new("impair-wall");
        let mut tx = hub.attach("tx");
        let mut rx = Impaired::new(hub.attach("rx"), LinkClock::Wall(Instant::now()), 5);
        rx.add(LinkFault {
            drop: 0.0,
            delay: Duration::from_millis(30),
            jitter: Duration::ZERO,
            from_us: 0,
            until_us: None,
        });
        let t0 = Instant::now();
        tx.send(&f(7)).unwrap();
        assert_eq!(rx.recv_timeout(Duration::from_millis(5)).unwrap(), None);
        assert_eq!(rx.recv_timeout(Duration::from_secs(2)).unwrap(), Some(f(7)));
        assert!(t0.elapsed() >= Duration::from_millis(30));
    }
}
