//! Measuring a contact: the table raises the panel under the pin until the first valid touch
//! packet; the measured z is the table position read right after it (conventions §8).
//!
//! The final approach speed is chosen so that (panel latency + bus latency) × speed ≤ the
//! allowed overshoot (0.005 mm by default, rig file), both latencies from the rig file.
//!
//! Two forms: [`measure_contact`] on plain devices (one blocking wait for the touch), and
//! [`approach`], the session's, on its asynchronous device handles: the wait for the touch
//! races the drives' supervision alarm and the timeout, so a drive fault or a lost heartbeat
//! stops the table at once instead of after the timeout. (On real time the panel and the table
//! answer from their own threads; the hand-over adds microseconds to the latency the speed
//! rule allows for, a negligible overshoot at approach speeds.)
//!
//! Two ways a reading comes later than its latency shows are caught there too: a touch already
//! waiting when the wait begins (it came while a slow or repeated exchange was starting the
//! move) has its latency counted from the panel's clear, and a packet the panel dropped during
//! the wait (bad checksum, out of range; the first touch may have been it) costs the contact.
//!
//! Where the table latches the contact height itself ([`Approach::latch`], the rig file's
//! `[devices.table] touch_probe = true`, conventions §8's CiA 402 touch probe), the z drive's
//! latch is armed before the move and the height is the position it latched at the touch's
//! positive edge, read once the touch packet is in: no latency, of the panel, the bus or the
//! host, biases it. The panel still gives (u, v) and the touch/release sequencing, and the
//! position read after the touch still gives x and y (standing still) and the latency, which
//! the recording keeps.

use std::time::Duration;

use crate::devices::actor::DeviceActor;
use crate::devices::pace::Pace;
use crate::devices::supervision::Alarm;
use crate::devices::traits::{DeviceError, DeviceName, Panel, PanelStats, Table, Touch};

/// Timeout of the device exchanges around a contact.
const IO: Duration = Duration::from_secs(1);

/// The largest approach speed (mm/s) for which the overshoot between the touch and the position
/// read stays within `max_overshoot_mm`.
pub fn approach_speed(
    panel_latency: Duration,
    bus_latency: Duration,
    max_overshoot_mm: f64,
) -> f64 {
    let lat = (panel_latency + bus_latency).as_secs_f64().max(1e-6);
    max_overshoot_mm / lat
}

/// One contact measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Table position at the first valid touch packet (mm, table frame; panel centre).
    pub table_mm: [f64; 3],
    /// The touch.
    pub touch: Touch,
    /// How long the table's position took to come once the touch was seen (request to
    /// answer, on the devices' clock): the part of the overshoot the bus adds. A touch that
    /// was already waiting when [`approach`] began to wait for it (it came while the move was
    /// being started) counts from the panel's clear before the move, the earliest it can have
    /// come: its true latency is unknown and at most that. `None` where it was not measured
    /// ([`measure_contact`] has no clock).
    pub read_latency: Option<Duration>,
    /// True when `table_mm[2]` is the height the z drive latched at the touch (its
    /// touch probe), which no latency biases; false when it is the position read after the
    /// touch packet.
    pub latched: bool,
}

impl Contact {
    /// The measured point in the table frame: table position plus the panel's (u, v) offset.
    pub fn point_table_mm(&self) -> [f64; 3] {
        [
            self.table_mm[0] + self.touch.u_mm,
            self.table_mm[1] + self.touch.v_mm,
            self.table_mm[2],
        ]
    }
}

/// Raises the table at (`x`, `y`) from its current z to `z_end_mm` at `speed` (mm/s) and waits
/// up to `timeout` for a touch. The table must already stand at the approach start. On a touch
/// the position is read at once and the table halted; without one, the table is halted and
/// [`DeviceError::MissedTouch`] returned.
pub fn measure_contact(
    table: &mut dyn Table,
    panel: &mut dyn Panel,
    xy_mm: [f64; 2],
    z_start_mm: f64,
    z_end_mm: f64,
    speed: f64,
    timeout: Duration,
) -> Result<Contact, DeviceError> {
    let io = Duration::from_secs(1);
    panel.clear()?;
    table.set_speed(speed, io)?;
    table.start_move([xy_mm[0], xy_mm[1], z_end_mm], io)?;
    match panel.wait_touch(timeout) {
        Ok(touch) => {
            let table_mm = table.position(io)?;
            table.halt(io)?;
            Ok(Contact {
                table_mm,
                touch,
                read_latency: None,
                latched: false,
            })
        }
        Err(DeviceError::Timeout { .. }) => {
            let reached = table.halt(io).ok();
            Err(DeviceError::MissedTouch {
                z_from_mm: z_start_mm,
                z_to_mm: z_end_mm,
                reached_mm: reached,
            })
        }
        Err(e) => {
            let _ = table.halt(io);
            Err(e)
        }
    }
}

/// One approach of the table under the pin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Approach {
    /// Where the table stands in x and y (mm); it must already stand at the start.
    pub xy_mm: [f64; 2],
    /// The approach's start (mm, table z).
    pub z_from_mm: f64,
    /// Its end (mm): the table rises to here unless a touch comes first.
    pub z_to_mm: f64,
    /// The approach speed (mm/s).
    pub speed_mm_s: f64,
    /// How long to wait for the touch.
    pub timeout: Duration,
    /// Arm the z drive's touch-probe latch before the move and take the height it latched
    /// (see the module docs).
    pub latch: bool,
}

/// How the wait for a touch ended.
enum Ended {
    /// A touch, seen as it came — or found waiting when the wait began, with the earliest
    /// moment it can have come (the panel's clear): the move is started with several exchanges
    /// on the bus, and one slow or repeated (a lost frame costs an SDO timeout) lets the table
    /// reach the pin before the wait begins. Such a touch's reading is as late as the time
    /// since then, for all anyone knows, and its latency is counted from there.
    Touch(Touch, Option<Duration>),
    Failed(DeviceError),
    TimedOut,
}

/// Measures one contact on the session's device handles (see the module docs): the table
/// rises from `a.z_from_mm` towards `a.z_to_mm` and the first of a touch, a drive alarm or the
/// timeout ends the wait. On a touch the position is read at once and the table halted; on an
/// alarm the table is halted and the drive's error returned; without a touch, the table is
/// halted and [`DeviceError::MissedTouch`] returned.
pub async fn approach(
    table: &DeviceActor<dyn Table>,
    panel: &DeviceActor<dyn Panel>,
    alarm: &Alarm,
    pace: &Pace,
    a: &Approach,
) -> Result<Contact, DeviceError> {
    panel.run(IO, |p| p.clear()).await?;
    let cleared = pace.now();
    let before = panel.run(IO, |p| Ok(p.stats())).await?;
    let speed = a.speed_mm_s;
    if a.latch {
        table.run(IO, |t| t.arm_touch_probe(IO)).await?;
    }
    table.run(IO, move |t| t.set_speed(speed, IO)).await?;
    let target = [a.xy_mm[0], a.xy_mm[1], a.z_to_mm];
    table.run(IO, move |t| t.start_move(target, IO)).await?;
    let deadline = pace.now() + a.timeout;
    let ended = match panel.run(IO, |p| p.poll_touch(Duration::ZERO)).await? {
        // Already there: the touch came while the move was being started (see `Ended`).
        Some(t) => Ended::Touch(t, Some(cleared)),
        None => tokio::select! {
            biased;
            e = alarm.raised() => Ended::Failed(e),
            t = first_touch(panel, pace, deadline) => match t {
                Ok(t) => Ended::Touch(t, None),
                Err(e) => Ended::Failed(e),
            },
            () = pace.until(deadline) => Ended::TimedOut,
        },
    };
    match ended {
        Ended::Touch(touch, came_after) => {
            let asked = pace.now();
            let mut table_mm = table.run(IO, |t| t.position(IO)).await?;
            let since = came_after.unwrap_or(asked);
            let read_latency = Some(pace.now().saturating_sub(since));
            table.run(IO, |t| t.halt(IO)).await?;
            let latched = if a.latch {
                table.run(IO, |t| t.latched_z(IO)).await?
            } else {
                None
            };
            if let Some(z) = latched {
                table_mm[2] = z;
            }
            let after = panel.run(IO, |p| Ok(p.stats())).await?;
            packets_intact(&before, &after)?;
            Ok(Contact {
                table_mm,
                touch,
                read_latency,
                latched: latched.is_some(),
            })
        }
        Ended::TimedOut => {
            let reached = table.run(IO, |t| t.halt(IO)).await.ok();
            Err(DeviceError::MissedTouch {
                z_from_mm: a.z_from_mm,
                z_to_mm: a.z_to_mm,
                reached_mm: reached,
            })
        }
        Ended::Failed(e) => {
            // The fault is what counts; a failing halt adds nothing to it.
            let _ = table.run(IO, |t| t.halt(IO)).await;
            Err(e)
        }
    }
}

/// `Err` when the panel dropped a packet (bad checksum, out of range) between `before` and
/// `after` — during the wait for a touch: the first touch may have been that packet, and the
/// one taken, a report period (10 ms on a PenMount) later, reads the table that much higher
/// (0.004 mm at the shipped rig's approach speed, nearly the whole overshoot budget again).
/// The contact is repeated like any bad reading.
fn packets_intact(before: &PanelStats, after: &PanelStats) -> Result<(), DeviceError> {
    let dropped = (after.bad_checksum + after.out_of_range)
        .saturating_sub(before.bad_checksum + before.out_of_range);
    if dropped == 0 {
        return Ok(());
    }
    Err(DeviceError::Protocol {
        device: DeviceName::Panel,
        request: "touch".into(),
        detail: format!(
            "{dropped} packet(s) dropped (bad checksum or out of range) while waiting for the touch: the first touch may have been among them, and a later one reads the table too high"
        ),
    })
}

/// The first touch the panel reports, waited for in slices up to `deadline` (then this waits
/// on, for the timeout branch beside it to end the race).
async fn first_touch(
    panel: &DeviceActor<dyn Panel>,
    pace: &Pace,
    deadline: Duration,
) -> Result<Touch, DeviceError> {
    loop {
        let slice = pace.slice_until(deadline);
        match panel.run(slice, move |p| p.poll_touch(slice)).await? {
            Some(t) => return Ok(t),
            None => pace.yield_now().await,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn approach_speed_keeps_overshoot() {
        let v = approach_speed(Duration::from_millis(10), Duration::from_millis(2), 0.005);
        assert!((v * 0.012 - 0.005).abs() < 1e-12);
    }
}
