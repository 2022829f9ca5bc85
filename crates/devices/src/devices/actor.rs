//! A device as the session's asynchronous choreography holds it: calls run inline on a
//! virtual clock, on the device's own thread on real time (see [`crate::devices::pace`]).
//!
//! The drivers stay synchronous (a blocking call with a timeout); a [`DeviceActor`] turns each
//! call into a future. On real time the future waits on the device thread through a channel,
//! so a `select!` may stop waiting (drop the future) while the thread finishes its short slice
//! and takes the next request, e.g. a halt.

use std::sync::{mpsc, Arc, Mutex};
use std::time::Duration;

use crate::devices::emulators::lock;
use crate::devices::traits::{DeviceError, DeviceName};

/// How long past a call's own timeout a device thread may take to answer before the call
/// gives up on it.
const THREAD_GRACE: Duration = Duration::from_secs(5);

type Job<D> = Box<dyn FnOnce(&mut D) + Send>;

/// A cloneable handle to one device (see the module docs).
pub struct DeviceActor<D: ?Sized + Send + 'static> {
    name: DeviceName,
    mode: Arc<Mode<D>>,
}

enum Mode<D: ?Sized + Send + 'static> {
    Inline(Mutex<Box<D>>),
    Thread(mpsc::Sender<Job<D>>),
}

impl<D: ?Sized + Send + 'static> Clone for DeviceActor<D> {
    fn clone(&self) -> Self {
        DeviceActor {
            name: self.name,
            mode: Arc::clone(&self.mode),
        }
    }
}

impl<D: ?Sized + Send + 'static> std::fmt::Debug for DeviceActor<D> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mode = match *self.mode {
            Mode::Inline(_) => "inline",
            Mode::Thread(_) => "thread",
        };
        f.debug_struct("DeviceActor")
            .field("device", &self.name)
            .field("mode", &mode)
            .finish()
    }
}

impl<D: ?Sized + Send + 'static> DeviceActor<D> {
    /// Calls run on the caller's thread, one at a time (virtual clock: deterministic).
    pub fn inline(name: DeviceName, device: Box<D>) -> Self {
        DeviceActor {
            name,
            mode: Arc::new(Mode::Inline(Mutex::new(device))),
        }
    }

    /// Calls run one at a time on a thread of the device's own; the thread ends when the last
    /// handle is dropped (after the call it is in).
    pub fn spawn(name: DeviceName, device: Box<D>) -> Result<Self, DeviceError> {
        let (tx, rx) = mpsc::channel::<Job<D>>();
        std::thread::Builder::new()
            .name(format!("rigcal-{name}"))
            .spawn(move || {
                let mut device = device;
                while let Ok(job) = rx.recv() {
                    job(&mut device);
                }
            })
            .map_err(|e| DeviceError::NotReady {
                device: name,
                detail: format!("cannot start the device thread: {e}"),
            })?;
        Ok(DeviceActor {
            name,
            mode: Arc::new(Mode::Thread(tx)),
        })
    }

    /// Inline on a virtual clock, on a thread of its own on real time.
    pub fn for_clock(
        name: DeviceName,
        device: Box<D>,
        virtual_clock: bool,
    ) -> Result<Self, DeviceError> {
        if virtual_clock {
            Ok(Self::inline(name, device))
        } else {
            Self::spawn(name, device)
        }
    }

    /// Which device.
    pub fn name(&self) -> DeviceName {
        self.name
    }

    /// Runs `f` on the device. `within` is the longest the call itself may wait (its own
    /// timeout); a device thread that takes longer still is given up on.
    pub async fn call<R, F>(&self, within: Duration, f: F) -> Result<R, DeviceError>
    where
        F: FnOnce(&mut D) -> R + Send + 'static,
        R: Send + 'static,
    {
        match &*self.mode {
            Mode::Inline(device) => Ok(f(&mut **lock(device))),
            Mode::Thread(jobs) => {
                let (tx, rx) = tokio::sync::oneshot::channel();
                let job: Job<D> = Box::new(move |d: &mut D| {
                    // The caller may have stopped waiting: then nobody needs the result.
                    let _ = tx.send(f(d));
                });
                jobs.send(job).map_err(|_| self.gone())?;
                match tokio::time::timeout(within + THREAD_GRACE, rx).await {
                    Ok(Ok(r)) => Ok(r),
                    Ok(Err(_)) => Err(self.gone()),
                    Err(_) => Err(DeviceError::Timeout {
                        device: self.name,
                        waiting_for: "the device thread to answer".into(),
                        waited: within + THREAD_GRACE,
                        target: "a device call".into(),
                        current: "the device thread is still busy".into(),
                    }),
                }
            }
        }
    }

    /// Runs a device call that returns a device result, flattening the two errors.
    pub async fn run<R, F>(&self, within: Duration, f: F) -> Result<R, DeviceError>
    where
        F: FnOnce(&mut D) -> Result<R, DeviceError> + Send + 'static,
        R: Send + 'static,
    {
        self.call(within, f).await?
    }

    fn gone(&self) -> DeviceError {
        DeviceError::NotReady {
            device: self.name,
            detail: format!(
                "the {} thread stopped (its driver panicked); restart rigcal and resume the session",
                self.name
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inline_and_threaded_calls_reach_the_same_device_state() {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_time()
            .build()
            .expect("runtime");
        for threaded in [false, true] {
            let a = DeviceActor::<Vec<u32>>::for_clock(DeviceName::Arm, Box::default(), !threaded)
                .expect("actor");
            let b = a.clone();
            let n = rt.block_on(async {
                a.call(Duration::from_secs(1), |v| v.push(1)).await?;
                b.call(Duration::from_secs(1), |v| v.push(2)).await?;
                a.call(Duration::from_secs(1), |v| v.len()).await
            });
            assert_eq!(n.expect("calls"), 2);
        }
    }
}
