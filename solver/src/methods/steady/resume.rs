//! Checkpoints of the steady solves, steady CG's and FETI's projected CG (\[XGDF]): CG's state
//! between two iterations (`cg::State`), written by the process's checkpointer
//! (`checkpoint::take`) every N iterations, every so many wall seconds and on the stopping
//! signal, so that a steady run stopped at iteration k resumes there with the record of a run
//! never stopped (`resumed_from_step` is then the iteration).
//!
//! What is cheap to make again is not saved: the operator, FETI's subdomain factorisations and
//! coarse problem (the set-up, which a resumed run repeats), and z = M r. Over ranks each rank
//! saves its share of the vectors, at an iteration all agree on, as the time loop does.

use crate::integrate::checkpoint::{self, Carried, Checkpointer};
use crate::integrate::progress::{self, Reporter};
use crate::linalg::cg::{Checkpoints, State};
use crate::output::record::Traffic;
use crate::parallel::exchange::Exchange;
use std::time::Instant;

/// A steady solve's checkpoints (none when the process has no checkpointer), what the segments
/// of the solve before this one measured, and its progress file (`--progress`), if any.
pub(crate) struct SolveCheckpoints<'a> {
    checkpointer: Option<Checkpointer>,
    progress: Option<Reporter>,
    /// The solve's tolerance and iteration cap, for the progress file's estimate.
    rtol: f64,
    max_iterations: usize,
    exchange: &'a dyn Exchange,
    /// The traffic, communication seconds and wall clock when this segment's solve started.
    at_start: (Traffic, f64, Instant),
    earlier: Earlier,
}

/// What the earlier segments of a resumed solve measured.
#[derive(Default)]
struct Earlier {
    /// The iteration resumed from (0: none).
    iteration: usize,
    solve_s: Vec<f64>,
    comm_s: f64,
}

/// A steady solve's seconds over all its segments.
pub(crate) struct Resumed {
    /// The iteration it resumed from, 0 for a solve in one piece.
    pub from_iteration: usize,
    /// The solve's seconds in all, and each segment's when it was resumed.
    pub solve_s: f64,
    pub segments_s: Option<Vec<f64>>,
}

impl<'a> SolveCheckpoints<'a> {
    /// The process's checkpointer and progress file, taken for the solve about to start on the
    /// ranks of `exchange`, to `rtol` within `max_iterations`.
    pub fn take(exchange: &'a dyn Exchange, rtol: f64, max_iterations: usize) -> Self {
        SolveCheckpoints {
            checkpointer: checkpoint::take(max_iterations, None),
            progress: progress::take()
                .map(|r| r.counting(schema::protocol::ProgressUnit::Iteration)),
            rtol,
            max_iterations,
            exchange,
            at_start: (exchange.traffic(), exchange.seconds(), Instant::now()),
            earlier: Earlier::default(),
        }
    }

    /// The solve's seconds, given this segment's.
    pub fn resumed(&self, this_segment_s: f64) -> Resumed {
        let Earlier {
            iteration, solve_s, ..
        } = &self.earlier;
        let segments: Vec<f64> = solve_s.iter().copied().chain([this_segment_s]).collect();
        Resumed {
            from_iteration: *iteration,
            solve_s: segments.iter().sum(),
            segments_s: (*iteration > 0).then_some(segments),
        }
    }

    /// The iteration the solve resumed from (0: none).
    pub fn resumed_from(&self) -> usize {
        self.earlier.iteration
    }

    /// The communication seconds of the solve's earlier segments.
    pub fn earlier_comm_s(&self) -> f64 {
        self.earlier.comm_s
    }
}

impl Checkpoints for SolveCheckpoints<'_> {
    fn resume(&mut self, len: usize) -> Option<State<Vec<f64>>> {
        let checkpointer = self.checkpointer.as_mut()?;
        checkpointer.agree_over_ranks(self.exchange);
        // Counted from here, where a run that resumes and one that does not stand alike.
        self.at_start = (
            self.exchange.traffic(),
            self.exchange.seconds(),
            Instant::now(),
        );
        let carried = checkpointer.resume.take()?;
        let vector = |name: &str| {
            carried
                .values(name)
                .filter(|v| v.len() == len)
                .map(<[f64]>::to_vec)
        };
        let scalars = carried
            .values("cg.scalars")
            .and_then(|s| <[f64; 3]>::try_from(s).ok());
        let (Some(x), Some(r), Some(p), Some([rz, reference, relative_residual])) =
            (vector("cg.x"), vector("cg.r"), vector("cg.p"), scalars)
        else {
            // Of this case and build, so of this solve: unreachable but for a bug, said.
            eprintln!("nlsolve: the checkpoint holds no CG state of this solve; it starts afresh");
            return None;
        };
        if let Some(earlier) = carried.traffic() {
            self.exchange.count_earlier(earlier);
        }
        self.earlier = Earlier {
            iteration: carried.step,
            solve_s: carried.values("solve.segments_s").unwrap_or(&[]).to_vec(),
            comm_s: carried.number("solve.comm_s").unwrap_or(0.0),
        };
        Some(State {
            iteration: carried.step,
            x,
            r,
            p,
            rz,
            reference,
            relative_residual,
        })
    }

    fn after_iteration(&mut self, state: State<&[f64]>) {
        if let Some(reporter) = self.progress.as_mut() {
            let expected = expected_iterations(
                state.iteration,
                state.relative_residual,
                self.rtol,
                self.max_iterations,
            );
            reporter.note(state.iteration, expected);
        }
        let Some(checkpointer) = self.checkpointer.as_mut() else {
            return;
        };
        let exchange = self.exchange;
        let on_any_rank = |holds: bool| exchange.bookkeeping_max(f64::from(u8::from(holds))) > 0.0;
        let k = state.iteration;
        let stop = on_any_rank(checkpoint::stop_requested());
        if stop || on_any_rank(checkpointer.due(k)) {
            let (traffic, comm_s, started) = self.at_start;
            let mut carried = Carried::at(k);
            carried.put(
                "cg.scalars",
                vec![state.rz, state.reference, state.relative_residual],
            );
            let mut segments = self.earlier.solve_s.clone();
            // Each segment's seconds are its slowest rank's, as the record's solve_s is.
            segments.push(exchange.bookkeeping_max(started.elapsed().as_secs_f64()));
            carried.put("solve.segments_s", segments);
            carried.put_number(
                "solve.comm_s",
                self.earlier.comm_s + exchange.seconds() - comm_s,
            );
            carried.put_traffic_since(exchange.traffic(), traffic);
            // The vectors are written as they lie: no copy of them is made.
            let vectors = [("cg.x", state.x), ("cg.r", state.r), ("cg.p", state.p)];
            checkpointer.save(&carried, &vectors);
        }
        // Every rank's file is written before any rank exits.
        if stop && on_any_rank(true) {
            checkpointer.stop("iteration", k);
        }
    }
}

/// The iterations a solve is likely to take in all, after `k` brought its residual (relative, so
/// 1 at the start) to `relative_residual`: as many as the decay so far needs to reach `rtol`,
/// between k + 1 and the cap.
fn expected_iterations(
    k: usize,
    relative_residual: f64,
    rtol: f64,
    max_iterations: usize,
) -> usize {
    let rate = relative_residual.ln() / k.max(1) as f64;
    let needed = if rate.is_finite() && rate < 0.0 {
        (rtol.ln() / rate).round()
    } else {
        max_iterations as f64
    };
    (needed as usize).clamp(k + 1, max_iterations.max(k + 1))
}

#[cfg(test)]
mod tests {
    use super::expected_iterations;

    #[test]
    fn the_iterations_expected_follow_the_residual_s_decay_within_the_cap() {
        // 10⁻² after 20 iterations: 10⁻⁸ takes 80.
        assert_eq!(expected_iterations(20, 1e-2, 1e-8, 1000), 80);
        assert_eq!(expected_iterations(20, 1e-2, 1e-8, 50), 50, "the cap");
        assert_eq!(expected_iterations(20, 2.0, 1e-8, 500), 500, "no decay yet");
        assert_eq!(
            expected_iterations(20, 1e-9, 1e-8, 500),
            21,
            "at least one more"
        );
        assert_eq!(expected_iterations(3, f64::NAN, 1e-8, 500), 500);
    }
}
