//! The model file: what calibration produced, versioned, with the rig it belongs to and what it
//! was fitted from. JSON; parameters in mm and degrees.
//!
//! ```json
//! { "format": "rigcal-model", "version": 1, "created_by": "rigcal 0.1.0",
//!   "rig": { "name": "rv-m2", "path": "rigs/rv-m2.toml", "toml": "…" },
//!   "fitted_from": { "recording": "out/rec", "measurements": 100 },
//!   "model": { "type": "constant", "parameters": [ {"name": "theta0", "value": 0.05, "unit": "deg", "sigma": 0.001} ],
//!              "fit": { … } } }
//! ```

pub mod effects;
pub mod hybrid;

use crate::division::{DivisionSpace, RegionModel, RegionTree};
use crate::identification::{FitResult, ResidualStats};
use crate::learners::{LearnedModel, Learner};
use rigcal_core::kinematics::{ErrorModel, ErrorParams, Robot};
use rigcal_core::rig::{Rig, RigError};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The `format` tag of a model file.
pub const MODEL_FORMAT: &str = "rigcal-model";
/// The version this build writes and reads.
pub const MODEL_VERSION: u32 = 1;

/// What went wrong with a model file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ModelError {
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Not valid JSON, or a key is missing or mistyped.
    #[error("{path}: line {line}, column {column}: {reason}")]
    Json {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// The parser's message.
        reason: String,
    },
    /// Valid JSON that is not a model this version can use.
    #[error("{path}: {reason}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong and what to do.
        reason: String,
    },
    /// The rig embedded in the model is not valid.
    #[error("{path}: the embedded rig: {source}")]
    Rig {
        /// The file.
        path: PathBuf,
        /// The rig error.
        source: RigError,
    },
}

/// The rig a model belongs to, embedded so the model stands alone.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct RigRecord {
    /// The rig's name.
    pub name: String,
    /// Where it was read from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<String>,
    /// The rig file's text.
    pub toml: String,
}

/// What the model was fitted from.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, Default)]
pub struct Provenance {
    /// The recording (directory or CSV).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub recording: Option<String>,
    /// Measurements used.
    pub measurements: usize,
    /// Anything else worth knowing (scenario, seed, command line).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub notes: Option<String>,
}

/// One parameter in file units.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ParamEntry {
    /// Name (`theta0`, `d1`, `frame.x`).
    pub name: String,
    /// Value (mm or deg).
    pub value: f64,
    /// `mm` or `deg`.
    pub unit: String,
    /// Standard deviation (same unit), when estimated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma: Option<f64>,
}

/// How a constant-parameter fit went.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct FitSummary {
    /// κ of eq. (4) at the solution (column-scaled, (σmax/σmin)²).
    pub kappa_eq4: f64,
    /// Residuals before the fit (nominal model).
    pub before: ResidualStats,
    /// Residuals after the fit.
    pub after: ResidualStats,
    /// Estimated noise per coordinate (mm).
    pub sigma0_mm: f64,
    /// Iterations.
    pub iterations: usize,
}

/// The body of a model.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case")]
#[non_exhaustive]
#[allow(clippy::large_enum_variant)] // one per model file; boxing would only add indirection
pub enum ModelBody {
    /// Conventional calibration: one set of error parameters for the whole workspace.
    Constant {
        /// Fitted parameters (others are zero).
        parameters: Vec<ParamEntry>,
        /// How the fit went.
        fit: FitSummary,
    },
    /// The variable D-H parameter model: CEPs per region of a recursive division, optionally
    /// generalised by a learner; with the conventional fit on the same measurements for
    /// comparison.
    Variable {
        /// Conventional calibration on the same measurements.
        conventional: Vec<ParamEntry>,
        /// How the conventional fit went.
        fit: FitSummary,
        /// How the division was made.
        division: DivisionSummary,
        /// The region tree (CEPs in internal units: mm, rad).
        tree: RegionTree,
        /// The learner, when one was trained (outputs in mm and degrees).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        learner: Option<Learner>,
    },
    /// A neuro-kinematic model (seed 001): a network beside the nominal kinematics, scheme 2
    /// (joint correction) or 4 (position correction), direct or inverse; see
    /// [`crate::neural::rig_model`] for how it acts as an error model.
    Neural {
        /// The network and how it was trained.
        network: crate::neural::rig_model::NeuralModel,
    },
}

/// How a division was made.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct DivisionSummary {
    /// Demanded accuracy (mm).
    pub accuracy_mm: f64,
    /// Region cap.
    pub max_regions: usize,
    /// Measurements per region asked for.
    pub per_region: usize,
    /// Regions (leaves) made.
    pub regions: usize,
    /// Identification measurements used.
    pub measurements: usize,
    /// Test measurements made (planning mode).
    pub test_measurements: usize,
    /// `planning` or `offline`.
    pub mode: String,
    /// Random poses the identifiable basis was chosen on (older files: the paper's 100).
    #[serde(default = "paper_design_poses")]
    pub design_poses: usize,
    /// The learner tolerance the learner's CEPs were made with (a fraction of `accuracy_mm`;
    /// older files: 0, the paper's).
    #[serde(default)]
    pub learner_tolerance: f64,
    /// The box of the division space that could not be measured (seed 000 Fig. 8; internal
    /// units: rad, mm): nothing inside it was measured or fitted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unmeasurable: Option<crate::division::Bounds>,
}

/// The design poses of files written before they were recorded.
fn paper_design_poses() -> usize {
    100
}

/// A model file.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ModelFile {
    /// Always `rigcal-model`.
    pub format: String,
    /// File format version.
    pub version: u32,
    /// The program that wrote it.
    pub created_by: String,
    /// The rig.
    pub rig: RigRecord,
    /// What it was fitted from.
    pub fitted_from: Provenance,
    /// The model.
    pub model: ModelBody,
    /// Measurements removed from the fit as outliers (`rigcal identify`), each with its row.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub outliers: Vec<crate::identification::outliers::Outlier>,
    /// Joint-space effects fitted beside the geometry (`rigcal identify --effects`), which
    /// compensation undoes; absent in older files and in geometric-only models.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub effects: Vec<effects::ModelEffect>,
    /// When `effects` is not empty: the geometry fitted without them, which stands alone where
    /// the effects cannot go (`rigcal export urdf`: a URDF carries geometry only, and the
    /// geometry fitted beside the effects is worse than this one without them). Absent in
    /// older files and in models without effects.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub standalone_parameters: Vec<ParamEntry>,
    /// The covariance of the fitted (conventional) parameters, in file units, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub covariance: Option<Covariance>,
    /// Parameters the measurements did not determine (`rigcal identify`): held at nominal,
    /// so absent from the parameters and from every export.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub undetermined: Vec<UndeterminedEntry>,
}

/// A parameter the measurements did not determine, in file units.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct UndeterminedEntry {
    /// Its name (`d5`, `marker.z`).
    pub name: String,
    /// Its column's part independent of the determined ones, relative to its length (below
    /// [`crate::identification::DETERMINED_TOL`]).
    pub independent: f64,
    /// The determined parameters whose shifts have its effect: `[name, coefficient]` with the
    /// coefficient in their unit per this parameter's unit (mm or deg), largest first.
    pub equivalent: Vec<(String, f64)>,
}

/// The undetermined parameters of a fit as model-file entries.
pub fn undetermined_entries(rig: &Rig, fit: &FitResult) -> Vec<UndeterminedEntry> {
    let layout = rig.chain.layout();
    fit.undetermined
        .iter()
        .map(|u| {
            let id = layout.ids()[u.param];
            UndeterminedEntry {
                name: layout.name(id),
                independent: u.independent,
                equivalent: u
                    .combination
                    .iter()
                    .filter(|(_, c)| c.abs() > 1e-9)
                    .take(6)
                    .map(|&(b, c)| {
                        let bid = layout.ids()[b];
                        // basis units per parameter unit → file units per file unit
                        let v = bid.kind.to_file_units(c) / id.kind.to_file_units(1.0);
                        (layout.name(bid), v)
                    })
                    .collect(),
            }
        })
        .collect()
}

/// The covariance of a model's fitted parameters (mm and degrees, as the entries).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Covariance {
    /// The parameters, in the order of the rows (the entries' order).
    pub names: Vec<String>,
    /// Row-major values, `names.len()` rows of `names.len()`.
    pub values: Vec<Vec<f64>>,
}

impl Covariance {
    /// The covariance of a fit's free parameters, in file units.
    pub fn of(rig: &Rig, fit: &FitResult) -> Self {
        let layout = rig.chain.layout();
        let scale: Vec<f64> = fit
            .free
            .iter()
            .map(|&i| layout.ids()[i].kind.to_file_units(1.0))
            .collect();
        let n = fit.free.len().min(fit.covariance.nrows());
        Self {
            names: fit
                .free
                .iter()
                .map(|&i| layout.name(layout.ids()[i]))
                .collect(),
            values: (0..n)
                .map(|i| {
                    (0..n)
                        .map(|j| fit.covariance[(i, j)] * scale[i] * scale[j])
                        .collect()
                })
                .collect(),
        }
    }

    /// As a matrix (empty when the rows are ragged).
    pub fn matrix(&self) -> nalgebra::DMatrix<f64> {
        let n = self.names.len();
        if self.values.len() != n || self.values.iter().any(|r| r.len() != n) {
            return nalgebra::DMatrix::zeros(0, 0);
        }
        nalgebra::DMatrix::from_fn(n, n, |i, j| self.values[i][j])
    }
}

/// An error model with its name (`conventional`, `regions`, `fcmac`, `cmac`).
pub type NamedModel = (String, Box<dyn ErrorModel>);

/// A model ready to use: its rig and its error parameters as a function of the pose.
pub struct LoadedModel {
    /// The rig embedded in the model.
    pub rig: Rig,
    /// The file as read.
    pub file: ModelFile,
    /// Error parameters by pose.
    pub errors: Box<dyn ErrorModel>,
}

impl ModelFile {
    /// A constant-parameter model from a fit.
    pub fn constant(rig: &Rig, fit: &FitResult, provenance: Provenance) -> Self {
        let mut file = Self::new(
            rig,
            provenance,
            ModelBody::Constant {
                parameters: entries(rig, fit),
                fit: summary(fit),
            },
        );
        file.covariance = Some(Covariance::of(rig, fit));
        file.undetermined = undetermined_entries(rig, fit);
        file
    }

    /// A model file around a body.
    pub fn new(rig: &Rig, provenance: Provenance, model: ModelBody) -> Self {
        Self {
            format: MODEL_FORMAT.into(),
            version: MODEL_VERSION,
            created_by: format!("rigcal {}", env!("CARGO_PKG_VERSION")),
            rig: RigRecord {
                name: rig.name.clone(),
                path: rig.source.path.as_ref().map(|p| p.display().to_string()),
                toml: rig.source.text.clone(),
            },
            fitted_from: provenance,
            model,
            outliers: Vec::new(),
            effects: Vec::new(),
            standalone_parameters: Vec::new(),
            covariance: None,
            undetermined: Vec::new(),
        }
    }

    /// Writes the model as pretty JSON. A value that is not a finite number (JSON would write
    /// it as `null`, which no reader takes for a number) is refused, naming where it is, and
    /// nothing is written.
    pub fn save(&self, path: &Path) -> Result<(), ModelError> {
        if let Err(at) = finite::check(self) {
            return Err(ModelError::Format {
                path: path.to_path_buf(),
                reason: format!(
                    "not written: `{at}` is not a finite number; the fit or model it came from is broken (refit, and report it if the recording is sound)"
                ),
            });
        }
        let text = serde_json::to_string_pretty(self).map_err(|e| ModelError::Format {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        std::fs::write(path, text + "\n").map_err(|source| ModelError::Io {
            path: path.to_path_buf(),
            source,
        })
    }

    /// Reads and checks a model file, and builds its rig and error model.
    pub fn load(path: &Path) -> Result<LoadedModel, ModelError> {
        let text = std::fs::read_to_string(path).map_err(|source| ModelError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        // A byte-order mark (left by some Windows editors) is accepted, as the CSV and TOML
        // readers accept one; serde_json would refuse it as an unexpected character.
        let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
        let value: serde_json::Value =
            serde_json::from_str(text).map_err(|e| json_error(path, &e))?;
        let format = value.get("format").and_then(|v| v.as_str()).unwrap_or("");
        if format != MODEL_FORMAT {
            return Err(ModelError::Format {
                path: path.to_path_buf(),
                reason: format!("not a rigcal model (format is `{format}`, expected `{MODEL_FORMAT}`): pass the file written by `rigcal identify` or `rigcal calibrate`"),
            });
        }
        let version = value.get("version").and_then(|v| v.as_u64()).unwrap_or(0);
        if version != u64::from(MODEL_VERSION) {
            return Err(ModelError::Format {
                path: path.to_path_buf(),
                reason: format!("model format version {version}; this rigcal reads version {MODEL_VERSION}: refit with this version"),
            });
        }
        let file: ModelFile = serde_json::from_str(text).map_err(|e| json_error(path, &e))?;
        let rig_path = file
            .rig
            .path
            .as_ref()
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from("<embedded rig>"));
        let rig =
            Rig::parse(&file.rig.toml, Some(&rig_path)).map_err(|source| ModelError::Rig {
                path: path.to_path_buf(),
                source,
            })?;
        let errors = file.error_model(&rig, path)?;
        Ok(LoadedModel { rig, file, errors })
    }

    fn error_model(&self, rig: &Rig, path: &Path) -> Result<Box<dyn ErrorModel>, ModelError> {
        let mut all = self.error_models(rig, path)?;
        Ok(all.remove(0).1)
    }

    /// Every error model the file holds, the one compensation uses first: for a variable model
    /// the learner (if any), then the regions, then the conventional parameters.
    pub fn error_models(&self, rig: &Rig, path: &Path) -> Result<Vec<NamedModel>, ModelError> {
        match &self.model {
            ModelBody::Neural { network } => {
                let m = crate::neural::rig_model::NeuralErrorModel::new(network.nk.clone(), rig)
                    .map_err(|e| ModelError::Format {
                        path: path.to_path_buf(),
                        reason: e.to_string(),
                    })?;
                Ok(vec![(
                    format!("nn-{}", network.nk.scheme.name()),
                    Box::new(m),
                )])
            }
            ModelBody::Constant { parameters, .. } => Ok(vec![(
                "conventional".into(),
                Box::new(params_from_entries(rig, parameters, path)?),
            )]),
            ModelBody::Variable {
                conventional,
                tree,
                learner,
                ..
            } => {
                let bad = |reason: String| ModelError::Format {
                    path: path.to_path_buf(),
                    reason,
                };
                let layout = rig.chain.layout();
                let basis = tree
                    .basis
                    .iter()
                    .map(|n| {
                        layout
                            .find(n)
                            .and_then(|id| layout.index_of(id))
                            .ok_or_else(|| {
                                bad(format!("CEP `{n}` does not exist in rig `{}`", rig.name))
                            })
                    })
                    .collect::<Result<Vec<_>, _>>()?;
                let space = DivisionSpace::new(rig, tree.space).map_err(|e| bad(e.to_string()))?;
                let mut out: Vec<NamedModel> = Vec::new();
                if let Some(l) = learner {
                    let name = match l {
                        Learner::Fcmac(_) => "fcmac",
                        Learner::Cmac(_) => "cmac",
                    };
                    let scale = cep_scale(rig, &basis);
                    out.push((
                        name.into(),
                        Box::new(LearnedModel::new(
                            l.clone(),
                            space.clone(),
                            basis.clone(),
                            scale,
                            layout.len(),
                        )),
                    ));
                }
                out.push((
                    "regions".into(),
                    Box::new(RegionModel::new(tree.clone(), space, basis, layout.len())),
                ));
                out.push((
                    "conventional".into(),
                    Box::new(params_from_entries(rig, conventional, path)?),
                ));
                Ok(out)
            }
        }
    }
}

/// Factors from internal units to file units for CEPs (180/π for angles, 1 for lengths).
pub fn cep_scale(rig: &Rig, basis: &[usize]) -> Vec<f64> {
    let layout = rig.chain.layout();
    basis
        .iter()
        .map(|&i| {
            if layout.ids()[i].kind.is_angle() {
                180.0 / std::f64::consts::PI
            } else {
                1.0
            }
        })
        .collect()
}

/// Parameter entries (file units, with σ) of a fit.
pub fn entries(rig: &Rig, fit: &FitResult) -> Vec<ParamEntry> {
    let layout = rig.chain.layout();
    fit.free
        .iter()
        .zip(&fit.sigma)
        .map(|(&i, &s)| {
            let id = layout.ids()[i];
            ParamEntry {
                name: layout.name(id),
                value: id.kind.to_file_units(fit.params.get(i)),
                unit: id.kind.unit().to_string(),
                sigma: Some(id.kind.to_file_units(s)),
            }
        })
        .collect()
}

/// The summary of a fit for a model file.
pub fn summary(fit: &FitResult) -> FitSummary {
    FitSummary {
        kappa_eq4: fit.kappa,
        before: fit.before,
        after: fit.after,
        sigma0_mm: fit.sigma0_mm,
        iterations: fit.iterations,
    }
}

/// Error parameters from file entries; unknown names are an error.
pub fn params_from_entries(
    rig: &Rig,
    entries: &[ParamEntry],
    path: &Path,
) -> Result<ErrorParams, ModelError> {
    let layout = rig.chain.layout();
    let mut e = ErrorParams::zeros(layout);
    let mut given = Vec::with_capacity(entries.len());
    for p in entries {
        let Some(id) = layout.find(&p.name) else {
            return Err(ModelError::Format {
                path: path.to_path_buf(),
                reason: format!(
                    "parameter `{}` does not exist in rig `{}`",
                    p.name, rig.name
                ),
            });
        };
        if p.unit != id.kind.unit() {
            return Err(ModelError::Format {
                path: path.to_path_buf(),
                reason: format!(
                    "parameter `{}` is in `{}`; expected `{}`",
                    p.name,
                    p.unit,
                    id.kind.unit()
                ),
            });
        }
        if !p.value.is_finite() {
            return Err(ModelError::Format {
                path: path.to_path_buf(),
                reason: format!("parameter `{}` is not a finite number", p.name),
            });
        }
        if let Some(i) = layout.index_of(id) {
            e.set(i, id.kind.from_file_units(p.value));
            given.push(i);
        }
    }
    // The bounds a fit is held to hold for a file read back too: a hand-edited or foreign
    // model with a 2 000° offset would otherwise compensate every target by it.
    crate::identification::checks::check_parameters(rig, &rig.chain, &e, &given).map_err(|d| {
        ModelError::Format {
            path: path.to_path_buf(),
            reason: format!(
                "{} for rig `{}` (a model read back is held to the bounds a fit is held to): refit, or state larger bounds in the rig file's [calibration]",
                d.what, rig.name
            ),
        }
    })?;
    Ok(e)
}

fn json_error(path: &Path, e: &serde_json::Error) -> ModelError {
    ModelError::Json {
        path: path.to_path_buf(),
        line: e.line(),
        column: e.column(),
        reason: e.to_string(),
    }
}

/// Finds a float that is not finite anywhere in a serialisable value: a serializer that writes
/// nothing and keeps the path of keys and indices it is at (`model.parameters[3].value`).
mod finite {
    use serde::ser::{self, Serialize};
    use std::fmt;

    /// The path of the first non-finite float in `value`, as `Err`.
    pub(super) fn check<T: Serialize + ?Sized>(value: &T) -> Result<(), String> {
        let mut walker = Walker { path: Vec::new() };
        match value.serialize(&mut walker) {
            Ok(()) => Ok(()),
            Err(Found(at)) => Err(at),
        }
    }

    #[derive(Debug)]
    pub(super) struct Found(String);

    impl fmt::Display for Found {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str(&self.0)
        }
    }

    impl std::error::Error for Found {}

    impl ser::Error for Found {
        fn custom<M: fmt::Display>(msg: M) -> Self {
            Found(msg.to_string())
        }
    }

    struct Walker {
        path: Vec<String>,
    }

    impl Walker {
        fn here(&self) -> String {
            let mut s = String::new();
            for p in &self.path {
                if !p.starts_with('[') && !s.is_empty() {
                    s.push('.');
                }
                s.push_str(p);
            }
            if s.is_empty() {
                s.push_str("(top level)");
            }
            s
        }

        fn float(&self, v: f64) -> Result<(), Found> {
            if v.is_finite() {
                Ok(())
            } else {
                Err(Found(format!("{} = {v}", self.here())))
            }
        }

        fn at<T: Serialize + ?Sized>(&mut self, key: String, v: &T) -> Result<(), Found> {
            self.path.push(key);
            let r = v.serialize(&mut *self);
            self.path.pop();
            r
        }
    }

    /// A compound value being walked: its next index.
    pub(super) struct Compound<'a> {
        walker: &'a mut Walker,
        next: usize,
    }

    impl Compound<'_> {
        fn element<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Found> {
            let key = format!("[{}]", self.next);
            self.next += 1;
            self.walker.at(key, v)
        }
    }

    macro_rules! ok {
        ($($name:ident($($t:ty),*)),* $(,)?) => {
            $(fn $name(self, $(_: $t),*) -> Result<(), Found> { Ok(()) })*
        };
    }

    impl<'a> ser::Serializer for &'a mut Walker {
        type Ok = ();
        type Error = Found;
        type SerializeSeq = Compound<'a>;
        type SerializeTuple = Compound<'a>;
        type SerializeTupleStruct = Compound<'a>;
        type SerializeTupleVariant = Compound<'a>;
        type SerializeMap = Compound<'a>;
        type SerializeStruct = Compound<'a>;
        type SerializeStructVariant = Compound<'a>;

        ok!(
            serialize_bool(bool),
            serialize_i8(i8),
            serialize_i16(i16),
            serialize_i32(i32),
            serialize_i64(i64),
            serialize_u8(u8),
            serialize_u16(u16),
            serialize_u32(u32),
            serialize_u64(u64),
            serialize_char(char),
            serialize_str(&str),
            serialize_bytes(&[u8]),
            serialize_none(),
            serialize_unit(),
            serialize_unit_struct(&'static str),
            serialize_unit_variant(&'static str, u32, &'static str),
        );

        fn serialize_f32(self, v: f32) -> Result<(), Found> {
            self.float(f64::from(v))
        }

        fn serialize_f64(self, v: f64) -> Result<(), Found> {
            self.float(v)
        }

        fn serialize_some<T: Serialize + ?Sized>(self, v: &T) -> Result<(), Found> {
            v.serialize(self)
        }

        fn serialize_newtype_struct<T: Serialize + ?Sized>(
            self,
            _: &'static str,
            v: &T,
        ) -> Result<(), Found> {
            v.serialize(self)
        }

        fn serialize_newtype_variant<T: Serialize + ?Sized>(
            self,
            _: &'static str,
            _: u32,
            variant: &'static str,
            v: &T,
        ) -> Result<(), Found> {
            self.at(variant.to_string(), v)
        }

        fn serialize_seq(self, _: Option<usize>) -> Result<Compound<'a>, Found> {
            Ok(Compound {
                walker: self,
                next: 0,
            })
        }

        fn serialize_tuple(self, _: usize) -> Result<Compound<'a>, Found> {
            self.serialize_seq(None)
        }

        fn serialize_tuple_struct(self, _: &'static str, _: usize) -> Result<Compound<'a>, Found> {
            self.serialize_seq(None)
        }

        fn serialize_tuple_variant(
            self,
            _: &'static str,
            _: u32,
            _: &'static str,
            _: usize,
        ) -> Result<Compound<'a>, Found> {
            self.serialize_seq(None)
        }

        fn serialize_map(self, _: Option<usize>) -> Result<Compound<'a>, Found> {
            self.serialize_seq(None)
        }

        fn serialize_struct(self, _: &'static str, _: usize) -> Result<Compound<'a>, Found> {
            self.serialize_seq(None)
        }

        fn serialize_struct_variant(
            self,
            _: &'static str,
            _: u32,
            _: &'static str,
            _: usize,
        ) -> Result<Compound<'a>, Found> {
            self.serialize_seq(None)
        }
    }

    impl ser::SerializeSeq for Compound<'_> {
        type Ok = ();
        type Error = Found;
        fn serialize_element<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Found> {
            self.element(v)
        }
        fn end(self) -> Result<(), Found> {
            Ok(())
        }
    }

    impl ser::SerializeTuple for Compound<'_> {
        type Ok = ();
        type Error = Found;
        fn serialize_element<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Found> {
            self.element(v)
        }
        fn end(self) -> Result<(), Found> {
            Ok(())
        }
    }

    impl ser::SerializeTupleStruct for Compound<'_> {
        type Ok = ();
        type Error = Found;
        fn serialize_field<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Found> {
            self.element(v)
        }
        fn end(self) -> Result<(), Found> {
            Ok(())
        }
    }

    impl ser::SerializeTupleVariant for Compound<'_> {
        type Ok = ();
        type Error = Found;
        fn serialize_field<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Found> {
            self.element(v)
        }
        fn end(self) -> Result<(), Found> {
            Ok(())
        }
    }

    impl ser::SerializeMap for Compound<'_> {
        type Ok = ();
        type Error = Found;
        fn serialize_key<T: Serialize + ?Sized>(&mut self, _: &T) -> Result<(), Found> {
            Ok(())
        }
        fn serialize_value<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Found> {
            self.element(v)
        }
        fn end(self) -> Result<(), Found> {
            Ok(())
        }
    }

    impl ser::SerializeStruct for Compound<'_> {
        type Ok = ();
        type Error = Found;
        fn serialize_field<T: Serialize + ?Sized>(
            &mut self,
            key: &'static str,
            v: &T,
        ) -> Result<(), Found> {
            self.walker.at(key.to_string(), v)
        }
        fn end(self) -> Result<(), Found> {
            Ok(())
        }
    }

    impl ser::SerializeStructVariant for Compound<'_> {
        type Ok = ();
        type Error = Found;
        fn serialize_field<T: Serialize + ?Sized>(
            &mut self,
            key: &'static str,
            v: &T,
        ) -> Result<(), Found> {
            self.walker.at(key.to_string(), v)
        }
        fn end(self) -> Result<(), Found> {
            Ok(())
        }
    }

    #[cfg(test)]
    mod tests {
        #[derive(serde::Serialize)]
        struct Inner {
            value: f64,
            note: Option<f64>,
        }

        #[derive(serde::Serialize)]
        struct Outer {
            name: String,
            parameters: Vec<Inner>,
        }

        #[test]
        fn the_first_non_finite_float_is_named_by_its_path() {
            let mut o = Outer {
                name: "m".into(),
                parameters: vec![
                    Inner {
                        value: 1.0,
                        note: None,
                    },
                    Inner {
                        value: 2.0,
                        note: Some(3.0),
                    },
                ],
            };
            assert_eq!(super::check(&o), Ok(()));
            o.parameters[1].value = f64::NAN;
            assert_eq!(
                super::check(&o),
                Err("parameters[1].value = NaN".to_string())
            );
        }
    }
}
