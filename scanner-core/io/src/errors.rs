//! A failing command's error as data: one line of JSON with each cause's kind, when the
//! environment asks for it.

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

/// A command line its parser refused, as one error: `Debug` reads `Usage(ValueValidation)`, so
/// that its record's kinds are `Usage` and the parser's own kind.
struct UsageError {
    kind: String,
    message: String,
}

impl std::fmt::Debug for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Usage({})", self.kind)
    }
}

impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.message.trim_end())
    }
}

impl std::error::Error for UsageError {}

/// A refused command line as an [`error_record`]: kinds `Usage` and `kind` (the parser's, e.g.
/// clap's `ValueValidation` or `UnknownArgument`), with the parser's words.
pub fn usage_record(program: &str, kind: &str, message: &str) -> String {
    let e = UsageError {
        kind: kind.to_string(),
        message: message.to_string(),
    };
    error_record(program, std::iter::once(&e as &dyn std::error::Error))
}

/// Prints `record` (an [`error_record`]) to standard error when [`ERRORS_ENV`] asks for JSON.
pub fn error_record_if_asked(record: impl FnOnce() -> String) {
    if std::env::var(ERRORS_ENV).is_ok_and(|v| v == "json") {
        crate::errln!("{}", record());
    }
}

#[cfg(test)]
mod tests {
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

    #[test]
    fn a_refused_command_line_is_a_record_of_two_kinds() {
        let line = usage_record(
            "scanner-host",
            "ValueValidation",
            "error: invalid value 'x' for '--sheet <MM>'\n",
        );
        assert_eq!(
            line,
            "{\"program\":\"scanner-host\",\"error\":[{\"kind\":\"Usage::ValueValidation\",\"message\":\"error: invalid value 'x' for '--sheet <MM>'\"}]}"
        );
    }
}
