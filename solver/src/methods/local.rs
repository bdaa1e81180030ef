//! The local diffusion equation ∂c/∂t = D∇²c of \[HPCSE] on the grid: explicit finite differences
//! and Peaceman–Rachford ADI, on D = (−L/2, L/2)^d with c = 0 on the boundary.
//!
//! The grid has n interior nodes per side, x_i = −L/2 + (i + 1) h with h = L/(n + 1), so the
//! boundary nodes i = −1 and i = n, where c = 0, are not stored.
//!
//! **Von Neumann bound of the explicit scheme.** Forward Euler with the (2d+1)-point Laplacian
//! multiplies the Fourier mode e^{i k·x} by g = 1 − (4 D dt / h²) Σ_a sin²(k_a h/2). The worst
//! mode has every sin² = 1, so g = 1 − 4 d D dt / h², and |g| ≤ 1 requires dt ≤ h² / (2 d D).
//! With zero Dirichlet data the modes are the sines of the grid, whose largest sin² is
//! cos²(π/(2(n+1))) < 1, so the bound is (just) sufficient on the bounded grid too.

use crate::case::ValidCase;
use crate::case::{positive, refuse_given, Case, CaseError, Problem, SourceMode};
use crate::discretization::grid::Lattice;
use crate::integrate::amplification::{amplification, middle_node, positivity};
use crate::integrate::checkpoint::{self, Carried, Checkpointer};
use crate::integrate::stepper::Stepper;
use crate::integrate::timed::{timed_steps_observed, Checkpoints, Stepping, Trajectory};
use crate::operator::InstructionSet;
use crate::output::diagnostics;
use crate::output::outcome::Outcome;
use crate::output::record::Resolved;
use crate::parallel::exchange::Ranks;
use rayon::prelude::*;
use std::borrow::Cow;
use std::f64::consts::PI;
use std::time::Instant;

/// Lines ADI solves side by side: one 64-byte cache line of f64.
const TILE: usize = 8;

/// The rules of `fd_explicit` and `adi`: no horizon, and those of every local method.
pub fn validate(case: &Case) -> Result<(), CaseError> {
    let method = serde_json::to_value(case.method).unwrap_or_default();
    refuse_given(
        &[("m", case.m.is_some()), ("eps", case.eps.is_some())],
        |field| format!("method {method} has no horizon; leave `{field}` out"),
    )?;
    validate_domain(case)
}

/// The rules every local method (FD, ADI, PSE) obeys: \[HPCSE]'s problems on (−L/2, L/2)^d, no
/// source and no nonlocal fields, one rank.
pub(crate) fn validate_domain(case: &Case) -> Result<(), CaseError> {
    let method = serde_json::to_value(case.method).unwrap_or_default();
    if !case.problem.is_local() {
        return Err(CaseError::new(
            "problem",
            format!(
                "method {method} solves `eigenmode` or `square` ([HPCSE]'s setup); set `problem`"
            ),
        ));
    }
    if case.source.is_some_and(|s| s != SourceMode::None) || case.error_total {
        return Err(CaseError::new(
            if case.error_total {
                "error_total"
            } else {
                "source"
            },
            format!("method {method} has no source term and no total error; leave it out"),
        ));
    }
    refuse_given(
        &[
            ("quadrature", !case.quadrature.is_midpoint()),
            ("collar", !case.collar.is_zero()),
            ("integrator", !case.integrator.is_forward_euler()),
        ],
        |_| format!("belongs to the nonlocal method; method {method} has none, leave it out"),
    )?;
    if case.ranks > 1 {
        return Err(CaseError::new(
            "ranks",
            format!("method {method} runs on one rank; use threads"),
        ));
    }
    if let Some(length) = case.length {
        positive("length", length)?;
    }
    Ok(())
}

/// The interior nodes of (−L/2, L/2)^d, n per side.
#[derive(Clone, Copy, Debug)]
pub struct LocalGrid {
    pub dim: usize,
    pub n: usize,
    pub length: f64,
    pub h: f64,
}

impl LocalGrid {
    pub fn new(dim: usize, n: usize, length: f64) -> Self {
        LocalGrid {
            dim,
            n,
            length,
            h: length / (n + 1) as f64,
        }
    }

    pub fn nodes(&self) -> usize {
        self.n.pow(self.dim as u32)
    }

    pub fn volume(&self) -> f64 {
        self.h.powi(self.dim as i32)
    }

    fn coordinate(&self, i: usize) -> f64 {
        -self.length / 2.0 + (i + 1) as f64 * self.h
    }

    /// The coordinates of node `index` (index = iy·n + ix; one coordinate in 1D).
    fn position(&self, index: usize) -> [f64; 2] {
        let (ix, iy) = (index % self.n, index / self.n);
        [self.coordinate(ix), self.coordinate(iy)]
    }

    /// h² / (2 d D): the explicit scheme's stable step (module comment).
    pub fn explicit_dt_stable(&self, diffusivity: f64) -> f64 {
        self.h * self.h / (2.0 * self.dim as f64 * diffusivity)
    }

    /// The initial field of `problem` on the nodes.
    pub fn sample(&self, problem: Problem) -> Vec<f64> {
        (0..self.nodes())
            .into_par_iter()
            .map(|i| initial_value(problem, &self.position(i)[..self.dim], self.length))
            .collect()
    }
}

/// c(x, 0) of a local problem at x ∈ (−L/2, L/2)^d.
pub(crate) fn initial_value(problem: Problem, x: &[f64], length: f64) -> f64 {
    match problem {
        Problem::Eigenmode => x.iter().map(|&s| (PI * s / length).cos()).product(),
        // c = 1 where every |x_a| < L/4 ([HPCSE]), 0 elsewhere.
        _ => f64::from(u8::from(x.iter().all(|s| s.abs() < length / 4.0))),
    }
}

/// The exact eigenmode solution's decay factor at time t: exp(−d π² D t / L²).
pub fn eigenmode_decay(dim: usize, length: f64, diffusivity: f64, t: f64) -> f64 {
    (-(dim as f64) * PI * PI * diffusivity * t / (length * length)).exp()
}

/// Forward Euler on the (2d+1)-point Laplacian, swapping two buffers: each step reads cⁿ and
/// writes cⁿ⁺¹ in one sweep over rows, so the field is never copied. The row sweep is compiled
/// for AVX2 and AVX-512 too and the widest the processor has runs, as the stencil's kernel
/// (`operator::InstructionSet`): the same operations in the same order, so the same bits.
pub struct ExplicitFd {
    grid: LocalGrid,
    /// a = dt D / h².
    a: f64,
    /// The boundary's row of zeros.
    zero_row: Vec<f64>,
    isa: InstructionSet,
}

impl ExplicitFd {
    pub fn new(grid: LocalGrid, diffusivity: f64, dt: f64) -> Self {
        Self::with_instruction_set(grid, diffusivity, dt, InstructionSet::detected())
    }

    /// The same, running `isa`'s row sweep; panics unless the processor has it.
    pub fn with_instruction_set(
        grid: LocalGrid,
        diffusivity: f64,
        dt: f64,
        isa: InstructionSet,
    ) -> Self {
        assert!(
            InstructionSet::available().contains(&isa),
            "this processor cannot run {}",
            isa.name()
        );
        ExplicitFd {
            grid,
            a: dt * diffusivity / (grid.h * grid.h),
            zero_row: vec![0.0; grid.n],
            isa,
        }
    }

    /// next = cⁿ⁺¹ from u = cⁿ; returns max |cⁿ⁺¹|.
    pub fn step(&self, u: &[f64], next: &mut [f64]) -> f64 {
        let (n, a) = (self.grid.n, self.a);
        let across = if self.grid.dim == 2 { a } else { 0.0 };
        next.par_chunks_mut(n)
            .enumerate()
            .map(|(y, out)| {
                let (below, above) = neighbour_rows(u, y, n, &self.zero_row);
                let row = &u[y * n..(y + 1) * n];
                match self.isa {
                    // SAFETY: `with_instruction_set` admits only what the processor has.
                    #[cfg(target_arch = "x86_64")]
                    InstructionSet::Avx512 => unsafe {
                        relax_row_avx512(out, row, below, above, a, across)
                    },
                    #[cfg(target_arch = "x86_64")]
                    InstructionSet::Avx2 => unsafe {
                        relax_row_avx2(out, row, below, above, a, across)
                    },
                    _ => relax_row(out, row, below, above, a, across),
                }
            })
            .reduce(|| 0.0, f64::max)
    }

    fn integrate(&self, u: Vec<f64>, stepping: &Stepping) -> Trajectory {
        let mut state = (u, vec![0.0; self.grid.nodes()]);
        let checkpointer = resumed(&mut state.0, stepping.steps);
        let mut carry =
            |(u, _): &(Vec<f64>, Vec<f64>), carried: &mut Carried| carried.put("field", u.clone());
        let (timing, observed) = timed_steps_observed(
            &mut state,
            stepping,
            |(u, _)| Cow::Borrowed(u),
            |(u, next), _| {
                let max_abs = self.step(u, next);
                std::mem::swap(u, next);
                max_abs
            },
            |_, _| {},
            checkpointer.map(|checkpointer| Checkpoints {
                checkpointer,
                carry: &mut carry,
                on_any_rank: &|holds| holds,
            }),
        );
        Trajectory::observed(state.0, timing, observed)
    }
}

/// The process's checkpointer for a loop of `steps` steps, if any (`checkpoint::take`), with
/// the field `u` of the run it resumes from put in place: the grid methods carry nothing else
/// from step to step.
fn resumed(u: &mut [f64], steps: usize) -> Option<Checkpointer> {
    let checkpointer = checkpoint::take(steps, Some(u.len()))?;
    if let Some(field) = checkpointer.resume.as_ref().and_then(|c| c.values("field")) {
        u.copy_from_slice(field);
    }
    Some(checkpointer)
}

/// The rows below and above row y of a row-major n × n field (in 1D, n × 1), with `zero_row`
/// standing for the boundary where c = 0.
fn neighbour_rows<'a>(
    u: &'a [f64],
    y: usize,
    n: usize,
    zero_row: &'a [f64],
) -> (&'a [f64], &'a [f64]) {
    let rows = u.len() / n;
    let below = if y > 0 {
        &u[(y - 1) * n..y * n]
    } else {
        zero_row
    };
    let above = if y + 1 < rows {
        &u[(y + 1) * n..(y + 2) * n]
    } else {
        zero_row
    };
    (below, above)
}

/// `relax_row` compiled for AVX-512.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn relax_row_avx512(
    out: &mut [f64],
    row: &[f64],
    below: &[f64],
    above: &[f64],
    ax: f64,
    ay: f64,
) -> f64 {
    relax_row(out, row, below, above, ax, ay)
}

/// `relax_row` compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn relax_row_avx2(
    out: &mut [f64],
    row: &[f64],
    below: &[f64],
    above: &[f64],
    ax: f64,
    ay: f64,
) -> f64 {
    relax_row(out, row, below, above, ax, ay)
}

/// out = c + ax δx² c + ay δy² c along one row (c = 0 beyond its ends); returns max |out|. The
/// ends are done apart so that the inner loop has no branch and vectorises.
#[inline(always)]
fn relax_row(out: &mut [f64], row: &[f64], below: &[f64], above: &[f64], ax: f64, ay: f64) -> f64 {
    let n = row.len();
    let (out, below, above) = (&mut out[..n], &below[..n], &above[..n]);
    let value = |x: usize, left: f64, right: f64| {
        let c = row[x];
        c + ax * (left - 2.0 * c + right) + ay * (below[x] - 2.0 * c + above[x])
    };
    if n == 1 {
        out[0] = value(0, 0.0, 0.0);
    } else {
        out[0] = value(0, 0.0, row[1]);
        for x in 1..n - 1 {
            out[x] = value(x, row[x - 1], row[x + 1]);
        }
        out[n - 1] = value(n - 1, row[n - 2], 0.0);
    }
    diagnostics::block_max_abs(out)
}

/// The time step of a grid case, checked as `run` checks it: what `nlsolve check` refuses
/// before anything runs.
pub fn preflight(case: &ValidCase, implicit: bool) -> Result<(), CaseError> {
    let dt_stable =
        LocalGrid::new(case.dim, case.n, case.length()).explicit_dt_stable(case.diffusivity);
    crate::integrate::time_step::time_step(case, dt_stable, implicit).map(drop)
}

/// Runs a grid case (`fd_explicit`, or `adi` when `implicit`).
pub fn run(case: &ValidCase, implicit: bool) -> Result<Outcome, CaseError> {
    let setup_started = Instant::now();
    let grid = LocalGrid::new(case.dim, case.n, case.length());
    let dt_stable = grid.explicit_dt_stable(case.diffusivity);
    let (dt, steps) = crate::integrate::time_step::time_step(case, dt_stable, implicit)?;
    let u0 = grid.sample(case.problem);
    let divergence_bound =
        crate::integrate::time_step::divergence_bound(case, diagnostics::max_abs(&u0), None);
    let setup_s = setup_started.elapsed().as_secs_f64();
    let stepping = Stepping::of_case(case, dt, steps, divergence_bound, grid.volume());
    let mut trajectory = if implicit {
        Adi::new(grid, case.diffusivity, dt).integrate(u0, &stepping)
    } else {
        ExplicitFd::new(grid, case.diffusivity, dt).integrate(u0, &stepping)
    };
    // Untimed, after the run: at the step asked for, before it was lowered to land on t_end.
    if let Some(steps) = case.amplification_steps {
        let (asked, _) = crate::integrate::time_step::requested(case, dt_stable);
        let mut step: Box<dyn Stepper> = match implicit {
            true => Box::new(AdiStepper::new(Adi::new(grid, case.diffusivity, asked))),
            false => Box::new(FdStepper::new(ExplicitFd::new(
                grid,
                case.diffusivity,
                asked,
            ))),
        };
        let (single, nodes) = (Ranks::single(), grid.nodes());
        trajectory.amplification = amplification(step.as_mut(), single, None, nodes, asked, steps);
        let spike = middle_node(grid.dim, grid.n);
        trajectory.positivity = positivity(step.as_mut(), single, None, nodes, asked, spike);
    }
    let resolved = Resolved {
        h: grid.h,
        dt,
        dt_stable,
        // Explicit FD's step is non-negative up to its stability limit, 1 − 2dD dt/h² ≥ 0; each
        // of ADI's half steps multiplies by the inverse of an M-matrix and by I + dt/2 D δ², which
        // is non-negative up to dt = h²/D, 2d times that (sufficient).
        dt_positive: Some(match implicit {
            true => 2.0 * grid.dim as f64 * dt_stable,
            false => dt_stable,
        }),
        steps,
        nodes: grid.nodes(),
        bonds: 2 * grid.dim * grid.nodes(),
        ..Resolved::default()
    };
    let position = |i: usize| grid.position(i);
    Ok(outcome(
        case, resolved, setup_s, &stepping, trajectory, position,
    ))
}

/// Explicit FD as a `Stepper` (the heat problem has no source): what the measurement of the
/// step's amplification steps.
struct FdStepper {
    fd: ExplicitFd,
    next: Vec<f64>,
}

impl FdStepper {
    fn new(fd: ExplicitFd) -> Self {
        let next = vec![0.0; fd.grid.nodes()];
        FdStepper { fd, next }
    }
}

impl Stepper for FdStepper {
    fn step(&mut self, u: &mut [f64], _: f64, _: f64) -> f64 {
        let max_abs = self.fd.step(u, &mut self.next);
        u.copy_from_slice(&self.next);
        max_abs
    }
}

/// ADI as a `Stepper`, likewise.
struct AdiStepper {
    adi: Adi,
    workspace: AdiWorkspace,
}

impl AdiStepper {
    fn new(adi: Adi) -> Self {
        let workspace = adi.workspace();
        AdiStepper { adi, workspace }
    }
}

impl Stepper for AdiStepper {
    fn step(&mut self, u: &mut [f64], _: f64, _: f64) -> f64 {
        self.adi.step(u, &mut self.workspace)
    }
}

/// The outcome of a local run whose node or particle i sits at `position(i)`: errors against
/// the exact eigenmode (when that is the problem), diagnostics and the record.
pub(crate) fn outcome(
    case: &Case,
    resolved: Resolved,
    setup_s: f64,
    stepping: &Stepping,
    trajectory: Trajectory,
    position: impl Fn(usize) -> [f64; 2] + Sync,
) -> Outcome {
    let t_final = trajectory.timing.steps_done as f64 * stepping.dt;
    let decay = eigenmode_decay(case.dim, case.length(), case.diffusivity, t_final);
    let eigenmode = |i: usize| {
        decay * initial_value(Problem::Eigenmode, &position(i)[..case.dim], case.length())
    };
    let exact = (case.problem == Problem::Eigenmode).then_some(&eigenmode);
    let lattice = Lattice {
        dim: case.dim,
        n: case.n,
        origin: position(0)[0],
        spacing: resolved.h,
    };
    crate::integrate::measure::serial_outcome(
        case,
        resolved,
        setup_s,
        stepping,
        trajectory,
        lattice,
        exact.map(|e| e as &(dyn Fn(usize) -> f64 + Sync)),
    )
}

/// Peaceman–Rachford ADI: per step of dt, a half step implicit in x and explicit in y, then one
/// implicit in y and explicit in x, each of dt/2:
///     (1 − ½dt D δx²) c* = (1 + ½dt D δy²) cⁿ,   (1 − ½dt D δy²) cⁿ⁺¹ = (1 + ½dt D δx²) c*.
/// \[HPCSE] writes each half step with Δt; its Δt is our dt/2. In 1D there is no y: the two
/// halves compose to Crank–Nicolson. Both are second order in dt and unconditionally stable.
pub struct Adi {
    grid: LocalGrid,
    /// r = ½ dt D / h².
    r: f64,
    thomas: Thomas,
}

impl Adi {
    pub fn new(grid: LocalGrid, diffusivity: f64, dt: f64) -> Self {
        let r = 0.5 * dt * diffusivity / (grid.h * grid.h);
        Adi {
            grid,
            r,
            thomas: Thomas::new(grid.n, -r, 1.0 + 2.0 * r),
        }
    }

    /// The buffers a step works in, allocated once.
    pub fn workspace(&self) -> AdiWorkspace {
        AdiWorkspace {
            row_tiles: vec![0.0; self.grid.nodes()],
            column_tiles: vec![0.0; self.grid.nodes()],
            zero_row: vec![0.0; self.grid.n],
        }
    }

    /// Steps forward from u, in the shared timed loop.
    fn integrate(&self, mut u: Vec<f64>, stepping: &Stepping) -> Trajectory {
        let mut workspace = self.workspace();
        let checkpointer = resumed(&mut u, stepping.steps);
        let mut carry = |u: &Vec<f64>, carried: &mut Carried| carried.put("field", u.clone());
        let (timing, observed) = timed_steps_observed(
            &mut u,
            stepping,
            |u| Cow::Borrowed(u),
            |u, _| self.step(u, &mut workspace),
            |_, _| {},
            checkpointer.map(|checkpointer| Checkpoints {
                checkpointer,
                carry: &mut carry,
                on_any_rank: &|holds| holds,
            }),
        );
        Trajectory::observed(u, timing, observed)
    }

    /// One step; returns max |cⁿ⁺¹|. Both halves work on TILE lines at a time, interleaved
    /// (element i of line k at i·lanes + k), so that the tile's Thomas solves run in lockstep:
    /// one solve is a chain of dependent multiply-adds, several side by side keep the FPU busy.
    pub fn step(&self, u: &mut [f64], workspace: &mut AdiWorkspace) -> f64 {
        let AdiWorkspace {
            row_tiles,
            column_tiles,
            zero_row,
        } = workspace;
        let (row_tiles, column_tiles, zero_row) =
            (&mut row_tiles[..], &mut column_tiles[..], &zero_row[..]);
        let n = self.grid.n;
        let r = self.r;
        if self.grid.dim == 1 {
            // c* solves the implicit half; cⁿ⁺¹ = (1 + r δx²) c*.
            row_tiles.copy_from_slice(u);
            self.thomas.solve(row_tiles, 1);
            return relax_row(u, row_tiles, zero_row, zero_row, r, 0.0);
        }
        let lanes_of = |tile: usize| TILE.min(n - tile * TILE);
        // Half 1, rows y0 .. y0 + lanes: rhs = (1 + r δy²) cⁿ, then the x-implicit solves.
        row_tiles
            .par_chunks_mut(TILE * n)
            .enumerate()
            .for_each(|(t, tile)| {
                let (y0, lanes) = (t * TILE, lanes_of(t));
                // Row by row, so that u is read in three streams (row tiles are L2-sized).
                for k in 0..lanes {
                    let y = y0 + k;
                    let (below, above) = neighbour_rows(u, y, n, zero_row);
                    let row = &u[y * n..(y + 1) * n];
                    for x in 0..n {
                        tile[x * lanes + k] = row[x] + r * (below[x] - 2.0 * row[x] + above[x]);
                    }
                }
                self.thomas.solve(tile, lanes);
            });
        let half = |y: usize, x: usize| {
            let t = y / TILE;
            row_tiles[t * TILE * n + x * lanes_of(t) + y % TILE]
        };
        // Half 2, columns x0 .. x0 + lanes: rhs = (1 + r δx²) c*, then the y-implicit solves.
        column_tiles
            .par_chunks_mut(TILE * n)
            .enumerate()
            .for_each(|(t, tile)| {
                let (x0, lanes) = (t * TILE, lanes_of(t));
                for y in 0..n {
                    for k in 0..lanes {
                        let x = x0 + k;
                        let left = if x > 0 { half(y, x - 1) } else { 0.0 };
                        let right = if x + 1 < n { half(y, x + 1) } else { 0.0 };
                        tile[y * lanes + k] = half(y, x) + r * (left - 2.0 * half(y, x) + right);
                    }
                }
                self.thomas.solve(tile, lanes);
            });
        // Back to rows, TILE rows at a time: each column tile holds them as one contiguous run.
        u.par_chunks_mut(TILE * n)
            .enumerate()
            .map(|(row_tile, rows)| {
                let y0 = row_tile * TILE;
                let mut max_abs: f64 = 0.0;
                for t in 0..n.div_ceil(TILE) {
                    let (x0, lanes) = (t * TILE, lanes_of(t));
                    let run = &column_tiles[t * TILE * n + y0 * lanes..];
                    for (row, solved) in rows.chunks_mut(n).zip(run.chunks(lanes)) {
                        for (value, &v) in row[x0..x0 + lanes].iter_mut().zip(solved) {
                            *value = v;
                            max_abs = max_abs.max(diagnostics::magnitude(v));
                        }
                    }
                }
                max_abs
            })
            .reduce(|| 0.0, f64::max)
    }
}

/// c* in row tiles, cⁿ⁺¹ in column tiles, and the boundary's zero row.
pub struct AdiWorkspace {
    row_tiles: Vec<f64>,
    column_tiles: Vec<f64>,
    zero_row: Vec<f64>,
}

/// The Thomas algorithm for the constant tridiagonal matrix (a, b, a) of order n with the
/// elimination factors precomputed once, so that a solve is two sweeps over the line and
/// allocates nothing.
pub struct Thomas {
    a: f64,
    /// c'_i of the forward sweep and 1/(b − a c'_{i−1}).
    upper: Vec<f64>,
    inverse_pivot: Vec<f64>,
}

impl Thomas {
    pub fn new(n: usize, a: f64, b: f64) -> Self {
        let mut upper = Vec::with_capacity(n);
        let mut inverse_pivot = Vec::with_capacity(n);
        let mut previous = 0.0;
        for _ in 0..n {
            let pivot = 1.0 / (b - a * previous);
            inverse_pivot.push(pivot);
            previous = a * pivot;
            upper.push(previous);
        }
        Thomas {
            a,
            upper,
            inverse_pivot,
        }
    }

    /// Solves `lanes` systems at once, overwriting their right-hand sides with the solutions;
    /// they are interleaved: d[i·lanes + k] is element i of system k.
    pub fn solve(&self, d: &mut [f64], lanes: usize) {
        let n = d.len() / lanes;
        for value in &mut d[..lanes] {
            *value *= self.inverse_pivot[0];
        }
        for i in 1..n {
            let (done, rest) = d.split_at_mut(i * lanes);
            let previous = &done[(i - 1) * lanes..];
            let pivot = self.inverse_pivot[i];
            for (value, &p) in rest[..lanes].iter_mut().zip(previous) {
                *value = (*value - self.a * p) * pivot;
            }
        }
        for i in (0..n.saturating_sub(1)).rev() {
            let (head, tail) = d.split_at_mut((i + 1) * lanes);
            let upper = self.upper[i];
            for (value, &next) in head[i * lanes..].iter_mut().zip(&tail[..lanes]) {
                *value -= upper * next;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Interleaved solves satisfy each tridiagonal system (a, b, a) to rounding.
    #[test]
    fn thomas_solves_interleaved_systems() {
        let (n, lanes, a, b) = (37, 3, -0.7, 2.9);
        let rhs: Vec<f64> = (0..n * lanes)
            .map(|i| ((i * 37) % 11) as f64 - 5.0)
            .collect();
        let mut x = rhs.clone();
        Thomas::new(n, a, b).solve(&mut x, lanes);
        for k in 0..lanes {
            let at = |i: usize| x[i * lanes + k];
            for i in 0..n {
                let left = if i > 0 { a * at(i - 1) } else { 0.0 };
                let right = if i + 1 < n { a * at(i + 1) } else { 0.0 };
                let residual = left + b * at(i) + right - rhs[i * lanes + k];
                assert!(residual.abs() < 1e-12, "system {k} row {i}: {residual:e}");
            }
        }
    }

    /// Every instruction set's row sweep gives the portable one's bits, and the same maximum,
    /// also for a NaN (counted as +∞) and rows shorter than a vector.
    #[test]
    fn every_instruction_set_gives_the_portable_fd_step_bits() {
        for (dim, n) in [(1, 1001), (2, 3), (2, 130)] {
            let grid = LocalGrid::new(dim, n, 1.0);
            let mut u: Vec<f64> = (0..grid.nodes())
                .map(|i| ((i * 7919) % 101) as f64 / 50.0 - 1.0)
                .collect();
            for nan in [false, true] {
                if nan {
                    u[grid.nodes() / 2] = f64::NAN;
                }
                let step = |isa: InstructionSet| {
                    let dt = 0.2 * grid.explicit_dt_stable(1.0);
                    let mut next = vec![0.0; u.len()];
                    let max =
                        ExplicitFd::with_instruction_set(grid, 1.0, dt, isa).step(&u, &mut next);
                    (next, max)
                };
                let (portable, portable_max) = step(InstructionSet::Portable);
                for &isa in &InstructionSet::available()[1..] {
                    let (next, max) = step(isa);
                    let same = portable
                        .iter()
                        .zip(&next)
                        .all(|(a, b)| a.to_bits() == b.to_bits());
                    assert!(
                        same && max.to_bits() == portable_max.to_bits(),
                        "{isa:?}, {dim}D n = {n}"
                    );
                }
                assert_eq!(nan, portable_max == f64::INFINITY);
            }
        }
    }
}
