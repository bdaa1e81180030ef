//! `nlsolve serve --connect HOST:PORT`: a worker on another node of an allocation serves the
//! pool that started it over a TCP connection of its own instead of its standard input and
//! output. A scheduler's forwarding of a step's standard streams costs tens of milliseconds
//! per answer (Slurm 22.05 splits a line into 1024-byte messages, and Nagle's algorithm holds
//! the last one until the first is acknowledged, which the other side delays by 40 ms); the
//! connection sends each answer at once (`TCP_NODELAY`).

use crate::ErrorExit;
use clap::Args;
use schema::protocol::{SERVE_TOKEN_ENV, SERVE_TOKEN_MOST_BYTES};
use std::io::Write;
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

#[derive(Args)]
pub(crate) struct ServeArgs {
    /// Serve the pool listening at HOST:PORT over a connection of its own, which opens with the
    /// token in $NLSOLVE_SERVE_TOKEN, rather than over standard input and output (what `nlstudy`
    /// starts on another node of an allocation).
    #[arg(long, value_name = "HOST:PORT")]
    pub connect: Option<String>,
}

/// How long each address of the pool is tried.
const DIAL_TIMEOUT: Duration = Duration::from_secs(20);

/// The connection to the pool at `address`, opened with this worker's token.
pub(crate) fn dial(address: &str) -> Result<TcpStream, ErrorExit> {
    let token = std::env::var(SERVE_TOKEN_ENV).map_err(|_| {
        ErrorExit::BadInput(format!(
            "--connect needs the pool's token in ${SERVE_TOKEN_ENV}, which is not set"
        ))
    })?;
    if token.is_empty() || token.len() >= SERVE_TOKEN_MOST_BYTES || token.contains('\n') {
        return Err(ErrorExit::BadInput(format!(
            "${SERVE_TOKEN_ENV} is not a token (one line of at most {} bytes)",
            SERVE_TOKEN_MOST_BYTES - 1
        )));
    }
    let unreachable =
        |why: String| ErrorExit::Output(format!("cannot reach the pool at {address}: {why}"));
    let candidates = address.to_socket_addrs().map_err(|e| {
        ErrorExit::BadInput(format!("--connect {address:?}: not a HOST:PORT ({e})"))
    })?;
    let mut last = String::from("no address");
    for candidate in candidates {
        match TcpStream::connect_timeout(&candidate, DIAL_TIMEOUT) {
            Ok(mut stream) => {
                stream
                    .set_nodelay(true)
                    .and_then(|()| stream.write_all(format!("{token}\n").as_bytes()))
                    .map_err(|e| unreachable(e.to_string()))?;
                return Ok(stream);
            }
            Err(e) => last = format!("{candidate}: {e}"),
        }
    }
    Err(unreachable(last))
}
