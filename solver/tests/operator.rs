//! The fast backends (stencil, FFT) against the literal Algorithm 1 (neighbour list), and thread
//! independence.

mod common;

use common::{random_field, same_bits};
use solver::case::{Backend, Kernel, Quadrature};
use solver::discretization::grid::{Grid, Horizon};
use solver::discretization::stencil::Stencil;
use solver::operator::{plan, Cost, LinearOperator, Planned};

/// The horizon of a test case, in cells or as a length.
#[derive(Clone, Copy, Debug)]
enum Reach {
    Cells(usize),
    Length(f64),
}

fn operator_pair(
    dim: usize,
    n: usize,
    reach: Reach,
    kernel: Kernel,
    quadrature: Quadrature,
) -> (Stencil, [Planned; 3]) {
    let grid = Grid::new(dim, n);
    let horizon = match reach {
        Reach::Cells(m) => Horizon::from_m(&grid, m),
        Reach::Length(eps) => Horizon::from_eps(&grid, eps),
    };
    let stencil = Stencil::new(grid, horizon, kernel, quadrature, 1.0);
    let backends =
        [Backend::Stencil, Backend::Fft, Backend::NeighbourList].map(|b| plan(b, &stencil));
    (stencil, backends)
}

/// Every dimension, kernel and quadrature.
fn every_operator() -> impl Iterator<Item = (usize, Kernel, Quadrature)> {
    [1, 2].into_iter().flat_map(|dim| {
        Kernel::ALL
            .into_iter()
            .flat_map(move |k| Quadrature::ALL.into_iter().map(move |q| (dim, k, q)))
    })
}

#[test]
fn fast_backends_equal_the_neighbour_list_on_random_fields() {
    for (dim, kernel, quadrature) in every_operator() {
        // ε = m·h for m in {1, 2, 3, 5}; ε between nodes (2.5h); ε = 0.1 with n = 30, where ε/h
        // rounds to 3.0000000000000004 and the bonds at distance 3h must stay in; horizons beyond
        // n/4 and beyond n (bonds that only reach the collar); and in 2D rows longer than the
        // stencil kernel's register block, with a partial block at their end.
        let n = if dim == 1 { 37 } else { 23 };
        let cases = [
            (n, Reach::Cells(1)),
            (n, Reach::Cells(2)),
            (n, Reach::Cells(3)),
            (n, Reach::Cells(5)),
            (n, Reach::Length(2.5 / n as f64)),
            (30, Reach::Length(0.1)),
            (n, Reach::Cells(n / 4 + 3)),
            (n, Reach::Cells(n + 4)),
            (150, Reach::Cells(4)),
        ];
        for (seed, (n, reach)) in cases.into_iter().enumerate() {
            let (stencil, [blocked, fft, oracle]) =
                operator_pair(dim, n, reach, kernel, quadrature);
            let u = random_field(stencil.grid.nodes(), (dim * 100 + seed) as u64);
            let apply = |operator: &Planned| {
                let mut out = vec![0.0; u.len()];
                operator.apply_once(&u, &mut out);
                out
            };
            let expected = apply(&oracle);
            // The oracle sums one term of size ~c V |u_j − u_i| per bond, so its round-off scale
            // is c V · bonds. (Not W: for J = 1 − r and m = 1 every bond has J = 0 and W = 0,
            // while the oracle's J(1 − δ) is a round-off-sized number.) The FFT's error is
            // relative to the largest |L_h u|, which on a random field is of the size of W |u|.
            // Two summation orders differ by some ulps of that scale per bond summed: 10⁻¹²
            // of it leaves a wrong bond (a term of size c V) 10⁸ times over the tolerance.
            let bond_scale = stencil.c * stencil.grid.volume() * stencil.offsets as f64;
            let largest = expected.iter().fold(0.0, |m: f64, v| m.max(v.abs()));
            for (name, operator, tolerance) in [
                ("stencil", &blocked, 1e-12 * bond_scale),
                ("fft", &fft, 1e-11 * largest + 1e-12 * bond_scale),
            ] {
                let worst = apply(operator)
                    .iter()
                    .zip(&expected)
                    .map(|(x, y)| (x - y).abs())
                    .fold(0.0, f64::max);
                assert!(
                    worst <= tolerance,
                    "{name}, {dim}D {kernel:?} {quadrature:?} n={n} {reach:?}: max difference {worst:e} vs tolerance {tolerance:e}"
                );
            }
        }
    }
}

#[test]
fn neighbour_list_holds_the_ball_with_collar_nodes() {
    // m = 2 in 2D: offsets with |o| ≤ 2 are the 12 lattice points of the disc of radius 2 (centre
    // excluded): (±1,0),(0,±1),(±1,±1),(±2,0),(0,±2) → 4 + 4 + 4 = 12.
    let (stencil, _) = operator_pair(
        2,
        10,
        Reach::Cells(2),
        Kernel::Constant,
        Quadrature::Midpoint,
    );
    assert_eq!(stencil.offsets, 12);
    assert_eq!(stencil.bonds(), 100 * 12);
    // m = 3: adds (±2,±1),(±1,±2) (|o|² = 5), (±2,±2) (8 ≤ 9), (±3,0),(0,±3): 12 + 8 + 4 + 4 = 28.
    let (stencil, _) = operator_pair(
        2,
        10,
        Reach::Cells(3),
        Kernel::Constant,
        Quadrature::Midpoint,
    );
    assert_eq!(stencil.offsets, 28);
    let (stencil, _) = operator_pair(
        1,
        10,
        Reach::Cells(3),
        Kernel::Constant,
        Quadrature::Midpoint,
    );
    assert_eq!(stencil.offsets, 6);
}

#[test]
fn operators_kill_constants_away_from_the_collar() {
    // L_h 1 = 0 wherever the ball misses the collar, for every backend (a patch test of order 0).
    for dim in [1, 2] {
        let (stencil, ops) = operator_pair(
            dim,
            20,
            Reach::Cells(3),
            Kernel::Gaussian,
            Quadrature::Midpoint,
        );
        let grid = stencil.grid;
        let u = vec![1.0; grid.nodes()];
        for op in ops {
            let mut out = vec![0.0; u.len()];
            op.apply_once(&u, &mut out);
            for (i, value) in out.iter().enumerate() {
                let x = grid.position(i);
                let interior = (0..dim).all(|a| x[a] > 3.0 * grid.h && x[a] < 1.0 - 3.0 * grid.h);
                if interior {
                    assert!(
                        value.abs() <= 1e-12 * stencil.total_weight,
                        "node {i}: {value}"
                    );
                } else {
                    assert!(
                        *value < 0.0,
                        "node {i} sees the zero collar, so L_h 1 < 0: {value}"
                    );
                }
            }
        }
    }
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    for dim in [1, 2] {
        let n = if dim == 1 { 10_000 } else { 70 };
        let (stencil, ops) = operator_pair(dim, n, Reach::Cells(4), Kernel::Linear, Quadrature::Ac);
        let u = random_field(stencil.grid.nodes(), 7);
        for op in ops {
            // One workspace for every pool: it is reused, and grows when a pool is larger.
            let mut workspace = op.workspace();
            let outputs: Vec<Vec<f64>> = [1, 3, 2, 1]
                .iter()
                .map(|&threads| {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap();
                    let mut out = vec![0.0; u.len()];
                    pool.install(|| op.apply(&u, &mut out, &mut workspace));
                    out
                })
                .collect();
            for out in &outputs[1..] {
                assert!(same_bits(out, &outputs[0]));
            }
        }
    }
}

#[test]
fn a_horizon_landing_on_a_node_keeps_that_node() {
    // ε = 0.1, n = 30: ε/h = 3.0000000000000004 in floating point; the closed ball holds the
    // nodes at distance exactly 3h ([JD] uses |x_j − x_i| ≤ ε), so m = 3 and 6 bonds in 1D.
    let (stencil, _) = operator_pair(
        1,
        30,
        Reach::Length(0.1),
        Kernel::Constant,
        Quadrature::Midpoint,
    );
    assert_eq!((stencil.horizon.m, stencil.offsets), (3, 6));
    let (stencil, _) = operator_pair(
        1,
        40,
        Reach::Length(0.1),
        Kernel::Constant,
        Quadrature::Midpoint,
    );
    assert_eq!((stencil.horizon.m, stencil.offsets), (4, 8));
}

#[test]
fn auto_follows_the_cost_model() {
    // On the model (docs/performance.md), not on a timing: the stencil for m = 1, the FFT for a
    // long horizon, at every grid size of the perf study, and the choice is the cheaper cost.
    for (dim, sizes) in [(1, [1000, 100_000, 1_000_000]), (2, [256, 1024, 4096])] {
        for n in sizes {
            let grid = Grid::new(dim, n);
            let of = |m| {
                Stencil::new(
                    grid,
                    Horizon::from_m(&grid, m),
                    Kernel::Linear,
                    Quadrature::Midpoint,
                    1.0,
                )
            };
            let (short, long) = (of(1), of(if dim == 1 { 400 } else { 32 }));
            assert_eq!(
                solver::operator::resolve(Backend::Auto, &short),
                Backend::Stencil,
                "{dim}D n={n}, m=1"
            );
            assert_eq!(
                solver::operator::resolve(Backend::Auto, &long),
                Backend::Fft,
                "{dim}D n={n}, long horizon"
            );
            // Explicit choices are kept as they are.
            for backend in [Backend::Stencil, Backend::Fft, Backend::NeighbourList] {
                assert_eq!(solver::operator::resolve(backend, &of(1)), backend);
            }
        }
    }
}

/// `auto` against the clock: on a 2D grid where the model predicts one backend 4× or more
/// faster than the other (a horizon of one cell, and of 32), both are timed (the fastest of
/// seven applications each, alternating: a busy machine only ever adds time, and the median of
/// five, of about a millisecond each, could be pushed past the other backend's by a few
/// preemptions) and `auto` must have picked the one measured faster.
#[test]
fn auto_picks_the_backend_measured_faster_where_the_two_differ_widely() {
    let grid = Grid::new(2, 512);
    for m in [1, 32] {
        let stencil = Stencil::new(
            grid,
            Horizon::from_m(&grid, m),
            Kernel::Linear,
            Quadrature::Midpoint,
            1.0,
        );
        let cost = Cost::of_stencil(&stencil);
        let predicted = (cost.fft / cost.stencil).max(cost.stencil / cost.fft);
        assert!(
            predicted >= 4.0,
            "m = {m}: the model predicts only {predicted:.1}x"
        );
        let u = random_field(grid.nodes(), 7);
        let mut out = vec![0.0; grid.nodes()];
        let operators = [Backend::Stencil, Backend::Fft].map(|b| (b, plan(b, &stencil)));
        let mut seconds = [Vec::new(), Vec::new()];
        for _ in 0..7 {
            for (k, (_, operator)) in operators.iter().enumerate() {
                let mut workspace = operator.workspace();
                let started = std::time::Instant::now();
                operator.apply(&u, &mut out, &mut workspace);
                seconds[k].push(started.elapsed().as_secs_f64());
            }
        }
        let fastest = |times: &[f64]| times.iter().copied().fold(f64::INFINITY, f64::min);
        let (stencil_s, fft_s) = (fastest(&seconds[0]), fastest(&seconds[1]));
        let faster = if fft_s < stencil_s {
            Backend::Fft
        } else {
            Backend::Stencil
        };
        eprintln!("m = {m}: stencil {stencil_s:.2e} s, FFT {fft_s:.2e} s");
        assert_eq!(
            solver::operator::resolve(Backend::Auto, &stencil),
            faster,
            "m = {m}: stencil {stencil_s:.2e} s, FFT {fft_s:.2e} s"
        );
    }
}

/// The stencil kernel compiled for each instruction set this processor has (portable, AVX2,
/// AVX-512) gives the same bits: the same operations in the same order per output, no fused
/// multiply–add. Rows longer and shorter than every register block, with partial blocks.
#[test]
fn every_instruction_set_gives_the_portable_kernels_bits() {
    use solver::operator::{InstructionSet, StencilOperator};
    let available = InstructionSet::available();
    assert_eq!(available[0], InstructionSet::Portable);
    assert!(available.contains(&InstructionSet::detected()));
    for (dim, n, m) in [
        (1, 1000, 7),
        (1, 61, 3),
        (2, 150, 4),
        (2, 37, 9),
        (2, 200, 1),
    ] {
        let grid = Grid::new(dim, n);
        let stencil = Stencil::new(
            grid,
            Horizon::from_m(&grid, m),
            Kernel::Linear,
            Quadrature::Ac,
            0.7,
        );
        let u = random_field(grid.nodes(), 7 + n as u64);
        let out = |isa: InstructionSet| {
            let operator = StencilOperator::with_instruction_set(&stencil, isa);
            let mut out = vec![0.0; grid.nodes()];
            operator.apply_once(&u, &mut out);
            out
        };
        let portable = out(InstructionSet::Portable);
        for &isa in &available[1..] {
            let dispatched = out(isa);
            let same = same_bits(&portable, &dispatched);
            assert!(
                same,
                "{isa:?} differs from the portable kernel (dim {dim}, n {n}, m {m})"
            );
        }
    }
}
