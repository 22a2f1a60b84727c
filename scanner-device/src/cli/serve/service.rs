//! The dispatcher: each command judged against what runs, answered, and its work started.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Receiver;
use std::time::Duration;

use anyhow::Result;
use scanner_wire::{
    Command, CommandError, CommandFrame, CommandFrameError, HeadState, Message, Outcome,
    PreviewRequest, Reply, WireError,
};

use super::worker::{Change, Worker};
use super::{
    ENDING_GRACE, Ended, Event, LASER_SAFE_AFTER, MAX_SHOTS, MIN_PREVIEW_SIDE, MIN_TARGET_SHOTS,
    READ_POLL, Running, Service, WORKER_STACK, Work,
};

impl Service {
    pub(super) fn state(&self) -> HeadState {
        self.running.as_ref().map_or(HeadState::Idle, |r| r.state)
    }

    pub(super) fn reply(&self, seq: u32, outcome: Outcome, field: u8, detail: i32) -> Reply {
        Reply {
            seq,
            outcome,
            state: self.state(),
            field,
            detail,
        }
    }

    pub(super) fn dispatch(&mut self, rx: &Receiver<Event>) {
        loop {
            let ev = match rx.recv_timeout(READ_POLL) {
                Ok(ev) => ev,
                Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                    self.watch();
                    continue;
                }
                Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break,
            };
            match ev {
                Event::Command(r) => {
                    self.heard = Some(std::time::Instant::now());
                    if let Some(quiet) = self.silenced.take() {
                        self.tell_silenced(quiet);
                    }
                    self.command(r);
                }
                // a job already reaped (replaced by the preview's new settings, or ended
                // while a command waited for it) was settled then
                Event::Ended(id) => {
                    if self.running.as_ref().is_some_and(|r| r.id == id) {
                        self.reap();
                        // the preview a shot interrupted comes back
                        if let Some(p) = self.resume.take() {
                            self.start(Work::Preview(p));
                        }
                    }
                }
                Event::Quit => break,
            }
            self.watch();
        }
        if let Some(r) = &self.running {
            r.stop.store(true, Ordering::SeqCst);
            self.reap();
        }
        crate::errln!("service ended");
    }

    /// Waits for the running work to end and takes what it came to: a shot kept, a calibration
    /// made, its line in the log.
    pub(super) fn reap(&mut self) {
        let Some(r) = self.running.take() else { return };
        let e = r.thread.join().unwrap_or_else(|_| panicked());
        self.settle(e.change);
        match e.result {
            Ok(line) => crate::errln!("{}: {line}", e.what),
            Err(err) => crate::errln!("{} failed: {err:#}", e.what),
        }
    }

    /// `true` when the running work ends within [`ENDING_GRACE`] (then reaped): a command
    /// that came as it ended is decided as if it had come after.
    pub(super) fn ended_within_grace(&mut self) -> bool {
        let Some(r) = &self.running else { return true };
        let until = std::time::Instant::now() + ENDING_GRACE;
        while !r.thread.is_finished() {
            if std::time::Instant::now() >= until {
                return false;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        self.reap();
        true
    }

    /// Switches the lasers off once the host has been silent for [`LASER_SAFE_AFTER`].
    pub(super) fn watch(&mut self) {
        let Some(at) = self.heard else { return };
        let quiet = at.elapsed();
        if quiet < LASER_SAFE_AFTER || self.silenced.is_some() {
            return;
        }
        let was_on = self.laser.swap(false, Ordering::SeqCst);
        self.silenced = Some(quiet);
        crate::errln!(
            "no word from the host for {:.1} s: every laser this head drives is off{}",
            quiet.as_secs_f64(),
            if was_on { "" } else { " (it was)" }
        );
    }

    /// Tells the host that came back that the lasers were switched off for its silence.
    pub(super) fn tell_silenced(&mut self, quiet: Duration) {
        let n = scanner_wire::Notice {
            scan_id: 0,
            kind: scanner_wire::NoticeKind::LaserOffUnheard,
            seconds: u16::try_from(quiet.as_secs()).unwrap_or(u16::MAX),
        };
        if let Err(e) = self.out.send(&Message::Notice(n)) {
            crate::errln!("could not tell the host the laser is off: {e}");
        }
    }

    pub(super) fn send(&mut self, r: Reply) {
        if let Err(e) = self.out.send(&Message::Reply(r)) {
            crate::errln!("could not answer command {}: {e}", r.seq);
        }
    }

    pub(super) fn command(&mut self, r: Result<CommandFrame, CommandFrameError>) {
        let frame = match r {
            Ok(f) => f,
            Err(e) => {
                let reply = match e {
                    CommandFrameError::Command(CommandError::Unknown(seq, v)) => self.reply(
                        seq,
                        Outcome::Unknown,
                        0,
                        i32::try_from(v).unwrap_or(i32::MAX),
                    ),
                    CommandFrameError::Command(CommandError::Malformed(seq)) => {
                        self.reply(seq, Outcome::Malformed, 0, 0)
                    }
                    CommandFrameError::Command(CommandError::Unreadable) => {
                        self.reply(0, Outcome::Malformed, 0, 0)
                    }
                    CommandFrameError::Frame(WireError::Oversize) => {
                        self.reply(0, Outcome::Oversized, 0, scanner_wire::MAX_COMMAND as i32)
                    }
                    CommandFrameError::Frame(WireError::UnknownVersion(v)) => {
                        self.reply(0, Outcome::Version, 0, i32::from(v))
                    }
                    // a damaged frame: its number cannot be trusted; the host sends it again
                    CommandFrameError::Frame(_) => return,
                };
                self.send(reply);
                return;
            }
        };
        if let Some((seq, mut reply)) = self.last
            && seq == frame.seq
        {
            reply.state = self.state();
            self.send(reply);
            return;
        }
        let (reply, job) = match frame.command.check() {
            Err((field, limit)) => (
                self.reply(frame.seq, Outcome::OutOfRange, field, limit),
                None,
            ),
            Ok(()) => self.decide(frame),
        };
        let started = job.is_some();
        if let Some(job) = job {
            self.start(job);
        }
        // the state the reply tells is the one the command leaves
        let reply = Reply {
            state: if started { self.state() } else { reply.state },
            ..reply
        };
        self.send(reply);
        self.last = Some((frame.seq, reply));
    }

    /// What to answer, and the job to start.
    pub(super) fn decide(&mut self, f: CommandFrame) -> (Reply, Option<Work>) {
        let seq = f.seq;
        let ok = |s: &Self| s.reply(seq, Outcome::Accepted, 0, 0);
        let busy = self.running.is_some();
        match f.command {
            Command::Hello => (ok(self), None),
            Command::Stop if self.resume.take().is_some() => (ok(self), None),
            Command::Stop => match &self.running {
                Some(r) => {
                    r.stop.store(true, Ordering::SeqCst);
                    (ok(self), None)
                }
                None => (self.reply(seq, Outcome::NothingToStop, 0, 0), None),
            },
            // the preview a shot interrupted stays off
            Command::Preview(p) if !p.on && self.resume.take().is_some() => (ok(self), None),
            Command::Preview(p) if !p.on => match &self.running {
                Some(r) if r.state == HeadState::Previewing => {
                    r.stop.store(true, Ordering::SeqCst);
                    (ok(self), None)
                }
                _ => (self.reply(seq, Outcome::NothingToStop, 0, 0), None),
            },
            // the camera, the laser and the turntable may change while the preview runs
            // a control set by hand: now on a camera, and for every job after (a sweep's
            // exposure stays as its reference was taken: refused while one runs)
            Command::Camera { control, value } => {
                let Some(c) = scanner_wire::Adjustable::from_u8(control) else {
                    return (self.reply(seq, Outcome::OutOfRange, 1, 3), None);
                };
                if self.state() == HeadState::Sweeping && !self.ended_within_grace() {
                    return (self.reply(seq, Outcome::Busy, 0, 0), None);
                }
                use crate::source::{SourceError, controls::AdjustError};
                match crate::source::adjust_control(&self.args.scan.source, c, value) {
                    Ok(()) => {}
                    Err(SourceError::Control(AdjustError::NotOffered(_))) => {
                        return (self.reply(seq, Outcome::NotHere, 0, 0), None);
                    }
                    Err(SourceError::Control(AdjustError::OutOfRange { min, max, .. })) => {
                        let limit = if i64::from(value) < min { min } else { max };
                        let limit = i32::try_from(limit).unwrap_or(i32::MAX);
                        return (self.reply(seq, Outcome::OutOfRange, 2, limit), None);
                    }
                    Err(e) => {
                        crate::errln!("camera control: {e}");
                        return (self.reply(seq, Outcome::Failed, 0, 0), None);
                    }
                }
                let mut by_hand = self.args.scan.camera.by_hand();
                by_hand.set(c, value);
                self.args.scan.camera.set_by_hand(by_hand);
                // the preview starts again with it: a new reference, taken alike
                let again = if self.previews() {
                    self.stop_preview().map(Work::Preview)
                } else {
                    None
                };
                (ok(self), again)
            }
            Command::Laser { on } => {
                if self.rig_views.is_none() {
                    return (self.reply(seq, Outcome::NotHere, 0, 0), None);
                }
                self.laser.store(on, Ordering::SeqCst);
                (ok(self), None)
            }
            Command::Turn { .. }
                if self.state() == HeadState::Sweeping && !self.ended_within_grace() =>
            {
                (self.reply(seq, Outcome::Busy, 0, 0), None)
            }
            Command::Turn { steps } => match self.rig_views {
                Some(views) if views > 1 => {
                    let n = views as i64;
                    let from = self.view;
                    self.view = (self.view as i64 + i64::from(steps)).rem_euclid(n) as usize;
                    // the answer tells where the turntable stands (from 1) and the angle
                    // it turned, hundredths of a degree
                    let turned = match (self.rig_turns.get(from), self.rig_turns.get(self.view)) {
                        (Some(a), Some(b)) => {
                            ((b * a.inverse()).angle().to_degrees() * 100.0).round() as i32
                        }
                        _ => scanner_wire::TURN_UNKNOWN,
                    };
                    let at = u8::try_from(self.view + 1).unwrap_or(u8::MAX);
                    (self.reply(seq, Outcome::Accepted, at, turned), None)
                }
                _ => (self.reply(seq, Outcome::NotHere, 0, 0), None),
            },
            // the preview's new settings (a zoom): the running preview makes way
            Command::Preview(_) if self.previews() => {
                self.stop_preview();
                self.decide(f)
            }
            // a shot or the calibration while the preview runs: the preview makes way and
            // comes back after it
            Command::Shot { .. } | Command::Calibrate if self.previews() => {
                let preview = self.stop_preview();
                let (reply, job) = self.decide(f);
                match (job, preview) {
                    (Some(job), p) => {
                        self.resume = p;
                        (reply, Some(job))
                    }
                    // refused: the preview goes on as it was
                    (None, p) => (reply, p.map(Work::Preview)),
                }
            }
            _ if busy && self.ended_within_grace() => self.decide(f),
            _ if busy => (self.reply(seq, Outcome::Busy, 0, 0), None),
            Command::Preview(p) => {
                let (w, h) = self.frame_size;
                let largest = (w.min(h) / MIN_PREVIEW_SIDE).max(1);
                if usize::from(p.scale) > largest {
                    return (
                        self.reply(seq, Outcome::OutOfRange, 3, largest as i32),
                        None,
                    );
                }
                (ok(self), Some(Work::Preview(p)))
            }
            Command::Shot { board } => {
                let kept = if board {
                    self.board_shots
                } else {
                    self.target_shots
                };
                if kept >= MAX_SHOTS {
                    return (
                        self.reply(seq, Outcome::OutOfRange, 1, i32::from(MAX_SHOTS)),
                        None,
                    );
                }
                (ok(self), Some(Work::Shot { seq, board }))
            }
            Command::Calibrate => {
                if self.target_shots < MIN_TARGET_SHOTS {
                    return (
                        self.reply(seq, Outcome::TooFewShots, 1, i32::from(MIN_TARGET_SHOTS)),
                        None,
                    );
                }
                if self.board_shots == 0 {
                    return (self.reply(seq, Outcome::TooFewShots, 2, 1), None);
                }
                (ok(self), Some(Work::Calibrate { seq }))
            }
            Command::Sweep(s) => {
                if self.calibration.is_none() {
                    return (self.reply(seq, Outcome::NotCalibrated, 0, 0), None);
                }
                (ok(self), Some(Work::Sweep(s)))
            }
        }
    }

    /// Whether the preview runs.
    fn previews(&self) -> bool {
        self.running
            .as_ref()
            .is_some_and(|r| r.state == HeadState::Previewing)
    }

    /// Stops the running preview and waits for it; its settings.
    fn stop_preview(&mut self) -> Option<PreviewRequest> {
        if let Some(r) = &self.running {
            r.stop.store(true, Ordering::SeqCst);
            self.reap();
        }
        self.previewing.take()
    }

    pub(super) fn start(&mut self, job: Work) {
        let stop = Arc::new(AtomicBool::new(false));
        self.previewing = match job {
            Work::Preview(p) => Some(p),
            _ => None,
        };
        let state = match job {
            Work::Preview(_) => HeadState::Previewing,
            Work::Sweep(_) => HeadState::Sweeping,
            Work::Shot { .. } | Work::Calibrate { .. } => HeadState::Calibrating,
        };
        let mut scan = self.args.scan.clone();
        scan.calibration = self.calibration.clone();
        if self.rig_views.is_some_and(|v| v > 1) {
            scan.view = Some(self.view);
        }
        let w = Worker {
            scan,
            args: self.args.clone(),
            out: self.out.clone(),
            stop: stop.clone(),
            laser: self.laser.clone(),
        };
        let shots = (self.target_shots, self.board_shots);
        let tx = self.events.clone();
        self.jobs += 1;
        let id = self.jobs;
        let spawned = std::thread::Builder::new()
            .name("worker".into())
            .stack_size(WORKER_STACK)
            .spawn(move || {
                // a panic in the work (a bug) ends it like an error: the service goes on
                let ended =
                    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| w.run(job, shots)))
                        .unwrap_or_else(|_| panicked());
                let _ = tx.send(Event::Ended(id));
                ended
            });
        match spawned {
            Ok(thread) => {
                self.running = Some(Running {
                    id,
                    state,
                    stop,
                    thread,
                })
            }
            Err(e) => crate::errln!("cannot start the worker: {e}"),
        }
    }

    /// What an ended job changes: a shot kept, a calibration made.
    pub(super) fn settle(&mut self, change: Change) {
        match change {
            Change::Nothing => {}
            Change::Kept { board: true } => self.board_shots += 1,
            Change::Kept { board: false } => self.target_shots += 1,
            Change::Calibrated(path) => self.calibration = Some(path),
        }
    }
}

/// What work that panicked (a bug) came to.
fn panicked() -> Ended {
    Ended {
        what: "work",
        result: Err(anyhow::anyhow!(
            "stopped on an internal error (a bug; its message is above)"
        )),
        change: Change::Nothing,
    }
}
