//! Compensation (seed 000 section 3.2): joint commands that bring the modelled real arm to a
//! target.
//!
//! q^n is the nominal inverse kinematics of the target; then q^c = q^n − dq^c is iterated:
//! dq^c solves J(q)·dq = P_model(q) − target with J the position Jacobian over the moving
//! joints, until the modelled error is below the tolerance (1 nm by default, well under the
//! 1 µm the method asks for). Error parameters come from an [`ErrorModel`] evaluated at the
//! target's nominal solution, so constant, region-wise and learned parameters share one path.
//! Units: mm and rad inside.

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use rigcal_core::kinematics::{
    solve_position_ik, solve_position_ik_at, ChainAt, ErrorModel, ErrorParams, IkError, IkOptions,
    Robot,
};
use rigcal_core::recording::Target;

/// Why a target cannot be compensated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CompensationError {
    /// The nominal inverse kinematics failed (unreachable, joint limit, singular).
    #[error(transparent)]
    Ik(#[from] IkError),
    /// The corrected command leaves the joint limits.
    #[error("target ({:.3}, {:.3}, {:.3}) mm: the compensated command puts joint {joint} at {value:.4} {unit}, outside {min}..{max} {unit}", target[0], target[1], target[2])]
    JointLimit {
        /// The target (mm).
        target: [f64; 3],
        /// Joint number (1-based).
        joint: usize,
        /// Commanded value (deg or mm).
        value: f64,
        /// Lower limit.
        min: f64,
        /// Upper limit.
        max: f64,
        /// `deg` or `mm`.
        unit: &'static str,
    },
    /// The iteration did not bring the modelled error under the tolerance.
    #[error("target ({:.3}, {:.3}, {:.3}) mm: compensation stopped {residual_mm:.2e} mm short after {iterations} iterations (is the target near a singular pose or a region boundary?)", target[0], target[1], target[2])]
    NotConverged {
        /// The target (mm).
        target: [f64; 3],
        /// Modelled error left (mm).
        residual_mm: f64,
        /// Iterations made.
        iterations: usize,
    },
}

/// Settings of compensation.
#[derive(Debug, Clone)]
pub struct CompensationOptions {
    /// Modelled error to reach (mm).
    pub tolerance_mm: f64,
    /// Iteration cap.
    pub max_iterations: usize,
    /// Inverse-kinematics settings for q^n.
    pub ik: IkOptions,
}

impl Default for CompensationOptions {
    fn default() -> Self {
        Self {
            tolerance_mm: 1e-6,
            max_iterations: 30,
            ik: IkOptions::default(),
        }
    }
}

/// A compensated command.
#[derive(Debug, Clone, PartialEq)]
pub struct Compensated {
    /// Nominal solution q^n (rad or mm).
    pub nominal: Vec<f64>,
    /// Command q^c (rad or mm).
    pub command: Vec<f64>,
    /// Modelled position error left at q^c (mm).
    pub residual_mm: f64,
    /// Iterations made.
    pub iterations: usize,
}

/// Compensates one target. `held[j] = Some(v)` keeps joint j at v; `seed` guides the nominal
/// inverse kinematics (the previous point of a path, say).
pub fn compensate(
    robot: &dyn Robot,
    model: &dyn ErrorModel,
    target: &Vector3<f64>,
    held: &[Option<f64>],
    seed: Option<&[f64]>,
    opts: &CompensationOptions,
) -> Result<Compensated, CompensationError> {
    let nominal_params = ErrorParams::zeros(robot.layout());
    let nominal = solve_position_ik(robot, &nominal_params, target, held, seed, &opts.ik)?;
    compensate_from(robot, model, target, held, nominal, opts)
}

/// Compensates a target whose nominal solution q^n is already known.
pub fn compensate_from(
    robot: &dyn Robot,
    model: &dyn ErrorModel,
    target: &Vector3<f64>,
    held: &[Option<f64>],
    nominal: Vec<f64>,
    opts: &CompensationOptions,
) -> Result<Compensated, CompensationError> {
    let free: Vec<usize> = (0..robot.dof())
        .filter(|&j| held.get(j).copied().flatten().is_none())
        .collect();
    // The error parameters are those at the target (the nominal solution), held while iterating,
    // so a region boundary between q^n and q^c cannot make the iteration oscillate.
    let e = model.params_at(&nominal);
    let mut q = nominal.clone();
    let mut residual = f64::INFINITY;
    let mut iterations = 0;
    while iterations < opts.max_iterations {
        let err = robot.position(&q, &e) - target;
        residual = err.norm();
        if residual <= opts.tolerance_mm {
            break;
        }
        iterations += 1;
        let j = robot.joint_jacobian(&q, &e);
        let jf = DMatrix::from_fn(3, free.len(), |r, c| j[(r, free[c])]);
        let svd = jf.svd(true, true);
        let Ok(dq) = svd.solve(&DVector::from_column_slice(err.as_slice()), 1e-12) else {
            break;
        };
        for (k, &jn) in free.iter().enumerate() {
            q[jn] -= dq[k];
        }
    }
    finish_command(robot, target, nominal, q, residual, iterations, opts)
}

/// A target of [`compensate_targets`] that could not be compensated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("target at line {line}: {source}")]
pub struct TargetError {
    /// The target's line in its file.
    pub line: u64,
    /// Why.
    pub source: CompensationError,
}

/// Compensates targets in order (each with its line in the file, as
/// [`rigcal_core::recording::read_targets`] gives them). A position target's nominal inverse
/// kinematics starts from the previous command, so a path stays on one branch; a joint target's
/// nominal position is the target, reached from its own joints, with the joints the rig holds
/// kept at the target's values. Stops at the first target that cannot be compensated.
pub fn compensate_targets(
    robot: &dyn Robot,
    model: &dyn ErrorModel,
    held: &[Option<f64>],
    targets: &[(u64, Target)],
    opts: &CompensationOptions,
) -> Result<Vec<Compensated>, TargetError> {
    targets_in_order(robot, model, held, targets, opts, true)
        .into_iter()
        .collect()
}

/// [`compensate_targets`] past failures: one result per target, in order. A target that cannot
/// be compensated is skipped, so the next one starts from the last command compensated (where
/// the arm would be).
pub fn compensate_each(
    robot: &dyn Robot,
    model: &dyn ErrorModel,
    held: &[Option<f64>],
    targets: &[(u64, Target)],
    opts: &CompensationOptions,
) -> Vec<Result<Compensated, TargetError>> {
    targets_in_order(robot, model, held, targets, opts, false)
}

/// The targets in order, the last result an error when `stop_at_first` and one failed.
fn targets_in_order(
    robot: &dyn Robot,
    model: &dyn ErrorModel,
    held: &[Option<f64>],
    targets: &[(u64, Target)],
    opts: &CompensationOptions,
    stop_at_first: bool,
) -> Vec<Result<Compensated, TargetError>> {
    let nominal = ErrorParams::zeros(robot.layout());
    let mut fast = Compensator::new(robot, model, opts);
    let mut out: Vec<Result<Compensated, TargetError>> = Vec::with_capacity(targets.len());
    let mut seed: Option<Vec<f64>> = None;
    for (line, target) in targets {
        let c = match target {
            Target::Position(p) => fast.compensate(p, held, seed.as_deref()),
            Target::Joints(q) => {
                let p = robot.position(q, &nominal);
                let held_here: Vec<Option<f64>> =
                    held.iter().zip(q).map(|(h, v)| h.map(|_| *v)).collect();
                fast.compensate_from(&p, &held_here, q.clone())
            }
        }
        .map_err(|source| TargetError {
            line: *line,
            source,
        });
        let failed = c.is_err();
        if let Ok(c) = &c {
            seed = Some(c.command.clone());
        }
        out.push(c);
        if failed && stop_at_first {
            break;
        }
    }
    out
}

/// Compensation of many targets with one robot and error model, as [`compensate`] and
/// [`compensate_from`] give it, at a fraction of the cost for a serial chain: the nominal chain
/// and the chain at the model's parameters are multiplied out once ([`ChainAt`]; the latter
/// again only when the model's parameters change from one target to the next), the nominal
/// inverse kinematics tries the seed's start on the stack first ([`solve_position_ik_at`]),
/// and the Newton steps are 3 × 3 solves on the stack. Results equal the one-target functions'
/// up to rounding. Other robots go through the one-target functions.
pub struct Compensator<'a> {
    robot: &'a dyn Robot,
    model: &'a dyn ErrorModel,
    opts: CompensationOptions,
    nominal_params: ErrorParams,
    /// The nominal chain multiplied out; `None` for robots that are not serial chains.
    nominal: Option<ChainAt>,
    /// The model's parameters at the last target and the chain at them.
    at_model: Option<(ErrorParams, ChainAt)>,
}

impl<'a> Compensator<'a> {
    /// A compensator for `robot` corrected by `model`.
    pub fn new(
        robot: &'a dyn Robot,
        model: &'a dyn ErrorModel,
        opts: &CompensationOptions,
    ) -> Self {
        let nominal_params = ErrorParams::zeros(robot.layout());
        let nominal = robot.as_serial_chain().map(|c| c.at(&nominal_params));
        Self {
            robot,
            model,
            opts: opts.clone(),
            nominal_params,
            nominal,
            at_model: None,
        }
    }

    /// [`compensate`] of one target; `seed` is the previous command along a path, say.
    pub fn compensate(
        &mut self,
        target: &Vector3<f64>,
        held: &[Option<f64>],
        seed: Option<&[f64]>,
    ) -> Result<Compensated, CompensationError> {
        let Some(nominal_chain) = &self.nominal else {
            return compensate(self.robot, self.model, target, held, seed, &self.opts);
        };
        let nominal = solve_position_ik_at(
            self.robot,
            nominal_chain,
            &self.nominal_params,
            target,
            held,
            seed,
            &self.opts.ik,
        )?;
        self.compensate_from(target, held, nominal)
    }

    /// [`compensate_from`]: a target whose nominal solution is known.
    pub fn compensate_from(
        &mut self,
        target: &Vector3<f64>,
        held: &[Option<f64>],
        nominal: Vec<f64>,
    ) -> Result<Compensated, CompensationError> {
        let Some(chain) = self.robot.as_serial_chain() else {
            return compensate_from(self.robot, self.model, target, held, nominal, &self.opts);
        };
        let mut free = [0usize; 3];
        let mut n_free = 0;
        for j in (0..self.robot.dof()).filter(|&j| held.get(j).copied().flatten().is_none()) {
            if n_free < 3 {
                free[n_free] = j;
            }
            n_free += 1;
        }
        if n_free != 3 {
            return compensate_from(self.robot, self.model, target, held, nominal, &self.opts);
        }
        let e = self.model.params_at(&nominal);
        if self.at_model.as_ref().is_none_or(|(last, _)| *last != e) {
            let at = chain.at(&e);
            self.at_model = Some((e, at));
        }
        let (_, at) = self.at_model.as_ref().expect("set just above");
        let opts = &self.opts;
        let mut q = nominal.clone();
        let mut cols = [Vector3::zeros(); 3];
        let mut residual = f64::INFINITY;
        let mut iterations = 0;
        while iterations < opts.max_iterations {
            let err = at.position(&q) - target;
            residual = err.norm();
            if residual <= opts.tolerance_mm {
                break;
            }
            iterations += 1;
            at.position_and_joint_columns(&q, &free, &mut cols);
            let Some(dq) = newton_step(&Matrix3::from_columns(&cols), &err) else {
                break;
            };
            for (k, &jn) in free.iter().enumerate() {
                q[jn] -= dq[k];
            }
        }
        finish_command(self.robot, target, nominal, q, residual, iterations, opts)
    }
}

/// The least-squares step of [`compensate_from`] (an SVD solve dropping singular values below
/// 1e-12) for a 3 × 3 Jacobian: LU when well away from singular, the SVD otherwise.
fn newton_step(j: &Matrix3<f64>, err: &Vector3<f64>) -> Option<Vector3<f64>> {
    let lu = j.lu();
    let scale = j.abs().max();
    if lu.determinant().abs() > 1e-6 * scale * scale * scale {
        if let Some(dq) = lu.solve(err) {
            return Some(dq);
        }
    }
    j.svd(true, true).solve(err, 1e-12).ok()
}

/// The convergence and joint-limit checks of [`compensate_from`] on the final command.
fn finish_command(
    robot: &dyn Robot,
    target: &Vector3<f64>,
    nominal: Vec<f64>,
    q: Vec<f64>,
    residual: f64,
    iterations: usize,
    opts: &CompensationOptions,
) -> Result<Compensated, CompensationError> {
    let arr = [target.x, target.y, target.z];
    if residual > opts.tolerance_mm {
        return Err(CompensationError::NotConverged {
            target: arr,
            residual_mm: residual,
            iterations,
        });
    }
    if let Some((jn, spec)) = robot
        .joints()
        .iter()
        .enumerate()
        .find(|(jn, s)| !s.within(q[*jn]))
    {
        return Err(CompensationError::JointLimit {
            target: arr,
            joint: jn + 1,
            value: spec.kind.to_file_units(q[jn]),
            min: spec.kind.to_file_units(spec.min),
            max: spec.kind.to_file_units(spec.max),
            unit: spec.kind.unit(),
        });
    }
    Ok(Compensated {
        nominal,
        command: q,
        residual_mm: residual,
        iterations,
    })
}
