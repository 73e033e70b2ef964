//! The thesis's stability maps on the lab (`demo --scenario stability`): the card's laws
//! against the linear two-mass plant, each boundary bisected from the recordings, held
//! against the thesis's closed forms and the Routh criterion. The lab's verdicts come from
//! the plant's motion alone (a fitted recurrence's growth rate), never from the analysis.

mod common;

use common::{demo_json, dir, hil};
use serde_json::Value;

/// The points of `curve` in `map`.
fn curve<'a>(j: &'a Value, map: &str, curve: &str) -> &'a Vec<Value> {
    let find = |v: &'a Value, key: &str, name: &str| -> &'a Value {
        v[key]
            .as_array()
            .unwrap()
            .iter()
            .find(|x| x["name"] == name)
            .unwrap_or_else(|| panic!("no {name} in {key}"))
    };
    find(find(j, "maps", map), "curves", curve)["points"]
        .as_array()
        .unwrap()
}

/// A boundary's value, `None` where that side found none in range.
fn at(e: &Value) -> Option<f64> {
    (e["kind"] == "at").then(|| e["value"].as_f64().unwrap())
}

/// (x, reference, lab) per point of `curve` in `map`, the reference being the closed form
/// where there is one, else Routh.
fn points(j: &Value, map: &str, name: &str) -> Vec<(f64, Option<f64>, Option<f64>)> {
    curve(j, map, name)
        .iter()
        .map(|p| {
            let reference = if p["thesis"].is_null() {
                &p["routh"]
            } else {
                &p["thesis"]
            };
            (p["x"].as_f64().unwrap(), at(reference), at(&p["lab"]))
        })
        .collect()
}

/// (x, sampled analysis, lab) per point of `curve` in `map`.
fn vs_sampled(j: &Value, map: &str, name: &str) -> Vec<(f64, Option<f64>, Option<f64>)> {
    curve(j, map, name)
        .iter()
        .map(|p| (p["x"].as_f64().unwrap(), at(&p["sampled"]), at(&p["lab"])))
        .collect()
}

/// Every point of the curve is stable to the top of its range, in the lab and by Routh.
fn stable_throughout(j: &Value, map: &str, name: &str) -> bool {
    curve(j, map, name)
        .iter()
        .all(|p| p["lab"]["kind"] == "beyond" && p["routh"]["kind"] == "beyond")
}

fn within(pts: &[(f64, Option<f64>, Option<f64>)], tol: f64, what: &str) {
    for (x, r, l) in pts {
        let (r, l) = (
            r.expect(what),
            l.unwrap_or_else(|| panic!("{what} at {x}: no lab boundary")),
        );
        assert!((l / r - 1.0).abs() <= tol, "{what} at {x}: lab {l} vs {r}");
    }
}

#[test]
fn the_lab_finds_the_thesis_boundaries() {
    let out = dir("stability", "maps");
    let j = demo_json(&["--scenario", "stability"], &out);
    for png in ["pd", "force", "impedance", "ceiling"] {
        assert!(out.join(format!("stability-{png}.png")).exists(), "{png}");
    }

    // Non-colocated PD: the closed form, within 5 % across the region, and colocated PD stable
    // wherever the card's own guard lets the gains through.
    let nc = points(&j, "pd", "non-colocated (x2)");
    within(&nc, 0.05, "non-colocated PD");
    assert!(
        nc.windows(2).all(|w| w[1].2 < w[0].2),
        "more Be, less Ke: {nc:?}"
    );
    assert!(stable_throughout(&j, "pd", "colocated (x1)"));

    // P force control: input-velocity damping follows the closed form within 5 %; its Ke
    // limit dips and then grows again ("no hard limit on electronic damping").
    let input = points(&j, "force", "input-velocity damping");
    within(&input, 0.05, "input damping");
    let lab: Vec<f64> = input.iter().map(|p| p.2.unwrap()).collect();
    let low = lab.iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(
        low < lab[0] / 3.0 && *lab.last().unwrap() > 2.0 * low,
        "{lab:?}"
    );
    // Force-rate damping closes the region: within 5 % on its plateau; toward the tip the
    // sampled derivative weakens the damping that destabilises and the card holds more
    // (docs/design/thesis-experiments.md), but the limit still falls by half.
    let rate = points(&j, "force", "force-rate damping");
    within(&rate[..4], 0.05, "force-rate plateau");
    within(&rate, 0.2, "force-rate");
    assert!(
        rate.last().unwrap().2.unwrap() < 0.6 * rate[0].2.unwrap(),
        "{rate:?}"
    );
    // The same law sampled as the card runs it (zero-order hold, backward differences)
    // accounts for the tip: within 5 % there too, and on every closed-form curve.
    for (map, name) in [
        ("force", "force-rate damping"),
        ("force", "input-velocity damping"),
        ("pd", "non-colocated (x2)"),
    ] {
        within(
            &vs_sampled(&j, map, name),
            0.05,
            &format!("{name} vs sampled"),
        );
    }

    // Impedance: reducing the desired inertia (Km < 0) shrinks the non-colocated form's
    // damping range, as Routh says (the thesis gives no closed form here), within 5 % up to
    // Km = 0.75; at 0.9, nine tenths of the contact force fed back, the lab sits 5.0 % above
    // (held to 10 %); the colocated form is stable throughout.
    let imp = points(&j, "impedance", "non-colocated");
    within(&imp[..imp.len() - 1], 0.05, "non-colocated impedance");
    within(&imp, 0.1, "non-colocated impedance at Km 0.9");
    assert!(imp.windows(2).all(|w| w[1].2 > w[0].2), "{imp:?}");
    assert!(stable_throughout(&j, "impedance", "colocated"));

    // The damping-ratio ceiling: the lab's dominant ζ follows the roots' at every damping,
    // stays within a tenth of the open loop's least damped pair, and at the most damping
    // is back within 10 % of the held-rotor asymptote.
    let c = &j["ceiling"];
    let open = c["open_loop"].as_f64().unwrap();
    let asymptote = c["asymptote"].as_f64().unwrap();
    let pts = c["points"].as_array().unwrap();
    for p in pts {
        let (be, roots, lab) = (
            p["be"].as_f64().unwrap(),
            p["zeta_roots"].as_f64().unwrap(),
            p["zeta_lab"].as_f64().unwrap(),
        );
        assert!(
            (lab - roots).abs() < 0.0015,
            "Be {be}: lab {lab} vs {roots}"
        );
        assert!(
            lab < 1.1 * open,
            "Be {be}: lab {lab} above the open loop's {open}"
        );
    }
    let last = pts.last().unwrap()["zeta_lab"].as_f64().unwrap();
    assert!(
        (last / asymptote - 1.0).abs() < 0.1,
        "{last} vs {asymptote}"
    );
    let low = pts
        .iter()
        .map(|p| p["zeta_lab"].as_f64().unwrap())
        .fold(f64::INFINITY, f64::min);
    assert!(low < 0.7 * open, "the dip: {low} vs {open}");
}

#[test]
fn the_maps_refuse_a_plant_they_would_ignore() {
    let out = dir("stability", "refuse");
    let o = hil()
        .args([
            "demo",
            "--scenario",
            "stability",
            "--preset",
            "cyclo-29",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--preset/--model"));
}
