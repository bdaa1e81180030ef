//! Shared helpers of the end-to-end tests: locate the workspace's binaries and run them as a user
//! or a cluster job would.

use serde_json::Value;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The record's fields that describe the result (timings and provenance left out).
pub use schema::record::RESULTS as RESULT_FIELDS;

/// The variable naming the directory of the workspace's binaries, which `scripts/run-tests` sets
/// (`target/release`): needed when cargo's build directory is apart from its target directory
/// (`.ci/run` keeps the dependencies' builds in one across clones), as the test executables
/// are then in the build directory and the binaries in the target directory.
pub const BINARIES: &str = "NLSTUDY_BINARIES";

/// Path of a workspace binary built in the same profile as this test: in `$NLSTUDY_BINARIES`,
/// else beside the test executable's directory (target/<profile>/<name>).
pub fn binary(name: &str) -> PathBuf {
    let profile_dir = match std::env::var_os(BINARIES) {
        Some(dir) => PathBuf::from(dir),
        None => {
            let exe = std::env::current_exe().expect("test executable path");
            let deps = exe.parent().expect("target/<profile>/deps");
            deps.parent().expect("target/<profile>").to_path_buf()
        }
    };
    let path = profile_dir.join(name);
    assert!(
        path.exists(),
        "{} is not built; run the tests with `make test` (it builds the binaries first; with cargo's build directory apart from its target directory, set {BINARIES} to the binaries' directory)",
        path.display()
    );
    path
}

/// Runs `nlsolve` with `args`, feeding `stdin` if given.
pub fn nlsolve(args: &[&str], stdin: Option<&str>) -> Output {
    let mut child = Command::new(binary("nlsolve"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("nlsolve starts");
    if let Some(text) = stdin {
        child
            .stdin
            .take()
            .unwrap()
            .write_all(text.as_bytes())
            .unwrap();
    }
    drop(child.stdin.take());
    child.wait_with_output().expect("nlsolve finishes")
}

/// The record `nlsolve` printed: exactly one JSON line on stdout.
pub fn record(output: &Output) -> serde_json::Value {
    let stdout = String::from_utf8_lossy(&output.stdout);
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), 1, "expected one record line, got: {stdout}");
    serde_json::from_str(lines[0]).expect("the record is JSON")
}

/// Longest an MPI run of the tests may take before it counts as hung: far beyond the longest's
/// 20-odd seconds on a quiet machine, since its ranks oversubscribe the cores beside the other
/// tests, and a slower machine of this kind took up to three times as long.
const MPI_DEADLINE: Duration = Duration::from_secs(180);

/// How long mpirun may leave an exited rank unreaped before the job counts as Open MPI 4.1's
/// hang, as `nlstudy run` judges it (its `UNREAPED_RANK_GRACE`): the launcher then waits for
/// good.
const UNREAPED_RANK_GRACE: Duration = Duration::from_secs(10);

/// `scripts/mpirun -n ranks <program> <args>`: mpirun set up to run as root and with more ranks
/// than cores. Panics if the job is still running after `MPI_DEADLINE`: a hang is a failure, not
/// a stuck test suite.
pub fn mpirun(ranks: usize, program: &[&str]) -> Output {
    mpirun_with(ranks, program, &[])
}

/// Whether an mpirun's output is Open MPI 4.1's fault at a job's teardown: a rank that ran to
/// its end reported as "exiting improperly" (with "PID 0"), now and then and more often on a
/// loaded machine (open-mpi/ompi issues 7833 and 12607, not fixed on the 4.x branches). The job's
/// results were printed; its exit status is the runtime's.
pub fn open_mpi_teardown_fault(said: &str) -> bool {
    said.contains("with PID 0 on") && said.contains("exiting improperly")
}

/// How an MPI job ended: its output, or the runtime's hang with an exited rank unreaped (the
/// job killed).
enum Ended {
    Output(Output),
    LeftARankUnreaped,
}

/// `mpirun` with extra environment variables (Open MPI reads `OMPI_MCA_*` as its settings). One
/// job at a time: ranks beyond the cores already oversubscribe this machine (a lock within a test
/// binary under `cargo test`; under cargo-nextest, a process per test, the test group `mpi` of
/// .config/nextest.toml). A job that meets Open MPI's teardown fault (`open_mpi_teardown_fault`)
/// or its hang (`UNREAPED_RANK_GRACE`) runs once more, saying so: the fault is the runtime's,
/// and a run of the tests should not fail by it.
pub fn mpirun_with(ranks: usize, program: &[&str], env: &[(&str, &str)]) -> Output {
    static ONE_JOB_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _turn = ONE_JOB_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let fault = match mpirun_once(ranks, program, env) {
        Ended::Output(output) => {
            let stderr = String::from_utf8_lossy(&output.stderr);
            if output.status.success() || !open_mpi_teardown_fault(&stderr) {
                return output;
            }
            format!("met Open MPI's teardown fault:\n{stderr}")
        }
        Ended::LeftARankUnreaped => {
            format!("left an exited rank unreaped for {UNREAPED_RANK_GRACE:?}, Open MPI 4.1's hang")
        }
    };
    eprintln!("mpirun -n {ranks} {program:?} {fault}; run once more");
    match mpirun_once(ranks, program, env) {
        Ended::Output(output) => output,
        Ended::LeftARankUnreaped => {
            panic!("mpirun -n {ranks} {program:?} left an exited rank unreaped twice")
        }
    }
}

fn mpirun_once(ranks: usize, program: &[&str], env: &[(&str, &str)]) -> Ended {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/mpirun");
    let child = Command::new(script)
        .args(["-n", &ranks.to_string()])
        .args(program)
        .envs(env.iter().copied())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("scripts/mpirun starts");
    // (The script execs mpirun: the child is the launcher, the ranks its children.)
    watched(child, &format!("mpirun -n {ranks} {program:?}"))
}

/// The end of the MPI job whose launcher is `child`, watched: killed once it left an exited rank
/// unreaped for `UNREAPED_RANK_GRACE`, or (a panic) once past `MPI_DEADLINE`.
fn watched(child: std::process::Child, job: &str) -> Ended {
    let launcher = child.id();
    let (done, finished) = std::sync::mpsc::channel();
    let waiter = std::thread::spawn(move || {
        let output = child.wait_with_output().expect("mpirun finishes");
        let _ = done.send(());
        output
    });
    let started = Instant::now();
    let mut unreaped_since: Option<Instant> = None;
    while finished.recv_timeout(Duration::from_secs(1)).is_err() {
        let ranks_states = children_of(launcher);
        if ranks_states.iter().any(|&(_, state)| state == 'Z') {
            let since = *unreaped_since.get_or_insert_with(Instant::now);
            if since.elapsed() > UNREAPED_RANK_GRACE {
                kill_job(launcher, &ranks_states);
                let _ = waiter.join();
                return Ended::LeftARankUnreaped;
            }
        } else {
            unreaped_since = None;
        }
        if started.elapsed() > MPI_DEADLINE {
            kill_job(launcher, &ranks_states);
            panic!(
                "{job} did not finish in {MPI_DEADLINE:?}: a hang (its ranks' pids and states: {ranks_states:?})"
            );
        }
    }
    Ended::Output(waiter.join().expect("waiter thread"))
}

/// The children of process `parent` (an MPI launcher's ranks) and their states (`Z`: exited,
/// not reaped).
fn children_of(parent: u32) -> Vec<(u32, char)> {
    processes()
        .filter(|&(_, ppid, _)| ppid == parent)
        .map(|(pid, _, state)| (pid, state))
        .collect()
}

/// Every process's pid, parent's pid and state (`Z`: exited, not reaped), from /proc.
pub fn processes() -> impl Iterator<Item = (u32, u32, char)> {
    std::fs::read_dir("/proc")
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|entry| {
            let pid = entry.file_name().to_str()?.parse::<u32>().ok()?;
            let stat = std::fs::read_to_string(entry.path().join("stat")).ok()?;
            // After the command name's closing parenthesis: the state, then the parent's pid.
            let (_, rest) = stat.rsplit_once(')')?;
            let mut fields = rest.split_whitespace();
            let state = fields.next()?.chars().next()?;
            let ppid = fields.next()?.parse::<u32>().ok()?;
            Some((pid, ppid, state))
        })
}

/// Kills an MPI job: its launcher and its ranks (left alone, they would spin in MPI for good).
fn kill_job(launcher: u32, ranks: &[(u32, char)]) {
    let pids = std::iter::once(launcher).chain(ranks.iter().map(|&(pid, _)| pid));
    let _ = Command::new("kill")
        .arg("-9")
        .args(pids.map(|pid| pid.to_string()))
        .status();
}

/// A field written by `nlsolve run --write-field`: little-endian f64 in node order.
pub fn read_field(path: &std::path::Path) -> Vec<f64> {
    std::fs::read(path)
        .unwrap_or_else(|e| panic!("cannot read field {}: {e}", path.display()))
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
        .collect()
}

/// A scratch directory with a study file; removed when dropped.
pub struct Scratch {
    pub dir: PathBuf,
    _removed_on_drop: tempfile::TempDir,
}

impl Scratch {
    pub fn new(name: &str, study: &Value) -> Scratch {
        let temporary = tempfile::Builder::new()
            .prefix(&format!("nlstudy-{name}-"))
            .tempdir()
            .expect("scratch directory");
        let scratch = Scratch {
            dir: temporary.path().to_path_buf(),
            _removed_on_drop: temporary,
        };
        scratch.write_study(study);
        scratch
    }

    pub fn write_study(&self, study: &Value) {
        std::fs::write(self.study(), study.to_string()).expect("study file");
    }

    pub fn study(&self) -> PathBuf {
        self.dir.join("study.json")
    }

    pub fn runs(&self, name: &str) -> PathBuf {
        self.dir.join("results").join(name).join("runs")
    }

    /// `nlstudy <verb> study.json --results <scratch>/results <extra…>`.
    pub fn command(&self, verb: &str, extra: &[&str]) -> Command {
        let mut command = Command::new(binary("nlstudy"));
        command
            .arg(verb)
            .arg(self.study())
            .arg("--results")
            .arg(self.dir.join("results"))
            .args(extra);
        command
    }

    /// That command, run to its end.
    pub fn nlstudy(&self, verb: &str, extra: &[&str]) -> Output {
        self.command(verb, extra).output().expect("nlstudy starts")
    }

    /// That command started in the background, its output captured.
    pub fn spawn(&self, verb: &str, extra: &[&str]) -> std::process::Child {
        self.command(verb, extra)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("nlstudy starts")
    }
}

/// An executable in `dir` that runs `tests/scripts/<script>` with the interpreter itself,
/// without its site packages: a version manager's shim (pyenv's is a bash script) or the site's
/// imports would cost more than the runs.
pub fn python_stub(dir: &Path, script: &str) -> PathBuf {
    let python = Command::new("python3")
        .args(["-c", "import sys; print(sys.executable)"])
        .output()
        .expect("python3 starts");
    let source = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/scripts")
        .join(script);
    let stub = dir.join(script);
    std::fs::write(
        &stub,
        format!(
            "#!/bin/sh\nexec '{}' -S '{}' \"$@\"\n",
            text(&python).trim(),
            source.display()
        ),
    )
    .unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&stub, std::fs::Permissions::from_mode(0o755)).unwrap();
    stub
}

pub fn text(output: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    )
}

/// The keys `nlstudy plan` lists for the study of `scratch`, each once: the points a store
/// should hold records of.
pub fn planned_keys(scratch: &Scratch) -> std::collections::BTreeSet<String> {
    let plan = scratch.nlstudy("plan", &[]);
    String::from_utf8_lossy(&plan.stdout)
        .lines()
        .filter_map(|line| line.split_whitespace().next())
        .filter(|word| word.len() == 32 && word.bytes().all(|b| b.is_ascii_hexdigit()))
        .map(String::from)
        .collect()
}

/// The keys of `records`, each once.
pub fn stored_keys(records: &[Value]) -> std::collections::BTreeSet<String> {
    records
        .iter()
        .map(|r| r["key"].as_str().expect("a key").to_string())
        .collect()
}

/// The stored records, the latest of each key, in key order: read from the store's segments
/// (`runs/segments/*.seg`, frames `nlrecord <seq> <length> <crc32>` and the record) by this
/// reader of their format, and from files of the store's older layout (`runs/<key>.json`).
pub fn records(runs: &Path) -> Vec<Value> {
    let mut latest: std::collections::BTreeMap<String, (u128, Value)> = Default::default();
    let mut keep = |seq: u128, record: Value| {
        let key = record["key"]
            .as_str()
            .expect("a record has its key")
            .to_string();
        if latest.get(&key).is_none_or(|(s, _)| *s < seq) {
            latest.insert(key, (seq, record));
        }
    };
    for segment in segment_files(runs) {
        for (seq, body) in frames(&std::fs::read(&segment).unwrap()) {
            keep(
                seq.into(),
                serde_json::from_slice(&body).expect("whole JSON"),
            );
        }
    }
    for path in files_in(runs) {
        if path.extension().is_some_and(|x| x == "json") {
            let modified = std::fs::metadata(&path).unwrap().modified().unwrap();
            let seq = modified
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap()
                .as_nanos();
            let text = std::fs::read_to_string(&path).unwrap();
            keep(seq, serde_json::from_str(&text).expect("whole JSON"));
        }
    }
    latest.into_values().map(|(_, record)| record).collect()
}

/// The store's segments, in name order.
pub fn segment_files(runs: &Path) -> Vec<PathBuf> {
    let mut paths = files_in(&runs.join("segments"));
    paths.retain(|p| p.extension().is_some_and(|x| x == "seg"));
    paths
}

/// The files in `dir`, in name order (none when it is missing).
fn files_in(dir: &Path) -> Vec<PathBuf> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    paths.retain(|p| p.is_file());
    paths.sort();
    paths
}

/// The whole frames of a segment's bytes, their sequence numbers and bodies; a frame whose
/// length or CRC-32 does not hold ends the reading (a test's segments are not corrupt).
pub fn frames(bytes: &[u8]) -> Vec<(u64, Vec<u8>)> {
    let mut found = Vec::new();
    let mut rest = bytes;
    while let Some(newline) = rest.iter().position(|&b| b == b'\n') {
        let header = std::str::from_utf8(&rest[..newline]).unwrap_or("");
        let fields: Vec<&str> = header.split(' ').collect();
        let ["nlrecord", seq, length, crc] = fields.as_slice() else {
            break;
        };
        let (Ok(seq), Ok(length), Ok(crc)) = (
            seq.parse::<u64>(),
            length.parse::<usize>(),
            u32::from_str_radix(crc, 16),
        ) else {
            break;
        };
        let Some(body) = rest.get(newline + 1..newline + 1 + length) else {
            break;
        };
        if crc32(body) != crc || body.last() != Some(&b'\n') {
            break;
        }
        found.push((seq, body[..length - 1].to_vec()));
        rest = &rest[newline + 1 + length..];
    }
    found
}

/// Rewrites a study's stored records in place, as an editor or a foreign writer would: each
/// record `edit` changes (it returns true) is written back in a frame whose length and CRC-32
/// hold, so the segment grows or shrinks where the frame stood. Returns how many changed.
pub fn edit_records(runs: &Path, mut edit: impl FnMut(&mut serde_json::Value) -> bool) -> usize {
    let mut changed = 0;
    for segment in segment_files(runs) {
        let bytes = std::fs::read(&segment).unwrap();
        let mut out = Vec::with_capacity(bytes.len());
        for (seq, body) in frames(&bytes) {
            let mut record: serde_json::Value = serde_json::from_slice(&body).unwrap();
            let body = match edit(&mut record) {
                true => {
                    changed += 1;
                    record.to_string().into_bytes()
                }
                false => body,
            };
            let mut whole = body;
            whole.push(b'\n');
            out.extend(format!("nlrecord {seq} {} {:08x}\n", whole.len(), crc32(&whole)).bytes());
            out.extend(whole);
        }
        std::fs::write(&segment, out).unwrap();
    }
    changed
}

/// CRC-32 (IEEE, reflected), bit by bit: the check the store's frames carry.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &byte in bytes {
        crc ^= u32::from(byte);
        for _ in 0..8 {
            crc = (crc >> 1) ^ (0xEDB8_8320 & (crc & 1).wrapping_neg());
        }
    }
    !crc
}

/// Debian's Chromium, which `scripts/setup.sh --tests` (run by `make test`) installs.
pub const CHROMIUM: &str = "/usr/bin/chromium";

/// Headless Chromium on `page` with `extra` flags, as root on a machine without a network or a
/// session bus: no sandbox, no GPU, no background connections, a profile of its own.
pub fn chromium(scratch: &Scratch, page: &Path, extra: &[&str]) -> Output {
    assert!(
        Path::new(CHROMIUM).exists(),
        "{CHROMIUM} is missing: `scripts/setup.sh --tests` (run by `make test`) installs Debian's chromium"
    );
    let profile = scratch.dir.join("chromium-profile");
    Command::new(CHROMIUM)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--enable-logging=stderr",
            "--v=0",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(extra)
        .arg(format!("file://{}", page.display()))
        .output()
        .expect("chromium starts")
}

/// A PNG of `page` as Chromium draws it in a window of `size` (`1200,2400`), checked to be one.
pub fn screenshot(scratch: &Scratch, page: &Path, size: &str, extra: &[&str]) -> Vec<u8> {
    let png = scratch.dir.join("screenshot.png");
    let mut flags = vec![
        format!("--screenshot={}", png.display()),
        format!("--window-size={size}"),
    ];
    flags.extend(extra.iter().map(|f| f.to_string()));
    let flags: Vec<&str> = flags.iter().map(String::as_str).collect();
    let shot = chromium(scratch, page, &flags);
    assert!(
        shot.status.success(),
        "{}",
        String::from_utf8_lossy(&shot.stderr)
    );
    let bytes = std::fs::read(&png).expect("the screenshot was saved");
    assert!(bytes.starts_with(b"\x89PNG"), "not a PNG");
    bytes
}

/// The JSON a harness page wrote into its `<pre id="measured">`, from Chromium's `--dump-dom`.
pub fn measured(dom: &str) -> Value {
    let text = dom
        .split("<pre id=\"measured\">")
        .nth(1)
        .and_then(|rest| rest.split("</pre>").next())
        .unwrap_or_else(|| panic!("no measurement in the page: {dom}"))
        .replace("&quot;", "\"")
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&amp;", "&");
    serde_json::from_str(&text)
        .unwrap_or_else(|e| panic!("the page measured nothing ({e}): {text}"))
}

/// A stored record without what measures the run rather than the case: its timings, peak
/// memory and `run_id`, when and under what load it ran, and whether it was resumed from a
/// checkpoint. Two runs of one point share the rest bit for bit, however they ran.
pub fn numbers_of(record: &Value) -> Value {
    let mut record = record.clone();
    let fields = record.as_object_mut().expect("a record is an object");
    for measured in schema::record::columns::TIMINGS.iter().chain(&[
        "peak_memory_bytes",
        "solve_cpu_s_ranks",
        "run_id",
        "resumed_from_step",
        "solve_s_segments",
        "feti_phases",
    ]) {
        fields.remove(*measured);
    }
    if let Some(provenance) = fields.get_mut("provenance").and_then(Value::as_object_mut) {
        for measured in ["timestamp", "load_start", "load_end", "noisy"] {
            provenance.remove(measured);
        }
    }
    record
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A launcher that leaves an exited "rank" unreaped and waits on, as Open MPI 4.1's mpirun
    /// sometimes does, is ended (both killed) instead of waited for until the deadline.
    #[test]
    fn a_launcher_leaving_an_exited_rank_unreaped_is_ended() {
        // The subshell exits at once; `exec` keeps the pid, and sleep never waits for children.
        let launcher = Command::new("sh")
            .args(["-c", "(exit 1) & exec sleep 600"])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let pid = launcher.id();
        assert!(matches!(
            watched(launcher, "a hanging launcher"),
            Ended::LeftARankUnreaped
        ));
        assert!(
            !Path::new(&format!("/proc/{pid}")).exists(),
            "the launcher still runs"
        );
    }
}
