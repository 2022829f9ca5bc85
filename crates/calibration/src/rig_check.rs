//! Checking a model on the rig itself, where the truth is what the instrument measures: the
//! targets of a path and the commands a model compensates for them, the measured distance to
//! each target of a path session, and the floor the controller's command path sets.

use super::CalibrationError;
use nalgebra::Vector3;
use rigcal_core::kinematics::{ErrorModel, ErrorParams, Robot};
use rigcal_core::recording::{Recording, RegistrationInfo, Status};
use rigcal_core::rig::Rig;
use rigcal_model::compensation::{compensate_from, CompensationOptions};
use rigcal_model::report::PathSpec;
use std::path::Path;

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

/// The targets of `path`: the nominal positions of its points (mm).
pub fn path_targets(rig: &Rig, path: &PathSpec) -> Vec<Vector3<f64>> {
    let nominal = ErrorParams::zeros(rig.chain.layout());
    path.points
        .iter()
        .map(|q| rig.chain.position(q, &nominal))
        .collect()
}

/// The commands `model` compensates for `targets` (mm), each solved from its point of `path`.
pub fn compensated_commands(
    rig: &Rig,
    model: &dyn ErrorModel,
    path: &PathSpec,
    targets: &[Vector3<f64>],
) -> Result<Vec<Vec<f64>>, CalibrationError> {
    let opts = CompensationOptions::default();
    path.points
        .iter()
        .zip(targets)
        .map(|(q, t)| {
            compensate_from(&rig.chain, model, t, rig.held(), q.clone(), &opts)
                .map(|c| c.command)
                .map_err(|source| CalibrationError::Compensation {
                    target: [t.x, t.y, t.z],
                    source,
                })
        })
        .collect()
}

/// The measured distance to each target of the points of `region` in a path session's
/// recording (mm; NaN where the point was not measured): a session runs several passes along
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
    let k =
        rigcal_devices::devices::drivers::movemaster::controller::ControllerKinematics::of_rig(rig)
            .ok()?;
    let servo = rigcal_devices::config::DevicesConfig::read_opt(rig)
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
pub fn command_path(rig: &Rig) -> rigcal_devices::devices::CommandPath {
    rigcal_devices::config::DevicesConfig::read_opt(rig)
        .as_ref()
        .map(|d| d.arm.command_path)
        .unwrap_or_default()
}

/// The arm controller's command resolution (deg).
fn resolution_deg(rig: &Rig) -> f64 {
    rigcal_devices::config::DevicesConfig::read(rig)
        .arm
        .resolution_deg
}

#[cfg(test)]
mod tests {
    use super::*;
    use rigcal_model::report::joint_path;

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
        assert!(
            mean(&cart) < 0.08 && mean(&joint) > 0.2,
            "{joint:?} {cart:?}"
        );
        assert!(cart.iter().all(|d| *d < 0.1 * 3f64.sqrt()));
    }
}
