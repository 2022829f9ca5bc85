//! Setting a session up as `rigcal session` does: the session directory checked, the plan kept
//! in it (`plan.csv`, written at the start and read back from there on a resume), the rig time
//! estimated beforehand, and the [`SessionOptions`] the session runs with.

use std::path::{Path, PathBuf};

use crate::session::journal::JOURNAL_FILE;
use crate::session::options::SessionOptions;
use crate::session::plan::{
    estimate, plan, read_plan, registration_points, write_plan, ContactSettings, PlanError,
    PlanOptions, PlannedPoint, RigTimeEstimate,
};
use crate::session::procedure::ContactProcedure;
use crate::session::run::CSV_FILE;
use crate::session::speeds::RigSpeeds;
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::{Recording, RecordingError, RegistrationInfo, SessionInfo};
use rigcal_core::rig::Rig;

/// The session's own copy of its plan, in the session directory.
pub const PLAN_FILE: &str = "plan.csv";

/// Why a session could not be set up.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SetupError {
    /// A new session would overwrite a recording.
    #[error("{} already holds a recording; resume it with --resume or choose another --out", dir.display())]
    AlreadyRecorded {
        /// The session directory.
        dir: PathBuf,
    },
    /// A resume where no session was begun.
    #[error("{}: no session to resume here (no {JOURNAL_FILE}); start one without --resume", dir.display())]
    NothingToResume {
        /// The session directory.
        dir: PathBuf,
    },
    /// The session directory could not be made.
    #[error("creating {}", dir.display())]
    CreateDir {
        /// The session directory.
        dir: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The session whose registration is to be reused could not be read.
    #[error("reading the session {}", dir.display())]
    ReadSession {
        /// Its directory.
        dir: PathBuf,
        /// The cause.
        source: RecordingError,
    },
    /// The session whose registration is to be reused has none.
    #[error("{}: its session.toml holds no [registration]", dir.display())]
    NoRegistration {
        /// Its directory.
        dir: PathBuf,
    },
    /// The plan could not be made, read or written.
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// The session's plan could not be read back.
    #[error("reading the session plan {}", path.display())]
    ReadPlan {
        /// The plan file.
        path: PathBuf,
        /// The cause.
        source: PlanError,
    },
}

/// Where a fresh session's points come from.
#[derive(Debug, Clone)]
pub enum PlanSource<'a> {
    /// A plan file (from `rigcal plan`).
    File(&'a Path),
    /// Planned now with these options.
    Make(PlanOptions),
}

/// How a session is set up: the command line's choices, which the session directory, its
/// `session.toml` and the estimate follow.
#[derive(Debug, Clone)]
pub struct SessionSetup<'a> {
    /// The session directory (measurements.csv, session.toml, journal.json, plan.csv).
    pub dir: &'a Path,
    /// Continue the session in `dir` from its journal.
    pub resume: bool,
    /// The rig file, noted in session.toml.
    pub rig_file: &'a Path,
    /// The scenario file of a dry run, noted in session.toml.
    pub scenario_file: Option<&'a Path>,
    /// The scenario's own seed, noted in session.toml.
    pub scenario_seed: Option<u64>,
    /// Seed of the plan and the registration poses.
    pub seed: u64,
    /// The contact procedure on the table rig.
    pub procedure: ContactProcedure,
    /// Poses of the registration step.
    pub registration_points: usize,
    /// An earlier session directory whose registration is reused instead of registering again.
    pub registration_from: Option<&'a Path>,
    /// fsync every row and journal even on the virtual clock (always on with real devices).
    pub fsync: bool,
}

impl SessionSetup<'_> {
    /// Refuses a fresh session over a recording and a resume where there is no session, then
    /// makes the directory. Called before planning: a refused run touches none of its files.
    pub fn prepare_dir(&self) -> Result<(), SetupError> {
        let dir = self.dir.to_path_buf();
        if !self.resume && self.dir.join(CSV_FILE).exists() {
            return Err(SetupError::AlreadyRecorded { dir });
        }
        if self.resume && !self.dir.join(JOURNAL_FILE).exists() {
            return Err(SetupError::NothingToResume { dir });
        }
        std::fs::create_dir_all(self.dir).map_err(|source| SetupError::CreateDir { dir, source })
    }

    /// The session's plan file ([`PLAN_FILE`] in its directory).
    pub fn plan_path(&self) -> PathBuf {
        self.dir.join(PLAN_FILE)
    }

    /// The session's plan. On a fresh run it is read or made from `source` (made: its dropped
    /// candidates are written beside the plan file and their summary handed to `dropped`) and
    /// written to the plan file; then, on a fresh and a resumed run (`source` None) alike, it
    /// is read back from there.
    pub fn plan(
        &self,
        rig: &Rig,
        source: Option<PlanSource<'_>>,
        dropped: &mut dyn FnMut(&str),
    ) -> Result<Vec<PlannedPoint>, SetupError> {
        let path = self.plan_path();
        if let Some(source) = source {
            let points = match source {
                PlanSource::File(p) => read_plan(p, rig)?,
                PlanSource::Make(opts) => {
                    let p = plan(rig, &opts)?;
                    dropped(&p.write_dropped(rig, &path)?);
                    p.points
                }
            };
            write_plan(&path, rig, &points)?;
        }
        read_plan(&path, rig).map_err(|source| SetupError::ReadPlan { path, source })
    }

    /// The rig time the session should take: the registration step's own poses first (none
    /// when the registration is reused, or on a resume, which estimates the whole plan again),
    /// then `points`.
    pub fn estimate(&self, rig: &Rig, points: &[PlannedPoint]) -> RigTimeEstimate {
        let registration = if self.registration_from.is_none() && !self.resume {
            registration_points(rig, self.registration_points, self.seed)
        } else {
            Vec::new()
        };
        estimate(
            rig,
            &[registration.as_slice(), points].concat(),
            &RigSpeeds::of(rig),
            &ContactSettings::for_procedure(rig, self.procedure),
        )
    }

    /// The options of a session of `points` planned points; `virtual_clock` for a dry run on
    /// the virtual clock (fsync then only when asked for). A reused registration is read from
    /// its session here.
    pub fn options(
        &self,
        rig: &Rig,
        points: usize,
        virtual_clock: bool,
    ) -> Result<SessionOptions, SetupError> {
        let mut opts = SessionOptions::new(self.dir);
        opts.resume = self.resume;
        opts.registration_points = self.registration_points;
        if let Some(dir) = self.registration_from {
            opts.registration = Some(reused_registration(rig, dir)?);
        }
        opts.seed = self.seed;
        opts.procedure = self.procedure;
        opts.fsync = self.fsync || !virtual_clock;
        opts.info = SessionInfo {
            rig: Some(self.rig_file.display().to_string()),
            scenario: self.scenario_file.map(|p| p.display().to_string()),
            seed: self.scenario_seed,
            notes: Some(format!(
                "rigcal session: {points} points, {} contact procedure{}",
                self.procedure.name(),
                if virtual_clock {
                    ", dry run on the virtual clock"
                } else {
                    ""
                }
            )),
            ..Default::default()
        };
        Ok(opts)
    }
}

/// The registration of the earlier session in `dir`, to reuse (same rig set-up).
fn reused_registration(rig: &Rig, dir: &Path) -> Result<RegistrationInfo, SetupError> {
    let rec =
        Recording::read(dir, rig.chain.joints()).map_err(|source| SetupError::ReadSession {
            dir: dir.to_path_buf(),
            source,
        })?;
    rec.session
        .and_then(|s| s.registration)
        .ok_or_else(|| SetupError::NoRegistration {
            dir: dir.to_path_buf(),
        })
}
