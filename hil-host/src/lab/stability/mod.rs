//! `demo --scenario stability`: the thesis's stability maps (§3.3) on the lab. Each map holds
//! one gain fixed and sweeps another; at every point the card's own law, running against the
//! linear two-mass plant in `sim-plant`, is bisected to the gain where a small step's motion
//! stops dying out. Beside it: the thesis's closed form where there is one, and the Routh
//! criterion on the continuous-time quartic. The plants' modes (0.4–1.8 Hz) sit far below
//! the card's 1 kHz rate and 100 Hz velocity observer, where a continuous analysis holds to a
//! few per cent.

mod plot;
pub mod routh;
pub mod sampled;
pub mod trial;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use rayon::prelude::*;

use routh::{Law, TwoMass};
use trial::Joint;

pub use plot::plot;

/// A two-mass joint, output-referred: the harmonic drive's soft-zone stiffness KT =
/// 2 500 N·m/rad of the thesis's Ch. 3 analysis between a reflected rotor and an output of
/// equal inertia (where non-colocated control is least stable, §2.2), each 108 kg·m² so that
/// the modes are slow against the card's sampling, and about 5 % damping to ground each side.
pub const FREE: TwoMass = TwoMass {
    j1: 108.0,
    b1: 52.0,
    kt: 2500.0,
    j2: 108.0,
    b2: 52.0,
    kf: 0.0,
};

/// The joint in contact with a torque sensor and surface 20 times stiffer than the
/// transmission (the thesis's "Kf/KT ≥ 20"), with four times the inertias and twice the
/// damping (the same damping ratios): the output's mode against the sensor is then 1.8 Hz,
/// where the card's 1 ms sampling moves the force boundaries by a few per cent (at 3.5 Hz it
/// moved the tip of the force-rate region by a quarter; docs/design/thesis-experiments.md).
pub const CONTACT: TwoMass = TwoMass {
    j1: 4.0 * FREE.j1,
    b1: 2.0 * FREE.b1,
    j2: 4.0 * FREE.j2,
    b2: 2.0 * FREE.b2,
    kf: 5.0e4,
    ..FREE
};

/// The joint against a surface as stiff as its transmission (Kf = KT, one of the thesis's
/// ratios): the output still moves, so Km's share of the law shows.
pub const SOFT_CONTACT: TwoMass = TwoMass { kf: 2500.0, ..FREE };

/// Gear ratio and motor torque limit of the joint.
pub const JOINT: Joint = Joint {
    ratio: 60.0,
    max_torque: 3.0,
};

/// Relative width to which each boundary is bisected (log space).
const REL: f64 = 0.005;

/// Where a swept gain stops being stable.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
#[serde(tag = "kind", content = "value", rename_all = "snake_case")]
pub enum Edge {
    /// Unstable over the whole range.
    None,
    /// The boundary.
    At(f64),
    /// Stable up to the range's top (the value).
    Beyond(f64),
}

impl Edge {
    fn from(b: Option<f64>, hi: f64) -> Edge {
        match b {
            None => Edge::None,
            Some(x) if x >= hi => Edge::Beyond(hi),
            Some(x) => Edge::At(x),
        }
    }
    /// The boundary's value, if there is one in range.
    pub fn at(&self) -> Option<f64> {
        match *self {
            Edge::At(x) => Some(x),
            _ => None,
        }
    }
    fn show(&self, scale: f64) -> String {
        match *self {
            Edge::None => "unstable".into(),
            Edge::At(x) => format!("{:.4}", x * scale),
            Edge::Beyond(x) => format!("> {:.4}", x * scale),
        }
    }
}

/// One point of a curve: the fixed coordinate and the boundary three ways.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Point {
    /// The swept-over coordinate (the map's x).
    pub x: f64,
    /// The thesis's closed form, where there is one.
    pub thesis: Option<Edge>,
    /// The Routh criterion on the quartic.
    pub routh: Edge,
    /// The same law sampled as the card runs it (zero-order hold, backward differences at
    /// 1 ms): what the sampling alone moves.
    pub sampled: Edge,
    /// The lab.
    pub lab: Edge,
    /// Lab runs it took.
    pub runs: usize,
}

impl Point {
    /// The lab's boundary over the reference's (closed form, else Routh) − 1, where both are
    /// in range.
    pub fn error(&self) -> Option<f64> {
        let reference = self.thesis.unwrap_or(self.routh).at()?;
        Some(self.lab.at()? / reference - 1.0)
    }

    /// The lab's boundary over the sampled analysis' − 1, where both are in range.
    pub fn sampled_error(&self) -> Option<f64> {
        Some(self.lab.at()? / self.sampled.at()? - 1.0)
    }
}

/// One law's boundary across the map.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Curve {
    /// The law, as the legend names it.
    pub name: String,
    /// Its points.
    pub points: Vec<Point>,
}

/// A map: what is held, what is swept, and the curves.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Map {
    /// Short name.
    pub name: &'static str,
    /// What it shows (the thesis's finding).
    pub title: &'static str,
    /// The x axis.
    pub x_label: &'static str,
    /// The boundary's axis.
    pub y_label: &'static str,
    /// Display factor from SI to the y axis's unit.
    pub y_scale: f64,
    /// The curves.
    pub curves: Vec<Curve>,
}

/// One curve to compute: the law at (x, gain), the range the gain is searched in, the closed
/// form if any.
#[derive(Clone, Copy)]
struct Job {
    map: usize,
    curve: usize,
    x: f64,
    plant: TwoMass,
    law: fn(f64, f64) -> Law,
    lo: f64,
    hi: f64,
    closed: Option<fn(&TwoMass, f64) -> Option<f64>>,
}

struct Spec {
    name: &'static str,
    title: &'static str,
    x_label: &'static str,
    y_label: &'static str,
    y_scale: f64,
    curves: Vec<CurveSpec>,
}

struct CurveSpec {
    name: &'static str,
    plant: TwoMass,
    xs: Vec<f64>,
    law: fn(f64, f64) -> Law,
    lo: f64,
    hi: f64,
    closed: Option<fn(&TwoMass, f64) -> Option<f64>>,
}

const DEG: f64 = std::f64::consts::PI / 180.0;

fn specs() -> Vec<Spec> {
    let be_pd = vec![4.0, 12.0, 24.0, 40.0, 56.0, 72.0, 88.0];
    let km = vec![-1.0, -0.75, -0.5, -0.25, 0.0, 0.25, 0.5, 0.75, 0.9];
    vec![
        Spec {
            name: "pd",
            title: "PD position control, free output: Ke limit vs Be",
            x_label: "Be, output N·m·s/rad",
            y_label: "Ke limit, N·m/deg at the output",
            y_scale: DEG,
            curves: vec![
                CurveSpec {
                    name: "non-colocated (x2)",
                    plant: FREE,
                    xs: be_pd.clone(),
                    law: |be, ke| Law::PdNonColocated { ke, be },
                    lo: 50.0,
                    hi: 5.0e4,
                    closed: Some(routh::pd_noncolocated_ke_max),
                },
                CurveSpec {
                    name: "colocated (x1)",
                    plant: FREE,
                    xs: be_pd,
                    law: |be, ke| Law::PdColocated { ke, be },
                    lo: 50.0,
                    hi: 5.0e4,
                    closed: None,
                },
            ],
        },
        Spec {
            name: "force",
            title: "P force control in contact (Kf = 20 KT): Ke limit vs damping",
            x_label: "damping, output N·m·s/rad (force rate: Bf·Kf)",
            y_label: "force gain Ke limit (output N·m per N·m)",
            y_scale: 1.0,
            curves: vec![
                CurveSpec {
                    name: "force-rate damping",
                    plant: CONTACT,
                    // Bf·Kf in N·m·s/rad: Bf from 0.8 to 32 ms.
                    xs: vec![40.0, 120.0, 240.0, 480.0, 800.0, 1200.0, 1600.0],
                    law: |b, ke| Law::ForceRate {
                        ke,
                        be: b / CONTACT.kf,
                    },
                    lo: 0.02,
                    hi: 50.0,
                    closed: Some(|p, b| routh::force_ke_max(p, b / p.kf, false)),
                },
                CurveSpec {
                    name: "input-velocity damping",
                    plant: CONTACT,
                    xs: vec![40.0, 120.0, 240.0, 800.0, 2400.0, 8000.0, 24000.0],
                    law: |b, ke| Law::ForceInputDamping { ke, be: b },
                    lo: 0.02,
                    hi: 50.0,
                    closed: Some(|p, b| routh::force_ke_max(p, b, true)),
                },
            ],
        },
        Spec {
            name: "impedance",
            title: "Impedance control against a surface as stiff as the transmission, Ke = 5.2 N·m/deg: Be limit vs Km",
            x_label: "Km = 1 − Ia/Id",
            y_label: "Be limit, output N·m·s/rad",
            y_scale: 1.0,
            curves: vec![
                CurveSpec {
                    name: "non-colocated",
                    plant: SOFT_CONTACT,
                    xs: km.clone(),
                    law: |km, be| Law::ImpedanceNonColocated {
                        ke: IMPEDANCE_KE,
                        be,
                        km,
                    },
                    lo: 5.0,
                    hi: 12000.0,
                    closed: None,
                },
                CurveSpec {
                    name: "colocated",
                    plant: SOFT_CONTACT,
                    xs: km,
                    law: |km, be| Law::ImpedanceColocated {
                        ke: IMPEDANCE_KE,
                        be,
                        km,
                    },
                    lo: 5.0,
                    hi: 12000.0,
                    closed: None,
                },
            ],
        },
    ]
}

/// The impedance map's stiffness, output N·m/rad (5.2 N·m/deg).
const IMPEDANCE_KE: f64 = 300.0;

/// Every map, the lab's points run in parallel; `tick` is called after each lab run.
pub fn maps(seed: u64, out: &Path, tick: impl Fn() + Sync) -> Result<Vec<Map>> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let specs = specs();
    let mut jobs = Vec::new();
    for (m, s) in specs.iter().enumerate() {
        for (c, cs) in s.curves.iter().enumerate() {
            for &x in &cs.xs {
                jobs.push(Job {
                    map: m,
                    curve: c,
                    x,
                    plant: cs.plant,
                    law: cs.law,
                    lo: cs.lo,
                    hi: cs.hi,
                    closed: cs.closed,
                });
            }
        }
    }
    let points: Vec<Point> = jobs
        .par_iter()
        .enumerate()
        .map(|(i, j)| point(j, seed, &out.join(format!("trial-{i}.csv")), &tick))
        .collect::<Result<_>>()?;
    let mut maps: Vec<Map> = specs
        .iter()
        .map(|s| Map {
            name: s.name,
            title: s.title,
            x_label: s.x_label,
            y_label: s.y_label,
            y_scale: s.y_scale,
            curves: s
                .curves
                .iter()
                .map(|c| Curve {
                    name: c.name.into(),
                    points: Vec::new(),
                })
                .collect(),
        })
        .collect();
    for (j, p) in jobs.iter().zip(points) {
        maps[j.map].curves[j.curve].points.push(p);
    }
    for (i, _) in jobs.iter().enumerate() {
        let _ = std::fs::remove_file(out.join(format!("trial-{i}.csv")));
    }
    Ok(maps)
}

/// The card's own guard (§2.9: the discrete rigid-rotor PD region, on the rotor inertia the
/// supervisor declares) as a ceiling on a PD law's Ke at damping `be`: the card refuses gains
/// above it, so the lab searches below. `None` for the laws it does not check.
fn guard(p: &TwoMass, law: &Law) -> Option<f64> {
    let be = match *law {
        Law::PdColocated { be, .. } | Law::PdNonColocated { be, .. } => be,
        _ => return None,
    };
    let t = 1e-3;
    let s = controller::units::pd_stability(0.0, be, p.j1, t, 0.0).ok()?;
    Some(0.98 * s.kp_max * p.j1 / (t * t))
}

fn point(j: &Job, seed: u64, csv: &Path, tick: &(impl Fn() + Sync)) -> Result<Point> {
    let law = j.law;
    let hi = guard(&j.plant, &law(j.x, 1.0)).map_or(j.hi, |g| g.min(j.hi));
    let j = &Job { hi, ..*j };
    let routh = Edge::from(
        routh::boundary(
            |g| routh::stable(&routh::characteristic(&j.plant, &law(j.x, g))),
            j.lo,
            j.hi,
            1e-6,
        ),
        j.hi,
    );
    let sampled = Edge::from(
        routh::boundary(
            |g| sampled::stable(&j.plant, &law(j.x, g)),
            j.lo,
            j.hi,
            1e-6,
        ),
        j.hi,
    );
    let thesis = j
        .closed
        .map(|f| Edge::from(f(&j.plant, j.x).filter(|g| *g > j.lo), j.hi));
    let runs = std::cell::Cell::new(0usize);
    let failure = std::cell::RefCell::new(None);
    let lab = routh::boundary(
        |g| {
            runs.set(runs.get() + 1);
            let v = trial::run(&j.plant, &law(j.x, g), &JOINT, seed, csv);
            tick();
            match v {
                Ok(v) => v.stable,
                Err(e) => {
                    failure.borrow_mut().get_or_insert(e);
                    false
                }
            }
        },
        j.lo,
        j.hi,
        REL,
    );
    if let Some(e) = failure.into_inner() {
        return Err(e);
    }
    Ok(Point {
        x: j.x,
        thesis,
        routh,
        sampled,
        lab: Edge::from(lab, j.hi),
        runs: runs.get(),
    })
}

/// The force loop's gain for the damping-ratio ceiling (output N·m per N·m).
pub const CEILING_KE: f64 = 0.5;

/// Input damping values of the ceiling sweep, output N·m·s/rad.
const CEILING_BE: [f64; 8] = [
    40.0, 120.0, 400.0, 1200.0, 4000.0, 12000.0, 40000.0, 120000.0,
];

/// The damping-ratio ceiling (§2.4): P force control in contact with input-velocity damping
/// at Ke = [`CEILING_KE`]. The thesis: the dominant pair's ζ approaches an asymptote and
/// does not rise above the open loop's. Here it dips, then returns to the held-rotor value.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Ceiling {
    /// Per damping value.
    pub points: Vec<CeilingPoint>,
    /// ζ of the open loop's least damped pair (no control).
    pub open_loop: f64,
    /// ζ of the output's mode against the surface with the rotor held (Be → ∞).
    pub asymptote: f64,
}

/// One damping value of the ceiling sweep.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct CeilingPoint {
    /// Input damping Be, output N·m·s/rad.
    pub be: f64,
    /// ζ of the dominant pair from the quartic's roots (`None`: nothing oscillates).
    pub zeta_roots: Option<f64>,
    /// ζ of the dominant pair measured on the lab.
    pub zeta_lab: Option<f64>,
}

/// Runs the ceiling sweep on the lab (in parallel).
pub fn ceiling(seed: u64, out: &Path, tick: impl Fn() + Sync) -> Result<Ceiling> {
    let p = CONTACT;
    let law = |be: f64| Law::ForceInputDamping { ke: CEILING_KE, be };
    let points = CEILING_BE
        .par_iter()
        .enumerate()
        .map(|(i, &be)| {
            let theory = routh::dominant(&routh::roots(&routh::characteristic(&p, &law(be))));
            let csv = out.join(format!("ceiling-{i}.csv"));
            let v = trial::run(&p, &law(be), &JOINT, seed, &csv)?;
            let _ = std::fs::remove_file(&csv);
            tick();
            Ok(CeilingPoint {
                be,
                zeta_roots: theory.map(|d| d.0),
                zeta_lab: v.dominant.map(|d| d.0),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let open = routh::characteristic(&p, &Law::ForceInputDamping { ke: 0.0, be: 0.0 });
    // The open loop's least damped pair (on these plants both pairs decay at one rate,
    // B1/I1 = B2/I2, so "closest to the axis" would be a tie).
    let open_loop = routh::roots(&open)
        .iter()
        .filter(|s| s.im > 0.0)
        .map(|s| -s.re / s.norm())
        .fold(f64::NAN, f64::min);
    let asymptote = p.b2 / (2.0 * ((p.kt + p.kf) * p.j2).sqrt());
    Ok(Ceiling {
        points,
        open_loop,
        asymptote,
    })
}

/// The ceiling's plot: ζ from the roots and from the lab against log10 Be, with the open
/// loop's ζ as the line they stay under.
pub fn plot_ceiling(path: &Path, c: &Ceiling) -> Result<PathBuf> {
    use plotters::style::colors::{BLACK, BLUE, RED};
    let pts = |f: fn(&CeilingPoint) -> Option<f64>| -> Vec<(f64, f64)> {
        c.points
            .iter()
            .filter_map(|p| Some((p.be.log10(), f(p)?)))
            .collect()
    };
    let theory = pts(|p| p.zeta_roots);
    let lab = pts(|p| p.zeta_lab);
    let (x0, x1) = (
        CEILING_BE[0].log10(),
        CEILING_BE[CEILING_BE.len() - 1].log10(),
    );
    let y_max = theory
        .iter()
        .chain(&lab)
        .map(|p| p.1)
        .fold(c.open_loop, f64::max)
        * 1.3;
    let y_min = theory.iter().chain(&lab).map(|p| p.1).fold(0.0, f64::min);
    crate::lab::plot::line_chart(
        path,
        "P force control in contact: dominant ζ vs input damping (the open loop's is the ceiling)",
        ("log10 input damping Be, output N·m·s/rad", x0..x1),
        ("damping ratio ζ of the dominant pair", y_min..y_max),
        vec![
            crate::lab::plot::Line {
                name: "open loop".into(),
                colour: BLACK,
                points: vec![(x0, c.open_loop), (x1, c.open_loop)],
            },
            crate::lab::plot::Line {
                name: "roots of the quartic".into(),
                colour: BLUE,
                points: theory,
            },
            crate::lab::plot::Line {
                name: "lab (Prony on the recording)".into(),
                colour: RED,
                points: lab,
            },
        ],
    )?;
    Ok(path.to_path_buf())
}

/// The ceiling as text.
pub fn ceiling_table(c: &Ceiling) -> String {
    let mut s = format!(
        "\n  ceiling — P force control in contact, Ke = {CEILING_KE}: the dominant pair's ζ vs \
         input damping\n    open loop ζ {:.4}; the output's mode with the rotor held ζ {:.4}\n",
        c.open_loop, c.asymptote
    );
    s += &format!("      {:>10} {:>10} {:>10}\n", "Be", "ζ roots", "ζ lab");
    let f = |z: Option<f64>| z.map_or("—".into(), |z| format!("{z:.4}"));
    for p in &c.points {
        s += &format!(
            "      {:>10} {:>10} {:>10}\n",
            p.be,
            f(p.zeta_roots),
            f(p.zeta_lab)
        );
    }
    s
}

/// The maps as text: per point the closed form, Routh and the lab, and the lab's deviation.
pub fn table(maps: &[Map]) -> String {
    let mut s = String::new();
    for m in maps {
        s += &format!("\n  {} — {}\n", m.name, m.title);
        s += &format!("    y: {}\n", m.y_label);
        for c in &m.curves {
            s += &format!("    {}\n", c.name);
            s += &format!(
                "      {:>10} {:>13} {:>13} {:>13} {:>13} {:>8} {:>8}\n",
                "x", "closed form", "Routh", "sampled", "lab", "vs cont.", "vs samp."
            );
            let pct = |e: Option<f64>| e.map_or("—".into(), |e| format!("{:+.1} %", 100.0 * e));
            for p in &c.points {
                s += &format!(
                    "      {:>10} {:>13} {:>13} {:>13} {:>13} {:>8} {:>8}\n",
                    format!("{}", p.x),
                    p.thesis.map_or("—".into(), |e| e.show(m.y_scale)),
                    p.routh.show(m.y_scale),
                    p.sampled.show(m.y_scale),
                    p.lab.show(m.y_scale),
                    pct(p.error()),
                    pct(p.sampled_error()),
                );
            }
        }
    }
    s
}
