//! Atomic file replacement: write a temporary file in the target's directory, fsync it,
//! rename it over the target, then fsync the directory.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Replace the file at `path` atomically with what `fill` writes.
///
/// Readers see either the old file or the complete new one, never a partial file: the data
/// goes to a hidden temporary file in the same directory (so the rename cannot cross file
/// systems), which is flushed and `fsync`ed, renamed over `path`, and then the directory is
/// `fsync`ed (on Unix) so that the rename itself is durable. On error the temporary file is
/// removed and `path` is left untouched.
///
/// Only regular files are written ([`writable_target`]): a device, a FIFO, a socket or a
/// directory at `path`, or a symbolic link whose target lies outside `path`'s folder, is
/// refused with [`io::ErrorKind::InvalidInput`] before anything is created, and left as
/// it was. A link to a file in the same folder replaces that file and keeps the link.
pub fn write_atomic(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> io::Result<()> {
    let path = &writable_target(path)?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "path has no file name"))?;
    let (tmp, file) = create_temp(&dir, &name.to_string_lossy())?;
    let result = (|| {
        let mut w = BufWriter::with_capacity(1 << 20, file);
        fill(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        drop(file);
        fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = fs::remove_file(&tmp);
        return Err(e);
    }
    sync_dir(&dir)
}

/// The file the atomic writer may replace for `path` (issue 16: run as root it replaced
/// `/dev/full`, a FIFO and a symlink's target outside the folder with a regular file):
///
/// * nothing there, or a regular file: `path` itself;
/// * a symbolic link whose final target is in the same folder as `path` (and is a regular
///   file or absent): that target, so the link stays a link;
/// * anything else (a device, a FIFO, a socket, a directory, a link out of the folder, a
///   link loop): an [`io::ErrorKind::InvalidInput`] error naming the path and what it is.
///
/// The check and the rename are not one atomic step: a writer racing to put a device in
/// the folder between them wins; the folder is the user's own.
pub fn writable_target(path: &Path) -> io::Result<PathBuf> {
    let refuse = |what: String| {
        Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{}: {what}; flexid writes only regular files (nothing was written)",
                path.display()
            ),
        ))
    };
    let meta = match fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(path.to_path_buf()),
        Err(e) => return Err(e),
    };
    let t = meta.file_type();
    if t.is_file() {
        return Ok(path.to_path_buf());
    }
    if !t.is_symlink() {
        return refuse(format!("is {}", kind_of(&t)));
    }
    // a symbolic link: where does it end, and is that in the folder?
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let folder = fs::canonicalize(dir)?;
    let target = match fs::canonicalize(path) {
        Ok(t) => t,
        // dangling: its own text, resolved against the folder (one level)
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            let link = fs::read_link(path)?;
            let joined = folder.join(&link);
            match (joined.parent().map(fs::canonicalize), joined.file_name()) {
                (Some(Ok(p)), Some(n)) if p == folder && fs::symlink_metadata(&joined).is_err() => {
                    p.join(n)
                }
                _ => {
                    return refuse(format!(
                        "is a symbolic link to {}, outside its folder {}",
                        link.display(),
                        folder.display()
                    ))
                }
            }
        }
        Err(e) => return refuse(format!("is a symbolic link that cannot be followed ({e})")),
    };
    if target.parent() != Some(folder.as_path()) {
        return refuse(format!(
            "is a symbolic link to {}, outside its folder {}",
            target.display(),
            folder.display()
        ));
    }
    match fs::symlink_metadata(&target) {
        Ok(m) if m.file_type().is_file() => Ok(target),
        Ok(m) => refuse(format!(
            "is a symbolic link to {}, which is {}",
            target.display(),
            kind_of(&m.file_type())
        )),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(target),
        Err(e) => Err(e),
    }
}

fn kind_of(t: &fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if t.is_dir() {
        "a directory"
    } else if t.is_symlink() {
        "a symbolic link"
    } else {
        "not a regular file"
    }
}

/// Replace the file at `path` atomically with `bytes` (see [`write_atomic`]).
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_atomic(path, |w| w.write_all(bytes))
}

fn create_temp(dir: &Path, name: &str) -> io::Result<(PathBuf, File)> {
    let pid = std::process::id();
    loop {
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let tmp = dir.join(format!(".{name}.{pid}.{n}.tmp"));
        match OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(f) => return Ok((tmp, f)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
}

#[cfg(unix)]
fn sync_dir(dir: &Path) -> io::Result<()> {
    File::open(dir)?.sync_all()
}

#[cfg(not(unix))]
fn sync_dir(_dir: &Path) -> io::Result<()> {
    // Directories cannot be opened for fsync on this platform; the rename is still atomic.
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaces_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        write_bytes_atomic(&p, b"one").unwrap();
        write_bytes_atomic(&p, b"two").unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"two");
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn failed_fill_keeps_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        write_bytes_atomic(&p, b"old").unwrap();
        let r = write_atomic(&p, |w| {
            w.write_all(b"partial")?;
            Err(io::Error::other("boom"))
        });
        assert!(r.is_err());
        assert_eq!(fs::read(&p).unwrap(), b"old");
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    fn mkfifo(p: &Path) {
        let st = std::process::Command::new("mkfifo")
            .arg(p)
            .status()
            .expect("run mkfifo");
        assert!(st.success(), "mkfifo {}", p.display());
    }

    fn refused(p: &Path, what: &str) -> io::Error {
        let e = write_bytes_atomic(p, b"new").expect_err("refused");
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput, "{e}");
        let msg = e.to_string();
        assert!(msg.contains(what), "{msg} does not say {what}");
        e
    }

    /// Issue 16: run as root, the writer replaced a FIFO with a regular file.
    #[test]
    fn a_fifo_is_refused_and_kept() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.json");
        mkfifo(&p);
        refused(&p, "FIFO");
        let t = fs::symlink_metadata(&p).unwrap().file_type();
        use std::os::unix::fs::FileTypeExt;
        assert!(t.is_fifo(), "the FIFO is still there");
        assert_eq!(
            fs::read_dir(dir.path()).unwrap().count(),
            1,
            "no temporary left"
        );
    }

    /// Issue 16: the writer replaced `/dev/full`; a device is refused. Only the check is
    /// asked about the real devices: the writer itself is never pointed at one, so that a
    /// regression cannot replace `/dev/null` of the machine running the tests as root
    /// (it did once, while this test was written against the old writer).
    #[test]
    fn a_device_is_refused() {
        use std::os::unix::fs::FileTypeExt;
        let mut asked = 0;
        for dev in ["/dev/null", "/dev/full", "/dev/zero"] {
            let p = Path::new(dev);
            let Ok(m) = fs::symlink_metadata(p) else {
                continue;
            };
            if !m.file_type().is_char_device() {
                continue;
            }
            let e = writable_target(p).expect_err("a device is refused");
            assert_eq!(e.kind(), io::ErrorKind::InvalidInput, "{e}");
            assert!(e.to_string().contains("character device"), "{e}");
            asked += 1;
        }
        assert!(asked > 0, "no character device to ask about");
        // the writer, through a link in a temporary folder (a regression replaces the link)
        let dir = tempfile::tempdir().unwrap();
        let link = dir.path().join("full.json");
        std::os::unix::fs::symlink("/dev/full", &link).unwrap();
        refused(&link, "outside");
        assert!(fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
    }

    /// Issue 16: the writer replaced a symlink's target outside the output folder; a link
    /// out of the folder is refused and both the link and its target are kept.
    #[test]
    fn a_symlink_out_of_the_folder_is_refused() {
        let outside = tempfile::tempdir().unwrap();
        let victim = outside.path().join("precious.txt");
        fs::write(&victim, b"keep me").unwrap();
        let dir = tempfile::tempdir().unwrap();
        let link = dir.path().join("result.json");
        std::os::unix::fs::symlink(&victim, &link).unwrap();
        refused(&link, "outside");
        assert_eq!(fs::read(&victim).unwrap(), b"keep me");
        assert!(fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        // a link to a device is refused too
        let null = dir.path().join("null.json");
        std::os::unix::fs::symlink("/dev/null", &null).unwrap();
        refused(&null, "outside");
    }

    /// A symlink to a file in the same folder: its target is replaced, the link kept.
    #[test]
    fn a_symlink_inside_the_folder_replaces_its_target() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("v1.json");
        fs::write(&target, b"old").unwrap();
        let link = dir.path().join("latest.json");
        std::os::unix::fs::symlink("v1.json", &link).unwrap();
        write_bytes_atomic(&link, b"new").unwrap();
        assert_eq!(fs::read(&target).unwrap(), b"new");
        assert!(fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    /// A directory in the way is refused (not an `EISDIR` from the rename after the
    /// temporary was written).
    #[test]
    fn a_directory_is_refused_and_kept() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.svg");
        fs::create_dir(&p).unwrap();
        fs::write(p.join("inside"), b"x").unwrap();
        refused(&p, "directory");
        assert_eq!(fs::read(p.join("inside")).unwrap(), b"x");
    }
}
