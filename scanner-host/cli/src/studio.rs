//! `studio`: the head started (or reached over its cable), the job opened from its project
//! folder, the page served until Ctrl-C; the page's merge is [`crate::merge`]'s.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use scanner_host::outln;
use scanner_web::studio::head::HeadLink;
use scanner_web::studio::job::Job;
use scanner_web::studio::{MergeFailed, MergeFn, Studio, StudioServer};

use crate::args::StudioArgs;

/// A merge's error as the studio shows it: the merge's refusal typed (the page words it),
/// anything else in the merge's words.
fn refusal_of(e: anyhow::Error) -> MergeFailed {
    let e = match e.downcast::<scanner_host::views::ViewsError>() {
        Ok(scanner_host::views::ViewsError::Merge(refused)) => {
            return MergeFailed::Refused(refused);
        }
        Ok(other) => anyhow::Error::from(other),
        Err(e) => e,
    };
    match e.downcast::<scanner_merge::MergeError>() {
        Ok(refused) => MergeFailed::Refused(refused),
        Err(e) => MergeFailed::Other(format!("{e:#}")),
    }
}

/// How often the studio asks the head how it is.
const HEARTBEAT: Duration = Duration::from_millis(500);

/// The head this studio started, ended with it.
struct ChildHead(Child);

impl Drop for ChildHead {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

type Ends = (Box<dyn Read + Send>, Box<dyn Write + Send>);

/// Runs the studio until Ctrl-C or `--for-secs`.
///
/// # Errors
/// The project folder, the head or the address cannot be opened.
pub fn studio(a: &StudioArgs) -> Result<()> {
    if let Some(s) = a.for_secs
        && !(s > 0.0 && s <= 1e7)
    {
        bail!("--for-secs must be positive, found {s}");
    }
    std::fs::create_dir_all(&a.project)
        .with_context(|| format!("cannot create the project folder {}", a.project.display()))?;
    let job = Job::open(&a.project)?;
    let (ends, _child, _pty) = open_head(a)?;
    let link = HeadLink::start(ends.0, ends.1, job, a.project.clone())
        .context("cannot start the head's reader")?;
    let merge: MergeFn = Box::new(|views: &[PathBuf], out: &Path, min_overlap: f64| {
        let options = scanner_merge::MergeOptions {
            min_overlap,
            ..scanner_merge::MergeOptions::default()
        };
        let plan = crate::merge::MergePlan::new(
            views,
            out,
            (None, scanner_host::views::Thickness::Mm(0.0)),
            options,
            true,
        )
        .map_err(|e| MergeFailed::Other(format!("{e:#}")))?;
        crate::merge::run(&plan, None).map_err(refusal_of)
    });
    let studio = Arc::new(Studio::new(link, merge));
    let server = StudioServer::start(a.listen, &a.allow_host, studio.clone())?;
    outln!(
        "studio: open {} (project {})",
        server.url,
        a.project.display()
    );
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        let _ = ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst));
    }
    // a heartbeat: the head's state on the page follows what it does (a sweep that ended, the
    // preview stopped), and a silent head is seen as such
    {
        let (studio, stop) = (studio.clone(), stop.clone());
        std::thread::Builder::new()
            .name("heartbeat".into())
            .spawn(move || {
                let mut restored = false;
                while !stop.load(Ordering::SeqCst) {
                    let answered = studio
                        .link
                        .ask(scanner_wire::Command::Hello, Duration::from_secs(2))
                        .is_ok();
                    // the job's camera controls, once the head first answers
                    if answered && !restored {
                        studio.restore_camera();
                        restored = true;
                    }
                    if !answered {
                        let mut job = studio.link.shared.job();
                        job.head.heard = false;
                    }
                    std::thread::sleep(HEARTBEAT);
                }
            })
            .context("cannot start the heartbeat")?;
    }
    let t0 = Instant::now();
    while !stop.load(Ordering::SeqCst) && a.for_secs.is_none_or(|s| t0.elapsed().as_secs_f64() < s)
    {
        std::thread::sleep(Duration::from_millis(100));
    }
    server.stop();
    // what the job holds is on disk already; once more for the log's last lines
    let job = studio.link.shared.job();
    job.save(&a.project)?;
    Ok(())
}

/// The link's two ends, and what keeps them open: a child head (pipes or a pseudo-terminal),
/// or a serial port.
fn open_head(a: &StudioArgs) -> Result<(Ends, Option<ChildHead>, Option<serialport::TTYPort>)> {
    if a.head != "child" {
        let spec = scanner_io::link_spec::SerialSpec::parse(&a.head)
            .map_err(|e| anyhow::anyhow!("--head {:?}: {e}", a.head))?
            .ok_or_else(|| {
                anyhow::anyhow!("--head {:?}: give child or serial:PATH[@BAUD]", a.head)
            })?;
        let port = serialport::new(spec.path, spec.baud)
            .timeout(Duration::from_millis(200))
            .open_native()
            .with_context(|| format!("cannot open the head's port {}", spec.path))?;
        let writer = port.try_clone_native().context("cannot share the port")?;
        return Ok(((Box::new(port), Box::new(writer)), None, None));
    }
    let exe = std::env::current_exe()
        .context("cannot find this program")?
        .with_file_name("scanner-device");
    if !exe.exists() {
        bail!(
            "--head child needs scanner-device beside scanner-host ({} is missing): build both (cargo build --release)",
            exe.display()
        );
    }
    let log = a.project.join("head.log");
    let err = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&log)
        .with_context(|| format!("cannot write {}", log.display()))?;
    let mut cmd = std::process::Command::new(&exe);
    cmd.arg("serve").args(["--source", &a.source]);
    if let Some(size) = &a.size {
        cmd.args(["--size", size]);
    }
    cmd.args(a.head_args.split_whitespace())
        .arg("--work")
        .arg(a.project.join("head"))
        .stderr(err);
    if a.pty {
        use serialport::SerialPort;
        let (mut ours, theirs) = serialport::TTYPort::pair().context("a pseudo-terminal pair")?;
        ours.set_timeout(Duration::from_millis(200))?;
        let name = theirs.name().context("the pseudo-terminal's name")?;
        let child = cmd
            .arg("--out")
            .arg(format!("serial:{name}"))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .spawn()
            .with_context(|| format!("cannot start {}", exe.display()))?;
        let writer = ours
            .try_clone_native()
            .context("cannot share the pseudo-terminal")?;
        return Ok((
            (Box::new(ours), Box::new(writer)),
            Some(ChildHead(child)),
            Some(theirs),
        ));
    }
    let mut child = cmd
        .args(["--out", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .with_context(|| format!("cannot start {}", exe.display()))?;
    let (Some(input), Some(output)) = (child.stdout.take(), child.stdin.take()) else {
        bail!("the head's pipes did not open");
    };
    Ok((
        (Box::new(input), Box::new(output)),
        Some(ChildHead(child)),
        None,
    ))
}
