//! Where the host's bytes come from: `serial:PATH[@BAUD]`, `pty` (a new pseudo-terminal pair
//! whose device end the head writes to, like a serial cable), `-` (stdin) or a recorded file.

use std::io::Read;
use std::path::PathBuf;
use std::time::Duration;

use scanner_io::link_spec::{SerialSpec, SpecError};

/// How long a read waits before the receive loop looks at Ctrl-C and the progress again.
const READ_TIMEOUT: Duration = Duration::from_millis(200);

/// An input, parsed from its name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Input {
    /// Standard input (`-`).
    Stdin,
    /// A new pseudo-terminal pair (`pty`).
    Pty,
    /// A serial port.
    Serial {
        /// Device path.
        path: String,
        /// Baud rate.
        baud: u32,
    },
    /// A recorded stream or journal.
    File(PathBuf),
}

/// Why an input cannot be opened.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// A `serial:` name that is not one.
    #[error("{text:?}: {why}")]
    BadSerial {
        /// What was given.
        text: String,
        /// What is wrong.
        why: SpecError,
    },
    /// An empty input name.
    #[error("no input given (serial:PATH@BAUD, pty, - or a file)")]
    Empty,
    /// The serial port cannot be opened.
    #[error("cannot open serial port {path} at {baud} baud")]
    Serial {
        /// The port.
        path: String,
        /// Its rate.
        baud: u32,
        /// Why.
        #[source]
        source: serialport::Error,
    },
    /// The pseudo-terminal pair cannot be made.
    #[error("cannot create a pseudo-terminal pair")]
    Pty(#[source] serialport::Error),
    /// A folder was given where a recording belongs.
    #[error("{} is a folder: give a recorded stream or journal file (e.g. OUT/journal.stream)", path.display())]
    Folder {
        /// The folder.
        path: PathBuf,
    },
    /// The file cannot be read.
    #[error("cannot read {}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
}

impl std::str::FromStr for Input {
    type Err = InputError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "" => return Err(InputError::Empty),
            "-" => return Ok(Input::Stdin),
            "pty" => return Ok(Input::Pty),
            _ => {}
        }
        match SerialSpec::parse(s) {
            Ok(Some(spec)) => Ok(Input::Serial {
                path: spec.path.to_string(),
                baud: spec.baud,
            }),
            Ok(None) => Ok(Input::File(s.into())),
            Err(why) => Err(InputError::BadSerial {
                text: s.chars().take(80).collect(),
                why,
            }),
        }
    }
}

/// An open input: the reader, and for `pty` the device end's name and the far end, kept open
/// here so that the head may open and close it freely.
pub struct OpenedInput {
    /// The bytes.
    pub reader: Box<dyn Read>,
    /// For `pty`: the path the head writes to.
    pub device: Option<String>,
    _far_end: Option<serialport::TTYPort>,
}

impl Input {
    /// Opens the input. Serial ports and pseudo-terminals read with a short timeout, so that a
    /// quiet link does not block Ctrl-C.
    ///
    /// # Errors
    /// [`InputError`] naming the port or file.
    pub fn open(&self) -> Result<OpenedInput, InputError> {
        let plain = |reader: Box<dyn Read>| OpenedInput {
            reader,
            device: None,
            _far_end: None,
        };
        Ok(match self {
            Input::Stdin => plain(Box::new(std::io::stdin())),
            Input::File(path) => plain(Box::new(open_file(path)?)),
            Input::Serial { path, baud } => plain(Box::new(
                serialport::new(path, *baud)
                    .timeout(READ_TIMEOUT)
                    .open_native()
                    .map_err(|source| InputError::Serial {
                        path: path.clone(),
                        baud: *baud,
                        source,
                    })?,
            )),
            Input::Pty => {
                use serialport::SerialPort;
                let (mut ours, theirs) = serialport::TTYPort::pair().map_err(InputError::Pty)?;
                let device = theirs.name();
                ours.set_timeout(READ_TIMEOUT).map_err(InputError::Pty)?;
                OpenedInput {
                    reader: Box::new(ours),
                    device,
                    _far_end: Some(theirs),
                }
            }
        })
    }
}

/// Opens a recorded stream or journal for reading; a folder is named as one.
///
/// # Errors
/// [`InputError::Folder`] or [`InputError::File`] naming the path.
pub fn open_file(path: &std::path::Path) -> Result<std::fs::File, InputError> {
    let file = |source| InputError::File {
        path: path.to_path_buf(),
        source,
    };
    let f = std::fs::File::open(path).map_err(file)?;
    if f.metadata().map_err(file)?.is_dir() {
        return Err(InputError::Folder {
            path: path.to_path_buf(),
        });
    }
    Ok(f)
}
