//! What a session tells whoever watches it: points done, rig time. The library draws nothing;
//! the command line turns this into a bar or log lines.

/// Someone watching a session (the command line's bar, say).
pub trait ProgressSink: Send + Sync {
    /// `done` of `total` points are measured, at session time `rig_s` (s).
    fn update(&self, done: usize, total: usize, rig_s: f64);
    /// The session has ended.
    fn finish(&self) {}
}

/// A session's progress: nobody watching, or a [`ProgressSink`].
pub enum Progress {
    /// No one is told.
    Quiet,
    /// Each measured point is told to the sink.
    Watch(Box<dyn ProgressSink>),
}

impl std::fmt::Debug for Progress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Progress::Quiet => f.write_str("Progress::Quiet"),
            Progress::Watch(_) => f.write_str("Progress::Watch(..)"),
        }
    }
}

impl Progress {
    /// Tells the sink that `done` of `total` points are measured at session time `rig_s`.
    pub(crate) fn update(&self, done: usize, total: usize, rig_s: f64) {
        if let Progress::Watch(sink) = self {
            sink.update(done, total, rig_s);
        }
    }

    /// Tells the sink that the session has ended.
    pub(crate) fn finish(&self) {
        if let Progress::Watch(sink) = self {
            sink.finish();
        }
    }
}
