//! What a cluster job asks of its scheduler: the study's `resources` section and the flags of
//! `nlstudy submit`, one definition for both. Every value is checked where it is read, against
//! what the scheduler's directive accepts, because it is written into a job script: a newline
//! in a partition name would end the `#SBATCH` line and run the rest as a shell command.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::num::NonZeroUsize;
use std::str::FromStr;

/// The cluster schedulers nlstudy writes job scripts for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Scheduler {
    Slurm,
    Lsf,
}

impl fmt::Display for Scheduler {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Scheduler::Slurm => "slurm",
            Scheduler::Lsf => "lsf",
        })
    }
}

/// What a job asks of the scheduler: the study's `resources` section, overridden by flags.
#[derive(Clone, Debug, Default, Deserialize, PartialEq, clap::Args)]
#[serde(deny_unknown_fields)]
pub struct Resources {
    /// Nodes per job.
    #[arg(long)]
    pub nodes: Option<NonZeroUsize>,
    /// MPI tasks per job (default: the largest rank count among the job's cases).
    #[arg(long)]
    pub tasks: Option<NonZeroUsize>,
    /// Wall time per job: MINUTES, HH:MM:SS, D-HH, D-HH:MM or D-HH:MM:SS (LSF gets it as
    /// [HH:]MM, rounded up to the minute). `A:B` is refused: Slurm reads it as MM:SS, LSF as
    /// HH:MM. Without it, a job's limit comes from its points' stored timings.
    #[arg(long)]
    pub time: Option<WallTime>,
    /// Slurm partition or LSF queue.
    #[arg(long)]
    pub queue: Option<SchedulerName>,
    /// The account (Slurm) or project (LSF) charged.
    #[arg(long)]
    pub account: Option<SchedulerName>,
    /// Cases packed into one job (default: all of them in one job).
    #[arg(long)]
    pub cases_per_job: Option<NonZeroUsize>,
}

impl Resources {
    /// `self` with every field `over` sets replaced.
    pub fn overridden_by(&self, over: &Resources) -> Resources {
        Resources {
            nodes: over.nodes.or(self.nodes),
            tasks: over.tasks.or(self.tasks),
            time: over.time.or(self.time),
            queue: over.queue.clone().or_else(|| self.queue.clone()),
            account: over.account.clone().or_else(|| self.account.clone()),
            cases_per_job: over.cases_per_job.or(self.cases_per_job),
        }
    }
}

/// The longest name taken: Slurm's partition and account names are far shorter in practice.
const LONGEST_NAME: usize = 64;

/// A partition, queue or account name: letters, digits and `_ . -` (commas too, which separate
/// Slurm's partitions), the characters Slurm and LSF names use and no shell or directive can
/// misread.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(try_from = "String")]
pub struct SchedulerName(String);

impl fmt::Display for SchedulerName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl TryFrom<String> for SchedulerName {
    type Error = String;

    fn try_from(name: String) -> Result<Self, String> {
        let allowed = |c: char| c.is_ascii_alphanumeric() || "_.-,".contains(c);
        if name.is_empty() || name.len() > LONGEST_NAME {
            return Err(format!(
                "a scheduler name has 1 to {LONGEST_NAME} characters (got {})",
                name.chars().count()
            ));
        }
        if let Some(bad) = name.chars().find(|c| !allowed(*c)) {
            return Err(format!(
                "{:?} holds {bad:?}; a partition, queue or account name is letters, digits and `_ . - ,`, as the scheduler names it",
                name
            ));
        }
        Ok(SchedulerName(name))
    }
}

impl FromStr for SchedulerName {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        SchedulerName::try_from(text.to_string())
    }
}

/// The longest wall time taken: a year, beyond any cluster's limit.
const LONGEST_WALL_TIME_S: u64 = 366 * 24 * 3600;

/// A job's wall time, parsed from Slurm's forms and written in each scheduler's own.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(try_from = "String")]
pub struct WallTime {
    seconds: u64,
}

impl WallTime {
    /// `seconds`, if a wall time takes it (above zero, at most 366 days).
    pub fn from_seconds(seconds: u64) -> Option<WallTime> {
        (seconds > 0 && seconds <= LONGEST_WALL_TIME_S).then_some(WallTime { seconds })
    }

    pub fn seconds(&self) -> u64 {
        self.seconds
    }

    /// Slurm's `--time`: `HH:MM:SS`, or `D-HH:MM:SS` from a day on.
    pub fn slurm(&self) -> String {
        let (days, rest) = (self.seconds / 86_400, self.seconds % 86_400);
        let hms = format!(
            "{:02}:{:02}:{:02}",
            rest / 3600,
            rest % 3600 / 60,
            rest % 60
        );
        match days {
            0 => hms,
            d => format!("{d}-{hms}"),
        }
    }

    /// LSF's `-W`: `HH:MM`, the minutes rounded up so a job never gets less than asked.
    pub fn lsf(&self) -> String {
        let minutes = self.seconds.div_ceil(60);
        format!("{}:{:02}", minutes / 60, minutes % 60)
    }
}

impl TryFrom<String> for WallTime {
    type Error = String;

    fn try_from(text: String) -> Result<Self, String> {
        text.parse()
    }
}

impl FromStr for WallTime {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        let refuse = || {
            format!(
                "{text:?} is not a wall time; write MINUTES, HH:MM:SS, D-HH, D-HH:MM or D-HH:MM:SS (e.g. 00:30:00)"
            )
        };
        let number = |part: &str| -> Result<u64, String> {
            let digits = !part.is_empty() && part.len() <= 9;
            match digits && part.bytes().all(|b| b.is_ascii_digit()) {
                true => part.parse().map_err(|_| refuse()),
                false => Err(refuse()),
            }
        };
        let (days, clock) = match text.split_once('-') {
            Some((days, clock)) => (Some(number(days)?), clock),
            None => (None, text),
        };
        let parts = clock
            .split(':')
            .map(number)
            .collect::<Result<Vec<u64>, String>>()?;
        let (h, m, s) = match (days.is_some(), parts.as_slice()) {
            (false, [m]) => (0, *m, 0),
            (false, [a, b]) => {
                return Err(format!(
                    "{text:?} is ambiguous: Slurm reads A:B as minutes and seconds, LSF as hours and minutes; write 00:{a:02}:{b:02} or {a:02}:{b:02}:00 (HH:MM:SS)"
                ))
            }
            (_, [h, m, s]) => (*h, *m, *s),
            (true, [h]) => (*h, 0, 0),
            (true, [h, m]) => (*h, *m, 0),
            _ => return Err(refuse()),
        };
        let sexagesimal = parts.len() > 1 && (m >= 60 || s >= 60);
        if sexagesimal || (days.is_some() && h >= 24) {
            return Err(refuse());
        }
        let seconds = days.unwrap_or(0) * 86_400 + h * 3600 + m * 60 + s;
        if seconds == 0 || seconds > LONGEST_WALL_TIME_S {
            return Err(format!(
                "{text:?}: a wall time is above zero and at most 366 days"
            ));
        }
        Ok(WallTime { seconds })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn time(text: &str) -> Result<WallTime, String> {
        text.parse()
    }

    #[test]
    fn wall_times_are_read_in_slurms_forms_and_written_in_each_schedulers() {
        let cases = [
            ("30", "00:30:00", "0:30"),
            ("90", "01:30:00", "1:30"),
            ("01:00:00", "01:00:00", "1:00"),
            ("2-00", "2-00:00:00", "48:00"),
            ("1-02:03", "1-02:03:00", "26:03"),
            ("1-02:03:04", "1-02:03:04", "26:04"),
            ("00:00:01", "00:00:01", "0:01"),
        ];
        for (text, slurm, lsf) in cases {
            let t = time(text).unwrap();
            assert_eq!(
                (t.slurm().as_str(), t.lsf().as_str()),
                (slurm, lsf),
                "{text}"
            );
        }
    }

    #[test]
    fn anything_else_is_refused_with_the_forms() {
        for text in [
            "",
            "0",
            "00:00:00",
            "1:2:3:4",
            "-5",
            "1-",
            "1-25",
            "10:60",
            "05:30",
            "01:60:00",
            "1h",
            "01:00:00\ntouch /tmp/x",
            " 30",
            "400-00",
            "99999999999",
        ] {
            let e = time(text).unwrap_err();
            assert!(
                e.contains("wall time") || e.contains("ambiguous"),
                "{text:?}: {e}"
            );
        }
    }

    #[test]
    fn scheduler_names_hold_only_what_a_directive_cannot_misread() {
        for good in ["debug", "gpu-a100", "normal,long", "proj_42.x"] {
            assert_eq!(SchedulerName::from_str(good).unwrap().to_string(), good);
        }
        for bad in [
            "",
            "debug\ntouch /tmp/pwned",
            "a b",
            "x;id",
            "$(id)",
            "`id`",
            "q'",
            "q\"",
            "q\\",
            "q#",
            "q\u{1b}[2J",
            &"a".repeat(65),
        ] {
            assert!(SchedulerName::from_str(bad).is_err(), "{bad:?} accepted");
        }
    }
}
