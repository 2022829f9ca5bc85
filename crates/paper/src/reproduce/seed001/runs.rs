//! Training a scheme on a learning set and measuring it on a validation set, and the error
//! statistics every table prints. Units: the pose's (mm, rad).

use crate::reproduce::direct_schemes::{OtherDirect, OtherDirectModel};
use crate::reproduce::evaluation::{ErrorStats, PoseErrors};
use rigcal_core::kinematics::Robot;
use rigcal_model::neural::{
    AngularSum, NeuralError, NkModel, Sample, Scheme, TrainConfig, TrainOutcome,
};
use std::time::Instant;

/// Mean and largest norm of whole error vectors.
pub(super) fn norms(v: &[Vec<f64>]) -> ErrorStats {
    ErrorStats::of(v, 0..v.first().map_or(0, Vec::len), 1.0)
}

/// One trained scheme's results on a learning and a validation set.
#[derive(Debug, Clone)]
pub struct SchemeRun {
    /// Apparent error vectors, learning set.
    pub lea_ap: Vec<Vec<f64>>,
    /// Actual error vectors, learning set (empty when the truth is unknown).
    pub lea_ac: Vec<Vec<f64>>,
    /// Apparent error vectors, validation set.
    pub val_ap: Vec<Vec<f64>>,
    /// Actual error vectors, validation set.
    pub val_ac: Vec<Vec<f64>>,
    /// Training time (s).
    pub train_s: f64,
    /// Epochs run and the one kept.
    pub epochs: (usize, usize),
}

/// Trains `scheme` on `lea` and evaluates on `lea` and `val`.
pub fn run_scheme(
    nominal: &dyn Robot,
    lea: &[Sample],
    val: &[Sample],
    scheme: Scheme,
    sum: AngularSum,
    cfg: &TrainConfig,
) -> Result<SchemeRun, NeuralError> {
    let t0 = Instant::now();
    let (model, outcome) = NkModel::train(nominal, lea, scheme, sum, cfg)?;
    let train_s = t0.elapsed().as_secs_f64();
    measure(&model, nominal, lea, val, train_s, &outcome)
}

/// The errors of a trained model on its learning and validation sets.
fn measure(
    model: &dyn PoseErrors,
    nominal: &dyn Robot,
    lea: &[Sample],
    val: &[Sample],
    train_s: f64,
    outcome: &TrainOutcome,
) -> Result<SchemeRun, NeuralError> {
    let (lap, lac) = model.errors(nominal, lea)?;
    let (vap, vac) = model.errors(nominal, val)?;
    Ok(SchemeRun {
        lea_ap: lap,
        lea_ac: lac.into_iter().flatten().collect(),
        val_ap: vap,
        val_ac: vac.into_iter().flatten().collect(),
        train_s,
        epochs: (outcome.epochs, outcome.best_epoch),
    })
}

/// The random error of every sample whose truth is known: S_noisy − S_constant.
pub(super) fn random_vecs(s: &[Sample]) -> Vec<Vec<f64>> {
    s.iter()
        .filter_map(|x| {
            x.s_true
                .as_ref()
                .map(|t| x.s.iter().zip(t).map(|(a, b)| a - b).collect())
        })
        .collect()
}

/// The error of the nominal kinematics on every sample: S − K(Q) (zero where K fails).
pub(super) fn nominal_errors(k: &dyn Robot, s: &[Sample]) -> Vec<Vec<f64>> {
    s.iter()
        .map(|x| {
            let p = k.forward(&x.q).unwrap_or_else(|_| x.s.clone());
            x.s.iter().zip(&p).map(|(a, b)| a - b).collect()
        })
        .collect()
}

/// How a table labels a random-error scale.
pub(super) fn random_label(scale: f64) -> &'static str {
    if scale >= 1.0 {
        "δLr"
    } else if scale > 0.0 {
        "δLr/2"
    } else {
        "δLr=0"
    }
}

/// Mean and max, as the tables print them.
pub(super) fn fmt_stats(s: ErrorStats) -> String {
    format!("{:>7.3} {:>7.3}", s.mean, s.max)
}

/// A direct scheme (Tables 5, 17, 18 and Fig. 7): 2 and 4 from [`rigcal_model::neural::schemes`], the
/// others from [`crate::reproduce::direct_schemes`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum AnyDirect {
    Nk(Scheme),
    Other(OtherDirect),
}

impl AnyDirect {
    pub(super) const ALL: [AnyDirect; 7] = [
        AnyDirect::Other(OtherDirect::Scheme1),
        AnyDirect::Nk(Scheme::Direct2),
        AnyDirect::Other(OtherDirect::Scheme3),
        AnyDirect::Nk(Scheme::Direct4),
        AnyDirect::Other(OtherDirect::Scheme5),
        AnyDirect::Other(OtherDirect::Scheme6),
        AnyDirect::Other(OtherDirect::Scheme7),
    ];

    /// The paper's scheme number.
    pub(super) fn number(self) -> u8 {
        match self {
            AnyDirect::Nk(s) => s.number(),
            AnyDirect::Other(s) => s.number(),
        }
    }

    /// Trains the scheme on `lea` and evaluates it on `lea` and `val`.
    pub(super) fn run(
        self,
        nominal: &dyn Robot,
        lea: &[Sample],
        val: &[Sample],
        sum: AngularSum,
        cfg: &TrainConfig,
    ) -> Result<SchemeRun, NeuralError> {
        match self {
            AnyDirect::Nk(scheme) => run_scheme(nominal, lea, val, scheme, sum, cfg),
            AnyDirect::Other(scheme) => {
                let t0 = Instant::now();
                let (model, outcome) = OtherDirectModel::train(nominal, lea, scheme, cfg)?;
                let train_s = t0.elapsed().as_secs_f64();
                measure(&model, nominal, lea, val, train_s, &outcome)
            }
        }
    }
}

/// Runs `f` for cases 1, 2 and 3 of Table 4 on threads of their own; results in case order.
pub(super) fn for_each_case<T: Send>(
    f: impl Fn(u8) -> Result<T, NeuralError> + Sync,
) -> Result<Vec<T>, NeuralError> {
    std::thread::scope(|scope| {
        let f = &f;
        let handles: Vec<_> = (1..=3u8).map(|case| scope.spawn(move || f(case))).collect();
        handles
            .into_iter()
            .map(|h| {
                h.join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
            })
            .collect()
    })
}
