//! The variable D-H parameter model on seed 000's simulation scenario, through the command line
//! a user runs: `rigcal calibrate` (planning mode against `sim/paper-sim.toml`) then
//! `rigcal evaluate` along the paper's paths; and the same pipeline as library calls.

use std::collections::HashMap;
use std::process::Command;

fn rigcal(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_rigcal"))
        .args(args)
        .output()
        .expect("run rigcal");
    assert!(
        out.status.success(),
        "rigcal {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Per path name, per model: (mean, max, failures, CEP jumps).
type Table = HashMap<String, HashMap<String, (f64, f64, usize, Vec<f64>)>>;

fn parse(out: &str) -> Table {
    let mut t = Table::new();
    let mut path = String::new();
    for line in out.lines() {
        if !line.starts_with(' ') && line.contains("points)") {
            path = line.split(" (").next().unwrap().to_string();
            continue;
        }
        let f: Vec<&str> = line.split_whitespace().collect();
        if f.len() >= 4
            && ["uncalibrated", "conventional", "regions", "fcmac", "cmac"].contains(&f[0])
        {
            let jumps = f[4..].iter().map(|v| v.parse().unwrap()).collect();
            t.entry(path.clone()).or_default().insert(
                f[0].to_string(),
                (
                    f[1].parse().unwrap(),
                    f[2].parse().unwrap(),
                    f[3].parse().unwrap(),
                    jumps,
                ),
            );
        }
    }
    t
}

fn calibrate_and_evaluate(extra: &[&str], paths: &[&str]) -> (String, Table) {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("m.json");
    let m = model.to_str().unwrap();
    let mut args = vec![
        "calibrate",
        "--rig",
        "rigs/rv-m2-ideal.toml",
        "--scenario",
        "sim/paper-sim.toml",
        "--out",
        m,
    ];
    args.extend_from_slice(extra);
    let summary = rigcal(&args);
    let mut eval = vec![
        "evaluate",
        "--model",
        m,
        "--scenario",
        "sim/paper-sim.toml",
        "--random-paths",
        "3",
    ];
    for p in paths {
        eval.extend_from_slice(&["--path", p]);
    }
    (summary, parse(&rigcal(&eval)))
}

#[test]
fn paper_settings_meet_the_papers_accuracy_on_every_path() {
    let (summary, t) = calibrate_and_evaluate(&[], &["fig6", "fig7", "random"]);
    assert!(
        summary.contains("paper: 110 regions, 2200 measurements"),
        "{summary}"
    );
    let fig6 = &t["Fig. 6 joint path"];
    let (_, uncal_max, _, _) = fig6["uncalibrated"];
    assert!(
        (0.4..=1.2).contains(&uncal_max),
        "uncalibrated max {uncal_max}"
    );
    assert_eq!(t.len(), 5, "{t:?}");
    for (path, models) in &t {
        let conv = models["conventional"].1;
        assert!(conv < 0.2, "{path}: conventional max {conv}");
        for m in ["regions", "fcmac"] {
            let (_, max, failures, _) = models[m];
            assert!(
                max < 0.1 && failures == 0,
                "{path}: {m} max {max}, {failures} failures"
            );
            assert!(
                max <= conv + 1e-4,
                "{path}: {m} ({max}) worse than conventional ({conv})"
            );
        }
    }
}

#[test]
fn a_finer_demand_divides_and_the_fcmac_is_smoother_than_regions_and_cmac() {
    let (summary, fcmac) = calibrate_and_evaluate(&["--accuracy-mm", "0.02"], &["fig6", "fig7"]);
    let regions: usize = summary
        .split("regions ")
        .nth(1)
        .unwrap()
        .split_whitespace()
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(regions > 5, "{summary}");
    let (_, cmac) = calibrate_and_evaluate(
        &["--accuracy-mm", "0.02", "--learner", "cmac"],
        &["fig6", "fig7"],
    );
    for path in ["Fig. 6 joint path", "Fig. 7 spherical path"] {
        let f = &fcmac[path]["fcmac"];
        let r = &fcmac[path]["regions"];
        let c = &cmac[path]["cmac"];
        assert!(f.1 < 0.1, "{path}: FCMAC max {}", f.1);
        assert!(
            r.1 < fcmac[path]["conventional"].1,
            "{path}: regions should beat conventional"
        );
        for k in 0..4 {
            if r.3[k] < 1e-9 {
                // The path crosses no region boundary that changes this CEP.
                assert!(f.3[k] < 1e-3, "{path}: CEP {k} FCMAC jump {}", f.3[k]);
                continue;
            }
            assert!(
                f.3[k] < 0.5 * r.3[k],
                "{path}: CEP {k} FCMAC jump {} vs regions {}",
                f.3[k],
                r.3[k]
            );
            assert!(
                f.3[k] < c.3[k],
                "{path}: CEP {k} FCMAC jump {} vs CMAC {}",
                f.3[k],
                c.3[k]
            );
        }
    }
}

#[test]
fn an_unmeasurable_region_on_the_path_is_generalised_by_the_fcmac() {
    let (summary, t) = calibrate_and_evaluate(
        &["--accuracy-mm", "0.02", "--unmeasurable-at", "92,75,-22"],
        &["fig6"],
    );
    assert!(
        summary.contains("could not be measured: no measurement was taken inside it"),
        "{summary}"
    );
    let (_, max, failures, _) = t["Fig. 6 joint path"]["fcmac"];
    assert!(
        max < 0.1 && failures == 0,
        "FCMAC max {max} on the Fig. 8 case"
    );
}

/// The pipeline as library calls (no command-line words): calibrate on the scenario, save and
/// reload the model, evaluate along the Fig. 6 path.
#[test]
fn the_pipeline_as_library_calls_meets_the_papers_accuracy_on_the_fig6_path() {
    use rigcal::calibration::{self, CalibrationOptions, PathChoice, PathOptions, Source};
    use std::path::Path;
    let sc = rigcal::world::Scenario::load(Path::new("sim/paper-sim.toml"), None).unwrap();
    let opts = CalibrationOptions::default();
    let cal = calibration::calibrate(&sc.rig, Source::Scenario(&sc), &opts).unwrap();
    assert!(cal.text().contains("paper: 110 regions, 2200 measurements"));
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("m.json");
    cal.model.save(&file).unwrap();
    let loaded = rigcal::model::ModelFile::load(&file).unwrap();
    let paths = calibration::build_paths(&loaded.rig, &[PathChoice::Fig6], &PathOptions::default())
        .unwrap();
    let names = calibration::PAPER_TRACED_CEPS.map(String::from);
    let trace = calibration::traced_ceps(&loaded.rig, &names).unwrap();
    let results = calibration::evaluate(&loaded, &file, &sc, &paths, &trace).unwrap();
    let max = |model: &str| {
        let r = results[0].iter().find(|r| r.model == model).unwrap();
        assert_eq!(r.failures, 0, "{model}");
        r.stats().max_mm
    };
    assert!((0.4..=1.2).contains(&max("uncalibrated")));
    assert!(max("conventional") < 0.2);
    for model in ["regions", "fcmac"] {
        assert!(max(model) < 0.1, "{model}: {}", max(model));
    }
    let table = calibration::path_table(&paths[0], &results[0], &trace);
    assert!(
        table.contains("Δθ1 (deg) Δd1 (mm) Δa1 (mm) Δα1 (deg)"),
        "{table}"
    );
}
