//! Drivers against the emulators in-process, on the virtual clock: home, move, read back,
//! error mode and reset, drive fault and fault reset, heartbeat loss, contact with the latency
//! rule, missed touch, and every wait's timeout firing.

use std::path::Path;
use std::time::Duration;

use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::rig::{Instrument, Rig};
use rigcal_devices::devices::contact::{approach_speed, measure_contact};
use rigcal_devices::devices::emulators::faults::InjectedFault;
use rigcal_devices::devices::{
    open_devices, Backend, DeviceError, DeviceErrorKind, RigDevices, SimSetup,
};

const T: Duration = Duration::from_secs(30);

fn rig() -> Rig {
    Rig::load(Path::new("rigs/rv-m2.toml")).unwrap()
}

fn devices(rig: &Rig) -> RigDevices {
    open_devices(rig, Backend::Simulated(SimSetup::nominal(rig))).unwrap()
}

fn deg(v: &[f64]) -> Vec<f64> {
    v.iter().map(|x| x.to_radians()).collect()
}

#[test]
fn arm_homes_moves_and_reports_the_rounded_commanded_joints() {
    let rig = rig();
    let mut d = devices(&rig);
    let sim = d.sim.clone().unwrap();
    let nest = d.arm.home(T).unwrap();
    assert_eq!(nest, deg(&[0.0, 90.0, -90.0, 0.0, 0.0]));
    let targets = [
        [10.04, 80.06, -60.02, 0.0, 0.0],
        [10.08, 80.12, -60.04, 0.0, 0.0],
        [10.12, 80.18, -60.06, 0.0, 0.0],
    ];
    for t in targets {
        let got = d.arm.move_to(&deg(&t), T).unwrap();
        for (g, w) in got.iter().zip(t) {
            let rounded = (w * 10.0_f64).round() / 10.0;
            assert!((g.to_degrees() - rounded).abs() < 1e-9, "{g} vs {rounded}");
        }
        assert_eq!(d.arm.commanded().unwrap(), got);
    }
    let log = sim.arm.unwrap().lock().unwrap().received.clone();
    assert_eq!(&log[..4], &["NT", "ER", "SP 5", "ER"]);
    // Increments are differences of rounded absolute targets: (10.0, 80.1, -60.0), then
    // (10.1, 80.1, -60.0) — one joint, so DJ — then (10.1, 80.2, -60.1).
    assert_eq!(log[4], "MJ +10.0,-9.9,+30.0,+0.0,+0.0");
    assert!(log.contains(&"DJ 1,+0.1".to_string()), "{log:?}");
    assert!(
        log.contains(&"MJ +0.0,+0.1,-0.1,+0.0,+0.0".to_string()),
        "{log:?}"
    );
    // Never pipelined: every motion command is followed by ER before anything else.
    for w in log.windows(2) {
        if w[0].starts_with("MJ") || w[0].starts_with("DJ") || w[0] == "NT" {
            assert_eq!(w[1], "ER");
        }
    }
    let pose = d.arm.where_pose(T).unwrap();
    let q = d.arm.commanded().unwrap();
    let p = rig
        .chain
        .position(&q, &ErrorParams::zeros(rig.chain.layout()));
    assert!((nalgebra::Vector3::from(pose.xyz_mm) - p).norm() < 0.1);
}

#[test]
fn arm_error_mode_is_reported_with_its_command_and_reset_only_when_safe() {
    let rig = rig();
    let mut d = devices(&rig);
    let faults = d.sim.clone().unwrap().arm.unwrap();
    d.arm.home(T).unwrap();
    let before = d.arm.commanded();
    faults.lock().unwrap().error_on_next_move = Some(2);
    let e = d
        .arm
        .move_to(&deg(&[5.0, 80.0, -60.0, 0.0, 0.0]), T)
        .unwrap_err();
    match &e {
        DeviceError::ArmErrorMode { command, code, .. } => {
            assert_eq!(*code, 2);
            assert_eq!(command, "MJ +5.0,-10.0,+30.0,+0.0,+0.0");
        }
        other => panic!("{other}"),
    }
    assert_eq!(e.kind(), DeviceErrorKind::DeviceFault);
    assert_eq!(d.arm.commanded(), before);
    assert_eq!(
        d.arm.status(T).unwrap(),
        rigcal_devices::devices::ArmStatus::PositionError
    );
    d.arm.reset(T).unwrap();
    assert_eq!(
        d.arm.status(T).unwrap(),
        rigcal_devices::devices::ArmStatus::Ok
    );
    d.arm
        .move_to(&deg(&[5.0, 80.0, -60.0, 0.0, 0.0]), T)
        .unwrap();

    faults.lock().unwrap().error_on_next_move = Some(1);
    let e = d
        .arm
        .move_to(&deg(&[6.0, 80.0, -60.0, 0.0, 0.0]), T)
        .unwrap_err();
    assert!(
        matches!(e, DeviceError::ArmErrorMode { code: 1, .. }),
        "{e}"
    );
    assert!(d.arm.commanded().is_none());
    assert!(matches!(
        d.arm.reset(T),
        Err(DeviceError::ResetNotSafe { .. })
    ));
    let e = d
        .arm
        .move_to(&deg(&[6.0, 80.0, -60.0, 0.0, 0.0]), T)
        .unwrap_err();
    assert_eq!(e.kind(), DeviceErrorKind::NotReady);
}

#[test]
fn arm_waits_time_out_and_garbled_replies_are_protocol_errors() {
    let rig = rig();
    let mut d = devices(&rig);
    let faults = d.sim.clone().unwrap().arm.unwrap();
    d.arm.home(T).unwrap();
    faults.lock().unwrap().drop_replies = 1;
    let t0 = d.clock.now();
    let e = d
        .arm
        .move_to(
            &deg(&[1.0, 90.0, -90.0, 0.0, 0.0]),
            Duration::from_millis(500),
        )
        .unwrap_err();
    assert_eq!(e.kind(), DeviceErrorKind::Timeout, "{e}");
    assert!(e.is_retryable());
    let waited = d.clock.now() - t0;
    assert!(
        waited >= Duration::from_millis(500) && waited < Duration::from_millis(600),
        "{waited:?}"
    );
    faults.lock().unwrap().garble_replies = 1;
    let e = d.arm.status(T).unwrap_err();
    assert_eq!(e.kind(), DeviceErrorKind::Protocol, "{e}");
    assert_eq!(
        d.arm.status(T).unwrap(),
        rigcal_devices::devices::ArmStatus::Ok
    );
}

#[test]
fn moves_outside_limits_or_travel_are_refused_before_any_byte() {
    let rig = rig();
    let mut d = devices(&rig);
    let sim = d.sim.clone().unwrap();
    d.arm.home(T).unwrap();
    d.table().unwrap().enable(T).unwrap();
    let lines = sim.arm.as_ref().unwrap().lock().unwrap().received.len();
    let frames = sim.table.as_ref().unwrap().lock().unwrap().frames_received;
    let e = d
        .arm
        .move_to(&deg(&[0.0, 120.0, -90.0, 0.0, 0.0]), T)
        .unwrap_err();
    assert_eq!(e.kind(), DeviceErrorKind::Refused, "{e}");
    assert!(e.to_string().contains("J2"), "{e}");
    let e = d
        .table()
        .unwrap()
        .start_move([100.0, 600.0, 10.0], T)
        .unwrap_err();
    assert_eq!(e.kind(), DeviceErrorKind::Refused, "{e}");
    d.table().unwrap().begin_pass();
    d.table()
        .unwrap()
        .start_move([100.0, 100.0, 200.0], T)
        .unwrap();
    d.table().unwrap().wait_reached(T).unwrap();
    let frames = frames.max(sim.table.as_ref().unwrap().lock().unwrap().frames_received);
    let e = d
        .table()
        .unwrap()
        .start_move([100.0, 100.0, 150.0], T)
        .unwrap_err();
    assert!(e.to_string().contains("ascend"), "{e}");
    assert_eq!(
        sim.arm.as_ref().unwrap().lock().unwrap().received.len(),
        lines
    );
    assert_eq!(
        sim.table.as_ref().unwrap().lock().unwrap().frames_received,
        frames
    );
    d.table().unwrap().begin_pass();
    d.table()
        .unwrap()
        .start_move([100.0, 100.0, 150.0], T)
        .unwrap();
}

#[test]
fn table_enables_moves_and_reads_back_on_trapezoidal_profiles() {
    let rig = rig();
    let mut d = devices(&rig);
    d.table().unwrap().enable(T).unwrap();
    let t0 = d.clock.now();
    d.table()
        .unwrap()
        .start_move([100.0, 200.0, 300.0], T)
        .unwrap();
    let p = d.table().unwrap().wait_reached(T).unwrap();
    for (a, b) in p.iter().zip([100.0, 200.0, 300.0]) {
        assert!((a - b).abs() <= 0.001, "{p:?}");
    }
    // The longest axis: 300 mm at 100 mm/s with 500 mm/s² → 3.2 s.
    let took = (d.clock.now() - t0).as_secs_f64();
    assert!((3.2..3.4).contains(&took), "{took}");
    let again = d.table().unwrap().position(T).unwrap();
    assert_eq!(again, p);
}

#[test]
fn drive_fault_stops_the_move_with_its_emcy_and_fault_reset_recovers() {
    let rig = rig();
    let mut d = devices(&rig);
    let faults = d.sim.clone().unwrap().table.unwrap();
    d.table().unwrap().enable(T).unwrap();
    faults.lock().unwrap().fault_on_next_move = Some(InjectedFault {
        axis: 2,
        after: Duration::from_millis(300),
        emcy_code: 0x8611,
    });
    d.table()
        .unwrap()
        .start_move([400.0, 280.0, 200.0], T)
        .unwrap();
    let e = d.table().unwrap().wait_reached(T).unwrap_err();
    match &e {
        DeviceError::DriveFault {
            axis,
            emcy_code,
            target_mm,
            ..
        } => {
            assert_eq!(*axis, 'z');
            assert_eq!(*emcy_code, Some(0x8611));
            assert_eq!(*target_mm, Some(200.0));
        }
        other => panic!("{other}"),
    }
    assert!(!e.is_retryable());
    d.table().unwrap().fault_reset(T).unwrap();
    d.table()
        .unwrap()
        .start_move([400.0, 280.0, 200.0], T)
        .unwrap();
    let p = d.table().unwrap().wait_reached(T).unwrap();
    assert!((p[2] - 200.0).abs() < 0.001);
}

#[test]
fn a_silent_drive_is_reported_after_three_heartbeat_periods_and_sdo_timeouts_fire() {
    let rig = rig();
    let mut d = devices(&rig);
    let faults = d.sim.clone().unwrap().table.unwrap();
    d.table().unwrap().enable(T).unwrap();
    d.table()
        .unwrap()
        .start_move([400.0, 280.0, 10.0], T)
        .unwrap();
    d.table().unwrap().wait_reached(T).unwrap();
    d.clock.sleep(Duration::from_millis(250));
    d.table()
        .unwrap()
        .start_move([400.0, 280.0, 11.0], T)
        .unwrap();
    d.table().unwrap().wait_reached(T).unwrap();
    faults.lock().unwrap().silent_heartbeat[1] = true;
    d.clock.sleep(Duration::from_millis(400));
    let e = d
        .table()
        .unwrap()
        .start_move([400.0, 280.0, 12.0], T)
        .unwrap_err();
    match e {
        DeviceError::HeartbeatLost {
            axis,
            silent_for,
            limit,
            ..
        } => {
            assert_eq!(axis, 'y');
            assert_eq!(limit, Duration::from_millis(300));
            assert!(silent_for > limit);
        }
        other => panic!("{other}"),
    }
    faults.lock().unwrap().ignore_sdo = true;
    let t0 = d.clock.now();
    let e = d.table().unwrap().position(T).unwrap_err();
    assert_eq!(e.kind(), DeviceErrorKind::Timeout, "{e}");
    let waited = d.clock.now() - t0;
    // Each of the driver's attempts waits out the SDO timeout.
    let attempts = rigcal_devices::devices::drivers::canopen::table::SDO_ATTEMPTS;
    let timeouts = Duration::from_millis(200) * attempts;
    assert!(
        waited >= timeouts && waited < timeouts + Duration::from_millis(50),
        "{waited:?}"
    );
}

/// A pose the rig can measure, its true tip, and the table position that brings the panel
/// centre to (tip − offset) at contact.
fn contact_setup(rig: &Rig) -> (Vec<f64>, nalgebra::Vector3<f64>, nalgebra::Vector3<f64>) {
    let Instrument::TablePanel(tp) = &rig.instrument else {
        panic!()
    };
    for q2 in (0..=90).step_by(5) {
        for q3 in (-120..=0).rev().step_by(5) {
            let q = deg(&[20.0, f64::from(q2), f64::from(q3), 0.0, 0.0]);
            if rig.measurable(&q).is_ok() {
                let tip = rig
                    .chain
                    .position(&q, &ErrorParams::zeros(rig.chain.layout()));
                let table = tip - tp.table_to_world_mm;
                if table.z > 5.0 {
                    return (q, tip, table);
                }
            }
        }
    }
    panic!("no measurable pose")
}

#[test]
fn contact_is_measured_within_the_overshoot_rule() {
    let rig = rig();
    let mut d = devices(&rig);
    let sim = d.sim.clone().unwrap();
    d.arm.home(T).unwrap();
    let (q, _tip, table_at_tip) = contact_setup(&rig);
    let q = d.arm.move_to(&q, T).unwrap();
    let tip = rig
        .chain
        .position(&q, &ErrorParams::zeros(rig.chain.layout()));
    let Instrument::TablePanel(tp) = &rig.instrument else {
        panic!()
    };
    let centre_xy = [table_at_tip.x - 10.3, table_at_tip.y + 5.2];
    let zc = tip.z - tp.table_to_world_mm.z;
    d.table().unwrap().enable(T).unwrap();
    d.table().unwrap().begin_pass();
    d.table()
        .unwrap()
        .start_move([centre_xy[0], centre_xy[1], zc - 1.0], T)
        .unwrap();
    d.table().unwrap().wait_reached(T).unwrap();
    let v = approach_speed(
        d.panel().unwrap().latency(),
        d.table().unwrap().latency(),
        0.005,
    );
    let (table, panel) = d.table_and_panel().unwrap();
    let c = measure_contact(
        table,
        panel,
        centre_xy,
        zc - 1.0,
        zc + 0.5,
        v,
        Duration::from_secs(10),
    )
    .unwrap();
    let overshoot = c.table_mm[2] - zc;
    assert!(
        (0.0..=0.005 + 1e-6).contains(&overshoot),
        "overshoot {overshoot} mm at {v} mm/s"
    );
    assert!(
        overshoot > 0.004,
        "the emulator models the latency: {overshoot}"
    );
    let true_contact_z = sim
        .panel
        .unwrap()
        .lock()
        .unwrap()
        .last_contact_table_z
        .unwrap();
    assert!((true_contact_z - zc).abs() < 1e-3);
    // The panel reports where the pin touched, quantised to 0.26 × 0.31 mm counts.
    assert!(
        (c.touch.u_mm - 10.3).abs() <= 133.0 / 512.0 / 2.0 + 1e-9,
        "{:?}",
        c.touch
    );
    assert!(
        (c.touch.v_mm + 5.2).abs() <= 80.0 / 256.0 / 2.0 + 1e-9,
        "{:?}",
        c.touch
    );
    let p = c.point_table_mm();
    assert!((p[0] + tp.table_to_world_mm.x - tip.x).abs() < 0.14);
    assert!((p[1] + tp.table_to_world_mm.y - tip.y).abs() < 0.16);
}

#[test]
fn a_missed_touch_is_a_typed_error_and_bad_packets_are_dropped() {
    let rig = rig();
    let mut d = devices(&rig);
    let sim = d.sim.clone().unwrap();
    let pf = sim.panel.unwrap();
    d.arm.home(T).unwrap();
    let (q, _, table_at_tip) = contact_setup(&rig);
    let q = d.arm.move_to(&q, T).unwrap();
    let tip = rig
        .chain
        .position(&q, &ErrorParams::zeros(rig.chain.layout()));
    let Instrument::TablePanel(tp) = &rig.instrument else {
        panic!()
    };
    let xy = [table_at_tip.x, table_at_tip.y];
    let zc = tip.z - tp.table_to_world_mm.z;
    d.table().unwrap().enable(T).unwrap();
    d.table()
        .unwrap()
        .start_move([xy[0], xy[1], zc - 0.5], T)
        .unwrap();
    d.table().unwrap().wait_reached(T).unwrap();
    pf.lock().unwrap().miss_next_touch = true;
    let (table, panel) = d.table_and_panel().unwrap();
    let e = measure_contact(
        table,
        panel,
        xy,
        zc - 0.5,
        zc + 0.2,
        1.0,
        Duration::from_secs(2),
    )
    .unwrap_err();
    assert!(matches!(e, DeviceError::MissedTouch { .. }), "{e}");
    assert!(e.is_retryable());

    // Back down, then garbage and a corrupted packet before the touch: counted, dropped, and
    // the next valid packet is the measurement.
    d.table().unwrap().begin_pass();
    d.table().unwrap().set_speed(100.0, T).unwrap();
    d.table()
        .unwrap()
        .start_move([xy[0], xy[1], zc - 0.5], T)
        .unwrap();
    d.table().unwrap().wait_reached(T).unwrap();
    {
        let mut f = pf.lock().unwrap();
        f.garbage_before_next = vec![0x00, 0xFF, 0x70, 0x12];
        f.corrupt_next_packet = true;
    }
    let (table, panel) = d.table_and_panel().unwrap();
    let c = measure_contact(
        table,
        panel,
        xy,
        zc - 0.5,
        zc + 0.2,
        0.4,
        Duration::from_secs(5),
    )
    .unwrap();
    assert!(
        c.touch.u_mm.abs() < 0.3 && c.touch.v_mm.abs() < 0.3,
        "{:?}",
        c.touch
    );
    let s = d.panel().unwrap().stats();
    assert!(s.bad_checksum >= 1 && s.discarded_bytes >= 4, "{s:?}");
}

#[test]
fn the_rig_file_backend_opens_the_simulated_devices_it_names() {
    let rig = rig();
    let mut d = open_devices(&rig, Backend::RigFile).unwrap();
    assert!(d.clock.is_virtual(), "all devices are `sim` in rv-m2.toml");
    assert!(d.sim.is_some());
    d.arm.home(T).unwrap();
    d.table().unwrap().enable(T).unwrap();
    assert_eq!(
        d.panel().unwrap().stats(),
        rigcal_devices::devices::PanelStats::default()
    );
}

#[test]
fn threaded_emulators_serve_canopen_over_the_simulated_bus_and_movemaster_over_a_pipe() {
    use rigcal_devices::devices::clock::RealClock;
    use rigcal_devices::devices::drivers::canopen::CanOpenTable;
    use rigcal_devices::devices::drivers::movemaster::MovemasterArm;
    use rigcal_devices::devices::emulators::{serve_bytes, serve_frames};
    use rigcal_devices::devices::factory::sim_emulators;
    use rigcal_devices::devices::{Arm, Table};
    use rigcal_devices::transports::{PipeTransport, SimBus};
    let rig = rig();
    let mut cfg = rigcal_devices::config::DevicesConfig::read_opt(&rig).unwrap();
    cfg.arm.sim_joint_speed_deg_s = 2000.0;
    cfg.table.profile_velocity_mm_s = 500.0;
    cfg.table.profile_acceleration_mm_s2 = 5000.0;
    cfg.table.profile_deceleration_mm_s2 = 5000.0;
    let mut s = SimSetup::nominal(&rig);
    s.clock = RealClock::shared();
    let emus = sim_emulators(&rig, &cfg, &s).unwrap();
    let bus = SimBus::new();
    let _table = serve_frames(emus.table.emulator, bus.endpoint(), s.clock.clone());
    let (a, b) = PipeTransport::pair();
    let _arm = serve_bytes(emus.arm.emulator, a, s.clock.clone());
    let mut table = CanOpenTable::new(bus.endpoint(), &cfg.table, s.clock.clone()).unwrap();
    table.enable(T).unwrap();
    table.start_move([300.0, 200.0, 5.0], T).unwrap();
    let p = table.wait_reached(T).unwrap();
    assert!((p[2] - 5.0).abs() < 0.001, "{p:?}");
    let mut arm = MovemasterArm::new(b, rig.chain.clone(), &cfg.arm, s.clock.clone()).unwrap();
    arm.home(T).unwrap();
    arm.move_to(&deg(&[1.0, 85.0, -85.0, 0.0, 0.0]), T).unwrap();
}

#[test]
fn waiting_for_the_table_times_out_with_target_and_position() {
    let rig = rig();
    let mut d = devices(&rig);
    d.table().unwrap().enable(T).unwrap();
    d.table()
        .unwrap()
        .start_move([400.0, 280.0, 500.0], T)
        .unwrap();
    let t0 = d.clock.now();
    let e = d
        .table()
        .unwrap()
        .wait_reached(Duration::from_millis(300))
        .unwrap_err();
    let waited = d.clock.now() - t0;
    assert!(
        waited >= Duration::from_millis(300) && waited < Duration::from_millis(400),
        "{waited:?}"
    );
    match &e {
        DeviceError::Timeout {
            target, current, ..
        } => {
            assert!(target.contains("500.0"), "{target}");
            assert!(current.contains("Some"), "{current}");
        }
        other => panic!("{other}"),
    }
    assert!(e.is_retryable());
    let p = d.table().unwrap().wait_reached(T).unwrap();
    assert!((p[2] - 500.0).abs() < 0.001);
}

#[test]
fn cartesian_moves_send_mp_and_land_within_the_command_rounding() {
    use rigcal_devices::devices::drivers::movemaster::ControllerKinematics;
    let rig = rig();
    let mut d = devices(&rig);
    let sim = d.sim.clone().unwrap();
    d.arm.home(T).unwrap();
    let k = ControllerKinematics::of_rig(&rig).unwrap();
    let nominal = ErrorParams::zeros(rig.chain.layout());
    let targets = [
        [10.037, 80.061, -60.023, 0.0, 0.0],
        [-20.511, 60.203, -75.777, 0.0, 0.0],
    ];
    for t in targets {
        let q = deg(&t);
        let landed = d.arm.move_cartesian(&q, T).unwrap();
        for (a, b) in d.arm.commanded().unwrap().iter().zip(&landed) {
            assert!((a - b).abs() < 1e-12);
        }
        // Off the 0.1° grid, but within 0.05 mm per axis of the target: the pose's rounding.
        let miss =
            (rig.chain.position(&landed, &nominal) - rig.chain.position(&q, &nominal)).norm();
        assert!(miss <= 0.05 * 3f64.sqrt() + 1e-6, "{miss}");
        // The controller's own report of where it is (0.1 mm) agrees.
        let wh = d.arm.where_pose(T).unwrap();
        let p = k.frame().from_world(&rig.chain.position(&landed, &nominal));
        assert!((nalgebra::Vector3::from(wh.xyz_mm) - p).norm() < 0.1);
        let sent = sim.arm.as_ref().unwrap().lock().unwrap().received.clone();
        let pose = ControllerKinematics::rounded(&k.pose(&q));
        let text = String::from_utf8(
            rigcal_devices::protocols::movemaster::Command::move_pose(&pose)
                .unwrap()
                .encode(),
        )
        .unwrap();
        assert!(sent.contains(&text.trim_end().to_string()), "{sent:?}");
    }
    // A joint move after a Cartesian one stays relative to where the arm really is.
    let before = d.arm.commanded().unwrap();
    let mut q = before.clone();
    q[0] += 0.1_f64.to_radians();
    let got = d.arm.move_to(&q, T).unwrap();
    assert!((got[0] - q[0]).abs() < 1e-9 && (got[1] - before[1]).abs() < 1e-12);
}

#[test]
fn cartesian_targets_outside_the_limits_are_refused_before_any_byte() {
    let rig = rig();
    let mut d = devices(&rig);
    let sim = d.sim.clone().unwrap();
    d.arm.home(T).unwrap();
    let sent = sim.arm.as_ref().unwrap().lock().unwrap().received.len();
    let e = d
        .arm
        .move_cartesian(&deg(&[10.0, 105.0, -60.0, 0.0, 0.0]), T)
        .unwrap_err();
    assert_eq!(e.kind(), DeviceErrorKind::Refused, "{e}");
    assert_eq!(sim.arm.unwrap().lock().unwrap().received.len(), sent);
}
