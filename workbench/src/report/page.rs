//! The HTML report: one self-contained file (inline SVGs, an inline zoomable view, no
//! network), which says what was found before how, explains its numbers, and records what it
//! was made from so that a report found later can be reproduced or doubted.

use std::io::Read;
use std::path::{Path, PathBuf};

use serde::Serialize;
use sha2::{Digest, Sha256};

use super::{draw, Chart, ReportError};

/// What a report was made from.
#[derive(Debug, Clone, Serialize)]
pub struct Provenance {
    /// The command line, as typed (arguments quoted where a shell would need it).
    pub command: String,
    /// The program and its version.
    pub version: String,
    /// When, UTC, RFC 3339.
    pub date: String,
    /// The files read, with their size and SHA-256.
    pub inputs: Vec<InputFile>,
}

/// One input file of a report.
#[derive(Debug, Clone, Serialize)]
pub struct InputFile {
    /// Its path, as given.
    pub path: PathBuf,
    /// Its size in bytes.
    pub bytes: u64,
    /// Its SHA-256, hex.
    pub sha256: String,
}

impl InputFile {
    /// Hash `path`.
    pub fn hash(path: &Path) -> Result<Self, ReportError> {
        let io = |source| ReportError::Io {
            path: path.to_path_buf(),
            source,
        };
        let mut f = std::fs::File::open(path).map_err(io)?;
        let mut h = Sha256::new();
        let mut buf = vec![0u8; 1 << 16];
        let mut bytes = 0u64;
        loop {
            let k = f.read(&mut buf).map_err(io)?;
            if k == 0 {
                break;
            }
            bytes += k as u64;
            h.update(buf.get(..k).unwrap_or_default());
        }
        let sha256 = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
        Ok(InputFile {
            path: path.to_path_buf(),
            bytes,
            sha256,
        })
    }
}

impl Provenance {
    /// This process's command line, `version` (e.g. `hil-host 0.3.0`), now, and the hashes of
    /// `inputs` (each once, in order).
    pub fn now(version: &str, inputs: &[PathBuf]) -> Result<Self, ReportError> {
        let mut seen: Vec<&PathBuf> = Vec::new();
        let mut files = Vec::new();
        for p in inputs {
            if !seen.contains(&p) {
                seen.push(p);
                files.push(InputFile::hash(p)?);
            }
        }
        Ok(Provenance {
            command: std::env::args_os()
                .map(|a| shell_quote(&a.to_string_lossy()))
                .collect::<Vec<_>>()
                .join(" "),
            version: version.to_string(),
            date: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
            inputs: files,
        })
    }
}

/// `a` as a POSIX shell would need it to read back as one word.
fn shell_quote(a: &str) -> String {
    let plain = !a.is_empty()
        && a.chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c));
    if plain {
        a.to_string()
    } else {
        format!("'{}'", a.replace('\'', r"'\''"))
    }
}

/// A panel of the zoomable view: series over the view's shared time axis.
#[derive(Debug, Clone, Serialize)]
pub struct Panel {
    /// Y axis label, with unit.
    pub y_label: String,
    /// The curves.
    pub series: Vec<Trace>,
}

/// One curve of a [`Panel`], a value per time sample.
#[derive(Debug, Clone, Serialize)]
pub struct Trace {
    /// Legend name.
    pub name: String,
    /// Values, one per sample of [`ZoomView::time`]: single precision is finer than a screen's
    /// pixels and halves the page.
    pub y: Vec<f32>,
    /// Drawn grey (the measurement), not in a model's colour.
    pub reference: bool,
}

/// The interactive view: panels sharing one time axis, zoomed together.
#[derive(Debug, Clone, Serialize)]
pub struct ZoomView {
    /// X axis label.
    pub x_label: String,
    /// Time of each sample.
    pub time: Vec<f64>,
    /// The panels, top to bottom.
    pub panels: Vec<Panel>,
}

/// A report page.
#[derive(Debug, Clone, Copy)]
pub struct Page<'a> {
    /// Title.
    pub title: &'a str,
    /// What was found, first, in a few sentences.
    pub finding: &'a str,
    /// What it was made from.
    pub provenance: &'a Provenance,
    /// Text sections (title, preformatted body) after the plots.
    pub sections: &'a [(String, String)],
    /// The charts.
    pub charts: &'a [Chart],
    /// The zoomable time view, above the charts.
    pub zoom: Option<&'a ZoomView>,
    /// The models compared (name, TOML text), shown whole.
    pub models: &'a [(String, String)],
}

/// What each number in a report means (shown at the end of every report).
pub const GLOSSARY: &[(&str, &str)] = &[
    ("fit %", "100·(1 − ‖y − ŷ‖/‖y − ȳ‖), MATLAB's NRMSE fit: 100 % is perfect, 0 % no better than the mean of the record, below 0 worse than it."),
    ("RMS", "root mean square of the residual e = measured − model, in the residual's unit (the input's for the equation error, the position's for the output error)."),
    ("noise floor, ×floor", "the RMS the residual would have from measurement noise alone: for the equation error, the recorded input's noise and the encoder's noise carried through the differentiator, both measured on the record; otherwise estimated from the residual's second difference (smooth model error cancels there). ×floor = RMS / floor: near 1, nothing is left that a better model could explain. The spectrum draws it spread flat up to Nyquist, as white noise of that RMS would be."),
    ("relative error", "‖e‖/‖y‖ in %, the measure of the EMPS benchmark papers."),
    ("Ljung–Box Q, p", "a test that the residual is white over its first 20 lags: a small p (below 0.01, the finding's threshold) says it is not, i.e. it has structure a model could explain."),
    ("autocorrelation, 99 % band", "corr(e(t), e(t−k)); a white residual stays inside ±2.58/√N at every lag k ≠ 0 (99 % each)."),
    ("cross-correlation, 99 % band", "corr(e(t), x(t−k)) between the residual and x: the input for the output error (as MATLAB's resid), the velocity for the equation error (whose residual is the input minus its prediction, correlated with the input by construction). The band is 2.58·√(Σ r_e(k)·r_x(k) / N), right even when the residual is not white. k > 0: x's past drives the error, dynamics the model misses; k < 0: the error leads x, feedback. The finding tests all 101 lags at once (99 %, Bonferroni), so one lag just outside the per-lag band is no finding."),
    ("ERR", "error reduction ratio: the fraction of the residual's variance that one effect's fingerprint explains by least squares (diagnose ranks the effects by it)."),
    ("Holm p", "an effect's p-value (F-test of its fingerprint against the noise), adjusted by Holm's step-down method for testing every effect of the library at once: below α (0.05) the effect is significant."),
    ("ρ", "the RMS an effect explains, in units of the noise floor: significant but small effects (ρ < 0.25) are not worth a parameter."),
];

const ZOOM_JS: &str = include_str!("zoom.js");

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Write SVGs (and PNGs if asked) of the page's charts into `dir`, and `report.html` with
/// everything inlined. Returns the HTML's path.
pub fn write(dir: &Path, page: &Page<'_>, with_png: bool) -> Result<PathBuf, ReportError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| ReportError::Io { path, source }
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let mut html = format!(
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{t}</title>\n\
         <style>{css}</style></head>\n<body>\n<h1>{t}</h1>\n\
         <p class=\"finding\"><b>Finding.</b> {f}</p>\n<nav>{nav}</nav>\n",
        t = esc(page.title),
        css = CSS,
        f = esc(page.finding),
        nav = nav(page),
    );
    if let Some(z) = page.zoom {
        // `<`, `>` and `&` as JSON escapes: no text in the data (a model's name) can close
        // the script element or open a comment inside it.
        let json = serde_json::to_string(z)
            .unwrap_or_default()
            .replace('<', "\\u003c")
            .replace('>', "\\u003e")
            .replace('&', "\\u0026");
        html.push_str(&format!(
            "<h2 id=\"zoom-view\">zoomable time view</h2>\n<p class=\"hint\">Drag across a \
             panel to zoom to that span; ctrl+wheel zooms around the cursor, shift+wheel pans; \
             double-click shows the whole record. Showing <span id=\"zoom-span\"></span>.\n\
             <button id=\"zoom-left\">◀</button> <button id=\"zoom-right\">▶</button> \
             <button id=\"zoom-reset\">whole record</button></p>\n<div id=\"zoom\"></div>\n\
             <script type=\"application/json\" id=\"zoom-data\">{json}</script>\n"
        ));
    }
    for c in page.charts {
        let s = draw::svg(c)?;
        let p = dir.join(format!("{}.svg", c.id));
        std::fs::write(&p, &s).map_err(io(&p))?;
        if with_png {
            draw::png(c, &dir.join(format!("{}.png", c.id)))?;
        }
        html.push_str(&format!(
            "<h2 id=\"{}\">{}</h2>\n<div class=\"chart\">{}</div>\n",
            esc(&c.id),
            esc(&c.title),
            s
        ));
    }
    for (h, body) in page.sections {
        html.push_str(&format!("<h2>{}</h2>\n<pre>{}</pre>\n", esc(h), esc(body)));
    }
    for (name, toml) in page.models {
        html.push_str(&format!(
            "<h2>model {}</h2>\n<pre>{}</pre>\n",
            esc(name),
            esc(toml)
        ));
    }
    html.push_str("<h2 id=\"glossary\">what the numbers mean</h2>\n<dl>\n");
    for (term, text) in GLOSSARY {
        html.push_str(&format!("<dt>{}</dt><dd>{}</dd>\n", esc(term), esc(text)));
    }
    html.push_str("</dl>\n");
    html.push_str(&provenance(page.provenance));
    html.push_str(&format!(
        "<pre id=\"layout\" hidden></pre>\n<script>\n{ZOOM_JS}</script>\n</body></html>\n"
    ));
    let p = dir.join("report.html");
    std::fs::write(&p, html).map_err(io(&p))?;
    Ok(p)
}

/// Links to the page's parts.
fn nav(page: &Page<'_>) -> String {
    let mut links = Vec::new();
    if page.zoom.is_some() {
        links.push("<a href=\"#zoom-view\">time view</a>".to_string());
    }
    for c in page.charts {
        links.push(format!("<a href=\"#{}\">{}</a>", esc(&c.id), esc(&c.id)));
    }
    links.push("<a href=\"#glossary\">glossary</a>".into());
    links.push("<a href=\"#provenance\">provenance</a>".into());
    links.join(" · ")
}

fn provenance(p: &Provenance) -> String {
    let mut s = format!(
        "<h2 id=\"provenance\">provenance</h2>\n<table>\n<tr><th>command</th><td><code>{}</code></td></tr>\n\
         <tr><th>program</th><td>{}</td></tr>\n<tr><th>date</th><td>{}</td></tr>\n",
        esc(&p.command),
        esc(&p.version),
        esc(&p.date)
    );
    for f in &p.inputs {
        s.push_str(&format!(
            "<tr><th>input</th><td><code>{}</code>, {} bytes, SHA-256 <code>{}</code></td></tr>\n",
            esc(&f.path.display().to_string()),
            f.bytes,
            f.sha256
        ));
    }
    s.push_str("</table>\n");
    s
}

const CSS: &str = "body{font-family:sans-serif;max-width:1000px;margin:auto;padding:0 8px;color:#222}\
pre{background:#f4f4f4;padding:8px;overflow-x:auto}\
.finding{background:#eef5fb;border-left:4px solid #1f77b4;padding:10px;font-size:1.05em}\
.hint{color:#555;font-size:.9em}#zoom canvas{display:block;width:100%;margin-bottom:6px;cursor:crosshair}\
table{border-collapse:collapse}th{text-align:left;padding-right:12px;vertical-align:top}\
dt{font-weight:bold;margin-top:6px}nav{font-size:.9em;margin-bottom:12px}.chart svg{max-width:100%;height:auto}";
