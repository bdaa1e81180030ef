//! What a measured run would take on another allocation: its timeline's cases replayed on
//! `nodes × cores` lanes by one driver, as `nlstudy run` runs a whole study in one allocation
//! (`submit --whole`). The inputs are measured, not assumed: each case's time on its lane (its
//! solver's, with its hand-off), the driver's own time per case (reading an answer, storing
//! its record: serial, however many lanes), a worker's start, and the time between the pool's
//! batches (a search planning its next round: the driver's, serial too).
//!
//! The model: each batch's cases, longest first, each onto the lane free first (the pool's
//! order where it runs cases side by side), each answer stored by the driver in turn; the
//! batches one after another with the measured gaps between them. What it leaves out, printed
//! with it: the scheduler's queue and the job's start, the driver's plan before and tables after
//! the job, and contention for memory or the network between lanes.

use crate::statistics::median;
use crate::store::timeline::{Event, RunTimeline};
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// A measured run reduced to what the model needs.
#[derive(Debug)]
pub struct Measured {
    /// Each batch's cases' times on a lane (set-up to answer, less a worker's start).
    pub batches: Vec<Vec<f64>>,
    /// The gaps between batches.
    pub gaps: Vec<f64>,
    /// The driver's time per case: its answer read and its record stored (the median).
    pub driver_s: f64,
    /// A worker's start, before its first case (the median over fresh workers).
    pub start_s: f64,
    /// The lanes it ran on and how long it took (its first batch's begin to its last's end).
    pub lanes: usize,
    pub length: f64,
}

impl Measured {
    /// `None` for a run with no batch or no case.
    pub fn of(run: &RunTimeline) -> Option<Measured> {
        let batches = run.batches();
        if batches.is_empty() {
            return None;
        }
        let mut times = vec![Vec::new(); batches.len()];
        let (mut driver, mut starts) = (Vec::new(), Vec::new());
        let mut lanes = std::collections::BTreeSet::new();
        for event in &run.events {
            let Event::Case {
                node,
                lane,
                started,
                answered,
                saved,
                fresh,
                phases,
                ..
            } = event
            else {
                continue;
            };
            lanes.insert((node.as_str(), *lane));
            let heard = answered - started;
            // A fresh worker's start is the time before its solver's own.
            let start = match (fresh, phases) {
                (true, Some(p)) => (heard - p.wall_s).max(0.0),
                _ => 0.0,
            };
            if *fresh && phases.is_some() {
                starts.push(start);
            }
            driver.push(saved - answered);
            let batch = batches.iter().rposition(|b| b.0 <= *started).unwrap_or(0);
            times[batch].push(heard - start);
        }
        if driver.is_empty() {
            return None;
        }
        Some(Measured {
            gaps: batches
                .windows(2)
                .map(|w| (w[1].0 - w[0].1).max(0.0))
                .collect(),
            length: batches.last()?.1 - batches.first()?.0,
            batches: times,
            driver_s: median(&driver),
            start_s: if starts.is_empty() {
                0.0
            } else {
                median(&starts)
            },
            lanes: lanes.len(),
        })
    }

    /// The predicted length of the run on `lanes` lanes.
    pub fn on(&self, lanes: usize) -> f64 {
        let batches: f64 = self
            .batches
            .iter()
            .map(|cases| batch_makespan(cases, lanes, self.driver_s))
            .sum();
        self.start_s + batches + self.between_rounds()
    }

    /// The time between the batches in all (never -0: an empty sum of floats is).
    pub fn between_rounds(&self) -> f64 {
        self.gaps.iter().sum::<f64>().max(0.0)
    }
}

/// One batch on `lanes` lanes with one driver storing each answer in `driver_s`, in the order
/// the answers come: cases longest first, each onto the lane its last record freed.
fn batch_makespan(cases: &[f64], lanes: usize, driver_s: f64) -> f64 {
    let mut longest_first = cases.to_vec();
    longest_first.sort_by(|a, b| b.total_cmp(a));
    let mut queue = longest_first.into_iter();
    // Answers to come, by when, in nanoseconds (a heap needs a total order).
    let ns = |s: f64| (s * 1e9).round() as u64;
    let mut answers: BinaryHeap<Reverse<u64>> = queue
        .by_ref()
        .take(lanes.max(1))
        .map(|case| Reverse(ns(case)))
        .collect();
    let mut stored = 0.0_f64;
    while let Some(Reverse(answered)) = answers.pop() {
        stored = stored.max(answered as f64 * 1e-9) + driver_s;
        if let Some(case) = queue.next() {
            answers.push(Reverse(ns(stored + case)));
        }
    }
    stored
}

/// `4`, `4x2`: nodes, and cores on each (default `cores`).
pub fn parse_shape(text: &str, cores: usize) -> Result<(usize, usize), String> {
    let number = |s: &str| {
        s.trim()
            .parse::<usize>()
            .ok()
            .filter(|&n| (1..=1 << 20).contains(&n))
    };
    let shape = match text.split_once(['x', 'X']) {
        Some((nodes, per)) => number(nodes).zip(number(per)),
        None => number(text).map(|n| (n, cores)),
    };
    shape.ok_or_else(|| {
        format!(
            "--simulate: `{}` is not NODES or NODESxCORES (e.g. 16 or 16x4), counts from 1",
            text.escape_debug()
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A batch fills its lanes longest first; the driver's serial time bounds it once lanes
    /// are many.
    #[test]
    fn a_batch_takes_its_longest_lane_or_its_drivers_time() {
        let cases = [4.0, 3.0, 3.0, 2.0, 2.0, 2.0];
        assert_eq!(batch_makespan(&cases, 1, 0.0), 16.0);
        // LPT on 2 lanes: 4+2+2 and 3+3+2.
        assert_eq!(batch_makespan(&cases, 2, 0.0), 8.0);
        assert_eq!(batch_makespan(&cases, 6, 0.0), 4.0);
        assert_eq!(batch_makespan(&cases, 100, 0.0), 4.0);
        // Each answer costs the driver 1: the answers at 2, 2, 2, 3, 3, 4 are stored at 3 to 8.
        assert_eq!(batch_makespan(&cases, 6, 1.0), 8.0);
        assert_eq!(batch_makespan(&cases, 100, 1.0), 8.0);
        let run = Measured {
            batches: vec![cases.to_vec(), vec![1.0]],
            gaps: vec![0.5],
            driver_s: 0.0,
            start_s: 0.25,
            lanes: 2,
            length: 9.0,
        };
        assert_eq!(run.on(2), 0.25 + 8.0 + 0.5 + 1.0);
        assert_eq!(parse_shape("16", 2), Ok((16, 2)));
        assert_eq!(parse_shape("16x4", 2), Ok((16, 4)));
        assert!(parse_shape("0", 2).unwrap_err().contains("NODESxCORES"));
        assert!(parse_shape("4x", 2).is_err());
    }
}
