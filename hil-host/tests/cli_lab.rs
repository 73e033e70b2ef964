//! The HIL commands as a user runs them.

mod common;

use common::{demo_json, hil};

#[test]
fn demo_writes_recording_log_and_plot_and_prints_the_summary() {
    let dir = std::env::temp_dir().join(format!("jl-cli-demo-{}", std::process::id()));
    let out = hil()
        .args([
            "demo",
            "--scenario",
            "damper",
            "--preset",
            "kamo-ball-30",
            "--quiet",
            "--out",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for want in [
        "achieved damping",
        "peak torque command",
        "bus load (exact bits)",
    ] {
        assert!(text.contains(want), "summary lacks `{want}`:\n{text}");
    }
    for ext in ["csv", "log", "png"] {
        let p = dir.join(format!("demo-damper-kamo-ball-30.{ext}"));
        let len = std::fs::metadata(&p).map(|m| m.len()).unwrap_or(0);
        assert!(len > 1000, "{} is {len} bytes", p.display());
    }
    let csv = std::fs::read_to_string(dir.join("demo-damper-kamo-ball-30.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    assert!(
        header.starts_with("time_s,seq,setpoint_pos_rad"),
        "{header}"
    );
    assert_eq!(csv.lines().count(), 1 + 6200, "one row per 1 ms tick");
    // the log replays/decodes
    let rep = hil()
        .arg("replay")
        .arg(dir.join("demo-damper-kamo-ball-30.log"))
        .output()
        .unwrap();
    assert!(rep.status.success());
    assert!(String::from_utf8_lossy(&rep.stdout).contains("Sensor[1] motor_counts="));
    std::fs::remove_dir_all(&dir).ok();
}

/// `--preset list` is a question, not an error: the names on stdout, one per line, exit 0,
/// and nothing run.
#[test]
fn preset_list_prints_the_names_and_succeeds() {
    let dir = std::env::temp_dir().join(format!("jointlab-preset-list-{}", std::process::id()));
    let o = hil()
        .args(["demo", "--preset", "list", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    let names: Vec<&str> = out.lines().collect();
    assert!(names.contains(&"whoi-cable-30"), "{out}");
    assert!(names.contains(&"harmonic-drive-60"), "{out}");
    assert!(!dir.exists(), "--preset list ran the demo");
}

#[test]
fn bad_input_gets_a_clear_error() {
    let run = |args: &[&str]| {
        let o = hil().args(args).output().unwrap();
        assert!(!o.status.success(), "{args:?} should fail");
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    assert!(run(&["demo", "--scenario", "wobble"]).contains("unknown scenario `wobble`"));
    assert!(run(&["demo", "--preset", "nope"]).contains("unknown preset `nope`"));
    let e = run(&["run", "--bus", "vcan9", "--scenario", "step"]);
    assert!(
        e.contains("ip link add dev vcan0 type vcan") || e.contains("vcan9"),
        "{e}"
    );
    let e = run(&[
        "supervise",
        "--bus",
        "inproc",
        "--scenario",
        "step",
        "--stiffness",
        "1e9",
    ]);
    assert!(
        e.contains("stability guard") || e.contains("out of range"),
        "{e}"
    );
    // A file that is not there: named, and the OS's reason given once (the error's own text
    // and its source chain both carry it).
    let io = ["--input", "u_Nm", "--output", "x_rad"];
    let rec = std::env::temp_dir().join(format!("jointlab-cli-lab-{}.csv", std::process::id()));
    let rows: String = (0..400)
        .map(|k| {
            format!(
                "{},{},{}\n",
                k as f64 * 1e-3,
                (k as f64 * 0.01).sin(),
                (k as f64 * 0.01).cos()
            )
        })
        .collect();
    std::fs::write(&rec, format!("time_s,u_Nm,x_rad\n{rows}")).unwrap();
    let rec = rec.to_str().unwrap();
    // The same motion logged at 100 Hz: a validation record that cannot carry the
    // estimation record's default band (100 Hz for a noise-free position at 1 kHz).
    let slow = std::env::temp_dir().join(format!("jointlab-cli-slow-{}.csv", std::process::id()));
    let rows: String = (0..100)
        .map(|k| {
            let t = k as f64 * 1e-2;
            format!("{t},{},{}\n", (10.0 * t).sin(), (10.0 * t).cos())
        })
        .collect();
    std::fs::write(&slow, format!("time_s,u_Nm,x_rad\n{rows}")).unwrap();
    let slow = slow.to_str().unwrap();
    for args in [
        &["compare", "/nonexistent/rec.csv"][..],
        &[
            "fit",
            rec,
            "--model",
            "/nonexistent/m.toml",
            "--add",
            "offset",
        ][..],
    ] {
        let e = run(&[args, &io[..]].concat());
        assert!(e.contains("/nonexistent/"), "{e}");
        assert_eq!(e.matches("os error 2").count(), 1, "{e}");
    }
    // Options out of range, or meaningful only with --auto, are refused before any work.
    for (args, what) in [
        (
            &["diagnose", rec, "--alpha", "2"][..],
            "strictly between 0 and 1",
        ),
        (&["diagnose", rec, "--cutoff", "600"][..], "Nyquist"),
        (&["compare", rec, "--period", "0"][..], "above 0"),
        (&["diagnose", rec, "--validate", rec][..], "--auto"),
        (
            &["fit", rec, "--validate", slow][..],
            "is read in by default (100.0000 Hz",
        ),
        (
            &["fit", rec, "--validate", slow][..],
            "pass a cut-off below 50.0000 Hz",
        ),
        (
            &["fit", rec, "--validate", slow, "--cutoff", "60"][..],
            "--cutoff 60: ",
        ),
    ] {
        let e = run(&[args, &io[..]].concat());
        assert!(e.contains(what), "{args:?}: {e}");
    }
    // The band named reads both records.
    let saved = std::env::temp_dir().join(format!("jointlab-cli-slow-{}.toml", std::process::id()));
    let o = hil()
        .args([
            "fit",
            rec,
            "--validate",
            slow,
            "--cutoff",
            "20",
            "--json",
            "--save-model",
        ])
        .arg(&saved)
        .args(io)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let _ = std::fs::remove_file(saved);
    let _ = std::fs::remove_file(rec);
    let _ = std::fs::remove_file(slow);
}

/// In real time the report carries the plant's tick lateness (p50, p99, max) and says
/// whether this machine held 1 kHz; the exit code follows the verdict (a machine that
/// misses actuator frames above the threshold, or whose stall trips the card, does not
/// get a 0).
#[test]
fn run_over_threads_in_real_time_reports_lateness() {
    let out = hil()
        .args([
            "run",
            "--bus",
            "inproc",
            "--scenario",
            "step",
            "--preset",
            "harmonic-drive-60",
            "--realtime",
            "--seconds",
            "0.5",
            "--quiet",
        ])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    let all = format!("{text}{}", String::from_utf8_lossy(&out.stderr));
    assert!(text.contains("(real time)"), "{all}");
    let held = text.contains("this machine held 1 kHz: tick lateness p50");
    let not_held = text.contains("this machine did NOT hold 1 kHz: the worst stall was");
    assert!(held ^ not_held, "one lateness line: {all}");
    assert!(text.contains("p99"), "{all}");
    let ok = text.lines().nth(2).is_some_and(|l| l.starts_with("  OK: "));
    assert_eq!(out.status.code(), Some(if ok { 0 } else { 1 }), "{all}");
    assert!(text.contains("actuator frames missing"), "{all}");
}

fn figure(j: &serde_json::Value, name: &str) -> f64 {
    j["figures"]
        .as_array()
        .unwrap()
        .iter()
        .find(|f| f["name"] == name)
        .unwrap_or_else(|| panic!("no figure {name}: {j}"))["value"]
        .as_f64()
        .unwrap()
}

/// `run --stiffness K` reports K as the desired stiffness (it used to report the
/// scenario's default while running K).
#[test]
fn the_summary_desires_what_the_run_asked_for() {
    let o = hil()
        .args(["run", "--bus", "inproc", "--scenario", "stiffness"])
        .args(["--preset", "whoi-cable-30", "--stiffness", "30", "--json"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(figure(&j, "desired stiffness"), 30.0);
    let ratio = figure(&j, "achieved / desired");
    assert!((0.9..1.1).contains(&ratio), "{ratio}");
}

/// Two models whose names differ after a dot (`cyclo-bl0.2`, `cyclo-bl0.4`) write two sets
/// of files; the names used to be cut at the dot, and the second run overwrote the first.
#[test]
fn model_names_with_dots_keep_their_files_apart() {
    let dir = std::env::temp_dir().join(format!("jointlab-dots-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let m = sim_plant::preset("cyclo-29").unwrap();
    for name in ["cyclo-bl0.2", "cyclo-bl0.4"] {
        let p = dir.join(format!("{name}.toml"));
        m.save(&p).unwrap();
        let j = demo_json(
            &["--scenario", "step", "--model", p.to_str().unwrap()],
            &dir,
        );
        assert_eq!(j["verdict"], "ok", "{j}");
    }
    for name in ["cyclo-bl0.2", "cyclo-bl0.4"] {
        for ext in ["csv", "log", "png"] {
            let f = dir.join(format!("demo-step-{name}.{ext}"));
            assert!(f.exists(), "{} missing", f.display());
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A scenario that did not do what it is for says so: on sumitomo-59 the damper saturates
/// the motor, the wall never reaches its force, and the identification run never moves; on
/// the cable drive none of this happens and nothing is said.
#[test]
fn scenarios_that_miss_their_purpose_say_so() {
    let dir = std::env::temp_dir().join(format!("jointlab-warn-{}", std::process::id()));
    let warnings = |scenario: &str, preset: &str| -> Vec<String> {
        let j = demo_json(&["--scenario", scenario, "--preset", preset], &dir);
        j["warnings"]
            .as_array()
            .unwrap_or_else(|| panic!("{j}"))
            .iter()
            .map(|w| w.as_str().unwrap().to_string())
            .collect()
    };
    let has = |w: &[String], what: &str| w.iter().any(|x| x.contains(what));
    let damper = warnings("damper", "sumitomo-59");
    assert!(has(&damper, "at its torque limit"), "{damper:?}");
    assert!(has(&damper, "does not emulate the damping"), "{damper:?}");
    let wall = warnings("wall", "sumitomo-59");
    assert!(has(&wall, "never reached its setpoint"), "{wall:?}");
    let identify = warnings("identify", "sumitomo-59");
    assert!(has(&identify, "hardly moved"), "{identify:?}");
    for scenario in ["stiffness", "damper", "step", "wall", "identify"] {
        let w = warnings(scenario, "whoi-cable-30");
        assert!(w.is_empty(), "{scenario} on whoi-cable-30: {w:?}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A gain set the card refuses (forced past the supervisor's guard) is reported as such
/// first, with the figures withheld: it used to print a summary of zeros with the refusal on
/// its last line.
#[test]
fn a_refused_gain_set_opens_the_report_and_withholds_the_figures() {
    let o = hil()
        .args(["run", "--bus", "inproc", "--scenario", "stiffness"])
        .args(["--preset", "whoi-cable-30", "--stiffness", "1e6", "--force"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    let out = String::from_utf8_lossy(&o.stdout);
    let verdict = out
        .lines()
        .skip_while(|l| l.trim().is_empty())
        .nth(1)
        .unwrap_or("");
    assert!(
        verdict.starts_with("  INCOMPLETE: the gain set was never committed: Commit refused"),
        "{out}"
    );
    assert!(out.contains("figures withheld"), "{out}");
    assert!(!out.contains("achieved stiffness"), "{out}");
}
