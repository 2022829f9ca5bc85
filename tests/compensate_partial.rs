//! `rigcal compensate` with a target out of reach (issue "Never silently wrong, never unsafe",
//! point 6): by default the reachable targets are written, each row with a `status`, the
//! unreachable one kept in its place with empty commands, and the exit status 3 says the result
//! is partial; `--strict` writes nothing and fails. The plain geometric path and the hybrid one
//! (`--approach consistent`) behave alike.

use std::path::Path;
use std::process::Command;

/// Runs `rigcal`: exit code, stdout, stderr.
fn rigcal(args: &[&str]) -> (Option<i32>, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(args)
        .output()
        .expect("run rigcal");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A model identified from a short simulated session.
fn model(dir: &Path) -> std::path::PathBuf {
    let rec = dir.join("recording");
    let (code, _, err) = rigcal(&[
        "session",
        "--rig",
        "rigs/rv-m2-ideal.toml",
        "--sim",
        "sim/paper-sim-noise.toml",
        "--points",
        "100",
        "--out",
        s(&rec),
    ]);
    assert_eq!(code, Some(0), "{err}");
    let model = dir.join("m.json");
    let (code, _, err) = rigcal(&[
        "identify",
        "--rig",
        "rigs/rv-m2-ideal.toml",
        "--recording",
        s(&rec),
        "--out",
        s(&model),
    ]);
    assert_eq!(code, Some(0), "{err}");
    model
}

/// `rigcal compensate` of `targets` into `out` with `extra` arguments.
fn compensate(
    model: &Path,
    targets: &Path,
    out: &Path,
    extra: &[&str],
) -> (Option<i32>, String, String) {
    let mut args = vec![
        "compensate",
        "--model",
        s(model),
        "--targets",
        s(targets),
        "--out",
        s(out),
    ];
    args.extend_from_slice(extra);
    rigcal(&args)
}

#[test]
fn an_unreachable_target_leaves_the_others_written_with_statuses_unless_strict() {
    let dir = tempfile::tempdir().unwrap();
    let model = model(dir.path());
    let targets = dir.path().join("targets.csv");
    std::fs::write(
        &targets,
        "x_mm,y_mm,z_mm\n0,600,500\n0,2000,400\n100,550,450\n",
    )
    .unwrap();

    // Plain geometric path: three rows in the targets' order, the second empty.
    let cmds = dir.path().join("cmds.csv");
    let (code, out, err) = compensate(&model, &targets, &cmds, &[]);
    assert_eq!(code, Some(3), "{out}\n{err}");
    assert!(
        out.contains("2 of 3 targets compensated") && out.contains("1 not reachable"),
        "{out}"
    );
    assert!(
        err.contains("1 of 3 targets not compensated")
            && err.contains("targets.csv: line 3")
            && err.contains("out of reach"),
        "{err}"
    );
    let text = std::fs::read_to_string(&cmds).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(
        lines[0], "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,status",
        "{text}"
    );
    assert_eq!(lines.len(), 4, "{text}");
    assert!(
        lines[1].ends_with(",ok") && lines[3].ends_with(",ok"),
        "{text}"
    );
    assert!(
        lines[2].starts_with(",,,,,unreachable: "),
        "the unreachable target keeps its row with empty commands: {text}"
    );
    // The reachable rows are the commands a file of those targets alone gets.
    let alone = dir.path().join("alone.csv");
    std::fs::write(&alone, "x_mm,y_mm,z_mm\n0,600,500\n").unwrap();
    let alone_cmds = dir.path().join("alone-cmds.csv");
    let (code, _, err) = compensate(&model, &alone, &alone_cmds, &[]);
    assert_eq!(code, Some(0), "{err}");
    let alone_text = std::fs::read_to_string(&alone_cmds).unwrap();
    assert_eq!(
        alone_text
            .lines()
            .nth(1)
            .map(|l| format!("{l},ok"))
            .as_deref(),
        Some(lines[1])
    );
    // A reader of the joints (the targets reader) refuses the empty row rather than moving.
    let q1: Vec<Option<f64>> = lines[1..]
        .iter()
        .map(|l| l.split(',').next().unwrap().parse().ok())
        .collect();
    assert!(
        q1[0].is_some() && q1[1].is_none() && q1[2].is_some(),
        "{q1:?}"
    );

    // Hybrid path: the via and target rows of the reachable targets, one row for the other.
    let hybrid = dir.path().join("hybrid.csv");
    let (code, out, err) = compensate(&model, &targets, &hybrid, &["--approach", "consistent"]);
    assert_eq!(code, Some(3), "{out}\n{err}");
    assert!(err.contains("targets.csv: line 3"), "{err}");
    let text = std::fs::read_to_string(&hybrid).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(
        lines[0], "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,move,status",
        "{text}"
    );
    assert_eq!(lines.len(), 1 + 2 + 1 + 2, "{text}");
    assert!(
        lines[1].ends_with(",via,ok") && lines[2].ends_with(",target,ok"),
        "{text}"
    );
    assert!(lines[3].starts_with(",,,,,target,unreachable: "), "{text}");
    assert!(
        lines[4].ends_with(",via,ok") && lines[5].ends_with(",target,ok"),
        "{text}"
    );

    // --strict: nothing written, the first failure named, exit status 1.
    for extra in [&["--strict"][..], &["--strict", "--approach", "consistent"]] {
        let strict = dir.path().join("strict.csv");
        let (code, _, err) = compensate(&model, &targets, &strict, extra);
        assert_eq!(code, Some(1), "{extra:?}: {err}");
        assert!(
            err.contains("targets.csv: line 3") && err.contains("out of reach"),
            "{err}"
        );
        assert!(!strict.exists(), "{extra:?}: --strict wrote a file");
    }
}

#[test]
fn help_says_the_exit_status_of_a_partial_result() {
    let (code, out, _) = rigcal(&["compensate", "--help"]);
    assert_eq!(code, Some(0));
    assert!(
        out.contains("--strict") && out.contains("3 when some are not"),
        "{out}"
    );
}
