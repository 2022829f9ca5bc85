//! The fuzz and fault suite (issue 34, item 8): generated malformed recordings, rig files, model
//! files, plans, targets and device fault schedules, each run through what a user runs (the
//! binary) or the library call behind it, asserting for every case:
//!
//! - no panic (a panicking binary exits with 101; a library panic fails the case),
//! - no hang (every case runs under a wall-clock bound, [`CASE_BOUND`]),
//! - a clear error or a correct result, never a silently wrong one: an identification that
//!   succeeds predicts the clean recording as well as the clean fit does; a model that loads
//!   compensates to finite joints; a plan that reads holds only finite points within the joint
//!   limits; a session under faults ends with one row per point, every skip explained, every
//!   measured row equal to the fault-free session's within the instrument's resolution.
//!
//! A harness of its own (`harness = false`), so it always prints its case counts. The cases are
//! drawn from a fixed seed, so CI is reproducible; `RIGCAL_FUZZ_SEED=N` draws another set and
//! `RIGCAL_FUZZ_CASES=K` multiplies the counts by K (for a longer run by hand).

use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestCaseError, TestRng, TestRunner};
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::Recording;
use rigcal_core::rig::Rig;
use rigcal_devices::session::{plan, read_plan, write_plan, PlanOptions};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{mpsc, Arc};
use std::time::{Duration, Instant};

/// The longest any one case may take before it counts as a hang (generous: CI has 2 cores).
const CASE_BOUND: Duration = Duration::from_secs(30);
const RIG: &str = "rigs/rv-m2-ideal.toml";
const TABLE_RIG: &str = "rigs/rv-m2.toml";
const SCENARIO: &str = "sim/paper-sim.toml";

/// Cases of the running family that ended in a result (checked) and in an error (said).
static ACCEPTED: AtomicUsize = AtomicUsize::new(0);
static REFUSED: AtomicUsize = AtomicUsize::new(0);

fn accepted() {
    ACCEPTED.fetch_add(1, Ordering::Relaxed);
}

fn refused() {
    REFUSED.fetch_add(1, Ordering::Relaxed);
}

fn main() {
    // `cargo test NAME` passes NAME to every test binary: run only when it names this suite.
    let filters: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    if !filters.is_empty() && !filters.iter().any(|f| "fuzz".contains(f.as_str())) {
        return;
    }
    if std::env::args().any(|a| a == "--list") {
        println!("fuzz: test");
        return;
    }
    let start = Instant::now();
    let base = Arc::new(Base::make());
    let families: Vec<(&str, u32, Family)> = vec![
        (
            "recordings through identify (library)",
            400,
            recordings_library,
        ),
        (
            "recordings through `rigcal identify`",
            100,
            recordings_binary,
        ),
        (
            "rig files through parse, FK and `rigcal observability`",
            150,
            rig_files,
        ),
        ("model files through `rigcal compensate`", 150, model_files),
        ("plans through read_plan", 300, plans),
        ("targets through `rigcal compensate`", 100, targets),
        (
            "device fault schedules through a dry-run session",
            16,
            fault_schedules,
        ),
    ];
    let scale: u32 = env_u64("RIGCAL_FUZZ_CASES").map_or(1, |k| k.max(1) as u32);
    let seed = env_u64("RIGCAL_FUZZ_SEED").unwrap_or(34);
    let mut total = 0;
    let mut failed = Vec::new();
    for (name, cases, run) in families {
        let cases = cases * scale;
        let mut runner = runner(cases, seed);
        let t = Instant::now();
        ACCEPTED.store(0, Ordering::Relaxed);
        REFUSED.store(0, Ordering::Relaxed);
        match run(&base, &mut runner) {
            Ok(()) => println!(
                "fuzz: {name}: {cases} cases passed ({} gave a checked result, {} a stated \
                 error; {:.1} s)",
                ACCEPTED.load(Ordering::Relaxed),
                REFUSED.load(Ordering::Relaxed),
                t.elapsed().as_secs_f64()
            ),
            Err(e) => {
                println!("fuzz: {name}: FAILED: {e}");
                failed.push(name);
            }
        }
        total += cases;
    }
    println!(
        "fuzz suite: {total} cases in {:.1} s, seed {seed}; {} famil{} failed",
        start.elapsed().as_secs_f64(),
        failed.len(),
        if failed.len() == 1 { "y" } else { "ies" }
    );
    if !failed.is_empty() {
        std::process::exit(1);
    }
}

/// A family of cases: runs them all with the runner, or says which failed and why.
type Family = fn(&Arc<Base>, &mut TestRunner) -> Result<(), String>;

fn env_u64(name: &str) -> Option<u64> {
    std::env::var(name).ok()?.parse().ok()
}

fn runner(cases: u32, seed: u64) -> TestRunner {
    let mut bytes = [0u8; 32];
    bytes[..8].copy_from_slice(&seed.to_le_bytes());
    TestRunner::new_with_rng(
        Config {
            cases,
            failure_persistence: None,
            // Shrinking re-runs whole processes: keep it short, the first failure is printed.
            max_shrink_iters: 32,
            ..Config::default()
        },
        TestRng::from_seed(RngAlgorithm::ChaCha, &bytes),
    )
}

/// Runs a whole property family and turns its failure into text.
fn run_family<S: Strategy>(
    runner: &mut TestRunner,
    strategy: S,
    check: impl Fn(S::Value) -> Result<(), TestCaseError>,
) -> Result<(), String>
where
    S::Value: std::fmt::Debug,
{
    runner.run(&strategy, check).map_err(|e| match e {
        proptest::test_runner::TestError::Fail(why, input) => {
            format!("{why}\nminimal failing input: {input:#?}")
        }
        other => other.to_string(),
    })
}

/// Runs `f` on a thread and fails the case if it panics or does not end within [`CASE_BOUND`].
fn bounded<T: Send + 'static>(
    what: &str,
    f: impl FnOnce() -> T + Send + 'static,
) -> Result<T, TestCaseError> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
        let _ = tx.send(r);
    });
    match rx.recv_timeout(CASE_BOUND) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(p)) => Err(TestCaseError::fail(format!(
            "{what} panicked: {}",
            panic_text(&p)
        ))),
        Err(_) => Err(TestCaseError::fail(format!(
            "{what} did not end within {} s (a hang)",
            CASE_BOUND.as_secs()
        ))),
    }
}

fn panic_text(p: &Box<dyn std::any::Any + Send>) -> String {
    p.downcast_ref::<String>()
        .cloned()
        .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_else(|| "(no message)".into())
}

/// What a run of the binary gave.
struct Ran {
    code: Option<i32>,
    stderr: String,
}

/// Runs the binary with a wall-clock bound; a hang or a panic fails the case.
fn rigcal(args: &[&str]) -> Result<Ran, TestCaseError> {
    let mut child: Child = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| TestCaseError::fail(format!("starting rigcal: {e}")))?;
    let start = Instant::now();
    loop {
        match child.try_wait() {
            Ok(Some(status)) => {
                let mut stderr = String::new();
                if let Some(mut e) = child.stderr.take() {
                    use std::io::Read;
                    let _ = e.read_to_string(&mut stderr);
                }
                let ran = Ran {
                    code: status.code(),
                    stderr,
                };
                if ran.code == Some(101) || ran.stderr.contains("panicked") {
                    return Err(TestCaseError::fail(format!(
                        "rigcal {} panicked:\n{}",
                        args.join(" "),
                        ran.stderr
                    )));
                }
                return Ok(ran);
            }
            Ok(None) if start.elapsed() > CASE_BOUND => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(TestCaseError::fail(format!(
                    "rigcal {} did not end within {} s (a hang)",
                    args.join(" "),
                    CASE_BOUND.as_secs()
                )));
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(5)),
            Err(e) => return Err(TestCaseError::fail(format!("waiting for rigcal: {e}"))),
        }
    }
}

/// An error a person can act on: said on stderr, not a bare code.
fn said_why(ran: &Ran, args: &str) -> Result<(), TestCaseError> {
    prop_assert!(
        ran.stderr.trim().len() > 10,
        "rigcal {args} failed (exit {:?}) without saying why",
        ran.code
    );
    Ok(())
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

// ---- the valid files every mutation starts from ---------------------------------------------

/// Valid inputs, made once: a simulated recording, its clean fit's error, a model, a plan.
struct Base {
    rig: Rig,
    _dir: tempfile::TempDir,
    recording_dir: PathBuf,
    recording_csv: String,
    /// RMS (mm) of the clean fit on the clean recording.
    clean_rms: f64,
    model_json: String,
    targets_csv: String,
    rig_toml: String,
    plan_csv: String,
    table_rig: Rig,
}

impl Base {
    fn make() -> Base {
        let dir = tempfile::tempdir().expect("temp dir");
        let rec = dir.path().join("rec");
        let out = Command::new(env!("CARGO_BIN_EXE_rigcal"))
            .args(["simulate", "--rig", RIG, "--scenario", SCENARIO])
            .args(["--random", "120", "--seed", "7", "--out", s(&rec)])
            .output()
            .expect("run rigcal simulate");
        assert!(out.status.success(), "{out:?}");
        let model = dir.path().join("model.json");
        let out = Command::new(env!("CARGO_BIN_EXE_rigcal"))
            .args(["identify", "--rig", RIG, "--recording", s(&rec), "--out"])
            .arg(&model)
            .output()
            .expect("run rigcal identify");
        assert!(out.status.success(), "{out:?}");
        let rig = Rig::load(Path::new(RIG)).expect("rig");
        let clean = Recording::read(&rec, rig.chain.joints()).expect("clean recording");
        let clean_rms = library_fit(&rig, &clean, &clean)
            .expect("clean fit")
            .expect("clean fit succeeds");
        let table_rig = Rig::load(Path::new(TABLE_RIG)).expect("table rig");
        let points = plan(
            &table_rig,
            &PlanOptions {
                points: 24,
                regions: 4,
                seed: 3,
                ..PlanOptions::default()
            },
        )
        .expect("plan")
        .points;
        let plan_path = dir.path().join("plan.csv");
        write_plan(&plan_path, &table_rig, &points).expect("write plan");
        let targets_csv =
            "x_mm,y_mm,z_mm\n300,100,250\n320,-80,300\n280,0,200\n350,50,280\n".to_string();
        Base {
            recording_csv: read(&rec.join("measurements.csv")),
            model_json: read(&model),
            rig_toml: read(Path::new(RIG)),
            plan_csv: read(&plan_path),
            recording_dir: rec,
            clean_rms,
            rig,
            table_rig,
            targets_csv,
            _dir: dir,
        }
    }
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// Identifies `rec` and returns the fitted model's RMS error (mm) on `clean`, or `None` when
/// identification refused; the error text must be non-empty.
fn library_fit(rig: &Rig, rec: &Recording, clean: &Recording) -> Result<Option<f64>, String> {
    use rigcal_model::identification::{identify, HeldOut, Level};
    let mut opts = rigcal_model::diagnosis::outliers::identify_options();
    opts.heldout = vec![HeldOut {
        name: "clean".into(),
        recording: clean.clone(),
    }];
    match identify(rig, rec, Level::Full, &opts) {
        Ok(id) => {
            let finite = (0..id.fit.params.len()).all(|i| id.fit.params.get(i).is_finite());
            if !finite {
                return Err("identify returned a non-finite parameter".into());
            }
            let held = id
                .heldout
                .first()
                .ok_or("identify dropped the held-out recording")?;
            Ok(Some(held.fitted.rms_mm))
        }
        Err(e) if e.to_string().trim().is_empty() => Err("identify failed saying nothing".into()),
        Err(_) => Ok(None),
    }
}

// ---- mutations of a text file ---------------------------------------------------------------

/// One edit of a delimited text file.
#[derive(Debug, Clone)]
enum Edit {
    /// Replace a cell (row and column taken modulo the file's).
    Cell(usize, usize, String),
    /// Add `delta` to a numeric cell.
    Nudge(usize, usize, f64),
    /// Keep the first `per_mille` thousandths of the bytes.
    Truncate(u16),
    /// Repeat a line.
    DuplicateLine(usize),
    /// Remove a line (0: the header).
    DropLine(usize),
    /// Swap two header names.
    SwapHeader(usize, usize),
    /// A byte-order mark in front.
    Bom,
    /// CRLF line ends.
    Crlf,
    /// A line of garbage bytes.
    Garbage(usize, Vec<u8>),
}

/// Values a hostile cell takes.
fn hostile_value() -> impl Strategy<Value = String> {
    prop_oneof![
        Just(String::new()),
        Just("nan".to_string()),
        Just("NaN".to_string()),
        Just("inf".to_string()),
        Just("-inf".to_string()),
        Just("1e308".to_string()),
        Just("-1e308".to_string()),
        Just("1e300".to_string()),
        Just("1e12".to_string()),
        Just("1e5".to_string()),
        Just("-1e5".to_string()),
        Just("1e-320".to_string()),
        Just("0".to_string()),
        Just("abc".to_string()),
        Just("1,5".to_string()),
        Just("\"".to_string()),
        Just("9".repeat(400)),
        (-1.0e4..1.0e4f64).prop_map(|v| format!("{v}")),
    ]
}

fn edit() -> impl Strategy<Value = Edit> {
    let ix = 0usize..10_000;
    prop_oneof![
        6 => (ix.clone(), ix.clone(), hostile_value()).prop_map(|(r, c, v)| Edit::Cell(r, c, v)),
        3 => (ix.clone(), ix.clone(), prop_oneof![-5.0..5.0f64, -500.0..500.0f64])
            .prop_map(|(r, c, d)| Edit::Nudge(r, c, d)),
        1 => (1u16..1000).prop_map(Edit::Truncate),
        1 => ix.clone().prop_map(Edit::DuplicateLine),
        1 => ix.clone().prop_map(Edit::DropLine),
        1 => (ix.clone(), ix.clone()).prop_map(|(a, b)| Edit::SwapHeader(a, b)),
        1 => Just(Edit::Bom),
        1 => Just(Edit::Crlf),
        1 => (ix, proptest::collection::vec(any::<u8>(), 1..40)).prop_map(|(l, b)| Edit::Garbage(l, b)),
    ]
}

fn edits() -> impl Strategy<Value = Vec<Edit>> {
    proptest::collection::vec(edit(), 1..4)
}

/// Applies edits to CSV text; rows count from 1 (0 is the header) for cells.
fn apply(text: &str, edits: &[Edit]) -> Vec<u8> {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut bom = false;
    let mut crlf = false;
    let mut truncate = None;
    let mut garbage: Vec<(usize, Vec<u8>)> = Vec::new();
    for e in edits {
        let n = lines.len().max(1);
        match e {
            Edit::Cell(r, c, v) => {
                let r = 1 + r % (n - 1).max(1);
                if let Some(line) = lines.get_mut(r) {
                    *line = with_cell(line, *c, |_| v.clone());
                }
            }
            Edit::Nudge(r, c, d) => {
                let r = 1 + r % (n - 1).max(1);
                if let Some(line) = lines.get_mut(r) {
                    *line = with_cell(line, *c, |old| match old.parse::<f64>() {
                        Ok(x) => format!("{}", x + d),
                        Err(_) => old.to_string(),
                    });
                }
            }
            Edit::Truncate(pm) => truncate = Some(*pm),
            Edit::DuplicateLine(l) => {
                let l = l % n;
                if let Some(line) = lines.get(l).cloned() {
                    lines.insert(l, line);
                }
            }
            Edit::DropLine(l) => {
                if !lines.is_empty() {
                    lines.remove(l % n);
                }
            }
            Edit::SwapHeader(a, b) => {
                if let Some(h) = lines.first_mut() {
                    let mut cols: Vec<String> = h.split(',').map(str::to_string).collect();
                    let k = cols.len();
                    cols.swap(a % k, b % k);
                    *h = cols.join(",");
                }
            }
            Edit::Bom => bom = true,
            Edit::Crlf => crlf = true,
            Edit::Garbage(l, b) => garbage.push((l % (n + 1), b.clone())),
        }
    }
    let end: &[u8] = if crlf { b"\r\n" } else { b"\n" };
    let mut out = Vec::new();
    if bom {
        out.extend_from_slice("\u{feff}".as_bytes());
    }
    for (i, line) in lines.iter().enumerate() {
        for (_, g) in garbage.iter().filter(|(l, _)| *l == i) {
            out.extend_from_slice(g);
            out.extend_from_slice(end);
        }
        out.extend_from_slice(line.as_bytes());
        out.extend_from_slice(end);
    }
    if let Some(pm) = truncate {
        let keep = out.len() * pm as usize / 1000;
        out.truncate(keep);
    }
    out
}

fn with_cell(line: &str, c: usize, f: impl Fn(&str) -> String) -> String {
    let mut cells: Vec<String> = line.split(',').map(str::to_string).collect();
    let k = cells.len();
    let c = c % k;
    cells[c] = f(&cells[c]);
    cells.join(",")
}

/// Edits of a TOML or JSON text: numbers replaced, lines dropped or repeated, a cut.
#[derive(Debug, Clone)]
enum TextEdit {
    /// Replace the `k`-th number (modulo the count) by a hostile one.
    Number(usize, String),
    /// Remove a line.
    DropLine(usize),
    /// Repeat a line.
    DuplicateLine(usize),
    /// Keep the first `per_mille` thousandths.
    Truncate(u16),
}

fn hostile_number() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("1e308".to_string()),
        Just("-1e308".to_string()),
        Just("1e300".to_string()),
        Just("1e15".to_string()),
        Just("1e5".to_string()),
        Just("-1e5".to_string()),
        Just("0".to_string()),
        Just("-0.0".to_string()),
        Just("1e-300".to_string()),
        Just("1e400".to_string()),
        Just("\"x\"".to_string()),
        Just("-1".to_string()),
        Just("4294967296".to_string()),
        (-1.0e3..1.0e3f64).prop_map(|v| format!("{v:.3}")),
    ]
}

fn text_edits() -> impl Strategy<Value = Vec<TextEdit>> {
    let ix = 0usize..10_000;
    proptest::collection::vec(
        prop_oneof![
            6 => (ix.clone(), hostile_number()).prop_map(|(k, v)| TextEdit::Number(k, v)),
            1 => ix.clone().prop_map(TextEdit::DropLine),
            1 => ix.prop_map(TextEdit::DuplicateLine),
            1 => (1u16..1000).prop_map(TextEdit::Truncate),
        ],
        1..4,
    )
}

fn apply_text(text: &str, edits: &[TextEdit]) -> String {
    let mut t = text.to_string();
    for e in edits {
        match e {
            TextEdit::Number(k, v) => {
                let spans = number_spans(&t);
                if !spans.is_empty() {
                    let (a, b) = spans[k % spans.len()];
                    t.replace_range(a..b, v);
                }
            }
            TextEdit::DropLine(l) | TextEdit::DuplicateLine(l) => {
                let mut lines: Vec<&str> = t.lines().collect();
                if lines.is_empty() {
                    continue;
                }
                let l = l % lines.len();
                if matches!(e, TextEdit::DropLine(_)) {
                    lines.remove(l);
                } else {
                    lines.insert(l, lines[l]);
                }
                t = lines.join("\n") + "\n";
            }
            TextEdit::Truncate(pm) => {
                let mut keep = t.len() * *pm as usize / 1000;
                while !t.is_char_boundary(keep) {
                    keep -= 1;
                }
                t.truncate(keep);
            }
        }
    }
    t
}

/// Byte ranges of the numbers (after `=`, `:`, `[`, `,` or a space) in a TOML or JSON text.
fn number_spans(t: &str) -> Vec<(usize, usize)> {
    let b = t.as_bytes();
    let mut spans = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts = (b[i].is_ascii_digit() || b[i] == b'-')
            && i > 0
            && matches!(b[i - 1], b'=' | b':' | b'[' | b',' | b' ');
        if starts {
            let mut j = i + 1;
            while j < b.len()
                && (b[j].is_ascii_digit() || matches!(b[j], b'.' | b'e' | b'E' | b'-' | b'+'))
            {
                j += 1;
            }
            spans.push((i, j));
            i = j;
        } else {
            i += 1;
        }
    }
    spans
}

// ---- the families ---------------------------------------------------------------------------

/// The ways an identification may end on a malformed recording.
fn check_identification(base: &Base, csv: Vec<u8>) -> Result<(), TestCaseError> {
    let dir = tempfile::tempdir().map_err(|e| TestCaseError::fail(e.to_string()))?;
    std::fs::write(dir.path().join("measurements.csv"), &csv)
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    let rig = base.rig.clone();
    let clean_dir = base.recording_dir.clone();
    let path = dir.path().to_path_buf();
    let outcome = bounded("reading and identifying a malformed recording", move || {
        let joints = rig.chain.joints();
        let clean = Recording::read(&clean_dir, joints).map_err(|e| e.to_string())?;
        match Recording::read_measured(&path, joints) {
            Err(e) if e.to_string().trim().is_empty() => Err("read failed saying nothing".into()),
            Err(_) => Ok(None),
            Ok(rec) => library_fit(&rig, &rec, &clean),
        }
    })?;
    match outcome {
        Err(e) => Err(TestCaseError::fail(e)),
        Ok(None) => {
            refused();
            Ok(())
        }
        Ok(Some(rms)) => {
            accepted();
            // Accepted: the model must predict the clean recording about as well as the clean
            // fit does (an outlier kept or a wrong cell read would show here).
            prop_assert!(
                rms.is_finite() && rms <= base.clean_rms + 0.5,
                "identification accepted a malformed recording and predicts the clean one at \
                 {rms:.3} mm RMS (clean fit {:.3} mm): a silently wrong result",
                base.clean_rms
            );
            Ok(())
        }
    }
}

fn recordings_library(base: &Arc<Base>, runner: &mut TestRunner) -> Result<(), String> {
    let b = Arc::clone(base);
    run_family(runner, edits(), move |e| {
        check_identification(&b, apply(&b.recording_csv, &e))
    })
}

fn recordings_binary(base: &Arc<Base>, runner: &mut TestRunner) -> Result<(), String> {
    let b = Arc::clone(base);
    run_family(runner, edits(), move |e| {
        let dir = tempfile::tempdir().map_err(|e| TestCaseError::fail(e.to_string()))?;
        let rec = dir.path().join("rec");
        std::fs::create_dir(&rec).map_err(|e| TestCaseError::fail(e.to_string()))?;
        std::fs::write(rec.join("measurements.csv"), apply(&b.recording_csv, &e))
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        let model = dir.path().join("model.json");
        let args = [
            "identify",
            "--rig",
            RIG,
            "--recording",
            s(&rec),
            "--out",
            s(&model),
        ];
        let ran = rigcal(&args)?;
        if ran.code == Some(0) {
            accepted();
            let loaded = rigcal_model::model::ModelFile::load(&model);
            prop_assert!(
                loaded.is_ok(),
                "identify exited 0 but wrote a model that cannot be read back: {:?}",
                loaded.err()
            );
        } else {
            refused();
            said_why(&ran, &args.join(" "))?;
            prop_assert!(
                !model.exists(),
                "identify failed (exit {:?}) but left a model file",
                ran.code
            );
        }
        Ok(())
    })
}

fn rig_files(base: &Arc<Base>, runner: &mut TestRunner) -> Result<(), String> {
    let b = Arc::clone(base);
    run_family(runner, text_edits(), move |e| {
        let text = apply_text(&b.rig_toml, &e);
        let parsed = {
            let text = text.clone();
            bounded("parsing a malformed rig file", move || {
                Rig::parse(&text, None).map(|rig| {
                    // Every pose within the limits has a finite position.
                    let q: Vec<f64> = rig
                        .chain
                        .joints()
                        .iter()
                        .map(|j| 0.5 * (j.min + j.max))
                        .collect();
                    let p = rig.chain.position(
                        &q,
                        &rigcal_core::kinematics::ErrorParams::zeros(rig.chain.layout()),
                    );
                    p.iter().all(|v| v.is_finite())
                })
            })?
        };
        match parsed {
            Err(err) => {
                refused();
                prop_assert!(!err.to_string().trim().is_empty(), "rig refused silently")
            }
            Ok(finite) => {
                accepted();
                prop_assert!(finite, "a rig file was accepted whose FK is not finite");
                let dir = tempfile::tempdir().map_err(|e| TestCaseError::fail(e.to_string()))?;
                let path = dir.path().join("rig.toml");
                std::fs::write(&path, &text).map_err(|e| TestCaseError::fail(e.to_string()))?;
                let args = ["observability", "--rig", s(&path), "--poses", "40"];
                let ran = rigcal(&args)?;
                if ran.code != Some(0) {
                    said_why(&ran, &args.join(" "))?;
                }
            }
        }
        Ok(())
    })
}

fn model_files(base: &Arc<Base>, runner: &mut TestRunner) -> Result<(), String> {
    let b = Arc::clone(base);
    run_family(runner, text_edits(), move |e| {
        let dir = tempfile::tempdir().map_err(|e| TestCaseError::fail(e.to_string()))?;
        let model = dir.path().join("model.json");
        let targets = dir.path().join("targets.csv");
        let out = dir.path().join("out.csv");
        std::fs::write(&model, apply_text(&b.model_json, &e))
            .and_then(|()| std::fs::write(&targets, &b.targets_csv))
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        check_compensate(&model, &targets, &out)
    })
}

fn targets(base: &Arc<Base>, runner: &mut TestRunner) -> Result<(), String> {
    let b = Arc::clone(base);
    run_family(runner, edits(), move |e| {
        let dir = tempfile::tempdir().map_err(|e| TestCaseError::fail(e.to_string()))?;
        let model = dir.path().join("model.json");
        let targets = dir.path().join("targets.csv");
        let out = dir.path().join("out.csv");
        std::fs::write(&model, &b.model_json)
            .and_then(|()| std::fs::write(&targets, apply(&b.targets_csv, &e)))
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        check_compensate(&model, &targets, &out)
    })
}

/// `compensate` ends with finite joint commands for what it writes, or says why it wrote none.
fn check_compensate(model: &Path, targets: &Path, out: &Path) -> Result<(), TestCaseError> {
    let args = [
        "compensate",
        "--model",
        s(model),
        "--targets",
        s(targets),
        "--out",
        s(out),
    ];
    let ran = rigcal(&args)?;
    match ran.code {
        Some(0) | Some(3) => {
            accepted();
            let text = std::fs::read_to_string(out).map_err(|e| {
                TestCaseError::fail(format!("compensate exited 0/3, no output: {e}"))
            })?;
            let mut lines = text.lines();
            let header: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
            for line in lines {
                for (name, cell) in header.iter().zip(line.split(',')) {
                    if name.ends_with("_deg") || name.ends_with("_mm") {
                        // A target left out has an empty cell and a status; a written one is finite.
                        if !cell.is_empty() {
                            let v: f64 = cell.parse().map_err(|_| {
                                TestCaseError::fail(format!("{name} = {cell:?} is not a number"))
                            })?;
                            prop_assert!(v.is_finite(), "{name} = {cell} in the output");
                        }
                    }
                }
            }
            if ran.code == Some(3) {
                said_why(&ran, &args.join(" "))?;
            }
        }
        _ => {
            refused();
            said_why(&ran, &args.join(" "))?;
            prop_assert!(
                !out.exists(),
                "compensate failed but wrote {}",
                out.display()
            );
        }
    }
    Ok(())
}

fn plans(base: &Arc<Base>, runner: &mut TestRunner) -> Result<(), String> {
    let b = Arc::clone(base);
    run_family(runner, edits(), move |e| {
        let dir = tempfile::tempdir().map_err(|e| TestCaseError::fail(e.to_string()))?;
        let path = dir.path().join("plan.csv");
        let bytes = apply(&b.plan_csv, &e);
        let data_lines = bytes.split(|&c| c == b'\n').count();
        std::fs::write(&path, bytes).map_err(|e| TestCaseError::fail(e.to_string()))?;
        let rig = b.table_rig.clone();
        let read = bounded("reading a malformed plan", move || {
            read_plan(&path, &rig).map_err(|e| e.to_string())
        })?;
        match read {
            Err(e) => {
                refused();
                prop_assert!(!e.trim().is_empty(), "plan refused silently")
            }
            Ok(points) => {
                accepted();
                prop_assert!(!points.is_empty(), "an empty plan was accepted");
                prop_assert!(points.len() <= data_lines, "more points than lines");
                for p in &points {
                    prop_assert!(
                        p.q.iter().chain(&p.table_mm).all(|v| v.is_finite()),
                        "plan point {} holds a non-finite value: {p:?}",
                        p.point
                    );
                    for (j, (q, spec)) in p.q.iter().zip(b.table_rig.chain.joints()).enumerate() {
                        prop_assert!(
                            spec.within(*q),
                            "plan point {} has joint {} at {:.3}° outside its limits",
                            p.point,
                            j + 1,
                            q.to_degrees()
                        );
                    }
                }
            }
        }
        Ok(())
    })
}

// ---- device fault schedules -----------------------------------------------------------------

/// A fault to inject into the emulated rig once `after` points are measured.
#[derive(Debug, Clone)]
enum DeviceFault {
    /// The arm controller drops `n` replies (lost bytes).
    ArmDrop(u32),
    /// The arm controller garbles `n` replies.
    ArmGarble(u32),
    /// The next arm move ends in error mode 1 (hardware) or 2 (position/format).
    ArmError(u8),
    /// A table drive faults during its next move (following error, over-current).
    DriveFault(usize, u16),
    /// The table answers late (ms) from here on.
    TableLate(u64),
    /// The table loses this share of SDO frames from here on.
    SdoLoss(f64),
    /// The table stops answering SDOs for good.
    TableDead,
    /// The panel misses the next touch.
    PanelMiss,
    /// Garbage bytes before the next panel packet.
    PanelGarbage(Vec<u8>),
    /// The next panel packet has a wrong checksum.
    PanelCorrupt,
}

fn device_fault() -> impl Strategy<Value = DeviceFault> {
    prop_oneof![
        (1u32..3).prop_map(DeviceFault::ArmDrop),
        (1u32..3).prop_map(DeviceFault::ArmGarble),
        prop_oneof![Just(1u8), Just(2u8)].prop_map(DeviceFault::ArmError),
        (0usize..3, prop_oneof![Just(0x8611u16), Just(0x2310u16)])
            .prop_map(|(a, c)| DeviceFault::DriveFault(a, c)),
        (5u64..150).prop_map(DeviceFault::TableLate),
        (0.01f64..0.05).prop_map(DeviceFault::SdoLoss),
        Just(DeviceFault::TableDead),
        Just(DeviceFault::PanelMiss),
        proptest::collection::vec(any::<u8>(), 1..12).prop_map(DeviceFault::PanelGarbage),
        Just(DeviceFault::PanelCorrupt),
    ]
}

/// A schedule: each fault with the number of measured points after which it strikes.
fn fault_schedule() -> impl Strategy<Value = Vec<(usize, DeviceFault)>> {
    proptest::collection::vec((0usize..SCHEDULE_POINTS, device_fault()), 1..5)
}

const SCHEDULE_POINTS: usize = 10;
const FAULT_SCENARIO: &str = "sim/rig-realistic.toml";

/// Injects the schedule's faults as the session reports its progress.
struct Injector {
    schedule: Vec<(usize, DeviceFault)>,
    controls: rigcal_devices::devices::factory::SimControls,
    done: std::sync::Mutex<usize>,
}

impl Injector {
    fn strike(&self, f: &DeviceFault) {
        use rigcal_devices::devices::emulators::faults::{FrameLoss, InjectedFault};
        let c = &self.controls;
        match f {
            DeviceFault::ArmDrop(n) => lock(&c.arm, |a| a.drop_replies += n),
            DeviceFault::ArmGarble(n) => lock(&c.arm, |a| a.garble_replies += n),
            DeviceFault::ArmError(m) => lock(&c.arm, |a| a.error_on_next_move = Some(*m)),
            DeviceFault::DriveFault(axis, code) => lock(&c.table, |t| {
                t.fault_on_next_move = Some(InjectedFault {
                    axis: *axis,
                    after: Duration::from_millis(40),
                    emcy_code: *code,
                })
            }),
            DeviceFault::TableLate(ms) => {
                lock(&c.table, |t| t.extra_delay = Duration::from_millis(*ms))
            }
            DeviceFault::SdoLoss(rate) => lock(&c.table, |t| t.sdo_loss = FrameLoss::new(*rate, 7)),
            DeviceFault::TableDead => lock(&c.table, |t| t.ignore_sdo = true),
            DeviceFault::PanelMiss => lock(&c.panel, |p| p.miss_next_touch = true),
            DeviceFault::PanelGarbage(b) => lock(&c.panel, |p| p.garbage_before_next = b.clone()),
            DeviceFault::PanelCorrupt => lock(&c.panel, |p| p.corrupt_next_packet = true),
        }
    }
}

fn lock<T>(h: &Option<Arc<std::sync::Mutex<T>>>, f: impl FnOnce(&mut T)) {
    if let Some(h) = h {
        let mut g = h.lock().unwrap_or_else(|e| e.into_inner());
        f(&mut g);
    }
}

impl rigcal_devices::session::ProgressSink for Injector {
    fn update(&self, done: usize, _total: usize, _rig_s: f64) {
        let mut last = self.done.lock().unwrap_or_else(|e| e.into_inner());
        for (at, f) in &self.schedule {
            if *at >= *last && *at < done.max(*last + 1) {
                self.strike(f);
            }
        }
        *last = done.max(*last);
    }
}

/// Points of the fault family's sessions, and the fault-free recording's measured rows.
struct FaultBase {
    scenario: rigcal_sim::world::Scenario,
    points: Vec<rigcal_devices::session::PlannedPoint>,
    clean: Vec<(String, [f64; 3])>,
}

fn fault_base() -> &'static FaultBase {
    static BASE: std::sync::OnceLock<FaultBase> = std::sync::OnceLock::new();
    BASE.get_or_init(|| {
        let mut scenario =
            rigcal_sim::world::Scenario::load(Path::new(FAULT_SCENARIO), None).expect("scenario");
        // The arm's geometric errors and the instrument, without the effects whose truth
        // depends on time or on the motion history (drift, backlash): a fault's retry then
        // cannot change what a point truly measures, so a row under faults must equal the
        // fault-free row.
        scenario.effects.clear();
        // Nor random scatter drawn per move (a retried move draws again): the panel's
        // quantisation stays, and it is deterministic.
        scenario.measurement.arm_repeatability_mm = 0.0;
        scenario.measurement.table_accuracy_mm = 0.0;
        scenario.measurement.noise_mm = 0.0;
        let points = plan(
            &scenario.rig,
            &PlanOptions {
                points: SCHEDULE_POINTS,
                regions: 2,
                reference_every: 0,
                seed: 5,
                ..PlanOptions::default()
            },
        )
        .expect("plan")
        .points;
        let dir = tempfile::tempdir().expect("temp dir");
        run_faulty(&scenario, &points, dir.path(), Vec::new(), false).expect("clean session");
        if std::env::var("RIGCAL_FUZZ_KEEP").is_ok() {
            let _ = std::fs::copy(dir.path().join("measurements.csv"), "/tmp/fault_clean.csv");
        }
        let clean = measured_rows(&scenario.rig, dir.path()).expect("clean recording");
        FaultBase {
            scenario,
            points,
            clean,
        }
    })
}

fn session_options(dir: &Path, resume: bool) -> rigcal_devices::session::SessionOptions {
    let mut o = rigcal_devices::session::SessionOptions::new(dir);
    o.registration_points = 4;
    o.fsync = false;
    o.resume = resume;
    o
}

/// Runs (or resumes) a dry-run session in `dir` with the fault schedule.
fn run_faulty(
    sc: &rigcal_sim::world::Scenario,
    points: &[rigcal_devices::session::PlannedPoint],
    dir: &Path,
    schedule: Vec<(usize, DeviceFault)>,
    resume: bool,
) -> Result<rigcal_devices::session::SessionReport, rigcal_devices::session::SessionError> {
    use rigcal_devices::devices::SimClock;
    use rigcal_devices::session::{run_session, Progress};
    let opened = rigcal_sim::emulation::open_rig(&sc.rig, Some(sc), SimClock::Virtual)
        .expect("emulators open");
    let controls = opened.devices.sim.clone().expect("emulated devices");
    let progress = Progress::Watch(Box::new(Injector {
        schedule,
        controls,
        done: std::sync::Mutex::new(0),
    }));
    run_session(
        &sc.rig,
        opened,
        points,
        session_options(dir, resume),
        &progress,
    )
}

/// The measured point rows: (joints as text, table position at contact).
fn measured_rows(rig: &Rig, dir: &Path) -> Result<Vec<(String, [f64; 3])>, String> {
    use rigcal_core::recording::Status;
    let rec = Recording::read(&dir.join("measurements.csv"), rig.chain.joints())
        .map_err(|e| e.to_string())?;
    Ok(rec
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
        .collect())
}

fn fault_schedules(_base: &Arc<Base>, runner: &mut TestRunner) -> Result<(), String> {
    run_family(runner, fault_schedule(), |schedule| {
        let fb = fault_base();
        let dir = tempfile::tempdir().map_err(|e| TestCaseError::fail(e.to_string()))?;
        let path = dir.path().to_path_buf();
        let (sc, pts) = (fb.scenario.clone(), fb.points.clone());
        let first = bounded("a session under faults", move || {
            run_faulty(&sc, &pts, &path, schedule, false).map_err(|e| e.to_string())
        })?;
        if let Err(e) = first {
            // Ended early: it must say why and leave a session that resumes (faults gone).
            refused();
            prop_assert!(!e.trim().is_empty(), "a session ended saying nothing");
            let journal = rigcal_devices::session::Journal::load(dir.path());
            if let Ok(j) = &journal {
                prop_assert!(
                    !j.finished,
                    "ended with `{e}` but the journal says finished"
                );
            }
            let (sc, pts, path) = (
                fb.scenario.clone(),
                fb.points.clone(),
                dir.path().to_path_buf(),
            );
            let resumed = bounded("resuming a faulted session", move || {
                run_faulty(&sc, &pts, &path, Vec::new(), journal.is_ok()).map_err(|e| e.to_string())
            })?;
            prop_assert!(
                resumed.is_ok(),
                "after `{e}`, the resume failed: {:?}",
                resumed.err()
            );
        } else {
            accepted();
        }
        // Every point is accounted for, every skip explained, every measured row right.
        let text = std::fs::read_to_string(dir.path().join("measurements.csv"))
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        let skipped_without_reason = text
            .lines()
            .filter(|l| l.ends_with(",skipped") || l.ends_with(",skipped:"))
            .count();
        prop_assert_eq!(
            skipped_without_reason,
            0,
            "a skipped row without its reason"
        );
        let rows = measured_rows(&fb.scenario.rig, dir.path()).map_err(TestCaseError::fail)?;
        for (q, p) in &rows {
            let Some((_, want)) = fb.clean.iter().find(|(cq, _)| cq == q) else {
                return Err(TestCaseError::fail(format!(
                    "a measured row at joints {q} that the plan does not hold"
                )));
            };
            let d =
                ((p[0] - want[0]).powi(2) + (p[1] - want[1]).powi(2) + (p[2] - want[2]).powi(2))
                    .sqrt();
            if d > FAULT_TOLERANCE_MM && std::env::var("RIGCAL_FUZZ_KEEP").is_ok() {
                let _ = std::fs::copy(dir.path().join("measurements.csv"), "/tmp/fault_dbg.csv");
            }
            prop_assert!(
                d <= FAULT_TOLERANCE_MM,
                "joints {q}: measured {p:?} under faults, {want:?} without (Δ {d:.4} mm)"
            );
        }
        Ok(())
    })
}

/// How far a row measured under faults may lie from the fault-free one in a world without
/// scatter. Only the contact's overshoot can differ: the fault-free reading's is the rig's
/// budget exactly (0.42 mm/s × (10 ms panel + 2 ms bus) = 0.005 mm, the speed rule), and the
/// session accepts a reading up to 1.5 × the budget (0.0075 mm: a drive 5 ms late is kept);
/// so 0.0025 mm, plus one count of the drives' position (0.001 mm). A late reading's bias
/// (0.07 mm and up), a touch read after a slow move start (0.02 mm) and a touch taken one
/// report period late after a corrupt packet (0.004 mm) all lie beyond it.
const FAULT_TOLERANCE_MM: f64 = 0.0035;
