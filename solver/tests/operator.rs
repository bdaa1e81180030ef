//! The stencil backend against the literal Algorithm 1 (neighbour list), and thread independence.

mod common;

use common::random_field;
use solver::grid::{Grid, Horizon};
use solver::influence::{scaling_constant, Kernel};
use solver::operator::{plan, Backend, NonlocalOperator};
use solver::stencil::Stencil;

fn operator_pair(
    dim: usize,
    n: usize,
    m: usize,
    kernel: Kernel,
) -> (Stencil, [Box<dyn NonlocalOperator>; 2]) {
    let grid = Grid::new(dim, n);
    let horizon = Horizon::from_m(&grid, m);
    let c = scaling_constant(dim, kernel, horizon.eps, 1.0);
    let stencil = Stencil::new(grid, &horizon, kernel, c);
    let backends =
        [Backend::Stencil, Backend::NeighbourList].map(|b| plan(b, &stencil, &horizon, kernel, c));
    (stencil, backends)
}

#[test]
fn stencil_equals_neighbour_list_on_random_fields() {
    for dim in [1, 2] {
        for kernel in Kernel::ALL {
            for m in [1, 2, 3, 5] {
                let n = if dim == 1 { 37 } else { 23 };
                let (stencil, [fast, oracle]) = operator_pair(dim, n, m, kernel);
                let u = random_field(stencil.grid.nodes(), (dim * 100 + m) as u64);
                let (mut a, mut b) = (vec![0.0; u.len()], vec![0.0; u.len()]);
                fast.apply(&u, &mut a);
                oracle.apply(&u, &mut b);
                // Both sum one term of size ~c V |u_j − u_i| per bond: the round-off scale is
                // c V · bonds. (Not W: for J = 1 − r and m = 1 every bond has J = 0 and W = 0, while
                // the oracle's J(1 − δ) is a round-off-sized number.)
                let c = scaling_constant(dim, kernel, stencil.grid.h * m as f64, 1.0);
                let scale = c * stencil.grid.volume() * stencil.offsets as f64;
                let worst = a
                    .iter()
                    .zip(&b)
                    .map(|(x, y)| (x - y).abs())
                    .fold(0.0, f64::max);
                assert!(
                    worst <= 1e-13 * scale,
                    "{dim}D {kernel:?} m={m}: max difference {worst:e} vs scale {scale:e}"
                );
            }
        }
    }
}

#[test]
fn neighbour_list_holds_the_ball_with_collar_nodes() {
    // m = 2 in 2D: offsets with |o| ≤ 2 are the 12 lattice points of the disc of radius 2 (centre
    // excluded): (±1,0),(0,±1),(±1,±1),(±2,0),(0,±2) → 4 + 4 + 4 = 12.
    let (stencil, _) = operator_pair(2, 10, 2, Kernel::Constant);
    assert_eq!(stencil.offsets, 12);
    assert_eq!(stencil.bonds(), 100 * 12);
    // m = 3: adds (±2,±1),(±1,±2) (|o|² = 5), (±2,±2) (8 ≤ 9), (±3,0),(0,±3): 12 + 8 + 4 + 4 = 28.
    let (stencil, _) = operator_pair(2, 10, 3, Kernel::Constant);
    assert_eq!(stencil.offsets, 28);
    let (stencil, _) = operator_pair(1, 10, 3, Kernel::Constant);
    assert_eq!(stencil.offsets, 6);
}

#[test]
fn operators_kill_constants_away_from_the_collar() {
    // L_h 1 = 0 wherever the ball misses the collar, for every backend (a patch test of order 0).
    for dim in [1, 2] {
        let (stencil, ops) = operator_pair(dim, 20, 3, Kernel::Gaussian);
        let grid = stencil.grid;
        let u = vec![1.0; grid.nodes()];
        for op in ops {
            let mut out = vec![0.0; u.len()];
            op.apply(&u, &mut out);
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
        let (stencil, ops) = operator_pair(dim, n, 4, Kernel::Linear);
        let u = random_field(stencil.grid.nodes(), 7);
        for op in ops {
            let outputs: Vec<Vec<f64>> = [1, 2, 3]
                .iter()
                .map(|&threads| {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap();
                    let mut out = vec![0.0; u.len()];
                    pool.install(|| op.apply(&u, &mut out));
                    out
                })
                .collect();
            for out in &outputs[1..] {
                assert!(out
                    .iter()
                    .zip(&outputs[0])
                    .all(|(a, b)| a.to_bits() == b.to_bits()));
            }
        }
    }
}
