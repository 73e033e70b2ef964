//! Model builders shared by the integration tests.
#![allow(dead_code)]

use sim_plant::effects::{backlash, compliance, coulomb, stribeck, viscous};
use sim_plant::param::Param;
use sim_plant::Model;

pub fn p(v: f64) -> Param {
    Param::fixed(v)
}

/// Rigid single inertia J (N = 1, motor inertia = J), no effects, no torque limit to speak of.
pub fn rigid(j: f64) -> Model {
    let mut m = Model::default();
    m.motor.inertia = p(j);
    m.motor.max_torque = p(1e3);
    m.plant.gear_ratio = p(1.0);
    m
}

/// Lossless 2-mass: motor inertia `i1` at the motor, ratio `n`, output inertia `i2`, spring `k`.
pub fn two_mass(i1: f64, n: f64, i2: f64, k: f64) -> Model {
    let mut m = Model::default();
    m.motor.inertia = p(i1);
    m.motor.max_torque = p(1e3);
    m.plant.gear_ratio = p(n);
    m.plant.output_inertia = p(i2);
    m.effects.compliance = Some(compliance::Params {
        stiffness: p(k),
        ..Default::default()
    });
    m
}

pub fn with_friction(mut m: Model, coulomb_level: f64, excess: f64, vs: f64, b: f64) -> Model {
    m.effects.coulomb = Some(coulomb::Params {
        torque: p(coulomb_level),
    });
    if excess > 0.0 {
        m.effects.stribeck = Some(stribeck::Params {
            excess: p(excess),
            velocity: p(vs),
            exponent: p(2.0),
        });
    }
    if b > 0.0 {
        m.effects.viscous = Some(viscous::Params { damping: p(b) });
    }
    m
}

pub fn with_backlash(mut m: Model, width: f64) -> Model {
    m.effects.backlash = Some(backlash::Params { width: p(width) });
    m
}

/// Times (s) at which `x` crosses zero upwards, by linear interpolation between samples.
pub fn upward_zero_crossings(x: &[f64], dt: f64) -> Vec<f64> {
    x.windows(2)
        .enumerate()
        .filter(|(_, w)| w[0] < 0.0 && w[1] >= 0.0)
        .map(|(i, w)| (i as f64 + w[0] / (w[0] - w[1])) * dt)
        .collect()
}

/// Mean period from first to last upward crossing.
pub fn mean_period(x: &[f64], dt: f64) -> f64 {
    let z = upward_zero_crossings(x, dt);
    assert!(z.len() >= 3, "not oscillating: {} crossings", z.len());
    (z[z.len() - 1] - z[0]) / (z.len() - 1) as f64
}

/// Least squares for a few columns (normal equations, Gaussian elimination with pivoting).
pub fn lstsq(cols: &[Vec<f64>], y: &[f64], mask: &[bool]) -> Vec<f64> {
    let k = cols.len();
    let mut a = vec![vec![0.0; k + 1]; k];
    for (t, &yt) in y.iter().enumerate() {
        if !mask[t] {
            continue;
        }
        for i in 0..k {
            for j in 0..k {
                a[i][j] += cols[i][t] * cols[j][t];
            }
            a[i][k] += cols[i][t] * yt;
        }
    }
    for c in 0..k {
        let piv = (c..k)
            .max_by(|&r, &s| a[r][c].abs().total_cmp(&a[s][c].abs()))
            .unwrap();
        a.swap(c, piv);
        let pivot_row = a[c].clone();
        for (r, row) in a.iter_mut().enumerate() {
            if r != c {
                let f = row[c] / pivot_row[c];
                for (x, pv) in row.iter_mut().zip(&pivot_row).skip(c) {
                    *x -= f * pv;
                }
            }
        }
    }
    (0..k).map(|i| a[i][k] / a[i][i]).collect()
}
