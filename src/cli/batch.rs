//! `foldmatch batch` (every scan of a folder, in parallel) and `foldmatch sequence` (the frames
//! of a folder in order, each warm-started from the previous fit).
//!
//! Both keep `OUT_DIR/report.json` valid at all times: it is written (atomically) before the
//! first file, rewritten (atomically) as each file finishes, and written a last time at the
//! end, so an interrupted or killed run still leaves a report of what was done.
//!
//! An output is committed in two steps: the fitted mesh (and its `--preview` image) is written
//! to a staged file next to it ([`stage_path`]), the report that records it as done is written, and only then is the
//! staged file renamed to the output. So every output in the folder is recorded as done by
//! the report (a `kill -9` never leaves an unrecorded output that `--resume` would fit again),
//! and a kill between the two steps leaves a recorded staged file, which `--resume` renames
//! into place instead of fitting it again.
//!
//! Both hold the output folder's lock ([`OutputLock`]) for as long as they run, and `--resume`
//! refuses an earlier report written with other parameters or another template: the outputs
//! of one folder are always of one parameter set.

use super::args::{BatchCmd, ParamArgs, SequenceCmd};
use super::files::{find_scans, named_files, output_paths, Found};
use super::interrupt;
use super::job::{
    garment_mask_path, preview_path, read_named, stage_path, Job, Runner, ScanWeights, Template,
};
use super::lock::OutputLock;
use super::report::{write_json, FileReport, RunReport, RunState, Status, Summary};
use super::ui::Ui;
use super::{exit_code, Context};
use crate::fit::FitParams;
use crate::track::{TrackParams, Tracker};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// Where the scans of a run come from.
pub(super) enum Source<'a> {
    /// Every `.ply` / `.obj` file of a folder (natural order).
    Folder {
        /// The folder.
        dir: &'a Path,
        /// Also look into subfolders.
        recursive: bool,
        /// Only the files matching this pattern.
        glob: Option<&'a str>,
    },
    /// These files, in this order (named from the folder that holds them all).
    Files(&'a [PathBuf]),
}

/// What `batch` and `sequence` share before the first fit.
pub(super) struct Setup {
    pub(super) params: FitParams,
    pub(super) template: Template,
    pub(super) found: Vec<Found>,
    pub(super) outputs: Vec<PathBuf>,
    pub(super) input_dir: PathBuf,
    pub(super) out_dir: PathBuf,
    pub(super) report_path: PathBuf,
    previous: HashMap<String, FileReport>,
    /// Held until the run ends (the Dask path's `RunBook` releases it when it finishes).
    pub(super) lock: Option<OutputLock>,
}

#[allow(clippy::too_many_arguments)]
pub(super) fn setup(
    ui: &Ui,
    params: &ParamArgs,
    default_preset: &str,
    template: &Path,
    source: Source<'_>,
    out_dir: &Path,
    extension: &str,
    resume: bool,
) -> Result<Setup, String> {
    let params = params.to_params_over(default_preset)?;
    ui.detail(format_args!("parameters: {}", params.to_json()));
    let template = Template::load(template, &params)?;
    let (input_dir, found) = match source {
        Source::Folder {
            dir,
            recursive,
            glob,
        } => (
            dir.to_path_buf(),
            folder_scans(dir, out_dir, recursive, glob)?,
        ),
        Source::Files(paths) => named_files(paths)?,
    };
    std::fs::create_dir_all(out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    let lock = OutputLock::acquire(out_dir)?;
    if let Some(owner) = &lock.stale {
        ui.detail(format_args!(
            "{}: taking over the lock of a run that did not end cleanly ({owner})",
            lock.path.display()
        ));
    }
    let outputs = output_paths(&found, out_dir, extension);
    for (scan, output) in found.iter().zip(&outputs) {
        if scan.path.canonicalize().ok() == output.canonicalize().ok() && output.exists() {
            return Err(format!(
                "the output {} is the scan {}: choose another -o",
                output.display(),
                scan.path.display()
            ));
        }
    }
    let report_path = out_dir.join("report.json");
    let mut previous = HashMap::new();
    if resume {
        if report_path.exists() {
            match RunReport::load(&report_path) {
                Ok(old) => {
                    check_same_run(&old, &params, template.path.as_path(), &report_path)?;
                    previous = old.files.into_iter().map(|f| (f.name.clone(), f)).collect();
                }
                Err(e) => ui.warn(format_args!("--resume: {e}; starting over")),
            }
        } else {
            ui.info(format_args!(
                "--resume: no {} yet; fitting every file",
                report_path.display()
            ));
        }
    }
    Ok(Setup {
        params,
        template,
        found,
        outputs,
        input_dir,
        out_dir: out_dir.to_path_buf(),
        report_path,
        previous,
        lock: Some(lock),
    })
}

/// The scans of a folder, which must not be the output folder.
fn folder_scans(
    input_dir: &Path,
    out_dir: &Path,
    recursive: bool,
    glob: Option<&str>,
) -> Result<Vec<Found>, String> {
    if !input_dir.is_dir() {
        return Err(match std::fs::metadata(input_dir) {
            Err(e) => format!("{}: {e}", input_dir.display()),
            Ok(_) => format!("{}: not a folder", input_dir.display()),
        });
    }
    if let (Ok(a), Ok(b)) = (input_dir.canonicalize(), out_dir.canonicalize()) {
        if a == b {
            return Err(format!(
                "the output folder {} is the input folder: choose another -o",
                out_dir.display()
            ));
        }
    }
    let found = find_scans(input_dir, recursive, glob, Some(out_dir))?;
    if found.is_empty() {
        let filter = glob.map(|g| format!(" matching {g:?}")).unwrap_or_default();
        return Err(format!(
            "{}: no .ply or .obj files{filter}",
            input_dir.display()
        ));
    }
    Ok(found)
}

/// `--resume` continues a run only with the same parameters and template: otherwise the
/// folder would hold outputs of two parameter sets under a report that names one.
fn check_same_run(
    old: &RunReport,
    params: &FitParams,
    template: &Path,
    report_path: &Path,
) -> Result<(), String> {
    let new = serde_json::to_value(params).unwrap_or_default();
    let mut differences: Vec<String> = Vec::new();
    if let (Some(a), Some(b)) = (old.params.as_object(), new.as_object()) {
        for (key, value) in b {
            match a.get(key) {
                Some(v) if v == value => {}
                Some(v) => differences.push(format!("{key} {v} -> {value}")),
                None => differences.push(format!("{key} (new) {value}")),
            }
        }
    } else if old.params != new {
        differences.push("params".into());
    }
    if old.template != template.display().to_string() {
        differences.push(format!(
            "template {} -> {}",
            old.template,
            template.display()
        ));
    }
    if differences.is_empty() {
        return Ok(());
    }
    let shown = differences.len().min(5);
    let more = if differences.len() > shown {
        format!(" and {} more", differences.len() - shown)
    } else {
        String::new()
    };
    Err(format!(
        "--resume: {} was written with other settings ({}{more}); resume with the same \
         parameters and template, or run without --resume to fit every file again",
        report_path.display(),
        differences[..shown].join(", ")
    ))
}

impl Setup {
    /// The entry carried over from the earlier run when `--resume` may skip the file. An
    /// output (or preview) the earlier run recorded but had not yet renamed into place (killed
    /// between the two steps) is renamed now; a staged file it had not recorded is removed.
    pub(super) fn resumable(&self, i: usize) -> Option<FileReport> {
        let old = self.previous.get(&self.found[i].name);
        let done = old.is_some_and(|o| o.status.is_done());
        let output = &self.outputs[i];
        for path in [output.clone(), preview_path(output)] {
            let staged = stage_path(&path);
            if staged.is_file() {
                if done {
                    let _ = std::fs::rename(&staged, &path);
                } else {
                    let _ = std::fs::remove_file(&staged);
                }
            }
        }
        let old = old?;
        if !done || !self.outputs[i].is_file() {
            return None;
        }
        let mut entry = old.clone();
        entry.status = Status::Skipped;
        entry.scan = self.found[i].path.display().to_string();
        entry.output = self.outputs[i].display().to_string();
        Some(entry)
    }

    pub(super) fn gt_for(&self, gt_dir: Option<&Path>, i: usize) -> Option<PathBuf> {
        let p = gt_dir?.join(&self.found[i].name);
        p.is_file().then_some(p)
    }

    pub(super) fn report(&self, command: &str, files: Vec<FileReport>) -> RunReport {
        RunReport {
            foldmatch_version: env!("CARGO_PKG_VERSION").into(),
            command: command.into(),
            template: self.template.path.display().to_string(),
            input_dir: self.input_dir.display().to_string(),
            output_dir: self.out_dir.display().to_string(),
            state: RunState::Running,
            seconds: 0.0,
            summary: Summary::of(&files),
            params: serde_json::to_value(&self.params).unwrap_or_default(),
            suspicious: Vec::new(),
            files,
        }
    }
}

/// The report shared by the workers.
pub(super) struct Shared {
    pub(super) report: RunReport,
    path: PathBuf,
    started: Instant,
    write_error: Option<String>,
}

impl Shared {
    /// Starts a run's report and writes it once (state `running`), so an interrupted run
    /// still leaves a valid report; an error when it cannot be written.
    pub(super) fn start(report: RunReport, path: &Path) -> Result<Self, String> {
        let now = Instant::now();
        let mut shared = Self {
            report,
            path: path.to_path_buf(),
            started: now,
            write_error: None,
        };
        shared.write(RunState::Running);
        if let Some(e) = shared.write_error.take() {
            return Err(format!("cannot write the report: {e}"));
        }
        Ok(shared)
    }

    fn write(&mut self, state: RunState) {
        self.report.state = state;
        self.report.seconds = self.started.elapsed().as_secs_f64();
        self.report.summary = Summary::of(&self.report.files);
        self.report.suspicious = self
            .report
            .files
            .iter()
            .filter(|f| f.status.is_done() && f.suspicious_reasons().is_some())
            .map(|f| f.name.clone())
            .collect();
        if let Err(e) = write_json(&self.path, &self.report) {
            self.write_error = Some(e);
        }
    }

    /// Records a finished file and writes the report (atomically), then commits its staged
    /// outputs (`commits`: staged path → final path, the mesh first, then its preview):
    /// renamed into place only once the report that records them is on disk. A failed rename
    /// turns the entry into an error and the files not yet renamed are removed.
    pub(super) fn record(&mut self, i: usize, entry: FileReport, commits: &[(PathBuf, PathBuf)]) {
        let mut ok = entry.status == Status::Ok;
        self.report.files[i] = entry;
        self.write(RunState::Running);
        for (stage, output) in commits.iter().filter(|(s, _)| s.is_file()) {
            if !ok {
                let _ = std::fs::remove_file(stage);
                continue;
            }
            if let Err(e) = std::fs::rename(stage, output) {
                let _ = std::fs::remove_file(stage);
                ok = false;
                let entry = &mut self.report.files[i];
                entry.status = Status::Error;
                entry.error = Some(format!("{}: {e}", output.display()));
                self.write(RunState::Running);
            }
        }
    }
}

/// One log line per finished file.
pub(super) fn log_file(ui: &Ui, done: usize, total: usize, entry: &FileReport) {
    let width = total.to_string().len();
    let head = format!("[{done:>width$}/{total}]");
    match entry.status {
        Status::Ok => {
            let distance = entry.scan_to_fit_note("scan-to-fit");
            ui.info(format_args!(
                "{head} ok      {} -> {} ({} it, {:.2} s{distance})",
                entry.name,
                entry.output,
                entry.iterations.unwrap_or(0),
                entry.seconds.unwrap_or(0.0)
            ));
            ui.detail(format_args!("{head} {}", entry.quality_note()));
            if let Some(reasons) = entry.suspicious_reasons() {
                ui.warn(format_args!(
                    "{head} {} looks wrong (quality verdict suspicious): {}",
                    entry.name,
                    reasons.join("; ")
                ));
            }
            if let Some(note) = entry.reading_note() {
                ui.detail(format_args!("{head} {}: {note}", entry.name));
            }
        }
        Status::Error => ui.error(format_args!(
            "{head} {}: {}",
            entry.name,
            entry.error.as_deref().unwrap_or("?")
        )),
        Status::Skipped => ui.detail(format_args!(
            "{head} skipped {} (done by an earlier run)",
            entry.name
        )),
        Status::Interrupted => ui.info(format_args!("{head} stopped {} (interrupted)", entry.name)),
        Status::Pending => {}
    }
}

/// Exit code and summary line of a finished run.
/// `interrupted`: the run was stopped (Ctrl-C) before every file was attempted.
pub(super) fn finish(ui: &Ui, shared: &mut Shared, what: &str, interrupted: bool) -> i32 {
    // An attempt killed while writing its staged output (a Dask worker that died, an earlier run
    // killed before this `--resume`) left a temporary file: no write is under way now.
    let folders: std::collections::BTreeSet<&Path> = shared
        .report
        .files
        .iter()
        .filter_map(|f| Path::new(&f.output).parent())
        .collect();
    for folder in folders {
        crate::io::remove_torn_writes(folder, |target| {
            target.starts_with('.') && target.contains(".staged.")
        });
    }
    shared.write(if interrupted {
        RunState::Interrupted
    } else {
        RunState::Complete
    });
    let s = &shared.report.summary;
    let failed: Vec<&str> = shared
        .report
        .files
        .iter()
        .filter(|f| f.status == Status::Error)
        .map(|f| f.name.as_str())
        .collect();
    ui.info(format_args!(
        "{what}: {} ok, {} failed, {} skipped{}{} in {:.1} s; report: {}",
        s.ok,
        s.error,
        s.skipped,
        if s.interrupted + s.pending > 0 {
            format!(", {} not done", s.interrupted + s.pending)
        } else {
            String::new()
        },
        if interrupted { " (interrupted)" } else { "" },
        shared.report.seconds,
        shared.path.display()
    ));
    if !failed.is_empty() {
        ui.error(format_args!(
            "{} of {} files failed: {}",
            failed.len(),
            s.total,
            failed.join(", ")
        ));
    }
    let suspicious = &shared.report.suspicious;
    if !suspicious.is_empty() {
        ui.warn(format_args!(
            "{} of {} fits look wrong (quality verdict suspicious; the report says why): {}",
            suspicious.len(),
            s.total,
            suspicious.join(", ")
        ));
    }
    if let Some(e) = &shared.write_error {
        ui.error(format_args!("cannot write the report: {e}"));
    }
    if interrupted {
        exit_code::INTERRUPTED
    } else if shared.write_error.is_some() {
        exit_code::FATAL
    } else if !failed.is_empty() {
        exit_code::PARTIAL
    } else {
        exit_code::OK
    }
}

/// `foldmatch batch`.
pub fn batch(cmd: &BatchCmd, ctx: &Context) -> i32 {
    let ui = &ctx.ui;
    if let Some(address) = &cmd.scheduler {
        return needs_python(ui, "batch", address);
    }
    let setup = match setup(
        ui,
        &cmd.params,
        "default",
        &cmd.template,
        Source::Folder {
            dir: &cmd.scan_dir,
            recursive: cmd.recursive,
            glob: cmd.glob.as_deref(),
        },
        &cmd.output,
        cmd.format.extension(),
        cmd.resume,
    ) {
        Ok(s) => s,
        Err(e) => {
            ui.error(e);
            return exit_code::FATAL;
        }
    };
    let n = setup.found.len();
    let mut files = Vec::with_capacity(n);
    let mut todo = Vec::new();
    for i in 0..n {
        match setup.resumable(i) {
            Some(entry) => files.push(entry),
            None => {
                files.push(FileReport::pending(
                    &setup.found[i].name,
                    &setup.found[i].path,
                    &setup.outputs[i],
                ));
                todo.push(i);
            }
        }
    }
    let jobs = cmd
        .jobs
        .map(usize::from)
        .unwrap_or_else(default_jobs)
        .min(todo.len())
        .max(1);
    ui.info(format_args!(
        "batch: {n} scans in {}, {} to fit, {jobs} at a time -> {}",
        cmd.scan_dir.display(),
        todo.len(),
        setup.out_dir.display()
    ));
    let shared = match Shared::start(setup.report("batch", files), &setup.report_path) {
        Ok(s) => s,
        Err(e) => {
            ui.error(e);
            return exit_code::FATAL;
        }
    };
    let done = AtomicUsize::new(0);
    for entry in shared
        .report
        .files
        .iter()
        .filter(|e| e.status == Status::Skipped)
    {
        log_file(ui, done.fetch_add(1, Ordering::Relaxed) + 1, n, entry);
    }
    let shared = Mutex::new(shared);
    let files_bar = ui.files_bar(n);
    files_bar.set(done.load(Ordering::Relaxed));
    let runner = Runner {
        template: &setup.template,
        params: &setup.params,
        ui,
        pool: &ctx.pool,
    };
    let next = AtomicUsize::new(0);
    std::thread::scope(|scope| {
        for _ in 0..jobs {
            scope.spawn(|| loop {
                if interrupt::requested() {
                    break;
                }
                let k = next.fetch_add(1, Ordering::SeqCst);
                let Some(&i) = todo.get(k) else { break };
                let job = Job {
                    name: setup.found[i].name.clone(),
                    scan: setup.found[i].path.clone(),
                    output: setup.outputs[i].clone(),
                    gt: setup.gt_for(cmd.gt_dir.as_deref(), i),
                    tracker: None,
                    ascii: cmd.ascii,
                    weights: cmd.scan_weights_property.clone().map(ScanWeights::Property),
                    landmarks: None,
                    stage: Some(stage_path(&setup.outputs[i])),
                    preview: cmd.preview.then(|| preview_path(&setup.outputs[i])),
                    garment_mask: cmd
                        .garment_masks
                        .then(|| garment_mask_path(&setup.outputs[i])),
                    scan_normals: cmd.scan_normals,
                };
                let outcome = runner.run(&job);
                let finished = done.fetch_add(1, Ordering::SeqCst) + 1;
                log_file(ui, finished, n, &outcome.report);
                files_bar.inc();
                files_bar.message(&job.name);
                shared.lock().unwrap_or_else(|p| p.into_inner()).record(
                    i,
                    outcome.report,
                    &job.commits(),
                );
            });
        }
    });
    files_bar.finish();
    finish(
        ui,
        &mut shared.into_inner().unwrap_or_else(|p| p.into_inner()),
        "batch",
        interrupt::requested(),
    )
}

/// `--scheduler` given to the standalone program: the Dask path lives in the Python package.
fn needs_python(ui: &Ui, command: &str, address: &str) -> i32 {
    ui.error(format_args!(
        "--scheduler {address}: running on a Dask cluster needs the Python package \
         and Dask (pip install 'dask[distributed]', then `python -m foldmatch_rs {command} ... \
         --scheduler {address}`); see docs/cluster.md"
    ));
    exit_code::FATAL
}

/// Default `--jobs`: one file per core, at most 4 (each fit is itself parallel).
fn default_jobs() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .min(4)
}

/// `foldmatch sequence`.
pub fn sequence(cmd: &SequenceCmd, ctx: &Context) -> i32 {
    let ui = &ctx.ui;
    if let Some(address) = &cmd.scheduler {
        return needs_python(ui, "sequence", address);
    }
    let setup = match setup(
        ui,
        &cmd.params,
        // Warm-started frames start close to their scans: no softening annealing.
        "tracking",
        &cmd.template,
        Source::Folder {
            dir: &cmd.frame_dir,
            recursive: false,
            glob: cmd.glob.as_deref(),
        },
        &cmd.output,
        cmd.format.extension(),
        cmd.resume,
    ) {
        Ok(s) => s,
        Err(e) => {
            ui.error(e);
            return exit_code::FATAL;
        }
    };
    let n = setup.found.len();
    ui.info(format_args!(
        "sequence: {n} frames in {} ({} … {}) -> {}",
        cmd.frame_dir.display(),
        setup.found[0].name,
        setup.found[n - 1].name,
        setup.out_dir.display()
    ));
    let files = (0..n)
        .map(|i| {
            FileReport::pending(
                &setup.found[i].name,
                &setup.found[i].path,
                &setup.outputs[i],
            )
        })
        .collect();
    let mut shared = match Shared::start(setup.report("sequence", files), &setup.report_path) {
        Ok(s) => s,
        Err(e) => {
            ui.error(e);
            return exit_code::FATAL;
        }
    };
    let runner = Runner {
        template: &setup.template,
        params: &setup.params,
        ui,
        pool: &ctx.pool,
    };
    let files_bar = ui.files_bar(n);
    // One tracker for the whole sequence (docs/method.md "Tracking"): every frame starts from
    // the previous fits and is anchored to the template.
    let rules = TrackParams {
        fit: setup.params.clone(),
        prediction: cmd.prediction,
        reanchor: cmd.reanchor,
        ..TrackParams::default()
    };
    let tracker = match Tracker::new(&setup.template.vertices, &setup.template.faces, rules) {
        Ok(t) => Mutex::new(t),
        Err(e) => {
            ui.error(format_args!("sequence: {e}"));
            return exit_code::FATAL;
        }
    };
    // The name of the last frame fitted (or resumed), the next one's warm start.
    let mut warm: Option<String> = None;
    for i in 0..n {
        if interrupt::requested() {
            break;
        }
        let name = setup.found[i].name.clone();
        if let Some(mut entry) = setup.resumable(i) {
            match read_named("resumed frame", &setup.outputs[i]) {
                Ok(mesh) if mesh.vertices.len() == setup.template.vertices.len() => {
                    entry.warm_start = warm.clone();
                    log_file(ui, i + 1, n, &entry);
                    shared.record(i, entry, &[]);
                    let mut t = tracker.lock().unwrap_or_else(|e| e.into_inner());
                    if let Err(e) = t.accept(&mesh.vertices) {
                        ui.warn(format_args!("{}: {e}", setup.outputs[i].display()));
                        t.skip();
                    }
                    warm = Some(name);
                    files_bar.inc();
                    continue;
                }
                Ok(_) => ui.warn(format_args!(
                    "{}: vertex count differs from the template; fitting it again",
                    setup.outputs[i].display()
                )),
                Err(e) => ui.warn(format_args!("{e}; fitting it again")),
            }
        }
        let job = Job {
            name: name.clone(),
            scan: setup.found[i].path.clone(),
            output: setup.outputs[i].clone(),
            gt: setup.gt_for(cmd.gt_dir.as_deref(), i),
            tracker: Some(&tracker),
            ascii: cmd.ascii,
            weights: cmd.scan_weights_property.clone().map(ScanWeights::Property),
            landmarks: None,
            stage: Some(stage_path(&setup.outputs[i])),
            preview: None,
            garment_mask: cmd
                .garment_masks
                .then(|| garment_mask_path(&setup.outputs[i])),
            scan_normals: false,
        };
        let before = tracker.lock().map_or(i, |t| t.frames());
        let mut outcome = runner.run(&job);
        outcome.report.warm_start = warm.clone();
        log_file(ui, i + 1, n, &outcome.report);
        shared.record(i, outcome.report, &job.commits());
        let mut t = tracker.lock().unwrap_or_else(|e| e.into_inner());
        if t.frames() == before {
            // Failed before its fit (an unreadable scan): the tracker did not see it.
            t.skip();
        }
        if outcome.fitted.is_some() {
            warm = Some(name);
        }
        files_bar.inc();
    }
    files_bar.finish();
    finish(ui, &mut shared, "sequence", interrupt::requested())
}
