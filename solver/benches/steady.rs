//! FETI's coarse problem at the seed's sizes (`cargo bench -p solver --bench steady`): GᵀG of
//! p × p subdomains at L/p = 288 and m = 4 (\[XGDF]'s largest run: p = 48), factored once
//! and solved twice per projected-CG iteration. What a projection to p = 48 needs and a run on
//! this machine cannot reach; the subdomain products are measured by the `feti` records.

use divan::{black_box, Bencher};
use faer::linalg::solvers::Solve;
use faer::MatMut;
use solver::methods::steady::decomposition::Decomposition;

fn main() {
    divan::main();
}

const SUBDOMAINS_PER_SIDE: [usize; 3] = [12, 24, 48];

fn decomposition(p: usize) -> Decomposition {
    Decomposition::new(288 * p, p, 4)
}

#[divan::bench(args = SUBDOMAINS_PER_SIDE, sample_count = 3)]
fn feti_coarse_factor(bencher: Bencher, p: usize) {
    let decomposition = decomposition(p);
    bencher.bench_local(|| black_box(decomposition.coarse_factor()));
}

#[divan::bench(args = SUBDOMAINS_PER_SIDE)]
fn feti_coarse_solve(bencher: Bencher, p: usize) {
    let decomposition = decomposition(p);
    let factor = decomposition
        .coarse_factor()
        .expect("p ≥ 3 has floating subdomains")
        .expect("GᵀG is definite");
    let nf = decomposition.floating.len();
    let mut v: Vec<f64> = (0..nf).map(|i| (i as f64 * 0.37).sin()).collect();
    bencher.bench_local(|| {
        factor.solve_in_place(MatMut::from_column_major_slice_mut(&mut v, nf, 1));
    });
}
