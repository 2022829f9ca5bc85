//! Emulated PenMount 6000 touch controller on the table's z arm.
//!
//! The pin touches the panel when the true panel centre (from the table's true motion and the
//! physics) has risen to the true pin tip, with the tip over the sensitive area and the pin
//! pointing down. From the touch on, the controller samples the contact every report period and
//! sends each sample as a 6-byte packet with the touch flag a panel latency later (so the first
//! packet comes a latency after the touch, and packets of a contact keep coming for a latency
//! after the pin has lifted, as from the real controller); a packet reports where the pin
//! touched, quantised to counts: cx = ⌊(u' + 66.5)·512/133⌋, cy = ⌊(v' + 40)·256/80⌋ where
//! (u', v') is the offset from the panel centre along table x, y with the rig file's flip and
//! shift undone (conventions §8). When the contact ends, one packet without the touch flag, a
//! latency later too.
//! Faults: a missed touch (no packets for the next contact), garbage bytes before the next
//! packet, a corrupted checksum on the next packet.
//!
//! The controller's touch output (a switching output that is on while the pin touches, wired
//! to the z drive's touch-probe input where the rig latches the contact height) rises at each
//! contact's start: the emulator records that edge with the table's position at the exact
//! contact ([`TableTruth::touch_began`](crate::devices::emulators::TableTruth::touch_began)),
//! the height found from the world's geometry so that it does not depend on when the contact
//! was looked for. A missed touch raises no edge either.

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Duration;

use nalgebra::Vector3;

use crate::devices::drivers::penmount::settings::PanelConfig;
use crate::devices::emulators::faults::PanelFaultHandle;
use crate::devices::emulators::physics::SharedPhysics;
use crate::devices::emulators::{lock, ByteEmulator, SharedTable, TouchEdge};
use crate::protocols::penmount::PenMountPacket;
use rigcal_core::rig::TablePanel;

/// Scan step when looking for a change of contact.
const SCAN_STEP: Duration = Duration::from_millis(1);

/// How far before a contact's found start the exact contact height is bracketed: twice the
/// 1 µs to which [`PanelEmulator::find_change`] finds it.
const EDGE_BRACKET: Duration = Duration::from_micros(2);

/// Bisection steps for the exact contact height: 60 halve a bracket of a few nm to below a
/// float's resolution.
const BISECTIONS: usize = 60;

/// The emulated controller.
#[derive(Debug)]
pub struct PanelEmulator {
    cfg: PanelConfig,
    size: [f64; 2],
    counts: [u32; 2],
    physics: SharedPhysics,
    table: SharedTable,
    faults: PanelFaultHandle,
    checked_until: Duration,
    contact: Option<(u16, u16)>,
    suppressed: bool,
    /// The contact's next sample (a packet a latency later), while touching.
    next_sample: Option<Duration>,
    out: VecDeque<(Duration, Vec<u8>)>,
}

impl PanelEmulator {
    /// A panel of the rig's size and counts with the `[devices.panel]` settings.
    pub fn new(
        tp: &TablePanel,
        cfg: &PanelConfig,
        physics: SharedPhysics,
        table: SharedTable,
    ) -> Self {
        PanelEmulator {
            cfg: cfg.clone(),
            size: tp.panel_size_mm,
            counts: tp.panel_counts,
            physics,
            table,
            faults: PanelFaultHandle::default(),
            checked_until: Duration::ZERO,
            contact: None,
            suppressed: false,
            next_sample: None,
            out: VecDeque::new(),
        }
    }

    /// The fault and counter handle.
    pub fn faults(&self) -> PanelFaultHandle {
        Arc::clone(&self.faults)
    }

    fn latency(&self) -> Duration {
        Duration::from_secs_f64(self.cfg.latency_ms.max(0.0) / 1000.0)
    }

    fn period(&self) -> Duration {
        Duration::from_secs_f64(self.cfg.sim_report_ms.max(0.1) / 1000.0)
    }

    /// Counts where the pin touches at `t`, if it does.
    fn touch_at(&self, t: Duration) -> Option<(u16, u16)> {
        let pin = lock(&self.physics).pin(t)?;
        let table = lock(&self.table).position(t);
        let centre = lock(&self.physics).panel_centre_world(table);
        if pin.direction.z >= 0.0 || centre.z < pin.tip_mm.z {
            return None;
        }
        let u = pin.tip_mm.x - centre.x;
        let v = pin.tip_mm.y - centre.y;
        let fu = (u - self.cfg.shift_u_mm) * if self.cfg.flip_u { -1.0 } else { 1.0 };
        let fv = (v - self.cfg.shift_v_mm) * if self.cfg.flip_v { -1.0 } else { 1.0 };
        let (hu, hv) = (self.size[0] / 2.0, self.size[1] / 2.0);
        if fu.abs() > hu || fv.abs() > hv {
            return None;
        }
        let cx = ((fu + hu) * f64::from(self.counts[0]) / self.size[0]).floor();
        let cy = ((fv + hv) * f64::from(self.counts[1]) / self.size[1]).floor();
        let cx = cx.clamp(0.0, f64::from(self.counts[0].saturating_sub(1)).min(511.0)) as u16;
        let cy = cy.clamp(0.0, f64::from(self.counts[1].saturating_sub(1)).min(255.0)) as u16;
        Some((cx, cy))
    }

    /// The touch output's edge for a contact that `find_change` found beginning at `t`: the
    /// table's x and y then, and the exact contact height — where the true panel centre, at
    /// that x and y, rises to the true pin tip — by bisection in z between the table's heights
    /// a few microseconds before `t` and at `t` (to a float's resolution, far below a drive
    /// count). Where the table did not rise into the pin there (the pin came down, or the
    /// contact's start was bracketed otherwise), the table's position at `t`.
    fn touch_edge(&self, t: Duration) -> TouchEdge {
        let (before, at) = {
            let table = lock(&self.table);
            (
                table.position(t.saturating_sub(EDGE_BRACKET)),
                table.position(t),
            )
        };
        let table_mm = [at.x, at.y, at.z];
        let Some(pin) = lock(&self.physics).pin(t) else {
            return TouchEdge { at: t, table_mm };
        };
        let physics = lock(&self.physics);
        let touching =
            |z: f64| physics.panel_centre_world(Vector3::new(at.x, at.y, z)).z >= pin.tip_mm.z;
        let (mut below, mut above) = (before.z, at.z);
        if !(below < above && !touching(below) && touching(above)) {
            return TouchEdge { at: t, table_mm };
        }
        for _ in 0..BISECTIONS {
            let mid = 0.5 * (below + above);
            if touching(mid) {
                above = mid;
            } else {
                below = mid;
            }
        }
        TouchEdge {
            at: t,
            table_mm: [at.x, at.y, above],
        }
    }

    /// The first time in (from, to] at which touching differs from `touching`.
    fn find_change(&self, from: Duration, to: Duration, touching: bool) -> Option<Duration> {
        let mut a = from;
        while a < to {
            let b = (a + SCAN_STEP).min(to);
            if self.touch_at(b).is_some() != touching {
                let (mut lo, mut hi) = (a, b);
                while hi - lo > Duration::from_micros(1) {
                    let mid = lo + (hi - lo) / 2;
                    if self.touch_at(mid).is_some() != touching {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                return Some(hi);
            }
            a = b;
        }
        None
    }

    fn packet(&mut self, at: Duration, touch: bool, c: (u16, u16)) {
        if self.suppressed {
            return;
        }
        let Ok(p) = PenMountPacket::new(touch, c.0, c.1) else {
            return;
        };
        let mut f = lock(&self.faults);
        let mut bytes = std::mem::take(&mut f.garbage_before_next);
        let mut enc = p.encode();
        if f.corrupt_next_packet {
            f.corrupt_next_packet = false;
            enc[5] ^= 0x5A;
        }
        bytes.extend_from_slice(&enc);
        f.packets_sent += 1;
        self.out.push_back((at, bytes));
    }

    fn advance(&mut self, now: Duration) {
        while self.checked_until < now {
            // While touching, look for the end of the contact only up to the next sample: a
            // report must never be sent for a moment after the contact ended.
            let touching = self.contact.is_some();
            let horizon = match (touching, self.next_sample) {
                (true, Some(next)) => next.min(now),
                _ => now,
            };
            match self.find_change(self.checked_until, horizon, touching) {
                None => {
                    self.checked_until = horizon;
                    if let (Some(c), Some(next)) = (self.contact, self.next_sample) {
                        if next <= horizon {
                            self.packet(next + self.latency(), true, c);
                            self.next_sample = Some(next + self.period());
                        }
                    }
                }
                Some(t) => {
                    self.checked_until = t;
                    let lat = self.latency();
                    if touching {
                        let c = self.contact.take().unwrap_or((0, 0));
                        self.packet(t + lat, false, c);
                        self.next_sample = None;
                        self.suppressed = false;
                    } else if let Some(c) = self.touch_at(t) {
                        let z = lock(&self.table).position(t).z;
                        {
                            let mut f = lock(&self.faults);
                            self.suppressed = std::mem::take(&mut f.miss_next_touch);
                            f.last_contact_at = Some(t);
                            f.last_contact_table_z = Some(z);
                        }
                        if !self.suppressed {
                            let edge = self.touch_edge(t);
                            lock(&self.table).touch_began(edge);
                        }
                        self.contact = Some(c);
                        self.packet(t + lat, true, c);
                        self.next_sample = Some(t + self.period());
                    }
                }
            }
        }
    }
}

impl ByteEmulator for PanelEmulator {
    fn input(&mut self, _bytes: &[u8], now: Duration) {
        // The PenMount 6000 only talks; host bytes are ignored.
        self.advance(now);
    }

    fn output(&mut self, now: Duration) -> Vec<u8> {
        self.advance(now);
        let mut out = Vec::new();
        while let Some((t, _)) = self.out.front() {
            if *t > now {
                break;
            }
            if let Some((_, b)) = self.out.pop_front() {
                out.extend(b);
            }
        }
        out
    }

    fn next_event(&mut self, now: Duration, horizon: Duration) -> Option<Duration> {
        self.advance(now);
        let queued = self.out.front().map(|(t, _)| *t);
        let report = if self.suppressed {
            None
        } else {
            self.next_sample
                .filter(|_| self.contact.is_some())
                .map(|t| t + self.latency())
        };
        let change = self
            .find_change(now, horizon, self.contact.is_some())
            .map(|t| t + self.latency());
        [queued, report, change].into_iter().flatten().min()
    }
}

#[cfg(test)]
mod touch_output {
    use super::*;
    use crate::devices::emulators::physics::NominalPhysics;
    use crate::devices::emulators::{Profile, TableTruth};
    use rigcal_core::kinematics::{ErrorParams, Robot};
    use rigcal_core::rig::{Instrument, Rig};
    use std::sync::Mutex;

    fn rig() -> Rig {
        let path = std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../rigs/rv-m2.toml"
        ));
        Rig::load(path).unwrap()
    }

    /// The touch output's edge when the table rises into the pin from `t0` at `speed` (mm/s),
    /// the panel polled every `poll`.
    fn edge(rig: &Rig, t0: Duration, speed: f64, poll: Duration) -> (TouchEdge, f64) {
        let Instrument::TablePanel(tp) = &rig.instrument else {
            panic!("a table rig")
        };
        let q: Vec<f64> = [20.0f64, 45.0, -100.0, 0.0, 0.0]
            .iter()
            .map(|d| d.to_radians())
            .collect();
        let physics = NominalPhysics::nominal(rig).shared();
        lock(&physics).arm_commanded(&q, Duration::ZERO);
        let tip = rig
            .chain
            .position(&q, &ErrorParams::zeros(rig.chain.layout()));
        let at_tip = tip - tp.table_to_world_mm;
        let table: SharedTable = Arc::new(Mutex::new(TableTruth::at([0.0; 3])));
        lock(&table).axes = [
            Profile::still(at_tip.x - 20.0),
            Profile::still(at_tip.y + 10.0),
            Profile::new(t0, at_tip.z - 0.5, at_tip.z + 0.5, speed, 1e6, 1e6),
        ];
        let cfg = PanelConfig::default();
        let mut panel = PanelEmulator::new(tp, &cfg, physics, Arc::clone(&table));
        let mut now = Duration::ZERO;
        while now < t0 + Duration::from_secs(5) {
            now += poll;
            panel.output(now);
            if let Some(e) = lock(&table).first_touch(Duration::ZERO, now) {
                return (e, at_tip.z);
            }
        }
        panic!("no touch")
    }

    #[test]
    fn the_touch_output_carries_the_exact_contact_height_whatever_the_speed_or_polling() {
        let rig = rig();
        // The contact is where the nominal panel centre (table + registration) reaches the
        // nominal tip: at the table height `contact`, whatever the approach's timing.
        let runs = [
            (Duration::from_millis(3), 0.42, Duration::from_millis(1)),
            (
                Duration::from_millis(1234),
                0.42,
                Duration::from_micros(700),
            ),
            (Duration::from_millis(50), 2.9, Duration::from_millis(3)),
            (Duration::from_millis(7), 30.0, Duration::from_millis(2)),
        ];
        for (t0, speed, poll) in runs {
            let (e, contact) = edge(&rig, t0, speed, poll);
            assert!(
                (e.table_mm[2] - contact).abs() < 1e-9,
                "{speed} mm/s from {t0:?}: {} against {contact}",
                e.table_mm[2]
            );
            // The edge's moment, within the 1 µs the contact's start is found to: 0.5 mm at
            // `speed` after `t0`, plus the half of the (1e6 mm/s²) acceleration's time lost.
            let expected = t0.as_secs_f64() + 0.5 / speed + speed / (2.0 * 1e6);
            assert!((e.at.as_secs_f64() - expected).abs() < 1.5e-6, "{e:?}");
        }
    }
}
