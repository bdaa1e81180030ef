//! The ends of L_h's spectrum measured once per study, not once per worker: a stability
//! search's probes differ in the step alone, and the ends serve every step and integrator of
//! the operator, so every process of the study (the workers of one machine, of every node of a
//! job, of the jobs of later rounds) takes them from one entry per operator in the directory
//! `configure` names (`nlsolve run --spectra DIR`, or the line `nlsolve serve` reads), and this
//! process remembers them besides.
//!
//! An entry is distrusted like a record: it is read only as a regular file (never through a
//! link) of at most `MOST_BYTES`, its CRC-32 must hold over every byte before it, and it must
//! name this build's fingerprint and the operator asked for (a foreign entry whose name
//! collides is not believed); anything else is measured again and replaced. It is written
//! under a name of the writer's own and renamed into place, so a reader sees a whole entry or
//! none. While a process measures an operator it holds the entry's lock (`<entry>.lock`,
//! `flock`), so a second process asking for it waits and then reads the entry instead of
//! measuring it too; a process that dies lets go of its lock.
//!
//! A measurement allowed k Lanczos iterations serves another allowed k' when they give the
//! same bits: k = k', or ends that settled at one of the regular looks (every `CHECK_EVERY`
//! iterations) before both caps, which the other cap reaches through the same looks. Those are
//! kept under the operator; ends a cap cut short under the operator and the cap.

use crate::linalg::lanczos::{End, Ends, CHECK_EVERY};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// What one measurement of an operator found: its ends and the applications they took (None:
/// the operator is not symmetric, or a value was not finite), and the iterations it was
/// allowed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measurement {
    pub found: Option<(Ends, usize)>,
    pub iterations: usize,
}

impl Measurement {
    /// Whether a measurement allowed `iterations` gives these bits (`settled`: the stop test
    /// it ran with).
    pub fn serves(&self, iterations: usize, settled: &dyn Fn(&Ends) -> bool) -> bool {
        self.iterations == iterations || self.settled_early(settled).is_some_and(|j| j < iterations)
    }

    /// The iteration the ends settled at, where that was one of the regular looks before the
    /// cap: the ends then serve any cap beyond it.
    fn settled_early(&self, settled: &dyn Fn(&Ends) -> bool) -> Option<usize> {
        let (ends, _) = self.found?;
        let j = ends.applications;
        (settled(&ends) && j % CHECK_EVERY == 0 && j < self.iterations).then_some(j)
    }
}

/// The entry an ill-formed file may claim to be is refused past this size.
pub const MOST_BYTES: u64 = 4096;

/// The first line of an entry.
const MAGIC: &str = "nlsolve spectrum 1\n";

/// The directory of the study's entries, when one was given.
static DIRECTORY: Mutex<Option<PathBuf>> = Mutex::new(None);

/// What this process measured or read, by operator.
static REMEMBERED: Mutex<BTreeMap<String, Measurement>> = Mutex::new(BTreeMap::new());

/// The runs to come share their spectra through `dir` (`None`: this process alone).
pub fn configure(dir: Option<PathBuf>) {
    *DIRECTORY.lock().unwrap_or_else(|e| e.into_inner()) = dir;
}

/// The ends of operator `key` as a measurement allowed `iterations` gives them: remembered by
/// this process, read from the study's entry, or measured by `measure` (and kept in both).
/// Ends that settled early are kept under the operator, for every cap; ends a cap cut short,
/// under the operator and that cap (a search's integrators ask for several caps in turn).
pub fn measured_once(
    key: &str,
    iterations: usize,
    settled: &dyn Fn(&Ends) -> bool,
    measure: impl FnOnce() -> Option<(Ends, usize)>,
) -> Option<(Ends, usize)> {
    let capped = format!("{key} cap {iterations}");
    let serving = |m: &Measurement| m.serves(iterations, settled);
    let remembered = |k: &str| {
        let remembered = REMEMBERED.lock().ok()?;
        remembered.get(k).copied().filter(serving)
    };
    if let Some(known) = remembered(key).or_else(|| remembered(&capped)) {
        return known.found;
    }
    let dir = DIRECTORY.lock().unwrap_or_else(|e| e.into_inner()).clone();
    // Made by the first run that measures a spectrum: a study without one has no directory.
    // One level only: a directory whose parent is gone is not made again.
    if let Some(dir) = &dir {
        let _ = std::fs::create_dir(dir);
    }
    let entries = dir
        .as_deref()
        .map(|dir| (Entry::of(dir, key), Entry::of(dir, &capped)));
    // Held until the entry is written: another process waits, then reads it.
    let _lock = entries.as_ref().and_then(|(entry, _)| entry.lock());
    let read = entries.as_ref().and_then(|(entry, capped_entry)| {
        (entry.read(key).filter(serving).map(|m| (key, m)))
            .or_else(|| Some((capped.as_str(), capped_entry.read(&capped).filter(serving)?)))
    });
    let (under, measurement) = match read {
        Some(read) => read,
        None => {
            let measurement = Measurement {
                found: measure(),
                iterations,
            };
            let early = measurement.settled_early(settled).is_some();
            let under = if early { key } else { capped.as_str() };
            let entry = entries
                .as_ref()
                .map(|(general, cut)| if early { general } else { cut });
            // Not written, not shared: the next process measures it again.
            let _ = entry.map(|e| e.write(under, &measurement));
            (under, measurement)
        }
    };
    if let Ok(mut remembered) = REMEMBERED.lock() {
        remembered.insert(under.to_string(), measurement);
    }
    measurement.found
}

/// An operator's entry in the study's directory: its file and the file its writer locks.
struct Entry {
    path: PathBuf,
    lock: PathBuf,
}

impl Entry {
    /// The entry of `key` in `dir`, named by a hash of this build's fingerprint and the key.
    fn of(dir: &Path, key: &str) -> Entry {
        let name = format!(
            "{:016x}",
            fnv1a(&[fingerprint().as_bytes(), b"\n", key.as_bytes()])
        );
        Entry {
            path: dir.join(format!("{name}.spectrum")),
            lock: dir.join(format!("{name}.lock")),
        }
    }

    /// The lock of the entry, held (None where it cannot be taken: then processes may measure
    /// the operator side by side, each for itself).
    fn lock(&self) -> Option<File> {
        use std::os::unix::fs::OpenOptionsExt;
        let file = File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .custom_flags(libc::O_NOFOLLOW)
            .open(&self.lock)
            .ok()?;
        file.lock().ok()?;
        Some(file)
    }

    /// The measurement the entry holds for `key`, if it is whole, this build's, and `key`'s.
    fn read(&self, key: &str) -> Option<Measurement> {
        let bytes = schema::regular::read(&self.path, MOST_BYTES, "a spectrum entry").ok()?;
        parse(&bytes, key)
    }

    /// Writes `measurement` of `key` whole, in place of whatever stood there.
    fn write(&self, key: &str, measurement: &Measurement) -> std::io::Result<()> {
        let name = self.path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        // The writer's own name, on any node of a shared file system.
        let partial =
            self.path
                .with_file_name(format!(".{name}.{}.{}.partial", host(), std::process::id()));
        schema::atomic::write_through(&partial, &self.path, format(key, measurement).as_bytes())
            .map_err(|(_, e)| e)
    }
}

/// The entry's text: the magic line, this build's fingerprint, the operator, the iterations
/// allowed, the ends (each value as its bits) or `none`, then the CRC-32 of all before it.
pub fn format(key: &str, measurement: &Measurement) -> String {
    let mut text = format!(
        "{MAGIC}fingerprint {}\noperator {}\niterations {}\n",
        fingerprint(),
        key.replace('\n', " "),
        measurement.iterations
    );
    match measurement.found {
        None => text.push_str("ends none\n"),
        Some((ends, applications)) => {
            let bits = |x: f64| format!("{:016x}", x.to_bits());
            let _ = writeln!(
                text,
                "ends {} {} {} {} {} {applications}",
                bits(ends.lowest.ritz),
                bits(ends.lowest.bound),
                bits(ends.highest.ritz),
                bits(ends.highest.bound),
                ends.applications,
            );
        }
    }
    let crc = crc32fast::hash(text.as_bytes());
    let _ = writeln!(text, "crc {crc:08x}");
    text
}

/// The measurement in `bytes` if they are a whole entry of this build for `key`.
pub fn parse(bytes: &[u8], key: &str) -> Option<Measurement> {
    let text = std::str::from_utf8(bytes).ok()?;
    let body_end = text.trim_end_matches('\n').rfind('\n')? + 1;
    let (body, tail) = text.split_at(body_end);
    let crc = u32::from_str_radix(tail.strip_prefix("crc ")?.strip_suffix('\n')?, 16).ok()?;
    if crc != crc32fast::hash(body.as_bytes()) {
        return None;
    }
    let mut lines = body.strip_prefix(MAGIC)?.lines();
    let mut field = |name: &str| lines.next()?.strip_prefix(name)?.strip_prefix(' ');
    if field("fingerprint")? != fingerprint() || field("operator")? != key.replace('\n', " ") {
        return None;
    }
    let iterations = field("iterations")?.parse().ok()?;
    let ends = field("ends")?;
    let found = match ends {
        "none" => None,
        _ => {
            let words: Vec<&str> = ends.split(' ').collect();
            let [a, b, c, d, j, applications] = words[..] else {
                return None;
            };
            let value = |w: &str| u64::from_str_radix(w, 16).ok().map(f64::from_bits);
            let ends = Ends {
                lowest: End {
                    ritz: value(a)?,
                    bound: value(b)?,
                },
                highest: End {
                    ritz: value(c)?,
                    bound: value(d)?,
                },
                applications: j.parse().ok()?,
            };
            // Ends are finite, ordered, with bounds that are bounds: an entry whose CRC was
            // made good over other values is no measurement.
            let bounded = |e: &End| e.ritz.is_finite() && e.bound.is_finite() && e.bound >= 0.0;
            let measured = bounded(&ends.lowest)
                && bounded(&ends.highest)
                && ends.lowest.ritz <= ends.highest.ritz;
            if !measured {
                return None;
            }
            Some((ends, applications.parse().ok()?))
        }
    };
    Some(Measurement { found, iterations })
}

fn fingerprint() -> &'static str {
    crate::output::record::FINGERPRINT
}

/// This node's name, for the names of partial files on a file system several nodes share
/// (the record's host, kept to the characters a file name takes anywhere).
fn host() -> String {
    crate::output::record::host()
        .chars()
        .filter(char::is_ascii_alphanumeric)
        .collect()
}

/// FNV-1a, 64 bits: an entry's name, stable across builds and machines (which std's hasher
/// does not promise).
fn fnv1a(parts: &[&[u8]]) -> u64 {
    parts
        .iter()
        .flat_map(|p| p.iter())
        .fold(0xcbf2_9ce4_8422_2325, |h, &b| {
            (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ends(j: usize) -> Ends {
        Ends {
            lowest: End {
                ritz: -4.0 - 1e-17,
                bound: 3e-11,
            },
            highest: End {
                ritz: -0.1,
                bound: 1e-16,
            },
            applications: j,
        }
    }

    fn settled(e: &Ends) -> bool {
        e.lowest.bound <= 1e-10 * 4.0
    }

    #[test]
    fn an_entry_reads_back_bit_for_bit_and_nothing_else_is_believed() {
        let m = Measurement {
            found: Some((ends(48), 50)),
            iterations: 398,
        };
        let text = format("op grid", &m);
        assert_eq!(parse(text.as_bytes(), "op grid"), Some(m));
        let none = Measurement {
            found: None,
            iterations: 7,
        };
        assert_eq!(parse(format("op", &none).as_bytes(), "op"), Some(none));
        // Another operator's entry (a colliding name), a cut, a changed digit, an empty file.
        assert_eq!(parse(text.as_bytes(), "op other"), None);
        assert_eq!(parse(&text.as_bytes()[..text.len() - 3], "op grid"), None);
        let damaged = text.replacen("iterations 398", "iterations 399", 1);
        assert_eq!(parse(damaged.as_bytes(), "op grid"), None);
        assert_eq!(parse(b"", "op grid"), None);
        // Another build's entry, its CRC made good.
        let foreign = text.replacen(fingerprint(), "0123", 1);
        let body = &foreign[..foreign.rfind("crc ").unwrap()];
        let foreign = format!("{body}crc {:08x}\n", crc32fast::hash(body.as_bytes()));
        assert_eq!(parse(foreign.as_bytes(), "op grid"), None);
    }

    /// Mutated entries (`make test`: 10⁴, half with their CRC made good again, so that the
    /// fields past it are read) never panic the reader, and what it believes is finite and
    /// ordered. The counts are in docs/reliability.md.
    #[test]
    fn fuzz_spectra_entries() {
        let cases: usize = std::env::var("FUZZ_CASES")
            .ok()
            .and_then(|n| n.parse().ok())
            .unwrap_or(10_000);
        let m = Measurement {
            found: Some((ends(48), 50)),
            iterations: 398,
        };
        let corpus = [
            format("op grid", &m),
            format(
                "op grid",
                &Measurement {
                    found: None,
                    iterations: 7,
                },
            ),
        ];
        let mut random = fastrand::Rng::with_seed(0x5eed_f11e);
        let mut believed = 0;
        for _ in 0..cases {
            let mut bytes = corpus[random.usize(..corpus.len())].clone().into_bytes();
            for _ in 0..1 + random.usize(..3) {
                if bytes.is_empty() {
                    break;
                }
                let at = random.usize(..bytes.len());
                match random.usize(..4) {
                    0 => bytes[at] ^= 1 << random.u32(..8),
                    1 => bytes[at] = b"0123456789abcdef -\n."[random.usize(..20)],
                    2 => drop(bytes.drain(at..(at + 1 + random.usize(..8)).min(bytes.len()))),
                    _ => bytes.truncate(at),
                }
            }
            if random.bool() {
                if let Some(crc) = bytes.windows(4).rposition(|w| w == b"crc ") {
                    bytes.truncate(crc);
                    let sum = crc32fast::hash(&bytes);
                    bytes.extend(std::format!("crc {sum:08x}\n").bytes());
                }
            }
            if let Some(Measurement {
                found: Some((e, _)),
                ..
            }) = parse(&bytes, "op grid")
            {
                believed += 1;
                assert!(e.lowest.ritz.is_finite() && e.highest.ritz.is_finite());
                assert!(e.lowest.ritz <= e.highest.ritz && e.lowest.bound >= 0.0);
            }
        }
        println!("fuzz spectra: {cases} cases, {believed} believed");
    }

    /// Ends settled at a regular look before both caps serve any cap beyond them; ends cut
    /// off by a cap, or settled at the cap's own look, serve that cap alone.
    #[test]
    fn a_measurement_serves_the_caps_that_give_its_bits() {
        let settled_early = Measurement {
            found: Some((ends(48), 50)),
            iterations: 398,
        };
        assert!(settled_early.serves(398, &settled));
        assert!(settled_early.serves(1598, &settled));
        assert!(settled_early.serves(49, &settled));
        assert!(!settled_early.serves(48, &settled), "the cap's own look");
        let at_cap = Measurement {
            found: Some((ends(48), 50)),
            iterations: 48,
        };
        assert!(!at_cap.serves(398, &settled));
        let off_look = Measurement {
            found: Some((ends(45), 47)),
            iterations: 398,
        };
        assert!(!off_look.serves(1598, &settled), "an invariant subspace");
        let unsettled = Measurement {
            found: Some((
                Ends {
                    lowest: End {
                        ritz: -4.0,
                        bound: 1.0,
                    },
                    ..ends(48)
                },
                50,
            )),
            iterations: 398,
        };
        assert!(!unsettled.serves(1598, &settled));
        assert!(unsettled.serves(398, &settled));
    }
}
