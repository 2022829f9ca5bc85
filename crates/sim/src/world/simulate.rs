//! A simulated session: given or random poses measured in a scenario's truth world, as a
//! recording with its sidecar (what `rigcal simulate` writes).
//!
//! Poses are taken in the order given, `seconds_per_point` apart (scenario `[measurement]`);
//! every random draw depends on (seed, seq, attempt) only, so a seed gives the same bytes.

use super::scenario::Scenario;
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::{Recording, RegistrationInfo, SessionInfo};
use rigcal_core::rig::{Instrument, Rig};
use rigcal_model::effects::setup_rng;
use rigcal_model::identification::random_poses;
use std::path::{Path, PathBuf};

/// Index of the setup generator that draws random poses (apart from the effects').
const POSES_STREAM: usize = usize::MAX - 1;

/// Why a session could not be simulated.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimulateError {
    /// The scenario was written for another rig.
    #[error("scenario {} assumes rig {} (`{}`), but --rig {} is `{}`", scenario.display(), scenario_rig.display(), scenario_rig_name, rig.display(), rig_name)]
    OtherRig {
        /// The scenario file.
        scenario: PathBuf,
        /// The rig file the scenario names.
        scenario_rig: PathBuf,
        /// That rig's name.
        scenario_rig_name: String,
        /// The rig file given.
        rig: PathBuf,
        /// Its name.
        rig_name: String,
    },
}

/// Checks that `scenario` was written for `rig` (same name and instrument).
pub fn check_same_rig(
    rig: &Rig,
    rig_path: &Path,
    scenario: &Scenario,
) -> Result<(), SimulateError> {
    if rig.name == scenario.rig.name && rig.instrument == scenario.rig.instrument {
        return Ok(());
    }
    Err(SimulateError::OtherRig {
        scenario: scenario.path.clone(),
        scenario_rig: scenario.rig_path.clone(),
        scenario_rig_name: scenario.rig.name.clone(),
        rig: rig_path.to_path_buf(),
        rig_name: rig.name.clone(),
    })
}

/// `n` random poses of the scenario's seed (the ones `rigcal simulate --random N` measures).
pub fn random_session_poses(rig: &Rig, scenario: &Scenario, n: usize) -> Vec<Vec<f64>> {
    let mut rng = setup_rng(scenario.seed, POSES_STREAM);
    random_poses(rig.chain.joints(), rig.held(), n, &mut rng)
}

/// Measures `poses` in the scenario's world (first seq 1) and describes the session in the
/// recording's sidecar; `rig_path` is recorded as given.
pub fn simulate_session(
    rig: &Rig,
    rig_path: &Path,
    scenario: &Scenario,
    poses: &[Vec<f64>],
) -> Result<Recording, SimulateError> {
    check_same_rig(rig, rig_path, scenario)?;
    let mut rec = scenario.world().record(poses, 1);
    rec.session = Some(session_info(rig, rig_path, scenario));
    Ok(rec)
}

fn session_info(rig: &Rig, rig_path: &Path, scenario: &Scenario) -> SessionInfo {
    // The simulated session measures through the nominal registration, as a session before any
    // registration step would.
    let registration = match &rig.instrument {
        Instrument::TablePanel(tp) => Some(RegistrationInfo {
            translation_mm: tp.table_to_world_mm.into(),
            rpy_deg: [0.0; 3],
            rms_mm: None,
        }),
        _ => None,
    };
    let what = if scenario.description.is_empty() {
        "simulated session"
    } else {
        &scenario.description
    };
    SessionInfo {
        rig: Some(rig_path.display().to_string()),
        scenario: Some(scenario.path.display().to_string()),
        seed: Some(scenario.seed),
        registration,
        notes: Some(format!("rigcal simulate: {what}")),
        ..Default::default()
    }
}
