//! `vcan-up [NAME...]`: creates virtual CAN interfaces (default `vcan0`) over netlink and
//! brings them up; an interface that already exists is only brought up.
//!
//! This is the guest-side helper of the `.ci/vm` stage: busybox `ip link add … type vcan`
//! does not work there, so the interface is made with `socketcan::CanInterface` (rtnetlink).
//! Needs root (CAP_NET_ADMIN) and the `vcan` kernel module loaded.

#[cfg(target_os = "linux")]
fn up(name: &str) -> Result<String, String> {
    use jointlab_can::bus::socketcan_bus::sys::CanInterface;
    let (iface, created) = match CanInterface::open(name) {
        Ok(i) => (i, false),
        Err(_) => (
            CanInterface::create_vcan(name, None)
                .map_err(|e| format!("create vcan `{name}` over netlink: {e}"))?,
            true,
        ),
    };
    iface
        .bring_up()
        .map_err(|e| format!("bring `{name}` up: {e}"))?;
    Ok(format!(
        "vcan-up: {name} {} and up",
        if created { "created" } else { "exists" }
    ))
}

#[cfg(not(target_os = "linux"))]
fn up(name: &str) -> Result<String, String> {
    Err(format!("vcan-up: `{name}`: SocketCAN exists only on Linux"))
}

fn main() {
    let mut names: Vec<String> = std::env::args().skip(1).collect();
    if names.iter().any(|a| a == "-h" || a == "--help") {
        println!("usage: vcan-up [NAME...]   (default: vcan0)");
        return;
    }
    if names.is_empty() {
        names.push("vcan0".into());
    }
    let mut failed = false;
    for n in &names {
        match up(n) {
            Ok(msg) => println!("{msg}"),
            Err(e) => {
                eprintln!("vcan-up: {e}");
                failed = true;
            }
        }
    }
    if failed {
        std::process::exit(1);
    }
}
