//! Scenario files (`sim/*.toml`): the truth a simulation runs on. TOML, mm and degrees, unknown
//! keys rejected; parsed raw, then validated; every error names the file and the key.
//!
//! ```toml
//! description = "RV-M2 with backlash on J2"
//! seed = 7
//! rig = "../rigs/rv-m2.toml"                 # relative to this file
//!
//! [geometric]                                # explicit values override drawn ones
//! values = { theta0 = 0.05, a1 = -0.4 }      # mm / deg, by parameter name
//! random = { length_mm = 0.4, angle_deg = 0.05, distribution = "signs" }
//!
//! [[effects]]
//! kind = "backlash"                          # see registry::REGISTRY for every kind
//! joint = 2
//! lost_motion_deg = 0.02
//!
//! [measurement]
//! noise_mm = 0.0                             # Gaussian, per coordinate (1σ)
//! arm_repeatability_mm = 0.03                # pin scatter per move (1σ per coordinate)
//! table_accuracy_mm = 0.02                   # table_panel only; default: the rig's
//! quantise = true                            # table_panel only; default true
//! seconds_per_point = 5.0
//! ```

use super::effect::{Effect, ParseCtx};
use super::geometric::{self, RawGeometric};
use super::instrument::MeasurementSettings;
use super::registry::parse_effect;
use super::World;
use rigcal_core::kinematics::ErrorParams;
use rigcal_core::rig::{Instrument, Rig, RigError};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// What went wrong with a scenario file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ScenarioError {
    /// The file could not be read.
    #[error("cannot read scenario file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Not valid TOML, or an unknown, missing or mistyped key.
    #[error("scenario file {path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The parser's message, with line and column.
        message: String,
    },
    /// A value is out of range or inconsistent.
    #[error("scenario file {path}: `{key}`: {reason}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The key, as a TOML path.
        key: String,
        /// What is wrong and what is expected.
        reason: String,
    },
    /// The rig the scenario names could not be loaded.
    #[error("scenario file {path}: `rig`: {source}")]
    Rig {
        /// The scenario file.
        path: PathBuf,
        /// The rig's error.
        source: RigError,
    },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    #[serde(default)]
    description: String,
    seed: u64,
    rig: String,
    #[serde(default)]
    geometric: RawGeometric,
    #[serde(default)]
    effects: Vec<toml::Table>,
    #[serde(default)]
    measurement: RawMeasurement,
}

#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawMeasurement {
    noise_mm: Option<f64>,
    arm_repeatability_mm: Option<f64>,
    table_accuracy_mm: Option<f64>,
    quantise: Option<bool>,
    seconds_per_point: Option<f64>,
}

/// A validated scenario.
#[derive(Debug, Clone)]
pub struct Scenario {
    /// The scenario file.
    pub path: PathBuf,
    /// Free text.
    pub description: String,
    /// The seed of every random draw (the file's, or an override).
    pub seed: u64,
    /// The rig file, as resolved.
    pub rig_path: PathBuf,
    /// The rig.
    pub rig: Rig,
    /// The true geometric errors.
    pub truth: ErrorParams,
    /// The non-geometric effects, in file order.
    pub effects: Vec<Arc<dyn Effect>>,
    /// Random-error settings.
    pub measurement: MeasurementSettings,
}

impl Scenario {
    /// Reads and validates a scenario file; `seed` overrides the file's seed.
    pub fn load(path: &Path, seed: Option<u64>) -> Result<Scenario, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, path, seed)
    }

    /// Parses and validates scenario text; `path` names it in errors and anchors the rig path.
    pub fn parse(text: &str, path: &Path, seed: Option<u64>) -> Result<Scenario, ScenarioError> {
        let raw: RawScenario = toml::from_str(text).map_err(|e| ScenarioError::Parse {
            path: path.to_path_buf(),
            message: e.to_string().trim_end().to_string(),
        })?;
        let seed = seed.unwrap_or(raw.seed);
        let rig_path = path
            .parent()
            .unwrap_or_else(|| Path::new(""))
            .join(&raw.rig);
        let rig = Rig::load(&rig_path).map_err(|source| ScenarioError::Rig {
            path: path.to_path_buf(),
            source,
        })?;
        let truth = geometric::build(&raw.geometric, &rig, seed, path)?;
        let mut effects = Vec::new();
        for (k, table) in raw.effects.iter().enumerate() {
            let key = format!("effects[{k}]");
            let ctx = ParseCtx {
                path,
                key: &key,
                chain: &rig.chain,
                truth: &truth,
                instrument: &rig.instrument,
                seed,
                index: k,
            };
            effects.push(parse_effect(&ctx, table)?);
        }
        let measurement = settings(&raw.measurement, &rig.instrument, path)?;
        Ok(Scenario {
            path: path.to_path_buf(),
            description: raw.description,
            seed,
            rig_path,
            rig,
            truth,
            effects,
            measurement,
        })
    }

    /// The truth world of this scenario, with a fresh motion history.
    pub fn world(&self) -> World {
        World::with_effects(
            self.rig.chain.clone(),
            self.truth.clone(),
            self.rig.instrument.clone(),
            self.effects.clone(),
            self.measurement,
            self.seed,
        )
    }
}

fn settings(
    m: &RawMeasurement,
    instrument: &Instrument,
    path: &Path,
) -> Result<MeasurementSettings, ScenarioError> {
    let invalid = |key: &str, reason: &str| ScenarioError::Invalid {
        path: path.to_path_buf(),
        key: format!("measurement.{key}"),
        reason: reason.to_string(),
    };
    let non_negative = |key: &str, v: Option<f64>| -> Result<f64, ScenarioError> {
        match v {
            None => Ok(0.0),
            Some(v) if v.is_finite() && v >= 0.0 => Ok(v),
            Some(_) => Err(invalid(key, "must be zero or positive")),
        }
    };
    let noise_mm = non_negative("noise_mm", m.noise_mm)?;
    let arm_repeatability_mm = non_negative("arm_repeatability_mm", m.arm_repeatability_mm)?;
    let seconds_per_point = match m.seconds_per_point {
        None => 5.0,
        Some(v) if v.is_finite() && v > 0.0 => v,
        Some(_) => return Err(invalid("seconds_per_point", "must be positive")),
    };
    let (table_accuracy_mm, quantise) = match instrument {
        Instrument::TablePanel(tp) => (
            match m.table_accuracy_mm {
                None => tp.accuracy_mm,
                some => non_negative("table_accuracy_mm", some)?,
            },
            m.quantise.unwrap_or(true),
        ),
        _ => {
            if m.table_accuracy_mm.is_some() {
                return Err(invalid(
                    "table_accuracy_mm",
                    "only for a rig with instrument kind = \"table_panel\"",
                ));
            }
            if m.quantise.is_some() {
                return Err(invalid(
                    "quantise",
                    "only for a rig with instrument kind = \"table_panel\"",
                ));
            }
            (0.0, false)
        }
    };
    Ok(MeasurementSettings {
        noise_mm,
        arm_repeatability_mm,
        table_accuracy_mm,
        quantise,
        seconds_per_point,
    })
}
