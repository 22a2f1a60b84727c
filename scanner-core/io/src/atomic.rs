//! A file written whole or not at all: through a temporary file beside it, synced, renamed over
//! it.

use std::io::Write as _;
use std::path::Path;

/// The buffered temporary file a [`write_atomic_with`] writer writes to.
pub type TempWriter = std::io::BufWriter<tempfile::NamedTempFile>;

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename
/// ([`write_atomic_with`]).
///
/// # Errors
/// Any I/O error.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// Writes `path` through a temporary file in the same folder (`tempfile`), its content streamed
/// by `fill` (a mesh of millions of faces is written as it is formatted, never held whole in
/// memory), synced, then renamed over `path`: a crash never leaves a half-written file in place
/// of a good one. The file is made as any new file is (0666 less the umask), not with tempfile's
/// private 0600: calibration files, shots, sheets and models are the user's to share.
///
/// # Errors
/// Any I/O error, `fill`'s included; `path` is then left as it was.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut TempWriter) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let mut temp = tempfile::Builder::new();
    #[cfg(unix)]
    temp.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
    let mut w = std::io::BufWriter::with_capacity(1 << 20, temp.tempfile_in(dir)?);
    fill(&mut w)?;
    let f = w
        .into_inner()
        .map_err(std::io::IntoInnerError::into_error)?;
    f.as_file().sync_all()?;
    f.persist(path).map_err(|e| e.error)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_is_written_whole_or_left_as_it_was() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("model.obj");
        write_atomic(&path, b"v 0 0 0\n").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"v 0 0 0\n");
        // A writer that fails half-way leaves the old file, and no temporary file beside it.
        let failed = write_atomic_with(&path, |w| {
            w.write_all(b"v 1 1 1\n")?;
            Err(std::io::Error::other("disk full"))
        });
        assert_eq!(failed.unwrap_err().to_string(), "disk full");
        assert_eq!(std::fs::read(&path).unwrap(), b"v 0 0 0\n");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[cfg(unix)]
    #[test]
    fn a_file_is_made_as_any_new_file_is_not_private() {
        use std::os::unix::fs::PermissionsExt as _;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("calibration.toml");
        write_atomic(&path, b"x = 1\n").unwrap();
        let plain = dir.path().join("plain");
        std::fs::File::create(&plain).unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&path), mode(&plain));
    }
}
