//! Points packed by their predicted cost: the jobs of one round (and the elements of an array)
//! should end together, or the round waits for its slowest job while the others' nodes idle.
//!
//! A point's cost is its estimated wall time from the store (`limits::History`: its own runs,
//! else its series' smaller grids scaled); a point never timed gets the cost model's work,
//! nodes × bonds per node × steps, in seconds at the median rate of the timed points (or in
//! work units when none was timed: only the ratios between points matter here). Points go
//! longest first onto the least loaded job (LPT scheduling, within 4/3 of the best makespan),
//! and each job lists its points longest first, so its workers take the long ones first too.

use super::cost::work_of;
use super::limits::History;
use crate::run::plan::Planned;
use crate::statistics::median;

/// The predicted costs of some points, and whether they are seconds.
#[derive(Clone, Debug, PartialEq)]
pub struct Predicted {
    pub costs: Vec<f64>,
    /// Seconds (every point timed, or the untimed scaled at the timed ones' rate), not units of
    /// the cost model's work.
    pub seconds: bool,
}

/// The predicted cost of each of `points`, in seconds where the store timed them or their
/// neighbours (the untimed scaled by the timed ones' rate, or the study's stored points'),
/// else in the cost model's work.
pub fn predicted_costs(points: &[&Planned], history: &History) -> Predicted {
    let work: Vec<Option<f64>> = points.iter().map(|p| work_of(p)).collect();
    let timed: Vec<Option<f64>> = points
        .iter()
        .map(|p| history.estimate(p).map(|e| e.seconds))
        .collect();
    let rates: Vec<f64> = timed
        .iter()
        .zip(&work)
        .filter_map(|(t, w)| Some(t.as_ref()? / w.filter(|w| *w > 0.0)?))
        .filter(|r| r.is_finite() && *r > 0.0)
        .collect();
    // This round's timed points give the rate, else every stored point of the study does (a
    // search's next probes are new points, its earlier ones timed).
    let rate = [&rates, &history.rates]
        .into_iter()
        .find(|r| !r.is_empty())
        .map(|r| median(r));
    let costs: Vec<Option<f64>> = timed
        .iter()
        .zip(&work)
        .map(|(t, w)| t.or(w.map(|w| w * rate.unwrap_or(1.0))))
        .map(|c| c.filter(|c| c.is_finite() && *c >= 0.0))
        .collect();
    // A point neither timed nor modelled (a case this build cannot read) counts as a typical one.
    let known: Vec<f64> = costs.iter().flatten().copied().collect();
    let typical = match known.is_empty() {
        true => 1.0,
        false => median(&known),
    };
    Predicted {
        seconds: rate.is_some() || timed.iter().all(Option::is_some),
        costs: costs.into_iter().map(|c| c.unwrap_or(typical)).collect(),
    }
}

/// `costs` split into `bins` groups whose sums are as even as LPT makes them: indices, each
/// group's longest first. Fewer groups when there are fewer costs than bins.
pub fn balance(costs: &[f64], bins: usize) -> Vec<Vec<usize>> {
    let mut order: Vec<usize> = (0..costs.len()).collect();
    // Longest first; equal costs in plan order.
    order.sort_by(|&a, &b| costs[b].total_cmp(&costs[a]).then(a.cmp(&b)));
    let bins = bins.clamp(1, costs.len().max(1));
    let mut groups: Vec<(f64, Vec<usize>)> = vec![(0.0, Vec::new()); bins];
    for i in order {
        let least = (0..bins)
            .min_by(|&a, &b| groups[a].0.total_cmp(&groups[b].0).then(a.cmp(&b)))
            .expect("at least one bin");
        groups[least].0 += costs[i];
        groups[least].1.push(i);
    }
    groups
        .into_iter()
        .map(|(_, group)| group)
        .filter(|g| !g.is_empty())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 100 points whose costs span 100× (a geometric ladder, shuffled by a fixed stride), in 4
    /// jobs: the predicted job costs end within 1.3× of each other (here within 1 %), where
    /// chunks in plan order of the sorted ladder differ by about 20×.
    #[test]
    fn a_hundred_points_spread_a_hundredfold_pack_into_four_jobs_within_1_3x() {
        let ladder: Vec<f64> = (0..100).map(|k| 100f64.powf(k as f64 / 99.0)).collect();
        let costs: Vec<f64> = (0..100).map(|k| ladder[(k * 37) % 100]).collect();
        let jobs = balance(&costs, 4);
        assert_eq!(jobs.len(), 4);
        let mut all: Vec<usize> = jobs.concat();
        all.sort_unstable();
        assert_eq!(all, (0..100).collect::<Vec<_>>(), "every point once");
        let sums: Vec<f64> = jobs
            .iter()
            .map(|j| j.iter().map(|&i| costs[i]).sum())
            .collect();
        let (low, high) = sums
            .iter()
            .fold((f64::MAX, 0f64), |(l, h), &s| (l.min(s), h.max(s)));
        assert!(high / low <= 1.3, "job costs {sums:?}");
        assert!(high / low <= 1.01, "LPT does far better here: {sums:?}");
        for job in &jobs {
            let own: Vec<f64> = job.iter().map(|&i| costs[i]).collect();
            assert!(
                own.windows(2).all(|w| w[0] >= w[1]),
                "longest first: {own:?}"
            );
        }
        // Chunks of 25 in cost order, what packing in a sorted plan's order gave: far apart.
        let sorted_chunks: Vec<f64> = ladder.chunks(25).map(|c| c.iter().sum()).collect();
        assert!(
            sorted_chunks[3] / sorted_chunks[0] > 10.0,
            "{sorted_chunks:?}"
        );
    }

    #[test]
    fn fewer_points_than_jobs_give_one_job_each_and_none_empty() {
        assert_eq!(balance(&[3.0, 1.0], 4), vec![vec![0], vec![1]]);
        assert_eq!(balance(&[], 3), Vec::<Vec<usize>>::new());
        assert_eq!(balance(&[1.0, 1.0, 1.0], 1), vec![vec![0, 1, 2]]);
    }

    /// A planned point of `fields` on the series `family`, its case checked (a case of this
    /// build) unless `readable` is false.
    fn planned(family: &str, fields: serde_json::Value, readable: bool) -> Planned {
        use crate::run::nlsolve::Checked;
        use crate::run::plan::{Decision, Reason};
        let map = fields.as_object().unwrap().clone();
        Planned {
            point: crate::model::study::Point::from_fields(map).with("family", family.into()),
            case: match readable {
                true => Ok(Checked::unresolved(&fields)),
                false => Err("not checked".into()),
            },
            key: crate::store::case_id_and_key(&fields.to_string(), "", 0).1,
            case_id: Default::default(),
            decision: Decision::Run(Reason::Missing),
            probe: None,
        }
    }

    /// A timed point costs its time; an untimed one its work at the timed points' rate; one
    /// this build cannot read, the median of the others.
    #[test]
    fn untimed_points_cost_their_work_at_the_rate_of_the_timed_ones() {
        let case = |n: u64| serde_json::json!({"dim": 1, "n": n, "m": 2, "t_end": 0.1, "dt": 0.01});
        let (timed, untimed) = (planned("a", case(64), true), planned("b", case(128), true));
        let unread = planned("c", case(8), false);
        let series = timed.point.series().refinement;
        let history = History::of_series(series, &[(64, &[2.0])]);
        let predicted = predicted_costs(&[&timed, &untimed, &unread], &history);
        // Twice the nodes, the same bonds and steps: twice the time.
        assert_eq!(predicted.costs, vec![2.0, 4.0, 3.0]);
        assert!(predicted.seconds);
        let none = predicted_costs(&[&timed, &untimed], &History::default());
        assert_eq!(
            none.costs[1] / none.costs[0],
            2.0,
            "work units when nothing is timed: {none:?}"
        );
        assert!(!none.seconds);
        // A search's next probes, none timed, at the rate of the study's stored points.
        let probes = predicted_costs(&[&untimed], &History::at_rate(1e-3));
        let checked = crate::run::nlsolve::Checked::unresolved(&case(128));
        let expected = crate::run::cluster::cost::work(&checked.case().unwrap()) * 1e-3;
        assert_eq!(probes.costs, vec![expected]);
        assert!(probes.seconds);
    }
}
