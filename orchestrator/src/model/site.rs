//! Site profiles: what one cluster needs in every job script, written once per cluster rather
//! than by hand in each script. A TOML (or JSON) file chosen by `submit --site NAME` or the
//! environment variable `NLSTUDY_SITE`: the scheduler, the partition, account, QoS, constraint,
//! memory and exclusive nodes, the modules to load, prologue lines, the MPI launcher, the cores
//! of a node, a default wall time and the warning before the time limit.
//!
//! Every value is checked where it is read, against what its place in the script accepts; the
//! prologue alone is shell code by design (the profile's author writes it, as they would in a
//! script), one line each.

use super::launcher::Launcher;
use super::resources::{Resources, Scheduler, SchedulerName, WallTime};
use schema::json::is_unsafe_char;
use serde::Deserialize;
use std::num::NonZeroUsize;
use std::path::{Path, PathBuf};

/// The environment variable naming the site profile when `--site` is not given.
pub const SITE_VARIABLE: &str = "NLSTUDY_SITE";
/// The environment variable naming a folder of site profiles (`NAME.toml`), searched first.
pub const SITES_VARIABLE: &str = "NLSTUDY_SITES";

/// A cluster's profile.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Site {
    /// Where the profile was read from (for the sentences that cite it).
    #[serde(skip)]
    pub file: PathBuf,
    pub scheduler: Option<Scheduler>,
    /// Slurm partition or LSF queue.
    pub queue: Option<SchedulerName>,
    /// Slurm account or LSF project.
    pub account: Option<SchedulerName>,
    /// Slurm's quality of service (`--qos`); LSF has none.
    pub qos: Option<SchedulerName>,
    /// Slurm's node features (`--constraint`, e.g. `cpu&ib`); LSF selects with `directives`.
    pub constraint: Option<Constraint>,
    /// Whole nodes for each job (`--exclusive`, `-x`); default: exclusive unless the study
    /// shares the machine (`share_machine`), since timings need the node to themselves.
    pub exclusive: Option<bool>,
    /// Memory per node (`--mem`, LSF `rusage[mem=…]`): megabytes, or a number with K, M, G or T;
    /// `0` asks Slurm for all of a node's memory.
    pub memory: Option<Memory>,
    /// Cores of one node: a job whose tasks × threads exceed it asks for more nodes.
    pub cores_per_node: Option<NonZeroUsize>,
    /// The wall time of a job when neither `--time`, the study nor stored timings give one.
    pub time: Option<WallTime>,
    /// How long before its time limit a job is sent SIGTERM, so it stops cleanly (Slurm's
    /// `--signal=B:TERM@…`, LSF's `-wa TERM -wt …`); default one minute. A job whose limit is
    /// under four times it is not warned (Slurm may send it a minute early).
    pub warning: Option<WallTime>,
    /// Whether the scheduler may requeue a job after a preemption or a node failure (Slurm's
    /// `--requeue`, LSF's `-r`); default yes: a requeued job runs only what is missing.
    pub requeue: Option<bool>,
    /// The MPI launcher inside each job (`srun --mpi=pmix -n {ranks}`, `mpirun -n {ranks}`).
    pub launcher: Option<Launcher>,
    /// Environment modules loaded before the study runs (`module load NAME`).
    #[serde(default)]
    pub modules: Vec<ModuleName>,
    /// Shell lines run before the study, after the modules (exports, a `source`): the
    /// profile's own code, one line each.
    #[serde(default)]
    pub prologue: Vec<PrologueLine>,
    /// Further scheduler options, one per line after the prefix (`--gres=gpu:1`, `-R
    /// "select[avx2]"`): each starts with `-` and holds no control character.
    #[serde(default)]
    pub directives: Vec<Directive>,
}

impl Site {
    /// The profile `--site` or `NLSTUDY_SITE` names: a path (it holds a `/` or ends in `.toml`
    /// or `.json`), or a name looked up as `NAME.toml` (then `NAME.json`) in `$NLSTUDY_SITES`,
    /// `~/.config/nlstudy/sites` and the project's `sites/` folder.
    pub fn find(given: &str) -> Result<Site, String> {
        let path = if given.contains('/') || given.ends_with(".toml") || given.ends_with(".json") {
            PathBuf::from(given)
        } else {
            if !given
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "_.-".contains(c))
            {
                return Err(format!(
                    "site {given:?}: a site name is letters, digits and `_ . -`; give a path to a profile file otherwise"
                ));
            }
            let folders = search_folders();
            folders
                .iter()
                .flat_map(|dir| ["toml", "json"].map(|x| dir.join(format!("{given}.{x}"))))
                .find(|p| p.is_file())
                .ok_or_else(|| {
                    let searched: Vec<String> =
                        folders.iter().map(|d| d.display().to_string()).collect();
                    format!(
                        "no site profile {given:?} ({given}.toml or {given}.json) in {}; give its path, or set {SITES_VARIABLE} to its folder",
                        searched.join(", ")
                    )
                })?
        };
        Site::read(&path)
    }

    /// The profile in `path`, TOML or JSON by its extension.
    pub fn read(path: &Path) -> Result<Site, String> {
        let text = schema::regular::read_at_most(path, 1 << 20, "a site profile")
            .and_then(|b| String::from_utf8(b).map_err(|_| std::io::Error::other("not UTF-8")))
            .map_err(|e| format!("cannot read the site profile {}: {e}", path.display()))?;
        let toml = path.extension().is_none_or(|x| x != "json");
        let mut site = Site::parse(&text, toml)
            .map_err(|e| format!("site profile {}: {e}", path.display()))?;
        site.file = path.to_path_buf();
        Ok(site)
    }

    /// A profile's text, TOML or JSON; an error names the field.
    pub fn parse(text: &str, toml: bool) -> Result<Site, String> {
        let value: serde_json::Value = match toml {
            true => super::toml_file::parse(text)?,
            // Read strictly: a key given twice is refused, not settled by the last.
            false => schema::json::parse(text).map_err(|e| e.to_string())?,
        };
        serde_path_to_error::deserialize(value).map_err(|e| {
            let message = format_serde(&e.inner().to_string());
            match e.path().to_string().as_str() {
                "." => message,
                field => format!("`{field}`: {message}"),
            }
        })
    }

    /// The study's resources with the profile's defaults filled in where neither the study nor
    /// a flag gives one.
    pub fn defaults(&self) -> Resources {
        Resources {
            queue: self.queue.clone(),
            account: self.account.clone(),
            time: self.time,
            ..Resources::default()
        }
    }

    /// The fields that only one scheduler understands, refused for the other with the field.
    pub fn check_for(&self, scheduler: Scheduler) -> Result<(), String> {
        let slurm_only = [
            ("qos", self.qos.is_some()),
            ("constraint", self.constraint.is_some()),
        ];
        match scheduler {
            Scheduler::Lsf => match slurm_only.iter().find(|(_, set)| *set) {
                Some((field, _)) => Err(format!(
                    "site profile {}: `{field}` is a Slurm setting that LSF has no directive for; remove it, or give LSF's own in `directives` (e.g. -R \"select[…]\")",
                    self.file.display()
                )),
                None => Ok(()),
            },
            Scheduler::Slurm => Ok(()),
        }
    }
}

/// Serde's sentence, with a guess at the field or value meant when one was mistyped.
fn format_serde(message: &str) -> String {
    let message = message.trim();
    match schema::error::suggestion(message) {
        Some(guess) => format!("{message}; did you mean `{guess}`?"),
        None => message.to_string(),
    }
}

fn search_folders() -> Vec<PathBuf> {
    let mut folders = Vec::new();
    if let Some(dir) = std::env::var_os(SITES_VARIABLE) {
        folders.push(PathBuf::from(dir));
    }
    if let Some(home) = std::env::var_os("HOME") {
        folders.push(Path::new(&home).join(".config/nlstudy/sites"));
    }
    folders.push(Path::new(env!("CARGO_MANIFEST_DIR")).join("../sites"));
    folders
}

/// Checks `text` against `allowed` characters and a length, naming `what` it is.
fn checked(text: String, what: &str, allowed: fn(char) -> bool) -> Result<String, String> {
    if text.is_empty() || text.len() > 200 {
        return Err(format!("{what} has 1 to 200 characters"));
    }
    match text.chars().find(|c| !allowed(*c)) {
        Some(bad) => Err(format!(
            "{what} {text:?} holds {bad:?}, which it cannot carry"
        )),
        None => Ok(text),
    }
}

/// Slurm's node features: names joined by `&`, `|`, `,`, with counts (`*2`) and brackets.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(try_from = "String")]
pub struct Constraint(pub String);

impl TryFrom<String> for Constraint {
    type Error = String;

    fn try_from(text: String) -> Result<Self, String> {
        let allowed = |c: char| c.is_ascii_alphanumeric() || "_.-&|,*[]:".contains(c);
        checked(text, "a constraint", allowed).map(Constraint)
    }
}

/// An environment module: `openmpi/4.1.6`, `gcc@12`, `intel-oneapi-mpi/2021.10.0+gcc`.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(try_from = "String")]
pub struct ModuleName(pub String);

impl TryFrom<String> for ModuleName {
    type Error = String;

    fn try_from(text: String) -> Result<Self, String> {
        let allowed = |c: char| c.is_ascii_alphanumeric() || "_.-/+@:".contains(c);
        checked(text, "a module name", allowed).map(ModuleName)
    }
}

/// One line of the profile's prologue: anything but a control character (a newline would make
/// one entry two lines, hidden from whoever reads the list).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(try_from = "String")]
pub struct PrologueLine(pub String);

impl TryFrom<String> for PrologueLine {
    type Error = String;

    fn try_from(text: String) -> Result<Self, String> {
        checked(text, "a prologue line", |c| !is_unsafe_char(c)).map(PrologueLine)
    }
}

/// One further scheduler option: starts with `-`, no control character (which would end the
/// directive's line and start a shell command).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(try_from = "String")]
pub struct Directive(pub String);

impl TryFrom<String> for Directive {
    type Error = String;

    fn try_from(text: String) -> Result<Self, String> {
        let text = checked(text, "a directive", |c| !is_unsafe_char(c))?;
        match text.starts_with('-') {
            true => Ok(Directive(text)),
            false => Err(format!(
                "the directive {text:?} is not an option: write it as after `#SBATCH ` or `#BSUB ` (e.g. --gres=gpu:1)"
            )),
        }
    }
}

/// Memory per node, in megabytes; zero asks Slurm for all of it.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(try_from = "String")]
pub struct Memory {
    pub megabytes: u64,
}

impl TryFrom<String> for Memory {
    type Error = String;

    fn try_from(text: String) -> Result<Self, String> {
        let refuse = || {
            format!("{text:?} is not a memory size; write megabytes (4000) or a number with K, M, G or T (4G)")
        };
        let (digits, unit) = match text.find(|c: char| !c.is_ascii_digit()) {
            Some(at) => text.split_at(at),
            None => (text.as_str(), "M"),
        };
        let number: u64 = match digits.len() {
            1..=12 => digits.parse().map_err(|_| refuse())?,
            _ => return Err(refuse()),
        };
        let megabytes = match unit.to_ascii_uppercase().as_str() {
            "K" => number.div_ceil(1024),
            "M" => number,
            "G" => number * 1024,
            "T" => number * 1024 * 1024,
            _ => return Err(refuse()),
        };
        Ok(Memory { megabytes })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(toml: &str) -> Result<Site, String> {
        Site::parse(toml, true)
    }

    #[test]
    fn the_documented_profiles_are_read() {
        for name in ["example-slurm", "example-lsf"] {
            let site = Site::find(name).unwrap();
            assert!(site.scheduler.is_some(), "{name}");
            assert!(!site.modules.is_empty(), "{name}");
            site.check_for(site.scheduler.unwrap()).unwrap();
        }
    }

    #[test]
    fn hostile_or_mistyped_values_are_refused_naming_the_field() {
        for (toml, says) in [
            ("queue = \"a\\ntouch X\"", "queue"),
            ("qos = \"$(id)\"", "qos"),
            ("constraint = \"a b\"", "constraint"),
            ("modules = [\"openmpi; id\"]", "module name"),
            ("prologue = [\"export A=1\\nid\"]", "prologue line"),
            ("directives = [\"--gres=gpu:1\\nid\"]", "directive"),
            ("directives = [\"gres=gpu:1\"]", "not an option"),
            ("memory = \"4 GB\"", "memory size"),
            ("time = \"1:30\"", "ambiguous"),
            ("launcher = \"srun -n 2\"", "{ranks}"),
            ("scheduler = \"pbs\"", "scheduler"),
            ("partition = \"x\"", "unknown field"),
            ("modueles = []", "did you mean `modules`"),
            ("cores_per_node = nan", "not a finite number"),
            ("time = 01:00:00", "quote it"),
            ("prologue = [\"echo \u{202e}gnp.exe\"]", "prologue line"),
        ] {
            let e = parse(toml).unwrap_err();
            assert!(e.contains(says), "{toml}: {e}");
        }
        // JSON is read as strictly as study files: a key given twice is refused.
        let twice = Site::parse(r#"{"queue": "a", "queue": "b"}"#, false).unwrap_err();
        assert!(twice.contains("given twice"), "{twice}");
    }

    #[test]
    fn memory_sizes_are_read_in_megabytes() {
        for (text, megabytes) in [
            ("4000", 4000),
            ("4G", 4096),
            ("512k", 1),
            ("0", 0),
            ("1T", 1 << 20),
        ] {
            let memory = Memory::try_from(text.to_string()).unwrap();
            assert_eq!(memory.megabytes, megabytes, "{text}");
        }
    }

    #[test]
    fn slurm_only_fields_are_refused_for_lsf() {
        let site = parse("qos = \"normal\"").unwrap();
        assert!(site.check_for(Scheduler::Slurm).is_ok());
        let e = site.check_for(Scheduler::Lsf).unwrap_err();
        assert!(e.contains("`qos`"), "{e}");
    }

    #[test]
    fn a_name_that_could_leave_the_profile_folders_is_refused() {
        let e = Site::find("..").unwrap_err();
        assert!(
            e.contains("no site profile") || e.contains("site name"),
            "{e}"
        );
        let e = Site::find("a b").unwrap_err();
        assert!(e.contains("site name"), "{e}");
    }
}
