//! `rigcal calibrate`: the variable D-H parameter model — recursive division, per-region CEPs and
//! a learner — from a recording (offline), a simulated world that measures what the division
//! asks for (planning), or a measurement session (planning through the rig); see
//! [`crate::calibration`].

use crate::calibration::{self, Calibrated, CalibrationOptions, NeuralOptions, PlanningFiles};
use crate::division::Space;
use crate::learners::{LearnerKind, LearnerSettings};
use crate::rig::Rig;
use anyhow::{bail, Result};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};

/// Arguments of `rigcal calibrate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Rig file (TOML).
    #[arg(long)]
    pub rig: PathBuf,
    /// Offline mode: divide using the points of this recording.
    #[arg(long, conflicts_with = "scenario")]
    pub recording: Option<PathBuf>,
    /// Planning mode: a simulated-world scenario measures wherever the division asks.
    #[arg(long, conflicts_with = "session")]
    pub scenario: Option<PathBuf>,
    /// Planning mode through the rig: a measurement session in this new directory measures
    /// wherever the division asks (the devices of the rig file, or emulators with --sim).
    #[arg(long, value_name = "DIR", conflicts_with = "recording")]
    pub session: Option<PathBuf>,
    /// With --session: a dry run on emulators of this scenario's world (virtual clock).
    #[arg(long, requires = "session")]
    pub sim: Option<PathBuf>,
    /// With --session: continue the session in DIR after a kill, crash or power cut. Give the
    /// first run's options again: the division asks for the points it finished once more and
    /// gets its recorded measurements, then the session measures on.
    #[arg(long, requires = "session")]
    pub resume: bool,
    /// Demanded accuracy after compensation (mm).
    #[arg(long, default_value_t = 0.1)]
    pub accuracy_mm: f64,
    /// Learner that generalises the region-wise CEPs.
    #[arg(long, value_enum, default_value_t = LearnerKind::Fcmac)]
    pub learner: LearnerKind,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Treat the region containing this point of the division space (q1,q2,q3 in degrees, or
    /// R mm,azimuth deg,elevation deg) as unmeasurable: its CEPs are dropped after the division
    /// and the learner must generalise there (seed 000 Fig. 8).
    #[arg(long, allow_hyphen_values = true, value_name = "A,B,C", value_parser = three_numbers)]
    pub unmeasurable_at: Option<[f64; 3]>,
    #[command(flatten)]
    pub paper: PaperArgs,
    #[command(flatten)]
    pub neural: NeuralArgs,
    /// Neural learners: with `--scenario`, the number of random poses measured (the paper's
    /// 110 regions × 20).
    #[arg(long, default_value_t = 2200)]
    pub measurements: usize,
    /// Where to write the model (JSON).
    #[arg(long)]
    pub out: PathBuf,
}

/// The division's and the learners' settings whose defaults are the paper's (seed 000).
#[derive(Debug, Clone, clap::Args)]
pub struct PaperArgs {
    /// Division space.
    #[arg(long, value_enum, default_value_t = Space::Joint)]
    pub division: Space,
    /// Most regions [default: 110 for joint, 130 for Cartesian division, as in the paper].
    #[arg(long)]
    pub max_regions: Option<usize>,
    /// Measurements per region.
    #[arg(long, default_value_t = 20)]
    pub per_region: usize,
    /// Test points per region (planning mode).
    #[arg(long, default_value_t = 20)]
    pub test_points: usize,
    /// Random poses the identifiable basis (the CEPs) is chosen on.
    #[arg(long, default_value_t = calibration::PAPER_DESIGN_POSES)]
    pub design_poses: usize,
    /// FCMAC sensors per input (the CMAC's cells too) [default: 17 on the first joint's
    /// coordinate, 11 on the others: 17,11,11 for joint, 11,17,11 for Cartesian division].
    #[arg(long, value_name = "A,B,C", value_parser = three_counts)]
    pub fcmac_sensors: Option<[usize; 3]>,
    /// FCMAC sensors an input excites per dimension (the paper's c).
    #[arg(long, value_name = "A,B,C", value_parser = three_counts, default_value = "3,3,3")]
    pub fcmac_c: [usize; 3],
    /// CMAC layers.
    #[arg(long, default_value_t = 3)]
    pub cmac_layers: usize,
}

/// Settings of the neural learners (`nn-direct`, `nn-inverse`).
#[derive(Debug, Clone, clap::Args)]
pub struct NeuralArgs {
    /// Neural learners: the scheme of seed 001, 2 (joint correction) or 4 (position
    /// correction). 4 is the default for arms: a joint correction computed by inverse
    /// kinematics blows up near singular poses (the stretched RV-M2).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(2..=4))]
    pub scheme: u8,
    /// Neural learners: hidden neurons.
    #[arg(long, default_value_t = 20)]
    pub hidden: usize,
    /// Neural learners: most epochs of batch back-propagation.
    #[arg(long, default_value_t = 3000)]
    pub epochs: usize,
    /// Neural learners: learning rate η on the batch-summed gradient [default: 0.46 / number
    /// of training poses, the paper's η = 0.01 at its 46 poses].
    #[arg(long)]
    pub learning_rate: Option<f64>,
}

/// Three comma-separated numbers.
fn three_numbers(text: &str) -> Result<[f64; 3], String> {
    let bad = || format!("`{text}`: give three numbers separated by commas");
    let v: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad())?;
    v.try_into().map_err(|_| bad())
}

/// Three comma-separated counts.
fn three_counts(text: &str) -> Result<[usize; 3], String> {
    let bad = || format!("`{text}`: give three whole numbers separated by commas");
    let v: Vec<usize> = text
        .split(',')
        .map(|v| v.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad())?;
    v.try_into().map_err(|_| bad())
}

impl PaperArgs {
    /// Calibration options with these settings, the rest at their defaults.
    pub(crate) fn options(
        &self,
        accuracy_mm: f64,
        learner: LearnerKind,
        seed: u64,
    ) -> CalibrationOptions {
        CalibrationOptions {
            space: self.division,
            accuracy_mm,
            max_regions: self.max_regions,
            per_region: self.per_region,
            test_points: self.test_points,
            design_poses: self.design_poses,
            learner,
            learner_settings: LearnerSettings {
                sensors: self.fcmac_sensors,
                c: self.fcmac_c,
                cmac_layers: self.cmac_layers,
            },
            seed,
            ..CalibrationOptions::default()
        }
    }
}

impl NeuralArgs {
    /// The neural options, `measurements` random poses from a scenario.
    pub(crate) fn options(&self, measurements: usize) -> NeuralOptions {
        NeuralOptions {
            scheme: self.scheme,
            hidden: self.hidden,
            epochs: self.epochs,
            learning_rate: self.learning_rate,
            measurements,
        }
    }
}

pub fn run(a: Args) -> Result<()> {
    let rig = Rig::load(&a.rig)?;
    let mut opts = a.paper.options(a.accuracy_mm, a.learner, a.seed);
    opts.neural = a.neural.options(a.measurements);
    opts.unmeasurable_at = a.unmeasurable_at;
    let calibrated = match (&a.recording, &a.scenario, &a.session) {
        (Some(dir), None, _) => {
            let rec = super::identify::read_recording(&rig, dir)?;
            let observations = super::observations(&rec);
            let label = dir.display().to_string();
            with_bar(&opts, |progress| {
                calibration::calibrate_with_progress(
                    &rig,
                    calibration::Source::Offline {
                        observations: &observations,
                        label,
                    },
                    &opts,
                    progress,
                )
            })?
        }
        (None, Some(scenario), _) => {
            let sc = crate::world::Scenario::load(scenario, None)?;
            with_bar(&opts, |progress| {
                calibration::calibrate_with_progress(
                    &rig,
                    calibration::Source::Scenario(&sc),
                    &opts,
                    progress,
                )
            })?
        }
        (None, None, Some(dir)) if !opts.is_neural() => through_session(&rig, &a, dir, &opts)?,
        (None, None, Some(_)) => return Err(calibration::CalibrationError::NeuralNeedsData.into()),
        _ => bail!("give --recording DIR (offline), --scenario FILE (planning on a simulated world) or --session DIR (planning through the rig)"),
    };
    calibrated.model.save(&a.out)?;
    println!("model written to {}", a.out.display());
    Ok(())
}

/// Runs a calibration under a progress bar of the division's regions and prints its figures.
pub(crate) fn with_bar(
    opts: &CalibrationOptions,
    run: impl FnOnce(&mut dyn FnMut(usize, usize)) -> Result<Calibrated, calibration::CalibrationError>,
) -> Result<Calibrated> {
    // A network does not divide: no bar.
    let bar = if opts.is_neural() {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(opts.region_cap() as u64)
    };
    bar.set_style(
        ProgressStyle::with_template("dividing {bar:30} {pos}/{len} regions {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let calibrated = run(&mut |n, _| bar.set_position(n as u64));
    bar.finish_and_clear();
    let calibrated = calibrated?;
    print!("{}", calibrated.text());
    Ok(calibrated)
}

/// Planning mode through a measurement session in `dir`: every measurement the division asks
/// for is made by the devices (emulated with `--sim`) and recorded there.
fn through_session(
    rig: &Rig,
    a: &Args,
    dir: &Path,
    opts: &CalibrationOptions,
) -> Result<Calibrated> {
    let files = PlanningFiles {
        rig: &a.rig,
        sim: a.sim.as_deref(),
    };
    if a.resume {
        calibration::refuse_other_options(dir, files, opts)?;
    }
    let note = calibration::planning_note(files, opts);
    let mut session = open_session(rig, a, dir, note)?;
    let recorded = if a.resume {
        let recorded = calibration::resumed_requests(rig, dir, session.points_done())?;
        eprintln!(
            "resuming {}: {} finished points replayed to the division, then measuring on",
            dir.display(),
            recorded.len()
        );
        recorded
    } else {
        Vec::new()
    };
    let calibrated = with_bar(opts, |progress| {
        calibration::through_session(rig, &mut session, dir, recorded, opts, progress)
    })?;
    let report = session.finish()?;
    println!(
        "session {}: {} points asked for{}, {} measured, {} skipped, rig time {:.0} s ({:.2} h){}",
        dir.display(),
        report.points,
        match report.resumed_at {
            Some(k) => format!(" ({k} from earlier runs, replayed; this run's counts follow)"),
            None => String::new(),
        },
        report.ok,
        report.skipped.len(),
        report.rig_time_s,
        report.rig_time_s / 3600.0,
        if a.sim.is_some() {
            " on the virtual clock"
        } else {
            ""
        }
    );
    Ok(calibrated)
}

/// Opens (or resumes) the planning-mode session in `dir` on the rig's devices, or on emulators
/// of `--sim`'s world; `note` records the options that shaped it.
fn open_session<'r>(
    rig: &'r Rig,
    a: &Args,
    dir: &Path,
    note: String,
) -> Result<crate::session::Session<'r>> {
    let scenario = super::session::load_scenario(rig, &a.rig, a.sim.as_deref(), None)?;
    let (devices, world) = super::session::open_rig(rig, scenario.as_ref(), false)?;
    let mut opts = crate::session::SessionOptions::new(dir);
    opts.seed = a.seed;
    opts.resume = a.resume;
    opts.fsync = !devices.clock.is_virtual();
    opts.info = crate::recording::SessionInfo {
        rig: Some(a.rig.display().to_string()),
        scenario: a.sim.as_ref().map(|p| p.display().to_string()),
        seed: scenario.as_ref().map(|s| s.seed),
        notes: Some(note),
        ..Default::default()
    };
    Ok(crate::session::Session::open(rig, devices, world, opts)?)
}
