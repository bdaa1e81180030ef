//! The study model: a study file and its expansion into points, the expression language of its
//! `derive` and `where`, the figure specs it lists, and the resources its cluster jobs ask for.
//! Pure data and rules: nothing here runs a process, touches the record store or draws.
//!
//! The adaptive questions are here too: the `Adaptive` trait (`adaptive`) and its kinds,
//! `boundary`, `refine` and `target`, each a spec (the study file's section) and the rules that
//! choose the next probes from the records so far; `run::search` runs them, and `kinds` (a layer
//! above) registers them, reads their sections into a study's question and writes their answers. A cluster's profile
//! is `site`, the MPI launcher `launcher`, and TOML files are read strictly by `toml_file`.

pub mod adaptive;
pub mod boundary;
pub mod expression;
pub mod figure_spec;
pub mod launcher;
pub mod refine;
pub mod resources;
pub mod site;
pub mod study;
pub mod target;
pub mod toml_file;
