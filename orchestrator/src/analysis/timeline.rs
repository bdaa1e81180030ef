//! A run's timeline as phases on each worker's lane: where its wall time went. A case's span,
//! from its start to its record stored, splits into the worker's start (a worker, job step or
//! process started for it) or the hand-off (the case sent to a worker that was up), the
//! solver's own set-up, solve and what it measured after (a spectrum's ends, the errors), and
//! the answer's way back and its storing. Between a lane's cases it is idle; between the
//! pool's batches (a search's rounds) the driver plans the next.

use crate::store::timeline::{Event, RunTimeline};

/// What a lane was doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Phase {
    Starting,
    Setup,
    Solve,
    /// After the solve: a step's amplification (the spectrum's ends), the errors.
    Measuring,
    /// The case sent to an idle worker, its answer read and stored.
    Passing,
    /// A case that left no record (failed, stopped): its span whole.
    Unrecorded,
    Idle,
    /// Between the pool's batches: the driver deciding the next round.
    Planning,
}

impl Phase {
    pub const ALL: [Phase; 8] = [
        Phase::Starting,
        Phase::Setup,
        Phase::Solve,
        Phase::Measuring,
        Phase::Passing,
        Phase::Unrecorded,
        Phase::Idle,
        Phase::Planning,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Phase::Starting => "starting",
            Phase::Setup => "set-up",
            Phase::Solve => "solve",
            Phase::Measuring => "spectrum and errors",
            Phase::Passing => "hand-off and store",
            Phase::Unrecorded => "no record",
            Phase::Idle => "idle",
            Phase::Planning => "between rounds",
        }
    }

    /// The solver's work and what serves it; idle and planning are waiting.
    pub fn busy(self) -> bool {
        !matches!(self, Phase::Idle | Phase::Planning)
    }
}

/// A span of one phase on lane `lane` (an index into `Timeline::lanes`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Span {
    pub lane: usize,
    pub from: f64,
    pub to: f64,
    pub phase: Phase,
}

/// A run's lanes (node, lane on the node), sorted by node, and the spans on them.
pub struct Timeline {
    pub run: String,
    pub begin: f64,
    pub end: f64,
    pub lanes: Vec<(String, usize)>,
    pub spans: Vec<Span>,
    /// Each lane's wall time: from the begin of the first batch it worked in to the run's end.
    pub walls: Vec<f64>,
    pub cases: usize,
}

impl Timeline {
    /// The spans of `run`'s events; `None` for a run that finished no batch or ran no case.
    pub fn of(run: &RunTimeline) -> Option<Timeline> {
        let batches = run.batches();
        let (begin, end) = (batches.first()?.0, batches.last()?.1);
        let mut lanes: Vec<(String, usize)> = Vec::new();
        let mut lane_of = |node: &str, lane: usize| -> usize {
            let at = lanes.iter().position(|l| l.0 == node && l.1 == lane);
            at.unwrap_or_else(|| {
                lanes.push((node.to_string(), lane));
                lanes.len() - 1
            })
        };
        let mut spans = Vec::new();
        let mut cases = 0;
        for event in &run.events {
            match event {
                Event::Batch { .. } => {}
                Event::Idle {
                    node,
                    lane,
                    from,
                    to,
                } => spans.push(Span {
                    lane: lane_of(node, *lane),
                    from: *from,
                    to: *to,
                    phase: Phase::Idle,
                }),
                Event::Case { node, lane, .. } => {
                    cases += 1;
                    spans.extend(case_spans(lane_of(node, *lane), event));
                }
            }
        }
        if cases == 0 {
            return None;
        }
        let mut order: Vec<usize> = (0..lanes.len()).collect();
        order.sort_by(|&a, &b| lanes[a].cmp(&lanes[b]));
        let rank: Vec<usize> = {
            let mut rank = vec![0; lanes.len()];
            for (k, &lane) in order.iter().enumerate() {
                rank[lane] = k;
            }
            rank
        };
        for span in &mut spans {
            span.lane = rank[span.lane];
        }
        let lanes: Vec<(String, usize)> = order.iter().map(|&k| lanes[k].clone()).collect();
        // A lane's wall starts with the first batch it worked in; the gaps between that batch
        // and the next ones are the driver's.
        let mut walls = vec![0.0; lanes.len()];
        for (lane, wall) in walls.iter_mut().enumerate() {
            let first = spans
                .iter()
                .filter(|s| s.lane == lane)
                .map(|s| s.from)
                .fold(f64::INFINITY, f64::min);
            let from = batches
                .iter()
                .rev()
                .find(|b| b.0 <= first)
                .map_or(first, |b| b.0);
            *wall = end - from;
            for pair in batches.windows(2).filter(|p| p[0].1 >= from) {
                spans.push(Span {
                    lane,
                    from: pair[0].1,
                    to: pair[1].0,
                    phase: Phase::Planning,
                });
            }
        }
        Some(Timeline {
            run: run.run.clone(),
            begin,
            end,
            lanes,
            spans,
            walls,
            cases,
        })
    }

    /// Seconds of each phase on `lane`, in `Phase::ALL`'s order.
    pub fn totals(&self, lane: usize) -> [f64; Phase::ALL.len()] {
        let mut totals = [0.0; Phase::ALL.len()];
        for span in self.spans.iter().filter(|s| s.lane == lane) {
            let k = Phase::ALL
                .iter()
                .position(|p| *p == span.phase)
                .expect("listed");
            totals[k] += (span.to - span.from).max(0.0);
        }
        totals
    }
}

/// A case's span split into its phases, in the order they happened.
fn case_spans(lane: usize, case: &Event) -> Vec<Span> {
    let Event::Case {
        started,
        answered,
        saved,
        fresh,
        phases,
        ..
    } = case
    else {
        return Vec::new();
    };
    let span = |from: f64, length: f64, phase| Span {
        lane,
        from,
        to: from + length.max(0.0),
        phase,
    };
    let Some(phases) = phases else {
        return vec![span(*started, saved - started, Phase::Unrecorded)];
    };
    // The solver's own clock within what the pool saw.
    let heard = (answered - started).max(0.0);
    let solver = phases.wall_s.clamp(0.0, heard);
    let setup = phases.setup_s.clamp(0.0, solver);
    let solve = phases.solve_s.clamp(0.0, solver - setup);
    let before = heard - solver;
    let first = match fresh {
        true => Phase::Starting,
        false => Phase::Passing,
    };
    let mut at = *started;
    let mut spans = Vec::new();
    for (length, phase) in [
        (before, first),
        (setup, Phase::Setup),
        (solve, Phase::Solve),
        (solver - setup - solve, Phase::Measuring),
        (saved - answered, Phase::Passing),
    ] {
        spans.push(span(at, length, phase));
        at += length.max(0.0);
    }
    spans
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::timeline::Phases;

    /// The share of `lane`'s wall time its spans account for.
    fn accounted(timeline: &Timeline, lane: usize) -> f64 {
        timeline.totals(lane).iter().sum::<f64>() / timeline.walls[lane]
    }

    fn case(lane: usize, started: f64, fresh: bool, phases: Option<Phases>) -> Event {
        Event::Case {
            node: "n".into(),
            lane,
            key: "k".into(),
            started,
            answered: started + 1.0,
            saved: started + 1.25,
            fresh,
            phases,
        }
    }

    /// Two batches with a round's planning between them; a fresh worker's first case starts,
    /// its second is handed off; a failed case is unrecorded; idle spans as recorded.
    #[test]
    fn a_lanes_wall_time_splits_into_its_phases() {
        let solved = Phases {
            setup_s: 0.25,
            solve_s: 0.5,
            wall_s: 0.875,
        };
        let phases = Some(solved);
        // A worker that was up takes a quarter second to hand the case over.
        let handed_off = Some(Phases {
            wall_s: 0.75,
            ..solved
        });
        let run = RunTimeline {
            run: "h-1-1".into(),
            events: vec![
                case(0, 10.0, true, phases),
                case(1, 10.0, true, None),
                Event::Idle {
                    node: "n".into(),
                    lane: 0,
                    from: 11.25,
                    to: 11.5,
                },
                Event::Idle {
                    node: "n".into(),
                    lane: 1,
                    from: 11.25,
                    to: 11.5,
                },
                Event::Batch {
                    begin: 10.0,
                    end: 11.5,
                },
                Event::Idle {
                    node: "n".into(),
                    lane: 0,
                    from: 12.0,
                    to: 12.25,
                },
                case(0, 12.25, false, handed_off),
                Event::Batch {
                    begin: 12.0,
                    end: 13.5,
                },
            ],
        };
        let timeline = Timeline::of(&run).unwrap();
        assert_eq!(timeline.lanes, vec![("n".into(), 0), ("n".into(), 1)]);
        assert_eq!(timeline.cases, 3);
        assert_eq!(timeline.walls, vec![3.5, 3.5]);
        let [starting, setup, solve, measuring, passing, unrecorded, idle, planning] =
            timeline.totals(0);
        assert_eq!(
            (starting, setup, solve, measuring),
            (0.125, 0.5, 1.0, 0.125)
        );
        assert_eq!(
            (passing, unrecorded, idle, planning),
            (0.25 + 0.25 + 0.25, 0.0, 0.5, 0.5)
        );
        assert_eq!(accounted(&timeline, 0), 1.0);
        let lane1 = timeline.totals(1);
        assert_eq!(lane1[5], 1.25, "the failed case's span");
        assert_eq!(lane1[6], 0.25);
        assert_eq!(lane1[7], 0.5);
        assert_eq!(
            accounted(&timeline, 1),
            2.0 / 3.5,
            "its second batch was not recorded"
        );
    }
}
