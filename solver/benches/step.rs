//! One step of each operator backend and local method: `cargo bench -p solver --bench step`.
//! Nonlocal backends count bond updates, the local methods nodes, and `copy` the bytes a
//! STREAM-like copy moves, the bandwidth the explicit FD step is read against (it moves 16 bytes
//! per node: u read once, the new field written once). Threads follow RAYON_NUM_THREADS.

use divan::counter::{BytesCount, ItemsCount};
use divan::{black_box, Bencher};
use rayon::prelude::*;
use solver::case::{Backend, Kernel, Quadrature};
use solver::discretization::grid::{Grid, Horizon};
use solver::discretization::stencil::Stencil;
use solver::methods::local::{Adi, ExplicitFd, LocalGrid};
use solver::methods::pse::{Particles, PseOperator};
use solver::operator::{plan, LinearOperator, SinePreconditioner};

fn main() {
    divan::main();
}

/// A field with no structure the backends could exploit.
fn field(len: usize) -> Vec<f64> {
    (0..len)
        .map(|i| ((i * 7919) % 1013) as f64 / 1013.0 - 0.5)
        .collect()
}

/// (n, m): the target (1024, 8), a short and a long horizon, and the largest grid.
const NONLOCAL: [(usize, usize); 4] = [(1024, 1), (1024, 8), (1024, 32), (4096, 8)];

fn nonlocal_step(bencher: Bencher, backend: Backend, n: usize, m: usize) {
    let grid = Grid::new(2, n);
    let horizon = Horizon::from_m(&grid, m);
    let kernel = if m == 1 {
        Kernel::Constant
    } else {
        Kernel::Linear
    };
    let stencil = Stencil::new(grid, horizon, kernel, Quadrature::Midpoint, 1.0);
    let operator = plan(backend, &stencil);
    let u = field(grid.nodes());
    let mut out = vec![0.0; grid.nodes()];
    let mut workspace = operator.workspace();
    bencher
        .counter(ItemsCount::new(stencil.bonds()))
        .bench_local(|| operator.apply(black_box(&u), &mut out, &mut workspace));
}

/// 2D, linear kernel (constant at m = 1, where J = 1 − r has no bond), midpoint weights.
#[divan::bench(args = NONLOCAL)]
fn stencil(bencher: Bencher, (n, m): (usize, usize)) {
    nonlocal_step(bencher, Backend::Stencil, n, m);
}

#[divan::bench(args = NONLOCAL)]
fn fft(bencher: Bencher, (n, m): (usize, usize)) {
    nonlocal_step(bencher, Backend::Fft, n, m);
}

/// The oracle, on a grid small enough for its bond lists.
#[divan::bench(args = [(256, 8)])]
fn neighbour_list(bencher: Bencher, (n, m): (usize, usize)) {
    nonlocal_step(bencher, Backend::NeighbourList, n, m);
}

const LOCAL_N: [usize; 2] = [1024, 4096];

/// The STREAM-like reference: copy one field into another, on every thread.
#[divan::bench(args = LOCAL_N)]
fn copy(bencher: Bencher, n: usize) {
    let u = field(n * n);
    let mut out = vec![0.0; n * n];
    bencher
        .counter(BytesCount::new(16 * n * n))
        .bench_local(|| {
            out.par_chunks_mut(1 << 16)
                .zip(black_box(&u).par_chunks(1 << 16))
                .for_each(|(to, from)| to.copy_from_slice(from))
        });
}

#[divan::bench(args = LOCAL_N)]
fn fd_explicit(bencher: Bencher, n: usize) {
    let grid = LocalGrid::new(2, n, 2.0);
    let fd = ExplicitFd::new(grid, 1.0, 0.2 * grid.h * grid.h);
    let u = field(n * n);
    let mut next = vec![0.0; n * n];
    bencher
        .counter(BytesCount::new(16 * n * n))
        .bench_local(|| fd.step(black_box(&u), &mut next));
}

#[divan::bench(args = LOCAL_N)]
fn adi(bencher: Bencher, n: usize) {
    let grid = LocalGrid::new(2, n, 2.0);
    let adi = Adi::new(grid, 1.0, 10.0 * grid.h * grid.h);
    let mut workspace = adi.workspace();
    let mut u = field(n * n);
    bencher
        .counter(ItemsCount::new(n * n))
        .bench_local(|| adi.step(black_box(&mut u), &mut workspace));
}

/// m = 4: the kernel width ε = 4h.
#[divan::bench(args = [256], sample_count = 10)]
fn pse(bencher: Bencher, n: usize) {
    let length = 2.0;
    let particles = Particles::new(2, n, length, 4.0 * length / n as f64);
    let operator = PseOperator::new(&particles, 1.0);
    let u = field(particles.count());
    let mut rate = vec![0.0; particles.count()];
    let mut workspace = operator.workspace();
    bencher
        .counter(ItemsCount::new(particles.count()))
        .bench_local(|| operator.apply(black_box(&u), &mut rate, &mut workspace));
}

/// The implicit integrators' sine-transform preconditioner (2D, m = 8): n = 2^k, whose DST-I
/// length n + 1 has large prime factors, against n = 2^k − 1.
#[divan::bench(args = [127, 128, 255, 256, 511, 512])]
fn sine_preconditioner(bencher: Bencher, n: usize) {
    let grid = Grid::new(2, n);
    let stencil = Stencil::new(
        grid,
        Horizon::from_m(&grid, 8),
        Kernel::Linear,
        Quadrature::Midpoint,
        1.0,
    );
    let preconditioner = SinePreconditioner::new(&stencil, 1e-4);
    let r = field(grid.nodes());
    let mut out = vec![0.0; grid.nodes()];
    let mut workspace = preconditioner.workspace();
    bencher
        .counter(ItemsCount::new(grid.nodes()))
        .bench_local(|| preconditioner.apply(black_box(&r), &mut out, &mut workspace));
}
