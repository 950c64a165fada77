//! Isometric refinement (docs/method.md "Isometric refinement"): after the schedule, the fit is
//! moved to the minimum of
//!
//! ```text
//! E(Y) = w Σ_edges ‖(Y_i − Y_k) − d_ik‖²        edge springs, d_ik = s ℓ⁰_ik (Y_i − Y_k) / ‖Y_i − Y_k‖
//!      + h Σ_edges ‖(Y_i − Y_k) − (Y⁰_i − Y⁰_k)‖²  hold: the edge vectors of the fit Y⁰ as the
//!                                                 refinement starts
//!      + Σ_i t_i (n_i · (Y_i − x_i))²             fit → scan: the plane through Y_i's nearest
//!                                                 scan point x_i, its normal n_i the scan's
//!                                                 there or the fit's own at Y_i ([`PlaneNormal`])
//!      + c Σ_j ω_j (e_j · (Σ_l b_jl Y_{f_j,l} − x_j))²
//!                                                 scan → fit: x_j's closest point on the faces
//!                                                 around its nearest vertex (face f_j,
//!                                                 barycentric b_j), measured along e_j
//! ```
//!
//! by local–global iterations: the local step fixes the edge directions `d` (every step), the
//! matches and their directions (every [`MATCH_EVERY`] steps) (e_j: the face's normal where the closest point lies inside the face,
//! towards x_j where it lies on the face's border — the scan beyond the fit's rim); the global
//! step is a sparse linear solve in 3 × 3 blocks, here a few block-Jacobi-preconditioned
//! conjugate-gradient steps warm-started from the current fit. The springs keep every edge at
//! its rest length ℓ⁰ and leave bending free: cloth barely stretches but folds anywhere. `s` is
//! 1 where the rest shape is the scan's own metric (a tracked frame's anchor); in a single fit
//! it is the fit's own scale as the refinement starts (the median over edges of its length ÷
//! ℓ⁰, [`SpringScale`]), so that a template placed at another size than its scan's (a
//! similarity placement, the harness's simulated drapes) keeps its proportions and is not
//! pulled back to its own size. The hold (`h`, 0 unless set) keeps the edge vectors near the
//! schedule's result: on a noisy scan, whose points the point-to-plane term would follow,
//! it keeps the mesh from crumpling at the edge-length scale (flipped faces); with
//! [`HoldWhere::Unsupported`] it holds only the edges where the scan has no points for the fit
//! (`hold.rs`: a garment the schedule left unstretched). Both
//! distance terms measure across the surface only, so the fit moves along the scan freely —
//! where the springs and the scan beyond its rim ask — which undoes a slide along the scan (what
//! makes a tracked sequence drift, docs/method.md "Tracking"). `c` makes the scan → fit term
//! weigh as much as the vertices; `t_i` is 0 for a vertex whose nearest scan point is beyond
//! [`TRIM`] × the median distance and [`REACH`] edge lengths (it has no scan under it) or that
//! lies in a region the schedule carried ([`IsometricRefine::without_scan_under`]), and
//! likewise `ω_j` for a scan point far from the fit; past a free edge `ω_j` is
//! [`FREE_EDGE_WEIGHT`].

use crate::curvature::neighbourhood_frame;
use crate::knn::{BoxTree, PointIndex};
use crate::math::{dist2, sym_eigen3, vec3, Mat3, Vec3};
use crate::mesh::{vertex_normals, VertexFaces};
use crate::metrics::upper_median;
use crate::quality::closest_barycentric;
use crate::rings::{adjacency, ring_lengths, Neighborhoods};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::sync::OnceLock;

mod hold;

/// Matches beyond this multiple of their median distance (and beyond [`REACH`]) are dropped
/// (fit → scan and scan → fit alike).
pub const TRIM: f64 = 3.0;
/// Matches within this many mean rest edge lengths are kept whatever the median: a fit on its
/// scan's surface but slid along it has a median distance of the noise, and the scan beyond
/// its receding rim — what tells the slide — lies farther than a multiple of that.
pub const REACH: f64 = 2.0;
/// Scan points whose plane estimates a scan point's normal.
const NORMAL_NEIGHBOURS: usize = 12;
/// The matches (the local step's correspondences) are refreshed every this many steps; the
/// edge directions every step.
pub const MATCH_EVERY: usize = 3;
/// A scan point whose closest point lies on a face's border counts as beyond the fit's rim
/// when its direction from there makes a cosine below this with the face's normal (it lies
/// along the surface, past the border, rather than above or below it).
pub const RIM_ACROSS: f64 = 0.7;
/// The weight of a scan point past a free edge ([`IsometricRefine::with_free_edges`]) against
/// one on the fit: the fit has not reached the garment's own points there, and their pull,
/// on the rim's faces alone, must carry the whole garment along the scan against the hold,
/// which keeps every edge's vector (a slide along a curved body turns the edges). At one
/// point's weight the hold keeps about half of that slide back (docs/method.md "Free edges").
pub const FREE_EDGE_WEIGHT: f64 = 10.0;
/// Conjugate-gradient steps per global step.
const CG_STEPS: usize = 10;
/// Chunk of the deterministic parallel sums (the same result for any thread count).
const CHUNK: usize = 512;

/// The refinement's fixed data: the mesh's edges with their rest lengths, its vertex–face
/// lists, and the scan with its normals.
pub struct IsometricRefine<'a> {
    faces: &'a [[u32; 3]],
    /// Every vertex's one-ring: the off-diagonal pattern of the global step's matrix.
    ring: Neighborhoods,
    rest_length: Vec<f64>,
    vertex_faces: &'a VertexFaces,
    /// For each slot of `ring.members` (the edge from vertex i to k): the faces holding the
    /// edge, at most two, with the corners of i and k (`u32::MAX`: none).
    edge_faces: Vec<[EdgeFace; 2]>,
    scan: &'a [[f64; 3]],
    weights: Option<&'a [f64]>,
    scan_index: PointIndex,
    /// The scan's normals, given ([`IsometricRefine::with_scan_normals`]) or computed when a
    /// run first needs them ([`PlaneNormal::Scan`]).
    normals: OnceLock<Vec<[f64; 3]>>,
    /// Whose normal the fit → scan plane takes.
    plane_normal: PlaneNormal,
    /// Matches within this distance are never dropped: [`REACH`] mean rest edge lengths.
    reach: f64,
    /// Anchors ([`IsometricRefine::with_anchors`]): each vertex's weight `a_i` (empty: none)
    /// and the point it is held at.
    anchor_weight: Vec<f64>,
    anchor_at: Vec<[f64; 3]>,
    /// Vertices without a fit → scan match (`t_i = 0`): a region the schedule carried without
    /// scan support ([`IsometricRefine::without_scan_under`]); empty: none.
    unmatched: &'a [bool],
    /// Whether scan points beyond the fit's rim pull it ([`IsometricRefine::without_rim_pull`]).
    rim_pull: bool,
    /// Per face, whether the scan beyond its rim pulls it even without the rim pull
    /// ([`IsometricRefine::with_free_edges`]; empty: none).
    free_edge: Vec<bool>,
}

/// The refinement's edge terms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Springs {
    /// `w`: each edge held at its rest length (times `scale`'s factor).
    pub weight: f64,
    /// `h`: each edge vector held at its value in the fit as the refinement starts.
    pub hold: f64,
    /// The size the rest lengths are taken at.
    pub scale: SpringScale,
    /// Which edges the hold applies to.
    pub hold_where: HoldWhere,
}

/// Which edges [`Springs::hold`] applies to.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum HoldWhere {
    /// Every edge.
    #[default]
    Everywhere,
    /// Only where the scan has no points for the fit (a hole, an unseen part): an edge holds
    /// `h` times the share of its two ends without support — a vertex whose one-ring the scan
    /// points choose as nearest less than a quarter as often as a typical vertex's, as the
    /// first matches found them, the region grown by one ring (`hold.rs`). The springs alone
    /// shape the rest: for a garment the schedule left unstretched (docs/method.md "Isometric
    /// refinement", unstretched garments).
    Unsupported,
}

/// The size the edge springs hold the rest shape's proportions at.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpringScale {
    /// The rest lengths themselves: the rest shape is the scan's own metric (a tracked
    /// sequence's first frame).
    Rest,
    /// The rest lengths times the fit's own scale as the refinement starts (the median edge
    /// length ratio): a template placed at any size keeps its proportions.
    Fit,
}

/// The normal of the plane each vertex is pulled onto (through its nearest scan point x_i).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum PlaneNormal {
    /// The scan's normal at x_i (the least-squares plane of its 12 nearest scan points): the
    /// pull has a component along the fit's surface wherever that plane is tilted against it,
    /// which moves a slid fit back (a single fit's default).
    #[default]
    Scan,
    /// The fit's own vertex normal (area-weighted, of the faces around the vertex): the vertex
    /// moves across its surface only, to x_i's level; the plane of a sparse or noisy scan's
    /// points, tilted at folds and by the noise, no longer pushes the fit along itself (the
    /// `"tracking"` preset, whose frames start on their scan; docs/method.md "Tracking").
    Fit,
}

/// Per-iteration buffers (allocated once).
struct Buffers {
    /// Fit → scan: each vertex's nearest scan point, weight `t_i`, and that point's tangent
    /// plane `n · y = n · x` (its normal `n_i` and `p_i = n (n · x)`).
    nearest: Vec<(u32, f64)>,
    t: Vec<f64>,
    normal: Vec<[f64; 3]>,
    p: Vec<[f64; 3]>,
    distance: Vec<f64>,
    /// Room for the medians: of the distances, and of the edge-length ratios ([`IsometricRefine::scale_of`]).
    scratch: Vec<f64>,
    /// Scan → fit: the tree of the fit's vertices, every scan point's nearest vertex (index,
    /// squared distance) and the face of that vertex its closest point lies on.
    tree: BoxTree,
    matched: Vec<(u32, f64)>,
    face_of: Vec<u32>,
    /// Every scan point's closest point on the faces of its nearest vertex: barycentric
    /// coordinates, distance, and the direction `e` its distance is measured along.
    closest: Vec<Closest>,
    /// Per face, over the scan points matched to it: `Σ ω b_l b_k e eᵀ` for each pair of
    /// corners l ≤ k ([`pair`]) and `Σ ω b_l e (e · x)` for each corner.
    face_q: Vec<[Mat3; 6]>,
    face_r: Vec<[Vec3; 3]>,
    /// The scan points that count, bucketed by their face (in scan order within a face):
    /// face `f`'s are `face_points[face_start[f]..face_start[f + 1]]`, so the faces'
    /// sums run in parallel and in the same order as one pass over the points.
    face_start: Vec<u32>,
    face_points: Vec<u32>,
    /// The global step's matrix (`diag`, and `off` on the ring's slots), right-hand side and
    /// conjugate-gradient vectors.
    diag: Vec<Mat3>,
    /// The diagonal blocks' inverses (the preconditioner).
    diag_inv: Vec<Mat3>,
    off: Vec<Mat3>,
    rhs: Vec<[f64; 3]>,
    r: Vec<[f64; 3]>,
    z: Vec<[f64; 3]>,
    dir: Vec<[f64; 3]>,
    a_dir: Vec<[f64; 3]>,
    partials: Vec<f64>,
    /// Each vertex's `Σ_k (Y⁰_i − Y⁰_k)` over its ring, `Y⁰` the fit as the refinement starts
    /// (the hold term's right-hand side), each term times its edge's hold when the holds differ
    /// per edge (`edge_hold`).
    held: Vec<[f64; 3]>,
    /// Per ring slot, the edge's hold, and per vertex the sum of its slots' ([`HoldWhere::
    /// Unsupported`]); empty: `h` on every edge.
    edge_hold: Vec<f64>,
    vertex_hold: Vec<f64>,
    /// The fit's vertex normals at the last match ([`PlaneNormal::Fit`]; empty otherwise).
    fit_normal: Vec<[f64; 3]>,
}

/// Below this many items a parallel loop is not split further.
const MIN_LEN: usize = 256;

impl<'a> IsometricRefine<'a> {
    /// The edges of `faces` at their lengths in `rest`, and the scan's k-d tree.
    /// `vertex_faces`: the faces' incidence lists.
    /// `weights`, when given, weigh the scan points (every point passed is one the fit is
    /// drawn to). `scan` must not be empty.
    pub fn new(
        rest: &[[f64; 3]],
        faces: &'a [[u32; 3]],
        vertex_faces: &'a VertexFaces,
        scan: &'a [[f64; 3]],
        weights: Option<&'a [f64]>,
    ) -> Self {
        let m = rest.len();
        let ring = adjacency(faces, m);
        let rest_length = ring_lengths(&ring, rest);
        let edges = rest_length.len().max(1) as f64;
        let reach = REACH * rest_length.iter().sum::<f64>() / edges;
        let edge_faces = (0..m)
            .flat_map(|i| {
                let ring = &ring;
                ring.of(i).iter().map(move |&k| {
                    let mut found = [EdgeFace::NONE; 2];
                    let shared = vertex_faces.of(i).iter().filter_map(|&f| {
                        let face = &faces[f as usize];
                        let lk = face.iter().position(|&u| u == k)?;
                        Some(EdgeFace {
                            face: f,
                            corners: [corner(face, i) as u8, lk as u8],
                        })
                    });
                    for (slot, e) in found.iter_mut().zip(shared) {
                        *slot = e;
                    }
                    found
                })
            })
            .collect();
        let scan_index = PointIndex::new(scan);
        Self {
            faces,
            ring,
            rest_length,
            vertex_faces,
            edge_faces,
            scan,
            weights,
            scan_index,
            normals: OnceLock::new(),
            plane_normal: PlaneNormal::Scan,
            reach,
            anchor_weight: Vec::new(),
            anchor_at: Vec::new(),
            unmatched: &[],
            rim_pull: true,
            free_edge: Vec::new(),
        }
    }

    /// The fit → scan plane's normal ([`PlaneNormal`]; the scan's unless set).
    pub fn with_plane_normal(mut self, plane_normal: PlaneNormal) -> Self {
        self.plane_normal = plane_normal;
        self
    }

    /// The scan's own normals (one per scan point, as a scanner writes them; normalized here,
    /// their sign does not matter) in place of the planes of their 12 nearest points.
    pub fn with_scan_normals(self, normals: &[[f64; 3]]) -> Self {
        let unit = normals
            .iter()
            .map(|n| {
                let n = crate::math::vec3(n);
                <[f64; 3]>::from(n / n.norm())
            })
            .collect();
        let _ = self.normals.set(unit);
        self
    }

    /// The scan's normals: the given ones, else each point's plane of its 12 nearest points
    /// (computed once).
    fn scan_normals(&self) -> &[[f64; 3]] {
        self.normals.get_or_init(|| {
            let (scan, index) = (self.scan, &self.scan_index);
            let k = NORMAL_NEIGHBOURS.min(scan.len());
            scan.par_iter()
                .map_init(
                    || (vec![0u32; k], vec![0.0; k]),
                    |(idx, d2), x| {
                        index.nearest_into(x, idx, d2);
                        // The normal of their best-fitting plane.
                        let normal = neighbourhood_frame(scan, idx)
                            .1
                            .vectors
                            .column(2)
                            .into_owned();
                        <[f64; 3]>::from(normal)
                    },
                )
                .collect()
        })
    }

    /// Scan points beyond the fit's rim (`RIM_ACROSS`) do not pull it: on the garment's
    /// points of a dressed-body scan, those are mostly skin that the garment cut left in (past
    /// a hem or a cuff), and the fit's rim must not follow them (docs/method.md "Scans of
    /// dressed people"). Elsewhere they are what tells a slide along the scan.
    pub fn without_rim_pull(mut self) -> Self {
        self.rim_pull = false;
        self
    }

    /// Without the rim pull ([`IsometricRefine::without_rim_pull`]), the scan beyond the rim
    /// still pulls the faces flagged in `faces` (one flag per face): those on a free edge of
    /// the garment, past which the scan points are the garment's own (docs/method.md "Free
    /// edges", `free_edges.rs`), each weighing `FREE_EDGE_WEIGHT` (10) points. An empty list
    /// flags none.
    pub fn with_free_edges(mut self, faces: Vec<bool>) -> Self {
        self.free_edge = faces;
        self
    }

    /// Holds the vertices `vertices` at `positions` with the weight `weight` each (against a
    /// fit → scan weight of 1): the term `a Σ ‖Y_v − z_v‖²` joins `E`, so that the refinement
    /// keeps a fit's landmark vertices at their landmarks (docs/method.md "Landmarks"). A
    /// second call adds its anchors to the first's (the rim matching's, "Rim matching"; a
    /// vertex in both keeps the second's). Indices out of range are ignored.
    pub fn with_anchors(mut self, vertices: &[u32], positions: &[[f64; 3]], weight: f64) -> Self {
        let m = self.ring.len();
        if weight > 0.0 && !vertices.is_empty() {
            if self.anchor_weight.len() != m {
                self.anchor_weight = vec![0.0; m];
                self.anchor_at = vec![[0.0; 3]; m];
            }
            for (&v, z) in vertices.iter().zip(positions) {
                if let Some(a) = self.anchor_weight.get_mut(v as usize) {
                    *a = weight;
                    self.anchor_at[v as usize] = *z;
                }
            }
        }
        self
    }

    /// No fit → scan match for the vertices marked in `vertices` (one flag per vertex): the
    /// region a one-sided scan left unseen, which the schedule carried (docs/method.md
    /// "Partial scans"). Its nearest scan points lie on the seen side, so a plane through one
    /// of them would draw the unseen back onto the front's edge; it keeps its shape by the
    /// springs and the hold alone. A mask of another length than the vertices' is ignored.
    pub fn without_scan_under(mut self, vertices: &'a [bool]) -> Self {
        if vertices.len() == self.ring.len() {
            self.unmatched = vertices;
        }
        self
    }

    /// The anchor weight `a_i` of vertex `i` (0: none).
    fn anchor(&self, i: usize) -> f64 {
        self.anchor_weight.get(i).copied().unwrap_or(0.0)
    }

    /// `iterations` local–global steps from `vertices` (moved in place) with the edge
    /// terms of `springs`, against a fit → scan weight of 1 per vertex.
    pub fn run(&self, vertices: &mut [[f64; 3]], iterations: usize, springs: Springs) {
        let (m, n) = (vertices.len(), self.scan.len());
        let mut b = Buffers {
            nearest: vec![(u32::MAX, f64::INFINITY); m],
            t: vec![0.0; m],
            normal: vec![[0.0; 3]; m],
            p: vec![[0.0; 3]; m],
            distance: vec![0.0; m.max(n)],
            scratch: Vec::with_capacity(m.max(n).max(self.ring.members.len())),
            tree: BoxTree::default(),
            matched: vec![(u32::MAX, f64::INFINITY); n],
            face_of: vec![0; n],
            closest: vec![Closest::default(); n],
            face_q: vec![[Mat3::zeros(); 6]; self.faces.len()],
            face_r: vec![[Vec3::zeros(); 3]; self.faces.len()],
            face_start: vec![0; self.faces.len() + 1],
            face_points: vec![0; n],
            diag: vec![Mat3::zeros(); m],
            diag_inv: vec![Mat3::zeros(); m],
            off: vec![Mat3::zeros(); self.ring.members.len()],
            rhs: vec![[0.0; 3]; m],
            r: vec![[0.0; 3]; m],
            z: vec![[0.0; 3]; m],
            dir: vec![[0.0; 3]; m],
            a_dir: vec![[0.0; 3]; m],
            partials: vec![0.0; m.div_ceil(CHUNK)],
            held: vec![[0.0; 3]; m],
            edge_hold: Vec::new(),
            vertex_hold: Vec::new(),
            fit_normal: match self.plane_normal {
                PlaneNormal::Fit => vec![[0.0; 3]; m],
                PlaneNormal::Scan => Vec::new(),
            },
        };
        let scale = match springs.scale {
            SpringScale::Rest => 1.0,
            SpringScale::Fit => self.scale_of(vertices, &mut b.scratch),
        };
        let mut c = 0.0;
        for step in 0..iterations {
            if step % MATCH_EVERY == 0 {
                self.fit_to_scan(vertices, &mut b);
                c = self.scan_to_fit(vertices, &mut b);
                if step == 0 {
                    self.hold_at_start(vertices, &mut b, &springs);
                }
                let uniform = if b.edge_hold.is_empty() {
                    springs.hold
                } else {
                    0.0
                };
                self.assemble_matrix(&mut b, springs.weight + uniform, c);
            }
            self.assemble_rhs(vertices, &mut b, &springs, c, scale);
            solve(vertices, &self.ring, &mut b);
        }
    }

    /// The hold term's right-hand side at the fit as the refinement starts, and, for
    /// [`HoldWhere::Unsupported`], each edge's hold from the first matches.
    fn hold_at_start(&self, start: &[[f64; 3]], b: &mut Buffers, springs: &Springs) {
        if springs.hold <= 0.0 {
            return;
        }
        if springs.hold_where == HoldWhere::Unsupported {
            let unsupported = hold::unsupported(&self.ring, &b.matched, self.weights);
            (b.edge_hold, b.vertex_hold) = hold::edge_holds(&self.ring, &unsupported, springs.hold);
        }
        let ring = &self.ring;
        let edge_hold = &b.edge_hold;
        b.held
            .par_iter_mut()
            .enumerate()
            .with_min_len(MIN_LEN)
            .for_each(|(i, held)| {
                let si = vec3(&start[i]);
                let lo = ring.offsets[i];
                let sum: Vec3 = ring
                    .of(i)
                    .iter()
                    .enumerate()
                    .map(|(e, &k)| {
                        let edge = si - vec3(&start[k as usize]);
                        edge_hold.get(lo + e).map_or(edge, |&h| h * edge)
                    })
                    .sum();
                *held = sum.into();
            });
    }

    /// The springs' scale `s`: the median over edges of `y`'s length ÷ the rest length.
    fn scale_of(&self, y: &[[f64; 3]], scratch: &mut Vec<f64>) -> f64 {
        scratch.clear();
        for i in 0..y.len() {
            let lo = self.ring.offsets[i];
            for (e, &k) in self.ring.of(i).iter().enumerate() {
                let r0 = self.rest_length[lo + e];
                if r0 > 0.0 {
                    scratch.push((vec3(&y[i]) - vec3(&y[k as usize])).norm() / r0);
                }
            }
        }
        if scratch.is_empty() {
            1.0
        } else {
            upper_median(scratch)
        }
    }

    /// `t_i`, `p_i`: each vertex projected onto the plane through its nearest scan point
    /// ([`PlaneNormal`]).
    fn fit_to_scan(&self, y: &[[f64; 3]], b: &mut Buffers) {
        let m = y.len();
        let scan_normals = match self.plane_normal {
            PlaneNormal::Scan => Some(self.scan_normals()),
            PlaneNormal::Fit => {
                vertex_normals(y, self.faces, self.vertex_faces, &mut b.fit_normal);
                None
            }
        };
        let fit_normal = &b.fit_normal;
        b.p.par_iter_mut()
            .zip(b.normal.par_iter_mut())
            .zip(b.nearest.par_iter_mut())
            .zip(b.distance[..m].par_iter_mut())
            .zip(y.par_iter().enumerate())
            .with_min_len(MIN_LEN)
            .for_each(|((((p, normal), near), d), (i, v))| {
                // From the last iteration's nearest point (the scan does not move).
                let known = match near.0 {
                    u32::MAX => (u32::MAX, f64::INFINITY),
                    j => (j, dist2(v, &self.scan[j as usize])),
                };
                *near = self.scan_index.nearest_from(v, known);
                let j = near.0 as usize;
                let x = vec3(&self.scan[j]);
                let n = match scan_normals {
                    Some(normals) => vec3(&normals[j]),
                    // A vertex no face uses has no normal: pulled towards x.
                    None => vec3(&fit_normal[i])
                        .try_normalize(0.0)
                        .or_else(|| (x - vec3(v)).try_normalize(0.0))
                        .unwrap_or_else(Vec3::zeros),
                };
                *normal = n.into();
                *p = (x.dot(&n) * n).into();
                *d = near.1.sqrt();
            });
        let cut = (TRIM * median(&b.distance[..m], &mut b.scratch)).max(self.reach);
        let unmatched = self.unmatched;
        b.t.par_iter_mut()
            .zip(b.distance[..m].par_iter())
            .enumerate()
            .with_min_len(MIN_LEN)
            .for_each(|(i, (t, &d))| {
                let under = !unmatched.get(i).copied().unwrap_or(false);
                *t = if d <= cut && under { 1.0 } else { 0.0 };
            });
    }

    /// Matches every scan point to its closest point on the faces around its nearest vertex
    /// and sums the matches per face; returns the scan → fit weight `c` (the term's total
    /// weight equals the vertex count).
    fn scan_to_fit(&self, y: &[[f64; 3]], b: &mut Buffers) -> f64 {
        b.tree.update(y);
        let tree = &b.tree;
        let (faces, vertex_faces) = (self.faces, &self.vertex_faces);
        b.matched
            .par_iter_mut()
            .zip(b.face_of.par_iter_mut())
            .zip(b.closest.par_iter_mut())
            .zip(self.scan.par_iter())
            .with_min_len(MIN_LEN)
            .for_each(|(((mt, face_of), cl), x)| {
                // From the last iteration's nearest vertex, moved with the fit.
                let known = match mt.0 {
                    u32::MAX => (u32::MAX, f64::INFINITY),
                    v => (v, dist2(x, &y[v as usize])),
                };
                *mt = tree.nearest_one_from(x, known);
                let xv = vec3(x);
                let mut best = (f64::INFINITY, 0u32, [1.0, 0.0, 0.0]);
                for &f in vertex_faces.of(mt.0 as usize) {
                    let corners = faces[f as usize].map(|v| vec3(&y[v as usize]));
                    let w = closest_barycentric(&xv, &corners);
                    let on = w[0] * corners[0] + w[1] * corners[1] + w[2] * corners[2];
                    let d2 = (xv - on).norm_squared();
                    if d2 < best.0 {
                        best = (d2, f, w);
                    }
                }
                let (_, f, w) = best;
                *face_of = f;
                let corners = faces[f as usize].map(|v| vec3(&y[v as usize]));
                let on = w[0] * corners[0] + w[1] * corners[1] + w[2] * corners[2];
                let residual = xv - on;
                let distance = residual.norm();
                // Inside the face: along its normal (point to plane); on its border (the
                // scan beyond the fit's rim): towards the point.
                let normal = (corners[1] - corners[0])
                    .cross(&(corners[2] - corners[0]))
                    .try_normalize(0.0);
                let inside = w.iter().all(|&b| b > 0.0);
                let direction = match normal {
                    Some(n) if inside || distance == 0.0 => n,
                    _ if distance > 0.0 => residual / distance,
                    _ => Vec3::zeros(),
                };
                // Off the face's border and along the surface rather than across it: the scan
                // beyond the fit's rim.
                let beyond_rim =
                    !inside && normal.is_some_and(|n| direction.dot(&n).abs() < RIM_ACROSS);
                *cl = Closest {
                    bary: w,
                    distance,
                    direction,
                    beyond_rim,
                };
            });
        let n = self.scan.len();
        for (d, cl) in b.distance[..n].iter_mut().zip(&b.closest) {
            *d = cl.distance;
        }
        let cut = (TRIM * median(&b.distance[..n], &mut b.scratch)).max(self.reach);
        // A point's pull on face f: 0 when it does not count (too far, or past a rim that is
        // not pulled), FREE_EDGE_WEIGHT past a free edge without the rim pull, else 1.
        let free_edge = &self.free_edge;
        let pull = |cl: &Closest, f: u32| -> f64 {
            if cl.distance > cut {
                0.0
            } else if !cl.beyond_rim || self.rim_pull {
                1.0
            } else if free_edge.get(f as usize).copied().unwrap_or(false) {
                FREE_EDGE_WEIGHT
            } else {
                0.0
            }
        };
        let counts = |cl: &Closest, f: u32| pull(cl, f) > 0.0;
        // The counting sort of the points that count by face (sequential, integers only).
        let (start, points) = (&mut b.face_start, &mut b.face_points);
        start.iter_mut().for_each(|s| *s = 0);
        let mut total = 0.0;
        for (j, (&f, cl)) in b.face_of.iter().zip(&b.closest).enumerate() {
            if counts(cl, f) {
                start[f as usize + 1] += 1;
                total += self.weights.map_or(1.0, |w| w[j]);
            }
        }
        for f in 0..self.faces.len() {
            start[f + 1] += start[f];
        }
        // Each point at its face's cursor, which ends at the next face's start; shifted back.
        for (j, (&f, cl)) in b.face_of.iter().zip(&b.closest).enumerate() {
            if counts(cl, f) {
                points[start[f as usize] as usize] = j as u32;
                start[f as usize] += 1;
            }
        }
        start.copy_within(..self.faces.len(), 1);
        start[0] = 0;
        // Per face, in parallel: Σ ω b_l b_k e eᵀ and Σ ω b_l e (e · x) over its points.
        let (start, points, closest) = (&b.face_start, &b.face_points, &b.closest);
        let (scan, weights) = (self.scan, self.weights);
        b.face_q
            .par_iter_mut()
            .zip(b.face_r.par_iter_mut())
            .enumerate()
            .with_min_len(MIN_LEN)
            .for_each(|(f, (q, r))| {
                *q = [Mat3::zeros(); 6];
                *r = [Vec3::zeros(); 3];
                for &j in &points[start[f] as usize..start[f + 1] as usize] {
                    let j = j as usize;
                    let cl = &closest[j];
                    let w = weights.map_or(1.0, |w| w[j]) * pull(cl, f as u32);
                    let (e, bc) = (cl.direction, cl.bary);
                    let eet = w * e * e.transpose();
                    let along = w * e.dot(&vec3(&scan[j])) * e;
                    for l in 0..3 {
                        r[l] += bc[l] * along;
                        for k in l..3 {
                            q[pair(l, k)] += (bc[l] * bc[k]) * eet;
                        }
                    }
                }
            });
        if total > 0.0 {
            y.len() as f64 / total
        } else {
            0.0
        }
    }

    /// The global step's matrix, in 3 × 3 blocks on the ring's pattern (two vertices of one
    /// face are neighbours); it changes only with the matches:
    /// A = (w + h) L ⊗ I + diag(t n nᵀ + a I) + c Σ_j ω_j (b_j b_jᵀ) ⊗ e_j e_jᵀ.
    fn assemble_matrix(&self, b: &mut Buffers, edges: f64, c: f64) {
        let ring = &self.ring;
        let t = &b.t;
        let face_q = &b.face_q;
        let normal = &b.normal;
        // The scan → fit block of corners (l, k) of face f.
        let coupling = |f: usize, l: usize, k: usize| face_q[f][pair(l, k)];
        let edge_hold = &b.edge_hold;
        b.off
            .par_iter_mut()
            .zip(self.edge_faces.par_iter())
            .enumerate()
            .with_min_len(MIN_LEN)
            .for_each(|(slot, (a, shared))| {
                *a = -(edges + edge_hold.get(slot).copied().unwrap_or(0.0)) * Mat3::identity();
                for e in shared.iter().filter(|e| e.face != u32::MAX) {
                    let [li, lk] = e.corners;
                    *a += c * coupling(e.face as usize, li as usize, lk as usize);
                }
            });
        let vertex_hold = &b.vertex_hold;
        b.diag
            .par_iter_mut()
            .zip(b.diag_inv.par_iter_mut())
            .enumerate()
            .with_min_len(MIN_LEN)
            .for_each(|(i, (diag, diag_inv))| {
                let n = vec3(&normal[i]);
                let held = vertex_hold.get(i).copied().unwrap_or(0.0);
                let mut d = (edges * ring.of(i).len() as f64 + held + self.anchor(i))
                    * Mat3::identity()
                    + t[i] * n * n.transpose();
                for &f in self.vertex_faces.of(i) {
                    let f = f as usize;
                    let l = corner(&self.faces[f], i);
                    d += c * coupling(f, l, l);
                }
                *diag = d;
                *diag_inv = block_inverse(&d);
            });
    }

    /// The global step's right-hand side at the edge directions of `y` (the local step):
    /// rhs = w Dᵀd + h Dᵀd⁰ + t n (n · x) + a z + c Σ_j ω_j b_j e_j (e_j · x_j).
    fn assemble_rhs(&self, y: &[[f64; 3]], b: &mut Buffers, springs: &Springs, c: f64, scale: f64) {
        let (ring, rest_length) = (&self.ring, &self.rest_length);
        let (t, p, face_r) = (&b.t, &b.p, &b.face_r);
        let held = &b.held;
        let per_edge = !b.edge_hold.is_empty();
        b.rhs
            .par_iter_mut()
            .enumerate()
            .with_min_len(MIN_LEN)
            .for_each(|(i, rhs)| {
                let lo = ring.offsets[i];
                let vi = vec3(&y[i]);
                let mut sum = Vec3::zeros();
                for (e, &k) in ring.of(i).iter().enumerate() {
                    let edge = vi - vec3(&y[k as usize]);
                    let len = edge.norm();
                    if len > 0.0 {
                        sum += edge * (scale * rest_length[lo + e] / len);
                    }
                }
                // The holds are in `held` already when they differ per edge.
                let hold = if per_edge { 1.0 } else { springs.hold };
                let mut out = springs.weight * sum + hold * vec3(&held[i]) + t[i] * vec3(&p[i]);
                let a = self.anchor(i);
                if a > 0.0 {
                    out += a * vec3(&self.anchor_at[i]);
                }
                for &f in self.vertex_faces.of(i) {
                    let f = f as usize;
                    out += c * face_r[f][corner(&self.faces[f], i)];
                }
                *rhs = out.into();
            });
    }
}

/// A scan point's closest point on the fit (see [`Buffers::closest`]).
#[derive(Clone, Copy, Debug, Default)]
struct Closest {
    bary: [f64; 3],
    distance: f64,
    direction: Vec3,
    /// The point lies beyond the fit's rim ([`RIM_ACROSS`]).
    beyond_rim: bool,
}

/// The index of the pair of corners `(l, k)`, in either order, among the six of a face.
#[inline]
fn pair(l: usize, k: usize) -> usize {
    let (a, b) = if l <= k { (l, k) } else { (k, l) };
    // (0,0) (0,1) (0,2) (1,1) (1,2) (2,2)
    a * 3 - a * (a + 1) / 2 + b
}

/// A face holding an edge (i, k), with the corners of i and k in it.
#[derive(Clone, Copy, Debug)]
struct EdgeFace {
    face: u32,
    corners: [u8; 2],
}

impl EdgeFace {
    const NONE: Self = Self {
        face: u32::MAX,
        corners: [0; 2],
    };
}

/// [`CG_STEPS`] block-Jacobi-preconditioned conjugate-gradient steps on `b`'s system, from
/// `y` (the point-to-plane term couples a vertex's coordinates: one system of 3M unknowns).
///
/// Two fused passes per step, each over fixed chunks with its dot product summed per chunk
/// (the same result for any thread count): the update `y += α p, r −= α A p, z = M⁻¹ r` with
/// `r · z`, then the new direction `p = z + β p` with `A p = A z + β A p` (the product's
/// recurrence, so one product per step reads `z` alone) and `p · A p`.
fn solve(y: &mut [[f64; 3]], ring: &Neighborhoods, b: &mut Buffers) {
    let system = System {
        ring,
        diag: &b.diag,
        diag_inv: &b.diag_inv,
        off: &b.off,
    };
    // r = rhs − A y, z = M⁻¹ r.
    let mut rz = system.residual(y, &b.rhs, &mut b.r, &mut b.z, &mut b.partials);
    // p = z, A p.
    let mut pap = system.direction(&b.z, 0.0, &mut b.dir, &mut b.a_dir, &mut b.partials);
    for step in 0..CG_STEPS {
        if pap <= 0.0 || rz <= 0.0 {
            break;
        }
        let alpha = rz / pap;
        let rz_next = system.update(
            alpha,
            y,
            &mut b.r,
            &mut b.z,
            &b.dir,
            &b.a_dir,
            &mut b.partials,
        );
        if step + 1 == CG_STEPS {
            break;
        }
        let beta = rz_next / rz;
        rz = rz_next;
        pap = system.direction(&b.z, beta, &mut b.dir, &mut b.a_dir, &mut b.partials);
    }
}

/// The global step's matrix in 3 × 3 blocks: `diag` and `off` (on the ring's slots).
struct System<'s> {
    ring: &'s Neighborhoods,
    diag: &'s [Mat3],
    diag_inv: &'s [Mat3],
    off: &'s [Mat3],
}

impl System<'_> {
    /// `(A x)_i`.
    #[inline]
    fn row(&self, i: usize, x: &[[f64; 3]]) -> Vec3 {
        let (lo, hi) = (self.ring.offsets[i], self.ring.offsets[i + 1]);
        let mut v = self.diag[i] * vec3(&x[i]);
        for (&k, a) in self.ring.members[lo..hi].iter().zip(&self.off[lo..hi]) {
            v += a * vec3(&x[k as usize]);
        }
        v
    }

    /// `r = rhs − A y`, `z = M⁻¹ r` (M the 3 × 3 diagonal blocks); returns `r · z`.
    fn residual(
        &self,
        y: &[[f64; 3]],
        rhs: &[[f64; 3]],
        r: &mut [[f64; 3]],
        z: &mut [[f64; 3]],
        partials: &mut [f64],
    ) -> f64 {
        chunked_sum(r, z, partials, |i, r, z| {
            let ri = vec3(&rhs[i]) - self.row(i, y);
            let zi = self.diag_inv[i] * ri;
            *r = ri.into();
            *z = zi.into();
            ri.dot(&zi)
        })
    }

    /// `p = z + β p` and `A p = A z + β A p` (β = 0: `p = z`, `A p = A z`); returns `p · A p`.
    fn direction(
        &self,
        z: &[[f64; 3]],
        beta: f64,
        dir: &mut [[f64; 3]],
        a_dir: &mut [[f64; 3]],
        partials: &mut [f64],
    ) -> f64 {
        chunked_sum(dir, a_dir, partials, |i, d, ad| {
            let di = vec3(&z[i]) + beta * vec3(d);
            let adi = self.row(i, z) + beta * vec3(ad);
            *d = di.into();
            *ad = adi.into();
            di.dot(&adi)
        })
    }

    /// `y += α p`, `r −= α A p`, `z = M⁻¹ r`; returns `r · z`.
    #[allow(clippy::too_many_arguments)]
    fn update(
        &self,
        alpha: f64,
        y: &mut [[f64; 3]],
        r: &mut [[f64; 3]],
        z: &mut [[f64; 3]],
        dir: &[[f64; 3]],
        a_dir: &[[f64; 3]],
        partials: &mut [f64],
    ) -> f64 {
        y.par_chunks_mut(CHUNK)
            .zip(r.par_chunks_mut(CHUNK))
            .zip(z.par_chunks_mut(CHUNK))
            .zip(partials.par_iter_mut())
            .enumerate()
            .for_each(|(chunk, (((y, r), z), partial))| {
                let base = chunk * CHUNK;
                let mut sum = 0.0;
                for (o, ((y, r), z)) in y.iter_mut().zip(r.iter_mut()).zip(z.iter_mut()).enumerate()
                {
                    let i = base + o;
                    let yi = vec3(y) + alpha * vec3(&dir[i]);
                    let ri = vec3(r) - alpha * vec3(&a_dir[i]);
                    let zi = self.diag_inv[i] * ri;
                    sum += ri.dot(&zi);
                    *y = yi.into();
                    *r = ri.into();
                    *z = zi.into();
                }
                *partial = sum;
            });
        partials.iter().sum()
    }
}

/// `f(i, &mut a[i], &mut b[i])` for every vertex, in parallel over [`CHUNK`]-sized chunks,
/// returning the sum of its values: summed per chunk, then over the chunks in order (the same
/// result for any thread count). `partials` holds one slot per chunk.
fn chunked_sum(
    a: &mut [[f64; 3]],
    b: &mut [[f64; 3]],
    partials: &mut [f64],
    f: impl Fn(usize, &mut [f64; 3], &mut [f64; 3]) -> f64 + Sync,
) -> f64 {
    a.par_chunks_mut(CHUNK)
        .zip(b.par_chunks_mut(CHUNK))
        .zip(partials.par_iter_mut())
        .enumerate()
        .for_each(|(chunk, ((a, b), partial))| {
            let base = chunk * CHUNK;
            *partial = a
                .iter_mut()
                .zip(b.iter_mut())
                .enumerate()
                .map(|(o, (a, b))| f(base + o, a, b))
                .sum();
        });
    partials.iter().sum()
}

/// The (pseudo-)inverse of a diagonal block, which is symmetric positive semi-definite. A
/// vertex with springs has a well-conditioned block (its Cholesky factor); one without (a
/// vertex no face uses, or spring weight 0) may have a singular block, say `t n nᵀ` alone,
/// whose pseudo-inverse keeps the vertex's step in the block's range — an inverse of a
/// round-off pivot would send it along its tangent plane without bound.
fn block_inverse(d: &Mat3) -> Mat3 {
    if let Some(ch) = d.cholesky() {
        let l = ch.l_dirty();
        let pivots = [l[(0, 0)], l[(1, 1)], l[(2, 2)]].map(|x| x * x);
        let (lo, hi) = pivots
            .iter()
            .fold((f64::INFINITY, 0.0_f64), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            });
        if lo > SINGULAR * hi {
            return ch.inverse();
        }
    }
    let eigen = sym_eigen3(d);
    let largest = eigen.values.iter().fold(0.0_f64, |m, &x| m.max(x));
    eigen.map(|x| if x > SINGULAR * largest { 1.0 / x } else { 0.0 })
}

/// A block's eigenvalue (or squared Cholesky pivot) below this share of its largest counts as
/// zero.
const SINGULAR: f64 = 1e-9;

/// The position of corner `i` of `face`.
#[inline]
fn corner(face: &[u32; 3], i: usize) -> usize {
    face.iter().position(|&u| u as usize == i).unwrap_or(0)
}

/// The upper median of `values` (0 when empty), selected in `scratch`.
fn median(values: &[f64], scratch: &mut Vec<f64>) -> f64 {
    scratch.clear();
    scratch.extend_from_slice(values);
    if scratch.is_empty() {
        return 0.0;
    }
    upper_median(scratch)
}

#[cfg(test)]
mod tests;
