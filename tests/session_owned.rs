//! The session directory is owned (issue 34, item 1): one writer at a time (a lock held for
//! the run), and a resume checks everything it continues from — rig file, scenario, seeds,
//! procedure, plan, the recording against its journal — before any device moves, refusing with
//! what differs. A directory left before the first journal commit starts again cleanly.
//!
//! "Before any device moves" is seen in the binary's debug log: the arm driver logs every
//! command it sends (`arm: send`), and a refused resume has sent none.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use rigcal_devices::session::{Journal, SessionLock, LOCK_FILE};

const RIG: &str = "rigs/rv-m2.toml";
const SCENARIO: &str = "sim/rig-realistic.toml";

/// The arguments of a small dry run (8 points, 4 registration poses) in `dir`.
fn session_args(dir: &Path) -> Vec<OsString> {
    let mut a: Vec<OsString> = [
        "session",
        "--rig",
        RIG,
        "--sim",
        SCENARIO,
        "--points",
        "8",
        "--regions",
        "2",
        "--reference-every",
        "0",
        "--registration-points",
        "4",
        "--out",
    ]
    .iter()
    .map(OsString::from)
    .collect();
    a.push(dir.into());
    a
}

/// The binary with `args`, debug-logged.
fn command(args: Vec<OsString>) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_rigcal"));
    c.args(args).env("RUST_LOG", "debug").env("NO_COLOR", "1");
    c
}

/// A small dry run in `dir` with `extra` arguments.
fn session(dir: &Path, resume: bool, extra: &[&str]) -> Command {
    let mut a = session_args(dir);
    a.extend(extra.iter().map(OsString::from));
    if resume {
        a.push("--resume".into());
    }
    command(a)
}

/// A resume of the small dry run in `dir` with the value after `flag` replaced by `value`.
fn resume_with(dir: &Path, flag: &str, value: impl Into<OsString>) -> Command {
    let mut a = session_args(dir);
    let at = a
        .iter()
        .position(|x| x == flag)
        .expect("a flag of the dry run")
        + 1;
    a[at] = value.into();
    a.push("--resume".into());
    command(a)
}

fn run(mut c: Command) -> Output {
    c.output().expect("the binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn run_ok(c: Command) -> Output {
    let o = run(c);
    assert!(o.status.success(), "{}", stderr(&o));
    o
}

/// Whether a run sent any command to the arm.
fn moved(o: &Output) -> bool {
    stderr(o).contains("arm: send")
}

/// A finished session in `base/name`.
fn finished_session(base: &Path, name: &str) -> PathBuf {
    let dir = base.join(name);
    run_ok(session(&dir, false, &[]));
    dir
}

/// The bytes of the files a resume must leave alone when it is refused.
fn files(dir: &Path) -> Vec<Vec<u8>> {
    [
        "measurements.csv",
        "journal.json",
        "plan.csv",
        "session.toml",
    ]
    .iter()
    .map(|f| std::fs::read(dir.join(f)).unwrap_or_default())
    .collect()
}

/// A copy of the session directory `from` as `to` (its files only).
fn copy_dir(from: &Path, to: &Path) -> PathBuf {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_file() {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
    to.to_path_buf()
}

/// Asserts that resuming `dir` with `extra` is refused with `want` in the message, before any
/// device moved and with every file as it was.
fn refused(dir: &Path, extra: &[&str], want: &str) {
    refused_by(dir, session(dir, true, extra), want);
}

/// Asserts that `c` (a resume of `dir`) is refused with `want` in the message, before any
/// device moved and with every file as it was.
fn refused_by(dir: &Path, c: Command, want: &str) {
    let before = files(dir);
    let shown = format!("{:?}", c.get_args().collect::<Vec<_>>());
    let o = run(c);
    let err = stderr(&o);
    assert!(!o.status.success(), "{shown}: accepted\n{err}");
    assert!(err.contains(want), "{shown}: wanted `{want}` in\n{err}");
    assert!(
        !moved(&o),
        "{shown}: the arm was commanded before the refusal\n{err}"
    );
    assert!(
        before == files(dir),
        "{shown}: the refused resume changed the session's files"
    );
}

#[test]
fn a_second_writer_is_refused_while_the_first_holds_the_directory() {
    let base = tempfile::tempdir().unwrap();
    let dir = finished_session(base.path(), "a");
    let pid = format!("pid {}", std::process::id());

    // This test plays the first run: it holds the lock.
    let held = SessionLock::acquire(&dir).unwrap();
    refused(&dir, &[], "in use by another run");
    refused(&dir, &[], &pid);

    // A fresh run into a directory another run holds writes nothing, not even its plan.
    let fresh = base.path().join("fresh");
    std::fs::create_dir_all(&fresh).unwrap();
    let held_fresh = SessionLock::acquire(&fresh).unwrap();
    let o = run(session(&fresh, false, &[]));
    assert!(
        !o.status.success() && stderr(&o).contains(&pid),
        "{}",
        stderr(&o)
    );
    assert!(!moved(&o));
    assert!(!fresh.join("plan.csv").exists() && !fresh.join("measurements.csv").exists());

    // Released: the resume runs (and does command the arm: the log shows motion).
    drop(held);
    drop(held_fresh);
    let o = run_ok(session(&dir, true, &[]));
    assert!(moved(&o));
    run_ok(session(&fresh, false, &[]));

    // A lock file left by a run that was killed (its lock ended with it) does not block.
    std::fs::write(
        dir.join(LOCK_FILE),
        "pid = 4000000\nstarted = \"2020-01-01T00:00:00Z\"\ncommand = \"rigcal session\"\n",
    )
    .unwrap();
    let o = run_ok(session(&dir, true, &[]));
    assert!(
        stderr(&o).contains("did not end normally"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn a_resume_with_other_inputs_is_refused_before_any_device_moves() {
    let base = tempfile::tempdir().unwrap();
    let dir = finished_session(base.path(), "a");

    // The same rig file, edited.
    let rig = base.path().join("edited-rig.toml");
    let mut text = std::fs::read_to_string(RIG).unwrap();
    text.push_str("\n# edited after the session began\n");
    std::fs::write(&rig, text).unwrap();
    refused_by(
        &dir,
        resume_with(&dir, "--rig", &rig),
        "--rig: the rig file's content",
    );
    // Another scenario of the same rig: another world.
    refused_by(
        &dir,
        resume_with(&dir, "--sim", "sim/rig-sec7.toml"),
        "--sim: the scenario file's content",
    );
    refused(&dir, &["--seed", "5"], "--seed: was 31, now 5");
    refused(
        &dir,
        &["--sim-seed", "32"],
        "--sim-seed: the simulated world's seed was 31, now 32",
    );
    refused(
        &dir,
        &["--procedure", "baseline"],
        "--procedure: was rigcal, now baseline",
    );
    refused_by(
        &dir,
        resume_with(&dir, "--registration-points", "5"),
        "--registration-points: was 4, now 5",
    );

    // An edited plan: one point fewer.
    let plan = std::fs::read_to_string(dir.join("plan.csv")).unwrap();
    let mut lines: Vec<&str> = plan.lines().collect();
    lines.remove(3);
    std::fs::write(dir.join("plan.csv"), lines.join("\n") + "\n").unwrap();
    refused(&dir, &[], "plan.csv: edited since the session began");
    std::fs::write(dir.join("plan.csv"), plan).unwrap();

    // Unchanged: accepted.
    run_ok(session(&dir, true, &[]));

    // A session begun before the check was noted resumes, saying what it cannot check.
    let toml_path = dir.join("session.toml");
    let info = std::fs::read_to_string(&toml_path).unwrap();
    let mut doc: toml::Table = toml::from_str(&info).unwrap();
    assert!(doc.remove("resume_check").is_some(), "{info}");
    std::fs::write(&toml_path, toml::to_string(&doc).unwrap()).unwrap();
    let o = run_ok(session(&dir, true, &[]));
    assert!(stderr(&o).contains("no [resume_check]"), "{}", stderr(&o));
    // …and still refuses what its session.toml and journal do say.
    refused(&dir, &["--sim-seed", "32"], "--sim-seed");
}

/// Rewrites the journal of `dir` through `edit`.
fn edit_journal(dir: &Path, edit: impl FnOnce(&mut Journal)) {
    let mut j = Journal::load(dir).unwrap();
    edit(&mut j);
    j.save(dir).unwrap();
}

#[test]
fn a_recording_cut_or_torn_inside_its_committed_rows_is_refused() {
    let base = tempfile::tempdir().unwrap();
    let done = finished_session(base.path(), "done");
    let committed = Journal::load(&done).unwrap().csv_bytes;
    assert_eq!(
        committed,
        std::fs::metadata(done.join("measurements.csv"))
            .unwrap()
            .len()
    );

    // Cut inside the last committed row.
    let cut = copy_dir(&done, &base.path().join("cut"));
    let f = std::fs::OpenOptions::new()
        .write(true)
        .open(cut.join("measurements.csv"))
        .unwrap();
    f.set_len(committed - 30).unwrap();
    drop(f);
    refused(&cut, &[], "30 bytes of measured rows are missing");

    // A journal claiming more bytes than the recording holds.
    let claims = copy_dir(&done, &base.path().join("claims"));
    edit_journal(&claims, |j| j.csv_bytes += 200);
    refused(&claims, &[], "200 bytes of measured rows are missing");

    // A committed row torn in the middle of the file, the length unchanged.
    let torn = copy_dir(&done, &base.path().join("torn"));
    let csv = std::fs::read_to_string(torn.join("measurements.csv")).unwrap();
    let row_start = csv.match_indices('\n').nth(4).unwrap().0 + 1;
    let comma = row_start + csv[row_start..].find(',').unwrap();
    let mut bytes = csv.into_bytes();
    bytes[comma] = b'\n';
    std::fs::write(torn.join("measurements.csv"), bytes).unwrap();
    refused(&torn, &[], "a committed row does not read");

    // A journal counting rows the file does not hold (the same bytes).
    let counts = copy_dir(&done, &base.path().join("counts"));
    edit_journal(&counts, |j| j.rows += 1);
    refused(&counts, &[], "committed rows");
}

#[test]
fn a_corrupt_journal_is_reported_before_any_device_moves() {
    let base = tempfile::tempdir().unwrap();
    let dir = finished_session(base.path(), "a");
    std::fs::write(
        dir.join("journal.json"),
        "{\"version\": 1, \"next_point\": ",
    )
    .unwrap();
    refused(&dir, &[], "cannot resume safely");
}

/// Takes a finished session back to the state a kill between creating `measurements.csv` and
/// the first journal commit leaves: the plan and the start's session.toml, the header alone,
/// no journal.
fn before_first_commit(dir: &Path) {
    std::fs::remove_file(dir.join("journal.json")).unwrap();
    let csv = std::fs::read_to_string(dir.join("measurements.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    std::fs::write(dir.join("measurements.csv"), format!("{header}\n")).unwrap();
    let mut doc: toml::Table =
        toml::from_str(&std::fs::read_to_string(dir.join("session.toml")).unwrap()).unwrap();
    doc.remove("registration");
    doc.remove("notes");
    std::fs::write(dir.join("session.toml"), toml::to_string(&doc).unwrap()).unwrap();
}

#[test]
fn a_directory_left_before_the_first_commit_resumes_and_restarts_cleanly() {
    let base = tempfile::tempdir().unwrap();
    let whole = finished_session(base.path(), "whole");
    let want = std::fs::read(whole.join("measurements.csv")).unwrap();
    let left = finished_session(base.path(), "left");
    before_first_commit(&left);
    let again = copy_dir(&left, &base.path().join("again"));

    let o = run_ok(session(&left, true, &[]));
    assert!(
        stderr(&o).contains("before its first journal commit"),
        "{}",
        stderr(&o)
    );
    assert!(
        want == std::fs::read(left.join("measurements.csv")).unwrap(),
        "resumed"
    );

    run_ok(session(&again, false, &[]));
    assert!(
        want == std::fs::read(again.join("measurements.csv")).unwrap(),
        "restarted"
    );

    // Rows without a journal are not a session that never began: refused both ways.
    let rows = copy_dir(&whole, &base.path().join("rows"));
    std::fs::remove_file(rows.join("journal.json")).unwrap();
    refused(&rows, &[], "holds rows but there is no journal.json");
    let o = run(session(&rows, false, &[]));
    assert!(!o.status.success() && stderr(&o).contains("already holds a recording"));
}

/// `rigcal calibrate --session` (planning mode through the rig) owns its directory as `rigcal
/// session` does: while another run holds it, nothing is measured or written.
#[test]
fn a_planning_mode_session_is_refused_while_another_run_holds_its_directory() {
    let base = tempfile::tempdir().unwrap();
    let dir = base.path().join("planning");
    std::fs::create_dir_all(&dir).unwrap();
    let held = SessionLock::acquire(&dir).unwrap();
    let mut args: Vec<OsString> = [
        "calibrate",
        "--rig",
        RIG,
        "--sim",
        SCENARIO,
        "--accuracy-mm",
        "0.5",
        "--learner",
        "none",
        "--max-regions",
        "2",
        "--session",
    ]
    .iter()
    .map(OsString::from)
    .collect();
    args.push(dir.clone().into());
    args.push("--out".into());
    args.push(base.path().join("model.json").into());
    let o = run(command(args.clone()));
    let pid = format!("pid {}", std::process::id());
    assert!(
        !o.status.success() && stderr(&o).contains("in use by another run"),
        "{}",
        stderr(&o)
    );
    assert!(stderr(&o).contains(&pid), "{}", stderr(&o));
    assert!(!moved(&o));
    assert!(!dir.join("measurements.csv").exists());
    assert!(!base.path().join("model.json").exists());
    // Released: the same command runs.
    drop(held);
    let o = run(command(args));
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(base.path().join("model.json").exists());
}
