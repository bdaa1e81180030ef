//! The interface every backend of L_h implements.

pub trait NonlocalOperator: Send + Sync {
    /// out = L_h u on the nodes of D, with u = 0 on the collar (eq. 2.2).
    fn apply(&self, u: &[f64], out: &mut [f64]);
}
