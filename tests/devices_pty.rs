//! Drivers against the emulators through real pseudo-terminals, on real time: the arm and the
//! panel over `serialport`, the table over slcan. Each wait's timeout is shown firing.
//! Pseudo-terminal tests are serialised within this file.

use std::path::Path;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::rig::{Instrument, Rig};
use rigcal_devices::config::DevicesConfig;
use rigcal_devices::devices::clock::RealClock;
use rigcal_devices::devices::drivers::canopen::CanOpenTable;
use rigcal_devices::devices::drivers::movemaster::MovemasterArm;
use rigcal_devices::devices::drivers::penmount::PenMountPanel;
use rigcal_devices::devices::emulators::faults::InjectedFault;
use rigcal_devices::devices::emulators::{serve_bytes, Profile, SlcanAdapter};
use rigcal_devices::devices::factory::{sim_emulators, SimSetup};
use rigcal_devices::devices::{Arm, DeviceError, DeviceErrorKind, Panel, Table};
use rigcal_devices::transports::{SerialTransport, SlcanBus, SlcanBusConfig};
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

fn setup() -> (Rig, DevicesConfig, SimSetup) {
    let rig = Rig::load(Path::new("rigs/rv-m2.toml")).unwrap();
    let mut cfg = DevicesConfig::read_opt(&rig).unwrap();
    cfg.arm.sim_joint_speed_deg_s = 2000.0;
    cfg.arm.sim_reply_ms = 1.0;
    cfg.table.profile_velocity_mm_s = 500.0;
    cfg.table.profile_acceleration_mm_s2 = 5000.0;
    cfg.table.profile_deceleration_mm_s2 = 5000.0;
    cfg.table.bus_latency_ms = 0.5;
    cfg.panel.latency_ms = 2.0;
    let mut s = SimSetup::nominal(&rig);
    s.clock = RealClock::shared();
    (rig, cfg, s)
}

fn deg(v: &[f64]) -> Vec<f64> {
    v.iter().map(|x| x.to_radians()).collect()
}

const T: Duration = Duration::from_secs(5);

#[test]
fn arm_over_a_pseudo_terminal_homes_moves_reads_back_and_recovers_from_error_mode() {
    let _g = pty_lock();
    let (rig, cfg, s) = setup();
    let emus = sim_emulators(&rig, &cfg, &s).unwrap();
    let faults = emus.arm.faults.clone();
    let (device_end, host_end) = pty_pair();
    let _served = serve_bytes(emus.arm.emulator, device_end, s.clock.clone());
    let mut arm =
        MovemasterArm::new(host_end, rig.chain.clone(), &cfg.arm, s.clock.clone()).unwrap();

    assert_eq!(arm.home(T).unwrap(), deg(&[0.0, 90.0, -90.0, 0.0, 0.0]));
    let q = arm
        .move_to(&deg(&[12.34, 70.0, -45.66, 0.0, 0.0]), T)
        .unwrap();
    assert!((q[0].to_degrees() - 12.3).abs() < 1e-9 && (q[2].to_degrees() + 45.7).abs() < 1e-9);
    let pose = arm.where_pose(T).unwrap();
    let p = rig
        .chain
        .position(&q, &ErrorParams::zeros(rig.chain.layout()));
    assert!((nalgebra::Vector3::from(pose.xyz_mm) - p).norm() < 0.1);

    faults.lock().unwrap().error_on_next_move = Some(2);
    let e = arm
        .move_to(&deg(&[0.0, 70.0, -45.0, 0.0, 0.0]), T)
        .unwrap_err();
    assert!(
        matches!(&e, DeviceError::ArmErrorMode { code: 2, command, .. } if command.starts_with("MJ")),
        "{e}"
    );
    arm.reset(T).unwrap();
    arm.move_to(&deg(&[0.0, 70.0, -45.0, 0.0, 0.0]), T).unwrap();

    faults.lock().unwrap().drop_replies = 1;
    let t0 = Instant::now();
    let e = arm.status(Duration::from_millis(150)).unwrap_err();
    let waited = t0.elapsed();
    assert_eq!(e.kind(), DeviceErrorKind::Timeout, "{e}");
    assert!(
        waited >= Duration::from_millis(150) && waited < Duration::from_secs(1),
        "{waited:?}"
    );
    assert_eq!(
        arm.status(T).unwrap(),
        rigcal_devices::devices::ArmStatus::Ok
    );
}

#[test]
fn panel_over_a_pseudo_terminal_reports_touches_drops_garbage_and_times_out_on_a_missed_touch() {
    let _g = pty_lock();
    let (rig, cfg, s) = setup();
    let Instrument::TablePanel(tp) = &rig.instrument else {
        panic!()
    };
    let q = deg(&[20.0, 45.0, -100.0, 0.0, 0.0]);
    rig.measurable(&q).unwrap();
    s.physics.lock().unwrap().arm_commanded(&q, Duration::ZERO);
    let tip = rig
        .chain
        .position(&q, &ErrorParams::zeros(rig.chain.layout()));
    let emus = sim_emulators(&rig, &cfg, &s).unwrap();
    let faults = emus.panel.faults.clone();
    let truth = Arc::clone(&emus.table_truth);
    let table_at_tip = tip - tp.table_to_world_mm;
    let (device_end, host_end) = pty_pair();
    let _served = serve_bytes(emus.panel.emulator, device_end, s.clock.clone());
    let mut panel = PenMountPanel::new(
        host_end,
        tp.panel_size_mm,
        tp.panel_counts,
        &cfg.panel,
        s.clock.clone(),
    );

    let rise = |from: f64, to: f64| {
        let now = s.clock.now();
        let x = table_at_tip.x - 20.0;
        let y = table_at_tip.y + 10.0;
        let mut t = truth.lock().unwrap();
        t.axes = [
            Profile::still(x),
            Profile::still(y),
            Profile::new(now, from, to, 50.0, 1000.0, 1000.0),
        ];
    };
    faults.lock().unwrap().garbage_before_next = vec![0x12, 0x30, 0x99];
    rise(table_at_tip.z - 2.0, table_at_tip.z + 0.5);
    let touch = panel.wait_touch(T).unwrap();
    assert!(
        (touch.u_mm - 20.0).abs() < 0.14 && (touch.v_mm + 10.0).abs() < 0.16,
        "{touch:?}"
    );
    assert!(panel.stats().discarded_bytes >= 3, "{:?}", panel.stats());

    // Away, then a missed touch: the wait ends in a timeout at the time asked.
    rise(table_at_tip.z + 0.5, table_at_tip.z - 2.0);
    std::thread::sleep(Duration::from_millis(150));
    panel.clear().unwrap();
    faults.lock().unwrap().miss_next_touch = true;
    rise(table_at_tip.z - 2.0, table_at_tip.z + 0.5);
    let t0 = Instant::now();
    let e = panel.wait_touch(Duration::from_millis(200)).unwrap_err();
    let waited = t0.elapsed();
    assert_eq!(e.kind(), DeviceErrorKind::Timeout, "{e}");
    assert!(
        waited >= Duration::from_millis(200) && waited < Duration::from_secs(1),
        "{waited:?}"
    );
}

#[test]
fn table_over_slcan_on_a_pseudo_terminal_moves_faults_and_resets() {
    let _g = pty_lock();
    let (rig, cfg, s) = setup();
    let emus = sim_emulators(&rig, &cfg, &s).unwrap();
    let faults = emus.table.faults.clone();
    let (device_end, host_end) = pty_pair();
    let _served = serve_bytes(
        SlcanAdapter::new(emus.table.emulator),
        device_end,
        s.clock.clone(),
    );
    let bus = SlcanBus::open(host_end, SlcanBusConfig::default()).unwrap();
    let mut table = CanOpenTable::new(bus, &cfg.table, s.clock.clone()).unwrap();

    table.enable(T).unwrap();
    let start = table.position(T).unwrap();
    let target = [start[0] + 5.0, start[1] - 3.0, 20.0];
    table.start_move(target, T).unwrap();
    let p = table.wait_reached(T).unwrap();
    for (a, b) in p.iter().zip(target) {
        assert!((a - b).abs() <= 0.001, "{p:?}");
    }

    faults.lock().unwrap().fault_on_next_move = Some(InjectedFault {
        axis: 0,
        after: Duration::from_millis(5),
        emcy_code: 0x2310,
    });
    table.start_move([start[0] + 50.0, p[1], p[2]], T).unwrap();
    let e = table.wait_reached(T).unwrap_err();
    assert!(
        matches!(
            e,
            DeviceError::DriveFault {
                axis: 'x',
                emcy_code: Some(0x2310),
                ..
            }
        ),
        "{e}"
    );
    table.fault_reset(T).unwrap();
    table.start_move(target, T).unwrap();
    table.wait_reached(T).unwrap();

    faults.lock().unwrap().ignore_sdo = true;
    let t0 = Instant::now();
    let e = table.position(T).unwrap_err();
    let waited = t0.elapsed();
    assert_eq!(e.kind(), DeviceErrorKind::Timeout, "{e}");
    // Each of the driver's attempts waits out the SDO timeout.
    let attempts = rigcal_devices::devices::drivers::canopen::table::SDO_ATTEMPTS;
    let timeouts = Duration::from_millis(200) * attempts;
    assert!(
        waited >= timeouts && waited < timeouts + Duration::from_secs(1),
        "{waited:?}"
    );
}

/// The table's touch-probe latch through the real transports: the drives behind slcan and the
/// panel on their own pseudo-terminals, served on one world, the panel's touch output wired to
/// the z drive's probe input. The latched height is the world's contact height to the count,
/// where the position read after the touch packet came is higher by the latencies on the way.
#[test]
fn the_z_drive_latches_the_exact_contact_height_over_pseudo_terminals() {
    let _g = pty_lock();
    let (rig, mut cfg, s) = setup();
    cfg.table.touch_probe = true;
    let Instrument::TablePanel(tp) = &rig.instrument else {
        panic!()
    };
    let q = deg(&[20.0, 45.0, -100.0, 0.0, 0.0]);
    s.physics.lock().unwrap().arm_commanded(&q, Duration::ZERO);
    let tip = rig
        .chain
        .position(&q, &ErrorParams::zeros(rig.chain.layout()));
    // The nominal world: the panel centre is the table position plus the registration, so the
    // contact is at the table height of the tip.
    let contact = (tip - tp.table_to_world_mm).z;
    let (x, y) = (
        tip.x - tp.table_to_world_mm.x - 20.0,
        tip.y - tp.table_to_world_mm.y + 10.0,
    );
    let emus = sim_emulators(&rig, &cfg, &s).unwrap();
    let (table_end, table_host) = pty_pair();
    let (panel_end, panel_host) = pty_pair();
    let _table_served = serve_bytes(
        SlcanAdapter::new(emus.table.emulator),
        table_end,
        s.clock.clone(),
    );
    let _panel_served = serve_bytes(emus.panel.emulator, panel_end, s.clock.clone());
    let bus = SlcanBus::open(table_host, SlcanBusConfig::default()).unwrap();
    let mut table = CanOpenTable::new(bus, &cfg.table, s.clock.clone()).unwrap();
    let mut panel = PenMountPanel::new(
        panel_host,
        tp.panel_size_mm,
        tp.panel_counts,
        &cfg.panel,
        s.clock.clone(),
    );

    table.enable(T).unwrap();
    table.start_move([x, y, contact - 1.0], T).unwrap();
    table.wait_reached(T).unwrap();
    table.arm_touch_probe(T).unwrap();
    assert_eq!(table.latched_z(T).unwrap(), None, "nothing latched yet");
    panel.clear().unwrap();
    table.set_speed(2.0, T).unwrap();
    table.start_move([x, y, contact + 0.5], T).unwrap();
    panel.wait_touch(T).unwrap();
    let read = table.position(T).unwrap()[2];
    table.halt(T).unwrap();
    let latched = table.latched_z(T).unwrap().expect("a latched edge");
    // To the count (1000 counts/mm): the world's contact, rounded.
    assert!(
        (latched - (contact * 1000.0).round() / 1000.0).abs() < 1e-9,
        "latched {latched} mm, contact {contact} mm"
    );
    // The read came at least the panel's 2 ms after the touch, at 2 mm/s: 0.004 mm higher.
    assert!(
        read - latched >= 0.0035,
        "read {read} mm, latched {latched} mm"
    );
}
