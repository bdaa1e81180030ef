//! Progress of a run: an indicatif bar on a terminal, one plain line per finished case
//! otherwise (logs, CI), nothing with `--quiet`.

use indicatif::{ProgressBar, ProgressStyle};
use schema::record::Status;
use std::io::IsTerminal;

pub enum Mode {
    Bar,
    Lines,
    Quiet,
}

pub struct Progress {
    mode: Mode,
    bar: Option<ProgressBar>,
    total: usize,
    done: usize,
    failed: usize,
    skipped: usize,
    /// How far the long cases running now are, shown after the counts.
    running: String,
    /// The round of an adaptive study these cases are.
    round: Option<usize>,
}

impl Mode {
    /// A bar on a terminal, lines elsewhere, nothing under `--quiet`.
    pub fn detect() -> Mode {
        match (crate::console::quiet(), std::io::stderr().is_terminal()) {
            (true, _) => Mode::Quiet,
            (false, true) => Mode::Bar,
            (false, false) => Mode::Lines,
        }
    }
}

impl Progress {
    pub fn new(mode: Mode, total: usize, skipped: usize) -> Progress {
        let bar = matches!(mode, Mode::Bar).then(|| {
            let bar = ProgressBar::new(total as u64);
            bar.set_style(
                ProgressStyle::with_template(
                    "{prefix}{bar:30} {pos}/{len} {msg} [{elapsed} < {eta}]",
                )
                .expect("a valid template"),
            );
            bar
        });
        let mut progress = Progress {
            mode,
            bar,
            total,
            done: 0,
            failed: 0,
            skipped,
            running: String::new(),
            round: None,
        };
        progress.update_message();
        progress
    }

    /// The cases of round `round` of an adaptive study, which each line then names.
    pub fn in_round(mut self, round: Option<usize>) -> Progress {
        self.round = round;
        if let (Some(bar), Some(round)) = (&self.bar, round) {
            bar.set_prefix(format!("round {round} "));
        }
        self
    }

    /// `[k/N]`, or `[round r: k/N]` in an adaptive study.
    fn counter(&self) -> String {
        match self.round {
            Some(round) => format!("[round {round}: {}/{}]", self.done, self.total),
            None => format!("[{}/{}]", self.done, self.total),
        }
    }

    /// A case finished with `status`.
    pub fn finished(&mut self, label: &str, status: Status, message: &str) {
        self.done += 1;
        if status == Status::Failed {
            self.failed += 1;
        }
        match self.mode {
            Mode::Bar => {
                let bar = self.bar.as_ref().expect("bar mode has a bar");
                if status == Status::Failed {
                    bar.println(shown(format!("failed: {label}: {}", first_line(message))));
                }
                bar.inc(1);
                self.update_message();
            }
            Mode::Lines => {
                let detail = match status {
                    Status::Failed => format!(": {}", first_line(message)),
                    Status::Ok | Status::Diverged => String::new(),
                };
                let line = format!("{} {status} {label}{detail}", self.counter());
                errln!("{}", shown(line));
            }
            Mode::Quiet => {}
        }
    }

    /// A case that failed for a reason outside it (timeout, a killed process) starts again.
    pub fn retrying(&mut self, label: &str, attempt: usize, message: &str) {
        self.say(format!(
            "retrying {label} (attempt {attempt}): {}",
            first_line(message)
        ));
    }

    /// A case whose worker died or hung on it runs again in a process of its own.
    pub fn alone(&mut self, label: &str, why: &str) {
        self.say(format!(
            "running {label} again in a process of its own: {}",
            first_line(why)
        ));
    }

    /// A line above the bar, or on its own; nothing when quiet.
    fn say(&self, line: String) {
        let line = shown(line);
        match self.mode {
            Mode::Bar => self.bar.as_ref().expect("bar mode has a bar").println(line),
            Mode::Lines => errln!("{line}"),
            Mode::Quiet => {}
        }
    }

    /// A planned case that this process did not run: another one runs it or just ran it.
    pub fn passed(&mut self, label: &str, why: &str) {
        self.done += 1;
        self.skipped += 1;
        match self.mode {
            Mode::Bar => {
                let bar = self.bar.as_ref().expect("bar mode has a bar");
                bar.println(shown(format!("skipped: {label}: {why}")));
                bar.inc(1);
                self.update_message();
            }
            Mode::Lines => errln!(
                "{}",
                shown(format!("{} skipped {label}: {why}", self.counter()))
            ),
            Mode::Quiet => {}
        }
    }

    /// How far the long cases running now are (`label: step k/N, ~S s left` each), on the bar.
    pub fn running(&mut self, cases: &[String]) {
        if self.bar.is_some() {
            self.running = cases.join("; ");
            self.update_message();
        }
    }

    fn update_message(&mut self) {
        if let Some(bar) = &self.bar {
            let running = match self.running.as_str() {
                "" => String::new(),
                cases => format!("; running {cases}"),
            };
            bar.set_message(format!(
                "done {}, skipped {}, failed {}{running}",
                self.done, self.skipped, self.failed
            ));
        }
    }

    pub fn close(&self) {
        if let Some(bar) = &self.bar {
            bar.finish();
        }
    }
}

fn first_line(message: &str) -> &str {
    message.lines().next().unwrap_or("")
}

/// A line for the terminal: labels and messages come from study files and solvers, and what a
/// terminal would act on in them (escape sequences) is shown escaped.
fn shown(line: String) -> String {
    match schema::text::printable(&line) {
        std::borrow::Cow::Borrowed(_) => line,
        std::borrow::Cow::Owned(escaped) => escaped,
    }
}
