//! `rigcal compare`: conventional calibration, the variable D-H model with FCMAC (seed 000) and
//! the neuro-kinematic model (seed 001) on one recording and one validation set, side by side:
//! mean/max error on the validation set (apparent against the measurements, actual against the
//! simulated truth when a scenario gives it), along the paper's paths, measurements used and
//! training time; as a table (terminal and Markdown) and SVG plots.

use super::calibrate;
use crate::division::{Mode, Space};
use crate::identification::{analyse, candidate_order, fit, random_poses, FitOptions, Observation};
use crate::kinematics::{ErrorModel, ErrorParams, Robot};
use crate::learners::LearnerKind;
use crate::recording::Recording;
use crate::report::{evaluate_path, joint_path, plot_errors, spherical_path, PathResult};
use crate::rig::Rig;
use anyhow::{bail, Context, Result};
use rand::SeedableRng;
use std::fmt::Write;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `rigcal compare`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Rig file (TOML).
    #[arg(long)]
    pub rig: PathBuf,
    /// The simulated truth: simulates the recording and validation set when they are not given,
    /// and gives actual errors and the paths.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// The recording every method is fitted on.
    #[arg(long)]
    pub recording: Option<PathBuf>,
    /// A validation recording (otherwise random poses of the scenario).
    #[arg(long)]
    pub validation: Option<PathBuf>,
    /// Measurements simulated when no recording is given (the paper's 110 regions × 20).
    #[arg(long, default_value_t = 2200)]
    pub measurements: usize,
    /// Validation poses simulated when no validation recording is given.
    #[arg(long, default_value_t = 1000)]
    pub validation_points: usize,
    /// Demanded accuracy of the variable D-H model's division (mm).
    #[arg(long, default_value_t = 0.02)]
    pub accuracy_mm: f64,
    /// Paths (with a scenario): `fig6`, `fig7`. Repeatable.
    #[arg(long = "path", default_values_t = vec!["fig6".to_string(), "fig7".to_string()])]
    pub paths: Vec<String>,
    /// Neural network: scheme 2 or 4.
    #[arg(long, default_value_t = 4)]
    pub scheme: u8,
    /// Neural network: hidden neurons.
    #[arg(long, default_value_t = 20)]
    pub hidden: usize,
    /// Neural network: most epochs.
    #[arg(long, default_value_t = 3000)]
    pub epochs: usize,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Directory for the table (`compare.md`), plots (SVG) and CSVs.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

struct Method {
    name: String,
    model: Box<dyn ErrorModel>,
    measurements: usize,
    train_s: f64,
}

fn cal_args(a: &Args, learner: LearnerKind, out: PathBuf) -> calibrate::Args {
    calibrate::Args {
        rig: a.rig.clone(),
        recording: None,
        scenario: None,
        session: None,
        sim: None,
        resume: false,
        division: Space::Joint,
        accuracy_mm: a.accuracy_mm,
        max_regions: None,
        per_region: 20,
        test_points: 20,
        learner,
        seed: a.seed,
        unmeasurable_at: None,
        scheme: a.scheme,
        hidden: a.hidden,
        epochs: a.epochs,
        learning_rate: None,
        measurements: a.measurements,
        out,
    }
}

pub fn run(a: Args) -> Result<()> {
    let rig = Rig::load(&a.rig)?;
    let scenario = match &a.scenario {
        Some(p) => {
            let sc = crate::world::Scenario::load(p, None)?;
            if sc.rig.name != rig.name {
                bail!(
                    "scenario {} is for rig `{}`, not `{}`",
                    p.display(),
                    sc.rig.name,
                    rig.name
                );
            }
            Some(sc)
        }
        None => None,
    };
    let world = scenario.as_ref().map(|s| s.world());
    let joints = rig.chain.joints().to_vec();
    let record = |n: usize, seed: u64| -> Result<Vec<Observation>> {
        let Some(w) = &world else {
            bail!("give --scenario to simulate measurements, or --recording and --validation");
        };
        let poses = random_poses(
            &joints,
            rig.held(),
            n,
            &mut rand::rngs::ChaCha8Rng::seed_from_u64(seed),
        );
        Ok(super::observations(&w.record(&poses, seed << 32)))
    };
    let read = |dir: &PathBuf| -> Result<Vec<Observation>> {
        let rec = Recording::read(dir, &joints)?;
        Ok(super::observations(&rec))
    };
    let (obs, source) = match &a.recording {
        Some(d) => (read(d)?, d.display().to_string()),
        None => (
            record(a.measurements, a.seed)?,
            format!("{} simulated random poses", a.measurements),
        ),
    };
    let val = match &a.validation {
        Some(d) => read(d)?,
        None => record(a.validation_points, a.seed + 1000)?,
    };
    anyhow::ensure!(
        !obs.is_empty() && !val.is_empty(),
        "no measured rows to fit or validate on"
    );

    let mut methods: Vec<Method> = vec![Method {
        name: "uncalibrated".into(),
        model: Box::new(ErrorParams::zeros(rig.chain.layout())),
        measurements: 0,
        train_s: 0.0,
    }];
    // Conventional calibration.
    let t0 = Instant::now();
    let design = random_poses(
        &joints,
        rig.held(),
        100,
        &mut rand::rngs::ChaCha8Rng::seed_from_u64(a.seed),
    );
    let ident = analyse(&rig.chain, &design, &candidate_order(&rig));
    let conv = fit(
        &rig.chain,
        &obs,
        &ErrorParams::zeros(rig.chain.layout()),
        &ident.basis,
        &FitOptions::default(),
    )?;
    methods.push(Method {
        name: "conventional".into(),
        model: Box::new(conv.params.clone()),
        measurements: obs.len(),
        train_s: t0.elapsed().as_secs_f64(),
    });
    // Variable D-H model with FCMAC, offline on the same measurements.
    println!(
        "== variable D-H model (seed 000), offline division at {} mm",
        a.accuracy_mm
    );
    let t0 = Instant::now();
    let ca = cal_args(&a, LearnerKind::Fcmac, PathBuf::from("-"));
    let vfile = calibrate::calibrate(
        &rig,
        Mode::Offline(&obs),
        &ca,
        "offline",
        Some(source.clone()),
    )?;
    let vt = t0.elapsed().as_secs_f64();
    let vmeas = match &vfile.model {
        crate::model::ModelBody::Variable { division, .. } => division.measurements,
        _ => obs.len(),
    };
    let mut vmodels = vfile.error_models(&rig, std::path::Path::new("-"))?;
    vmodels.truncate(2); // fcmac, regions (the conventional one is above)
    for (name, model) in vmodels {
        methods.push(Method {
            name: format!("variable D-H: {name}"),
            model,
            measurements: vmeas,
            train_s: vt,
        });
    }
    // Neural network.
    println!("== neuro-kinematic model (seed 001)");
    let na = cal_args(&a, LearnerKind::NnDirect, PathBuf::from("-"));
    let t0 = Instant::now();
    let nfile = calibrate::neural_model(&rig, &obs, &na, Some(source.clone()))?;
    let nt = t0.elapsed().as_secs_f64();
    let (nname, nmodel) = nfile
        .error_models(&rig, std::path::Path::new("-"))?
        .into_iter()
        .next()
        .context("the neural model file holds no model")?;
    methods.push(Method {
        name: format!("neural: {nname}"),
        model: nmodel,
        measurements: obs.len(),
        train_s: nt,
    });

    // Validation errors.
    let stats = |v: &[f64]| -> (f64, f64) {
        let n = v.len().max(1) as f64;
        (
            v.iter().sum::<f64>() / n,
            v.iter().copied().fold(0.0, f64::max),
        )
    };
    let mut rows = Vec::new();
    for m in &methods {
        let mut ap = Vec::with_capacity(val.len());
        let mut ac = Vec::with_capacity(val.len());
        for o in &val {
            let p = rig.chain.position(&o.q, &m.model.params_at(&o.q));
            ap.push((p - o.p).norm());
            if let Some(w) = &world {
                ac.push((p - w.true_position(&o.q)).norm());
            }
        }
        rows.push((stats(&ap), (!ac.is_empty()).then(|| stats(&ac))));
    }
    // Paths.
    let mut path_results: Vec<(String, Vec<PathResult>)> = Vec::new();
    if let Some(w) = &world {
        let truth = |q: &[f64]| w.true_position(q);
        let refs: Vec<(String, &dyn ErrorModel)> = methods
            .iter()
            .skip(1)
            .map(|m| (m.name.clone(), m.model.as_ref()))
            .collect();
        for p in &a.paths {
            let spec = match p.as_str() {
                "fig6" => joint_path(
                    &rig,
                    "Fig. 6 joint path",
                    &[60.0, 60.0, -35.0],
                    &[125.0, 90.0, -10.0],
                    101,
                ),
                "fig7" => spherical_path(
                    &rig,
                    "Fig. 7 spherical path",
                    [640.0, 20.0, 0.0],
                    [740.0, 125.0, -20.0],
                    101,
                )?,
                other => bail!("unknown path `{other}`: use fig6 or fig7"),
            };
            path_results.push((p.clone(), evaluate_path(&rig, &spec, &refs, &truth, &[])));
        }
    }

    // The table.
    let mut md = String::new();
    let _ = write!(
        md,
        "| method | measurements | training (s) | validation mean / max, apparent (mm) | actual (mm) |"
    );
    for (p, _) in &path_results {
        let _ = write!(md, " {p} mean / max (mm) |");
    }
    md.push('\n');
    let _ = write!(md, "|---|---|---|---|---|");
    for _ in &path_results {
        md.push_str("---|");
    }
    md.push('\n');
    for (k, m) in methods.iter().enumerate() {
        let ((apm, apx), ac) = rows[k];
        let acs = ac.map_or("—".to_string(), |(m, x)| format!("{m:.4} / {x:.4}"));
        let _ = write!(
            md,
            "| {} | {} | {:.2} | {apm:.4} / {apx:.4} | {acs} |",
            m.name, m.measurements, m.train_s
        );
        for (_, res) in &path_results {
            let r = res
                .iter()
                .find(|r| r.model == m.name || (k == 0 && r.model == "uncalibrated"));
            match r {
                Some(r) => {
                    let s = r.stats();
                    let _ = write!(md, " {:.4} / {:.4} |", s.mean_mm, s.max_mm);
                }
                None => md.push_str(" — |"),
            }
        }
        md.push('\n');
    }
    println!("\n{md}");
    println!(
        "validation: {} poses; apparent = against the measurements, actual = against the simulated truth",
        val.len()
    );
    if let Some(dir) = &a.out {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let f = dir.join("compare.md");
        std::fs::write(&f, &md).with_context(|| format!("cannot write {}", f.display()))?;
        for (p, res) in &path_results {
            let svg = dir.join(format!("compare-{p}.svg"));
            plot_errors(
                &svg,
                &format!("position error along {p}: three calibrations"),
                res,
            )?;
            println!("plot: {}", svg.display());
        }
        println!("table: {}", f.display());
    }
    Ok(())
}
