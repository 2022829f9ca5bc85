//! rigcal's pipelines — the variable D-H parameter model of seed 000 as library calls: workspace division →
//! learner → model file, from a recording (offline), from a simulated world that measures where
//! the division asks, or through any [`Measurer`] (a measurement session: [`through_session`]);
//! with a neural learner, seed 001's network on the same measurements instead.
//!
//! - [`calibrate`]: one entry point for every source and learner; the paper's constants (region
//!   cap, design poses, FCMAC sensors and c) are [`CalibrationOptions`] with the paper's values
//!   as defaults (`rigcal_paper::preset` lists them).
//! - [`through_session`]: planning mode through an opened session, with resume.
//! - [`evaluate`](evaluate::evaluate): models along paths against a scenario's truth;
//!   [`PathFigures`] the same as data (and JSON), with the error inside an unmeasurable region;
//!   [`evaluate_files`] both from the files `rigcal evaluate` takes.
//! - [`compare`](compare::compare): conventional, variable D-H and neural side by side.
//! - [`commands`]: compensated joint commands for a targets file, as `rigcal compensate`
//!   writes them.
//! - [`conventional`]: conventional calibration as `rigcal identify` runs it, its text and
//!   model file; [`files`]: the recordings the commands read, with the path in the error.
//! - [`convert`]: a rig file from a URDF, and a calibration folded back into the URDF.
//! - [`rig_check`]: checking a model on the rig itself along a measurable path.
//!
//! Nothing here prints: each call returns the figures a command line shows, with a `text()`
//! that renders them as `rigcal` prints them.

#![warn(missing_docs)]
#![deny(clippy::unwrap_used)]

pub mod commands;
pub mod compare;
pub mod conventional;
pub mod convert;
pub mod evaluate;
pub mod evaluate_recording;
pub mod files;
mod neural;
pub mod path_figures;
pub mod rig_check;
mod through_session;
mod variable;

pub use compare::{
    compare, compare_files, measurements, paper_paths, simulated_observations, CompareFiles,
    CompareInput, Comparison, MethodRow,
};
pub use evaluate::{
    build_paths, effects_text, evaluate, fig6_path, fig7_path, path_table, traced_ceps,
    write_path_files, PathChoice, PathFiles, PathOptions, TracedCep,
};
pub use files::{read_heldout, read_recording, ReadRecordingError};
pub use path_figures::{evaluate_files, EvaluationJson, InsideFigures, MethodFigures, PathFigures};
pub use through_session::{
    command_path_text, open_session, planning_note, refuse_other_options, resumed_requests,
    through_session, PlanningFiles, PlanningSession, SessionCalibrated,
};
pub use variable::{with_learner, RegionParams, WorldMeasurer};

use rigcal_core::rig::Rig;
use rigcal_model::division::{DivisionError, Measurer, Selection, Space};
use rigcal_model::identification::Observation;
use rigcal_model::learners::{
    FcmacTraining, LearnerKind, LearnerSettings, SettingsError, TrainReport,
};
use rigcal_model::model::ModelFile;
use rigcal_sim::world::Scenario;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Settings of a calibration; every default is the paper's (seed 000, listed in
/// `rigcal_paper::preset`, and seed 001 for the network) or rigcal's where the paper says
/// nothing (test points, selection, learner tolerance). One field per setting a caller may
/// change, so that `..Default::default()` names only what differs: hence more than 12.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationOptions {
    /// Division space.
    pub space: Space,
    /// Demanded accuracy after compensation (mm; the paper's 0.1 by default).
    pub accuracy_mm: f64,
    /// Most regions; None: the paper's 110 for joint, 130 for Cartesian division
    /// ([`Space::paper_region_cap`]).
    pub max_regions: Option<usize>,
    /// Measurements per region (the paper's 20 by default).
    pub per_region: usize,
    /// Test points per region (planning mode): the 27 points of a 3 × 3 × 3 grid over the
    /// region (corners, edge midpoints, face centres, centre), then a Halton set; fewer take
    /// the corners first. 27 by default (the paper draws a number at random).
    pub test_points: usize,
    /// How each region's measurement locations are chosen from its candidates: `kappa` (the
    /// paper's: κ of eq. (4) lowered by random exchanges) or `d-optimal` (det of MᵀM raised by
    /// greedy choice and exchange passes). Either way a region keeps its parent's measurements
    /// that fall in it and measures only the missing ones.
    pub selection: Selection,
    /// Planning mode: a half keeps its parent's measurements that fall in it and measures only
    /// the missing ones (true); `--no-reuse` measures every region afresh (each region's fit
    /// uses only its own), for comparison.
    pub reuse_parent: bool,
    /// Random poses the identifiable basis (the CEPs) is chosen on (100 by default; the paper
    /// does not say).
    pub design_poses: usize,
    /// The learner that generalises the region-wise CEPs, or a neural network instead.
    pub learner: LearnerKind,
    /// Sizes of the FCMAC and CMAC (the paper's FCMAC by default).
    pub learner_settings: LearnerSettings,
    /// Train the learner on each region's CEPs with the part of their deviation from its
    /// parent's that the region's own measurements cannot see put back to the parent's, the
    /// predicted points moving by at most this fraction of the demanded accuracy (RMS over the
    /// region's measurements). Small regions are ill-conditioned and their least-squares CEPs
    /// wander along directions that cancel inside them but not in the learner's blend of
    /// neighbours. 0 (the paper's) trains on the CEPs as fitted; the regions' own CEPs are
    /// never changed. None: 0.5 for an FCMAC with position training, whose measured points
    /// the position training then puts right, so the tolerance only sets what the network
    /// carries where no measurement reaches; 0, the paper's, otherwise
    /// ([`learner_tolerance_in_use`](Self::learner_tolerance_in_use)).
    pub learner_tolerance: Option<f64>,
    /// A region is accepted when the upper confidence bound of its largest error from its test
    /// points, at this many standard deviations, meets the demand (planning mode; 0: on the
    /// test points' maximum, the paper's rule). See
    /// [`DivisionOptions::confidence_z`](rigcal_model::division::DivisionOptions).
    pub confidence_z: f64,
    /// Settings of a neural learner.
    pub neural: NeuralOptions,
    /// Seed of every random choice.
    pub seed: u64,
    /// A point of the division space (file units: deg, or mm for R) whose region cannot be
    /// measured (seed 000 Fig. 8): no measurement is taken (or, offline, used) inside it, so
    /// none reaches a fit; without a learner it takes its neighbours' mean CEPs, a learner
    /// generalises there.
    pub unmeasurable_at: Option<[f64; 3]>,
    /// The depth of that region in the division (the root is 0); None: the depth of the leaf
    /// containing the point in the same division made without it.
    pub unmeasurable_depth: Option<usize>,
    /// A half of a split region the rig cannot measure enough of becomes a region without
    /// measurements of its own instead of stopping the split (seed 000 section 7; see
    /// [`DivisionOptions::unmeasurable_halves`](rigcal_model::division::DivisionOptions)).
    pub unmeasurable_halves: bool,
    /// How each region's test is measured (planning mode): sequentially, reusing earlier
    /// tests ([`TestPlan`](rigcal_model::division::TestPlan)); the default, every test point
    /// afresh in one batch, is the paper's.
    pub test_plan: rigcal_model::division::TestPlan,
    /// Which failing region splits next (planning and offline; it matters at the region cap):
    /// [`SplitOrder`](rigcal_model::division::SplitOrder), the library's default unless a
    /// preset says otherwise.
    pub split_order: rigcal_model::division::SplitOrder,
    /// Regions' CEPs as a MAP estimate around their parent's (true, rigcal's) or the paper's
    /// plain least squares (false; [`DivisionOptions::map_prior`](rigcal_model::division::DivisionOptions)).
    pub map_prior: bool,
    /// Offline on a recording in an instrument's frame (a free measurement frame, registered
    /// first): which error parameters each region fits; the rest are held at the conventional
    /// fit's values in every region ([`RegionParams`]).
    pub region_params: RegionParams,
}

/// The learner tolerance of an FCMAC with position training when none is given. Chosen on data
/// no reported figure uses (docs/seeds.md): section 6 at seeds 101–120 along the tuning paths,
/// 0 (the paper's) against 0.5; 0.5 holds one more claim at ≥ 19 of 20 seeds (Fig. 7 at half
/// the measurements: 20/20 against 14/20) and loses none.
pub const POSITION_TRAINING_TOLERANCE: f64 = 0.5;

/// The design poses the identifiable basis is chosen on when none are given: the paper does not
/// say how many; rigcal's 100 (`rigcal_paper::preset`).
const DEFAULT_DESIGN_POSES: usize = 100;

impl Default for CalibrationOptions {
    fn default() -> Self {
        Self {
            space: Space::Joint,
            accuracy_mm: 0.1,
            max_regions: None,
            per_region: 20,
            test_points: 27,
            selection: Selection::Kappa,
            reuse_parent: true,
            design_poses: DEFAULT_DESIGN_POSES,
            learner: LearnerKind::Fcmac,
            learner_settings: LearnerSettings::default(),
            learner_tolerance: None,
            confidence_z: rigcal_model::division::CONFIDENCE_Z,
            neural: NeuralOptions::default(),
            seed: 1,
            unmeasurable_at: None,
            unmeasurable_depth: None,
            unmeasurable_halves: false,
            test_plan: rigcal_model::division::TestPlan::default(),
            split_order: rigcal_model::division::SplitOrder::default(),
            map_prior: true,
            region_params: RegionParams::default(),
        }
    }
}

impl CalibrationOptions {
    /// The region cap in use: the option's, or the paper's for the space.
    pub fn region_cap(&self) -> usize {
        self.max_regions
            .unwrap_or_else(|| self.space.paper_region_cap())
    }

    /// The learner tolerance in use: the option's, or [`POSITION_TRAINING_TOLERANCE`] for an
    /// FCMAC with position training, or 0 (the paper's).
    pub fn learner_tolerance_in_use(&self) -> f64 {
        let positions = self.learner == LearnerKind::Fcmac
            && self.learner_settings.training == FcmacTraining::Positions;
        self.learner_tolerance.unwrap_or(if positions {
            POSITION_TRAINING_TOLERANCE
        } else {
            0.0
        })
    }

    /// Whether the learner is a neural network (seed 001) rather than a CEP learner.
    pub fn is_neural(&self) -> bool {
        matches!(self.learner, LearnerKind::NnDirect | LearnerKind::NnInverse)
    }

    fn check(&self) -> Result<(), CalibrationError> {
        let bad = |option: &'static str, reason: &str| {
            Err(CalibrationError::Option {
                option,
                reason: reason.to_string(),
            })
        };
        if self.accuracy_mm.is_nan() || self.accuracy_mm <= 0.0 {
            return bad("--accuracy-mm", "must be positive");
        }
        if self.per_region < 6 {
            return bad("--per-region", "must be at least 6");
        }
        if self.region_cap() == 0 {
            return bad("--max-regions", "must be at least 1");
        }
        if self.design_poses < 6 {
            return bad("--design-poses", "must be at least 6");
        }
        if !(0.0..=10.0).contains(&self.confidence_z) {
            return bad(
                "--confidence-z",
                "must be between 0 (the test points' maximum) and 10 standard deviations",
            );
        }
        if !(0.0..=1.0).contains(&self.learner_tolerance_in_use()) {
            return bad(
                "--learner-tolerance",
                "must be a fraction of the demanded accuracy between 0 and 1",
            );
        }
        self.learner_settings.check()?;
        Ok(())
    }
}

/// Settings of a neural learner (`nn-direct`, `nn-inverse`), seed 001's.
#[derive(Debug, Clone, PartialEq)]
pub struct NeuralOptions {
    /// Neural learners: the scheme of seed 001, 2 (joint correction) or 4 (position
    /// correction). 4 is the default for arms: a joint correction computed by inverse
    /// kinematics blows up near singular poses (the stretched RV-M2).
    pub scheme: u8,
    /// Neural learners: hidden neurons.
    pub hidden: usize,
    /// Neural learners: most epochs of batch back-propagation.
    pub epochs: usize,
    /// Neural learners: learning rate η on the batch-summed gradient [default: 0.46 / number
    /// of training poses, the paper's η = 0.01 at its 46 poses].
    pub learning_rate: Option<f64>,
    /// Random poses measured on a scenario when no recording is given (the paper's 110
    /// regions × 20): by a neural learner, and by `compare` for every method.
    pub measurements: usize,
}

impl Default for NeuralOptions {
    fn default() -> Self {
        Self {
            scheme: 4,
            hidden: 20,
            epochs: 3000,
            learning_rate: None,
            measurements: 2200,
        }
    }
}

/// Where the measurements come from.
pub enum Source<'a> {
    /// Offline: the division uses the points of a recording that fall in each region.
    Offline {
        /// The measured rows.
        observations: &'a [Observation],
        /// What they are, for the model's provenance (the recording's path, say).
        label: String,
    },
    /// Planning on a scenario's simulated world, which measures wherever the division asks (a
    /// neural learner takes random poses of it instead).
    Scenario(&'a Scenario),
    /// Planning through any measurer (the rig, through a session).
    Measurer {
        /// What measures.
        measurer: &'a mut dyn Measurer,
        /// What it is, for the model's provenance.
        label: String,
    },
}

impl Source<'_> {
    /// `offline` or `planning`.
    fn mode_name(&self) -> &'static str {
        match self {
            Source::Offline { .. } => "offline",
            Source::Scenario(_) | Source::Measurer { .. } => "planning",
        }
    }
}

/// A calibration's result: the model file and the figures a command line prints.
#[derive(Debug, Clone)]
pub struct Calibrated {
    /// The model, ready to save.
    pub model: ModelFile,
    /// How it was made.
    pub figures: Figures,
}

impl Calibrated {
    /// The figures as `rigcal calibrate` prints them.
    pub fn text(&self) -> String {
        match &self.figures {
            Figures::Division(d) => d.text(),
            Figures::Neural(n) => n.text(),
        }
    }
}

/// How a calibration went.
#[derive(Debug, Clone, PartialEq)]
// One value per calibration, read by a person: boxing the division's figures would save
// nothing that matters and cost every caller a deref.
#[allow(clippy::large_enum_variant)]
pub enum Figures {
    /// The variable D-H model: division and learner.
    Division(DivisionFigures),
    /// A neural network.
    Neural(NeuralFigures),
}

/// How a division and its learner went: one field per figure `rigcal calibrate` prints (more
/// than 12: they are read one by one, and grouping them would only add a level).
#[derive(Debug, Clone, PartialEq)]
pub struct DivisionFigures {
    /// `offline` or `planning`.
    pub mode: String,
    /// Division space.
    pub space: Space,
    /// Demanded accuracy (mm).
    pub accuracy_mm: f64,
    /// Measurements per region asked for.
    pub per_region: usize,
    /// How measurement locations were chosen.
    pub selection: Selection,
    /// Region cap.
    pub max_regions: usize,
    /// Regions made (leaves).
    pub regions: usize,
    /// Regions that meet the accuracy on their test points.
    pub passing: usize,
    /// Identification measurements.
    pub measurements: usize,
    /// Test measurements (planning mode).
    pub test_measurements: usize,
    /// κ of eq. (4) over the regions: (median, max), when any is finite.
    pub kappa: Option<(f64, f64)>,
    /// The first regions left unsplit with a reason: (region id, reason).
    pub unsplit: Vec<(String, String)>,
    /// Conventional fit on the same data: (RMS, max) residual (mm).
    pub conventional_mm: (f64, f64),
    /// The region that could not be measured (Fig. 8); boxed, as most divisions have none.
    pub unmeasurable: Option<Box<UnmeasurableFigures>>,
    /// The learner, when one was trained.
    pub learner: Option<LearnerFigures>,
    /// The learner tolerance its CEPs were made with (fraction of `accuracy_mm`; 0: as fitted).
    pub learner_tolerance: f64,
    /// Time of the division.
    pub division_time: Duration,
    /// Time of the learner's training.
    pub learner_time: Duration,
}

/// The region of a Fig. 8 calibration that could not be measured.
#[derive(Debug, Clone, PartialEq)]
pub struct UnmeasurableFigures {
    /// The point asked for (file units: deg, or mm for R).
    pub at: [f64; 3],
    /// The region's id (`r0110…`).
    pub region: String,
    /// Its depth in the division.
    pub depth: usize,
    /// Its box (division-space units).
    pub bounds: rigcal_model::division::Bounds,
    /// The neighbours whose mean CEPs it takes; None when the division did not make it a
    /// region of its own (the cap came first).
    pub borrowed_from: Option<Vec<String>>,
}

/// How a CEP learner's training went.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum LearnerFigures {
    /// The FCMAC.
    Fcmac {
        /// Sensors per input.
        sensors: [usize; 3],
        /// Sensors excited per input.
        c: [usize; 3],
        /// Association cells.
        cells: usize,
        /// Training.
        report: Option<TrainReport>,
        /// The training on measured points that followed (`--fcmac-training positions`).
        positions: Option<rigcal_model::learners::PositionReport>,
    },
    /// Albus's CMAC.
    Cmac {
        /// Layers.
        layers: usize,
        /// Cells per dimension.
        cells: [usize; 3],
        /// Training.
        report: Option<TrainReport>,
    },
}

/// How a network's training went.
#[derive(Debug, Clone, PartialEq)]
pub struct NeuralFigures {
    /// The scheme.
    pub scheme: rigcal_model::neural::Scheme,
    /// The training settings.
    pub config: rigcal_model::neural::TrainConfig,
    /// Epochs run.
    pub epochs: usize,
    /// The epoch kept.
    pub best_epoch: usize,
    /// Training RMS (scaled units).
    pub train_rms: f64,
    /// Early-stopping RMS (scaled units), when a split was held out.
    pub validation_rms: Option<f64>,
    /// Training time (s).
    pub train_seconds: f64,
}

/// Why a calibration (or its evaluation) could not be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CalibrationError {
    /// An option out of its range.
    #[error("{option} {reason}")]
    Option {
        /// The option (as the command line spells it).
        option: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// The learner's settings make no network.
    #[error(transparent)]
    Learner(#[from] SettingsError),
    /// Nothing to calibrate from.
    #[error("{label}: no measured rows")]
    NoMeasurements {
        /// The source.
        label: String,
    },
    /// The scenario simulates another rig.
    #[error("scenario {} is for rig `{scenario_rig}`, not `{rig}`: pass --rig {}", scenario.display(), rig_path.display())]
    ScenarioRig {
        /// The scenario file.
        scenario: PathBuf,
        /// Its rig's name.
        scenario_rig: String,
        /// The rig in use.
        rig: String,
        /// The scenario's rig file.
        rig_path: PathBuf,
    },
    /// The scenario of a dry run emulates another rig than the one given.
    #[error("scenario {} assumes rig `{scenario_rig}`, but --rig {} is `{rig}`", scenario.display(), rig_path.display())]
    DryRunRig {
        /// The scenario file.
        scenario: PathBuf,
        /// Its rig's name.
        scenario_rig: String,
        /// The rig file given.
        rig_path: PathBuf,
        /// That rig's name.
        rig: String,
    },
    /// A network learns from given measurements, not by asking for them.
    #[error("the network learns from --recording DIR or --scenario FILE (--session is planning mode of the variable D-H model: run `rigcal session` first, then --recording)")]
    NeuralNeedsData,
    /// A scheme other than 2 or 4.
    #[error("--scheme {0}: use 2 or 4 with --learner nn-direct or nn-inverse")]
    Scheme(u8),
    /// The division failed.
    #[error(transparent)]
    Division(#[from] DivisionError),
    /// Training the network failed.
    #[error(transparent)]
    Neural(#[from] rigcal_model::neural::NeuralError),
    /// The conventional fit failed.
    #[error("conventional fit: {0}")]
    Fit(#[from] rigcal_model::identification::FitError),
    /// No recording to compare on and no scenario to simulate one.
    #[error("give --scenario to simulate measurements, or --recording and --validation")]
    NothingToCompare,
    /// The rig's devices (or their emulators) could not be opened.
    #[error(transparent)]
    Devices(#[from] rigcal_devices::devices::DeviceError),
    /// A session could not be opened (boxed: a session error is large, and rare).
    #[error(transparent)]
    OpenSession(Box<rigcal_devices::session::SessionError>),
    /// The session measuring for the division stopped.
    #[error("the session in {} stopped; its recording keeps every finished point", dir.display())]
    Session {
        /// The session directory.
        dir: PathBuf,
        /// Why it stopped (boxed: a session error is large, and rare).
        source: Box<rigcal_devices::session::SessionError>,
    },
    /// A recording or session file could not be read.
    #[error("reading {}", path.display())]
    Recording {
        /// The file or directory.
        path: PathBuf,
        /// The cause.
        source: rigcal_core::recording::RecordingError,
    },
    /// A resumed session that was not started by a planning-mode calibration.
    #[error("{}: its session.toml does not say which `rigcal calibrate --session` options made it; resume only sessions this command started", dir.display())]
    NotPlanningSession {
        /// The session directory.
        dir: PathBuf,
    },
    /// A resume with other options than the session was started with.
    #[error("{} was measured with other options; resume it with the same ones\n  recorded: {recorded}\n  given:    {given}", dir.display())]
    OtherOptions {
        /// The session directory.
        dir: PathBuf,
        /// The options recorded in its session.toml.
        recorded: String,
        /// The options given now.
        given: String,
    },
    /// The journal and the recording of a resumed session disagree.
    #[error("{}: the journal has {journal} finished points but the recording {recorded} requests of region div; was it written by `rigcal calibrate --session`?", dir.display())]
    ResumeMismatch {
        /// The session directory.
        dir: PathBuf,
        /// Points the journal has finished.
        journal: usize,
        /// Division requests in the recording.
        recorded: usize,
    },
    /// A session whose registration was to be reused has none.
    #[error("{}: its session.toml holds no [registration]", dir.display())]
    NoRegistration {
        /// The session directory.
        dir: PathBuf,
    },
    /// A model file could not be used.
    #[error(transparent)]
    Model(#[from] rigcal_model::model::ModelError),
    /// A model without a region tree where one is needed.
    #[error("the model is not a variable D-H model of this rig (no region tree with its CEPs)")]
    NotVariable,
    /// A scenario file could not be used.
    #[error(transparent)]
    Scenario(#[from] rigcal_sim::world::ScenarioError),
    /// The model and the scenario are for different rigs.
    #[error("the model is for rig `{model_rig}` but scenario {} is for `{scenario_rig}`", scenario.display())]
    ModelScenarioRig {
        /// The model's rig.
        model_rig: String,
        /// The scenario file.
        scenario: PathBuf,
        /// Its rig's name.
        scenario_rig: String,
    },
    /// A path that cannot be made.
    #[error(transparent)]
    Path(#[from] rigcal_model::report::PathError),
    /// A path given in words that are not a path.
    #[error("{0}")]
    PathWords(String),
    /// A traced CEP the rig does not have.
    #[error("traced CEP `{0}` does not exist in the rig (names like theta1, d1, a1, alpha1)")]
    UnknownCep(String),
    /// A compensated command could not be made for a target of a path.
    #[error("compensating the target ({:.3}, {:.3}, {:.3}) mm", target[0], target[1], target[2])]
    Compensation {
        /// The target (mm).
        target: [f64; 3],
        /// The cause.
        source: rigcal_model::compensation::CompensationError,
    },
    /// A point of a path could not be compensated.
    #[error("path point {line}")]
    PathPoint {
        /// The point (from 1).
        line: u64,
        /// The cause.
        source: rigcal_model::compensation::CompensationError,
    },
    /// A file of figures could not be written.
    #[error("writing {}", path.display())]
    Writing {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Figures could not be put as JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// A file could not be written.
    #[error("cannot write {}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

/// Calibrates `rig` from `source` with `opts`: the variable D-H model (division, CEPs per
/// region, a learner), or a neural network with a neural learner.
pub fn calibrate(
    rig: &Rig,
    source: Source<'_>,
    opts: &CalibrationOptions,
) -> Result<Calibrated, CalibrationError> {
    calibrate_with_progress(rig, source, opts, &mut |_, _| {})
}

/// [`calibrate`], reporting the division's progress as (regions, region cap).
pub fn calibrate_with_progress(
    rig: &Rig,
    source: Source<'_>,
    opts: &CalibrationOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Calibrated, CalibrationError> {
    if opts.is_neural() {
        return neural::calibrate(rig, source, opts);
    }
    variable::calibrate(rig, source, opts, progress)
}

/// Refuses a scenario made for another rig (a world that simulates another arm).
pub fn check_scenario_rig(rig: &Rig, sc: &Scenario) -> Result<(), CalibrationError> {
    if sc.rig.name == rig.name {
        return Ok(());
    }
    Err(CalibrationError::ScenarioRig {
        scenario: sc.path.clone(),
        scenario_rig: sc.rig.name.clone(),
        rig: rig.name.clone(),
        rig_path: sc.rig_path.clone(),
    })
}

/// The scenario of a dry run (`sim`, its own seed overridden by `sim_seed`), checked against
/// the rig in use (`rig_path` names it in the error): same rig name and instrument. None
/// without a scenario: the rig's own devices.
pub fn dry_run_scenario(
    rig: &Rig,
    rig_path: &Path,
    sim: Option<&Path>,
    sim_seed: Option<u64>,
) -> Result<Option<Scenario>, CalibrationError> {
    let Some(p) = sim else {
        return Ok(None);
    };
    let s = Scenario::load(p, sim_seed)?;
    if s.rig.name != rig.name || s.rig.instrument != rig.instrument {
        return Err(CalibrationError::DryRunRig {
            scenario: s.path.clone(),
            scenario_rig: s.rig.name.clone(),
            rig_path: rig_path.to_path_buf(),
            rig: rig.name.clone(),
        });
    }
    Ok(Some(s))
}

/// The identifiable basis (layout indices) on `opts.design_poses` random poses.
fn design_basis(rig: &Rig, opts: &CalibrationOptions) -> Vec<usize> {
    use rand::SeedableRng;
    let design = rigcal_model::identification::random_poses(
        rigcal_core::kinematics::Robot::joints(&rig.chain),
        rig.held(),
        opts.design_poses,
        &mut rand::rngs::ChaCha8Rng::seed_from_u64(opts.seed),
    );
    rigcal_model::identification::analyse(
        &rig.chain,
        &design,
        &rigcal_model::identification::candidate_order(rig),
    )
    .basis
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // a failing test says where
mod tests;
