//! Plant files read from disk (the parser is [`flexid_core::plant::PlantFile::parse`]).

use flexid_core::plant::{PlantFile, DEFAULT_PLANT};
use std::path::Path;

/// Read a plant file, or the embedded default when `path` is `None`. Errors name the file.
pub fn load_plant_file(path: Option<&Path>) -> Result<PlantFile, String> {
    match path {
        None => PlantFile::parse(DEFAULT_PLANT, "embedded default plant"),
        Some(p) => {
            let text = std::fs::read_to_string(p).map_err(|e| format!("{}: {e}", p.display()))?;
            PlantFile::parse(&text, &p.display().to_string())
        }
    }
}
