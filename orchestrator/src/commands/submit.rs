//! `nlstudy submit`: Slurm or LSF job scripts for the points not yet stored, submitted; with
//! `--follow`, round after round until the study is answered.

use super::failure::Failure;
use super::open::{index_of, no_refusals, opened, planned_and_index};
use super::run::{conclude, Ending};
use crate::cli::args::SubmitArgs;
use crate::console::{Reply, OUT};
use crate::model::site::{Site, SITE_VARIABLE};
use crate::model::study::Study;
use crate::run::cluster::follow::{self, Waited};
use crate::run::cluster::forecast;
use crate::run::cluster::submit::{self, Sent};
use crate::run::cluster::{ledger, scheduler::Scheduler};
use crate::run::nlsolve::Nlsolve;
use crate::run::plan::{plan, Options, Planned};
use crate::store::{Index, Store};
use schema::exit;
use schema::record::Status;
use std::process::ExitCode;
use std::time::Duration;

/// A line of what a submission did, on stdout as it happens (`--follow` may go on for hours).
fn say(line: String) {
    log::info!(target: OUT, "{line}");
}

pub(super) fn submit(args: &SubmitArgs) -> Result<Reply, Failure> {
    let site = match args
        .site
        .clone()
        .or_else(|| std::env::var(SITE_VARIABLE).ok())
    {
        Some(name) => Site::find(&name).map_err(Failure::BadInput)?,
        None => Site::default(),
    };
    let scheduler = match (args.scheduler, site.scheduler) {
        (Some(given), Some(site_s)) if given != site_s => {
            return Err(Failure::BadInput(format!(
                "--scheduler {given} but the site profile {} is for {site_s}; drop one",
                site.file.display()
            )))
        }
        (Some(s), _) | (None, Some(s)) => s,
        (None, None) => {
            return Err(Failure::BadInput(format!(
                "which scheduler? give --scheduler slurm|lsf, or a site profile (--site NAME or {SITE_VARIABLE})"
            )))
        }
    };
    site.check_for(scheduler).map_err(Failure::BadInput)?;
    let most = match args.follow {
        true => Some(poll(args.poll)?),
        false => None,
    };
    let Some(most) = most else {
        let (study, solver, store, index, planned) =
            planned_and_index(&args.common, &Options::default(), true)?;
        let rounds = study.question().and_then(|q| q.worst_case_rounds());
        let opened = (&study, &solver, &store, &index, planned.as_slice());
        let sent = submit_ready(args, scheduler, &site, opened)?;
        let mut reply = Reply::default();
        if let (Some(rounds), true) = (rounds, sent.jobs > 0) {
            reply.line(what_happens_next(args, rounds, sent));
            // Which round this is, no submit knows: the forecast only where the first bounds.
            if let (Some(round_s), Some(1)) = (sent.round_s, bounds_from(&study)) {
                reply.line(forecast::at_most(rounds, round_s));
            }
        }
        return Ok(reply);
    };
    follow_to_the_end(args, scheduler, &site, most)
}

/// `submit --follow`: round after round (or the whole study in one job), waiting for each, until
/// nothing is left to submit; then the answers, tables, figures and report.
fn follow_to_the_end(
    args: &SubmitArgs,
    scheduler: Scheduler,
    site: &Site,
    most: Duration,
) -> Result<Reply, Failure> {
    let (study, solver, store) = opened(&args.common, true)?;
    let options = Options::default();
    let asked = crate::kinds::Asked {
        study: &study,
        solver: &solver,
        store: &store,
        options: &options,
    };
    let (mut rounds, mut waited) = (0, Waited::default());
    let started = std::time::Instant::now();
    // The first prediction of the whole time, said again beside what it took at the end.
    let mut first_estimate: Option<(usize, f64)> = None;
    let most_rounds = study.question().and_then(|q| q.worst_case_rounds());
    // Each round's plan replays every search from the stored records, and the plan that finds
    // nothing left to submit holds the answers: they are not replayed again (3 s of the map's).
    let (answered, planned) = loop {
        let wait = follow::wait_for_jobs(&store, scheduler, most, &mut say)?;
        waited.questions += wait.questions;
        waited.seconds += wait.seconds;
        let index = index_of(&store);
        let (answered, planned) = match crate::kinds::answer(asked, &mut |_| Ok(false))? {
            Some(answers) => answers,
            None => (None, plan(&study, &solver, &index, &options)?),
        };
        let opened = (&study, &solver, &store, &index, planned.as_slice());
        if give_up_on_lost(opened, scheduler, args.resubmit)? > 0 {
            continue; // planned again: a failed probe is an answer of its search
        }
        let sent = submit_ready(args, scheduler, site, opened)?;
        if sent.jobs == 0 && sent.held == 0 {
            break (answered, planned);
        }
        if sent.jobs > 0 {
            rounds += 1;
        }
        let predicted = match rounds_left(&study, args.whole, rounds, sent) {
            Some((left, round_s)) => {
                first_estimate.get_or_insert((rounds, round_s * left as f64));
                format!("; {}", forecast::at_most(left, round_s))
            }
            None => String::new(),
        };
        if sent.jobs > 0 && args.whole {
            say(format!(
                "the whole study in one job, {} points so far{predicted}",
                sent.points
            ));
        } else if sent.jobs > 0 {
            let of_most = most_rounds.map_or(String::new(), |n| format!(" of at most {n}"));
            let eta = match predicted.is_empty() {
                true => eta(rounds, most_rounds, started.elapsed()),
                false => predicted,
            };
            say(format!(
                "round {rounds}{of_most}: {} jobs, {} points{eta}",
                sent.jobs, sent.points
            ));
        }
    };
    let submitted = match args.whole {
        true if rounds == 1 => "1 job of the whole study".to_string(),
        true => format!("{rounds} jobs of the whole study (resubmitted)"),
        false => format!("{rounds} rounds of jobs"),
    };
    let mut reply = Reply::default();
    reply.note(format!(
        "nlstudy: {submitted}; {} questions to {scheduler} in {:.0} s of waiting; it took {}{}",
        waited.questions,
        waited.seconds,
        forecast::seconds(started.elapsed().as_secs_f64()),
        beside(first_estimate)
    ));
    // The driver's jobs ran one build on the cluster's nodes: a whole study on several nodes
    // has tabulated its nodes' runs together (its job script), and rounds of jobs run wherever
    // the scheduler puts each job.
    let spanned = match args.whole {
        true => args.resources.nodes.is_some_and(|n| n.get() > 1),
        false => rounds > 0,
    };
    let allow_mixed = args.allow_mixed || spanned;
    answer(
        reply,
        (&study, &store, &planned),
        answered.as_deref(),
        allow_mixed,
    )
}

/// The first forecast of a followed study, `(round, seconds to go)`, as said beside what it took.
fn beside(first_estimate: Option<(usize, f64)>) -> String {
    match first_estimate {
        Some((1, total)) => format!(
            " (predicted at its first round: at most about {})",
            forecast::seconds(total)
        ),
        Some((k, total)) => format!(
            " (predicted at round {k}: at most about {} to go)",
            forecast::seconds(total)
        ),
        None => String::new(),
    }
}

/// The round of `study`'s question from which a round's length bounds each later one's.
fn bounds_from(study: &Study) -> Option<usize> {
    study.question()?.rounds_no_longer_from()
}

/// The rounds left at most, this one (`round`, as `sent`) included, and its predicted length:
/// where the round's points are timed and it bounds the later rounds (a whole study's job runs
/// every round, from the first).
fn rounds_left(study: &Study, whole: bool, round: usize, sent: Sent) -> Option<(usize, f64)> {
    let most = study.question()?.worst_case_rounds()?;
    let (this, left) = match whole {
        true => (1, most),
        false => (round, most.saturating_sub(round) + 1),
    };
    let bounded = bounds_from(study).is_some_and(|from| this >= from);
    Some((left, sent.round_s?)).filter(|_| bounded && sent.jobs > 0)
}

/// How long the rounds left may take, from the rounds done (`elapsed` since the first was
/// submitted, queue waits included): `; at most about …` once a round has ended and the
/// question bounds its rounds.
fn eta(round: usize, most: Option<usize>, elapsed: Duration) -> String {
    let (Some(most), true) = (most, round > 1) else {
        return String::new();
    };
    let per_round = elapsed.as_secs_f64() / (round - 1) as f64;
    let left = per_round * (most.saturating_sub(round) + 1) as f64;
    format!("; rounds so far took {per_round:.0} s each, so at most about {left:.0} s to go")
}

/// What a submit of an adaptive study of at most `rounds` rounds leads to, by the way it goes
/// to the cluster: a round per submit, or the whole study in one job (on every node of it).
fn what_happens_next(args: &SubmitArgs, rounds: usize, sent: Sent) -> String {
    let nodes = args.resources.nodes.map_or(1, |n| n.get());
    match (args.whole, nodes) {
        (true, 1) => format!(
            "the whole study in one job: its rounds, {rounds} at most, run inside the allocation"
        ),
        (true, nodes) => format!(
            "the whole study in one job: its rounds, {rounds} at most, run inside the allocation by a worker step on each of its {nodes} nodes"
        ),
        (false, _) => format!(
            "this round: {} jobs, {} points, of at most {rounds} rounds; submit again when its jobs are done (`status` says), or give --follow to have them all submitted",
            sent.jobs, sent.points
        ),
    }
}

/// A study opened and planned: its solver, store, the store's index and the plan.
type Opened<'a> = (&'a Study, &'a Nlsolve, &'a Store, &'a Index, &'a [Planned]);

/// The longest pause between two questions to the scheduler, from `--poll`.
fn poll(seconds: f64) -> Result<Duration, Failure> {
    match seconds.is_finite() && seconds >= 0.01 {
        true => Ok(Duration::from_secs_f64(seconds)),
        false => Err(Failure::BadInput(format!(
            "--poll {}: give the longest pause between two questions to the scheduler in seconds, at least 0.01 (e.g. 60)",
            schema::text::exact(seconds)
        ))),
    }
}

/// Submits what is ready of the study as planned (see `submit::submit_study`).
fn submit_ready(
    args: &SubmitArgs,
    scheduler: Scheduler,
    site: &Site,
    (study, solver, store, index, planned): Opened,
) -> Result<Sent, Failure> {
    if let Some(warning) = no_refusals(planned, args.allow_refused)? {
        log::warn!("{warning}");
    }
    let explicit = study.resources.overridden_by(&args.resources);
    let target = submit::Target {
        scheduler,
        resources: site.defaults().overridden_by(&explicit),
        time: explicit.time,
        site: site.clone(),
        array: args.array,
        throttle: args.throttle,
        results: args.common.results.clone(),
        study_file: args.common.study.clone(),
        dry_run: args.dry_run,
        retries: args.retries,
        launcher: args.launcher.clone(),
        whole: args.whole,
        allow_mixed: args.allow_mixed,
    };
    Ok(submit::submit_study(
        study, solver, planned, store, index, &target, &mut say,
    )?)
}

/// The end of a followed study, everything stored: its answers, tables, figures and report as
/// `run` makes them, said after `reply`; exit 1 when a point is stored failed.
fn answer(
    mut reply: Reply,
    (study, store, planned): (&Study, &Store, &[Planned]),
    answered: Option<&dyn crate::kinds::Found>,
    allow_mixed: bool,
) -> Result<Reply, Failure> {
    let ending = Ending {
        collect: true,
        allow_mixed,
    };
    if let Err(failure) = conclude(&mut reply, study, store, planned, answered, ending) {
        return Ok(failure.after(reply));
    }
    let failed = planned
        .iter()
        .any(|p| store.status(p.key.as_str()) == Some(Status::Failed));
    Ok(match failed {
        true => reply.ending(ExitCode::from(exit::CASE_FAILED)),
        false => reply,
    })
}

/// Stores failed the points whose jobs ended without their records more than `resubmit` times,
/// with what the scheduler says of those jobs; returns how many.
fn give_up_on_lost(
    (_, solver, store, _, planned): Opened,
    scheduler: Scheduler,
    resubmit: usize,
) -> Result<usize, Failure> {
    let lost = follow::lost(planned, &ledger::entries(store), resubmit);
    for lost in &lost {
        let key = lost.point.key.as_str();
        let Some(_lock) = store.lock(key)? else {
            continue; // another nlstudy holds it, and stores it
        };
        let message = follow::why_lost(scheduler, lost);
        log::info!("{}: {message}", lost.point.point.label());
        let record = crate::run::pool::failed_record(lost.point, solver, message);
        store.save(key, &record)?;
    }
    Ok(lost.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The time left is the rounds done's mean times the rounds left, this one included; none
    /// before a round has ended or without a bound on the rounds.
    #[test]
    fn the_time_left_is_the_rounds_left_at_the_mean_round() {
        let ten = Duration::from_secs(20);
        assert_eq!(eta(1, Some(5), Duration::ZERO), "");
        assert_eq!(eta(3, None, ten), "");
        assert_eq!(
            eta(3, Some(5), ten),
            "; rounds so far took 10 s each, so at most about 30 s to go"
        );
        assert!(
            eta(6, Some(5), ten).ends_with("about 4 s to go"),
            "{}",
            eta(6, Some(5), ten)
        );
    }
}
