//! The rehearsal through the real transports: `rigcal sim-device rig --pty --write-rig` serves
//! the rig's three emulators on pseudo-terminals around one simulated world, and `rigcal
//! session` runs through the written rig file — the arm and the panel over `serialport`, the
//! table over slcan — is killed (SIGKILL) mid-run and resumed, and ends with the points and
//! readings of the in-process dry run of the same rig, scenario, seed and plan.
//!
//! Real time, so the rig file is sped up (fast arm and table, 3.5 ms of panel and bus latency,
//! a 0.01 mm overshoot budget, a 30 mm/s locating approach) and the plan has 100 points: about
//! 30 s. The scenario is `sim/rig-realistic.toml` without its thermal drift, the one effect
//! that follows the clock (real time here, the virtual clock in the dry run).
//!
//! The rig latches its contact heights in the z drive (`[devices.table] touch_probe = true`,
//! the CiA 402 touch probe wired to the panel's touch output): a height is the world's contact
//! height at the touch, quantised to counts, whenever the touch packet reaches the session, so
//! real time's latencies (pseudo-terminals, threads, a busy machine) move no reading. What is
//! equal, exactly: every row's seq, region, status and joints, every touch's panel (u, v) (the
//! world's draws, motion history and pin, through the world's side channel), and every
//! height and coordinate. Only times and the recorded latencies differ. The rig's supervision
//! and SDO timeouts are generous (a 500 ms heartbeat supervised at 1.5 s, 1 s SDO timeouts),
//! so a loaded machine's scheduling delays are not taken for a lost drive; on the dry run's
//! virtual clock they change nothing.

#![cfg(unix)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

const POINTS: &str = "100";
const SEED: &str = "31";
/// Rows written before the kill (of about 230: registration, via rows and points).
const KILL_AFTER_ROWS: usize = 100;

fn rigcal() -> Command {
    Command::new(env!("CARGO_BIN_EXE_rigcal"))
}

/// A child process in a process group of its own, the whole group stopped and the child
/// reaped when dropped, so a failing test leaves no process behind (a script's server too):
/// SIGTERM first (a server removes its socket file), SIGKILL after a second.
struct Killed(Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let pid = i32::try_from(self.0.id()).ok();
        let group = |signal| {
            if let Some(pid) = pid {
                // SAFETY: kill(2) on the process group this test created; no memory involved.
                unsafe {
                    libc::kill(-pid, signal);
                }
            }
        };
        // Signalled only while the child lives (its group id cannot be another's then); the
        // whole group gets the SIGTERM, so a script's server ends with the script.
        if matches!(self.0.try_wait(), Ok(None)) {
            group(libc::SIGTERM);
            let until = Instant::now() + Duration::from_secs(1);
            while matches!(self.0.try_wait(), Ok(None)) && Instant::now() < until {
                std::thread::sleep(Duration::from_millis(10));
            }
            if matches!(self.0.try_wait(), Ok(None)) {
                group(libc::SIGKILL);
            }
        }
        let _ = self.0.wait();
    }
}

impl Killed {
    fn spawn(mut c: Command) -> Killed {
        use std::os::unix::process::CommandExt;
        Killed(c.process_group(0).spawn().expect("start rigcal"))
    }

    /// Waits up to `limit` for the process to end; its exit status.
    fn wait(&mut self, limit: Duration) -> std::process::ExitStatus {
        let until = Instant::now() + limit;
        loop {
            if let Some(st) = self.0.try_wait().expect("wait for rigcal") {
                return st;
            }
            assert!(
                Instant::now() < until,
                "rigcal did not end within {limit:?}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

/// `rigs/rv-m2.toml` sped up for real time, its contact heights latched by the z drive:
/// `key = value` lines replaced (`touch_probe = true` added after the table's last key).
fn fast_rig(dir: &Path) -> PathBuf {
    let mut text = std::fs::read_to_string("rigs/rv-m2.toml").expect("rigs/rv-m2.toml");
    for (key, value) in [
        ("speed", "9"),
        ("sim_joint_speed_deg_s", "2000.0"),
        ("sim_reply_ms", "1.0"),
        ("profile_velocity_mm_s", "10000.0"),
        ("profile_acceleration_mm_s2", "1000000.0"),
        ("profile_deceleration_mm_s2", "1000000.0"),
        ("bus_latency_ms", "0.5"),
        ("latency_ms", "3.0"),
        ("sim_report_ms", "2.0"),
        ("max_overshoot_mm", "0.01"),
        ("locate_speed_mm_s", "30.0"),
        ("backoff_mm", "0.25"),
        ("heartbeat_ms", "500"),
        ("sdo_timeout_ms", "1000"),
    ] {
        let at = text
            .lines()
            .position(|l| l.split('=').next().is_some_and(|k| k.trim() == key))
            .unwrap_or_else(|| panic!("no `{key}` in rigs/rv-m2.toml"));
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        lines[at] = format!("{key} = {value}");
        text = lines.join("\n");
    }
    let mut lines: Vec<&str> = text.lines().collect();
    let panel = lines
        .iter()
        .position(|l| l.trim() == "[devices.panel]")
        .expect("a [devices.panel] section after [devices.table]");
    lines.insert(panel, "touch_probe = true\n");
    let text = lines.join("\n");
    let path = dir.join("fast.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// `sim/rig-realistic.toml` on `rig`, without its time-dependent effects (drift).
fn scenario(dir: &Path, rig: &Path) -> PathBuf {
    let text = std::fs::read_to_string("sim/rig-realistic.toml").expect("sim/rig-realistic.toml");
    let mut doc: toml::Table = text.parse().unwrap();
    doc.insert("rig".into(), rig.display().to_string().into());
    let effects = doc["effects"].as_array_mut().unwrap();
    effects.retain(|e| !e["kind"].as_str().unwrap().contains("drift"));
    let path = dir.join("scenario.toml");
    std::fs::write(&path, toml::to_string(&doc).unwrap()).unwrap();
    path
}

/// `rigcal sim-device rig --pty --write-rig` running, once its rig file is written.
fn serve(rig: &Path, scenario: &Path, written: &Path) -> Killed {
    let mut c = rigcal();
    c.args(["sim-device", "rig", "--pty", "--rig"])
        .arg(rig)
        .arg("--sim")
        .arg(scenario)
        .arg("--write-rig")
        .arg(written)
        .stdout(Stdio::piped());
    let mut server = Killed::spawn(c);
    let stdout = server.0.stdout.take().unwrap();
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                return;
            }
        }
    });
    let until = Instant::now() + Duration::from_secs(20);
    let mut seen = Vec::new();
    loop {
        let left = until.saturating_duration_since(Instant::now());
        match rx.recv_timeout(left) {
            Ok(line) if line.starts_with("rig ") => break,
            Ok(line) => seen.push(line),
            Err(e) => panic!("no `rig FILE` line from sim-device rig ({e}); it printed {seen:?}"),
        }
    }
    for (name, prefix) in [
        ("arm", "/dev/"),
        ("table", "slcan:/dev/"),
        ("panel", "/dev/"),
    ] {
        assert!(
            seen.iter().any(|l| l
                .strip_prefix(name)
                .is_some_and(|p| p.trim_start().starts_with(prefix))),
            "no {name} port in {seen:?}"
        );
    }
    server
}

fn session(rig: &Path, out: &Path) -> Command {
    let mut c = rigcal();
    c.args(["session", "--seed", SEED, "--rig"])
        .arg(rig)
        .arg("--out")
        .arg(out)
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    c
}

/// Rows of a recording by column name.
fn rows(dir: &Path) -> Vec<std::collections::HashMap<String, String>> {
    let mut r = csv::Reader::from_path(dir.join("measurements.csv")).expect("measurements.csv");
    let header: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
    r.records()
        .map(|rec| {
            let rec = rec.unwrap();
            header
                .iter()
                .cloned()
                .zip(rec.iter().map(String::from))
                .collect()
        })
        .collect()
}

fn rows_written(dir: &Path) -> usize {
    std::fs::read_to_string(dir.join("measurements.csv"))
        .map(|t| t.lines().count().saturating_sub(1))
        .unwrap_or(0)
}

/// Points and readings of the rehearsal against the dry run: every row's seq, region, status,
/// joints, panel (u, v), heights and coordinates equal, as text.
fn compare(dry: &Path, rehearsal: &Path) {
    let (a, b) = (rows(dry), rows(rehearsal));
    let outline = |r: &[std::collections::HashMap<String, String>]| -> Vec<String> {
        r.iter()
            .map(|m| format!("{} {} {}", m["seq"], m["region"], m["status"]))
            .collect()
    };
    if a.len() != b.len() {
        let (oa, ob) = (outline(&a), outline(&b));
        let first = oa
            .iter()
            .zip(&ob)
            .position(|(x, y)| x != y)
            .unwrap_or(oa.len().min(ob.len()));
        let from = first.saturating_sub(3);
        panic!(
            "row count: dry run {}, rehearsal {}; from row {from}:\n dry run   {:?}\n rehearsal {:?}",
            a.len(),
            b.len(),
            &oa[from..(first + 4).min(oa.len())],
            &ob[from..(first + 4).min(ob.len())]
        );
    }
    let joints: Vec<&String> = a[0]
        .keys()
        .filter(|k| k.starts_with('q') && k.ends_with("_deg"))
        .collect();
    assert_eq!(joints.len(), 5);
    let readings = [
        "status",
        "panel_u_mm",
        "panel_v_mm",
        "x_mm",
        "y_mm",
        "z_mm",
        "table_x_mm",
        "table_y_mm",
        "table_z_mm",
    ];
    let mut touches = 0;
    for (ra, rb) in a.iter().zip(&b) {
        let columns = ["seq", "region"]
            .into_iter()
            .chain(joints.iter().map(|q| q.as_str()))
            .chain(readings);
        for col in columns {
            assert_eq!(
                ra[col], rb[col],
                "{col} at seq {} (dry run, rehearsal)",
                ra["seq"]
            );
        }
        touches += usize::from(ra["status"] == "ok");
    }
    assert!(touches >= 90, "only {touches} touches");
}

/// One real-time session at a time: two at once on a small machine would add latency.
static REAL_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    REAL_TIME
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

#[test]
fn a_session_through_pseudo_terminals_killed_and_resumed_measures_what_the_dry_run_measures() {
    let _g = one_at_a_time();
    let started = Instant::now();
    let dir = tempfile::tempdir().unwrap();
    let rig = fast_rig(dir.path());
    let scenario = scenario(dir.path(), &rig);

    let dry = dir.path().join("dry");
    let mut c = session(&rig, &dry);
    c.arg("--sim").arg(&scenario).args(["--points", POINTS]);
    assert!(
        Killed::spawn(c).wait(Duration::from_secs(60)).success(),
        "dry run"
    );

    let written = dir.path().join("pty-rig.toml");
    let _server = serve(&rig, &scenario, &written);
    let text = std::fs::read_to_string(&written).unwrap();
    assert!(
        text.contains("slcan:/dev/") && text.contains("world = "),
        "{text}"
    );

    let out = dir.path().join("rehearsal");
    let mut c = session(&written, &out);
    c.args(["--points", POINTS]);
    let mut first = Killed::spawn(c);
    let until = Instant::now() + Duration::from_secs(60);
    while rows_written(&out) < KILL_AFTER_ROWS {
        assert!(
            first.0.try_wait().unwrap().is_none(),
            "the session ended before the kill, after {} rows",
            rows_written(&out)
        );
        assert!(
            Instant::now() < until,
            "only {} rows after 60 s",
            rows_written(&out)
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    first.0.kill().unwrap();
    first.0.wait().unwrap();
    let at_kill = rows_written(&out);

    let mut c = session(&written, &out);
    c.arg("--resume");
    let st = Killed::spawn(c).wait(Duration::from_secs(90));
    assert!(st.success(), "resume: {st}");
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("journal.json")).unwrap()).unwrap();
    assert_eq!(j["finished"], true);
    assert!(
        at_kill < rows_written(&out),
        "killed after {at_kill} rows: nothing left to resume"
    );

    compare(&dry, &out);
    eprintln!(
        "rehearsal with a kill after {at_kill} rows: {:.1} s",
        started.elapsed().as_secs_f64()
    );
}

/// `scripts/hil-session.sh --rehearsal` runs its session through `sim-device rig --pty`: the
/// script's own path is checked, its recording against the dry run's.
#[test]
fn the_hil_script_rehearses_its_session_through_pseudo_terminals() {
    let _g = one_at_a_time();
    let dir = tempfile::tempdir().unwrap();
    let rig = fast_rig(dir.path());
    let scenario = scenario(dir.path(), &rig);
    let out = dir.path().join("hil");
    let mut c = Command::new("bash");
    c.arg("scripts/hil-session.sh")
        .arg("--rehearsal")
        .env("RIGCAL_BIN", env!("CARGO_BIN_EXE_rigcal"))
        .env("RIGCAL_RIG", &rig)
        .env("RIGCAL_SIM", &scenario)
        .env("RIGCAL_POINTS", "12")
        .env("RIGCAL_SEED", SEED)
        .env("RIGCAL_OUT", &out)
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    let st = Killed::spawn(c).wait(Duration::from_secs(60));
    assert!(st.success(), "hil-session.sh --rehearsal: {st}");

    let dry = dir.path().join("dry");
    let mut c = session(&rig, &dry);
    c.arg("--sim")
        .arg(&scenario)
        .args(["--points", "12", "--registration-points", "8"]);
    assert!(
        Killed::spawn(c).wait(Duration::from_secs(60)).success(),
        "dry run"
    );
    let (a, b) = (rows(&dry), rows(&out));
    assert_eq!(a.len(), b.len());
    for (ra, rb) in a.iter().zip(&b) {
        for col in [
            "seq",
            "status",
            "q1_deg",
            "q2_deg",
            "q3_deg",
            "panel_u_mm",
            "panel_v_mm",
        ] {
            assert_eq!(ra[col], rb[col], "{col} at seq {}", ra["seq"]);
        }
    }
}
