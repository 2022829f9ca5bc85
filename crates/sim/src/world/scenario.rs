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
//! kind = "backlash"                          # see rigcal_model::effects::EffectKind
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

use super::geometric::{self, RawGeometric};
use super::instrument::MeasurementSettings;
use super::World;
use rigcal_core::kinematics::ErrorParams;
use rigcal_core::rig::{Instrument, Rig, RigError};
use rigcal_model::effects::{parse_effect, Effect, EntryError, ParseCtx};
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
        let rig =
            rigcal_devices::config::load_rig(&rig_path).map_err(|source| ScenarioError::Rig {
                path: path.to_path_buf(),
                source,
            })?;
        let invalid = |e: EntryError| ScenarioError::Invalid {
            path: path.to_path_buf(),
            key: e.key,
            reason: e.reason,
        };
        let truth = geometric::build(&raw.geometric, &rig, seed).map_err(invalid)?;
        let mut effects = Vec::new();
        for (k, table) in raw.effects.iter().enumerate() {
            let key = format!("effects[{k}]");
            let ctx = ParseCtx {
                key: &key,
                chain: &rig.chain,
                truth: &truth,
                instrument: &rig.instrument,
                seed,
                index: k,
            };
            effects.push(parse_effect(&ctx, table).map_err(invalid)?);
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

#[cfg(test)]
mod tests {
    //! Every effect kind's scenario entry as the world reads and runs it.
    use super::*;
    use nalgebra::Vector3;
    use rigcal_model::effects::EffectKind;
    use std::collections::BTreeSet;

    fn parse_error(effect: &str) -> String {
        let text = format!("seed = 1\nrig = \"../rigs/rv-m2-ideal.toml\"\n[[effects]]\n{effect}");
        match Scenario::parse(
            &text,
            Path::new(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../../sim/registry-test.toml"
            )),
            None,
        ) {
            Ok(_) => panic!("`{effect}` parsed"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn the_shipped_scenarios_name_every_kind_but_the_fitted_discrepancy() {
        // The shipped scenarios name every kind between them; each parses to an effect that
        // reports the kind it was read as.
        let mut seen = BTreeSet::new();
        for file in [
            concat!(env!("CARGO_MANIFEST_DIR"), "/../../sim/rig-realistic.toml"),
            concat!(env!("CARGO_MANIFEST_DIR"), "/../../sim/paper-sim.toml"),
        ] {
            let text = std::fs::read_to_string(file).expect("shipped scenario");
            let sc = Scenario::parse(&text, Path::new(file), None).expect("shipped scenario");
            let doc: toml::Table = toml::from_str(&text).expect("toml");
            let names: Vec<&str> = doc
                .get("effects")
                .and_then(toml::Value::as_array)
                .map(|a| {
                    a.iter()
                        .filter_map(|t| t.get("kind").and_then(toml::Value::as_str))
                        .collect()
                })
                .unwrap_or_default();
            assert_eq!(names.len(), sc.effects.len());
            for (e, name) in sc.effects.iter().zip(names) {
                assert_eq!(e.kind().name(), name);
                seen.insert(e.kind());
            }
        }
        // A fitted discrepancy is written by the twin, never shipped: its own tests parse it.
        seen.insert(EffectKind::Discrepancy);
        assert_eq!(seen, EffectKind::ALL.iter().copied().collect());
    }

    #[test]
    fn a_missing_or_unknown_kind_lists_the_known_ones() {
        let missing = parse_error("joint = 1\n");
        assert!(missing.contains("effects[0].kind"), "{missing}");
        assert!(
            missing.contains(&format!("missing; one of {}", EffectKind::ALL[0])),
            "{missing}"
        );
        let not_string = parse_error("kind = 3\n");
        assert!(not_string.contains("must be a string"), "{not_string}");
        let unknown = parse_error("kind = \"gear_wobble\"\n");
        for k in EffectKind::ALL {
            assert!(unknown.contains(k.name()), "{unknown}");
        }
    }

    fn scenario(effect: &str) -> Result<Scenario, ScenarioError> {
        let text = format!(
            "seed = 1\nrig = \"../rigs/rv-m2-ideal.toml\"\n[measurement]\nnoise_mm = 0.0\n[[effects]]\nkind = \"discrepancy\"\n{effect}"
        );
        Scenario::parse(
            &text,
            Path::new(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../../sim/discrepancy-test.toml"
            )),
            None,
        )
    }

    fn tip(sc: &Scenario, q: &[f64]) -> Vector3<f64> {
        sc.world().noiseless().true_position(q)
    }

    #[test]
    fn a_joint_spline_moves_the_tip_as_its_joint_error_does() {
        // Joint 2's error: 0.05° everywhere (B-splines sum to one), so the tip moves as a
        // 0.05° change of q2 would.
        let coefs = ["0.05"; 7].join(", ");
        let sc = scenario(&format!(
            "[[effects.terms]]\ndepends_on = \"other_joint_angle\"\njoint = 2\ndriver_joint = 1\nbasis = \"spline\"\nrange_deg = [-150.0, 150.0]\nintervals = 4\ncoefficients_deg = [{coefs}]\n"
        ))
        .expect("parses");
        let plain = scenario(
            "[[effects.terms]]\ndepends_on = \"time\"\nbasis = \"spline\"\nrange_s = [0.0, 1.0]\nintervals = 1\nx_mm = [0.0, 0.0, 0.0, 0.0]\ny_mm = [0.0, 0.0, 0.0, 0.0]\nz_mm = [0.0, 0.0, 0.0, 0.0]\n",
        )
        .expect("parses");
        let q = [0.3, -0.2, -1.8, 0.0, 0.0];
        let mut q2 = q;
        q2[1] += 0.05f64.to_radians();
        let d = (tip(&sc, &q) - tip(&plain, &q2)).norm();
        assert!(d < 1e-9, "{d}");
    }

    #[test]
    fn a_position_term_displaces_the_tip_by_its_radial_sum() {
        let sc = scenario(
            "[[effects.terms]]\ndepends_on = \"position\"\nbasis = \"radial\"\ncentres_mm = [[0.0, 0.0, 0.0]]\nwidth_mm = 1e6\nx_mm = [0.1]\ny_mm = [-0.2]\nz_mm = [0.3]\n",
        )
        .expect("parses");
        let plain = scenario(
            "[[effects.terms]]\ndepends_on = \"position\"\nbasis = \"radial\"\ncentres_mm = [[0.0, 0.0, 0.0]]\nwidth_mm = 1e6\nx_mm = [0.0]\ny_mm = [0.0]\nz_mm = [0.0]\n",
        )
        .expect("parses");
        let q = [0.3, -0.2, -1.8, 0.0, 0.0];
        // A very wide radial function is ≈ 1 at any reachable tip.
        let d = tip(&sc, &q) - tip(&plain, &q);
        assert!((d - Vector3::new(0.1, -0.2, 0.3)).norm() < 1e-6, "{d}");
    }

    #[test]
    fn a_wrong_basis_or_count_says_what_is_expected() {
        let e = scenario(
            "[[effects.terms]]\ndepends_on = \"position\"\nbasis = \"spline\"\nrange_s = [0.0, 1.0]\nintervals = 2\n",
        )
        .expect_err("position splines are refused")
        .to_string();
        assert!(e.contains("radial"), "{e}");
        let e = scenario(
            "[[effects.terms]]\ndepends_on = \"own_joint_angle\"\njoint = 1\nbasis = \"spline\"\nrange_deg = [-10.0, 10.0]\nintervals = 2\ncoefficients_deg = [0.0]\n",
        )
        .expect_err("one coefficient for five functions")
        .to_string();
        assert!(e.contains("has 1 values; the basis has 5 functions"), "{e}");
    }
}
