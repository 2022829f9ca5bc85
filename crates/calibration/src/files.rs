//! Reading the files the commands take, with the path in the error: recordings, each for a
//! rig, and the scenario a twin replays a recording in.

use rigcal_core::kinematics::Robot;
use rigcal_core::recording::{Recording, RecordingError};
use rigcal_core::rig::Rig;
use rigcal_model::identification::HeldOut;
use rigcal_sim::world::{Scenario, ScenarioError};
use std::path::{Path, PathBuf};

/// A recording that could not be read for a rig.
#[derive(Debug, thiserror::Error)]
#[error("reading the recording {} for rig `{rig}` ({joints} joints)", path.display())]
pub struct ReadRecordingError {
    /// The recording's directory or CSV file.
    pub path: PathBuf,
    /// The rig's name.
    pub rig: String,
    /// The rig's joints.
    pub joints: usize,
    /// The cause (boxed: a recording error is large, and rare).
    pub source: Box<RecordingError>,
}

/// Reads the measured rows of the recording at `path` (a directory with measurements.csv, or a
/// CSV file) for `rig`.
pub fn read_recording(rig: &Rig, path: &Path) -> Result<Recording, ReadRecordingError> {
    Recording::read_measured(path, rig.chain.joints()).map_err(|source| ReadRecordingError {
        path: path.to_path_buf(),
        rig: rig.name.clone(),
        joints: rig.chain.joints().len(),
        source: Box::new(source),
    })
}

/// Reads held-out recordings (or training sessions), each named by its path.
pub fn read_heldout(rig: &Rig, paths: &[PathBuf]) -> Result<Vec<HeldOut>, ReadRecordingError> {
    paths
        .iter()
        .map(|p| {
            Ok(HeldOut {
                name: p.display().to_string(),
                recording: read_recording(rig, p)?,
            })
        })
        .collect()
}

/// A twin's scenario that could not be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TwinScenarioError {
    /// The file could not be read.
    #[error("reading {}", path.display())]
    Read {
        /// The scenario file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The file is not a scenario.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The scenario runs another rig than the recording is read with.
    #[error("the scenario {} runs rig `{scenario_rig}`, the recording is read with rig `{rig}`", path.display())]
    OtherRig {
        /// The scenario file.
        path: PathBuf,
        /// Its rig's name.
        scenario_rig: String,
        /// The rig the recording is read with.
        rig: String,
    },
}

/// The scenario file `sim` a twin replays a recording of `rig` in, with its text (the twin
/// writes an updated copy of it).
pub fn twin_scenario(rig: &Rig, sim: &Path) -> Result<(Scenario, String), TwinScenarioError> {
    let source = std::fs::read_to_string(sim).map_err(|source| TwinScenarioError::Read {
        path: sim.to_path_buf(),
        source,
    })?;
    let scenario = Scenario::parse(&source, sim, None)?;
    if scenario.rig.name != rig.name {
        return Err(TwinScenarioError::OtherRig {
            path: sim.to_path_buf(),
            scenario_rig: scenario.rig.name.clone(),
            rig: rig.name.clone(),
        });
    }
    Ok((scenario, source))
}
