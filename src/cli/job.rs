//! One file: read the scan, fit, write the output atomically, measure. Shared by `fit`,
//! `batch`, `sequence` and `demo`, so every command writes the same files and reports.

use super::interrupt;
use super::report::{FileReport, ScanWeightsReport, Status};
use super::ui::{Ui, Verbosity};
use crate::error::FoldMatchError;
use crate::fit::{
    deformation_model, fit_scan, validate_weights, FitParams, Progress, ScanExtras,
    TemplateTopology, Workspace,
};
use crate::io::{fitted_mesh, read_mesh, read_npy, read_ply_property, write_mesh, MeshData};
use crate::landmarks::Landmarks;
use crate::mesh::{clean_faces, VertexFaces};
use crate::metrics::{evaluate, Metrics, MetricsInput, MetricsParams};
use crate::normalize::Frame;
use crate::render::{render, write_png, PreviewOptions, Scene};
use crate::rings::{n_rings, Neighborhoods};
use crate::track::Tracker;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

/// The template mesh, read once per run, with what the wrinkle-field of a total motion needs.
pub struct Template {
    /// Where it was read from.
    pub path: PathBuf,
    /// Vertices.
    pub vertices: Vec<[f64; 3]>,
    /// Faces (as read).
    pub faces: Vec<[u32; 3]>,
    clean: Vec<[u32; 3]>,
    incidence: VertexFaces,
    rings: Neighborhoods,
}

impl Template {
    /// Reads the template; it must be a triangle mesh with finite coordinates.
    pub fn load(path: &Path, params: &FitParams) -> Result<Self, String> {
        let mesh = read_mesh(path).map_err(|e| format!("template: {e}"))?;
        Self::new(path, mesh.vertices, mesh.faces, params)
    }

    /// A template from memory (`demo`); `path` names it in messages.
    pub fn new(
        path: &Path,
        vertices: Vec<[f64; 3]>,
        faces: Vec<[u32; 3]>,
        params: &FitParams,
    ) -> Result<Self, String> {
        let name = path.display();
        if vertices.is_empty() {
            return Err(format!("template {name}: no vertices"));
        }
        if faces.is_empty() {
            return Err(format!(
                "template {name}: no faces (a point cloud); the template must be a triangle mesh"
            ));
        }
        crate::mesh::validate_points("template", &vertices)
            .map_err(|e| format!("template {name}: {e}"))?;
        crate::mesh::validate_faces("template faces", &faces, vertices.len())
            .map_err(|e| format!("template {name}: {e}"))?;
        let m = vertices.len();
        let clean = clean_faces(&faces).faces;
        let incidence = VertexFaces::new(&clean, m);
        let rings = n_rings(&clean, m, params.model.rings);
        Ok(Self {
            path: path.to_path_buf(),
            vertices,
            faces,
            clean,
            incidence,
            rings,
        })
    }

    /// The accumulated wrinkle-vector field of the motion template → `fitted` (paper Eq. 6–7),
    /// computed in the scan's normalized frame as the fit does.
    pub fn wrinkle_field(
        &self,
        fitted: &[[f64; 3]],
        scan: &[[f64; 3]],
        params: &FitParams,
    ) -> Vec<[f64; 3]> {
        let frame = if params.readings.normalize {
            Frame::of_target(scan)
        } else {
            Frame::identity()
        };
        let (old, new) = (frame.forward(&self.vertices), frame.forward(fitted));
        let topo = TemplateTopology {
            faces: &self.clean,
            incidence: &self.incidence,
            rings: &self.rings,
        };
        let mut ws = Workspace::new(self.vertices.len());
        deformation_model(&old, &new, &topo, params, &mut ws);
        ws.wvf
    }
}

/// Where a scan's per-point weights come from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ScanWeights {
    /// `--scan-weights FILE.npy`: an `(N,)` or `(N, 1)` NumPy array.
    File(PathBuf),
    /// `--scan-weights-property NAME`: a per-vertex scalar property of the scan's PLY.
    Property(String),
}

impl ScanWeights {
    /// The source named by `--scan-weights FILE.npy` or `--scan-weights-property NAME` (the
    /// two exclude each other on the command line); `None` without either.
    pub fn from_options(file: Option<&PathBuf>, property: Option<&String>) -> Option<Self> {
        match (file, property) {
            (Some(file), _) => Some(Self::File(file.clone())),
            (None, Some(name)) => Some(Self::Property(name.clone())),
            (None, None) => None,
        }
    }

    /// The scan at `path` and its weights, with their report entry and the name of the
    /// weights in messages (not validated yet). Errors name the file (and the property).
    #[allow(clippy::type_complexity)]
    pub(super) fn read(
        &self,
        path: &Path,
    ) -> Result<(MeshData, Vec<f64>, ScanWeightsReport, String), String> {
        let named = |e: FoldMatchError| name_file(path, e);
        let (scan, weights, source, report) = match self {
            Self::File(file) => {
                let scan = read_mesh(path).map_err(named)?;
                let weights = read_npy(file).map_err(|e| e.to_string())?;
                let source = format!("{} (the weights of {})", file.display(), path.display());
                (scan, weights, source, ScanWeightsReport::file(file))
            }
            Self::Property(name) => {
                let is_ply = path
                    .extension()
                    .is_some_and(|e| e.eq_ignore_ascii_case("ply"));
                if !is_ply {
                    return Err(format!(
                        "{}: --scan-weights-property {name} needs a PLY scan (other formats \
                         have no per-vertex properties)",
                        path.display()
                    ));
                }
                let (scan, weights) = read_ply_property(path, name).map_err(named)?;
                let source = format!("{}, property '{name}'", path.display());
                (scan, weights, source, ScanWeightsReport::property(name))
            }
        };
        let report = report.counted(&weights);
        Ok((scan, weights, report, source))
    }
}

/// One file to fit.
pub struct Job<'a> {
    /// Short name for logs and the report (relative path).
    pub name: String,
    /// The scan.
    pub scan: PathBuf,
    /// Where the fitted mesh goes (.ply / .obj).
    pub output: PathBuf,
    /// Ground truth for f_R.
    pub gt: Option<PathBuf>,
    /// Fit the scan as the next frame of this tracker (`sequence`, docs/method.md
    /// "Tracking"): it starts from its previous fits, anchored to the template.
    pub tracker: Option<&'a Mutex<Tracker>>,
    /// Write ASCII PLY.
    pub ascii: bool,
    /// Per-point weights of the scan, when given.
    pub weights: Option<ScanWeights>,
    /// Landmarks on the scan, when given (`fit --landmarks`).
    pub landmarks: Option<&'a Landmarks>,
    /// Write the fitted mesh here instead of `output` and leave it there (`batch` and
    /// `sequence` record the file in their report first, then rename it to `output`: see
    /// [`stage_path`]).
    pub stage: Option<PathBuf>,
    /// Also draw the fit into this PNG ([`crate::render`]); staged like the mesh when
    /// `stage` is set ([`stage_path`]).
    pub preview: Option<PathBuf>,
    /// Also write the scan points the fit took for the garment into this `.npy` mask
    /// (`fit --garment-mask`; not staged: `fit` writes in place).
    pub garment_mask: Option<PathBuf>,
    /// Fit with the scan's own vertex normals (`--scan-normals`; a scan without them fails).
    pub scan_normals: bool,
}

impl Job<'_> {
    /// The staged files of the job and where each goes once recorded (the mesh, then its
    /// preview); none when the job writes in place.
    pub fn commits(&self) -> Vec<(PathBuf, PathBuf)> {
        let Some(stage) = &self.stage else {
            return Vec::new();
        };
        let mut commits = vec![(stage.clone(), self.output.clone())];
        commits.extend(self.preview.iter().map(|p| (stage_path(p), p.clone())));
        commits
    }
}

/// The preview image `batch --preview` writes for `output`: the same name, `.png`.
pub fn preview_path(output: &Path) -> PathBuf {
    output.with_extension("png")
}

/// Where `batch --garment-masks` and `sequence --garment-masks` write a fit's garment mask:
/// `NAME.garment.npy` next to its output.
pub fn garment_mask_path(output: &Path) -> PathBuf {
    output.with_extension("garment.npy")
}

/// Where `batch` and `sequence` write an output before it is recorded: `.NAME.staged.EXT`
/// next to it (same folder, so the rename that commits it is atomic).
pub fn stage_path(output: &Path) -> PathBuf {
    let name = output
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let ext = output
        .extension()
        .map(|e| e.to_string_lossy().into_owned())
        .unwrap_or_default();
    output.with_file_name(format!(".{name}.staged.{ext}"))
}

/// What came of a [`Job`].
pub struct Outcome {
    /// The file's report entry.
    pub report: FileReport,
    /// The fitted vertices, when the fit succeeded.
    pub fitted: Option<Vec<[f64; 3]>>,
    /// Metrics, when computed.
    pub metrics: Option<Metrics>,
}

/// The context every job shares.
pub struct Runner<'a> {
    /// The template.
    pub template: &'a Template,
    /// Fit parameters.
    pub params: &'a FitParams,
    /// Output.
    pub ui: &'a Ui,
    /// The thread pool the fit runs in.
    pub pool: &'a rayon::ThreadPool,
}

impl Runner<'_> {
    /// Runs `job`; never panics (a panic becomes an error entry) and never fails: problems
    /// are recorded in the returned report.
    pub fn run(&self, job: &Job<'_>) -> Outcome {
        let started = Instant::now();
        let mut report = FileReport::pending(&job.name, &job.scan, &job.output);
        report.ground_truth = job.gt.as_ref().map(|p| p.display().to_string());
        let result = catch_unwind(AssertUnwindSafe(|| self.work(job, &mut report)));
        let (fitted, metrics) = match result {
            Ok(Ok(done)) => done,
            Ok(Err(message)) => {
                report.status = if message == INTERRUPTED {
                    Status::Interrupted
                } else {
                    Status::Error
                };
                report.error = Some(message);
                (None, None)
            }
            Err(panic) => {
                let what = panic
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| panic.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "unknown panic".into());
                report.status = Status::Error;
                report.error = Some(format!("{}: internal error: {what}", job.scan.display()));
                (None, None)
            }
        };
        report.total_seconds = Some(started.elapsed().as_secs_f64());
        Outcome {
            report,
            fitted,
            metrics,
        }
    }

    #[allow(clippy::type_complexity)]
    fn work(
        &self,
        job: &Job<'_>,
        report: &mut FileReport,
    ) -> Result<(Option<Vec<[f64; 3]>>, Option<Metrics>), String> {
        let template = self.template;
        let named = |e: FoldMatchError| name_file(&job.scan, e);
        let (scan, weights) = match &job.weights {
            None => (read_mesh(&job.scan).map_err(named)?, None),
            Some(source) => {
                let (scan, weights, entry, what) = source.read(&job.scan)?;
                report.scan_weights = Some(entry);
                // Refused here, before the fit, to name the weights' origin.
                validate_weights(&weights, scan.vertices.len())
                    .map_err(|e| format!("{what}: {e}"))?;
                (scan, Some(weights))
            }
        };
        // The points the fit explains (weight > 0): the metrics and the field are theirs.
        let explained = weights
            .as_deref()
            .filter(|w| w.contains(&0.0))
            .map(|w| crate::metrics::positive_points(&scan.vertices, w));
        let explained = explained.as_deref().unwrap_or(&scan.vertices);
        let gt = match &job.gt {
            None => None,
            Some(path) => {
                let g = read_mesh(path).map_err(|e| format!("ground truth: {e}"))?;
                if g.vertices.len() != template.vertices.len() {
                    return Err(format!(
                        "ground truth {}: {} vertices, but the template {} has {}",
                        path.display(),
                        g.vertices.len(),
                        template.path.display(),
                        template.vertices.len()
                    ));
                }
                Some(g.vertices)
            }
        };
        if interrupt::requested() {
            return Err(INTERRUPTED.into());
        }
        let start = &template.vertices;
        crate::limits::check_snapshots(self.params, start.len()).map_err(|e| e.to_string())?;
        let bar = self.ui.iterations_bar(&job.name, self.params.iterations);
        let every = (self.params.iterations / 10).max(1);
        let plain_detail = !self.ui.has_bars() && self.ui.verbosity() >= Verbosity::Verbose;
        let ui = self.ui;
        let name = job.name.as_str();
        let mut next_log = every;
        let mut observer = |p: &Progress| {
            bar.set(p.iteration);
            if plain_detail && (p.iteration >= next_log || p.iteration == p.iterations) {
                next_log = p.iteration + every;
                ui.detail(format_args!(
                    "  {name}: iteration {}/{}, mean displacement {:.3e}",
                    p.iteration, p.iterations, p.record.mean_displacement
                ));
            }
            !interrupt::requested()
        };
        let target_faces = (!scan.faces.is_empty()).then_some(scan.faces.as_slice());
        let normals = match (job.scan_normals, &scan.normals) {
            (false, _) => None,
            (true, Some(n)) => Some(n.as_slice()),
            (true, None) => {
                return Err(format!(
                    "{}: --scan-normals: the scan has no vertex normals (nx ny nz)",
                    job.scan.display()
                ))
            }
        };
        let fit_started = Instant::now();
        let result = match job.tracker {
            Some(tracker) => {
                let mut guard = tracker.lock().unwrap_or_else(|e| e.into_inner());
                let tracker: &mut Tracker = &mut guard;
                let frame = self
                    .pool
                    .install(|| {
                        tracker.step(
                            &scan.vertices,
                            target_faces,
                            weights.as_deref(),
                            &mut observer,
                        )
                    })
                    .map_err(named)?;
                report.tracking = serde_json::to_value(&frame.figures).ok();
                Ok(frame.result)
            }
            None => self.pool.install(|| {
                fit_scan(
                    start,
                    &template.faces,
                    &scan.vertices,
                    &ScanExtras {
                        faces: target_faces,
                        weights: weights.as_deref(),
                        normals,
                        landmarks: job.landmarks,
                    },
                    self.params,
                    &mut observer,
                )
            }),
        }
        .map_err(named)?;
        bar.finish();
        report.seconds = Some(fit_started.elapsed().as_secs_f64());
        report.iterations = Some(result.iterations);
        report.diagnostics = serde_json::to_value(&result.diagnostics).ok();
        report.quality = serde_json::to_value(&result.quality).ok();
        if result.diagnostics.stopped_by_callback {
            return Err(INTERRUPTED.into());
        }
        let field = if job.tracker.is_some() {
            self.pool
                .install(|| template.wrinkle_field(&result.vertices, explained, self.params))
        } else {
            result.wvf_accumulated
        };
        let fitted = result.vertices;
        let garment_points = result.garment_points;
        let (mesh, extra) = fitted_mesh(&fitted, &template.faces, &field);
        if let Some(dir) = job.output.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        }
        let written = job.stage.as_deref().unwrap_or(&job.output);
        write_mesh(written, &mesh, &extra, job.ascii).map_err(|e| e.to_string())?;
        if let Some(preview) = &job.preview {
            let at = match job.stage {
                Some(_) => stage_path(preview),
                None => preview.clone(),
            };
            let magnitude = extra[3].values.as_slice();
            // The scan's faces index all its points: drawn only when every point is.
            let scan_faces = (explained.len() == scan.vertices.len()).then_some(target_faces);
            let scene = Scene {
                field: Some(magnitude),
                scan: Some(explained),
                scan_faces: scan_faces.flatten(),
                ..Scene::mesh(&fitted, &template.faces)
            };
            self.pool
                .install(|| render(&scene, &PreviewOptions::default()))
                .and_then(|p| write_png(&at, &p.image, &p.png_text()))
                .map_err(|e| format!("preview: {e}"))?;
            report.preview = Some(preview.display().to_string());
        }
        if let Some(path) = &job.garment_mask {
            // The fit's own garment points; fitted whole, the points of positive weight.
            let mask: Vec<bool> = if garment_points.is_empty() {
                weights.as_deref().map_or_else(
                    || vec![true; scan.vertices.len()],
                    |w| w.iter().map(|&x| x > 0.0).collect(),
                )
            } else {
                let mut mask = vec![false; scan.vertices.len()];
                for &j in &garment_points {
                    mask[j as usize] = true;
                }
                mask
            };
            crate::io::write_npy_mask(path, &mask).map_err(|e| format!("garment mask: {e}"))?;
            report.garment_mask = Some(path.display().to_string());
        }
        let metrics = self.pool.install(|| {
            evaluate(
                &MetricsInput {
                    template_vertices: &template.vertices,
                    faces: &template.faces,
                    fitted_vertices: &fitted,
                    target: explained,
                    ground_truth: gt.as_deref(),
                },
                &MetricsParams::default(),
            )
        });
        let metrics = match metrics {
            Ok(m) => Some(m),
            Err(e) => {
                self.ui
                    .warn(format_args!("{}: metrics not computed: {e}", job.name));
                None
            }
        };
        report.metrics = metrics.as_ref().and_then(|m| serde_json::to_value(m).ok());
        report.status = Status::Ok;
        Ok((Some(fitted), metrics))
    }
}

/// The error text of an interrupted job.
pub const INTERRUPTED: &str = "interrupted";

/// Prefixes an error with the file's path unless it already names it.
pub fn name_file(path: &Path, err: FoldMatchError) -> String {
    let text = err.to_string();
    let shown = path.display().to_string();
    if text.contains(&shown) {
        text
    } else {
        format!("{shown}: {text}")
    }
}

/// Reads a mesh for `what` (ground truth, fitted mesh, ...), naming it in the error.
pub fn read_named(what: &str, path: &Path) -> Result<MeshData, String> {
    read_mesh(path).map_err(|e| format!("{what}: {e}"))
}
