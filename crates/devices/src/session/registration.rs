//! The registration step before a session's points (conventions §1): random reachable poses
//! measured with the nominal kinematics, the table-to-world transform fitted to them and
//! written to session.toml. A reused registration (another session's, same set-up) replaces
//! the step; a point sensor needs none (its frame is the world, or free and fitted with the
//! kinematics).

use nalgebra::{Isometry3, Vector3};

use crate::session::contact::TableContact;
use crate::session::core::{Outcome, SessionCore};
use crate::session::error::SessionError;
use crate::session::motion::Motion;
use crate::session::plan::{registration_candidates, table_target};
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::recording::{RegistrationInfo, Status};
use rigcal_core::rig::Instrument;
use rigcal_model::identification::registration::to_xyz_rpy;
use rigcal_model::identification::{register, Observation};

/// Region id of the registration rows.
const REGION: &str = "reg";

/// Registers the session's frame (see the module docs); `contact` is `None` on a point-sensor
/// rig.
pub(crate) async fn registration_step(
    core: &mut SessionCore<'_>,
    motion: &Motion,
    contact: Option<&mut TableContact>,
) -> Result<(), SessionError> {
    if let Some(info) = core.opts.registration {
        let pose = rigcal_core::rig::pose_from_xyz_rpy(info.translation_mm, info.rpy_deg);
        core.register(pose, Some(info));
        return core.write_info();
    }
    let Some(contact) = contact else {
        core.register(Isometry3::identity(), None);
        return core.write_info();
    };
    if core.opts.registration_points == 0 {
        let nominal = match &core.rig.instrument {
            Instrument::TablePanel(tp) => Isometry3::translation(
                tp.table_to_world_mm.x,
                tp.table_to_world_mm.y,
                tp.table_to_world_mm.z,
            ),
            _ => Isometry3::identity(),
        };
        core.register(nominal, Some(info(&nominal, None)));
        return core.write_info();
    }
    let obs = measure_poses(core, motion, contact).await?;
    let e = ErrorParams::zeros(core.rig.chain.layout());
    let reg = register(&core.rig.chain, &e, &obs)
        .map_err(|e| SessionError::Registration(e.to_string()))?;
    let rms = reg.stats.rms_mm;
    core.register(
        reg.world_from_instrument,
        Some(info(&reg.world_from_instrument, Some(rms))),
    );
    core.report.registration_rms_mm = Some(rms);
    core.write_info()
}

/// Measures registration poses until the options' count is reached (or the candidates run
/// out), one `via` row each with what the table measured.
async fn measure_poses(
    core: &mut SessionCore<'_>,
    motion: &Motion,
    contact: &mut TableContact,
) -> Result<Vec<Observation>, SessionError> {
    let rig = core.rig;
    let mut candidates = registration_candidates(rig, core.opts.seed);
    let mut obs = Vec::new();
    let mut k = 0usize;
    while obs.len() < core.opts.registration_points {
        let Some(q) = candidates.next() else {
            break;
        };
        let Some(nominal) = table_target(rig, &q) else {
            break;
        };
        k += 1;
        let (qc, out) = contact
            .measure(core, motion, k, REGION, &q, nominal)
            .await?;
        let mut m = core.row(qc.clone(), REGION, Status::Via);
        if let Outcome::Measured(c) = out {
            let t = Vector3::from(c.point_table_mm());
            m.table = Some(t);
            m.panel_uv = Some([c.touch.u_mm, c.touch.v_mm]);
            obs.push(Observation { q: qc, p: t });
        }
        core.report.via += 1;
        core.write(m)?;
    }
    Ok(obs)
}

/// What session.toml says of a registration.
fn info(world_from_table: &Isometry3<f64>, rms_mm: Option<f64>) -> RegistrationInfo {
    let (t, rpy) = to_xyz_rpy(world_from_table);
    RegistrationInfo {
        translation_mm: t,
        rpy_deg: rpy,
        rms_mm,
    }
}
