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
//! `model` → `fit` → `residual`, `metrics` → `diagnose` → `refine` → `closed_loop`, `report`.
//!
//! Effect features come from `sim_plant::effects::fingerprint` only; nothing here knows what
//! Coulomb friction looks like.

pub mod closed_loop;
pub mod data;
pub mod diagnose;
pub mod diff;
pub mod fit;
pub mod metrics;
pub mod model;
pub mod refine;
pub mod report;
pub mod residual;
pub mod spectral;
pub mod stats;
pub mod units;
