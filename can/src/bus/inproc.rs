//! In-process CAN bus: a hub that broadcasts every frame to all attached nodes.
//!
//! Semantics (chosen to match SocketCAN's defaults, see [`CanBus`]):
//!
//! * **Broadcast, no self-echo.** Every other attached node receives each frame; the sender
//!   does not (like `CAN_RAW_RECV_OWN_MSGS` off). [`InprocBus::set_recv_own`] turns the echo
//!   on for one node.
//! * **Deterministic, total order.** A send appends the frame to every receiver's queue
//!   while holding the hub lock, so all nodes see all frames in one global order: the order
//!   in which `send` calls took the lock. A single-threaded or lockstep simulation therefore
//!   replays identically. (Priority arbitration between frames pending at the same instant
//!   is not modelled: a send is a completed transmission.)
//! * **Thread-safe.** The hub is `Clone + Send + Sync`; each [`InprocBus`] is `Send` and can
//!   move to its own thread. Receivers block on a condition variable, no polling.
//! * **Optional finite RX queues** ([`InprocHub::with_rx_capacity`]): a full queue drops the
//!   new frame for that node and the node's next receive reports a controller RX-overflow
//!   [`BusFault`], as a real controller would.
//! * **Fault injection**: [`InprocHub::inject_fault`] delivers an error frame to every node.
//! * **Bus-load accounting** from the exact stuffed bit length of every frame (and the
//!   worst-case formula); see [`BusStats`].

use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, OnceLock};
use std::time::{Duration, Instant};

use super::bits;
use super::fault::{ctrl, BusError, BusFault};
use super::frame::ClassicFrame;
use super::CanBus;

/// Bus-load counters of a hub since creation or the last [`InprocHub::reset_stats`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BusStats {
    /// Frames transmitted.
    pub frames: u64,
    /// Sum of exact bit lengths (stuffing from the real frame bits, incl. 3-bit IFS).
    pub exact_bits: u64,
    /// Sum of worst-case bit lengths (`47 + 8n + floor((34+8n-1)/4)` for 11-bit IDs).
    pub worst_case_bits: u64,
    /// Wall time since the counters started.
    pub wall_elapsed: Duration,
}

impl BusStats {
    fn load(bits: u64, bitrate: u32, elapsed: Duration) -> f64 {
        let denom = f64::from(bitrate) * elapsed.as_secs_f64();
        if denom > 0.0 {
            bits as f64 / denom
        } else {
            0.0
        }
    }

    /// Bus load (0..1, can exceed 1 if the traffic would not fit) over wall time:
    /// `exact_bits / (bitrate · wall_elapsed)`.
    pub fn load_wall(&self, bitrate: u32) -> f64 {
        Self::load(self.exact_bits, bitrate, self.wall_elapsed)
    }

    /// Worst-case bus load over wall time.
    pub fn worst_case_load_wall(&self, bitrate: u32) -> f64 {
        Self::load(self.worst_case_bits, bitrate, self.wall_elapsed)
    }

    /// Bus load over a caller-provided (simulated) duration:
    /// `exact_bits / (bitrate · sim_elapsed)`.
    pub fn load_over(&self, bitrate: u32, sim_elapsed: Duration) -> f64 {
        Self::load(self.exact_bits, bitrate, sim_elapsed)
    }

    /// Worst-case bus load over a caller-provided (simulated) duration.
    pub fn worst_case_load_over(&self, bitrate: u32, sim_elapsed: Duration) -> f64 {
        Self::load(self.worst_case_bits, bitrate, sim_elapsed)
    }
}

#[derive(Debug)]
enum Item {
    Frame(ClassicFrame),
    Fault(BusFault),
}

#[derive(Debug, Default)]
struct RxState {
    items: VecDeque<Item>,
    dropped: u64,
}

#[derive(Debug)]
struct Node {
    id: u64,
    recv_own: bool,
    /// Receive queue length (`None` = unbounded).
    capacity: Option<usize>,
    rx: Mutex<RxState>,
    ready: Condvar,
}

#[derive(Debug)]
struct HubState {
    nodes: Vec<Arc<Node>>,
    next_id: u64,
    frames: u64,
    exact_bits: u64,
    worst_case_bits: u64,
    since: Instant,
}

#[derive(Debug)]
struct Hub {
    name: String,
    rx_capacity: Option<usize>,
    state: Mutex<HubState>,
}

/// A lock that survives a panicked holder: the protected data stays consistent because
/// every critical section here is a few pushes/pops that cannot panic half-way.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// An in-process bus. Cheap to clone (all clones are the same bus).
#[derive(Clone, Debug)]
pub struct InprocHub {
    hub: Arc<Hub>,
}

static REGISTRY: OnceLock<Mutex<HashMap<String, InprocHub>>> = OnceLock::new();

impl InprocHub {
    /// A new, private hub with unbounded RX queues.
    pub fn new(name: &str) -> Self {
        Self::build(name, None)
    }

    /// A new, private hub whose per-node RX queues hold at most `capacity` frames.
    pub fn with_rx_capacity(name: &str, capacity: usize) -> Self {
        Self::build(name, Some(capacity.max(1)))
    }

    fn build(name: &str, rx_capacity: Option<usize>) -> Self {
        Self {
            hub: Arc::new(Hub {
                name: name.to_string(),
                rx_capacity,
                state: Mutex::new(HubState {
                    nodes: Vec::new(),
                    next_id: 0,
                    frames: 0,
                    exact_bits: 0,
                    worst_case_bits: 0,
                    since: Instant::now(),
                }),
            }),
        }
    }

    /// The process-wide hub called `name`, created on first use (what [`super::open_bus`]
    /// (super::open_bus) uses for `"inproc"`).
    pub fn named(name: &str) -> Self {
        let reg = REGISTRY.get_or_init(|| Mutex::new(HashMap::new()));
        lock(reg)
            .entry(name.to_string())
            .or_insert_with(|| Self::new(name))
            .clone()
    }

    /// The hub's name.
    pub fn name(&self) -> &str {
        &self.hub.name
    }

    /// Attaches a new node. It receives every frame sent after this call by other nodes.
    pub fn attach(&self, node_name: &str) -> InprocBus {
        self.attach_with(node_name, self.hub.rx_capacity)
    }

    /// Attaches a node whose receive queue is unbounded whatever the hub's capacity (a
    /// logger with a deep socket buffer, as `candump` on a real bus).
    pub fn attach_unbounded(&self, node_name: &str) -> InprocBus {
        self.attach_with(node_name, None)
    }

    fn attach_with(&self, node_name: &str, capacity: Option<usize>) -> InprocBus {
        let mut st = lock(&self.hub.state);
        let node = Arc::new(Node {
            id: st.next_id,
            recv_own: false,
            capacity,
            rx: Mutex::new(RxState::default()),
            ready: Condvar::new(),
        });
        st.next_id += 1;
        st.nodes.push(node.clone());
        InprocBus {
            hub: self.hub.clone(),
            node,
            name: format!("inproc:{}/{}", self.hub.name, node_name),
        }
    }

    /// Number of attached nodes.
    pub fn node_count(&self) -> usize {
        lock(&self.hub.state).nodes.len()
    }

    /// Delivers an error frame to every attached node (fault injection).
    pub fn inject_fault(&self, fault: BusFault) {
        let st = lock(&self.hub.state);
        for n in &st.nodes {
            lock(&n.rx).items.push_back(Item::Fault(fault));
            n.ready.notify_one();
        }
    }

    /// Bus-load counters so far.
    pub fn stats(&self) -> BusStats {
        let st = lock(&self.hub.state);
        BusStats {
            frames: st.frames,
            exact_bits: st.exact_bits,
            worst_case_bits: st.worst_case_bits,
            wall_elapsed: st.since.elapsed(),
        }
    }

    /// Zeroes the counters and restarts the wall clock.
    pub fn reset_stats(&self) {
        let mut st = lock(&self.hub.state);
        st.frames = 0;
        st.exact_bits = 0;
        st.worst_case_bits = 0;
        st.since = Instant::now();
    }
}

/// One node attached to an [`InprocHub`]. Detaches on drop.
#[derive(Debug)]
pub struct InprocBus {
    hub: Arc<Hub>,
    node: Arc<Node>,
    name: String,
}

impl InprocBus {
    /// The hub this node is attached to.
    pub fn hub(&self) -> InprocHub {
        InprocHub {
            hub: self.hub.clone(),
        }
    }

    /// Also receive this node's own frames (SocketCAN `CAN_RAW_RECV_OWN_MSGS`).
    pub fn set_recv_own(&mut self, on: bool) {
        let mut st = lock(&self.hub.state);
        let node = Arc::new(Node {
            id: self.node.id,
            recv_own: on,
            capacity: self.node.capacity,
            rx: Mutex::new(std::mem::take(&mut *lock(&self.node.rx))),
            ready: Condvar::new(),
        });
        if let Some(slot) = st.nodes.iter_mut().find(|n| n.id == self.node.id) {
            *slot = node.clone();
        }
        self.node = node;
    }

    /// Frames waiting in this node's receive queue.
    pub fn pending(&self) -> usize {
        lock(&self.node.rx).items.len()
    }
}

impl Drop for InprocBus {
    fn drop(&mut self) {
        let mut st = lock(&self.hub.state);
        st.nodes.retain(|n| n.id != self.node.id);
    }
}

impl CanBus for InprocBus {
    fn send(&mut self, frame: &ClassicFrame) -> Result<(), BusError> {
        let exact = u64::from(bits::exact_bits(frame));
        let worst = u64::from(bits::worst_case_bits_of(frame));
        let mut st = lock(&self.hub.state);
        st.frames += 1;
        st.exact_bits += exact;
        st.worst_case_bits += worst;
        for n in &st.nodes {
            if n.id == self.node.id && !n.recv_own {
                continue;
            }
            let mut rx = lock(&n.rx);
            match n.capacity {
                Some(cap) if rx.items.len() >= cap => rx.dropped += 1,
                _ => {
                    rx.items.push_back(Item::Frame(*frame));
                    drop(rx);
                    n.ready.notify_one();
                }
            }
        }
        Ok(())
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<ClassicFrame>, BusError> {
        let deadline = Instant::now().checked_add(timeout);
        let mut rx = lock(&self.node.rx);
        loop {
            if rx.dropped > 0 {
                let lost = rx.dropped.min(255) as u8;
                rx.dropped = 0;
                return Err(BusError::Fault {
                    bus: self.name.clone(),
                    // data[7] is the RX error counter slot; we report the frames lost there.
                    fault: BusFault::controller(ctrl::RX_OVERFLOW, 0, lost),
                });
            }
            match rx.items.pop_front() {
                Some(Item::Frame(f)) => return Ok(Some(f)),
                Some(Item::Fault(fault)) => {
                    return Err(BusError::Fault {
                        bus: self.name.clone(),
                        fault,
                    })
                }
                None => {}
            }
            let now = Instant::now();
            let wait = match deadline {
                Some(d) if d <= now => return Ok(None),
                Some(d) => d - now,
                None => Duration::from_secs(3600),
            };
            rx = self
                .node
                .ready
                .wait_timeout(rx, wait)
                .unwrap_or_else(|p| p.into_inner())
                .0;
        }
    }

    fn name(&self) -> &str {
        &self.name
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::FaultCause;

    fn f(id: u16, d: &[u8]) -> ClassicFrame {
        ClassicFrame::std(id, d).unwrap()
    }

    #[test]
    fn broadcast_without_self_echo() {
        let hub = InprocHub::new("t");
        let mut a = hub.attach("a");
        let mut b = hub.attach("b");
        let mut c = hub.attach("c");
        a.send(&f(1, &[1])).unwrap();
        b.send(&f(2, &[2])).unwrap();
        assert_eq!(a.try_recv().unwrap(), Some(f(2, &[2])));
        assert_eq!(a.try_recv().unwrap(), None);
        assert_eq!(b.try_recv().unwrap(), Some(f(1, &[1])));
        assert_eq!(c.try_recv().unwrap(), Some(f(1, &[1])));
        assert_eq!(c.try_recv().unwrap(), Some(f(2, &[2])));
        a.set_recv_own(true);
        a.send(&f(3, &[])).unwrap();
        assert_eq!(a.try_recv().unwrap(), Some(f(3, &[])));
        drop(c);
        assert_eq!(hub.node_count(), 2);
    }

    #[test]
    fn timeout_returns_none() {
        let hub = InprocHub::new("t");
        let mut a = hub.attach("a");
        let t0 = Instant::now();
        assert_eq!(a.recv_timeout(Duration::from_millis(20)).unwrap(), None);
        assert!(t0.elapsed() >= Duration::from_millis(20));
    }

    #[test]
    fn same_global_order_for_all_receivers_across_threads() {
        let hub = InprocHub::new("order");
        let mut r1 = hub.attach("r1");
        let mut r2 = hub.attach("r2");
        let senders: Vec<_> = (0..4u16)
            .map(|t| {
                let mut s = hub.attach(&format!("s{t}"));
                std::thread::spawn(move || {
                    for i in 0..200u16 {
                        s.send(&f(t, &i.to_le_bytes())).unwrap();
                    }
                })
            })
            .collect();
        for s in senders {
            s.join().unwrap();
        }
        let drain = |r: &mut InprocBus| {
            let mut v = Vec::new();
            while let Some(x) = r.try_recv().unwrap() {
                v.push(x);
            }
            v
        };
        let (a, b) = (drain(&mut r1), drain(&mut r2));
        assert_eq!(a.len(), 800);
        assert_eq!(a, b);
        // per-sender FIFO order is kept
        for t in 0..4u16 {
            let seq: Vec<u16> = a
                .iter()
                .filter(|x| x.raw_id() == u32::from(t))
                .map(|x| u16::from_le_bytes([x.data()[0], x.data()[1]]))
                .collect();
            assert_eq!(seq, (0..200).collect::<Vec<_>>());
        }
    }

    #[test]
    fn blocking_receiver_wakes_on_send() {
        let hub = InprocHub::new("wake");
        let mut rx = hub.attach("rx");
        let mut tx = hub.attach("tx");
        let h = std::thread::spawn(move || rx.recv_timeout(Duration::from_secs(10)).unwrap());
        std::thread::sleep(Duration::from_millis(20));
        tx.send(&f(0x55, &[5])).unwrap();
        assert_eq!(h.join().unwrap(), Some(f(0x55, &[5])));
    }

    #[test]
    fn overflow_and_injected_faults_are_reported() {
        let hub = InprocHub::with_rx_capacity("ovf", 2);
        let mut a = hub.attach("a");
        let mut b = hub.attach("b");
        let mut logger = hub.attach_unbounded("logger");
        for i in 0..5 {
            a.send(&f(i, &[])).unwrap();
        }
        let e = b.try_recv().unwrap_err();
        let fault = *e.fault().unwrap();
        assert!(fault
            .causes()
            .contains(&FaultCause::Overflow(crate::bus::Direction::Rx)));
        assert_eq!(b.try_recv().unwrap(), Some(f(0, &[])));
        assert_eq!(b.try_recv().unwrap(), Some(f(1, &[])));
        assert_eq!(b.try_recv().unwrap(), None);
        for i in 0..5 {
            assert_eq!(
                logger.try_recv().unwrap(),
                Some(f(i, &[])),
                "the logger keeps all"
            );
        }

        hub.inject_fault(BusFault::bus_off());
        for n in [&mut a, &mut b, &mut logger] {
            let e = n.try_recv().unwrap_err();
            assert!(e.requires_safe_state(), "{e}");
            assert!(e.to_string().contains("bus-off"), "{e}");
        }
    }

    #[test]
    fn load_accounting() {
        let hub = InprocHub::new("load");
        let mut a = hub.attach("a");
        let _b = hub.attach("b");
        let fr = f(0, &[]);
        for _ in 0..1000 {
            a.send(&fr).unwrap();
        }
        let s = hub.stats();
        assert_eq!(s.frames, 1000);
        assert_eq!(s.exact_bits, 53_000);
        assert_eq!(s.worst_case_bits, 55_000);
        // 1000 frames of 53 bits in 1 simulated second at 1 Mbit/s: 5.3 %.
        let l = s.load_over(1_000_000, Duration::from_secs(1));
        assert!((l - 0.053).abs() < 1e-12, "{l}");
        assert!((s.worst_case_load_over(1_000_000, Duration::from_secs(1)) - 0.055).abs() < 1e-12);
        assert!(s.load_wall(1_000_000) > 0.0);
        hub.reset_stats();
        assert_eq!(hub.stats().frames, 0);
    }
}
