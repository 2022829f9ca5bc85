//! Emulators served on pseudo-terminals (`rigcal sim-device`), so that outside tools, HIL
//! scripts and a whole session talk to them as to the hardware, through the real serial and
//! slcan transports. The table speaks slcan there (an slcan adapter with the three drives
//! behind it). Real time.
//!
//! Two forms:
//! - [`serve_on_pty`]: one device's emulator on a nominal world (the arm at its nest, the
//!   table at its power-on position); three of these share no world, so a panel served alone
//!   never sees the pin.
//! - [`serve_rig_on_ptys`]: the whole rig (arm, table behind slcan, panel) in one process on
//!   one shared simulated world — the world an in-process dry run uses — plus the world's side
//!   channel ([`WorldChannel`], a Unix socket): what the protocols do not carry (which
//!   measurement's random draws come next, the session's time base, the motion history for the
//!   journal) reaches the served world through a [`RemoteHook`] exactly as an in-process dry
//!   run's hook reaches its world. A rig file naming the socket in `[devices] world`
//!   ([`rehearsal_rig_text`]) makes `rigcal session` use it. The panel's touch output reaches
//!   the drives' touch-probe inputs in that shared world (`[devices.table] touch_probe`): a
//!   latched height is the world's contact height, not a moment on the serving threads' clock,
//!   so it is the in-process dry run's.
//!
//! # The served world across a killed session
//! The server outlives the sessions that use it, and its world keeps moving after the last
//! journal commit of a killed session (the moves of the point in progress). So the served world
//! follows the in-process rule: each session process starts on a fresh world (a
//! [`WorldRequest::Begin`] on connecting restores the motion history the world had when served),
//! and a resume restores the journal's motion history through the hook, as an in-process resume
//! does. The random draws are a function of (seed, seq, attempt), set before each measurement.
//! What stays physical is the devices' own state (where the arm and the table stand, the drives
//! enabled), as on the rig. Time-dependent effects (drift) follow the session's real time, so
//! only they can differ from a dry run on the virtual clock.

use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use crate::devices::clock::{RealClock, SharedClock};
use crate::devices::config::DevicesConfig;
use crate::devices::emulators::{lock, serve_bytes, Served, SlcanAdapter};
use crate::devices::factory::{sim_emulators, SimSetup, SimWorld};
use crate::devices::hook::{HookError, RigHook};
use crate::devices::DeviceError;
use crate::transports::SerialTransport;
use rigcal_core::rig::Rig;
use serde::{Deserialize, Serialize};
use serialport::{SerialPort, TTYPort};

/// Which device's emulator to serve.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EmulatedDevice {
    /// The arm's controller (RS-232 lines).
    Arm,
    /// The table's drives behind an slcan adapter.
    Table,
    /// The panel's controller.
    Panel,
}

/// Why an emulator could not be served on a pseudo-terminal.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PtyError {
    /// The emulators could not be built from the rig file.
    #[error(transparent)]
    Device(#[from] DeviceError),
    /// The system gave no pseudo-terminal pair.
    #[error("cannot create a pseudo-terminal pair")]
    Pair(#[source] serialport::Error),
    /// The pseudo-terminal's device has no path.
    #[error("the pseudo-terminal has no name")]
    NoName,
    /// The world's socket could not be made.
    #[error("cannot serve the simulated world's side channel on {path}: {source}; remove a stale file there or choose another path")]
    Socket {
        /// The socket's path.
        path: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// The rig file's text could not be rewritten with the served ports.
    #[error("cannot write a rig file for the served ports: {0}")]
    RigText(String),
}

/// An emulator served on a pseudo-terminal: the port to open, and what keeps it served (the
/// serving thread stops when this is dropped).
#[derive(Debug)]
pub struct PtyServed {
    /// The path of the port (the pseudo-terminal's other end).
    pub path: String,
    _served: Served,
    // The other end stays open, so the served end sees no hang-up between clients.
    _port: TTYPort,
}

/// A new pseudo-terminal pair with `serve` serving its device end.
fn on_new_pty(serve: impl FnOnce(SerialTransport) -> Served) -> Result<PtyServed, PtyError> {
    let (master, port) = TTYPort::pair().map_err(PtyError::Pair)?;
    let path = port.name().ok_or(PtyError::NoName)?;
    let served = serve(SerialTransport::from_port(Box::new(master)));
    Ok(PtyServed {
        path,
        _served: served,
        _port: port,
    })
}

/// Serves `device`'s emulator (the driver and settings of `rig`'s `[devices]`) on a new
/// pseudo-terminal, on real time, in a nominal world of its own.
pub fn serve_on_pty(rig: &Rig, device: EmulatedDevice) -> Result<PtyServed, PtyError> {
    let cfg = DevicesConfig::read(rig);
    let mut setup = SimSetup::nominal(rig);
    setup.clock = RealClock::shared();
    let emus = sim_emulators(rig, &cfg, &setup)?;
    let clock = setup.clock.clone();
    on_new_pty(|io| match device {
        EmulatedDevice::Arm => serve_bytes(emus.arm.emulator, io, clock),
        EmulatedDevice::Panel => serve_bytes(emus.panel.emulator, io, clock),
        EmulatedDevice::Table => serve_bytes(SlcanAdapter::new(emus.table.emulator), io, clock),
    })
}

/// The whole rig's emulators served on pseudo-terminals around one world (see the module
/// docs). Everything stops when this is dropped.
#[derive(Debug)]
pub struct RigOnPtys {
    /// The arm controller's port (RS-232 lines).
    pub arm: PtyServed,
    /// The slcan adapter's port, the table's drives behind it.
    pub table: PtyServed,
    /// The panel controller's port.
    pub panel: PtyServed,
    /// The world's side channel.
    pub world: WorldChannel,
}

/// Serves `rig`'s three emulators (drivers and settings of its `[devices]`) on three new
/// pseudo-terminals around `world` (its physics and hook; the clock becomes real time), and
/// the world's side channel on a Unix socket at `socket`.
pub fn serve_rig_on_ptys(rig: &Rig, world: SimWorld, socket: &Path) -> Result<RigOnPtys, PtyError> {
    let cfg = DevicesConfig::read(rig);
    let SimWorld { mut setup, hook } = world;
    setup.clock = RealClock::shared();
    let emus = sim_emulators(rig, &cfg, &setup)?;
    let clock = setup.clock.clone();
    let arm = on_new_pty(|io| serve_bytes(emus.arm.emulator, io, clock.clone()))?;
    let table =
        on_new_pty(|io| serve_bytes(SlcanAdapter::new(emus.table.emulator), io, clock.clone()))?;
    let panel = on_new_pty(|io| serve_bytes(emus.panel.emulator, io, clock.clone()))?;
    let world = WorldChannel::serve(hook, clock, socket)?;
    Ok(RigOnPtys {
        arm,
        table,
        panel,
        world,
    })
}

/// `rig`'s file text with `[devices]` pointing at the served ports: the arm's and the panel's
/// transports at their pseudo-terminals, the table's at `slcan:` its adapter's, and `world` at
/// the world's socket. Every other key is kept (comments are not).
pub fn rehearsal_rig_text(rig: &Rig, served: &RigOnPtys) -> Result<String, PtyError> {
    let mut doc: toml::Table = rig
        .source
        .text
        .parse()
        .map_err(|e: toml::de::Error| PtyError::RigText(e.to_string()))?;
    let devices = sub_table(&mut doc, "devices")?;
    let set = |devices: &mut toml::Table, device: &str, value: String| -> Result<(), PtyError> {
        sub_table(devices, device)?.insert("transport".into(), toml::Value::String(value));
        Ok(())
    };
    set(devices, "arm", served.arm.path.clone())?;
    set(devices, "table", format!("slcan:{}", served.table.path))?;
    set(devices, "panel", served.panel.path.clone())?;
    devices.insert(
        "world".into(),
        toml::Value::String(served.world.path.display().to_string()),
    );
    let body = toml::to_string(&doc).map_err(|e| PtyError::RigText(e.to_string()))?;
    Ok(format!(
        "# Written by `rigcal sim-device rig --pty --write-rig` from {}: the same rig, its devices\n\
         # on the pseudo-terminals of that process (valid while it runs).\n{body}",
        rig.source
            .path
            .as_deref()
            .map_or_else(|| rig.name.clone(), |p| p.display().to_string()),
    ))
}

/// `table[key]` as a table, made empty when missing.
fn sub_table<'a>(table: &'a mut toml::Table, key: &str) -> Result<&'a mut toml::Table, PtyError> {
    table
        .entry(key)
        .or_insert_with(|| toml::Value::Table(toml::Table::new()))
        .as_table_mut()
        .ok_or_else(|| PtyError::RigText(format!("`{key}` in the rig file is not a table")))
}

/// One request on the world's side channel (one JSON line each way).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "op", rename_all = "snake_case")]
pub enum WorldRequest {
    /// A new session process: the world as it was when served (a fresh world in a dry run).
    Begin,
    /// [`RigHook::before_measurement`].
    BeforeMeasurement {
        /// The measurement's `seq`.
        seq: u64,
        /// Its attempt.
        attempt: u32,
    },
    /// [`RigHook::time_base`], as the session's time now (the two processes' clocks differ).
    TimeBase {
        /// Session time now (s).
        session_s: f64,
    },
    /// [`RigHook::snapshot`].
    Snapshot,
    /// [`RigHook::restore`].
    Restore {
        /// The journalled snapshot.
        state: serde_json::Value,
    },
}

/// The answer to a [`WorldRequest`].
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct WorldReply {
    /// The snapshot, for [`WorldRequest::Snapshot`].
    #[serde(default)]
    pub state: Option<serde_json::Value>,
    /// Why the request failed.
    #[serde(default)]
    pub error: Option<String>,
}

/// A served world's side channel: a Unix socket whose requests go to the world's hook. The
/// socket file is removed when this is dropped.
#[derive(Debug)]
pub struct WorldChannel {
    /// The socket's path.
    pub path: PathBuf,
    stop: Arc<AtomicBool>,
    handle: Option<JoinHandle<()>>,
}

/// The served world: its hook, its state when served, and the clock its time runs on.
struct ServedWorld {
    hook: Box<dyn RigHook>,
    fresh: Option<serde_json::Value>,
    clock: SharedClock,
}

impl ServedWorld {
    fn answer(&mut self, req: WorldRequest) -> WorldReply {
        let mut reply = WorldReply::default();
        match req {
            WorldRequest::Begin => {
                self.hook.before_measurement(0, 0);
                if let Some(fresh) = &self.fresh {
                    reply.error = self.hook.restore(fresh).err().map(|e| e.to_string());
                }
            }
            WorldRequest::BeforeMeasurement { seq, attempt } => {
                self.hook.before_measurement(seq, attempt);
            }
            WorldRequest::TimeBase { session_s } => {
                let offset = session_s - self.clock.now().as_secs_f64();
                self.hook.time_base(offset);
            }
            WorldRequest::Snapshot => reply.state = self.hook.snapshot(),
            WorldRequest::Restore { state } => {
                reply.error = self.hook.restore(&state).err().map(|e| e.to_string());
            }
        }
        reply
    }
}

/// How long the accepting thread sleeps between looks at its stop flag.
const ACCEPT_TICK: Duration = Duration::from_millis(10);

impl WorldChannel {
    /// Serves `hook` (the world's, on `clock`) on a new Unix socket at `path`.
    pub fn serve(
        hook: Box<dyn RigHook>,
        clock: SharedClock,
        path: &Path,
    ) -> Result<Self, PtyError> {
        let socket_err = |source| PtyError::Socket {
            path: path.to_path_buf(),
            source,
        };
        let listener = UnixListener::bind(path).map_err(socket_err)?;
        listener.set_nonblocking(true).map_err(socket_err)?;
        let fresh = hook.snapshot();
        let world = Arc::new(Mutex::new(ServedWorld { hook, fresh, clock }));
        let stop = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&stop);
        let handle = std::thread::spawn(move || {
            while !flag.load(Ordering::SeqCst) {
                match listener.accept() {
                    Ok((stream, _)) => {
                        let world = Arc::clone(&world);
                        // One thread per session process; it ends when that process goes.
                        std::thread::spawn(move || serve_session(stream, &world));
                    }
                    Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                        std::thread::sleep(ACCEPT_TICK);
                    }
                    Err(e) => {
                        tracing::error!(%e, "the world's side channel stopped accepting");
                        return;
                    }
                }
            }
        });
        Ok(WorldChannel {
            path: path.to_path_buf(),
            stop,
            handle: Some(handle),
        })
    }
}

impl Drop for WorldChannel {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Answers one session process's requests until it hangs up.
fn serve_session(stream: UnixStream, world: &Mutex<ServedWorld>) {
    // Accepted sockets may inherit the listener's non-blocking mode; requests are waited for.
    if stream.set_nonblocking(false).is_err() {
        return;
    }
    let Ok(mut out) = stream.try_clone() else {
        return;
    };
    for line in BufReader::new(stream).lines() {
        let Ok(line) = line else { return };
        let reply = match serde_json::from_str::<WorldRequest>(&line) {
            Ok(req) => lock(world).answer(req),
            Err(e) => WorldReply {
                error: Some(format!("not a world request ({e}): {line}")),
                ..WorldReply::default()
            },
        };
        let Ok(text) = serde_json::to_string(&reply) else {
            return;
        };
        if writeln!(out, "{text}").and_then(|()| out.flush()).is_err() {
            return;
        }
    }
}

/// How long the session waits for the served world to answer.
const WORLD_TIMEOUT: Duration = Duration::from_secs(5);

/// The session's [`RigHook`] on a world served by another process ([`serve_rig_on_ptys`]):
/// each call is a request on the world's socket, answered before the session goes on (so a
/// measurement's draws are set before its arm command leaves).
pub struct RemoteHook {
    path: PathBuf,
    link: Mutex<BufReader<UnixStream>>,
    clock: SharedClock,
}

impl std::fmt::Debug for RemoteHook {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RemoteHook")
            .field("path", &self.path)
            .finish_non_exhaustive()
    }
}

impl RemoteHook {
    /// Connects to the world at `path` and begins a session there (a fresh world); `clock` is
    /// the session's devices' clock (the time base is sent as session time).
    pub fn connect(path: &Path, clock: SharedClock) -> Result<Self, HookError> {
        let failed = |what: &str, e: std::io::Error| {
            HookError {
            reason: format!(
                "cannot {what} the simulated world's socket {} ({e}); is `rigcal sim-device rig` still running?",
                path.display()
            ),
        }
        };
        let stream = UnixStream::connect(path).map_err(|e| failed("connect to", e))?;
        stream
            .set_read_timeout(Some(WORLD_TIMEOUT))
            .and_then(|()| stream.set_write_timeout(Some(WORLD_TIMEOUT)))
            .map_err(|e| failed("set the timeouts of", e))?;
        let hook = RemoteHook {
            path: path.to_path_buf(),
            link: Mutex::new(BufReader::new(stream)),
            clock,
        };
        hook.call(&WorldRequest::Begin)?;
        Ok(hook)
    }

    /// One request and its answer.
    fn call(&self, req: &WorldRequest) -> Result<WorldReply, HookError> {
        let failed = |e: String| HookError {
            reason: format!("the simulated world at {}: {e}", self.path.display()),
        };
        let text = serde_json::to_string(req).map_err(|e| failed(e.to_string()))?;
        let mut link = lock(&self.link);
        writeln!(link.get_mut(), "{text}")
            .and_then(|()| link.get_mut().flush())
            .map_err(|e| failed(format!("request not sent ({e})")))?;
        let mut line = String::new();
        match link.read_line(&mut line) {
            Ok(0) => return Err(failed("it hung up".into())),
            Ok(_) => {}
            Err(e) => return Err(failed(format!("no answer within {WORLD_TIMEOUT:?} ({e})"))),
        }
        let reply: WorldReply =
            serde_json::from_str(&line).map_err(|e| failed(format!("unreadable answer ({e})")))?;
        match reply.error {
            Some(e) => Err(failed(e)),
            None => Ok(reply),
        }
    }

    /// A call whose failure the hook's signature cannot return: logged as an error (the
    /// rehearsal's readings are then not the dry run's).
    fn tell(&self, req: &WorldRequest) {
        if let Err(e) = self.call(req) {
            tracing::error!(%e, "the simulated world missed a request; this session's readings are not the dry run's");
        }
    }
}

impl RigHook for RemoteHook {
    fn before_measurement(&mut self, seq: u64, attempt: u32) {
        self.tell(&WorldRequest::BeforeMeasurement { seq, attempt });
    }

    fn time_base(&mut self, session_minus_clock_s: f64) {
        let session_s = self.clock.now().as_secs_f64() + session_minus_clock_s;
        self.tell(&WorldRequest::TimeBase { session_s });
    }

    fn snapshot(&self) -> Option<serde_json::Value> {
        match self.call(&WorldRequest::Snapshot) {
            Ok(reply) => reply.state,
            Err(e) => {
                tracing::error!(%e, "no motion history from the simulated world for the journal");
                None
            }
        }
    }

    fn restore(&mut self, snapshot: &serde_json::Value) -> Result<(), HookError> {
        self.call(&WorldRequest::Restore {
            state: snapshot.clone(),
        })
        .map(|_| ())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::devices::clock::RealClock;

    /// A world that is its last (seq, attempt) and a counter of moves.
    #[derive(Default)]
    struct Counting {
        draws: (u64, u32),
        moves: u64,
    }

    impl RigHook for Counting {
        fn before_measurement(&mut self, seq: u64, attempt: u32) {
            self.draws = (seq, attempt);
            self.moves += 1;
        }
        fn snapshot(&self) -> Option<serde_json::Value> {
            Some(serde_json::json!({ "moves": self.moves, "seq": self.draws.0 }))
        }
        fn restore(&mut self, s: &serde_json::Value) -> Result<(), HookError> {
            self.moves = s["moves"].as_u64().ok_or_else(|| HookError {
                reason: "no moves".into(),
            })?;
            Ok(())
        }
    }

    #[test]
    fn a_remote_hook_reaches_the_served_world_and_each_session_begins_on_a_fresh_one() {
        let dir = tempfile::tempdir().expect("temporary directory");
        let path = dir.path().join("world.sock");
        let channel = WorldChannel::serve(Box::<Counting>::default(), RealClock::shared(), &path)
            .expect("served");
        let mut a = RemoteHook::connect(&path, RealClock::shared()).expect("connected");
        a.before_measurement(7, 1);
        a.before_measurement(8, 0);
        let seen = a.snapshot().expect("a snapshot");
        assert_eq!(seen["moves"], 2);
        assert_eq!(seen["seq"], 8);
        // A second session process (a resume) begins on the world as served, then restores.
        drop(a);
        let mut b = RemoteHook::connect(&path, RealClock::shared()).expect("connected");
        assert_eq!(b.snapshot().expect("a snapshot")["moves"], 0);
        b.restore(&seen).expect("restored");
        assert_eq!(b.snapshot().expect("a snapshot")["moves"], 2);
        let e = b.restore(&serde_json::json!({})).expect_err("refused");
        assert!(e.reason.contains("no moves"), "{e}");
        drop(channel);
        assert!(
            !path.exists(),
            "the socket file is removed with the channel"
        );
        let e = RemoteHook::connect(&path, RealClock::shared()).expect_err("nothing served");
        assert!(e.reason.contains("sim-device rig"), "{e}");
    }
}
