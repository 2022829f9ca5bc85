//! `rigcal demo`: a simulated RV-M2 with the paper's geometric errors, identified and checked.

use crate::compensation::{compensate, CompensationOptions};
use crate::identification::{analyse, candidate_order, random_poses, ResidualStats};
use crate::kinematics::{ErrorParams, Robot};
use crate::model::{ModelFile, Provenance};
use crate::recording::SessionInfo;
use crate::rig::Rig;
use crate::world::{paper_geometric_errors, World};
use anyhow::Result;
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::PathBuf;

/// The ideal-instrument RV-M2 rig, built in so the demo runs from any directory.
const RV_M2_IDEAL: &str = include_str!("../../rigs/rv-m2-ideal.toml");

/// Arguments of `rigcal demo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Directory for the recording and the model.
    #[arg(long, default_value = "out/demo")]
    out: PathBuf,
    /// Seed of the simulated arm's error signs, poses and noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Measurements to identify from.
    #[arg(long, default_value_t = 100)]
    measurements: usize,
    /// Measurement noise per coordinate (mm, 1σ).
    #[arg(long, default_value_t = 0.02)]
    noise_mm: f64,
}

pub fn run(a: Args) -> Result<()> {
    anyhow::ensure!(
        a.noise_mm >= 0.0 && a.noise_mm.is_finite(),
        "--noise-mm must be zero or positive"
    );
    let rig = Rig::parse(
        RV_M2_IDEAL,
        Some(std::path::Path::new("rigs/rv-m2-ideal.toml")),
    )?;
    let chain = &rig.chain;
    let layout = chain.layout();
    let mut rng = ChaCha8Rng::seed_from_u64(a.seed);
    println!(
        "rigcal demo: simulated {} ({}), seed {}",
        rig.robot_name, rig.name, a.seed
    );

    let design = random_poses(chain.joints(), rig.held(), 100, &mut rng);
    let ident = analyse(chain, &design, &candidate_order(&rig));
    println!("1. identifiability: rank {} of {} kinematic parameters with J4, J5 held (κ eq. 4 over random poses {:.0})", ident.rank, candidate_order(&rig).len(), ident.kappa);

    let truth = paper_geometric_errors(chain, &ident, a.seed);
    let world = World::new(chain.clone(), truth.clone(), a.noise_mm, a.seed);
    let poses = random_poses(chain.joints(), rig.held(), a.measurements, &mut rng);
    let mut rec = world.record(&poses, 1);
    rec.session = Some(SessionInfo {
        rig: Some("rigs/rv-m2-ideal.toml".into()),
        seed: Some(a.seed),
        notes: Some(format!(
            "rigcal demo: paper geometric errors (±0.4 mm / ±0.05°), noise {} mm",
            a.noise_mm
        )),
        ..Default::default()
    });
    let rec_dir = a.out.join("recording");
    rec.write_dir(&rec_dir)?;
    println!(
        "2. simulated {} measurements with ±0.4 mm / ±0.05° on the {} identifiable parameters and {} mm noise → {}",
        a.measurements,
        ident.basis.len(),
        a.noise_mm,
        rec_dir.display()
    );

    let (_, result) = super::identify::identify(&rig, &rec)?;
    println!("3. identified (Levenberg–Marquardt, column-scaled):");
    print!("{}", super::parameter_table(layout, &result, Some(&truth)));
    super::identify::print_fit_summary(&result);
    let model_path = a.out.join("model.json");
    ModelFile::constant(
        &rig,
        &result,
        Provenance {
            recording: Some(rec_dir.display().to_string()),
            measurements: result.after.n,
            notes: Some(format!("rigcal demo, seed {}", a.seed)),
        },
    )
    .save(&model_path)?;
    println!("   model → {}", model_path.display());

    let nominal = ErrorParams::zeros(layout);
    let fresh = random_poses(chain.joints(), rig.held(), 1000, &mut rng);
    let before: Vec<Vector3<f64>> = fresh
        .iter()
        .map(|q| world.true_position(q) - chain.position(q, &nominal))
        .collect();
    let after: Vec<Vector3<f64>> = fresh
        .iter()
        .map(|q| world.true_position(q) - chain.position(q, &result.params))
        .collect();
    println!("4. prediction error on 1000 fresh random poses (true position − model):");
    print_row("   nominal model", &ResidualStats::of(&before));
    print_row("   identified model", &ResidualStats::of(&after));

    let path = fig6_path(101);
    let opts = CompensationOptions::default();
    let mut seed: Option<Vec<f64>> = None;
    let mut uncal = Vec::new();
    let mut comp = Vec::new();
    for q in &path {
        let target = chain.position(q, &nominal);
        uncal.push(world.true_position(q) - target);
        let c = compensate(
            chain,
            &result.params,
            &target,
            rig.held(),
            seed.as_deref(),
            &opts,
        )?;
        comp.push(world.true_position(&c.command) - target);
        seed = Some(c.command);
    }
    println!("5. Fig. 6 joint path (60°, 60°, −35°) → (125°, 90°, −10°), 101 points, true arm vs target:");
    print_row("   uncalibrated", &ResidualStats::of(&uncal));
    print_row("   compensated", &ResidualStats::of(&comp));
    Ok(())
}

fn print_row(label: &str, s: &ResidualStats) {
    println!(
        "{label:<22} RMS {:.4} mm   mean {:.4} mm   max {:.4} mm",
        s.rms_mm, s.mean_mm, s.max_mm
    );
}

/// Seed 000's Fig. 6 path, straight in joint space, wrist at zero.
pub(crate) fn fig6_path(n: usize) -> Vec<Vec<f64>> {
    let a = [60.0f64, 60.0, -35.0];
    let b = [125.0f64, 90.0, -10.0];
    (0..n)
        .map(|k| {
            let t = k as f64 / (n.max(2) - 1) as f64;
            let mut q: Vec<f64> = (0..3)
                .map(|j| (a[j] + t * (b[j] - a[j])).to_radians())
                .collect();
            q.extend([0.0, 0.0]);
            q
        })
        .collect()
}

/// The simulated world as a division's measurer: each call is the next measurement, taken
/// `step_s` after the previous one, with the world's motion history (backlash, drift).
pub(crate) struct WorldMeasurer {
    pub world: World,
    pub seq: u64,
    pub t_s: f64,
    pub step_s: f64,
}

impl crate::division::Measurer for WorldMeasurer {
    fn measure(&mut self, q: &[f64]) -> Option<Vector3<f64>> {
        self.seq += 1;
        self.t_s += self.step_s;
        self.world.measure_at(q, self.t_s, self.seq, 0).position
    }
}
