//! Reading a small text file (a plant file, a configuration) with a bound: only a regular
//! file, at most a given size (issue 16: a FIFO blocked the reader, `/dev/zero` would have
//! filled the memory).

use std::io::{self, Read};
use std::path::Path;

/// Largest plant file or configuration [bytes].
pub const MAX_TEXT_FILE_BYTES: u64 = 1024 * 1024;

/// The text of the regular file `path`, refused with [`io::ErrorKind::InvalidInput`]
/// when it is no regular file or larger than `max_bytes`.
pub fn read_text_bounded(path: &Path, max_bytes: u64) -> io::Result<String> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "not a regular file (a FIFO, device or directory is not read)",
        ));
    }
    let too_large = || {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("larger than {max_bytes} bytes"),
        )
    };
    if meta.len() > max_bytes {
        return Err(too_large());
    }
    let mut text = String::new();
    std::fs::File::open(path)?
        .take(max_bytes + 1)
        .read_to_string(&mut text)?;
    if text.len() as u64 > max_bytes {
        return Err(too_large());
    }
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fifo_a_folder_and_a_large_file_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("p.toml");
        assert!(std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success());
        let e = read_text_bounded(&fifo, 100).unwrap_err();
        assert!(e.to_string().contains("not a regular file"), "{e}");
        let e = read_text_bounded(dir.path(), 100).unwrap_err();
        assert!(e.to_string().contains("not a regular file"), "{e}");
        let big = dir.path().join("big.toml");
        std::fs::write(&big, vec![b'#'; 101]).unwrap();
        let e = read_text_bounded(&big, 100).unwrap_err();
        assert!(e.to_string().contains("larger than 100"), "{e}");
        std::fs::write(&big, b"a = 1").unwrap();
        assert_eq!(read_text_bounded(&big, 100).unwrap(), "a = 1");
    }
}
