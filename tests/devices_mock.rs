//! Device-using code against mockall mocks of the device traits (interaction: these calls, in
//! this order), and the safety wrappers refusing before the wrapped device is called.

use std::time::Duration;

use mockall::predicate::eq;
use mockall::Sequence;
use rigcal_core::kinematics::{JointKind, JointSpec};
use rigcal_devices::devices::contact::{approach_speed, measure_contact};
use rigcal_devices::devices::safety::{LimitedArm, LimitedTable};
use rigcal_devices::devices::{
    Arm, DeviceError, DeviceErrorKind, DeviceName, MockArm, MockPanel, MockTable, Panel, Table,
    Touch,
};

fn touch() -> Touch {
    Touch {
        counts: [300, 100],
        u_mm: 11.4,
        v_mm: -8.6,
    }
}

#[test]
fn contact_clears_the_panel_starts_the_approach_and_reads_the_table_at_the_first_touch() {
    let mut seq = Sequence::new();
    let mut table = MockTable::new();
    let mut panel = MockPanel::new();
    panel
        .expect_clear()
        .times(1)
        .in_sequence(&mut seq)
        .returning(|| Ok(()));
    table
        .expect_set_speed()
        .with(eq(0.4), mockall::predicate::always())
        .times(1)
        .in_sequence(&mut seq)
        .returning(|_, _| Ok(()));
    table
        .expect_start_move()
        .with(eq([100.0, 200.0, 51.0]), mockall::predicate::always())
        .times(1)
        .in_sequence(&mut seq)
        .returning(|_, _| Ok(()));
    panel
        .expect_wait_touch()
        .times(1)
        .in_sequence(&mut seq)
        .returning(|_| Ok(touch()));
    table
        .expect_position()
        .times(1)
        .in_sequence(&mut seq)
        .returning(|_| Ok([100.0, 200.0, 50.2]));
    table
        .expect_halt()
        .times(1)
        .in_sequence(&mut seq)
        .returning(|_| Ok([100.0, 200.0, 50.2]));
    let c = measure_contact(
        &mut table,
        &mut panel,
        [100.0, 200.0],
        49.0,
        51.0,
        0.4,
        Duration::from_secs(6),
    )
    .unwrap();
    assert_eq!(c.table_mm, [100.0, 200.0, 50.2]);
    let p = c.point_table_mm();
    assert!((p[0] - 111.4).abs() < 1e-12 && (p[1] - 191.4).abs() < 1e-12 && p[2] == 50.2);
}

#[test]
fn no_touch_halts_the_table_and_reports_a_missed_touch() {
    let mut table = MockTable::new();
    let mut panel = MockPanel::new();
    panel.expect_clear().returning(|| Ok(()));
    table.expect_set_speed().returning(|_, _| Ok(()));
    table.expect_start_move().returning(|_, _| Ok(()));
    panel.expect_wait_touch().returning(|t| {
        Err(DeviceError::Timeout {
            device: DeviceName::Panel,
            waiting_for: "a touch packet".into(),
            waited: t,
            target: "touch".into(),
            current: String::new(),
        })
    });
    table.expect_position().never();
    table
        .expect_halt()
        .times(1)
        .returning(|_| Ok([1.0, 2.0, 51.0]));
    let e = measure_contact(
        &mut table,
        &mut panel,
        [1.0, 2.0],
        49.0,
        51.0,
        0.4,
        Duration::from_secs(6),
    )
    .unwrap_err();
    match e {
        DeviceError::MissedTouch { reached_mm, .. } => {
            assert_eq!(reached_mm, Some([1.0, 2.0, 51.0]))
        }
        other => panic!("{other}"),
    }
}

#[test]
fn the_approach_speed_rule_uses_both_latencies() {
    let mut table = MockTable::new();
    let mut panel = MockPanel::new();
    table
        .expect_latency()
        .return_const(Duration::from_millis(2));
    panel
        .expect_latency()
        .return_const(Duration::from_millis(10));
    let v = approach_speed(panel.latency(), table.latency(), 0.005);
    assert!(v * 0.012 <= 0.005 + 1e-15);
}

fn joints() -> Vec<JointSpec> {
    (1..=5)
        .map(|i| JointSpec {
            name: format!("J{i}"),
            kind: JointKind::Revolute,
            min: (-90f64).to_radians(),
            max: 90f64.to_radians(),
        })
        .collect()
}

#[test]
fn the_arm_wrapper_refuses_a_move_outside_the_joint_limits_without_calling_the_arm() {
    let mut inner = MockArm::new();
    inner.expect_move_to().never();
    let mut arm = LimitedArm::new(inner, joints());
    let q = [0.0, 0.0, 100f64.to_radians(), 0.0, 0.0];
    let e = arm.move_to(&q, Duration::from_secs(1)).unwrap_err();
    assert_eq!(e.kind(), DeviceErrorKind::Refused);
    assert!(
        e.to_string().contains("joint J3") && e.to_string().contains("100.000"),
        "{e}"
    );
    let e = arm
        .move_to(&[f64::NAN, 0.0, 0.0, 0.0, 0.0], Duration::from_secs(1))
        .unwrap_err();
    assert_eq!(e.kind(), DeviceErrorKind::Refused);

    let mut inner = MockArm::new();
    inner
        .expect_move_to()
        .times(1)
        .returning(|q, _| Ok(q.to_vec()));
    let mut arm = LimitedArm::new(inner, joints());
    arm.move_to(&[0.1, 0.2, 0.3, 0.0, 0.0], Duration::from_secs(1))
        .unwrap();
}

#[test]
fn the_table_wrapper_enforces_travel_and_ascending_z_within_a_pass() {
    let mut inner = MockTable::new();
    inner
        .expect_start_move()
        .with(eq([10.0, 10.0, 100.0]), mockall::predicate::always())
        .times(1)
        .returning(|_, _| Ok(()));
    inner
        .expect_start_move()
        .with(eq([10.0, 10.0, 95.0]), mockall::predicate::always())
        .times(1)
        .returning(|_, _| Ok(()));
    inner
        .expect_start_move()
        .with(eq([10.0, 10.0, 50.0]), mockall::predicate::always())
        .times(1)
        .returning(|_, _| Ok(()));
    inner.expect_begin_pass().times(2).return_const(());
    let mut t = LimitedTable::new(inner, [800.0, 560.0, 580.0], 10.0);
    let s = Duration::from_secs(1);
    assert_eq!(
        t.start_move([-0.1, 10.0, 10.0], s).unwrap_err().kind(),
        DeviceErrorKind::Refused
    );
    assert_eq!(
        t.start_move([10.0, 560.5, 10.0], s).unwrap_err().kind(),
        DeviceErrorKind::Refused
    );
    assert_eq!(
        t.start_move([10.0, 10.0, 581.0], s).unwrap_err().kind(),
        DeviceErrorKind::Refused
    );
    t.begin_pass();
    t.start_move([10.0, 10.0, 100.0], s).unwrap();
    t.start_move([10.0, 10.0, 95.0], s).unwrap(); // within the 10 mm retract allowance
    let e = t.start_move([10.0, 10.0, 50.0], s).unwrap_err();
    assert!(e.to_string().contains("ascend"), "{e}");
    t.begin_pass();
    t.start_move([10.0, 10.0, 50.0], s).unwrap();
}

const T: Duration = Duration::from_secs(1);

fn refused() -> DeviceError {
    DeviceError::PoseRefused {
        pose: [300.0, 0.0, 400.0, -90.0, 0.0],
        detail: "J3 -120.007° outside -120..0".into(),
    }
}

#[test]
fn the_cartesian_arm_sends_every_move_as_a_pose_and_falls_back_to_joints_only_when_asked() {
    use rigcal_devices::devices::safety::CartesianArm;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Arc;
    let q = vec![0.1, 1.2, -1.9, 0.0, 0.0];
    // Strict: a refused pose is the caller's error, and no joint command is sent.
    let mut strict_inner = MockArm::new();
    strict_inner
        .expect_start_move_cartesian()
        .times(1)
        .returning(|_, _| Err(refused()));
    strict_inner.expect_start_move().never();
    let mut strict = CartesianArm::new(strict_inner);
    assert!(matches!(
        strict.start_move(&q, T),
        Err(DeviceError::PoseRefused { .. })
    ));
    // With the fallback: the first pose goes through MP, the refused one through MJ to the same
    // joints, counted once.
    let mut seq = Sequence::new();
    let mut inner = MockArm::new();
    let sent = q.clone();
    inner
        .expect_start_move_cartesian()
        .times(1)
        .in_sequence(&mut seq)
        .returning(move |q, _| Ok(q.to_vec()));
    inner
        .expect_start_move_cartesian()
        .times(1)
        .in_sequence(&mut seq)
        .returning(|_, _| Err(refused()));
    inner
        .expect_start_move()
        .withf(move |q, _| q == sent.as_slice())
        .times(1)
        .in_sequence(&mut seq)
        .returning(|q, _| Ok(q.to_vec()));
    let n = Arc::new(AtomicUsize::new(0));
    let mut arm = CartesianArm::with_joint_fallback(inner, Arc::clone(&n));
    assert_eq!(arm.start_move(&q, T).unwrap(), q);
    assert_eq!(n.load(Ordering::Relaxed), 0);
    assert_eq!(arm.start_move(&q, T).unwrap(), q);
    assert_eq!(n.load(Ordering::Relaxed), 1);
}
