//! A job's thread: a preview or a sweep (the shots and the calibration in [`super::shots`]).

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Result;
use scanner_core::stripe::PixelFormat;
use scanner_wire::{MAX_ENCODED, PreviewRequest, SweepRequest};

use super::super::scan::{ScanArgs, open_on, open_source, source_format};
use crate::link::Link;
use crate::preview::{PreviewOptions, run_preview};
use crate::source::{FrameSource, OwnedFrame, SourceError};

use super::{Ended, ServeArgs, SharedOut, Work};

/// What a worker's job leaves for the next commands.
pub(crate) enum Change {
    Nothing,
    Kept { board: bool },
    Calibrated(PathBuf),
}

/// A job's thread: the service's settings and its share of the link.
pub(super) struct Worker {
    pub(super) scan: ScanArgs,
    pub(super) args: ServeArgs,
    pub(super) out: SharedOut,
    pub(super) stop: Arc<AtomicBool>,
    pub(super) laser: Arc<AtomicBool>,
}

impl Worker {
    pub(super) fn run(self, job: Work, shots: (u16, u16)) -> Ended {
        match job {
            Work::Preview(p) => Ended {
                what: "preview",
                result: self.preview(p),
                change: Change::Nothing,
            },
            Work::Sweep(s) => Ended {
                what: "sweep",
                result: self.sweep(s),
                change: Change::Nothing,
            },
            Work::Shot { seq, board } => {
                let kept = if board { shots.1 } else { shots.0 };
                match self.shot(seq, board, kept) {
                    Ok((line, keep)) => Ended {
                        what: "shot",
                        result: Ok(line),
                        change: if keep {
                            Change::Kept { board }
                        } else {
                            Change::Nothing
                        },
                    },
                    Err(e) => Ended {
                        what: "shot",
                        result: Err(e),
                        change: Change::Nothing,
                    },
                }
            }
            Work::Calibrate { seq } => match self.calibrate(seq, shots) {
                Ok((line, path)) => Ended {
                    what: "calibration",
                    result: Ok(line),
                    change: path.map_or(Change::Nothing, Change::Calibrated),
                },
                Err(e) => Ended {
                    what: "calibration",
                    result: Err(e),
                    change: Change::Nothing,
                },
            },
        }
    }

    pub(super) fn link(&self) -> Link {
        Link::spawn(
            Box::new(self.out.clone()),
            self.scan.link_depth,
            MAX_ENCODED,
        )
    }

    pub(super) fn sweep(&self, s: SweepRequest) -> Result<String> {
        let mut a = self.scan.clone();
        a.disc = match s.disc {
            1 => Some(scanner_calib::disc::Paper::A4),
            2 => Some(scanner_calib::disc::Paper::A3),
            _ => None,
        };
        // 0: as the head was started (`--rows`, `--columns`, or found from the first frame)
        if s.axis != 0 {
            a.rows = s.axis == 1;
            a.columns = s.axis == 2;
        }
        a.colour = s.colour;
        a.keep_board = s.keep_board;
        a.frames = (s.frames > 0).then_some(s.frames);
        a.scan_id = None;
        let mut plan = super::super::scan::plan_on(&a, self.link())?;
        plan.stop.flag = Some(self.stop.clone());
        let report = crate::scan::run(plan, |_| {})?;
        Ok(format!(
            "{} frames, {} points{}",
            report.status.frames,
            report.status.points,
            report
                .ended_early
                .as_ref()
                .map(|e| format!("; {e}"))
                .unwrap_or_default()
        ))
    }

    pub(super) fn preview(&self, p: PreviewRequest) -> Result<String> {
        let mut a = self.scan.clone();
        a.scan_id = None;
        let mut o = open_on(&a, Some(self.link()))?;
        let options = PreviewOptions {
            scan_id: o.scan_id,
            every: u32::from(p.every),
            head: o.head,
            find_axis: o.find_axis,
            scale: usize::from(p.scale),
            picture: p.picture.then_some(p.zoom),
        };
        o.stop.flag = Some(self.stop.clone());
        let reopen = {
            let a = a.clone();
            move || -> Result<Box<dyn FrameSource>, SourceError> {
                let opts = a
                    .camera
                    .options()
                    .map_err(|e| SourceError::BadSpec(e.to_string()))?;
                let format =
                    source_format(&a, &opts).map_err(|e| SourceError::BadSpec(format!("{e:#}")))?;
                open_source(&a, format, &opts).map_err(|e| SourceError::BadSpec(format!("{e:#}")))
            }
        };
        let mut source = Endless {
            inner: o.source,
            reopen: Box::new(reopen),
            laser: self.laser.clone(),
            reference: None,
            count: 0,
        };
        let cal = o.calibration.as_ref();
        let report = run_preview(&mut source, cal, options, &mut o.link, &o.stop, |_| {})?;
        o.link.finish()?;
        Ok(format!(
            "{} frames, {} pictures",
            report.frames, report.previews
        ))
    }
}

/// The source forever: a source that ends (the rig, a folder) starts again; with the laser
/// switched off (the rig), each frame is the laser-off picture.
pub(super) struct Endless {
    inner: Box<dyn FrameSource>,
    reopen: Box<dyn FnMut() -> Result<Box<dyn FrameSource>, SourceError> + Send>,
    laser: Arc<AtomicBool>,
    reference: Option<OwnedFrame>,
    count: u64,
}

impl FrameSource for Endless {
    fn describe(&self) -> String {
        self.inner.describe()
    }

    fn format(&self) -> PixelFormat {
        self.inner.format()
    }

    fn size(&self) -> (usize, usize) {
        self.inner.size()
    }

    fn controls(&self) -> scanner_wire::Controls {
        self.inner.controls()
    }

    fn reference(&mut self) -> Result<OwnedFrame, SourceError> {
        let r = self.inner.reference()?;
        self.reference = Some(r.clone());
        Ok(r)
    }

    fn next_frame(&mut self) -> Result<Option<OwnedFrame>, SourceError> {
        self.count += 1;
        if !self.laser.load(Ordering::SeqCst)
            && let Some(r) = &self.reference
        {
            return Ok(Some(OwnedFrame {
                index: self.count,
                ..r.clone()
            }));
        }
        if let Some(f) = self.inner.next_frame()? {
            return Ok(Some(f));
        }
        self.inner = (self.reopen)()?;
        self.inner.next_frame()
    }

    fn pace(&self) -> Option<crate::source::CameraPace> {
        self.inner.pace()
    }

    fn give_back(&mut self, frame: OwnedFrame) {
        self.inner.give_back(frame);
    }
}
