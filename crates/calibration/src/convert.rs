//! Between a robot's own description and rigcal's files: a rig file from a URDF chain
//! (`rigcal rig from-urdf`), and a calibration folded back into the URDF its rig came from
//! (`rigcal export urdf`).

use rigcal_core::kinematics::urdf::{
    chain_from_urdf, max_tip_deviation, rig_file, urdf_path, RigFileNames, UrdfError,
};
use rigcal_core::kinematics::Robot;
use rigcal_core::rig::{Rig, RigError};
use rigcal_model::export::{
    export_urdf, exported_parameters, offsets_yaml, ExportError, ExportOptions, UrdfExport,
};
use rigcal_model::model::{ModelError, ModelFile};
use std::path::{Path, PathBuf};

/// Why a conversion failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConvertError {
    /// A file could not be read.
    #[error("cannot read {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The URDF's chain could not be converted.
    #[error("{}", path.display())]
    Chain {
        /// The URDF file.
        path: PathBuf,
        /// The cause.
        source: UrdfError,
    },
    /// The rig file made from the URDF does not load: a bug.
    #[error("the generated rig file does not validate (a bug: please report it)")]
    Invalid(#[source] RigError),
    /// The rig made from the URDF does not have the URDF's forward kinematics: a bug. Nothing is
    /// written.
    #[error(
        "the rig converted from {} differs from the URDF's own forward kinematics by {deviation_mm:.3e} mm \
         (tolerance {FK_TOLERANCE_MM:e} mm) at joint values {q_deg:?} deg/mm; no rig file written (a bug: please report it with the URDF)",
        path.display()
    )]
    Mismatch {
        /// The URDF file.
        path: PathBuf,
        /// Largest distance between the two tip frames (mm).
        deviation_mm: f64,
        /// The joint values where it was found (deg for revolute, mm for prismatic joints).
        q_deg: Vec<f64>,
    },
    /// The model file could not be used.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The model holds no parameters to export.
    #[error(transparent)]
    Parameters(ExportError),
    /// The model could not be folded into the URDF.
    #[error("exporting {} into {}", model.display(), urdf.display())]
    Export {
        /// The model file.
        model: PathBuf,
        /// The URDF file.
        urdf: PathBuf,
        /// The cause.
        source: ExportError,
    },
}

/// What `rigcal export urdf` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ExportFormat {
    /// The calibrated URDF.
    #[default]
    Urdf,
    /// A flat list of corrected joint offsets and origins (YAML).
    Yaml,
}

fn read(path: &Path) -> Result<String, ConvertError> {
    std::fs::read_to_string(path).map_err(|source| ConvertError::Read {
        path: path.to_path_buf(),
        source,
    })
}

/// How far (mm) a converted rig's tip may lie from the URDF's: rounding only.
pub const FK_TOLERANCE_MM: f64 = 1e-6;

/// Joint vectors at which a converted rig is compared with its URDF (q = 0 and random ones).
pub const FK_CHECK_SAMPLES: usize = 64;

/// A rig converted from a URDF: the file text, the rig it loads as, and how far its forward
/// kinematics lies from the URDF's.
#[derive(Debug)]
pub struct ConvertedRig {
    /// The rig file (TOML).
    pub toml: String,
    /// The rig the text loads as.
    pub rig: Rig,
    /// Largest distance (mm) between the rig's and the URDF's tip frames over
    /// [`FK_CHECK_SAMPLES`] joint vectors (at most [`FK_TOLERANCE_MM`]).
    pub deviation_mm: f64,
}

/// The rig file (TOML text, five-parameter convention) whose forward kinematics equals the
/// chain from link `base` to link `tip` of the URDF file `urdf`, named after the file, and the
/// rig it loads as (its file to be at `out`). The measurement frame and the marker are left
/// free.
///
/// The rig is checked against the URDF's own forward kinematics (joint origins and axes as
/// written) at [`FK_CHECK_SAMPLES`] joint vectors and refused ([`ConvertError::Mismatch`]) when
/// its tip frame lies more than [`FK_TOLERANCE_MM`] from the URDF's anywhere: a wrong rig is
/// never returned.
pub fn rig_from_urdf(
    urdf: &Path,
    base: &str,
    tip: &str,
    out: &Path,
) -> Result<ConvertedRig, ConvertError> {
    let text = read(urdf)?;
    let chain = chain_from_urdf(&text, base, tip).map_err(|source| ConvertError::Chain {
        path: urdf.to_path_buf(),
        source,
    })?;
    let name = urdf
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "robot".into());
    let source = urdf.display().to_string();
    let names = RigFileNames {
        name: &name,
        source: &source,
        base,
        tip,
    };
    let parse = |t: &str| Rig::parse(t, Some(out)).map_err(ConvertError::Invalid);
    let toml = rig_file(&names, &chain, |t| parse(t).map(|r| r.chain))?;
    let rig = parse(&toml)?;
    let reference = urdf_path(&text, base, tip).map_err(|source| ConvertError::Chain {
        path: urdf.to_path_buf(),
        source,
    })?;
    let (deviation_mm, q) = max_tip_deviation(&reference, &rig.chain, FK_CHECK_SAMPLES);
    // NaN (a degenerate chain) is refused too.
    if deviation_mm.is_nan() || deviation_mm > FK_TOLERANCE_MM {
        return Err(ConvertError::Mismatch {
            path: urdf.to_path_buf(),
            deviation_mm,
            q_deg: rig
                .chain
                .joints()
                .iter()
                .zip(&q)
                .map(|(j, v)| j.kind.to_file_units(*v))
                .collect(),
        });
    }
    Ok(ConvertedRig {
        toml,
        rig,
        deviation_mm,
    })
}

/// The model file `model`'s fitted parameters folded into the URDF file `urdf` its rig came
/// from: the text to write in `format`, and the export (its links and joints). A note on what
/// could not be exported is logged as a warning.
pub fn export_files(
    model: &Path,
    urdf: &Path,
    format: ExportFormat,
    options: &ExportOptions,
) -> Result<(String, UrdfExport), ConvertError> {
    let loaded = ModelFile::load(model)?;
    let (e, note) =
        exported_parameters(&loaded.file, &loaded.rig, model).map_err(ConvertError::Parameters)?;
    if let Some(n) = note {
        tracing::warn!("{n}");
    }
    let text = read(urdf)?;
    let x = export_urdf(&text, &loaded.rig.chain, &e, options).map_err(|source| {
        ConvertError::Export {
            model: model.to_path_buf(),
            urdf: urdf.to_path_buf(),
            source,
        }
    })?;
    let body = match format {
        ExportFormat::Urdf => x.text.clone(),
        ExportFormat::Yaml => offsets_yaml(&x, &urdf.display().to_string()),
    };
    Ok((body, x))
}
