//! Setpoint trajectories the supervisor streams: step, ramp, sine, chirp, or a CSV file.
//! Values are in the unit of the quantity being commanded (output rad for positions, output
//! N·m for force setpoints); the supervisor converts to wire units.

use std::path::Path;

use anyhow::{bail, Context, Result};

/// A setpoint as a function of time (s since streaming started).
#[derive(Clone, Debug, PartialEq)]
pub enum Trajectory {
    /// Hold `from` until `at`, then `to`.
    Step {
        /// Initial value.
        from: f64,
        /// Final value.
        to: f64,
        /// Step time, s.
        at: f64,
    },
    /// Linear from `from` to `to` over `duration` seconds, then hold.
    Ramp {
        /// Start.
        from: f64,
        /// End.
        to: f64,
        /// Seconds.
        duration: f64,
    },
    /// offset + amplitude·sin(2πft).
    Sine {
        /// Mean.
        offset: f64,
        /// Amplitude.
        amplitude: f64,
        /// Hz.
        freq: f64,
    },
    /// Linear chirp from f0 to f1 over `duration`.
    Chirp {
        /// Amplitude.
        amplitude: f64,
        /// Start frequency, Hz.
        f0: f64,
        /// End frequency, Hz.
        f1: f64,
        /// Sweep time, s.
        duration: f64,
    },
    /// Piecewise-linear samples (time s, value), e.g. from a CSV file.
    Samples(Vec<(f64, f64)>),
}

impl Trajectory {
    /// Value at time `t`.
    pub fn at(&self, t: f64) -> f64 {
        match self {
            Trajectory::Step { from, to, at } => {
                if t < *at {
                    *from
                } else {
                    *to
                }
            }
            Trajectory::Ramp { from, to, duration } => {
                let s = if *duration > 0.0 {
                    (t / duration).clamp(0.0, 1.0)
                } else {
                    1.0
                };
                from + (to - from) * s
            }
            Trajectory::Sine {
                offset,
                amplitude,
                freq,
            } => offset + amplitude * (std::f64::consts::TAU * freq * t).sin(),
            Trajectory::Chirp {
                amplitude,
                f0,
                f1,
                duration,
            } => amplitude * chirp(*f0, *f1, *duration, t).0.sin(),
            Trajectory::Samples(s) => interpolate(s, t),
        }
    }

    /// Rate of change at time `t` (units per second): what a supervisor sends as the velocity
    /// feed-forward. A step's jump has none (it is not a motion the reference can lead).
    pub fn velocity(&self, t: f64) -> f64 {
        use std::f64::consts::TAU;
        match self {
            Trajectory::Step { .. } => 0.0,
            Trajectory::Ramp { from, to, duration } => {
                if *duration > 0.0 && (0.0..*duration).contains(&t) {
                    (to - from) / duration
                } else {
                    0.0
                }
            }
            Trajectory::Sine {
                amplitude, freq, ..
            } => amplitude * TAU * freq * (TAU * freq * t).cos(),
            Trajectory::Chirp {
                amplitude,
                f0,
                f1,
                duration,
            } => {
                let (phase, rate) = chirp(*f0, *f1, *duration, t);
                amplitude * rate * phase.cos()
            }
            Trajectory::Samples(s) => match s.iter().position(|&(ti, _)| ti > t) {
                Some(i) if i > 0 => {
                    let (t0, v0) = s[i - 1];
                    let (t1, v1) = s[i];
                    (v1 - v0) / (t1 - t0)
                }
                _ => 0.0,
            },
        }
    }

    /// Parses a CLI description: `step:TO[@T]`, `ramp:TO:SECONDS`, `sine:AMP:HZ`,
    /// `chirp:AMP:F0:F1:SECONDS`, `csv:FILE` (columns `time_s,value`).
    pub fn parse(spec: &str) -> Result<Trajectory> {
        let parts: Vec<&str> = spec.split(':').collect();
        let num = |i: usize, what: &str| -> Result<f64> {
            let s = parts
                .get(i)
                .with_context(|| format!("trajectory `{spec}`: missing {what}"))?;
            s.parse::<f64>()
                .with_context(|| format!("trajectory `{spec}`: {what} `{s}` is not a number"))
        };
        Ok(match parts.first().copied() {
            Some("step") => {
                let (to, at) = match parts.get(1).and_then(|s| s.split_once('@')) {
                    Some((v, t)) => (
                        v.parse().with_context(|| format!("trajectory `{spec}`: bad value"))?,
                        t.parse().with_context(|| format!("trajectory `{spec}`: bad time"))?,
                    ),
                    None => (num(1, "value")?, 0.0),
                };
                Trajectory::Step { from: 0.0, to, at }
            }
            Some("ramp") => Trajectory::Ramp { from: 0.0, to: num(1, "value")?, duration: num(2, "seconds")? },
            Some("sine") => Trajectory::Sine { offset: 0.0, amplitude: num(1, "amplitude")?, freq: num(2, "Hz")? },
            Some("chirp") => Trajectory::Chirp {
                amplitude: num(1, "amplitude")?,
                f0: num(2, "f0")?,
                f1: num(3, "f1")?,
                duration: num(4, "seconds")?,
            },
            Some("csv") => {
                let path = parts.get(1..).map(|p| p.join(":")).unwrap_or_default();
                Trajectory::from_csv(Path::new(&path))?
            }
            _ => bail!(
                "trajectory `{spec}`: expected step:TO[@T], ramp:TO:S, sine:AMP:HZ, chirp:AMP:F0:F1:S or csv:FILE"
            ),
        })
    }

    /// Reads `time_s,value` rows (header required; other columns ignored).
    pub fn from_csv(path: &Path) -> Result<Trajectory> {
        let mut rd = csv::Reader::from_path(path)
            .with_context(|| format!("cannot open trajectory file {}", path.display()))?;
        let headers = rd.headers()?.clone();
        let ti = headers
            .iter()
            .position(|h| h == "time_s")
            .with_context(|| format!("{}: no `time_s` column", path.display()))?;
        let vi = (0..headers.len())
            .find(|&i| i != ti)
            .with_context(|| format!("{}: no value column", path.display()))?;
        let mut out = Vec::new();
        let mut last_t = f64::NEG_INFINITY;
        for (k, rec) in rd.records().enumerate() {
            let rec = rec.with_context(|| format!("{}: line {}", path.display(), k + 2))?;
            let get = |i: usize| -> Result<f64> {
                let s = rec.get(i).unwrap_or("");
                s.trim().parse::<f64>().with_context(|| {
                    format!(
                        "{}:{}:{}: `{s}` is not a number",
                        path.display(),
                        k + 2,
                        i + 1
                    )
                })
            };
            let (t, v) = (get(ti)?, get(vi)?);
            if t <= last_t || t.is_nan() || !v.is_finite() {
                bail!(
                    "{}:{}: time must increase and values be finite",
                    path.display(),
                    k + 2
                );
            }
            last_t = t;
            out.push((t, v));
        }
        if out.is_empty() {
            bail!("{}: no samples", path.display());
        }
        Ok(Trajectory::Samples(out))
    }
}

/// A linear chirp's phase (rad) at `t`, held after `duration`, and its rate (rad/s; 0
/// outside the sweep).
fn chirp(f0: f64, f1: f64, duration: f64, t: f64) -> (f64, f64) {
    use std::f64::consts::TAU;
    let k = if duration > 0.0 {
        (f1 - f0) / duration
    } else {
        0.0
    };
    let tt = t.clamp(0.0, duration);
    let rate = if duration > 0.0 && (0.0..duration).contains(&t) {
        TAU * (f0 + k * t)
    } else {
        0.0
    };
    (TAU * (f0 * tt + 0.5 * k * tt * tt), rate)
}

fn interpolate(s: &[(f64, f64)], t: f64) -> f64 {
    match s.iter().position(|&(ti, _)| ti > t) {
        None => s.last().map(|p| p.1).unwrap_or(0.0),
        Some(0) => s[0].1,
        Some(i) => {
            let (t0, v0) = s[i - 1];
            let (t1, v1) = s[i];
            v0 + (v1 - v0) * (t - t0) / (t1 - t0)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The velocity is the derivative of the position, checked by a central difference.
    #[test]
    fn velocity_is_the_derivative() {
        for spec in ["ramp:1:2", "sine:0.3:0.7", "chirp:0.3:0.2:2:8"] {
            let tr = Trajectory::parse(spec).unwrap();
            for k in 1..70 {
                let t = k as f64 * 0.1 + 0.013;
                let h = 1e-6;
                let d = (tr.at(t + h) - tr.at(t - h)) / (2.0 * h);
                assert!(
                    (tr.velocity(t) - d).abs() < 1e-5,
                    "{spec} at {t}: {}",
                    tr.velocity(t)
                );
            }
        }
        let s = Trajectory::Samples(vec![(0.0, 0.0), (1.0, 0.5), (2.0, 0.0)]);
        assert_eq!(s.velocity(0.5), 0.5);
        assert_eq!(s.velocity(1.5), -0.5);
        assert_eq!(s.velocity(3.0), 0.0);
    }

    #[test]
    fn shapes() {
        assert_eq!(Trajectory::parse("step:2@0.5").unwrap().at(0.4), 0.0);
        assert_eq!(Trajectory::parse("step:2@0.5").unwrap().at(0.5), 2.0);
        assert!((Trajectory::parse("ramp:1:2").unwrap().at(1.0) - 0.5).abs() < 1e-12);
        assert!((Trajectory::parse("sine:1:1").unwrap().at(0.25) - 1.0).abs() < 1e-12);
        assert!(Trajectory::parse("chirp:1:1:10:5").unwrap().at(0.0).abs() < 1e-12);
        assert!(Trajectory::parse("wobble:1").is_err());
        let e = Trajectory::parse("sine:x:1").unwrap_err().to_string();
        assert!(e.contains("`x` is not a number"), "{e}");
        let s = Trajectory::Samples(vec![(0.0, 0.0), (1.0, 2.0)]);
        assert!((s.at(0.5) - 1.0).abs() < 1e-12);
        assert_eq!(s.at(5.0), 2.0);
    }
}
