//! The neural learners (`nn-direct`, `nn-inverse`): seed 001's network on a rig's measurements,
//! stored as a neural model file.

use super::{
    check_scenario_rig, Calibrated, CalibrationError, CalibrationOptions, Figures, NeuralFigures,
    Source,
};
use rand::SeedableRng;
use rigcal_core::rig::Rig;
use rigcal_model::identification::{random_poses, Observation};
use rigcal_model::learners::LearnerKind;
use rigcal_model::model::{ModelBody, ModelFile, Provenance};
use rigcal_model::neural::{network::Method, Scheme, TrainConfig};

/// Trains a neural model on the measurements of `source` and builds its model file.
pub(super) fn calibrate(
    rig: &Rig,
    source: Source<'_>,
    opts: &CalibrationOptions,
) -> Result<Calibrated, CalibrationError> {
    let scheme = scheme(opts)?;
    let (obs, label) = measurements(rig, source, opts)?;
    if obs.is_empty() {
        return Err(CalibrationError::NoMeasurements { label });
    }
    let cfg = train_config(opts, obs.len());
    let (network, outcome) =
        rigcal_model::neural::rig_model::train_on_rig(rig, &obs, scheme, &cfg)?;
    let figures = NeuralFigures {
        scheme,
        config: cfg,
        epochs: outcome.epochs,
        best_epoch: outcome.best_epoch,
        train_rms: outcome.train_rms,
        validation_rms: outcome.validation_rms,
        train_seconds: network.train_seconds,
    };
    let model = ModelFile::new(
        rig,
        Provenance {
            recording: Some(label),
            measurements: obs.len(),
            notes: Some(format!(
                "neural scheme {}, seed {}",
                scheme.name(),
                opts.seed
            )),
        },
        ModelBody::Neural { network },
    );
    Ok(Calibrated {
        model,
        figures: Figures::Neural(figures),
    })
}

/// The measurements a network learns from, and what they are: a recording's, or random poses
/// of a scenario's world.
fn measurements(
    rig: &Rig,
    source: Source<'_>,
    opts: &CalibrationOptions,
) -> Result<(Vec<Observation>, String), CalibrationError> {
    match source {
        Source::Offline {
            observations,
            label,
        } => Ok((observations.to_vec(), label)),
        Source::Scenario(sc) => {
            check_scenario_rig(rig, sc)?;
            let n = opts.neural.measurements;
            let poses = random_poses(
                rigcal_core::kinematics::Robot::joints(&rig.chain),
                rig.held(),
                n,
                &mut rand::rngs::ChaCha8Rng::seed_from_u64(opts.seed),
            );
            let rec = sc.world().record(&poses, 0);
            Ok((
                rec.observations(),
                format!("scenario {}, {n} random poses", sc.path.display()),
            ))
        }
        Source::Measurer { .. } => Err(CalibrationError::NeuralNeedsData),
    }
}

/// The network settings for `n` observations.
fn train_config(opts: &CalibrationOptions, n: usize) -> TrainConfig {
    let nn = &opts.neural;
    TrainConfig {
        method: Method::Momentum,
        hidden: nn.hidden,
        // 0.8: the share of the poses that trains (the rest stops early).
        learning_rate: nn.learning_rate.unwrap_or(0.46 / (0.8 * n.max(1) as f64)),
        momentum: 0.9,
        epochs: nn.epochs,
        validation_fraction: 0.2,
        patience: (nn.epochs / 5).max(100),
        seed: opts.seed,
    }
}

/// The scheme of the learner and the scheme number.
fn scheme(opts: &CalibrationOptions) -> Result<Scheme, CalibrationError> {
    Ok(match (opts.learner, opts.neural.scheme) {
        (LearnerKind::NnDirect, 2) => Scheme::Direct2,
        (LearnerKind::NnDirect, 4) => Scheme::Direct4,
        (LearnerKind::NnInverse, 2) => Scheme::Inverse2,
        (LearnerKind::NnInverse, 4) => Scheme::Inverse4,
        (_, s) => return Err(CalibrationError::Scheme(s)),
    })
}

impl NeuralFigures {
    /// The figures as `rigcal calibrate` prints them.
    pub fn text(&self) -> String {
        format!(
            "neural {} scheme {} ({} hidden, η {:.2e}, momentum {}): {} epochs, kept epoch {}, training RMS {:.4} (scaled), early-stopping RMS {:.4}; {:.2} s\n",
            if self.scheme.is_direct() { "direct" } else { "inverse" },
            self.scheme.number(),
            self.config.hidden,
            self.config.learning_rate,
            self.config.momentum,
            self.epochs,
            self.best_epoch,
            self.train_rms,
            self.validation_rms.unwrap_or(f64::NAN),
            self.train_seconds
        )
    }
}
