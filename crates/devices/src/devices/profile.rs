//! Trapezoidal (or triangular) motion profiles of one axis, in mm and seconds: what a CiA 402
//! drive in profile position mode executes. The table's emulator moves its axes on them, and the
//! session's rig-time estimate times table moves with them.

use std::time::Duration;

/// A trapezoidal (or triangular) position profile of one axis, in mm and seconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Profile {
    /// Start time.
    pub t0: Duration,
    /// Start position (mm).
    pub from: f64,
    /// End position (mm).
    pub to: f64,
    /// Cruise speed reached (mm/s).
    pub v: f64,
    /// Acceleration (mm/s²).
    pub acc: f64,
    /// Deceleration (mm/s²).
    pub dec: f64,
}

impl Profile {
    /// Standing still at `p`.
    pub fn still(p: f64) -> Self {
        Profile::still_from(Duration::ZERO, p)
    }

    /// Standing at `p` from `t0` on.
    pub fn still_from(t0: Duration, p: f64) -> Self {
        Profile {
            t0,
            from: p,
            to: p,
            v: 1.0,
            acc: 1.0,
            dec: 1.0,
        }
    }

    /// A move from `from` to `to` starting at `t0` with at most `vmax`, `acc`, `dec` (all > 0).
    pub fn new(t0: Duration, from: f64, to: f64, vmax: f64, acc: f64, dec: f64) -> Self {
        let d = (to - from).abs();
        let (acc, dec, vmax) = (acc.max(1e-9), dec.max(1e-9), vmax.max(1e-9));
        let v = if vmax * vmax / (2.0 * acc) + vmax * vmax / (2.0 * dec) > d {
            (2.0 * d * acc * dec / (acc + dec)).sqrt()
        } else {
            vmax
        };
        Profile {
            t0,
            from,
            to,
            v: v.max(1e-12),
            acc,
            dec,
        }
    }

    fn phases(&self) -> (f64, f64, f64) {
        let d = (self.to - self.from).abs();
        let ta = self.v / self.acc;
        let td = self.v / self.dec;
        let da = self.v * ta / 2.0;
        let dd = self.v * td / 2.0;
        let tc = ((d - da - dd) / self.v).max(0.0);
        (ta, tc, td)
    }

    /// Duration of the move (s).
    pub fn duration_s(&self) -> f64 {
        if self.from == self.to {
            return 0.0;
        }
        let (ta, tc, td) = self.phases();
        ta + tc + td
    }

    /// End time.
    pub fn end(&self) -> Duration {
        self.t0 + Duration::from_secs_f64(self.duration_s())
    }

    /// Position at `t` (mm).
    pub fn position(&self, t: Duration) -> f64 {
        if self.from == self.to || t <= self.t0 {
            return self.from;
        }
        let s = (t - self.t0).as_secs_f64();
        let (ta, tc, td) = self.phases();
        let dist = if s < ta {
            0.5 * self.acc * s * s
        } else if s < ta + tc {
            0.5 * self.v * ta + self.v * (s - ta)
        } else if s < ta + tc + td {
            let r = ta + tc + td - s;
            (self.to - self.from).abs() - 0.5 * self.dec * r * r
        } else {
            (self.to - self.from).abs()
        };
        self.from + dist * (self.to - self.from).signum()
    }

    /// Speed at `t` (mm/s, magnitude).
    pub fn speed(&self, t: Duration) -> f64 {
        if self.from == self.to || t <= self.t0 {
            return 0.0;
        }
        let s = (t - self.t0).as_secs_f64();
        let (ta, tc, td) = self.phases();
        if s < ta {
            self.acc * s
        } else if s < ta + tc {
            self.v
        } else if s < ta + tc + td {
            self.dec * (ta + tc + td - s)
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_reaches_target_with_limited_speed() {
        let p = Profile::new(Duration::from_secs(1), 10.0, 110.0, 50.0, 100.0, 200.0);
        // 0.5 s accel (12.5 mm), 0.25 s decel (6.25 mm), cruise 81.25 mm at 50 mm/s.
        assert!((p.duration_s() - (0.5 + 0.25 + 81.25 / 50.0)).abs() < 1e-9);
        assert_eq!(p.position(Duration::from_secs(1)), 10.0);
        assert!((p.position(Duration::from_millis(1500)) - 22.5).abs() < 1e-9);
        assert!((p.position(p.end()) - 110.0).abs() < 1e-9);
        assert!(p.speed(Duration::from_secs(2)) <= 50.0 + 1e-9);
        let tri = Profile::new(Duration::ZERO, 0.0, -1.0, 50.0, 100.0, 100.0);
        assert!(tri.v < 50.0);
        assert!((tri.position(tri.end()) + 1.0).abs() < 1e-9);
    }
}
