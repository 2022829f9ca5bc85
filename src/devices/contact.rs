//! Measuring a contact: the table raises the panel under the pin until the first valid touch
//! packet; the measured z is the table position read right after it (conventions §8).
//!
//! The final approach speed is chosen so that (panel latency + bus latency) × speed ≤ the
//! allowed overshoot (0.005 mm by default, rig file), both latencies from the rig file.

use std::time::Duration;

use crate::devices::traits::{DeviceError, Panel, Table, Touch};

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
            Ok(Contact { table_mm, touch })
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn approach_speed_keeps_overshoot() {
        let v = approach_speed(Duration::from_millis(10), Duration::from_millis(2), 0.005);
        assert!((v * 0.012 - 0.005).abs() < 1e-12);
    }
}
