//! `rigcal diagnose` on hidden physics in and out of the library, from the generator of
//! `tests/common/shapes.rs` (issue 18, items 1–3): out-of-library shapes (a localised joint
//! dent, a cross-joint coupling, a harmonic above the library's orders, a local Cartesian
//! deformation) at visible sizes 1–5× the noise floor must claim no library effect, be described
//! as out of the library with the right variable, and be modelled by a discrepancy term that
//! improves the held-out fit; library effects (each kind, at their `tests/diagnose.rs` size, at
//! 1–5× and at 10× the floor) must be named exactly with no unexplained flag; nulls claim
//! nothing.
//!
//! CI runs a reduced set asserting the same properties; `rates` (ignored; `RIGCAL_RATE_SEEDS`,
//! default 20 per class and size, nulls 5× that per noise level) prints the full table and
//! asserts the targets, and the time of a 600-row diagnosis (median). Units: mm, degrees.

mod common;

use common::shapes::*;
use rigcal_model::diagnosis::{diagnose, Options, Report};
use std::time::Instant;

/// `kind:index` of each named effect, as `tests/diagnose.rs` names them.
fn names(r: &Report) -> Vec<String> {
    library_names(r)
}

fn run(c: &Case) -> Report {
    diagnose(&c.scenario.rig, &c.recording, &Options::default()).expect("diagnose")
}

/// The verdict on an out-of-library case.
#[derive(Debug, Default, Clone, Copy)]
struct Verdict {
    claimed: bool,
    described: bool,
    right_variable: bool,
    /// The shape's form is the hidden one (localised dent, periodic harmonic).
    right_form: bool,
    /// Held-out RMS with the discrepancy term ÷ without it.
    heldout_gain: Option<f64>,
}

/// Judges the report of an out-of-library case: the largest located shape must depend on the
/// hidden variable.
fn judge(c: &Case, r: &Report) -> Verdict {
    let main = r
        .out_of_library
        .iter()
        .max_by(|a, b| a.size_mm.total_cmp(&b.size_mm));
    let (right_variable, right_form) = match (c.truth, main) {
        (Truth::OwnAngle { joint, periodic }, Some(s)) => (
            s.depends_on == "own_joint_angle" && s.joint == Some(joint + 1),
            s.form == if periodic { "periodic" } else { "localised" },
        ),
        (Truth::OtherAngle { acted, driver }, Some(s)) => (
            s.depends_on == "other_joint_angle"
                && s.joint == Some(acted + 1)
                && s.driver_joint == Some(driver + 1),
            true,
        ),
        (Truth::Position { centre_mm }, Some(s)) => {
            let near = s
                .region
                .as_ref()
                .is_some_and(|g| (nalgebra::Vector3::from(g.centre_mm) - centre_mm).norm() < 150.0);
            (s.depends_on == "position", near)
        }
        _ => (false, false),
    };
    let heldout_gain = r
        .discrepancy
        .as_ref()
        .and_then(|d| Some(d.heldout_rms_with_mm? / d.heldout_rms_without_mm?));
    Verdict {
        claimed: !r.effects.is_empty(),
        described: r.unexplained && !r.out_of_library.is_empty(),
        right_variable,
        right_form,
        heldout_gain,
    }
}

/// Per-class counts.
#[derive(Debug, Default)]
struct Tally {
    n: usize,
    claimed: usize,
    described: usize,
    right_variable: usize,
    right_form: usize,
    gain_sum: f64,
    gains: usize,
}

impl Tally {
    fn add(&mut self, v: Verdict) {
        self.n += 1;
        self.claimed += usize::from(v.claimed);
        self.described += usize::from(v.described);
        self.right_variable += usize::from(v.right_variable);
        self.right_form += usize::from(v.right_form);
        if let Some(g) = v.heldout_gain {
            self.gain_sum += g;
            self.gains += 1;
        }
    }

    /// The targets of issue 18, item 3: no library effect claimed in ≥ 90 %, described as out
    /// of the library in ≥ 90 %, with the right variable in ≥ 80 %.
    fn meets_targets(&self) -> bool {
        let n = self.n as f64;
        (self.n - self.claimed) as f64 >= 0.9 * n
            && self.described as f64 >= 0.9 * n
            && self.right_variable as f64 >= 0.8 * n
    }

    fn line(&self, name: &str) -> String {
        format!(
            "| {name} | {}/{} | {}/{} | {}/{} | {}/{} | {:.2} |",
            self.n - self.claimed,
            self.n,
            self.described,
            self.n,
            self.right_variable,
            self.n,
            self.right_form,
            self.n,
            self.gain_sum / self.gains.max(1) as f64
        )
    }
}

/// Out-of-library cases of `class`, seeds `0..seeds`, visible sizes spread over 1–5× the floor.
fn out_of_library_tally(class: Class, seeds: u64) -> Tally {
    let mut t = Tally::default();
    for s in 0..seeds {
        let size = 1.0 + 4.0 * s as f64 / (seeds.max(2) - 1) as f64;
        let c = out_of_library(class, s, size);
        let r = run(&c);
        let v = judge(&c, &r);
        if v.claimed || !v.described || !v.right_variable {
            eprintln!("{} (size {size:.1}): {v:?}\n{}", c.label, r.text());
        }
        t.add(v);
    }
    t
}

/// In-library case `case` at `size` (None: its `tests/diagnose.rs` size), seeds `0..seeds`:
/// how many are named exactly, alone, with no unexplained flag.
fn in_library_count(case: &LibraryCase, size: Option<f64>, seeds: u64, first: u64) -> usize {
    let mut ok = 0;
    for s in first..first + seeds {
        let c = in_library(case, s, size);
        let r = run(&c);
        if names(&r) == vec![case.name.to_string()] && !r.unexplained {
            ok += 1;
        } else {
            eprintln!(
                "{} (visible {:.4} mm): {:?}\n{}",
                c.label,
                c.visible_mm,
                names(&r),
                r.text()
            );
        }
    }
    ok
}

/// Null recordings claiming something, of `n` at noise `noise_mm`.
fn null_claims(n: u64, noise_mm: f64) -> usize {
    (0..n)
        .filter(|&s| {
            let r = run(&null(s + (noise_mm * 1e4) as u64 * 1000, noise_mm));
            let claimed = r.mismatch.significant || !r.effects.is_empty() || r.unexplained;
            if claimed {
                eprintln!("null seed {s}, σ {noise_mm}:\n{}", r.text());
            }
            claimed
        })
        .count()
}

#[test]
fn out_of_library_shapes_are_described_not_named() {
    for class in Class::ALL {
        let t = out_of_library_tally(class, 3);
        eprintln!("{}", t.line(class.name()));
        assert_eq!(t.claimed, 0, "{}: {t:?}", class.name());
        assert_eq!(t.described, t.n, "{}: {t:?}", class.name());
        assert_eq!(t.right_variable, t.n, "{}: {t:?}", class.name());
        // The discrepancy term brings the held-out RMS well down (at 1–5× the floor the
        // named-effects-only held-out RMS is 1.4–5× the floor, with it about the floor).
        assert!(t.gains == t.n && t.gain_sum / (t.n as f64) < 0.75, "{t:?}");
    }
}

#[test]
fn a_located_shape_is_reported_with_where_and_its_size() {
    // A dent on one joint at 3× the floor: its report names the joint, says localised, gives
    // the interval around the dent's centre and a size near the hidden visible size.
    let c = out_of_library(Class::Dent, 1, 3.0);
    let r = run(&c);
    let Truth::OwnAngle { joint, .. } = c.truth else {
        panic!("a dent is on its own angle")
    };
    let s = &r.out_of_library[0];
    assert_eq!(
        (s.depends_on.as_str(), s.joint, s.form.as_str()),
        ("own_joint_angle", Some(joint + 1), "localised"),
        "{}",
        r.text()
    );
    let [a, b] = s.interval.expect("interval");
    assert!(
        b - a < 40.0 && s.interval_unit.as_deref() == Some("deg"),
        "{s:?}"
    );
    assert!(
        (s.size_mm / c.visible_mm - 1.0).abs() < 0.15,
        "{} vs {}",
        s.size_mm,
        c.visible_mm
    );
    assert!(
        s.size_sigma_mm > 0.0 && s.size_sigma_mm < 0.1 * s.size_mm,
        "{s:?}"
    );
    let text = r.text();
    assert!(
        text.contains("not in the library") && text.contains("discrepancy term"),
        "{text}"
    );
    // The JSON keeps `unexplained` a bool and adds the structured description.
    let v = serde_json::to_value(&r).expect("json");
    assert_eq!(v["unexplained"], true);
    assert_eq!(v["out_of_library"][0]["depends_on"], "own_joint_angle");
    assert_eq!(v["out_of_library"][0]["joint"], joint + 1);
    assert!(v["discrepancy"]["heldout_rms_with_mm"].as_f64().is_some());
    assert!(v["discrepancy"].get("model").is_none());
    // The fitted term reproduces what it fitted on the recording.
    let d = r.discrepancy.as_ref().expect("discrepancy");
    assert_eq!(d.model.shapes.len(), r.out_of_library.len());
}

#[test]
fn large_library_effects_are_named_alone_without_an_unexplained_flag() {
    for (k, case) in library_cases().iter().enumerate() {
        let ok = in_library_count(case, Some(10.0), 1, 100 + k as u64);
        assert_eq!(ok, 1, "{} at 10× the floor", case.name);
    }
}

#[test]
fn nulls_claim_nothing() {
    assert_eq!(null_claims(3, 0.01) + null_claims(3, 0.05), 0);
}

/// The full rate table (run with `--ignored --nocapture`, about 6 min on 2 cores at the default
/// 20 seeds): out-of-library classes, in-library kinds at three sizes, nulls, and the time of a
/// 600-row diagnosis.
#[test]
#[ignore]
fn rates() {
    let seeds: u64 = std::env::var("RIGCAL_RATE_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    let mut failures = Vec::new();
    eprintln!("| out-of-library class (1–5× the floor) | no library effect claimed | described as out of the library | right variable | right form | held-out RMS with ÷ without the discrepancy term |\n|---|---|---|---|---|---|");
    for class in Class::ALL {
        let t = out_of_library_tally(class, seeds);
        eprintln!("{}", t.line(class.name()));
        if !t.meets_targets() {
            failures.push(format!("{}: {t:?}", class.name()));
        }
    }
    eprintln!("| library effect | named exactly, nothing unexplained: tests/diagnose.rs size | 1–5× the floor | 10× the floor |\n|---|---|---|---|");
    for case in library_cases() {
        let natural = in_library_count(&case, None, seeds, 0);
        let mid: usize = (0..seeds)
            .map(|s| {
                let size = 1.0 + 4.0 * s as f64 / (seeds.max(2) - 1) as f64;
                in_library_count(&case, Some(size), 1, 1000 + s)
            })
            .sum();
        let large = in_library_count(&case, Some(10.0), seeds, 2000);
        eprintln!(
            "| {} | {natural}/{seeds} | {mid}/{seeds} | {large}/{seeds} |",
            case.name
        );
        for (what, k) in [("natural", natural), ("1–5×", mid), ("10×", large)] {
            if (k as f64) < 0.95 * seeds as f64 {
                failures.push(format!("{} {what}: {k}/{seeds}", case.name));
            }
        }
    }
    let n = 5 * seeds;
    let (a, b) = (null_claims(n, 0.01), null_claims(n, 0.05));
    eprintln!("nulls: something claimed in {a}/{n} at σ = 0.01 mm and {b}/{n} at σ = 0.05 mm");
    if (a + b) as f64 > 0.02 * (2 * n) as f64 {
        failures.push(format!("nulls: {a} + {b} of {}", 2 * n));
    }
    let mut times: Vec<f64> = (0..9)
        .map(|s| {
            let c = out_of_library(Class::Dent, 500 + s, 3.0);
            let t0 = Instant::now();
            let _ = run(&c);
            t0.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    let mut null_times: Vec<f64> = (0..9)
        .map(|s| {
            let c = null(600 + s, 0.02);
            let t0 = Instant::now();
            let _ = run(&c);
            t0.elapsed().as_secs_f64()
        })
        .collect();
    null_times.sort_by(f64::total_cmp);
    eprintln!(
        "a diagnosis of 600 rows: median {:.2} s with a dent at 3× the floor, {:.2} s on a null recording (9 runs each)",
        times[4], null_times[4]
    );
    assert!(failures.is_empty(), "{failures:#?}");
}
