//! What the session does about a device error: retry (after clearing what the protocol allows),
//! give the point up, or stop.
//!
//! A missed touch or a retryable device error is retried with doubling backoff; a drive fault is
//! cleared with `fault_reset` (and the supervision alarm lowered), an arm position error (mode
//! II) with `reset`, an arm that may have lost track of its joints is homed again; a hardware
//! error, a lost heartbeat or a configuration error stops the session (resume with `--resume`
//! after clearing the cause). A refused command gives the point up at once, any other error
//! after the last attempt.
//!
//! **A device lost** ends the session as a fault ([`SessionError::DeviceLost`], resumable),
//! never as a run of `skipped` rows: when a point is about to be given up
//! - for a timeout (or a transport error) of the table, the table is asked for its position
//!   once more; no answer to that either, and the table is lost;
//! - for a device's silence (a timeout of any device, a missed touch, a late reading) and the
//!   [`LOST_AFTER_POINTS`]` - 1` points before it were given up for silence too, the device is
//!   lost (a panel that no longer reports touches, a sensor that no longer sees, drives that
//!   answer too late for every contact).
//!
//! The point in progress is then not written: `--resume` measures it again.

use crate::devices::{DeviceError, DeviceErrorKind, DeviceName};
use crate::session::core::{Outcome, SessionCore};
use crate::session::error::SessionError;
use crate::session::motion::{Motion, IO, MOVE};
use rigcal_core::recording::Status;

/// Decides about `e` at attempt `attempt` of `stage`: `Ok(None)` to retry (after the backoff),
/// `Ok(Some(skip))` to give the point up, `Err` to stop the session.
pub(crate) async fn handle(
    core: &mut SessionCore<'_>,
    motion: &Motion,
    e: DeviceError,
    attempt: &mut u32,
    stage: &str,
) -> Result<Option<Outcome>, SessionError> {
    if fatal(&e) || motion.stop.is_requested() {
        // (A stop request: nothing is retried; the session's stop branch takes over.)
        motion.halt_table().await;
        return Err(stop(core, stage, e));
    }
    if matches!(e, DeviceError::Refused { .. }) {
        return Ok(Some(Outcome::Skipped(format!(
            "refused by the safety limits: {e}"
        ))));
    }
    if !recover(core, motion, &e).await? {
        motion.halt_table().await;
        return Err(stop(core, stage, e));
    }
    *attempt += 1;
    if *attempt >= core.opts.max_attempts {
        if let Some(lost) = lost_device(core, motion, &e, stage).await {
            motion.halt_table().await;
            return Err(lost);
        }
        return Ok(Some(Outcome::Skipped(format!(
            "{} after {} attempts ({stage})",
            short_reason(&e),
            attempt
        ))));
    }
    core.report.retries += 1;
    tracing::info!("retrying ({stage}, attempt {}): {e}", *attempt + 1);
    motion
        .pace
        .pause(core.opts.backoff * 2u32.saturating_pow(*attempt - 1))
        .await;
    Ok(None)
}

/// Points given up in a row for a device's silence after which the device counts as lost.
pub(crate) const LOST_AFTER_POINTS: u32 = 3;

/// The device-loss rule (see the module docs), as a point is about to be given up for `e`:
/// the error that ends the session, or `None` to give the point up.
async fn lost_device(
    core: &mut SessionCore<'_>,
    motion: &Motion,
    e: &DeviceError,
    stage: &str,
) -> Option<SessionError> {
    let stage = format!("point seq {}: {stage}", core.seq);
    let device = silent_device(e)?;
    if device == DeviceName::Table && matches!(e.kind(), DeviceErrorKind::Timeout) {
        if let Ok(table) = motion.table() {
            if let Err(probe) = table.run(IO, |t| t.position(IO)).await {
                if matches!(
                    probe.kind(),
                    DeviceErrorKind::Timeout | DeviceErrorKind::Transport
                ) {
                    return Some(SessionError::DeviceLost {
                        device,
                        stage,
                        detail: format!(
                            "{} attempts failed ({e}), and it did not answer a position read either ({probe})",
                            core.opts.max_attempts
                        ),
                    });
                }
            }
        }
    }
    core.silent_points += 1;
    if core.silent_points >= LOST_AFTER_POINTS {
        return Some(SessionError::DeviceLost {
            device,
            stage,
            detail: format!(
                "{} points in a row given up for its silence, the last for: {e}",
                core.silent_points
            ),
        });
    }
    None
}

/// The device whose silence `e` is — a timeout (or transport error) of a device, a missed
/// touch (the panel), a late reading — or `None` for any other error.
fn silent_device(e: &DeviceError) -> Option<DeviceName> {
    match e {
        DeviceError::Timeout { device, .. }
        | DeviceError::Transport { device, .. }
        | DeviceError::LateReading { device, .. } => Some(*device),
        DeviceError::MissedTouch { .. } => Some(DeviceName::Panel),
        _ => None,
    }
}

fn stop(core: &SessionCore<'_>, stage: &str, source: DeviceError) -> SessionError {
    SessionError::Device {
        stage: format!("point seq {}: {stage}", core.seq),
        source,
    }
}

/// Clears what the protocol allows; false if the error must stop the session.
async fn recover(
    core: &mut SessionCore<'_>,
    motion: &Motion,
    e: &DeviceError,
) -> Result<bool, SessionError> {
    if arm_lost_track(e) {
        // The controller may have executed a command whose reply was lost (MJ moves are
        // relative): home again so the driver knows the joints, then retry.
        return match motion.arm.run(MOVE, |a| a.home(MOVE)).await {
            Ok(nest) => {
                core.report
                    .faults_cleared
                    .push(format!("arm re-homed after: {e}"));
                core.arm_q = Some(nest.clone());
                let m = core.row(nest, "home", Status::Via);
                core.report.via += 1;
                core.write(m)?;
                Ok(true)
            }
            Err(_) => Ok(false),
        };
    }
    Ok(match e {
        DeviceError::DriveFault { .. } | DeviceError::FollowingError { .. } => {
            motion.halt_table().await;
            let reset = match motion.table() {
                Ok(t) => t.run(IO * 5, |t| t.fault_reset(IO * 5)).await,
                Err(e) => Err(e),
            };
            match reset {
                Ok(()) => {
                    motion.alarm.clear();
                    core.report.faults_cleared.push(format!("table: {e}"));
                    true
                }
                Err(_) => false,
            }
        }
        DeviceError::ArmErrorMode { code: 2, .. } => {
            match motion.arm.run(IO, |a| a.reset(IO)).await {
                Ok(()) => {
                    core.report.faults_cleared.push(format!("arm: {e}"));
                    true
                }
                Err(_) => false,
            }
        }
        other => other.is_retryable(),
    })
}

/// True for an error the session cannot clear by itself.
fn fatal(e: &DeviceError) -> bool {
    matches!(
        e,
        DeviceError::ArmErrorMode { code: 1, .. }
            | DeviceError::HeartbeatLost { .. }
            | DeviceError::Config { .. }
            | DeviceError::NotReady { .. }
            | DeviceError::ResetNotSafe { .. }
    )
}

/// True for an arm error after which the driver may not know where the arm is.
pub(crate) fn arm_lost_track(e: &DeviceError) -> bool {
    matches!(
        e,
        DeviceError::Timeout {
            device: DeviceName::Arm,
            ..
        } | DeviceError::Protocol {
            device: DeviceName::Arm,
            ..
        } | DeviceError::Transport {
            device: DeviceName::Arm,
            ..
        } | DeviceError::PoseMismatch { .. }
    )
}

/// True when a failed step leaves the arm's move to be made again.
pub(crate) fn arm_move_lost(e: &DeviceError) -> bool {
    arm_lost_track(e) || matches!(e, DeviceError::ArmErrorMode { .. })
}

/// A short reason for a `skipped:` row.
fn short_reason(e: &DeviceError) -> String {
    match e {
        DeviceError::MissedTouch { .. } => "missed touch".into(),
        DeviceError::Timeout { device, .. } => format!("{device} timeout"),
        DeviceError::LateReading {
            device, latency, ..
        } => format!(
            "{device} reading too late ({:.1} ms)",
            latency.as_secs_f64() * 1e3
        ),
        DeviceError::Protocol { device, detail, .. } => format!("{device} bad reply ({detail})"),
        DeviceError::Transport { device, .. } => format!("{device} transport error"),
        DeviceError::DriveFault { axis, .. } => format!("table axis {axis} drive fault"),
        DeviceError::FollowingError { axis, .. } => format!("table axis {axis} following error"),
        DeviceError::ArmErrorMode { code, .. } => format!("arm error mode {code}"),
        other => format!("{:?}", other.kind()),
    }
}
