//! `scanner-host`: the host tool's command line. Each command goes arguments ([`args`]), then a
//! checked plan, then the run, which calls the `scanner-host` library (and through it
//! `scanner-merge`) and writes the files; [`show`] is what the user sees meanwhile.
//!
//! # Layers
//! Each module uses only modules on its own line or below (`tests/tests/layers.rs` checks it):
//! ```text
//! studio
//! merge  check
//! receive
//! args  show
//! ```

mod args;
mod check;
mod merge;
mod receive;
mod show;
mod studio;

use std::process::ExitCode;

use anyhow::Result;
use clap::Parser;
use scanner_host::{errln, outln};

use crate::args::{Args, Command};

fn main() -> ExitCode {
    let args = match Args::try_parse() {
        Ok(a) => a,
        Err(e) => {
            let refused = e.use_stderr();
            let _ = e.print();
            if refused {
                scanner_io::error_record_if_asked(|| {
                    scanner_io::usage_record(
                        "scanner-host",
                        &format!("{:?}", e.kind()),
                        &e.to_string(),
                    )
                });
            }
            return ExitCode::from(u8::try_from(e.exit_code()).unwrap_or(2));
        }
    };
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            errln!("scanner-host: error: {e:#}");
            scanner_io::error_record_if_asked(|| {
                scanner_io::error_record("scanner-host", e.chain())
            });
            ExitCode::FAILURE
        }
    }
}

/// Runs a command.
fn run(args: &Args) -> Result<()> {
    if args.info {
        outln!(
            "scanner-host {}: units mm, camera +z forward, +y down",
            env!("CARGO_PKG_VERSION")
        );
        return Ok(());
    }
    match &args.command {
        None => {
            outln!("scanner-host: nothing to do (try --help)");
            Ok(())
        }
        Some(Command::Ports) => receive::ports(),
        Some(Command::Studio(a)) => studio::studio(a),
        Some(Command::Receive {
            input,
            until_done,
            append,
            merge: sweeps,
            turntable,
            min_overlap,
            view,
            view_for,
            out,
        }) => {
            show::check_view_for(*view_for)?;
            // The merge's options are checked before anything is received.
            let merging = scanner_merge::MergeOptions {
                turntable_deg: *turntable,
                min_overlap: *min_overlap,
                ..scanner_merge::MergeOptions::default()
            };
            merging.check()?;
            let plan = receive::ReceivePlan::new(input, (*until_done, *append), *view, out)?;
            let (summary, view) = receive::receive(&plan, !sweeps)?;
            outln!("{}", summary.text().trim_end());
            let merged = if *sweeps {
                merge::sweeps(&plan.out, merging, view.as_ref())
            } else {
                Ok(())
            };
            match view {
                Some(v) => merge::linger(&v, merged, &plan.out.dir.join("model"), *view_for),
                None => merged,
            }
        }
        Some(Command::Merge {
            views,
            out,
            cell,
            voxel,
            fuse_cell,
            min_overlap,
            turntable,
            no_disc,
            sheet,
            trim_unseen,
            flat_base,
            view,
            view_for,
            quiet,
        }) => {
            show::check_view_for(*view_for)?;
            let options = scanner_merge::MergeOptions {
                voxel_mm: *voxel,
                fuse_cell_mm: *fuse_cell,
                min_overlap: *min_overlap,
                turntable_deg: *turntable,
                closing: merge::MergePlan::closing(*trim_unseen, *flat_base),
                sheet: None,
                use_disc: !*no_disc,
            };
            let plan = merge::MergePlan::new(views, out, (*cell, *sheet), options, *quiet)?;
            let view = view.map(show::start_view).transpose()?;
            let merged = merge::run(&plan, view.as_ref());
            match view {
                Some(v) => merge::linger(&v, merged, out, *view_for),
                None => merged,
            }
        }
        Some(Command::Check {
            scan,
            spheres,
            spacing,
            plane,
            size_tolerance,
            form_tolerance,
            flatness_tolerance,
            cell,
            sheet,
            out,
        }) => {
            let plan = check::CheckPlan {
                scan: scan.clone(),
                spheres: spheres.clone(),
                spacing: *spacing,
                plane: *plane,
                tolerances: scanner_host::check::Tolerances {
                    size_pct: *size_tolerance,
                    form_pct: *form_tolerance,
                    flatness_pct: *flatness_tolerance,
                },
                cell: *cell,
                sheet_mm: *sheet,
                out: out.clone(),
            }
            .check()?;
            check::run(&plan)
        }
        Some(Command::Replay { input, out }) => {
            let plan = receive::OutputPlan::new(out)?;
            let summary = receive::replay(input, &plan)?;
            outln!("{}", summary.text().trim_end());
            Ok(())
        }
    }
}
