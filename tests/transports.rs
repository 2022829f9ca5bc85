//! Transport tests: real pseudo-terminals, the in-memory pipe, the simulated
//! CAN bus and slcan over a scripted adapter.
//!
//! Pseudo-terminal tests are serialised with [`PTY_LOCK`]; they use short real
//! timeouts because blocking serial reads do not follow tokio's paused clock.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread;
use std::time::{Duration, Instant};

use rigcal_devices::protocols::can::CanFrame;
use rigcal_devices::protocols::slcan::{Bitrate, SlcanDecoder, SlcanMessage};
use rigcal_devices::transports::{
    ByteTransport, CanBus, FlowControl, Parity, PipeTransport, SerialSettings, SerialTransport,
    SimBus, SlcanBus, SlcanBusConfig, TransportError,
};
use serialport::TTYPort;

static PTY_LOCK: Mutex<()> = Mutex::new(());

fn pty_lock() -> MutexGuard<'static, ()> {
    PTY_LOCK.lock().unwrap_or_else(PoisonError::into_inner)
}

fn pty_pair() -> (SerialTransport, SerialTransport) {
    let (master, slave) = TTYPort::pair().expect("pseudo-terminal pair");
    (
        SerialTransport::from_port(Box::new(master)),
        SerialTransport::from_port(Box::new(slave)),
    )
}

/// Reads exactly `n` bytes or fails after `timeout`.
fn read_exact(t: &mut dyn ByteTransport, n: usize, timeout: Duration) -> Vec<u8> {
    let deadline = Instant::now() + timeout;
    let mut out = Vec::new();
    let mut buf = [0u8; 64];
    while out.len() < n {
        let left = deadline.saturating_duration_since(Instant::now());
        let got = t.read(&mut buf, left).expect("data before the deadline");
        out.extend_from_slice(&buf[..got]);
    }
    out
}

// ============================================================== serial

#[test]
fn serial_pty_round_trip_both_directions() {
    let _g = pty_lock();
    let (mut host, mut device) = pty_pair();
    let cmd = b"MJ +10.0,-5.5,+0.0,+0.0,+0.0\r";
    host.write_all(cmd).unwrap();
    assert_eq!(
        read_exact(&mut device, cmd.len(), Duration::from_secs(2)),
        cmd
    );
    let reply = b"+250.0,+0.0,+400.0,-90.0,+0.0\r";
    device.write_all(reply).unwrap();
    assert_eq!(
        read_exact(&mut host, reply.len(), Duration::from_secs(2)),
        reply
    );
    // Binary bytes survive (raw mode: no CR/LF translation, no echo).
    device
        .write_all(&[0x70, 0x0D, 0x0A, 0x00, 0xFF, 0x03])
        .unwrap();
    assert_eq!(
        read_exact(&mut host, 6, Duration::from_secs(2)),
        [0x70, 0x0D, 0x0A, 0x00, 0xFF, 0x03]
    );
}

#[test]
fn serial_pty_read_timeout_reports_wait() {
    let _g = pty_lock();
    let (mut host, _device) = pty_pair();
    let mut buf = [0u8; 8];
    let started = Instant::now();
    let err = host.read(&mut buf, Duration::from_millis(100)).unwrap_err();
    let elapsed = started.elapsed();
    match err {
        TransportError::Timeout { waited } => {
            assert!(waited >= Duration::from_millis(90), "waited {waited:?}");
            assert!(waited <= elapsed);
            assert!(elapsed < Duration::from_secs(1), "took {elapsed:?}");
        }
        other => panic!("expected timeout, got {other:?}"),
    }
    assert!(TransportError::Timeout {
        waited: Duration::ZERO
    }
    .is_retryable());
}

#[test]
fn serial_pty_clear_input_discards_pending_bytes() {
    let _g = pty_lock();
    let (mut host, mut device) = pty_pair();
    device.write_all(b"stale\r").unwrap();
    thread::sleep(Duration::from_millis(50));
    host.clear_input().unwrap();
    device.write_all(b"0\r").unwrap();
    assert_eq!(read_exact(&mut host, 2, Duration::from_secs(2)), b"0\r");
}

#[test]
fn serial_open_missing_device_is_typed_error() {
    let err = SerialTransport::open("/dev/rigcal-does-not-exist", &SerialSettings::default())
        .unwrap_err();
    assert!(
        matches!(err, TransportError::Open { ref target, .. } if target == "/dev/rigcal-does-not-exist"),
        "{err:?}"
    );
    assert!(!err.is_retryable());
    let bad = SerialSettings {
        data_bits: 9,
        ..SerialSettings::default()
    };
    assert!(matches!(
        SerialTransport::open("/dev/null", &bad),
        Err(TransportError::InvalidSettings {
            field: "data_bits",
            ..
        })
    ));
}

#[test]
fn serial_settings_defaults_and_serde() {
    let d = SerialSettings::default();
    assert_eq!(
        (d.baud, d.data_bits, d.parity, d.stop_bits, d.flow),
        (9600, 7, Parity::Even, 2, FlowControl::None)
    );
    let parsed: SerialSettings = toml::from_str("").unwrap();
    assert_eq!(parsed, d);
    let parsed: SerialSettings = toml::from_str(
        "baud = 19200\ndata_bits = 8\nparity = \"none\"\nstop_bits = 1\nflow = \"hardware\"\n",
    )
    .unwrap();
    assert_eq!(
        parsed,
        SerialSettings {
            baud: 19200,
            data_bits: 8,
            parity: Parity::None,
            stop_bits: 1,
            flow: FlowControl::Hardware
        }
    );
    assert!(toml::from_str::<SerialSettings>("bauds = 1").is_err());
    assert!(toml::from_str::<SerialSettings>("parity = \"mark\"").is_err());
    assert!(matches!(
        SerialSettings { stop_bits: 3, ..d }.validate(),
        Err(TransportError::InvalidSettings {
            field: "stop_bits",
            ..
        })
    ));
}

// ============================================================== pipe

#[test]
fn pipe_round_trip_timeout_and_close() {
    let (mut a, mut b) = PipeTransport::pair();
    a.write_all(b"abc").unwrap();
    a.write_all(b"de").unwrap();
    let mut buf = [0u8; 2];
    assert_eq!(b.read(&mut buf, Duration::from_millis(100)).unwrap(), 2);
    assert_eq!(&buf, b"ab");
    assert_eq!(read_exact(&mut b, 3, Duration::from_millis(200)), b"cde");
    let started = Instant::now();
    match b.read(&mut buf, Duration::from_millis(50)) {
        Err(TransportError::Timeout { waited }) => {
            assert!(waited >= Duration::from_millis(45), "{waited:?}");
            assert!(started.elapsed() < Duration::from_secs(1));
        }
        other => panic!("{other:?}"),
    }
    a.write_all(b"zz").unwrap();
    b.clear_input().unwrap();
    assert!(matches!(
        b.read(&mut buf, Duration::ZERO),
        Err(TransportError::Timeout { .. })
    ));
    drop(a);
    assert!(matches!(
        b.read(&mut buf, Duration::from_millis(50)),
        Err(TransportError::Closed)
    ));
    assert!(matches!(b.write_all(b"x"), Err(TransportError::Closed)));
}

// ============================================================== SimBus

#[test]
fn sim_bus_broadcasts_to_all_others() {
    let bus = SimBus::new();
    let mut a = bus.endpoint();
    let mut b = bus.endpoint();
    let mut c = bus.endpoint();
    assert_eq!(bus.endpoint_count(), 3);
    let f = CanFrame::new_standard(0x602, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]).unwrap();
    a.send(&f).unwrap();
    assert_eq!(b.recv(Duration::from_millis(100)).unwrap(), f);
    assert_eq!(c.recv(Duration::from_millis(100)).unwrap(), f);
    // The sender does not hear itself.
    match a.recv(Duration::from_millis(50)) {
        Err(TransportError::Timeout { waited }) => {
            assert!(waited >= Duration::from_millis(45), "{waited:?}")
        }
        other => panic!("{other:?}"),
    }
    // Order is kept per sender; a dropped endpoint detaches.
    let g = CanFrame::new_standard(0x582, &[0x60]).unwrap();
    drop(c);
    assert_eq!(bus.endpoint_count(), 2);
    b.send(&g).unwrap();
    b.send(&f).unwrap();
    assert_eq!(a.recv(Duration::from_millis(100)).unwrap(), g);
    assert_eq!(a.recv(Duration::from_millis(100)).unwrap(), f);
    // Works across threads.
    let h = thread::spawn(move || b.recv(Duration::from_secs(2)));
    thread::sleep(Duration::from_millis(20));
    a.send(&g).unwrap();
    assert_eq!(h.join().unwrap().unwrap(), g);
}

// ============================================================== slcan

/// How the scripted adapter answers.
#[derive(Clone, Copy)]
struct Script {
    reject_bitrate: bool,
    reject_frames: bool,
}

/// A tiny slcan "adapter": OK to `Sn`/`O`/`C`, and for each frame: echo the
/// frame first, then `z\r`/`Z\r` (so the host must buffer the echo while it
/// waits for the ack). Returns the messages it received.
fn run_adapter<T: ByteTransport>(
    mut io: T,
    script: Script,
    stop: Arc<AtomicBool>,
) -> Vec<SlcanMessage> {
    let mut dec = SlcanDecoder::default();
    let mut seen = Vec::new();
    let mut buf = [0u8; 64];
    while !stop.load(Ordering::SeqCst) {
        let n = match io.read(&mut buf, Duration::from_millis(20)) {
            Ok(n) => n,
            Err(TransportError::Timeout { .. }) => continue,
            Err(_) => break,
        };
        for msg in dec.push(&buf[..n]).into_iter().flatten() {
            seen.push(msg);
            let reply: Vec<u8> = match msg {
                SlcanMessage::SetBitrate(_) if script.reject_bitrate => vec![0x07],
                SlcanMessage::SetBitrate(_) | SlcanMessage::Open | SlcanMessage::Close => {
                    b"\r".to_vec()
                }
                SlcanMessage::Frame { .. } if script.reject_frames => vec![0x07],
                SlcanMessage::Frame { frame, .. } => {
                    let mut r = SlcanMessage::frame(frame).encode();
                    r.extend_from_slice(if frame.is_extended() { b"Z\r" } else { b"z\r" });
                    r
                }
                _ => continue,
            };
            if io.write_all(&reply).is_err() {
                return seen;
            }
        }
    }
    seen
}

#[test]
fn slcan_bus_over_pty_opens_sends_and_receives() {
    let _g = pty_lock();
    let (adapter_end, host_end) = pty_pair();
    let stop = Arc::new(AtomicBool::new(false));
    let stop2 = Arc::clone(&stop);
    let script = Script {
        reject_bitrate: false,
        reject_frames: false,
    };
    let adapter = thread::spawn(move || run_adapter(adapter_end, script, stop2));

    let config = SlcanBusConfig {
        bitrate: Bitrate::K500,
        ack_timeout: Duration::from_millis(500),
        wait_transmit_ack: true,
    };
    let mut bus = SlcanBus::open(host_end, config).expect("adapter acknowledges S6 and O");
    let f = CanFrame::new_standard(0x123, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
    bus.send(&f).unwrap();
    // The echo arrived before the ack and was buffered.
    assert_eq!(bus.recv(Duration::from_millis(500)).unwrap(), f);
    let e = CanFrame::new_extended(0x1ABC_DEF0, &[0xDE, 0xAD]).unwrap();
    bus.send(&e).unwrap();
    assert_eq!(bus.recv(Duration::from_millis(500)).unwrap(), e);
    // Nothing else pending: a short recv times out.
    assert!(matches!(
        bus.recv(Duration::from_millis(60)),
        Err(TransportError::Timeout { .. })
    ));
    bus.close().unwrap();
    assert_eq!(bus.discarded_bytes(), 0);

    stop.store(true, Ordering::SeqCst);
    let seen = adapter.join().unwrap();
    assert_eq!(
        seen,
        vec![
            SlcanMessage::Close,
            SlcanMessage::SetBitrate(Bitrate::K500),
            SlcanMessage::Open,
            SlcanMessage::frame(f),
            SlcanMessage::frame(e),
            SlcanMessage::Close,
        ]
    );
}

#[test]
fn slcan_bus_bel_reply_is_protocol_error() {
    let _g = pty_lock();
    let (adapter_end, host_end) = pty_pair();
    let stop = Arc::new(AtomicBool::new(false));
    let stop2 = Arc::clone(&stop);
    let script = Script {
        reject_bitrate: true,
        reject_frames: false,
    };
    let adapter = thread::spawn(move || run_adapter(adapter_end, script, stop2));
    let err = SlcanBus::open(host_end, SlcanBusConfig::default()).unwrap_err();
    stop.store(true, Ordering::SeqCst);
    adapter.join().unwrap();
    match &err {
        TransportError::Protocol { detail } => assert!(detail.contains("S6"), "{detail}"),
        other => panic!("expected protocol error, got {other:?}"),
    }
    assert_eq!(
        err.kind(),
        rigcal_devices::transports::TransportErrorKind::Protocol
    );
}

#[test]
fn slcan_bus_rejected_frame_and_silent_adapter() {
    // Over the in-memory pipe: a BEL after a frame, then an adapter that stops answering.
    let (adapter_end, host_end) = PipeTransport::pair();
    let stop = Arc::new(AtomicBool::new(false));
    let stop2 = Arc::clone(&stop);
    let script = Script {
        reject_bitrate: false,
        reject_frames: true,
    };
    let adapter = thread::spawn(move || run_adapter(adapter_end, script, stop2));
    let config = SlcanBusConfig {
        ack_timeout: Duration::from_millis(200),
        ..SlcanBusConfig::default()
    };
    let mut bus = SlcanBus::open(host_end, config).unwrap();
    let f = CanFrame::new_standard(0x000, &[0x01, 0x00]).unwrap();
    assert!(matches!(bus.send(&f), Err(TransportError::Protocol { .. })));
    stop.store(true, Ordering::SeqCst);
    adapter.join().unwrap();
    // Adapter gone (its pipe end dropped): the next ack wait reports Closed.
    assert!(matches!(bus.send(&f), Err(TransportError::Closed)));
}

#[test]
fn slcan_bus_ack_timeout() {
    let (_adapter_end, host_end) = PipeTransport::pair();
    let config = SlcanBusConfig {
        ack_timeout: Duration::from_millis(80),
        ..SlcanBusConfig::default()
    };
    let started = Instant::now();
    match SlcanBus::open(host_end, config) {
        Err(TransportError::Timeout { waited }) => {
            assert!(waited >= Duration::from_millis(75), "{waited:?}");
            assert!(started.elapsed() < Duration::from_secs(1));
        }
        other => panic!("expected timeout, got {other:?}"),
    }
}

#[test]
fn traits_are_object_safe_and_boxed_transports_work() {
    // SlcanBus over a boxed, type-erased byte transport, used as a boxed CanBus.
    let (adapter_end, host_end) = PipeTransport::pair();
    let stop = Arc::new(AtomicBool::new(false));
    let stop2 = Arc::clone(&stop);
    let script = Script {
        reject_bitrate: false,
        reject_frames: false,
    };
    let adapter = thread::spawn(move || run_adapter(adapter_end, script, stop2));
    let io: Box<dyn ByteTransport> = Box::new(host_end);
    let mut bus: Box<dyn CanBus> = Box::new(SlcanBus::open(io, SlcanBusConfig::default()).unwrap());
    let f = CanFrame::new_standard(0x701, &[0x05]).unwrap();
    bus.send(&f).unwrap();
    assert_eq!(bus.recv(Duration::from_millis(500)).unwrap(), f);
    stop.store(true, Ordering::SeqCst);
    adapter.join().unwrap();
    let sim: Box<dyn CanBus> = Box::new(SimBus::new().endpoint());
    drop(sim);
}

// ============================================================== SocketCAN

#[cfg(target_os = "linux")]
#[test]
fn socketcan_open_missing_interface_is_typed_error() {
    match rigcal_devices::transports::SocketCanBus::open("can0") {
        Err(TransportError::Open { target, .. }) => assert_eq!(target, "can0"),
        Err(other) => panic!("unexpected error {other:?}"),
        // A machine with a real can0 is fine too.
        Ok(bus) => assert_eq!(bus.interface(), "can0"),
    }
}

#[cfg(target_os = "linux")]
#[test]
fn socketcan_on_tokio_behind_the_bridge_reports_a_missing_interface() {
    let r = rigcal_devices::transports::BridgedCanBus::spawn("can0", || {
        rigcal_devices::transports::AsyncSocketCan::open("can0")
    });
    match r {
        Err(TransportError::Open { target, .. }) => assert_eq!(target, "can0"),
        Err(other) => panic!("unexpected error {other:?}"),
        // A machine with a real can0 is fine too.
        Ok(_) => {}
    }
}

// ============================================================== tokio bridge

/// An in-memory asynchronous CAN device: answers every frame with the same data on id + 1.
struct EchoPlusOne {
    rx: tokio::sync::Mutex<tokio::sync::mpsc::UnboundedReceiver<CanFrame>>,
    tx: tokio::sync::mpsc::UnboundedSender<CanFrame>,
}

impl rigcal_devices::transports::AsyncFrames for EchoPlusOne {
    async fn read(&self) -> Result<CanFrame, TransportError> {
        self.rx
            .lock()
            .await
            .recv()
            .await
            .ok_or(TransportError::Closed)
    }
    async fn write(&self, frame: CanFrame) -> Result<(), TransportError> {
        let id = match frame.id() {
            rigcal_devices::protocols::can::CanId::Standard(id) => id + 1,
            rigcal_devices::protocols::can::CanId::Extended(id) => id as u16 + 1,
        };
        let reply = CanFrame::new(
            rigcal_devices::protocols::can::CanId::Standard(id),
            frame.data(),
        )
        .map_err(|e| TransportError::Protocol {
            detail: e.to_string(),
        })?;
        self.tx.send(reply).map_err(|_| TransportError::Closed)
    }
}

#[test]
fn the_tokio_bridge_carries_frames_both_ways_and_times_out() {
    let mut bus = rigcal_devices::transports::BridgedCanBus::spawn("mem", || {
        let (tx, rx) = tokio::sync::mpsc::unbounded_channel();
        Ok(EchoPlusOne {
            rx: tokio::sync::Mutex::new(rx),
            tx,
        })
    })
    .unwrap();
    let t0 = Instant::now();
    match bus.recv(Duration::from_millis(30)) {
        Err(TransportError::Timeout { waited }) => assert!(waited >= Duration::from_millis(30)),
        other => panic!("{other:?}"),
    }
    assert!(t0.elapsed() >= Duration::from_millis(30));
    for k in 0..5u8 {
        let f = CanFrame::new(
            rigcal_devices::protocols::can::CanId::Standard(0x600),
            &[k, 2, 3],
        )
        .unwrap();
        bus.send(&f).unwrap();
        let r = bus.recv(Duration::from_secs(1)).unwrap();
        assert_eq!(
            r.id(),
            rigcal_devices::protocols::can::CanId::Standard(0x601)
        );
        assert_eq!(r.data(), &[k, 2, 3]);
    }
    drop(bus);
}
