//! What the head's (`scanner-device`, `scanner-calib`) and the host's (`scanner-host`) binaries
//! share at their edges, so that each behaviour has one implementation:
//! - [`outln!`] and [`errln!`]: a line to standard output or error, where a closed stream (the
//!   output piped into `head`, say) is not an error for the work itself;
//! - [`write_atomic`] and [`write_atomic_with`]: a file written whole or not at all;
//! - [`image_file`] and [`text_file`]: image and text files read with their sizes checked
//!   against stated limits before anything is allocated;
//! - [`link_spec`]: the `serial:PATH[@BAUD]` name of a link, as both ends parse it;
//! - [`words`]: what the wire's numbers (skip reasons, notices, camera controls) say to people;
//! - [`error_record`]: a failing command's error as one line of JSON too, when
//!   `SCANNER_ERRORS=json` asks for it.
//!
//! `scanner-core` stays `no_std` and free of I/O; this crate is the standard library's side.
//!
//! # Layers
//! ```text
//! image_file  link_spec  text_file  words  atomic  errors
//! ```
#![deny(missing_docs)]

mod atomic;
mod errors;
pub mod image_file;
pub mod link_spec;
pub mod text_file;
pub mod words;

pub use atomic::{TempWriter, write_atomic, write_atomic_with};
pub use errors::{ERRORS_ENV, error_record, error_record_if_asked, usage_record};

/// Prints a line to standard output. A closed stdout (`scanner-host replay … | head -1`) is not
/// an error for the work itself: a failed write is ignored and the command carries on (its
/// outputs are still written).
#[macro_export]
macro_rules! outln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($t)*);
    }};
}

/// Prints a line to standard error, ignoring a closed stderr like [`outln!`].
#[macro_export]
macro_rules! errln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr().lock(), $($t)*);
    }};
}
