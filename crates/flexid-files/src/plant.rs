//! Plant files read from disk (the parser is [`flexid_core::plant::PlantFile::parse`]).

use flexid_core::plant::{PlantFile, PlantFileError, DEFAULT_PLANT};
use std::path::{Path, PathBuf};

/// Why a plant file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum LoadPlantError {
    /// The file could not be read.
    #[error("{}: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// The file was read but its content was refused.
    #[error(transparent)]
    Parse(#[from] PlantFileError),
}

/// Read a plant file, or the embedded default when `path` is `None`. Errors name the file.
pub fn load_plant_file(path: Option<&Path>) -> Result<PlantFile, LoadPlantError> {
    match path {
        None => Ok(PlantFile::parse(DEFAULT_PLANT, "embedded default plant")?),
        Some(p) => {
            let text =
                crate::bounded_read::read_text_bounded(p, crate::bounded_read::MAX_TEXT_FILE_BYTES)
                    .map_err(|source| LoadPlantError::Read {
                        path: p.to_path_buf(),
                        source,
                    })?;
            Ok(PlantFile::parse(&text, &p.display().to_string())?)
        }
    }
}
