//! A 2200-point dry-run session through the drivers and emulators on the virtual clock (wall
//! time, the optimised order), and the planned rig time of the optimised order against the
//! paper's z-then-x-y order of the same points, with the breakdown and each one's dry-run clock
//! (printed once: they are deterministic).

use criterion::{criterion_group, criterion_main, Criterion};
use rigcal::devices::{open_rig, SimClock};
use rigcal::session::{
    estimate, plan, registration_points, run_session, ContactSettings, Ordering, PlanOptions,
    PlannedPoint, Progress, RigSpeeds, SessionOptions, SessionReport,
};
use rigcal::world::Scenario;
use std::path::Path;

fn dry_run(sc: &Scenario, points: &[PlannedPoint]) -> SessionReport {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let opened = open_rig(&sc.rig, Some(sc), SimClock::Virtual).unwrap_or_else(|e| panic!("{e}"));
    let mut o = SessionOptions::new(dir.path());
    o.fsync = false;
    run_session(&sc.rig, opened, points, o, &Progress::Quiet).unwrap_or_else(|e| panic!("{e}"))
}

fn session_2200(c: &mut Criterion) {
    let sc =
        Scenario::load(Path::new("sim/rig-realistic.toml"), None).unwrap_or_else(|e| panic!("{e}"));
    let rig = sc.rig.clone();
    let opts = |order| PlanOptions {
        points: 2200,
        order,
        ..PlanOptions::default()
    };
    let speeds = RigSpeeds::of(&rig);
    let contact = ContactSettings::of(&rig);
    let reg = registration_points(
        &rig,
        SessionOptions::new(Path::new(".")).registration_points,
        1,
    );
    let mut optimised = Vec::new();
    let mut totals = Vec::new();
    for order in [Ordering::Optimised, Ordering::ZThenXY] {
        let p = plan(&rig, &opts(order)).unwrap_or_else(|e| panic!("{e}"));
        let e = estimate(
            &rig,
            &[reg.clone(), p.points.clone()].concat(),
            &speeds,
            &contact,
        );
        let clock = dry_run(&sc, &p.points);
        println!(
            "planned rig time, 2200 points, {} order: {:.0} s ({}); dry-run clock {:.0} s, {} extra passes",
            order.name(),
            e.total_s,
            e.breakdown.describe(),
            clock.rig_time_s,
            clock.extra_passes
        );
        totals.push((e.total_s, clock.rig_time_s));
        if order == Ordering::Optimised {
            optimised = p.points;
        }
    }
    println!(
        "optimised against z-then-xy: {:.1} % less planned, {:.1} % less on the dry-run clock",
        100.0 * (1.0 - totals[0].0 / totals[1].0),
        100.0 * (1.0 - totals[0].1 / totals[1].1)
    );
    let mut group = c.benchmark_group("session");
    group.sample_size(10);
    group.bench_function(
        "dry-run 2200 points (rig-realistic, virtual clock)",
        |bch| bch.iter(|| dry_run(&sc, &optimised)),
    );
    group.finish();
}

criterion_group!(benches, session_2200);
criterion_main!(benches);
