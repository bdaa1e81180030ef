//! The interface every linear operator of the solver implements: the backends of L_h, the
//! distributed operator over ranks, PSE's particle sum and the implicit integrators'
//! preconditioner.
//!
//! Scratch space is the caller's (as with faer's `LinOp` or rustfft's scratch buffers): made once
//! by `workspace`, passed to every `apply`, so an operator is shared freely between threads and
//! applying it never locks or allocates.

pub trait LinearOperator {
    /// Buffers one application writes between its input and its output.
    type Workspace;

    fn workspace(&self) -> Self::Workspace;

    /// out = L u (for L_h: on the nodes of D, with u = 0 on the collar, eq. 2.2).
    fn apply(&self, u: &[f64], out: &mut [f64], workspace: &mut Self::Workspace);

    /// One application with a workspace of its own, for callers that apply once.
    fn apply_once(&self, u: &[f64], out: &mut [f64]) {
        self.apply(u, out, &mut self.workspace());
    }
}

/// No operator at all, z = r: the preconditioner of a CG with none.
pub struct Identity;

impl LinearOperator for Identity {
    type Workspace = ();

    fn workspace(&self) {}

    fn apply(&self, r: &[f64], z: &mut [f64], _: &mut ()) {
        z.copy_from_slice(r);
    }
}
