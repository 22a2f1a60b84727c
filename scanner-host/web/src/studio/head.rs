//! The studio's end of the link to the head: commands out, numbered and sent again until
//! answered; everything the head sends in, by a reader thread, to the job.

use std::collections::HashMap;
use std::io::{Read, Write};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use scanner_wire::{
    Command, CommandFrame, Decoder, MAX_COMMAND_ENCODED, MAX_ENCODED, Message, Reply,
    encode_command,
};

use super::job::{Job, Journals, take};

/// How long the studio waits for a reply before sending the command again.
const RESEND: Duration = Duration::from_millis(300);

/// Why a command got no answer.
#[derive(Debug, thiserror::Error)]
pub enum HeadError {
    /// Nothing came back in time (the cable, the head not running).
    #[error("the head did not answer within {0:?}: is it running and its cable plugged in?")]
    NoAnswer(Duration),
    /// The command could not be written.
    #[error("cannot write to the head")]
    Write(#[source] std::io::Error),
}

/// What the reader and the commands share.
pub struct LinkState {
    /// The job.
    pub job: Mutex<Job>,
    /// The project folder.
    pub project: PathBuf,
    replies: Mutex<HashMap<u32, Reply>>,
    answered: Condvar,
    /// The link's input ended.
    pub closed: AtomicBool,
}

impl LinkState {
    /// The job, locked (a thread that panicked while holding it left it whole: every change
    /// is one assignment).
    pub fn job(&self) -> std::sync::MutexGuard<'_, Job> {
        self.job
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// The studio's link to the head.
pub struct HeadLink {
    writer: Mutex<Box<dyn Write + Send>>,
    seq: AtomicU32,
    /// The state both threads see.
    pub shared: Arc<LinkState>,
}

impl HeadLink {
    /// Starts the reader on `input`; commands go to `output`.
    ///
    /// # Errors
    /// The reader thread cannot start.
    pub fn start(
        input: Box<dyn Read + Send>,
        output: Box<dyn Write + Send>,
        job: Job,
        project: PathBuf,
    ) -> std::io::Result<HeadLink> {
        let shared = Arc::new(LinkState {
            job: Mutex::new(job),
            project,
            replies: Mutex::new(HashMap::new()),
            answered: Condvar::new(),
            closed: AtomicBool::new(false),
        });
        let s = shared.clone();
        std::thread::Builder::new()
            .name("head-reader".into())
            .spawn(move || read_loop(input, &s))?;
        Ok(HeadLink {
            writer: Mutex::new(output),
            // numbers start from the clock, so that a restarted studio does not reuse the
            // number the head answered last
            seq: AtomicU32::new(
                std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(1, |d| (d.as_millis() as u32) | 1),
            ),
            shared,
        })
    }

    /// Sends a command and waits for its reply, sending it again (same number) every
    /// 300 ms until one comes or `within` passes.
    ///
    /// # Errors
    /// [`HeadError`]: no answer, or the link cannot be written.
    pub fn ask(&self, command: Command, within: Duration) -> Result<Reply, HeadError> {
        let seq = self.seq.fetch_add(1, Ordering::SeqCst).max(1);
        let mut frame = [0u8; MAX_COMMAND_ENCODED];
        let n = encode_command(&CommandFrame { seq, command }, &mut frame)
            .expect("a command fits its frame");
        let t0 = Instant::now();
        loop {
            {
                let mut w = self
                    .writer
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner);
                w.write_all(&frame[..n])
                    .and_then(|()| w.flush())
                    .map_err(HeadError::Write)?;
            }
            let mut replies = self
                .shared
                .replies
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            let until = Instant::now() + RESEND;
            while Instant::now() < until {
                if let Some(r) = replies.remove(&seq) {
                    return Ok(r);
                }
                let left = until.saturating_duration_since(Instant::now());
                replies = self
                    .shared
                    .answered
                    .wait_timeout(replies, left)
                    .unwrap_or_else(std::sync::PoisonError::into_inner)
                    .0;
            }
            if t0.elapsed() >= within {
                return Err(HeadError::NoAnswer(within));
            }
        }
    }
}

fn read_loop(mut input: Box<dyn Read + Send>, s: &LinkState) {
    let mut d = Box::new(Decoder::<MAX_ENCODED>::new());
    let mut journals = Journals::default();
    let mut buf = vec![0u8; 64 * 1024];
    loop {
        let n = match input.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::TimedOut
                        | std::io::ErrorKind::Interrupted
                        | std::io::ErrorKind::WouldBlock
                ) =>
            {
                continue;
            }
            // a pulled cable: try again after a moment (nothing received is lost: the
            // journals hold it)
            Err(_) => {
                std::thread::sleep(Duration::from_millis(200));
                continue;
            }
        };
        d.feed(&buf[..n], |m| {
            let Ok(msg) = m else { return };
            // the job first, then the waiting command: a page that reads the job after its
            // command's answer sees what the answer changed
            {
                let mut job = s
                    .job
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner);
                match take(&mut job, &mut journals, &s.project, &msg) {
                    Ok(u) if u.save => {
                        if let Err(e) = job.save(&s.project) {
                            job.say(e.to_string());
                        }
                    }
                    Ok(_) => {}
                    Err(e) => job.say(e.to_string()),
                }
            }
            if let Message::Reply(r) = &msg {
                let mut replies = s
                    .replies
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner);
                if replies.len() > 1024 {
                    replies.clear();
                }
                replies.insert(r.seq, *r);
                s.answered.notify_all();
            }
        });
    }
    journals.close();
    s.closed.store(true, Ordering::SeqCst);
}
