//! How long a round of jobs may take, and so a whole adaptive study at most: from the first
//! round on, from the points' predicted costs in seconds (`balance::predicted_costs`: their
//! stored timings or their series' smaller grids). A job runs its points side by side on its
//! lanes (its cores over the cores of its largest case), longest first, as its pool does; the
//! jobs of a round run at once; an adaptive study takes at most its question's worst case of
//! rounds, each no longer than this one. Queue waits are not in it, and are said not to be.

use super::balance::balance;
use super::pack::Pack;
use crate::run::plan::Planned;
use std::collections::HashMap;

/// The predicted length of `costs` run longest first on `lanes` lanes: LPT's makespan.
pub fn makespan(costs: &[f64], lanes: usize) -> f64 {
    balance(costs, lanes)
        .iter()
        .map(|lane| lane.iter().map(|&i| costs[i]).sum::<f64>())
        .fold(0.0, f64::max)
}

/// The cases `pack`'s allocation runs side by side: its cores over its largest case's.
pub fn lanes(pack: &Pack, points: &[&Planned]) -> usize {
    let largest = points
        .iter()
        .filter_map(|p| p.case.as_ref().ok())
        .map(|c| c.ranks() * c.threads())
        .max()
        .unwrap_or(1)
        .max(1);
    (pack.shape.cores() / largest).max(1)
}

/// The predicted length of a round of `packs`, whose points cost `cost[key]` seconds: its
/// longest job (or array element) if the scheduler starts them all at once.
pub fn round(packs: &[Pack], cost: &HashMap<&str, f64>) -> f64 {
    packs
        .iter()
        .flat_map(|pack| pack.bundles.iter().map(move |bundle| (pack, bundle)))
        .map(|(pack, bundle)| {
            let costs: Vec<f64> = bundle
                .iter()
                .map(|p| cost.get(p.key.as_str()).copied().unwrap_or(0.0))
                .collect();
            makespan(&costs, lanes(pack, bundle))
        })
        .fold(0.0, f64::max)
}

/// The sentence of a study's time left at most: `rounds` (this one included) of `round_s`.
pub fn at_most(rounds: usize, round_s: f64) -> String {
    let rounds_text = match rounds {
        1 => "this round".to_string(),
        k => format!("{k} rounds at most"),
    };
    format!(
        "predicted {} a round from the points' stored timings, so about {} for {rounds_text}, queue waits not included",
        seconds(round_s),
        seconds(round_s * rounds as f64)
    )
}

/// `s` seconds to the precision a forecast has, with hours beside a long one.
pub fn seconds(s: f64) -> String {
    match s {
        s if s < 1.0 => format!("{s:.2} s"),
        s if s < 10.0 => format!("{s:.1} s"),
        s if s < 3600.0 => format!("{s:.0} s"),
        s => format!("{s:.0} s ({:.1} h)", s / 3600.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::run::cluster::pack::Shape;
    use crate::run::nlsolve::Checked;
    use crate::run::plan::{Decision, Reason};

    fn point(n: u64, threads: u64) -> Planned {
        let case = serde_json::json!({"dim": 1, "n": n, "m": 2, "threads": threads});
        Planned {
            point: crate::model::study::Point::from_fields(case.as_object().unwrap().clone()),
            case: Ok(Checked::unresolved(&case)),
            key: crate::store::case_id_and_key(&case.to_string(), "", 0).1,
            case_id: Default::default(),
            decision: Decision::Run(Reason::Missing),
            probe: None,
        }
    }

    fn job(bundle: Vec<&Planned>, tasks: usize, threads: usize) -> Pack<'_> {
        Pack {
            name: "j".into(),
            bundles: vec![bundle],
            shape: Shape {
                nodes: 1,
                tasks,
                threads,
            },
            array: false,
        }
    }

    #[test]
    fn a_makespan_is_the_longest_lane_of_longest_first() {
        assert_eq!(makespan(&[4.0, 3.0, 3.0, 2.0], 2), 6.0);
        assert_eq!(makespan(&[4.0, 3.0, 3.0, 2.0], 1), 12.0);
        assert_eq!(makespan(&[4.0, 1.0], 8), 4.0);
        assert_eq!(makespan(&[], 2), 0.0);
    }

    /// Two jobs of a round: one of four one-core points on a four-core allocation, one of a
    /// single two-thread point on two cores; the round is its longer job.
    #[test]
    fn a_round_lasts_its_longest_job_on_its_lanes() {
        let points = [point(10, 1), point(11, 1), point(12, 1), point(13, 1)];
        let wide = point(14, 2);
        let four = job(points.iter().collect(), 4, 1);
        let alone = job(vec![&wide], 1, 2);
        assert_eq!(lanes(&four, &four.bundles[0]), 4);
        assert_eq!(
            lanes(&alone, &alone.bundles[0]),
            1,
            "two cores, a two-core case"
        );
        let mut cost: HashMap<&str, f64> = points
            .iter()
            .zip([5.0, 1.0, 1.0, 1.0])
            .map(|(p, c)| (p.key.as_str(), c))
            .collect();
        cost.insert(wide.key.as_str(), 3.0);
        assert_eq!(round(&[four, alone], &cost), 5.0);
        let text = at_most(13, 5.0);
        assert!(text.contains("predicted 5.0 s a round"), "{text}");
        assert!(text.contains("about 65 s for 13 rounds at most"), "{text}");
        assert_eq!(seconds(0.123), "0.12 s");
        assert_eq!(seconds(7200.0), "7200 s (2.0 h)");
        assert!(text.contains("queue waits not included"), "{text}");
    }
}
