//! A touched panel keeps reporting the touch for its latency after the pin lifts (the emulated
//! PenMount as the real one: each sample leaves a latency after it is taken). With a back-off
//! quicker than that latency, packets of the locating touch are still on their way when the
//! final approach begins; one taken for the final touch would give the locating touch's (u, v)
//! and a height read at the final approach's start. The session waits for the release packet
//! after the back-off (the pin seen lifted), so every final touch is the final contact's own.

use std::path::Path;
use std::process::Command;

/// `rigs/rv-m2.toml` with `key = value` lines replaced.
fn rig_with(dir: &Path, keys: &[(&str, &str)]) -> std::path::PathBuf {
    let mut lines: Vec<String> = std::fs::read_to_string("rigs/rv-m2.toml")
        .expect("rigs/rv-m2.toml")
        .lines()
        .map(String::from)
        .collect();
    for (key, value) in keys {
        let at = lines
            .iter()
            .position(|l| l.split('=').next().is_some_and(|k| k.trim() == *key))
            .unwrap_or_else(|| panic!("no `{key}` in rigs/rv-m2.toml"));
        lines[at] = format!("{key} = {value}");
    }
    let path = dir.join("rig.toml");
    std::fs::write(&path, lines.join("\n")).unwrap();
    path
}

#[test]
fn a_late_packet_of_the_locating_touch_is_never_taken_for_the_final_touch() {
    let dir = tempfile::tempdir().unwrap();
    // A back-off of about a millisecond (very fast drives), the back-off at the standoff
    // (2 × 5 mm/s × 22 ms = 0.22 mm) and 20 ms of panel latency: a dozen packets of the locating
    // touch arrive after the table has left the pin.
    let rig = rig_with(
        dir.path(),
        &[
            ("profile_velocity_mm_s", "10000.0"),
            ("profile_acceleration_mm_s2", "1000000.0"),
            ("profile_deceleration_mm_s2", "1000000.0"),
            ("latency_ms", "20.0"),
            ("sim_report_ms", "2.0"),
            ("backoff_mm", "0.22"),
        ],
    );
    // The nominal world, no scatter: the pin is never on the panel at an approach's start, so
    // every contact succeeds at its first attempt unless a stale packet is taken.
    let scenario = dir.path().join("scenario.toml");
    std::fs::write(
        &scenario,
        format!(
            "description = \"nominal\"\nseed = 5\nrig = \"{}\"\n[measurement]\nnoise_mm = 0.0\narm_repeatability_mm = 0.0\ntable_accuracy_mm = 0.0\nquantise = true\n",
            rig.display()
        ),
    )
    .unwrap();
    let out = dir.path().join("session");
    let run = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(["session", "--seed", "3", "--points", "10", "--rig"])
        .arg(&rig)
        .arg("--sim")
        .arg(&scenario)
        .arg("--out")
        .arg(&out)
        .output()
        .expect("run rigcal session");
    let stdout = String::from_utf8_lossy(&run.stdout);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stdout}\n{stderr}");
    let summary = stdout
        .lines()
        .find(|l| l.starts_with("session "))
        .unwrap_or_else(|| panic!("no summary line in {stdout}"));
    assert!(
        summary.contains("11 measured, 0 skipped") && summary.contains(" 0 retries"),
        "every contact at its first attempt, none refused for a stale touch: {summary}\n{stderr}"
    );
    // A stale touch is read at the final approach's start (the pin a standoff, 0.22 mm, above
    // it) and refused as "final touch at its start": each one would show as a retry above.
    let mut r = csv::Reader::from_path(out.join("measurements.csv")).unwrap();
    let status = r
        .headers()
        .unwrap()
        .iter()
        .position(|h| h == "status")
        .unwrap();
    let ok = r
        .records()
        .filter(|rec| rec.as_ref().unwrap().get(status) == Some("ok"))
        .count();
    assert_eq!(ok, 11);
}
