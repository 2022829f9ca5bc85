//! The contact procedure of the table-and-panel rig, per point: the arm goes to a pre-approach
//! (via) pose while the table travels to the approach start — down to its travel height first
//! ([`travel_height`](crate::session::plan::travel_height): a clearance below the current contact, or straight to the next approach
//! start when that is lower), then x-y with the arm (both at once) — the arm goes on to the
//! target while the table rises to the approach start (both at once: that start lies a margin
//! below the tip at the via pose and at the target), and a two-stage contact follows: a
//! locating approach at the locating speed, a back-off, a quick rise to the standoff just
//! below the located contact, and the final approach from there at the latency-rule speed
//! (conventions §8). Its thresholds are [`ContactSettings`] (`[devices.contact]` of the rig
//! file). The baseline procedure ([`ContactProcedure::Baseline`]) makes the same steps one
//! after another: a clearance below both heights, the rise after the arm's last move, the
//! final approach from the back-off.
//!
//! Each final contact's reading is timed ([`Contact::read_latency`]): the table kept rising at
//! the approach speed while its position was on its way, so a reading whose latency-induced
//! overshoot — approach speed × (panel latency + the reading's latency) — exceeds the rig's
//! budget (`[devices.panel] max_overshoot_mm`) by more than [`LATENCY_SLACK`] is refused
//! ([`DeviceError::LateReading`]) and the contact repeated like any bad reading. The speed
//! rule puts a reading at the rig file's latencies exactly at the budget; the slack takes
//! the jitter of a real bus (6 ms at the shipped rig's 0.42 mm/s), while drives answering
//! 20 ms late or more are refused. A touch that came while the approach's move was still
//! being started (a lost SDO frame costs a 200 ms timeout there) counts as late from the
//! panel's clear, and a panel packet dropped during the wait costs the contact
//! ([`approach`](crate::devices::contact::approach)).
//!
//! Where the rig file says the z drive latches the contact height (`[devices.table]
//! touch_probe = true`, conventions §8's CiA 402 touch probe), both approaches arm the latch
//! and take the latched height: no latency biases it, so the latency rule above does not
//! apply to it (the latency is still measured and recorded), and the locating touch places
//! the back-off and the standoff from the true contact however late its packet came. A touch
//! packet without a latched edge costs the contact (a pin already on the panel when the latch
//! was armed, or a probe input not wired to the panel's touch output).
//!
//! The table keeps ascending z within a pass (the safety wrapper refuses anything lower than
//! the pass's top minus the retract allowance): a new pass begins with each region, each
//! registration pose, and wherever the procedure must go lower (counted as an extra pass).

use crate::devices::contact::{Approach, Contact};
use crate::devices::{DeviceError, DeviceName};
use crate::session::core::{Outcome, SessionCore};
use crate::session::error::SessionError;
use crate::session::motion::{Motion, IO};
use crate::session::plan::{approach_signs, table_target, via_pose, ContactSettings};
use crate::session::procedure::ContactProcedure;
use crate::session::recovery::{arm_move_lost, handle};
use rigcal_core::rig::{Instrument, Rig};

/// Closer than this (mm) to where it should be, the table need not move.
const AT_TARGET_MM: f64 = 1e-3;

/// How far a final contact's latency-induced overshoot may exceed the budget, as a fraction
/// of it, before the reading is refused (see the module docs).
pub(crate) const LATENCY_SLACK: f64 = 0.5;

/// How long past four panel latencies the final approach waits for the locating touch's
/// release packet before repeating the contact.
const LIFT_MARGIN: std::time::Duration = std::time::Duration::from_millis(100);

/// The final approach: its speed from the latency rule (conventions §8), and what its readings
/// are held to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct FinalApproach {
    /// The approach speed (mm/s).
    pub speed_mm_s: f64,
    /// The panel's reporting latency (rig file): the part of the overshoot no reading shows.
    pub panel_latency: std::time::Duration,
    /// The overshoot budget (mm).
    pub budget_mm: f64,
}

impl FinalApproach {
    /// The overshoot (mm) of a contact whose position took `read_latency` to come.
    pub fn overshoot_mm(&self, read_latency: std::time::Duration) -> f64 {
        self.speed_mm_s * (self.panel_latency + read_latency).as_secs_f64()
    }

    /// `Err` for a reading too late to be trusted (see the module docs); a latched height is
    /// never late.
    pub fn check(&self, c: &Contact) -> Result<(), DeviceError> {
        let Some(latency) = c.read_latency.filter(|_| !c.latched) else {
            return Ok(());
        };
        let error_mm = self.overshoot_mm(latency);
        if error_mm > self.budget_mm * (1.0 + LATENCY_SLACK) {
            return Err(DeviceError::LateReading {
                device: DeviceName::Table,
                latency,
                error_mm,
                budget_mm: self.budget_mm,
            });
        }
        Ok(())
    }
}

/// The contact procedure's settings and its pass state.
#[derive(Debug)]
pub(crate) struct TableContact {
    settings: ContactSettings,
    /// Ordinary table moves (mm/s).
    travel_mm_s: f64,
    /// The final approach: the latency rule's speed and budget.
    last: FinalApproach,
    /// The z drive latches the contact heights (`[devices.table] touch_probe`).
    latch: bool,
    /// Top of the table's z travel (mm).
    travel_z: f64,
    /// How far below a pass's top a move may go (mm).
    retract_mm: f64,
    pass_region: Option<String>,
    pass_top: Option<f64>,
    /// The current point's lower approach start (its own, or its via pose's), the height the
    /// table rises to while the arm goes from the via pose onto the target (mm).
    rise_z: f64,
}

/// Time allowed for an approach over `d` mm at `v` mm/s.
fn approach_timeout(d: f64, v: f64) -> std::time::Duration {
    std::time::Duration::from_secs_f64(2.0 * d / v + 2.0)
}

/// A touch that cannot be right (retryable).
fn bad_touch(detail: String) -> DeviceError {
    DeviceError::Protocol {
        device: DeviceName::Panel,
        request: "touch".into(),
        detail,
    }
}

/// `Err` (retryable) for a contact whose height should have been latched and was not: the
/// panel reported a touch, but the z drive's probe stored no positive edge since it was armed.
fn latched(c: &Contact, latch: bool, which: &str) -> Result<(), DeviceError> {
    if !latch || c.latched {
        return Ok(());
    }
    Err(DeviceError::Protocol {
        device: DeviceName::Table,
        request: "touch probe".into(),
        detail: format!(
            "the panel reported the {which} touch (table z {:.3} mm), but the z drive latched no positive edge of its probe input since it was armed: check that the panel controller's touch output is wired to the z drive's touch probe 1 input, which [devices.table] touch_probe = true needs",
            c.table_mm[2]
        ),
    })
}

impl TableContact {
    /// `procedure` on `rig` with the final approach `last`.
    pub fn new(rig: &Rig, last: FinalApproach, procedure: ContactProcedure) -> Self {
        let cfg = crate::devices::config::DevicesConfig::read(rig);
        TableContact {
            settings: ContactSettings::for_procedure(rig, procedure),
            travel_mm_s: cfg.table.profile_velocity_mm_s,
            last,
            latch: cfg.table.touch_probe,
            travel_z: match &rig.instrument {
                Instrument::TablePanel(tp) => tp.travel_mm.z,
                _ => f64::MAX,
            },
            retract_mm: cfg.table.pass_retract_mm,
            pass_region: None,
            pass_top: None,
            rise_z: 0.0,
        }
    }

    /// Measures at `q` with the table under `nominal`: via move, final move, two-stage contact,
    /// retries. Returns the joints commanded and how the point ended.
    pub async fn measure(
        &mut self,
        core: &mut SessionCore<'_>,
        motion: &Motion,
        point: usize,
        region: &str,
        q: &[f64],
        nominal: [f64; 3],
    ) -> Result<(Vec<f64>, Outcome), SessionError> {
        let c = self.settings;
        let rig = core.rig;
        let signs = approach_signs(rig, point);
        let via = via_pose(rig, q, &signs, c.via_delta);
        let mut start = [nominal[0], nominal[1], (nominal[2] - c.margin_mm).max(0.0)];
        let end_z = (nominal[2] + c.margin_mm).min(self.travel_z);
        self.pass(motion, region).await;
        // 1. Via pose, the table to the approach start — or lower, when the via pose (a small
        // joint offset away, to set the approach directions) brings the pin below the approach
        // start: the panel must never sit above the pin while the arm moves onto the target.
        let via_z = table_target(rig, &via).map_or(start[2], |t| t[2] - c.margin_mm);
        let via_start = [start[0], start[1], start[2].min(via_z).max(0.0)];
        self.rise_z = via_start[2];
        if let Some(out) = self.via(core, motion, region, &via, via_start).await? {
            return Ok((q.to_vec(), out));
        }
        // 2. The target, then the contact.
        let mut attempt = 0u32;
        let mut commanded: Option<Vec<f64>> = None;
        loop {
            let mut pin_on_panel = false;
            let step = self
                .target_and_contact(
                    core,
                    motion,
                    q,
                    start,
                    end_z,
                    attempt,
                    &mut commanded,
                    &mut pin_on_panel,
                )
                .await;
            let e = match step {
                Ok(contact) => {
                    let q = commanded.unwrap_or_else(|| q.to_vec());
                    return Ok((q, Outcome::Measured(contact)));
                }
                Err(e) => e,
            };
            if arm_move_lost(&e) {
                commanded = None;
            }
            if pin_on_panel {
                // The pin is lower than the nominal kinematics say, by more than the margin:
                // start the next attempt lower, never from the same place.
                start[2] = (start[2] - c.margin_mm).max(0.0);
            }
            if let Some(out) = handle(core, motion, e, &mut attempt, "measuring").await? {
                return Ok((commanded.unwrap_or_else(|| q.to_vec()), out));
            }
        }
    }

    /// The move to a point's via pose (arm and table together), retried like any device
    /// error, and its `via` row; `Some` when the point is given up.
    async fn via(
        &mut self,
        core: &mut SessionCore<'_>,
        motion: &Motion,
        region: &str,
        via: &[f64],
        start: [f64; 3],
    ) -> Result<Option<Outcome>, SessionError> {
        let mut attempt = 0u32;
        loop {
            core.before_measurement(attempt);
            match self.travel(core, motion, via, start).await {
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

    /// From wherever the table stands towards the approach start `start` while the arm goes
    /// to `via`: down to the travel height first, then x-y with the arm (at once).
    async fn travel(
        &mut self,
        core: &mut SessionCore<'_>,
        motion: &Motion,
        via: &[f64],
        start: [f64; 3],
    ) -> Result<Vec<f64>, DeviceError> {
        let c = self.settings;
        let here = self.table_here(core, motion).await?;
        // A clearance below the current contact, and no higher than the next approach start
        // (below the via pose's tip too).
        let via_z = table_target(core.rig, via).map_or(start[2], |t| t[2] - c.margin_mm);
        let clear = c.travel_z(here[2], start[2].min(via_z));
        self.new_pass_below(core, motion, clear).await?;
        if here[2] > clear + AT_TARGET_MM {
            self.table_to(core, motion, [here[0], here[1], clear])
                .await?;
        }
        motion.table_speed(self.travel_mm_s).await?;
        self.start_table(motion, [start[0], start[1], clear])
            .await?;
        core.table_at = None;
        let (q, at) = motion.arm_and_table(via).await?;
        core.table_at = Some(at);
        core.arm_q = Some(q.clone());
        Ok(q)
    }

    /// One attempt at the target: the arm onto it (unless already there), the table back to
    /// the approach start, the locating approach, the back-off and the final approach.
    #[allow(clippy::too_many_arguments)]
    async fn target_and_contact(
        &mut self,
        core: &mut SessionCore<'_>,
        motion: &Motion,
        q: &[f64],
        start: [f64; 3],
        end_z: f64,
        attempt: u32,
        commanded: &mut Option<Vec<f64>>,
        pin_on_panel: &mut bool,
    ) -> Result<Contact, DeviceError> {
        let c = self.settings;
        if commanded.is_none() {
            core.before_measurement(attempt);
            let done = self.arm_onto_target(core, motion, q, start).await?;
            core.arm_q = Some(done.clone());
            *commanded = Some(done);
        }
        // Back to the approach start (a retry): from wherever the table was halted.
        let here = self.table_here(core, motion).await?;
        self.new_pass_below(core, motion, start[2]).await?;
        if (here[2] - start[2]).abs() > AT_TARGET_MM || (here[0] - start[0]).abs() > AT_TARGET_MM {
            self.table_to(core, motion, start).await?;
        }
        let xy = [start[0], start[1]];
        let locate = Approach {
            xy_mm: xy,
            z_from_mm: start[2],
            z_to_mm: end_z,
            speed_mm_s: c.fast_mm_s,
            timeout: approach_timeout(end_z - start[2], c.fast_mm_s),
            latch: self.latch,
        };
        let first = motion.contact(&locate).await;
        core.table_at = None;
        self.raise_top(end_z);
        let first = first?;
        if first.table_mm[2] <= start[2] + c.z_tolerance_mm {
            *pin_on_panel = true;
            return Err(bad_touch(format!(
                "touch at the approach start (z {:.3} mm): the pin was already on the panel",
                first.table_mm[2]
            )));
        }
        latched(&first, self.latch, "locating")?;
        let off = |t: &Contact| t.touch.u_mm.abs().max(t.touch.v_mm.abs());
        if off(&first) > c.max_offset_mm {
            return Err(bad_touch(format!(
                "touch at ({:.2}, {:.2}) mm from the panel centre, more than {} mm: a stale or misread packet",
                first.touch.u_mm, first.touch.v_mm, c.max_offset_mm
            )));
        }
        // Off the panel (as far as ever, so the release is seen before the final approach),
        // then quickly back up to the standoff: only that last stretch is crept.
        let back = (first.table_mm[2] - c.backoff_mm).max(0.0);
        motion.table_speed(self.travel_mm_s).await?;
        self.start_table(motion, [xy[0], xy[1], back]).await?;
        motion.table_reached().await?;
        // A touched panel reports for its latency after the pin lifts: only after its release
        // packet can no packet of the locating touch be taken for the final one.
        let wait = self.last.panel_latency * 4 + LIFT_MARGIN;
        if !motion
            .panel()?
            .run(IO, move |p| p.wait_lifted(wait))
            .await?
        {
            *pin_on_panel = true;
            return Err(bad_touch(format!(
                "the panel still reports the locating touch {} ms after the back-off of {} mm: the pin was not seen lifted",
                wait.as_millis(),
                c.backoff_mm
            )));
        }
        let from = (first.table_mm[2] - c.standoff_mm).max(back);
        if from > back + AT_TARGET_MM {
            self.start_table(motion, [xy[0], xy[1], from]).await?;
            motion.table_reached().await?;
        }
        let top = (first.table_mm[2] + 2.0 * c.backoff_mm).min(self.travel_z);
        let last = Approach {
            xy_mm: xy,
            z_from_mm: from,
            z_to_mm: top,
            speed_mm_s: self.last.speed_mm_s,
            timeout: approach_timeout(top - from, self.last.speed_mm_s),
            latch: self.latch,
        };
        let fin = motion.contact(&last).await;
        self.raise_top(top);
        let fin = fin?;
        core.table_at = Some(fin.table_mm);
        self.last.check(&fin)?;
        let du = (fin.touch.u_mm - first.touch.u_mm).abs();
        let dv = (fin.touch.v_mm - first.touch.v_mm).abs();
        if fin.table_mm[2] <= from + c.z_tolerance_mm {
            // The pin below the standoff: the next attempt starts lower.
            *pin_on_panel = true;
            return Err(bad_touch(format!(
                "final touch at its start (z {:.3} mm): the pin was on the panel, the standoff of {} mm below the locating touch too small",
                fin.table_mm[2], c.standoff_mm
            )));
        }
        latched(&fin, self.latch, "final")?;
        if du.max(dv) > c.max_disagreement_mm || fin.table_mm[2] < from - c.z_tolerance_mm {
            return Err(bad_touch(format!(
                "final touch at ({:.2}, {:.2}) mm, z {:.3} mm disagrees with the locating touch at ({:.2}, {:.2}) mm, z {:.3} mm",
                fin.touch.u_mm, fin.touch.v_mm, fin.table_mm[2], first.touch.u_mm, first.touch.v_mm, first.table_mm[2]
            )));
        }
        Ok(fin)
    }

    /// The arm onto the target `q`. Where the table stands below the rise height right under
    /// the approach start (after the travel), it rises there at the same time: that height is
    /// a margin below the tip at the via pose and at the target alike.
    async fn arm_onto_target(
        &mut self,
        core: &mut SessionCore<'_>,
        motion: &Motion,
        q: &[f64],
        start: [f64; 3],
    ) -> Result<Vec<f64>, DeviceError> {
        if self.settings.procedure == ContactProcedure::Baseline {
            // One move after another: the table rises once the arm is on the target.
            return motion.arm_to(q).await;
        }
        let here = self.table_here(core, motion).await?;
        let rise = [start[0], start[1], self.rise_z.min(start[2])];
        let under =
            (here[0] - rise[0]).abs() <= AT_TARGET_MM && (here[1] - rise[1]).abs() <= AT_TARGET_MM;
        if !(under && here[2] < rise[2] - AT_TARGET_MM) {
            return motion.arm_to(q).await;
        }
        motion.table_speed(self.travel_mm_s).await?;
        self.start_table(motion, rise).await?;
        core.table_at = None;
        let (done, at) = motion.arm_and_table(q).await?;
        core.table_at = Some(at);
        Ok(done)
    }

    /// Where the table stands: as last seen, or read.
    async fn table_here(
        &self,
        core: &SessionCore<'_>,
        motion: &Motion,
    ) -> Result<[f64; 3], DeviceError> {
        match core.table_at {
            Some(p) => Ok(p),
            None => motion.table()?.run(IO, |t| t.position(IO)).await,
        }
    }

    /// A table move at travel speed to `target`, waited for; where it ended.
    async fn table_to(
        &mut self,
        core: &mut SessionCore<'_>,
        motion: &Motion,
        target: [f64; 3],
    ) -> Result<[f64; 3], DeviceError> {
        motion.table_speed(self.travel_mm_s).await?;
        self.start_table(motion, target).await?;
        core.table_at = None;
        let at = motion.table_reached().await?;
        core.table_at = Some(at);
        Ok(at)
    }

    /// Starts a table move and tracks the pass's top.
    async fn start_table(&mut self, motion: &Motion, target: [f64; 3]) -> Result<(), DeviceError> {
        motion.start_table(target).await?;
        self.raise_top(target[2]);
        Ok(())
    }

    fn raise_top(&mut self, z: f64) {
        self.pass_top = Some(self.pass_top.map_or(z, |top| top.max(z)));
    }

    /// Going down to `z` would break the ascending pass: start a new one (away from the pin).
    async fn new_pass_below(
        &mut self,
        core: &mut SessionCore<'_>,
        motion: &Motion,
        z: f64,
    ) -> Result<(), DeviceError> {
        if let Some(top) = self.pass_top {
            if z < top - self.retract_mm {
                motion.begin_pass().await?;
                self.pass_top = None;
                core.report.extra_passes += 1;
            }
        }
        Ok(())
    }

    /// The pass rule: a new ascending-z pass whenever the region changes (and for every
    /// registration pose).
    async fn pass(&mut self, motion: &Motion, region: &str) {
        if self.pass_region.as_deref() != Some(region) || region == "reg" {
            // A point-sensor rig has no table, and nothing to start.
            let _ = motion.begin_pass().await;
            self.pass_top = None;
            self.pass_region = Some(region.to_string());
        }
    }

    /// Returns the table to `t` on a resume (a new pass: it may have to go down).
    pub async fn table_back(
        &mut self,
        core: &mut SessionCore<'_>,
        motion: &Motion,
        t: [f64; 3],
    ) -> Result<[f64; 3], DeviceError> {
        motion.begin_pass().await?;
        let at = self.table_to(core, motion, t).await;
        self.pass_top = None;
        at
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::devices::contact::approach_speed;
    use crate::devices::Touch;
    use std::time::Duration;

    fn contact(read_latency: Option<Duration>) -> Contact {
        Contact {
            table_mm: [0.0; 3],
            touch: Touch {
                counts: [0, 0],
                u_mm: 0.0,
                v_mm: 0.0,
            },
            read_latency,
            latched: false,
        }
    }

    #[test]
    fn a_reading_at_the_rigs_latencies_passes_and_a_late_one_is_refused() {
        // The shipped rig: panel 10 ms, bus 2 ms, budget 0.005 mm: 0.42 mm/s.
        let (panel, bus) = (Duration::from_millis(10), Duration::from_millis(2));
        let last = FinalApproach {
            speed_mm_s: approach_speed(panel, bus, 0.005),
            panel_latency: panel,
            budget_mm: 0.005,
        };
        assert!((last.overshoot_mm(bus) - 0.005).abs() < 1e-12);
        assert!(last.check(&contact(Some(bus))).is_ok());
        assert!(last.check(&contact(Some(Duration::from_millis(7)))).is_ok());
        assert!(last.check(&contact(None)).is_ok());
        let e = last
            .check(&contact(Some(Duration::from_millis(20))))
            .unwrap_err();
        match e {
            DeviceError::LateReading { error_mm, .. } => {
                assert!((error_mm - 0.0125).abs() < 1e-9, "{error_mm}")
            }
            other => panic!("{other}"),
        }
        assert!(last
            .check(&contact(Some(Duration::from_millis(9))))
            .is_err());
        // A height the z drive latched at the touch: no latency biases it, none refuses it.
        let latched = Contact {
            latched: true,
            ..contact(Some(Duration::from_millis(150)))
        };
        assert!(last.check(&latched).is_ok());
    }

    #[test]
    fn a_touch_without_a_latched_edge_costs_the_contact_only_where_the_rig_latches() {
        let read = contact(Some(Duration::from_millis(2)));
        assert!(latched(&read, false, "final").is_ok());
        let e = latched(&read, true, "final").unwrap_err();
        assert!(e.is_retryable(), "{e}");
        assert!(e.to_string().contains("probe input"), "{e}");
        let ok = Contact {
            latched: true,
            ..read
        };
        assert!(latched(&ok, true, "final").is_ok());
    }
}
