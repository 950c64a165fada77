//! Criterion benchmarks of every stage of one FoldMatch iteration, and of one whole iteration,
//! on the paper-sized generated case (a 115×115 sheet = 13,225 template vertices, 14,400 scan
//! points; K = 28, 2-ring neighborhoods of ≈ 19 vertices).
//!
//! ```sh
//! CARGO_TARGET_DIR=target/bench cargo bench --bench stages            # all, a few minutes
//! CARGO_TARGET_DIR=target/bench cargo bench --bench stages -- regularize   # one group
//! ```
//!
//! The state is built once: the template after [`WARM_UP`] iterations of the paper preset (so
//! the rings are curved and the gradients are not the identity, as in the middle of a fit), the
//! motion proposed by one N-body step from there, normals, rings, raw and regularized
//! gradients. Every benchmark then times one stage on that state with all cores (rayon's
//! global pool) unless its name says otherwise. End-to-end figures (wall time, peak memory,
//! peers) are `bench/perf.py`'s; see docs/performance.md.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, SamplingMode};
use foldmatch::curvature::gaussian_curvature_points;
use foldmatch::deformation::deformation_gradient;
use foldmatch::fit::{deformation_model, fit_simple, FitParams, TemplateTopology, Workspace};
use foldmatch::knn::{neighborhood_size, NeighborCache, PointIndex, TargetNeighbours};
use foldmatch::math::{
    nearest_rotation, nearest_rotation_fast, nearest_rotation_of_near_rotation, polar, sym_eigen3,
    vec3, Mat3,
};
use foldmatch::mesh::{vertex_normals, VertexFaces};
use foldmatch::nbody::{self, TwoWayPull};
use foldmatch::normalize::Frame;
use foldmatch::regularize::{regularize, RegularizeBuffers};
use foldmatch::rings::{n_rings, Neighborhoods};
use foldmatch::rotation::{ring_centroids, solve_rotation, transform_vertex};
use foldmatch::synthetic::{folded_sheet, SheetSpec};
use foldmatch::wrinkle::modified_stretch;
use rayon::prelude::*;
use std::hint::black_box;
use std::time::Duration;

/// Side of the generated sheet (115² = 13,225 vertices, the paper's template size).
const SIDE: usize = 115;
/// Scan points (the paper's target size).
const SCAN_POINTS: usize = 14_400;
/// Iterations of the paper preset run before the state is taken.
const WARM_UP: usize = 10;

/// The fit's fast 3×3 matrix functions, which every fit uses (the exact eigen-decomposition
/// path exists for the equivalence tests only).
const FAST_MATRIX: bool = true;

/// Everything one iteration reads, in the normalized frame.
struct State {
    params: FitParams,
    scan: Vec<[f64; 3]>,
    kappa: Vec<f64>,
    index: PointIndex,
    k: usize,
    faces: Vec<[u32; 3]>,
    incidence: VertexFaces,
    rings: Neighborhoods,
    /// Positions Y at the start of the iteration.
    pos: Vec<[f64; 3]>,
    /// Velocities at the start of the iteration.
    vel: Vec<[f64; 3]>,
    /// k-NN of every vertex (M × K) and their squared distances.
    nn_idx: Vec<u32>,
    nn_d2: Vec<f64>,
    /// Positions proposed by the N-body step.
    proposed: Vec<[f64; 3]>,
    normals_old: Vec<[f64; 3]>,
    normals_new: Vec<[f64; 3]>,
    /// Raw (Eq. 4) and regularized (Eq. 5) gradients, the latter as R̄ and Ū.
    raw: Vec<Mat3>,
    reg_rotation: Vec<Mat3>,
    reg_stretch: Vec<Mat3>,
    /// ψ-modified stretches Û (Eq. 6).
    stretch_hat: Vec<Mat3>,
}

fn setup() -> State {
    let spec = SheetSpec {
        nx: SIDE,
        ny: SIDE,
        scan_points: SCAN_POINTS,
        noise: 0.001,
        ..Default::default()
    };
    let case = folded_sheet(&spec);
    let params = FitParams::paper();
    let warm_params = {
        let mut p = params.clone();
        p.iterations = WARM_UP;
        p
    };
    let warm = fit_simple(
        &case.template_vertices,
        &case.faces,
        &case.scan,
        None,
        &warm_params,
    )
    .expect("warm-up fit");

    let frame = Frame::of_target(&case.scan);
    let scan = frame.forward(&case.scan);
    let pos = frame.forward(&warm.vertices);
    let m = pos.len();
    let index = PointIndex::new(&scan);
    let k = neighborhood_size(
        params.model.rho,
        scan.len(),
        params.model.k_min,
        params.model.k_max,
    );
    let kappa = gaussian_curvature_points(&scan, &index);
    let faces = case.faces;
    let incidence = VertexFaces::new(&faces, m);
    let rings = n_rings(&faces, m, params.model.rings);

    let mut nn_idx = vec![0u32; m * k];
    let mut nn_d2 = vec![0.0; m * k];
    index.nearest_all(&pos, k, &mut nn_idx, &mut nn_d2);
    // One step from rest gives the first motion; a second one, from the synchronized velocity,
    // the motion of an iteration in progress.
    let mut vel = vec![[0.0; 3]; m];
    let mut proposed = vec![[0.0; 3]; m];
    nbody::step(
        &pos,
        &mut vel,
        &nn_idx,
        k,
        &scan,
        &kappa,
        None,
        None,
        &params.model.nbody,
        None,
        &mut proposed,
    );
    let start_vel = vel.clone();
    nbody::step(
        &pos,
        &mut vel,
        &nn_idx,
        k,
        &scan,
        &kappa,
        None,
        None,
        &params.model.nbody,
        None,
        &mut proposed,
    );
    let vel = start_vel;

    let mut normals_old = vec![[0.0; 3]; m];
    let mut normals_new = vec![[0.0; 3]; m];
    vertex_normals(&pos, &faces, &incidence, &mut normals_old);
    vertex_normals(&proposed, &faces, &incidence, &mut normals_new);
    let raw: Vec<Mat3> = (0..m)
        .into_par_iter()
        .map(|v| {
            deformation_gradient(
                v,
                rings.of(v),
                &pos,
                &proposed,
                &normals_old[v],
                &normals_new[v],
                params.model.normal_completion,
                FAST_MATRIX,
            )
            .0
        })
        .collect();
    let mut buffers = RegularizeBuffers::new(m);
    let mut reg_rotation = vec![Mat3::identity(); m];
    let mut reg_stretch = vec![Mat3::identity(); m];
    regularize(
        &raw,
        &rings,
        params.readings.regularization,
        FAST_MATRIX,
        &mut buffers,
        &mut reg_rotation,
        &mut reg_stretch,
    );
    let stretch_hat = reg_stretch
        .par_iter()
        .map(|u| modified_stretch(u, params.model.psi).stretch)
        .collect();

    State {
        params,
        scan,
        kappa,
        index,
        k,
        faces,
        incidence,
        rings,
        pos,
        vel,
        nn_idx,
        nn_d2,
        proposed,
        normals_old,
        normals_new,
        raw,
        reg_rotation,
        reg_stretch,
        stretch_hat,
    }
}

/// Buffers of one whole iteration, allocated once (as the fit driver does).
struct IterationBuffers {
    pos: Vec<[f64; 3]>,
    vel: Vec<[f64; 3]>,
    nn_idx: Vec<u32>,
    nn_d2: Vec<f64>,
    /// The fit's k-NN candidate cache, primed at the state's positions.
    cache: NeighborCache,
    proposed: Vec<[f64; 3]>,
    next: Vec<[f64; 3]>,
    ws: Workspace,
}

impl IterationBuffers {
    fn new(s: &State) -> Self {
        let m = s.pos.len();
        let (mut nn_idx, mut nn_d2) = (vec![0; m * s.k], vec![0.0; m * s.k]);
        let mut cache = NeighborCache::new(m, s.k, s.scan.len());
        cache.query(&s.index, &s.pos, &mut nn_idx, &mut nn_d2);
        Self {
            pos: s.pos.clone(),
            vel: s.vel.clone(),
            nn_idx,
            nn_d2,
            cache,
            proposed: vec![[0.0; 3]; m],
            next: vec![[0.0; 3]; m],
            ws: Workspace::new(m),
        }
    }
}

/// One iteration of the paper preset (the FoldMatch phase): k-NN (through the fit's candidate
/// cache, as `fit` does by default), N-body step, Eq. 4–8, per-vertex update. Starts from the same state every time (positions and velocities are
/// restored first; that copy is two M×3 memcpys, negligible).
fn one_iteration(s: &State, b: &mut IterationBuffers) {
    b.pos.copy_from_slice(&s.pos);
    b.vel.copy_from_slice(&s.vel);
    b.cache.query(&s.index, &b.pos, &mut b.nn_idx, &mut b.nn_d2);
    nbody::step(
        &b.pos,
        &mut b.vel,
        &b.nn_idx,
        s.k,
        &s.scan,
        &s.kappa,
        None,
        None,
        &s.params.model.nbody,
        None,
        &mut b.proposed,
    );
    let topo = TemplateTopology {
        faces: &s.faces,
        incidence: &s.incidence,
        rings: &s.rings,
    };
    deformation_model(&b.pos, &b.proposed, &topo, &s.params, &mut b.ws);
    let (rot, old, new) = (&b.ws.rotation, &b.pos, &b.proposed);
    b.next.par_iter_mut().enumerate().for_each(|(v, out)| {
        let (c_old, c_new) = ring_centroids(s.rings.of(v), old, new);
        *out = transform_vertex(&rot[v], &vec3(&old[v]), &c_old, &c_new).into();
    });
    black_box(&b.next);
}

fn configure(c: &mut Criterion) -> criterion::BenchmarkGroup<'_, criterion::measurement::WallTime> {
    let mut g = c.benchmark_group("paper_sized");
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    g.sampling_mode(SamplingMode::Flat);
    g
}

fn bench_stages(c: &mut Criterion) {
    let s = setup();
    let m = s.pos.len();
    eprintln!(
        "paper-sized state: M = {m}, N = {}, K = {}, mean ring = {:.1}, threads = {}",
        s.scan.len(),
        s.k,
        s.rings.members.len() as f64 / m as f64,
        rayon::current_num_threads()
    );
    let mut g = configure(c);

    // Target neighborhoods Γᵏ_X (every iteration) and the scan's k-d tree (once per fit).
    g.bench_function("knn/nearest_all", |b| {
        let (mut idx, mut d2) = (vec![0u32; m * s.k], vec![0.0; m * s.k]);
        b.iter(|| {
            s.index
                .nearest_all(black_box(&s.pos), s.k, &mut idx, &mut d2)
        });
    });
    g.bench_function("knn/neighbor_cache", |b| {
        // The fit's default path: candidates cached at `pos`, queried at the moved positions.
        let (mut idx, mut d2) = (vec![0u32; m * s.k], vec![0.0; m * s.k]);
        let mut cache = NeighborCache::new(m, s.k, s.scan.len());
        cache.query(&s.index, &s.pos, &mut idx, &mut d2);
        b.iter(|| cache.query(&s.index, black_box(&s.proposed), &mut idx, &mut d2));
    });
    g.bench_function("knn/build_scan_tree", |b| {
        b.iter(|| PointIndex::new(black_box(&s.scan)))
    });

    // Two-way attraction (default preset): nearest vertex of every scan point (from the
    // forward lists, or a template tree for every scan point), reverse forces.
    let forward = TargetNeighbours {
        indices: &s.nn_idx,
        dist2: &s.nn_d2,
        k: s.k,
        exact: true,
    };
    for (name, from_forward) in [
        ("two_way/reverse_attraction", true),
        ("two_way/reverse_attraction_tree_only", false),
    ] {
        g.bench_function(name, |b| {
            let mut reverse = nbody::ReverseAttraction::new(m, s.scan.len(), from_forward);
            let mut force = vec![[0.0; 3]; m];
            b.iter(|| {
                let (x, kappa, p) = (&s.scan, &s.kappa, &s.params.model.nbody);
                let two_way = nbody::TwoWay {
                    weight: 1.0,
                    pull: TwoWayPull::Coverage,
                    trust_radius: f64::INFINITY,
                    rim: None,
                    weights: None,
                };
                reverse.compute(&s.pos, x, kappa, forward, &two_way, p, &mut force)
            });
        });
    }

    // Force and integration, Eq. 2–3.
    g.bench_function("force/nbody_step", |b| {
        let mut proposed = vec![[0.0; 3]; m];
        b.iter_batched_ref(
            || s.vel.clone(),
            |vel| {
                nbody::step(
                    &s.pos,
                    vel,
                    &s.nn_idx,
                    s.k,
                    &s.scan,
                    &s.kappa,
                    None,
                    None,
                    &s.params.model.nbody,
                    None,
                    &mut proposed,
                )
            },
            BatchSize::LargeInput,
        );
    });

    // Deformation gradients, Eq. 4 (normals of both states, then one 3×3 solve per vertex).
    g.bench_function("gradient/vertex_normals_x2", |b| {
        let mut n = vec![[0.0; 3]; m];
        b.iter(|| {
            vertex_normals(&s.pos, &s.faces, &s.incidence, &mut n);
            vertex_normals(&s.proposed, &s.faces, &s.incidence, &mut n);
        });
    });
    g.bench_function("gradient/deformation_gradient", |b| {
        let mut out = vec![Mat3::identity(); m];
        let c = s.params.model.normal_completion;
        b.iter(|| {
            out.par_iter_mut().enumerate().for_each(|(v, h)| {
                *h = deformation_gradient(
                    v,
                    s.rings.of(v),
                    &s.pos,
                    &s.proposed,
                    &s.normals_old[v],
                    &s.normals_new[v],
                    c,
                    FAST_MATRIX,
                )
                .0;
            });
        });
    });

    // Regularization, Eq. 5: the polar decompositions alone, then the whole stage.
    g.bench_function("regularize/polar", |b| {
        let mut out = vec![(Mat3::identity(), Mat3::identity()); m];
        b.iter(|| {
            out.par_iter_mut().zip(s.raw.par_iter()).for_each(|(o, h)| {
                let p = polar(h);
                *o = (p.rotation, p.stretch);
            });
        });
    });
    g.bench_function("regularize/full", |b| {
        let mut buffers = RegularizeBuffers::new(m);
        let (mut r, mut u) = (vec![Mat3::identity(); m], vec![Mat3::identity(); m]);
        b.iter(|| {
            regularize(
                &s.raw,
                &s.rings,
                s.params.readings.regularization,
                FAST_MATRIX,
                &mut buffers,
                &mut r,
                &mut u,
            )
        });
    });

    // ψ-modified stretch and wrinkle vectors (Eq. 6–7), rotation solve (Eq. 8).
    g.bench_function("wrinkle/modified_stretch", |b| {
        let mut out = vec![Mat3::identity(); m];
        b.iter(|| {
            out.par_iter_mut()
                .zip(s.reg_stretch.par_iter())
                .for_each(|(o, u)| *o = modified_stretch(u, s.params.model.psi).stretch);
        });
    });
    g.bench_function("rotation/solve_rotation", |b| {
        let mut out = vec![Mat3::identity(); m];
        b.iter(|| {
            out.par_iter_mut().enumerate().for_each(|(v, o)| {
                *o = solve_rotation(
                    &(s.reg_rotation[v] * s.reg_stretch[v]),
                    &s.stretch_hat[v],
                    FAST_MATRIX,
                );
            });
        });
    });

    // Per-vertex update: ring centroids and Y_k ← R_k* (Y_k − c) + c'.
    g.bench_function("update/transform", |b| {
        let mut out = vec![[0.0; 3]; m];
        b.iter(|| {
            out.par_iter_mut().enumerate().for_each(|(v, o)| {
                let (c_old, c_new) = ring_centroids(s.rings.of(v), &s.pos, &s.proposed);
                *o = transform_vertex(&s.reg_rotation[v], &vec3(&s.pos[v]), &c_old, &c_new).into();
            });
        });
    });

    // The whole deformation model (Eq. 4–8) and one whole iteration.
    g.bench_function("model/deformation_model", |b| {
        let mut ws = Workspace::new(m);
        let topo = TemplateTopology {
            faces: &s.faces,
            incidence: &s.incidence,
            rings: &s.rings,
        };
        b.iter(|| deformation_model(&s.pos, &s.proposed, &topo, &s.params, &mut ws));
    });
    g.bench_function("iteration/all_threads", |b| {
        let mut buffers = IterationBuffers::new(&s);
        b.iter(|| one_iteration(&s, &mut buffers));
    });
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        g.bench_function(format!("iteration/threads_{threads}"), |b| {
            let mut buffers = IterationBuffers::new(&s);
            b.iter(|| pool.install(|| one_iteration(&s, &mut buffers)));
        });
    }

    // Per-fit setup: template rings and the point-cloud curvature of the scan.
    g.bench_function("setup/n_rings", |b| {
        b.iter(|| n_rings(black_box(&s.faces), m, s.params.model.rings))
    });
    g.bench_function("setup/curvature_points", |b| {
        b.iter(|| gaussian_curvature_points(&s.scan, &s.index))
    });
    g.finish();

    bench_layouts(c, &s);

    // The 3×3 kernels every stage is built on, per call, over the regularized stretches and
    // raw gradients of the state (sequential, one core).
    let mut g = c.benchmark_group("kernels");
    g.sample_size(20)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1));
    let sample = 4096.min(m);
    g.throughput(criterion::Throughput::Elements(sample as u64));
    g.bench_function("sym_eigen3", |b| {
        b.iter(|| {
            s.reg_stretch[..sample]
                .iter()
                .map(|u| sym_eigen3(black_box(u)).values[0])
                .sum::<f64>()
        })
    });
    g.bench_function("polar", |b| {
        b.iter(|| {
            s.raw[..sample]
                .iter()
                .map(|h| polar(black_box(h)).stretch[(0, 0)])
                .sum::<f64>()
        })
    });
    // The nearest rotation of the raw gradients: the eigen-decomposition (the exact reference
    // path), the unit-quaternion solution and the Newton–Schulz iteration the fast paths use
    // (the latter for near-rotations such as these per-iteration gradients).
    type RotationPath = fn(&Mat3) -> Mat3;
    let eigen: RotationPath = nearest_rotation;
    let quaternion: RotationPath = nearest_rotation_fast;
    let newton_schulz: RotationPath = nearest_rotation_of_near_rotation;
    for (name, rotation) in [
        ("nearest_rotation/eigen", eigen),
        ("nearest_rotation/quaternion", quaternion),
        ("nearest_rotation/newton_schulz", newton_schulz),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| {
                s.raw[..sample]
                    .iter()
                    .map(|h| rotation(black_box(h))[(0, 0)])
                    .sum::<f64>()
            })
        });
    }
    g.finish();
}

/// Positions in a layout: the fit's array of structs `[f64; 3]`, a padded `[f64; 4]`, or a
/// struct of arrays (x, y, z apart), for [`bench_layouts`].
trait Layout: Sized {
    fn from_points(points: &[[f64; 3]]) -> Self;
    fn at(&self, j: usize) -> [f64; 3];
    /// `self += a · other`, point by point (a streaming update, as the velocity and
    /// displacement loops).
    fn axpy(&mut self, a: f64, other: &Self);
}

struct Aos(Vec<[f64; 3]>);
struct Padded(Vec<[f64; 4]>);
struct Soa([Vec<f64>; 3]);

impl Layout for Aos {
    fn from_points(points: &[[f64; 3]]) -> Self {
        Self(points.to_vec())
    }
    #[inline]
    fn at(&self, j: usize) -> [f64; 3] {
        self.0[j]
    }
    fn axpy(&mut self, a: f64, other: &Self) {
        for (p, q) in self.0.iter_mut().zip(&other.0) {
            (0..3).for_each(|i| p[i] += a * q[i]);
        }
    }
}

impl Layout for Padded {
    fn from_points(points: &[[f64; 3]]) -> Self {
        Self(points.iter().map(|p| [p[0], p[1], p[2], 0.0]).collect())
    }
    #[inline]
    fn at(&self, j: usize) -> [f64; 3] {
        let p = &self.0[j];
        [p[0], p[1], p[2]]
    }
    fn axpy(&mut self, a: f64, other: &Self) {
        for (p, q) in self.0.iter_mut().zip(&other.0) {
            (0..4).for_each(|i| p[i] += a * q[i]);
        }
    }
}

impl Layout for Soa {
    fn from_points(points: &[[f64; 3]]) -> Self {
        Self([0, 1, 2].map(|i| points.iter().map(|p| p[i]).collect()))
    }
    #[inline]
    fn at(&self, j: usize) -> [f64; 3] {
        [self.0[0][j], self.0[1][j], self.0[2][j]]
    }
    fn axpy(&mut self, a: f64, other: &Self) {
        for (xs, ys) in self.0.iter_mut().zip(&other.0) {
            xs.iter_mut().zip(ys).for_each(|(x, y)| *x += a * y);
        }
    }
}

/// Σ over the rows of `rows` (CSR-like: row v is `members[offsets[v]..offsets[v + 1]]`) of the
/// members' positions: the gather every stage does (Eq. 2 over the K nearest scan points,
/// Eq. 4 and 8 over the 2-ring).
fn gather_sums<L: Layout>(
    points: &L,
    rows: impl Fn(usize) -> std::ops::Range<usize>,
    members: &[u32],
    m: usize,
) -> f64 {
    (0..m)
        .map(|v| {
            let mut s = [0.0; 3];
            for &j in &members[rows(v)] {
                let p = points.at(j as usize);
                (0..3).for_each(|i| s[i] += p[i]);
            }
            s[0] + s[1] + s[2]
        })
        .sum()
}

/// The position layout, measured (issue "Performance": "SoA/AoS layout chosen by measurement")
/// on the paper-sized state, one core: the gathers through the K-NN lists (scan points, random
/// order within a neighbourhood) and through the 2-rings (template vertices), which every stage
/// does, and a streaming update over all vertices, the one access SoA favours.
fn bench_layouts(c: &mut Criterion, s: &State) {
    fn run<L: Layout>(
        g: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
        name: &str,
        s: &State,
    ) {
        let (m, k) = (s.pos.len(), s.k);
        let scan = L::from_points(&s.scan);
        let pos = L::from_points(&s.pos);
        g.bench_function(format!("gather_knn/{name}"), |b| {
            b.iter(|| gather_sums(black_box(&scan), |v| v * k..(v + 1) * k, &s.nn_idx, m))
        });
        let offsets = &s.rings.offsets;
        g.bench_function(format!("gather_rings/{name}"), |b| {
            b.iter(|| {
                gather_sums(
                    black_box(&pos),
                    |v| offsets[v]..offsets[v + 1],
                    &s.rings.members,
                    m,
                )
            })
        });
        let mut moving = L::from_points(&s.pos);
        let vel = L::from_points(&s.vel);
        g.bench_function(format!("stream_axpy/{name}"), |b| {
            b.iter(|| moving.axpy(black_box(1e-3), &vel))
        });
    }
    let mut g = c.benchmark_group("layout");
    g.sample_size(20)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1));
    run::<Aos>(&mut g, "aos", s);
    run::<Padded>(&mut g, "padded", s);
    run::<Soa>(&mut g, "soa", s);
    g.finish();
}

criterion_group!(benches, bench_stages);
criterion_main!(benches);
