//! The MPI launcher: the command prefix that starts a case's ranks (`mpirun -n {ranks}`, `srun
//! --mpi=pmix -n {ranks}`), given by `--launcher`, a site profile or the default. Its words are
//! split by the shell's quoting rules once, and written back quoted into job scripts.

/// How `mpirun` is called by default; `{ranks}` is replaced by the case's rank count.
pub const DEFAULT_LAUNCHER: &str = "mpirun --oversubscribe -n {ranks}";

/// The placeholders a launcher may hold: the case's rank count, and its threads per rank (the
/// cores each rank needs: `srun -c {threads}`, `mpirun --map-by slot:PE={threads}`).
pub const PLACEHOLDERS: [&str; 2] = ["{ranks}", "{threads}"];

/// The command prefix that starts an MPI case, split into words by the shell's quoting rules;
/// one of them holds `{ranks}`, which becomes the case's rank count, and any may hold
/// `{threads}`, its threads per rank. Any other `{…}` is refused: it would reach the command
/// as it is.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(try_from = "String")]
pub struct Launcher {
    words: Vec<String>,
}

impl Launcher {
    /// The words that start a case of `ranks` ranks of `threads` threads each: the program and
    /// its arguments.
    pub fn argv(&self, ranks: u64, threads: u64) -> Vec<String> {
        self.words
            .iter()
            .map(|w| {
                w.replace("{ranks}", &ranks.to_string())
                    .replace("{threads}", &threads.to_string())
            })
            .collect()
    }

    /// The launcher as one command line, each word quoted as the shell needs (for job scripts).
    pub fn text(&self) -> String {
        shlex::try_join(self.words.iter().map(String::as_str))
            .expect("a launcher's words hold no NUL: control characters are refused")
    }
}

impl std::str::FromStr for Launcher {
    type Err = String;

    fn from_str(text: &str) -> Result<Launcher, String> {
        let words = shlex::split(text)
            .ok_or_else(|| format!("{text:?} is not a command line: a quote is not closed"))?;
        if words.is_empty() {
            return Err(format!(
                "the launcher is empty; give e.g. {DEFAULT_LAUNCHER:?}"
            ));
        }
        if let Some(word) = words
            .iter()
            .find(|w| w.chars().any(schema::json::is_unsafe_char))
        {
            return Err(format!(
                "{word:?} holds a control character or a bidirectional control"
            ));
        }
        let unknown = words
            .iter()
            .flat_map(|w| placeholders(w))
            .find(|p| !PLACEHOLDERS.contains(p));
        if let Some(unknown) = unknown {
            return Err(format!(
                "{text:?} holds `{unknown}`, which is no placeholder; a launcher knows {} (a `{{` that is no placeholder has no place in a launcher)",
                PLACEHOLDERS.join(" and ")
            ));
        }
        if !words.iter().any(|w| w.contains("{ranks}")) {
            return Err(format!(
                "{text:?} has no `{{ranks}}`, so every MPI case would start with the launcher's own rank count; write it where the rank count goes, e.g. {DEFAULT_LAUNCHER:?}"
            ));
        }
        Ok(Launcher { words })
    }
}

/// The `{…}` of a word, and a lone `{` or `}` as itself.
fn placeholders(word: &str) -> Vec<&str> {
    let mut found = Vec::new();
    let mut rest = word;
    while let Some(open) = rest.find(['{', '}']) {
        let after = &rest[open..];
        match (after.starts_with('{'), after.find('}')) {
            (true, Some(close)) => {
                found.push(&after[..=close]);
                rest = &after[close + 1..];
            }
            _ => {
                found.push(&after[..1]);
                rest = &after[1..];
            }
        }
    }
    found
}

impl TryFrom<String> for Launcher {
    type Error = String;

    fn try_from(text: String) -> Result<Launcher, String> {
        text.parse()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_launcher_is_split_by_shell_quoting_and_must_say_where_the_ranks_go() {
        let launcher: Launcher =
            r#"env "A=b c" mpirun -n {ranks} --bind-to 'core'"#.parse().unwrap();
        assert_eq!(
            launcher.argv(3, 1),
            ["env", "A=b c", "mpirun", "-n", "3", "--bind-to", "core"]
        );
        let srun: Launcher = "srun --mpi=pmi2 -n {ranks} -c {threads}".parse().unwrap();
        assert_eq!(
            srun.argv(2, 4),
            ["srun", "--mpi=pmi2", "-n", "2", "-c", "4"]
        );
        for (bad, says) in [
            ("", "empty"),
            ("   ", "empty"),
            ("mpirun -n 2", "{ranks}"),
            (
                "srun -n {ranks} -c {thread}",
                "`{thread}`, which is no placeholder",
            ),
            ("srun -n {ranks} -c {threads", "`{`"),
            ("mpirun -n {ranks} }", "`}`"),
            ("mpirun 'unclosed {ranks}", "quote"),
            ("mpirun -n {ranks} \u{1b}x", "control"),
        ] {
            let e = bad.parse::<Launcher>().unwrap_err();
            assert!(e.contains(says), "{bad:?}: {e}");
        }
    }
}
