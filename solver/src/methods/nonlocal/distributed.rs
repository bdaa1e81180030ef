//! The fully distributed solver (seed 000, section 3 and Algorithm 3) over MPI.
//!
//! Every rank plans its `Subdomain` once from the ownership map (a block partition each rank
//! computes alike, or a METIS partition made on rank 0 and broadcast), then steps forward Euler
//! on its own nodes. Each step it posts non-blocking receives and sends for the halo, computes
//! its interior nodes while the messages are in flight, waits, and computes its boundary nodes.
//! The per-node arithmetic is the serial stencil's, in the same order, so the distributed field
//! equals the serial one bit for bit; errors and mass are sums over ranks and agree to rounding.
//!
//! MPI is called from the main thread only (`Threading::Funneled`); the computing runs on the
//! case's rayon pool.

use super::Plan;
use crate::case::ValidCase;
use crate::case::{Case, CaseError, Problem, SourceMode};
use crate::discretization::grid::RowRun;
use crate::integrate::euler::{is_sampled, timed_steps, MAX_TIMED_STEPS};
use crate::integrate::time_step::divergence_bound;
use crate::operator::stencil::apply_on_runs;
use crate::output::diagnostics::median;
use crate::output::diagnostics::{self, magnitude};
use crate::output::outcome::{self, Measured, Outcome};
use crate::parallel::exchange::{all_max, all_sum, distribution, ownership};
use crate::parallel::halo::HaloExchange;
use crate::parallel::partition::Ownership;
use crate::parallel::subdomain::Subdomain;
use crate::problem::source::PointwiseSource;
use crate::problem::{self, manufactured_solution, Source};
use crate::threads::BLOCK;
use mpi::point_to_point::Source as _;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use rayon::prelude::*;
use rayon::ThreadPool;
use std::time::Instant;

/// Runs a nonlocal case on the ranks of `world` (its size already checked against
/// `case.ranks`). Rank 0 gets the outcome (with the whole field when `gather_field`), the other
/// ranks `None`.
pub fn run(
    world: &SimpleCommunicator,
    case: &ValidCase,
    gather_field: bool,
) -> Result<Option<Outcome>, CaseError> {
    let pool = crate::threads::pool(case.threads)?;
    let setup_started = Instant::now();
    let plan = pool.install(|| Plan::new(case))?;
    let ownership = ownership(world, case, &plan.stencil)?;
    let rank = world.rank() as usize;
    let subdomain = Subdomain::new(&ownership, &plan.stencil, rank);
    let mut rank_run = RankRun::new(world, &pool, case, &plan, &subdomain);
    let setup_s = setup_started.elapsed().as_secs_f64();
    let measured = rank_run.integrate(case, setup_s, &ownership);

    let field = gather_field.then(|| rank_run.gather_field(&ownership));
    let grid = plan.stencil.grid;
    Ok((rank == 0).then(|| Outcome {
        record: outcome::record(case, plan.resolved(), measured),
        field: field.flatten().unwrap_or_default(),
        lattice: grid.lattice(),
        frames: Vec::new(), // refused for ranks > 1 by the case's validation
    }))
}

/// One rank's state: its values on its window and its share of the source, in compact order.
struct RankRun<'a> {
    world: &'a SimpleCommunicator,
    pool: &'a ThreadPool,
    plan: &'a Plan,
    subdomain: &'a Subdomain,
    /// u on the window: owned nodes and ghosts (other cells are never read).
    u: Vec<f64>,
    source: Option<Source>,
    /// Runs sorted by their place in the window, with that place: for the update.
    placed_runs: Vec<(usize, RowRun)>,
    halo: HaloExchange<'a>,
    volume: f64,
}

impl<'a> RankRun<'a> {
    fn new(
        world: &'a SimpleCommunicator,
        pool: &'a ThreadPool,
        case: &Case,
        plan: &'a Plan,
        subdomain: &'a Subdomain,
    ) -> Self {
        let stencil = &plan.stencil;
        let grid = stencil.grid;
        let window = &subdomain.window;
        let window_nodes: Vec<usize> = (0..window.len())
            .map(|w| (window.y0 + w / window.nx) * grid.n + window.x0 + w % window.nx)
            .collect();
        let nodes = subdomain.node_indices(grid.n);
        let sample = |f: fn(usize, [f64; 2]) -> f64, at: &[usize]| -> Vec<f64> {
            pool.install(|| {
                at.par_iter()
                    .map(|&i| f(grid.dim, grid.position(i)))
                    .collect()
            })
        };
        let (u, source) = if case.problem == Problem::Bump {
            (sample(problem::bump, &window_nodes), None)
        } else {
            let phi_window = sample(problem::profile, &window_nodes);
            let phi = sample(problem::profile, &nodes);
            let psi = match case.source() {
                SourceMode::Discrete => {
                    let mut psi = vec![0.0; nodes.len()];
                    let runs: Vec<RowRun> = subdomain.runs().copied().collect();
                    pool.install(|| apply_on_runs(stencil, window, &runs, &phi_window, &mut psi));
                    psi
                }
                SourceMode::Continuum | SourceMode::Local => {
                    let pointwise = PointwiseSource::new(case, stencil).expect("a pointwise mode");
                    pool.install(|| nodes.par_iter().map(|&i| pointwise.psi(i)).collect())
                }
                SourceMode::None => {
                    unreachable!("validated: the manufactured problem has a source")
                }
            };
            (phi_window, Some(Source { phi, psi }))
        };
        let mut placed_runs: Vec<(usize, RowRun)> = subdomain
            .runs()
            .map(|run| (window.index(run.x0, run.y), *run))
            .collect();
        placed_runs.sort_unstable_by_key(|&(place, _)| place);
        RankRun {
            world,
            pool,
            plan,
            subdomain,
            u,
            source,
            placed_runs,
            halo: HaloExchange::new(&subdomain.neighbours),
            volume: grid.volume(),
        }
    }

    /// The time loop, then the errors and diagnostics reduced over ranks.
    fn integrate(&mut self, case: &Case, setup_s: f64, ownership: &Ownership) -> Measured {
        let (plan, subdomain, pool, world) = (self.plan, self.subdomain, self.pool, self.world);
        let stencil = &plan.stencil;
        let window = &subdomain.window;
        let dt = plan.dt;
        let owned = subdomain.owned();
        let interior_nodes: usize = subdomain.interior.iter().map(RowRun::len).sum();

        let u0 = self.owned_values();
        let u0_max = all_max(world, pool.install(|| diagnostics::max_abs(&u0)));
        let source_max = self.source.as_ref().map(|s| {
            (
                all_max(world, pool.install(|| diagnostics::max_abs(&s.phi))),
                all_max(world, pool.install(|| diagnostics::max_abs(&s.psi))),
            )
        });
        let divergence_bound = divergence_bound(case, u0_max, source_max);
        let track_total_error = case.error_total && self.source.is_some();
        let mut error_total = if track_total_error {
            self.squared_error(0.0)
        } else {
            0.0
        };

        let mut lu = vec![0.0; owned];
        let mut comm_seconds = Vec::with_capacity(plan.steps.min(MAX_TIMED_STEPS));
        let timing = timed_steps(
            self,
            plan.steps,
            divergence_bound,
            |run, k| {
                let (lu_interior, lu_boundary) = lu.split_at_mut(interior_nodes);
                let mut comm_s = run.halo.exchange(world, &mut run.u, |u| {
                    pool.install(|| {
                        apply_on_runs(stencil, window, &subdomain.interior, u, lu_interior)
                    })
                });
                let u = &mut run.u;
                pool.install(|| {
                    apply_on_runs(stencil, window, &subdomain.boundary, u, lu_boundary)
                });
                let local_max = pool.install(|| match &run.source {
                    Some(source) => {
                        let (alpha, beta) = Source::coefficients(k as f64 * dt);
                        update(&run.placed_runs, u, &lu, dt, |i, l| {
                            l + alpha * source.phi[i] + beta * source.psi[i]
                        })
                    }
                    None => update(&run.placed_runs, u, &lu, dt, |_, l| l),
                });
                let reduce_started = Instant::now();
                let max_abs = all_max(world, local_max);
                comm_s += reduce_started.elapsed().as_secs_f64();
                if is_sampled(plan.steps, k) {
                    comm_seconds.push(comm_s);
                }
                max_abs
            },
            |run, steps_done| {
                if track_total_error {
                    error_total += run.squared_error(steps_done as f64 * dt);
                }
            },
        );
        let (steps_done, diverged_at) = (timing.steps_done, timing.diverged_at);

        let t_final = steps_done as f64 * dt;
        let u_owned = self.owned_values();
        let phi = self.phi();
        let errors = match (&self.source, diverged_at) {
            (Some(_), None) => Some((
                self.squared_error(t_final),
                all_max(
                    world,
                    pool.install(|| {
                        diagnostics::max_error(manufactured_solution(phi, t_final), &u_owned)
                    }),
                ),
            )),
            _ => None,
        };
        Measured {
            setup_s: all_max(world, setup_s),
            solve_s: all_max(world, timing.solve_seconds),
            step_s: all_max(world, median(timing.step_seconds)),
            steps_done,
            diverged_at,
            divergence_bound,
            errors,
            error_total: (track_total_error && diverged_at.is_none()).then_some(error_total),
            mass: all_sum(
                world,
                pool.install(|| diagnostics::total_mass(&u_owned, self.volume)),
            ),
            max_abs: all_max(world, pool.install(|| diagnostics::max_abs(&u_owned))),
            // Refused for ranks > 1 by the case's validation.
            c_tot: None,
            histogram: None,
            field: None,
            distribution: distribution(world, case, ownership, subdomain, median(comm_seconds)),
        }
    }

    fn phi(&self) -> &[f64] {
        self.source.as_ref().map_or(&[], |s| &s.phi)
    }

    /// The owned values in compact order.
    fn owned_values(&self) -> Vec<f64> {
        let window = &self.subdomain.window;
        self.subdomain
            .runs()
            .flat_map(|run| {
                let start = window.index(run.x0, run.y);
                self.u[start..start + run.len()].iter().copied()
            })
            .collect()
    }

    /// eᵏ at time t, summed over ranks.
    fn squared_error(&self, t: f64) -> f64 {
        let u = self.owned_values();
        let (phi, volume) = (self.phi(), self.volume);
        let local = self
            .pool
            .install(|| diagnostics::squared_l2_error(manufactured_solution(phi, t), &u, volume));
        all_sum(self.world, local)
    }

    /// The whole field on rank 0 (None elsewhere), assembled from every rank's owned values.
    fn gather_field(&self, ownership: &Ownership) -> Option<Vec<f64>> {
        let world = self.world;
        let nodes: Vec<u64> = self
            .subdomain
            .node_indices(ownership.grid.n)
            .into_iter()
            .map(|i| i as u64)
            .collect();
        let values = self.owned_values();
        if world.rank() != 0 {
            let root = world.process_at_rank(0);
            root.send(&nodes[..]);
            root.send(&values[..]);
            return None;
        }
        let mut field = vec![0.0; ownership.grid.nodes()];
        let mut place = |nodes: &[u64], values: &[f64]| {
            for (&i, &v) in nodes.iter().zip(values) {
                field[i as usize] = v;
            }
        };
        place(&nodes, &values);
        for r in 1..world.size() {
            let source = world.process_at_rank(r);
            let (nodes, _) = source.receive_vec::<u64>();
            let (values, _) = source.receive_vec::<f64>();
            place(&nodes, &values);
        }
        Some(field)
    }
}

/// uᵢ += dt · rate(i, (L_h u)ᵢ) on the owned nodes (i their compact index), in fixed chunks of the
/// window; returns max |uᵢ| after the update (+∞ if any is NaN).
fn update(
    placed_runs: &[(usize, RowRun)],
    u: &mut [f64],
    lu: &[f64],
    dt: f64,
    rate: impl Fn(usize, f64) -> f64 + Sync,
) -> f64 {
    u.par_chunks_mut(BLOCK)
        .enumerate()
        .map(|(c, chunk)| {
            let (c0, c1) = (c * BLOCK, c * BLOCK + chunk.len());
            let first = placed_runs.partition_point(|(place, run)| place + run.len() <= c0);
            let mut chunk_max: f64 = 0.0;
            for (place, run) in placed_runs[first..]
                .iter()
                .take_while(|(place, _)| *place < c1)
            {
                for w in (*place).max(c0)..(place + run.len()).min(c1) {
                    let i = run.offset + (w - place);
                    let ui = &mut chunk[w - c0];
                    *ui += dt * rate(i, lu[i]);
                    chunk_max = chunk_max.max(magnitude(*ui));
                }
            }
            chunk_max
        })
        .reduce(|| 0.0, f64::max)
}
