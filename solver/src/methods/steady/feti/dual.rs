//! The layout of the multipliers: each subdomain's local copy of every multiplier it touches
//! (λ_n = R^D_n λ), and the exchange that sums a partner's contribution on each interface.

use crate::methods::steady::decomposition::Decomposition;
use crate::parallel::exchange::Exchange;
use std::collections::BTreeMap;

/// Where each owned subdomain's multipliers sit in the rank's dual vectors, and who adds what.
pub(super) struct DualLayout {
    pub(super) offsets: Vec<usize>,
    /// Interfaces between two owned subdomains: (start in one, start in the other, length).
    pub(super) local_pairs: Vec<(usize, usize, usize)>,
    /// Per other rank: its number and the blocks (start, length) it shares, in the order both
    /// sides agree on (by the pair of subdomain numbers).
    pub(super) peers: Vec<usize>,
    pub(super) peer_blocks: Vec<Vec<(usize, usize)>>,
}

/// A block of multipliers a peer rank also holds: the subdomain pair of its interface, and its
/// start and length in this rank's vector.
type RemotePair = ((usize, usize), usize, usize);

impl DualLayout {
    pub(super) fn new(
        decomposition: &Decomposition,
        owned: &[usize],
        rank: usize,
        ranks: usize,
    ) -> Self {
        let mut offsets = vec![0];
        for &n in owned {
            offsets.push(offsets.last().unwrap() + decomposition.subdomains[n].multipliers());
        }
        let start_of = |n: usize| offsets[n - owned[0]];
        let mut local_pairs = Vec::new();
        let mut remote: BTreeMap<usize, Vec<RemotePair>> = BTreeMap::new();
        for &n in owned {
            for interface in &decomposition.subdomains[n].interfaces {
                let start = start_of(n) + interface.offset;
                let len = interface.nodes.len();
                let other = interface.other;
                let owner = decomposition.owner(other, ranks);
                if owner == rank {
                    if n < other {
                        let back = decomposition.subdomains[other]
                            .interfaces
                            .iter()
                            .find(|i| i.other == n)
                            .expect("interfaces come in pairs");
                        local_pairs.push((start, start_of(other) + back.offset, len));
                    }
                } else {
                    let key = (n.min(other), n.max(other));
                    remote.entry(owner).or_default().push((key, start, len));
                }
            }
        }
        let mut peers = Vec::new();
        let mut peer_blocks = Vec::new();
        for (peer, mut blocks) in remote {
            blocks.sort_unstable_by_key(|&(key, _, _)| key);
            peers.push(peer);
            peer_blocks.push(blocks.into_iter().map(|(_, s, l)| (s, l)).collect());
        }
        DualLayout {
            offsets,
            local_pairs,
            peers,
            peer_blocks,
        }
    }

    pub(super) fn len(&self) -> usize {
        *self.offsets.last().unwrap()
    }

    /// Each owned subdomain's part of a dual vector.
    pub(super) fn split<'v>(&self, x: &'v mut [f64]) -> Vec<&'v mut [f64]> {
        let mut parts = Vec::with_capacity(self.offsets.len() - 1);
        let mut rest = x;
        for window in self.offsets.windows(2) {
            let (part, tail) = rest.split_at_mut(window[1] - window[0]);
            parts.push(part);
            rest = tail;
        }
        parts
    }

    /// x ← the sum of both subdomains' contributions on every interface (the R^D exchange).
    pub(super) fn interface_sum(&self, exchange: &dyn Exchange, x: &mut [f64]) {
        for &(a, b, len) in &self.local_pairs {
            for i in 0..len {
                let sum = x[a + i] + x[b + i];
                x[a + i] = sum;
                x[b + i] = sum;
            }
        }
        if self.peers.is_empty() {
            return;
        }
        let send: Vec<Vec<f64>> = self
            .peer_blocks
            .iter()
            .map(|blocks| {
                blocks
                    .iter()
                    .flat_map(|&(s, l)| x[s..s + l].iter().copied())
                    .collect()
            })
            .collect();
        let mut receive: Vec<Vec<f64>> = send.iter().map(|b| vec![0.0; b.len()]).collect();
        exchange.swap(&self.peers, &send, &mut receive);
        for (blocks, received) in self.peer_blocks.iter().zip(&receive) {
            let mut at = 0;
            for &(s, l) in blocks {
                for i in 0..l {
                    x[s + i] += received[at + i];
                }
                at += l;
            }
        }
    }
}
