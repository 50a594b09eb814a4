//! The API's bearer token: read from a file that only the service user may read, and
//! compared in constant time.

use std::path::{Path, PathBuf};

/// Errors of reading the token file.
#[derive(Debug, thiserror::Error)]
pub enum TokenError {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(
        "{}: mode {mode:04o} is too open: the token file must be readable only by the service user (chmod 0600 or 0400)",
        path.display()
    )]
    Mode { path: PathBuf, mode: u32 },
    #[error("{}: owned by uid {owner}, but the service runs as uid {uid}", path.display())]
    Owner { path: PathBuf, owner: u32, uid: u32 },
    #[error("{}: {reason}", path.display())]
    Content { path: PathBuf, reason: &'static str },
}

/// The bearer token (never printed: `Debug` hides it).
#[derive(Clone)]
pub struct Token(Vec<u8>);

impl std::fmt::Debug for Token {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Token(..)")
    }
}

impl Token {
    /// Read the token from `path`: the file must be a regular file owned by the current
    /// uid with mode 0600 or 0400 (no group or other bits); its content, trimmed of
    /// surrounding white space, is the token (16..=4096 printable ASCII characters).
    pub fn load(path: &Path) -> Result<Token, TokenError> {
        use std::os::unix::fs::MetadataExt;
        let io = |source| TokenError::Io {
            path: path.to_path_buf(),
            source,
        };
        let meta = std::fs::metadata(path).map_err(io)?;
        if !meta.is_file() {
            return Err(TokenError::Content {
                path: path.into(),
                reason: "not a regular file",
            });
        }
        let mode = meta.mode() & 0o7777;
        if mode != 0o600 && mode != 0o400 {
            return Err(TokenError::Mode {
                path: path.into(),
                mode,
            });
        }
        let uid = current_uid();
        if meta.uid() != uid {
            return Err(TokenError::Owner {
                path: path.into(),
                owner: meta.uid(),
                uid,
            });
        }
        let text = std::fs::read(path).map_err(io)?;
        Token::from_bytes(text.trim_ascii()).map_err(|reason| TokenError::Content {
            path: path.into(),
            reason,
        })
    }

    /// A token from its bytes (16..=4096 printable ASCII characters without spaces).
    pub fn from_bytes(b: &[u8]) -> Result<Token, &'static str> {
        if b.len() < 16 {
            return Err("the token must have at least 16 characters");
        }
        if b.len() > 4096 {
            return Err("the token must have at most 4096 characters");
        }
        if !b.iter().all(|c| c.is_ascii_graphic()) {
            return Err("the token must be printable ASCII without spaces");
        }
        Ok(Token(b.to_vec()))
    }

    /// Does `candidate` equal the token? Constant time in the content (the time depends
    /// only on the candidate's length).
    pub fn matches(&self, candidate: &[u8]) -> bool {
        let mut diff = (self.0.len() ^ candidate.len()) as u64;
        for (i, c) in candidate.iter().enumerate() {
            let t = self.0.get(i % self.0.len().max(1)).copied().unwrap_or(0);
            diff |= u64::from(t ^ c);
        }
        std::hint::black_box(diff) == 0
    }
}

fn current_uid() -> u32 {
    // /proc/self is owned by the process's effective uid; avoids a libc dependency.
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata("/proc/self").map_or(u32::MAX, |m| m.uid())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt;

    #[test]
    fn compare() {
        let t = Token::from_bytes(b"0123456789abcdef").unwrap();
        assert!(t.matches(b"0123456789abcdef"));
        assert!(!t.matches(b"0123456789abcdeg"));
        assert!(!t.matches(b"0123456789abcdef0"));
        assert!(!t.matches(b""));
        assert!(Token::from_bytes(b"short").is_err());
    }

    #[test]
    fn mode_is_checked() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("token");
        std::fs::write(&p, "0123456789abcdef\n").unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o644)).unwrap();
        let e = Token::load(&p).unwrap_err().to_string();
        assert!(e.contains("mode 0644") && e.contains("token"), "{e}");
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o600)).unwrap();
        assert!(Token::load(&p).unwrap().matches(b"0123456789abcdef"));
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o400)).unwrap();
        assert!(Token::load(&p).is_ok());
    }
}
