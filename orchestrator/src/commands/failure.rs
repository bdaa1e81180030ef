//! Why a command stopped, by kind: the kind decides the exit status (`schema::exit`). A command
//! says which kind each failure is where it happens; nothing is classified by its type alone
//! (a `String` was once taken for bad input wherever it came from).

use crate::console::Reply;
use crate::model::study::StudyError;
use crate::store::{Fault, FileError};
use schema::exit;

#[derive(Debug, thiserror::Error)]
pub enum Failure {
    /// A bad study file, flag or value: nothing ran.
    #[error("{0}")]
    BadInput(String),
    /// A case failed, a table or figure could not be made of the runs, or `compare` found
    /// something worse.
    #[error("{0}")]
    CaseFailed(String),
    /// A file could not be read or written, or a program could not be started.
    #[error("{0}")]
    Io(String),
}

impl Failure {
    /// The exit status of its kind.
    pub fn code(&self) -> u8 {
        match self {
            Failure::BadInput(_) => exit::BAD_INPUT,
            Failure::CaseFailed(_) => exit::CASE_FAILED,
            Failure::Io(_) => exit::IO,
        }
    }

    /// `reply`, ending in this failure: said last (`nlstudy: …`), and its exit status.
    pub fn after(self, reply: Reply) -> Reply {
        let code = std::process::ExitCode::from(self.code());
        reply.failed(self.to_string(), code)
    }
}

impl From<Fault> for Failure {
    fn from(fault: Fault) -> Failure {
        match fault {
            Fault::Input(message) => Failure::BadInput(message),
            Fault::Io(message) => Failure::Io(message),
        }
    }
}

impl From<FileError> for Failure {
    fn from(e: FileError) -> Failure {
        Failure::Io(e.to_string())
    }
}

impl From<StudyError> for Failure {
    fn from(e: StudyError) -> Failure {
        Failure::BadInput(e.to_string())
    }
}
