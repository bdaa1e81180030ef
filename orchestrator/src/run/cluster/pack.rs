//! Packing a study's points into scheduler submissions: as many jobs as `cases_per_job` points
//! each make (one job by default), or, with `--array`, one job array per allocation shape
//! whose elements each run a bundle of points; the points balanced by predicted cost over the
//! jobs or bundles (`balance`), so that they end together. One array is one `sbatch` or `bsub` call however
//! many points it holds, which spares the scheduler the per-job overhead (Slurm's RPC limits)
//! that hundreds of small jobs meet.

use super::balance::balance;
use crate::model::resources::Resources;
use crate::run::nlsolve::Checked;
use crate::run::plan::Planned;
use std::num::NonZeroUsize;

/// The most elements one array holds: Slurm's default `MaxArraySize` is 1001 (indices 0 to
/// 1000). Bundles grow to keep a larger study within it.
pub const MOST_ELEMENTS: usize = 1000;

/// The allocation of one job or array element: nodes, MPI tasks, threads per task.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Shape {
    pub nodes: usize,
    pub tasks: usize,
    pub threads: usize,
}

impl Shape {
    /// Cores of the allocation: each task's threads.
    pub fn cores(&self) -> usize {
        self.tasks * self.threads
    }
}

/// One submission: a job running one bundle of points, or an array of bundles.
pub struct Pack<'a> {
    pub name: String,
    pub bundles: Vec<Vec<&'a Planned>>,
    pub shape: Shape,
    pub array: bool,
}

/// The submissions for `runnable` (whose predicted costs are `costs`): ⌈points /
/// `cases_per_job`⌉ jobs, or with `array` one array per shape with ⌈its points /
/// `cases_per_job`⌉ bundles (one point each by default, more when the shape has over
/// `MOST_ELEMENTS` of them); each job or bundle holds points of about equal total cost (their
/// counts may differ), longest first.
pub fn pack<'a>(
    study_name: &str,
    runnable: &[&'a Planned],
    costs: &[f64],
    resources: &Resources,
    cores_per_node: Option<NonZeroUsize>,
    array: bool,
) -> Vec<Pack<'a>> {
    let name = |k: usize| format!("nlstudy-{study_name}-{k}");
    if !array {
        let per_job = resources
            .cases_per_job
            .map_or(runnable.len(), NonZeroUsize::get)
            .max(1);
        return balanced(runnable, costs, runnable.len().div_ceil(per_job))
            .into_iter()
            .enumerate()
            .map(|(k, pack)| Pack {
                name: name(k),
                shape: shape(&pack, resources, cores_per_node),
                bundles: vec![pack],
                array: false,
            })
            .collect();
    }
    let mut by_shape: Vec<(Shape, Vec<&'a Planned>, Vec<f64>)> = Vec::new();
    for (&p, &cost) in runnable.iter().zip(costs) {
        let own = shape(&[p], resources, cores_per_node);
        match by_shape.iter_mut().find(|(s, _, _)| *s == own) {
            Some((_, points, costs)) => {
                points.push(p);
                costs.push(cost);
            }
            None => by_shape.push((own, vec![p], vec![cost])),
        }
    }
    by_shape
        .into_iter()
        .enumerate()
        .map(|(k, (shape, points, costs))| {
            let per_bundle = resources
                .cases_per_job
                .map_or(1, NonZeroUsize::get)
                .max(points.len().div_ceil(MOST_ELEMENTS));
            Pack {
                name: name(k),
                bundles: balanced(&points, &costs, points.len().div_ceil(per_bundle)),
                shape,
                array: true,
            }
        })
        .collect()
}

/// `points` in `groups` groups of about equal predicted cost, each longest first.
fn balanced<'a>(points: &[&'a Planned], costs: &[f64], groups: usize) -> Vec<Vec<&'a Planned>> {
    debug_assert_eq!(points.len(), costs.len());
    balance(costs, groups)
        .into_iter()
        .map(|group| group.into_iter().map(|i| points[i]).collect())
        .collect()
}

/// One job for the whole study (`submit --whole`): its points so far in one bundle, on the
/// allocation that fits the largest, widened to a node's cores (`cores_per_node`) when the
/// resources set no task count, so that the pool inside runs several points at once.
pub fn whole<'a>(
    study_name: &str,
    runnable: &[&'a Planned],
    resources: &Resources,
    cores_per_node: Option<NonZeroUsize>,
) -> Pack<'a> {
    let mut shape = shape(runnable, resources, cores_per_node);
    if let (None, Some(cores)) = (resources.tasks, cores_per_node) {
        let per_node = (cores.get() / shape.threads).max(1);
        shape.tasks = shape.tasks.max(per_node * shape.nodes);
    }
    // A task on every node at least: Slurm refuses more nodes than tasks.
    shape.tasks = shape.tasks.max(shape.nodes);
    Pack {
        name: format!("nlstudy-{study_name}-whole"),
        bundles: vec![runnable.to_vec()],
        shape,
        array: false,
    }
}

/// The allocation that fits every point of `pack`: the largest rank and thread counts (tasks
/// as `resources` sets them), on as many nodes as `resources` asks, or as the cores need.
fn shape(pack: &[&Planned], resources: &Resources, cores_per_node: Option<NonZeroUsize>) -> Shape {
    let largest = |count: fn(&Checked) -> usize| {
        pack.iter()
            .filter_map(|p| p.case.as_ref().ok().map(count))
            .max()
            .unwrap_or(1)
    };
    let tasks = resources
        .tasks
        .map_or(largest(Checked::ranks), NonZeroUsize::get);
    let threads = largest(Checked::threads);
    let nodes = match (resources.nodes, cores_per_node) {
        (Some(nodes), _) => nodes.get(),
        (None, Some(cores)) => (tasks * threads).div_ceil(cores.get()).min(tasks),
        (None, None) => 1,
    };
    Shape {
        nodes: nodes.max(1),
        tasks,
        threads,
    }
}
