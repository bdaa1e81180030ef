//! The study model: a study file and its expansion into points, the expression language of its
//! `derive` and `where`, the figure specs it lists, and the resources its cluster jobs ask for.
//! Pure data and rules: nothing here runs a process, touches the record store or draws.

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
