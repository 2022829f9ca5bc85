//! The rig's speeds as the planner sees them: the device speeds of the rig-time estimate
//! ([`RigSpeeds`]) and the move time between two points that the optimised order minimises
//! ([`MoveTime`]), both from the rig file's `[devices]`.

use rigcal_core::rig::{Instrument, Rig};

use crate::devices::config::{DevicesConfig, TableConfig};
use crate::devices::contact::approach_speed;

/// The time the rig needs between two points (s), the metric the optimised order
/// ([`Ordering::Optimised`](crate::session::plan::Ordering::Optimised)) orders by: arm and
/// table move together, so the slower counts — the table's x and y profiles
/// (trapezoidal, at the rig file's velocity and accelerations) against the arm's largest joint
/// change at its joint speed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoveTime {
    /// Table profile velocity (mm/s); infinite on a rig without a table.
    pub table_mm_s: f64,
    /// Table acceleration (mm/s²).
    pub table_acc: f64,
    /// Table deceleration (mm/s²).
    pub table_dec: f64,
    /// Arm joint speed (deg/s); infinite to order by the table alone.
    pub arm_deg_s: f64,
}

impl MoveTime {
    /// The metric of `rig`'s devices (the table's terms only on the table rig).
    pub fn of(rig: &Rig) -> MoveTime {
        let s = RigSpeeds::of(rig);
        let table = matches!(rig.instrument, Instrument::TablePanel(_));
        MoveTime {
            table_mm_s: if table { s.table_mm_s } else { f64::INFINITY },
            table_acc: s.table_acc,
            table_dec: s.table_dec,
            arm_deg_s: s.arm_deg_s,
        }
    }

    /// The table alone, on the default drive profile (for batches without joints).
    pub fn table_only() -> MoveTime {
        let t = TableConfig::default();
        MoveTime {
            table_mm_s: t.profile_velocity_mm_s,
            table_acc: t.profile_acceleration_mm_s2,
            table_dec: t.profile_deceleration_mm_s2,
            arm_deg_s: f64::INFINITY,
        }
    }

    /// One axis's trapezoidal (or triangular) profile over `d` mm (s).
    pub(crate) fn axis_s(&self, d: f64) -> f64 {
        let d = d.abs();
        if !self.table_mm_s.is_finite() || d == 0.0 {
            return 0.0;
        }
        let (v, a, b) = (
            self.table_mm_s,
            self.table_acc.max(1e-9),
            self.table_dec.max(1e-9),
        );
        // Distance to reach v and stop again.
        let ramp = v * v / (2.0 * a) + v * v / (2.0 * b);
        if d >= ramp {
            v / a / 2.0 + v / b / 2.0 + d / v
        } else {
            // Triangular: peak speed w with w²/2a + w²/2b = d.
            let w = (2.0 * d * a * b / (a + b)).sqrt();
            w / a + w / b
        }
    }

    /// From the point at (`qa`, `ta`) to the one at (`qb`, `tb`) (s).
    pub fn between(&self, qa: &[f64], ta: &[f64; 3], qb: &[f64], tb: &[f64; 3]) -> f64 {
        let table = self.axis_s(ta[0] - tb[0]).max(self.axis_s(ta[1] - tb[1]));
        let arm = if self.arm_deg_s.is_finite() {
            largest_joint_change_deg(qa, qb) / self.arm_deg_s.max(1e-9)
        } else {
            0.0
        };
        table.max(arm)
    }
}

/// The device speeds the rig-time estimate uses (from the rig file's `[devices]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigSpeeds {
    /// Arm joint speed at the session's speed level (deg/s).
    pub arm_deg_s: f64,
    /// Table profile velocity (mm/s).
    pub table_mm_s: f64,
    /// Table acceleration (mm/s²).
    pub table_acc: f64,
    /// Table deceleration (mm/s²).
    pub table_dec: f64,
    /// Final approach speed (mm/s), from the latency rule.
    pub approach_mm_s: f64,
    /// The arm controller's reply latency (s).
    pub arm_reply_s: f64,
    /// The table's bus latency per CAN exchange (s).
    pub bus_latency_s: f64,
    /// Touch to first panel packet (s).
    pub touch_latency_s: f64,
}

impl RigSpeeds {
    /// From the rig file's device settings.
    pub fn of(rig: &Rig) -> RigSpeeds {
        let cfg = DevicesConfig::read(rig);
        let lat = std::time::Duration::from_secs_f64(
            (cfg.panel.latency_ms + cfg.table.bus_latency_ms).max(0.0) / 1000.0,
        );
        RigSpeeds {
            arm_deg_s: cfg.arm.sim_joint_speed_deg_s * f64::from(cfg.arm.speed + 1) / 10.0,
            table_mm_s: cfg.table.profile_velocity_mm_s,
            table_acc: cfg.table.profile_acceleration_mm_s2,
            table_dec: cfg.table.profile_deceleration_mm_s2,
            approach_mm_s: approach_speed(
                lat,
                std::time::Duration::ZERO,
                cfg.panel.max_overshoot_mm,
            ),
            arm_reply_s: cfg.arm.sim_reply_ms / 1000.0,
            bus_latency_s: cfg.table.bus_latency_ms / 1000.0,
            touch_latency_s: cfg.panel.latency_ms / 1000.0,
        }
    }
}

/// The largest joint change between `a` and `b` (deg).
pub(crate) fn largest_joint_change_deg(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs().to_degrees())
        .fold(0.0, f64::max)
}
