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
//! image_file  link_spec  text_file  words
//! ```
#![deny(missing_docs)]

pub mod image_file;
pub mod link_spec;
pub mod text_file;
pub mod words;

use std::io::Write as _;
use std::path::Path;

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

/// The environment variable that asks the binaries for their errors as data too: with
/// `SCANNER_ERRORS=json`, a failing command prints, after its line for people, one line of JSON
/// ([`error_record`]) for scripts and tests to read.
pub const ERRORS_ENV: &str = "SCANNER_ERRORS";

/// An error and its causes as one line of JSON:
/// `{"program":"…","error":[{"kind":"SizeMismatch","message":"…"},…]}`, outermost first. A
/// cause's `kind` is the variant names its `Debug` starts with — for the scanner's error enums,
/// `SizeMismatch`, or `Merge::TooFewViews` for one wrapped in another — and `null` for a message
/// added on the way.
pub fn error_record<'a>(
    program: &str,
    chain: impl Iterator<Item = &'a (dyn std::error::Error + 'static)>,
) -> String {
    let causes: Vec<String> = chain
        .map(|e| {
            let debug = format!("{e:?}");
            let names = variant_names(&debug);
            let kind = if names.is_empty() {
                "null".to_string()
            } else {
                format!("\"{}\"", names.join("::"))
            };
            format!(
                "{{\"kind\":{kind},\"message\":\"{}\"}}",
                json_escaped(&e.to_string())
            )
        })
        .collect();
    format!(
        "{{\"program\":\"{}\",\"error\":[{}]}}",
        json_escaped(program),
        causes.join(",")
    )
}

/// The variant names a `Debug` text starts with, outermost first: `Merge(TooFewViews(1))` gives
/// `Merge`, `TooFewViews`; a text that starts with no capitalised name (a message) gives none.
fn variant_names(debug: &str) -> Vec<&str> {
    let mut names = Vec::new();
    let mut rest = debug;
    loop {
        let len = rest
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .unwrap_or(rest.len());
        let (name, after) = rest.split_at(len);
        let ends_variant =
            after.is_empty() || after.starts_with(['(', ')']) || after.starts_with(" {");
        if !name.starts_with(|c: char| c.is_ascii_uppercase()) || !ends_variant {
            return names;
        }
        names.push(name);
        match after.strip_prefix('(') {
            Some(inner) => rest = inner,
            None => return names,
        }
    }
}

/// `s` as the inside of a JSON string.
fn json_escaped(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if (c as u32) < 0x20 => out.push_str(&format!("\\u{:04x}", c as u32)),
            c => out.push(c),
        }
    }
    out
}

/// Prints `record` (an [`error_record`]) to standard error when [`ERRORS_ENV`] asks for JSON.
pub fn error_record_if_asked(record: impl FnOnce() -> String) {
    if std::env::var(ERRORS_ENV).is_ok_and(|v| v == "json") {
        errln!("{}", record());
    }
}

#[cfg(test)]
mod error_record_tests {
    use super::*;

    #[derive(Debug)]
    enum Inner {
        SizeMismatch { width: u32 },
    }
    impl std::fmt::Display for Inner {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("the calibration is for \"another\" size")
        }
    }
    impl std::error::Error for Inner {}

    #[test]
    fn an_error_chain_is_one_line_of_json_with_each_causes_kind() {
        let inner = Inner::SizeMismatch { width: 640 };
        let context: Box<dyn std::error::Error> = "reading\tframes".into();
        let chain: Vec<&(dyn std::error::Error + 'static)> = vec![context.as_ref(), &inner];
        let line = error_record("scanner-device", chain.into_iter());
        assert_eq!(
            line,
            "{\"program\":\"scanner-device\",\"error\":[{\"kind\":null,\"message\":\"reading\\tframes\"},\
             {\"kind\":\"SizeMismatch\",\"message\":\"the calibration is for \\\"another\\\" size\"}]}"
        );
        let Inner::SizeMismatch { width } = inner;
        assert_eq!(width, 640);
        assert_eq!(
            variant_names("Merge(TooFewViews(1))"),
            ["Merge", "TooFewViews"]
        );
        assert_eq!(variant_names("Io { path: \"x\" }"), ["Io"]);
        assert!(variant_names("\"a message\"").is_empty());
        assert!(variant_names("Custom: x").is_empty());
    }
}
