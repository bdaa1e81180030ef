use super::*;

#[test]
fn fold_mirrors_oddly_across_both_faces() {
    assert_eq!(fold(-1, 4), (0, -1.0));
    assert_eq!(fold(4, 4), (3, -1.0));
    assert_eq!(fold(-5, 4), (3, 1.0));
    assert_eq!(fold(9, 4), (1, 1.0));
}

/// The rates equal eq. (2) evaluated literally: every particle against every lattice point
/// of the odd extension, with the kernel of eq. (3), no cutoff and no cell list.
#[test]
fn rates_equal_the_literal_sum_of_eq_2_over_the_odd_extension() {
    let (length, diffusivity) = (2.0, 0.7);
    for (dim, n, eps) in [(1, 30, 0.15), (2, 10, 0.3), (2, 7, 0.11)] {
        let particles = Particles::new(dim, n, length, eps);
        let field: Vec<f64> = (0..particles.count())
            .map(|i| ((i * 7919) % 101) as f64 / 50.0 - 1.0)
            .collect();
        let mut rates = vec![0.0; particles.count()];
        PseOperator::new(&particles, diffusivity).apply_once(&field, &mut rates);

        let h = length / n as f64;
        let volume = h.powi(dim as i32);
        let eta = |r2: f64| {
            4.0 / (PI.powf(dim as f64 / 2.0) * eps.powi(dim as i32)) * (-r2 / (eps * eps)).exp()
        };
        let wide = 3 * n as isize;
        let coordinate = |i: isize| -length / 2.0 + (i as f64 + 0.5) * h;
        let rows: Vec<isize> = if dim == 2 {
            (-wide..n as isize + wide).collect()
        } else {
            vec![0]
        };
        let mut largest: f64 = 0.0;
        for (i, &phi_i) in field.iter().enumerate() {
            let xi = particles.lattice_position(i);
            let mut literal = 0.0;
            for &jy in &rows {
                for jx in -wide..n as isize + wide {
                    let (sx, fx) = fold(jx, n);
                    let (sy, fy) = if dim == 2 { fold(jy, n) } else { (0, 1.0) };
                    let phi_j = fx * fy * field[sy * n + sx];
                    let yj = if dim == 2 { coordinate(jy) } else { 0.0 };
                    let r2 = (coordinate(jx) - xi[0]).powi(2) + (yj - xi[1]).powi(2);
                    literal += volume * (phi_j - phi_i) * eta(r2);
                }
            }
            literal *= diffusivity / (eps * eps);
            let ours = rates[i];
            largest = largest.max(literal.abs());
            assert!(
                (ours - literal).abs() <= 1e-12 * largest.max(1.0),
                "dim {dim} n {n} particle {i}: {ours} vs {literal}"
            );
        }
    }
}

fn case(dim: usize, n: usize, eps: f64) -> Case {
    Case::parse(serde_json::json!({
        "method": "pse", "problem": "eigenmode", "dim": dim, "n": n, "eps": eps,
        "t_end": 0.01, "cfl": 0.5
    }))
    .unwrap()
}

/// A cutoff below h is refused by `validate`, before `Particles::new` would bin the lattice
/// into some 10¹⁷ cells.
#[test]
fn a_kernel_narrower_than_the_spacing_is_refused_by_validation() {
    for dim in [1, 2] {
        let refusal = validate(&case(dim, 100, 1e-9)).unwrap_err();
        assert_eq!(refusal.field, "eps", "{refusal}");
        assert!(validate(&case(dim, 100, 0.02)).is_ok());
    }
}

/// The memory estimate counts the slots `Particles::new` makes (at 80 bytes each, give or
/// take the images it drops): a wide kernel's images, not the n^d particles, dominate.
#[test]
fn the_memory_estimate_counts_particles_and_images() {
    for (dim, n, eps) in [(1, 200, 0.05), (2, 40, 0.1), (2, 64, 1.0)] {
        let slots = Particles::new(dim, n, 2.0, eps).slots() as f64;
        let bytes = memory_bytes(&case(dim, n, eps));
        assert!(
            bytes >= 64.0 * slots && bytes <= 128.0 * slots,
            "dim {dim} n {n} ε {eps}: {bytes:e} bytes for {slots} slots"
        );
    }
    let wide = memory_bytes(&case(2, 64, 1.0));
    assert!(wide > 50.0 * 4.0 * 64.0 * 64.0 * 8.0, "{wide:e}");
}

/// The cell-list sweep visits every pair with a real particle within r_c exactly once:
/// compare with all pairs by brute force, images included.
#[test]
fn cell_lists_find_every_pair_within_the_cutoff_once() {
    for (dim, n, eps) in [(1, 40, 0.1), (2, 12, 0.2), (2, 9, 0.05), (2, 5, 0.9)] {
        let particles = Particles::new(dim, n, 2.0, eps);
        let reals = particles.count();
        let slots = particles.position.len();
        let brute = (0..slots)
            .flat_map(|i| (i + 1..slots).map(move |j| (i, j)))
            .filter(|&(i, j)| i < reals || j < reals)
            .filter(|&(i, j)| particles.distance_squared(i, j) < particles.cutoff_squared)
            .count();
        assert_eq!(
            particles.count_pairs().1,
            brute,
            "dim {dim} n {n} eps {eps}"
        );
    }
}
