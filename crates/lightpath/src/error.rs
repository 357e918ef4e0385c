//! Typed errors of the library. Every error that comes from a file names the file and,
//! where the format has them, the line and column.

use std::fmt;
use std::path::PathBuf;

/// A position in a source file (1-based line and column).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Location {
    pub file: PathBuf,
    pub line: u32,
    pub column: u32,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line > 0 {
            write!(f, "{}:{}:{}", self.file.display(), self.line, self.column)
        } else {
            write!(f, "{}", self.file.display())
        }
    }
}

/// Everything that can go wrong in the library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A scene file is malformed (bad XML, unknown plugin, bad value, ...).
    #[error("{location}: {message}")]
    Scene { location: Location, message: String },
    /// A mesh file is malformed.
    #[error("{path}: {message}")]
    Mesh { path: PathBuf, message: String },
    /// An image file is malformed or could not be encoded.
    #[error("{path}: {message}")]
    Image { path: PathBuf, message: String },
    /// A value passed through the API is invalid.
    #[error("{0}")]
    Invalid(String),
}

impl Error {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
    pub fn mesh(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Mesh {
            path: path.into(),
            message: message.into(),
        }
    }
    pub fn image(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Image {
            path: path.into(),
            message: message.into(),
        }
    }
    pub fn scene(location: Location, message: impl Into<String>) -> Self {
        Error::Scene {
            location,
            message: message.into(),
        }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;
