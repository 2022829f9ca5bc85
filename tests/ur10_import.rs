//! Real files as they come: the UR10 laser-tracker series (tests/data/ur10-landgraf/, a
//! byte-for-byte subset of the upstream files, provenance there) import with the ordinary
//! options — `;` separators, decimal commas, CRLF and Series A's missing final line end
//! detected and accepted; orientation (intrinsic X-Y-Z Euler angles in degrees), the tracker's
//! standard deviations and the temperature kept; Series A's timestamps kept and B–D's (a
//! spreadsheet's `2,02011E+13` in every row) reported as lost. A recording on the wrong scale
//! (metres read as millimetres, radians as degrees, millimetres as metres) is refused with the
//! likely cause.
//!
//! The expected values are read from the files here with a few lines of text handling and
//! nalgebra, not through rigcal's importer.

use nalgebra::{UnitQuaternion, Vector3};
use rigcal_core::recording::Recording;
use rigcal_core::rig::Rig;
use std::path::Path;
use std::process::{Command, Output};

mod common;
use common::ur10::{rig as ur10_rig, DATA};

const JOINTS: &str =
    "shoulder_pan_joint,shoulder_lift_joint,elbow_joint,wrist_1_joint,wrist_2_joint,wrist_3_joint";
const SERIES: [&str; 4] = [
    "Series_A/measurements_grid.csv",
    "Series_B/measurements_joint_configurations.csv",
    "Series_C/measurements_random_poses.csv",
    "Series_D/measurements_iso_cubes.csv",
];

fn rigcal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(args)
        .output()
        .unwrap()
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// `rigcal import FILE --rig RIG --joints … ARGS --out DIR`.
fn import(file: &Path, rig: &Path, out: &Path, args: &[&str]) -> Output {
    let mut all = vec![
        "import",
        file.to_str().unwrap(),
        "--rig",
        rig.to_str().unwrap(),
        "--joints",
        JOINTS,
        "--out",
        out.to_str().unwrap(),
    ];
    all.extend_from_slice(args);
    rigcal(&all)
}

const MEASURED: [&str; 2] = ["--point", "measurement_x,measurement_y,measurement_z"];

/// The ordinary options for a series: tracker millimetres, joint radians, orientation in
/// degrees, temperature and time by name, the standard deviations where the series has them.
fn ordinary(with_sigma: bool) -> Vec<&'static str> {
    let mut a = vec![
        MEASURED[0],
        MEASURED[1],
        "--length-unit",
        "mm",
        "--angle-unit",
        "rad",
        "--time",
        "Timestamp",
        "--temperature",
        "measurement_temperature",
        "--orientation",
        "measurement_rx,measurement_ry,measurement_rz",
        "--euler",
        "intrinsic-xyz",
        "--orientation-unit",
        "deg",
    ];
    if with_sigma {
        a.extend([
            "--point-sigma",
            "measurement_std_x,measurement_std_y,measurement_std_z",
            "--orientation-sigma",
            "measurement_std_rx,measurement_std_ry,measurement_std_rz",
        ]);
    }
    a
}

/// The file's header and rows split by hand: `;` separators, decimal commas, CRLF.
fn rows_by_hand(file: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let bytes = std::fs::read(file).unwrap();
    let t = String::from_utf8(bytes).unwrap();
    let mut lines = t.split("\r\n").filter(|l| !l.is_empty());
    let header = lines.next().unwrap().split(';').map(String::from).collect();
    let rows = lines
        .map(|l| l.split(';').map(|c| c.replace(',', ".")).collect())
        .collect();
    (header, rows)
}

fn cell(header: &[String], row: &[String], name: &str) -> f64 {
    let k = header.iter().position(|h| h == name).unwrap();
    row[k].parse().unwrap()
}

#[test]
fn the_subset_keeps_the_upstream_quirks() {
    // What the importer must cope with is really in the committed files.
    for s in SERIES {
        let bytes = std::fs::read(Path::new(DATA).join(s)).unwrap();
        let t = String::from_utf8(bytes.clone()).unwrap();
        assert!(
            t.contains(";0,") || t.contains(";-0,"),
            "{s}: decimal commas"
        );
        assert_eq!(
            t.matches('\n').count(),
            t.matches("\r\n").count(),
            "{s}: CRLF only"
        );
        assert_eq!(
            bytes.ends_with(b"\r\n"),
            !s.starts_with("Series_A"),
            "{s}: only A lacks a final line end"
        );
    }
}

#[test]
fn each_series_imports_with_the_ordinary_options() {
    let dir = tempfile::tempdir().unwrap();
    let rig_path = ur10_rig(dir.path());
    let rig = Rig::load(&rig_path).unwrap();
    for s in SERIES {
        let file = Path::new(DATA).join(s);
        let a = s.starts_with("Series_A");
        let out = dir.path().join(&s[..8]);
        let o = import(&file, &rig_path, &out, &ordinary(!a));
        assert!(o.status.success(), "{s}: {}", text(&o));
        assert!(
            text(&o).contains("read with `;` separators, decimal comma"),
            "{}",
            text(&o)
        );
        let rec = Recording::read(&out, rig.chain_joints()).unwrap();
        let (header, rows) = rows_by_hand(&file);
        assert_eq!(rec.rows.len(), rows.len(), "{s}");
        assert_eq!(rec.rows.len(), 99, "{s}");
        for (m, row) in rec.rows.iter().zip(&rows) {
            // Joints (rad), written in degrees to 1e-6.
            for (k, name) in JOINTS.split(',').enumerate() {
                let v = cell(&header, row, name);
                assert!((m.q[k] - v).abs() < 1e-7, "{s} {name}: {} vs {v}", m.q[k]);
            }
            let p = Vector3::new(
                cell(&header, row, "measurement_x"),
                cell(&header, row, "measurement_y"),
                cell(&header, row, "measurement_z"),
            );
            assert!((m.position.unwrap() - p).norm() < 1e-4, "{s}");
            let t = cell(&header, row, "measurement_temperature");
            assert!((m.temp_c.unwrap() - t).abs() < 1e-9, "{s}");
            // Intrinsic X-Y-Z: R = Rx(rx)·Ry(ry)·Rz(rz), built here independently.
            let [rx, ry, rz] = ["measurement_rx", "measurement_ry", "measurement_rz"]
                .map(|n| cell(&header, row, n).to_radians());
            let want = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), rx)
                * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), ry)
                * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), rz);
            let got = m.orientation.expect("orientation kept");
            assert!(got.angle_to(&want) < 1e-7, "{s}: {}", got.angle_to(&want));
            if !a {
                let sp = Vector3::new(
                    cell(&header, row, "measurement_std_x"),
                    cell(&header, row, "measurement_std_y"),
                    cell(&header, row, "measurement_std_z"),
                );
                assert!((m.position_sigma.unwrap() - sp).norm() < 1e-7, "{s}");
                // σ of a small rotation about the probe frame's own axes: for R = Rx(a)·Ry(b)·Rz(c)
                // the body angular velocity is Rz(c)ᵀRy(b)ᵀ·x ȧ + Rz(c)ᵀ·y ḃ + z ċ.
                let sig = [
                    "measurement_std_rx",
                    "measurement_std_ry",
                    "measurement_std_rz",
                ]
                .map(|n| cell(&header, row, n).to_radians());
                let rot = |axis: nalgebra::Unit<Vector3<f64>>, v: f64| {
                    nalgebra::Rotation3::from_axis_angle(&axis, v)
                };
                let cols = [
                    (rot(Vector3::y_axis(), ry) * rot(Vector3::z_axis(), rz)).inverse()
                        * Vector3::x(),
                    rot(Vector3::z_axis(), rz).inverse() * Vector3::y(),
                    Vector3::z(),
                ];
                let want = Vector3::from_fn(|k, _| {
                    (0..3)
                        .map(|j| (cols[j][k] * sig[j]).powi(2))
                        .sum::<f64>()
                        .sqrt()
                });
                let so = m.orientation_sigma.expect("orientation σ kept");
                assert!((so - want).norm() < 1e-9, "{s}: {so} vs {want}");
            } else {
                assert_eq!(m.position_sigma, None);
            }
        }
        let info = rec.session.unwrap();
        let import = info.import.expect("[import] in session.toml");
        assert_eq!(
            (import.separator.as_str(), import.decimal.as_str()),
            (";", "comma")
        );
        if a {
            // A keeps its times: seconds from the earliest row (16:39:04 on 14 July).
            assert_eq!(import.time, "kept");
            assert_eq!(info.start_time.as_deref(), Some("2020-07-14T16:39:04"));
            assert_eq!(rec.rows[0].t_s, Some(0.0));
            assert_eq!(rec.rows[1].t_s, Some(20.0));
            // The last rows are re-measurements with earlier times, kept as they are.
            let last = rec.rows.last().unwrap().t_s.unwrap();
            assert!(last < rec.rows[80].t_s.unwrap(), "{last}");
            assert!(!text(&o).contains("warning"), "{}", text(&o));
        } else {
            // B–D: the spreadsheet's constant is not handed on as a time.
            assert_eq!(import.time, "lost", "{s}");
            assert!(import.time_lost());
            assert!(
                import.time_note.unwrap().contains("2,02"),
                "the note quotes the cell"
            );
            assert!(rec.rows.iter().all(|m| m.t_s.is_none()), "{s}");
            assert!(text(&o).contains("warning: times lost"), "{}", text(&o));
        }
    }
}

#[test]
fn a_byte_order_mark_and_a_forced_dialect_are_accepted_and_a_wrong_one_explained() {
    let dir = tempfile::tempdir().unwrap();
    let rig = ur10_rig(dir.path());
    let mut bytes = b"\xEF\xBB\xBF".to_vec();
    bytes.extend(std::fs::read(Path::new(DATA).join(SERIES[3])).unwrap());
    let bom = dir.path().join("bom.csv");
    std::fs::write(&bom, bytes).unwrap();
    let o = import(&bom, &rig, &dir.path().join("bom"), &ordinary(true));
    assert!(o.status.success(), "{}", text(&o));
    let file = Path::new(DATA).join(SERIES[2]);
    let mut forced = ordinary(true);
    forced.extend(["--dialect", "semicolon-decimal-comma"]);
    let o = import(&file, &rig, &dir.path().join("forced"), &forced);
    assert!(o.status.success(), "{}", text(&o));
    // Read as commas, the header is one column: the error shows it and how it was split.
    let mut wrong = ordinary(true);
    wrong.extend(["--dialect", "comma"]);
    let o = import(&file, &rig, &dir.path().join("wrong"), &wrong);
    assert!(!o.status.success());
    assert!(
        text(&o).contains("read with `,` separators, decimal point; the file's 1 columns"),
        "{}",
        text(&o)
    );
}

#[test]
fn a_missing_column_names_the_closest_and_lists_the_columns() {
    let dir = tempfile::tempdir().unwrap();
    let rig = ur10_rig(dir.path());
    let file = Path::new(DATA).join(SERIES[1]);
    let o = import(
        &file,
        &rig,
        &dir.path().join("r"),
        &[
            "--point",
            "measurement_x,measurement_y,measurment_z",
            "--length-unit",
            "mm",
        ],
    );
    assert!(!o.status.success());
    let t = text(&o);
    assert!(
        t.contains("no column `measurment_z`; did you mean `measurement_z`?"),
        "{t}"
    );
    assert!(
        t.contains("the file's 26 columns are `Timestamp`, `Goal x`"),
        "{t}"
    );
}

#[test]
fn metres_read_as_millimetres_are_refused_with_the_hint() {
    let dir = tempfile::tempdir().unwrap();
    let rig = ur10_rig(dir.path());
    // The commanded TCP (`Goal x/y/z`) is in metres.
    let file = Path::new(DATA).join(SERIES[2]);
    let out = dir.path().join("r");
    let o = import(
        &file,
        &rig,
        &out,
        &["--point", "Goal x,Goal y,Goal z", "--length-unit", "mm"],
    );
    assert!(!o.status.success(), "{}", text(&o));
    let t = text(&o);
    assert!(
        t.contains("metres read as millimetres: use --length-unit m"),
        "{t}"
    );
    assert!(!out.exists(), "nothing written");
    // Read as metres, they import.
    let o = import(
        &file,
        &rig,
        &out,
        &["--point", "Goal x,Goal y,Goal z", "--length-unit", "m"],
    );
    assert!(o.status.success(), "{}", text(&o));
    // The tracker's millimetres read as metres put the marker kilometres away.
    let o = import(
        &file,
        &rig,
        &dir.path().join("km"),
        &[MEASURED[0], MEASURED[1], "--length-unit", "m"],
    );
    assert!(!o.status.success());
    let t = text(&o);
    assert!(t.contains("km from the instrument's origin"), "{t}");
    assert!(t.contains("use --length-unit mm"), "{t}");
}

#[test]
fn radians_read_as_degrees_are_refused_with_the_hint() {
    let dir = tempfile::tempdir().unwrap();
    let rig = ur10_rig(dir.path());
    let file = Path::new(DATA).join(SERIES[0]);
    let out = dir.path().join("r");
    let args = [
        MEASURED[0],
        MEASURED[1],
        "--length-unit",
        "mm",
        "--angle-unit",
        "deg",
    ];
    let o = import(&file, &rig, &out, &args);
    assert!(!o.status.success(), "{}", text(&o));
    let t = text(&o);
    assert!(
        t.contains("joint angles look like radians read as degrees: use --angle-unit rad"),
        "{t}"
    );
    assert!(!out.exists());
    // The check can be left out on purpose.
    let mut forced = args.to_vec();
    forced.push("--no-scale-check");
    assert!(import(&file, &rig, &out, &forced).status.success());
    // Orientation angles in degrees read as radians.
    let o = import(
        &file,
        &rig,
        &dir.path().join("o"),
        &[
            MEASURED[0],
            MEASURED[1],
            "--length-unit",
            "mm",
            "--orientation",
            "measurement_rx,measurement_ry,measurement_rz",
            "--euler",
            "intrinsic-xyz",
        ],
    );
    assert!(!o.status.success());
    assert!(
        text(&o).contains("use --orientation-unit deg"),
        "{}",
        text(&o)
    );
}

/// `Rig::chain`'s joints, in order.
trait ChainJoints {
    fn chain_joints(&self) -> &[rigcal_core::kinematics::JointSpec];
}

impl ChainJoints for Rig {
    fn chain_joints(&self) -> &[rigcal_core::kinematics::JointSpec] {
        use rigcal_core::kinematics::Robot;
        self.chain.joints()
    }
}
