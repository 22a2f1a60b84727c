//! Reading a small text file (a board, calibration or scene file) with its size checked against
//! [`MAX_TEXT_FILE_BYTES`] before it is read, and a folder named as a folder.

use std::io::Read;
use std::path::Path;

/// The largest board, calibration or scene file read, bytes (the files are a few hundred bytes;
/// a board of 256 listed markers is under 10 KB).
pub const MAX_TEXT_FILE_BYTES: u64 = 1 << 20;

/// Reads a UTF-8 text file of at most [`MAX_TEXT_FILE_BYTES`].
///
/// # Errors
/// The I/O error; a folder, a larger file and non-UTF-8 text are `InvalidData`/`InvalidInput`
/// errors that say so.
pub fn read(path: &Path) -> std::io::Result<String> {
    let file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    if meta.is_dir() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "it is a folder, not a file",
        ));
    }
    let mut text = String::new();
    let n = file
        .take(MAX_TEXT_FILE_BYTES + 1)
        .read_to_string(&mut text)?;
    if n as u64 > MAX_TEXT_FILE_BYTES {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("larger than {MAX_TEXT_FILE_BYTES} bytes: not a file of this kind"),
        ));
    }
    Ok(text)
}
