//! Session progress on the terminal: a bar with rate and ETA, or plain lines in a log.

use std::io::IsTerminal;
use std::time::Instant;

/// Progress output: a bar with rate and ETA on a terminal, plain lines otherwise.
#[derive(Debug)]
pub enum Progress {
    /// No output.
    Quiet,
    /// A log line every `every` points.
    Lines {
        /// Points between lines.
        every: usize,
        /// Started at.
        started: Instant,
    },
    /// An indicatif bar.
    Bar(indicatif::ProgressBar),
}

impl Progress {
    /// A bar if stderr is a terminal, lines otherwise.
    pub fn auto(total: usize) -> Progress {
        if std::io::stderr().is_terminal() {
            let bar = indicatif::ProgressBar::new(total as u64);
            if let Ok(style) = indicatif::ProgressStyle::with_template(
                "{bar:40} {pos}/{len} points  {per_sec}  ETA {eta}  {msg}",
            ) {
                bar.set_style(style);
            }
            Progress::Bar(bar)
        } else {
            Progress::Lines {
                every: (total / 10).max(1),
                started: Instant::now(),
            }
        }
    }

    /// Shows `done` of `total` points at session time `rig_s`.
    pub(crate) fn update(&self, done: usize, total: usize, rig_s: f64) {
        match self {
            Progress::Quiet => {}
            Progress::Lines { every, started } => {
                if done.is_multiple_of(*every) || done == total {
                    let el = started.elapsed().as_secs_f64();
                    eprintln!(
                        "session: {done}/{total} points, rig time {:.0} s, {:.1} points/s",
                        rig_s,
                        done as f64 / el.max(1e-9)
                    );
                }
            }
            Progress::Bar(b) => {
                b.set_position(done as u64);
                b.set_message(format!("rig {:.0} s", rig_s));
            }
        }
    }

    /// Ends the output.
    pub(crate) fn finish(&self) {
        if let Progress::Bar(b) = self {
            b.finish();
        }
    }
}
