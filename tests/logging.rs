//! Logs redirected to a file carry no terminal escape codes (a user greps them, a CI job
//! stores them).

use std::process::Command;

fn rigcal(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(args)
        .output()
        .expect("rigcal runs")
}

#[test]
fn debug_logs_to_a_pipe_are_plain_text() {
    let dir = std::env::temp_dir().join(format!("rigcal-logging-{}", std::process::id()));
    let rec = dir.join("rec");
    let rec = rec.to_str().expect("utf-8 path");
    let sim = rigcal(&[
        "simulate",
        "--rig",
        "rigs/rv-m2-ideal.toml",
        "--scenario",
        "sim/paper-sim-noise.toml",
        "--random",
        "300",
        "--out",
        rec,
    ]);
    assert!(
        sim.status.success(),
        "{}",
        String::from_utf8_lossy(&sim.stderr)
    );
    let out = rigcal(&[
        "diagnose",
        "-vv",
        "--rig",
        "rigs/rv-m2-ideal.toml",
        "--recording",
        rec,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let log = String::from_utf8_lossy(&out.stderr);
    // The diagnosis logs its shape choices at debug level: the test sees real log lines.
    assert!(log.contains("DEBUG"), "no debug lines: {log}");
    assert!(
        !log.contains('\u{1b}'),
        "escape codes in a piped log: {log:?}"
    );
}
