//! Why a command stopped, and the exit status of its kind (`schema::exit`).

use crate::store::{Fault, FileError};
use schema::exit;

/// Why a command stopped: the sentence for the user and the exit status that tells its kind.
#[derive(Debug)]
pub struct Failure {
    pub message: String,
    pub code: u8,
}

impl From<String> for Failure {
    fn from(message: String) -> Failure {
        Failure {
            message,
            code: exit::BAD_INPUT,
        }
    }
}

impl From<&str> for Failure {
    fn from(message: &str) -> Failure {
        Failure::from(message.to_string())
    }
}

impl From<Fault> for Failure {
    fn from(fault: Fault) -> Failure {
        let code = match &fault {
            Fault::Input(_) => exit::BAD_INPUT,
            Fault::Io(_) => exit::IO,
        };
        Failure {
            message: fault.to_string(),
            code,
        }
    }
}

impl From<FileError> for Failure {
    fn from(e: FileError) -> Failure {
        Failure {
            message: e.to_string(),
            code: exit::IO,
        }
    }
}
