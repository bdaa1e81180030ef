//! One step of each operator backend and local method, reported per second of bond updates (or
//! node updates) by divan: `cargo bench -p solver --bench step`. Threads follow RAYON_NUM_THREADS.

use divan::counter::ItemsCount;
use divan::Bencher;
use solver::grid::{Grid, Horizon};
use solver::influence::Kernel;
use solver::operator::{plan, Backend};
use solver::quadrature::Quadrature;
use solver::stencil::Stencil;

fn main() {
    divan::main();
}

/// A field with no structure the backends could exploit.
fn field(len: usize) -> Vec<f64> {
    (0..len)
        .map(|i| ((i * 7919) % 1013) as f64 / 1013.0 - 0.5)
        .collect()
}

fn nonlocal_step(bencher: Bencher, backend: Backend, n: usize, m: usize) {
    let grid = Grid::new(2, n);
    let horizon = Horizon::from_m(&grid, m);
    let stencil = Stencil::new(grid, horizon, Kernel::Linear, Quadrature::Midpoint, 1.0);
    let operator = plan(backend, &stencil);
    let u = field(grid.nodes());
    let mut out = vec![0.0; grid.nodes()];
    bencher
        .counter(ItemsCount::new(stencil.bonds()))
        .bench_local(|| operator.apply(divan::black_box(&u), &mut out));
}

/// 2D, linear kernel, midpoint weights; the counter is bond updates.
#[divan::bench(args = [(1024, 1), (1024, 8), (1024, 32), (4096, 8)])]
fn stencil(bencher: Bencher, (n, m): (usize, usize)) {
    nonlocal_step(bencher, Backend::Stencil, n, m);
}
