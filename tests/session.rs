//! Automatic measurement sessions: the world-backed emulators, an end-to-end dry run that
//! `rigcal identify` accepts, kill-and-resume of the binary, fault injection, and a property
//! test of the commands actually sent.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::{JointSpec, Robot};
use rigcal_core::recording::{Recording, Status};
use rigcal_core::rig::{Instrument, Rig};
use rigcal_devices::devices::contact::{approach_speed, measure_contact};
use rigcal_devices::devices::emulators::faults::InjectedFault;
use rigcal_devices::devices::{
    open_devices, Arm, ArmPose, ArmStatus, Backend, DeviceError, InstrumentDevices, OpenedRig,
    RigDevices, SimClock, Table,
};
use rigcal_devices::session::{
    estimate, plan, registration_points, run_session, z_window_mm, ContactSettings, Ordering,
    PlanOptions, PlannedPoint, Progress, RigSpeeds, SessionOptions,
};
use rigcal_sim::world::Scenario;

const T: Duration = Duration::from_secs(30);
const SCENARIO: &str = "sim/rig-realistic.toml";

fn scenario() -> Scenario {
    Scenario::load(Path::new(SCENARIO), None).unwrap()
}

fn points(rig: &Rig, n: usize, seed: u64) -> Vec<PlannedPoint> {
    plan(
        rig,
        &PlanOptions {
            points: n,
            regions: 4,
            reference_every: 10,
            seed,
            ..PlanOptions::default()
        },
    )
    .unwrap()
    .points
}

#[test]
fn a_contact_through_drivers_and_emulators_agrees_with_the_world() {
    let sc = scenario();
    let rig = sc.rig.clone();
    let Instrument::TablePanel(tp) = &rig.instrument else {
        panic!()
    };
    let (setup, world) = rigcal_sim::emulation::setup_from_scenario(&sc);
    let mut d = open_devices(&rig, Backend::Simulated(setup)).unwrap();
    let nest = d.arm.home(T).unwrap();
    let mut reference = sc.world();
    reference.move_arm(&nest, d.clock.now().as_secs_f64());
    let mut checked = 0;
    for p in points(&rig, 6, 5).iter().filter(|p| p.region != "ref") {
        let seq = 100 + p.point as u64;
        world.lock().unwrap().set_draws(seq, 0);
        let q = d.arm.move_to(&p.q, T).unwrap();
        let t_arrive = d.clock.now().as_secs_f64();
        let expected = reference.measure_at(&q, t_arrive, seq, 0);
        let want = expected.table.expect("the world measures this pose");
        let xy = [p.table_mm[0], p.table_mm[1]];
        d.table().unwrap().begin_pass();
        d.table().unwrap().enable(T).unwrap();
        d.table().unwrap().set_speed(100.0, T).unwrap();
        d.table()
            .unwrap()
            .start_move([xy[0], xy[1], p.table_mm[2] - 3.0], T)
            .unwrap();
        d.table().unwrap().wait_reached(T).unwrap();
        let v = approach_speed(
            d.panel().unwrap().latency(),
            d.table().unwrap().latency(),
            0.005,
        );
        let (table, panel) = d.table_and_panel().unwrap();
        let c = measure_contact(
            table,
            panel,
            xy,
            p.table_mm[2] - 3.0,
            p.table_mm[2] + 3.0,
            v,
            Duration::from_secs(60),
        )
        .unwrap();
        let got = c.point_table_mm();
        for k in 0..3 {
            assert!(
                (got[k] - want[k]).abs() < 0.3,
                "axis {k}: emulated {got:?} vs world {want:?}"
            );
        }
        // And the point is not just the nominal one: the world's errors show.
        let nominal = rig.chain.position(
            &q,
            &rigcal_core::kinematics::ErrorParams::zeros(rig.chain.layout()),
        ) - tp.table_to_world_mm;
        assert!((nominal - nalgebra::Vector3::from(got)).norm() > 0.05);
        checked += 1;
    }
    assert!(checked >= 4);
}

fn sim_devices(sc: &Scenario) -> OpenedRig {
    rigcal_sim::emulation::open_rig(&sc.rig, Some(sc), SimClock::Virtual).unwrap()
}

fn options(dir: &Path) -> SessionOptions {
    let mut o = SessionOptions::new(dir);
    o.registration_points = 6;
    o.fsync = false;
    o
}

fn read(dir: &Path, rig: &Rig) -> Recording {
    Recording::read(&dir.join("measurements.csv"), rig.chain.joints()).unwrap()
}

/// Rows for the planned points (not registration), in order.
fn point_rows(rec: &Recording) -> Vec<&rigcal_core::recording::Measurement> {
    rec.rows
        .iter()
        .filter(|m| m.region.as_deref() != Some("reg") && m.status != Status::Via)
        .collect()
}

#[test]
fn a_dry_run_session_end_to_end_is_accepted_by_identify() {
    let sc = scenario();
    let rig = sc.rig.clone();
    let pts = points(&rig, 36, 2);
    let dir = tempfile::tempdir().unwrap();
    let d = sim_devices(&sc);
    let report = run_session(&rig, d, &pts, options(dir.path()), &Progress::Quiet).unwrap();
    // Known limitation (see the session report): a rare off-centre phantom touch in the
    // emulated world is rejected by the contact check and the point skipped, with its reason.
    assert!(report.ok + 1 >= pts.len(), "{:?}", report.skipped);
    assert!(report.skipped.iter().all(|(_, r)| !r.is_empty()));
    assert!(
        report.rig_time_s > 2.0 * pts.len() as f64,
        "{}",
        report.rig_time_s
    );
    let rec = read(dir.path(), &rig);
    let rows = point_rows(&rec);
    assert_eq!(rows.len(), pts.len());
    // Every move leaves a row: one via per point and per registration pose, plus the points.
    let via = rec.rows.iter().filter(|m| m.status == Status::Via).count();
    assert_eq!(via, pts.len() + 2 * 6);
    // Seq strictly increasing, rows in time order.
    for w in rec.rows.windows(2) {
        assert!(w[1].seq > w[0].seq);
        assert!(w[1].t_s >= w[0].t_s);
    }
    // Measured positions are close to the truth (registration absorbs the frame).
    let world = sc.world();
    for (m, p) in rec.measured() {
        let truth = world.true_position(&m.q);
        assert!((truth - p).norm() < 3.0, "{truth} vs {p} at {m:?}");
        assert!(m.table.is_some() && m.panel_uv.is_some());
    }
    let info = std::fs::read_to_string(dir.path().join("session.toml")).unwrap();
    assert!(
        info.contains("[registration]") && info.contains("rms_mm"),
        "{info}"
    );
    // The rig-time estimate plans the registration poses the session measured, and comes
    // within 30 % of the rig time the dry run took.
    let seed = options(dir.path()).seed;
    let reg = registration_points(&rig, 6, seed);
    let measured_reg: Vec<_> = rec
        .rows
        .iter()
        .filter(|m| m.region.as_deref() == Some("reg") && m.table.is_some())
        .collect();
    assert_eq!(reg.len(), measured_reg.len());
    for (planned, row) in reg.iter().zip(&measured_reg) {
        for (a, b) in planned.q.iter().zip(&row.q) {
            // The Movemaster commands joints in steps of 0.1°.
            assert!((a - b).abs().to_degrees() < 0.051, "{planned:?} vs {row:?}");
        }
    }
    let est = estimate(
        &rig,
        &[reg, pts.clone()].concat(),
        &RigSpeeds::of(&rig),
        &ContactSettings::default(),
    );
    assert_eq!(est.registration_points, 6);
    let ratio = est.total_s / report.rig_time_s;
    assert!(
        (0.7..1.3).contains(&ratio),
        "estimate {} s vs {} s",
        est.total_s,
        report.rig_time_s
    );
    let out = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(["identify", "--rig", "rigs/rv-m2.toml", "--recording"])
        .arg(dir.path())
        .arg("--out")
        .arg(dir.path().join("model.json"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("measurements used"));
}

fn session_cmd(dir: &Path, resume: bool) -> Command {
    session_cmd_on("rigs/rv-m2.toml", SCENARIO, dir, resume)
}

fn session_cmd_on(rig: &str, sim: &str, dir: &Path, resume: bool) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_rigcal"));
    c.args([
        "session",
        "--rig",
        rig,
        "--sim",
        sim,
        "--points",
        "60",
        "--regions",
        "4",
        "--reference-every",
        "15",
        "--registration-points",
        "6",
        "--out",
    ])
    .arg(dir)
    .stdout(std::process::Stdio::null())
    .stderr(std::process::Stdio::null());
    if resume {
        c.arg("--resume");
    }
    c
}

fn fields(dir: &Path) -> Vec<Vec<String>> {
    std::fs::read_to_string(dir.join("measurements.csv"))
        .unwrap()
        .lines()
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

#[test]
fn a_session_killed_at_random_moments_resumes_to_the_uninterrupted_recording() {
    kill_and_resume(
        &|dir, resume| session_cmd(dir, resume),
        20,
        7,
        Duration::from_millis(50),
    );
}

/// The same on the ideal-instrument rig (arm and simulated point sensor), with noise, so the
/// resumed draws must be the uninterrupted ones.
#[test]
fn a_point_sensor_session_killed_and_resumed_matches_the_uninterrupted_one() {
    let cmd = |dir: &Path, resume: bool| {
        session_cmd_on(
            "rigs/rv-m2-ideal.toml",
            "sim/paper-sim-noise.toml",
            dir,
            resume,
        )
    };
    // No cap below the whole run: on a loaded machine the start-up alone can outlast 50 ms,
    // and kills that never get past it make no progress.
    kill_and_resume(&cmd, 5, 11, Duration::from_secs(2));
}

/// Planning mode through a session (`calibrate --session`), killed at random moments and
/// resumed with `--resume`: the division replays the finished points from the recording and
/// measures on, so recording and model end as in an uninterrupted run.
#[test]
fn a_planning_mode_session_killed_and_resumed_matches_the_uninterrupted_one() {
    let planning = |dir: &Path, resume: bool, sim: &str, accuracy: &str, seed: &str| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_rigcal"));
        c.args([
            "calibrate",
            "--rig",
            "rigs/rv-m2.toml",
            "--sim",
            sim,
            "--accuracy-mm",
            accuracy,
            "--seed",
            seed,
            "--learner",
            "none",
            "--session",
        ])
        .arg(dir)
        .arg("--out")
        .arg(dir.join("model.json"))
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null());
        if resume {
            c.arg("--resume");
        }
        c
    };
    let cmd = |dir: &Path, resume: bool| planning(dir, resume, SCENARIO, "0.5", "1");
    let dirs = kill_and_resume(&cmd, 6, 13, Duration::from_secs(3));
    batches_ascend_in_z(&dirs.0);
    let model = |d: &Path| -> serde_json::Value {
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join("model.json")).unwrap()).unwrap();
        v["fitted_from"]["recording"] = serde_json::Value::Null;
        v
    };
    assert_eq!(model(&dirs.0), model(&dirs.1));
    // Resumed with other options (other points, or another world): refused, naming both, and
    // nothing in the directory changes.
    let before = std::fs::read(dirs.1.join("session.toml")).unwrap();
    // The same world in another file: a scenario refers to its rig file relatively.
    let root = dirs.2.path();
    std::fs::create_dir_all(root.join("sim")).unwrap();
    std::fs::create_dir_all(root.join("rigs")).unwrap();
    std::fs::copy("rigs/rv-m2.toml", root.join("rigs/rv-m2.toml")).unwrap();
    let other_world = root.join("sim/other-world.toml");
    std::fs::copy(SCENARIO, &other_world).unwrap();
    let other_world = other_world.to_str().unwrap();
    for other in [
        (SCENARIO, "0.5", "2"),
        (SCENARIO, "0.4", "1"),
        (other_world, "0.5", "1"),
    ] {
        let out = planning(&dirs.1, true, other.0, other.1, other.2)
            .stderr(std::process::Stdio::piped())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success()
                && err.contains("was measured with other options")
                && err.contains("recorded:"),
            "{other:?}: {err}"
        );
    }
    assert_eq!(before, std::fs::read(dirs.1.join("session.toml")).unwrap());
    compare(&dirs.0, &dirs.1);
}

/// The session orders a batch by the *planned* table z (no point more than the rig's z window
/// below an earlier one); the recording holds the *measured* contact z, which differs from the
/// plan by the uncalibrated arm's errors (up to about 0.45 mm between two neighbours of a batch
/// on `sim/rig-realistic.toml`).
const Z_ASCENT_TOLERANCE_MM: f64 = 1.0;

/// A planning-mode recording's region batches (`div<k>`): several, and within each no measured
/// table z more than the z window ([`rigcal_devices::session::z_window_mm`]) below an earlier
/// one of its batch (the session measures a batch as one ascending pass, ordered inside the
/// window by move time).
fn batches_ascend_in_z(dir: &Path) {
    let rig = Rig::load(Path::new("rigs/rv-m2.toml")).unwrap();
    let window = rigcal_devices::session::z_window_mm(&rig);
    let rec = read(dir, &rig);
    let mut batches: std::collections::BTreeMap<String, Vec<f64>> = Default::default();
    for m in &rec.rows {
        let region = m.region.clone().unwrap_or_default();
        if region.starts_with("div") && region.len() > 3 && m.status == Status::Ok {
            batches.entry(region).or_default().push(m.table.unwrap().z);
        }
    }
    assert!(batches.len() >= 3, "{} batches", batches.len());
    assert!(batches.values().any(|z| z.len() >= 10));
    for (region, z) in &batches {
        let mut top = f64::NEG_INFINITY;
        for &zi in z {
            assert!(
                zi >= top - window - Z_ASCENT_TOLERANCE_MM,
                "{region}: table z {z:?}"
            );
            top = top.max(zi);
        }
    }
}

/// Runs a session to the end, then again killed (SIGKILL) at random moments and resumed until
/// `want_kills` kills have happened, and compares the two recordings.
fn kill_and_resume(
    cmd: &dyn Fn(&Path, bool) -> Command,
    want_kills: usize,
    seed: u64,
    longest_run: Duration,
) -> (PathBuf, PathBuf, tempfile::TempDir) {
    let base = tempfile::tempdir().unwrap();
    let a = base.path().join("a");
    let t0 = std::time::Instant::now();
    let st = cmd(&a, false).status().unwrap();
    assert!(st.success());
    // Kill moments spread over a whole run, so they land in every phase (plan, homing,
    // registration, points), whatever the machine's speed.
    let whole_us = (t0.elapsed().as_micros() as u64).clamp(2_000, longest_run.as_micros() as u64);
    let b = base.path().join("b");
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(seed);
    let mut kills = 0;
    let mut runs = 0;
    let started = std::time::Instant::now();
    loop {
        runs += 1;
        assert!(runs < 400, "no progress after {runs} runs");
        let fresh = !b.join("journal.json").exists();
        if fresh {
            let _ = std::fs::remove_dir_all(&b);
        }
        let mut child = cmd(&b, !fresh).spawn().unwrap();
        let delay = Duration::from_micros(rng.random_range(whole_us / 10..whole_us));
        std::thread::sleep(delay);
        match child.try_wait().unwrap() {
            Some(st) => {
                assert!(st.success(), "run {runs} failed: {st}");
                if kills >= want_kills {
                    break;
                }
                // Finished before the kill: start over to collect more kills.
                let j: serde_json::Value =
                    serde_json::from_str(&std::fs::read_to_string(b.join("journal.json")).unwrap())
                        .unwrap();
                assert_eq!(j["finished"], true);
                compare(&a, &b);
                std::fs::remove_dir_all(&b).unwrap();
            }
            None => {
                child.kill().unwrap();
                child.wait().unwrap();
                kills += 1;
            }
        }
    }
    assert!(kills >= want_kills);
    compare(&a, &b);
    assert!(started.elapsed() < Duration::from_secs(60));
    (a, b, base)
}

/// Same seq, joints, positions and status; t_s within a millisecond.
fn compare(a: &Path, b: &Path) {
    let (fa, fb) = (fields(a), fields(b));
    assert_eq!(fa.len(), fb.len(), "row count");
    assert_eq!(fa[0], fb[0]);
    for (ra, rb) in fa.iter().zip(&fb).skip(1) {
        assert_eq!(ra.len(), rb.len());
        assert_eq!(ra[0], rb[0], "seq");
        let ta: f64 = ra[1].parse().unwrap();
        let tb: f64 = rb[1].parse().unwrap();
        assert!(
            (ta - tb).abs() <= 0.0015,
            "t_s {ta} vs {tb} at seq {}",
            ra[0]
        );
        for k in 2..ra.len() {
            if k == 1 {
                continue;
            }
            match (ra[k].parse::<f64>(), rb[k].parse::<f64>()) {
                (Ok(x), Ok(y)) => assert!(
                    (x - y).abs() <= 0.0015,
                    "seq {} column {k}: {x} vs {y}",
                    ra[0]
                ),
                _ => assert_eq!(ra[k], rb[k], "seq {} column {k}", ra[0]),
            }
        }
    }
}

/// Wraps the arm: injects emulator faults at given move numbers and logs what was sent.
struct FaultyArm {
    inner: Box<dyn Arm>,
    moves: usize,
    at: Vec<(usize, Box<dyn Fn() + Send>)>,
    sent: Arc<Mutex<Vec<Vec<f64>>>>,
}

impl Arm for FaultyArm {
    fn home(&mut self, t: Duration) -> Result<Vec<f64>, DeviceError> {
        self.inner.home(t)
    }
    fn set_speed(&mut self, l: u8, t: Duration) -> Result<(), DeviceError> {
        self.inner.set_speed(l, t)
    }
    fn move_to(&mut self, q: &[f64], t: Duration) -> Result<Vec<f64>, DeviceError> {
        self.moves += 1;
        for (n, f) in &self.at {
            if *n == self.moves {
                f();
            }
        }
        let r = self.inner.move_to(q, t);
        if let Ok(done) = &r {
            self.sent.lock().unwrap().push(done.clone());
        }
        r
    }
    fn commanded(&self) -> Option<Vec<f64>> {
        self.inner.commanded()
    }
    fn where_pose(&mut self, t: Duration) -> Result<ArmPose, DeviceError> {
        self.inner.where_pose(t)
    }
    fn status(&mut self, t: Duration) -> Result<ArmStatus, DeviceError> {
        self.inner.status(t)
    }
    fn reset(&mut self, t: Duration) -> Result<(), DeviceError> {
        self.inner.reset(t)
    }
}

/// A table command as sent: a target, or the start of a pass.
#[derive(Debug, Clone, Copy, PartialEq)]
enum TableCmd {
    Pass,
    Move([f64; 3]),
}

struct FaultyTable {
    inner: Box<dyn Table>,
    moves: usize,
    at: Vec<(usize, Box<dyn Fn() + Send>)>,
    sent: Arc<Mutex<Vec<TableCmd>>>,
}

impl Table for FaultyTable {
    fn enable(&mut self, t: Duration) -> Result<(), DeviceError> {
        self.inner.enable(t)
    }
    fn set_speed(&mut self, v: f64, t: Duration) -> Result<(), DeviceError> {
        self.inner.set_speed(v, t)
    }
    fn start_move(&mut self, target: [f64; 3], t: Duration) -> Result<(), DeviceError> {
        self.moves += 1;
        for (n, f) in &self.at {
            if *n == self.moves {
                f();
            }
        }
        let r = self.inner.start_move(target, t);
        if r.is_ok() {
            self.sent.lock().unwrap().push(TableCmd::Move(target));
        }
        r
    }
    fn wait_reached(&mut self, t: Duration) -> Result<[f64; 3], DeviceError> {
        self.inner.wait_reached(t)
    }
    fn position(&mut self, t: Duration) -> Result<[f64; 3], DeviceError> {
        self.inner.position(t)
    }
    fn halt(&mut self, t: Duration) -> Result<[f64; 3], DeviceError> {
        self.inner.halt(t)
    }
    fn fault_reset(&mut self, t: Duration) -> Result<(), DeviceError> {
        self.inner.fault_reset(t)
    }
    fn latency(&self) -> Duration {
        self.inner.latency()
    }
    fn begin_pass(&mut self) {
        self.sent.lock().unwrap().push(TableCmd::Pass);
        self.inner.begin_pass();
    }
}

struct Logged {
    arm: Arc<Mutex<Vec<Vec<f64>>>>,
    table: Arc<Mutex<Vec<TableCmd>>>,
}

fn wrap(
    mut d: RigDevices,
    arm_at: Vec<(usize, Box<dyn Fn() + Send>)>,
    table_at: Vec<(usize, Box<dyn Fn() + Send>)>,
) -> (RigDevices, Logged) {
    let log = Logged {
        arm: Arc::default(),
        table: Arc::default(),
    };
    d.arm = Box::new(FaultyArm {
        inner: d.arm,
        moves: 0,
        at: arm_at,
        sent: Arc::clone(&log.arm),
    });
    if let InstrumentDevices::TablePanel { table, .. } = &mut d.instrument {
        let inner = std::mem::replace(table, Box::new(rigcal_devices::devices::MockTable::new()));
        *table = Box::new(FaultyTable {
            inner,
            moves: 0,
            at: table_at,
            sent: Arc::clone(&log.table),
        });
    }
    (d, log)
}

#[test]
fn injected_faults_leave_a_complete_recording_with_every_skip_explained() {
    let sc = scenario();
    let rig = sc.rig.clone();
    let mut pts = points(&rig, 30, 3);
    // One point the rig cannot measure (the pin points up).
    let n = pts.len();
    pts.insert(
        5,
        PlannedPoint {
            point: 999,
            region: "r1".into(),
            q: [0.0, 10.0, -10.0, 0.0, 0.0].map(f64::to_radians).to_vec(),
            table_mm: [400.0, 280.0, 300.0],
        },
    );
    let OpenedRig { devices: d, hook } = sim_devices(&sc);
    let sim = d.sim.clone().unwrap();
    let (af, tf, pf) = (
        sim.arm.clone().unwrap(),
        sim.table.clone().unwrap(),
        sim.panel.clone().unwrap(),
    );
    let (a1, a2, t1, p1, p2) = (af.clone(), af, tf, pf.clone(), pf.clone());
    let arm_at: Vec<(usize, Box<dyn Fn() + Send>)> = vec![
        // A dropped reply (lost bytes): the move times out and is retried.
        (20, Box::new(move || a1.lock().unwrap().drop_replies = 1)),
        // Error mode II: reset, retried.
        (
            30,
            Box::new(move || a2.lock().unwrap().error_on_next_move = Some(2)),
        ),
    ];
    let table_at: Vec<(usize, Box<dyn Fn() + Send>)> = vec![
        (
            60,
            Box::new(move || {
                t1.lock().unwrap().fault_on_next_move = Some(InjectedFault {
                    axis: 1,
                    after: Duration::from_millis(50),
                    emcy_code: 0x8611,
                })
            }),
        ),
        // One missed touch: retried and measured.
        (
            70,
            Box::new(move || p1.lock().unwrap().miss_next_touch = true),
        ),
    ];
    let (mut d, _log) = wrap(d, arm_at, table_at);
    // Garbage bytes on the panel line before a packet: dropped, never measured.
    p2.lock().unwrap().garbage_before_next = vec![0xFF, 0x00, 0x13];
    // Three touches in a row missed: one point is skipped after its last attempt.
    if let InstrumentDevices::TablePanel { panel, .. } = &mut d.instrument {
        let inner = std::mem::replace(panel, Box::new(rigcal_devices::devices::MockPanel::new()));
        *panel = Box::new(MissingPanel {
            inner,
            calls: 0,
            miss: 40..43,
            faults: pf,
        });
    }
    let dir = tempfile::tempdir().unwrap();
    let report = run_session(
        &rig,
        OpenedRig { devices: d, hook },
        &pts,
        options(dir.path()),
        &Progress::Quiet,
    )
    .unwrap();
    let rec = read(dir.path(), &rig);
    let rows = point_rows(&rec);
    assert_eq!(rows.len(), n + 1, "one row per planned point");
    let skipped: Vec<_> = rows
        .iter()
        .filter_map(|m| match &m.status {
            Status::Skipped(r) => Some(r.clone()),
            _ => None,
        })
        .collect();
    assert_eq!(skipped.len(), report.skipped.len());
    assert!(skipped.iter().all(|r| !r.is_empty()));
    assert!(
        skipped.iter().any(|r| r.contains("pin meets the panel")),
        "{skipped:?}"
    );
    assert!(
        skipped.iter().any(|r| r.contains("missed touch")),
        "{skipped:?}"
    );
    assert!(
        skipped.len() <= 5,
        "{skipped:?}\n{report:?}\n{}",
        std::fs::read_to_string(dir.path().join("measurements.csv")).unwrap()
    );
    assert!(report.retries >= 4, "{report:?}");
    assert!(
        report.faults_cleared.iter().any(|f| f.starts_with("table")),
        "{report:?}"
    );
    assert!(
        report.faults_cleared.iter().any(|f| f.starts_with("arm")),
        "{report:?}"
    );
}

/// A panel that misses the touches of the `miss` range of approaches (counted by `clear`).
struct MissingPanel {
    inner: Box<dyn rigcal_devices::devices::Panel>,
    calls: usize,
    miss: std::ops::Range<usize>,
    faults: rigcal_devices::devices::emulators::faults::PanelFaultHandle,
}

impl rigcal_devices::devices::Panel for MissingPanel {
    fn clear(&mut self) -> Result<(), DeviceError> {
        self.calls += 1;
        if self.miss.contains(&self.calls) {
            self.faults.lock().unwrap().miss_next_touch = true;
        }
        self.inner.clear()
    }
    fn wait_touch(&mut self, t: Duration) -> Result<rigcal_devices::devices::Touch, DeviceError> {
        self.inner.wait_touch(t)
    }
    fn stats(&self) -> rigcal_devices::devices::PanelStats {
        self.inner.stats()
    }
    fn latency(&self) -> Duration {
        self.inner.latency()
    }
}

fn in_limits(joints: &[JointSpec], q: &[f64]) -> bool {
    joints.iter().zip(q).all(|(s, v)| s.within(*v))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 6, ..ProptestConfig::default() })]
    #[test]
    fn commands_sent_stay_in_limits_and_z_ascends_within_a_region_pass(
        seed in 0u64..10_000, n in 8usize..24, regions in prop::sample::select(vec![2usize, 4, 8]),
    ) {
        let sc = scenario();
        let rig = sc.rig.clone();
        let Instrument::TablePanel(tp) = &rig.instrument else { panic!() };
        let pts = plan(&rig, &PlanOptions {
            points: n, regions, reference_every: 7, seed, ..PlanOptions::default()
        }).unwrap().points;
        let OpenedRig { devices: d, hook } = sim_devices(&sc);
        let (d, log) = wrap(d, vec![], vec![]);
        let dir = tempfile::tempdir().unwrap();
        let report = run_session(&rig, OpenedRig { devices: d, hook }, &pts, options(dir.path()), &Progress::Quiet)
            .unwrap();
        // Nothing refused by the safety wrappers (the known phantom-touch skips aside).
        prop_assert!(
            report.skipped.iter().all(|(_, r)| r.contains("touch at")),
            "{:?}",
            report.skipped
        );
        for q in log.arm.lock().unwrap().iter() {
            prop_assert!(in_limits(rig.chain.joints(), q), "{q:?}");
        }
        let retract = rigcal_devices::config::DevicesConfig::read(&rig).table.pass_retract_mm;
        let mut top: Option<f64> = None;
        for c in log.table.lock().unwrap().iter() {
            match c {
                TableCmd::Pass => top = None,
                TableCmd::Move(t) => {
                    for k in 0..3 {
                        prop_assert!(t[k] >= 0.0 && t[k] <= tp.travel_mm[k], "{t:?}");
                    }
                    if let Some(z) = top {
                        prop_assert!(t[2] >= z - retract, "z {} after a pass top of {z}", t[2]);
                    }
                    top = Some(top.map_or(t[2], |z: f64| z.max(t[2])));
                }
            }
        }
        // Within a region's run of points the measured z ascends (up to one z layer).
        let rec = read(dir.path(), &rig);
        let rows = point_rows(&rec);
        let mut prev: Option<(String, f64)> = None;
        for m in rows {
            let (Some(region), Some(t)) = (&m.region, m.table) else { continue };
            if let Some((r, z)) = &prev {
                if r == region {
                    prop_assert!(t.z >= z - 2.0 - 3.0, "region {region}: z {} after {z}", t.z);
                }
            }
            let z = match &prev { Some((r, z)) if r == region => z.max(t.z), _ => t.z };
            prev = Some((region.clone(), z));
        }
    }
}

/// A session on the ideal-instrument rig (the papers' simulations): the same drivers and arm
/// emulator, a simulated point sensor instead of the table and panel, no registration step.
#[test]
fn a_dry_run_on_the_ideal_rig_reads_the_true_tip_at_every_commanded_pose() {
    let sc = Scenario::load(Path::new("sim/paper-sim.toml"), None).unwrap();
    let rig = sc.rig.clone();
    assert!(matches!(rig.instrument, Instrument::Ideal));
    let pts = plan(
        &rig,
        &PlanOptions {
            points: 40,
            regions: 4,
            reference_every: 10,
            seed: 3,
            ..PlanOptions::default()
        },
    )
    .unwrap()
    .points;
    let dir = tempfile::tempdir().unwrap();
    let d = sim_devices(&sc);
    assert!(!d.devices.has_table());
    let report = run_session(&rig, d, &pts, options(dir.path()), &Progress::Quiet).unwrap();
    assert_eq!(report.ok, pts.len(), "{:?}", report.skipped);
    assert_eq!(report.registration_rms_mm, None);
    let rec = read(dir.path(), &rig);
    assert_eq!(
        rec.rows.iter().filter(|m| m.status == Status::Via).count(),
        pts.len(),
        "one via row per point, no registration rows"
    );
    // The paper scenario is static and noise-free: each reading is the true tip at the joints
    // the controller was commanded to (0.1° resolution), which the row records.
    let truth = sc.world();
    for (m, p) in rec.measured() {
        let want = truth.true_position(&m.q);
        assert!((want - p).norm() < 1e-3, "{want} vs {p} at seq {}", m.seq);
        assert!(m.table.is_none());
    }
    // The plan's last columns are the nominal tip, not a table position.
    let plan_text = {
        let p = dir.path().join("plan.csv");
        rigcal_devices::session::write_plan(&p, &rig, &pts).unwrap();
        std::fs::read_to_string(p).unwrap()
    };
    assert!(plan_text
        .lines()
        .next()
        .unwrap()
        .ends_with("tip_x_mm,tip_y_mm,tip_z_mm"));
}

/// Planning mode through the rig: the division asks for every measurement and a dry-run
/// session (drivers and emulators) makes it; the recording holds each one, and the model from
/// it meets the demand along the Fig. 6 path.
#[test]
fn calibrate_through_a_session_measures_where_the_division_asks() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("session");
    let model = dir.path().join("model.json");
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_rigcal"))
            .args(args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let out = run(&[
        "calibrate",
        "--rig",
        "rigs/rv-m2-ideal.toml",
        "--session",
        session.to_str().unwrap(),
        "--sim",
        "sim/paper-sim.toml",
        "--accuracy-mm",
        "0.03",
        "--out",
        model.to_str().unwrap(),
    ]);
    assert!(out.contains("points asked for"), "{out}");
    let rig = Rig::load(Path::new("rigs/rv-m2-ideal.toml")).unwrap();
    let rec = read(&session, &rig);
    let asked = rec
        .rows
        .iter()
        .filter(|m| {
            m.region
                .as_deref()
                .is_some_and(rigcal_devices::session::is_division_region)
                && m.status != Status::Via
        })
        .count();
    assert!(asked >= 40, "{asked} division rows");
    assert_eq!(rec.measured().count(), asked);
    let eval = run(&[
        "evaluate",
        "--model",
        model.to_str().unwrap(),
        "--scenario",
        "sim/paper-sim.toml",
    ]);
    let max_of = |name: &str| -> f64 {
        eval.lines()
            .find(|l| l.trim_start().starts_with(name))
            .and_then(|l| l.split_whitespace().nth(2))
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("{name} in {eval}"))
    };
    assert!(max_of("uncalibrated") > 0.5, "{eval}");
    assert!(max_of("fcmac") < 0.03, "{eval}");
}

/// A table that, before its `nth` move in x-y (the travel beside the arm's move to a via
/// pose), schedules a drive fault 30 ms into that move.
struct FaultOnTravel {
    inner: Box<dyn Table>,
    last_xy: Option<[f64; 2]>,
    travels: usize,
    nth: usize,
    faults: rigcal_devices::devices::emulators::faults::TableFaultHandle,
}

impl Table for FaultOnTravel {
    fn enable(&mut self, t: Duration) -> Result<(), DeviceError> {
        self.inner.enable(t)
    }
    fn set_speed(&mut self, v: f64, t: Duration) -> Result<(), DeviceError> {
        self.inner.set_speed(v, t)
    }
    fn start_move(&mut self, target: [f64; 3], t: Duration) -> Result<(), DeviceError> {
        let xy = [target[0], target[1]];
        if self.last_xy.is_some_and(|l| l != xy) {
            self.travels += 1;
            if self.travels == self.nth {
                self.faults.lock().unwrap().fault_on_next_move = Some(InjectedFault {
                    axis: 0,
                    after: Duration::from_millis(30),
                    emcy_code: 0x2310,
                });
            }
        }
        self.last_xy = Some(xy);
        self.inner.start_move(target, t)
    }
    fn wait_reached(&mut self, t: Duration) -> Result<[f64; 3], DeviceError> {
        self.inner.wait_reached(t)
    }
    fn poll_reached(&mut self, s: Duration, l: Duration) -> Result<Option<[f64; 3]>, DeviceError> {
        self.inner.poll_reached(s, l)
    }
    fn supervise(&mut self) -> Result<(), DeviceError> {
        self.inner.supervise()
    }
    fn position(&mut self, t: Duration) -> Result<[f64; 3], DeviceError> {
        self.inner.position(t)
    }
    fn halt(&mut self, t: Duration) -> Result<[f64; 3], DeviceError> {
        self.inner.halt(t)
    }
    fn fault_reset(&mut self, t: Duration) -> Result<(), DeviceError> {
        self.inner.fault_reset(t)
    }
    fn latency(&self) -> Duration {
        self.inner.latency()
    }
    fn begin_pass(&mut self) {
        self.inner.begin_pass();
    }
}

/// A drive fault while arm and table move together: the session clears it (fault reset),
/// reports it, and measures on; the point does not wait out the arm's move timeout.
#[test]
fn a_table_fault_during_a_simultaneous_move_is_cleared_and_reported() {
    let sc = scenario();
    let rig = sc.rig.clone();
    let pts = points(&rig, 8, 4);
    let OpenedRig {
        devices: mut d,
        hook,
    } = sim_devices(&sc);
    let faults = d.sim.clone().unwrap().table.unwrap();
    if let InstrumentDevices::TablePanel { table, .. } = &mut d.instrument {
        let inner = std::mem::replace(table, Box::new(rigcal_devices::devices::MockTable::new()));
        *table = Box::new(FaultOnTravel {
            inner,
            last_xy: None,
            travels: 0,
            nth: 3,
            faults: faults.clone(),
        });
    }
    let dir = tempfile::tempdir().unwrap();
    let mut o = options(dir.path());
    o.registration_points = 0;
    let report = run_session(
        &rig,
        OpenedRig { devices: d, hook },
        &pts,
        o,
        &Progress::Quiet,
    )
    .unwrap();
    assert!(
        faults.lock().unwrap().fault_on_next_move.is_none(),
        "the fault struck"
    );
    assert!(
        report
            .faults_cleared
            .iter()
            .any(|f| f.starts_with("table") && f.contains("fault")),
        "{report:?}"
    );
    let rec = read(dir.path(), &rig);
    assert_eq!(point_rows(&rec).len(), pts.len());
    // Every point within a few seconds of rig time: nothing waited out a 120 s timeout.
    let times: Vec<f64> = rec.rows.iter().filter_map(|m| m.t_s).collect();
    for w in times.windows(2) {
        assert!(w[1] - w[0] < 30.0, "{} s between rows", w[1] - w[0]);
    }
}

/// A panel that, at its `at`-th contact (counted by `clear`), runs `then` (e.g. silences a
/// drive) and misses the touch, so only a fault can end that approach before its timeout.
struct SilencingPanel {
    inner: Box<dyn rigcal_devices::devices::Panel>,
    calls: usize,
    at: usize,
    then: Box<dyn Fn() + Send>,
    faults: rigcal_devices::devices::emulators::faults::PanelFaultHandle,
}

impl rigcal_devices::devices::Panel for SilencingPanel {
    fn clear(&mut self) -> Result<(), DeviceError> {
        self.calls += 1;
        if self.calls == self.at {
            self.faults.lock().unwrap().miss_next_touch = true;
            (self.then)();
        }
        self.inner.clear()
    }
    fn wait_touch(&mut self, t: Duration) -> Result<rigcal_devices::devices::Touch, DeviceError> {
        self.inner.wait_touch(t)
    }
    fn stats(&self) -> rigcal_devices::devices::PanelStats {
        self.inner.stats()
    }
    fn latency(&self) -> Duration {
        self.inner.latency()
    }
}

/// A drive falls silent during an approach: the supervision task notices, the approach is
/// aborted (table halted, long before its timeout), the session stops with the lost heartbeat
/// and every finished point saved — and resumes once the drive is back.
#[test]
fn a_lost_heartbeat_aborts_the_approach_and_stops_the_session() {
    let sc = scenario();
    let rig = sc.rig.clone();
    let pts = points(&rig, 6, 8);
    let OpenedRig { mut devices, hook } = sim_devices(&sc);
    let sim = devices.sim.clone().unwrap();
    let table_faults = sim.table.clone().unwrap();
    if let InstrumentDevices::TablePanel { panel, .. } = &mut devices.instrument {
        let inner = std::mem::replace(panel, Box::new(rigcal_devices::devices::MockPanel::new()));
        *panel = Box::new(SilencingPanel {
            inner,
            calls: 0,
            at: 5,
            then: Box::new(move || table_faults.lock().unwrap().silent_heartbeat[1] = true),
            faults: sim.panel.clone().unwrap(),
        });
    }
    let dir = tempfile::tempdir().unwrap();
    let mut o = options(dir.path());
    o.registration_points = 0;
    let e = run_session(&rig, OpenedRig { devices, hook }, &pts, o, &Progress::Quiet).unwrap_err();
    match &e {
        rigcal_devices::session::SessionError::Device {
            source: DeviceError::HeartbeatLost { axis: 'y', .. },
            stage,
        } => assert!(stage.contains("measuring"), "{stage}"),
        other => panic!("{other}"),
    }
    // Halted at once: the table stands still, not at the end of the approach.
    let truth = sim.table_truth.lock().unwrap();
    for axis in &truth.axes {
        assert_eq!(axis.from, axis.to, "{axis:?}");
    }
    drop(truth);
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("journal.json")).unwrap())
            .unwrap();
    assert_eq!(j["finished"], false);
    // The drive is back (new devices): the session resumes and finishes.
    let mut o = options(dir.path());
    o.registration_points = 0;
    o.resume = true;
    let report = run_session(&rig, sim_devices(&sc), &pts, o, &Progress::Quiet).unwrap();
    assert_eq!(report.points, pts.len());
    assert_eq!(point_rows(&read(dir.path(), &rig)).len(), pts.len());
}

/// Planning mode: a fault the session cannot clear (arm error mode I) stops the division at
/// once, with the session's error as the cause; nothing more is asked of the rig.
#[test]
fn a_fatal_rig_fault_stops_the_division_at_once() {
    use rigcal_model::division::{divide, DivisionError, DivisionOptions, Measurer, Mode};
    use rigcal_model::identification::{analyse, candidate_order, random_poses, Observation};
    let sc = Scenario::load(Path::new("sim/paper-sim.toml"), None).unwrap();
    let rig = sc.rig.clone();
    let OpenedRig { devices, hook } = sim_devices(&sc);
    let arm = devices.sim.clone().unwrap().arm.unwrap();
    let (devices, _log) = wrap(
        devices,
        vec![(
            25,
            Box::new(move || arm.lock().unwrap().error_on_next_move = Some(1)),
        )],
        vec![],
    );
    let dir = tempfile::tempdir().unwrap();
    let mut session = rigcal_devices::session::Session::open(
        &rig,
        OpenedRig { devices, hook },
        options(dir.path()),
    )
    .unwrap();
    struct Counting<'a, 's, 'r> {
        inner: &'a mut rigcal_devices::session::SessionMeasurer<'s, 'r>,
        calls: usize,
        failed_at: Option<usize>,
    }
    impl Measurer for Counting<'_, '_, '_> {
        fn measure(
            &mut self,
            q: &[f64],
        ) -> Result<Option<Observation>, rigcal_model::division::MeasureError> {
            assert!(
                self.failed_at.is_none(),
                "asked again after the session stopped"
            );
            self.calls += 1;
            let r = self.inner.measure(q);
            if r.is_err() {
                self.failed_at = Some(self.calls);
            }
            r
        }
    }
    let mut inner = rigcal_devices::session::SessionMeasurer::new(&mut session, &rig);
    let mut m = Counting {
        inner: &mut inner,
        calls: 0,
        failed_at: None,
    };
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(1);
    let design = random_poses(rig.chain.joints(), rig.held(), 100, &mut rng);
    let basis = analyse(&rig.chain, &design, &candidate_order(&rig)).basis;
    let opts = DivisionOptions {
        accuracy_mm: 0.001,
        ..DivisionOptions::default()
    };
    let e = match divide(&rig, &basis, Mode::Planning(&mut m), &opts, |_, _| {}) {
        Err(e) => e,
        Ok(_) => panic!("the division went on past the fault"),
    };
    let failed_at = m.failed_at.expect("a measurement failed");
    assert_eq!(failed_at, m.calls);
    let DivisionError::Measurement(me) = &e else {
        panic!("{e}")
    };
    match me
        .source
        .downcast_ref::<rigcal_devices::session::SessionError>()
    {
        Some(rigcal_devices::session::SessionError::Device {
            source: DeviceError::ArmErrorMode { code: 1, .. },
            ..
        }) => {}
        other => panic!("{other:?}"),
    }
}

/// The rig-time estimate walks the session's own moves: within 5 % of the dry run's virtual
/// clock on the table rig and on the ideal point-sensor rig (it was 17–23 % off when it left
/// out the clearance moves and counted a flat 0.3 s of exchanges per point).
#[test]
fn the_rig_time_estimate_matches_the_dry_run_clock_within_5_percent_on_both_rigs() {
    for (scenario, n) in [(SCENARIO, 40), ("sim/paper-sim.toml", 40)] {
        let sc = Scenario::load(Path::new(scenario), None).unwrap();
        let rig = sc.rig.clone();
        let pts = points(&rig, n, 5);
        let dir = tempfile::tempdir().unwrap();
        let o = options(dir.path());
        let reg = registration_points(&rig, o.registration_points, o.seed);
        let est = estimate(
            &rig,
            &[reg, pts.clone()].concat(),
            &RigSpeeds::of(&rig),
            &ContactSettings::of(&rig),
        );
        let report = run_session(&rig, sim_devices(&sc), &pts, o, &Progress::Quiet).unwrap();
        let ratio = est.total_s / report.rig_time_s;
        eprintln!(
            "{scenario}: estimate {:.1} s, clock {:.1} s",
            est.total_s, report.rig_time_s
        );
        assert!(
            (0.95..=1.05).contains(&ratio),
            "{scenario}: estimate {:.1} s vs clock {:.1} s",
            est.total_s,
            report.rig_time_s
        );
        // The breakdown's parts add up to the total.
        assert!((est.breakdown.total_s() - est.total_s).abs() < 1e-6 * est.total_s);
        assert!(est.breakdown.approach_s > 0.0 && est.breakdown.arm_s > 0.0);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]
    /// The optimised order reorders freely inside the z window, never beyond it: within each
    /// region, no point's nominal contact lies more than the window below an earlier one's.
    #[test]
    fn the_optimised_order_never_breaks_the_ascending_z_rule_within_a_pass(
        seed in 0u64..10_000, n in 20usize..200, regions in prop::sample::select(vec![1usize, 2, 4, 8]),
        reference_every in prop::sample::select(vec![0usize, 7, 50]),
    ) {
        let rig = scenario().rig;
        let window = z_window_mm(&rig);
        let retract = rigcal_devices::config::DevicesConfig::read(&rig).table.pass_retract_mm;
        let c = ContactSettings::of(&rig);
        // The window leaves the pass rule its margins (see `z_window_mm`).
        prop_assert!(window > 0.0 && window + 2.0 * c.margin_mm + c.clearance_mm <= retract);
        let p = plan(&rig, &PlanOptions {
            points: n, regions, reference_every, seed, order: Ordering::Optimised,
            ..PlanOptions::default()
        }).unwrap();
        let mut top: std::collections::HashMap<&str, f64> = Default::default();
        for pt in p.points.iter().filter(|p| p.region != "ref") {
            let z = pt.table_mm[2];
            if let Some(t) = top.get(pt.region.as_str()) {
                prop_assert!(z >= t - window - 1e-9, "{}: z {z} after a top of {t}", pt.region);
            }
            let t = top.entry(pt.region.as_str()).or_insert(z);
            *t = t.max(z);
        }
        // The same points as the paper's order, in another order.
        let zxy = plan(&rig, &PlanOptions {
            points: n, regions, reference_every, seed, order: Ordering::ZThenXY,
            ..PlanOptions::default()
        }).unwrap();
        let key = |v: &[PlannedPoint]| {
            let mut k: Vec<String> = v.iter().map(|p| format!("{}{:?}", p.region, p.table_mm)).collect();
            k.sort();
            k
        };
        prop_assert_eq!(key(&p.points), key(&zxy.points));
    }
}

/// The two-phase final approach, by hand: locating from a margin below at the locating speed,
/// the back-off at travel speed, the quick rise to the standoff (twice the locating touch's
/// latency overshoot below it), the creep over the standoff at the latency-rule speed.
#[test]
fn the_estimate_counts_the_two_phase_approach_by_hand() {
    let rig = scenario().rig;
    let pts = points(&rig, 12, 9);
    let p = pts.iter().find(|p| p.region != "ref").unwrap();
    let (speeds, c) = (RigSpeeds::of(&rig), ContactSettings::of(&rig));
    let one = estimate(&rig, std::slice::from_ref(p), &speeds, &c);
    // rv-m2: 5 mm/s locating, (10 + 2) ms latency, 100 mm/s and 500 mm/s²; the back-off at
    // the standoff (0.12 mm), so one quick move down to it.
    let standoff = (2.0 * 5.0 * 0.012_f64).min(c.backoff_mm);
    assert!(
        (c.standoff_mm - standoff).abs() < 1e-12,
        "{}",
        c.standoff_mm
    );
    let v = 0.005 / 0.012;
    assert!((speeds.approach_mm_s - v).abs() < 1e-12);
    let trapezoid = |d: f64, v: f64| d / v + v / 500.0;
    let triangle = |d: f64| {
        if d > 0.0 {
            2.0 * (d / 500.0).sqrt()
        } else {
            0.0
        }
    };
    let by_hand = trapezoid(2.5, 5.0)
        + triangle(c.backoff_mm)
        + triangle(c.backoff_mm - standoff)
        + trapezoid(standoff, v);
    // The single-stage creep over the whole 0.3 mm back-off it replaced: 0.4 s more a point.
    let single = trapezoid(2.5, 5.0) + triangle(0.3) + trapezoid(0.3, v);
    assert!(single - by_hand > 0.4, "{single} vs {by_hand}");
    assert!(
        (one.breakdown.approach_s - by_hand).abs() < 1e-3,
        "{} s vs {by_hand} s by hand",
        one.breakdown.approach_s
    );
}

/// On the same points the optimised order's planned rig time is well below the paper's order
/// (the x-y table moves, which dominate, shortened inside the z window), and the dry run's
/// clock agrees with both estimates.
#[test]
fn the_optimised_order_saves_rig_time_against_z_then_xy_planned_and_on_the_clock() {
    let sc = scenario();
    let rig = sc.rig.clone();
    let (speeds, c) = (RigSpeeds::of(&rig), ContactSettings::of(&rig));
    let plan_of = |order| {
        plan(
            &rig,
            &PlanOptions {
                points: 300,
                regions: 2,
                seed: 4,
                order,
                ..PlanOptions::default()
            },
        )
        .unwrap()
        .points
    };
    let (opt, zxy) = (plan_of(Ordering::Optimised), plan_of(Ordering::ZThenXY));
    let (a, b) = (
        estimate(&rig, &opt, &speeds, &c),
        estimate(&rig, &zxy, &speeds, &c),
    );
    assert!(
        a.breakdown.table_s < 0.85 * b.breakdown.table_s && a.total_s < 0.92 * b.total_s,
        "optimised {} s (table {:.0} s) vs z-then-xy {} s (table {:.0} s)",
        a.total_s,
        a.breakdown.table_s,
        b.total_s,
        b.breakdown.table_s
    );
    for pts in [&opt[..60], &zxy[..60]] {
        let dir = tempfile::tempdir().unwrap();
        let o = options(dir.path());
        let reg = registration_points(&rig, o.registration_points, o.seed);
        let e = estimate(&rig, &[reg, pts.to_vec()].concat(), &speeds, &c);
        let report = run_session(&rig, sim_devices(&sc), pts, o, &Progress::Quiet).unwrap();
        let ratio = e.total_s / report.rig_time_s;
        assert!(
            (0.95..=1.05).contains(&ratio),
            "estimate {:.1} s vs clock {:.1} s",
            e.total_s,
            report.rig_time_s
        );
    }
}
