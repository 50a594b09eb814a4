use std::path::PathBuf;

/// Errors of the importers. Every variant names the file, and the variable where one is
/// involved, so that a message is useful without further context.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// The file could not be read.
    #[error("{path}: cannot read: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file is not a MAT v5 file (wrong size, version or endian indicator; e.g. v7.3/HDF5).
    #[error("{path}: not a MATLAB v5 MAT-file: {reason}")]
    NotMat5 { path: PathBuf, reason: String },
    /// The file is a MAT v5 file but its contents are inconsistent (truncated, bad sizes,
    /// bad zlib stream). `variable` is the top-level variable being read, when known;
    /// `offset` the byte offset (in the file, or in the decompressed element) of the problem.
    #[error(
        "{path}: corrupt MAT data{} at byte {offset}: {reason}",
        variable_suffix(variable)
    )]
    Corrupt {
        path: PathBuf,
        variable: Option<String>,
        offset: usize,
        reason: String,
    },
    /// A requested variable (or struct field path such as `ms.harm.fs`) is not in the file.
    #[error("{path}: no variable `{name}` (variables: {})", available.join(", "))]
    MissingVariable {
        path: PathBuf,
        name: String,
        available: Vec<String>,
    },
    /// A variable exists but has the wrong class or shape for its use.
    #[error("{path}: variable `{name}`: {reason}")]
    BadVariable {
        path: PathBuf,
        name: String,
        reason: String,
    },
    /// A line of a text (DaISy) file could not be parsed.
    #[error("{path}:{line}: {reason}")]
    Text {
        path: PathBuf,
        line: usize,
        reason: String,
    },
    /// The import specification does not fit the data (no sample rate, too few periods, ...).
    #[error("{path}: {reason}")]
    Spec { path: PathBuf, reason: String },
}

fn variable_suffix(v: &Option<String>) -> String {
    match v {
        Some(v) => format!(" in variable `{v}`"),
        None => String::new(),
    }
}
