//! Processor-in-the-loop: the card as the firmware's `qemu-pil` image on an emulated
//! Cortex-M4F (`qemu-system-arm -machine mps2-an386`), reached over SLCAN on the machine's
//! UART0 (a Unix-socket chardev). `--card qemu[:IMAGE]` on `demo` and `run`.
//!
//! Why a byte link and not semihosting files: the same [`SlcanBus`] then also drives a real
//! USB-CAN adapter, and the frames cross the serial encoding a deployed card would see.
//!
//! Lockstep: every frame the card's bus handle receives is written to the line, and
//! [`QemuCard::exchange`] waits for the image to acknowledge them all. The image sends its
//! answers to a frame *before* that frame's `z`, so after the last `z` the host holds the
//! card's whole answer, in order, and puts it on the bus where the host card would have. The
//! card's clock is its count of `Sensor` frames, as on the host: the run is bit-identical
//! to a host-card run on the same seed (the card is the same integer code).
//!
//! Real time: the image reads the host clock (semihosting `SYS_ELAPSED`), polls its
//! timeouts every millisecond on SysTick, and its frames are forwarded as they come.

use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::str::FromStr;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
use controller::proto::NodeId;

use jointlab_can::bus::slcan::REPLY_TIMEOUT;
use jointlab_can::bus::{BusError, CanBus, ClassicFrame, SlcanBus};

/// Rust target of the PIL image (mps2-an386 is a Cortex-M4F).
pub const TARGET: &str = "thumbv7em-none-eabihf";
/// Cargo profile of the firmware images (root Cargo.toml `[profile.firmware]`: fat LTO,
/// opt-level "s"; the same as `firmware::host::PROFILE`).
pub const PROFILE: &str = "firmware";
/// Environment variable naming a prebuilt image (instead of building one).
pub const IMAGE_ENV: &str = "JOINTLAB_PIL_IMAGE";
/// How long QEMU may take to start and connect to the socket.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(20);

/// Which card a lab run uses.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum CardChoice {
    /// `controller::card` in this process.
    #[default]
    Host,
    /// The firmware image under QEMU; `None`: build (or find) the workspace's `qemu-pil`.
    Qemu(Option<PathBuf>),
}

impl FromStr for CardChoice {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "host" => Ok(CardChoice::Host),
            "qemu" => Ok(CardChoice::Qemu(None)),
            other => match other.strip_prefix("qemu:") {
                Some("") => Err("`qemu:` needs an image path, e.g. qemu:target/qemu-pil".into()),
                Some(p) => Ok(CardChoice::Qemu(Some(PathBuf::from(p)))),
                None => Err(format!(
                    "unknown card `{other}`; `host`, `qemu` or `qemu:IMAGE` (the firmware's qemu-pil ELF)"
                )),
            },
        }
    }
}

impl CardChoice {
    /// Short description for the run's header line.
    pub fn label(&self) -> &'static str {
        match self {
            CardChoice::Host => "host card",
            CardChoice::Qemu(_) => "QEMU card (mps2-an386 Cortex-M4F over SLCAN)",
        }
    }
}

/// The workspace root this binary was built from (where `firmware/` lives).
fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

/// The image to run: the given path, else `$JOINTLAB_PIL_IMAGE`, else the workspace's
/// `qemu-pil` built now (a no-op when it is up to date).
pub fn resolve_image(choice: Option<&Path>) -> Result<PathBuf> {
    let p = match (choice, std::env::var_os(IMAGE_ENV)) {
        (Some(p), _) => p.to_path_buf(),
        (None, Some(p)) => PathBuf::from(p),
        (None, None) => return build_image(),
    };
    if !p.is_file() {
        bail!(
            "QEMU card image {} does not exist; build it with `cargo build -p firmware --bin qemu-pil \
             --no-default-features --features qemu --profile {PROFILE} --target {TARGET}`",
            p.display()
        );
    }
    Ok(p)
}

/// Builds the `qemu-pil` image with the same command, features and target directory as the
/// firmware's QEMU tests (`firmware::host::build_image`), so the two share one build.
pub fn build_image() -> Result<PathBuf> {
    let root = workspace_root();
    if !root.join("firmware").join("Cargo.toml").is_file() {
        bail!(
            "no QEMU card image given and no jointlab source tree at {}: pass --card qemu:IMAGE \
             or set {IMAGE_ENV}",
            root.display()
        );
    }
    let target_dir = root.join("target").join("qemu-images");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let status = Command::new(cargo)
        .current_dir(&root)
        .args(["build", "-q", "-p", "firmware", "--bin", "qemu-pil"])
        .args(["--no-default-features", "--features", "qemu"])
        .args(["--profile", PROFILE, "--target", TARGET])
        .arg("--target-dir")
        .arg(&target_dir)
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .status()
        .context("running cargo to build the qemu-pil image")?;
    if !status.success() {
        bail!("building the qemu-pil image failed ({status}); is the {TARGET} target installed (`rustup target add {TARGET}`)?");
    }
    Ok(target_dir.join(TARGET).join(PROFILE).join("qemu-pil"))
}

/// `qemu-system-arm --version`'s first line, or why it cannot run.
pub fn qemu_version() -> Result<String> {
    let out = Command::new("qemu-system-arm")
        .arg("--version")
        .output()
        .map_err(|e| {
            anyhow!(
                "qemu-system-arm not found ({e}); install it with \
                 `apt-get install -y --no-install-recommends qemu-system-arm`"
            )
        })?;
    Ok(String::from_utf8_lossy(&out.stdout)
        .lines()
        .next()
        .unwrap_or("")
        .to_string())
}

/// The QEMU process, its scratch directory (socket, console log) and image. Dropping it
/// stops QEMU and removes the directory.
struct Proc {
    child: Child,
    dir: PathBuf,
    log: PathBuf,
    image: PathBuf,
}

impl Proc {
    fn accept(&mut self, listener: &UnixListener) -> Result<UnixStream> {
        let t0 = Instant::now();
        loop {
            match listener.accept() {
                Ok((s, _)) => {
                    s.set_nonblocking(false)?;
                    return Ok(s);
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
                Err(e) => return Err(e.into()),
            }
            if let Some(st) = self.child.try_wait()? {
                return Err(self.failed(anyhow!(
                    "qemu-system-arm exited with {st} before connecting"
                )));
            }
            if t0.elapsed() > CONNECT_TIMEOUT {
                return Err(self.failed(anyhow!(
                    "qemu-system-arm did not connect to its UART socket within {CONNECT_TIMEOUT:?}"
                )));
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// `e` with QEMU's console output (the image's semihosting lines, QEMU's own errors).
    fn failed(&mut self, e: anyhow::Error) -> anyhow::Error {
        let text = std::fs::read_to_string(&self.log).unwrap_or_default();
        let status = match self.child.try_wait() {
            Ok(Some(s)) => format!("exited with {s}"),
            _ => "still running".into(),
        };
        let mut tail: Vec<&str> = text.lines().rev().take(10).collect();
        tail.reverse();
        e.context(format!(
            "QEMU card {} ({status}); its console:\n  {}",
            self.image.display(),
            if tail.is_empty() {
                "(nothing)".to_string()
            } else {
                tail.join("\n  ")
            }
        ))
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// A running QEMU card and its SLCAN line. Dropping it closes the channel and stops QEMU.
pub struct QemuCard {
    // Field order is drop order: the line says `C` before QEMU is stopped.
    link: SlcanBus,
    proc: Proc,
    frames: u64,
}

impl std::fmt::Debug for QemuCard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("QemuCard")
            .field("pid", &self.proc.child.id())
            .field("image", &self.proc.image)
            .field("frames", &self.frames)
            .finish()
    }
}

static INSTANCE: AtomicU64 = AtomicU64::new(0);

impl QemuCard {
    /// Starts `image` as card `node` (lockstep, or `realtime`) and opens its SLCAN channel.
    pub fn spawn(image: &Path, node: NodeId, realtime: bool) -> Result<QemuCard> {
        qemu_version()?;
        let dir = std::env::temp_dir().join(format!(
            "jointlab-pil-{}-{}",
            std::process::id(),
            INSTANCE.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        let sock = dir.join("uart0.sock");
        let log = dir.join("qemu.log");
        let listener =
            UnixListener::bind(&sock).with_context(|| format!("binding {}", sock.display()))?;
        listener.set_nonblocking(true)?;
        let mut semi = format!(
            "enable=on,target=native,arg=qemu-pil,arg=node={}",
            node.get()
        );
        if realtime {
            semi.push_str(",arg=realtime");
        }
        let logf = std::fs::File::create(&log)?;
        let child = Command::new("qemu-system-arm")
            .args(["-machine", "mps2-an386", "-cpu", "cortex-m4"])
            .args(["-nographic", "-monitor", "none"])
            .arg("-chardev")
            .arg(format!("socket,id=uart0,path={}", sock.display()))
            .args(["-serial", "chardev:uart0", "-semihosting-config", &semi])
            .arg("-kernel")
            .arg(image)
            .stdin(Stdio::null())
            .stdout(logf.try_clone()?)
            .stderr(logf)
            .spawn()
            .context("starting qemu-system-arm")?;
        let mut proc = Proc {
            child,
            dir,
            log,
            image: image.to_path_buf(),
        };
        let stream = proc.accept(&listener)?;
        let name = format!("slcan:qemu:{}", proc.child.id());
        let link = SlcanBus::from_unix(stream, &name).map_err(|e| proc.failed(e.into()))?;
        Ok(QemuCard {
            link,
            proc,
            frames: 0,
        })
    }

    fn failed(&mut self, e: anyhow::Error) -> anyhow::Error {
        self.proc.failed(e)
    }

    /// Lockstep: hands `frames` (what the card's bus handle received, in bus order) to the
    /// image and returns everything it sent in answer, in the order it sent it.
    pub fn exchange(&mut self, frames: &[ClassicFrame]) -> Result<Vec<ClassicFrame>> {
        let r = self.exchange_inner(frames);
        r.map_err(|e| self.failed(e.into()))
    }

    fn exchange_inner(&mut self, frames: &[ClassicFrame]) -> Result<Vec<ClassicFrame>, BusError> {
        self.link.set_synchronous(false);
        for f in frames {
            self.link.send(f)?;
            self.frames += 1;
        }
        self.link.wait_acks(REPLY_TIMEOUT)?;
        let mut out = Vec::new();
        while let Some(g) = self.link.recv_timeout(Duration::ZERO)? {
            out.push(g);
        }
        Ok(out)
    }

    /// Frames handed to the image so far.
    pub fn frames_sent(&self) -> u64 {
        self.frames
    }

    /// The SLCAN line (real time: forward both ways as frames come).
    pub fn link(&mut self) -> &mut SlcanBus {
        &mut self.link
    }

    /// Lines of QEMU's console so far (the image's greeting, its failure messages).
    pub fn console(&self) -> String {
        std::fs::read_to_string(&self.proc.log).unwrap_or_default()
    }
}

/// The card thread of `hil-host run --card qemu`: a bridge between the run's bus and the
/// QEMU card, until `stop`. Lockstep: each batch of received frames is exchanged (the
/// answer complete before the next frame is read). Real time: frames are forwarded both
/// ways as they come, and the image keeps its own clock.
pub fn run_qemu_card(
    bus: &mut dyn CanBus,
    card: &mut QemuCard,
    lockstep: bool,
    stop: &AtomicBool,
) -> Result<()> {
    let mut batch = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        let wait = if lockstep {
            Duration::from_millis(2)
        } else {
            Duration::from_micros(200)
        };
        match bus.recv_timeout(wait) {
            Ok(Some(f)) => batch.push(f),
            Ok(None) => {}
            // A CAN error frame is the host bus's business; the emulated card sees no bus.
            Err(BusError::Fault { .. }) => {}
            Err(e) => return Err(anyhow!("card bus failed: {e}")),
        }
        // everything else already waiting joins the batch
        while let Ok(Some(f)) = bus.recv_timeout(Duration::ZERO) {
            batch.push(f);
        }
        if lockstep {
            if !batch.is_empty() {
                for g in card.exchange(&batch)? {
                    bus.send(&g)?;
                }
                batch.clear();
            }
        } else {
            for f in batch.drain(..) {
                card.link.send(&f).map_err(|e| card.failed(e.into()))?;
                card.frames += 1;
            }
            while let Some(g) = card
                .link
                .recv_timeout(Duration::ZERO)
                .map_err(|e| card.failed(e.into()))?
            {
                bus.send(&g)?;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn card_choices() {
        assert_eq!("host".parse(), Ok(CardChoice::Host));
        assert_eq!("qemu".parse(), Ok(CardChoice::Qemu(None)));
        assert_eq!(
            "qemu:/tmp/img".parse(),
            Ok(CardChoice::Qemu(Some("/tmp/img".into())))
        );
        assert!("qemu:"
            .parse::<CardChoice>()
            .unwrap_err()
            .contains("image path"));
        assert!("fpga"
            .parse::<CardChoice>()
            .unwrap_err()
            .contains("qemu:IMAGE"));
        let e = resolve_image(Some(Path::new("/no/such/image")))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("does not exist") && e.contains("qemu-pil"),
            "{e}"
        );
    }
}
