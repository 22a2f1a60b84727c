//! `serial:PATH[@BAUD]`, the name of a serial link on the command line of both ends: one parser
//! (borrowing the path) so that the head and the host agree on what it means.

use core::fmt;

/// Baud rate when `@BAUD` is left out.
pub const DEFAULT_BAUD: u32 = 921_600;
/// The slowest and fastest rates a serial link is opened at.
pub const BAUD_RANGE: (u32, u32) = (300, 12_000_000);

/// A parsed `serial:PATH[@BAUD]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SerialSpec<'a> {
    /// Device path, e.g. `/dev/ttyUSB0`.
    pub path: &'a str,
    /// Baud rate.
    pub baud: u32,
}

/// Why a `serial:` name is not one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpecError {
    /// No device path after `serial:`.
    NoPath,
    /// The text after `@` is not a number.
    BadBaud,
    /// A baud rate outside [`BAUD_RANGE`].
    BaudOutOfRange(u32),
}

impl fmt::Display for SpecError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoPath => f.write_str("no serial device path (serial:/dev/ttyUSB0@921600)"),
            Self::BadBaud => f.write_str("the baud rate after @ is not a number"),
            Self::BaudOutOfRange(b) => write!(
                f,
                "baud rate {b} is outside {}..={}",
                BAUD_RANGE.0, BAUD_RANGE.1
            ),
        }
    }
}

impl core::error::Error for SpecError {}

impl<'a> SerialSpec<'a> {
    /// Parses `serial:PATH[@BAUD]`; `Ok(None)` for a name that does not start with `serial:`.
    ///
    /// # Errors
    /// [`SpecError`] for a `serial:` name without a path or with a bad rate.
    pub fn parse(s: &'a str) -> Result<Option<Self>, SpecError> {
        let Some(rest) = s.strip_prefix("serial:") else {
            return Ok(None);
        };
        let (path, baud) = match rest.rsplit_once('@') {
            Some((p, b)) => (p, b.parse::<u32>().map_err(|_| SpecError::BadBaud)?),
            None => (rest, DEFAULT_BAUD),
        };
        if path.is_empty() {
            return Err(SpecError::NoPath);
        }
        if !(BAUD_RANGE.0..=BAUD_RANGE.1).contains(&baud) {
            return Err(SpecError::BaudOutOfRange(baud));
        }
        Ok(Some(SerialSpec { path, baud }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn serial_names() {
        assert_eq!(SerialSpec::parse("file.stream"), Ok(None));
        assert_eq!(
            SerialSpec::parse("serial:/dev/ttyACM0"),
            Ok(Some(SerialSpec {
                path: "/dev/ttyACM0",
                baud: DEFAULT_BAUD
            }))
        );
        assert_eq!(
            SerialSpec::parse("serial:/dev/ttyUSB0@115200")
                .unwrap()
                .unwrap()
                .baud,
            115_200
        );
        assert_eq!(SerialSpec::parse("serial:@9600"), Err(SpecError::NoPath));
        assert_eq!(SerialSpec::parse("serial:"), Err(SpecError::NoPath));
        assert_eq!(
            SerialSpec::parse("serial:/dev/x@fast"),
            Err(SpecError::BadBaud)
        );
        assert_eq!(
            SerialSpec::parse("serial:/dev/x@0"),
            Err(SpecError::BaudOutOfRange(0))
        );
    }
}
