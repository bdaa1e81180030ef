//! Influence functions J(r) on r ∈ [0, 1], their moments M_i = ∫₀¹ J(r) rⁱ dr (\[JD], eq. 1.6),
//! and the scaling constant c of eq. 1.5 that makes the nonlocal operator tend to kΔ as ε → 0.

use crate::case::Kernel;
use std::f64::consts::PI;

/// erf(1), needed in closed form by the truncated Gaussian's even moments.
const ERF_1: f64 = 0.842_700_792_949_714_9;

/// What a kernel choice means: its influence function and moments.
pub trait Influence {
    fn influence(self, r: f64) -> f64;
    fn moment(self, i: u32) -> f64;
}

impl Influence for Kernel {
    /// J(r) for 0 < r ≤ 1. Membership in the ball is the caller's decision, so that a bond at
    /// distance ε up to round-off is weighted by its formula rather than cut to zero.
    #[inline]
    fn influence(self, r: f64) -> f64 {
        match self {
            Kernel::Constant => 1.0,
            Kernel::Linear => 1.0 - r,
            Kernel::Gaussian => (-r * r).exp(),
            Kernel::InverseDistance => 1.0 / r,
        }
    }

    /// M_i = ∫₀¹ J(r) rⁱ dr in closed form.
    ///
    /// Truncated Gaussian: with G_i = ∫₀¹ e^{−r²} rⁱ dr, integration by parts gives
    /// G_i = ((i − 1)/2) G_{i−2} − e^{−1}/2, from G_0 = (√π/2) erf(1) and G_1 = (1 − e^{−1})/2.
    fn moment(self, i: u32) -> f64 {
        let fi = f64::from(i);
        match self {
            Kernel::Constant => 1.0 / (fi + 1.0),
            Kernel::Linear => 1.0 / ((fi + 1.0) * (fi + 2.0)),
            Kernel::InverseDistance => {
                if i == 0 {
                    f64::INFINITY
                } else {
                    1.0 / fi
                }
            }
            Kernel::Gaussian => {
                let e = (-1.0f64).exp();
                let mut g = if i.is_multiple_of(2) {
                    0.5 * PI.sqrt() * ERF_1
                } else {
                    0.5 * (1.0 - e)
                };
                let mut j = i % 2;
                while j < i {
                    j += 2;
                    g = 0.5 * f64::from(j - 1) * g - 0.5 * e;
                }
                g
            }
        }
    }
}

/// The constant c of eq. 1.5: k/(ε³ M₂) in 1D and 2k/(π ε⁴ M₃) in 2D.
///
/// Pinned to the formula by a test: the public HPX code of \[JD] drops the π in 2D and
/// truncates c to an integer in 1D, which changes the limit the scheme converges to.
pub fn scaling_constant(dim: usize, kernel: Kernel, eps: f64, diffusivity: f64) -> f64 {
    match dim {
        1 => diffusivity / (eps.powi(3) * kernel.moment(2)),
        2 => 2.0 * diffusivity / (PI * eps.powi(4) * kernel.moment(3)),
        _ => unreachable!("dimension is validated to be 1 or 2"),
    }
}
