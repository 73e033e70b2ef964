//! Real SocketCAN on `vcan0`: two sockets round-trip frames, error frames are enabled and
//! decoded, a candump log written from real traffic parses back, a second *process* talks
//! to us over vcan0, and the round-trip rate is printed (`FIGURE …` lines).
//!
//! Without vcan0 (no interface, or a kernel without AF_CAN) every test prints
//! `SKIPPED: vcan0 not available (…)` to stderr and passes — unless
//! `JOINTLAB_REQUIRE_VCAN=1`, then it fails. `.ci/vm/run-vcan-tests.sh` runs this file inside
//! a QEMU guest with a real vcan0 and sets `JOINTLAB_REQUIRE_VCAN=1`.
//!
//! All tests share vcan0, and every socket on it sees every frame, so they run one at a
//! time (a process-wide lock).
#![cfg(target_os = "linux")]

use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

use jointlab_can::bus::embedded_can::{self, ExtendedId, StandardId};
use jointlab_can::bus::socketcan_bus::sys::{self, Socket, SocketOptions};
use jointlab_can::bus::{
    fault::ctrl, open_bus, BusError, BusFault, CanBus, ClassicFrame, Direction, FaultCause,
    InprocHub, SocketCanBus,
};
use jointlab_can::candump::{read_log, CandumpWriter, LoggedFrame, Timestamp};

const IFACE: &str = "vcan0";
const T: Duration = Duration::from_secs(2);

static VCAN: Mutex<()> = Mutex::new(());

/// Bypasses libtest's output capture so the line shows up in `cargo test` output.
fn say(msg: &str) {
    let _ = writeln!(std::io::stderr(), "{msg}");
}

/// Takes the vcan0 lock and checks vcan0 can be opened. `None` = skipped (announced).
fn vcan(test: &str) -> Option<MutexGuard<'static, ()>> {
    let guard = VCAN.lock().unwrap_or_else(|p| p.into_inner());
    match SocketCanBus::open(IFACE) {
        Ok(_) => Some(guard),
        Err(e @ (BusError::NoSuchInterface { .. } | BusError::NoCanSupport { .. })) => {
            if std::env::var("JOINTLAB_REQUIRE_VCAN").as_deref() == Ok("1") {
                panic!("{test}: JOINTLAB_REQUIRE_VCAN=1 but vcan0 is not available: {e}");
            }
            say(&format!("SKIPPED: vcan0 not available ({e}) [{test}]"));
            None
        }
        Err(e) => panic!("{test}: opening vcan0 failed unexpectedly: {e}"),
    }
}

fn frames() -> Vec<ClassicFrame> {
    let mut v = vec![
        ClassicFrame::std(0x000, &[]).unwrap(),
        ClassicFrame::std(0x7FF, &[0xFF; 8]).unwrap(),
        ClassicFrame::std(0x123, &[0xDE, 0xAD, 0xBE, 0xEF]).unwrap(),
        ClassicFrame::ext(0x1ABC_DEF0, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap(),
        ClassicFrame::ext(0x0000_0001, &[]).unwrap(),
        ClassicFrame::new_rtr(StandardId::new(0x321).unwrap(), 0).unwrap(),
        ClassicFrame::new_rtr(ExtendedId::new(0x1234_5678).unwrap(), 5).unwrap(),
    ];
    for n in 0..=8u8 {
        v.push(ClassicFrame::std(0x200 + u16::from(n), &(0..n).collect::<Vec<_>>()).unwrap());
    }
    v
}

#[test]
fn vcan_two_sockets_round_trip() {
    let Some(_g) = vcan("vcan_two_sockets_round_trip") else {
        return;
    };
    let mut a = SocketCanBus::open(IFACE).unwrap();
    let mut b = SocketCanBus::open(IFACE).unwrap();
    for f in frames() {
        a.send(&f).unwrap();
        assert_eq!(b.recv_timeout(T).unwrap(), Some(f), "a -> b");
        b.send(&f).unwrap();
        assert_eq!(a.recv_timeout(T).unwrap(), Some(f), "b -> a");
    }
    assert_eq!(a.try_recv().unwrap(), None, "no self-echo on a");
    assert_eq!(b.try_recv().unwrap(), None, "no self-echo on b");

    // Receive timeout: nothing pending -> Ok(None) after about the timeout.
    let t0 = Instant::now();
    assert_eq!(a.recv_timeout(Duration::from_millis(30)).unwrap(), None);
    let waited = t0.elapsed();
    assert!(waited >= Duration::from_millis(25), "{waited:?}");
    // Zero timeout polls.
    let t0 = Instant::now();
    assert_eq!(a.recv_timeout(Duration::ZERO).unwrap(), None);
    assert!(t0.elapsed() < Duration::from_millis(500));

    // Own frames on request (CAN_RAW_RECV_OWN_MSGS).
    a.set_recv_own(true).unwrap();
    let f = ClassicFrame::std(0x42, &[4, 2]).unwrap();
    a.send(&f).unwrap();
    assert_eq!(a.recv_timeout(T).unwrap(), Some(f));
    assert_eq!(b.recv_timeout(T).unwrap(), Some(f));

    // Kernel filters: b only takes 0x300..0x30F.
    b.set_filters(&[(0x300, 0x7F0)]).unwrap();
    a.send(&ClassicFrame::std(0x400, &[]).unwrap()).unwrap();
    a.send(&ClassicFrame::std(0x305, &[5]).unwrap()).unwrap();
    assert_eq!(
        b.recv_timeout(T).unwrap(),
        Some(ClassicFrame::std(0x305, &[5]).unwrap())
    );
    say("vcan_two_sockets_round_trip: vcan0 available, round trips OK");
}

#[test]
fn vcan_error_frames_enabled_and_decoded() {
    let Some(_g) = vcan("vcan_error_frames_enabled_and_decoded") else {
        return;
    };
    let a = SocketCanBus::open(IFACE).unwrap();
    let mut b = SocketCanBus::open(IFACE).unwrap();
    assert_eq!(b.error_mask().unwrap(), 0x1FFF_FFFF, "all error classes on");

    // A plain socket (default: no error classes) must not see error frames.
    let plain = sys::CanSocket::open(IFACE).unwrap();
    assert_eq!(plain.error_filter().unwrap(), 0);
    plain.set_read_timeout(T).unwrap();

    a.inject_fault(&BusFault::bus_off()).unwrap();
    let e = b.recv_timeout(T).unwrap_err();
    let fault = *e.fault().expect("a bus fault");
    assert!(fault.is_bus_off(), "{fault:?}");
    assert!(e.requires_safe_state());
    assert!(e.to_string().contains("bus-off"), "{e}");

    let passive = BusFault::controller(ctrl::TX_PASSIVE, 130, 5);
    a.inject_fault(&passive).unwrap();
    let e = b.recv_timeout(T).unwrap_err();
    let causes = e.fault().unwrap().causes();
    assert!(
        causes.contains(&FaultCause::ErrorPassive(Direction::Tx)),
        "{causes:?}"
    );
    assert!(
        causes.contains(&FaultCause::Counters { tx: 130, rx: 5 }),
        "{causes:?}"
    );
    assert!(e.requires_safe_state());

    a.inject_fault(&BusFault::no_ack()).unwrap();
    let e = b.recv_timeout(T).unwrap_err();
    assert_eq!(
        embedded_can::Error::kind(&e),
        embedded_can::ErrorKind::Acknowledge
    );
    assert!(!e.requires_safe_state());

    // The plain socket's first frame is this data frame, not one of the error frames.
    let mut a = a;
    let marker = ClassicFrame::std(0x77, &[7]).unwrap();
    a.send(&marker).unwrap();
    let got = plain.read_frame().unwrap();
    let got: ClassicFrame = jointlab_can::bus::convert(&got).unwrap();
    assert_eq!(got, marker);
    assert_eq!(b.recv_timeout(T).unwrap(), Some(marker));
    say("vcan_error_frames_enabled_and_decoded: error frames delivered and decoded");
}

#[test]
fn vcan_candump_log_from_real_traffic() {
    let Some(_g) = vcan("vcan_candump_log_from_real_traffic") else {
        return;
    };
    let mut a = SocketCanBus::open(IFACE).unwrap();
    let mut b = SocketCanBus::open(IFACE).unwrap();
    let path = std::env::temp_dir().join(format!("jointlab-vcan-{}.log", std::process::id()));
    let mut w = CandumpWriter::new(std::io::BufWriter::new(
        std::fs::File::create(&path).unwrap(),
    ));
    let mut sent = Vec::new();
    for (i, f) in frames().into_iter().cycle().take(60).enumerate() {
        a.send(&f).unwrap();
        sent.push(LoggedFrame::Can(f));
        if i == 30 {
            a.inject_fault(&BusFault::bus_off()).unwrap();
            sent.push(LoggedFrame::Error(BusFault::bus_off()));
        }
    }
    for _ in 0..sent.len() {
        match b.recv_timeout(T) {
            Ok(Some(f)) => w.write_frame(Timestamp::now(), IFACE, &f).unwrap(),
            Ok(None) => panic!("timeout"),
            Err(e) => {
                let fault = *e.fault().unwrap_or_else(|| panic!("{e}"));
                w.write_fault(Timestamp::now(), IFACE, &fault).unwrap();
            }
        }
    }
    w.flush().unwrap();
    drop(w);
    let recs = read_log(&path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::remove_file(&path).ok();
    assert_eq!(recs.len(), sent.len());
    for (r, s) in recs.iter().zip(&sent) {
        assert_eq!(r.iface, IFACE);
        assert_eq!(&r.frame, s);
    }
    assert!(recs.windows(2).all(|w| w[0].time <= w[1].time));
    assert!(
        text.lines().any(|l| l.ends_with(" vcan0 123#DEADBEEF")),
        "{text}"
    );
    assert!(text
        .lines()
        .any(|l| l.ends_with(" vcan0 20000040#0000000000000000")));
    say(&format!(
        "vcan_candump_log_from_real_traffic: {} records, first line: {}",
        recs.len(),
        text.lines().next().unwrap_or("")
    ));
}

#[test]
fn vcan_open_bus_spec_and_missing_interface() {
    let Some(_g) = vcan("vcan_open_bus_spec_and_missing_interface") else {
        return;
    };
    let mut a = open_bus(IFACE).unwrap();
    let mut b = open_bus(IFACE).unwrap();
    let f = ClassicFrame::std(0x10, &[1]).unwrap();
    a.send(&f).unwrap();
    assert_eq!(b.recv_timeout(T).unwrap(), Some(f));
    let e = open_bus("vcanmissing9").err().expect("must fail");
    assert!(matches!(e, BusError::NoSuchInterface { .. }), "{e:?}");
    assert!(e.to_string().contains(
        "sudo modprobe vcan && sudo ip link add dev vcan0 type vcan && sudo ip link set up vcan0"
    ));
}

/// Path of a helper binary: `$JOINTLAB_BIN_DIR/NAME` (the VM stage copies binaries to
/// /bin), else the one cargo built next to this test.
fn helper_bin(name: &str, built: &str) -> std::path::PathBuf {
    match std::env::var_os("JOINTLAB_BIN_DIR") {
        Some(dir) => std::path::Path::new(&dir).join(name),
        None => built.into(),
    }
}

#[test]
fn vcan_second_process_echoes() {
    let Some(_g) = vcan("vcan_second_process_echoes") else {
        return;
    };
    const N: u64 = 300;
    let exe = helper_bin("vcan-echo", env!("CARGO_BIN_EXE_vcan-echo"));
    let mut child = Command::new(&exe)
        .args([IFACE, &N.to_string()])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("spawn {}: {e}", exe.display()));
    let mut out = BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    out.read_line(&mut line).unwrap();
    assert_eq!(line.trim(), "vcan-echo: ready");
    let mut bus = SocketCanBus::open(IFACE).unwrap();
    let t0 = Instant::now();
    for i in 0..N {
        let f = ClassicFrame::std(0x500, &i.to_le_bytes()).unwrap();
        bus.send(&f).unwrap();
        let r = bus.recv_timeout(T).unwrap().expect("echo reply");
        assert_eq!(r, ClassicFrame::std(0x501, &i.to_le_bytes()).unwrap());
    }
    let dt = t0.elapsed();
    line.clear();
    out.read_line(&mut line).unwrap();
    assert_eq!(line.trim(), format!("vcan-echo: done {N}"));
    assert!(child.wait().unwrap().success());
    say(&format!(
        "FIGURE vcan0 two-process ping-pong: {N} round trips in {:.1} ms = {:.0} round trips/s",
        dt.as_secs_f64() * 1e3,
        N as f64 / dt.as_secs_f64()
    ));
}

/// a -> b, b -> a, all in one thread: the cost of the transport without scheduler hops.
fn same_thread_round_trips(a: &mut dyn CanBus, b: &mut dyn CanBus, n: u32) -> Duration {
    let t0 = Instant::now();
    for i in 0..n {
        let f = ClassicFrame::std(0x100, &i.to_le_bytes()).unwrap();
        a.send(&f).unwrap();
        let g = b.recv_timeout(T).unwrap().unwrap();
        b.send(&g).unwrap();
        assert_eq!(a.recv_timeout(T).unwrap(), Some(f));
    }
    t0.elapsed()
}

/// a sends, an echo thread on b answers, a waits: latency including thread wake-ups.
fn ping_pong(mut a: Box<dyn CanBus>, mut b: Box<dyn CanBus>, n: u32) -> Duration {
    let echo = std::thread::spawn(move || {
        for _ in 0..n {
            let f = b.recv_timeout(T).unwrap().unwrap();
            b.send(&f).unwrap();
        }
    });
    let t0 = Instant::now();
    for i in 0..n {
        let f = ClassicFrame::std(0x100, &i.to_le_bytes()).unwrap();
        a.send(&f).unwrap();
        assert_eq!(a.recv_timeout(T).unwrap(), Some(f));
    }
    let dt = t0.elapsed();
    echo.join().unwrap();
    dt
}

fn figure(what: &str, n: u32, dt: Duration) {
    say(&format!(
        "FIGURE {what}: {n} round trips in {:.1} ms = {:.0} round trips/s ({:.1} us each)",
        dt.as_secs_f64() * 1e3,
        f64::from(n) / dt.as_secs_f64(),
        dt.as_secs_f64() * 1e6 / f64::from(n)
    ));
}

#[test]
fn vcan_round_trip_rate() {
    let Some(_g) = vcan("vcan_round_trip_rate") else {
        return;
    };
    const N: u32 = 5_000;
    let mut a = SocketCanBus::open(IFACE).unwrap();
    let mut b = SocketCanBus::open(IFACE).unwrap();
    figure(
        "vcan0 same-thread a->b->a",
        N,
        same_thread_round_trips(&mut a, &mut b, N),
    );
    figure(
        "vcan0 ping-pong with echo thread",
        N,
        ping_pong(Box::new(a), Box::new(b), N),
    );
    // The in-process bus on the same machine, for comparison.
    let hub = InprocHub::new("rate");
    let (mut a, mut b) = (hub.attach("a"), hub.attach("b"));
    figure(
        "inproc same-thread a->b->a",
        N,
        same_thread_round_trips(&mut a, &mut b, N),
    );
    figure(
        "inproc ping-pong with echo thread",
        N,
        ping_pong(Box::new(a), Box::new(b), N),
    );
}

/// `None` (announced) when the can-utils program is not installed, unless
/// `JOINTLAB_REQUIRE_CANUTILS=1` (the VM stage copies candump/canplayer into the guest).
fn can_utils(prog: &str, test: &str) -> Option<()> {
    let found = std::env::var_os("PATH")
        .map(|p| std::env::split_paths(&p).any(|d| d.join(prog).is_file()))
        .unwrap_or(false);
    if found {
        return Some(());
    }
    if std::env::var("JOINTLAB_REQUIRE_CANUTILS").as_deref() == Ok("1") {
        panic!("{test}: JOINTLAB_REQUIRE_CANUTILS=1 but `{prog}` is not on PATH");
    }
    say(&format!(
        "SKIPPED: {prog} (can-utils) not installed [{test}]"
    ));
    None
}

fn interop_frames() -> Vec<LoggedFrame> {
    let mut v: Vec<LoggedFrame> = frames().into_iter().map(LoggedFrame::Can).collect();
    v.push(LoggedFrame::Error(BusFault::controller(
        ctrl::RX_WARNING,
        0,
        97,
    )));
    v.push(LoggedFrame::Error(BusFault::bus_off()));
    v
}

/// can-utils `candump -L` captures our traffic; every line parses with our reader into
/// exactly the frames we sent (data, remote with DLC, 29-bit, error frames).
#[test]
fn vcan_candump_tool_output_parses() {
    let Some(_g) = vcan("vcan_candump_tool_output_parses") else {
        return;
    };
    if can_utils("candump", "vcan_candump_tool_output_parses").is_none() {
        return;
    }
    // `IFACE,#MASK` sets candump's error mask (its `-e` conflicts with `-L` in can-utils
    // 2020.11: "Log file format selected: Please disable ASCII/BINARY/SWAP options!").
    let mut child = Command::new("candump")
        .args(["-L", &format!("{IFACE},#1FFFFFFF")])
        .stdout(Stdio::piped())
        .spawn()
        .expect("spawn candump");
    let (tx, rx) = std::sync::mpsc::channel::<String>();
    let out = child.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(out).lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let mut a = SocketCanBus::open(IFACE).unwrap();
    // Wait until candump is listening: send a sync frame until it shows up.
    let sync = ClassicFrame::std(0x7F0, &[0x55]).unwrap();
    let deadline = Instant::now() + Duration::from_secs(20);
    'wait: loop {
        assert!(
            Instant::now() < deadline,
            "candump never printed the sync frame"
        );
        if let Some(st) = child.try_wait().unwrap() {
            panic!("candump exited early: {st}");
        }
        a.send(&sync).unwrap();
        while let Ok(l) = rx.recv_timeout(Duration::from_millis(100)) {
            if l.ends_with(" vcan0 7F0#55") {
                break 'wait;
            }
        }
    }
    let sent = interop_frames();
    for f in &sent {
        match f {
            LoggedFrame::Can(c) => a.send(c).unwrap(),
            LoggedFrame::Error(e) => a.inject_fault(e).unwrap(),
        }
    }
    let end = ClassicFrame::std(0x7F1, &[0xAA]).unwrap();
    a.send(&end).unwrap();
    let mut lines = Vec::new();
    loop {
        let l = rx
            .recv_timeout(Duration::from_secs(10))
            .expect("candump output");
        if l.ends_with(" vcan0 7F1#AA") {
            break;
        }
        if !l.ends_with(" vcan0 7F0#55") {
            lines.push(l);
        }
    }
    child.kill().ok();
    child.wait().ok();
    let got: Vec<LoggedFrame> = lines
        .iter()
        .enumerate()
        .map(|(i, l)| {
            jointlab_can::candump::parse_line(l, i + 1)
                .unwrap()
                .unwrap()
                .frame
        })
        .collect();
    assert_eq!(got, sent, "candump lines:\n{}", lines.join("\n"));
    say(&format!(
        "vcan_candump_tool_output_parses: {} candump -L lines parsed, e.g. `{}` and `{}`",
        lines.len(),
        lines.iter().find(|l| l.contains("#R")).map_or("", |s| s),
        lines.last().map_or("", |s| s)
    ));
}

/// can-utils `canplayer` replays a log written by our writer onto vcan0; we receive the
/// same frames.
#[test]
fn vcan_canplayer_replays_our_log() {
    let Some(_g) = vcan("vcan_canplayer_replays_our_log") else {
        return;
    };
    if can_utils("canplayer", "vcan_canplayer_replays_our_log").is_none() {
        return;
    }
    let path = std::env::temp_dir().join(format!("jointlab-play-{}.log", std::process::id()));
    let sent: Vec<ClassicFrame> = frames();
    let mut w = CandumpWriter::new(std::fs::File::create(&path).unwrap());
    for (i, f) in sent.iter().enumerate() {
        let t = Timestamp::from_duration(Duration::from_millis(1_000 + i as u64));
        w.write_frame(t, IFACE, f).unwrap();
    }
    w.flush().unwrap();
    drop(w);
    let mut b = SocketCanBus::open(IFACE).unwrap();
    let status = Command::new("canplayer")
        .arg("-I")
        .arg(&path)
        .status()
        .expect("run canplayer");
    std::fs::remove_file(&path).ok();
    assert!(status.success(), "canplayer: {status}");
    let mut got = Vec::new();
    while let Some(f) = b.recv_timeout(Duration::from_secs(2)).unwrap() {
        got.push(f);
        if got.len() == sent.len() {
            break;
        }
    }
    assert_eq!(got, sent);
    say(&format!(
        "vcan_canplayer_replays_our_log: canplayer replayed {} frames",
        got.len()
    ));
}
