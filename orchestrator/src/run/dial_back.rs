//! Workers on other nodes of an allocation answer over a TCP connection of their own
//! (`nlsolve serve --connect`), not through the job step's standard streams: Slurm forwards a
//! step's output in 1024-byte messages, and Nagle's algorithm holds the rest of a longer line
//! until the first message is acknowledged, which the receiver delays by 40 ms. A record is
//! about 1.7 kB, so every answer took about 44 ms, more than most probes of a stability map.
//! Over its own connection (`TCP_NODELAY`) an answer takes a fraction of a millisecond.
//!
//! The pool listens on its node's address (the one the scheduler knows the node by) at a port
//! the kernel picks. Each worker gets a token of 128 random bits in its environment, opens its
//! connection with it, and is matched to its worker by it; a connection without a token the
//! pool is waiting for is closed unread.

use schema::protocol::SERVE_TOKEN_MOST_BYTES;
use std::collections::HashMap;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{IpAddr, Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How long a connection may take to say its token.
const TOKEN_WITHIN: Duration = Duration::from_secs(10);

/// A line a worker said, or `None` once its answers ended (what `worker::Said` carries).
pub type Heard = (u64, Option<String>);

/// The pool's side of one worker's connection: what was sent before it connected, and the
/// stream once it has.
#[derive(Default)]
pub struct Dial {
    queued: Vec<u8>,
    stream: Option<TcpStream>,
    /// When it connected: the worker's start is over.
    pub connected_at: Option<Instant>,
    /// The pool has no more cases for it: its input is closed, or will be as it connects.
    closed: bool,
    /// Its process ended before it connected: a connection with its token is refused.
    gone: bool,
}

impl Dial {
    /// Sends `line` now, or once the worker connects; false when the connection failed.
    pub fn send(&mut self, line: &[u8]) -> bool {
        match &mut self.stream {
            Some(stream) => stream.write_all(line).is_ok(),
            None => {
                self.queued.extend_from_slice(line);
                true
            }
        }
    }

    /// No more cases: the worker reads the end of its input and exits.
    pub fn close(&mut self) {
        self.closed = true;
        if let Some(stream) = &self.stream {
            let _ = stream.shutdown(Shutdown::Write);
        }
    }

    /// Marks a worker whose process ended as gone; true when it had never connected (its
    /// answers end here, not at the end of a connection).
    pub fn ended_unconnected(&mut self) -> bool {
        let never = self.stream.is_none();
        self.gone |= never;
        never
    }
}

/// A worker the listener waits for.
struct Awaited {
    worker: u64,
    dial: Arc<Mutex<Dial>>,
    said: Sender<Heard>,
}

/// The pool's listening socket and the workers it waits for, by token.
pub struct Listener {
    /// Where workers connect: `HOST:PORT`.
    pub address: SocketAddr,
    awaited: Arc<Mutex<HashMap<String, Awaited>>>,
}

impl Listener {
    /// Listens on `ip` at a port the kernel picks; accepts in a thread of its own.
    pub fn bind(ip: IpAddr) -> std::io::Result<Listener> {
        let socket = TcpListener::bind((ip, 0))?;
        let address = socket.local_addr()?;
        let awaited: Arc<Mutex<HashMap<String, Awaited>>> = Arc::default();
        let waiting = Arc::clone(&awaited);
        std::thread::spawn(move || {
            for stream in socket.incoming().flatten() {
                let waiting = Arc::clone(&waiting);
                std::thread::spawn(move || admit(stream, &waiting));
            }
        });
        Ok(Listener { address, awaited })
    }

    /// Waits for worker `worker`'s connection: returns its token (for its environment) and its
    /// side of the connection. Its lines go to `said`.
    pub fn expect(&self, worker: u64, said: Sender<Heard>) -> (String, Arc<Mutex<Dial>>) {
        let token = token();
        let dial: Arc<Mutex<Dial>> = Arc::default();
        let awaited = Awaited {
            worker,
            dial: Arc::clone(&dial),
            said,
        };
        lock(&self.awaited).insert(token.clone(), awaited);
        (token, dial)
    }
}

/// Reads a connection's token; hands the connection to the worker it names, then reads its
/// answers until it closes. A connection that names none, or names it too slowly, is closed.
fn admit(stream: TcpStream, awaited: &Mutex<HashMap<String, Awaited>>) {
    let _ = stream.set_read_timeout(Some(TOKEN_WITHIN));
    let Some(token) = first_line(&stream) else {
        return;
    };
    let Some(worker) = lock(awaited).remove(&token) else {
        return;
    };
    let _ = stream.set_read_timeout(None);
    let _ = stream.set_nodelay(true);
    {
        let mut dial = lock(&worker.dial);
        if dial.gone || (dial.closed && dial.queued.is_empty()) {
            // Its process ended, or it was let go, before it called.
            return;
        }
        let Ok(mut writer) = stream.try_clone() else {
            return;
        };
        if writer.write_all(&dial.queued).is_err() {
            return;
        }
        dial.queued.clear();
        if dial.closed {
            let _ = writer.shutdown(Shutdown::Write);
        }
        dial.stream = Some(writer);
        dial.connected_at = Some(Instant::now());
    }
    for line in BufReader::new(stream).lines() {
        let Ok(line) = line else { break };
        if worker.said.send((worker.worker, Some(line))).is_err() {
            return;
        }
    }
    let _ = worker.said.send((worker.worker, None));
}

/// The connection's first line without its newline, read a byte at a time so that nothing
/// after it is taken; `None` past `SERVE_TOKEN_MOST_BYTES`, at its end or on an error.
fn first_line(mut stream: &TcpStream) -> Option<String> {
    let mut line = Vec::new();
    let mut byte = [0u8; 1];
    while line.len() < SERVE_TOKEN_MOST_BYTES {
        stream.read_exact(&mut byte).ok()?;
        if byte[0] == b'\n' {
            return String::from_utf8(line).ok();
        }
        line.push(byte[0]);
    }
    None
}

/// 128 random bits from the kernel, as hex.
fn token() -> String {
    let mut bytes = [0u8; 16];
    let read = std::fs::File::open("/dev/urandom").and_then(|mut f| f.read_exact(&mut bytes));
    read.expect("the kernel's random source (/dev/urandom) is readable");
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn lock<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(|e| e.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc::channel;

    /// A worker's side: connects, says `token`, and gives back what it reads.
    fn call(listener: &Listener, token: &str) -> TcpStream {
        let mut stream = TcpStream::connect(listener.address).unwrap();
        stream.write_all(format!("{token}\n").as_bytes()).unwrap();
        stream
    }

    /// A case sent before the worker connects reaches it once it does; its answers come to the
    /// pool as lines of its id, then the end of them; closing its input ends its connection.
    /// A connection with a token the pool does not wait for (or none) is closed unread.
    #[test]
    fn a_worker_is_matched_by_its_token_and_a_stranger_is_closed() {
        let listener = Listener::bind("127.0.0.1".parse().unwrap()).unwrap();
        let (said, heard) = channel();
        let (token, dial) = listener.expect(7, said);
        assert_eq!(token.len(), 32, "{token}");
        assert!(lock(&dial).send(b"{\"case\": 1}\n"));

        let mut stranger = call(&listener, "0123");
        let mut read = Vec::new();
        stranger.read_to_end(&mut read).unwrap();
        assert!(read.is_empty(), "a stranger was sent {read:?}");

        let worker = call(&listener, &token);
        let mut lines = BufReader::new(worker.try_clone().unwrap()).lines();
        assert_eq!(lines.next().unwrap().unwrap(), "{\"case\": 1}");
        assert!(lock(&dial).connected_at.is_some());
        (&worker).write_all(b"{\"answer\": 1}\n").unwrap();
        let within = Duration::from_secs(10);
        assert_eq!(
            heard.recv_timeout(within).unwrap(),
            (7, Some("{\"answer\": 1}".to_string()))
        );
        // The token was used: a second caller with it is a stranger.
        let mut again = call(&listener, &token);
        let mut read = Vec::new();
        again.read_to_end(&mut read).unwrap();
        assert!(read.is_empty());

        lock(&dial).close();
        assert!(lines.next().is_none(), "its input did not end");
        worker.shutdown(Shutdown::Write).unwrap();
        assert_eq!(heard.recv_timeout(within).unwrap(), (7, None));
    }

    /// A worker whose process ended before it connected is refused if it calls after all.
    #[test]
    fn a_worker_that_ended_unconnected_is_refused() {
        let listener = Listener::bind("127.0.0.1".parse().unwrap()).unwrap();
        let (said, _heard) = channel();
        let (token, dial) = listener.expect(1, said);
        assert!(lock(&dial).send(b"{}\n"));
        assert!(lock(&dial).ended_unconnected());
        let mut late = call(&listener, &token);
        let mut read = Vec::new();
        late.read_to_end(&mut read).unwrap();
        assert!(read.is_empty(), "{read:?}");
    }
}
