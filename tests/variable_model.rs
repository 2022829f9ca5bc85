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
    use rigcal_calibration::{
        self as calibration, CalibrationOptions, PathChoice, PathOptions, Source,
    };
    use std::path::Path;
    let sc = rigcal_sim::world::Scenario::load(Path::new("sim/paper-sim.toml"), None).unwrap();
    let opts = CalibrationOptions::default();
    let cal = calibration::calibrate(&sc.rig, Source::Scenario(&sc), &opts).unwrap();
    assert!(cal.text().contains("paper: 110 regions, 2200 measurements"));
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("m.json");
    cal.model.save(&file).unwrap();
    let loaded = rigcal_model::model::ModelFile::load(&file).unwrap();
    let paths = calibration::build_paths(&loaded.rig, &[PathChoice::Fig6], &PathOptions::default())
        .unwrap();
    let names = rigcal_paper::preset::SEED_000.traced_ceps();
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

/// Seed 000 section 6 as its figures show it (`sim/paper-fig6.toml`, conventions §3): a
/// division at the paper's settings on the simulated arm, saved, reloaded and evaluated along
/// `path`; the model and the figures per method (with the error inside an unmeasurable region).
mod paper_fig6 {
    use rigcal_calibration::{
        self as calibration, CalibrationOptions, PathChoice, PathFigures, PathOptions, Source,
    };
    use rigcal_model::learners::LearnerKind;
    use rigcal_model::model::{ModelBody, ModelFile};
    use std::path::Path;

    pub const SCENARIO: &str = "sim/paper-fig6.toml";

    pub fn scenario() -> rigcal_sim::world::Scenario {
        rigcal_sim::world::Scenario::load(Path::new(SCENARIO), None).unwrap()
    }

    /// The figures of `model` along `path` (Fig. 6 or Fig. 7).
    pub fn figures(model: &ModelFile, path: PathChoice) -> PathFigures {
        let sc = scenario();
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("m.json");
        model.save(&file).unwrap();
        let loaded = ModelFile::load(&file).unwrap();
        let paths =
            calibration::build_paths(&loaded.rig, &[path], &PathOptions::default()).unwrap();
        let names = rigcal_paper::preset::SEED_000.traced_ceps();
        let trace = calibration::traced_ceps(&loaded.rig, &names).unwrap();
        let results = calibration::evaluate(&loaded, &file, &sc, &paths, &trace).unwrap();
        PathFigures::of(&loaded, &paths[0], &results[0], &trace)
    }

    pub fn calibrate(opts: &CalibrationOptions) -> ModelFile {
        let sc = scenario();
        calibration::calibrate(&sc.rig, Source::Scenario(&sc), opts)
            .unwrap()
            .model
    }

    pub fn regions(model: &ModelFile) -> usize {
        match &model.model {
            ModelBody::Variable { division, .. } => division.regions,
            _ => panic!("not a variable model"),
        }
    }

    pub fn max(f: &PathFigures, method: &str) -> f64 {
        let m = f.method(method).unwrap();
        assert_eq!(m.failures, 0, "{method} failed somewhere on {}", f.path);
        m.max_mm
    }

    pub fn with(learner: LearnerKind, model: &ModelFile) -> ModelFile {
        let sc = scenario();
        calibration::with_learner(model, &sc.rig, learner, &Default::default()).unwrap()
    }
}

/// Fig. 6 at the paper's settings: conventional calibration between 0.1 and 0.2 mm (so 0.1 mm
/// needs the division), tens of joint-space regions, regions and FCMAC below 0.1 mm, and the
/// FCMAC's largest CEP jump below the regions' and CMAC's on the same division.
#[test]
fn paper_fig6_joint_division_meets_the_papers_figures_on_the_fig6_path() {
    use rigcal_calibration::{CalibrationOptions, PathChoice};
    use rigcal_model::learners::LearnerKind;
    let model = paper_fig6::calibrate(&CalibrationOptions::default());
    let regions = paper_fig6::regions(&model);
    assert!((20..=110).contains(&regions), "{regions} regions");
    let f = paper_fig6::figures(&model, PathChoice::Fig6);
    let uncal = paper_fig6::max(&f, "uncalibrated");
    assert!((0.4..=1.2).contains(&uncal), "uncalibrated max {uncal}");
    let conv = paper_fig6::max(&f, "conventional");
    assert!((0.1..0.2).contains(&conv), "conventional max {conv}");
    for m in ["regions", "fcmac"] {
        let max = paper_fig6::max(&f, m);
        assert!(max < 0.1, "{m} max {max}");
    }
    let cmac = paper_fig6::figures(
        &paper_fig6::with(LearnerKind::Cmac, &model),
        PathChoice::Fig6,
    );
    let jumps = |f: &rigcal_calibration::PathFigures, m: &str| {
        f.method(m).unwrap().largest_cep_jump.clone()
    };
    let (fcmac, regions_j, cmac_j) = (
        jumps(&f, "fcmac"),
        jumps(&f, "regions"),
        jumps(&cmac, "cmac"),
    );
    assert_eq!(fcmac.len(), 4);
    for (cep, j) in &fcmac {
        assert!(
            *j < regions_j[cep] && *j < cmac_j[cep],
            "{cep}: FCMAC {j}, regions {}, CMAC {}",
            regions_j[cep],
            cmac_j[cep]
        );
    }
}

/// Fig. 7 at the paper's settings (Cartesian division, its cap of 130): tens of regions, the
/// FCMAC below 0.1 mm on the spherical path and smoother than the regions.
#[test]
fn paper_fig6_cartesian_division_keeps_the_fcmac_below_the_demand_on_the_fig7_path() {
    use rigcal_calibration::{CalibrationOptions, PathChoice};
    use rigcal_model::division::Space;
    let model = paper_fig6::calibrate(&CalibrationOptions {
        space: Space::Cartesian,
        ..CalibrationOptions::default()
    });
    let regions = paper_fig6::regions(&model);
    assert!((20..=130).contains(&regions), "{regions} regions");
    let f = paper_fig6::figures(&model, PathChoice::Fig7);
    let fcmac = paper_fig6::max(&f, "fcmac");
    assert!(fcmac < 0.1, "FCMAC max {fcmac}");
    assert!(fcmac < paper_fig6::max(&f, "conventional"));
}

/// Fig. 7 with the Cartesian division run until every region meets 0.1 mm (the paper's cap of
/// 130 leaves about 30 regions short of it): regions and FCMAC below 0.1 mm. Slow (≈ 20 s).
#[test]
#[ignore]
fn paper_fig6_converged_cartesian_division_meets_the_demand_on_the_fig7_path() {
    use rigcal_calibration::{CalibrationOptions, PathChoice};
    use rigcal_model::division::Space;
    let model = paper_fig6::calibrate(&CalibrationOptions {
        space: Space::Cartesian,
        max_regions: Some(260),
        ..CalibrationOptions::default()
    });
    let f = paper_fig6::figures(&model, PathChoice::Fig7);
    for m in ["regions", "fcmac"] {
        let max = paper_fig6::max(&f, m);
        assert!(max < 0.1, "{m} max {max}");
    }
}

/// Fig. 8 on paper-fig6: the region around (92°, 75°, −22°) at the depth the Fig. 6 division
/// gives it is never measured; the path's error inside it is reported per model, the
/// region-wise model (its neighbours' mean CEPs) keeps it below 0.1 mm there, and the FCMAC
/// (position training on the tolerant CEPs, the defaults) beats that on mean and max.
#[test]
fn paper_fig6_unmeasurable_region_is_reported_on_the_fig6_path() {
    use rigcal_calibration::{CalibrationOptions, PathChoice};
    let model = paper_fig6::calibrate(&CalibrationOptions {
        unmeasurable_at: Some([92.0, 75.0, -22.0]),
        unmeasurable_depth: Some(7),
        ..CalibrationOptions::default()
    });
    let f = paper_fig6::figures(&model, PathChoice::Fig6);
    let inside = f
        .inside_unmeasurable
        .as_ref()
        .expect("the path crosses the region");
    assert_eq!(inside.region.as_deref(), Some("r1111110"));
    assert!(inside.points.len() >= 10, "{:?}", inside.points);
    let method = |m: &str| inside.methods.iter().find(|x| x.method == m).unwrap();
    let at = |m: &str| method(m).max_mm;
    assert!(at("regions") < 0.1, "regions inside {}", at("regions"));
    assert!(at("regions") < at("conventional"));
    let (fcmac, regions) = (method("fcmac"), method("regions"));
    assert!(
        fcmac.mean_mm < regions.mean_mm && fcmac.max_mm < regions.max_mm,
        "inside: FCMAC {} / {}, neighbours' mean CEPs {} / {}",
        fcmac.mean_mm,
        fcmac.max_mm,
        regions.mean_mm,
        regions.max_mm
    );
}
