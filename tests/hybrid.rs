//! A model that compensates with the physics (issue 18 item 5): in simulation with backlash and
//! with gravity compliance hidden, `identify --effects` fits the effect beside the geometry, and
//! the compensated path's true error (the world's truth) falls from the geometric-only figure
//! to near the noise floor. Reduced sizes: 300 measurements, 50 targets. Units: mm, degrees.

use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::Target;
use rigcal_model::identification::{identify, random_poses, Level};
use rigcal_model::model::effects::{fit_recording_effects, EffectSpec, ModelEffect};
use rigcal_model::model::hybrid::{Approach, HybridOptions};
use rigcal_model::model::LoadedModel;
use rigcal_model::model::{ModelFile, Provenance};
use rigcal_sim::twin::hybrid::{compensated_errors, PathErrors};
use rigcal_sim::world::Scenario;
use std::path::{Path, PathBuf};

const NOISE_MM: f64 = 0.02;

/// The ideal RV-M2 with link masses (the scenario's compliance masses, so the rig file states
/// the physics the world runs).
fn rig_with_masses() -> String {
    let text = std::fs::read_to_string("rigs/rv-m2-ideal.toml").expect("rig");
    let masses = [
        ("name = \"J1\"", "mass_kg = 0.5\ncom_mm = [0.0, 0.0, 0.0]\n"),
        (
            "name = \"J2\"",
            "mass_kg = 3.5\ncom_mm = [-125.0, 0.0, 0.0]\n",
        ),
        (
            "name = \"J3\"",
            "mass_kg = 2.5\ncom_mm = [-130.0, 0.0, 0.0]\n",
        ),
        ("name = \"J4\"", "mass_kg = 0.2\ncom_mm = [0.0, 0.0, 0.0]\n"),
        (
            "name = \"J5\"",
            "mass_kg = 1.0\ncom_mm = [-150.0, 0.0, 0.0]\n",
        ),
    ];
    let mut out = text.replace("name = \"rv-m2-ideal\"", "name = \"rv-m2-masses\"");
    for (anchor, m) in masses {
        out = out.replace(anchor, &format!("{anchor}\n{m}"));
    }
    out
}

fn dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rigcal-hybrid-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(d.join("rigs")).expect("temp dir");
    std::fs::create_dir_all(d.join("sim")).expect("temp dir");
    std::fs::write(d.join("rigs/rv-m2-masses.toml"), rig_with_masses()).expect("rig");
    d
}

const COMPLIANCE_MASSES: &str = "masses = [ { link = 1, kg = 0.5, at_mm = [0.0, 0.0, 0.0] }, { link = 2, kg = 3.5, at_mm = [-125.0, 0.0, 0.0] }, { link = 3, kg = 2.5, at_mm = [-130.0, 0.0, 0.0] }, { link = 4, kg = 0.2, at_mm = [0.0, 0.0, 0.0] }, { link = 5, kg = 1.0, at_mm = [-150.0, 0.0, 0.0] }";

fn scenario(d: &Path, name: &str, effects: &str) -> Scenario {
    let text = format!(
        "seed = 11\nrig = \"../rigs/rv-m2-masses.toml\"\n\
         [geometric]\nrandom = {{ length_mm = 0.4, angle_deg = 0.05, distribution = \"signs\" }}\n\
         {effects}\n[measurement]\nnoise_mm = {NOISE_MM}\nseconds_per_point = 5.0\n"
    );
    let path = d.join("sim").join(format!("{name}.toml"));
    std::fs::write(&path, &text).expect("scenario");
    Scenario::load(&path, None).expect("scenario parses")
}

fn measurable_poses(sc: &Scenario, n: usize, seed: u64) -> Vec<Vec<f64>> {
    let rig = &sc.rig;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::new();
    while out.len() < n {
        let q = random_poses(rig.chain.joints(), rig.held(), 1, &mut rng).remove(0);
        if rig.measurable(&q).is_ok() {
            out.push(q);
        }
    }
    out
}

/// Models of `sc`'s recording: the conventional (geometric-only) one and one with `specs`
/// (`identify` then `identify --effects`), each written and read back.
struct Models {
    geometric: LoadedModel,
    hybrid: LoadedModel,
}

fn model_with(sc: &Scenario, d: &Path, specs: &[EffectSpec]) -> (Models, Vec<ModelEffect>) {
    let rec = sc.world().record(&measurable_poses(sc, 300, 1), 1);
    let id = identify(
        &sc.rig,
        &rec,
        Level::Full,
        &rigcal_model::diagnosis::outliers::identify_options(),
    )
    .expect("identify");
    let fitted = fit_recording_effects(&sc.rig, &rec, &id, specs).expect("effects fit");
    let mut file = ModelFile::constant(&sc.rig, &fitted.fit, Provenance::default());
    file.effects = fitted.effects.clone();
    let path = d.join("model.json");
    file.save(&path).expect("save");
    let hybrid = ModelFile::load(&path).expect("load");
    assert_eq!(
        hybrid.file.effects, fitted.effects,
        "the effects round-trip"
    );
    let plain = d.join("geometric.json");
    ModelFile::constant(&sc.rig, &id.fit, Provenance::default())
        .save(&plain)
        .expect("save");
    let geometric = ModelFile::load(&plain).expect("load");
    (Models { geometric, hybrid }, fitted.effects)
}

fn compare(
    m: &Models,
    world: &rigcal_sim::world::World,
    t: &[(u64, Target)],
    opts: &HybridOptions,
) -> [PathErrors; 2] {
    [
        compensated_errors(&m.geometric, false, world, t, opts, "geometric only").unwrap(),
        compensated_errors(&m.hybrid, true, world, t, opts, "with effects").unwrap(),
    ]
}

fn targets(sc: &Scenario) -> Vec<(u64, Target)> {
    measurable_poses(sc, 50, 99)
        .into_iter()
        .enumerate()
        .map(|(k, q)| (k as u64 + 2, Target::Joints(q)))
        .collect()
}

fn show(case: &str, r: &[PathErrors; 2]) {
    for p in r {
        eprintln!(
            "{case}: {:<15} mean {:.4} mm, max {:.4} mm ({} moves)",
            p.model,
            p.mean_mm(),
            p.max_mm(),
            p.moves
        );
    }
}

#[test]
fn backlash_compensated_from_the_path_order_and_with_a_consistent_approach() {
    let d = dir("backlash");
    let sc = scenario(
        &d,
        "backlash",
        "[[effects]]\nkind = \"backlash\"\njoint = 2\nlost_motion_deg = 0.05\n\
         [[effects]]\nkind = \"backlash\"\njoint = 3\nlost_motion_deg = 0.04\n",
    );
    let (model, effects) = model_with(&sc, &d, &[EffectSpec::Backlash(1), EffectSpec::Backlash(2)]);
    for (e, want) in effects.iter().zip([0.05, 0.04]) {
        let ModelEffect::Backlash {
            lost_motion_deg,
            sigma_deg,
            ..
        } = e
        else {
            panic!("{e:?}")
        };
        let s = sigma_deg.expect("σ");
        eprintln!("fitted {}", e.text());
        assert!((lost_motion_deg - want).abs() < 4.0 * s + 1e-3, "{e:?}");
    }
    let world = sc.world();
    let t = targets(&sc);
    let from_path = compare(&model, &world, &t, &HybridOptions::default());
    show("backlash, path order", &from_path);
    let consistent = HybridOptions {
        approach: Approach::Consistent,
        ..HybridOptions::default()
    };
    let planned = compare(&model, &world, &t, &consistent);
    show("backlash, consistent approach", &planned);
    let floor = NOISE_MM * 3f64.sqrt();
    let [geo, hyb] = &from_path;
    assert!(
        geo.mean_mm() > 2.0 * floor,
        "the backlash shows: {}",
        geo.mean_mm()
    );
    assert!(
        hyb.mean_mm() < 0.5 * floor,
        "with effects {} mm",
        hyb.mean_mm()
    );
    assert!(hyb.max_mm() < floor, "with effects max {} mm", hyb.max_mm());
    let [_, hyb_c] = &planned;
    assert_eq!(hyb_c.moves, 100, "a via move before each target");
    assert!(
        hyb_c.mean_mm() < 0.5 * floor,
        "consistent {} mm",
        hyb_c.mean_mm()
    );
}

#[test]
fn compliance_compensated_with_the_rigs_masses_and_a_payload() {
    let d = dir("compliance");
    let joints =
        "joints = [ { joint = 2, deg_per_nm = 0.002 }, { joint = 3, deg_per_nm = 0.003 } ]";
    // Identified without payload…
    let bare = scenario(
        &d,
        "compliance",
        &format!("[[effects]]\nkind = \"joint_compliance\"\n{COMPLIANCE_MASSES} ]\n{joints}\n"),
    );
    let (model, effects) = model_with(
        &bare,
        &d,
        &[
            EffectSpec::JointCompliance(1),
            EffectSpec::JointCompliance(2),
        ],
    );
    for (e, want) in effects.iter().zip([0.002, 0.003]) {
        let ModelEffect::JointCompliance {
            deg_per_nm,
            sigma_deg_per_nm,
            ..
        } = e
        else {
            panic!("{e:?}")
        };
        eprintln!("fitted {}", e.text());
        let s = sigma_deg_per_nm.expect("σ");
        assert!((deg_per_nm - want).abs() < 4.0 * s + 2e-5, "{e:?}");
    }
    let t = targets(&bare);
    let none = compare(&model, &bare.world(), &t, &HybridOptions::default());
    show("compliance, no payload", &none);
    // …and used with a 2 kg payload at the tool, which the world carries too.
    let loaded = scenario(
        &d,
        "compliance-payload",
        &format!(
            "[[effects]]\nkind = \"joint_compliance\"\n{COMPLIANCE_MASSES}, {{ link = 5, kg = 2.0, at_mm = [0.0, 0.0, 0.0] }} ]\n{joints}\n"
        ),
    );
    let opts = HybridOptions {
        payload_kg: 2.0,
        ..HybridOptions::default()
    };
    let payload = compare(&model, &loaded.world(), &t, &opts);
    show("compliance, 2 kg payload", &payload);
    let floor = NOISE_MM * 3f64.sqrt();
    let [geo, hyb] = &payload;
    assert!(
        geo.mean_mm() > 2.0 * floor,
        "the payload's deflection shows: {}",
        geo.mean_mm()
    );
    assert!(
        hyb.mean_mm() < 0.5 * floor,
        "with effects {} mm",
        hyb.mean_mm()
    );
    assert!(hyb.max_mm() < floor, "with effects max {} mm", hyb.max_mm());
    let [g0, h0] = &none;
    assert!(h0.mean_mm() <= g0.mean_mm() && h0.mean_mm() < 0.5 * floor);
}

#[test]
fn older_model_files_without_effects_still_read() {
    let d = dir("old");
    let sc = scenario(&d, "plain", "");
    let rec = sc.world().record(&measurable_poses(&sc, 60, 3), 1);
    let id = identify(
        &sc.rig,
        &rec,
        Level::Full,
        &rigcal_model::diagnosis::outliers::identify_options(),
    )
    .unwrap();
    let file = ModelFile::constant(&sc.rig, &id.fit, Provenance::default());
    let text = serde_json::to_string_pretty(&file).unwrap();
    assert!(
        !text.contains("\"effects\""),
        "no section when there are none"
    );
    let path = d.join("old.json");
    std::fs::write(&path, text).unwrap();
    assert!(ModelFile::load(&path).unwrap().file.effects.is_empty());
}

#[test]
fn compliance_without_masses_is_refused_with_what_to_add() {
    let rig = rigcal_core::rig::Rig::load(Path::new("rigs/rv-m2-ideal.toml")).unwrap();
    let e = EffectSpec::JointCompliance(1)
        .check(&rig.link_masses, 5)
        .unwrap_err()
        .to_string();
    assert!(e.contains("mass_kg") && e.contains("joint 2"), "{e}");
}

#[test]
fn cli_identify_with_effects_then_compensate_with_a_consistent_approach() {
    let d = dir("cli");
    let sc = scenario(
        &d,
        "cli",
        "[[effects]]\nkind = \"backlash\"\njoint = 2\nlost_motion_deg = 0.05\n",
    );
    let rec_dir = d.join("rec");
    sc.world()
        .record(&measurable_poses(&sc, 200, 4), 1)
        .write_dir(&rec_dir)
        .unwrap();
    let rig = d.join("rigs/rv-m2-masses.toml");
    let model = d.join("cli-model.json");
    let bin = env!("CARGO_BIN_EXE_rigcal");
    let out = std::process::Command::new(bin)
        .arg("identify")
        .arg("--rig")
        .arg(&rig)
        .arg("--recording")
        .arg(&rec_dir)
        .args(["--effects", "backlash:2", "--out"])
        .arg(&model)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("backlash on joint 2: lost motion 0.0"),
        "{stdout}"
    );
    let targets = d.join("targets.csv");
    let poses = measurable_poses(&sc, 5, 8);
    std::fs::write(
        &targets,
        rigcal_core::recording::commands_csv(
            sc.rig.chain.joints(),
            poses.iter().map(|q| q.as_slice()),
        ),
    )
    .unwrap();
    let cmds = d.join("commands.csv");
    let out = std::process::Command::new(bin)
        .arg("compensate")
        .arg("--model")
        .arg(&model)
        .arg("--targets")
        .arg(&targets)
        .args(["--approach", "consistent", "--out"])
        .arg(&cmds)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&cmds).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].ends_with(",move"), "{text}");
    assert_eq!(lines.len(), 1 + 2 * 5, "{text}");
    assert!(
        lines[1].ends_with(",via") && lines[2].ends_with(",target"),
        "{text}"
    );
}
