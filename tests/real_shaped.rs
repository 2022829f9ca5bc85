//! `rigcal diagnose` on real-shaped recordings (issue 35, item 5): the generator of
//! `tests/common/shapes.rs` roughened by `tests/common/real_shaped.rs` — pose-dependent
//! repeatability, a smooth un-modelled residual at the noise floor, gross rows, few poses
//! (20–60), and held-out sessions with moved frames.
//!
//! Targets: a null names no library effect in ≥ 99 %; a library effect at 1–5× the floor is
//! named exactly (that effect and no other; the roughening's smooth residual may be reported
//! unexplained) in ≥ 95 %; an out-of-library shape names no library effect in ≥ 95 %.
//!
//! `rates` (ignored; `RIGCAL_RATE_SEEDS` seeds per library kind and out-of-library class,
//! default 20, nulls 5× that per realism class; `RIGCAL_REALISM=rough|few|sessions|few-no-gross`
//! runs one class; `RIGCAL_RATE_SEED_BASE` its first seed, default 5 000) prints the table of
//! docs/diagnosis.md;
//! `RIGCAL_RATE_DENT_LINES=1` also prints every comparison of a harmonic with a local dent
//! (`diagnosis::ambiguity`), passed or not;
//! `a_fast_subset_meets_the_targets` runs a few of each in CI. Seeds: the rates use 5 000 + s,
//! the fast subset 9 000 + s. `RISE_Z` was chosen on the sessions class at 5 000–5 019; that
//! class re-run from 6 000 (docs/diagnosis.md) gives the same figures. Units: mm.

mod common;

use common::real_shaped::{roughen_with, Realism};
use common::shapes::*;
use rigcal_core::rig::FrameMode;
use rigcal_model::diagnosis::{diagnose, Options, Report};

/// What a recording of a realism class was, and what the diagnosis said.
struct Outcome {
    /// The library names the report gives.
    named: Vec<String>,
    /// Kept effects a held-out session rose for (RMS with > without, however little): what the
    /// earlier rule (any rise refuses) would have refused.
    rose_on_a_session: usize,
    report: Report,
}

fn diagnose_case(mut c: Case, realism: Realism, seed: u64) -> Outcome {
    let sessions = realism.sessions(&c, seed);
    roughen_with(&mut c.recording, seed, realism.outliers());
    let mut rig = c.scenario.rig.clone();
    if !sessions.is_empty() {
        // An outside instrument whose frame moves between sessions is not registered: its
        // frame is fitted (the generator's rig fixes it, as a registered panel is).
        rig.calibration.measurement_frame = FrameMode::Free;
    }
    let report = diagnose(
        &rig,
        &c.recording,
        &Options {
            sessions,
            ..Default::default()
        },
    )
    .expect("diagnose");
    let rose_on_a_session = report
        .effects
        .iter()
        .filter(|e| {
            e.heldout_gain
                .as_ref()
                .and_then(|g| g.sessions_gain_mm)
                .is_some_and(|g| g < 0.0)
        })
        .count();
    Outcome {
        named: library_names(&report),
        rose_on_a_session,
        report,
    }
}

/// With `RIGCAL_RATE_DENT_LINES` set, prints every comparison of a harmonic with a local dent
/// in `o`'s report, kept or not, after `what`: what a threshold on it decides.
fn print_dent_lines(what: &str, o: &Outcome) {
    if std::env::var_os("RIGCAL_RATE_DENT_LINES").is_none() {
        return;
    }
    let r = &o.report;
    let lines = r.notes.iter().cloned().chain(
        r.below_evidence
            .iter()
            .map(|w| format!("{}: {}", w.label, w.reason)),
    );
    for l in lines.filter(|l| l.contains("local dent")) {
        eprintln!("dent-line {what}: {l}");
    }
}

/// A null recording of the class: names no library effect.
fn null_ok(realism: Realism, seed: u64) -> bool {
    let c = null_n(seed, NOISE_MM, realism.poses(seed));
    let o = diagnose_case(c, realism, seed);
    if !o.named.is_empty() {
        eprintln!(
            "{} null seed {seed}: {:?}\n{}",
            realism.name(),
            o.named,
            o.report.text()
        );
    }
    o.named.is_empty()
}

/// A library case at `size` × the floor: named exactly. Returns (ok, rose on a session).
fn library_ok(realism: Realism, case: &LibraryCase, seed: u64, size: f64) -> (bool, usize) {
    let c = in_library_n(case, seed, Some(size), realism.poses(seed));
    let label = c.label.clone();
    let o = diagnose_case(c, realism, seed);
    print_dent_lines(&format!("library {} seed {seed}", case.name), &o);
    let ok = o.named == vec![case.name.to_string()];
    if !ok {
        eprintln!(
            "{} {label} seed {seed} (×{size:.1} the floor): {:?}\n{}",
            realism.name(),
            o.named,
            o.report.text()
        );
    }
    (ok, o.rose_on_a_session)
}

/// An out-of-library case at `size` × the floor: names no library effect.
fn shape_ok(realism: Realism, class: Class, seed: u64, size: f64) -> bool {
    let c = out_of_library_n(class, seed, size, realism.poses(seed));
    let label = c.label.clone();
    let o = diagnose_case(c, realism, seed);
    print_dent_lines(&format!("shape {} seed {seed}", class.name()), &o);
    if !o.named.is_empty() {
        eprintln!(
            "{} {label} seed {seed}: {:?}\n{}",
            realism.name(),
            o.named,
            o.report.text()
        );
    }
    o.named.is_empty()
}

/// The out-of-library classes a realism class can carry: a deformation applied after
/// recording is not in the scenario's world, so held-out sessions could not show it.
fn shape_classes(realism: Realism) -> &'static [Class] {
    match realism {
        Realism::Sessions => &[Class::Dent, Class::Coupling, Class::Harmonic],
        _ => &Class::ALL,
    }
}

/// The size of seed `s` of `seeds`, spread over 1–5× the floor.
fn size_of(s: u64, seeds: u64) -> f64 {
    1.0 + 4.0 * s as f64 / (seeds.max(2) - 1) as f64
}

#[test]
fn a_fast_subset_meets_the_targets() {
    for realism in [Realism::Rough, Realism::Sessions] {
        for s in 0..2 {
            assert!(null_ok(realism, 9_000 + s), "{} null {s}", realism.name());
        }
    }
    for s in 0..4 {
        assert!(null_ok(Realism::FewPoses, 9_100 + s), "few-poses null {s}");
    }
    let cases = library_cases();
    for (k, name) in ["backlash:3", "transmission_error:1"].iter().enumerate() {
        let case = cases.iter().find(|c| c.name == *name).expect("case");
        for realism in [Realism::Rough, Realism::Sessions] {
            let (ok, _) = library_ok(realism, case, 9_200 + k as u64, 3.0);
            assert!(ok, "{} {name}", realism.name());
        }
    }
    for (k, class) in [Class::Dent, Class::Coupling].into_iter().enumerate() {
        for realism in [Realism::Rough, Realism::Sessions] {
            assert!(
                shape_ok(realism, class, 9_300 + k as u64, 3.0),
                "{} {}",
                realism.name(),
                class.name()
            );
        }
    }
}

/// The rate table of docs/diagnosis.md (run with `--ignored --nocapture`).
#[test]
#[ignore]
fn rates() {
    let seeds: u64 = std::env::var("RIGCAL_RATE_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    let mut failures = Vec::new();
    let mut rows = Vec::new();
    let only = std::env::var("RIGCAL_REALISM").ok();
    // The first seed: 5 000 for the table of docs/diagnosis.md; another base re-runs it on
    // seeds no constant was chosen on.
    let base: u64 = std::env::var("RIGCAL_RATE_SEED_BASE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(5_000);
    for realism in Realism::ALL {
        if only.as_deref().is_some_and(|k| k != realism.key()) {
            continue;
        }
        let nulls = 5 * seeds;
        let null_pass = (0..nulls).filter(|&s| null_ok(realism, base + s)).count() as u64;
        let (mut lib_pass, mut lib_n, mut rose) = (0u64, 0u64, 0usize);
        let mut per_kind = Vec::new();
        for case in library_cases() {
            let mut k_pass = 0;
            for s in 0..seeds {
                let (ok, r) = library_ok(realism, &case, base + s, size_of(s, seeds));
                k_pass += u64::from(ok);
                rose += r;
            }
            per_kind.push(format!("{} {k_pass}/{seeds}", case.name));
            lib_pass += k_pass;
            lib_n += seeds;
        }
        let (mut shape_pass, mut shape_n) = (0u64, 0u64);
        for &class in shape_classes(realism) {
            for s in 0..seeds {
                shape_pass += u64::from(shape_ok(realism, class, base + s, size_of(s, seeds)));
                shape_n += 1;
            }
        }
        let row = format!(
            "| {} | {null_pass}/{nulls} | {lib_pass}/{lib_n} ({}) | {shape_pass}/{shape_n} | {rose} |",
            realism.name(),
            per_kind.join(", ")
        );
        eprintln!("{row}");
        rows.push(row);
        if realism == Realism::FewPosesNoGross {
            continue;
        }
        if (null_pass as f64) < 0.99 * nulls as f64 {
            failures.push(format!("{} nulls {null_pass}/{nulls}", realism.name()));
        }
        if (lib_pass as f64) < 0.95 * lib_n as f64 {
            failures.push(format!("{} library {lib_pass}/{lib_n}", realism.name()));
        }
        if (shape_pass as f64) < 0.95 * shape_n as f64 {
            failures.push(format!("{} shapes {shape_pass}/{shape_n}", realism.name()));
        }
    }
    eprintln!("| recordings | nulls naming nothing | library effects at 1–5× the floor named exactly | out-of-library shapes naming no library effect | named effects a held-out session rose for |\n|---|---|---|---|---|");
    for r in &rows {
        eprintln!("{r}");
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Three gross rows (0.6 mm, 17× the floor) in a recording of 30 are 10 % of it, past the 5 %
/// the outlier search removes on suspicion: they are gross beyond doubt (far past the robust
/// scale), so they are removed and named, and an effect at 3× the floor is named exactly.
/// Seeds 7 001 and 7 006 (30 poses each), not among the rate table's.
#[test]
fn three_gross_rows_of_thirty_are_removed_and_an_effect_at_three_floors_named() {
    let cases = library_cases();
    for (seed, name) in [(7_001, "backlash:3"), (7_006, "table_scale:x")] {
        let case = cases.iter().find(|c| c.name == name).expect("case");
        let c = in_library_n(case, seed, Some(3.0), Realism::FewPoses.poses(seed));
        assert_eq!(c.recording.rows.len(), 30);
        let o = diagnose_case(c, Realism::FewPoses, seed);
        // Two or three: a gross row the fit partly follows can stay under the gate, and two
        // of the three draws may fall on one row.
        assert!(
            o.report.outliers.len() >= 2,
            "seed {seed}: {}",
            o.report.text()
        );
        assert!(
            !o.report
                .notes
                .iter()
                .any(|n| n.contains("outliers not removed")),
            "seed {seed}: {}",
            o.report.text()
        );
        assert_eq!(o.named, vec![name.to_string()], "{}", o.report.text());
    }
}

/// A warm-up drift at 3× the floor in recordings of 30–60 rows is named exactly: it is judged
/// on folds interleaved in time (`crossval::interleaved_folds`), so each held-out fold is
/// predicted inside the session's span instead of a third of the warm-up being extrapolated.
/// Beside it, nulls of the same sizes (same seeds) claim nothing. Seeds 7 501–7 504 (30, 40,
/// 50, 60 rows), fixed before the test was first run, with its pass count (7 of the 8 drift
/// cases at least: the 95 % target allows one miss in twenty, not none in eight).
#[test]
fn a_drift_at_three_floors_in_few_rows_is_named_on_time_interleaved_folds() {
    let cases = library_cases();
    let mut named = 0;
    let mut report = String::new();
    for name in ["thermal_drift:z", "thermal_drift:2"] {
        let case = cases.iter().find(|c| c.name == name).expect("case");
        for seed in 7_501..=7_504 {
            let c = in_library_n(case, seed, Some(3.0), Realism::FewPoses.poses(seed));
            assert!((30..=60).contains(&c.recording.rows.len()));
            let o = diagnose_case(c, Realism::FewPoses, seed);
            if o.named == vec![name.to_string()] {
                named += 1;
                let g = o.report.effects[0].heldout_gain.as_ref().expect("gain");
                assert!(g.interleaved, "{}", o.report.text());
            } else {
                report.push_str(&format!("{name} seed {seed}: {}\n", o.report.text()));
            }
        }
    }
    assert!(named >= 7, "{named}/8 named:\n{report}");
    for seed in 7_501..=7_504 {
        assert!(null_ok(Realism::FewPoses, seed), "null seed {seed}");
    }
}

/// A local dent of one joint (5–8 % of its range wide) in 20–60 poses is not named as that
/// joint's transmission error: the harmonic must predict held-out blocks better than the best
/// local dent of the joint's angle by 2 σ (`diagnosis::ambiguity`), and when it does not the
/// report says "a harmonic or a local dent, this recording cannot tell" or reports the shape
/// as unexplained structure outside the library. Seeds 7 006, 7 008, 7 010, 7 017 and 7 019 at their
/// rate-table sizes: the five dents of the tuning seeds (7 000–7 019, not reported) that the
/// rule before this one named as transmission errors. Beside them, nulls claim nothing.
#[test]
fn a_local_dent_in_few_poses_is_not_named_as_a_transmission_error() {
    for seed in [7_006u64, 7_008, 7_010, 7_017, 7_019] {
        let size = size_of(seed - 7_000, 20);
        let c = out_of_library_n(Class::Dent, seed, size, Realism::FewPoses.poses(seed));
        let o = diagnose_case(c, Realism::FewPoses, seed);
        assert!(o.named.is_empty(), "seed {seed}: {}", o.report.text());
        let r = &o.report;
        let said = r.unexplained
            || !r.out_of_library.is_empty()
            || r.below_evidence
                .iter()
                .any(|w| w.reason.contains("this recording cannot tell"));
        assert!(
            said,
            "seed {seed}: neither the shape nor \"cannot tell\": {}",
            r.text()
        );
        assert!(null_ok(Realism::FewPoses, seed), "null seed {seed}");
    }
}
