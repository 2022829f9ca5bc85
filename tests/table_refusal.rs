//! The CANopen table driver reads each node's device type (0x1000) before it enables anything
//! and refuses a node that is not a CiA 402 drive, without writing a single object to any node:
//! a mis-set node ID must not send 402 controlwords to, say, an I/O module. A scripted bus
//! answers the SDO requests (no emulator), so the test sees every frame the driver sends.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use rigcal_core::rig::Rig;
use rigcal_devices::devices::clock::VirtualClock;
use rigcal_devices::devices::drivers::canopen::CanOpenTable;
use rigcal_devices::devices::Table;
use rigcal_devices::protocols::can::CanFrame;
use rigcal_devices::protocols::canopen::{SdoData, SdoRequest, SdoResponse};
use rigcal_devices::transports::{CanBus, TransportError};

/// Answers SDO uploads of 0x1000 with `device_type(node)`, acknowledges every download, and
/// keeps the requests it saw.
struct ScriptedBus {
    device_type: fn(u8) -> u32,
    replies: VecDeque<CanFrame>,
    seen: Arc<Mutex<Vec<(u8, SdoRequest)>>>,
}

impl CanBus for ScriptedBus {
    fn send(&mut self, frame: &CanFrame) -> Result<(), TransportError> {
        let Ok((node, req)) = SdoRequest::decode(frame) else {
            return Ok(()); // NMT and other broadcasts: nothing to answer
        };
        self.seen.lock().expect("lock").push((node.get(), req));
        let reply = match req {
            SdoRequest::Upload { index: 0x1000, sub } => SdoResponse::UploadData {
                index: 0x1000,
                sub,
                data: SdoData::from_u32((self.device_type)(node.get())),
            },
            SdoRequest::Upload { index, sub } => SdoResponse::UploadData {
                index,
                sub,
                data: SdoData::from_u32(0),
            },
            SdoRequest::Download { index, sub, .. } | SdoRequest::Abort { index, sub, .. } => {
                SdoResponse::DownloadAck { index, sub }
            }
        };
        self.replies.push_back(reply.encode(node));
        Ok(())
    }

    fn recv(&mut self, timeout: Duration) -> Result<CanFrame, TransportError> {
        self.replies
            .pop_front()
            .ok_or(TransportError::Timeout { waited: timeout })
    }
}

fn enable_with(device_type: fn(u8) -> u32) -> (Result<(), String>, Vec<(u8, SdoRequest)>) {
    let rig = Rig::load(std::path::Path::new("rigs/rv-m2.toml")).expect("rig");
    let cfg = rigcal_devices::config::DevicesConfig::read_opt(&rig)
        .expect("[devices]")
        .table;
    let seen = Arc::new(Mutex::new(Vec::new()));
    let bus = ScriptedBus {
        device_type,
        replies: VecDeque::new(),
        seen: Arc::clone(&seen),
    };
    let mut table = CanOpenTable::new(bus, &cfg, VirtualClock::shared()).expect("driver");
    let r = table
        .enable(Duration::from_millis(200))
        .map_err(|e| e.to_string());
    let seen = seen.lock().expect("lock").clone();
    (r, seen)
}

#[test]
fn a_node_that_is_not_a_cia_402_drive_is_refused_before_anything_is_written() {
    // Node 2 answers as a CiA 401 I/O module (0x000F_0191).
    let (r, seen) = enable_with(|node| if node == 2 { 0x000F_0191 } else { 0x0002_0192 });
    let e = r.expect_err("node 2 refused");
    assert!(e.contains("not a CiA 402 drive"), "{e}");
    assert!(e.contains("node 2"), "{e}");
    assert!(e.contains("0x000f0191"), "{e}");
    assert!(
        !seen
            .iter()
            .any(|(_, r)| matches!(r, SdoRequest::Download { .. })),
        "objects written before every node was checked: {seen:?}"
    );
    // Node 3 was never asked: the driver stops at the first foreign node.
    assert!(!seen.iter().any(|(n, _)| *n == 3), "{seen:?}");
}

#[test]
fn cia_402_drives_pass_the_check_and_are_then_configured() {
    let (_, seen) = enable_with(|_| 0x0002_0192);
    for node in 1..=3u8 {
        assert!(
            seen.contains(&(
                node,
                SdoRequest::Upload {
                    index: 0x1000,
                    sub: 0
                }
            )),
            "node {node} not checked: {seen:?}"
        );
    }
    // After the checks the driver goes on to write the drives' settings.
    let first_write = seen
        .iter()
        .position(|(_, r)| matches!(r, SdoRequest::Download { .. }))
        .expect("the driver configures the drives");
    let checks = seen
        .iter()
        .filter(|(_, r)| matches!(r, SdoRequest::Upload { index: 0x1000, .. }))
        .count();
    assert_eq!(checks, 3);
    assert!(first_write >= 3, "{seen:?}");
}
