//! What every command opens first: the study file, its solver, its store (once the file owns
//! it) and the plan of its points; and what several commands say of a plan and of what they
//! wrote.

use super::failure::Failure;
use crate::cli::args::CommonArgs;
use crate::console::Reply;
use crate::model::study::Study;
use crate::run::nlsolve::Nlsolve;
use crate::run::plan::{Options, Planned};
use crate::store::owner::Refusal;
use crate::store::{Index, Store};

/// The file beside a study's store that keeps the solver's verdicts on its cases.
const VERDICTS: &str = ".verdicts";

/// The study file, its adaptive question and its figures checked against the columns its
/// records and tables will have.
pub(super) fn read_study(path: &std::path::Path) -> Result<Study, Failure> {
    let study = crate::kinds::read(path)?;
    crate::kinds::check(&study)?;
    crate::analysis::figure_columns::check(&study)?;
    Ok(study)
}

/// The study's store, once the study file is known to own it (see `store::owner`); a command
/// that `writes` records the file as its owner.
pub(super) fn open_store(args: &CommonArgs, study: &Study, writes: bool) -> Result<Store, Failure> {
    let store = Store::open(&args.results, &study.name);
    claim(args, study, &store, writes)?;
    if writes {
        // A store of the old layout, a file per record, moves into segments.
        store.migrate()?;
    }
    Ok(store)
}

/// Checks that the study file owns `store`, and with `writes` records it as the owner.
pub(super) fn claim(
    args: &CommonArgs,
    study: &Study,
    store: &Store,
    writes: bool,
) -> Result<(), Failure> {
    let folder = store.table("");
    if let Some(link) = crate::store::fs::planted_link(&folder) {
        return Err(Failure::Io(format!(
            "{} is a symbolic link inside the study's results folder {}: nlstudy follows no link there, so its writes cannot be carried elsewhere; remove the link (a link for the whole folder is allowed)",
            link.display(),
            folder.display()
        )));
    }
    match store.claim(&args.study, &study.text, args.adopt, writes) {
        Ok(()) => Ok(()),
        Err(Refusal::Io(e)) => Err(e.into()),
        Err(Refusal::OwnedBy(owner)) => Err(Failure::BadInput(format!(
            "{} holds the results of another study file of the same name `{}`: {}; give this study its own `name`, or --adopt to make {} the owner (the stored runs stay, and its points that are the same cases reuse them)",
            store.table("").display(),
            study.name,
            owner.display(),
            args.study.display()
        ))),
    }
}

/// The study, its solver and store, and the plan of its points; see `open_store` for `writes`.
pub(super) fn planned(
    args: &CommonArgs,
    options: &Options,
    writes: bool,
) -> Result<(Study, Nlsolve, Store, Vec<Planned>), Failure> {
    let (study, solver, store, _, planned) = planned_and_index(args, options, writes)?;
    Ok((study, solver, store, planned))
}

/// `planned`, with the store's index it planned against.
pub(super) fn planned_and_index(
    args: &CommonArgs,
    options: &Options,
    writes: bool,
) -> Result<(Study, Nlsolve, Store, Index, Vec<Planned>), Failure> {
    let (study, solver, store) = opened(args, writes)?;
    let index = index_of(&store);
    let asked = crate::kinds::Asked {
        study: &study,
        solver: &solver,
        store: &store,
        options,
    };
    let planned = match crate::kinds::probes_so_far(asked)? {
        Some(probes) => probes,
        None => crate::run::plan::plan(&study, &solver, &index, options)?,
    };
    Ok((study, solver, store, index, planned))
}

/// The study, its solver (keeping its verdicts beside the store) and its store; see
/// `open_store` for `writes`.
pub(super) fn opened(args: &CommonArgs, writes: bool) -> Result<(Study, Nlsolve, Store), Failure> {
    let study = read_study(&args.study)?;
    let mut solver = Nlsolve::locate(args.solver.as_deref())?;
    let store = open_store(args, &study, writes)?;
    solver.keep_verdicts_in(store.table(VERDICTS));
    Ok((study, solver, store))
}

/// The store's index, what it could not read warned of.
pub(super) fn index_of(store: &Store) -> Index {
    let index = store.index();
    for unreadable in &index.unreadable {
        log::warn!("{unreadable}");
    }
    index
}

/// Names the points to run that this machine could not (memory, cores): `run` would store them
/// failed here, a cluster may run them (`submit`), so they are said (a note), not refused.
pub(super) fn what_does_not_fit(planned: &[Planned]) -> Option<String> {
    let crowded: Vec<(&Planned, &str)> = planned
        .iter()
        .filter(|p| p.runs())
        .filter_map(|p| Some((p, p.case.as_ref().ok()?.machine.as_deref()?)))
        .collect();
    let (first, why) = crowded.first()?;
    Some(format!(
        "{} points to run do not fit this machine, and would fail if run here (the first, {}: {why}); `nlstudy submit` them to a cluster, or make them smaller",
        crowded.len(),
        first.point.label()
    ))
}

/// Notes refinement series whose observed orders may come to measure the time error, not the
/// grid's: `eps` held fixed while `cfl` sets the step. At fixed ε the nonlocal operator's largest
/// eigenvalue goes as 1/ε², not 1/h², so dt_stable, and with it the time error, stays as h
/// shrinks while the spatial error falls below it. The note, if any series is so.
pub(super) fn what_refinement_cannot_show(planned: &[Planned]) -> Option<String> {
    use std::collections::{BTreeSet, HashMap};
    let given = |p: &Planned, field: &str| p.point.get(field).filter(|v| !v.is_null()).cloned();
    let fixed_eps_cfl = |p: &Planned| {
        let method = given(p, "method");
        (method.is_none() || method == Some("nonlocal".into()))
            && given(p, "eps").is_some()
            && given(p, "m").is_none()
            && given(p, "dt").is_none()
            && given(p, "cfl").is_some()
    };
    if !planned.iter().any(fixed_eps_cfl) {
        return None; // (the common case, said without naming each point's series)
    }
    // Per series (by its label, which names the branch too): whether every point holds ε
    // fixed with `cfl`, its grids, its horizons.
    type Series = (bool, BTreeSet<String>, BTreeSet<String>);
    let mut series: HashMap<String, Series> = HashMap::new();
    let mut order = Vec::new();
    for p in planned.iter().filter(|p| p.point.repeat == 0) {
        let name = p.point.series().refinement;
        let entry = series.entry(name.clone()).or_insert_with(|| {
            order.push(name);
            (true, BTreeSet::new(), BTreeSet::new())
        });
        entry.0 &= fixed_eps_cfl(p);
        entry
            .1
            .insert(given(p, "n").unwrap_or_default().to_string());
        entry
            .2
            .insert(given(p, "eps").unwrap_or_default().to_string());
    }
    let hidden: Vec<&String> = (order.iter())
        .filter(|name| {
            let (all, grids, horizons) = &series[*name];
            *all && grids.len() > 1 && horizons.len() == 1
        })
        .collect();
    let first = match hidden.first()?.as_str() {
        "" => String::new(),
        label => format!(" (first: {label})"),
    };
    Some(format!(
        "note: {} refinement series hold `eps` fixed and take the time step from `cfl`{first}: at fixed ε the stable step, and with it the time error, does not shrink with h, so their observed orders are the grid's only while its error stays well above the time error (a run at a smaller `cfl` tells); to refine both, give `\"cfl\": null` and `dt` zipped with `n` or derived (`\"derive\": {{\"dt\": \"h^2/4\"}}`)",
        hidden.len()
    ))
}

/// Stops a command when the solver refused points (unless `allowed`, when they are the warning
/// returned): each distinct refusal once, with the number of points it refused.
pub(super) fn no_refusals(planned: &[Planned], allowed: bool) -> Result<Option<String>, Failure> {
    let refusals = crate::run::plan::refusals(planned);
    if refusals.is_empty() {
        return Ok(None);
    }
    let points: usize = refusals.iter().map(|r| r.points).sum();
    let text = crate::run::plan::describe_refusals(&refusals);
    if allowed {
        return Ok(Some(format!(
            "the solver refuses {points} points; they are stored as failed:\n{text}"
        )));
    }
    Err(Failure::BadInput(format!(
        "the solver refuses {points} of the study's points, so nothing runs:\n{text}\nfix the study file, or give --allow-refused to run the other points and store these as failed"
    )))
}

/// Notes each figure: drawn, up to date or not drawn.
pub(super) fn figures_drawn(reply: &mut Reply, figures: &[crate::output::plot::Figure]) {
    use crate::output::plot::Outcome;
    for figure in figures {
        let what = match figure.outcome {
            Outcome::Drawn => "drawn",
            Outcome::UpToDate => "up to date",
            Outcome::Failed(_) => "not drawn",
        };
        reply.note(format!("figure {what}: {}", figure.path.display()));
    }
}

/// Notes the tables written, and the runs they lack or leave out.
pub(super) fn tables_written(reply: &mut Reply, collected: &crate::analysis::collect::Collected) {
    reply.note(format!(
        "tables: {} ({} runs), {} ({} points){}",
        collected.runs.display(),
        collected.rows,
        collected.summary.display(),
        collected.points,
        match (collected.up_to_date, collected.spliced) {
            (true, _) => ": up to date, no record changed since they were made".to_string(),
            (false, Some(read)) =>
                format!(": {read} runs read anew, the rest kept from the tables"),
            (false, None) => String::new(),
        }
    ));
    if collected.missing > 0 {
        reply.note(format!(
            "  {} runs of the study are not stored yet",
            collected.missing
        ));
    }
    if collected.left_out > 0 {
        reply.note(format!(
            "  {} stored records are left out: their points are no longer in the study or were run by another solver version",
            collected.left_out
        ));
    }
}
