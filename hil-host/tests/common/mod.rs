//! What the command-line tests share: the built `hil-host`, a scratch directory per test, and
//! a failed command's output in the assertion message.
#![allow(dead_code)] // each test crate uses its own subset

use std::path::PathBuf;
use std::process::{Command, Output};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The `hil-host` binary cargo built for these tests.
pub fn hil() -> Command {
    Command::new(env!("CARGO_BIN_EXE_hil-host"))
}

/// A fresh scratch directory `jointlab-<suite>-<pid>-<n>-<name>` under the system's temp dir.
/// `n` counts the calls in this process: tests run in parallel threads, and two of them may
/// ask for the same name (the same preset, say) and must not write into one directory.
pub fn dir(suite: &str, name: &str) -> PathBuf {
    static CALLS: AtomicUsize = AtomicUsize::new(0);
    let n = CALLS.fetch_add(1, Ordering::Relaxed);
    let d = std::env::temp_dir().join(format!(
        "jointlab-{suite}-{}-{n}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A command's stdout and stderr, for an assertion message.
pub fn text(o: &Output) -> String {
    format!(
        "stdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// The stdout of a command that must succeed.
pub fn ok(o: Output) -> String {
    assert!(o.status.success(), "{}", text(&o));
    String::from_utf8(o.stdout).unwrap()
}

/// `hil-host demo ARGS… --json --out OUT`: its JSON report (a run that printed none fails
/// the test with its stderr).
pub fn demo_json(args: &[&str], out: &std::path::Path) -> serde_json::Value {
    let o = hil()
        .arg("demo")
        .args(args)
        .args(["--json", "--out"])
        .arg(out)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    serde_json::from_str(&text)
        .unwrap_or_else(|e| panic!("{e}: {text}\n{}", String::from_utf8_lossy(&o.stderr)))
}

/// The repository's root (shipped datasets and data live there).
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}
