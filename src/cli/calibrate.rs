//! `rigcal calibrate`: the variable D-H parameter model — recursive division, per-region CEPs and
//! a learner — from a recording (offline), a simulated world that measures what the division
//! asks for (planning), or a measurement session (planning through the rig); see
//! [`rigcal_calibration`].

use anyhow::{bail, Result};
use indicatif::{ProgressBar, ProgressStyle};
use rigcal_calibration::{
    self as calibration, Calibrated, CalibrationError, CalibrationOptions, PlanningFiles, Source,
};
use rigcal_core::rig::Rig;
use rigcal_devices::devices::controller::CommandPath;
use rigcal_model::learners::LearnerKind;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

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
    /// Make the region containing this point of the division space (q1,q2,q3 in degrees, or
    /// R mm,azimuth deg,elevation deg) unmeasurable (seed 000 Fig. 8): no measurement is taken
    /// inside it (offline: no recorded point inside it is used), so none reaches a fit. Without
    /// a learner the region takes the mean CEPs of its neighbours; the learner generalises
    /// there. `rigcal evaluate` reports the error inside it.
    #[arg(long, allow_hyphen_values = true, value_name = "A,B,C", value_parser = three_numbers)]
    pub unmeasurable_at: Option<[f64; 3]>,
    /// The depth of that region in the division (0 is the whole workspace) [default: the depth
    /// of the leaf containing the point in the division made without it, found by a first
    /// division whose measurements are then dropped; a session needs the depth given].
    #[arg(long, requires = "unmeasurable_at", value_name = "N")]
    pub unmeasurable_depth: Option<usize>,
    #[command(flatten)]
    pub settings: CalibrationOptions,
    /// Where to write the model (JSON).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write a self-contained HTML report (the conventional parameters, the fit, the
    /// division's regions) here.
    #[arg(long, value_name = "FILE.html")]
    pub report: Option<PathBuf>,
}

/// Three numbers separated by commas.
fn three_numbers(text: &str) -> Result<[f64; 3], String> {
    let bad = || format!("`{text}`: give three numbers separated by commas");
    let v: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse().map_err(|_| bad()))
        .collect::<Result<_, _>>()?;
    v.try_into().map_err(|_| bad())
}

pub fn run(a: Args) -> Result<()> {
    let rig = Rig::load(&a.rig)?;
    let opts = CalibrationOptions {
        accuracy_mm: a.accuracy_mm,
        learner: a.learner,
        unmeasurable_at: a.unmeasurable_at,
        unmeasurable_depth: a.unmeasurable_depth,
        ..a.settings.clone()
    };
    let calibrated = match (&a.recording, &a.scenario, &a.session) {
        (Some(dir), None, _) => offline(&rig, dir, &opts)?,
        (None, Some(scenario), _) => {
            let sc = rigcal_sim::world::Scenario::load(scenario, None)?;
            let c = with_bar(&opts, |p| {
                calibration::calibrate_with_progress(&rig, Source::Scenario(&sc), &opts, p)
            })?;
            print!("{}", c.text());
            c
        }
        (None, None, Some(dir)) => through_session(&rig, &a, dir, &opts)?,
        _ => bail!("give --recording DIR (offline), --scenario FILE (planning on a simulated world) or --session DIR (planning through the rig)"),
    };
    calibrated.model.save(&a.out)?;
    println!("model written to {}", a.out.display());
    if let Some(path) = &a.report {
        let from = a
            .recording
            .as_ref()
            .or(a.scenario.as_ref())
            .or(a.session.as_ref());
        let from = from.map(|p| p.as_path()).unwrap_or(Path::new("-"));
        let rows = calibrated.model.fitted_from.measurements;
        let source = super::report_source(&rig, &a.rig, from, rows);
        let html = rigcal_model::report::html::model_report(&source, &calibrated.model);
        super::write_report(path, &html)?;
    }
    Ok(())
}

/// Offline calibration from the recording in `dir`, its figures printed.
pub(crate) fn offline(rig: &Rig, dir: &Path, opts: &CalibrationOptions) -> Result<Calibrated> {
    let rec = super::read_recording(rig, dir)?;
    let observations = rec.observations();
    let label = dir.display().to_string();
    let c = with_bar(opts, |p| {
        let source = Source::Offline {
            observations: &observations,
            label,
        };
        calibration::calibrate_with_progress(rig, source, opts, p)
    })?;
    print!("{}", c.text());
    Ok(c)
}

/// Runs a calibration under a progress bar of the division's regions.
fn with_bar<T>(
    opts: &CalibrationOptions,
    run: impl FnOnce(&mut dyn FnMut(usize, usize)) -> Result<T, CalibrationError>,
) -> Result<T> {
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
    let done = run(&mut |n, _| bar.set_position(n as u64));
    bar.finish_and_clear();
    Ok(done?)
}

/// Planning mode through a measurement session in `dir`: every measurement the division asks
/// for is made by the devices (emulated with `--sim`) and recorded there.
fn through_session(
    rig: &Rig,
    a: &Args,
    dir: &Path,
    opts: &CalibrationOptions,
) -> Result<Calibrated> {
    if opts.is_neural() {
        return Err(CalibrationError::NeuralNeedsData.into());
    }
    let files = PlanningFiles {
        rig: &a.rig,
        sim: a.sim.as_deref(),
    };
    if a.resume {
        calibration::refuse_other_options(dir, files, opts)?;
    }
    let fallbacks = Arc::new(AtomicUsize::new(0));
    let session = open_session(
        rig,
        a,
        dir,
        calibration::planning_note(files, opts),
        &fallbacks,
    )?;
    let mut recorded = Vec::new();
    if a.resume {
        recorded = calibration::resumed_requests(rig, dir, session.points_done())?;
        let n = recorded.len();
        eprintln!(
            "resuming {}: {n} finished points replayed to the division, then measuring on",
            dir.display()
        );
    }
    let s = with_bar(opts, |p| {
        calibration::through_session(rig, session, dir, recorded, opts, p)
    })?;
    print!(
        "{}{}{}",
        s.calibrated.text(),
        s.session_text(dir, a.sim.is_some()),
        command_path_text(rig, fallbacks.load(Ordering::Relaxed))
    );
    Ok(s.calibrated)
}

/// How the session's arm moves went: on a `cartesian` rig through `MP`, with the count that
/// went through `MJ` instead.
fn command_path_text(rig: &Rig, mj_moves: usize) -> String {
    match calibration::rig_check::command_path(rig) {
        CommandPath::Cartesian => format!(
            "arm moves through MP (the rig's cartesian command path); {mj_moves} through MJ, their MP solution refused at a joint limit\n"
        ),
        CommandPath::Joint => String::new(),
    }
}

/// Opens (or resumes) the planning-mode session in `dir` on the rig's devices, or on emulators
/// of `--sim`'s world, every arm move on the rig's command path (`MP` on a `cartesian` rig,
/// `MJ` moves counted in `fallbacks`); `note` records the options that shaped it.
fn open_session<'r>(
    rig: &'r Rig,
    a: &Args,
    dir: &Path,
    note: String,
    fallbacks: &Arc<AtomicUsize>,
) -> Result<rigcal_devices::session::Session<'r>> {
    let scenario = super::session::load_scenario(rig, &a.rig, a.sim.as_deref(), None)?;
    let opened = rigcal_sim::emulation::open_rig(
        rig,
        scenario.as_ref(),
        rigcal_devices::devices::SimClock::Virtual,
    )?
    .on_command_path(calibration::rig_check::command_path(rig), fallbacks);
    let mut opts = rigcal_devices::session::SessionOptions::new(dir);
    opts.seed = a.settings.seed;
    opts.resume = a.resume;
    opts.fsync = !opened.devices.clock.is_virtual();
    opts.info = rigcal_core::recording::SessionInfo {
        rig: Some(a.rig.display().to_string()),
        scenario: a.sim.as_ref().map(|p| p.display().to_string()),
        seed: scenario.as_ref().map(|s| s.seed),
        notes: Some(note),
        ..Default::default()
    };
    Ok(rigcal_devices::session::Session::open(rig, opened, opts)?)
}
