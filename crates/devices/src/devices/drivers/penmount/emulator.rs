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

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Duration;

use crate::devices::drivers::penmount::settings::PanelConfig;
use crate::devices::emulators::faults::PanelFaultHandle;
use crate::devices::emulators::physics::SharedPhysics;
use crate::devices::emulators::{lock, ByteEmulator, SharedTable};
use crate::protocols::penmount::PenMountPacket;
use rigcal_core::rig::TablePanel;

/// Scan step when looking for a change of contact.
const SCAN_STEP: Duration = Duration::from_millis(1);

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
