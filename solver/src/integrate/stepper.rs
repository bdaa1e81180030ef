//! What every time integrator of u' = L u + b(t) shares: the right-hand side with its operator
//! workspace, the `Stepper` interface, and the timed run of a stepper with its error bookkeeping.

use super::checkpoint::{self, Carried};
use super::timed::{
    is_sampled, timed_steps_observed, Checkpoints, Stepping, Trajectory, MAX_TIMED_STEPS,
};
use crate::operator::LinearOperator;
use crate::output::diagnostics;
use crate::output::record::ImplicitSolves;
use crate::parallel::exchange::Ranks;
use crate::problem::{manufactured_solution, Source};
use crate::threads::BLOCK;
use rayon::prelude::*;
use std::borrow::Cow;
use std::cell::{Cell, RefCell};

/// One step of a time integrator.
pub trait Stepper {
    /// u ← u(t + dt); returns max |u| after the step over all ranks (+∞ if any is NaN).
    fn step(&mut self, u: &mut [f64], t: f64, dt: f64) -> f64;

    /// What the linear solves of an implicit stepper took; nothing for explicit ones.
    fn solves(&self) -> ImplicitSolves {
        ImplicitSolves::default()
    }

    /// The times it applied its operator L_h so far (each stage, each Krylov iteration): the
    /// machine-independent work of its run; None for a stepper that does not count.
    fn applications(&self) -> Option<usize> {
        None
    }

    /// Adds what the stepper carries from step to step, beyond the field, to a checkpoint.
    fn carry(&self, _: &mut Carried) {}

    /// Takes back what `carry` saved, in a run resumed from a checkpoint.
    fn take_back(&mut self, _: &Carried) {}
}

/// The right-hand side f(t, u) = L u + b(t) on some ranks, with b(t) = α(t) φ + β(t) ψ (the
/// manufactured source; none for the bump).
pub struct Rhs<'a, Op: LinearOperator> {
    operator: &'a Op,
    workspace: Op::Workspace,
    pub source: Option<&'a Source>,
    pub ranks: Ranks<'a>,
    /// The times `apply` ran.
    pub applications: usize,
}

impl<'a, Op: LinearOperator> Rhs<'a, Op> {
    pub fn new(operator: &'a Op, source: Option<&'a Source>, ranks: Ranks<'a>) -> Self {
        Rhs {
            workspace: operator.workspace(),
            operator,
            source,
            ranks,
            applications: 0,
        }
    }

    /// out = L v.
    pub fn apply(&mut self, v: &[f64], out: &mut [f64]) {
        self.applications += 1;
        self.operator.apply(v, out, &mut self.workspace);
    }

    /// out = L v + b(t).
    pub fn rate(&mut self, t: f64, v: &[f64], out: &mut [f64]) {
        self.apply(v, out);
        self.add_source(&[(t, 1.0)], out);
    }

    /// out += Σ c·b(t) over the (t, c) of `terms`, in one pass.
    pub fn add_source(&self, terms: &[(f64, f64)], out: &mut [f64]) {
        let Some(source) = self.source else { return };
        let (mut alpha, mut beta) = (0.0, 0.0);
        for &(t, c) in terms {
            let (a, b) = Source::coefficients(t);
            (alpha, beta) = (alpha + c * a, beta + c * b);
        }
        self.ranks.on(|| {
            out.par_chunks_mut(BLOCK)
                .enumerate()
                .for_each(|(b, block)| {
                    let at = b * BLOCK;
                    for (k, o) in block.iter_mut().enumerate() {
                        *o += alpha * source.phi[at + k] + beta * source.psi[at + k];
                    }
                })
        });
    }
}

/// The checkpoint's part that counts the operator's applications.
const APPLICATIONS: &str = "operator_applications";

/// The timed run of `stepper` over `stepping` from u, with the total error e = Σₖ eᵏ against the
/// manufactured solution of `source` when the case tracks it (summed over ranks).
pub fn integrate(
    stepper: &mut dyn Stepper,
    ranks: Ranks,
    mut u: Vec<f64>,
    source: Option<&Source>,
    stepping: &Stepping,
) -> Trajectory {
    let (dt, volume) = (stepping.dt, stepping.volume);
    let total_error_source = source.filter(|_| stepping.track_total_error);
    let squared_error = |u: &[f64], t: f64| {
        total_error_source.map_or(0.0, |s| {
            let local = ranks
                .on(|| diagnostics::squared_l2_error(manufactured_solution(&s.phi, t), u, volume));
            ranks.sum(local)
        })
    };
    // Shared by the loop's closures and the checkpoints' parts.
    let error_total = Cell::new(squared_error(&u, 0.0));
    let comm_seconds = RefCell::new(Vec::with_capacity(stepping.steps.min(MAX_TIMED_STEPS)));
    let stepper = RefCell::new(stepper);
    let mut checkpointer = checkpoint::take(stepping.steps, Some(u.len()));
    if let Some(checkpointer) = checkpointer.as_mut() {
        checkpointer.agree_over_ranks(ranks.exchange);
    }
    let exchange = ranks.exchange;
    if let Some(resume) = checkpointer.as_ref().and_then(|c| c.resume.as_ref()) {
        // `take` checked that it holds a field of this length.
        if let Some(field) = resume.values("field") {
            u.copy_from_slice(field);
        }
        error_total.set(resume.number("error_total").unwrap_or(0.0));
        *comm_seconds.borrow_mut() = resume.values("comm_seconds").unwrap_or(&[]).to_vec();
        stepper.borrow_mut().take_back(resume);
    }
    // The operator's applications: those before a checkpoint resumed from, and the loop's.
    let applied_earlier = (checkpointer.as_ref())
        .and_then(|c| c.resume.as_ref()?.count(APPLICATIONS))
        .unwrap_or(0);
    let at_start = stepper.borrow().applications();
    let applied = |stepper: &dyn Stepper| {
        Some(applied_earlier + stepper.applications()? - at_start.unwrap_or(0))
    };
    // The loop's traffic: a resumed run counts the steps before its checkpoint as sent.
    let at_loop_start = exchange.traffic();
    if let Some(earlier) = checkpointer
        .as_ref()
        .and_then(|c| c.resume.as_ref()?.traffic())
    {
        exchange.count_earlier(earlier);
    }
    let mut carry = |u: &Vec<f64>, carried: &mut Carried| {
        carried.put("field", u.clone());
        carried.put_number("error_total", error_total.get());
        carried.put("comm_seconds", comm_seconds.borrow().clone());
        carried.put_traffic_since(exchange.traffic(), at_loop_start);
        if let Some(applied) = applied(*stepper.borrow()) {
            carried.put_count(APPLICATIONS, applied);
        }
        stepper.borrow().carry(carried);
    };
    let on_any_rank = |holds: bool| exchange.bookkeeping_max(f64::from(u8::from(holds))) > 0.0;
    let checkpoints = checkpointer.map(|checkpointer| Checkpoints {
        checkpointer,
        carry: &mut carry,
        on_any_rank: &on_any_rank,
    });
    let (timing, observed) = timed_steps_observed(
        &mut u,
        stepping,
        |u| Cow::Borrowed(u),
        |u, k| {
            let comm_before = ranks.exchange.seconds();
            let max_abs = stepper.borrow_mut().step(u, k as f64 * dt, dt);
            if is_sampled(stepping.steps, k) {
                comm_seconds
                    .borrow_mut()
                    .push(ranks.exchange.seconds() - comm_before);
            }
            max_abs
        },
        |u, steps_done| {
            error_total.set(error_total.get() + squared_error(u, steps_done as f64 * dt))
        },
        checkpoints,
    );
    let (error_total, comm_seconds, stepper) = (
        error_total.get(),
        comm_seconds.into_inner(),
        stepper.into_inner(),
    );
    let tracked = total_error_source.is_some() && timing.diverged_at.is_none();
    Trajectory {
        error_total: tracked.then_some(error_total),
        step_comm_s: diagnostics::median(comm_seconds),
        implicit: stepper.solves(),
        operator_applications: applied(stepper),
        ..Trajectory::observed(u, timing, observed)
    }
}
