//! The polynomial fields of \[LSSM]'s patch tests and coupling examples, with what the local and
//! the nonlocal operator give on them: u = x, x² and x² − x⁴.
//!
//! With c = k/(ε³ M₂) (eq. 1.5 in 1D, M_i = ∫₀¹ J(r) rⁱ dr) the 1D operator
//! L u(x) = c ∫_{−ε}^{ε} J(|s|/ε)(u(x + s) − u(x)) ds keeps only the even powers of s:
//! L x² = 2c ε³ M₂ = 2k and L x⁴ = 12x² · c ε³ M₂ + 2c ε⁵ M₄ = 12k x² + 2k ε² M₄/M₂
//! (kε² for \[LSSM]'s γ = 1/(ε²|x − y|), J = 1/r, M₄/M₂ = ½: its f_n = −2 + 12x² + ε²).

use crate::case::{Kernel, PatchField};
use crate::discretization::influence::Influence;

pub trait PolynomialField {
    /// u(x).
    fn value(self, x: f64) -> f64;
    /// k u''(x), the local operator.
    fn local_operator(self, x: f64, k: f64) -> f64;
    /// L u(x) for the 1D nonlocal operator of horizon ε with `kernel`, scaled to the limit kΔ.
    fn nonlocal_operator(self, x: f64, k: f64, kernel: Kernel, eps: f64) -> f64;
}

impl PolynomialField for PatchField {
    fn value(self, x: f64) -> f64 {
        match self {
            PatchField::Linear => x,
            PatchField::Quadratic => x * x,
            PatchField::Quartic => x * x - x.powi(4),
        }
    }

    fn local_operator(self, x: f64, k: f64) -> f64 {
        match self {
            PatchField::Linear => 0.0,
            PatchField::Quadratic => 2.0 * k,
            PatchField::Quartic => k * (2.0 - 12.0 * x * x),
        }
    }

    fn nonlocal_operator(self, x: f64, k: f64, kernel: Kernel, eps: f64) -> f64 {
        match self {
            PatchField::Linear | PatchField::Quadratic => self.local_operator(x, k),
            PatchField::Quartic => {
                let quartic =
                    12.0 * k * x * x + 2.0 * k * eps * eps * kernel.moment(4) / kernel.moment(2);
                2.0 * k - quartic
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discretization::influence::scaling_constant;

    /// L u(x) by Gauss–Legendre in s on (0, ε), the even part of u(x + s) − u(x).
    fn by_quadrature(field: PatchField, x: f64, kernel: Kernel, eps: f64, k: f64) -> f64 {
        let c = scaling_constant(1, kernel, eps, k);
        let rule =
            gauss_quad::legendre::GaussLegendre::new(std::num::NonZeroUsize::new(20).unwrap());
        c * rule.integrate(0.0, eps, |s| {
            kernel.influence(s / eps)
                * (field.value(x + s) + field.value(x - s) - 2.0 * field.value(x))
        })
    }

    #[test]
    fn the_closed_forms_are_the_integrals() {
        for kernel in Kernel::ALL {
            for field in [
                PatchField::Linear,
                PatchField::Quadratic,
                PatchField::Quartic,
            ] {
                let (x, eps, k) = (0.37, 0.065, 1.5);
                let want = by_quadrature(field, x, kernel, eps, k);
                let got = field.nonlocal_operator(x, k, kernel, eps);
                assert!(
                    (got - want).abs() < 1e-11 * (1.0 + want.abs()),
                    "{kernel:?} {field:?}: {got} vs {want}"
                );
            }
        }
        // [LSSM]'s Example 2: f_n = −L u = −2 + 12x² + ε².
        let (x, eps) = (0.6, 0.065);
        let f_n = -PatchField::Quartic.nonlocal_operator(x, 1.0, Kernel::InverseDistance, eps);
        assert!((f_n - (-2.0 + 12.0 * x * x + eps * eps)).abs() < 1e-14);
    }
}
