//! The MPI launcher: the command prefix that starts a case's ranks (`mpirun -n {ranks}`, `srun
//! --mpi=pmix -n {ranks}`), given by `--launcher`, a site profile or the default. Its words are
//! split by the shell's quoting rules once, and written back quoted into job scripts.

/// How `mpirun` is called by default; `{ranks}` is replaced by the case's rank count.
pub const DEFAULT_LAUNCHER: &str = "mpirun --oversubscribe -n {ranks}";

/// The command prefix that starts an MPI case, split into words by the shell's quoting rules;
/// one of them holds `{ranks}`, which becomes the case's rank count.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(try_from = "String")]
pub struct Launcher {
    words: Vec<String>,
}

impl Launcher {
    /// The words that start a case of `ranks` ranks: the program and its arguments.
    pub fn words(&self, ranks: u64) -> Vec<String> {
        self.words
            .iter()
            .map(|w| w.replace("{ranks}", &ranks.to_string()))
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
        if !words.iter().any(|w| w.contains("{ranks}")) {
            return Err(format!(
                "{text:?} has no `{{ranks}}`, so every MPI case would start with the launcher's own rank count; write it where the rank count goes, e.g. {DEFAULT_LAUNCHER:?}"
            ));
        }
        Ok(Launcher { words })
    }
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
            launcher.words(3),
            ["env", "A=b c", "mpirun", "-n", "3", "--bind-to", "core"]
        );
        for (bad, says) in [
            ("", "empty"),
            ("   ", "empty"),
            ("mpirun -n 2", "{ranks}"),
            ("mpirun 'unclosed {ranks}", "quote"),
            ("mpirun -n {ranks} \u{1b}x", "control"),
        ] {
            let e = bad.parse::<Launcher>().unwrap_err();
            assert!(e.contains(says), "{bad:?}: {e}");
        }
    }
}
