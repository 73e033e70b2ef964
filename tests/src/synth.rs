//! A small recording the workbench's end-to-end and bad-input tests write as a user's CSV: a
//! 2 kg mass with viscous (3 N·s/m) and Coulomb (0.8 N) friction tracking two sines under a PD
//! loop at 1 kHz, integrated at ten substeps per sample. It is generated here, not by the
//! workbench, so the tests do not share the workbench's conventions.

use std::path::Path;

/// How the record is written.
#[derive(Clone, Copy, Debug)]
pub struct PdMass {
    /// Rows (1 ms each).
    pub rows: usize,
    /// The position column in mm (`pos_mm`) instead of m (`pos_m`).
    pub position_in_mm: bool,
    /// Log the position in the middle of each command's hold, not when the command is computed
    /// (zero-order hold).
    pub log_mid_hold: bool,
    /// Peak of the uniform noise added to the logged command (the applied one has none), N.
    pub logged_input_noise: f64,
}

impl PdMass {
    /// `rows` rows in m, logged as a drive logs (zero-order hold), the command as applied.
    pub fn new(rows: usize) -> Self {
        PdMass {
            rows,
            position_in_mm: false,
            log_mid_hold: false,
            logged_input_noise: 0.0,
        }
    }

    /// The CSV text (`time_s,force_N,pos_m|pos_mm`); `edit(row, [t, u, x])` may change a row's
    /// cells (as text) before it is written.
    pub fn csv(&self, edit: impl Fn(usize, &mut [String; 3])) -> String {
        let dt = 1e-3;
        let (m, b, fc) = (2.0, 3.0, 0.8);
        let (mut x, mut v) = (0.0f64, 0.0f64);
        let mut seed = 7u64;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let pos = if self.position_in_mm {
            "pos_mm"
        } else {
            "pos_m"
        };
        let mut s = format!("time_s,force_N,{pos}\n");
        let logged_at = if self.log_mid_hold { 5 } else { 0 };
        for k in 0..self.rows {
            let t = k as f64 * dt;
            let r = 0.05 * (std::f64::consts::TAU * 0.7 * t).sin()
                + 0.02 * (std::f64::consts::TAU * 1.9 * t).sin();
            let u = 400.0 * (r - x) - 40.0 * v + 0.5 * rnd();
            for j in 0..10 {
                if j == logged_at {
                    let logged_u = if self.logged_input_noise > 0.0 {
                        u + 2.0 * self.logged_input_noise * rnd()
                    } else {
                        u
                    };
                    let x_out = if self.position_in_mm { 1e3 * x } else { x };
                    let mut cells = [t.to_string(), logged_u.to_string(), x_out.to_string()];
                    edit(k, &mut cells);
                    s.push_str(&cells.join(","));
                    s.push('\n');
                }
                let h = dt / 10.0;
                let a = (u - b * v - fc * v.signum()) / m;
                v += h * a;
                x += h * v;
            }
        }
        s
    }

    /// [`PdMass::csv`] written to `path`.
    pub fn write(&self, path: &Path, edit: impl Fn(usize, &mut [String; 3])) {
        std::fs::write(path, self.csv(edit)).expect("the test record is written");
    }
}
