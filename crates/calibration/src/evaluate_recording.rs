//! `rigcal evaluate --recording`: every model a model file holds, scored on a measured
//! recording (a held-out series of a real arm, say) instead of a simulated one.
//!
//! Rows, each with the mean, RMS and largest 3-D position error (mm), and the orientation
//! error (degrees) when the recording has orientations:
//! * `nominal, frame refitted`: the rig's nominal kinematics, only the measurement frame fitted
//!   to this recording (the marker at the rig's nominal): the uncalibrated arm.
//! * `nominal, frame + marker refitted`: the same with the marker fitted too (`--level frames`
//!   on this recording, in sample): what registering the instrument alone reaches.
//! * one row per model ([`ModelFile::error_models`]: conventional, regions, FCMAC, …) and one
//!   for the conventional model with the model file's effects, with the model's own
//!   measurement frame, or with `refit_frame` the frame refitted to this recording and
//!   everything else (kinematics, marker, effects) kept, as for a series measured with its own
//!   tracker set-up.
//!
//! The frame refit of any model is the closed-form rigid registration (Kabsch) of the model's
//! predicted points (frame at nominal) onto the measured ones: the frame enters every predicted
//! point as one rigid transform, so this is the exact least-squares frame whatever the model's
//! parameters do from pose to pose.
//!
//! Orientation: `identify` fits the probe's rotation C relative to the last link when the
//! recording has orientations ([`rigcal_model::identification::pose`]), but a model file does
//! not carry it (and a probe may be re-mounted between campaigns), so it is fitted here per
//! model and recording as the rotation C minimising Σ‖R_predicted·C − R_measured‖² (the
//! projection of Σ R_predictedᵀ·R_measured onto the rotations), alike for every model; the
//! error of a row is the angle of (R_predicted·C)ᵀ·R_measured, the one identification reports
//! (mean, RMS and max in degrees, apart from the position's millimetres).

use nalgebra::{Isometry3, Matrix3, UnitQuaternion, Vector3};
use rigcal_core::kinematics::{ErrorParams, Robot, SerialChain, TransformId};
use rigcal_core::recording::Recording;
use rigcal_core::rig::Rig;
use rigcal_model::identification::registration::kabsch;
use rigcal_model::identification::{identify_at, Level, ResidualStats};
use rigcal_model::model::effects::joint_offsets;
use rigcal_model::model::ModelFile;
use std::fmt::Write;
use std::path::Path;

/// Why a recording could not be scored.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EvaluateRecordingError {
    /// The recording has no measured rows.
    #[error("{name}: no measured rows (status ok with x_mm, y_mm, z_mm)")]
    NoMeasurements {
        /// The recording's name.
        name: String,
    },
    /// The model file's models could not be built.
    #[error(transparent)]
    Model(#[from] rigcal_model::model::ModelError),
    /// The frames-only fit of the nominal rows failed.
    #[error("fitting the measurement frame and marker of the nominal kinematics to {name}")]
    Nominal {
        /// The recording's name.
        name: String,
        /// The cause.
        source: rigcal_model::identification::IdentifyError,
    },
}

/// Orientation error statistics (degrees): identification's own
/// ([`rigcal_model::identification::pose::OrientationStats`]), so `identify` and `evaluate`
/// report one definition.
pub use rigcal_model::identification::pose::OrientationStats as AngleStats;

/// One model's score on the recording.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ModelScore {
    /// The model (`nominal, frame refitted`, `conventional`, `regions`, `fcmac`, …).
    pub model: String,
    /// How the measurement frame was set: `refitted`, `refitted with marker`, or `model's`.
    pub frame: String,
    /// 3-D position errors (mm).
    pub position: ResidualStats,
    /// Orientation errors (degrees), when the recording has orientations.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orientation: Option<AngleStats>,
}

/// Every model of a model file scored on one recording.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct RecordingScores {
    /// The model file.
    pub model_file: String,
    /// The recording.
    pub recording: String,
    /// Measured rows scored.
    pub points: usize,
    /// Whether each model's measurement frame was refitted to the recording.
    pub refit_frame: bool,
    /// Nominal rows first, then the model file's models.
    pub scores: Vec<ModelScore>,
}

/// One measured row: joints, approach directions, measured point and orientation.
struct Row {
    q: Vec<f64>,
    direction: Vec<i8>,
    p: Vector3<f64>,
    orientation: Option<UnitQuaternion<f64>>,
}

/// The measured rows, each with the approach direction of every joint (the sign of its last
/// change, as the effects' fit reads it).
fn rows_of(rec: &Recording) -> Vec<Row> {
    use rigcal_core::recording::Status;
    let mut direction: Vec<i8> = Vec::new();
    let mut prev: Option<&[f64]> = None;
    let mut rows = Vec::new();
    for m in &rec.rows {
        if direction.len() != m.q.len() {
            direction = vec![0; m.q.len()];
        }
        if let Some(p) = prev.filter(|p| p.len() == m.q.len()) {
            for (j, (a, b)) in m.q.iter().zip(p).enumerate() {
                if (a - b).abs() > 1e-9 {
                    direction[j] = if a > b { 1 } else { -1 };
                }
            }
        }
        prev = Some(&m.q);
        if let (Status::Ok, Some(p)) = (&m.status, m.position) {
            rows.push(Row {
                q: m.q.clone(),
                direction: direction.clone(),
                p,
                orientation: m.orientation,
            });
        }
    }
    rows
}

/// `e` with the measurement frame's parameters at nominal.
fn without_frame(chain: &SerialChain, e: &ErrorParams) -> ErrorParams {
    let mut e = e.clone();
    for (i, id) in chain.layout().ids().iter().enumerate() {
        if id.transform == TransformId::Frame {
            e.set(i, 0.0);
        }
    }
    e
}

/// The predicted marker point with the last link's orientation, in the chain's world frame.
fn pose(chain: &SerialChain, q: &[f64], e: &ErrorParams) -> Isometry3<f64> {
    let rotation = chain.tool_pose(q, e).rotation;
    Isometry3::from_parts(chain.position(q, e).into(), rotation)
}

/// Predicted tool poses of the rows (the marker point as translation), world frame as `e`'s.
type Predict<'a> = dyn Fn(&Row) -> Isometry3<f64> + 'a;

/// Scores predictions against the rows: with `refit` the predictions are computed with the
/// frame at nominal and registered onto the measured points first.
fn score(rows: &[Row], predict: &Predict<'_>, refit: bool) -> (ResidualStats, Option<AngleStats>) {
    let poses: Vec<Isometry3<f64>> = rows.iter().map(predict).collect();
    let frame = if refit {
        let model: Vec<Vector3<f64>> = poses.iter().map(|t| t.translation.vector).collect();
        let measured: Vec<Vector3<f64>> = rows.iter().map(|r| r.p).collect();
        kabsch(&model, &measured)
    } else {
        Isometry3::identity()
    };
    let errors: Vec<Vector3<f64>> = rows
        .iter()
        .zip(&poses)
        .map(|(r, t)| r.p - (frame * t).translation.vector)
        .collect();
    let rotations: Vec<(UnitQuaternion<f64>, UnitQuaternion<f64>)> = rows
        .iter()
        .zip(&poses)
        .filter_map(|(r, t)| r.orientation.map(|m| ((frame * t).rotation, m)))
        .collect();
    let orientation = (!rotations.is_empty()).then(|| orientation_errors(&rotations));
    (ResidualStats::of(&errors), orientation)
}

/// Orientation errors after the probe's constant rotation C (fitted, see the module docs).
fn orientation_errors(pairs: &[(UnitQuaternion<f64>, UnitQuaternion<f64>)]) -> AngleStats {
    let mut sum = Matrix3::zeros();
    for (p, m) in pairs {
        sum += p.to_rotation_matrix().matrix().transpose() * m.to_rotation_matrix().matrix();
    }
    let c = rigcal_model::identification::pose::nearest_rotation(&sum);
    let angles: Vec<f64> = pairs
        .iter()
        .map(|(p, m)| (p * c).rotation_to(m).angle())
        .collect();
    AngleStats::of_angles(&angles)
}

/// Scores the nominal kinematics and every model of the model file at `model_path` (read as
/// `file`, for `rig`) on the recording `rec` (named `name`); see the module docs.
pub fn evaluate_recording(
    rig: &Rig,
    file: &ModelFile,
    model_path: &Path,
    rec: &Recording,
    name: &str,
    refit_frame: bool,
) -> Result<RecordingScores, EvaluateRecordingError> {
    let rows = rows_of(rec);
    if rows.is_empty() {
        return Err(EvaluateRecordingError::NoMeasurements { name: name.into() });
    }
    let chain = &rig.chain;
    let nominal = ErrorParams::zeros(chain.layout());
    let mut scores = Vec::new();
    let (position, orientation) = score(&rows, &|r| pose(chain, &r.q, &nominal), true);
    scores.push(ModelScore {
        model: "nominal".into(),
        frame: "refitted".into(),
        position,
        orientation,
    });
    let obs = rec.observations();
    let (frames_chain, frames) = identify_at(rig, &obs, Level::Frames).map_err(|source| {
        EvaluateRecordingError::Nominal {
            name: name.into(),
            source,
        }
    })?;
    let (position, orientation) =
        score(&rows, &|r| pose(&frames_chain, &r.q, &frames.params), false);
    scores.push(ModelScore {
        model: "nominal".into(),
        frame: "refitted with marker".into(),
        position,
        orientation,
    });
    let frame_label = if refit_frame { "refitted" } else { "model's" };
    let models = file.error_models(rig, model_path)?;
    for (model_name, model) in &models {
        let params = |r: &Row| {
            let e = model.params_at(&r.q);
            if refit_frame {
                without_frame(chain, &e)
            } else {
                e
            }
        };
        let (position, orientation) = score(&rows, &|r| pose(chain, &r.q, &params(r)), refit_frame);
        scores.push(ModelScore {
            model: model_name.clone(),
            frame: frame_label.into(),
            position,
            orientation,
        });
        if model_name == "conventional" && !file.effects.is_empty() {
            let (position, orientation) = score(
                &rows,
                &|r| {
                    let e = params(r);
                    let ctx = rigcal_model::effects::EffectContext {
                        chain,
                        e: &e,
                        masses: &rig.link_masses,
                        payload_kg: 0.0,
                    };
                    let dq = joint_offsets(&file.effects, &ctx, &r.q, &r.direction);
                    let actual: Vec<f64> = r.q.iter().zip(&dq).map(|(a, b)| a + b).collect();
                    pose(chain, &actual, &e)
                },
                refit_frame,
            );
            let names: Vec<String> = file.effects.iter().map(|e| e.spec().label()).collect();
            scores.push(ModelScore {
                model: format!("conventional + {}", names.join(", ")),
                frame: frame_label.into(),
                position,
                orientation,
            });
        }
    }
    Ok(RecordingScores {
        model_file: model_path.display().to_string(),
        recording: name.into(),
        points: rows.len(),
        refit_frame,
        scores,
    })
}

/// The scores as `rigcal evaluate --recording` prints them: one line per model, position then
/// orientation.
pub fn recording_scores_text(s: &RecordingScores) -> String {
    let mut out = format!(
        "{} on {} ({} points){}\n",
        s.model_file,
        s.recording,
        s.points,
        if s.refit_frame {
            ", each model's measurement frame refitted to the recording"
        } else {
            ""
        }
    );
    let _ = writeln!(
        out,
        "  {:<40} {:<22} {:>9} {:>9} {:>9}   {:>8} {:>8} {:>8}",
        "model", "frame", "mean mm", "RMS mm", "max mm", "mean °", "RMS °", "max °"
    );
    for m in &s.scores {
        let o = m
            .orientation
            .map(|o| {
                format!(
                    "   {:>8.4} {:>8.4} {:>8.4}",
                    o.mean_deg, o.rms_deg, o.max_deg
                )
            })
            .unwrap_or_default();
        let _ = writeln!(
            out,
            "  {:<40} {:<22} {:>9.4} {:>9.4} {:>9.4}{o}",
            m.model, m.frame, m.position.mean_mm, m.position.rms_mm, m.position.max_mm
        );
    }
    out
}
