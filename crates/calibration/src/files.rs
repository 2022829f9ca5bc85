//! Reading the files the commands take, with the path in the error: recordings, each for a
//! rig, and the scenario a twin replays a recording in.

use rigcal_core::kinematics::Robot;
use rigcal_core::recording::import::{check_scale, ScaleMismatch};
use rigcal_core::recording::{Recording, RecordingError};
use rigcal_core::rig::Rig;
use rigcal_model::identification::HeldOut;
use rigcal_sim::world::{Scenario, ScenarioError};
use std::path::{Path, PathBuf};

/// A recording that could not be read for a rig.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReadRecordingError {
    /// The files could not be read or parsed.
    #[error("reading the recording {} for rig `{rig}` ({joints} joints)", path.display())]
    Read {
        /// The recording's directory or CSV file.
        path: PathBuf,
        /// The rig's name.
        rig: String,
        /// The rig's joints.
        joints: usize,
        /// The cause (boxed: a recording error is large, and rare).
        source: Box<RecordingError>,
    },
    /// The recording's positions or orientations are not on the rig's scale (metres written as
    /// millimetres, radians as degrees): refused before anything is fitted to them.
    #[error("the recording {} does not fit rig `{rig}`: {source}", path.display())]
    Scale {
        /// The recording's directory or CSV file.
        path: PathBuf,
        /// The rig's name.
        rig: String,
        /// What does not fit, and the likely cause.
        source: ScaleMismatch,
    },
}

/// Reads the measured rows of the recording at `path` (a directory with measurements.csv, or a
/// CSV file) for `rig`, and checks that they are on the rig's scale ([`check_scale`]: the same
/// check `rigcal import` makes, for recordings written by other means).
pub fn read_recording(rig: &Rig, path: &Path) -> Result<Recording, ReadRecordingError> {
    let rec = Recording::read_measured(path, rig.chain.joints()).map_err(|source| {
        ReadRecordingError::Read {
            path: path.to_path_buf(),
            rig: rig.name.clone(),
            joints: rig.chain.joints().len(),
            source: Box::new(source),
        }
    })?;
    check_scale(&rec, &rig.chain, None).map_err(|source| ReadRecordingError::Scale {
        path: path.to_path_buf(),
        rig: rig.name.clone(),
        source,
    })?;
    Ok(rec)
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
