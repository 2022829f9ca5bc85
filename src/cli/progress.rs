//! Session progress on the terminal: a bar with rate and ETA on a terminal, a log line every
//! tenth of the points otherwise.

use std::io::IsTerminal;
use std::time::Instant;

use rigcal_devices::session::{Progress, ProgressSink};

/// A bar if stderr is a terminal, lines otherwise.
pub(crate) fn session_progress(total: usize) -> Progress {
    if std::io::stderr().is_terminal() {
        let bar = indicatif::ProgressBar::new(total as u64);
        if let Ok(style) = indicatif::ProgressStyle::with_template(
            "{bar:40} {pos}/{len} points  {per_sec}  ETA {eta}  {msg}",
        ) {
            bar.set_style(style);
        }
        Progress::Watch(Box::new(Bar(bar)))
    } else {
        Progress::Watch(Box::new(Lines {
            every: (total / 10).max(1),
            started: Instant::now(),
        }))
    }
}

struct Bar(indicatif::ProgressBar);

impl ProgressSink for Bar {
    fn update(&self, done: usize, _total: usize, rig_s: f64) {
        self.0.set_position(done as u64);
        self.0.set_message(format!("rig {rig_s:.0} s"));
    }

    fn finish(&self) {
        self.0.finish();
    }
}

struct Lines {
    every: usize,
    started: Instant,
}

impl ProgressSink for Lines {
    fn update(&self, done: usize, total: usize, rig_s: f64) {
        if done.is_multiple_of(self.every) || done == total {
            let elapsed = self.started.elapsed().as_secs_f64();
            eprintln!(
                "session: {done}/{total} points, rig time {rig_s:.0} s, {:.1} points/s",
                done as f64 / elapsed.max(1e-9)
            );
        }
    }
}
