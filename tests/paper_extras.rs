//! What seed 000 has and the demo lacked (`rigcal_paper::extras`), at reduced sizes: the
//! FCMAC's initial weights, CMAC and FCMAC on equal training, the ten paths' rule, the noise
//! run's σ, and the rig's CEP plots (Fig. 10 e–g).

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rigcal_calibration::{calibrate, with_learner, CalibrationOptions, Source};
use rigcal_core::kinematics::Robot;
use rigcal_core::rig::Rig;
use rigcal_model::division::{DivisionSpace, Space};
use rigcal_model::learners::{FcmacInit, FcmacTraining, Learner, LearnerKind, LearnerSettings};
use rigcal_model::model::{ModelBody, ModelFile};
use rigcal_paper::demo::DemoOptions;
use rigcal_paper::extras::{self, Extras};
use rigcal_paper::preset::SEED_000;
use rigcal_paper::sec7::{self, Sec7Files, Sec7Options};
use rigcal_sim::world::Scenario;
use std::path::Path;

fn scenario(file: &str) -> Scenario {
    Scenario::load(Path::new(file), None).expect("a shipped scenario")
}

/// A small joint-space division of the paper's regime (4 regions), its FCMAC trained on the
/// regions' CEPs only.
fn small_model(sc: &Scenario) -> ModelFile {
    let opts = CalibrationOptions {
        accuracy_mm: 0.02,
        max_regions: Some(4),
        learner_settings: LearnerSettings {
            training: FcmacTraining::Ceps,
            ..LearnerSettings::default()
        },
        ..CalibrationOptions::default()
    };
    calibrate(&sc.rig, Source::Scenario(sc), &opts)
        .expect("a small division")
        .model
}

fn fcmac(model: &ModelFile) -> &rigcal_model::learners::Fcmac {
    let ModelBody::Variable {
        learner: Some(Learner::Fcmac(f)),
        ..
    } = &model.model
    else {
        panic!("no FCMAC in the model");
    };
    f
}

/// `--fcmac-init zero`: the network starts from zero and (A5) carries it to the regions' CEPs;
/// the three starts give three different networks.
#[test]
fn zero_initialised_fcmac_cells_start_at_zero_and_training_moves_them() {
    let sc = scenario("sim/paper-fig6.toml");
    let model = small_model(&sc);
    let with = |init| {
        let settings = LearnerSettings {
            training: FcmacTraining::Ceps,
            init,
            ..LearnerSettings::default()
        };
        with_learner(&model, &sc.rig, LearnerKind::Fcmac, &settings).expect("a learner")
    };
    let (zero, ceps, conventional) = (
        with(FcmacInit::Zero),
        with(FcmacInit::Ceps),
        with(FcmacInit::Conventional),
    );
    let (z, c, k) = (fcmac(&zero), fcmac(&ceps), fcmac(&conventional));
    assert_ne!(z.weights, c.weights, "zero start ignored");
    assert_ne!(k.weights, c.weights, "conventional start ignored");
    // Trained from zero, the weights moved: most cells are far from zero, and at each leaf's
    // centre the network gives that leaf's CEPs to within a fraction of their size.
    let moved = z.weights.iter().filter(|w| w.abs() > 1e-6).count();
    assert!(
        moved > z.weights.len() / 2,
        "{moved} of {} moved",
        z.weights.len()
    );
    let ModelBody::Variable { tree, .. } = &model.model else {
        panic!("not a variable model");
    };
    let report = z.report.expect("a training report");
    assert!(report.epochs >= 1, "{report:?}");
    let scale: Vec<f64> = {
        let layout = sc.rig.chain.layout();
        tree.basis
            .iter()
            .map(|n| {
                let id = layout.find(n).expect("a basis name");
                id.kind.to_file_units(1.0)
            })
            .collect()
    };
    for leaf in tree.root.leaves() {
        let (Some(cep), true) = (
            leaf.learner_cep.as_ref().or(leaf.cep.as_ref()),
            leaf.is_measured(),
        ) else {
            continue;
        };
        let centre: [f64; 3] =
            std::array::from_fn(|d| 0.5 * (leaf.bounds.lo[d] + leaf.bounds.hi[d]));
        let y = z.predict(&centre);
        let size: f64 = cep
            .iter()
            .zip(&scale)
            .map(|(v, s)| (v * s).abs())
            .fold(0.0, f64::max);
        let off: f64 = y
            .iter()
            .zip(cep.iter().zip(&scale))
            .map(|(a, (v, s))| (a - v * s).abs())
            .fold(0.0, f64::max);
        assert!(
            off < 0.5 * size,
            "leaf {}: network {off} from its CEPs of size {size}",
            leaf.id
        );
    }
}

/// `--equal-training`: the CMAC and the FCMAC of a seed's Fig. 6 division both learn its CEPs
/// only, and the claims come out for that seed.
#[test]
fn equal_training_gives_both_learners_the_same_ceps_and_its_claims() {
    let sc = scenario("sim/paper-fig6.toml");
    let dir = tempfile::tempdir().expect("a temporary directory");
    let seed_dir = dir.path().join("seed-7");
    std::fs::create_dir_all(&seed_dir).expect("the seed directory");
    small_model(&sc)
        .save(&seed_dir.join("paper-fig6-model.json"))
        .expect("the model written");
    let demo = DemoOptions {
        out: dir.path().to_path_buf(),
        preset: SEED_000,
        path_points: 21,
        seed: 7,
        learner_tolerance: None,
        fcmac_training: FcmacTraining::Positions,
        confidence_z: None,
        plain_least_squares: false,
        fcmac_init: FcmacInit::Ceps,
        noise_share: None,
    };
    let extras = Extras {
        equal_training: true,
        ..Extras::default()
    };
    let t = extras::measure(&demo, &[7], extras).expect("the extras");
    assert_eq!(t.rows.len(), 3, "{:?}", t.rows);
    for r in &t.rows {
        assert_eq!(r.values.len(), 1, "{r:?}");
        assert!(r.values[0].1.is_finite() && r.values[0].1 > 0.0, "{r:?}");
    }
    let load = |name: &str| {
        ModelFile::load(&seed_dir.join(format!("paper-fig6-equal-{name}-model.json")))
            .expect("the equal-training model")
            .file
    };
    let f = load("fcmac");
    assert!(fcmac(&f).positions.is_none(), "the FCMAC learned positions");
    assert!(
        matches!(
            &load("cmac").model,
            ModelBody::Variable {
                learner: Some(Learner::Cmac(_)),
                ..
            }
        ),
        "no CMAC"
    );
    assert!(t.text().contains("equal training (CEPs only)"));
}

/// The ten section 6 paths: ten distinct lines of 101 points, each at least 60° long, every
/// point measurable and inside both division boxes; the same ten at every call.
#[test]
fn ten_paths_are_distinct_and_inside_the_measurable_workspace() {
    let rig = Rig::load(Path::new("rigs/rv-m2-ideal.toml")).expect("the ideal rig");
    let paths = extras::ten_joint_paths(&rig).expect("ten paths");
    assert_eq!(paths.len(), 10);
    let joint = DivisionSpace::new(&rig, Space::Joint).expect("joint space");
    let cartesian = DivisionSpace::new(&rig, Space::Cartesian).expect("Cartesian space");
    for (k, p) in paths.iter().enumerate() {
        assert_eq!(p.points.len(), 101);
        let (a, b) = (&p.points[0], &p.points[100]);
        let length_deg = a
            .iter()
            .zip(b)
            .map(|(x, y)| (x - y).powi(2))
            .sum::<f64>()
            .sqrt()
            .to_degrees();
        assert!(length_deg >= 60.0, "path {k}: {length_deg}°");
        for q in &p.points {
            assert!(rig.measurable(q).is_ok(), "path {k}: {q:?}");
            assert!(joint.full.holds(&joint.coords(q)), "path {k}: {q:?}");
            assert!(
                cartesian.full.holds(&cartesian.coords(q)),
                "path {k}: {q:?}"
            );
        }
        for other in &paths[..k] {
            assert_ne!(other.points[0], p.points[0], "path {k} repeats");
            assert_ne!(other.name, p.name);
        }
    }
    let again = extras::ten_joint_paths(&rig).expect("ten paths");
    assert!(paths.iter().zip(&again).all(|(a, b)| a.points == b.points));
}

/// The noise run's σ: noise vectors of that σ have a mean length of 3 % of the mean
/// uncalibrated error along the Fig. 6 path (checked by drawing them), and on
/// `sim/paper-sim.toml` it is the 0.016 mm that `sim/paper-sim-noise.toml` was given by hand.
#[test]
fn the_noise_runs_sigma_makes_noise_three_percent_of_the_error() {
    let sc = scenario("sim/paper-fig6.toml");
    let sigma = rigcal_paper::paper_regime::noise_sigma_mm(&sc, 0.03);
    let total = sc
        .world()
        .error_split(&rigcal_sim::world::fig6_path(101, sc.rig.chain.dof()))
        .mean_total();
    let normal = Normal::new(0.0, sigma).expect("a normal distribution");
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(3);
    let n = 200_000;
    let mean_length = (0..n)
        .map(|_| {
            let v: [f64; 3] = std::array::from_fn(|_| normal.sample(&mut rng));
            v.iter().map(|x| x * x).sum::<f64>().sqrt()
        })
        .sum::<f64>()
        / n as f64;
    let share = mean_length / total;
    assert!((share - 0.03).abs() < 0.0005, "share {share}");
    let literal = rigcal_paper::paper_regime::noise_sigma_mm(&scenario("sim/paper-sim.toml"), 0.03);
    assert!((literal - 0.016).abs() < 0.0005, "σ {literal}");
}

/// The rig's CEP plot (Fig. 10 e–g) of a reduced section 7 run has a series per model and
/// a panel per traced CEP; the CSV's conventional CEPs are constant along the path, the
/// regions' are not; and another path is measured by the rig with the same division.
#[test]
fn the_rig_cep_plot_has_the_series_and_another_path_is_measured() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let mut opts = Sec7Options::default();
    opts.calibration.max_regions = Some(12);
    opts.path_points = 21;
    let files = Sec7Files {
        rig: Path::new("rigs/rv-m2.toml"),
        scenario: Path::new("sim/rig-sec7.toml"),
        out: dir.path(),
    };
    let report = sec7::run(files, &opts, &mut |_| {}).expect("the reduced section 7 run");
    let plots = dir.path().join("plots");
    let written =
        rigcal_paper::sec7::rig_cep_plot(&report, &SEED_000, &plots).expect("the CEP plot");
    let svg = std::fs::read_to_string(&written.svg).expect("the SVG");
    for name in [
        "conventional",
        "regions",
        "fcmac",
        "theta1",
        "d1",
        "a1",
        "alpha1",
    ] {
        assert!(svg.contains(name), "{name} missing from the plot");
    }
    let csv = std::fs::read_to_string(&written.csv).expect("the CSV");
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().expect("a header").split(',').collect();
    assert_eq!(header.len(), 1 + 3 * 4, "{header:?}");
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().expect("a number")).collect())
        .collect();
    assert_eq!(rows.len(), 21);
    let column = |name: &str| {
        let i = header
            .iter()
            .position(|h| *h == name)
            .unwrap_or_else(|| panic!("no column {name}"));
        rows.iter().map(|r| r[i]).collect::<Vec<f64>>()
    };
    let spread = |v: &[f64]| {
        v.iter().copied().fold(f64::NEG_INFINITY, f64::max)
            - v.iter().copied().fold(f64::INFINITY, f64::min)
    };
    assert!(spread(&column("conventional_a1_mm")) < 1e-12);
    let regions: f64 = ["theta1_deg", "d1_mm", "a1_mm", "alpha1_deg"]
        .iter()
        .map(|c| spread(&column(&format!("regions_{c}"))))
        .sum();
    assert!(
        regions > 0.0,
        "the regions' CEPs do not change along the path"
    );

    let rig = Rig::load(Path::new("rigs/rv-m2.toml")).expect("the rig");
    let ends = extras::ten_rig_paths(&rig).expect("ten rig paths");
    assert_eq!(ends.len(), 10);
    for e in &ends {
        let length: f64 = (0..3)
            .map(|k| (e[1][k] - e[0][k]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(length >= 400.0, "{e:?}");
    }
    let other = dir.path().join("other");
    let run = sec7::measure_another_path(files, ends[0], 21, &other).expect("another path");
    assert_eq!(run.results.len(), 4);
    for r in &run.results {
        assert_eq!(r.errors.len(), 21, "{}", r.model);
        assert!(r.errors.iter().all(|e| e.is_finite()), "{}", r.model);
    }
    assert!(other.join("path-cartesian").exists());
}
