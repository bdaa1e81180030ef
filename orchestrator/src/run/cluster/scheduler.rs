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
