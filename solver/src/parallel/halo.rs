//! The halo exchange of a rank's subdomain: each step the owned values its neighbours need go
//! out and its ghosts come in, non-blocking, while computation that needs no ghost runs.

use crate::parallel::subdomain::Neighbour;
use mpi::point_to_point::Source as _;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::time::Instant;

/// The halo of one rank: per neighbour, a buffer of the values it sends and one for those it
/// receives, allocated once.
pub(crate) struct HaloExchange<'a> {
    neighbours: &'a [Neighbour],
    send: Vec<Vec<f64>>,
    receive: Vec<Vec<f64>>,
}

impl<'a> HaloExchange<'a> {
    pub(crate) fn new(neighbours: &'a [Neighbour]) -> Self {
        HaloExchange {
            neighbours,
            send: neighbours
                .iter()
                .map(|nb| vec![0.0; nb.send.len()])
                .collect(),
            receive: neighbours
                .iter()
                .map(|nb| vec![0.0; nb.receive.len()])
                .collect(),
        }
    }

    /// Sends the owned values other ranks need and receives the ghosts into `u`, running
    /// `overlap` (which must not read ghosts) while the messages are in flight. Returns the
    /// seconds spent on the exchange itself, `overlap` excluded.
    pub(crate) fn exchange(
        &mut self,
        world: &SimpleCommunicator,
        u: &mut [f64],
        overlap: impl FnOnce(&[f64]),
    ) -> f64 {
        let started = Instant::now();
        for (nb, buffer) in self.neighbours.iter().zip(&mut self.send) {
            for (b, &w) in buffer.iter_mut().zip(&nb.send) {
                *b = u[w];
            }
        }
        let mut overlap_s = 0.0;
        let (send, receive) = (&self.send, &mut self.receive);
        let neighbours = self.neighbours;
        mpi::request::scope(|scope| {
            let mut requests = Vec::with_capacity(2 * neighbours.len());
            for (nb, buffer) in neighbours.iter().zip(receive.iter_mut()) {
                let from = world.process_at_rank(nb.rank as i32);
                requests.push(from.immediate_receive_into(scope, &mut buffer[..]));
            }
            for (nb, buffer) in neighbours.iter().zip(send) {
                let to = world.process_at_rank(nb.rank as i32);
                requests.push(to.immediate_send(scope, &buffer[..]));
            }
            let overlap_started = Instant::now();
            overlap(u);
            overlap_s = overlap_started.elapsed().as_secs_f64();
            for request in requests {
                request.wait();
            }
        });
        for (nb, buffer) in self.neighbours.iter().zip(&self.receive) {
            for (&w, &b) in nb.receive.iter().zip(buffer) {
                u[w] = b;
            }
        }
        started.elapsed().as_secs_f64() - overlap_s
    }
}
