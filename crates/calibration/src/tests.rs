//! `calibrate` as a library call: every source, the paper's constants as options, and the
//! errors a caller can branch on.

use super::*;
use rigcal_model::learners::Learner;
use rigcal_model::model::ModelBody;
use std::path::Path;

fn paper_scenario() -> Scenario {
    Scenario::load(
        Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../sim/paper-sim.toml"
        )),
        None,
    )
    .expect("the shipped paper scenario")
}

fn coarse() -> CalibrationOptions {
    CalibrationOptions {
        accuracy_mm: 0.1,
        max_regions: Some(4),
        ..CalibrationOptions::default()
    }
}

#[test]
fn planning_on_a_scenario_builds_a_variable_model_with_the_papers_fcmac() {
    let sc = paper_scenario();
    let cal = calibrate(&sc.rig, Source::Scenario(&sc), &coarse()).expect("calibrate");
    let ModelBody::Variable {
        division, learner, ..
    } = &cal.model.model
    else {
        panic!("not a variable model");
    };
    assert_eq!(division.mode, "planning");
    assert_eq!(division.max_regions, 4);
    assert_eq!(division.design_poses, DEFAULT_DESIGN_POSES);
    let Some(Learner::Fcmac(f)) = learner else {
        panic!("no FCMAC");
    };
    assert_eq!(f.config.cells, [17, 11, 11]);
    assert_eq!(f.config.c, [3, 3, 3]);
    assert_eq!(f.cell_count(), 2057);
    let Figures::Division(d) = &cal.figures else {
        panic!("no division figures");
    };
    assert!(d.regions >= 1 && d.regions <= 4, "{d:?}");
    assert!(d.measurements >= 20, "{d:?}");
    let text = cal.text();
    assert!(text.contains("planning division in Joint space"), "{text}");
    assert!(
        text.contains("paper: 110 regions, 2200 measurements"),
        "{text}"
    );
    assert!(
        text.contains("FCMAC: [17, 11, 11] sensors, c = [3, 3, 3], 2057 association cells"),
        "{text}"
    );
    // The scenario is named as it was given (here by an absolute path from this crate).
    let from = cal
        .model
        .fitted_from
        .recording
        .as_deref()
        .unwrap_or_default();
    assert!(
        from.starts_with("scenario ") && from.ends_with("sim/paper-sim.toml"),
        "{from}"
    );
}

#[test]
fn offline_from_observations_honours_the_learner_settings_and_design_poses() {
    let sc = paper_scenario();
    let obs = simulated_observations(&sc.rig, &sc.world(), 300, 3);
    let opts = CalibrationOptions {
        space: Space::Cartesian,
        design_poses: 60,
        learner_settings: LearnerSettings {
            sensors: Some([9, 7, 5]),
            c: [2, 2, 2],
            cmac_layers: 3,
            ..Default::default()
        },
        ..coarse()
    };
    let source = Source::Offline {
        observations: &obs,
        label: "300 simulated poses".into(),
    };
    let cal = calibrate(&sc.rig, source, &opts).expect("calibrate");
    let ModelBody::Variable {
        division, learner, ..
    } = &cal.model.model
    else {
        panic!("not a variable model");
    };
    assert_eq!(
        (division.mode.as_str(), division.design_poses),
        ("offline", 60)
    );
    assert_eq!(division.measurements, 300);
    let Some(Learner::Fcmac(f)) = learner else {
        panic!("no FCMAC");
    };
    assert_eq!(
        (f.config.cells, f.config.c, f.cell_count()),
        ([9, 7, 5], [2, 2, 2], 315)
    );
    assert!(cal.text().contains("offline division in Cartesian space"));
}

#[test]
fn the_papers_sensors_follow_the_first_joints_coordinate() {
    let s = LearnerSettings::default();
    assert_eq!(s.sensors_for(Space::Joint), [17, 11, 11]);
    assert_eq!(s.sensors_for(Space::Cartesian), [11, 17, 11]);
    assert_eq!(s.cmac_config(Space::Cartesian).cells, [11, 17, 11]);
    assert_eq!(s.cmac_config(Space::Joint).layers, 3);
    let opts = CalibrationOptions::default();
    assert_eq!(opts.region_cap(), 110);
    let cartesian = CalibrationOptions {
        space: Space::Cartesian,
        ..opts
    };
    assert_eq!(cartesian.region_cap(), 130);
}

#[test]
fn any_measurer_can_measure_and_an_unmeasurable_region_is_never_measured() {
    let sc = paper_scenario();
    let mut world = WorldMeasurer::of(&sc);
    let opts = CalibrationOptions {
        learner: LearnerKind::None,
        unmeasurable_at: Some([92.0, 75.0, -22.0]),
        unmeasurable_depth: Some(2),
        ..coarse()
    };
    let source = Source::Measurer {
        measurer: &mut world,
        label: "a world".into(),
    };
    let cal = calibrate(&sc.rig, source, &opts).expect("calibrate");
    assert!(world.seq > 0, "the measurer was not asked");
    let Figures::Division(d) = &cal.figures else {
        panic!("no division figures");
    };
    let u = d.unmeasurable.as_ref().expect("an unmeasurable region");
    // q1 splits first (300° against 130° and 120°), then q2 (130/130 against 120/120 of q3):
    // 92° is in the upper half of q1, 75° in the upper half of q2.
    assert_eq!(u.region, "r11");
    let neighbours = u.borrowed_from.as_ref().expect("its neighbours' CEPs");
    assert_eq!(neighbours, &["r0", "r10"]);
    let text = cal.text();
    assert!(
        text.starts_with(
            "region r11 (depth 2, containing 92,75,-22) could not be measured: no measurement was taken inside it"
        ),
        "{text}"
    );
    assert!(
        text.contains("no learner: compensation uses each region's CEPs"),
        "{text}"
    );
}

#[test]
fn a_network_learns_from_random_poses_of_a_scenario_but_not_from_a_measurer() {
    let sc = paper_scenario();
    let opts = CalibrationOptions {
        learner: LearnerKind::NnDirect,
        neural: NeuralOptions {
            epochs: 20,
            measurements: 120,
            ..NeuralOptions::default()
        },
        ..CalibrationOptions::default()
    };
    let cal = calibrate(&sc.rig, Source::Scenario(&sc), &opts).expect("calibrate");
    assert!(matches!(cal.model.model, ModelBody::Neural { .. }));
    assert_eq!(cal.model.fitted_from.measurements, 120);
    assert!(
        cal.text().starts_with("neural direct scheme 4 (20 hidden"),
        "{}",
        cal.text()
    );
    let mut world = WorldMeasurer::of(&sc);
    let source = Source::Measurer {
        measurer: &mut world,
        label: "a world".into(),
    };
    let err = calibrate(&sc.rig, source, &opts).unwrap_err();
    assert!(matches!(err, CalibrationError::NeuralNeedsData), "{err}");
    let bad = CalibrationOptions {
        neural: NeuralOptions {
            scheme: 3,
            ..opts.neural.clone()
        },
        ..opts
    };
    let err = calibrate(&sc.rig, Source::Scenario(&sc), &bad).unwrap_err();
    assert!(matches!(err, CalibrationError::Scheme(3)), "{err}");
}

/// The tolerance's default follows the learner: position training starts from tolerant CEPs,
/// the paper's CEP training and the CMAC from the CEPs as fitted; a given value always wins.
#[test]
fn learner_tolerance_defaults_follow_the_training() {
    let ceps = LearnerSettings {
        training: FcmacTraining::Ceps,
        ..LearnerSettings::default()
    };
    let cases = [
        (LearnerKind::Fcmac, LearnerSettings::default(), None, 0.5),
        (LearnerKind::Fcmac, ceps.clone(), None, 0.0),
        (LearnerKind::Cmac, LearnerSettings::default(), None, 0.0),
        (
            LearnerKind::Fcmac,
            LearnerSettings::default(),
            Some(0.2),
            0.2,
        ),
        (LearnerKind::Fcmac, ceps, Some(0.3), 0.3),
    ];
    for (learner, learner_settings, learner_tolerance, expected) in cases {
        let opts = CalibrationOptions {
            learner,
            learner_settings,
            learner_tolerance,
            ..CalibrationOptions::default()
        };
        assert_eq!(opts.learner_tolerance_in_use(), expected, "{opts:?}");
    }
}

#[test]
fn bad_options_and_sources_are_refused_before_measuring() {
    let sc = paper_scenario();
    let cases = [
        CalibrationOptions {
            accuracy_mm: 0.0,
            ..coarse()
        },
        CalibrationOptions {
            per_region: 5,
            ..coarse()
        },
        CalibrationOptions {
            learner_settings: LearnerSettings {
                c: [3, 12, 3],
                ..LearnerSettings::default()
            },
            ..coarse()
        },
        CalibrationOptions {
            learner_tolerance: Some(1.5),
            ..coarse()
        },
    ];
    for opts in &cases {
        let mut world = WorldMeasurer::of(&sc);
        let source = Source::Measurer {
            measurer: &mut world,
            label: "a world".into(),
        };
        assert!(calibrate(&sc.rig, source, opts).is_err(), "{opts:?}");
        assert_eq!(world.seq, 0, "measured before refusing {opts:?}");
    }
    let empty = Source::Offline {
        observations: &[],
        label: "rec".into(),
    };
    let err = calibrate(&sc.rig, empty, &coarse()).unwrap_err();
    assert_eq!(err.to_string(), "rec: no measured rows");
    let real = Rig::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../rigs/rv-m2.toml"
    )))
    .expect("rig");
    let other = Scenario::load(
        Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../sim/paper-sim.toml"
        )),
        None,
    )
    .expect("scenario");
    let ideal_only = Rig {
        name: "another".into(),
        ..real
    };
    let err = calibrate(&ideal_only, Source::Scenario(&other), &coarse()).unwrap_err();
    assert!(matches!(err, CalibrationError::ScenarioRig { .. }), "{err}");
}

#[test]
fn a_planning_note_names_the_design_poses_only_when_not_the_papers() {
    let files = PlanningFiles {
        rig: Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../rigs/rv-m2.toml"
        )),
        sim: None,
    };
    let paper = planning_note(files, &CalibrationOptions::default());
    assert!(
        paper.ends_with("--seed 1 --unmeasurable-at (none)"),
        "{paper}"
    );
    assert!(paper.contains("--sim (none: the rig)") && paper.contains("--max-regions (default)"));
    let other = planning_note(
        files,
        &CalibrationOptions {
            design_poses: 50,
            unmeasurable_at: Some([1.5, 2.0, -3.0]),
            ..CalibrationOptions::default()
        },
    );
    assert!(
        other.ends_with("--unmeasurable-at 1.5,2,-3 --design-poses 50"),
        "{other}"
    );
    // Section 7's acceptance and test plan (set through the library) are part of what a resume
    // must match: they decide which regions split, so which points come next.
    let sec7 = planning_note(
        files,
        &CalibrationOptions {
            confidence_z: 0.0,
            unmeasurable_halves: true,
            test_plan: rigcal_model::division::TestPlan {
                first_stage: 9,
                reuse: true,
                refit: true,
            },
            ..CalibrationOptions::default()
        },
    );
    assert!(
        sec7.ends_with(
            " --unmeasurable-halves --confidence-z 0 --test-plan first-stage=9,reuse=true,refit=true"
        ),
        "{sec7}"
    );
    let other_plan = planning_note(
        files,
        &CalibrationOptions {
            confidence_z: 0.0,
            unmeasurable_halves: true,
            test_plan: rigcal_model::division::TestPlan {
                first_stage: 9,
                reuse: false,
                refit: true,
            },
            ..CalibrationOptions::default()
        },
    );
    assert_ne!(sec7, other_plan);
}

#[test]
fn paths_are_parsed_and_traced_ceps_checked() {
    assert_eq!(PathChoice::parse("fig6").ok(), Some(PathChoice::Fig6));
    let Ok(PathChoice::Joint { from, to, .. }) = PathChoice::parse("joint:1,2,3:4,5,6") else {
        panic!("a joint path");
    };
    assert_eq!((from, to), (vec![1.0, 2.0, 3.0], vec![4.0, 5.0, 6.0]));
    let err = PathChoice::parse("joint:1,x,3:4,5,6")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("`x` in --path joint:1,x,3:4,5,6 is not a number"),
        "{err}"
    );
    assert!(PathChoice::parse("fig9")
        .unwrap_err()
        .to_string()
        .contains("unknown path `fig9`"));
    let rig = Rig::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../rigs/rv-m2-ideal.toml"
    )))
    .expect("rig");
    let names: Vec<String> = ["theta1", "d1", "a1", "alpha1"].map(String::from).to_vec();
    let traced = traced_ceps(&rig, &names).expect("the paper's CEPs");
    let shown: Vec<String> = traced
        .iter()
        .map(|t| format!("{} ({})", t.symbol, t.unit))
        .collect();
    assert_eq!(shown.join(" "), "Δθ1 (deg) Δd1 (mm) Δa1 (mm) Δα1 (deg)");
    assert!(matches!(
        traced_ceps(&rig, &["theta9".to_string()]),
        Err(CalibrationError::UnknownCep(_))
    ));
    let paths = build_paths(
        &rig,
        &[PathChoice::Fig6, PathChoice::Random],
        &PathOptions {
            points: 11,
            random_paths: 2,
            seed: 7,
        },
    )
    .expect("paths");
    assert_eq!(paths.len(), 3);
    assert!(paths.iter().all(|p| p.points.len() == 11));
}
