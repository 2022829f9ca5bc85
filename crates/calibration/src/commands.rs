//! Compensated joint commands for a targets file with a calibrated model, as `rigcal compensate`
//! writes them: the geometric compensation ([`compensate_targets`]), or, when the model holds
//! effects or a consistent approach is asked for, the hybrid one with via moves
//! ([`compensate_path`]); on a rig whose arm moves on the `cartesian` command path, each plain
//! command's `MP` pose beside it.
//!
//! A target that cannot be compensated does not stop the others unless `strict` is asked for:
//! its row keeps its place with empty command cells, and a `status` column, appended last so
//! positional readers still find the joints, says `ok` or why not. Empty cells rather than a
//! marker such as `NaN`: a CSV reader takes an empty cell as missing (pandas: NaN in a float
//! column), whereas `NaN` parses as a number in Rust and numpy and could reach a controller as
//! a command, and a word would turn the column into text.

use rigcal_core::kinematics::{IkError, Robot};
use rigcal_core::recording::{commands_csv, read_targets, RecordingError, Target};
use rigcal_devices::devices::drivers::movemaster::controller::{
    with_pose_columns, ControllerKinematics, PoseError,
};
use rigcal_devices::devices::CommandPath;
use rigcal_model::compensation::{
    compensate_each, CompensationError, CompensationOptions, TargetError,
};
use rigcal_model::model::effects::ModelEffect;
use rigcal_model::model::hybrid::{
    compensate_path_each, path_csv, Approach, HybridArm, HybridCommand, HybridOptions,
};
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
    /// Fail on the first target that cannot be compensated (no commands at all) instead of
    /// giving the others with a `status` column.
    pub strict: bool,
}

/// The commands of a targets file, and what `rigcal compensate` says about them.
#[derive(Debug, Clone)]
pub struct Commands {
    /// The commands as CSV: one row of joint commands (`q1_deg…`) per target, or with effects
    /// or a consistent approach one row per move with a `move` column; the `MP` pose columns
    /// on a `cartesian` rig; when a target could not be compensated, its row with empty cells
    /// and a last `status` column (`ok` or why not).
    pub csv: String,
    /// The largest modelled position error left (mm).
    pub worst_mm: f64,
    /// Targets in the file.
    pub targets: usize,
    /// The targets that could not be compensated, in order (empty with `strict`).
    pub failed: Vec<TargetError>,
    /// The targets file.
    pub path: PathBuf,
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
        if self.failed.is_empty() {
            s.push_str(&format!(
                "{} targets compensated (largest modelled error left {:.1e} mm); commands written to {}\n",
                self.targets,
                self.worst_mm,
                out.display()
            ));
        } else {
            s.push_str(&format!(
                "{} of {} targets compensated (largest modelled error left {:.1e} mm), {} not reachable; commands written to {} with a `status` column (empty commands where not `ok`)\n",
                self.targets - self.failed.len(),
                self.targets,
                self.worst_mm,
                self.failed.len(),
                out.display()
            ));
        }
        s
    }

    /// Whether every target was compensated.
    pub fn complete(&self) -> bool {
        self.failed.is_empty()
    }

    /// Each target that could not be compensated: `<targets file>: line N: why`, one a line.
    pub fn failures_text(&self) -> String {
        self.failed
            .iter()
            .map(|e| format!("{}: line {}: {}\n", self.path.display(), e.line, e.source))
            .collect()
    }
}

/// The `status` cell of a target that could not be compensated: the reason, briefly (the
/// target's position is in its row's line of the targets file).
pub fn status_text(e: &CompensationError) -> String {
    match e {
        CompensationError::Ik(IkError::Unreachable { closest_mm, .. }) => {
            format!("unreachable: {closest_mm:.3} mm away at closest")
        }
        CompensationError::Ik(IkError::JointLimit {
            joint,
            value,
            min,
            max,
            unit,
            ..
        }) => format!(
            "joint limit: joint {joint} would be at {value:.3} {unit} outside {min:.3}..{max:.3} {unit}"
        ),
        CompensationError::Ik(IkError::Singular { sigma_min, .. }) => {
            format!("singular pose: smallest singular value {sigma_min:.2e} mm/unit")
        }
        CompensationError::JointLimit {
            joint,
            value,
            min,
            max,
            unit,
            ..
        } => format!(
            "joint limit: compensated joint {joint} at {value:.4} {unit} outside {min}..{max} {unit}"
        ),
        CompensationError::NotConverged {
            residual_mm,
            iterations,
            ..
        } => format!(
            "not converged: {residual_mm:.2e} mm left after {iterations} iterations"
        ),
        other => format!("not compensated: {other}"),
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
    let (rows, worst_mm, failed) = if hybrid {
        hybrid_commands(&loaded, &list, opts)
    } else {
        plain_commands(&loaded, &list, command_path)?
    };
    let mut failed = failed;
    if opts.strict && !failed.is_empty() {
        return Err(at_line(failed.remove(0)));
    }
    Ok(Commands {
        csv: rows.csv(&failed),
        worst_mm,
        targets: list.len(),
        failed,
        path: targets.to_path_buf(),
        command_path,
        effects: loaded.file.effects,
    })
}

/// The CSV of the targets compensated, and where the others go.
struct Rows {
    /// Header and rows of the targets compensated, as if they were the only ones.
    compensated: String,
    /// Per target in order: the rows it takes in `compensated` (a via move and its command
    /// make two), or None when it could not be compensated.
    rows: Vec<Option<usize>>,
    /// The `move` cell of a target's row, when the CSV has that column.
    move_column: bool,
}

impl Rows {
    /// The CSV written: as `compensated` when every target is there, else one row per move
    /// with empty cells for each target missing and a last `status` column.
    fn csv(&self, failed: &[TargetError]) -> String {
        if failed.is_empty() {
            return self.compensated.clone();
        }
        let mut lines = self.compensated.lines();
        let header = lines.next().unwrap_or_default();
        let columns = header.split(',').count();
        let mut out = format!("{header},status\n");
        let mut reasons = failed.iter();
        for rows in &self.rows {
            match rows {
                Some(n) => {
                    for line in lines.by_ref().take(*n) {
                        out.push_str(line);
                        out.push_str(",ok\n");
                    }
                }
                None => {
                    let empty = columns - usize::from(self.move_column);
                    out.push_str(&",".repeat(empty.saturating_sub(1)));
                    if self.move_column {
                        out.push_str(",target");
                    }
                    let why = reasons
                        .next()
                        .map(|e| status_text(&e.source))
                        .unwrap_or_default();
                    out.push(',');
                    out.push_str(&csv_field(&why));
                    out.push('\n');
                }
            }
        }
        out
    }
}

/// A CSV cell holding `text`: quoted when it holds a comma, quote or line break.
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

/// The geometric compensation: the rows, the largest error left (mm) and the targets that
/// could not be compensated; on a `cartesian` rig each command's `MP` pose beside it.
fn plain_commands(
    loaded: &LoadedModel,
    targets: &[(u64, Target)],
    command_path: CommandPath,
) -> Result<(Rows, f64, Vec<TargetError>), CommandsError> {
    let chain = &loaded.rig.chain;
    let results = compensate_each(
        chain,
        loaded.errors.as_ref(),
        loaded.rig.held(),
        targets,
        &CompensationOptions::default(),
    );
    let rows = results.iter().map(|r| r.as_ref().ok().map(|_| 1)).collect();
    let (commands, failed) = split(results);
    let worst = commands.iter().map(|c| c.residual_mm).fold(0.0, f64::max);
    let joints: Vec<Vec<f64>> = commands.into_iter().map(|c| c.command).collect();
    let text = commands_csv(chain.joints(), joints.iter().map(Vec::as_slice));
    let compensated = if command_path == CommandPath::Cartesian {
        with_pose_columns(&text, &ControllerKinematics::of_rig(&loaded.rig)?, &joints)
    } else {
        text
    };
    let rows = Rows {
        compensated,
        rows,
        move_column: false,
    };
    Ok((rows, worst, failed))
}

/// The hybrid compensation (effects, via moves): the rows, the largest error left (mm) and the
/// targets that could not be compensated.
fn hybrid_commands(
    loaded: &LoadedModel,
    targets: &[(u64, Target)],
    opts: &CommandOptions,
) -> (Rows, f64, Vec<TargetError>) {
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
    let results = compensate_path_each(
        &arm,
        loaded.errors.as_ref(),
        &loaded.file.effects,
        targets,
        None,
        &opts,
    );
    let rows = results
        .iter()
        .map(|r| {
            r.as_ref()
                .ok()
                .map(|c: &HybridCommand| 1 + usize::from(c.via.is_some()))
        })
        .collect();
    let (path, failed) = split(results);
    let worst = path.iter().map(|c| c.residual_mm).fold(0.0, f64::max);
    let rows = Rows {
        compensated: path_csv(rig.chain.joints(), &path),
        rows,
        move_column: true,
    };
    (rows, worst, failed)
}

/// The results compensated and the failures, each in order.
fn split<T>(results: Vec<Result<T, TargetError>>) -> (Vec<T>, Vec<TargetError>) {
    let mut done = Vec::with_capacity(results.len());
    let mut failed = Vec::new();
    for r in results {
        match r {
            Ok(c) => done.push(c),
            Err(e) => failed.push(e),
        }
    }
    (done, failed)
}
