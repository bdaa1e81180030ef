//! What `nlstudy submit --follow` needs beyond one submission: waiting for a round's jobs (the
//! scheduler asked with a growing pause, never a busy loop) and giving up on points whose jobs
//! keep ending without their records. The loop itself is the command's (`commands::submit`):
//! plan from the store, submit what is ready, wait, again, until nothing is left.

use super::ledger::{self, LedgerEntry};
use super::scheduler::{self, Scheduler};
use crate::run::plan::Planned;
use crate::store::{Fault, Store};
use std::collections::HashMap;
use std::time::{Duration, Instant};

/// The first pause between two questions to the scheduler; each later one is half as long
/// again, up to the driver's `--poll` (Snakemake's Slurm executor grows its pause likewise).
const FIRST_PAUSE: Duration = Duration::from_secs(1);

/// The first pause once every job left its mark: they leave the queue within moments, and a
/// round's next jobs wait for that (a second's pause was a second of every round).
const ENDED_PAUSE: Duration = Duration::from_millis(100);

/// Questions to the scheduler that may fail in a row (a restarting controller) before the
/// driver stops; its jobs stay queued, and the driver started again finds them.
const FAILED_QUESTIONS: usize = 5;

/// Pauses that grow by half from `FIRST_PAUSE` to `most`.
pub struct Backoff {
    next: Duration,
    most: Duration,
}

impl Backoff {
    pub fn new(most: Duration) -> Backoff {
        Backoff::from(FIRST_PAUSE, most)
    }

    fn from(first: Duration, most: Duration) -> Backoff {
        Backoff {
            next: first.min(most),
            most,
        }
    }

    /// The next pause.
    pub fn pause(&mut self) -> Duration {
        let now = self.next;
        self.next = (self.next * 3 / 2).min(self.most);
        now
    }
}

/// How long a wait took and how often it asked the scheduler.
#[derive(Clone, Copy, Debug, Default)]
pub struct Waited {
    pub questions: usize,
    pub seconds: f64,
}

/// Sleeps until the scheduler holds none of the study's ledger jobs, asking it after pauses that
/// grow to `most`, and says how many are pending and running whenever that changes.
pub fn wait_for_jobs(
    store: &Store,
    scheduler: Scheduler,
    most: Duration,
    say: &mut dyn FnMut(String),
) -> Result<Waited, Fault> {
    let started = Instant::now();
    let mut backoff = Backoff::new(most);
    let (mut questions, mut failed, mut said) = (0, 0, String::new());
    loop {
        questions += 1;
        match ledger::held(store, scheduler) {
            Ok(held) if held.is_empty() => {
                return Ok(Waited {
                    questions,
                    seconds: started.elapsed().as_secs_f64(),
                })
            }
            Ok(held) => {
                failed = 0;
                let pending = held.iter().filter(|h| h.pending()).count();
                let line = format!(
                    "  jobs: {pending} pending, {} running",
                    held.len() - pending
                );
                if line != said {
                    said = line.clone();
                    say(line);
                }
                let ids: Vec<&str> = held.iter().map(|h| h.id.as_str()).collect();
                if pause_unless_ended(store, &ids, backoff.pause()) {
                    // Their `nlstudy run` ended: they leave the queue within moments.
                    backoff = Backoff::from(ENDED_PAUSE, most);
                }
            }
            Err(message) => {
                std::thread::sleep(backoff.pause());
                failed += 1;
                if failed == FAILED_QUESTIONS {
                    return Err(Fault::Io(format!(
                        "cannot ask {scheduler} which jobs are queued ({failed} times in a row: {message}); its jobs stay queued, and `nlstudy submit --follow` started again waits for them"
                    )));
                }
                log::warn!(
                    "cannot ask {scheduler} which jobs are queued ({message}); asking again"
                );
            }
        }
    }
}

/// How often a pause looks for the jobs' marks (a `stat` each).
const MARKS_EVERY: Duration = Duration::from_millis(250);

/// Sleeps `pause`, or less if every job of `ids` leaves its mark (`ended`) meanwhile: true
/// then. Marks there from the start do not shorten it (a job still leaving the queue).
fn pause_unless_ended(store: &Store, ids: &[&str], pause: Duration) -> bool {
    let until = Instant::now() + pause;
    let all_ended = || ids.iter().all(|id| super::ended::ended(store, id));
    let already = all_ended();
    loop {
        if !already && all_ended() {
            return true;
        }
        let now = Instant::now();
        if now >= until {
            return false;
        }
        std::thread::sleep(MARKS_EVERY.min(until - now));
    }
}

/// A point to run whose jobs ended without its record, more times than the driver resubmits.
pub struct Lost<'a> {
    pub point: &'a Planned,
    /// The jobs (array elements) that held it, oldest first.
    pub jobs: Vec<String>,
}

/// The points of `planned` still to run that the ledger's jobs held more than `resubmit` times
/// (every such job has ended: the driver asks only once the scheduler holds none).
pub fn lost<'a>(planned: &'a [Planned], entries: &[LedgerEntry], resubmit: usize) -> Vec<Lost<'a>> {
    // The jobs of each key, once: a scan of the ledger per point was the driver's most costly
    // step by the last rounds of the map (1,134 points × 13,600 keys a round).
    let mut jobs_of: HashMap<&str, Vec<String>> = HashMap::new();
    for (id, keys) in entries.iter().flat_map(LedgerEntry::parts) {
        for key in keys {
            jobs_of.entry(key.as_str()).or_default().push(id.clone());
        }
    }
    planned
        .iter()
        .filter(|p| p.runs())
        .filter_map(|point| {
            let jobs = jobs_of.get(point.key.as_str())?;
            (jobs.len() > resubmit).then(|| Lost {
                point,
                jobs: jobs.clone(),
            })
        })
        .collect()
}

/// Why a lost point is stored failed: its jobs and what became of each, from Slurm's accounting
/// where the cluster keeps one (`CANCELLED`, `TIMEOUT`, `NODE_FAIL`…), else that it left the
/// queue.
pub fn why_lost(scheduler: Scheduler, lost: &Lost) -> String {
    let ids: Vec<&str> = lost.jobs.iter().map(String::as_str).collect();
    let states = match scheduler {
        Scheduler::Slurm => final_states(&ids),
        Scheduler::Lsf => Default::default(),
    };
    let ended: Vec<String> = ids
        .iter()
        .map(|id| match states.get(*id) {
            Some(state) => format!("job {id} {state}"),
            None => format!("job {id} left the queue"),
        })
        .collect();
    format!(
        "submitted {} times, and its jobs ended without its record: {}",
        lost.jobs.len(),
        ended.join(", ")
    )
}

/// Slurm's accounting of the ended jobs `ids`, asked again (up to five times, a second apart)
/// while it still names one held (`scheduler::phase`), not how it ended: the controller tells slurmdbd a moment after the
/// job leaves the queue. Empty where the cluster keeps no accounting.
fn final_states(ids: &[&str]) -> std::collections::HashMap<String, String> {
    let mut states = Default::default();
    for ask in 0..5 {
        if ask > 0 {
            std::thread::sleep(Duration::from_secs(1));
        }
        let Ok(now) = scheduler::accounted_states(ids) else {
            return states;
        };
        states = now;
        if ids.iter().all(|id| {
            states
                .get(*id)
                .is_some_and(|s| scheduler::phase(s).is_none())
        }) {
            break;
        }
    }
    states
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::run::plan::{Decision, Reason, Skipped};
    use serde_json::json;

    /// Points n = 8, 16, 32 to run.
    fn points() -> Vec<Planned> {
        let study = json!({"name": "lost", "base": {}, "sweep": [{"product": {"n": [8, 16, 32]}}]});
        let points = crate::kinds::parse(&study.to_string())
            .unwrap()
            .expand()
            .unwrap();
        points
            .into_iter()
            .map(|point| Planned {
                key: crate::store::case_id_and_key(&point.label(), "", 0).1,
                point,
                case: Err("not checked".into()),
                case_id: Default::default(),
                decision: Decision::Run(Reason::Missing),
                probe: None,
            })
            .collect()
    }

    /// A job of the ledger that held `points`.
    fn job(id: &str, points: &[&Planned]) -> LedgerEntry {
        LedgerEntry {
            scheduler: Scheduler::Slurm,
            id: id.into(),
            name: format!("nlstudy-lost-{id}"),
            keys: points.iter().map(|p| p.key.to_string()).collect(),
            elements: Vec::new(),
            submitted: 0,
            whole: false,
        }
    }

    /// A point is given up on once its jobs ended without it more than `resubmit` times; one
    /// stored since (no longer to run) is not, whatever its jobs.
    #[test]
    fn a_point_is_lost_after_its_resubmissions() {
        let mut planned = points();
        let (a, b, c) = (&planned[0], &planned[1], &planned[2]);
        let ledger = [job("41", &[a, b, c]), job("42", &[a, b]), job("43", &[a])];
        let lost = |planned: &[Planned], resubmit| -> Vec<(String, Vec<String>)> {
            let lost = super::lost(planned, &ledger, resubmit);
            lost.into_iter()
                .map(|l| (l.point.point.label(), l.jobs))
                .collect()
        };
        assert_eq!(
            lost(&planned, 1),
            [
                (
                    "n=8".to_string(),
                    vec!["41".to_string(), "42".into(), "43".into()]
                ),
                ("n=16".to_string(), vec!["41".to_string(), "42".into()]),
            ]
        );
        assert_eq!(lost(&planned, 2).len(), 1);
        assert!(lost(&planned, 3).is_empty());
        planned[0].decision = Decision::Skip(Skipped::Stored(schema::record::Status::Ok));
        assert_eq!(lost(&planned, 2).len(), 0);
    }

    #[test]
    fn pauses_grow_by_half_to_the_most() {
        let mut backoff = Backoff::new(Duration::from_secs(4));
        let pauses: Vec<u64> = (0..6).map(|_| backoff.pause().as_millis() as u64).collect();
        assert_eq!(pauses, [1000, 1500, 2250, 3375, 4000, 4000]);
        assert_eq!(
            Backoff::new(Duration::from_millis(300)).pause().as_millis(),
            300
        );
    }
}
