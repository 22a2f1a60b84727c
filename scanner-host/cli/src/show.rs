//! What the user sees while a command runs: the progress line on the terminal, Ctrl-C, and the
//! live view in a browser.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Result;
use scanner_host::errln;
use scanner_web::live::LiveView;

/// A spinner with the elapsed time and a message (hidden with `quiet`).
pub fn progress_bar(quiet: bool) -> indicatif::ProgressBar {
    if quiet {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::new_spinner();
    pb.set_style(
        indicatif::ProgressStyle::with_template("{spinner} {elapsed} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
    );
    pb
}

/// Set by Ctrl-C (and SIGTERM); the handler is installed once per process.
pub fn interrupted() -> &'static AtomicBool {
    static STOP: AtomicBool = AtomicBool::new(false);
    static INSTALL: std::sync::Once = std::sync::Once::new();
    INSTALL.call_once(|| {
        // Another handler already installed in this process (tests) leaves the flag unset.
        let _ = ctrlc::set_handler(|| STOP.store(true, Ordering::SeqCst));
    });
    &STOP
}

/// Refuses a `--view-for` that is no duration.
pub fn check_view_for(secs: Option<f64>) -> Result<()> {
    match secs {
        Some(s) if !(s.is_finite() && (0.0..=31_536_000.0).contains(&s)) => {
            anyhow::bail!("--view-for must be 0 to 31536000 seconds (a year), found {s}")
        }
        _ => Ok(()),
    }
}

/// Starts the live view and says where it is.
pub fn start_view(addr: SocketAddr) -> Result<LiveView> {
    let v = LiveView::start(addr, &[])?;
    if v.is_public() {
        errln!(
            "warning: the live view is served on {addr}, reachable from other machines on the network; the token in its address is the only key"
        );
    }
    errln!("live view: {}", v.url());
    Ok(v)
}

/// Keeps the live view up after the work: `for_secs`, or until Ctrl-C.
pub fn linger(v: &LiveView, for_secs: Option<f64>) {
    match for_secs {
        Some(s) => errln!("the live view shows the result at {} for {s} s", v.url()),
        None => errln!(
            "the live view shows the result at {}; Ctrl-C to quit",
            v.url()
        ),
    }
    // A Ctrl-C that ended the work does not end the page: the next one does.
    let stop = interrupted();
    stop.store(false, Ordering::SeqCst);
    v.linger(stop, for_secs);
}
