//! Progress of a run on stderr.
//!
//! On a terminal this is indicatif's bar, redrawn four times a second. Without one
//! (`make`, a log file, CI) indicatif draws nothing, so a plain line is written
//! instead, at most once every [`log_interval`] (60 s unless `BALLAST_PROGRESS_S` says
//! otherwise). The runs of hours (`make track-paper`, the seed-sized beds, the Table 3
//! bench) then say in their logs how far they are and when they will end.

use std::io::{IsTerminal, Write as _};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// The environment variable that sets the seconds between two progress lines when
/// stderr is not a terminal.
pub const INTERVAL_VAR: &str = "BALLAST_PROGRESS_S";

/// Seconds between two progress lines without a terminal, when the environment does
/// not set [`INTERVAL_VAR`].
const DEFAULT_INTERVAL_S: f64 = 60.0;

/// The interval between two progress lines without a terminal: [`INTERVAL_VAR`] (a
/// number of seconds, 0 for a line at every update) or 60 s. A value that is not a
/// number of seconds is reported once on stderr and the default used.
pub fn log_interval() -> Duration {
    match std::env::var(INTERVAL_VAR) {
        Err(_) => Duration::from_secs_f64(DEFAULT_INTERVAL_S),
        Ok(text) => match text.trim().parse::<f64>() {
            Ok(s) if s.is_finite() && s >= 0.0 => Duration::from_secs_f64(s),
            _ => {
                eprintln!(
                    "warning: {INTERVAL_VAR}={text:?} is not a number of seconds ≥ 0; \
                     progress lines every {DEFAULT_INTERVAL_S} s"
                );
                Duration::from_secs_f64(DEFAULT_INTERVAL_S)
            }
        },
    }
}

/// A run's progress: a bar on a terminal, throttled lines otherwise.
pub struct Progress {
    bar: ProgressBar,
    label: String,
    len: Option<u64>,
    lines: Option<Lines>,
}

/// The state of the plain lines written without a terminal.
struct Lines {
    every: Duration,
    start: Instant,
    last: Instant,
    /// The position of the first update (a resumed run starts part way).
    first: Option<u64>,
}

impl Progress {
    /// A bar over `len` steps; `label` names the run in the lines ("ballast-qdem:
    /// track").
    pub fn steps(len: u64, label: &str) -> Self {
        Self::new(
            Some(len),
            label,
            "{prefix}{bar:40} {pos}/{len} steps, {per_sec}, eta {eta} {msg}",
        )
    }

    /// A spinner with a message, for a run whose length is not known in advance (a
    /// deposition runs until its phases settle).
    pub fn spinner(label: &str) -> Self {
        Self::new(None, label, "{prefix}{spinner} {elapsed} {msg}")
    }

    fn new(len: Option<u64>, label: &str, template: &str) -> Self {
        let terminal = std::io::stderr().is_terminal();
        let target = if terminal {
            ProgressDrawTarget::stderr_with_hz(4)
        } else {
            ProgressDrawTarget::hidden()
        };
        let bar = ProgressBar::with_draw_target(len, target);
        bar.set_style(ProgressStyle::with_template(template).expect("valid template"));
        bar.set_prefix(format!("{label} "));
        let now = Instant::now();
        Progress {
            bar,
            label: label.to_string(),
            len,
            lines: (!terminal).then(|| Lines {
                every: log_interval(),
                start: now,
                last: now,
                first: None,
            }),
        }
    }

    /// Moves the bar to `pos` steps done; without a terminal, writes a line if the
    /// interval has passed since the last one.
    pub fn set_position(&mut self, pos: u64) {
        self.bar.set_position(pos);
        self.maybe_line(pos);
    }

    /// Sets the text shown after the bar (the spinner's state, or what a bar of steps
    /// adds to its next line). A spinner without a terminal writes a line if the
    /// interval has passed; a bar of steps waits for its next position.
    pub fn set_message(&mut self, message: String) {
        self.bar.set_message(message);
        self.bar.tick();
        if self.len.is_none() {
            self.maybe_line(0);
        }
    }

    /// Writes `line` to stdout above the bar (a note the run's log keeps).
    pub fn note(&self, line: &str) {
        self.bar.suspend(|| println!("{line}"));
    }

    /// Leaves the bar as it stands (the run stopped on an error).
    pub fn abandon(&self) {
        self.bar.abandon();
    }

    /// Clears the bar at the end of the run.
    pub fn finish_and_clear(&self) {
        self.bar.finish_and_clear();
    }

    fn maybe_line(&mut self, pos: u64) {
        let Some(lines) = &mut self.lines else {
            return;
        };
        let first = *lines.first.get_or_insert(pos);
        let now = Instant::now();
        // A bar that has not moved has nothing to tell (a spinner's news is its message).
        let moved = self.len.is_none() || pos > first;
        if !moved || now.duration_since(lines.last) < lines.every {
            return;
        }
        lines.last = now;
        let elapsed = now.duration_since(lines.start);
        let message = self.bar.message();
        let line = match self.len {
            Some(len) => steps_line(&self.label, pos, len, pos - first, elapsed, &message),
            None => format!(
                "{}: {message}, {} elapsed",
                self.label,
                duration_text(elapsed)
            ),
        };
        let _ = writeln!(std::io::stderr().lock(), "{line}");
    }
}

/// One progress line of a run of `len` steps at `pos`, `done` of them in `elapsed`
/// (since this process started: a resumed run's rate is its own):
/// `label: step 1200/365200 (0.3 %), 412 steps/s, eta 14 min 42 s`, then `message`.
fn steps_line(
    label: &str,
    pos: u64,
    len: u64,
    done: u64,
    elapsed: Duration,
    message: &str,
) -> String {
    let percent = 100.0 * pos as f64 / len.max(1) as f64;
    let seconds = elapsed.as_secs_f64();
    let rate = if seconds > 0.0 {
        done as f64 / seconds
    } else {
        0.0
    };
    let eta = if rate > 0.0 {
        duration_text(Duration::from_secs_f64(
            len.saturating_sub(pos) as f64 / rate,
        ))
    } else {
        "unknown".to_string()
    };
    let mut line =
        format!("{label}: step {pos}/{len} ({percent:.1} %), {rate:.0} steps/s, eta {eta}");
    if !message.is_empty() {
        line.push_str(", ");
        line.push_str(message);
    }
    line
}

/// A duration for people: `45 s`, `12 min 30 s`, `2 h 05 min`.
fn duration_text(d: Duration) -> String {
    let s = d.as_secs_f64().round() as u64;
    match s {
        0..60 => format!("{s} s"),
        60..3600 => format!("{} min {:02} s", s / 60, s % 60),
        _ => format!("{} h {:02} min", s / 3600, (s % 3600) / 60),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_gives_the_share_done_the_rate_and_the_time_left() {
        // 1 000 of 10 000 steps, 500 of them in this process in 10 s: 50 steps/s, and
        // the 9 000 left take 180 s.
        let line = steps_line(
            "ballast-qdem: track",
            1_000,
            10_000,
            500,
            Duration::from_secs(10),
            "t = 0.0100 s",
        );
        assert_eq!(
            line,
            "ballast-qdem: track: step 1000/10000 (10.0 %), 50 steps/s, eta 3 min 00 s, t = 0.0100 s"
        );
        let start = steps_line("x", 0, 10, 0, Duration::ZERO, "");
        assert_eq!(start, "x: step 0/10 (0.0 %), 0 steps/s, eta unknown");
    }

    #[test]
    fn durations_read_in_the_largest_units() {
        assert_eq!(duration_text(Duration::from_secs_f64(44.6)), "45 s");
        assert_eq!(duration_text(Duration::from_secs(750)), "12 min 30 s");
        assert_eq!(duration_text(Duration::from_secs(7_500)), "2 h 05 min");
    }
}
