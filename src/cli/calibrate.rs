//! `rigcal calibrate`: the variable D-H parameter model — recursive division, per-region CEPs and
//! a learner — from a recording (offline) or a simulated world that measures what the division
//! asks for (planning).

use crate::division::{divide, DivisionOptions, DivisionReport, Mode, Space};
use crate::identification::{analyse, candidate_order, random_poses};
use crate::learners::{self, LearnerKind};
use crate::model::{
    cep_scale, entries, summary, DivisionSummary, ModelBody, ModelFile, Provenance,
};
use crate::rig::Rig;
use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use rand::SeedableRng;
use std::path::PathBuf;

/// Arguments of `rigcal calibrate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Rig file (TOML).
    #[arg(long)]
    pub rig: PathBuf,
    /// Offline mode: divide using the points of this recording.
    #[arg(long, conflicts_with = "scenario")]
    pub recording: Option<PathBuf>,
    /// Planning mode: a simulated-world scenario measures wherever the division asks.
    #[arg(long, conflicts_with = "session")]
    pub scenario: Option<PathBuf>,
    /// Planning mode through the rig: a measurement session in this new directory measures
    /// wherever the division asks (the devices of the rig file, or emulators with --sim).
    #[arg(long, value_name = "DIR", conflicts_with = "recording")]
    pub session: Option<PathBuf>,
    /// With --session: a dry run on emulators of this scenario's world (virtual clock).
    #[arg(long, requires = "session")]
    pub sim: Option<PathBuf>,
    /// With --session: continue the session in DIR after a kill, crash or power cut. Give the
    /// first run's options again: the division asks for the points it finished once more and
    /// gets its recorded measurements, then the session measures on.
    #[arg(long, requires = "session")]
    pub resume: bool,
    /// Division space.
    #[arg(long, value_enum, default_value_t = Space::Joint)]
    pub division: Space,
    /// Demanded accuracy after compensation (mm).
    #[arg(long, default_value_t = 0.1)]
    pub accuracy_mm: f64,
    /// Most regions [default: 110 for joint, 130 for Cartesian division, as in the paper].
    #[arg(long)]
    pub max_regions: Option<usize>,
    /// Measurements per region.
    #[arg(long, default_value_t = 20)]
    pub per_region: usize,
    /// Test points per region (planning mode).
    #[arg(long, default_value_t = 20)]
    pub test_points: usize,
    /// Learner that generalises the region-wise CEPs.
    #[arg(long, value_enum, default_value_t = LearnerKind::Fcmac)]
    pub learner: LearnerKind,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Treat the region containing this point of the division space (q1,q2,q3 in degrees, or
    /// R mm,azimuth deg,elevation deg) as unmeasurable: its CEPs are dropped after the division
    /// and the learner must generalise there (seed 000 Fig. 8).
    #[arg(long, allow_hyphen_values = true, value_name = "A,B,C")]
    pub unmeasurable_at: Option<String>,
    /// Neural learners (`nn-direct`, `nn-inverse`): the scheme of seed 001, 2 (joint
    /// correction) or 4 (position correction). 4 is the default for arms: a joint correction
    /// computed by inverse kinematics blows up near singular poses (the stretched RV-M2).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(2..=4))]
    pub scheme: u8,
    /// Neural learners: hidden neurons.
    #[arg(long, default_value_t = 20)]
    pub hidden: usize,
    /// Neural learners: most epochs of batch back-propagation.
    #[arg(long, default_value_t = 3000)]
    pub epochs: usize,
    /// Neural learners: learning rate η on the batch-summed gradient [default: 0.46 / number
    /// of training poses, the paper's η = 0.01 at its 46 poses].
    #[arg(long)]
    pub learning_rate: Option<f64>,
    /// Neural learners: with `--scenario`, the number of random poses measured (the paper's
    /// 110 regions × 20).
    #[arg(long, default_value_t = 2200)]
    pub measurements: usize,
    /// Where to write the model (JSON).
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(a: Args) -> Result<()> {
    let rig = Rig::load(&a.rig)?;
    if matches!(a.learner, LearnerKind::NnDirect | LearnerKind::NnInverse) {
        return run_neural(&rig, &a);
    }
    match (&a.recording, &a.scenario) {
        (Some(dir), None) => {
            let rec = super::identify::read_recording(&rig, dir)?;
            let obs = super::observations(&rec);
            if obs.is_empty() {
                bail!("{}: no measured rows", dir.display());
            }
            let model = calibrate(
                &rig,
                Mode::Offline(&obs),
                &a,
                "offline",
                Some(dir.display().to_string()),
            )?;
            model.save(&a.out)?;
        }
        (None, Some(scenario)) => {
            let mut world = planning_world(&rig, scenario, a.seed)?;
            let model = calibrate(
                &rig,
                Mode::Planning(&mut world),
                &a,
                "planning",
                Some(format!("scenario {}", scenario.display())),
            )?;
            model.save(&a.out)?;
        }
        (None, None) if a.session.is_some() => {
            let dir = a.session.clone().unwrap_or_default();
            let model = calibrate_through_session(&rig, &a, &dir)?;
            model.save(&a.out)?;
        }
        _ => bail!("give --recording DIR (offline), --scenario FILE (planning on a simulated world) or --session DIR (planning through the rig)"),
    }
    println!("model written to {}", a.out.display());
    Ok(())
}

/// How `session.toml` notes a planning-mode session; the options that shaped it follow.
const PLANNING_NOTE: &str =
    "rigcal calibrate --session: planning-mode division, the session measures where it asks; options: ";

/// The options that decide which points a planning-mode session measures and what it measures
/// them on: a resume must be given the same.
fn planning_options(a: &Args) -> String {
    let file = |p: &std::path::Path| {
        std::fs::canonicalize(p)
            .unwrap_or_else(|_| p.to_path_buf())
            .display()
            .to_string()
    };
    format!(
        "--rig {} --sim {} --division {:?} --accuracy-mm {} --max-regions {} --per-region {} --test-points {} --seed {} --unmeasurable-at {}",
        file(&a.rig),
        a.sim.as_deref().map_or("(none: the rig)".to_string(), file),
        a.division,
        a.accuracy_mm,
        a.max_regions.map_or("(default)".to_string(), |n| n.to_string()),
        a.per_region,
        a.test_points,
        a.seed,
        a.unmeasurable_at.as_deref().unwrap_or("(none)"),
    )
}

/// Refuses to resume the planning-mode session in `dir` with options other than its own: the
/// division would ask for other points, or the session would mix measurements of two set-ups.
fn refuse_other_options(a: &Args, dir: &std::path::Path) -> Result<()> {
    let info = crate::recording::read_session_info(dir)
        .with_context(|| format!("reading {}/session.toml", dir.display()))?;
    let Some(recorded) = info
        .and_then(|i| i.notes)
        .and_then(|n| n.strip_prefix(PLANNING_NOTE).map(str::to_string))
    else {
        bail!(
            "{}: its session.toml does not say which `rigcal calibrate --session` options made it; resume only sessions this command started",
            dir.display()
        );
    };
    let now = planning_options(a);
    if recorded != now {
        bail!(
            "{} was measured with other options; resume it with the same ones\n  recorded: {recorded}\n  given:    {now}",
            dir.display()
        );
    }
    Ok(())
}

/// Planning mode through a measurement session in `dir`: every measurement the division asks
/// for is made by the devices (emulated with `--sim`) and recorded there.
fn calibrate_through_session(rig: &Rig, a: &Args, dir: &std::path::Path) -> Result<ModelFile> {
    use crate::session::{recorded_requests, Session, SessionMeasurer, SessionOptions};
    let scenario = super::session::load_scenario(rig, &a.rig, a.sim.as_deref(), None)?;
    let opened =
        crate::devices::open_rig(rig, scenario.as_ref(), crate::devices::SimClock::Virtual)?;
    let mut opts = SessionOptions::new(dir);
    opts.seed = a.seed;
    opts.resume = a.resume;
    opts.fsync = !opened.devices.clock.is_virtual();
    opts.info = crate::recording::SessionInfo {
        rig: Some(a.rig.display().to_string()),
        scenario: a.sim.as_ref().map(|p| p.display().to_string()),
        seed: scenario.as_ref().map(|s| s.seed),
        notes: Some(format!("{PLANNING_NOTE}{}", planning_options(a))),
        ..Default::default()
    };
    if a.resume {
        refuse_other_options(a, dir)?;
    }
    let mut session = Session::open(rig, opened, opts)?;
    // Read after opening: a resumed session has cut its recording back to the last finished
    // point.
    let recorded = if a.resume {
        let rec =
            crate::recording::Recording::read(dir, crate::kinematics::Robot::joints(&rig.chain))
                .with_context(|| format!("reading the session {}", dir.display()))?;
        let recorded = recorded_requests(&rec);
        if recorded.len() != session.points_done() {
            bail!(
                "{}: the journal has {} finished points but the recording {} requests of region div; was it written by `rigcal calibrate --session`?",
                dir.display(),
                session.points_done(),
                recorded.len()
            );
        }
        eprintln!(
            "resuming {}: {} finished points replayed to the division, then measuring on",
            dir.display(),
            recorded.len()
        );
        recorded
    } else {
        Vec::new()
    };
    let mut measurer = SessionMeasurer::resuming(&mut session, rig, recorded);
    let model = calibrate(
        rig,
        Mode::Planning(&mut measurer),
        a,
        "planning",
        Some(dir.display().to_string()),
    );
    let model = model.map_err(|e| {
        if e.chain().any(|c| c.is::<crate::session::SessionError>()) {
            e.context(format!(
                "the session in {} stopped; its recording keeps every finished point",
                dir.display()
            ))
        } else {
            e
        }
    })?;
    let report = session.finish()?;
    println!(
        "session {}: {} points asked for{}, {} measured, {} skipped, rig time {:.0} s ({:.2} h){}",
        dir.display(),
        report.points,
        match report.resumed_at {
            Some(k) => format!(" ({k} from earlier runs, replayed; this run's counts follow)"),
            None => String::new(),
        },
        report.ok,
        report.skipped.len(),
        report.rig_time_s,
        report.rig_time_s / 3600.0,
        if a.sim.is_some() {
            " on the virtual clock"
        } else {
            ""
        }
    );
    Ok(model)
}

/// Runs the division, trains the learner and builds the model file, printing a summary.
pub(crate) fn calibrate(
    rig: &Rig,
    mode: Mode<'_>,
    a: &Args,
    mode_name: &str,
    source: Option<String>,
) -> Result<ModelFile> {
    anyhow::ensure!(a.accuracy_mm > 0.0, "--accuracy-mm must be positive");
    anyhow::ensure!(a.per_region >= 6, "--per-region must be at least 6");
    let chain = &rig.chain;
    let design = random_poses(
        crate::kinematics::Robot::joints(chain),
        rig.held(),
        100,
        &mut rand::rngs::ChaCha8Rng::seed_from_u64(a.seed),
    );
    let ident = analyse(chain, &design, &candidate_order(rig));
    let max_regions = a.max_regions.unwrap_or(match a.division {
        Space::Joint => 110,
        Space::Cartesian => 130,
    });
    let opts = DivisionOptions {
        space: a.division,
        accuracy_mm: a.accuracy_mm,
        max_regions,
        per_region: a.per_region,
        test_points: a.test_points,
        seed: a.seed,
        ..DivisionOptions::default()
    };
    let bar = ProgressBar::new(max_regions as u64);
    bar.set_style(
        ProgressStyle::with_template("dividing {bar:30} {pos}/{len} regions {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let t0 = std::time::Instant::now();
    let mut report = divide(rig, &ident.basis, mode, &opts, |n, _| {
        bar.set_position(n as u64)
    })?;
    bar.finish_and_clear();
    if let Some(p) = &a.unmeasurable_at {
        let x = unmeasurable_point(a.division, p)?;
        let id = crate::division::forget_region(&mut report.tree, &x);
        println!("region {id} (containing {p}) treated as unmeasurable: its CEPs are dropped");
    }
    let t_div = t0.elapsed();
    let t1 = std::time::Instant::now();
    let scale = cep_scale(rig, &ident.basis);
    let init: Vec<f64> = ident
        .basis
        .iter()
        .map(|&i| report.conventional.params.get(i))
        .collect();
    let learner = learners::train(a.learner, &report.tree, &init, &scale);
    let t_learn = t1.elapsed();
    print_summary(
        &report,
        max_regions,
        a,
        mode_name,
        t_div,
        t_learn,
        learner.as_ref(),
    );
    let division = DivisionSummary {
        accuracy_mm: a.accuracy_mm,
        max_regions,
        per_region: a.per_region,
        regions: report.tree.leaf_count(),
        measurements: report.observations.len(),
        test_measurements: report.test_measurements,
        mode: mode_name.into(),
    };
    Ok(ModelFile::new(
        rig,
        Provenance {
            recording: source,
            measurements: report.observations.len(),
            notes: Some(format!(
                "{mode_name} division in {:?} space, seed {}",
                a.division, a.seed
            )),
        },
        ModelBody::Variable {
            conventional: entries(rig, &report.conventional),
            fit: summary(&report.conventional),
            division,
            tree: report.tree,
            learner,
        },
    ))
}

fn print_summary(
    r: &DivisionReport,
    max_regions: usize,
    a: &Args,
    mode: &str,
    t_div: std::time::Duration,
    t_learn: std::time::Duration,
    learner: Option<&learners::Learner>,
) {
    let leaves = r.tree.root.leaves();
    let passing = leaves
        .iter()
        .filter(|l| l.test.is_some_and(|t| t.max_mm <= a.accuracy_mm))
        .count();
    let paper = match a.division {
        Space::Joint => "110 regions, 2200 measurements",
        Space::Cartesian => "130 regions, 2600 measurements",
    };
    println!(
        "{mode} division in {:?} space, demanded accuracy {} mm, {} per region (paper: {paper})",
        a.division, a.accuracy_mm, a.per_region
    );
    println!(
        "  regions {} (cap {max_regions}), {} meet the accuracy on their test points; {} identification measurements, {} test measurements; {:.2} s",
        leaves.len(),
        passing,
        r.observations.len(),
        r.test_measurements,
        t_div.as_secs_f64()
    );
    let kappas: Vec<f64> = leaves
        .iter()
        .map(|l| l.kappa)
        .filter(|k| k.is_finite())
        .collect();
    if !kappas.is_empty() {
        let mut k = kappas.clone();
        k.sort_by(f64::total_cmp);
        println!(
            "  κ (eq. 4) per region: median {:.3e}, max {:.3e}",
            k[k.len() / 2],
            k[k.len() - 1]
        );
    }
    for l in leaves.iter().filter(|l| l.note.is_some()).take(5) {
        println!(
            "  region {} not split further: {}",
            l.id,
            l.note.as_deref().unwrap_or("")
        );
    }
    println!(
        "  conventional fit on the same data: RMS {:.4} mm, max {:.4} mm",
        r.conventional.after.rms_mm, r.conventional.after.max_mm
    );
    match learner {
        Some(crate::learners::Learner::Fcmac(f)) => {
            let rep = f.report.unwrap_or(crate::learners::TrainReport {
                epochs: 0,
                max_error: f64::NAN,
                rms_error: f64::NAN,
                converged: false,
            });
            println!(
                "  FCMAC: {:?} sensors, c = {:?}, {} association cells; {} epochs, pattern error max {:.4} RMS {:.4} (mm/deg); {:.2} s",
                f.config.cells, f.config.c, f.cell_count(), rep.epochs, rep.max_error, rep.rms_error, t_learn.as_secs_f64()
            );
        }
        Some(crate::learners::Learner::Cmac(c)) => {
            let rep = c.report.unwrap_or(crate::learners::TrainReport {
                epochs: 0,
                max_error: f64::NAN,
                rms_error: f64::NAN,
                converged: false,
            });
            println!("  CMAC: {} layers of {:?} cells; {} epochs, pattern error max {:.4} RMS {:.4}; {:.2} s", c.config.layers, c.config.cells, rep.epochs, rep.max_error, rep.rms_error, t_learn.as_secs_f64());
        }
        None => println!("  no learner: compensation uses each region's CEPs"),
    }
}

/// The scenario's world as the division's measurer; the scenario must be for this rig.
fn planning_world(rig: &Rig, scenario: &std::path::Path, _seed: u64) -> Result<WorldMeasurer> {
    let sc = crate::world::Scenario::load(scenario, None)?;
    if sc.rig.name != rig.name {
        bail!(
            "scenario {} is for rig `{}`, not `{}`: pass --rig {}",
            scenario.display(),
            sc.rig.name,
            rig.name,
            sc.rig_path.display()
        );
    }
    Ok(WorldMeasurer {
        world: sc.world(),
        seq: 0,
        t_s: 0.0,
        step_s: sc.measurement.seconds_per_point,
    })
}

/// A division-space point from file units (deg for angles, mm for R).
fn unmeasurable_point(space: Space, text: &str) -> Result<[f64; 3]> {
    let p: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| {
            anyhow::anyhow!("--unmeasurable-at `{text}`: give three numbers separated by commas")
        })?;
    anyhow::ensure!(
        p.len() == 3,
        "--unmeasurable-at `{text}`: give three numbers separated by commas"
    );
    Ok(match space {
        Space::Joint => [p[0].to_radians(), p[1].to_radians(), p[2].to_radians()],
        Space::Cartesian => [p[0], p[1].to_radians(), p[2].to_radians()],
    })
}

/// The simulated world as a division's measurer: each call is the next measurement, taken
/// `step_s` after the previous one, with the world's motion history (backlash, drift).
pub(crate) struct WorldMeasurer {
    pub world: crate::world::World,
    pub seq: u64,
    pub t_s: f64,
    pub step_s: f64,
}

impl crate::division::Measurer for WorldMeasurer {
    fn measure(
        &mut self,
        q: &[f64],
    ) -> Result<Option<crate::identification::Observation>, crate::division::MeasureError> {
        self.seq += 1;
        self.t_s += self.step_s;
        let p = self.world.measure_at(q, self.t_s, self.seq, 0).position;
        Ok(p.map(|p| crate::identification::Observation { q: q.to_vec(), p }))
    }
}

/// The network settings of `calibrate --learner nn-*` for `n` observations.
pub(crate) fn neural_config(a: &Args, n: usize) -> crate::neural::TrainConfig {
    crate::neural::TrainConfig {
        method: crate::neural::network::Method::Momentum,
        hidden: a.hidden,
        learning_rate: a.learning_rate.unwrap_or(0.46 / (0.8 * n.max(1) as f64)),
        momentum: 0.9,
        epochs: a.epochs,
        validation_fraction: 0.2,
        patience: (a.epochs / 5).max(100),
        seed: a.seed,
    }
}

/// The neural scheme of `--learner` and `--scheme`.
pub(crate) fn neural_scheme(a: &Args) -> Result<crate::neural::Scheme> {
    use crate::neural::Scheme;
    Ok(match (a.learner, a.scheme) {
        (LearnerKind::NnDirect, 2) => Scheme::Direct2,
        (LearnerKind::NnDirect, 4) => Scheme::Direct4,
        (LearnerKind::NnInverse, 2) => Scheme::Inverse2,
        (LearnerKind::NnInverse, 4) => Scheme::Inverse4,
        (_, s) => bail!("--scheme {s}: use 2 or 4 with --learner nn-direct or nn-inverse"),
    })
}

/// Trains a neural model on the rig's measurements and builds its model file.
pub(crate) fn neural_model(
    rig: &Rig,
    obs: &[crate::identification::Observation],
    a: &Args,
    source: Option<String>,
) -> Result<ModelFile> {
    let scheme = neural_scheme(a)?;
    let cfg = neural_config(a, obs.len());
    let (network, outcome) = crate::neural::rig_model::train_on_rig(rig, obs, scheme, &cfg)?;
    println!(
        "neural {} scheme {} ({} hidden, η {:.2e}, momentum {}): {} epochs, kept epoch {}, training RMS {:.4} (scaled), early-stopping RMS {:.4}; {:.2} s",
        if scheme.is_direct() { "direct" } else { "inverse" },
        scheme.number(),
        cfg.hidden,
        cfg.learning_rate,
        cfg.momentum,
        outcome.epochs,
        outcome.best_epoch,
        outcome.train_rms,
        outcome.validation_rms.unwrap_or(f64::NAN),
        network.train_seconds
    );
    Ok(ModelFile::new(
        rig,
        Provenance {
            recording: source,
            measurements: obs.len(),
            notes: Some(format!("neural scheme {}, seed {}", scheme.name(), a.seed)),
        },
        ModelBody::Neural { network },
    ))
}

fn run_neural(rig: &Rig, a: &Args) -> Result<()> {
    let (obs, source) = match (&a.recording, &a.scenario) {
        (Some(dir), None) => {
            let rec = super::identify::read_recording(rig, dir)?;
            (super::observations(&rec), Some(dir.display().to_string()))
        }
        (None, Some(scenario)) => {
            let sc = crate::world::Scenario::load(scenario, None)?;
            let poses = random_poses(
                crate::kinematics::Robot::joints(&rig.chain),
                rig.held(),
                a.measurements,
                &mut rand::rngs::ChaCha8Rng::seed_from_u64(a.seed),
            );
            let rec = sc.world().record(&poses, 0);
            (
                super::observations(&rec),
                Some(format!(
                    "scenario {}, {} random poses",
                    scenario.display(),
                    a.measurements
                )),
            )
        }
        _ => bail!("the network learns from --recording DIR or --scenario FILE (--session is planning mode of the variable D-H model: run `rigcal session` first, then --recording)"),
    };
    if obs.is_empty() {
        bail!("no measured rows");
    }
    let model = neural_model(rig, &obs, a, source)?;
    model.save(&a.out)?;
    println!("model written to {}", a.out.display());
    Ok(())
}
