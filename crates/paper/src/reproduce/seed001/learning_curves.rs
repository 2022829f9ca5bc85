//! Fig. 7: the mean validation error of the seven direct schemes during training, Table 5's
//! poses and fits, cases 1–3. Units: mm.

use super::poses::{scara2_samples, scara2_spread};
use super::runs::{for_each_case, norms, AnyDirect};
use super::{ReproOptions, TABLE5_LM_ITERATIONS};
use crate::reproduce::direct_schemes::OtherDirectModel;
use crate::reproduce::evaluation::{ErrorVectors, PoseErrors};
use crate::reproduce::robots::scara2::{Scara2, Scara2Errors, Scara2Real};
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use rigcal_model::neural::network::Method;
use rigcal_model::neural::{NeuralError, NkModel};
use std::fmt::Write;

/// Iterations at which Fig. 7's curves are sampled (about evenly on a log axis).
pub const FIG7_CHECKPOINTS: [usize; 17] = [
    1, 2, 3, 4, 5, 7, 10, 14, 20, 30, 40, 50, 70, 100, 140, 200, 300,
];

/// The hidden neurons of Table 5's HN column, schemes 1–7.
const FIG7_HIDDEN: [usize; 7] = [20, 20, 20, 20, 20, 15, 20];

/// One learning curve of Fig. 7.
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    /// The paper's scheme number.
    pub scheme: u8,
    /// Hidden neurons.
    pub hidden: usize,
    /// (iteration, mean validation error in mm) at [`FIG7_CHECKPOINTS`] reached; a fit that
    /// converges early ends early.
    pub points: Vec<(usize, f64)>,
}

/// Fig. 7: mean validation error during training, the seven direct schemes, cases 1–3.
#[derive(Debug, Clone, PartialEq)]
pub struct Fig7 {
    /// Curves per case (index 0 = case 1), one per scheme.
    pub cases: Vec<Vec<Curve>>,
}

impl Fig7 {
    /// A text table: the validation error of every scheme at a few iterations, per case.
    pub fn render(&self) -> String {
        let shown = [1usize, 10, 100, 300];
        let mut s = String::from(
            "== Fig. 7: 2-DOF SCARA, mean validation error (mm) during training, Levenberg–Marquardt iterations\n",
        );
        for (c, curves) in self.cases.iter().enumerate() {
            let _ = write!(s, "  case {}  {:<8}", c + 1, "scheme");
            for it in shown {
                let _ = write!(s, " {:>11}", format!("iter {it}"));
            }
            s.push('\n');
            for curve in curves {
                let _ = write!(
                    s,
                    "          {:<8}",
                    format!("{} (HN {})", curve.scheme, curve.hidden)
                );
                for it in shown {
                    // The last value reached by that iteration (a converged fit stops early).
                    let v = curve
                        .points
                        .iter()
                        .take_while(|(i, _)| *i <= it)
                        .last()
                        .map_or(f64::NAN, |p| p.1);
                    let _ = write!(s, " {v:>11.5}");
                }
                s.push('\n');
            }
        }
        s.push_str("  note: Table 5's poses and fits (46 evenly spread poses, Levenberg–Marquardt), the hidden neurons of its HN column; the paper's Fig. 7 shows 1000 epochs of its gradient descent\n");
        s
    }

    /// Comma-separated values: case, scheme, hidden, iteration, error_mm.
    pub fn csv(&self) -> String {
        let mut s = String::from("case,scheme,hidden,iteration,validation_error_mm\n");
        for (c, curves) in self.cases.iter().enumerate() {
            for curve in curves {
                for (it, e) in &curve.points {
                    let _ = writeln!(s, "{},{},{},{it},{e}", c + 1, curve.scheme, curve.hidden);
                }
            }
        }
        s
    }
}

/// Fig. 7: trains the seven direct schemes of Table 5 (its poses, Levenberg–Marquardt, the
/// hidden neurons of its HN column) and records the mean validation error at
/// [`FIG7_CHECKPOINTS`].
pub fn fig7(o: &ReproOptions) -> Result<Fig7, NeuralError> {
    let poses = o.table5_poses.max(2);
    Ok(Fig7 {
        cases: for_each_case(|case| fig7_case(o, case, poses))?,
    })
}

/// Fig. 7's curves of one case.
fn fig7_case(o: &ReproOptions, case: u8, poses: usize) -> Result<Vec<Curve>, NeuralError> {
    let nominal = Scara2::default();
    let real = Scara2Real {
        nominal,
        errors: Scara2Errors::case(case),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(o.seed.wrapping_mul(31).wrapping_add(case as u64));
    let lea = scara2_spread(&real, poses);
    let val = scara2_samples(&real, None, 1244 / o.reduce.max(1), &mut rng);
    let lm = ReproOptions {
        method: Method::LevenbergMarquardt,
        epochs: TABLE5_LM_ITERATIONS,
        ..*o
    };
    let mut curves = Vec::with_capacity(AnyDirect::ALL.len());
    for scheme in AnyDirect::ALL {
        let hidden = FIG7_HIDDEN[scheme.number() as usize - 1];
        let cfg = lm.cfg(hidden, false, o.seed + case as u64);
        let mut points = Vec::new();
        // The validation error is worked out at the checkpoints only: it costs 1244 poses.
        let mut record = |epoch: usize, errors: &dyn Fn() -> Result<ErrorVectors, NeuralError>| {
            if FIG7_CHECKPOINTS.contains(&epoch) {
                points.push((epoch, errors().map_or(f64::NAN, |e| norms(&e.0).mean)));
            }
        };
        match scheme {
            AnyDirect::Nk(s) => {
                NkModel::train_observed(&nominal, &lea, s, o.angular_sum, &cfg, &mut |e, m| {
                    record(e, &|| m.errors(&nominal, &val))
                })?;
            }
            AnyDirect::Other(s) => {
                OtherDirectModel::train_observed(&nominal, &lea, s, &cfg, &mut |e, m| {
                    record(e, &|| m.errors(&nominal, &val))
                })?;
            }
        }
        curves.push(Curve {
            scheme: scheme.number(),
            hidden,
            points,
        });
    }
    Ok(curves)
}
