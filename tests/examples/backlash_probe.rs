//! Probe: how far is the workbench's backlash deflection δ(t) from the truth's?
//!
//! `cargo run --release -p jointlab-tests --example backlash_probe -- SEED RHO [SEED RHO …]`
//!
//! Environment: `SUMMARY=1` one line per trial (true δ, main's window-started estimate, the
//! pre-rolled one, impact-model variants; est/val RMS over the floors); `SERIES=a:b` the
//! low-passed true and estimated δ every 5 samples of the window (`VAL=1`: validation
//! record; `ALT=e`: an impact model with restitution e instead); `DUMP=a:b` raw samples;
//! `SCAN=1` width scans of the raw/low-passed operators.
//!
//! For each trial: the column −J2·(δ̈ + δ̇/τ) from the *true* δ = x_motor − x_load (low-passed
//! as the motion), from the workbench's estimate at the true width and τ, and from variants;
//! each fitted with inertia + viscous on the estimation record and scored on validation,
//! relative to the trial's noise floors. Then where the estimate's error sits (contact / gap,
//! near crossings).

use hil_host::workbench::residual::Prepared;
use jointlab_tests::hidden::{cutoff, generate, probe_args, Family, Trial};
use sim_plant::effects::{backlash, signal};

fn col_from_delta_lp(d: &[f64], tau: f64, dt: f64) -> Vec<f64> {
    let n = d.len();
    let mut col = vec![0.0; n];
    for i in 1..n - 1 {
        let acc = (d[i + 1] - 2.0 * d[i] + d[i - 1]) / (dt * dt);
        let vel = (d[i + 1] - d[i - 1]) / (2.0 * dt);
        col[i] = -(acc + if tau > 0.0 { vel / tau } else { 0.0 });
    }
    col[0] = col[1];
    col[n - 1] = col[n - 2];
    col
}

fn lp(x: &[f64], p: &Prepared) -> Vec<f64> {
    signal::filtfilt(x, p.cutoff_hz, 1.0 / p.dt)
}

/// Window of a whole-record series.
fn win(x: &[f64], p: &Prepared) -> Vec<f64> {
    x[p.raw_offset..p.raw_offset + p.len()].to_vec()
}

fn rms(x: &[f64]) -> f64 {
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

/// Fit [a, v, col] on est, return (θ, est rms, val rms).
fn score(pe: &Prepared, ce: &[f64], pv: &Prepared, cv: &[f64]) -> ([f64; 3], f64, f64) {
    let rows = (0..pe.len()).map(|i| ([pe.acceleration[i], pe.velocity[i], ce[i]], pe.input[i]));
    let th = sim_plant::experiments::least_squares(rows).unwrap_or([f64::NAN; 3]);
    let res = |p: &Prepared, c: &[f64]| {
        let r: Vec<f64> = (0..p.len())
            .map(|i| p.input[i] - th[0] * p.acceleration[i] - th[1] * p.velocity[i] - th[2] * c[i])
            .collect();
        rms(&r)
    };
    (th, res(pe, ce), res(pv, cv))
}

struct Rec<'a> {
    p: Prepared,
    x1: &'a [f64],
    x2: &'a [f64],
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    for (seed, rho) in probe_args(&args, "backlash_probe SEED RHO [SEED RHO …]") {
        let Some(t) = generate(seed, &[Family::Backlash], rho) else {
            println!("seed {seed}: unstable");
            continue;
        };
        probe(seed, &t);
        if let Ok(r) = std::env::var("DUMP") {
            let mut it = r.split(':').filter_map(|x| x.parse().ok());
            if let (Some(a), Some(b)) = (it.next(), it.next()) {
                dump(&t, a, b);
            }
        }
    }
}

fn probe(seed: u64, t: &Trial) {
    let pl = &t.plant;
    let b = pl.backlash;
    let tau = pl.j2 / pl.b_pos;
    let recs = [
        Rec {
            p: Prepared::new(&t.est, cutoff()),
            x1: &t.est.output,
            x2: &t.load[0],
        },
        Rec {
            p: Prepared::new(&t.val, cutoff()),
            x1: &t.val.output,
            x2: &t.load[1],
        },
    ];
    let dt = recs[0].p.dt;
    let mu = pl.j1 / (pl.j1 + pl.j2);
    println!(
        "== seed {seed}: ρ {:.2}, J1 {:.4} J2 {:.4} b_visc {:.4} τ {:.3} s, gap {:.3e} rad ({:.1} counts), floors {:.3e}/{:.3e}",
        t.rho,
        pl.j1,
        pl.j2,
        pl.b_pos,
        tau,
        b,
        b / (std::f64::consts::TAU / 65536.0),
        t.floor_est,
        t.floor_val
    );
    // True δ (whole record), low-passed, windowed.
    let true_lp: Vec<Vec<f64>> = recs
        .iter()
        .map(|r| {
            let d: Vec<f64> = r.x1.iter().zip(r.x2).map(|(a, b)| a - b).collect();
            win(&lp(&d, &r.p), &r.p)
        })
        .collect();
    // The estimate of main before the pre-roll, at the true shape: the play operator on the
    // trimmed window's smoothed motion, starting mid-gap.
    let wb_lp: Vec<Vec<f64>> = recs
        .iter()
        .map(|r| {
            let tr = r.p.trajectory();
            let d = backlash::gap_deflection(tr.position, tr.velocity, b, tau, dt);
            tr.lowpass(&d)
        })
        .collect();
    let quiet = std::env::var_os("SUMMARY").is_some();
    let report = |name: &str, d: &[Vec<f64>]| -> (f64, f64, f64, f64) {
        let ce = col_from_delta_lp(&d[0], tau, dt);
        let cv = col_from_delta_lp(&d[1], tau, dt);
        let (th, e, v) = score(&recs[0].p, &ce, &recs[1].p, &cv);
        let err: Vec<f64> = d[0].iter().zip(&true_lp[0]).map(|(a, b)| a - b).collect();
        let cerr = col_from_delta_lp(&err, tau, dt);
        let nn = cerr.len() as f64;
        let (mut ep, mut ec) = (0.0, 0.0);
        for (i, c) in cerr.iter().enumerate() {
            if true_lp[0][i].abs() >= 0.8 * 0.5 * b {
                ep += c * c;
            } else {
                ec += c * c;
            }
        }
        let split = format!(
            "push {:.2} cross {:.2}",
            pl.j2 * (ep / nn).sqrt() / t.floor_est,
            pl.j2 * (ec / nn).sqrt() / t.floor_est
        );
        if !quiet {
            println!(
            "  {name:<28} est {e_r:.3}  val {v_r:.3}   J {:.5} b {:.5} J2 {:.5}   δlp err rms {:.2e} ({:.1} % gap), J2·col err {:.3} floor {split}",
            th[0],
            th[1],
            th[2],
            rms(&err),
            100.0 * rms(&err) / b,
            pl.j2 * rms(&cerr) / t.floor_est,
            e_r = e / t.floor_est,
            v_r = v / t.floor_val,
        );
        }
        (
            e / t.floor_est,
            v / t.floor_val,
            pl.j2 * (ep / nn).sqrt() / t.floor_est,
            pl.j2 * (ec / nn).sqrt() / t.floor_est,
        )
    };
    // Baseline only.
    {
        let z = vec![vec![0.0; recs[0].p.len()], vec![0.0; recs[1].p.len()]];
        report("baseline (no column)", &z);
    }
    let tr = report("true δ", &true_lp);
    let wb = report("workbench (true b, τ)", &wb_lp);
    if quiet {
        let wh: Vec<Vec<f64>> = recs
            .iter()
            .map(|r| {
                let d = hil_host::workbench::diff::differentiate(r.x1, dt, r.p.cutoff_hz);
                win(
                    &lp(
                        &backlash::gap_deflection(&d.position, &d.velocity, b, tau, dt),
                        &r.p,
                    ),
                    &r.p,
                )
            })
            .collect();
        let whole = report("whole", &wh);
        let mut extra = String::new();
        let motors = [&t.motor[0], &t.motor[1]];
        for (name, src) in [("oracle true x1", 0), ("oracle enc x1", 1)] {
            let d: Vec<Vec<f64>> = recs
                .iter()
                .enumerate()
                .map(|(k, r)| {
                    let xm: &[f64] = if src == 0 { motors[k] } else { r.x1 };
                    let x2 = load_from_motor(xm, dt, 20, pl);
                    let dd: Vec<f64> = r.x1.iter().zip(&x2).map(|(a, b)| a - b).collect();
                    win(&lp(&dd, &r.p), &r.p)
                })
                .collect();
            let q = report(name, &d);
            extra += &format!(" {name}: {:.2}/{:.2}", q.0, q.1);
        }
        for (name, e) in [
            ("play true x1", -1.0),
            ("impact0.85 true x1", 0.85),
            ("impact0.5 true x1", 0.5),
            ("impact0.85 enc x1", 1.85),
        ] {
            let d: Vec<Vec<f64>> = recs
                .iter()
                .enumerate()
                .map(|(k, r)| {
                    let xm: &[f64] = if e > 1.0 { r.x1 } else { motors[k] };
                    let e = if e > 1.0 { e - 1.0 } else { e };
                    let nn = xm.len();
                    let vm: Vec<f64> = (0..nn)
                        .map(|i| (xm[(i + 1).min(nn - 1)] - xm[i.saturating_sub(1)]) / (2.0 * dt))
                        .collect();
                    let dd = if e < 0.0 {
                        backlash::gap_deflection(xm, &vm, b, tau, dt)
                    } else {
                        impact_play(xm, &vm, b, tau, dt, mu, e, true)
                    };
                    // δ against the recorded motor position, as the column would be.
                    let x2: Vec<f64> = xm.iter().zip(&dd).map(|(a, d)| a - d).collect();
                    let dd: Vec<f64> = r.x1.iter().zip(&x2).map(|(a, b)| a - b).collect();
                    win(&lp(&dd, &r.p), &r.p)
                })
                .collect();
            let q = report(name, &d);
            extra += &format!(" {name}: {:.2}/{:.2}", q.0, q.1);
        }
        for fc2 in [40.0, 100.0, 200.0] {
            for e in [0.0, 0.5, 0.85] {
                let d: Vec<Vec<f64>> = recs
                    .iter()
                    .map(|r| {
                        let d = hil_host::workbench::diff::differentiate(r.x1, dt, fc2);
                        win(
                            &lp(
                                &impact_play(&d.position, &d.velocity, b, tau, dt, mu, e, true),
                                &r.p,
                            ),
                            &r.p,
                        )
                    })
                    .collect();
                let q = report("x", &d);
                extra += &format!(" {fc2}/{e}: {:.2}", q.1);
            }
        }
        println!(
            "SUM {seed} ρ {:5.2} J2/J1 {:5.2} gap {:6.1} cnt | true {:.2}/{:.2} | wb {:.2}/{:.2} push {:.2} cross {:.2} | whole {:.2}/{:.2} |{extra}",
            t.rho,
            pl.j2 / pl.j1,
            b / (std::f64::consts::TAU / 65536.0),
            tr.0, tr.1, wb.0, wb.1, wb.2, wb.3, whole.0, whole.1
        );
        return;
    }
    // Variants on the raw (whole-record) motor position.
    let variant = |name: &str, f: &dyn Fn(&Rec) -> Vec<f64>| {
        let d: Vec<Vec<f64>> = recs.iter().map(|r| win(&lp(&f(r), &r.p), &r.p)).collect();
        report(name, &d);
    };
    let vel_lp = |r: &Rec| -> Vec<f64> {
        let d = hil_host::workbench::diff::differentiate(r.x1, dt, r.p.cutoff_hz);
        d.velocity
    };
    let pos_lp = |r: &Rec| -> Vec<f64> {
        let d = hil_host::workbench::diff::differentiate(r.x1, dt, r.p.cutoff_hz);
        d.position
    };
    let raw_vel = |x: &[f64]| -> Vec<f64> {
        let n = x.len();
        (0..n)
            .map(|i| (x[(i + 1).min(n - 1)] - x[i.saturating_sub(1)]) / (2.0 * dt))
            .collect()
    };
    variant("lp x1 whole, lp v", &|r| {
        backlash::gap_deflection(&pos_lp(r), &vel_lp(r), b, tau, dt)
    });
    variant("raw x1, lp v", &|r| {
        backlash::gap_deflection(r.x1, &vel_lp(r), b, tau, dt)
    });
    for (src, e_rest, clamp) in [
        ("lp", 0.0, true),
        ("lp", 0.85, true),
        ("lp", 0.85, false),
        ("raw", 0.0, true),
        ("raw", 0.85, true),
        ("raw", 0.85, false),
        ("raw", 0.5, false),
    ] {
        variant(&format!("{src} impact e {e_rest} μ clamp {clamp}"), &|r| {
            let (x, v) = if src == "raw" {
                (r.x1.to_vec(), raw_vel(r.x1))
            } else {
                (pos_lp(r), vel_lp(r))
            };
            impact_play(&x, &v, b, tau, dt, mu, e_rest, clamp)
        });
    }
    if std::env::var_os("SCAN").is_some() {
        for k in [0.9, 1.0, 1.05, 1.1, 1.15, 1.2, 1.3, 1.5] {
            variant(&format!("raw x1 lp v, width×{k}"), &|r| {
                backlash::gap_deflection(r.x1, &vel_lp(r), k * b, tau, dt)
            });
            variant(&format!("lp x1 lp v, width×{k}"), &|r| {
                backlash::gap_deflection(&pos_lp(r), &vel_lp(r), k * b, tau, dt)
            });
            let d: Vec<Vec<f64>> = recs
                .iter()
                .map(|r| {
                    let tr = r.p.trajectory();
                    tr.lowpass(&backlash::gap_deflection(
                        tr.position,
                        tr.velocity,
                        k * b,
                        tau,
                        dt,
                    ))
                })
                .collect();
            report(&format!("window lp, width×{k}"), &d);
        }
    }
    variant("raw x1, raw v", &|r| {
        backlash::gap_deflection(r.x1, &raw_vel(r.x1), b, tau, dt)
    });
    variant("raw x1, v=0 (pure play)", &|r| {
        backlash::gap_deflection(r.x1, &vec![0.0; r.x1.len()], b, 0.0, dt)
    });

    // Two-column fits: the workbench's δ plus a chatter-intensity term σ(t)·A(t).
    let report2 = |name: &str, d: &[Vec<f64>], extra: &[Vec<f64>]| {
        let c1e = col_from_delta_lp(&d[0], tau, dt);
        let c1v = col_from_delta_lp(&d[1], tau, dt);
        let c2e = col_from_delta_lp(&extra[0], tau, dt);
        let c2v = col_from_delta_lp(&extra[1], tau, dt);
        let (pe, pv) = (&recs[0].p, &recs[1].p);
        let rows = (0..pe.len()).map(|i| {
            (
                [pe.acceleration[i], pe.velocity[i], c1e[i], c2e[i]],
                pe.input[i],
            )
        });
        let th = sim_plant::experiments::least_squares(rows).unwrap_or([f64::NAN; 4]);
        let res = |p: &Prepared, c1: &[f64], c2: &[f64]| {
            let r: Vec<f64> = (0..p.len())
                .map(|i| {
                    p.input[i]
                        - th[0] * p.acceleration[i]
                        - th[1] * p.velocity[i]
                        - th[2] * c1[i]
                        - th[3] * c2[i]
                })
                .collect();
            rms(&r)
        };
        println!(
            "  {name:<28} est {:.3}  val {:.3}   J {:.5} J2 {:.5} k2 {:.4e}",
            res(pe, &c1e, &c2e) / t.floor_est,
            res(pv, &c1v, &c2v) / t.floor_val,
            th[0],
            th[2],
            th[3]
        );
    };
    let hf_env = |x: &[f64], lpx: &[f64], p: &Prepared, fenv: f64| -> Vec<f64> {
        let sq: Vec<f64> = x.iter().zip(lpx).map(|(a, b)| (a - b) * (a - b)).collect();
        signal::filtfilt(&sq, fenv, 1.0 / p.dt)
            .iter()
            .map(|v| v.max(0.0).sqrt())
            .collect()
    };
    for fenv in [5.0, 10.0, 20.0] {
        for src in ["x1", "u"] {
            let extra: Vec<Vec<f64>> = recs
                .iter()
                .enumerate()
                .map(|(k, r)| {
                    let (x, lx) = if src == "x1" {
                        (r.x1.to_vec(), pos_lp(r))
                    } else {
                        let u = if k == 0 { &t.est.input } else { &t.val.input };
                        (u.clone(), lp(u, &r.p))
                    };
                    let a = hf_env(&x, &lx, &r.p, fenv);
                    let a = win(&a, &r.p);
                    // side: the workbench δ relative to the half gap.
                    let side: Vec<f64> = wb_lp[k].iter().map(|d| d / (0.5 * b)).collect();
                    let prod: Vec<f64> = a.iter().zip(&side).map(|(a, s)| a * s).collect();
                    lp(&prod, &r.p)
                })
                .collect();
            report2(&format!("wb + {src} HF env {fenv} Hz"), &wb_lp, &extra);
        }
    }

    // Correlates of the pushing-phase error s = side·(δwb − δtrue), band-passed 5–40 Hz.
    {
        let r = &recs[0];
        let pe = &r.p;
        let n = pe.len();
        let side: Vec<f64> = wb_lp[0].iter().map(|d| d / (0.5 * b)).collect();
        let push: Vec<bool> = side.iter().map(|s| s.abs() > 0.995).collect();
        let s_err: Vec<f64> = (0..n)
            .map(|i| side[i] * (wb_lp[0][i] - true_lp[0][i]))
            .collect();
        let hp = |x: &[f64]| -> Vec<f64> {
            let l = signal::filtfilt(x, 5.0, 1.0 / dt);
            x.iter().zip(&l).map(|(a, b)| a - b).collect()
        };
        let sh = hp(&s_err);
        let corr = |y: &[f64]| -> f64 {
            let yh = hp(y);
            let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
            for i in 0..n {
                if push[i] {
                    sxy += sh[i] * yh[i];
                    sxx += sh[i] * sh[i];
                    syy += yh[i] * yh[i];
                }
            }
            sxy / (sxx * syy).sqrt()
        };
        let u_hf = win(&hf_env(&t.est.input, &lp(&t.est.input, pe), pe, 20.0), pe);
        let x_hf = win(&hf_env(r.x1, &pos_lp(r), pe, 20.0), pe);
        let sa: Vec<f64> = (0..n).map(|i| side[i] * pe.acceleration[i]).collect();
        let sv: Vec<f64> = (0..n).map(|i| side[i] * pe.velocity[i]).collect();
        let su: Vec<f64> = (0..n).map(|i| side[i] * pe.input[i]).collect();
        let jerk: Vec<f64> = (0..n)
            .map(|i| {
                side[i]
                    * (pe.acceleration[(i + 1).min(n - 1)] - pe.acceleration[i.saturating_sub(1)])
            })
            .collect();
        let res: Vec<f64> = (0..n).map(|i| side[i] * (pe.input[i] - 0.0)).collect();
        let _ = res;
        let fpush = push.iter().filter(|&&p| p).count() as f64 / n as f64;
        let e_push: f64 = {
            let cerr = col_from_delta_lp(&s_err, tau, dt);
            let tot: f64 = cerr.iter().map(|v| v * v).sum();
            cerr.iter()
                .zip(&push)
                .filter(|(_, &p)| p)
                .map(|(v, _)| v * v)
                .sum::<f64>()
                / tot
        };
        println!(
            "  pushing (wb |δ| = half): {:.0} % of samples, {:.0} % of column error energy; s rms {:.2} counts; corr with side·a {:.2}, side·v {:.2}, side·u {:.2}, side·jerk {:.2}, u HF env {:.2}, x1 HF env {:.2}",
            100.0 * fpush,
            100.0 * e_push,
            rms(&sh) / (std::f64::consts::TAU / 65536.0),
            corr(&sa),
            corr(&sv),
            corr(&su),
            corr(&jerk),
            corr(&u_hf),
            corr(&x_hf)
        );
    }

    // Where is the error? Contact phases by the truth.
    let which = if std::env::var_os("VAL").is_some() {
        1
    } else {
        0
    };
    let wb_lp: Vec<Vec<f64>> = match std::env::var("ALT").ok().as_deref() {
        Some(alt) => recs
            .iter()
            .map(|r| {
                let d = hil_host::workbench::diff::differentiate(r.x1, dt, r.p.cutoff_hz);
                let e: f64 = alt.parse().unwrap_or(0.85);
                win(
                    &lp(
                        &impact_play(&d.position, &d.velocity, b, tau, dt, mu, e, true),
                        &r.p,
                    ),
                    &r.p,
                )
            })
            .collect(),
        None => wb_lp,
    };
    let r = &recs[which];
    let o = r.p.raw_offset;
    let n = r.p.len();
    let contact: Vec<bool> = (0..n)
        .map(|i| (r.x1[o + i] - r.x2[o + i]).abs() >= 0.5 * b)
        .collect();
    let err: Vec<f64> = wb_lp[which]
        .iter()
        .zip(&true_lp[which])
        .map(|(a, b)| a - b)
        .collect();
    let cerr = col_from_delta_lp(&err, tau, dt);
    // Samples within ±30 ms of a contact↔gap change.
    let mut near = vec![false; n];
    let mut crossings = 0;
    for i in 1..n {
        if contact[i] != contact[i - 1] {
            crossings += 1;
            for m in &mut near[i.saturating_sub(30)..(i + 30).min(n)] {
                *m = true;
            }
        }
    }
    let frac_contact = contact.iter().filter(|&&c| c).count() as f64 / n as f64;
    let e_tot: f64 = cerr.iter().map(|v| v * v).sum();
    let e_near: f64 = cerr
        .iter()
        .zip(&near)
        .filter(|(_, &m)| m)
        .map(|(v, _)| v * v)
        .sum();
    let frac_near = near.iter().filter(|&&c| c).count() as f64 / n as f64;
    println!(
        "  contact {:.1} % of samples, {crossings} contact changes ({:.1}/s), ±30 ms of them: {:.1} % of samples, {:.1} % of column error energy",
        100.0 * frac_contact,
        crossings as f64 / (n as f64 * dt),
        100.0 * frac_near,
        100.0 * e_near / e_tot
    );
    // δ_lp time series: sections of 1 s, rms error per section vs motion speed.
    let sec = 1000;
    let mut line = String::new();
    for k in 0..n / sec {
        let s = k * sec..(k + 1) * sec;
        let e = pl.j2 * rms(&cerr[s.clone()]) / t.floor_est;
        line += &format!("{:.1}", e);
        line += " ";
    }
    println!("  J2·col err / floor per second: {line}");
    if let Ok(sr) = std::env::var("SERIES") {
        let mut it = sr.split(':').filter_map(|x| x.parse::<usize>().ok());
        if let (Some(a), Some(z)) = (it.next(), it.next()) {
            let half = 0.5 * b;
            for k in (a..z.min(n)).step_by(5) {
                let s = k..(k + 5).min(n);
                let ce = pl.j2 * rms(&cerr[s.clone()]) / t.floor_est;
                let cont = contact[s.clone()].iter().filter(|&&c| c).count();
                println!(
                    "{k:6} v {:7.3} a {:8.2} δtrue {:6.3} δwb {:6.3} diff {:7.4} colerr {:5.2} {} contact {}/5 u {:7.4}",
                    r.p.velocity[k],
                    r.p.acceleration[k],
                    true_lp[which][k] / half,
                    wb_lp[which][k] / half,
                    err[k] / half,
                    ce,
                    "#".repeat((ce * 4.0).min(40.0) as usize),
                    cont,
                    r.p.input[k]
                );
            }
        }
    }
}

/// Dump samples `from..to` of the estimation record: raw motor, load, δ/half-gap, input.
#[allow(dead_code)]
pub fn dump(t: &Trial, from: usize, to: usize) {
    let b = t.plant.backlash;
    let x1 = &t.est.output;
    let x2 = &t.load[0];
    let enc = std::f64::consts::TAU / 65536.0;
    for i in from..to {
        println!(
            "{i:6} x1 {:9.2} x2 {:9.2} δ/half {:6.2} u {:8.4}",
            (x1[i] - x1[from]) / enc,
            (x2[i] - x1[from]) / enc,
            (x1[i] - x2[i]) / (0.5 * b),
            t.est.input[i]
        );
    }
}

/// Play operator whose impacts exchange momentum: load velocity += (1+e)·μ·(v1 − v2) when the
/// motor reaches an edge while approaching; `clamp` pins the load to the edge.
#[allow(clippy::too_many_arguments)]
fn impact_play(
    x: &[f64],
    v: &[f64],
    b: f64,
    tau: f64,
    dt: f64,
    mu: f64,
    e: f64,
    clamp: bool,
) -> Vec<f64> {
    let half = 0.5 * b;
    let (decay, drift) = if tau > 0.0 {
        let d = (-dt / tau).exp();
        (d, tau * (1.0 - d))
    } else {
        (1.0, dt)
    };
    let (mut x2, mut v2) = (x[0], v[0]);
    let mut out = Vec::with_capacity(x.len());
    for i in 0..x.len() {
        if i > 0 {
            x2 += drift * v2;
            v2 *= decay;
        }
        let d = x[i] - x2;
        if d > half {
            if v[i] > v2 {
                v2 += (1.0 + e) * mu * (v[i] - v2);
            }
            if clamp {
                x2 = x[i] - half;
            }
        } else if d < -half {
            if v[i] < v2 {
                v2 += (1.0 + e) * mu * (v[i] - v2);
            }
            if clamp {
                x2 = x[i] + half;
            }
        }
        out.push(x[i] - x2);
    }
    out
}

/// Oracle: the truth's load driven through the truth's contact law (spring k, damping c in
/// contact, gap b, viscous b_load, inertia J2) by a motor path known only at the samples
/// (Catmull–Rom interpolation between them), RK4 at `sub` steps per sample. What the load
/// would be if the motor's 1 kHz path (`x1`) were all one needed.
fn load_from_motor(
    x1: &[f64],
    dt: f64,
    sub: usize,
    pl: &jointlab_tests::hidden::truth::Plant,
) -> Vec<f64> {
    let n = x1.len();
    let at = |t: f64| -> (f64, f64) {
        let k = (t / dt).floor().clamp(0.0, (n - 2) as f64) as usize;
        let u = t / dt - k as f64;
        let p0 = x1[k.saturating_sub(1)];
        let p1 = x1[k];
        let p2 = x1[k + 1];
        let p3 = x1[(k + 2).min(n - 1)];
        let (m1, m2) = (0.5 * (p2 - p0), 0.5 * (p3 - p1));
        let (u2, u3) = (u * u, u * u * u);
        let x = (2.0 * u3 - 3.0 * u2 + 1.0) * p1
            + (u3 - 2.0 * u2 + u) * m1
            + (-2.0 * u3 + 3.0 * u2) * p2
            + (u3 - u2) * m2;
        let v = ((6.0 * u2 - 6.0 * u) * p1
            + (3.0 * u2 - 4.0 * u + 1.0) * m1
            + (-6.0 * u2 + 6.0 * u) * p2
            + (3.0 * u2 - 2.0 * u) * m2)
            / dt;
        (x, v)
    };
    let half = 0.5 * pl.backlash;
    let acc = |t: f64, x2: f64, v2: f64| -> f64 {
        let (x, v) = at(t);
        let d = x - x2;
        let defl = backlash::dead_zone(d, half);
        let f = pl.k * defl + if defl != 0.0 { pl.c * (v - v2) } else { 0.0 };
        (f - pl.b_pos * v2) / pl.j2
    };
    let h = dt / sub as f64;
    let (mut x2, mut v2) = (x1[0], 0.0);
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        out.push(x2);
        for j in 0..sub {
            let t = k as f64 * dt + j as f64 * h;
            let (a1, b1) = (v2, acc(t, x2, v2));
            let (a2, b2) = (
                v2 + 0.5 * h * b1,
                acc(t + 0.5 * h, x2 + 0.5 * h * a1, v2 + 0.5 * h * b1),
            );
            let (a3, b3) = (
                v2 + 0.5 * h * b2,
                acc(t + 0.5 * h, x2 + 0.5 * h * a2, v2 + 0.5 * h * b2),
            );
            let (a4, b4) = (v2 + h * b3, acc(t + h, x2 + h * a3, v2 + h * b3));
            x2 += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
            v2 += h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4);
        }
    }
    out
}
