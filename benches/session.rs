//! A 2200-point dry-run session through the drivers and emulators on the virtual clock (wall
//! time), and the planned rig time of the nearest-neighbour order against the paper's
//! z-then-x-y order (printed once).

use criterion::{criterion_group, criterion_main, Criterion};
use rigcal::devices::{open_rig, SimClock};
use rigcal::session::{
    estimate, plan, run_session, ContactSettings, Ordering, PlanOptions, Progress, RigSpeeds,
    SessionOptions,
};
use rigcal::world::Scenario;
use std::path::Path;

fn session_2200(c: &mut Criterion) {
    let sc =
        Scenario::load(Path::new("sim/rig-realistic.toml"), None).unwrap_or_else(|e| panic!("{e}"));
    let rig = sc.rig.clone();
    let opts = |order| PlanOptions {
        points: 2200,
        order,
        ..PlanOptions::default()
    };
    let nn = plan(&rig, &opts(Ordering::NearestNeighbour)).unwrap_or_else(|e| panic!("{e}"));
    let zxy = plan(&rig, &opts(Ordering::ZThenXY)).unwrap_or_else(|e| panic!("{e}"));
    let speeds = RigSpeeds::of(&rig);
    let contact = ContactSettings::default();
    let (a, b) = (
        estimate(&rig, &nn.points, &speeds, &contact),
        estimate(&rig, &zxy.points, &speeds, &contact),
    );
    println!(
        "planned rig time, 2200 points: nearest neighbour {:.0} s (motion {:.0} s), paper z-then-x-y {:.0} s (motion {:.0} s)",
        a.total_s, a.motion_s, b.total_s, b.motion_s
    );
    let mut group = c.benchmark_group("session");
    group.sample_size(10);
    group.bench_function(
        "dry-run 2200 points (rig-realistic, virtual clock)",
        |bch| {
            bch.iter(|| {
                let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
                let opened =
                    open_rig(&rig, Some(&sc), SimClock::Virtual).unwrap_or_else(|e| panic!("{e}"));
                let mut o = SessionOptions::new(dir.path());
                o.fsync = false;
                run_session(&rig, opened, &nn.points, o, &Progress::Quiet)
                    .unwrap_or_else(|e| panic!("{e}"))
            })
        },
    );
    group.finish();
}

criterion_group!(benches, session_2200);
criterion_main!(benches);
