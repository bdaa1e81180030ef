//! `nlstudy submit`: Slurm or LSF job scripts for the points not yet stored, submitted.

use super::failure::Failure;
use super::open::{no_refusals, planned_and_index};
use crate::cli::args::SubmitArgs;
use crate::model::site::{Site, SITE_VARIABLE};
use crate::run::cluster::submit;
use crate::run::plan::Options;
use std::process::ExitCode;

pub(super) fn submit(args: &SubmitArgs) -> Result<ExitCode, Failure> {
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
    let (study, solver, store, index, planned) =
        planned_and_index(&args.common, &Options::default(), true)?;
    no_refusals(&planned, args.allow_refused)?;
    let explicit = study.resources.overridden_by(&args.resources);
    let target = submit::Target {
        scheduler,
        resources: site.defaults().overridden_by(&explicit),
        time: explicit.time,
        site,
        array: args.array,
        throttle: args.throttle,
        results: args.common.results.clone(),
        study_file: args.common.study.clone(),
        dry_run: args.dry_run,
        retries: args.retries,
        launcher: args.launcher.clone(),
    };
    submit::submit_study(&study, &solver, &planned, &store, &index, &target)?;
    Ok(ExitCode::SUCCESS)
}
