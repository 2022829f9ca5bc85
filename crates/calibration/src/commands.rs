//! Compensated joint commands for a targets file with a calibrated model, as `rigcal compensate`
//! writes them: the geometric compensation ([`compensate_targets`]), or, when the model holds
//! effects or a consistent approach is asked for, the hybrid one with via moves
//! ([`compensate_path`]); on a rig whose arm moves on the `cartesian` command path, each plain
//! command's `MP` pose beside it.

use rigcal_core::kinematics::Robot;
use rigcal_core::recording::{commands_csv, read_targets, RecordingError, Target};
use rigcal_devices::devices::drivers::movemaster::controller::{
    with_pose_columns, ControllerKinematics, PoseError,
};
use rigcal_devices::devices::CommandPath;
use rigcal_model::compensation::{
    compensate_targets, CompensationError, CompensationOptions, TargetError,
};
use rigcal_model::model::effects::ModelEffect;
use rigcal_model::model::hybrid::{compensate_path, path_csv, Approach, HybridArm, HybridOptions};
use rigcal_model::model::{LoadedModel, ModelError, ModelFile};
use std::path::{Path, PathBuf};

/// How the commands are made.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CommandOptions {
    /// How backlash sees each target: from the path's order, or every target from below
    /// through a via move.
    pub approach: Approach,
    /// Payload at the tool (kg), for the model's joint compliance.
    pub payload_kg: f64,
}

/// The commands of a targets file, and what `rigcal compensate` says about them.
#[derive(Debug, Clone)]
pub struct Commands {
    /// The commands as CSV: one row of joint commands (`q1_deg…`) per target, or with effects
    /// or a consistent approach one row per move with a `move` column; the `MP` pose columns
    /// on a `cartesian` rig.
    pub csv: String,
    /// The largest modelled position error left (mm).
    pub worst_mm: f64,
    /// Targets compensated.
    pub targets: usize,
    /// The rig's command path for compensated moves.
    pub command_path: CommandPath,
    /// The effects the model compensates beside the geometry.
    pub effects: Vec<ModelEffect>,
}

impl Commands {
    /// What `rigcal compensate` prints once the commands are written to `out`.
    pub fn text(&self, out: &Path) -> String {
        let mut s = format!("command path: {}\n", self.command_path);
        for e in &self.effects {
            s.push_str(&format!("compensating {}\n", e.text()));
        }
        s.push_str(&format!(
            "{} targets compensated (largest modelled error left {:.1e} mm); commands written to {}\n",
            self.targets,
            self.worst_mm,
            out.display()
        ));
        s
    }
}

/// Why the commands could not be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CommandsError {
    /// The model file could not be used.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The targets file could not be read.
    #[error(transparent)]
    Targets(#[from] RecordingError),
    /// A negative or non-finite payload.
    #[error("--payload-kg must be zero or positive")]
    Payload,
    /// A target that could not be compensated.
    #[error("{}: line {line}", path.display())]
    Target {
        /// The targets file.
        path: PathBuf,
        /// The target's line in it.
        line: u64,
        /// Why.
        source: CompensationError,
    },
    /// The controller's kinematics for the `MP` poses could not be set up.
    #[error(transparent)]
    Controller(#[from] PoseError),
}

/// The compensated commands for the targets in the file `targets` with the model in the file
/// `model`.
pub fn compensate_files(
    model: &Path,
    targets: &Path,
    opts: &CommandOptions,
) -> Result<Commands, CommandsError> {
    let loaded = ModelFile::load(model)?;
    let list = read_targets(targets, loaded.rig.chain.joints())?;
    let at_line = |e: TargetError| CommandsError::Target {
        path: targets.to_path_buf(),
        line: e.line,
        source: e.source,
    };
    if !(opts.payload_kg.is_finite() && opts.payload_kg >= 0.0) {
        return Err(CommandsError::Payload);
    }
    let hybrid = !loaded.file.effects.is_empty() || opts.approach == Approach::Consistent;
    let command_path = rigcal_devices::config::DevicesConfig::read_opt(&loaded.rig)
        .map(|d| d.arm.command_path)
        .unwrap_or_default();
    let (csv, worst_mm) = if hybrid {
        hybrid_commands(&loaded, &list, opts).map_err(at_line)?
    } else {
        let (csv, worst, joints) = plain_commands(&loaded, &list).map_err(at_line)?;
        let csv = if command_path == CommandPath::Cartesian {
            with_pose_columns(&csv, &ControllerKinematics::of_rig(&loaded.rig)?, &joints)
        } else {
            csv
        };
        (csv, worst)
    };
    Ok(Commands {
        csv,
        worst_mm,
        targets: list.len(),
        command_path,
        effects: loaded.file.effects,
    })
}

/// The geometric compensation: the CSV, the largest error left (mm) and the commands (rad).
fn plain_commands(
    loaded: &LoadedModel,
    targets: &[(u64, Target)],
) -> Result<(String, f64, Vec<Vec<f64>>), TargetError> {
    let chain = &loaded.rig.chain;
    let commands = compensate_targets(
        chain,
        loaded.errors.as_ref(),
        loaded.rig.held(),
        targets,
        &CompensationOptions::default(),
    )?;
    let worst = commands.iter().map(|c| c.residual_mm).fold(0.0, f64::max);
    let text = commands_csv(
        chain.joints(),
        commands.iter().map(|c| c.command.as_slice()),
    );
    Ok((
        text,
        worst,
        commands.into_iter().map(|c| c.command).collect(),
    ))
}

/// The hybrid compensation (effects, via moves): the CSV and the largest error left (mm).
fn hybrid_commands(
    loaded: &LoadedModel,
    targets: &[(u64, Target)],
    opts: &CommandOptions,
) -> Result<(String, f64), TargetError> {
    let rig = &loaded.rig;
    let arm = HybridArm {
        chain: &rig.chain,
        masses: &rig.link_masses,
        held: rig.held(),
    };
    let opts = HybridOptions {
        approach: opts.approach,
        payload_kg: opts.payload_kg,
        ..HybridOptions::default()
    };
    let path = compensate_path(
        &arm,
        loaded.errors.as_ref(),
        &loaded.file.effects,
        targets,
        None,
        &opts,
    )?;
    let worst = path.iter().map(|c| c.residual_mm).fold(0.0, f64::max);
    Ok((path_csv(rig.chain.joints(), &path), worst))
}
