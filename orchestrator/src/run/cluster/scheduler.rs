//! The cluster schedulers nlstudy speaks to, Slurm and LSF: handing them a job script, reading
//! the job id they print, and asking which jobs they still hold.

use crate::store::Fault;
use std::collections::HashMap;
use std::path::Path;
use std::process::Command;

pub use crate::model::resources::Scheduler;

/// The scheduler's state of each job and array element it still holds (queued, running,
/// completing…), by id: `42`, and an array's elements as `42_3` (Slurm) or `42[4]` (LSF).
pub fn live_jobs(scheduler: Scheduler) -> Result<HashMap<String, String>, String> {
    let (program, args): (&str, &[&str]) = match scheduler {
        // `-r`: one line per array element, pending ones too.
        Scheduler::Slurm => ("squeue", &["-h", "-r", "-o", "%i %T"]),
        Scheduler::Lsf => ("bjobs", &["-noheader", "-o", "jobid jobindex stat"]),
    };
    let printed = run(program, args)?;
    Ok(match scheduler {
        Scheduler::Slurm => parse_slurm_states(&printed, ' '),
        Scheduler::Lsf => parse_bjobs(&printed),
    }
    .into_iter()
    // LSF keeps finished jobs listed for a while.
    .filter(|(_, state)| !matches!(state.as_str(), "DONE" | "EXIT"))
    .collect())
}

/// The final or current state of each job and array element among `ids`, from Slurm's
/// accounting (`sacct`, one call): what became of jobs that have left the queue. `Err` where
/// the cluster keeps no accounting (then only the queue can be asked).
pub fn accounted_states(ids: &[&str]) -> Result<HashMap<String, String>, String> {
    if ids.is_empty() {
        return Ok(HashMap::new());
    }
    // Accounting forgets nothing, so the window starts at the epoch rather than today.
    let list = ids.join(",");
    let args = [
        "-X",
        "-n",
        "-P",
        "-S",
        "1970-01-01",
        "-o",
        "JobID,State,ExitCode",
        "-j",
        &list,
    ];
    let printed = run("sacct", &args)?;
    Ok(parse_slurm_states(&printed, '|'))
}

/// What a job the scheduler still holds is doing (`phase`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    Waiting,
    Running,
    Suspended,
    Requeued,
}

/// Whether the scheduler still holds a job in `state` (Slurm's or LSF's word), and doing what;
/// None once it has ended (or in a state nlstudy does not know).
pub fn phase(state: &str) -> Option<Phase> {
    Some(match state.to_ascii_uppercase().trim_end_matches('+') {
        "PENDING" | "PEND" | "CONFIGURING" | "REQUEUE_HOLD" | "REQUEUE_FED" | "RESV_DEL_HOLD" => {
            Phase::Waiting
        }
        "RUNNING" | "RUN" | "COMPLETING" | "RESIZING" | "SIGNALING" | "STAGE_OUT" => Phase::Running,
        "SUSPENDED" | "STOPPED" | "PSUSP" | "USUSP" | "SSUSP" => Phase::Suspended,
        "REQUEUED" => Phase::Requeued,
        _ => return None,
    })
}

/// Not a Slurm state: a job that ended FAILED with exit status 143, nlstudy's for SIGTERM
/// (which Slurm 22.05 accounts as `15:0`).
pub const STOPPED_BY_SIGTERM: &str = "STOPPED_BY_SIGTERM";

/// What `program args` printed, or why it could not run or failed.
pub(crate) fn run(program: &str, args: &[&str]) -> Result<String, String> {
    let output = Command::new(program)
        .args(args)
        .output()
        .map_err(|e| format!("cannot run {program}: {e}"))?;
    if !output.status.success() {
        return Err(format!(
            "{program} failed: {}",
            String::from_utf8_lossy(&output.stderr).trim()
        ));
    }
    Ok(String::from_utf8_lossy(&output.stdout).into_owned())
}

/// The id of the job the scheduler holds that `submit` marked with `token`, if it holds one.
pub fn job_marked(scheduler: Scheduler, token: &str) -> Result<Option<String>, String> {
    let (program, args): (&str, &[&str]) = match scheduler {
        Scheduler::Slurm => ("squeue", &["-h", "-o", "%i %k"]),
        Scheduler::Lsf => ("bjobs", &["-noheader", "-o", "jobid job_description"]),
    };
    Ok(marked(&run(program, args)?, token))
}

/// The id on the `ID MARK` line whose mark is `token`.
fn marked(printed: &str, token: &str) -> Option<String> {
    printed.lines().find_map(|line| {
        let (id, mark) = line.trim().split_once(char::is_whitespace)?;
        (mark.trim() == token).then(|| id.to_string())
    })
}

/// `ID STATE` lines of squeue, or `ID|STATE|EXIT` of sacct (`CANCELLED by 0` keeps its first
/// word; a job that failed with nlstudy's status for SIGTERM, 143, is `STOPPED_BY_SIGTERM`: it stopped
/// cleanly at its warning or a signal); an array's pending elements folded as `42_[4-19%2]` or
/// `42_[1,3-5]` are unfolded.
fn parse_slurm_states(printed: &str, separator: char) -> HashMap<String, String> {
    let mut states = HashMap::new();
    for line in printed.lines() {
        let mut fields = line.trim().split(separator);
        let (Some(id), Some(state)) = (fields.next(), fields.next()) else {
            continue;
        };
        let state = state.split_whitespace().next().unwrap_or_default();
        let state = match (state, fields.next()) {
            // Slurm records an exit status of 128 + n as n: 143 shows as `15:0`.
            ("FAILED", Some("143:0" | "15:0")) => STOPPED_BY_SIGTERM.to_string(),
            _ => state.to_string(),
        };
        match id.split_once("_[") {
            Some((array, ranges)) => {
                let ranges = ranges.trim_end_matches(']');
                let ranges = ranges.split('%').next().unwrap_or_default();
                for range in ranges.split(',') {
                    let (from, to) = range.split_once('-').unwrap_or((range, range));
                    let (Ok(from), Ok(to)) = (from.parse::<u64>(), to.parse::<u64>()) else {
                        continue;
                    };
                    for k in from..=to.min(from + 100_000) {
                        states.insert(format!("{array}_{k}"), state.clone());
                    }
                }
            }
            None => {
                states.insert(id.to_string(), state);
            }
        }
    }
    states
}

/// `JOBID JOBINDEX STAT` lines of bjobs: an array's element as `42[4]`.
fn parse_bjobs(printed: &str) -> HashMap<String, String> {
    printed
        .lines()
        .filter_map(|line| {
            let words: Vec<&str> = line.split_whitespace().collect();
            let [id, index, state] = words[..] else {
                return None;
            };
            let id = match index {
                "0" | "-" => id.to_string(),
                k => format!("{id}[{k}]"),
            };
            Some((id, state.to_string()))
        })
        .collect()
}

/// The id the scheduler gives element `index` (from 0) of array `array`: Slurm counts from 0
/// (`42_0`), LSF from 1 (`42[1]`), as the scripts' indices do.
pub fn element_id(scheduler: Scheduler, array: &str, index: usize) -> String {
    match scheduler {
        Scheduler::Slurm => format!("{array}_{index}"),
        Scheduler::Lsf => format!("{array}[{}]", index + 1),
    }
}

/// What a job's state (as `squeue`, `sacct` or `bjobs` names it) means for its points, in a
/// phrase for `status`. Preempted and requeued jobs are not failures: the points they finished
/// are stored, and what is missing runs again (by the requeued job, or the next `submit`).
pub fn state_meaning(state: &str) -> &'static str {
    match phase(state) {
        Some(Phase::Waiting) => return "waiting for its allocation",
        Some(Phase::Running) => return "running",
        Some(Phase::Suspended) => return "suspended, will resume",
        Some(Phase::Requeued) => {
            return "requeued, not a failure: it runs again and takes up what is missing"
        }
        None => {}
    }
    match state.to_ascii_uppercase().trim_end_matches('+') {
        "PREEMPTED" => {
            "preempted, not a failure: its finished points are stored; `submit` again for the rest"
        }
        "COMPLETED" | "DONE" => "completed",
        "TIMEOUT" | "DEADLINE" => "ended at its time limit: its unfinished point is missing; `submit` again, with more --time",
        "OUT_OF_MEMORY" => "ended out of memory: its unfinished point is missing",
        "NODE_FAIL" | "BOOT_FAIL" => "ended by a node failure: `submit` again for what is missing",
        "CANCELLED" => "cancelled: `submit` again for what is missing",
        STOPPED_BY_SIGTERM => "stopped by SIGTERM before its limit (its warning, or a signal): its finished points are stored; `submit` again for the rest",
        "FAILED" | "EXIT" => "failed: see its output in results/<study>/jobs/",
        _ => "in a state nlstudy does not know",
    }
}

/// The job id in what the scheduler printed on submission: `42` or `42;cluster` (`sbatch
/// --parsable`, which this asks for: its output is meant to be read), or the human sentence
/// `Submitted batch job 42`; `Job <42> is submitted to queue <normal>.` (bsub).
pub fn submitted_id(scheduler: Scheduler, printed: &str) -> Option<String> {
    let id = match scheduler {
        Scheduler::Slurm => {
            let line = printed.lines().map(str::trim).find(|l| !l.is_empty())?;
            let line = line.strip_prefix("Submitted batch job ").unwrap_or(line);
            line.split(';').next()?.trim()
        }
        Scheduler::Lsf => printed.split_once('<')?.1.split_once('>')?.0,
    };
    (!id.is_empty() && id.chars().all(|c| c.is_ascii_digit())).then(|| id.to_string())
}

/// Hands a script to the scheduler (`sbatch SCRIPT` or `bsub < SCRIPT`), the job marked with
/// `token` (its comment, `sbatch --comment`, or description, `bsub -Jd`: `job_marked` finds it
/// by it), and returns the job's id. Every failure is the scheduler's or the system's (the
/// script was checked when written).
pub fn submit(scheduler: Scheduler, script: &Path, token: &str) -> Result<String, Fault> {
    let (program, output) = match scheduler {
        Scheduler::Slurm => (
            "sbatch",
            Command::new("sbatch")
                .arg("--parsable")
                .arg(format!("--comment={token}"))
                .arg(script)
                .output(),
        ),
        Scheduler::Lsf => (
            "bsub",
            std::fs::File::open(script).and_then(|file| {
                Command::new("bsub")
                    .args(["-Jd", token])
                    .stdin(file)
                    .output()
            }),
        ),
    };
    let output = output.map_err(|e| {
        Fault::Io(format!("cannot run {program}: {e}; on a machine without the scheduler use --dry-run to write the scripts only"))
    })?;
    let printed = String::from_utf8_lossy(&output.stdout);
    if !output.status.success() {
        return Err(Fault::Io(format!(
            "{program} refused {}: {}",
            script.display(),
            String::from_utf8_lossy(&output.stderr).trim()
        )));
    }
    submitted_id(scheduler, &printed).ok_or_else(|| {
        Fault::Io(format!(
            "{program} accepted {} but printed no job id: {printed}",
            script.display()
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_job_is_found_by_its_mark_and_only_by_all_of_it() {
        let printed = "41 (null)\n42 nlstudy-17-3\n 43 nlstudy-17-31\n";
        assert_eq!(marked(printed, "nlstudy-17-3"), Some("42".into()));
        assert_eq!(marked(printed, "nlstudy-17-31"), Some("43".into()));
        assert_eq!(marked(printed, "nlstudy-17"), None);
        assert_eq!(marked("", "nlstudy-17-3"), None);
    }

    #[test]
    fn every_scheduler_state_has_its_meaning_and_preemption_is_no_failure() {
        let slurm = [
            ("PENDING", "waiting"),
            ("RUNNING", "running"),
            ("COMPLETED", "completed"),
            ("FAILED", "failed"),
            ("TIMEOUT", "time limit"),
            ("OUT_OF_MEMORY", "out of memory"),
            ("PREEMPTED", "not a failure"),
            ("REQUEUED", "not a failure"),
            ("NODE_FAIL", "node failure"),
            ("CANCELLED", "cancelled"),
            ("CANCELLED+", "cancelled"),
            (STOPPED_BY_SIGTERM, "SIGTERM"),
            ("SUSPENDED", "suspended"),
            ("COMPLETING", "running"),
        ];
        let lsf = [
            ("PEND", "waiting"),
            ("RUN", "running"),
            ("DONE", "completed"),
            ("EXIT", "failed"),
        ];
        for (state, says) in slurm.into_iter().chain(lsf) {
            assert!(
                state_meaning(state).contains(says),
                "{state}: {}",
                state_meaning(state)
            );
            assert_eq!(state_meaning(state), state_meaning(&state.to_lowercase()));
        }
        assert!(state_meaning("BOGUS").contains("does not know"));
    }

    #[test]
    fn array_elements_are_read_one_by_one_from_squeue_sacct_and_bjobs() {
        let squeue = "42_0 COMPLETING\n42_1 RUNNING\n42_[2-4,7%2] PENDING\n43 RUNNING\n";
        let states = parse_slurm_states(squeue, ' ');
        let mut ids: Vec<&str> = states.keys().map(String::as_str).collect();
        ids.sort_unstable();
        assert_eq!(ids, ["42_0", "42_1", "42_2", "42_3", "42_4", "42_7", "43"]);
        assert_eq!(states["42_3"], "PENDING");
        let sacct = "44|CANCELLED by 0|0:15\n45_0|TIMEOUT|0:0\n45_1|COMPLETED|0:0\n46|FAILED|15:0\n47|FAILED|1:0\n48|FAILED|143:0\n";
        let states = parse_slurm_states(sacct, '|');
        assert_eq!(states["44"], "CANCELLED");
        assert_eq!(states["45_0"], "TIMEOUT");
        assert_eq!(
            (
                states["46"].as_str(),
                states["47"].as_str(),
                states["48"].as_str()
            ),
            (STOPPED_BY_SIGTERM, "FAILED", STOPPED_BY_SIGTERM)
        );
        let bjobs = "7 0 RUN\n8 1 PEND\n8 2 DONE\n";
        let states = parse_bjobs(bjobs);
        assert_eq!(
            (
                states["7"].as_str(),
                states["8[1]"].as_str(),
                states["8[2]"].as_str()
            ),
            ("RUN", "PEND", "DONE")
        );
        assert_eq!(element_id(Scheduler::Slurm, "42", 0), "42_0");
        assert_eq!(element_id(Scheduler::Lsf, "8", 0), "8[1]");
    }

    #[test]
    fn job_ids_are_read_from_what_either_scheduler_prints() {
        assert_eq!(
            submitted_id(Scheduler::Slurm, "Submitted batch job 42\n").as_deref(),
            Some("42")
        );
        assert_eq!(
            submitted_id(Scheduler::Lsf, "Job <7> is submitted to queue <normal>.\n").as_deref(),
            Some("7")
        );
        assert_eq!(submitted_id(Scheduler::Slurm, "sbatch: error: …"), None);
        // `sbatch --parsable`: the id, and the cluster's name on a federation.
        assert_eq!(
            submitted_id(Scheduler::Slurm, "42\n").as_deref(),
            Some("42")
        );
        assert_eq!(
            submitted_id(Scheduler::Slurm, "43;cluster-a\n").as_deref(),
            Some("43")
        );
    }
}
