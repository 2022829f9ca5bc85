//! `rigcal session`: run an automatic measurement session on the rig, or a dry run through the
//! same drivers against emulators of a scenario's world (`--sim`), and resume one (`--resume`).
//!
//! The plan is written to `<out>/plan.csv` at the start and read back from there on a resume.
//! On the virtual clock (a dry run without `--real-time`) nothing waits: the report gives the
//! rig time the session would have taken.

use anyhow::{bail, Context, Result};
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::SessionInfo;
use rigcal_core::rig::Rig;
use rigcal_devices::devices::SimClock;
use rigcal_devices::session::{
    estimate, plan, read_plan, registration_points, run_session, write_plan, ContactProcedure,
    ContactSettings, RigSpeeds, SessionOptions,
};
use rigcal_sim::emulation::open_rig;
use rigcal_sim::world::Scenario;
use std::path::PathBuf;

/// Arguments of `rigcal session`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The rig file.
    #[arg(long)]
    rig: PathBuf,
    /// Dry run: emulate the devices on this scenario's truth (sim/*.toml).
    #[arg(long)]
    sim: Option<PathBuf>,
    /// Session directory (measurements.csv, session.toml, journal.json, plan.csv).
    #[arg(long)]
    out: PathBuf,
    /// Continue the session in --out from its journal.
    #[arg(long)]
    resume: bool,
    /// A plan from `rigcal plan`.
    #[arg(long, conflicts_with = "points")]
    plan: Option<PathBuf>,
    /// Plan this many points now.
    #[arg(long)]
    points: Option<usize>,
    /// Regions of the workspace when planning here.
    #[arg(long, default_value_t = 8)]
    regions: usize,
    /// Drift-reference interval when planning here (0: none).
    #[arg(long, default_value_t = 50)]
    reference_every: usize,
    /// Order within a region when planning here (see `rigcal plan --help`).
    #[arg(long, default_value = "optimised")]
    order: rigcal_devices::session::Ordering,
    /// Contact procedure on the table rig: `rigcal`, or the paper-style `baseline` (see
    /// `rigcal plan --help`); a resume keeps the one the session began with.
    #[arg(long, default_value = "rigcal")]
    procedure: ContactProcedure,
    /// Poses of the registration step.
    #[arg(long, default_value_t = 12)]
    registration_points: usize,
    /// Reuse the registration of this earlier session directory (same rig set-up) instead of
    /// registering again, so both recordings share one frame (e.g. to check a model on a path).
    #[arg(long, value_name = "DIR")]
    registration_from: Option<PathBuf>,
    /// Seed of the plan and the registration poses; default the scenario's seed, else 1.
    #[arg(long)]
    seed: Option<u64>,
    /// Overrides the scenario's own seed (its random errors and noise: another simulated arm).
    #[arg(long, requires = "sim")]
    sim_seed: Option<u64>,
    /// Run the emulators on real time instead of the virtual clock.
    #[arg(long)]
    real_time: bool,
    /// fsync every row and journal even on the virtual clock (always on with real devices).
    #[arg(long)]
    fsync: bool,
}

pub fn run(a: Args) -> Result<()> {
    let rig = Rig::load(&a.rig)?;
    let scenario = load_scenario(&rig, &a.rig, a.sim.as_deref(), a.sim_seed)?;
    let seed = a.seed.or(scenario.as_ref().map(|s| s.seed)).unwrap_or(1);
    check_session_dir(&a)?;
    let points = session_plan(&a, &rig, seed)?;
    // The registration step measures its own poses first (none when reused, on a point-sensor
    // rig, or on a resume, which estimates the whole plan again).
    let registration = if a.registration_from.is_none() && !a.resume {
        registration_points(&rig, a.registration_points, seed)
    } else {
        Vec::new()
    };
    let est = estimate(
        &rig,
        &[registration, points.clone()].concat(),
        &RigSpeeds::of(&rig),
        &ContactSettings::for_procedure(&rig, a.procedure),
    );
    println!("{}", super::plan::describe(&est));
    println!("{}", super::plan::breakdown(&est));
    let clock = if a.real_time {
        SimClock::Real
    } else {
        SimClock::Virtual
    };
    let opened = open_rig(&rig, scenario.as_ref(), clock)?;
    let virtual_clock = opened.devices.clock.is_virtual();
    let opts = session_options(
        &a,
        &rig,
        scenario.as_ref(),
        seed,
        points.len(),
        virtual_clock,
    )?;
    let progress = super::progress::session_progress(points.len());
    let report = run_session(&rig, opened, &points, opts, &progress)?;
    print_report(&a.out, &report, virtual_clock);
    println!(
        "estimated {:.0} s beside it ({:+.1} %)",
        est.total_s,
        100.0 * (est.total_s / report.rig_time_s.max(1e-9) - 1.0)
    );
    Ok(())
}

/// Refuses a fresh session over a recording, and a resume where there is no session.
fn check_session_dir(a: &Args) -> Result<()> {
    if !a.resume && a.out.join(rigcal_devices::session::run::CSV_FILE).exists() {
        // Before planning: a refused run must not touch the session's files.
        bail!(
            "{} already holds a recording; resume it with --resume or choose another --out",
            a.out.display()
        );
    }
    if a.resume
        && !a
            .out
            .join(rigcal_devices::session::journal::JOURNAL_FILE)
            .exists()
    {
        bail!(
            "{}: no session to resume here (no {}); start one without --resume",
            a.out.display(),
            rigcal_devices::session::journal::JOURNAL_FILE
        );
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))
}

/// The session's plan: made (or read from `--plan`) and written on a fresh run, then, on a
/// fresh and a resumed run alike, read back from the session's `plan.csv`.
fn session_plan(
    a: &Args,
    rig: &Rig,
    seed: u64,
) -> Result<Vec<rigcal_devices::session::PlannedPoint>> {
    let plan_path = a.out.join("plan.csv");
    if !a.resume {
        let points = match (&a.plan, a.points) {
            (Some(p), None) => read_plan(p, rig)?,
            (None, Some(n)) => {
                let opts = rigcal_devices::session::PlanOptions {
                    order: a.order,
                    ..super::plan::options(n, a.regions, a.reference_every, seed)
                };
                let p = plan(rig, &opts)?;
                super::plan::report_dropped(rig, &p, &plan_path)?;
                p.points
            }
            _ => bail!("give --plan FILE or --points N (or --resume to continue a session)"),
        };
        write_plan(&plan_path, rig, &points)?;
    } else if a.plan.is_some() || a.points.is_some() {
        eprintln!(
            "note: --resume continues the plan in {}; --plan/--points are ignored",
            plan_path.display()
        );
    }
    read_plan(&plan_path, rig)
        .with_context(|| format!("reading the session plan {}", plan_path.display()))
}

/// The session's options from the command line (a reused registration read from its session).
fn session_options(
    a: &Args,
    rig: &Rig,
    scenario: Option<&rigcal_sim::world::Scenario>,
    seed: u64,
    points: usize,
    virtual_clock: bool,
) -> Result<SessionOptions> {
    let mut opts = SessionOptions::new(&a.out);
    opts.resume = a.resume;
    opts.registration_points = a.registration_points;
    if let Some(dir) = &a.registration_from {
        let rec = rigcal_core::recording::Recording::read(dir, rig.chain.joints())
            .with_context(|| format!("reading the session {}", dir.display()))?;
        let reg = rec.session.and_then(|s| s.registration);
        opts.registration = Some(reg.with_context(|| {
            format!(
                "{}: its session.toml holds no [registration]",
                dir.display()
            )
        })?);
    }
    opts.seed = seed;
    opts.procedure = a.procedure;
    opts.fsync = a.fsync || !virtual_clock;
    opts.info = SessionInfo {
        rig: Some(a.rig.display().to_string()),
        scenario: a.sim.as_ref().map(|p| p.display().to_string()),
        seed: scenario.map(|s| s.seed),
        notes: Some(format!(
            "rigcal session: {points} points, {} contact procedure{}",
            a.procedure.name(),
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

/// What `rigcal session` prints at the end.
fn print_report(
    out: &std::path::Path,
    report: &rigcal_devices::session::SessionReport,
    virtual_clock: bool,
) {
    println!(
        "session {}: {} points, {} measured{}, {} skipped, {} via rows, {} retries, {} faults cleared, {} extra passes",
        out.display(),
        report.points,
        report.ok,
        match report.resumed_at {
            Some(k) if k >= report.points => " (already finished: nothing left to measure)".to_string(),
            Some(k) => format!(" (this run, resumed at point {})", k + 1),
            None => String::new(),
        },
        report.skipped.len(),
        report.via,
        report.retries,
        report.faults_cleared.len(),
        report.extra_passes
    );
    for (p, why) in &report.skipped {
        println!("  point {p} skipped: {why}");
    }
    for f in &report.faults_cleared {
        println!("  cleared: {f}");
    }
    if let Some(rms) = report.registration_rms_mm {
        println!("registration RMS {rms:.3} mm (written to session.toml)");
    }
    println!(
        "rig time {:.0} s ({:.2} h){}; wall time {:.2} s",
        report.rig_time_s,
        report.rig_time_s / 3600.0,
        if virtual_clock {
            " on the virtual clock: what the rig would have taken"
        } else {
            ""
        },
        report.wall.as_secs_f64()
    );
}

/// The scenario of a dry run, checked against the rig in use.
pub(crate) fn load_scenario(
    rig: &Rig,
    rig_path: &std::path::Path,
    sim: Option<&std::path::Path>,
    sim_seed: Option<u64>,
) -> Result<Option<Scenario>> {
    let Some(p) = sim else {
        return Ok(None);
    };
    let s = Scenario::load(p, sim_seed)?;
    if s.rig.name != rig.name || s.rig.instrument != rig.instrument {
        bail!(
            "scenario {} assumes rig `{}`, but --rig {} is `{}`",
            s.path.display(),
            s.rig.name,
            rig_path.display(),
            rig.name
        );
    }
    Ok(Some(s))
}
