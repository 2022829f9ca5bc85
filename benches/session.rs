//! A 2200-point dry-run session through the drivers and emulators on the virtual clock (wall
//! time, the optimised order with rigcal's contact procedure), and the planned rig time of the
//! compared orders and procedures of the same points — the paper's z-then-x-y order with the
//! baseline procedure (the reference), with rigcal's, and the optimised order — with
//! the breakdown, each one's dry-run clock and saving (printed once: they are deterministic).

use criterion::{criterion_group, criterion_main, Criterion};
use rigcal_devices::devices::SimClock;
use rigcal_devices::session::{
    plan_variant, registration_points, run_session, saving_pct, ContactProcedure, PlanOptions,
    PlannedPoint, Progress, SessionOptions, SessionReport, COMPARED,
};
use rigcal_sim::emulation::open_rig;
use rigcal_sim::world::Scenario;
use std::path::Path;

fn dry_run(sc: &Scenario, points: &[PlannedPoint], procedure: ContactProcedure) -> SessionReport {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let opened = open_rig(&sc.rig, Some(sc), SimClock::Virtual).unwrap_or_else(|e| panic!("{e}"));
    let mut o = SessionOptions::new(dir.path());
    o.fsync = false;
    o.procedure = procedure;
    run_session(&sc.rig, opened, points, o, &Progress::Quiet).unwrap_or_else(|e| panic!("{e}"))
}

fn session_2200(c: &mut Criterion) {
    let sc =
        Scenario::load(Path::new("sim/rig-realistic.toml"), None).unwrap_or_else(|e| panic!("{e}"));
    let rig = sc.rig.clone();
    let opts = PlanOptions {
        points: 2200,
        ..PlanOptions::default()
    };
    let reg = registration_points(
        &rig,
        SessionOptions::new(Path::new(".")).registration_points,
        1,
    );
    let mut optimised = Vec::new();
    let mut totals: Vec<(f64, f64)> = Vec::new();
    for (order, procedure) in COMPARED {
        let v = plan_variant(&rig, &opts, order, procedure, &reg).unwrap_or_else(|e| panic!("{e}"));
        let clock = dry_run(&sc, &v.points, procedure);
        let (planned, measured) = (v.estimate.total_s, clock.rig_time_s);
        let saving = totals.first().map_or(String::new(), |r| {
            format!(
                "; {:.1} % less planned, {:.1} % less on the clock than the reference",
                saving_pct(planned, r.0),
                saving_pct(measured, r.1)
            )
        });
        println!(
            "planned rig time, 2200 points, {}: {planned:.0} s ({}); dry-run clock {measured:.0} s ({:+.1} %), {} extra passes{saving}",
            v.label(),
            v.estimate.breakdown.describe(),
            100.0 * (planned / measured.max(1e-9) - 1.0),
            clock.extra_passes
        );
        totals.push((planned, measured));
        optimised = v.points;
    }
    let mut group = c.benchmark_group("session");
    group.sample_size(10);
    group.bench_function(
        "dry-run 2200 points (rig-realistic, virtual clock)",
        |bch| bch.iter(|| dry_run(&sc, &optimised, ContactProcedure::Rigcal)),
    );
    group.finish();
}

criterion_group!(benches, session_2200);
criterion_main!(benches);
