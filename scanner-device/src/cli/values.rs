//! The command line's value parsers: each option's text to its value, or a [`BadValue`] that
//! quotes what was given (at most 40 characters) and says what is expected.

use std::time::Duration;

/// An option's value that is not what the option takes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BadValue {
    /// What was given, cut to 40 characters.
    pub given: String,
    /// What the option takes.
    pub expected: String,
}

impl BadValue {
    fn new(given: &str, expected: impl Into<String>) -> BadValue {
        BadValue {
            given: given.chars().take(40).collect(),
            expected: expected.into(),
        }
    }
}

impl std::fmt::Display for BadValue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:?}: {}", self.given, self.expected)
    }
}

impl std::error::Error for BadValue {}

/// `--edge-reach`: a number of profile widths from 0 to 4.
pub fn edge_reach(text: &str) -> Result<f32, BadValue> {
    match text.parse::<f32>() {
        Ok(v) if (0.0..=4.0).contains(&v) => Ok(v),
        _ => Err(BadValue::new(
            text,
            "a number of profile widths from 0 to 4",
        )),
    }
}

/// `--print-ratio`: 0 (off), or a factor from 1.1 to 10.
pub fn print_ratio(text: &str) -> Result<f32, BadValue> {
    match text.parse::<f32>() {
        Ok(v) if v == 0.0 || (1.1..=10.0).contains(&v) => Ok(v),
        _ => Err(BadValue::new(text, "0 (off) or a factor from 1.1 to 10")),
    }
}

/// `--link-depth`: a whole number of buffers from 1 to [`crate::link::MAX_DEPTH`].
pub fn parse_link_depth(s: &str) -> Result<usize, BadValue> {
    let max = crate::link::MAX_DEPTH;
    s.trim()
        .parse::<usize>()
        .ok()
        .filter(|d| (1..=max).contains(d))
        .ok_or_else(|| {
            BadValue::new(
                s,
                format!(
                    "a whole number of buffers from 1 to {max} (each holds one packet of up to {} KB)",
                    scanner_wire::MAX_ENCODED / 1024
                ),
            )
        })
}

/// Seconds, more than 0 and at most a day.
pub fn parse_seconds(s: &str) -> Result<Duration, BadValue> {
    s.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| *v > 0.0 && *v <= 86_400.0)
        .map(Duration::from_secs_f64)
        .ok_or_else(|| BadValue::new(s, "seconds, more than 0 and at most 86400 (a day)"))
}

/// `--wait`: seconds as [`parse_seconds`], or 0 for no wait.
pub fn parse_wait(s: &str) -> Result<Duration, BadValue> {
    if s.trim() == "0" {
        return Ok(Duration::ZERO);
    }
    parse_seconds(s)
}

/// `--mains`: 50 or 60 (Hz).
pub fn parse_mains(s: &str) -> Result<u32, BadValue> {
    match s.trim() {
        "50" => Ok(50),
        "60" => Ok(60),
        _ => Err(BadValue::new(s, "the mains frequency is 50 or 60 (Hz)")),
    }
}

/// A board's grid, `COLSxROWS` (like 9x7): both at least 2, at most
/// [`scanner_core::config::MAX_MARKERS`] in all.
pub fn parse_grid(s: &str) -> Result<(usize, usize), BadValue> {
    let max = scanner_core::config::MAX_MARKERS as u32;
    let (a, b) = crate::source::parse_size(s).map_err(|_| {
        BadValue::new(
            s,
            format!("expected COLSxROWS, like 9x7, with at most {max} in all"),
        )
    })?;
    if a < 2 || b < 2 || a * b > max {
        return Err(BadValue::new(
            s,
            format!("both counts must be at least 2, and there can be at most {max} in all"),
        ));
    }
    Ok((a as usize, b as usize))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_in_and_out_of_range() {
        assert_eq!(edge_reach("4"), Ok(4.0));
        assert!(edge_reach("4.5").is_err());
        assert_eq!(print_ratio("0"), Ok(0.0));
        assert!(print_ratio("1.0").is_err());
        assert_eq!(parse_wait("0"), Ok(Duration::ZERO));
        assert!(parse_seconds("0").is_err());
        assert_eq!(parse_mains(" 60"), Ok(60));
        assert_eq!(parse_grid("9x7"), Ok((9, 7)));
        assert!(parse_grid("1x7").is_err());
        let long = "x".repeat(100);
        assert_eq!(parse_mains(&long).unwrap_err().given.len(), 40);
    }
}
