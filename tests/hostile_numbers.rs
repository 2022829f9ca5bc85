//! Never silently wrong with numbers: one gross cell gives the clean fit or an error, never a
//! diverged model; absurd values (1e12 … 1e308, beyond any measurement of the arm) are refused
//! up front with their row and column, in seconds rather than an endless SVD; rig lengths
//! beyond 100 m are refused; identical poses are a rank loss, not σ 0 and RMS 0; a fit beyond
//! the rig's bounds is an error with no model written; a model holding a non-finite value is
//! never written; `evaluate` prints no mean over zero compensated points and fails when a model
//! compensated none; a nest pose outside the joint limits is refused.

use rigcal_core::rig::{Rig, RigError};
use rigcal_model::identification::ResidualStats;
use rigcal_model::model::{FitSummary, ModelBody, ModelFile, ParamEntry, Provenance};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const RIG: &str = "rigs/rv-m2-ideal.toml";
const SCENARIO: &str = "sim/paper-sim.toml";

/// A run of the binary: success, stdout, stderr.
struct Run {
    ok: bool,
    out: String,
    err: String,
}

/// Runs `rigcal` with a hang guard (not a speed test): a run still going after a minute is
/// killed and fails the test.
fn rigcal(args: &[&str]) -> Run {
    let dir = tempfile::tempdir().unwrap();
    let (out_path, err_path) = (dir.path().join("out"), dir.path().join("err"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(args)
        .stdout(std::fs::File::create(&out_path).unwrap())
        .stderr(std::fs::File::create(&err_path).unwrap())
        .stdin(Stdio::null())
        .spawn()
        .expect("run rigcal");
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("rigcal {args:?} hangs (killed after 60 s)");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    Run {
        ok: status.success(),
        out: std::fs::read_to_string(&out_path).unwrap(),
        err: std::fs::read_to_string(&err_path).unwrap(),
    }
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The 300-row recording `rigcal simulate` makes on the ideal RV-M2 (the scenario's seed):
/// the recording of the reports.
fn simulated(dir: &Path) -> PathBuf {
    let rec = dir.join("clean");
    let r = rigcal(&[
        "simulate",
        "--rig",
        RIG,
        "--scenario",
        SCENARIO,
        "--random",
        "300",
        "--out",
        s(&rec),
    ]);
    assert!(r.ok, "{}", r.err);
    rec
}

/// A copy of recording `src` at `dst` with its CSV rewritten by `edit` (header, rows).
fn edited(src: &Path, dst: &Path, edit: impl FnOnce(&[String], &mut Vec<Vec<String>>)) -> PathBuf {
    std::fs::create_dir_all(dst).unwrap();
    for entry in std::fs::read_dir(src).unwrap() {
        let entry = entry.unwrap();
        std::fs::copy(entry.path(), dst.join(entry.file_name())).unwrap();
    }
    let csv = dst.join("measurements.csv");
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let mut rows: Vec<Vec<String>> = lines
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    edit(&header, &mut rows);
    let mut out = header.join(",") + "\n";
    for r in rows {
        out += &(r.join(",") + "\n");
    }
    std::fs::write(&csv, out).unwrap();
    dst.to_path_buf()
}

fn column(header: &[String], name: &str) -> usize {
    header.iter().position(|h| h == name).expect(name)
}

/// `src` with the cell (`seq`, `col`) set to `value`.
fn planted(src: &Path, dst: &Path, seq: usize, col: &str, value: &str) -> PathBuf {
    edited(src, dst, |header, rows| {
        let c = column(header, col);
        rows[seq - 1][c] = value.to_string();
    })
}

/// `src` without the row `seq`.
fn without_row(src: &Path, dst: &Path, seq: usize) -> PathBuf {
    edited(src, dst, |_, rows| {
        rows.remove(seq - 1);
    })
}

/// (name, value) of every parameter of a model file.
fn parameters(model: &Path) -> Vec<(String, f64)> {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(model).unwrap()).unwrap();
    v["model"]["parameters"]
        .as_array()
        .expect("parameters")
        .iter()
        .map(|p| {
            (
                p["name"].as_str().unwrap().to_string(),
                p["value"].as_f64().expect("a finite value"),
            )
        })
        .collect()
}

fn identify(rig: &str, rec: &Path, model: &Path) -> Run {
    rigcal(&[
        "identify",
        "--rig",
        rig,
        "--recording",
        s(rec),
        "--out",
        s(model),
    ])
}

// ---- 1. one gross cell: the clean fit or an error ----------------------------------------

#[test]
fn one_gross_cell_gives_the_clean_fit_never_a_diverged_model() {
    let dir = tempfile::tempdir().unwrap();
    let clean = simulated(dir.path());
    // The cells the reports (and a sweep of rows and sizes) found diverging: the
    // outlier named and removed, and the fit then ended 89–574 mm RMS, Δθ0 +360°, or with
    // Δθ2 −180° and Δa2 −500 mm (the same arm described with a joint turned half a turn).
    let cases = [
        (299, "1e5"),
        (2, "3e5"),
        (150, "3e5"),
        (299, "3e5"),
        (2, "1e6"),
        (150, "-1e6"),
    ];
    let mut reference = std::collections::BTreeMap::new();
    for (k, &(seq, value)) in cases.iter().enumerate() {
        let rec = planted(
            &clean,
            &dir.path().join(format!("gross{k}")),
            seq,
            "x_mm",
            value,
        );
        let model = dir.path().join(format!("gross{k}.json"));
        let r = identify(RIG, &rec, &model);
        assert!(r.ok, "x_mm = {value} at seq {seq}: {}{}", r.out, r.err);
        assert!(
            r.out
                .contains(&format!("outlier removed from the fit: seq {seq},")),
            "{}",
            r.out
        );
        let clean_params = reference.entry(seq).or_insert_with(|| {
            let rec = without_row(&clean, &dir.path().join(format!("without{seq}")), seq);
            let model = dir.path().join(format!("without{seq}.json"));
            let r = identify(RIG, &rec, &model);
            assert!(r.ok, "{}", r.err);
            parameters(&model)
        });
        let got = parameters(&model);
        assert_eq!(got.len(), clean_params.len());
        for ((name, v), (_, want)) in got.iter().zip(clean_params.iter()) {
            assert!(
                (v - want).abs() < 1e-4,
                "x_mm = {value} at seq {seq}: {name} = {v} against {want} without the row"
            );
        }
    }
}

// ---- 2. absurd values refused up front, with row and column -------------------------------

#[test]
fn absurd_cells_are_refused_with_their_row_and_column_and_no_model_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let clean = simulated(dir.path());
    for (k, (seq, col, value)) in [
        (101, "x_mm", "1e12"),
        (101, "x_mm", "1e300"),
        (101, "x_mm", "1e308"),
        (7, "y_mm", "-1e308"),
        (250, "z_mm", "1e7"),
    ]
    .into_iter()
    .enumerate()
    {
        let rec = planted(
            &clean,
            &dir.path().join(format!("absurd{k}")),
            seq,
            col,
            value,
        );
        let model = dir.path().join(format!("absurd{k}.json"));
        let start = Instant::now();
        let r = identify(RIG, &rec, &model);
        assert!(!r.ok, "{col} = {value} accepted: {}", r.out);
        assert!(!model.exists(), "{col} = {value}: a model was written");
        let line = seq + 1;
        assert!(
            r.err.contains(&format!("seq {seq} (line {line})"))
                && r.err.contains(&format!("`{col}`")),
            "{}",
            r.err
        );
        assert!(r.err.contains("reach"), "{}", r.err);
        assert!(start.elapsed() < Duration::from_secs(30), "{value}");
    }
}

#[test]
fn diagnose_and_register_refuse_an_absurd_cell_too() {
    let dir = tempfile::tempdir().unwrap();
    let clean = simulated(dir.path());
    let rec = planted(&clean, &dir.path().join("d"), 50, "x_mm", "1e308");
    let r = rigcal(&["diagnose", "--rig", RIG, "--recording", s(&rec)]);
    assert!(!r.ok, "{}", r.out);
    assert!(
        r.err.contains("seq 50 (line 51)") && r.err.contains("`x_mm`"),
        "{}",
        r.err
    );
    let rec = edited(&clean, &dir.path().join("t"), |header, rows| {
        let c = column(header, "table_x_mm");
        for (k, row) in rows.iter_mut().enumerate() {
            for (i, v) in ["100", "200", "300"].iter().enumerate() {
                row[c + i] = format!("{}{}", v, k % 7);
            }
        }
        rows[9][c + 1] = "1e308".into();
    });
    let r = rigcal(&["register", "--rig", RIG, "--recording", s(&rec)]);
    assert!(!r.ok, "{}", r.out);
    assert!(
        r.err.contains("seq 10 (line 11)") && r.err.contains("`table_y_mm`"),
        "{}",
        r.err
    );
}

// ---- 3. rig lengths bounded: no input hangs an SVD ----------------------------------------

fn rig_with_a2(value: &str) -> String {
    let text = std::fs::read_to_string(RIG).unwrap();
    assert!(text.contains("a_mm = 250.0"));
    text.replacen("a_mm = 250.0", &format!("a_mm = {value}"), 1)
}

#[test]
fn absurd_rig_lengths_are_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let clean = simulated(dir.path());
    for value in ["1e308", "1e300", "1e15", "100001"] {
        let rig = dir.path().join("big.toml");
        std::fs::write(&rig, rig_with_a2(value)).unwrap();
        let model = dir.path().join("big.json");
        for r in [
            identify(s(&rig), &clean, &model),
            rigcal(&["observability", "--rig", s(&rig)]),
        ] {
            assert!(!r.ok, "a_mm = {value} accepted: {}", r.out);
            assert!(
                r.err.contains("robot.joints[1].a_mm") && r.err.contains("100 m"),
                "{}",
                r.err
            );
        }
        assert!(!model.exists());
    }
    // 100 m is an arm still (if a large one).
    let e = Rig::parse(&rig_with_a2("100000"), None);
    assert!(e.is_ok(), "{e:?}");
}

#[test]
fn huge_counts_for_observability_and_evaluate_are_refused_up_front() {
    let r = rigcal(&["observability", "--rig", RIG, "--poses", "99999999999"]);
    assert!(!r.ok && r.err.contains("100000"), "{}", r.err);
    let r = rigcal(&[
        "evaluate",
        "--model",
        "no-such-model.json",
        "--scenario",
        SCENARIO,
        "--points",
        "99999999999",
    ]);
    assert!(!r.ok && r.err.contains("1000000"), "{}", r.err);
}

// ---- 4. degenerate designs -----------------------------------------------------------------

#[test]
fn identical_poses_are_refused_as_a_rank_loss() {
    let dir = tempfile::tempdir().unwrap();
    let clean = simulated(dir.path());
    // 50 rows of the first pose, with table coordinates for the registration.
    let rec = edited(&clean, &dir.path().join("same"), |header, rows| {
        let first = rows[0].clone();
        let (x, t) = (column(header, "x_mm"), column(header, "table_x_mm"));
        let seq = column(header, "seq");
        rows.clear();
        for k in 0..50 {
            let mut row = first.clone();
            row[seq] = (k + 1).to_string();
            for i in 0..3 {
                row[t + i] = row[x + i].clone();
            }
            rows.push(row);
        }
    });
    let model = dir.path().join("same.json");
    for (cmd, needed) in [
        ("identify", "at least 6 distinct poses"),
        ("diagnose", "at least 6 distinct poses"),
        ("register", "at least 3 distinct poses"),
    ] {
        let mut args = vec![cmd, "--rig", RIG, "--recording", s(&rec)];
        if cmd == "identify" {
            args.extend(["--out", s(&model)]);
        }
        let r = rigcal(&args);
        assert!(!r.ok, "{cmd} accepted 50 identical poses: {}", r.out);
        assert!(
            r.err.contains("50 measurements hold only 1 distinct pose")
                && r.err.contains("do not spread")
                && r.err.contains("rank loss")
                && r.err.contains(needed),
            "{cmd}: {}",
            r.err
        );
    }
    assert!(!model.exists());
}

// ---- 1b. a fit beyond the rig's bounds is an error ------------------------------------------

#[test]
fn a_fit_beyond_the_rigs_stated_bounds_is_an_error_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let clean = simulated(dir.path());
    // The scenario's errors are ±0.05° and ±0.4 mm: a bound of 0.01° refuses the fit.
    let text = std::fs::read_to_string(RIG).unwrap();
    let strict = text.replacen(
        "marker = \"fixed\"",
        "marker = \"fixed\"\nmax_angle_correction_deg = 0.01",
        1,
    );
    assert_ne!(strict, text);
    let rig = dir.path().join("strict.toml");
    std::fs::write(&rig, strict).unwrap();
    let model = dir.path().join("strict.json");
    let r = identify(s(&rig), &clean, &model);
    assert!(!r.ok, "{}", r.out);
    assert!(
        r.err.contains("the fit diverged")
            && r.err.contains("calibration.max_angle_correction_deg")
            && r.err.contains("No model was written"),
        "{}",
        r.err
    );
    assert!(!model.exists());
    // The rig's own defaults accept the fit.
    let r = identify(RIG, &clean, &model);
    assert!(r.ok, "{}", r.err);
}

// ---- 2b. no non-finite value reaches a written model ---------------------------------------

/// A conventional model of `rig` holding only Δθ1 = `value` (deg), as a file would.
fn theta1_model(rig: &Rig, value: f64) -> ModelFile {
    ModelFile::new(
        rig,
        Provenance::default(),
        ModelBody::Constant {
            parameters: vec![ParamEntry {
                name: "theta1".into(),
                value,
                unit: "deg".into(),
                sigma: Some(0.1),
            }],
            fit: FitSummary {
                kappa_eq4: 1.0,
                before: ResidualStats::default(),
                after: ResidualStats::default(),
                sigma0_mm: 0.0,
                iterations: 0,
            },
        },
    )
}

#[test]
fn a_model_holding_a_non_finite_value_is_not_written() {
    let dir = tempfile::tempdir().unwrap();
    let rig = Rig::load(Path::new(RIG)).unwrap();
    let file = theta1_model(&rig, f64::NAN);
    let path = dir.path().join("model.json");
    let e = file.save(&path).expect_err("a NaN was written");
    assert!(
        e.to_string().contains("model.parameters[0].value = NaN"),
        "{e}"
    );
    assert!(!path.exists());
}

/// A model file written by hand (or by another tool) with a correction no kinematic fit of this
/// rig may have is refused when read, as a fit beyond the bounds is refused when written.
#[test]
fn a_model_file_beyond_the_rigs_bounds_is_refused_when_read() {
    let dir = tempfile::tempdir().unwrap();
    let rig = Rig::load(Path::new(RIG)).unwrap();
    let model = |value: f64| theta1_model(&rig, value);
    let (small, huge) = (dir.path().join("small.json"), dir.path().join("huge.json"));
    model(0.5).save(&small).unwrap();
    model(2000.0).save(&huge).unwrap();
    assert!(ModelFile::load(&small).is_ok());
    let e = ModelFile::load(&huge)
        .err()
        .expect("a 2000° offset was read");
    let e = e.to_string();
    assert!(
        e.contains("Δθ1 = +2000") && e.contains("max_angle_correction_deg"),
        "{e}"
    );
    let targets = dir.path().join("targets.csv");
    std::fs::write(&targets, "x_mm,y_mm,z_mm\n250,0,300\n").unwrap();
    let r = rigcal(&[
        "compensate",
        "--model",
        s(&huge),
        "--targets",
        s(&targets),
        "--out",
        s(&dir.path().join("out.csv")),
    ]);
    assert!(!r.ok && r.err.contains("Δθ1 = +2000"), "{}", r.err);
}

/// A recording written by other means than `rigcal import` (its own format, but in metres) is
/// refused by every command that reads it, with the likely cause, as import refuses one; the
/// recording in millimetres with one gross cell is not (that is the outlier search's).
#[test]
fn a_recording_in_metres_is_refused_where_it_is_read_not_fitted() {
    let dir = tempfile::tempdir().unwrap();
    let clean = simulated(dir.path());
    let metres = edited(&clean, &dir.path().join("metres"), |header, rows| {
        for col in ["x_mm", "y_mm", "z_mm"] {
            let c = column(header, col);
            for r in rows.iter_mut() {
                let v: f64 = r[c].parse().unwrap();
                r[c] = format!("{}", v / 1000.0);
            }
        }
    });
    let model = dir.path().join("m.json");
    for args in [
        vec![
            "identify",
            "--rig",
            RIG,
            "--recording",
            s(&metres),
            "--out",
            s(&model),
        ],
        vec!["diagnose", "--rig", RIG, "--recording", s(&metres)],
    ] {
        let r = rigcal(&args);
        assert!(!r.ok, "{} accepted a recording in metres", args[0]);
        assert!(
            r.err.contains("does not fit rig") && r.err.contains("1000 times too small"),
            "{}: {}",
            args[0],
            r.err
        );
    }
    assert!(!model.exists());
    let gross = planted(&clean, &dir.path().join("gross"), 7, "x_mm", "100000");
    let r = identify(RIG, &gross, &model);
    assert!(!r.err.contains("does not fit rig"), "{}", r.err);
}

// ---- 5. evaluate with failures ---------------------------------------------------------------

#[test]
fn evaluate_prints_no_mean_over_zero_compensated_points_and_fails() {
    let dir = tempfile::tempdir().unwrap();
    let clean = simulated(dir.path());
    let model = dir.path().join("model.json");
    let r = identify(RIG, &clean, &model);
    assert!(r.ok, "{}", r.err);
    // A model that puts J2's link 5 m long: no target of the path is reachable with it.
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    let p = v["model"]["parameters"]
        .as_array_mut()
        .unwrap()
        .iter_mut()
        .find(|p| p["name"] == "a2")
        .expect("a2");
    p["value"] = serde_json::json!(5000.0);
    // The embedded rig states bounds that admit it (a model read back is held to the rig's).
    let rig = v["rig"]["toml"].as_str().expect("embedded rig").replace(
        "[calibration]\n",
        "[calibration]\nmax_length_correction_mm = 10000.0\n",
    );
    v["rig"]["toml"] = serde_json::json!(rig);
    let broken = dir.path().join("broken.json");
    std::fs::write(&broken, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    let r = rigcal(&["evaluate", "--model", s(&broken), "--scenario", SCENARIO]);
    assert!(!r.ok, "{}", r.out);
    assert!(!r.out.contains("0.0000     0.0000"), "{}", r.out);
    assert!(
        r.out
            .contains("conventional: none of the 101 points could be compensated"),
        "{}",
        r.out
    );
    assert!(
        r.err
            .contains("conventional: 101 of 101 points not compensated; the first, point 0 of Fig. 6 joint path:"),
        "{}",
        r.err
    );
    assert!(
        r.err.contains("compensated none of the points"),
        "{}",
        r.err
    );
    // The sound model evaluates as before.
    let r = rigcal(&["evaluate", "--model", s(&model), "--scenario", SCENARIO]);
    assert!(r.ok, "{}", r.err);
    assert!(!r.out.contains("could not be compensated"), "{}", r.out);
}

// ---- 6. the nest pose within the joint limits --------------------------------------------------

#[test]
fn a_nest_pose_outside_the_joint_limits_is_refused() {
    let text = std::fs::read_to_string("rigs/rv-m2.toml").unwrap();
    let nest = "nest_deg = [0.0, 90.0, -90.0, 0.0, 0.0]";
    assert!(text.contains(nest));
    Rig::parse(&text, None).expect("the rig's own nest pose");
    let bad = text.replacen(nest, "nest_deg = [0.0, 90.0, 30.0, 0.0, 0.0]", 1);
    let Err(e) = Rig::parse(&bad, Some(Path::new("nest.toml"))) else {
        panic!("a nest pose outside J3's limits was accepted")
    };
    let msg = e.to_string();
    assert!(matches!(e, RigError::Invalid { .. }), "{msg}");
    assert!(
        msg.contains("nest.toml")
            && msg.contains("devices.arm.nest_deg[2]")
            && msg.contains("J3")
            && msg.contains("30°")
            && msg.contains("[-120.00°, 0.00°]"),
        "{msg}"
    );
    // Through the binary, as a user meets it.
    let dir = tempfile::tempdir().unwrap();
    let rig = dir.path().join("nest.toml");
    std::fs::write(&rig, bad).unwrap();
    let r = rigcal(&["observability", "--rig", s(&rig)]);
    assert!(!r.ok && r.err.contains("J3"), "{}", r.err);
}
