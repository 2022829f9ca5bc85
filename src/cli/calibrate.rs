//! `rigcal calibrate`: the variable D-H parameter model — recursive division, per-region CEPs and
//! a learner — from a recording (offline), a simulated world that measures what the division
//! asks for (planning), or a measurement session (planning through the rig); see
//! [`rigcal_calibration`].

use super::options::{three_numbers, CalibrationArgs, LearnerArg};
use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use rigcal_calibration::{
    self as calibration, Calibrated, CalibrationError, CalibrationOptions, PlanningFiles,
    PlanningSession, Source,
};
use rigcal_core::rig::Rig;
use rigcal_devices::session::{SessionLock, StopRequest};
use std::path::{Path, PathBuf};

/// Arguments of `rigcal calibrate` (one field per flag or flag group: more than 12).
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
    #[arg(long, value_enum, default_value_t = LearnerArg::Fcmac)]
    pub learner: LearnerArg,
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
    /// Offline on a recording in an instrument's own frame (a tracker: the rig's measurement
    /// frame free), which is registered first: which error parameters each region fits.
    /// `all`: every parameter of the basis (seed 000's CEPs); `positioning`: the base's and the
    /// positioning joints' (the first three moving joints), the wrist's and the marker's held
    /// at the conventional fit's values in every region.
    #[arg(long, value_enum, default_value_t = RegionParamsArg::All)]
    pub region_params: RegionParamsArg,
    #[command(flatten)]
    pub settings: CalibrationArgs,
    /// Where to write the model (JSON).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write a self-contained HTML report (the conventional parameters, the fit, the
    /// division's regions) here.
    #[arg(long, value_name = "FILE.html")]
    pub report: Option<PathBuf>,
}

/// `--region-params` ([`calibration::RegionParams`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum RegionParamsArg {
    /// Every parameter of the identifiable basis.
    All,
    /// The base's and the positioning joints' only.
    Positioning,
}

impl From<RegionParamsArg> for calibration::RegionParams {
    fn from(a: RegionParamsArg) -> Self {
        match a {
            RegionParamsArg::All => Self::All,
            RegionParamsArg::Positioning => Self::Positioning,
        }
    }
}

pub fn run(a: Args) -> Result<()> {
    let rig = rigcal_devices::config::load_rig(&a.rig)?;
    let opts = CalibrationOptions {
        accuracy_mm: a.accuracy_mm,
        learner: a.learner.into(),
        unmeasurable_at: a.unmeasurable_at,
        unmeasurable_depth: a.unmeasurable_depth,
        region_params: a.region_params.into(),
        ..a.settings.clone().into()
    };
    let calibrated = match (&a.recording, &a.scenario, &a.session) {
        (Some(dir), None, _) => {
            let observations = calibration::read_recording(&rig, dir)?.observations();
            let label = dir.display().to_string();
            let source = Source::Offline {
                observations: &observations,
                label,
            };
            let c = calibrate(&rig, source, &opts)?;
            // A recording in an instrument's frame was registered first: say how.
            if let Some(notes) = &c.model.fitted_from.notes {
                if let Some((_, registration)) = notes.split_once("; instrument frame") {
                    println!("instrument frame{registration}");
                }
            }
            c
        }
        (None, Some(scenario), _) => {
            let sc = rigcal_sim::world::Scenario::load(scenario, None)?;
            calibrate(&rig, Source::Scenario(&sc), &opts)?
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
        let source = rigcal_model::report::html::Source::of(&rig, &a.rig, from, rows);
        let html = rigcal_model::report::html::model_report(&source, &calibrated.model);
        super::write_report(path, &html)?;
    }
    Ok(())
}

/// Calibrates from `source` under a progress bar, its figures printed.
fn calibrate(rig: &Rig, source: Source<'_>, opts: &CalibrationOptions) -> Result<Calibrated> {
    let c = with_bar(opts, |p| {
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
    let files = PlanningFiles {
        rig: &a.rig,
        sim: a.sim.as_deref(),
    };
    // The directory is owned for the whole run, as `rigcal session` owns its own: a second
    // writer (a resume started twice, say) is refused with who holds it.
    std::fs::create_dir_all(dir)
        .with_context(|| format!("creating the session directory {}", dir.display()))?;
    let lock = SessionLock::acquire(dir)?;
    if let Some(stale) = lock.stale_holder() {
        eprintln!("note: the run that held {} before ({stale}) did not end normally; it is gone, the directory is taken over", dir.display());
    }
    let stop = StopRequest::on_signals().context("listening for Ctrl-C and SIGTERM")?;
    let session = PlanningSession::open(rig, files, dir, opts, a.resume, stop)?;
    if a.resume {
        let n = session.replayed();
        eprintln!(
            "resuming {}: {n} finished points replayed to the division, then measuring on",
            dir.display()
        );
    }
    let (calibrated, text) = with_bar(opts, |p| session.calibrate(rig, opts, p))?;
    print!("{text}");
    drop(lock);
    Ok(calibrated)
}
