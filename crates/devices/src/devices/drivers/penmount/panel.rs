//! Driver for the PenMount 6000 touch panel over a serial line.
//!
//! Protocol: [`crate::protocols::penmount`], 6-byte packets the controller sends by itself.
//! Packets with a bad checksum or out of range are counted and dropped by the decoder, which
//! resynchronises on the next header; they never become a measurement.
//!
//! Units (conventions §8): raw counts cx 0..511, cy 0..255 over the effective area
//! 133 × 80 mm; u_mm = (cx + 0.5)·133/512 − 66.5 along table +x, v_mm = (cy + 0.5)·80/256 − 40
//! along table +y, then the rig file's flip (sign) and shift. Size and counts come from the
//! rig's `[instrument]`.

use std::time::Duration;

use crate::devices::clock::SharedClock;
use crate::devices::drivers::penmount::settings::PanelConfig;
use crate::devices::traits::{DeviceError, DeviceName, Panel, PanelStats, Touch};
use crate::protocols::penmount::PenMountDecoder;
use crate::transports::{ByteTransport, TransportError};

/// The PenMount driver over any byte transport.
#[derive(Debug)]
pub struct PenMountPanel<T: ByteTransport> {
    io: T,
    clock: SharedClock,
    cfg: PanelConfig,
    size: [f64; 2],
    counts: [u32; 2],
    decoder: PenMountDecoder,
    earlier: PanelStats,
    /// The touch flag of the last packet decoded since the last clear (false before any).
    touching: bool,
}

impl<T: ByteTransport> PenMountPanel<T> {
    /// A driver for a panel of `size_mm` and `counts` with the `[devices.panel]` settings.
    pub fn new(
        io: T,
        size_mm: [f64; 2],
        counts: [u32; 2],
        cfg: &PanelConfig,
        clock: SharedClock,
    ) -> Self {
        PenMountPanel {
            io,
            clock,
            cfg: cfg.clone(),
            size: size_mm,
            counts,
            decoder: PenMountDecoder::new(),
            earlier: PanelStats::default(),
            touching: false,
        }
    }

    /// Converts raw counts to (u, v) in mm from the panel centre (conventions §8).
    pub fn to_mm(&self, cx: u16, cy: u16) -> (f64, f64) {
        counts_to_mm(cx, cy, self.size, self.counts, &self.cfg)
    }
}

impl<T: ByteTransport> PenMountPanel<T> {
    /// The first touch packet within `timeout` (clock time), `None` if none came.
    fn touch_within(&mut self, timeout: Duration) -> Result<Option<Touch>, DeviceError> {
        let deadline = self.clock.now() + timeout;
        let mut buf = [0u8; 64];
        loop {
            let remaining = deadline.saturating_sub(self.clock.now());
            match self.io.read(&mut buf, remaining) {
                Ok(n) => {
                    // Every packet read updates the contact state (a release right behind the
                    // touch counts), the first touch is the answer.
                    let mut first = None;
                    for p in self.decoder.push(buf.get(..n).unwrap_or(&[])) {
                        self.touching = p.touch;
                        if p.touch && first.is_none() {
                            let (u_mm, v_mm) = self.to_mm(p.x, p.y);
                            first = Some(Touch {
                                counts: [p.x, p.y],
                                u_mm,
                                v_mm,
                            });
                        }
                    }
                    if first.is_some() {
                        return Ok(first);
                    }
                }
                Err(TransportError::Timeout { .. }) => return Ok(None),
                Err(source) => {
                    return Err(DeviceError::Transport {
                        device: DeviceName::Panel,
                        source,
                    })
                }
            }
            if self.clock.now() >= deadline {
                return Ok(None);
            }
        }
    }
}

/// Raw counts to (u, v) mm from the panel centre, with the rig file's flips and shifts.
fn counts_to_mm(
    cx: u16,
    cy: u16,
    size: [f64; 2],
    counts: [u32; 2],
    cfg: &PanelConfig,
) -> (f64, f64) {
    let u = (f64::from(cx) + 0.5) * size[0] / f64::from(counts[0]) - size[0] / 2.0;
    let v = (f64::from(cy) + 0.5) * size[1] / f64::from(counts[1]) - size[1] / 2.0;
    let u = if cfg.flip_u { -u } else { u } + cfg.shift_u_mm;
    let v = if cfg.flip_v { -v } else { v } + cfg.shift_v_mm;
    (u, v)
}

impl<T: ByteTransport> Panel for PenMountPanel<T> {
    fn clear(&mut self) -> Result<(), DeviceError> {
        self.io
            .clear_input()
            .map_err(|source| DeviceError::Transport {
                device: DeviceName::Panel,
                source,
            })?;
        // Drop what is buffered and a partial packet; keep the counters.
        let mut buf = [0u8; 256];
        for _ in 0..4096 {
            match self.io.read(&mut buf, Duration::ZERO) {
                Ok(n) if n > 0 => {}
                _ => break,
            }
        }
        self.earlier = self.stats();
        self.decoder = PenMountDecoder::new();
        self.touching = false;
        Ok(())
    }

    fn wait_lifted(&mut self, timeout: Duration) -> Result<bool, DeviceError> {
        let deadline = self.clock.now() + timeout;
        let mut buf = [0u8; 64];
        while self.touching {
            let remaining = deadline.saturating_sub(self.clock.now());
            if remaining.is_zero() {
                return Ok(false);
            }
            match self.io.read(&mut buf, remaining) {
                Ok(n) => {
                    if let Some(p) = self.decoder.push(buf.get(..n).unwrap_or(&[])).last() {
                        self.touching = p.touch;
                    }
                }
                Err(TransportError::Timeout { .. }) => return Ok(false),
                Err(source) => {
                    return Err(DeviceError::Transport {
                        device: DeviceName::Panel,
                        source,
                    })
                }
            }
        }
        Ok(true)
    }

    fn wait_touch(&mut self, timeout: Duration) -> Result<Touch, DeviceError> {
        let start = self.clock.now();
        match self.touch_within(timeout)? {
            Some(t) => Ok(t),
            None => Err(DeviceError::Timeout {
                device: DeviceName::Panel,
                waiting_for: "a touch packet".into(),
                waited: self.clock.now().saturating_sub(start),
                target: "touch".into(),
                current: format!("{:?}", self.stats()),
            }),
        }
    }

    fn poll_touch(&mut self, slice: Duration) -> Result<Option<Touch>, DeviceError> {
        self.touch_within(slice)
    }

    fn stats(&self) -> PanelStats {
        let s = self.decoder.stats();
        let e = self.earlier;
        PanelStats {
            good: e.good + s.good,
            bad_checksum: e.bad_checksum + s.bad_checksum,
            out_of_range: e.out_of_range + s.out_of_range,
            discarded_bytes: e.discarded_bytes + s.discarded_bytes,
        }
    }

    fn latency(&self) -> Duration {
        Duration::from_secs_f64(self.cfg.latency_ms.max(0.0) / 1000.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_convert_as_conventions_say() {
        let cfg = PanelConfig::default();
        let (u, v) = counts_to_mm(0, 0, [133.0, 80.0], [512, 256], &cfg);
        assert!((u - (0.5 * 133.0 / 512.0 - 66.5)).abs() < 1e-12);
        assert!((v - (0.5 * 80.0 / 256.0 - 40.0)).abs() < 1e-12);
        let (u, v) = counts_to_mm(511, 255, [133.0, 80.0], [512, 256], &cfg);
        assert!((u - (511.5 * 133.0 / 512.0 - 66.5)).abs() < 1e-12);
        assert!((v - (255.5 * 80.0 / 256.0 - 40.0)).abs() < 1e-12);
        let flipped = PanelConfig {
            flip_u: true,
            shift_v_mm: 1.0,
            ..PanelConfig::default()
        };
        let (u2, v2) = counts_to_mm(511, 255, [133.0, 80.0], [512, 256], &flipped);
        assert!((u2 + u).abs() < 1e-12 && (v2 - v - 1.0).abs() < 1e-12);
    }
}
