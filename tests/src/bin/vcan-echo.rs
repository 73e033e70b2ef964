//! `vcan-echo BUS COUNT`: a separate-process test peer. Receives COUNT frames on BUS (an
//! interface such as `vcan0`) and answers each with the same data on ID + 1 (wrapping in
//! the ID's width). Prints `vcan-echo: ready` once the socket is open, so a parent process
//! knows when it may start sending, and `vcan-echo: done N` at the end.
//! Exits 2 on a usage error, 1 on a bus error or a 10 s receive timeout.

use std::io::Write;
use std::time::Duration;

use jointlab_can::bus::{open_bus, ClassicFrame};

fn run(spec: &str, count: u64) -> Result<u64, String> {
    let mut bus = open_bus(spec).map_err(|e| e.to_string())?;
    println!("vcan-echo: ready");
    std::io::stdout().flush().map_err(|e| e.to_string())?;
    let mut n = 0;
    while n < count {
        let f = bus
            .recv_timeout(Duration::from_secs(10))
            .map_err(|e| format!("receive: {e}"))?
            .ok_or_else(|| format!("timeout after {n} of {count} frames"))?;
        let reply = if f.is_extended() {
            ClassicFrame::ext((f.raw_id() + 1) & 0x1FFF_FFFF, f.data())
        } else {
            ClassicFrame::std(((f.raw_id() + 1) & 0x7FF) as u16, f.data())
        }
        .ok_or("reply frame")?;
        bus.send(&reply).map_err(|e| format!("send: {e}"))?;
        n += 1;
    }
    Ok(n)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(spec), Some(count)) = (args.first(), args.get(1).and_then(|c| c.parse().ok())) else {
        eprintln!("usage: vcan-echo BUS COUNT   (e.g. vcan-echo vcan0 1000)");
        std::process::exit(2);
    };
    match run(spec, count) {
        Ok(n) => println!("vcan-echo: done {n}"),
        Err(e) => {
            eprintln!("vcan-echo: {e}");
            std::process::exit(1);
        }
    }
}
