//! Drive supervision: a task that checks the table's drives once a heartbeat period (the
//! master's side of CANopen heartbeats, conventions §8) and raises an [`Alarm`] when a drive
//! faults (EMCY) or falls silent for longer than its limit.
//!
//! The driver checks the drives itself whenever it talks to them; the task covers the time it
//! does not — while the arm moves, or while the table rises under the pin and the session only
//! listens to the panel. A wait that should stop on a fault races its work against
//! [`Alarm::raised`] in a `select!`. The alarm is a hint: [`Alarm::raised`] asks the table
//! again and returns that fresh error, so an alarm already dealt with (a fault reset) never
//! stops a later wait.

use std::time::Duration;

use tokio::sync::watch;

use crate::devices::actor::DeviceActor;
use crate::devices::pace::Pace;
use crate::devices::traits::{DeviceError, Table};

/// Longest a supervision check may take (it only reads what the bus already holds).
const CHECK: Duration = Duration::from_secs(1);

/// The supervision task's alarm, as the session's waits see it.
#[derive(Debug, Clone)]
pub struct Alarm {
    table: Option<DeviceActor<dyn Table>>,
    raised: watch::Receiver<Option<String>>,
    reset: Option<std::sync::Arc<watch::Sender<Option<String>>>>,
}

impl Alarm {
    /// An alarm that never rises (a rig without drives to supervise).
    pub fn never() -> Self {
        let (tx, rx) = watch::channel(None);
        // The sender lives as long as the alarm, so `raised` waits forever instead of ending.
        Alarm {
            table: None,
            raised: rx,
            reset: Some(std::sync::Arc::new(tx)),
        }
    }

    /// Starts supervising `table` every `period` on the current tokio runtime.
    pub fn supervise(table: DeviceActor<dyn Table>, pace: Pace, period: Duration) -> Self {
        let (tx, rx) = watch::channel(None);
        let tx = std::sync::Arc::new(tx);
        tokio::spawn(supervision(
            table.clone(),
            pace,
            period,
            std::sync::Arc::clone(&tx),
        ));
        Alarm {
            table: Some(table),
            raised: rx,
            reset: Some(tx),
        }
    }

    /// Ends when the drives have a fault or a lost heartbeat, with the table's own error (asked
    /// again when the alarm rises); never, while they are fine.
    pub async fn raised(&self) -> DeviceError {
        let Some(table) = &self.table else {
            return std::future::pending().await;
        };
        let mut rx = self.raised.clone();
        loop {
            if rx.wait_for(Option::is_some).await.is_err() {
                // The task is gone (the runtime shuts down): nothing will rise any more.
                return std::future::pending().await;
            }
            match table.run(CHECK, |t| t.supervise()).await {
                Err(e) => return e,
                Ok(()) => self.clear(),
            }
        }
    }

    /// Lowers the alarm (after the fault it reported was cleared).
    pub fn clear(&self) {
        if let Some(tx) = &self.reset {
            tx.send_replace(None);
        }
    }

    /// What the alarm says, if it is raised.
    pub fn reason(&self) -> Option<String> {
        self.raised.borrow().clone()
    }
}

/// The supervision task: a check every `period`, the alarm raised on the first failure (and
/// kept until the session lowers it).
async fn supervision(
    table: DeviceActor<dyn Table>,
    pace: Pace,
    period: Duration,
    alarm: std::sync::Arc<watch::Sender<Option<String>>>,
) {
    let mut next = pace.now() + period;
    // Until the session lets go of its alarm.
    while alarm.receiver_count() > 0 {
        pace.until(next).await;
        next = pace.now().max(next) + period;
        let reason = match table.run(CHECK, |t| t.supervise()).await {
            Ok(()) => continue,
            Err(e) => e.to_string(),
        };
        alarm.send_if_modified(|a| {
            if a.is_none() {
                tracing::warn!("table supervision: {reason}");
                *a = Some(reason);
                true
            } else {
                false
            }
        });
    }
}
