//! The `foldmatch` command line program (feature `cli`). The binary `src/bin/foldmatch.rs`
//! and the Python console script (`foldmatch`, `python -m foldmatch_rs`) both call [`run`],
//! so there is one implementation.
//!
//! | command | what it does |
//! |---|---|
//! | `fit TEMPLATE SCAN -o OUT` | one fit; `--report FILE` writes its JSON report |
//! | `batch TEMPLATE SCAN_DIR -o OUT_DIR` | every scan of a folder, in parallel, resumable, `OUT_DIR/report.json` |
//! | `sequence TEMPLATE FRAME_DIR -o OUT_DIR` | frames in natural order, each warm-started from the previous fit |
//! | `eval TEMPLATE FITTED SCAN` | the paper's metrics as JSON |
//! | `demo [-o DIR]` | the built-in generated example, fitted, with before/after figures |
//!
//! `batch` and `sequence` with `--scheduler ADDRESS|local` run on a Dask cluster from the
//! Python package only (`foldmatch_rs.distributed`, driven through [`cluster`]); the standalone
//! program says so and exits with 1.
//!
//! Exit status ([`exit_code`]): 0 success, 1 usage or fatal error, 2 partial failure (some
//! files of a batch or sequence failed), 130 interrupted by Ctrl-C.
//!
//! Every output is written atomically (a temporary file in the same folder, renamed into place
//! once complete) and only inside the `-o` path; Ctrl-C stops the fits at their next iteration
//! and leaves no half-written file. Progress bars are drawn on a terminal, plain log lines are
//! printed otherwise (all on standard error; standard output carries only `eval`'s JSON and
//! `demo`'s figures). See `docs/cli.md`.

mod args;
mod batch;
pub mod cluster;
mod demo;
mod eval;
mod files;
mod interrupt;
mod job;
mod lock;
mod report;
mod ui;

pub use args::Cli;

use args::{Command, FitCmd};
use clap::error::ErrorKind;
use job::{Job, Runner, ScanWeights, Template};
use report::{write_json, FitReport, Status};
use std::ffi::OsString;
use std::io::Write;
use std::panic::{catch_unwind, AssertUnwindSafe};
use ui::{Ui, Verbosity};

/// The exit codes of [`run`].
pub mod exit_code {
    /// Every file was fitted (or skipped by `--resume`).
    pub const OK: i32 = 0;
    /// Usage error, or a fatal error: unreadable template or folder, failed `fit` / `eval` /
    /// `demo`, unwritable report.
    pub const FATAL: i32 = 1;
    /// Partial failure: at least one file of a `batch` or `sequence` failed; the others were
    /// written (see the report).
    pub const PARTIAL: i32 = 2;
    /// Interrupted by Ctrl-C (128 + SIGINT, the shell convention).
    pub const INTERRUPTED: i32 = 130;
}

/// What every command gets.
pub(crate) struct Context {
    ui: Ui,
    pool: rayon::ThreadPool,
}

/// Runs the `foldmatch` program with `args` (the first is the program name, as in
/// `std::env::args_os()`) and returns its exit code ([`exit_code`]). Never panics.
///
/// Installs a Ctrl-C handler for the process on first use (see the `interrupt` module).
pub fn run<I, T>(args: I) -> i32
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let cli = match args::parse(args) {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return match e.kind() {
                ErrorKind::DisplayHelp | ErrorKind::DisplayVersion => exit_code::OK,
                _ => exit_code::FATAL,
            };
        }
    };
    let verbosity = if cli.quiet {
        Verbosity::Quiet
    } else if cli.verbose {
        Verbosity::Verbose
    } else {
        Verbosity::Normal
    };
    let _guard = interrupt::Guard::start();
    let outcome = catch_unwind(AssertUnwindSafe(|| dispatch(&cli, verbosity)));
    outcome.unwrap_or_else(|_| {
        let _ = writeln!(
            std::io::stderr(),
            "error: internal error (a bug: please report it with the command line)"
        );
        exit_code::FATAL
    })
}

fn dispatch(cli: &Cli, verbosity: Verbosity) -> i32 {
    let ui = Ui::new(verbosity);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(cli.threads.unwrap_or(0))
        .thread_name(|i| format!("foldmatch-{i}"))
        .build();
    let pool = match pool {
        Ok(p) => p,
        Err(e) => {
            ui.error(format_args!("cannot start the thread pool: {e}"));
            return exit_code::FATAL;
        }
    };
    let ctx = Context { ui, pool };
    match &cli.command {
        Command::Fit(cmd) => fit(cmd, &ctx),
        Command::Batch(cmd) => batch::batch(cmd, &ctx),
        Command::Sequence(cmd) => batch::sequence(cmd, &ctx),
        Command::Eval(cmd) => eval::eval(cmd, &ctx),
        Command::Demo(cmd) => demo::demo(cmd, &ctx),
    }
}

/// `foldmatch fit`.
fn fit(cmd: &FitCmd, ctx: &Context) -> i32 {
    let ui = &ctx.ui;
    let prepared = (|| {
        let params = cmd.params.to_params()?;
        ui.detail(format_args!("parameters: {}", params.to_json()));
        let extension = cmd
            .output
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        if !matches!(extension.as_deref(), Some("ply" | "obj")) {
            return Err(format!(
                "the output {} must end in .ply or .obj",
                cmd.output.display()
            ));
        }
        for (what, input) in [("template", &cmd.template), ("scan", &cmd.scan)] {
            if same_file(input, &cmd.output) {
                return Err(format!(
                    "the output {} is the {what}: choose another -o",
                    cmd.output.display()
                ));
            }
        }
        if let Some(preview) = &cmd.preview {
            let is_png = preview
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("png"));
            if !is_png {
                return Err(format!("--preview {}: must end in .png", preview.display()));
            }
        }
        if let Some(mask) = &cmd.garment_mask {
            let is_npy = mask
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("npy"));
            if !is_npy {
                return Err(format!(
                    "--garment-mask {}: must end in .npy",
                    mask.display()
                ));
            }
        }
        let template = Template::load(&cmd.template, &params)?;
        let landmarks = match &cmd.landmarks {
            Some(path) => Some(
                crate::io::read_landmarks(path)
                    .and_then(|f| f.for_template(path, template.vertices.len()))
                    .map_err(|e| format!("landmarks {e}"))?,
            ),
            None => None,
        };
        Ok((params, template, landmarks))
    })();
    let (params, template, landmarks) = match prepared {
        Ok(p) => p,
        Err(e) => {
            ui.error(e);
            return exit_code::FATAL;
        }
    };
    let runner = Runner {
        template: &template,
        params: &params,
        ui,
        pool: &ctx.pool,
    };
    let outcome = runner.run(&Job {
        stage: None,
        name: cmd.scan.display().to_string(),
        scan: cmd.scan.clone(),
        output: cmd.output.clone(),
        gt: cmd.gt.clone(),
        tracker: None,
        ascii: cmd.ascii,
        weights: ScanWeights::from_options(
            cmd.scan_weights.as_ref(),
            cmd.scan_weights_property.as_ref(),
        ),
        preview: cmd.preview.clone(),
        garment_mask: cmd.garment_mask.clone(),
        scan_normals: cmd.scan_normals,
        landmarks: landmarks.as_ref(),
    });
    let entry = &outcome.report;
    let mut code = match entry.status {
        Status::Ok => {
            let distance = entry.scan_to_fit_note("mean scan-to-fit");
            ui.info(format_args!(
                "fitted {} -> {} ({} iterations, {:.2} s{distance})",
                entry.scan,
                entry.output,
                entry.iterations.unwrap_or(0),
                entry.seconds.unwrap_or(0.0)
            ));
            ui.detail(entry.quality_note());
            if let Some(note) = entry.coherent_note() {
                ui.detail(note);
            }
            if let Some(reasons) = entry.suspicious_reasons() {
                ui.warn(format_args!(
                    "the fit looks wrong (quality verdict suspicious): {}",
                    reasons.join("; ")
                ));
            }
            if let Some(note) = entry.reading_note() {
                ui.info(format_args!("note: {note}"));
            }
            exit_code::OK
        }
        Status::Interrupted => {
            ui.info(format_args!("interrupted: {} not written", entry.output));
            exit_code::INTERRUPTED
        }
        _ => {
            ui.error(entry.error.as_deref().unwrap_or("fit failed"));
            exit_code::FATAL
        }
    };
    if let Some(path) = &cmd.report {
        let report = FitReport {
            foldmatch_version: env!("CARGO_PKG_VERSION"),
            command: "fit",
            template: cmd.template.display().to_string(),
            file: entry,
            params: serde_json::to_value(&params).unwrap_or_default(),
        };
        match write_json(path, &report) {
            Ok(()) => ui.detail(format_args!("wrote {}", path.display())),
            Err(e) => {
                ui.error(format_args!("cannot write the report: {e}"));
                if code == exit_code::OK {
                    code = exit_code::FATAL;
                }
            }
        }
    }
    code
}

/// Whether two paths name the same existing file.
fn same_file(a: &std::path::Path, b: &std::path::Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}
