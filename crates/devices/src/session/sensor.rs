//! The point-sensor procedure (a tracker, or the ideal instrument of the papers' simulations),
//! per point: the via pose, the target, one sensor reading, retries. Its thresholds are
//! [`SensorSettings`] (`[devices.sensor]` of the rig file).

use std::time::Duration;

use crate::devices::config::SensorConfig;
use crate::session::core::{Outcome, SessionCore};
use crate::session::error::SessionError;
use crate::session::motion::Motion;
use crate::session::plan::{approach_signs, via_pose};
use crate::session::recovery::{arm_move_lost, handle};
use rigcal_core::rig::Rig;

/// How the point-sensor procedure measures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorSettings {
    /// Joint offset of the pre-approach (via) pose (rad).
    pub via_delta: f64,
    /// Timeout of one reading.
    pub read_timeout: Duration,
}

impl Default for SensorSettings {
    fn default() -> Self {
        SensorSettings::from_config(&SensorConfig::default())
    }
}

impl SensorSettings {
    /// The rig file's `[devices.sensor]` (its defaults when the file has none).
    pub fn of(rig: &Rig) -> Self {
        SensorSettings::from_config(&crate::devices::config::DevicesConfig::read(rig).sensor)
    }

    /// From the `[devices.sensor]` section.
    pub fn from_config(c: &SensorConfig) -> Self {
        SensorSettings {
            via_delta: c.via_delta_deg.to_radians(),
            read_timeout: Duration::from_millis(c.read_timeout_ms),
        }
    }
}

/// The point-sensor procedure.
#[derive(Debug)]
pub(crate) struct SensorProcedure {
    settings: SensorSettings,
}

impl SensorProcedure {
    /// The procedure with the rig file's settings.
    pub fn new(rig: &Rig) -> Self {
        SensorProcedure {
            settings: SensorSettings::of(rig),
        }
    }

    /// Measures at `q`: via move, final move, one reading, retries. Returns the joints
    /// commanded and how the point ended.
    pub async fn measure(
        &self,
        core: &mut SessionCore<'_>,
        motion: &Motion,
        point: usize,
        region: &str,
        q: &[f64],
    ) -> Result<(Vec<f64>, Outcome), SessionError> {
        let signs = approach_signs(core.rig, point);
        let via = via_pose(core.rig, q, &signs, self.settings.via_delta);
        if let Some(out) = self.via(core, motion, region, &via).await? {
            return Ok((q.to_vec(), out));
        }
        let mut attempt = 0u32;
        let mut commanded: Option<Vec<f64>> = None;
        loop {
            core.before_measurement(attempt);
            let step = async {
                if commanded.is_none() {
                    let done = motion.arm_to(q).await?;
                    core.arm_q = Some(done.clone());
                    commanded = Some(done);
                }
                motion.read_sensor(self.settings.read_timeout).await
            };
            let e = match step.await {
                Ok(p) => return Ok((commanded.unwrap_or_else(|| q.to_vec()), Outcome::Seen(p))),
                Err(e) => e,
            };
            if arm_move_lost(&e) {
                commanded = None;
            }
            if let Some(out) = handle(core, motion, e, &mut attempt, "reading the sensor").await? {
                return Ok((commanded.unwrap_or_else(|| q.to_vec()), out));
            }
        }
    }

    /// The arm's move to the via pose, retried like any device error, and its `via` row;
    /// `Some` when the point is given up.
    async fn via(
        &self,
        core: &mut SessionCore<'_>,
        motion: &Motion,
        region: &str,
        via: &[f64],
    ) -> Result<Option<Outcome>, SessionError> {
        let mut attempt = 0u32;
        loop {
            core.before_measurement(attempt);
            match motion.arm_to(via).await {
                Ok(done) => {
                    core.via_row(done, region)?;
                    return Ok(None);
                }
                Err(e) => {
                    let stage = "moving to the via pose";
                    if let Some(out) = handle(core, motion, e, &mut attempt, stage).await? {
                        return Ok(Some(out));
                    }
                }
            }
        }
    }
}
