//! What a calibration is taken home as: the calibrated URDF ([`urdf::export_urdf`]) and a flat
//! YAML list of the corrected joint offsets and origins ([`yaml::offsets_yaml`]).

pub mod urdf;
mod xml;
pub mod yaml;

pub use urdf::{export_urdf, ExportOptions, ExportedJoint, UrdfExport};
pub use yaml::offsets_yaml;

/// Why a model cannot be folded into a URDF.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExportError {
    /// The file is not a valid URDF.
    #[error("not a valid URDF: {0}")]
    Urdf(String),
    /// The URDF text could not be scanned for its joints' spans.
    #[error("the URDF's text could not be scanned for its <joint> elements (an unterminated tag or comment?)")]
    Scan,
    /// The rig has no joints.
    #[error("the model's rig has no joints")]
    NoJoints,
    /// A rig joint is not in the URDF.
    #[error("the URDF has no joint named `{0}` (the rig's joints must carry the URDF's names, as `rigcal rig from-urdf` writes them)")]
    NoJoint(String),
    /// A link is not in the URDF.
    #[error("no link named `{0}` in the URDF")]
    NoLink(String),
    /// The tip does not descend from the base.
    #[error("link `{tip}` is not below `{base}` in the URDF's tree")]
    NotAChain {
        /// Base link.
        base: String,
        /// Tip link.
        tip: String,
    },
    /// The chain has a different number of moving joints.
    #[error("the rig has {rig} joints but the URDF chain has {urdf} moving joints")]
    JointCount {
        /// Rig joints.
        rig: usize,
        /// URDF moving joints between base and tip.
        urdf: usize,
    },
    /// The joints differ in name, kind or order.
    #[error(
        "the rig's joint `{rig}` meets the URDF's `{urdf}` (names, types and order must agree)"
    )]
    JointOrder {
        /// Rig joint.
        rig: String,
        /// URDF joint at the same place.
        urdf: String,
    },
    /// A joint type that is not one serial joint.
    #[error("joint `{0}` is neither revolute, continuous, prismatic nor fixed")]
    Unsupported(String),
    /// No ancestor of the first joint is the rig's world frame.
    #[error("no link above joint `{joint}` has the rig's world frame (closest: {mismatch:.3} mm + rad·1000 off): the URDF does not describe this rig, or give --base")]
    NoBase {
        /// The first joint.
        joint: String,
        /// The smallest mismatch seen.
        mismatch: f64,
    },
    /// The rig's nominal chain is not the URDF's.
    #[error("joint `{joint}`: the rig's nominal axis is {mm:.4} mm and {deg:.4}° off the URDF's: the URDF does not describe this rig (or --base is not its world frame)")]
    Mismatch {
        /// The joint.
        joint: String,
        /// Distance of the rig's joint frame from the URDF's axis line (mm).
        mm: f64,
        /// Angle between the axes (degrees).
        deg: f64,
    },
    /// The model holds no geometry to export, or does not load.
    #[error("{0}")]
    Model(String),
    /// A link the export adds already exists.
    #[error("the URDF already has a link named `{0}`")]
    NameTaken(String),
}

/// The constant error parameters a model exports: a conventional model's fit, or a variable
/// model's conventional fit (a URDF holds one geometry, not one per region; the second value
/// says so). A model with effects exports the geometry fitted without them (a URDF cannot carry
/// them, and the geometry fitted beside them does not stand alone), and says so. A neural model
/// has no geometry to export.
pub fn exported_parameters(
    file: &crate::model::ModelFile,
    rig: &rigcal_core::rig::Rig,
    path: &std::path::Path,
) -> Result<(rigcal_core::kinematics::ErrorParams, Option<String>), ExportError> {
    use crate::model::{params_from_entries, ModelBody};
    let model_error = |e: crate::model::ModelError| ExportError::Model(e.to_string());
    if !file.effects.is_empty() {
        let names: Vec<String> = file.effects.iter().map(|e| e.spec().label()).collect();
        let cannot = format!(
            "a URDF cannot carry the model's effects ({}): they stay in the model file, for `compensate` and `evaluate`",
            names.join(", ")
        );
        if !file.standalone_parameters.is_empty() {
            return Ok((
                params_from_entries(rig, &file.standalone_parameters, path).map_err(model_error)?,
                Some(format!(
                    "{cannot}; the URDF gets the geometry fitted without them, which stands alone"
                )),
            ));
        }
        if let ModelBody::Constant { parameters, .. } = &file.model {
            return Ok((
                params_from_entries(rig, parameters, path).map_err(model_error)?,
                Some(format!(
                    "{cannot}; this file (written before models kept a stand-alone geometry) has only the geometry fitted beside them, which alone may be worse than a plain fit: identify again without --effects for a URDF"
                )),
            ));
        }
    }
    match &file.model {
        ModelBody::Constant { parameters, .. } => Ok((
            params_from_entries(rig, parameters, path).map_err(model_error)?,
            None,
        )),
        ModelBody::Variable { conventional, .. } => Ok((
            params_from_entries(rig, conventional, path).map_err(model_error)?,
            Some("a variable model varies over the workspace; the URDF gets its conventional (constant) fit".into()),
        )),
        _ => Err(ExportError::Model(
            "a neural model corrects positions, not the geometry: export a model from `rigcal identify` or `rigcal calibrate`".into(),
        )),
    }
}
