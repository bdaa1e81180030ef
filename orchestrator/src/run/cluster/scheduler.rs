//! The cluster schedulers nlstudy speaks to, Slurm and LSF: handing them a job script, reading
//! the job id they print, and asking which jobs they still hold.

use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::Path;
use std::process::Command;

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Scheduler {
    Slurm,
    Lsf,
}

/// The scheduler's state of each job it still holds (queued, running, completing…), by id.
pub fn live_jobs(scheduler: Scheduler) -> Result<HashMap<String, String>, String> {
    let (program, args): (&str, &[&str]) = match scheduler {
        Scheduler::Slurm => ("squeue", &["-h", "-o", "%i %T"]),
        Scheduler::Lsf => ("bjobs", &["-noheader", "-o", "jobid stat"]),
    };
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
    Ok(String::from_utf8_lossy(&output.stdout)
        .lines()
        .filter_map(|line| {
            let mut words = line.split_whitespace();
            Some((words.next()?.to_string(), words.next()?.to_string()))
        })
        // LSF keeps finished jobs listed for a while.
        .filter(|(_, state)| !matches!(state.as_str(), "DONE" | "EXIT"))
        .collect())
}

/// What a job's state (as `squeue`, `sacct` or `bjobs` names it) means for its points, in a
/// phrase for `status`. Preempted and requeued jobs are not failures: the points they finished
/// are stored, and what is missing runs again (by the requeued job, or the next `submit`).
pub fn meaning(state: &str) -> &'static str {
    match state.to_ascii_uppercase().trim_end_matches('+') {
        "PENDING" | "PEND" | "CONFIGURING" | "REQUEUE_HOLD" | "REQUEUE_FED" | "RESV_DEL_HOLD" => {
            "waiting for its allocation"
        }
        "RUNNING" | "RUN" | "COMPLETING" | "RESIZING" | "SIGNALING" | "STAGE_OUT" => "running",
        "SUSPENDED" | "STOPPED" | "PSUSP" | "USUSP" | "SSUSP" => "suspended, will resume",
        "REQUEUED" => "requeued, not a failure: it runs again and takes up what is missing",
        "PREEMPTED" => {
            "preempted, not a failure: its finished points are stored; `submit` again for the rest"
        }
        "COMPLETED" | "DONE" => "completed",
        "TIMEOUT" | "DEADLINE" => "ended at its time limit: its unfinished point is missing; `submit` again, with more --time",
        "OUT_OF_MEMORY" => "ended out of memory: its unfinished point is missing",
        "NODE_FAIL" | "BOOT_FAIL" => "ended by a node failure: `submit` again for what is missing",
        "CANCELLED" => "cancelled: `submit` again for what is missing",
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

/// Hands a script to the scheduler (`sbatch SCRIPT` or `bsub < SCRIPT`) and returns the job's id.
pub fn submit(scheduler: Scheduler, script: &Path) -> Result<String, String> {
    let (program, output) = match scheduler {
        Scheduler::Slurm => (
            "sbatch",
            Command::new("sbatch")
                .arg("--parsable")
                .arg(script)
                .output(),
        ),
        Scheduler::Lsf => (
            "bsub",
            std::fs::File::open(script).and_then(|file| Command::new("bsub").stdin(file).output()),
        ),
    };
    let output = output.map_err(|e| {
        format!("cannot run {program}: {e}; on a machine without the scheduler use --dry-run to write the scripts only")
    })?;
    let printed = String::from_utf8_lossy(&output.stdout);
    if !output.status.success() {
        return Err(format!(
            "{program} refused {}: {}",
            script.display(),
            String::from_utf8_lossy(&output.stderr).trim()
        ));
    }
    submitted_id(scheduler, &printed).ok_or_else(|| {
        format!(
            "{program} accepted {} but printed no job id: {printed}",
            script.display()
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

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
            assert!(meaning(state).contains(says), "{state}: {}", meaning(state));
            assert_eq!(meaning(state), meaning(&state.to_lowercase()));
        }
        assert!(meaning("BOGUS").contains("does not know"));
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
