//! The `rigcal` binary end to end: the demo, observability, identify → compensate, and clear
//! errors on bad input.

use std::path::Path;
use std::process::Command;

fn rigcal(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(args)
        .output()
        .expect("run rigcal");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn observability_prints_rank_15_and_the_papers_basis() {
    let (ok, out, err) = rigcal(&["observability", "--rig", "rigs/rv-m2.toml"]);
    assert!(ok, "{err}");
    assert!(out.contains("rank of [M]: 15 of 35"), "{out}");
    assert!(
        out.contains("Δθ0 Δa0 Δα0 Δβ0 Δθ1 Δd1 Δa1 Δα1 Δθ2 Δa2 Δα2 Δβ2 Δθ3 Δd3 Δa3"),
        "{out}"
    );
    assert!(out.contains("Δd0        ≡ -1.0000·Δd1"), "{out}");
    let (ok, out, _) = rigcal(&["observability", "--rig", "rigs/rv-m2.toml", "--all-joints"]);
    assert!(ok);
    assert!(out.contains("rank of [M]: 23 of 35"), "{out}");
}

/// The mean and max of `model` on the summary line after `path` ("name mean / max").
fn summary_figure(summary: &str, path: &str, model: &str) -> (f64, f64) {
    let line = summary
        .lines()
        .skip_while(|l| !l.contains(path))
        .nth(1)
        .unwrap_or_else(|| panic!("no {path} in {summary}"));
    let rest = line
        .split(&format!("{model} "))
        .nth(1)
        .unwrap_or_else(|| panic!("no {model} in {line}"));
    let v: Vec<f64> = rest
        .split_whitespace()
        .filter_map(|w| w.parse().ok())
        .take(2)
        .collect();
    (v[0], v[1])
}

#[test]
fn demo_runs_sessions_calibrates_evaluates_and_diagnoses() {
    let dir = tempfile::tempdir().unwrap();
    let (ok, out, err) = rigcal(&["demo", "--out", s(dir.path()), "--path-points", "41"]);
    assert!(ok, "{err}");
    for f in [
        "paper-fig6-model.json",
        "paper-fig7-model.json",
        "paper-fig8-model.json",
        "paper-fig6-cmac-model.json",
        "paper-plots/paper-fig6-model/fig-6-joint-path-errors.svg",
        "rig/division/measurements.csv",
        "rig/sec7-model.json",
        "rig/path-cartesian/measurements.csv",
        "rig/path-joint/measurements.csv",
        "rig-plots/sec7-path-cartesian-measured-errors.svg",
        "rig-diagnosis.json",
        "summary.txt",
        "summary.json",
    ] {
        assert!(dir.path().join(f).exists(), "{f} missing; output:\n{out}");
    }
    let summary = std::fs::read_to_string(dir.path().join("summary.txt")).unwrap();
    let (uncal_mean, _) = summary_figure(&summary, "Fig. 6 joint path", "uncalibrated");
    let (_, fcmac_max) = summary_figure(&summary, "Fig. 6 joint path", "fcmac");
    let (_, conventional_max) = summary_figure(&summary, "Fig. 6 joint path", "conventional");
    assert!(uncal_mean > 0.5, "{summary}");
    assert!(
        fcmac_max < 0.1 && fcmac_max < conventional_max && conventional_max > 0.1,
        "{summary}"
    );
    // The section 7 part: the path measured by the rig through MP and MJ, every method, both
    // floors printed beside the measured errors.
    assert!(out.contains("floor: the MP rounding alone"), "{out}");
    assert!(out.contains("floor: the MJ rounding alone"), "{out}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    let rig = &json["rig"];
    assert!(rig["regions"].as_u64().unwrap() > 1, "{rig}");
    assert_eq!(rig["paper_regions"], 85);
    assert!(rig["measurements"].as_u64().unwrap() >= 20 * 2, "{rig}");
    assert!(rig["rig_hours_clock"].as_f64().unwrap() > 0.0, "{rig}");
    let paths = rig["command_paths"].as_array().unwrap();
    assert_eq!(paths.len(), 2, "{rig}");
    assert_eq!(paths[0]["command"], "MP");
    assert_eq!(paths[1]["command"], "MJ");
    for p in paths {
        let methods: Vec<&str> = p["methods"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m["method"].as_str().unwrap())
            .collect();
        assert_eq!(
            methods,
            ["uncalibrated", "conventional", "regions", "fcmac"]
        );
        for m in p["methods"].as_array().unwrap() {
            assert!(m["max_mm"].as_f64().unwrap() >= m["mean_mm"].as_f64().unwrap());
        }
        assert_eq!(p["floors"].as_array().unwrap().len(), 4);
    }
}

#[test]
fn identify_then_compensate_from_files() {
    let dir = tempfile::tempdir().unwrap();
    let (ok, _, err) = rigcal(&[
        "session",
        "--rig",
        "rigs/rv-m2-ideal.toml",
        "--sim",
        "sim/paper-sim-noise.toml",
        "--points",
        "100",
        "--out",
        s(&dir.path().join("recording")),
    ]);
    assert!(ok, "{err}");
    let model = dir.path().join("m.json");
    let (ok, out, err) = rigcal(&[
        "identify",
        "--rig",
        "rigs/rv-m2-ideal.toml",
        "--recording",
        s(&dir.path().join("recording")),
        "--out",
        s(&model),
    ]);
    assert!(ok, "{err}");
    assert!(out.contains("Δθ0") && out.contains("κ (eq. 4)"), "{out}");
    let targets = dir.path().join("targets.csv");
    std::fs::write(&targets, "x_mm,y_mm,z_mm\n0,600,500\n100,550,450\n").unwrap();
    let cmds = dir.path().join("cmds.csv");
    let (ok, _, err) = rigcal(&[
        "compensate",
        "--model",
        s(&model),
        "--targets",
        s(&targets),
        "--out",
        s(&cmds),
    ]);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&cmds).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg");
    assert_eq!(lines.len(), 3);
    // The first target lies in the plane x = 0, so the command's q1 is near zero.
    let q1: f64 = lines[1].split(',').next().unwrap().parse().unwrap();
    assert!(q1.abs() < 0.5, "{q1}");

    std::fs::write(&targets, "x_mm,y_mm,z_mm\n0,600,500\n0,2000,400\n").unwrap();
    let (ok, _, err) = rigcal(&[
        "compensate",
        "--model",
        s(&model),
        "--targets",
        s(&targets),
        "--out",
        s(&cmds),
    ]);
    assert!(!ok);
    assert!(
        err.contains("targets.csv: line 3") && err.contains("out of reach"),
        "{err}"
    );
}

#[test]
fn bad_input_gets_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("rec.csv");
    std::fs::write(&rec, "seq,t_s,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,x_mm,y_mm,z_mm\n1,0,10,20,-30,0,0,1,2,3\n2,1,10,twenty,-30,0,0,1,2,3\n").unwrap();
    let (ok, _, err) = rigcal(&[
        "identify",
        "--rig",
        "rigs/rv-m2.toml",
        "--recording",
        s(&rec),
        "--out",
        s(&dir.path().join("m.json")),
    ]);
    assert!(!ok);
    assert!(
        err.contains("rec.csv: line 3, column 4 (`q2_deg`): `twenty` is not a number"),
        "{err}"
    );

    let rig = dir.path().join("bad.toml");
    std::fs::write(
        &rig,
        "name = \"x\"\n[robot]\nbase = {}\ntool = {}\njoints = []\n",
    )
    .unwrap();
    let (ok, _, err) = rigcal(&["observability", "--rig", s(&rig)]);
    assert!(!ok);
    assert!(
        err.contains("bad.toml") && err.contains("robot.joints"),
        "{err}"
    );

    let model = dir.path().join("model.json");
    std::fs::write(&model, "{\"format\": \"something-else\"}").unwrap();
    let (ok, _, err) = rigcal(&[
        "compensate",
        "--model",
        s(&model),
        "--targets",
        s(&rec),
        "--out",
        s(&dir.path().join("o.csv")),
    ]);
    assert!(!ok);
    assert!(err.contains("not a rigcal model"), "{err}");

    let (ok, _, err) = rigcal(&[
        "identify",
        "--rig",
        "rigs/nope.toml",
        "--recording",
        s(&rec),
        "--out",
        "x.json",
    ]);
    assert!(!ok);
    assert!(err.contains("cannot read rig file rigs/nope.toml"), "{err}");
}

/// `rigcal sim-device arm --pty` prints a port path and answers Movemaster commands there.
#[test]
fn sim_device_serves_the_arm_on_a_pseudo_terminal() {
    use std::io::{BufRead, BufReader, Read, Write};
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(["sim-device", "arm", "--rig", "rigs/rv-m2.toml", "--pty"])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let mut line = String::new();
    BufReader::new(stdout).read_line(&mut line).unwrap();
    let path = line.trim().to_string();
    let result = std::panic::catch_unwind(|| {
        assert!(path.starts_with("/dev/"), "{path}");
        let mut port = serialport::new(&path, 9600)
            .timeout(std::time::Duration::from_millis(200))
            .open()
            .unwrap();
        port.write_all(b"ER\r").unwrap();
        let mut buf = [0u8; 2];
        port.read_exact(&mut buf).unwrap();
        assert_eq!(&buf, b"0\r");
    });
    let _ = child.kill();
    let _ = child.wait();
    result.unwrap();
}

#[test]
fn import_converts_units_keeps_columns_and_names_bad_cells() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("tracker.csv");
    std::fs::write(&csv, "time,a1,a2,a3,a4,a5,mx,my,mz,operator\n0.5,0.1,0.2,-0.3,0,0,0.1,0.725,0.4,ann\n1.0,0.2,0.3,-0.4,0,0,0.11,0.7,0.41,bob\n").unwrap();
    let out = dir.path().join("rec");
    let args = [
        "import",
        s(&csv),
        "--rig",
        "rigs/rv-m2-ideal.toml",
        "--joints",
        "a1,a2,a3,a4,a5",
        "--point",
        "mx,my,mz",
        "--time",
        "time",
        "--out",
        s(&out),
    ];
    let (ok, _, err) = rigcal(&args);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(out.join("measurements.csv")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].ends_with(",status,operator"), "{}", lines[0]);
    assert!(lines[1].starts_with("1,0.500,5.729578,11.459156,-17.188734,0.000000,0.000000,100.00000,725.00000,400.00000,"), "{}", lines[1]);
    assert!(lines[1].ends_with(",ok,ann"), "{}", lines[1]);

    std::fs::write(
        &csv,
        "time,a1,a2,a3,a4,a5,mx,my,mz\n0.5,0.1,0.2,-0.3,0,0,0.1,oops,0.4\n",
    )
    .unwrap();
    let (ok, _, err) = rigcal(&args);
    assert!(!ok);
    assert!(
        err.contains("line 2, column 8 (`my`): `oops` is not a number"),
        "{err}"
    );
    std::fs::write(
        &csv,
        "time,a1,a2,a3,a4,a5,mx,my,mz\n0.5,3.0,0.2,-0.3,0,0,0.1,0.7,0.4\n",
    )
    .unwrap();
    let (ok, _, err) = rigcal(&args);
    assert!(!ok);
    assert!(
        err.contains("line 2, column 2 (`a1`)") && err.contains("outside joint J1's limits"),
        "{err}"
    );
    let (ok, _, err) = rigcal(&[
        "import",
        s(&csv),
        "--rig",
        "rigs/rv-m2-ideal.toml",
        "--joints",
        "a1,a2,a3,a4,b5",
        "--point",
        "mx,my,mz",
        "--out",
        s(&out),
    ]);
    assert!(!ok);
    assert!(err.contains("no column `b5`"), "{err}");
}

#[test]
fn reproduce_writes_fig7_learning_curves_that_fall() {
    let dir = tempfile::tempdir().unwrap();
    let (ok, out, err) = rigcal(&[
        "reproduce",
        "seed001",
        "--figure",
        "7",
        "--out",
        s(dir.path()),
    ]);
    assert!(ok, "{err}");
    assert!(out.contains("Fig. 7"), "{out}");
    let svg = std::fs::read_to_string(dir.path().join("seed001-fig7.svg")).unwrap();
    assert!(svg.contains("case 3") && svg.contains("scheme 7"));
    let csv = std::fs::read_to_string(dir.path().join("seed001-fig7.csv")).unwrap();
    let mut curves: std::collections::BTreeMap<(u32, u32), Vec<(u32, f64)>> = Default::default();
    for line in csv.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let (case, scheme) = (f[0].parse().unwrap(), f[1].parse().unwrap());
        curves
            .entry((case, scheme))
            .or_default()
            .push((f[3].parse().unwrap(), f[4].parse().unwrap()));
    }
    assert_eq!(curves.len(), 21, "3 cases × 7 schemes");
    for ((case, scheme), points) in &curves {
        assert!(points.windows(2).all(|w| w[0].0 < w[1].0));
        let (first, last) = (points[0].1, points[points.len() - 1].1);
        assert!(
            last < first / 10.0,
            "case {case} scheme {scheme}: {first} → {last}"
        );
    }
    let (ok, _, err) = rigcal(&["reproduce", "seed001", "--figure", "3"]);
    assert!(!ok && err.contains("figure 3 is not reproduced"), "{err}");
}

/// `reproduce seed001 --seeds`: each seed's figures are the single-seed run's (read back from
/// its printed table), and the summary counts them per paper table.
#[test]
fn reproduce_over_seeds_summarises_the_single_seed_tables() {
    let dir = tempfile::tempdir().unwrap();
    let (ok, out, err) = rigcal(&[
        "reproduce",
        "seed001",
        "--table",
        "18",
        "--seeds",
        "1,2",
        "--out",
        s(dir.path()),
    ]);
    assert!(ok, "{err}");
    assert!(out.contains("over seeds 1–2 (2 runs)"), "{out}");
    for table in ["17", "18"] {
        assert!(
            out.lines()
                .any(|l| l.trim_start().starts_with(table) && l.contains("/10 (")),
            // 6 row pairs, one with equal paper values (δLc/2 δLr/2: 0.10 both): 5 × 2 seeds.
            "no line for Table {table} with 5 row pairs × 2 seeds compared: {out}"
        );
    }
    let csv = std::fs::read_to_string(dir.path().join("seed001-seeds.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 2 * 12, "{csv}");
    // Seed 2's δLc δLr=0 scheme 4 E_ac mean, as the single-seed run prints it (3 decimals).
    let (ok, single, err) = rigcal(&["reproduce", "seed001", "--table", "18", "--seed", "2"]);
    assert!(ok, "{err}");
    let printed: f64 = single
        .lines()
        .find(|l| l.contains("δLc δLr=0") && l.contains("scheme 4 (Table 18)"))
        .and_then(|l| l.split_whitespace().nth(6))
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no δLr=0 scheme 4 row: {single}"));
    let summarised: f64 = csv
        .lines()
        .find(|l| l.contains("δLc δLr=0 direct-4 E_ac mean\",2,"))
        .and_then(|l| l.rsplit(',').nth(2))
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no seed-2 row: {csv}"));
    assert!(
        (printed - summarised).abs() <= 0.0005,
        "{printed} vs {summarised}"
    );
    let (ok, _, err) = rigcal(&["reproduce", "seed001", "--seeds", "1-2", "--figure", "7"]);
    assert!(!ok && err.contains("tables only"), "{err}");
}

/// The shared option groups (`--rig`, `--recording`, `--out`) keep each command's own help text
/// and the usage line's order.
#[test]
fn shared_options_keep_their_help_per_command() {
    for (command, wanted) in [
        (
            &["identify", "--help"][..],
            &[
                "Usage: rigcal identify [OPTIONS] --rig <RIG> --recording <RECORDING> --out <OUT>",
                "Rig file (TOML)",
                "Recording: a directory with measurements.csv, or a CSV file",
                "Where to write the model (JSON)",
            ][..],
        ),
        (
            &["import", "--help"],
            &[
                "Usage: rigcal import [OPTIONS] --rig <RIG> --joints <JOINTS> --point <POINT> --out <OUT> <FILE>",
                "Rig file the joints belong to",
                "Output recording directory",
            ],
        ),
        (
            &["register", "--help"],
            &["Recording whose rows carry table_x_mm, table_y_mm, table_z_mm"],
        ),
        (
            &["simulate", "--help"],
            &[
                "The rig file the session runs on (must be the scenario's rig)",
                "Directory for measurements.csv and session.toml",
            ],
        ),
        (&["plan", "--help"], &["The rig file", "Where to write the plan (CSV)"]),
        (
            &["compensate", "--help"],
            &["Output CSV: one row of joint commands (`q1_deg…`) per target, same order"],
        ),
        (&["rig", "from-urdf", "--help"], &["Output rig file"]),
        (&["--help"], &["More log output (-v info, -vv debug)"]),
    ] {
        let (ok, out, err) = rigcal(command);
        assert!(ok, "{err}");
        for w in wanted {
            assert!(out.contains(w), "{command:?}: no `{w}` in\n{out}");
        }
    }
}

#[test]
fn plan_prints_the_breakdown_and_the_compared_orders_and_procedures() {
    let dir = tempfile::tempdir().unwrap();
    let out_csv = dir.path().join("p.csv");
    let (ok, out, err) = rigcal(&[
        "plan",
        "--rig",
        "rigs/rv-m2.toml",
        "--points",
        "150",
        "--regions",
        "2",
        "--order",
        "z-then-xy",
        "--out",
        s(&out_csv),
    ]);
    assert!(ok, "{err}");
    for part in [
        "arm moves",
        "table moves",
        "clearance moves",
        "approaches",
        "settling",
        "drift references",
    ] {
        assert!(out.contains(part), "{part}: {out}");
    }
    // "estimated rig time A s … (z-then-xy order, rigcal procedure)", then the same points
    // compared: "z-then-xy order, baseline procedure R s (… h)  reference", "z-then-xy order,
    // rigcal procedure A s (… h)  saves P % (this plan)", P = 100 (1 − A / R) from the printed
    // figures, and the optimised order below A.
    let number_after = |text: &str, key: &str| -> f64 {
        let rest = &text[text.find(key).unwrap_or_else(|| panic!("{key}: {text}")) + key.len()..];
        let num: String = rest
            .trim_start()
            .chars()
            .take_while(|c| c.is_ascii_digit() || *c == '.' || *c == '-')
            .collect();
        num.parse().unwrap_or_else(|_| panic!("{key} {rest}"))
    };
    assert!(out.contains("(z-then-xy order, rigcal procedure)"), "{out}");
    let a = number_after(&out, "estimated rig time");
    let compared = &out[out
        .find("rig time of the same points")
        .expect("the comparison")..];
    let reference = number_after(compared, "z-then-xy order, baseline procedure");
    let b = number_after(compared, "z-then-xy order, rigcal procedure");
    assert_eq!(a, b, "{out}");
    let line = compared
        .lines()
        .find(|l| l.contains("z-then-xy order, rigcal procedure"))
        .unwrap();
    assert!(line.ends_with("(this plan)"), "{out}");
    let saving = number_after(line, "saves");
    assert!(
        (saving - 100.0 * (1.0 - a / reference)).abs() < 0.1,
        "{out}"
    );
    let optimised = number_after(compared, "optimised order, rigcal procedure");
    assert!(
        optimised < a && a < reference,
        "the optimised order is quicker: {out}"
    );
    let (ok, _, err) = rigcal(&[
        "plan",
        "--rig",
        "rigs/rv-m2.toml",
        "--points",
        "10",
        "--order",
        "fastest",
        "--out",
        s(&out_csv),
    ]);
    assert!(
        !ok && err.contains("z-then-xy, nearest-neighbour or optimised"),
        "{err}"
    );
    let (ok, _, err) = rigcal(&[
        "plan",
        "--rig",
        "rigs/rv-m2.toml",
        "--points",
        "10",
        "--procedure",
        "paper",
        "--out",
        s(&out_csv),
    ]);
    assert!(!ok && err.contains("baseline or rigcal"), "{err}");
}
