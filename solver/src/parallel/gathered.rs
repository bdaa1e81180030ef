//! A whole-grid operator applied to a vector spread over ranks: every rank gathers the whole
//! vector, applies the operator to it, and keeps its own nodes' values.
//!
//! The implicit integrators' sine-transform preconditioner runs this way over ranks in 1D, where
//! the row of n values is small whatever the case (n = 10⁶ is 8 MB) and its transform costs
//! O(n log n) against the O(n m) of the operator the CG iteration also applies; in 2D it runs on
//! slabs of rows (`slab_sine`). The gather is one all-reduce of the grid's values per application
//! (each value summed with zeros, so exact). Every rank gets the bits of the serial
//! preconditioner.

use crate::operator::LinearOperator;
use crate::parallel::exchange::Ranks;
use rayon::prelude::*;

pub struct Gathered<'a, P: LinearOperator> {
    whole: &'a P,
    /// The grid index of each of this rank's values, in its compact order.
    nodes: Vec<usize>,
    len: usize,
    ranks: Ranks<'a>,
}

/// The whole grid's input and output, and the operator's workspace.
pub struct GatheredWorkspace<W> {
    input: Vec<f64>,
    output: Vec<f64>,
    whole: W,
}

impl<'a, P: LinearOperator + Sync> Gathered<'a, P> {
    /// `whole` acts on the `len` values of the grid; this rank holds those at `nodes`.
    pub fn new(whole: &'a P, nodes: Vec<usize>, len: usize, ranks: Ranks<'a>) -> Self {
        Gathered {
            whole,
            nodes,
            len,
            ranks,
        }
    }
}

impl<P: LinearOperator + Sync> LinearOperator for Gathered<'_, P>
where
    P::Workspace: Send,
{
    type Workspace = GatheredWorkspace<P::Workspace>;

    fn workspace(&self) -> Self::Workspace {
        GatheredWorkspace {
            input: vec![0.0; self.len],
            output: vec![0.0; self.len],
            whole: self.whole.workspace(),
        }
    }

    fn apply(&self, u: &[f64], out: &mut [f64], work: &mut Self::Workspace) {
        let GatheredWorkspace {
            input,
            output,
            whole,
        } = work;
        let (nodes, operator) = (&self.nodes, self.whole);
        self.ranks.on(|| {
            input.par_iter_mut().for_each(|v| *v = 0.0);
            for (&i, &v) in nodes.iter().zip(u) {
                input[i] = v;
            }
        });
        self.ranks.exchange.all_sum(input);
        self.ranks.on(|| {
            operator.apply(input, output, whole);
            out.par_iter_mut()
                .zip(nodes)
                .for_each(|(o, &i)| *o = output[i]);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::operator::LinearOperator;

    /// Reverses a vector: an operator whose every output depends on another node's input.
    struct Reverse;

    impl LinearOperator for Reverse {
        type Workspace = ();
        fn workspace(&self) {}
        fn apply(&self, u: &[f64], out: &mut [f64], _: &mut ()) {
            out.iter_mut()
                .zip(u.iter().rev())
                .for_each(|(o, &v)| *o = v);
        }
    }

    /// On one rank holding a permutation of the grid's nodes, each value lands where the whole
    /// operator puts it.
    #[test]
    fn a_rank_gets_the_whole_operators_values_at_its_nodes() {
        let nodes = [3, 0, 4, 1, 2];
        let u: Vec<f64> = nodes.iter().map(|&i| 10.0 + i as f64).collect();
        let gathered = Gathered::new(&Reverse, nodes.to_vec(), 5, Ranks::single());
        let mut out = vec![0.0; 5];
        gathered.apply_once(&u, &mut out);
        let expected: Vec<f64> = nodes.iter().map(|&i| 10.0 + (4 - i) as f64).collect();
        assert_eq!(out, expected);
    }
}
