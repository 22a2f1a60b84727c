//! The journal: every accepted frame, re-encoded exactly, appended and flushed as it arrives, so
//! that nothing received is lost to a crash, a pulled cable or Ctrl-C; `replay` rebuilds
//! everything from it.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use scanner_wire::{MAX_ENCODED, Message, WireError};

/// Why the journal cannot be kept.
#[derive(Debug, thiserror::Error)]
pub enum JournalError {
    /// The file cannot be opened.
    #[error("cannot open the journal {}", path.display())]
    Open {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// Writing or syncing failed (a full disk, a vanished drive).
    #[error("writing the journal")]
    Write(#[source] std::io::Error),
    /// A message did not re-encode (a bug: the buffers fit the largest).
    #[error("re-encoding a frame for the journal")]
    Encode(#[source] WireError),
}

/// The session's journal: accepted frames, re-encoded exactly, appended and flushed one by one
/// (and synced to disk at most once a second).
pub struct Journal {
    file: std::fs::File,
    scratch: Vec<u8>,
    out: Vec<u8>,
    last_sync: Instant,
}

impl Journal {
    /// Creates (or appends to) a journal file.
    ///
    /// # Errors
    /// [`JournalError::Open`] naming the file.
    pub fn open(path: &Path) -> Result<Journal, JournalError> {
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map_err(|source| JournalError::Open {
                path: path.to_path_buf(),
                source,
            })?;
        Ok(Journal {
            file,
            scratch: vec![0; scanner_wire::MAX_MESSAGE],
            out: vec![0; MAX_ENCODED],
            last_sync: Instant::now(),
        })
    }

    /// Appends one message.
    ///
    /// # Errors
    /// The write failed.
    pub fn append(&mut self, msg: &Message) -> Result<(), JournalError> {
        let n = scanner_wire::encode(msg, &mut self.scratch, &mut self.out)
            .map_err(JournalError::Encode)?;
        self.file
            .write_all(&self.out[..n])
            .and_then(|()| self.file.flush())
            .map_err(JournalError::Write)?;
        if self.last_sync.elapsed().as_secs_f64() >= 1.0 {
            self.file.sync_data().map_err(JournalError::Write)?;
            self.last_sync = Instant::now();
        }
        Ok(())
    }

    /// Syncs to disk.
    ///
    /// # Errors
    /// The sync failed.
    pub fn sync(&mut self) -> Result<(), JournalError> {
        self.file.sync_all().map_err(JournalError::Write)
    }
}
