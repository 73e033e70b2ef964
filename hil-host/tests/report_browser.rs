//! `compare`'s HTML report as a user opens it: in a real browser (headless Chromium), with
//! two models overlaid. The page must render with no console message at all (an error, a
//! warning, an uncaught exception), its zoomable view must draw, and every plot on the
//! screenshot must hold curves in the models' colours, not only axes.
//!
//! Without a Chromium the test says so and passes, unless `JOINTLAB_REQUIRE_BROWSER=1` (as in
//! `.ci/run`, which installs Debian's chromium). `JOINTLAB_CHROMIUM` names the binary.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{dir, hil, ok, repo, text};

fn chromium() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("JOINTLAB_CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    let path = std::env::var_os("PATH")?;
    [
        "chromium",
        "chromium-browser",
        "google-chrome",
        "google-chrome-stable",
    ]
    .iter()
    .flat_map(|name| std::env::split_paths(&path).map(move |d| d.join(name)))
    .find(|p| p.is_file())
}

/// Chromium, headless, on `page` with a viewport `height` px tall; `what` is the output flag
/// (`--dump-dom`, `--screenshot=FILE`). Returns (stdout, the console messages it logged).
fn browse(
    chrome: &Path,
    page: &Path,
    profile: &Path,
    height: u32,
    what: &str,
) -> (String, Vec<String>) {
    let o = Command::new(chrome)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--hide-scrollbars",
            "--force-device-scale-factor=1",
            "--enable-logging=stderr",
            "--v=0",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("--window-size=1280,{height}"))
        .arg(what)
        .arg(format!("file://{}", page.display()))
        .output()
        .expect("run chromium");
    assert!(o.status.success(), "chromium {what}: {}", text(&o));
    // Every console call (log, warn, error) and every uncaught exception is logged as CONSOLE.
    let console = String::from_utf8_lossy(&o.stderr)
        .lines()
        .filter(|l| l.contains(":CONSOLE"))
        .map(str::to_string)
        .collect();
    (String::from_utf8_lossy(&o.stdout).into_owned(), console)
}

/// The value of `name="…"` on the page's `<body>` as dumped.
fn body_attr(dom: &str, name: &str) -> Option<String> {
    let body = &dom[dom.find("<body")?..];
    let tag = &body[..body.find('>')?];
    let at = tag.find(&format!("{name}=\""))? + name.len() + 2;
    Some(tag[at..at + tag[at..].find('"')?].to_string())
}

#[derive(Debug, serde::Deserialize)]
struct Rect {
    what: String,
    x: u32,
    y: u32,
    w: u32,
    h: u32,
}

#[test]
fn the_compare_report_renders_in_a_browser_with_every_plot_drawn() {
    let d = dir("browser", "compare");
    let dataset = repo().join("datasets/xl330-pendulum.toml");
    let dataset = dataset.to_str().unwrap();
    // Two models of the shipped servo: the fitted baseline, and the baseline with gravity.
    ok(hil()
        .current_dir(&d)
        .args(["fit", dataset, "--save-model", "base.toml"])
        .output()
        .unwrap());
    ok(hil()
        .current_dir(&d)
        .args([
            "fit",
            dataset,
            "--add",
            "gravity",
            "--save-model",
            "gravity.toml",
        ])
        .output()
        .unwrap());
    // A model name that would end the page's script, open a comment or a tag if written raw.
    let base = std::fs::read_to_string(d.join("base.toml")).unwrap();
    let first = base.lines().next().unwrap();
    assert!(first.starts_with("name = "), "{first}");
    let hostile = r#"name = "base </script><!--<script> & <b>bold""#;
    std::fs::write(d.join("base.toml"), base.replacen(first, hostile, 1)).unwrap();
    let out = ok(hil()
        .current_dir(&d)
        .args([
            "compare",
            dataset,
            "--model",
            "base.toml",
            "--model",
            "gravity.toml",
        ])
        .args(["--report", "rep"])
        .output()
        .unwrap());
    let page = d.join("rep/report.html");
    assert!(out.contains("report: rep/report.html"), "{out}");
    let html = std::fs::read_to_string(&page).unwrap();

    // The finding comes first, then the plots; the legends carry each model's fit.
    let finding = html.find("Finding.").expect("a finding");
    assert!(finding < html.find("<svg").unwrap());
    assert!(html.matches("(fit ").count() >= 2, "legends with fit %");
    // Provenance: the command, and the CSV the dataset names, hashed (checked by sha256sum).
    let csv = repo().join("data/xl330-pendulum/sin_time_square_kp200.csv");
    let sum = Command::new("sha256sum").arg(&csv).output().unwrap();
    let sum = String::from_utf8(sum.stdout).unwrap();
    let sum = sum.split_whitespace().next().unwrap();
    assert_eq!(sum.len(), 64);
    assert!(
        html.contains(sum),
        "the CSV's SHA-256 {sum} is in the provenance"
    );
    assert!(html.contains("--model base.toml --model gravity.toml"));
    for term in ["fit %", "×floor", "ERR", "Holm p", "99 % band"] {
        assert!(html.contains(term), "the glossary explains {term}");
    }

    in_browser(&d, &page, 2, 8);
}

/// Open `page` in headless Chromium: no console message, `panels` zoom panels drawn, `charts`
/// SVG charts, and each of them holding curves on a screenshot of the whole page.
fn in_browser(d: &Path, page: &Path, panels: usize, charts: usize) {
    let Some(chrome) = chromium() else {
        assert!(
            std::env::var("JOINTLAB_REQUIRE_BROWSER").as_deref() != Ok("1"),
            "JOINTLAB_REQUIRE_BROWSER=1 but no chromium on PATH (or JOINTLAB_CHROMIUM)"
        );
        eprintln!("SKIPPED: no chromium on PATH; the page was checked as text only");
        return;
    };
    let profile = d.join("profile");
    let (dom, console) = browse(&chrome, page, &profile, 1500, "--dump-dom");
    assert!(console.is_empty(), "console messages: {console:#?}");
    assert_eq!(body_attr(&dom, "data-js-errors"), None);
    assert_eq!(
        body_attr(&dom, "data-rendered"),
        Some(panels.to_string()),
        "zoom panels"
    );
    let layout = &dom[dom.find("<pre id=\"layout\"").unwrap()..];
    let layout = &layout[layout.find('>').unwrap() + 1..layout.find("</pre>").unwrap()];
    let rects: Vec<Rect> = serde_json::from_str(layout).unwrap();
    let canvases = rects.iter().filter(|r| r.what == "canvas").count();
    let svgs = rects.iter().filter(|r| r.what == "svg").count();
    assert_eq!((canvases, svgs), (panels, charts), "{rects:?}");

    // Screenshot the whole page at once and look inside each plot.
    let height = rects.iter().map(|r| r.y + r.h).max().unwrap() + 50;
    let shot = d.join("shot.png");
    let (_, console) = browse(
        &chrome,
        page,
        &profile,
        height,
        &format!("--screenshot={}", shot.display()),
    );
    assert!(console.is_empty(), "console messages: {console:#?}");
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&shot).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    assert!(channels >= 3 && info.height >= height - 50, "{info:?}");
    for r in &rects {
        // A curve pixel is saturated colour; axes, grid, text and the grey measurement are not.
        let mut coloured = 0usize;
        for y in r.y..(r.y + r.h).min(info.height) {
            for x in r.x..(r.x + r.w).min(info.width) {
                let i = (y as usize * info.width as usize + x as usize) * channels;
                let (red, green, blue) = (buf[i], buf[i + 1], buf[i + 2]);
                let (hi, lo) = (red.max(green).max(blue), red.min(green).min(blue));
                if hi - lo > 60 {
                    coloured += 1;
                }
            }
        }
        assert!(
            coloured > 400,
            "{} at ({}, {}) {}×{}: {coloured} coloured pixels — an empty plot",
            r.what,
            r.x,
            r.y,
            r.w,
            r.h
        );
    }
}

#[test]
fn the_lab_report_renders_in_a_browser_with_every_plot_drawn() {
    let d = dir("browser", "lab");
    let out = ok(hil()
        .current_dir(&d)
        .args([
            "demo",
            "--scenario",
            "step",
            "--seconds",
            "1",
            "--report",
            "rep",
        ])
        .output()
        .unwrap());
    let page = d.join("rep/demo-step-whoi-cable-30/report.html");
    assert!(
        out.contains("wrote rep/demo-step-whoi-cable-30/report.html"),
        "{out}"
    );
    let html = std::fs::read_to_string(&page).unwrap();
    // The verdict is the finding; the recording it plots is listed with its hash.
    let finding = html
        .find("Finding.</b> OK: ran all ")
        .expect("the verdict first");
    assert!(finding < html.find("<svg").unwrap());
    let csv = d.join("out/demo-step-whoi-cable-30.csv");
    let sum = Command::new("sha256sum").arg(&csv).output().unwrap();
    let sum = String::from_utf8(sum.stdout).unwrap();
    assert!(html.contains(sum.split_whitespace().next().unwrap()));
    in_browser(&d, &page, 3, 3);
}
