//! How to run a session, and how to ask a running one to stop ([`StopRequest`]).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use crate::session::procedure::ContactProcedure;
use rigcal_core::recording::{RegistrationInfo, SessionInfo};

/// How to run a session.
#[derive(Debug, Clone)]
pub struct SessionOptions {
    /// Output directory (measurements.csv, session.toml, journal.json).
    pub dir: PathBuf,
    /// Continue the session in `dir` from its journal.
    pub resume: bool,
    /// Poses of the registration step.
    pub registration_points: usize,
    /// Attempts per point before it is skipped.
    pub max_attempts: u32,
    /// First retry backoff (doubles per attempt).
    pub backoff: Duration,
    /// Seed of the registration poses.
    pub seed: u64,
    /// fsync each row and the journal (on by default; a dry run on the virtual clock may turn it
    /// off: a killed process loses nothing that was written).
    pub fsync: bool,
    /// What goes into session.toml besides the registration.
    pub info: SessionInfo,
    /// A registration to reuse (another session's, same rig set-up) instead of the
    /// registration step: both recordings are then in one frame.
    pub registration: Option<RegistrationInfo>,
    /// The contact procedure on the table-and-panel rig (kept in the journal: a resume runs
    /// the one the session began with).
    pub procedure: ContactProcedure,
    /// A request to stop safely (see [`StopRequest`]); `rigcal session` raises it on SIGINT
    /// and SIGTERM. Never raised by default.
    pub stop: StopRequest,
}

impl SessionOptions {
    /// Defaults for a directory.
    pub fn new(dir: &Path) -> Self {
        SessionOptions {
            dir: dir.to_path_buf(),
            resume: false,
            registration_points: 12,
            max_attempts: 3,
            backoff: Duration::from_millis(200),
            seed: 1,
            fsync: true,
            info: SessionInfo::default(),
            registration: None,
            procedure: ContactProcedure::Rigcal,
            stop: StopRequest::new(),
        }
    }
}

/// A request to stop a running session safely, from any thread (a signal handler, a test, a
/// user interface). The session sees it between two device calls: it abandons the point in
/// progress, quick-stops the table's drives, stops the arm (see
/// [`Arm::stop`](crate::devices::Arm::stop)), leaves the journal at the last finished point and
/// ends with [`SessionError::Stopped`](crate::session::SessionError::Stopped): `--resume`
/// measures that point again. Clones share the request.
#[derive(Clone, Default)]
pub struct StopRequest {
    inner: Arc<StopInner>,
}

#[derive(Default)]
struct StopInner {
    raised: AtomicBool,
    reason: Mutex<Option<String>>,
    wake: tokio::sync::Notify,
}

impl std::fmt::Debug for StopRequest {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StopRequest")
            .field("reason", &self.reason())
            .finish()
    }
}

impl StopRequest {
    /// A request not raised yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Raises the request, saying why (`"SIGINT"`, …); the first reason is kept.
    pub fn request(&self, why: &str) {
        {
            let mut reason = self
                .inner
                .reason
                .lock()
                .unwrap_or_else(PoisonError::into_inner);
            reason.get_or_insert_with(|| why.to_string());
        }
        self.inner.raised.store(true, Ordering::SeqCst);
        self.inner.wake.notify_waiters();
    }

    /// True once raised.
    pub fn is_requested(&self) -> bool {
        self.inner.raised.load(Ordering::SeqCst)
    }

    /// Why it was raised; `None` while it is not.
    pub fn reason(&self) -> Option<String> {
        self.inner
            .reason
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// Ready (with the reason) once raised: the branch a session's `select!` looks at first.
    pub(crate) async fn requested(&self) -> String {
        loop {
            let woken = self.inner.wake.notified();
            tokio::pin!(woken);
            woken.as_mut().enable();
            if let Some(why) = self.reason() {
                return why;
            }
            woken.await;
        }
    }

    /// A request raised by SIGINT (Ctrl-C) or SIGTERM, from now on for the rest of the process:
    /// a thread of its own listens (so the session's runtime needs no signal driver, whichever
    /// clock it runs on). The listeners are in place when this returns; further signals while
    /// the session stops are noted in the log and otherwise ignored (the safe stop is bounded
    /// by its devices' timeouts).
    pub fn on_signals() -> std::io::Result<Self> {
        let stop = StopRequest::new();
        let raise = stop.clone();
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        std::thread::Builder::new()
            .name("rigcal-signals".into())
            .spawn(move || listen_for_signals(&raise, &ready_tx))?;
        match ready_rx.recv() {
            Ok(Ok(())) => Ok(stop),
            Ok(Err(e)) => Err(e),
            Err(_) => Err(std::io::Error::other(
                "the signal listener stopped before it was ready",
            )),
        }
    }
}

/// The body of the signal thread: registers the listeners, says so on `ready`, then raises
/// `stop` on every SIGINT or SIGTERM.
fn listen_for_signals(stop: &StopRequest, ready: &std::sync::mpsc::Sender<std::io::Result<()>>) {
    let runtime = match tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            let _ = ready.send(Err(e));
            return;
        }
    };
    runtime.block_on(async {
        let mut signals = match Signals::new() {
            Ok(s) => s,
            Err(e) => {
                let _ = ready.send(Err(e));
                return;
            }
        };
        let _ = ready.send(Ok(()));
        while let Some(name) = signals.next().await {
            // The session says it stops (with what it was doing); a repeat only here.
            if stop.is_requested() {
                tracing::warn!("{name} again: the session is already stopping safely");
            }
            stop.request(name);
        }
    });
}

/// SIGINT and SIGTERM on Unix; Ctrl-C elsewhere.
struct Signals {
    #[cfg(unix)]
    int: tokio::signal::unix::Signal,
    #[cfg(unix)]
    term: tokio::signal::unix::Signal,
}

impl Signals {
    #[cfg(unix)]
    fn new() -> std::io::Result<Self> {
        use tokio::signal::unix::{signal, SignalKind};
        Ok(Signals {
            int: signal(SignalKind::interrupt())?,
            term: signal(SignalKind::terminate())?,
        })
    }

    #[cfg(not(unix))]
    fn new() -> std::io::Result<Self> {
        Ok(Signals {})
    }

    /// The next signal's name; `None` when no more can come.
    #[cfg(unix)]
    async fn next(&mut self) -> Option<&'static str> {
        tokio::select! {
            s = self.int.recv() => s.map(|()| "SIGINT"),
            s = self.term.recv() => s.map(|()| "SIGTERM"),
        }
    }

    #[cfg(not(unix))]
    async fn next(&mut self) -> Option<&'static str> {
        tokio::signal::ctrl_c().await.ok().map(|()| "Ctrl-C")
    }
}
