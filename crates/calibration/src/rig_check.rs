//! Checking a model on the rig itself, where the truth is what the instrument measures: a path
//! the rig can measure at every point, the nominal and the compensated commands along it (each
//! measured as a session of its own), the measured distance to each target, and the floor the
//! controller's command resolution sets.

use super::CalibrationError;
use nalgebra::Vector3;
use rigcal_core::kinematics::{ErrorModel, ErrorParams, Robot};
use rigcal_core::recording::{Recording, RegistrationInfo, Status};
use rigcal_core::rig::Rig;
use rigcal_devices::session::plan::{table_target, REFERENCE_REGION};
use rigcal_devices::session::PlannedPoint;
use rigcal_model::compensation::{compensate_from, CompensationOptions};
use rigcal_model::report::{joint_path, plot_errors, PathError, PathResult, PathSpec};
use std::fmt::Write as _;
use std::path::Path;

/// Region id of the path's points in their sessions.
pub const PATH_REGION: &str = "path";

/// The longest straight joint path of `points` points between two of the first 80 planned
/// points of a rig session (drift references left out) whose every point the rig can measure.
pub fn measurable_path(rig: &Rig, planned: &[PlannedPoint], points: usize) -> Option<PathSpec> {
    let pts: Vec<&Vec<f64>> = planned
        .iter()
        .filter(|p| p.region != REFERENCE_REGION)
        .take(80)
        .map(|p| &p.q)
        .collect();
    let nominal = ErrorParams::zeros(rig.chain.layout());
    let mut best: Option<(f64, PathSpec)> = None;
    for (i, a) in pts.iter().enumerate() {
        for b in &pts[i + 1..] {
            let length = (rig.chain.position(a, &nominal) - rig.chain.position(b, &nominal)).norm();
            if best.as_ref().is_some_and(|(l, _)| *l >= length) {
                continue;
            }
            let spec = straight_path(rig, a, b, points);
            if spec.points.iter().all(|q| rig.measurable(q).is_ok()) {
                best = Some((length, spec));
            }
        }
    }
    best.map(|(_, s)| s)
}

/// The joint line from `a` to `b` (rad, mm), named by its ends in file units.
fn straight_path(rig: &Rig, a: &[f64], b: &[f64], points: usize) -> PathSpec {
    let joints = rig.chain.joints();
    let file_units = |q: &[f64]| -> Vec<f64> {
        rig.moving_joints()
            .iter()
            .map(|&j| joints[j].kind.to_file_units(q[j]))
            .collect()
    };
    let (da, db) = (file_units(a), file_units(b));
    let fmt = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:.1}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let name = format!("joint path ({}) → ({})", fmt(&da), fmt(&db));
    joint_path(rig, &name, &da, &db, points)
}

/// The registration an earlier session in `dir` made (its `session.toml`), for a path session
/// that reuses it so both recordings share one frame.
pub fn registration_of(rig: &Rig, dir: &Path) -> Result<RegistrationInfo, CalibrationError> {
    let rec =
        Recording::read(dir, rig.chain.joints()).map_err(|source| CalibrationError::Recording {
            path: dir.to_path_buf(),
            source,
        })?;
    rec.session
        .and_then(|s| s.registration)
        .ok_or_else(|| CalibrationError::NoRegistration {
            dir: dir.to_path_buf(),
        })
}

/// The commands along a path: its targets (the nominal positions), the nominal commands and
/// the commands `model` compensates.
#[derive(Debug, Clone, PartialEq)]
pub struct PathCommands {
    /// Target per point (mm).
    pub targets: Vec<Vector3<f64>>,
    /// Nominal commands (the path's points).
    pub nominal: Vec<Vec<f64>>,
    /// Compensated commands.
    pub compensated: Vec<Vec<f64>>,
}

/// The nominal and compensated commands of `path` under `model`.
pub fn path_commands(
    rig: &Rig,
    model: &dyn ErrorModel,
    path: &PathSpec,
) -> Result<PathCommands, CalibrationError> {
    let nominal = ErrorParams::zeros(rig.chain.layout());
    let targets: Vec<Vector3<f64>> = path
        .points
        .iter()
        .map(|q| rig.chain.position(q, &nominal))
        .collect();
    let opts = CompensationOptions::default();
    let compensated = path
        .points
        .iter()
        .zip(&targets)
        .map(|(q, t)| {
            compensate_from(&rig.chain, model, t, rig.held(), q.clone(), &opts)
                .map(|c| c.command)
                .map_err(|source| CalibrationError::Compensation {
                    target: [t.x, t.y, t.z],
                    source,
                })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(PathCommands {
        targets,
        nominal: path.points.clone(),
        compensated,
    })
}

/// A session plan that measures at `commands`, one point each, region [`PATH_REGION`].
pub fn path_plan(rig: &Rig, commands: &[Vec<f64>]) -> Vec<PlannedPoint> {
    commands
        .iter()
        .enumerate()
        .map(|(k, q)| PlannedPoint {
            point: k + 1,
            region: PATH_REGION.into(),
            q: q.clone(),
            table_mm: table_target(rig, q).unwrap_or_default(),
        })
        .collect()
}

/// The measured distance to each target of a path session's recording (mm); NaN where the
/// point was not measured.
pub fn measured_errors(rec: &Recording, targets: &[Vector3<f64>]) -> Vec<f64> {
    measured_errors_in(rec, PATH_REGION, targets)
}

/// [`measured_errors`] of the points of `region`: a session that runs several passes along
/// one path, each its own region.
pub fn measured_errors_in(rec: &Recording, region: &str, targets: &[Vector3<f64>]) -> Vec<f64> {
    rec.rows
        .iter()
        .filter(|m| m.region.as_deref() == Some(region) && m.status != Status::Via)
        .zip(targets)
        .map(|(m, t)| m.position.map_or(f64::NAN, |p| (p - t).norm()))
        .collect()
}

/// How far rounding each command to the arm controller's resolution moves the nominal tip
/// (mm): the floor of joint-command compensation on the rig.
pub fn resolution_floor(rig: &Rig, commands: &[Vec<f64>]) -> Vec<f64> {
    let step = resolution_deg(rig).to_radians();
    let nominal = ErrorParams::zeros(rig.chain.layout());
    commands
        .iter()
        .map(|q| {
            let rounded: Vec<f64> = q.iter().map(|v| (v / step).round() * step).collect();
            (rig.chain.position(&rounded, &nominal) - rig.chain.position(q, &nominal)).norm()
        })
        .collect()
}

/// How far the Cartesian command path moves the nominal tip from each command (mm): the pose
/// rounded to 0.1 mm / 0.1°, solved by the controller's nominal inverse kinematics, rounded to
/// its servo resolution: the floor of `MP` compensation on the rig. `None` if the rig's
/// controller has no Cartesian kinematics or a command has no solution.
pub fn cartesian_floor(rig: &Rig, commands: &[Vec<f64>]) -> Option<Vec<f64>> {
    let k = rigcal_devices::devices::controller::ControllerKinematics::of_rig(rig).ok()?;
    let servo = rigcal_devices::config::DevicesConfig::read_opt(&rig)
        .as_ref()
        .map_or(0.001, |d| d.arm.sim_servo_resolution_deg);
    commands
        .iter()
        .map(|q| {
            let landed = k.landing(q, servo).ok()?;
            Some((k.world_position(&landed) - k.world_position(q)).norm())
        })
        .collect()
}

/// The rig's command path for compensated moves.
pub fn command_path(rig: &Rig) -> rigcal_devices::devices::controller::CommandPath {
    rigcal_devices::config::DevicesConfig::read_opt(&rig)
        .as_ref()
        .map(|d| d.arm.command_path)
        .unwrap_or_default()
}

/// The arm controller's command resolution (deg).
pub fn resolution_deg(rig: &Rig) -> f64 {
    rigcal_devices::config::DevicesConfig::read(&rig)
        .arm
        .resolution_deg
}

/// A model checked on the rig along a path: the distance to each target the rig measured at the
/// nominal commands (`uncalibrated`) and at the commands the model compensates, and the floor
/// the controller's command resolution sets.
#[derive(Debug, Clone)]
pub struct RigPathCheck {
    /// The path's name.
    pub path: String,
    /// Points of the path.
    pub points: usize,
    /// Measured distance to target per point: uncalibrated, then the model.
    pub results: Vec<PathResult>,
    /// What rounding the compensated commands to the controller's resolution moves the tip (mm).
    pub floor_mm: Vec<f64>,
    /// The controller's command resolution (deg).
    pub resolution_deg: f64,
    /// What the Cartesian path's rounding moves the compensated tip (mm), if the controller has one.
    pub floor_cartesian_mm: Option<Vec<f64>>,
    /// The command path the compensated session went through.
    pub command_path: rigcal_devices::devices::controller::CommandPath,
}

impl RigPathCheck {
    /// The check from the recordings of the two path sessions: at `commands.nominal` and at
    /// `commands.compensated` (by the model named `model`).
    pub fn new(
        rig: &Rig,
        path: &PathSpec,
        commands: &PathCommands,
        model: &str,
        nominal: &Recording,
        compensated: &Recording,
    ) -> Self {
        let result = |name: &str, rec: &Recording| PathResult {
            model: name.to_string(),
            errors: measured_errors(rec, &commands.targets),
            traces: Vec::new(),
            failures: 0,
        };
        Self {
            path: path.name.clone(),
            points: path.points.len(),
            results: vec![result("uncalibrated", nominal), result(model, compensated)],
            floor_mm: resolution_floor(rig, &commands.compensated),
            resolution_deg: resolution_deg(rig),
            floor_cartesian_mm: cartesian_floor(rig, &commands.compensated),
            command_path: command_path(rig),
        }
    }

    /// Plots the measured distances along the path (SVG).
    pub fn plot(&self, file: &Path) -> Result<(), PathError> {
        plot_errors(
            file,
            &format!("distance to target measured by the rig along {}", self.path),
            &self.results,
        )
    }

    /// The check as `rigcal demo` prints it, with the plot's file.
    pub fn text(&self, plot: &Path) -> String {
        let mut s = format!(
            "{} ({} points), measured by the rig (panel quantisation and table accuracy included):\n",
            self.path, self.points
        );
        for r in &self.results {
            let st = r.stats();
            let missed = r.errors.iter().filter(|e| e.is_nan()).count();
            let _ = writeln!(
                s,
                "  {:<14} mean {:.4} mm   max {:.4} mm   {missed} point(s) not measured",
                r.model, st.mean_mm, st.max_mm
            );
        }
        let _ = writeln!(s, "  plot: {}", plot.display());
        let _ = writeln!(
            s,
            "  the controller's {}° command resolution alone moves the compensated tip by {:.4} mm mean, {:.4} mm max: the floor of joint-command compensation on this rig",
            self.resolution_deg,
            self.floor_mm.iter().sum::<f64>() / self.floor_mm.len().max(1) as f64,
            self.floor_mm.iter().copied().fold(0.0, f64::max)
        );
        if let Some(f) = &self.floor_cartesian_mm {
            let _ = writeln!(
                s,
                "  the Cartesian path (MP, 0.1 mm / 0.1°, then the servo) alone moves it by {:.4} mm mean, {:.4} mm max: the floor of MP compensation",
                f.iter().sum::<f64>() / f.len().max(1) as f64,
                f.iter().copied().fold(0.0, f64::max)
            );
        }
        let _ = writeln!(
            s,
            "  compensated commands went through the {} path",
            self.command_path
        );
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cartesian_floor_is_an_order_below_the_joint_floor() {
        let rig = Rig::load(Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../rigs/rv-m2.toml"
        )))
        .unwrap();
        let path = joint_path(
            &rig,
            "test",
            &[-20.0, 40.0, -60.0],
            &[25.0, 70.0, -100.0],
            41,
        );
        // Commands off the 0.1° grid, as compensated ones are.
        let commands: Vec<Vec<f64>> = path
            .points
            .iter()
            .enumerate()
            .map(|(k, q)| {
                let mut q = q.clone();
                for v in q.iter_mut().take(3) {
                    *v += (0.0123 * k as f64 + 0.031).to_radians();
                }
                q
            })
            .collect();
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let joint = resolution_floor(&rig, &commands);
        let cart = cartesian_floor(&rig, &commands).unwrap();
        eprintln!(
            "floors: joint {:.4} mean {:.4} max, cartesian {:.4} mean {:.4} max",
            mean(&joint),
            joint.iter().copied().fold(0.0, f64::max),
            mean(&cart),
            cart.iter().copied().fold(0.0, f64::max)
        );
        assert!(
            mean(&cart) < 0.08 && mean(&joint) > 0.2,
            "{joint:?} {cart:?}"
        );
        assert!(cart.iter().all(|d| *d < 0.1 * 3f64.sqrt()));
    }
}
