//! The command line grammar (clap derive). Doc comments are the help text; every fit
//! parameter is a flag whose value, when given, overrides the default (or `--params FILE`).

use crate::fit::FitParams;
use clap::{Args, CommandFactory, Parser, Subcommand, ValueEnum};
use serde_json::{Map, Value};
use std::path::PathBuf;

const AFTER_HELP: &str = "\
Examples:
  foldmatch fit template.ply scan.ply -o fitted.ply --report report.json
  foldmatch fit template.obj scan.ply -o fitted.ply --method nrga --iterations 50
  foldmatch batch template.ply scans/ -o fitted/ --jobs 4 --resume
  foldmatch sequence template.obj frames/ -o tracked/ --iterations 30
  foldmatch eval template.ply fitted.ply scan.ply --gt truth.ply
  foldmatch demo -o demo-out

Exit status:
  0    every file was fitted (or skipped by --resume)
  1    usage error, or a fatal error (unreadable template, failed `fit` or `eval`, ...)
  2    partial failure: at least one file of a batch or sequence failed (see its report)
  130  interrupted (Ctrl-C): finished outputs are kept, no half-written file is left

Outputs are written atomically (temporary file + rename) and only inside -o. See docs/cli.md.";

const FIT_AFTER_HELP: &str = "\
Examples:
  foldmatch fit template.ply scan.ply -o fitted.ply
  foldmatch fit template.obj scan.ply -o fitted.obj --iterations 50 --psi 0.1
  foldmatch fit template.ply scan.ply -o fitted.ply --params params.json --report report.json
  foldmatch fit shirt.ply dressed.ply -o fitted.ply --scan-weights shirt_mask.npy
  foldmatch fit shirt.ply dressed.ply -o fitted.ply --scan-weights-property label

The output holds the fitted vertices, the template's faces, the accumulated wrinkle-vector
field as vertex properties (wvf_x, wvf_y, wvf_z, wvf_magnitude; PLY only) and its magnitude
as viridis vertex colors. Exit status: 0 fitted, 1 failed, 130 interrupted.";

const BATCH_AFTER_HELP: &str = "\
Examples:
  foldmatch batch template.ply scans/ -o fitted/
  foldmatch batch template.ply scans/ -o fitted/ --recursive --glob 'session*/*.ply' --jobs 8
  foldmatch batch template.ply scans/ -o fitted/ --resume

Every .ply/.obj file of SCAN_DIR (hidden files excluded) is fitted to OUT_DIR/<same relative
path>.<format>; OUT_DIR/report.json records every file (status, error, iterations, seconds,
metrics) and is kept up to date while the batch runs. Exit status: 0 all fitted, 1 fatal
error, 2 some files failed, 130 interrupted.";

const SEQUENCE_AFTER_HELP: &str = "\
Examples:
  foldmatch sequence template.obj frames/ -o tracked/
  foldmatch sequence frames/0.obj frames/ -o tracked/ --iterations 20 --gt-dir frames/

Frames are taken in natural order (frame2 before frame10). The first frame starts from the
template, every later one from the previous frame's fit. The wrinkle-vector field written
with each frame is that of the total motion from the template. Exit status: 0 all frames
tracked, 1 fatal error, 2 some frames failed, 130 interrupted.";

/// Fit a garment template mesh onto 3D scans (FoldMatch: N-body motion model + wrinkle-vector
/// fields).
#[derive(Debug, Parser)]
#[command(
    name = "foldmatch",
    bin_name = "foldmatch",
    version,
    max_term_width = 100,
    after_help = AFTER_HELP
)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
    /// Print only errors: no progress, no summaries.
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    pub quiet: bool,
    /// Print more: parameters, per-iteration figures in plain logs, skipped files.
    #[arg(short, long, global = true)]
    pub verbose: bool,
    /// Worker threads of the fit, at most 4 per hardware thread [default: one per core].
    #[arg(long, global = true, value_name = "N", value_parser = parse_threads)]
    pub threads: Option<usize>,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Fit the template to one scan.
    #[command(after_help = FIT_AFTER_HELP)]
    Fit(FitCmd),
    /// Fit the template to every scan of a folder, in parallel, with one JSON report.
    #[command(after_help = BATCH_AFTER_HELP)]
    Batch(BatchCmd),
    /// Track a 4D sequence: fit the frames of a folder in order, each warm-started from the
    /// previous frame's fit and anchored to the template's shape.
    #[command(after_help = SEQUENCE_AFTER_HELP)]
    Sequence(SequenceCmd),
    /// Compute the paper's metrics of a fit and print them as JSON.
    Eval(EvalCmd),
    /// Generate the built-in example (a sheet template and a folded, noisy scan of it), fit
    /// it, write the outputs and print before/after figures.
    Demo(DemoCmd),
}

/// `foldmatch fit`.
#[derive(Debug, Args)]
pub struct FitCmd {
    /// Template mesh (.ply or .obj, with faces).
    pub template: PathBuf,
    /// Scan (.ply or .obj): a point cloud, or a mesh (its faces give the curvature).
    pub scan: PathBuf,
    /// Output mesh (.ply or .obj; the extension decides).
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
    /// Also write a JSON report (paths, status, iterations, seconds, metrics, parameters,
    /// diagnostics) to this file.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// Ground-truth positions of the template vertices (a mesh with the same vertex count and
    /// order) for the f_R metric.
    #[arg(long, value_name = "GT")]
    pub gt: Option<PathBuf>,
    /// A weight per scan point: a NumPy .npy array of shape (N,) or (N, 1) in the scan's point
    /// order (float64, float32, (u)int8..64 or bool, little endian). Weights are finite and
    /// >= 0; 0 removes the point (a segmentation mask is a 0/1 array).
    #[arg(
        long,
        value_name = "FILE.npy",
        conflicts_with = "scan_weights_property"
    )]
    pub scan_weights: Option<PathBuf>,
    /// A weight per scan point from this per-vertex property of the scan's PLY (e.g. a
    /// segmenter's `label` or a scanner's `confidence`; any scalar type), as --scan-weights.
    #[arg(long, value_name = "NAME")]
    pub scan_weights_property: Option<String>,
    /// Use the scan's own vertex normals (PLY `nx ny nz`, as a scanner writes them) as the
    /// planes of the final isometric refinement, in place of each point's plane of its 12
    /// nearest points (docs/guide.md "Scan normals"). A scan without normals is an error.
    #[arg(long)]
    pub scan_normals: bool,
    /// Landmarks: template vertices whose positions on the scan are known, as JSON
    /// `{"vertices": [i, ...], "positions": [[x, y, z], ...]}` (a .json file) or CSV lines
    /// `index,x,y,z`. They decide the pre-alignment and pull their vertices toward the
    /// positions while the fit deforms (weight: `landmark_weight` in --params).
    #[arg(long, value_name = "FILE")]
    pub landmarks: Option<PathBuf>,
    /// Write ASCII PLY instead of binary.
    #[arg(long)]
    pub ascii: bool,
    /// Also draw the fit into this PNG: the scan, the fit colored by the wrinkle field and by
    /// the distance to the scan, from the front, three-quarter and back (docs/cli.md).
    #[arg(long, value_name = "FILE.png")]
    pub preview: Option<PathBuf>,
    /// Also write which scan points the fit took for the garment, as a NumPy bool array of
    /// shape (N,) in the scan's point order (what --scan-weights reads): on a dressed-body
    /// scan the fit's own segmentation (docs/dressed.md), else every point of positive weight.
    #[arg(long, value_name = "FILE.npy")]
    pub garment_mask: Option<PathBuf>,
    #[command(flatten)]
    #[allow(missing_docs)]
    pub params: ParamArgs,
}

/// `foldmatch batch`.
#[derive(Debug, Args)]
pub struct BatchCmd {
    /// Template mesh (.ply or .obj, with faces).
    pub template: PathBuf,
    /// Folder of scans (.ply and .obj files).
    pub scan_dir: PathBuf,
    /// Output folder (created if needed); nothing is written outside it.
    #[arg(short, long, value_name = "OUT_DIR")]
    pub output: PathBuf,
    /// Scans fitted at the same time [default: min(cores, 4)].
    #[arg(short, long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub jobs: Option<u16>,
    /// Skip scans whose output exists and whose entry in OUT_DIR/report.json is ok.
    #[arg(long)]
    pub resume: bool,
    /// Also look into subfolders (outputs mirror the folder structure).
    #[arg(short, long)]
    pub recursive: bool,
    /// Only scans matching this pattern (`*`, `?`, `[..]`); matched against the file name,
    /// or against the path relative to SCAN_DIR when it contains a `/`.
    #[arg(long, value_name = "PATTERN")]
    pub glob: Option<String>,
    /// Output format.
    #[arg(long, value_enum, default_value_t = OutputFormat::Ply)]
    pub format: OutputFormat,
    /// Write ASCII PLY instead of binary.
    #[arg(long)]
    pub ascii: bool,
    /// Folder of ground-truth meshes named like the scans (same relative path), for f_R.
    #[arg(long, value_name = "DIR")]
    pub gt_dir: Option<PathBuf>,
    /// A weight per scan point from this per-vertex property of every scan (PLY scans only;
    /// e.g. `label` or `confidence`): finite, >= 0, 0 removes the point.
    #[arg(long, value_name = "NAME")]
    pub scan_weights_property: Option<String>,
    /// Use every scan's own vertex normals (PLY `nx ny nz`), as `fit --scan-normals`; a scan
    /// without them fails (and the batch goes on).
    #[arg(long, conflicts_with = "scheduler")]
    pub scan_normals: bool,
    /// Run the fits on a Dask cluster: `local` (worker processes on this machine) or the
    /// address of a running scheduler (tcp://host:8786). Only from the Python package with Dask
    /// beside it (`python -m foldmatch_rs`, `pip install 'dask[distributed]'`); see
    /// docs/cluster.md.
    #[arg(long, value_name = "ADDRESS")]
    pub scheduler: Option<String>,
    /// Also draw each fit into a PNG next to its output (`NAME.png`), as `fit --preview`.
    #[arg(long, conflicts_with = "scheduler")]
    pub preview: bool,
    /// Also write which scan points each fit took for the garment next to its output
    /// (`NAME.garment.npy`), as `fit --garment-mask`: on dressed-body scans the fit's own
    /// segmentation (docs/dressed.md).
    #[arg(long, conflicts_with = "scheduler")]
    pub garment_masks: bool,
    #[command(flatten)]
    #[allow(missing_docs)]
    pub params: ParamArgs,
}

/// `foldmatch sequence`.
#[derive(Debug, Args)]
pub struct SequenceCmd {
    /// Template mesh (.ply or .obj, with faces); the first frame starts from it.
    pub template: PathBuf,
    /// Folder of frames (.ply and .obj files), taken in natural order.
    pub frame_dir: PathBuf,
    /// Output folder (created if needed); nothing is written outside it.
    #[arg(short, long, value_name = "OUT_DIR")]
    pub output: PathBuf,
    /// Only frames whose file name matches this pattern (`*`, `?`, `[..]`).
    #[arg(long, value_name = "PATTERN")]
    pub glob: Option<String>,
    /// Skip frames whose output exists and whose entry in OUT_DIR/report.json is ok (the next
    /// frame then starts from that output).
    #[arg(long)]
    pub resume: bool,
    /// Output format.
    #[arg(long, value_enum, default_value_t = OutputFormat::Ply)]
    pub format: OutputFormat,
    /// Write ASCII PLY instead of binary.
    #[arg(long)]
    pub ascii: bool,
    /// Folder of ground-truth meshes named like the frames, for f_R.
    #[arg(long, value_name = "DIR")]
    pub gt_dir: Option<PathBuf>,
    /// A weight per scan point from this per-vertex property of every frame (PLY frames only;
    /// e.g. `label` or `confidence`): finite, >= 0, 0 removes the point.
    #[arg(long, value_name = "NAME")]
    pub scan_weights_property: Option<String>,
    /// Run the fits on a Dask cluster: `local` (worker processes on this machine) or the
    /// address of a running scheduler (tcp://host:8786). Only from the Python package with Dask
    /// beside it (`python -m foldmatch_rs`, `pip install 'dask[distributed]'`); see
    /// docs/cluster.md.
    #[arg(long, value_name = "ADDRESS")]
    pub scheduler: Option<String>,
    /// λ in [0, 1] of a frame's start: the previous fit moved on by λ × its last motion.
    #[arg(long, value_name = "L", default_value_t = crate::track::DEFAULT_PREDICTION)]
    pub prediction: f64,
    /// Also fit a flagged frame again from the template placed rigidly on its fit, and keep the
    /// better fit (docs/method.md "Tracking").
    #[arg(long)]
    pub reanchor: bool,
    /// Also write which scan points each frame's fit took for the garment next to its output
    /// (`NAME.garment.npy`), as `fit --garment-mask` (docs/dressed.md).
    #[arg(long, conflicts_with = "scheduler")]
    pub garment_masks: bool,
    #[command(flatten)]
    #[allow(missing_docs)]
    pub params: ParamArgs,
}

/// `foldmatch eval`.
#[derive(Debug, Args)]
pub struct EvalCmd {
    /// The template the fit started from (.ply or .obj, with faces).
    pub template: PathBuf,
    /// The fitted mesh (same vertex count and order as the template).
    pub fitted: PathBuf,
    /// The scan it was fitted to.
    pub scan: PathBuf,
    /// Ground-truth positions of the template vertices, for f_R.
    #[arg(long, value_name = "GT")]
    pub gt: Option<PathBuf>,
    /// A weight per scan point, as `fit --scan-weights` takes it (a NumPy .npy array of shape
    /// (N,) or (N, 1)): the points of weight 0 are left out of the metrics, as the fit left
    /// them out (a garment mask on a dressed-body scan).
    #[arg(
        long,
        value_name = "FILE.npy",
        conflicts_with = "scan_weights_property"
    )]
    pub scan_weights: Option<PathBuf>,
    /// A weight per scan point from this per-vertex property of the scan's PLY, as
    /// --scan-weights.
    #[arg(long, value_name = "NAME")]
    pub scan_weights_property: Option<String>,
    /// Also write the JSON to this file.
    #[arg(short, long, value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// Collapse threshold τ_S of f_S (area ratio below it) [default: 0.02].
    #[arg(long, value_name = "T")]
    pub tau_s: Option<f64>,
    /// Expansion threshold τ_E of f_E (area ratio above it) [default: 2].
    #[arg(long, value_name = "T")]
    pub tau_e: Option<f64>,
}

/// `foldmatch demo`.
#[derive(Debug, Args)]
pub struct DemoCmd {
    /// Output folder (created if needed).
    #[arg(short, long, value_name = "DIR", default_value = "foldmatch-demo")]
    pub output: PathBuf,
    /// Vertices along each side of the square sheet template.
    #[arg(long, value_name = "N", default_value_t = 41, value_parser = clap::value_parser!(u32).range(3..=2000))]
    pub size: u32,
    /// Points sampled on the folded sheet to make the scan.
    #[arg(long, value_name = "N", default_value_t = 4000, value_parser = clap::value_parser!(u32).range(10..=10_000_000))]
    pub scan_points: u32,
    /// Gaussian noise of the scan, relative to the sheet's width.
    #[arg(long, value_name = "SIGMA", default_value_t = 0.002)]
    pub noise: f64,
    #[command(flatten)]
    #[allow(missing_docs)]
    pub params: ParamArgs,
}

/// Output mesh format of `batch` and `sequence`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum OutputFormat {
    /// PLY with the wrinkle-vector field as vertex properties and colors.
    Ply,
    /// OBJ with colors (no place for the field's vector properties).
    Obj,
}

impl OutputFormat {
    /// The file extension.
    pub fn extension(self) -> &'static str {
        match self {
            Self::Ply => "ply",
            Self::Obj => "obj",
        }
    }
}

/// `--method`.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum MethodArg {
    /// The paper's method: n-ring deformation gradients (Eq. 4–8).
    Foldmatch,
    /// The NRGa baseline: per-vertex rigid fit of a k-NN neighborhood.
    Nrga,
}

/// `--numerator`.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum NumeratorArg {
    /// α (Y − X): translation-invariant.
    Centered,
    /// Y α − X, as printed in the paper.
    Literal,
}

/// `--summation`.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum SummationArg {
    /// Mean over the K neighbours.
    Mean,
    /// Plain sum, as printed.
    Sum,
}

/// `--damping-mode`.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum DampingModeArg {
    /// v ← (1 − η) v + F/m Δt.
    Fraction,
    /// F ← F − η v, as printed.
    Force,
}

/// `--regularization`.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum RegularizationArg {
    /// Eq. 5 on the stretch part.
    #[value(alias = "affine_invariant")]
    AffineInvariant,
    /// Log-Euclidean mean (faster).
    #[value(alias = "log_euclidean")]
    LogEuclidean,
    /// No regularization.
    None,
}

/// `--rotation-source`.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum RotationSourceArg {
    /// The regularized gradient (ψ then shapes only the field).
    Regularized,
    /// The raw Eq. 4 gradient (ψ acts on the rotation).
    Raw,
}

/// `--prealign`.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum PrealignArg {
    /// Fit as given (a template far from the scan is refused).
    None,
    /// Move the template's centroid onto the scan's first.
    Centroid,
    /// Turn and move the template onto the scan first, in any orientation (a placed template is
    /// left as given).
    Rigid,
    /// As rigid, and scale it too (a scan in other units or of another size).
    Similarity,
}

/// Every parameter of [`FitParams`] as an optional flag. Only the flags given override the
/// defaults (or the values of `--params FILE`).
#[derive(Debug, Default, Args)]
#[command(next_help_heading = "Fit parameters")]
pub struct ParamArgs {
    /// Starting values of every parameter: `default` (the most accurate configuration for its
    /// cost), `accurate` (the default with 150 iterations: closer to the truth and to the
    /// scan, 1.3× the time), `fast` (one schedule instead of the default's two: about 0.6×
    /// the time, less accurate), `paper` (the paper's method with only the converging readings) or
    /// `tracking` (the default without softening annealing, for warm-started fits)
    /// [default: default; for `sequence`: tracking].
    #[arg(long, value_name = "NAME")]
    pub preset: Option<String>,
    /// JSON file of parameters (the names of `FitParams`, e.g. {"iterations": 50}); it
    /// overrides the preset, flags override it.
    #[arg(long, value_name = "FILE.json")]
    pub params: Option<PathBuf>,
    /// Motion and deformation model [default: foldmatch].
    #[arg(long, value_enum, value_name = "METHOD")]
    pub method: Option<MethodArg>,
    /// ξ, the number of iterations [default: 80] (`accurate`: 150; `fast`, `paper`: 100; `tracking`: 60).
    #[arg(long, value_name = "N")]
    pub iterations: Option<usize>,
    /// n of the n-ring template neighborhoods, 1..=8 [default: 2].
    #[arg(long, value_name = "N")]
    pub rings: Option<usize>,
    /// ρ, the scan neighborhood size as a fraction of the scan's points [default: 0.001] (the paper preset: 0.002).
    #[arg(long, value_name = "F")]
    pub rho: Option<f64>,
    /// Lower clamp of the scan neighborhood size K [default: 8].
    #[arg(long, value_name = "N")]
    pub k_min: Option<usize>,
    /// Upper clamp of K [default: 32] (the paper preset: 64).
    #[arg(long, value_name = "N")]
    pub k_max: Option<usize>,
    /// G, the gravitational constant [default: 1.67].
    #[arg(long, value_name = "G")]
    pub gravity: Option<f64>,
    /// ε, the softening length [default: 0.1].
    #[arg(long, value_name = "EPS")]
    pub softening: Option<f64>,
    /// η, the damping, in [0, 1] [default: 0.1].
    #[arg(long, value_name = "ETA")]
    pub damping: Option<f64>,
    /// Δt, the time step [default: 0.006].
    #[arg(long, value_name = "DT")]
    pub time_step: Option<f64>,
    /// m(Y), the template particle mass [default: 1].
    #[arg(long, value_name = "M")]
    pub template_mass: Option<f64>,
    /// m(X), the scan particle mass [default: 1].
    #[arg(long, value_name = "M")]
    pub target_mass: Option<f64>,
    /// Positive floor of the curvature term α, in (0, 1] [default: 0.1].
    #[arg(long, value_name = "A")]
    pub alpha_floor: Option<f64>,
    /// Numerator reading of Eq. 2 [default: centered].
    #[arg(long, value_enum, value_name = "READING")]
    pub numerator: Option<NumeratorArg>,
    /// How neighbour forces combine [default: mean].
    #[arg(long, value_enum, value_name = "READING")]
    pub summation: Option<SummationArg>,
    /// How η dissipates velocity [default: fraction].
    #[arg(long, value_enum, value_name = "READING")]
    pub damping_mode: Option<DampingModeArg>,
    /// ψ, the wrinkle stretch coefficient, |ψ| < 1 [default: 0.05].
    #[arg(long, value_name = "PSI", allow_negative_numbers = true)]
    pub psi: Option<f64>,
    /// γ, weight of the normal completion of Eq. 4 (0 disables it) [default: 0.3].
    #[arg(long, value_name = "GAMMA")]
    pub normal_completion: Option<f64>,
    /// Mean used by Eq. 5 [default: log-euclidean] (the paper preset: affine-invariant).
    #[arg(long, value_enum, value_name = "MEAN")]
    pub regularization: Option<RegularizationArg>,
    /// Gradient used by the rotation solve of Eq. 8 [default: regularized].
    #[arg(long, value_enum, value_name = "SOURCE")]
    pub rotation_source: Option<RotationSourceArg>,
    /// Keep the integrated velocity instead of the applied motion (literal reading).
    #[arg(long)]
    pub no_velocity_sync: bool,
    /// Work in the user's frame instead of the normalized one (the paper's constants assume
    /// the normalized frame).
    #[arg(long)]
    pub no_normalize: bool,
    /// Stop when an iteration's mean displacement (normalized units) is below this; 0 never
    /// stops early [default: 0].
    #[arg(long, value_name = "TOL")]
    pub tolerance: Option<f64>,
    /// Drop the curvature term of Eq. 2 (κ = 0).
    #[arg(long)]
    pub no_curvature: bool,
    /// How the template is placed on the scan before the fit [default: rigid] (the paper and
    /// tracking presets, and so `sequence`: none).
    #[arg(long, value_enum, value_name = "MODE")]
    pub prealign: Option<PrealignArg>,
    /// Any parameter by its `FitParams` name, VALUE as JSON (e.g. --set psi=0.1 --set
    /// method=nrga; a word that is not JSON is taken as a string); repeatable, applied before
    /// the other flags.
    #[arg(long = "set", value_name = "KEY=VALUE", value_parser = parse_setting)]
    pub set: Vec<(String, Value)>,
}

/// The `FitParams` keys with a hand-written flag above (`snapshot_every` has none on purpose:
/// the CLI writes no snapshots).
const EXPLICIT: &[&str] = &[
    "method",
    "iterations",
    "rings",
    "rho",
    "k_min",
    "k_max",
    "gravity",
    "softening",
    "damping",
    "time_step",
    "template_mass",
    "target_mass",
    "alpha_floor",
    "numerator",
    "summation",
    "damping_mode",
    "psi",
    "normal_completion",
    "regularization",
    "rotation_source",
    "velocity_sync",
    "normalize",
    "tolerance",
    "use_curvature",
    "prealign",
    "snapshot_every",
];

/// The subcommands that take the fit parameters.
const FIT_COMMANDS: [&str; 4] = ["fit", "batch", "sequence", "demo"];

/// Every `FitParams` key without a hand-written flag, with its default: each gets a generated
/// flag `--KEY VALUE`, so a parameter added to the core is reachable (and listed in `--help`)
/// without a change here.
fn generated_params() -> Vec<(String, Value)> {
    let defaults = serde_json::to_value(FitParams::default()).expect("FitParams serializes");
    let Value::Object(defaults) = defaults else {
        unreachable!("FitParams is an object")
    };
    defaults
        .into_iter()
        .filter(|(k, _)| !EXPLICIT.contains(&k.as_str()))
        .collect()
}

fn generated_id(key: &str) -> String {
    format!("param.{key}")
}

/// A JSON value, or a string when the text is not JSON.
fn parse_json_value(text: &str) -> Result<Value, String> {
    Ok(
        serde_json::from_str(text.trim())
            .unwrap_or_else(|_| Value::String(text.trim().to_string())),
    )
}

/// The grammar: [`Cli`]'s, plus the generated parameter flags (see [`generated_params`]).
#[cfg(test)]
pub fn command() -> clap::Command {
    command_with(&generated_params())
}

fn command_with(generated: &[(String, Value)]) -> clap::Command {
    // clap (without its `string` feature) wants 'static names: leak a few bytes per flag, once
    // per run.
    let leak = |s: String| -> &'static str { Box::leak(s.into_boxed_str()) };
    let args: Vec<clap::Arg> = generated
        .iter()
        .map(|(key, default)| {
            let shown = match default {
                Value::String(s) => s.clone(),
                other => other.to_string(),
            };
            clap::Arg::new(leak(generated_id(key)))
                .long(leak(key.replace('_', "-")))
                .value_name("VALUE")
                .value_parser(parse_json_value)
                .help_heading("Fit parameters")
                .help(format!(
                    "The `{key}` setting of FitParams (see docs/parameters.md) [default: {shown}]"
                ))
        })
        .collect();
    let mut cmd = Cli::command();
    for name in FIT_COMMANDS {
        let args = args.clone();
        cmd = cmd.mut_subcommand(name, move |sub| sub.args(args));
    }
    cmd
}

/// Parses the command line (the first item is the program name).
pub fn parse<I, T>(args: I) -> Result<Cli, clap::Error>
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    use clap::FromArgMatches;
    let generated = generated_params();
    let mut cmd = command_with(&generated);
    let matches = cmd.try_get_matches_from_mut(args)?;
    let mut cli = Cli::from_arg_matches(&matches).map_err(|e| e.format(&mut cmd))?;
    if let (Some((_, sub)), Some(params)) = (matches.subcommand(), cli.command.params_mut()) {
        for (key, _) in &generated {
            if let Ok(Some(value)) = sub.try_get_one::<Value>(&generated_id(key)) {
                params.set.push((key.clone(), value.clone()));
            }
        }
    }
    Ok(cli)
}

impl Command {
    /// The fit parameters of the commands that fit.
    pub fn params_mut(&mut self) -> Option<&mut ParamArgs> {
        match self {
            Self::Fit(c) => Some(&mut c.params),
            Self::Batch(c) => Some(&mut c.params),
            Self::Sequence(c) => Some(&mut c.params),
            Self::Demo(c) => Some(&mut c.params),
            Self::Eval(_) => None,
        }
    }
}

/// Parses `--threads N`: 1 ..= 4 per hardware thread ([`crate::limits::max_threads`]).
fn parse_threads(text: &str) -> Result<usize, String> {
    let most = crate::limits::max_threads();
    let n: usize = text
        .trim()
        .parse()
        .map_err(|_| format!("expected a whole number in 1..={most}"))?;
    crate::limits::check_threads("--threads", n).map_err(|e| match e {
        crate::FoldMatchError::Parameter { reason, .. } => reason,
        other => other.to_string(),
    })
}

/// Parses `KEY=VALUE` of `--set`: VALUE as JSON, or as a string when it is not JSON.
fn parse_setting(text: &str) -> Result<(String, Value), String> {
    let (key, value) = text
        .split_once('=')
        .ok_or_else(|| format!("expected KEY=VALUE, got {text:?}"))?;
    let key = key.trim().replace('-', "_");
    if key.is_empty() {
        return Err(format!("expected KEY=VALUE, got {text:?}"));
    }
    let value = serde_json::from_str(value.trim())
        .unwrap_or_else(|_| Value::String(value.trim().to_string()));
    Ok((key, value))
}

/// A flag's number as JSON; a non-finite float (which JSON cannot hold) as its text ("NaN",
/// "inf"), which the validation then rejects naming the parameter alone.
fn json_number<T: Into<Value> + ToString + Copy>(x: T) -> Value {
    match x.into() {
        Value::Null => Value::String(x.to_string()),
        v => v,
    }
}

/// The serde name of a [`ValueEnum`] value: its kebab-case CLI name in snake_case.
fn enum_name<T: ValueEnum>(value: &T) -> Value {
    let name = value
        .to_possible_value()
        .expect("no skipped values")
        .get_name()
        .replace('-', "_");
    Value::String(name)
}

impl ParamArgs {
    /// The flags that were given, as a JSON object keyed by the [`FitParams`] names.
    pub fn overrides(&self) -> Map<String, Value> {
        let mut map: Map<String, Value> = self.set.iter().cloned().collect();
        let mut set = |key: &str, value: Option<Value>| {
            if let Some(v) = value {
                map.insert(key.to_string(), v);
            }
        };
        set("method", self.method.as_ref().map(enum_name));
        set("iterations", self.iterations.map(json_number));
        set("rings", self.rings.map(json_number));
        set("rho", self.rho.map(json_number));
        set("k_min", self.k_min.map(json_number));
        set("k_max", self.k_max.map(json_number));
        set("gravity", self.gravity.map(json_number));
        set("softening", self.softening.map(json_number));
        set("damping", self.damping.map(json_number));
        set("time_step", self.time_step.map(json_number));
        set("template_mass", self.template_mass.map(json_number));
        set("target_mass", self.target_mass.map(json_number));
        set("alpha_floor", self.alpha_floor.map(json_number));
        set("numerator", self.numerator.as_ref().map(enum_name));
        set("summation", self.summation.as_ref().map(enum_name));
        set("damping_mode", self.damping_mode.as_ref().map(enum_name));
        set("psi", self.psi.map(json_number));
        set("normal_completion", self.normal_completion.map(json_number));
        set(
            "regularization",
            self.regularization.as_ref().map(enum_name),
        );
        set(
            "rotation_source",
            self.rotation_source.as_ref().map(enum_name),
        );
        set(
            "velocity_sync",
            self.no_velocity_sync.then_some(Value::Bool(false)),
        );
        set("normalize", self.no_normalize.then_some(Value::Bool(false)));
        set("tolerance", self.tolerance.map(json_number));
        set(
            "use_curvature",
            self.no_curvature.then_some(Value::Bool(false)),
        );
        set("prealign", self.prealign.as_ref().map(enum_name));
        map
    }

    /// The parameters: defaults, overridden by `--params FILE` (when given), overridden by the
    /// flags; validated by [`FitParams::from_json`], so names and ranges live in one place.
    ///
    /// Errors name the file or the parameter.
    pub fn to_params(&self) -> Result<FitParams, String> {
        self.to_params_over("default")
    }

    /// As [`ParamArgs::to_params`], starting from `default_preset` when `--preset` is not given.
    pub fn to_params_over(&self, default_preset: &str) -> Result<FitParams, String> {
        let mut map = match &self.params {
            None => Map::new(),
            Some(path) => {
                let bytes = crate::io::read_bounded(path, crate::limits::MAX_PARAMS_FILE_BYTES)
                    .map_err(|e| e.to_string())?;
                let text = String::from_utf8(bytes)
                    .map_err(|_| format!("{}: not UTF-8 text", path.display()))?;
                match serde_json::from_str::<Value>(&text) {
                    Ok(Value::Object(map)) => map,
                    Ok(_) => {
                        return Err(format!(
                            "{}: expected a JSON object of parameters",
                            path.display()
                        ))
                    }
                    Err(e) => return Err(format!("{}: not valid JSON: {e}", path.display())),
                }
            }
        };
        map.extend(self.overrides());
        let base = FitParams::preset(self.preset.as_deref().unwrap_or(default_preset))
            .map_err(|e| e.to_string())?;
        let Value::Object(mut full) = serde_json::to_value(base).map_err(|e| e.to_string())? else {
            unreachable!("FitParams serializes to an object")
        };
        let unknown: Vec<String> = map
            .keys()
            .filter(|k| !full.contains_key(*k))
            .cloned()
            .collect();
        full.extend(map);
        if !unknown.is_empty() {
            // Only the unknown keys: from_json names the first and lists the known ones.
            full = unknown.iter().map(|k| (k.clone(), Value::Null)).collect();
        }
        FitParams::from_json(&Value::Object(full).to_string()).map_err(|e| match &self.params {
            Some(path) => format!("{e} (parameters from the flags and {})", path.display()),
            None => e.to_string(),
        })
    }
}

#[cfg(test)]
mod tests;
