//! The moments M_i and the constant c of eq. 1.5, pinned to their formulas.

use gauss_quad::legendre::GaussLegendre;
use solver::case::Kernel;
use solver::discretization::influence::scaling_constant;
use solver::discretization::influence::Influence;
use std::f64::consts::PI;

/// M_i by composite Gauss–Legendre (64 panels × 20 points), independent of the closed forms.
fn moment_by_quadrature(kernel: Kernel, i: i32) -> f64 {
    let rule = GaussLegendre::new(20.try_into().unwrap());
    let panels = 64;
    (0..panels)
        .map(|p| {
            let (a, b) = (p as f64 / panels as f64, (p + 1) as f64 / panels as f64);
            rule.integrate(a, b, |r| kernel.influence(r) * r.powi(i))
        })
        .sum()
}

#[test]
fn moments_match_quadrature_for_every_kernel() {
    for kernel in Kernel::ALL {
        // M_0 of 1/r diverges; every other moment is a proper integral.
        let first = if kernel == Kernel::InverseDistance {
            1
        } else {
            0
        };
        for i in first..=6 {
            let exact = kernel.moment(i as u32);
            let quadrature = moment_by_quadrature(kernel, i);
            assert!(
                (exact - quadrature).abs() <= 1e-13 * exact.abs(),
                "{kernel:?} M_{i}: closed form {exact} vs quadrature {quadrature}"
            );
        }
    }
    assert!(Kernel::InverseDistance.moment(0).is_infinite());
}

#[test]
fn moments_of_seed_000_examples() {
    // [JD], after eq. 1.6: J = 1 gives M_i = 1/(i+1); J = 1 − r gives M_2 = 1/12, M_3 = 1/20.
    for i in 0..6 {
        assert_eq!(Kernel::Constant.moment(i), 1.0 / (i as f64 + 1.0));
    }
    assert_eq!(Kernel::Linear.moment(2), 1.0 / 12.0);
    assert_eq!(Kernel::Linear.moment(3), 1.0 / 20.0);
    // Truncated Gaussian: M_3 = ∫₀¹ e^{−r²} r³ dr = 1/2 − 1/e.
    assert!((Kernel::Gaussian.moment(3) - (0.5 - (-1.0f64).exp())).abs() < 1e-16);
}

#[test]
fn scaling_constant_follows_eq_1_5_exactly() {
    let k = 1.7;
    for kernel in Kernel::ALL {
        for eps in [0.3, 0.05, 1.0 / 7.0] {
            let c1 = scaling_constant(1, kernel, eps, k);
            let c2 = scaling_constant(2, kernel, eps, k);
            let want1 = k / (eps.powi(3) * kernel.moment(2));
            let want2 = 2.0 * k / (PI * eps.powi(4) * kernel.moment(3));
            assert!(
                (c1 - want1).abs() <= 1e-15 * want1,
                "{kernel:?} 1D: {c1} vs {want1}"
            );
            assert!(
                (c2 - want2).abs() <= 1e-15 * want2,
                "{kernel:?} 2D: {c2} vs {want2}"
            );
        }
    }
    // Literal values at ε = 0.3, k = 1 (computed apart, with erf from the C library), so that a
    // wrong moment or a dropped π shows: 1D c is not truncated to an integer (444.44…, not 444),
    // and 2D c has the π that the public HPX code dropped.
    let literal = [
        (
            Kernel::Constant,
            111.111_111_111_111_14,
            314.380_134_502_509_35,
        ),
        (
            Kernel::Linear,
            444.444_444_444_444_57,
            1_571.900_672_512_546_6,
        ),
        (
            Kernel::Gaussian,
            195.474_631_807_885_26,
            594.873_608_789_483_3,
        ),
        (
            Kernel::InverseDistance,
            74.074_074_074_074_09,
            235.785_100_876_882,
        ),
    ];
    for (kernel, want1, want2) in literal {
        let (c1, c2) = (
            scaling_constant(1, kernel, 0.3, 1.0),
            scaling_constant(2, kernel, 0.3, 1.0),
        );
        assert!(
            (c1 - want1).abs() <= 1e-12 * want1,
            "{kernel:?} 1D c = {c1}, want {want1}"
        );
        assert!(
            (c2 - want2).abs() <= 1e-12 * want2,
            "{kernel:?} 2D c = {c2}, want {want2}"
        );
    }
}
