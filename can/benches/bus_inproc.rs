//! Frame round trips on the in-process bus, and the cost of exact bit-length accounting.
//!
//! `cargo bench -p jointlab-can --bench bus_inproc` (criterion; "thrpt" = round trips/s).
//! * `same_thread`: a.send → b.recv → b.send → a.recv in one thread (transport cost only).
//! * `ping_pong_thread`: a sends, an echo thread on b answers, a waits (includes two thread
//!   wake-ups per round trip: the lockstep case of card and plant on separate threads).
//! * `exact_bits`: stuffing + CRC-15 for one 8-byte frame (paid on every send).

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use jointlab_can::bus::{bits, CanBus, ClassicFrame, InprocHub};

const T: Duration = Duration::from_secs(5);

fn same_thread(c: &mut Criterion) {
    let hub = InprocHub::new("bench");
    let mut a = hub.attach("a");
    let mut b = hub.attach("b");
    let f = ClassicFrame::std(0x100, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
    let mut g = c.benchmark_group("inproc");
    g.throughput(Throughput::Elements(1));
    g.bench_function("same_thread_round_trip", |bch| {
        bch.iter(|| {
            a.send(black_box(&f)).unwrap();
            let x = b.recv_timeout(T).unwrap().unwrap();
            b.send(&x).unwrap();
            black_box(a.recv_timeout(T).unwrap().unwrap())
        })
    });
    g.bench_function("ping_pong_thread_round_trip", |bch| {
        bch.iter_custom(|iters| {
            let hub = InprocHub::new("pp");
            let mut a = hub.attach("a");
            let mut b = hub.attach("b");
            let echo = std::thread::spawn(move || {
                for _ in 0..iters {
                    let x = b.recv_timeout(T).unwrap().unwrap();
                    b.send(&x).unwrap();
                }
            });
            let t0 = Instant::now();
            for _ in 0..iters {
                a.send(&f).unwrap();
                black_box(a.recv_timeout(T).unwrap().unwrap());
            }
            let dt = t0.elapsed();
            echo.join().unwrap();
            dt
        })
    });
    g.finish();

    let mut g = c.benchmark_group("bits");
    g.throughput(Throughput::Elements(1));
    g.bench_function("exact_bits_8_byte_frame", |bch| {
        bch.iter(|| bits::exact_bits(black_box(&f)))
    });
    g.finish();
}

criterion_group!(benches, same_thread);
criterion_main!(benches);
