//! A blocking [`CanBus`] over an asynchronous CAN socket served by tokio on an I/O thread of
//! its own.
//!
//! The table's driver is synchronous and, on real time, runs on a device thread of its own
//! (see [`crate::devices::actor`]); its bus is this bridge. The socket itself is asynchronous:
//! on Linux SocketCAN through socketcan's tokio support
//! ([`AsyncSocketCan`](crate::transports::AsyncSocketCan)), read by a task that hands each
//! frame over as it arrives, written by a task that reports each write back. Anything that
//! implements [`AsyncFrames`] can stand behind the bridge (tests use an in-memory pair).

use std::future::Future;
use std::sync::mpsc;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::{CanBus, TransportError};
use crate::protocols::can::CanFrame;

/// How long a write may take to be reported before it counts as timed out.
const WRITE_ACK: Duration = Duration::from_secs(1);

/// An asynchronous CAN socket: frames read and written on a tokio runtime.
pub trait AsyncFrames: Send + Sync + 'static {
    /// The next frame received.
    fn read(&self) -> impl Future<Output = Result<CanFrame, TransportError>> + Send;
    /// Queues a frame for transmission.
    fn write(&self, frame: CanFrame) -> impl Future<Output = Result<(), TransportError>> + Send;
}

type WriteRequest = (CanFrame, mpsc::SyncSender<Result<(), TransportError>>);

/// The blocking side of the bridge (see the module docs); the I/O thread stops when it is
/// dropped.
#[derive(Debug)]
pub struct BridgedCanBus {
    writes: Option<tokio::sync::mpsc::UnboundedSender<WriteRequest>>,
    received: mpsc::Receiver<Result<CanFrame, TransportError>>,
    io: Option<JoinHandle<()>>,
}

impl BridgedCanBus {
    /// Starts the I/O thread, opens the socket there with `open` (inside its runtime, as an
    /// asynchronous socket needs), and returns once it is open — or with the error `open` gave.
    pub fn spawn<F, O>(name: &str, open: O) -> Result<Self, TransportError>
    where
        F: AsyncFrames,
        O: FnOnce() -> Result<F, TransportError> + Send + 'static,
    {
        let (ready_tx, ready_rx) = mpsc::sync_channel::<Result<(), TransportError>>(1);
        let (frames_tx, received) = mpsc::channel();
        let (writes, writes_rx) = tokio::sync::mpsc::unbounded_channel::<WriteRequest>();
        let io = std::thread::Builder::new()
            .name(format!("rigcal-can-{name}"))
            .spawn(move || serve(open, ready_tx, frames_tx, writes_rx))
            .map_err(|source| TransportError::Io { source })?;
        match ready_rx.recv() {
            Ok(Ok(())) => Ok(BridgedCanBus {
                writes: Some(writes),
                received,
                io: Some(io),
            }),
            Ok(Err(e)) => {
                let _ = io.join();
                Err(e)
            }
            Err(_) => {
                let _ = io.join();
                Err(TransportError::Closed)
            }
        }
    }
}

/// The I/O thread: a current-thread runtime with I/O and timers, the socket, a reader task and
/// the writer loop (which ends when the bridge is dropped).
fn serve<F, O>(
    open: O,
    ready: mpsc::SyncSender<Result<(), TransportError>>,
    frames: mpsc::Sender<Result<CanFrame, TransportError>>,
    mut writes: tokio::sync::mpsc::UnboundedReceiver<WriteRequest>,
) where
    F: AsyncFrames,
    O: FnOnce() -> Result<F, TransportError>,
{
    let rt = match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(source) => {
            let _ = ready.send(Err(TransportError::Io { source }));
            return;
        }
    };
    rt.block_on(async move {
        let socket = match open() {
            Ok(s) => Arc::new(s),
            Err(e) => {
                let _ = ready.send(Err(e));
                return;
            }
        };
        let _ = ready.send(Ok(()));
        let reader = Arc::clone(&socket);
        tokio::spawn(async move {
            loop {
                let r = reader.read().await;
                let fatal = matches!(&r, Err(e) if !e.is_retryable());
                if frames.send(r).is_err() || fatal {
                    return;
                }
            }
        });
        while let Some((frame, done)) = writes.recv().await {
            let _ = done.send(socket.write(frame).await);
        }
    });
}

impl Drop for BridgedCanBus {
    fn drop(&mut self) {
        // Closing the write channel ends the I/O thread's loop, and its runtime the reader.
        self.writes = None;
        if let Some(io) = self.io.take() {
            let _ = io.join();
        }
    }
}

impl CanBus for BridgedCanBus {
    fn send(&mut self, frame: &CanFrame) -> Result<(), TransportError> {
        let (done, result) = mpsc::sync_channel(1);
        let writes = self.writes.as_ref().ok_or(TransportError::Closed)?;
        writes
            .send((*frame, done))
            .map_err(|_| TransportError::Closed)?;
        match result.recv_timeout(WRITE_ACK) {
            Ok(r) => r,
            Err(mpsc::RecvTimeoutError::Timeout) => {
                Err(TransportError::Timeout { waited: WRITE_ACK })
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => Err(TransportError::Closed),
        }
    }

    fn recv(&mut self, timeout: Duration) -> Result<CanFrame, TransportError> {
        let started = Instant::now();
        match self.received.recv_timeout(timeout) {
            Ok(r) => r,
            Err(mpsc::RecvTimeoutError::Timeout) => Err(TransportError::Timeout {
                waited: started.elapsed(),
            }),
            Err(mpsc::RecvTimeoutError::Disconnected) => Err(TransportError::Closed),
        }
    }
}
