//! Stops are safe stops, timing faults are seen (issue 34, items 2 and 3): a stop request
//! (what SIGINT and SIGTERM raise) during a move quick-stops the table's drives on the
//! emulated bus, sends the arm nothing more, and leaves a session that `--resume` completes to
//! the uninterrupted recording; the binary does the same on SIGINT; a table that stops
//! answering SDOs ends the session as a fault, resumable; a few per cent of SDO frames lost
//! neither stop the bring-up nor the session; drives answering late get their contacts
//! refused and repeated, the latency kept in the recording, and a bus late for every contact
//! ends the session as a fault; a touch that comes while the approach's move is still being
//! started, or whose first packet is corrupt, costs the contact instead of biasing it; and
//! where the z drive latches the contact height (`[devices.table] touch_probe = true`), drives
//! 20–150 ms late move no height, while the position read after the touch would be that late.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use rigcal_core::kinematics::Robot;
use rigcal_core::recording::{Recording, Status};
use rigcal_core::rig::Rig;
use rigcal_devices::devices::emulators::faults::{FrameLoss, TableFaultHandle};
use rigcal_devices::devices::{
    open_devices, Backend, DeviceError, DeviceName, InstrumentDevices, OpenedRig, SimClock, Table,
};
use rigcal_devices::session::{
    plan, run_session, Journal, PlanOptions, PlannedPoint, Progress, SessionError, SessionOptions,
    SessionReport, StopRequest,
};
use rigcal_sim::world::Scenario;

const SCENARIO: &str = "sim/rig-realistic.toml";
const T: Duration = Duration::from_secs(30);
/// CiA 402 controlword: quick stop.
const QUICK_STOP: u16 = 0x0002;

fn scenario() -> Scenario {
    Scenario::load(Path::new(SCENARIO), None).unwrap()
}

fn points(rig: &Rig, n: usize) -> Vec<PlannedPoint> {
    plan(
        rig,
        &PlanOptions {
            points: n,
            regions: 2,
            reference_every: 0,
            seed: 3,
            ..PlanOptions::default()
        },
    )
    .unwrap()
    .points
}

fn options(dir: &Path) -> SessionOptions {
    let mut o = SessionOptions::new(dir);
    o.registration_points = 4;
    o.fsync = false;
    o
}

fn sim_devices(sc: &Scenario) -> OpenedRig {
    rigcal_sim::emulation::open_rig(&sc.rig, Some(sc), SimClock::Virtual).unwrap()
}

fn table_faults(opened: &OpenedRig) -> TableFaultHandle {
    opened.devices.sim.as_ref().unwrap().table.clone().unwrap()
}

/// A whole session in `dir`, undisturbed.
fn uninterrupted(sc: &Scenario, pts: &[PlannedPoint], dir: &Path) -> SessionReport {
    run_session(
        &sc.rig,
        sim_devices(sc),
        pts,
        options(dir),
        &Progress::Quiet,
    )
    .unwrap()
}

/// Resumes the session in `dir` on fresh emulators (the fault gone).
fn resume(sc: &Scenario, pts: &[PlannedPoint], dir: &Path) -> SessionReport {
    let mut o = options(dir);
    o.resume = true;
    run_session(&sc.rig, sim_devices(sc), pts, o, &Progress::Quiet).unwrap()
}

fn journal(dir: &Path) -> Journal {
    Journal::load(dir).unwrap()
}

fn read(dir: &Path, rig: &Rig) -> Recording {
    Recording::read(&dir.join("measurements.csv"), rig.chain.joints()).unwrap()
}

/// Column `name` of every row of the recording in `dir`, as text.
fn column(dir: &Path, name: &str) -> Vec<String> {
    let text = std::fs::read_to_string(dir.join("measurements.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let k = header
        .iter()
        .position(|c| *c == name)
        .unwrap_or_else(|| panic!("no `{name}` column in {header:?}"));
    lines
        .map(|l| l.split(',').nth(k).unwrap_or("").to_string())
        .collect()
}

/// The two recordings hold the same rows: same seq, status and region; numbers within
/// 0.0015 (t_s and the latency may differ by float rounding of a resumed time base).
fn same_recording(a: &Path, b: &Path) {
    let ta = std::fs::read_to_string(a.join("measurements.csv")).unwrap();
    let tb = std::fs::read_to_string(b.join("measurements.csv")).unwrap();
    let (la, lb): (Vec<&str>, Vec<&str>) = (ta.lines().collect(), tb.lines().collect());
    assert_eq!(la.len(), lb.len(), "row count");
    for (ra, rb) in la.iter().zip(&lb) {
        let (fa, fb): (Vec<&str>, Vec<&str>) = (ra.split(',').collect(), rb.split(',').collect());
        assert_eq!(fa.len(), fb.len());
        for (x, y) in fa.iter().zip(&fb) {
            match (x.parse::<f64>(), y.parse::<f64>()) {
                (Ok(x), Ok(y)) => assert!((x - y).abs() <= 0.0015, "{ra}\n{rb}"),
                _ => assert_eq!(x, y, "{ra}\n{rb}"),
            }
        }
    }
}

/// Wraps the rig's table: `then` runs (once) at the first table move longer than 20 mm once
/// the session's journal says `after` points are done; the move's target is kept.
struct OnLongMove {
    inner: Box<dyn Table>,
    journal_dir: PathBuf,
    after: usize,
    last_target: Option<[f64; 3]>,
    then: Option<Box<dyn FnOnce([f64; 3]) + Send>>,
}

impl OnLongMove {
    fn wrap(
        opened: &mut OpenedRig,
        dir: &Path,
        after: usize,
        then: Box<dyn FnOnce([f64; 3]) + Send>,
    ) {
        let InstrumentDevices::TablePanel { table, .. } = &mut opened.devices.instrument else {
            panic!("a table rig")
        };
        let inner = std::mem::replace(table, Box::new(rigcal_devices::devices::MockTable::new()));
        *table = Box::new(OnLongMove {
            inner,
            journal_dir: dir.to_path_buf(),
            after,
            last_target: None,
            then: Some(then),
        });
    }

    fn due(&self, target: [f64; 3]) -> bool {
        let long = self.last_target.is_some_and(|p| {
            let d: f64 = (0..3).map(|k| (target[k] - p[k]).powi(2)).sum();
            d.sqrt() > 20.0
        });
        long && self.then.is_some()
            && Journal::load(&self.journal_dir).is_ok_and(|j| j.next_point >= self.after)
    }
}

impl Table for OnLongMove {
    fn enable(&mut self, t: Duration) -> Result<(), DeviceError> {
        self.inner.enable(t)
    }
    fn set_speed(&mut self, v: f64, t: Duration) -> Result<(), DeviceError> {
        self.inner.set_speed(v, t)
    }
    fn start_move(&mut self, target: [f64; 3], t: Duration) -> Result<(), DeviceError> {
        let due = self.due(target);
        self.last_target = Some(target);
        let r = self.inner.start_move(target, t);
        if due {
            if let Some(then) = self.then.take() {
                then(target);
            }
        }
        r
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
    fn quick_stop(&mut self, t: Duration) -> Result<[f64; 3], DeviceError> {
        self.inner.quick_stop(t)
    }
    fn fault_reset(&mut self, t: Duration) -> Result<(), DeviceError> {
        self.inner.fault_reset(t)
    }
    fn latency(&self) -> Duration {
        self.inner.latency()
    }
    fn begin_pass(&mut self) {
        self.inner.begin_pass()
    }
}

/// True for a Movemaster command line that moves the arm (or changes how it moves).
fn is_motion(line: &str) -> bool {
    ["MJ", "MP", "DJ", "NT", "SP"]
        .iter()
        .any(|m| line.starts_with(m))
}

#[test]
fn a_stop_request_during_a_table_move_quick_stops_the_drives_and_a_resume_completes_the_session() {
    let sc = scenario();
    let pts = points(&sc.rig, 8);
    let base = tempfile::tempdir().unwrap();
    let (a, b) = (base.path().join("a"), base.path().join("b"));
    uninterrupted(&sc, &pts, &a);

    let mut opened = sim_devices(&sc);
    let sim = opened.devices.sim.clone().unwrap();
    let (tf, arm_log) = (sim.table.clone().unwrap(), sim.arm.clone().unwrap());
    let stop = StopRequest::new();
    // What the arm had received when the stop was requested, and the move then under way.
    let arm_seen = Arc::new(Mutex::new(None::<usize>));
    let target = Arc::new(Mutex::new(None::<[f64; 3]>));
    {
        let (stop, arm_log, arm_seen, target) = (
            stop.clone(),
            arm_log.clone(),
            Arc::clone(&arm_seen),
            Arc::clone(&target),
        );
        OnLongMove::wrap(
            &mut opened,
            &b,
            3,
            Box::new(move |t| {
                *target.lock().unwrap() = Some(t);
                *arm_seen.lock().unwrap() = Some(arm_log.lock().unwrap().received.len());
                stop.request("SIGINT");
            }),
        );
    }
    let mut o = options(&b);
    o.stop = stop;
    let e = run_session(&sc.rig, opened, &pts, o, &Progress::Quiet).unwrap_err();
    let SessionError::Stopped {
        reason, devices, ..
    } = &e
    else {
        panic!("not a safe stop: {e}")
    };
    assert_eq!(reason, "SIGINT");
    assert!(devices.contains("quick-stopped"), "{e}");
    assert!(e.to_string().contains("--resume"), "{e}");

    // Every drive got the CiA 402 quick stop, last, and stands still short of the target.
    let f = tf.lock().unwrap();
    assert_eq!(f.last_controlword, [Some(QUICK_STOP); 3], "{e}");
    drop(f);
    let target = target.lock().unwrap().expect("the stop was requested");
    let truth = sim.table_truth.lock().unwrap();
    assert!(
        truth.axes.iter().all(|p| p.from == p.to),
        "{:?}",
        truth.axes
    );
    let off: f64 = (0..3)
        .map(|k| (truth.axes[k].to - target[k]).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(off > 1.0, "stopped {off} mm from the move's target");
    drop(truth);
    // No motion reached the arm after the request.
    let seen = arm_seen.lock().unwrap().expect("the stop was requested");
    let after: Vec<String> = arm_log.lock().unwrap().received[seen..].to_vec();
    assert!(!after.iter().any(|l| is_motion(l)), "{after:?}");

    // Resumable: the journal is not finished, and --resume completes the session to the
    // recording of the uninterrupted one.
    assert!(!journal(&b).finished);
    resume(&sc, &pts, &b);
    assert!(journal(&b).finished);
    same_recording(&a, &b);
}

#[test]
fn a_table_that_stops_answering_sdos_ends_the_session_as_a_fault_that_resumes() {
    let sc = scenario();
    let pts = points(&sc.rig, 8);
    let base = tempfile::tempdir().unwrap();
    let (a, b) = (base.path().join("a"), base.path().join("b"));
    uninterrupted(&sc, &pts, &a);

    let mut opened = sim_devices(&sc);
    let tf = table_faults(&opened);
    {
        let tf = tf.clone();
        OnLongMove::wrap(
            &mut opened,
            &b,
            3,
            Box::new(move |_| tf.lock().unwrap().ignore_sdo = true),
        );
    }
    let e = run_session(&sc.rig, opened, &pts, options(&b), &Progress::Quiet).unwrap_err();
    assert!(
        matches!(
            e,
            SessionError::DeviceLost {
                device: DeviceName::Table,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("--resume"), "{e}");
    // Not finished, and the lost point not given up: no skipped row.
    let j = journal(&b);
    assert!(!j.finished);
    assert!(j.next_point >= 3 && j.next_point < pts.len(), "{j:?}");
    let rec = read(&b, &sc.rig);
    assert!(
        rec.rows
            .iter()
            .all(|m| !matches!(m.status, Status::Skipped(_))),
        "{:?}",
        rec.rows.iter().map(|m| &m.status).collect::<Vec<_>>()
    );
    resume(&sc, &pts, &b);
    same_recording(&a, &b);
}

#[test]
fn bring_up_and_a_session_survive_a_few_per_cent_of_lost_sdo_frames() {
    let sc = scenario();
    // The drives enabled with 5 % of SDO frames lost, each way, for several loss schedules.
    for seed in 1..=6 {
        let (setup, _world) = rigcal_sim::emulation::setup_from_scenario(&sc);
        let mut d = open_devices(&sc.rig, Backend::Simulated(setup)).unwrap();
        let tf = d.sim.as_ref().unwrap().table.clone().unwrap();
        tf.lock().unwrap().sdo_loss = FrameLoss::new(0.05, seed);
        d.table().unwrap().enable(T).unwrap();
        let lost = tf.lock().unwrap().sdo_loss.lost;
        assert!(lost > 0, "seed {seed}: no frame was lost");
    }
    // A whole session with 3 % lost: every point measured.
    let pts = points(&sc.rig, 6);
    let dir = tempfile::tempdir().unwrap();
    let opened = sim_devices(&sc);
    let tf = table_faults(&opened);
    tf.lock().unwrap().sdo_loss = FrameLoss::new(0.03, 7);
    let report = run_session(&sc.rig, opened, &pts, options(dir.path()), &Progress::Quiet).unwrap();
    assert!(tf.lock().unwrap().sdo_loss.lost > 5);
    assert_eq!(report.ok, pts.len(), "{report:?}");
}

/// Wraps the rig's table: a position read during a final approach (the table set to less than
/// 1 mm/s) answers `delay` late, for the final approaches numbered in `late` (1-based, counted
/// from the registration's first).
struct LateFinalReads {
    inner: Box<dyn Table>,
    faults: TableFaultHandle,
    delay: Duration,
    late: std::ops::Range<usize>,
    finals: usize,
    creeping: bool,
    late_reads: Arc<LateLog>,
}

/// What [`LateFinalReads`] saw: whether a late read happened, and the z each late read gave.
#[derive(Default)]
struct LateLog {
    happened: AtomicBool,
    z_mm: Mutex<Vec<f64>>,
}

impl LateFinalReads {
    fn wrap(opened: &mut OpenedRig, delay: Duration, late: std::ops::Range<usize>) -> Arc<LateLog> {
        let faults = table_faults(opened);
        let InstrumentDevices::TablePanel { table, .. } = &mut opened.devices.instrument else {
            panic!("a table rig")
        };
        let inner = std::mem::replace(table, Box::new(rigcal_devices::devices::MockTable::new()));
        let late_reads = Arc::new(LateLog::default());
        *table = Box::new(LateFinalReads {
            inner,
            faults,
            delay,
            late,
            finals: 0,
            creeping: false,
            late_reads: Arc::clone(&late_reads),
        });
        late_reads
    }
}

impl Table for LateFinalReads {
    fn enable(&mut self, t: Duration) -> Result<(), DeviceError> {
        self.inner.enable(t)
    }
    fn set_speed(&mut self, v: f64, t: Duration) -> Result<(), DeviceError> {
        self.creeping = v < 1.0;
        if self.creeping {
            self.finals += 1;
        }
        self.inner.set_speed(v, t)
    }
    fn start_move(&mut self, target: [f64; 3], t: Duration) -> Result<(), DeviceError> {
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
        let late = self.creeping && self.late.contains(&self.finals);
        if !late {
            return self.inner.position(t);
        }
        self.late_reads.happened.store(true, Ordering::SeqCst);
        self.faults.lock().unwrap().extra_delay = self.delay;
        let r = self.inner.position(t);
        self.faults.lock().unwrap().extra_delay = Duration::ZERO;
        if let Ok(p) = &r {
            self.late_reads.z_mm.lock().unwrap().push(p[2]);
        }
        r
    }
    fn halt(&mut self, t: Duration) -> Result<[f64; 3], DeviceError> {
        self.inner.halt(t)
    }
    fn quick_stop(&mut self, t: Duration) -> Result<[f64; 3], DeviceError> {
        self.inner.quick_stop(t)
    }
    fn fault_reset(&mut self, t: Duration) -> Result<(), DeviceError> {
        self.inner.fault_reset(t)
    }
    fn latency(&self) -> Duration {
        self.inner.latency()
    }
    fn begin_pass(&mut self) {
        self.inner.begin_pass()
    }
    fn arm_touch_probe(&mut self, t: Duration) -> Result<(), DeviceError> {
        self.inner.arm_touch_probe(t)
    }
    fn latched_z(&mut self, t: Duration) -> Result<Option<f64>, DeviceError> {
        self.inner.latched_z(t)
    }
}

/// The `latency_ms` of the `ok` rows of the recording in `dir`.
fn ok_latencies(dir: &Path) -> Vec<f64> {
    column(dir, "latency_ms")
        .iter()
        .zip(column(dir, "status"))
        .filter(|(_, s)| s == "ok")
        .map(|(l, _)| l.parse::<f64>().expect("an ok row has its latency"))
        .collect()
}

#[test]
fn a_late_contact_reading_is_refused_and_repeated_and_the_latency_recorded() {
    let sc = scenario();
    let pts = points(&sc.rig, 6);
    let base = tempfile::tempdir().unwrap();
    let (a, b) = (base.path().join("a"), base.path().join("b"));
    let normal = uninterrupted(&sc, &pts, &a);
    // The rig's latencies: a reading takes the bus latency of the rig file (2 ms).
    let la = ok_latencies(&a);
    assert_eq!(la.len(), pts.len());
    assert!(la.iter().all(|l| (1.5..=3.0).contains(l)), "{la:?}");

    // Final approach 6 (a point's, after the registration's four) answers 40 ms late: at the
    // final approach's 0.42 mm/s that would be 0.02 mm high, four times the budget.
    let mut opened = sim_devices(&sc);
    let late = LateFinalReads::wrap(&mut opened, Duration::from_millis(40), 6..7);
    let report = run_session(&sc.rig, opened, &pts, options(&b), &Progress::Quiet).unwrap();
    assert!(
        late.happened.load(Ordering::SeqCst),
        "the late reading happened"
    );
    assert_eq!(report.ok, pts.len(), "{report:?}");
    assert!(
        report.retries > normal.retries,
        "{report:?} against {normal:?}"
    );
    // Only timely readings were kept, each with its latency.
    let lb = ok_latencies(&b);
    assert_eq!(lb.len(), pts.len());
    assert!(lb.iter().all(|l| (1.5..=3.0).contains(l)), "{lb:?}");
}

#[test]
fn drives_late_for_every_contact_end_the_session_as_a_fault_not_as_biased_rows() {
    let sc = scenario();
    let pts = points(&sc.rig, 8);
    let dir = tempfile::tempdir().unwrap();
    // From the points on (after the registration's four final approaches), every final
    // reading answers 100 ms late (the 20–150 ms, inside the 200 ms SDO timeout).
    let mut opened = sim_devices(&sc);
    LateFinalReads::wrap(&mut opened, Duration::from_millis(100), 5..usize::MAX);
    let e = run_session(&sc.rig, opened, &pts, options(dir.path()), &Progress::Quiet).unwrap_err();
    let SessionError::DeviceLost { device, detail, .. } = &e else {
        panic!("not a device loss: {e}")
    };
    assert_eq!(*device, DeviceName::Table);
    assert!(detail.contains("overshoot"), "{e}");
    assert!(!journal(dir.path()).finished);
    // No biased row was written: every ok row's reading came in time.
    let l = ok_latencies(dir.path());
    assert!(l.iter().all(|l| *l <= 3.0), "{l:?}");
}

/// The shipped scenario without its time-dependent effect (thermal drift: late drives make a
/// session's times, and so its drift, differ), on the shipped rig with its z drive latching the
/// contact heights (`touch_probe = true`), as files in `dir`.
fn latching_scenario(dir: &Path) -> Scenario {
    let rig_text = std::fs::read_to_string("rigs/rv-m2.toml").unwrap();
    let rig_text = rig_text.replace("\n[devices.panel]", "touch_probe = true\n\n[devices.panel]");
    let rig = dir.join("latching.toml");
    std::fs::write(&rig, rig_text).unwrap();
    let mut doc: toml::Table = std::fs::read_to_string(SCENARIO).unwrap().parse().unwrap();
    doc.insert("rig".into(), rig.display().to_string().into());
    let effects = doc["effects"].as_array_mut().unwrap();
    effects.retain(|e| !e["kind"].as_str().unwrap().contains("drift"));
    let path = dir.join("scenario.toml");
    std::fs::write(&path, toml::to_string(&doc).unwrap()).unwrap();
    let sc = Scenario::load(&path, None).unwrap();
    let cfg = rigcal_devices::config::DevicesConfig::read(&sc.rig);
    assert!(cfg.table.touch_probe, "the rig latches");
    sc
}

#[test]
fn a_latched_contact_height_does_not_move_with_drives_20_to_150_ms_late() {
    let base = tempfile::tempdir().unwrap();
    let sc = latching_scenario(base.path());
    let pts = points(&sc.rig, 6);
    let on_time = base.path().join("on-time");
    let normal = uninterrupted(&sc, &pts, &on_time);
    assert_eq!(normal.ok, pts.len(), "{normal:?}");
    // The final approach's speed (the latency rule: 0.005 mm over 10 + 2 ms).
    let speed = 0.005 / 0.012;
    let kept = [
        "status",
        "table_x_mm",
        "table_y_mm",
        "table_z_mm",
        "panel_u_mm",
        "panel_v_mm",
        "x_mm",
        "y_mm",
        "z_mm",
    ];
    for ms in [20, 60, 150] {
        let dir = base.path().join(format!("late-{ms}"));
        let delay = Duration::from_millis(ms);
        // Every point's final reading (after the registration's four) answers `ms` late.
        let mut opened = sim_devices(&sc);
        let late = LateFinalReads::wrap(&mut opened, delay, 5..usize::MAX);
        let report = run_session(&sc.rig, opened, &pts, options(&dir), &Progress::Quiet).unwrap();
        // Nothing refused, nothing repeated: a latched height is never late.
        assert_eq!(report.ok, pts.len(), "{ms} ms: {report:?}");
        assert_eq!(report.retries, normal.retries, "{ms} ms: {report:?}");
        for col in kept {
            assert_eq!(
                column(&dir, col),
                column(&on_time, col),
                "{col}, {ms} ms late"
            );
        }
        // The latency is still recorded: the points' readings came `ms` late.
        let l = ok_latencies(&dir);
        assert!(l[4..].iter().all(|l| *l >= ms as f64), "{ms} ms: {l:?}");
        // The position read after the touch would have been biased: the table rose at the
        // approach speed for the panel's and the bus's latencies and the delay.
        let read = late.z_mm.lock().unwrap().clone();
        let latched: Vec<f64> = column(&dir, "table_z_mm")
            .iter()
            .zip(column(&dir, "region"))
            .filter(|(z, r)| !z.is_empty() && r != "reg")
            .map(|(z, _)| z.parse().unwrap())
            .collect();
        assert_eq!(read.len(), latched.len(), "{read:?} {latched:?}");
        let biases: Vec<String> = read
            .iter()
            .zip(&latched)
            .map(|(r, z)| format!("{:.4}", r - z))
            .collect();
        eprintln!("{ms} ms late: read-after-touch z minus latched z (mm): {biases:?}");
        for (r, z) in read.iter().zip(&latched) {
            let bias = r - z;
            let least = speed * delay.as_secs_f64();
            assert!(
                (least..=least + speed * 0.03).contains(&bias),
                "{ms} ms: read {r} mm, latched {z} mm: {bias:.4} mm, not ≥ {least:.4} mm"
            );
        }
    }
}

/// `rigcal session` on SIGINT: a clear message, a non-zero exit, a resumable session that
/// `--resume` completes to the uninterrupted recording.
#[cfg(unix)]
#[test]
fn sigint_stops_the_binary_safely_and_resume_completes_it() {
    let base = tempfile::tempdir().unwrap();
    let (a, b) = (base.path().join("a"), base.path().join("b"));
    let cmd = |dir: &Path, resume: bool| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_rigcal"));
        c.args([
            "session",
            "--rig",
            "rigs/rv-m2.toml",
            "--sim",
            SCENARIO,
            "--points",
            "300",
            "--regions",
            "4",
            "--registration-points",
            "6",
            "--out",
        ])
        .arg(dir)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped());
        if resume {
            c.arg("--resume");
        }
        c
    };
    assert!(cmd(&a, false).status().unwrap().success());
    let mut stopped = None;
    for _ in 0..20 {
        let _ = std::fs::remove_dir_all(&b);
        let child = cmd(&b, false).spawn().unwrap();
        // Once the first points are committed (the session runs, its signal handler is in).
        let t0 = std::time::Instant::now();
        while !Journal::load(&b).is_ok_and(|j| j.next_point >= 2)
            && t0.elapsed() < Duration::from_secs(30)
        {
            std::thread::sleep(Duration::from_millis(1));
        }
        // SAFETY: kill(2) on our own child's pid with a valid signal number.
        let rc = unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) };
        assert_eq!(rc, 0);
        let out = child.wait_with_output().unwrap();
        if out.status.success() {
            continue; // it had finished before the signal: try again
        }
        stopped = Some(out);
        break;
    }
    let out = stopped.expect("a run stopped by SIGINT");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("stopped on SIGINT"), "{stderr}");
    assert!(stderr.contains("quick-stopped"), "{stderr}");
    assert!(stderr.contains("--resume"), "{stderr}");
    assert!(!journal(&b).finished);
    let resumed = cmd(&b, true).output().unwrap();
    assert!(
        resumed.status.success(),
        "{}",
        String::from_utf8_lossy(&resumed.stderr)
    );
    same_recording(&a, &b);
}

/// The shipped scenario without the effects that depend on time or on the motion history and
/// without scatter drawn per move: a contact repeated measures exactly what the first did, so
/// a session with a fault must record the fault-free rows.
fn exact_scenario() -> Scenario {
    let mut sc = scenario();
    sc.effects.clear();
    sc.measurement.arm_repeatability_mm = 0.0;
    sc.measurement.table_accuracy_mm = 0.0;
    sc.measurement.noise_mm = 0.0;
    sc
}

/// The `ok` point rows of a recording: joints (as text) and the table's position at the
/// contact (mm).
type Contacts = Vec<(String, [f64; 3])>;

/// The [`Contacts`] of the recording in `dir`.
fn contacts(dir: &Path, rig: &Rig) -> Contacts {
    read(dir, rig)
        .rows
        .iter()
        .filter(|m| m.region.as_deref() != Some("reg") && m.status == Status::Ok)
        .filter_map(|m| {
            let t = m.table?;
            let q: Vec<String> =
                m.q.iter()
                    .map(|v| format!("{:.4}", v.to_degrees()))
                    .collect();
            Some((q.join(","), [t.x, t.y, t.z]))
        })
        .collect()
}

/// Every contact of `b` equals `a`'s at the same joints within `tol_mm`; both hold them all.
fn same_contacts(a: &[(String, [f64; 3])], b: &[(String, [f64; 3])], tol_mm: f64) {
    assert_eq!(a.len(), b.len(), "{a:?}\n{b:?}");
    for (q, p) in b {
        let (_, want) = a.iter().find(|(qa, _)| qa == q).expect("the same points");
        let d = (0..3).map(|k| (p[k] - want[k]).powi(2)).sum::<f64>().sqrt();
        assert!(
            d <= tol_mm,
            "joints {q}: {p:?} against {want:?} (Δ {d:.4} mm)"
        );
    }
}

/// Wraps the rig's table: `fault` runs (with `true`) as final approach number `at` (counted
/// from the registration's first; the table set below 1 mm/s) starts its move, and (with
/// `false`) once that start returned.
struct FinalApproachFault {
    inner: Box<dyn Table>,
    at: usize,
    finals: usize,
    creeping: bool,
    fault: Box<dyn FnMut(bool) + Send>,
}

impl FinalApproachFault {
    fn wrap(opened: &mut OpenedRig, at: usize, fault: Box<dyn FnMut(bool) + Send>) {
        let InstrumentDevices::TablePanel { table, .. } = &mut opened.devices.instrument else {
            panic!("a table rig")
        };
        let inner = std::mem::replace(table, Box::new(rigcal_devices::devices::MockTable::new()));
        *table = Box::new(FinalApproachFault {
            inner,
            at,
            finals: 0,
            creeping: false,
            fault,
        });
    }
}

impl Table for FinalApproachFault {
    fn enable(&mut self, t: Duration) -> Result<(), DeviceError> {
        self.inner.enable(t)
    }
    fn set_speed(&mut self, v: f64, t: Duration) -> Result<(), DeviceError> {
        self.creeping = v < 1.0;
        if self.creeping {
            self.finals += 1;
        }
        self.inner.set_speed(v, t)
    }
    fn start_move(&mut self, target: [f64; 3], t: Duration) -> Result<(), DeviceError> {
        let due = self.creeping && self.finals == self.at;
        if due {
            (self.fault)(true);
        }
        let r = self.inner.start_move(target, t);
        if due {
            (self.fault)(false);
        }
        r
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
    fn quick_stop(&mut self, t: Duration) -> Result<[f64; 3], DeviceError> {
        self.inner.quick_stop(t)
    }
    fn fault_reset(&mut self, t: Duration) -> Result<(), DeviceError> {
        self.inner.fault_reset(t)
    }
    fn latency(&self) -> Duration {
        self.inner.latency()
    }
    fn begin_pass(&mut self) {
        self.inner.begin_pass()
    }
}

/// A final approach and its contact under `fault` (see [`FinalApproachFault`]), against the
/// same session without it: the session's report and both sessions' contacts.
fn with_final_approach_fault(
    fault: impl FnOnce(&OpenedRig) -> Box<dyn FnMut(bool) + Send>,
) -> (SessionReport, SessionReport, Contacts, Contacts) {
    let sc = exact_scenario();
    let pts = points(&sc.rig, 4);
    let base = tempfile::tempdir().unwrap();
    let (a, b) = (base.path().join("a"), base.path().join("b"));
    let normal = uninterrupted(&sc, &pts, &a);
    let mut opened = sim_devices(&sc);
    let f = fault(&opened);
    // Final approach 6: the second point's (after the registration's four).
    FinalApproachFault::wrap(&mut opened, 6, f);
    let faulty = run_session(&sc.rig, opened, &pts, options(&b), &Progress::Quiet).unwrap();
    (normal, faulty, contacts(&a, &sc.rig), contacts(&b, &sc.rig))
}

#[test]
fn a_touch_that_comes_while_the_final_approach_is_still_being_started_is_not_read_late() {
    // Drives answering 100 ms late while the final approach's move is started (a dozen
    // exchanges; lost frames and their SDO timeouts do the same): the table reaches the pin
    // (0.06 mm above the standoff, 0.14 s at 0.42 mm/s) before the session begins to wait for
    // the touch. The touch is already there when the wait begins; read then, the position
    // would be tens of ms late (0.01 mm and more), with the read itself quick.
    let (normal, faulty, a, b) = with_final_approach_fault(|opened| {
        let tf = table_faults(opened);
        Box::new(move |starting| {
            tf.lock().unwrap().extra_delay = if starting {
                Duration::from_millis(100)
            } else {
                Duration::ZERO
            }
        })
    });
    same_contacts(&a, &b, 0.001);
    assert!(
        faulty.retries > normal.retries,
        "{faulty:?} against {normal:?}"
    );
}

#[test]
fn a_corrupt_first_touch_packet_is_not_passed_over_for_a_later_one() {
    // The final approach's first touch packet arrives with a bad checksum: the next packet
    // (the panel's report period, 10 ms, later) would put the contact 0.004 mm higher at
    // 0.42 mm/s — the overshoot twice the budget, unseen. A bad packet during the wait must
    // cost the contact, not bias it.
    let (normal, faulty, a, b) = with_final_approach_fault(|opened| {
        let pf = opened.devices.sim.as_ref().unwrap().panel.clone().unwrap();
        Box::new(move |starting| {
            if starting {
                pf.lock().unwrap().corrupt_next_packet = true;
            }
        })
    });
    same_contacts(&a, &b, 0.001);
    assert!(
        faulty.retries > normal.retries,
        "{faulty:?} against {normal:?}"
    );
}
