//! # The model-vs-measurement workbench
//!
//! `compare` a model with a recording, `diagnose` which physical effect it is missing, `fit`
//! the effect in, and watch the error fall. Pipeline:
//!
//! ```text
//! data (CSV → SI) → diff (zero-phase smoothing differentiator) → residual (equation / output
//! error of a model) → metrics (fit %, RMS, noise floor, where the error lives, whiteness)
//! → diagnose (fingerprints from sim-plant, shape search, batch-means Wald test, Holm)
//! → refine (add effect, LS + LM refit, ±1σ) → report (SVG/PNG plots, one HTML file)
//! ```
//!
//! Dependency order (a module uses only those before it): `data`, `diff`, `stats`, `spectral`,
//! `model` → `fit` → `residual`, `metrics` → `diagnose` → `refine` → `closed_loop`, `report`,
//! `schema` (what every JSON object carries).
//!
//! Effect features come from `sim_plant::effects::fingerprint` only; nothing here knows what
//! Coulomb friction looks like.
//!
//! ## From Rust
//!
//! The CLI's `diagnose` then `fit --add` on a recording, as a library (a 2 kg mass with
//! 0.8 N of Coulomb friction under a PD loop, written to a CSV as a drive would log it):
//!
//! ```
//! use jointlab_workbench::data::{self, Columns};
//! use jointlab_workbench::diagnose::{diagnose, Options};
//! use jointlab_workbench::model::Model;
//! use jointlab_workbench::refine::{refit_all, score};
//! use jointlab_workbench::residual::Prepared;
//! # use std::fmt::Write as _;
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! # let (mut x, mut v, mut csv) = (0.0f64, 0.0f64, String::from("time_s,force_N,pos_m\n"));
//! # for k in 0..4000 {
//! #     let t = k as f64 * 1e-3;
//! #     let u = 400.0 * (0.05 * (4.4 * t).sin() + 0.02 * (11.9 * t).sin() - x) - 40.0 * v;
//! #     writeln!(csv, "{t},{u},{x}")?;
//! #     for _ in 0..10 {
//! #         v += 1e-4 * (u - 3.0 * v - 0.8 * v.signum()) / 2.0;
//! #         x += 1e-4 * v;
//! #     }
//! # }
//! # let path = std::env::temp_dir().join(format!("jointlab-doc-{}.csv", std::process::id()));
//! # std::fs::write(&path, csv)?;
//! // Columns by name; units from the suffixes (`_s`, `_N`, `_m`), else give gains.
//! let rec = data::load(&path, &Columns::new("force_N", "pos_m"))?;
//! // Differentiated, checked for range, ready for any model.
//! let p = Prepared::checked(&rec, None)?;
//!
//! let mut model = Model::baseline(); // rigid inertia + viscous friction
//! refit_all(&mut model, &p)?;
//! let d = diagnose(&model, &p, &Options::default());
//! let missing = d.verdict.add.expect("Coulomb friction is missing");
//! assert_eq!(missing.name(), "coulomb");
//!
//! let before = score(&model, &p).fit_percent;
//! model.add(missing, Default::default());
//! refit_all(&mut model, &p)?;
//! assert!(score(&model, &p).fit_percent > before);
//! for q in model.params() {
//!     println!("{} = {:.4} ± {:.4}", q.name, q.value, q.sigma.unwrap_or(f64::NAN));
//! }
//! # std::fs::remove_file(&path)?;
//! # Ok(())
//! # }
//! ```

pub mod closed_loop;
pub mod data;
pub mod dataset;
pub mod diagnose;
pub mod diff;
pub mod fit;
pub mod metrics;
pub mod model;
pub mod names;
pub mod refine;
pub mod report;
pub mod residual;
pub mod schema;
pub mod spectral;
pub mod stats;
pub mod units;
