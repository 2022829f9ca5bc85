//! `rigcal session`: run an automatic measurement session on the rig, or a dry run through the
//! same drivers against emulators of a scenario's world (`--sim`), and resume one (`--resume`);
//! set up by [`SessionSetup`] (the session directory locked and a resume checked before any
//! device is opened, its `plan.csv`, the estimate).

use anyhow::{bail, Result};
use rigcal_calibration::dry_run_scenario;
use rigcal_core::rig::Rig;
use rigcal_devices::devices::SimClock;
use rigcal_devices::session::{
    run_session, ContactProcedure, PlanOptions, PlanSource, PlannedPoint, SessionSetup,
};
use rigcal_sim::emulation::open_rig;
use std::path::PathBuf;

/// Arguments of `rigcal session` (one field per flag or flag group: more than 12).
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
    /// Plan this many points now (1 to 1000000).
    #[arg(long, value_parser = super::plan::point_count)]
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
    let rig = rigcal_devices::config::load_rig(&a.rig)?;
    let scenario = dry_run_scenario(&rig, &a.rig, a.sim.as_deref(), a.sim_seed)?;
    let mut setup = SessionSetup {
        dir: &a.out,
        resume: a.resume,
        rig_file: &a.rig,
        scenario_file: a.sim.as_deref(),
        scenario_rig_file: scenario.as_ref().map(|s| s.rig_path.as_path()),
        scenario_seed: scenario.as_ref().map(|s| s.seed),
        seed: a.seed.or(scenario.as_ref().map(|s| s.seed)).unwrap_or(1),
        procedure: a.procedure,
        registration_points: a.registration_points,
        registration_from: a.registration_from.as_deref(),
        fsync: a.fsync,
    };
    // Held until the session has ended: no other run writes this directory meanwhile.
    let owned = setup.take_dir(&rig)?;
    for note in &owned.notes {
        eprintln!("note: {note}");
    }
    let points = session_plan(&a, &setup, &rig)?;
    let est = setup.estimate(&rig, &points);
    println!("{}", est.text());
    println!("{}", est.breakdown_text());
    let clock = if a.real_time {
        SimClock::Real
    } else {
        SimClock::Virtual
    };
    let opened = open_rig(&rig, scenario.as_ref(), clock)?;
    let virtual_clock = opened.devices.clock.is_virtual();
    let mut opts = setup.options(&rig, points.len(), virtual_clock)?;
    opts.stop = rigcal_devices::session::StopRequest::on_signals()?; // SIGINT/SIGTERM: a safe stop
    let progress = super::progress::session_progress(points.len());
    let report = run_session(&rig, opened, &points, opts, &progress)?;
    print!("{}", report.text(&a.out, virtual_clock));
    println!("{}", report.beside_estimate_text(est.total_s));
    drop(owned);
    Ok(())
}

/// The session's plan ([`SessionSetup::plan`]): from `--plan` or `--points` on a fresh run.
fn session_plan(a: &Args, setup: &SessionSetup, rig: &Rig) -> Result<Vec<PlannedPoint>> {
    let fresh = match (&a.plan, a.points) {
        _ if a.resume => None,
        (Some(p), None) => Some(PlanSource::File(p)),
        (None, Some(n)) => Some(PlanSource::Make(PlanOptions {
            points: n,
            regions: a.regions,
            reference_every: a.reference_every,
            seed: setup.seed,
            order: a.order,
            ..PlanOptions::default()
        })),
        _ => bail!("give --plan FILE or --points N (or --resume to continue a session)"),
    };
    if a.resume && (a.plan.is_some() || a.points.is_some()) {
        eprintln!(
            "note: --resume continues the plan in {}; --plan/--points are ignored",
            setup.plan_path().display()
        );
    }
    Ok(setup.plan(rig, fresh, &mut |dropped| print!("{dropped}"))?)
}
