//! A `batch` or `sequence` whose fits run elsewhere: the Dask path of the Python package
//! (`foldmatch_rs.distributed`). The driver plans the run and keeps its report with a
//! [`RunBook`] (the local commands' setup, report, log lines, progress bar, summary and exit
//! code); each worker fits files with a [`FileFitter`] (the local commands' `Runner`), so the
//! outputs are the local commands' bit for bit and the report has the same schema.

use super::args::{Command, ParamArgs};
use super::batch::{finish, log_file, setup, Setup, Shared, Source};
use super::job::{read_named, stage_path, Job, Outcome, Runner, ScanWeights, Template};
use super::lock::OutputLock;
use super::report::{RunReport, Status};
use super::ui::{Bar, Ui};

pub use super::report::FileReport;
pub use super::ui::Verbosity;
use crate::fit::FitParams;
use crate::track::{TrackParams, Tracker, TrackerState};
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

/// Which command a run does.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RunKind {
    /// Every scan independently (`foldmatch batch`).
    Batch,
    /// Frames in order, each warm-started from the previous fit (`foldmatch sequence`).
    Sequence,
}

impl RunKind {
    fn name(self) -> &'static str {
        match self {
            Self::Batch => "batch",
            Self::Sequence => "sequence",
        }
    }

    /// The preset when none is given (as the local commands).
    fn default_preset(self) -> &'static str {
        match self {
            Self::Batch => "default",
            Self::Sequence => "tracking",
        }
    }
}

/// A run to plan, as the Python package sends it (JSON); the options of `foldmatch batch` and
/// `foldmatch sequence`.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Request {
    /// `batch` or `sequence`.
    pub command: RunKind,
    /// The template mesh.
    pub template: PathBuf,
    /// The folder of scans or frames (or `files`).
    #[serde(default)]
    pub input_dir: Option<PathBuf>,
    /// The scans or frames, in this order (or `input_dir`).
    #[serde(default)]
    pub files: Option<Vec<PathBuf>>,
    /// The output folder.
    pub output: PathBuf,
    /// `--resume`.
    #[serde(default)]
    pub resume: bool,
    /// `--recursive` (batch).
    #[serde(default)]
    pub recursive: bool,
    /// `--glob`.
    #[serde(default)]
    pub glob: Option<String>,
    /// `--format`: `ply` or `obj`.
    #[serde(default = "ply")]
    pub format: String,
    /// `--ascii`.
    #[serde(default)]
    pub ascii: bool,
    /// `--gt-dir`.
    #[serde(default)]
    pub gt_dir: Option<PathBuf>,
    /// `--preset` (none: the command's default).
    #[serde(default)]
    pub preset: Option<String>,
    /// `--params FILE`.
    #[serde(default)]
    pub params_file: Option<PathBuf>,
    /// Parameters by their `FitParams` names (the flags, `--set`); they override the file.
    #[serde(default)]
    pub params: Map<String, Value>,
    /// `--scan-weights-property`: the per-vertex PLY property that weighs every scan's points.
    #[serde(default)]
    pub scan_weights_property: Option<String>,
    /// `sequence`'s tracking rules (`--prediction`, `--reanchor`).
    #[serde(default)]
    pub tracking: TrackOptions,
}

/// The tracking rules of a `sequence` run ([`crate::track::TrackParams`] beyond the fit's
/// settings), as `foldmatch sequence --prediction/--reanchor` sets them.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TrackOptions {
    /// `--prediction`.
    pub prediction: f64,
    /// `--reanchor`.
    pub reanchor: bool,
}

impl Default for TrackOptions {
    fn default() -> Self {
        Self {
            prediction: crate::track::DEFAULT_PREDICTION,
            reanchor: false,
        }
    }
}

fn ply() -> String {
    "ply".into()
}

impl Request {
    /// The run that `argv` asks of a Dask cluster (`batch` or `sequence` with `--scheduler`),
    /// with the scheduler's address and the global options; `None` for anything else,
    /// including a command line that does not parse (the local program reports it).
    pub fn from_cli(argv: Vec<String>) -> Option<CliRun> {
        let cli = super::args::parse(argv).ok()?;
        // A batch and a sequence plan alike but for their kind, their folder and recursion.
        macro_rules! folder_run {
            ($cmd:ident, $kind:expr, $input_dir:expr, $recursive:expr) => {
                Self {
                    command: $kind,
                    template: $cmd.template,
                    input_dir: Some($input_dir),
                    files: None,
                    output: $cmd.output,
                    resume: $cmd.resume,
                    recursive: $recursive,
                    glob: $cmd.glob,
                    format: $cmd.format.extension().into(),
                    ascii: $cmd.ascii,
                    gt_dir: $cmd.gt_dir,
                    preset: $cmd.params.preset.clone(),
                    params_file: $cmd.params.params.clone(),
                    params: $cmd.params.overrides(),
                    scan_weights_property: $cmd.scan_weights_property,
                    tracking: TrackOptions::default(),
                }
            };
        }
        let (request, scheduler, jobs) = match cli.command {
            Command::Batch(cmd) => (
                folder_run!(cmd, RunKind::Batch, cmd.scan_dir, cmd.recursive),
                cmd.scheduler?,
                cmd.jobs,
            ),
            Command::Sequence(cmd) => {
                let tracking = TrackOptions {
                    prediction: cmd.prediction,
                    reanchor: cmd.reanchor,
                };
                let mut run = folder_run!(cmd, RunKind::Sequence, cmd.frame_dir, false);
                run.tracking = tracking;
                (run, cmd.scheduler?, None)
            }
            _ => return None,
        };
        Some(CliRun {
            request,
            scheduler,
            workers: jobs.map(usize::from),
            threads: cli.threads,
            verbosity: if cli.quiet {
                "quiet"
            } else if cli.verbose {
                "verbose"
            } else {
                "normal"
            },
        })
    }

    fn param_args(&self) -> ParamArgs {
        ParamArgs {
            preset: self.preset.clone(),
            params: self.params_file.clone(),
            set: self.params.clone().into_iter().collect(),
            ..ParamArgs::default()
        }
    }
}

/// What the Python console script needs to run a command line on a Dask cluster.
#[derive(Clone, Debug, Serialize)]
pub struct CliRun {
    /// The run.
    pub request: Request,
    /// `--scheduler`: `local` or an address.
    pub scheduler: String,
    /// `--jobs` (batch): the workers of a local cluster.
    pub workers: Option<usize>,
    /// `--threads`: the fit threads of each task.
    pub threads: Option<usize>,
    /// `quiet`, `normal` or `verbose`.
    pub verbosity: &'static str,
}

/// One file for a worker.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Planned {
    /// Its place in the report.
    pub index: usize,
    /// The report's name (relative path).
    pub name: String,
    /// The scan.
    pub scan: PathBuf,
    /// The output.
    pub output: PathBuf,
    /// Ground truth for f_R.
    pub gt: Option<PathBuf>,
    /// `sequence --resume`: the earlier run's entry, when its output may be reused (the worker
    /// reads it back to warm-start the next frame, or fits it again when it cannot).
    pub resumed: Option<FileReport>,
    /// `--scan-weights-property`: the scan's per-vertex property that weighs its points.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scan_weights_property: Option<String>,
}

/// The driver's side of a run: its plan, its report (`OUT_DIR/report.json`, kept up to date as
/// files finish), the log lines and the progress bar.
pub struct RunBook {
    kind: RunKind,
    ui: Ui,
    setup: Setup,
    gt_dir: Option<PathBuf>,
    scan_weights_property: Option<String>,
    tracking: TrackOptions,
    live: Mutex<Live>,
}

struct Live {
    shared: Shared,
    /// The output folder's lock, released by [`RunBook::finish`] (not when Python collects
    /// the book).
    lock: Option<OutputLock>,
    done: usize,
    bar: Bar,
    code: Option<i32>,
}

impl RunBook {
    /// Plans `request`: reads the template, finds the scans, resolves the parameters, reads the
    /// earlier report (`resume`) and writes the first report (every file pending, or skipped
    /// when an earlier batch did it). Errors are the local commands' fatal errors.
    pub fn start(request: &Request, verbosity: Verbosity) -> Result<Self, String> {
        let ui = Ui::new(verbosity);
        let source = match (&request.input_dir, &request.files) {
            (Some(dir), None) => Source::Folder {
                dir,
                recursive: request.recursive,
                glob: request.glob.as_deref(),
            },
            (None, Some(files)) => {
                if request.recursive || request.glob.is_some() {
                    return Err(
                        "recursive and glob apply to a folder, not to a list of files".into(),
                    );
                }
                Source::Files(files)
            }
            _ => return Err("give either a folder or a list of files".into()),
        };
        if !matches!(request.format.as_str(), "ply" | "obj") {
            return Err(format!(
                "format {:?}: expected \"ply\" or \"obj\"",
                request.format
            ));
        }
        let kind = request.command;
        let mut setup = setup(
            &ui,
            &request.param_args(),
            kind.default_preset(),
            &request.template,
            source,
            &request.output,
            &request.format,
            request.resume,
        )?;
        let n = setup.found.len();
        let files: Vec<FileReport> = (0..n)
            .map(|i| match kind {
                RunKind::Batch => setup.resumable(i),
                RunKind::Sequence => None,
            })
            .enumerate()
            .map(|(i, resumed)| {
                resumed.unwrap_or_else(|| {
                    FileReport::pending(
                        &setup.found[i].name,
                        &setup.found[i].path,
                        &setup.outputs[i],
                    )
                })
            })
            .collect();
        let shared = Shared::start(setup.report(kind.name(), files), &setup.report_path)?;
        let mut done = 0;
        for entry in shared
            .report
            .files
            .iter()
            .filter(|e| e.status == Status::Skipped)
        {
            done += 1;
            log_file(&ui, done, n, entry);
        }
        let bar = ui.files_bar(n);
        bar.set(done);
        Ok(Self {
            kind,
            gt_dir: request.gt_dir.clone(),
            scan_weights_property: request.scan_weights_property.clone(),
            tracking: request.tracking,
            live: Mutex::new(Live {
                shared,
                lock: setup.lock.take(),
                done,
                bar,
                code: None,
            }),
            ui,
            setup,
        })
    }

    fn live(&self) -> MutexGuard<'_, Live> {
        self.live.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The files to send to workers, in order: a batch's files still to fit, or every frame of
    /// a sequence.
    pub fn files(&self) -> Vec<Planned> {
        let live = self.live();
        let setup = &self.setup;
        (0..setup.found.len())
            .filter(|&i| live.shared.report.files[i].status == Status::Pending)
            .map(|i| Planned {
                index: i,
                name: setup.found[i].name.clone(),
                scan: setup.found[i].path.clone(),
                output: setup.outputs[i].clone(),
                gt: setup.gt_for(self.gt_dir.as_deref(), i),
                resumed: match self.kind {
                    RunKind::Batch => None,
                    RunKind::Sequence => setup.resumable(i),
                },
                scan_weights_property: self.scan_weights_property.clone(),
            })
            .collect()
    }

    /// The resolved parameters, every key, as JSON (what the workers fit with).
    pub fn params_json(&self) -> String {
        self.setup.params.to_json()
    }

    /// A sequence's tracking rules as JSON ([`TrackOptions`], for [`FileFitter::track`]).
    pub fn tracking_json(&self) -> String {
        serde_json::to_string(&self.tracking).unwrap_or_default()
    }

    /// The template's path.
    pub fn template(&self) -> &Path {
        &self.setup.template.path
    }

    /// Where the report is written.
    pub fn report_path(&self) -> &Path {
        &self.setup.report_path
    }

    /// The number of files of the run.
    pub fn total(&self) -> usize {
        self.setup.found.len()
    }

    /// Prints a normal line (not when quiet), above the progress bar.
    pub fn info(&self, message: &str) {
        self.ui.info(message);
    }

    /// Records a finished file: its log line, the bar, the report (rewritten atomically), then
    /// commits the output the worker staged (`stage_path`) as the local commands do: renamed
    /// into place once the report records it, removed when the entry is not `ok`. `index` is
    /// [`Planned::index`].
    pub fn record(&self, index: usize, entry: FileReport) -> Result<(), String> {
        if index >= self.total() {
            return Err(format!("file index {index} out of 0..{}", self.total()));
        }
        let output = &self.setup.outputs[index];
        let stage = stage_path(output);
        let mut live = self.live();
        live.done += 1;
        log_file(&self.ui, live.done, self.total(), &entry);
        live.bar.inc();
        live.bar.message(&entry.name);
        live.shared.record(index, entry, &[(stage, output.clone())]);
        Ok(())
    }

    /// Records a file whose task failed on the cluster (its worker died too often, or the task
    /// itself raised): an `error` entry with `message`.
    pub fn record_failure(&self, index: usize, message: &str) -> Result<(), String> {
        let Some(found) = self.setup.found.get(index) else {
            return Err(format!("file index {index} out of 0..{}", self.total()));
        };
        let entry = FileReport::failed(
            &found.name,
            &found.path,
            &self.setup.outputs[index],
            format!("{}: {message}", found.path.display()),
        );
        self.record(index, entry)
    }

    /// Writes the last report, prints the summary, releases the output folder's lock and
    /// returns the exit code ([`super::exit_code`]) with the report; `interrupted` when the run
    /// was stopped before every file was attempted. A second call returns the first call's
    /// code.
    pub fn finish(&self, interrupted: bool) -> (i32, RunReport) {
        let mut live = self.live();
        if live.code.is_none() {
            live.bar.finish();
            let code = finish(&self.ui, &mut live.shared, self.kind.name(), interrupted);
            live.code = Some(code);
            live.lock = None;
        }
        (live.code.unwrap_or_default(), live.shared.report.clone())
    }
}

/// The worker's side: the template and parameters of a run, loaded once, and a thread pool of
/// its own (never rayon's global pool, which does not survive a `fork`).
pub struct FileFitter {
    template: Template,
    params: FitParams,
    pool: rayon::ThreadPool,
    ui: Ui,
}

impl FileFitter {
    /// Loads the template for `params_json` ([`RunBook::params_json`]), with a pool of
    /// `threads` threads (at least one).
    pub fn new(template: &Path, params_json: &str, threads: usize) -> Result<Self, String> {
        let params = FitParams::from_json(params_json).map_err(|e| e.to_string())?;
        let template = Template::load(template, &params)?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads.max(1))
            .thread_name(|i| format!("foldmatch-task-{i}"))
            .build()
            .map_err(|e| format!("cannot start {threads} threads: {e}"))?;
        Ok(Self {
            template,
            params,
            pool,
            ui: Ui::new(Verbosity::Quiet),
        })
    }

    /// The number of template vertices.
    pub fn vertex_count(&self) -> usize {
        self.template.vertices.len()
    }

    /// Fits one file exactly as `batch` does, writing the output to its staged path
    /// (`stage_path`) for [`RunBook::record`] to commit; never fails: problems are in the
    /// entry.
    pub fn fit(&self, file: &Planned, ascii: bool) -> Outcome {
        self.runner().run(&self.job(file, ascii, None))
    }

    /// Fits one frame of a sequence exactly as `sequence` does: by a [`Tracker`] with the
    /// run's `tracking` rules that continues from `state` (the previous frame's task's; `None`
    /// for the first frame), the entry's warm start named `warm_name`. Returns the outcome and
    /// the state for the next frame (after a failed frame, the tracker's skip: the next frame
    /// starts from the last fit). Never fails: problems are in the entry.
    pub fn track(
        &self,
        file: &Planned,
        ascii: bool,
        tracking: TrackOptions,
        state: Option<TrackerState>,
        warm_name: Option<&str>,
    ) -> (Outcome, TrackerState) {
        let rules = TrackParams {
            fit: self.params.clone(),
            prediction: tracking.prediction,
            reanchor: tracking.reanchor,
            ..TrackParams::default()
        };
        let tracker =
            Tracker::new(&self.template.vertices, &self.template.faces, rules).and_then(|mut t| {
                if let Some(state) = state.clone() {
                    t.restore(state)?;
                }
                Ok(t)
            });
        let tracker = match tracker {
            Ok(t) => Mutex::new(t),
            Err(e) => {
                let outcome = Outcome {
                    report: FileReport::failed(
                        &file.name,
                        &file.scan,
                        &file.output,
                        format!("sequence: {e}"),
                    ),
                    fitted: None,
                    metrics: None,
                };
                return (outcome, state.unwrap_or_default());
            }
        };
        let before = state.as_ref().map_or(0, |s| s.frames);
        let mut outcome = self.runner().run(&self.job(file, ascii, Some(&tracker)));
        outcome.report.warm_start = warm_name.map(str::to_string);
        let mut t = tracker.into_inner().unwrap_or_else(|e| e.into_inner());
        if t.frames() == before {
            // Failed before its fit (an unreadable scan): the tracker did not see it.
            t.skip();
        }
        (outcome, t.state())
    }

    /// A sequence frame done by an earlier run (`sequence --resume`), taken as the tracker's
    /// next fit: the state that follows `state`.
    pub fn accept(&self, state: Option<TrackerState>, fitted: &[[f64; 3]]) -> TrackerState {
        let mut state = state.unwrap_or_default();
        state.previous.insert(0, fitted.to_vec());
        state.previous.truncate(2);
        state.frames += 1;
        state
    }

    fn runner(&self) -> Runner<'_> {
        Runner {
            template: &self.template,
            params: &self.params,
            ui: &self.ui,
            pool: &self.pool,
        }
    }

    fn job<'a>(&self, file: &Planned, ascii: bool, tracker: Option<&'a Mutex<Tracker>>) -> Job<'a> {
        Job {
            name: file.name.clone(),
            scan: file.scan.clone(),
            output: file.output.clone(),
            gt: file.gt.clone(),
            tracker,
            ascii,
            weights: file
                .scan_weights_property
                .clone()
                .map(ScanWeights::Property),
            landmarks: None,
            // The driver renames it into place once its report records it (`RunBook::record`).
            stage: Some(stage_path(&file.output)),
            // `--preview` conflicts with `--scheduler` (args.rs): previews are local only.
            preview: None,
            garment_mask: None,
            scan_normals: false,
        }
    }

    /// `sequence --resume`: the frame's earlier output, read back to warm-start the next
    /// frame, and its entry (skipped, named after `warm_name`); an error (the local command's
    /// warning) when it cannot be read or does not match the template, and the frame is then
    /// fitted again.
    pub fn resume_frame(
        &self,
        file: &Planned,
        warm_name: Option<&str>,
    ) -> Result<(FileReport, Vec<[f64; 3]>), String> {
        let Some(entry) = &file.resumed else {
            return Err(format!("{}: nothing to resume", file.name));
        };
        let mesh = read_named("resumed frame", &file.output)?;
        if mesh.vertices.len() != self.vertex_count() {
            return Err(format!(
                "{}: vertex count differs from the template; fitting it again",
                file.output.display()
            ));
        }
        let mut entry = entry.clone();
        entry.warm_start = warm_name.map(str::to_string);
        Ok((entry, mesh.vertices))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parameters_cross_processes_bit_for_bit() {
        for name in ["default", "accurate", "fast", "paper", "tracking"] {
            let p = FitParams::preset(name).unwrap();
            let back = FitParams::from_json(&p.to_json()).unwrap();
            assert_eq!(back, p, "{name}");
        }
        // A value whose shortest decimal form has 17 digits.
        let p = {
            let mut p = FitParams::default();
            p.model.psi = 0.1 + 0.2 - 0.3 + 0.07;
            p
        };
        assert_eq!(
            FitParams::from_json(&p.to_json())
                .unwrap()
                .model
                .psi
                .to_bits(),
            p.model.psi.to_bits()
        );
    }

    #[test]
    fn the_cli_asks_for_a_cluster_only_with_scheduler() {
        let argv = |s: &str| s.split(' ').map(String::from).collect::<Vec<_>>();
        assert!(Request::from_cli(argv("foldmatch batch t.ply d -o o")).is_none());
        assert!(Request::from_cli(argv("foldmatch batch t.ply -o o --scheduler local")).is_none());
        let run = Request::from_cli(argv(
            "foldmatch -q --threads 1 batch t.ply d -o o --scheduler tcp://h:8786 --jobs 3 \
             --resume --iterations 7 --set psi=0.2 --format obj",
        ))
        .unwrap();
        assert_eq!(run.scheduler, "tcp://h:8786");
        assert_eq!(
            (run.workers, run.threads, run.verbosity),
            (Some(3), Some(1), "quiet")
        );
        let r = &run.request;
        assert_eq!(r.command, RunKind::Batch);
        assert!(r.resume && r.format == "obj");
        assert_eq!(r.params["iterations"], Value::from(7));
        assert_eq!(r.params["psi"], Value::from(0.2));
        let text = serde_json::to_string(r).unwrap();
        let back: Request = serde_json::from_str(&text).unwrap();
        let params = back.param_args().to_params_over("default").unwrap();
        assert_eq!((params.iterations, params.model.psi), (7, 0.2));
        assert_eq!(back.scan_weights_property, None);
        let run = Request::from_cli(argv(
            "foldmatch sequence t.ply f -o o --scheduler local --scan-weights-property label",
        ))
        .unwrap();
        assert_eq!(run.request.command, RunKind::Sequence);
        assert_eq!(run.request.command.default_preset(), "tracking");
        assert_eq!(run.request.scan_weights_property.as_deref(), Some("label"));
        let text = serde_json::to_string(&run.request).unwrap();
        let back: Request = serde_json::from_str(&text).unwrap();
        assert_eq!(back.scan_weights_property.as_deref(), Some("label"));
        assert_eq!(back.tracking, TrackOptions::default());
        // The tracking rules travel to the workers.
        let run = Request::from_cli(argv(
            "foldmatch sequence t.ply f -o o --scheduler local --prediction 0.25 --reanchor",
        ))
        .unwrap();
        let text = serde_json::to_string(&run.request).unwrap();
        let back: Request = serde_json::from_str(&text).unwrap();
        assert_eq!(
            back.tracking,
            TrackOptions {
                prediction: 0.25,
                reanchor: true
            }
        );
    }
}
