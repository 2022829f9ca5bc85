//! The section 7 dry run (`calibration::sec7`, `sim/rig-sec7.toml`): registration, the
//! Cartesian division at 0.5 mm through region sessions, the path through `MP` and `MJ` on the
//! emulators. Wall time is the benchmark; the planned rig hours, the hours on the dry-run
//! clock, the measurements and regions are printed once.

use criterion::{criterion_group, criterion_main, Criterion};
use rigcal_paper::sec7::{self, Sec7Files, Sec7Options};
use std::path::Path;

fn dry_run(out: &Path) -> sec7::Sec7Report {
    let _ = std::fs::remove_dir_all(out);
    let files = Sec7Files {
        rig: Path::new("rigs/rv-m2.toml"),
        scenario: Path::new("sim/rig-sec7.toml"),
        out,
    };
    sec7::run(files, &Sec7Options::default(), &mut |_| {}).unwrap_or_else(|e| panic!("{e}"))
}

fn section7(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let out = dir.path().join("sec7");
    let r = dry_run(&out);
    let (ident, tests) = r.measurements();
    println!(
        "section 7 dry run: {} regions (paper 85), {ident} identification + {tests} test measurements in the division, {} path points per method and command path; rig time planned {:.2} h, on the dry-run clock {:.2} h (division {:.2} h); wall {:.1} s",
        r.regions(),
        r.path.points.len(),
        r.planned_s() / 3600.0,
        r.rig_time_s() / 3600.0,
        r.division.report.rig_time_s / 3600.0,
        r.wall.as_secs_f64()
    );
    let mut group = c.benchmark_group("sec7");
    group.sample_size(10);
    group.bench_function("dry run (rig-sec7, virtual clock)", |b| {
        b.iter(|| dry_run(&out))
    });
    group.finish();
}

criterion_group!(benches, section7);
criterion_main!(benches);
