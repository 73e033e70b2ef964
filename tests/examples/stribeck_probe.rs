//! Probe: what friction form, driven by which velocity, can reach the floor on a Stribeck
//! trial? With the truth's friction parameters.
//!
//! `cargo run --release -p jointlab-tests --example stribeck_probe -- SEED RHO [SEED RHO …]`
//!
//! For each trial, friction series F(t) on the whole record from the truth's parameters
//! (fc, fs, vs, σ0 = fs/z_s, σ1 = 2√(σ0·J2)), low-passed as the input, windowed; fitted as
//! `u = J·a + b·v + θ·F` (bias-compensated J) on the estimation record, scored on validation
//! (RMS over the trial's floors). Velocity sources: the workbench's (40 Hz zero-phase) motor
//! velocity, and the truth's load velocity (central difference at 1 kHz; probes only).
//! Variants: the truth's exact friction (from the load's equation of motion, the reference),
//! static curves, LuGre states driven by either velocity (z_s scaled), the true stick state,
//! hold columns (u, or the balancing torque u − J·a − b·v), wider-band velocities.
//!
//! Environment: `STARTS=1` each start of the workbench's Stribeck refit on its own (est and
//! val over the floors; `refine::refit_all` keeps the lowest est); `WB_ONLY=1` only the
//! workbench's own refit (val/floor and fitted shapes);
//! `DUMP=1` the workbench refit's validation residual by |v| band and its worst 50 ms windows,
//! `RANGE=a:b` (`STRIDE=k`) the samples with the truth's band-limited friction beside the
//! model's.

use hil_host::workbench::diff;
use hil_host::workbench::fit;
use hil_host::workbench::model::Model;
use hil_host::workbench::refine;
use hil_host::workbench::residual::Prepared;
use jointlab_tests::hidden::{cutoff, generate, probe_args, start_model, Family, Trial};
use sim_plant::effects::{signal, EffectKind};

fn rms(x: &[f64]) -> f64 {
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

struct Rec {
    p: Prepared,
    /// Workbench velocity, whole record.
    v_meas: Vec<f64>,
    /// Truth load velocity, whole record.
    v_true: Vec<f64>,
    /// Raw input, whole record.
    u: Vec<f64>,
    /// Raw encoder (whole record).
    x: Vec<f64>,
    /// Workbench acceleration, whole record.
    a_meas: Vec<f64>,
    /// Truth friction (load side, from the load's equation), whole record, unfiltered.
    f_true: Vec<f64>,
}

/// The load's friction from its equation of motion: spring − viscous − J2·a2, from the
/// truth's noise-free motor and load positions (1 kHz second differences; only meaningful
/// band-limited).
fn friction_truth(
    pl: &jointlab_tests::hidden::truth::Plant,
    x1: &[f64],
    x2: &[f64],
    dt: f64,
) -> Vec<f64> {
    let v1 = central(x1, dt);
    let v2 = central(x2, dt);
    let n = x2.len();
    (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
            let a2 = if b - a == 2 {
                (x2[b] - 2.0 * x2[i] + x2[a]) / (dt * dt)
            } else {
                0.0
            };
            pl.k * (x1[i] - x2[i]) + pl.c * (v1[i] - v2[i]) - pl.b_pos * v2[i] - pl.j2 * a2
        })
        .collect()
}

fn g(pl: &jointlab_tests::hidden::truth::Plant, v: f64) -> f64 {
    (pl.fc + (pl.fs - pl.fc) * (-(v / pl.vs).powi(2)).exp()).max(1e-12)
}

/// Static friction sign(v)·g(|v|).
fn static_f(pl: &jointlab_tests::hidden::truth::Plant, v: &[f64]) -> Vec<f64> {
    v.iter().map(|&v| v.signum() * g(pl, v)).collect()
}

/// LuGre driven by v (held over each sample), `sub` exact sub-steps per sample; mean force
/// over the sample. `damp` scales σ1.
fn lugre_f(
    pl: &jointlab_tests::hidden::truth::Plant,
    v: &[f64],
    zs: f64,
    damp: f64,
    dt: f64,
) -> Vec<f64> {
    let s0 = pl.fs.max(pl.fc) / zs;
    let s1 = damp * 2.0 * (s0 * pl.j2).sqrt();
    let sub = 20;
    let h = dt / sub as f64;
    let mut z = 0.0f64;
    let interp = std::env::var_os("NOINTERP").is_none();
    (0..v.len())
        .map(|k| {
            let mut acc = 0.0;
            for j in 0..sub {
                // v linearly interpolated over the sample (v[k] at its middle).
                let tau = (j as f64 + 0.5) / sub as f64 - 0.5;
                let vv = if !interp {
                    v[k]
                } else if tau < 0.0 {
                    let p = v[k.saturating_sub(1)];
                    v[k] + tau * (v[k] - p)
                } else {
                    let nx = v[(k + 1).min(v.len() - 1)];
                    v[k] + tau * (nx - v[k])
                };
                let lam = s0 * vv.abs() / g(pl, vv);
                let z0 = z;
                if lam * h < 1e-12 {
                    z += vv * h;
                } else {
                    let zss = vv / lam;
                    z = zss + (z - zss) * (-lam * h).exp();
                }
                let zm = 0.5 * (z0 + z);
                acc += s0 * zm + s1 * (z - z0) / h;
            }
            acc / sub as f64
        })
        .collect()
}

fn win(x: &[f64], p: &Prepared) -> Vec<f64> {
    x[p.raw_offset..p.raw_offset + p.len()].to_vec()
}

fn lpw(x: &[f64], p: &Prepared) -> Vec<f64> {
    win(&signal::filtfilt(x, p.cutoff_hz, 1.0 / p.dt), p)
}

/// Fit u = J a + b v + Σθ cols on est; (θ, est rms, val rms, val residual).
fn score(
    e: &Prepared,
    ce: &[Vec<f64>],
    v: &Prepared,
    cv: &[Vec<f64>],
    fixed: bool,
) -> (Vec<f64>, f64, f64, Vec<f64>) {
    let mk = |p: &Prepared, c: &[Vec<f64>]| {
        let mut cols = vec![p.acceleration.clone(), p.velocity.clone()];
        let mut y = p.input.clone();
        if fixed {
            for cc in c {
                for (yy, x) in y.iter_mut().zip(cc) {
                    *yy -= x;
                }
            }
        } else {
            cols.extend(c.iter().cloned());
        }
        (cols, y)
    };
    let (cols, y) = mk(e, ce);
    let mut noise = vec![0.0; cols.len()];
    noise[0] = e.len() as f64 * e.acceleration_noise_var;
    let Ok(f) = fit::least_squares_compensated(&cols, &y, &noise) else {
        return (vec![], f64::NAN, f64::NAN, vec![]);
    };
    let (cv2, yv) = mk(v, cv);
    let mut r = yv.clone();
    for (j, c) in cv2.iter().enumerate() {
        for (rr, x) in r.iter_mut().zip(c) {
            *rr -= f.theta[j] * x;
        }
    }
    let er = (f.rss / e.len() as f64).sqrt();
    (f.theta.clone(), er, rms(&r), r)
}

fn central(x: &[f64], dt: f64) -> Vec<f64> {
    let n = x.len();
    (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
            (x[b] - x[a]) / ((b - a) as f64 * dt)
        })
        .collect()
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    for (seed, rho) in probe_args(&args, "stribeck_probe SEED RHO [SEED RHO …]") {
        let Some(t) = generate(seed, &[Family::Stribeck], rho) else {
            println!("seed {seed}: unstable");
            continue;
        };
        if std::env::var_os("DUMP").is_some() {
            dump(&t);
        } else {
            probe(seed, &t);
        }
    }
}

fn probe(seed: u64, t: &Trial) {
    let pl = &t.plant;
    let fc = cutoff().unwrap_or(40.0);
    let dt = t.est.dt;
    let recs: Vec<Rec> = [
        (&t.est, &t.load[0], &t.motor[0]),
        (&t.val, &t.load[1], &t.motor[1]),
    ]
    .iter()
    .map(|(r, load, motor)| Rec {
        f_true: friction_truth(pl, motor, load, dt),
        p: Prepared::new(r, cutoff()),
        v_meas: diff::differentiate(&r.output, dt, fc).velocity,
        a_meas: diff::differentiate(&r.output, dt, fc).acceleration,
        x: r.output.clone(),
        v_true: central(load, dt),
        u: r.input.clone(),
    })
    .collect();
    let s0 = pl.fs / pl.z_scale;
    let s1 = 2.0 * (s0 * pl.j2).sqrt();
    println!(
        "== seed {seed}: ρ {:.2}, J {:.4} (J2 {:.4}) b {:.4} fc {:.4} fs {:.4} (ratio {:.1}) vs {:.4} σ0 {:.2e} σ1 {:.2} floors {:.3e}/{:.3e} stick_v {:.3e}",
        t.rho,
        pl.j1 + pl.j2,
        pl.j2,
        pl.b_pos,
        pl.fc,
        pl.fs,
        pl.fs / pl.fc,
        pl.vs,
        s0,
        s1,
        t.floor_est,
        t.floor_val,
        recs[0].p.stick_velocity
    );
    // Each start of the refit on its own (est, val over the floor).
    if std::env::var_os("STARTS").is_some() {
        let mut m: Model = start_model(&[Family::Stribeck]);
        let (pe, pv) = (&recs[0].p, &recs[1].p);
        if refine::refit_all(&mut m, pe).is_ok() {
            let _ = hil_host::workbench::residual::refit(&mut m, pe);
            let shape = refine::best_shape(&m, pe, EffectKind::Stribeck).unwrap_or_default();
            m.add(EffectKind::Stribeck, shape);
            let mut line = String::from("  starts:");
            for (k, (ms, r)) in refine::refit_each_start(&m, pe).iter().enumerate() {
                if r.is_ok() {
                    line += &format!(
                        " s{k} est {:.4} sval {:.4}",
                        refine::score(ms, pe).rms / t.floor_est,
                        refine::score(ms, pv).rms / t.floor_val
                    );
                }
            }
            println!("{line}");
        }
        return;
    }
    // The workbench's own refit.
    {
        let mut m: Model = start_model(&[Family::Stribeck]);
        let (pe, pv) = (&recs[0].p, &recs[1].p);
        if refine::refit_all(&mut m, pe).is_ok() {
            if let Ok(r) = refine::fit_add(&mut m, pe, Some(EffectKind::Stribeck), Some(pv)) {
                let s = &m
                    .effects
                    .last()
                    .map(|e| e.shape.clone())
                    .unwrap_or_default();
                println!(
                    "  workbench: est {:.3} val {:.3}  vs {:.4} δ {:.1} vh {:.3e} lead {:.2e} eps {:.2e}",
                    r.after.rms / t.floor_est,
                    r.after_validation.map_or(f64::NAN, |v| v.rms) / t.floor_val,
                    s.stribeck_velocity,
                    s.stribeck_exponent,
                    s.stick_velocity,
                    s.sign_lead,
                    s.sign_epsilon
                );
            }
        }
    }
    if std::env::var_os("WB_ONLY").is_some() {
        return;
    }
    let report = |name: &str, f: &dyn Fn(&Rec) -> Vec<f64>| {
        let ce = vec![lpw(&f(&recs[0]), &recs[0].p)];
        let cv = vec![lpw(&f(&recs[1]), &recs[1].p)];
        let (th, e, v, _) = score(&recs[0].p, &ce, &recs[1].p, &cv, false);
        let (_, e1, v1, _) = score(&recs[0].p, &ce, &recs[1].p, &cv, true);
        println!(
            "  {name:<34} θ-free est {:.3} val {:.3} (J {:.4} θ {:.3}) | θ=1 est {:.3} val {:.3}",
            e / t.floor_est,
            v / t.floor_val,
            th.first().copied().unwrap_or(f64::NAN),
            th.get(2).copied().unwrap_or(f64::NAN),
            e1 / t.floor_est,
            v1 / t.floor_val
        );
    };
    report("TRUE friction (load eq.)", &|r| r.f_true.clone());
    report("static(v_meas)", &|r| static_f(pl, &r.v_meas));
    let tau_b = 2.0 * (pl.j2 / s0).sqrt();
    for (lead, kap) in [
        (1.0, 0.0),
        (1.0, 0.7),
        (1.0, 1.0),
        (1.0, 2.0),
        (0.5, 0.7),
        (0.0, 0.7),
    ] {
        report(&format!("dynsign(v_meas) τb×{lead} κ=zs×{kap}"), &|r| {
            (0..r.u.len())
                .map(|i| {
                    let (v, a) = (r.v_meas[i], r.a_meas[i]);
                    let arg = v + lead * tau_b * a
                        - a.signum() * (2.0 * kap * pl.z_scale * a.abs()).sqrt();
                    arg.signum() * g(pl, v)
                })
                .collect()
        });
    }
    report("static(v_true)", &|r| static_f(pl, &r.v_true));
    report("lugre(v_true)", &|r| {
        lugre_f(pl, &r.v_true, pl.z_scale, 1.0, dt)
    });
    report("lugre(v_true) σ1=0", &|r| {
        lugre_f(pl, &r.v_true, pl.z_scale, 0.0, dt)
    });
    for k in [1.0, 10.0, 30.0, 100.0, 300.0] {
        report(&format!("lugre(v_meas) zs×{k}"), &|r| {
            lugre_f(pl, &r.v_meas, pl.z_scale * k, 1.0, dt)
        });
    }
    for k in [1.0, 10.0, 100.0] {
        report(&format!("lugre(v_meas) zs×{k} σ1=0"), &|r| {
            lugre_f(pl, &r.v_meas, pl.z_scale * k, 0.0, dt)
        });
    }
    // Oracles: the true stick state (|v_true| < thr), friction = u there.
    for thr in [1e-4, 1e-3, 3e-3] {
        report(&format!("stuck_true<{thr:.0e}: u | static(v_true)"), &|r| {
            r.v_true
                .iter()
                .zip(&r.u)
                .map(|(&v, &u)| {
                    if v.abs() < thr {
                        u
                    } else {
                        v.signum() * g(pl, v)
                    }
                })
                .collect()
        });
        report(&format!("stuck_true<{thr:.0e}: u | static(v_meas)"), &|r| {
            r.v_true
                .iter()
                .zip(&r.v_meas)
                .zip(&r.u)
                .map(|((&vt, &v), &u)| {
                    if vt.abs() < thr {
                        u
                    } else {
                        v.signum() * g(pl, v)
                    }
                })
                .collect()
        });
    }
    // Friction nonlinearity on a wider-band velocity (hold window on it too).
    for fcv in [40.0, 80.0, 120.0, 200.0] {
        for k in [1.0, 2.0, 4.0] {
            report(&format!("hold vh×{k} + static(v@{fcv}Hz)"), &|r| {
                let d = diff::differentiate(&r.x, dt, fcv);
                let vh = k * recs[0].p.stick_velocity * (fcv / 40.0f64).powf(1.5);
                (0..r.u.len())
                    .map(|i| {
                        let v = d.velocity[i];
                        let w = sim_plant::effects::stribeck::stick_window_mean(
                            v,
                            d.acceleration[i],
                            dt,
                            vh,
                        );
                        (1.0 - w) * v.signum() * g(pl, v) + w * r.u[i]
                    })
                    .collect()
            });
        }
    }
    // Hold of the balancing torque: (1 − w)·static + w·(u − J·a − b·v) (truth J, b).
    for k in [0.5, 1.0, 2.0, 4.0, 8.0] {
        let vh = k * recs[0].p.stick_velocity;
        let jt = pl.j1 + pl.j2;
        report(&format!("hold(u-Ja-bv) vh×{k} + static(v_meas)"), &|r| {
            (0..r.u.len())
                .map(|i| {
                    let v = r.v_meas[i];
                    let w = sim_plant::effects::stribeck::stick_window(v, vh);
                    (1.0 - w) * v.signum() * g(pl, v)
                        + w * (r.u[i] - jt * r.a_meas[i] - pl.b_pos * v)
                })
                .collect()
        });
    }
    // Hold at rest: (1 − w)·static + w·u, with w from the measured velocity.
    for k in [0.5, 1.0, 2.0] {
        let vh = k * recs[0].p.stick_velocity;
        report(&format!("hold vh×{k} + static(v_meas)"), &|r| {
            r.v_meas
                .iter()
                .zip(&r.u)
                .map(|(&v, &u)| {
                    let w = sim_plant::effects::stribeck::stick_window(v, vh);
                    (1.0 - w) * v.signum() * g(pl, v) + w * u
                })
                .collect()
        });
    }
}

/// `DUMP=1`: the workbench refit's validation residual around its largest excursions, with
/// the truth's load velocity.
pub fn dump(t: &Trial) {
    let pe = Prepared::new(&t.est, cutoff());
    let pv = Prepared::new(&t.val, cutoff());
    let mut m: Model = start_model(&[Family::Stribeck]);
    if refine::refit_all(&mut m, &pe).is_err() {
        return;
    }
    if refine::fit_add(&mut m, &pe, Some(EffectKind::Stribeck), Some(&pv)).is_err() {
        return;
    }
    let r = hil_host::workbench::residual::equation_error(&m, &pv);
    let ft = lpw(
        &friction_truth(&t.plant, &t.motor[1], &t.load[1], pv.dt),
        &pv,
    );
    let pars = m.params();
    let (jf, bf) = (pars[0].value, pars[1].value);
    let vt = central(&t.load[1], pv.dt);
    let st = lpw(&static_f(&t.plant, &vt), &pv);
    let lg = lpw(&lugre_f(&t.plant, &vt, t.plant.z_scale, 1.0, pv.dt), &pv);
    let ftr = friction_truth(&t.plant, &t.motor[1], &t.load[1], pv.dt);
    let vt = win(&vt, &pv);
    // Residual energy by |v_true| band and by |v_meas| band.
    let bands = [0.0, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0, 1e9];
    let floor2 = t.floor_val * t.floor_val;
    let n = pv.len() as f64;
    for (name, vel) in [("v_true", &vt), ("v_meas", &pv.velocity)] {
        let mut e = vec![0.0; bands.len() - 1];
        let mut c = vec![0usize; bands.len() - 1];
        for (k, &v) in vel.iter().enumerate() {
            let b = bands
                .windows(2)
                .position(|w| v.abs() >= w[0] && v.abs() < w[1])
                .unwrap_or(0);
            e[b] += r.residual[k] * r.residual[k];
            c[b] += 1;
        }
        let line: Vec<String> = (0..e.len())
            .map(|b| {
                format!(
                    "<{:.0e}: {:.0}% of rows, {:.2} floor² ",
                    bands[b + 1],
                    100.0 * c[b] as f64 / n,
                    e[b] / n / floor2
                )
            })
            .collect();
        println!("  residual² by |{name}|: {}", line.join("| "));
    }
    let stride: usize = std::env::var("STRIDE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(5);
    if let Ok(range) = std::env::var("RANGE") {
        let mut it = range.split(':').filter_map(|x| x.parse::<usize>().ok());
        let (a, b) = (it.next().unwrap_or(0), it.next().unwrap_or(0));
        println!("   k      u_f       pred      res/fl   v_meas    v_true    a_meas  F_true_f  F_model  (F_true-F_model)/fl  static(vt)_f lugre(vt)_f  F_true_raw");
        for k in (a..b.min(pv.len())).step_by(stride) {
            println!(
                "{k:6} {:9.4} {:9.4} {:7.2} {:9.4} {:9.4} {:9.3} {:9.4} {:9.4} {:7.2} {:9.4} {:9.4} {:9.4}",
                r.measured[k], r.predicted[k], r.residual[k] / t.floor_val, pv.velocity[k], vt[k], pv.acceleration[k],
                ft[k], r.predicted[k] - jf * pv.acceleration[k] - bf * pv.velocity[k],
                (ft[k] - (r.predicted[k] - jf * pv.acceleration[k] - bf * pv.velocity[k])) / t.floor_val,
                st[k], lg[k], ftr[k + pv.raw_offset]
            );
        }
    } else {
        // The worst 50 ms windows.
        let w = 50;
        let mut seg: Vec<(f64, usize)> = (0..pv.len() / w)
            .map(|s| {
                (
                    r.residual[s * w..(s + 1) * w]
                        .iter()
                        .map(|x| x * x)
                        .sum::<f64>(),
                    s * w,
                )
            })
            .collect();
        seg.sort_by(|a, b| b.0.total_cmp(&a.0));
        let tot: f64 = r.residual.iter().map(|x| x * x).sum();
        for (e, k) in seg.iter().take(8) {
            println!(
                "  window {k}: {:.1}% of residual² ; v_true {:.3}..{:.3}",
                100.0 * e / tot,
                vt[*k..k + w].iter().cloned().fold(f64::INFINITY, f64::min),
                vt[*k..k + w]
                    .iter()
                    .cloned()
                    .fold(f64::NEG_INFINITY, f64::max)
            );
        }
    }
}
