//! The state every schedule of a fit shares: the inputs validated and in the normalized frame,
//! the scan's k-d tree, K and curvature, the template's neighborhoods and the phases' samples.

use super::attraction::{explained_points, Rim, ScanPoints, DRESSED_TRUST_FACTOR};
use super::landmark_pull::LandmarkTargets;
use super::model::TemplateTopology;
use super::params::{FitParams, Method, Prealign, FAR_AWAY};
use super::result::Diagnostics;
use super::rim_match::RimMatch;
use super::symmetry::RigidSymmetry;
use crate::curvature::{gaussian_curvature_mesh, gaussian_curvature_points};
use crate::error::{FoldMatchError, Result};
use crate::knn::{morton_order, neighborhood_size, PointIndex};
use crate::landmarks::Landmarks;
use crate::math::{vec3, Vec3};
use crate::mesh::{clean_faces, validate_faces, validate_points, VertexFaces};
use crate::normalize::Frame;
use crate::rings::{adjacency, n_rings_of, Neighborhoods, RingDeltas};
use crate::rotation::ring_centroids;
use rayon::prelude::*;

/// What every schedule of a fit reads and none writes: the inputs validated and in the normalized
/// frame (docs/method.md, "Frame"), the scan's k-d tree and curvature, the template's topology.
/// Built once per [`fit`](super::fit), shared by both runs of schedule selection.
pub(super) struct Prepared {
    pub(super) faces: Vec<[u32; 3]>,
    pub(super) frame: Frame,
    /// The scan in the normalized frame, in [`morton_order`], with its curvature, tree and K.
    pub(super) target: ScanPoints,
    /// The template in the normalized frame, after any pre-alignment.
    pub(super) start: Vec<[f64; 3]>,
    /// The rest shape of the rest-shape rigidity in the normalized frame: `start`, or the
    /// template a warm-started frame is anchored to ([`fit_anchored`](super::fit_anchored),
    /// docs/method.md "Tracking").
    pub(super) rest: Vec<[f64; 3]>,
    pub(super) incidence: VertexFaces,
    /// Γᵏ_Y: n-rings (FoldMatch) or k-NN neighborhoods (NRGa).
    pub(super) rings: Neighborhoods,
    /// The centroid of every vertex's ring of `rest`, for
    /// [`rest_rigidity`](crate::fit::Schedule::rest_rigidity) and the carried vertices of
    /// [`carry_unsupported`](crate::fit::Schedule::carry_unsupported); empty when no schedule
    /// uses them.
    pub(super) rest_centroids: Vec<Vec3>,
    /// The coarse phase's neighborhoods, one per level (empty when no schedule has one).
    pub(super) coarse_levels: Vec<Neighborhoods>,
    /// Their rows as differences of adjacent rows, for the sums over them.
    pub(super) coarse_deltas: Vec<RingDeltas>,
    /// Under `coarse_sample` = s > 1: per level, the sampled members of every vertex's coarse
    /// ring, as indices into the sample (vertex u ≡ 0 mod s is sample u / s).
    pub(super) coarse_sampled: Vec<Neighborhoods>,
    /// Every vertex index (the rigid phase's "ring"; empty when no schedule has one).
    pub(super) all_vertices: Vec<u32>,
    /// The rigid phase's parts where the template has several connected components (garments,
    /// paper Fig. 1) and the scan holds more than the template: each vertex's part, and the
    /// vertices of each part ([`rigid_parts`]); empty for a template of one piece, on a
    /// garment-only scan, or when no schedule has a rigid phase.
    pub(super) rigid_parts: RigidParts,
    /// The template's free axes for the rigid phase, when it has any as placed (a tube's
    /// axis; docs/method.md "Rigid phase").
    pub(super) symmetry: Option<RigidSymmetry>,
    /// The phases' scan samples
    /// ([`rigid_scan_sample`](crate::fit::Acceleration::rigid_scan_sample),
    /// [`coarse_scan_sample`](crate::fit::Acceleration::coarse_scan_sample)), one per stride > 1 in
    /// use.
    pub(super) scan_samples: Vec<ScanPoints>,
    /// The strides of the rigid and the coarse phase's scan samples (1: the whole scan).
    pub(super) scan_strides: [usize; 2],
    /// The template's mean edge length in the normalized frame (the floor of the two-way
    /// trust radius, [`two_way_trust`](crate::fit::Schedule::two_way_trust)).
    pub(super) edge_length: f64,
    /// The template's boundary vertices and their one-rings (for
    /// [`two_way_rim`](crate::fit::Schedule::two_way_rim); empty when no schedule uses it).
    pub(super) rim: Rim,
    /// The template's and the mesh target's boundary loops, when a schedule matches them
    /// ([`rim_weight`](crate::fit::Schedule::rim_weight)) on a mesh target of the garment
    /// alone, every point kept (docs/method.md "Rim matching").
    pub(super) rim_match: Option<RimMatch>,
    /// The scan points (user indices) that schedule selection's scan distance averages over:
    /// those the template explains where the scan holds more than the garment
    /// ([`explained_points`]); `None`: every point of positive weight.
    pub(super) garment: Option<Vec<usize>>,
    /// The landmarks, in the normalized frame (docs/method.md "Landmarks").
    pub(super) landmarks: Option<LandmarkTargets>,
    /// The diagnostics every run starts from.
    pub(super) diagnostics: Diagnostics,
}

impl Prepared {
    /// Validates the inputs and builds the shared state; `schedules` differ at most in their
    /// schedule fields ([`FitParams::sharp_schedule`]), the first one's structure is used.
    /// `rest`: the rest shape of the rest-shape rigidity when it is not the template itself
    /// (same vertex count; the caller validates it). With `landmarks` the template comes placed
    /// by them (`fit_from`) and no pre-alignment moves it here.
    #[allow(clippy::too_many_arguments)] // the fit's inputs, as `fit_scan` takes them
    pub(super) fn new(
        template_vertices: &[[f64; 3]],
        rest: Option<&[[f64; 3]]>,
        template_faces: &[[u32; 3]],
        target: &[[f64; 3]],
        target_faces: Option<&[[u32; 3]]>,
        weights: Option<&[f64]>,
        kept: Option<&[usize]>,
        landmarks: Option<&Landmarks>,
        several: bool,
        schedules: &[FitParams],
    ) -> Result<Self> {
        let params = &schedules[0];
        validate_points("template_vertices", template_vertices)?;
        validate_points("target", target)?;
        let user_target = target;
        validate_faces("template_faces", template_faces, template_vertices.len())?;
        if let Some(tf) = target_faces {
            validate_faces("target_faces", tf, target.len())?;
        }
        let m = template_vertices.len();
        let cleaned = clean_faces(template_faces);
        let faces = cleaned.faces;

        // The scan points that remain (weight > 0), with their weights.
        let remaining: Option<Vec<[f64; 3]>> = kept.map(|k| k.iter().map(|&j| target[j]).collect());
        let fitted = remaining.as_deref().unwrap_or(target);
        let weights: Option<Vec<f64>> =
            weights.map(|w| kept.map_or_else(|| w.to_vec(), |k| k.iter().map(|&j| w[j]).collect()));

        // Normalized frame (docs/method.md, "Frame"), of the points that remain, or of those the
        // template explains where the scan holds far more than the garment (a dressed body).
        let garment = explained_points(fitted, template_vertices, template_faces, params, several);
        let garment_points: Option<Vec<[f64; 3]>> = garment
            .as_ref()
            .map(|g| g.iter().map(|&j| fitted[j as usize]).collect());
        let frame_points = garment_points.as_deref().unwrap_or(fitted);
        let frame = if params.readings.normalize {
            Frame::of_target(frame_points)
        } else {
            Frame::identity()
        };
        let all_scan = frame.forward(target);
        let mut start = frame.forward(template_vertices);
        let centroid = start.iter().fold(Vec3::zeros(), |acc, p| acc + vec3(p)) / m as f64;
        let scan_centroid = (fitted.iter().fold(Vec3::zeros(), |acc, p| acc + vec3(p))
            / fitted.len() as f64
            - vec3(&frame.center))
            / frame.scale;
        let scan_diag = if params.readings.normalize {
            1.0
        } else {
            Frame::of_target(fitted).scale
        };
        let offset = centroid - scan_centroid;
        match params.prealign {
            // Placed by the landmarks already (`fit_from`).
            _ if landmarks.is_some() => {}
            Prealign::Centroid => {
                for p in &mut start {
                    *p = (vec3(p) - offset).into();
                }
            }
            Prealign::None if offset.norm() > FAR_AWAY * scan_diag => {
                return Err(FoldMatchError::FarAway {
                    distance: offset.norm() / scan_diag,
                });
            }
            Prealign::None | Prealign::Rigid | Prealign::Similarity => {}
        }

        // Target side, in space-filling-curve order ([`morton_order`]; only round-off depends
        // on the scan's order): k-d tree, K, curvature (a mesh's, of the given order).
        // A mesh's curvature is of the whole mesh; only the remaining points are fitted.
        let mesh_kappa = target_faces
            .filter(|f| params.readings.use_curvature && !f.is_empty())
            .map(|tf| gaussian_curvature_mesh(&all_scan, tf))
            .map(|kappa| match kept {
                Some(k) => k.iter().map(|&j| kappa[j]).collect(),
                None => kappa,
            });
        let scan = match kept {
            Some(k) => k.iter().map(|&j| all_scan[j]).collect(),
            None => all_scan,
        };
        let order = morton_order(&scan);
        let scan: Vec<[f64; 3]> = order.iter().map(|&j| scan[j as usize]).collect();
        let weights: Option<Vec<f64>> =
            weights.map(|w| order.iter().map(|&j| w[j as usize]).collect());
        let index = PointIndex::new(&scan);
        let k = neighborhood_size(
            params.model.rho,
            frame_points.len(),
            params.model.k_min,
            params.model.k_max,
        );
        let (kappa, curvature_source) = match mesh_kappa {
            _ if !params.readings.use_curvature => (vec![0.0; scan.len()], "off"),
            Some(kappa) => (order.iter().map(|&j| kappa[j as usize]).collect(), "mesh"),
            None => (gaussian_curvature_points(&scan, &index), "point_cloud"),
        };

        // Template side: incidence, neighborhoods, the phases' neighborhoods.
        let incidence = VertexFaces::new(&faces, m);
        let isolated = (0..m)
            .filter(|&v| incidence.offsets[v] == incidence.offsets[v + 1])
            .count();
        // The one-rings, for the n-rings and the ring deltas (built once, and only if used:
        // NRGa's neighbourhoods are k-nearest, and it has no coarse phase).
        let one_rings = std::cell::LazyCell::new(|| adjacency(&faces, m));
        let rings = match params.method {
            Method::FoldMatch => n_rings_of(&one_rings, params.model.rings),
            Method::Nrga => knn_neighborhoods(&start, params),
        };
        let phases: Vec<(usize, usize)> =
            schedules.iter().map(FitParams::phase_iterations).collect();
        let target = ScanPoints {
            stride: 1,
            points: scan,
            kappa,
            weights,
            index,
            k,
        };
        let n = target.points.len();
        let scan_strides = [
            if phases.iter().any(|p| p.0 > 0) {
                params.rigid_scan_stride(m, n)
            } else {
                1
            },
            if phases.iter().any(|p| p.1 > 0) {
                params.coarse_scan_stride(m, n)
            } else {
                1
            },
        ];
        let mut scan_samples: Vec<ScanPoints> = Vec::new();
        for &stride in &scan_strides {
            if stride > 1 && !scan_samples.iter().any(|s| s.stride == stride) {
                scan_samples.push(target.sample(stride));
            }
        }
        let all_vertices = if phases.iter().any(|p| p.0 > 0) {
            (0..m as u32).collect()
        } else {
            Vec::new()
        };
        // One rigid motion per garment on a scan that holds more than the template (a dressed
        // body with several garments); on a garment-only scan the components are pieces of one
        // garment (panels, sleeves as separate tubes), which move together.
        let rigid_parts = if garment.is_some() && phases.iter().any(|p| p.0 > 0) {
            rigid_parts(&faces, m)
        } else {
            RigidParts::default()
        };
        let symmetry = if phases.iter().any(|p| p.0 > 0) {
            RigidSymmetry::new(&start, &faces)
        } else {
            None
        };
        let coarse_radius = if phases.iter().any(|p| p.1 > 0) {
            params.coarse_radius(m)
        } else {
            0
        };
        let coarse_levels = if coarse_radius > 0 {
            (0..params.schedule.coarse_levels)
                .map(|l| n_rings_of(&one_rings, (coarse_radius >> l).max(1)))
                .collect()
        } else {
            Vec::new()
        };
        let rest = match rest {
            Some(r) => frame.forward(r),
            None => start.clone(),
        };
        let rest_centroids = if schedules.iter().any(|p| {
            (p.method == Method::FoldMatch && p.schedule.rest_rigidity > 0.0) || p.carries()
        }) {
            (0..m)
                .into_par_iter()
                .map(|v| ring_centroids(rings.of(v), &rest, &rest).0)
                .collect()
        } else {
            Vec::new()
        };
        let coarse_deltas = if coarse_levels.is_empty() {
            Vec::new()
        } else {
            coarse_levels
                .iter()
                .map(|rings| RingDeltas::new(rings, &one_rings))
                .collect()
        };
        let stride = params.acceleration.coarse_sample;
        let coarse_sampled = if stride > 1 {
            coarse_levels
                .iter()
                .map(|rings: &Neighborhoods| {
                    Neighborhoods::from_rows(
                        (0..m)
                            .map(|v| {
                                let ring = rings.of(v).iter();
                                ring.filter(|&&u| (u as usize).is_multiple_of(stride))
                                    .map(|&u| u / stride as u32)
                                    .collect()
                            })
                            .collect(),
                    )
                })
                .collect()
        } else {
            Vec::new()
        };

        let landmarks = landmarks.map(|l| LandmarkTargets::new(l, &frame, &coarse_levels));
        let edge_length = mean_edge_length(&start, &faces);
        // The rim rule is for scans that hold more than the garment: on a garment alone, the
        // scan beyond a boundary is garment the template has yet to cover.
        let rim = if garment.is_some()
            && schedules
                .iter()
                .any(|p| p.schedule.two_way_rim > 0.0 && p.schedule.two_way > 0.0)
        {
            let vertices = crate::mesh::boundary_vertices(&faces, m);
            let rings = Neighborhoods::from_rows(
                vertices
                    .iter()
                    .map(|&v| one_rings.of(v as usize).to_vec())
                    .collect(),
            );
            Rim { vertices, rings }
        } else {
            Rim::default()
        };
        let rim_match = target_faces
            .filter(|_| garment.is_none() && kept.is_none() && !several)
            .filter(|_| schedules.iter().any(|p| p.schedule.rim_weight > 0.0))
            .and_then(|tf| RimMatch::new(&rest, &faces, &frame.forward(user_target), tf));
        let diagnostics = Diagnostics {
            target_neighbours: k,
            coarse_rings: coarse_radius,
            mean_ring_size: rings.members.len() as f64 / m as f64,
            degenerate_faces: cleaned.degenerate,
            duplicate_faces: cleaned.duplicate,
            isolated_vertices: isolated,
            omega0_dt_squared: params.model.nbody.omega0_dt_squared(k),
            curvature: curvature_source.into(),
            frame: Some(frame),
            schedule: "given".into(),
            free_axes: symmetry.as_ref().map_or(0, RigidSymmetry::axes),
            ..Default::default()
        };
        Ok(Self {
            faces,
            frame,
            target,
            start,
            rest,
            incidence,
            rings,
            rest_centroids,
            coarse_levels,
            coarse_deltas,
            coarse_sampled,
            all_vertices,
            rigid_parts,
            symmetry,
            scan_samples,
            scan_strides,
            edge_length,
            rim,
            rim_match,
            garment: garment.map(|g| {
                g.iter()
                    .map(|&j| kept.map_or(j as usize, |k| k[j as usize]))
                    .collect()
            }),
            landmarks,
            diagnostics,
        })
    }

    /// The two-way trust radius's multiple c of a schedule:
    /// [`two_way_trust`](crate::fit::Schedule::two_way_trust), or [`DRESSED_TRUST_FACTOR`] of it on
    /// a scan that holds more than the garment.
    pub(super) fn trust(&self, params: &FitParams) -> f64 {
        match self.garment {
            Some(_) => DRESSED_TRUST_FACTOR * params.schedule.two_way_trust,
            None => params.schedule.two_way_trust,
        }
    }

    /// The scan points a phase sees: the whole scan (`stride` 1), or the scan sample of that
    /// stride.
    pub(super) fn scan_points(&self, stride: usize) -> &ScanPoints {
        self.scan_samples
            .iter()
            .find(|s| s.stride == stride)
            .unwrap_or(&self.target)
    }

    pub(super) fn topology(&self) -> TemplateTopology<'_> {
        TemplateTopology {
            faces: &self.faces,
            incidence: &self.incidence,
            rings: &self.rings,
        }
    }
}

/// The rigid phase's parts of a template with several garments: each vertex's part and each
/// part's vertices, in increasing order.
#[derive(Default)]
pub(super) struct RigidParts {
    pub(super) of: Vec<u32>,
    pub(super) vertices: Vec<Vec<u32>>,
}

/// A connected component of the template with fewer vertices than this moves with the largest
/// component in the rigid phase: a stray vertex or a small piece does not determine a rigid
/// motion of its own.
pub const MIN_RIGID_PART: usize = 16;

/// The rigid phase's parts: the template's connected components of at least [`MIN_RIGID_PART`]
/// vertices, the smaller ones joined to the largest (docs/method.md "Rigid phase"); none when that
/// leaves one part.
pub(super) fn rigid_parts(faces: &[[u32; 3]], m: usize) -> RigidParts {
    let (label, count) = crate::mesh::connected_components(faces, m);
    let mut size = vec![0usize; count];
    label.iter().for_each(|&l| size[l as usize] += 1);
    let largest = (0..count)
        .max_by_key(|&c| (size[c], usize::MAX - c))
        .unwrap_or(0);
    let mut part = vec![u32::MAX; count];
    let mut parts = 0u32;
    for c in 0..count {
        if size[c] >= MIN_RIGID_PART || c == largest {
            part[c] = parts;
            parts += 1;
        }
    }
    if parts < 2 {
        return RigidParts::default();
    }
    let of: Vec<u32> = label
        .iter()
        .map(|&l| match part[l as usize] {
            u32::MAX => part[largest],
            p => p,
        })
        .collect();
    let mut vertices = vec![Vec::new(); parts as usize];
    for (v, &p) in of.iter().enumerate() {
        vertices[p as usize].push(v as u32);
    }
    RigidParts { of, vertices }
}

/// The mean length of the template's edges (each face's three, shared edges counted twice).
pub(super) fn mean_edge_length(vertices: &[[f64; 3]], faces: &[[u32; 3]]) -> f64 {
    let sum: f64 = faces
        .iter()
        .map(|f| {
            let p = f.map(|v| &vertices[v as usize]);
            (0..3)
                .map(|i| crate::math::dist2(p[i], p[(i + 1) % 3]).sqrt())
                .sum::<f64>()
        })
        .sum();
    sum / (3 * faces.len()).max(1) as f64
}

/// NRGa neighborhoods: the K_Y nearest template points of every template vertex (itself
/// included), `K_Y = clamp(⌊ρM⌋, k_min, k_max)`, on the initial template.
pub(super) fn knn_neighborhoods(start: &[[f64; 3]], params: &FitParams) -> Neighborhoods {
    let m = start.len();
    let k = neighborhood_size(params.model.rho, m, params.model.k_min, params.model.k_max);
    let index = PointIndex::new(start);
    let mut idx = vec![0u32; m * k];
    let mut d2 = vec![0.0; m * k];
    index.nearest_all(start, k, &mut idx, &mut d2);
    Neighborhoods {
        offsets: (0..=m).map(|i| i * k).collect(),
        members: idx,
    }
}
