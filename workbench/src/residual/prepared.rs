//! A recording made ready for the residuals: position differentiated by the smoothing
//! differentiator, the filter's edge samples dropped, and the noise the encoder and the input
//! leave in the regressors estimated (quantisation step, position noise, the probe of the
//! differentiator's response to it).

use sim_plant::effects::{Intersample, Trajectory};

use super::super::data::{DataError, Recording};
use super::super::diff;
use super::super::fit;

/// A recording after differentiation, with the filter's edge samples dropped.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// Time.
    pub time: Vec<f64>,
    /// Measured input (SI force/torque), low-passed by the differentiator's zero-phase filter
    /// ("parallel filtering", as in IDIM): both sides of the inverse-dynamics equation then
    /// see the same bandwidth. Without it the input's content above the cut-off — sensor noise,
    /// but also real torque the feedback puts there (PD on a quantised encoder) — has no
    /// counterpart in the smoothed acceleration and ends up as structured residual that
    /// broadband fingerprints (compliance, delay) happily "explain".
    pub input: Vec<f64>,
    /// Measured input as recorded (SI), the whole record (edges included: fingerprints filter
    /// it with its history, see `sim_plant::effects::Trajectory::raw_input`).
    pub raw_input: Vec<f64>,
    /// Index in `raw_input` of the first kept sample.
    pub raw_offset: usize,
    /// White-noise RMS of the raw input (second-difference estimate) times the filter's noise
    /// gain: the RMS a perfect model would leave in the equation-error residual.
    pub noise_floor: f64,
    /// Measured (raw) position.
    pub raw_position: Vec<f64>,
    /// Samples in a run of equal recorded positions long enough that a joint moving at
    /// [`Prepared::stick_velocity`] would have changed the count: the encoder's own evidence
    /// of rest, which the smoothed velocity blurs (see `residual::design::at_rest`). Empty
    /// for a probe.
    pub held: Vec<bool>,
    /// Acceleration over the whole record (edges included, indexed as `raw_input`): dynamic
    /// fingerprints of the motion filter it from the record's start (see
    /// `sim_plant::effects::Trajectory::raw_acceleration`).
    pub raw_acceleration: Vec<f64>,
    /// Smoothed position.
    pub position: Vec<f64>,
    /// Velocity.
    pub velocity: Vec<f64>,
    /// Acceleration.
    pub acceleration: Vec<f64>,
    /// Sample period.
    pub dt: f64,
    /// Differentiator cut-off used (Hz).
    pub cutoff_hz: f64,
    /// Motion-based reconstruction of the input (see [`Prepared::trajectory`]).
    pub input_instrument: Vec<f64>,
    /// Speed below which the joint may be stuck: the peak speed the differentiator shows for
    /// one step of the position's quantisation (the smallest nonzero position change in the
    /// record; about 0 for unquantised data). A joint at rest does not show white
    /// quantisation noise but whole counts flickering as its spring and bristles take up the
    /// holding torque: each flicker is a one-count step, and 3σ of white quantisation noise
    /// (about 40 % of this) left most of a held phase outside the band, where the clamp to the
    /// breakaway level then mispredicted it. See [`super::static_friction`].
    pub stick_velocity: f64,
    /// The position's quantisation step (the smallest nonzero change in the record; about 0
    /// for unquantised data).
    pub position_step: f64,
    /// Variance of the white noise on the recorded position (encoder quantisation and sensor
    /// noise, see `position_noise_variance`). Through the differentiator it reaches every
    /// regressor built linearly from the motion — the acceleration, the velocity, the
    /// compliance motion form's resonant filter of the acceleration — and least squares with
    /// noisy regressors is biased (errors-in-variables: at a 40 Hz cut-off a 16-bit encoder's
    /// acceleration noise is a few percent of a joint's acceleration, and the inertia comes
    /// out that much low); [`super::refit`] takes the noise's covariance off the Gram matrix (see
    /// [`super::noise_gram`]).
    pub position_noise_var: f64,
    /// [`Prepared::position_noise_var`] through the differentiator's acceleration gain: the
    /// inertia column's own noise variance, all a model without compliance compensates (see
    /// [`super::refit`]).
    pub acceleration_noise_var: f64,
    /// Smoothed load-side position (an output encoder, `Recording::load_output`), through the
    /// same zero-phase filter as [`Prepared::position`] and trimmed to the same window; empty
    /// when the recording has none. The deflection δ = position − load_position is then
    /// measured, not inferred (see `sim_plant::effects::backlash::fingerprint`).
    pub load_position: Vec<f64>,
    /// What the position measures (from its unit: metres are a linear axis), so a model
    /// fitted here names its parameters' units as the data do.
    pub axis: sim_plant::units::Axis,
    /// The input's unit (`crate::data::input_unit`): the parameters' force unit.
    pub input_unit: String,
    /// Variance of the load encoder's noise in the load's acceleration (as
    /// [`Prepared::acceleration_noise_var`]; 0 without a load position).
    pub load_acceleration_noise_var: f64,
    /// How the recorded input behaved between samples (`Recording::columns`): [`Prepared::input`]
    /// is the input mapped to the position's sample instants by it, and input-built columns
    /// are mapped the same way (`Trajectory::input_lowpass`).
    pub intersample: Intersample,
    /// Turns of the position per turn of the joint's output (`Columns::gear_ratio`).
    pub gear_ratio: f64,
    /// The same preparation applied to a unit impulse of the raw *input* (zero position), on
    /// a record of the same length and window: its `input` is the residual's response to one
    /// sample of input noise, and a column built from the recorded input (compliance's
    /// command form) gives that column's response — together what the input's noise shares
    /// between such a column and the residual (see `diagnose`). `None` as for `noise_probe`.
    pub input_probe: Option<Box<Prepared>>,
    /// Variance of the white noise on the raw input (its second-difference estimate; a
    /// dithered command reads high).
    pub input_noise_var: f64,
    /// The same preparation applied to a unit impulse of the raw position (zero input), on a
    /// record of the same length and window: the columns it gives are the impulse responses
    /// of the motion-linear regressors to the position's noise (see [`super::noise_gram`]). `None`
    /// on the probe itself and on records too short to hold the differentiator's response.
    pub noise_probe: Option<Box<Prepared>>,
}

/// A differentiator cut-off the record cannot carry ([`Prepared::checked`]).
#[derive(Debug, thiserror::Error)]
#[error("{}", self.message())]
pub struct CutoffError {
    /// The record's file (or [`crate::data::ARRAYS`]).
    pub file: std::path::PathBuf,
    /// The cut-off asked for (Hz).
    pub cutoff: f64,
    /// The record's Nyquist frequency (Hz).
    pub nyquist: f64,
    /// When the caller did not choose the cut-off: the estimation record whose default band
    /// this (validation) record was to be read in ([`Prepared::checked_in_band`]).
    pub default_of: Option<std::path::PathBuf>,
}

impl CutoffError {
    fn message(&self) -> String {
        let (file, nyquist) = (self.file.display(), self.nyquist);
        match &self.default_of {
            None => format!(
                "--cutoff {}: the differentiator's cut-off must be above 0 and below the \
                 Nyquist frequency of {file} ({nyquist:.4} Hz)",
                self.cutoff
            ),
            Some(est) => format!(
                "{file}: its Nyquist frequency ({nyquist:.4} Hz) is below the band the \
                 estimation record {} is read in by default ({:.4} Hz, set by its encoder and \
                 sample rate), and a validation record is read in the estimation record's \
                 band: pass a cut-off below {nyquist:.4} Hz (--cutoff, or cutoff= in Python)",
                est.display(),
                self.cutoff
            ),
        }
    }
}

/// Why [`Prepared::checked`] refused a record. Two kinds, kept apart because a caller reports
/// them differently: the cut-off is the caller's choice (the CLI exits 2, a usage error), an
/// out-of-range signal is in the data (exit 1).
#[derive(Debug, thiserror::Error)]
pub enum PrepareError {
    /// The cut-off asked for does not suit this record.
    #[error(transparent)]
    Cutoff(CutoffError),
    /// A differentiated or filtered signal is out of range ([`DataError::Derived`]).
    #[error(transparent)]
    Data(DataError),
}

impl Prepared {
    /// RMS the position's noise (encoder quantisation and sensor noise) leaves in an
    /// equation-error residual through a model of inertia `inertia`: `J·σ_a`, the inertia
    /// times the acceleration's share of that noise after the differentiator. The velocity's
    /// share (through the viscous friction) is left out: the differentiator's velocity gain
    /// is ~ω_c below its acceleration gain.
    pub fn encoder_floor(&self, inertia: f64) -> f64 {
        inertia.abs() * self.acceleration_noise_var.max(0.0).sqrt()
    }

    /// The input's noise in a residual of sum of squares `rss`, for practical-significance
    /// thresholds: [`Prepared::noise_floor`], but no more than the residual's own RMS. The
    /// floor is estimated from the input alone (its second difference), and a command with
    /// a white dither, PRBS steps or a PD's kicks at encoder counts reads several times too
    /// high there (up to 40× on the hidden trials): that content moves the joint and cancels
    /// in the equation error. A residual is at least its noise, so it bounds the floor.
    pub fn practical_floor(&self, rss: f64) -> f64 {
        let n = self.len().max(1) as f64;
        self.noise_floor.min((rss.max(0.0) / n).sqrt())
    }

    /// Noise floor of an equation-error residual of a model of inertia `inertia`: the input's
    /// own noise ([`Prepared::noise_floor`]) and [`Prepared::encoder_floor`], independent and
    /// so added in power. With a coarse encoder and a sharp differentiator the second
    /// dominates — a rigid joint on a 2¹⁶-count encoder, 0.2 rad/s and a 40 Hz cut-off leaves
    /// 6× the input noise — and a floor of the input noise alone would read it as a missing
    /// effect.
    pub fn equation_floor(&self, inertia: f64) -> f64 {
        self.noise_floor.hypot(self.encoder_floor(inertia))
    }

    /// [`Prepared::new`] for a fit, checked both ways a record can fail to prepare: a
    /// caller's cut-off the differentiator cannot use (not above 0, not below the record's
    /// Nyquist frequency), and differentiated or filtered signals out of range for a fit (not
    /// finite, or a sum of squares that overflows) — finite cells can still differentiate to
    /// infinity (a jump of 1e308 over one sample), and a fit on them gives NaN where it
    /// should give an error naming where. The CLI's `--cutoff` and the Python package's
    /// `cutoff` both come through here.
    pub fn checked(rec: &Recording, cutoff_hz: Option<f64>) -> Result<Self, PrepareError> {
        if let Some(cutoff) = cutoff_hz {
            let nyquist = 0.5 / rec.dt;
            if !(cutoff.is_finite() && cutoff > 0.0 && cutoff < nyquist) {
                return Err(PrepareError::Cutoff(CutoffError {
                    file: rec.path.clone(),
                    cutoff,
                    nyquist,
                    default_of: None,
                }));
            }
        }
        let p = Self::new(rec, cutoff_hz);
        // Each signal with the clock it is indexed by (the raw ones span the whole record).
        for (signal, x, time) in [
            ("input after the intersample filter", &p.input, &p.time),
            ("position after smoothing", &p.position, &p.time),
            ("velocity after differentiation", &p.velocity, &p.time),
            (
                "acceleration after differentiation",
                &p.acceleration,
                &p.time,
            ),
            (
                "acceleration at the record's edges",
                &p.raw_acceleration,
                &rec.time,
            ),
            ("load position after smoothing", &p.load_position, &p.time),
            (
                "input reconstructed from the motion",
                &p.input_instrument,
                &p.time,
            ),
        ] {
            if let Some((k, why)) = super::super::data::out_of_range(x) {
                return Err(PrepareError::Data(DataError::Derived {
                    file: rec.path.clone(),
                    signal,
                    time: time.get(k).copied().unwrap_or(f64::NAN),
                    value: x[k],
                    why,
                }));
            }
        }
        for (statistic, value) in [
            ("input noise floor", p.noise_floor),
            ("input noise variance", p.input_noise_var),
            ("position noise variance", p.position_noise_var),
            ("acceleration noise variance", p.acceleration_noise_var),
            (
                "load acceleration noise variance",
                p.load_acceleration_noise_var,
            ),
            ("stick velocity", p.stick_velocity),
        ] {
            if !value.is_finite() {
                return Err(PrepareError::Data(DataError::Noise {
                    file: rec.path.clone(),
                    statistic,
                    value,
                }));
            }
        }
        Ok(p)
    }

    /// [`Prepared::checked`] of a validation record in the estimation record's band `band`:
    /// both are read alike. `default_of` names the estimation record when the band is its
    /// default rather than the caller's choice, so a band the validation record cannot carry
    /// (sampled slower) is reported as that, with the cut-off to pass.
    pub fn checked_in_band(
        rec: &Recording,
        band: f64,
        default_of: Option<&std::path::Path>,
    ) -> Result<Self, PrepareError> {
        Self::checked(rec, Some(band)).map_err(|e| match e {
            PrepareError::Cutoff(c) => PrepareError::Cutoff(CutoffError {
                default_of: default_of.map(std::path::Path::to_path_buf),
                ..c
            }),
            e => e,
        })
    }

    /// Differentiate a recording (cut-off `cutoff_hz`; by default the band where the
    /// record's own encoder noise reaches the acceleration at a set level, see
    /// [`diff::default_cutoff`]).
    /// Does not check the result's range: see [`Prepared::checked`].
    pub fn new(rec: &Recording, cutoff_hz: Option<f64>) -> Self {
        // Noise is measured on the samples as recorded: a resampled record's interpolation
        // averages neighbours and would hide the encoder's step and part of the noise (on
        // the XL330 logs the step would read 40–500× finer than one count).
        let (raw_input, raw_output, raw_load) = match &rec.recorded {
            Some(r) => (&r.input, &r.output, r.load_output.as_ref()),
            None => (&rec.input, &rec.output, rec.load_output.as_ref()),
        };
        let position_noise_var = position_noise_variance(raw_output);
        let axis = sim_plant::units::Axis::of_position_unit(&rec.units.1);
        let fc = cutoff_hz.unwrap_or_else(|| band(rec.dt, axis, position_noise_var));
        let d = diff::differentiate(&rec.output, rec.dt, fc);
        let e = diff::edge_samples(rec.dt, fc).min(rec.len() / 4);
        let r = e..rec.len() - e;
        // The input at the position's sample instants (a drive's hold lags it half a sample),
        // then the parallel filter.
        let intersample = rec.columns.intersample;
        let uf = intersample.band_limited(&rec.input, fc, 1.0 / rec.dt);
        let input_sigma = super::super::stats::noise_floor(raw_input);
        let floor = input_sigma * diff::noise_gain(fc, 1.0 / rec.dt);
        let acc_gain2 = diff::acceleration_noise_gain(fc, rec.dt).powi(2);
        let acceleration_noise_var = position_noise_var * acc_gain2;
        // A load column of another length is not the same record's: ignored rather than
        // misaligned (`data::load` reads both from one file, so only a hand-built recording
        // can get here).
        let load = rec
            .load_output
            .as_ref()
            .filter(|x| x.len() == rec.output.len());
        let (load_position, load_acceleration_noise_var) = match load {
            Some(x) => (
                diff::filtfilt(x, fc, 1.0 / rec.dt)[r.clone()].to_vec(),
                position_noise_variance(raw_load.unwrap_or(x)) * acc_gain2,
            ),
            None => (Vec::new(), 0.0),
        };
        let step_peak = diff::step_velocity_peak(fc, rec.dt);
        let position_step = quantisation_step(raw_output);
        let mut p = Prepared {
            time: rec.time[r.clone()].to_vec(),
            input: uf[r.clone()].to_vec(),
            raw_input: rec.input.clone(),
            raw_offset: e,
            noise_floor: floor,
            raw_position: rec.output[r.clone()].to_vec(),
            held: Vec::new(),
            position: d.position[r.clone()].to_vec(),
            velocity: d.velocity[r.clone()].to_vec(),
            acceleration: d.acceleration[r].to_vec(),
            raw_acceleration: d.acceleration.clone(),
            dt: rec.dt,
            cutoff_hz: fc,
            input_instrument: Vec::new(),
            stick_velocity: position_step * step_peak,
            position_step,
            position_noise_var,
            acceleration_noise_var,
            load_position,
            axis,
            input_unit: crate::data::input_unit(&rec.columns),
            load_acceleration_noise_var,
            intersample,
            gear_ratio: rec.columns.gear_ratio,
            input_probe: None,
            input_noise_var: input_sigma * input_sigma,
            noise_probe: None,
        };
        p.held = held(&p.raw_position, rest_run(step_peak, rec.dt));
        p.input_instrument = instrument(&p);
        p.noise_probe = noise_probe(rec.len(), e, rec.dt, fc, Impulse::Position).map(Box::new);
        p.input_probe =
            noise_probe(rec.len(), e, rec.dt, fc, Impulse::Input(intersample)).map(Box::new);
        p
    }

    /// The cut-off [`Prepared::new`] uses for `rec` when none is given: see
    /// [`diff::default_cutoff`].
    pub fn default_cutoff(rec: &Recording) -> f64 {
        let raw_output = rec.recorded.as_ref().map_or(&rec.output, |r| &r.output);
        let axis = sim_plant::units::Axis::of_position_unit(&rec.units.1);
        band(rec.dt, axis, position_noise_variance(raw_output))
    }

    /// The same record read with another intersample behaviour: the input (and the
    /// instrument built on it) mapped to the position's instants that way instead.
    pub fn with_intersample(&self, intersample: Intersample) -> Prepared {
        let window = self.raw_offset..self.raw_offset + self.len();
        let uf = intersample.band_limited(&self.raw_input, self.cutoff_hz, 1.0 / self.dt);
        let mut p = Prepared {
            input: uf[window].to_vec(),
            intersample,
            ..self.clone()
        };
        p.input_instrument = instrument(&p);
        let edge = self.raw_offset;
        p.input_probe = noise_probe(
            self.raw_input.len(),
            edge,
            self.dt,
            self.cutoff_hz,
            Impulse::Input(intersample),
        )
        .map(Box::new);
        p
    }

    /// Borrow as a library trajectory.
    ///
    /// Its `input` is the **instrument**, not the measured input: fingerprints built from the
    /// input (dead zone, delay, quantisation) would otherwise contain the input's measurement
    /// noise, which is also in the target of the regression, and "explain" the residual's own
    /// noise (errors-in-variables). The instrument is the least-squares reconstruction of the
    /// input from motion alone (`a`, `v`, `sign v`, 1), so it is independent of input noise
    /// while following the input's shape.
    pub fn trajectory(&self) -> Trajectory<'_> {
        Trajectory {
            dt: self.dt,
            input: &self.input_instrument,
            position: &self.position,
            velocity: &self.velocity,
            acceleration: &self.acceleration,
            raw_input: &self.raw_input,
            raw_offset: self.raw_offset,
            raw_acceleration: &self.raw_acceleration,
            lowpass_hz: self.cutoff_hz,
            load_position: &self.load_position,
            intersample: self.intersample,
            gear_ratio: self.gear_ratio,
            position_step: self.position_step,
            rest_velocity: self.stick_velocity,
        }
    }

    /// Samples.
    pub fn len(&self) -> usize {
        self.time.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.time.is_empty()
    }
}

/// The default band of a record at period `dt` on `axis` whose position noise variance is
/// `noise_var`: scaled by the encoder's noise on a rotary axis (in rad); a linear axis's
/// counts have no revolution to compare with the reference encoder.
fn band(dt: f64, axis: sim_plant::units::Axis, noise_var: f64) -> f64 {
    let rotary = (axis == sim_plant::units::Axis::Rotary).then(|| noise_var.sqrt());
    diff::default_cutoff(dt, rotary)
}

/// Samples between the window's start and the probe's impulse: the zero-phase
/// differentiator's response reaches about 4/fc either side of it (100 samples at 40 Hz and
/// 1 kHz), so the whole response lies inside the window, and the rest of the window holds the
/// ringing tail of a resonant column.
const PROBE_LEAD: usize = 256;

/// Longest window of the probe, in samples after its impulse: the differentiator's response
/// is ~100 samples long, and a lightly damped compliance mode rings for 1/(ζ₂ω₂) — at
/// ζ₂ω₂ = 0.3 s⁻¹ the energy left after 2¹⁴ samples at 1 kHz is e⁻¹⁰. Longer records do not
/// need a longer probe, and a probe as long as a 10⁵-sample record was a full extra
/// differentiation in every [`Prepared::new`].
const PROBE_SPAN: usize = 1 << 14;

/// Which raw signal a probe's impulse is in.
#[derive(Debug, Clone, Copy)]
enum Impulse {
    /// The position (the input zero).
    Position,
    /// The input, read with this intersample behaviour (the position zero).
    Input(Intersample),
}

/// The preparation of a unit impulse of the raw position or input at [`PROBE_LEAD`] samples
/// into the window (see [`Prepared::noise_probe`], [`Prepared::input_probe`]), on a record as
/// long as the data's but at most [`PROBE_SPAN`] samples past the impulse; `None` when the
/// window is shorter than twice [`PROBE_LEAD`].
fn noise_probe(len: usize, edge: usize, dt: f64, fc: f64, what: Impulse) -> Option<Prepared> {
    let n = len.checked_sub(2 * edge)?;
    if n < 2 * PROBE_LEAD || dt <= 0.0 {
        return None;
    }
    let n = n.min(PROBE_LEAD + PROBE_SPAN);
    let len = n + 2 * edge;
    let mut impulse = vec![0.0; len];
    impulse[edge + PROBE_LEAD] = 1.0;
    let zero = vec![0.0; len];
    let (x, u, intersample) = match what {
        Impulse::Position => (impulse, zero, Intersample::Bl),
        Impulse::Input(is) => (zero, impulse, is),
    };
    let d = diff::differentiate(&x, dt, fc);
    let uf = intersample.band_limited(&u, fc, 1.0 / dt);
    let r = edge..len - edge;
    Some(Prepared {
        time: (0..n).map(|k| k as f64 * dt).collect(),
        input: uf[r.clone()].to_vec(),
        raw_input: u,
        raw_offset: edge,
        noise_floor: 0.0,
        raw_position: x[r.clone()].to_vec(),
        held: Vec::new(),
        position: d.position[r.clone()].to_vec(),
        velocity: d.velocity[r.clone()].to_vec(),
        acceleration: d.acceleration[r].to_vec(),
        raw_acceleration: d.acceleration,
        dt,
        cutoff_hz: fc,
        input_instrument: vec![0.0; n],
        stick_velocity: 0.0,
        position_step: 0.0,
        position_noise_var: 0.0,
        acceleration_noise_var: 0.0,
        load_position: Vec::new(),
        axis: sim_plant::units::Axis::Rotary,
        input_unit: String::new(),
        load_acceleration_noise_var: 0.0,
        intersample,
        gear_ratio: 1.0,
        input_probe: None,
        input_noise_var: 0.0,
        noise_probe: None,
    })
}

/// The shortest run of equal position samples that means rest by the encoder alone: a joint
/// moving at [`Prepared::stick_velocity`] (one count's peak speed through the differentiator,
/// `step_peak` counts per second) moves a count within `run − 1` sample periods. So a run this
/// long says what the speed threshold says, without the differentiator's smear. Never, for a
/// nonsensical rate.
fn rest_run(step_peak: f64, dt: f64) -> usize {
    let periods = (1.0 / (step_peak * dt)).ceil();
    if periods.is_finite() && periods >= 0.0 {
        (periods as usize).saturating_add(1)
    } else {
        usize::MAX
    }
}

/// Samples in runs of at least `min_run` equal values.
fn held(x: &[f64], min_run: usize) -> Vec<bool> {
    let mut out = vec![false; x.len()];
    let mut start = 0;
    for k in 1..=x.len() {
        if k == x.len() || x[k] != x[start] {
            if k - start >= min_run {
                out[start..k].fill(true);
            }
            start = k;
        }
    }
    out
}

/// Smallest nonzero change between successive samples of a position record (its encoder
/// step when quantised); 0 for fewer than two samples.
fn quantisation_step(x: &[f64]) -> f64 {
    let range = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    x.windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|&d| d > 1e-12 * range)
        .fold(f64::INFINITY, f64::min)
        .min(range)
}

/// Variance of the white noise on a position record (encoder quantisation and sensor noise),
/// from its fourth difference: white noise of variance σ² gives Δ⁴ a variance of 70σ², while a
/// joint's motion, smooth at the sample rate, contributes `x⁗·dt⁴` — nothing. Estimated from
/// the data rather than from the quantisation step (step²/12) because a dithered or noisy
/// encoder is noisier than its step says, and an encoder held at rest is quieter.
fn position_noise_variance(x: &[f64]) -> f64 {
    if x.len() < 5 {
        return 0.0;
    }
    let ss: f64 = x
        .windows(5)
        .map(|w| {
            let d = w[4] - 4.0 * w[3] + 6.0 * w[2] - 4.0 * w[1] + w[0];
            d * d
        })
        .sum();
    ss / (70.0 * (x.len() - 4) as f64)
}

/// Motion-based reconstruction of the input: LS fit of the input on (a, v, sign v, 1).
fn instrument(p: &Prepared) -> Vec<f64> {
    let n = p.len();
    let cols = vec![
        p.acceleration.clone(),
        p.velocity.clone(),
        p.velocity.iter().map(|v| v.signum()).collect(),
        vec![1.0; n],
    ];
    match fit::least_squares(&cols, &p.input) {
        Ok(f) => p
            .input
            .iter()
            .zip(&f.residual)
            .map(|(u, e)| u - e)
            .collect(),
        Err(_) => p.input.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs of equal samples count as held from the given length on, whole; a run as long as
    /// a joint at the stick velocity takes to cross a count is that length.
    #[test]
    fn held_runs() {
        let x = [0.0, 1.0, 1.0, 1.0, 2.0, 2.0, 3.0, 3.0, 3.0];
        let h = held(&x, 3);
        assert_eq!(h, [false, true, true, true, false, false, true, true, true]);
        assert!(held(&x, 1).iter().all(|&b| b));
        assert!(held(&[], 2).is_empty());
        // 1/(peak·dt) = 12.5 periods: 13 periods, 14 samples.
        assert_eq!(rest_run(80.0, 1e-3), 14);
        assert_eq!(rest_run(f64::NAN, 1e-3), usize::MAX);
        assert_eq!(rest_run(0.0, 1e-3), usize::MAX);
    }

    /// The probe stops [`PROBE_SPAN`] samples after its impulse on a long record, and its
    /// acceleration response still carries the differentiator's whole noise gain.
    #[test]
    fn noise_probe_is_capped_and_complete() {
        let (n, dt, fc) = (100_000, 1e-3, 40.0);
        let edge = diff::edge_samples(dt, fc);
        let probe = noise_probe(n, edge, dt, fc, Impulse::Position).expect("probe");
        assert_eq!(probe.len(), PROBE_LEAD + PROBE_SPAN);
        assert_eq!(probe.raw_acceleration.len(), probe.len() + 2 * edge);
        let e: f64 = probe.acceleration.iter().map(|a| a * a).sum();
        let ga = diff::acceleration_noise_gain(fc, dt).powi(2);
        assert!((e / ga - 1.0).abs() < 1e-6, "{e} vs {ga}");
        // A window shorter than twice the lead holds no probe.
        assert!(noise_probe(2 * edge + PROBE_LEAD, edge, dt, fc, Impulse::Position).is_none());
    }

    /// The fourth-difference estimate sees the noise on a position, not the motion under it.
    #[test]
    fn position_noise_variance_ignores_smooth_motion() {
        let sigma: f64 = 1e-4;
        let x: Vec<f64> = (0..20_000)
            .map(|i| {
                let u = crate::stats::tests_support::unit_uniform(i as u64);
                (i as f64 * 2e-3).sin() * 2.0 + (u - 0.5) * 12f64.sqrt() * sigma
            })
            .collect();
        let v = position_noise_variance(&x);
        assert!((v / (sigma * sigma) - 1.0).abs() < 0.1, "{v:e}");
        let smooth: Vec<f64> = (0..20_000).map(|i| (i as f64 * 2e-3).sin()).collect();
        assert!(position_noise_variance(&smooth) < 1e-6 * sigma * sigma);
    }

    /// A load position goes through the same filter and window as the motor's (so a load
    /// that follows the motor exactly gives δ ≡ 0), its noise is estimated like the motor's,
    /// and a load column of another length is ignored rather than misaligned.
    #[test]
    fn load_position_is_processed_like_the_motor_position() {
        let n = 3000;
        let dt = 1e-3;
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * dt * 3.0).sin()).collect();
        let rec = |load: Option<Vec<f64>>| Recording {
            path: "synthetic".into(),
            time: (0..n).map(|i| i as f64 * dt).collect(),
            input: x.iter().map(|v| 0.1 * v).collect(),
            output: x.clone(),
            load_output: load,
            dt,
            units: ("N·m".into(), "rad".into()),
            columns: crate::data::Columns::new("u_Nm", "q_rad"),
            resampled: None,
            recorded: None,
        };
        let p = Prepared::new(&rec(Some(x.clone())), Some(40.0));
        assert_eq!(p.load_position.len(), p.position.len());
        assert!(p.load_position.iter().zip(&p.position).all(|(a, b)| a == b));
        assert_eq!(p.trajectory().load(), Some(&p.load_position[..]));
        assert!((p.load_acceleration_noise_var - p.acceleration_noise_var).abs() < 1e-12);
        let short = Prepared::new(&rec(Some(x[..n - 1].to_vec())), Some(40.0));
        assert!(short.load_position.is_empty() && short.trajectory().load().is_none());
        assert!(Prepared::new(&rec(None), Some(40.0))
            .load_position
            .is_empty());
    }

    /// A resampled record's noise statistics are those of its samples as recorded: the same
    /// quantised position and noisy input, once on a uniform clock and once on a jittered
    /// one spanning the same time, give the same encoder step (stick band), position noise
    /// and input noise floor. Measured on the interpolated columns instead, the step reads
    /// 40–500× finer than one count on the XL330 logs and the floors 30 % low.
    #[test]
    fn resampled_record_keeps_the_recorded_noise() {
        let dir = std::env::temp_dir().join(format!("jointlab-rsnoise-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let n = 2000;
        let step = 2.0 * std::f64::consts::PI / 4096.0;
        let write = |name: &str, jitter: f64| {
            let mut csv = String::from("time_s,u_V,q_rad\n");
            for k in 0..n {
                // Jitter inside the record only: both clocks span the same time.
                let wobble = if k == 0 || k == n - 1 {
                    0.0
                } else {
                    [1.0, -1.0, 0.5, -0.5][k % 4]
                };
                let t = k as f64 * 5e-3 + jitter * wobble * 5e-3;
                let clean = 0.8 * (k as f64 * 5e-3 * 2.0).sin();
                let noise = crate::stats::tests_support::unit_uniform(k as u64) - 0.5;
                let q = (clean / step).round() * step;
                csv += &format!("{t},{},{q}\n", clean + 0.05 * noise);
            }
            let path = dir.join(name);
            std::fs::write(&path, csv).expect("write csv");
            path
        };
        let cols = crate::data::Columns::new("u_V", "q_rad");
        let load = |path: std::path::PathBuf| crate::data::load(&path, &cols).expect("load");
        let uniform = load(write("uniform.csv", 0.0));
        let jittered = load(write("jittered.csv", 0.15));
        std::fs::remove_dir_all(&dir).ok();
        assert!(uniform.resampled.is_none() && jittered.resampled.is_some());
        assert!((uniform.dt - jittered.dt).abs() < 1e-15);
        let (a, b) = (
            Prepared::new(&uniform, None),
            Prepared::new(&jittered, None),
        );
        let same = |x: f64, y: f64, what: &str| {
            assert!((x - y).abs() <= 1e-9 * x.abs(), "{what}: {x:e} vs {y:e}");
        };
        same(a.stick_velocity, b.stick_velocity, "stick velocity");
        same(a.position_noise_var, b.position_noise_var, "position noise");
        same(a.noise_floor, b.noise_floor, "input noise floor");
        assert!(a.stick_velocity > 0.0 && a.noise_floor > 0.0);
    }
}
