//! The landmarks inside a fit (docs/method.md "Landmarks"): their targets in the normalized
//! frame, their pull in the coarse phase's ring fits (weighted
//! pairs of Kabsch's problem), and their spring in the FoldMatch (or NRGa) iterations.

use crate::landmarks::Landmarks;
use crate::math::{nearest_rotation_with, vec3, Mat3, Vec3};
use crate::normalize::Frame;
use crate::rings::Neighborhoods;
use crate::rotation::transform_vertex;
use rayon::prelude::*;

/// The landmarks of a fit, in the normalized frame.
pub(super) struct LandmarkTargets {
    /// The constrained template vertices.
    pub(super) vertices: Vec<u32>,
    /// Their targets, in the normalized frame.
    pub(super) targets: Vec<Vec3>,
    /// Per coarse level: every vertex whose coarse ring holds a landmark, with the indices
    /// (into `vertices`) of the landmarks it holds, in vertex order.
    pub(super) coarse: Vec<Vec<(u32, Vec<u32>)>>,
}

impl LandmarkTargets {
    /// Targets already in the fit's frame, pulled in the FoldMatch (or NRGa) iterations only
    /// (no coarse ring holds them): the rim matching's (docs/method.md "Rim matching").
    pub(super) fn in_frame(vertices: Vec<u32>, targets: Vec<Vec3>) -> Self {
        Self {
            vertices,
            targets,
            coarse: Vec::new(),
        }
    }

    /// The landmarks' targets mapped into `frame`, and the coarse rings that hold them (the
    /// n-rings are symmetric: v's ring holds u exactly when u's ring holds v).
    pub(super) fn new(
        landmarks: &Landmarks,
        frame: &Frame,
        coarse_levels: &[Neighborhoods],
    ) -> Self {
        let coarse = holders(&landmarks.vertices, coarse_levels);
        Self {
            vertices: landmarks.vertices.clone(),
            targets: frame
                .forward(&landmarks.positions)
                .iter()
                .map(vec3)
                .collect(),
            coarse,
        }
    }

    /// The rigid fit of the pairs `ring_old[j] → ring_new[j]` (j in `ring`) and the landmark
    /// pairs `old[u_i] → t_i` (i in `held`), the landmarks together weighing `eta` times the
    /// ring's pairs: `(R, c_old, c_new)`, the weighted centroids and the nearest rotation of
    /// the weighted covariance.
    #[allow(clippy::too_many_arguments)] // the ring's motion, the landmarks', and the solver
    pub(super) fn weighted_fit(
        &self,
        ring: &[u32],
        ring_old: &[[f64; 3]],
        ring_new: &[[f64; 3]],
        held: &[u32],
        old: &[[f64; 3]],
        eta: f64,
        fast: bool,
    ) -> (Mat3, Vec3, Vec3) {
        let n = ring.len() as f64;
        let w = eta * n / held.len() as f64;
        let total = n + eta * n;
        let (mut s_old, mut s_new) = (Vec3::zeros(), Vec3::zeros());
        for &j in ring {
            s_old += vec3(&ring_old[j as usize]);
            s_new += vec3(&ring_new[j as usize]);
        }
        for &i in held {
            s_old += w * vec3(&old[self.vertices[i as usize] as usize]);
            s_new += w * self.targets[i as usize];
        }
        let (c_old, c_new) = (s_old / total, s_new / total);
        let mut cov = Mat3::zeros();
        for &j in ring {
            cov += (vec3(&ring_new[j as usize]) - c_new)
                * (vec3(&ring_old[j as usize]) - c_old).transpose();
        }
        for &i in held {
            let o = vec3(&old[self.vertices[i as usize] as usize]);
            cov += w * (self.targets[i as usize] - c_new) * (o - c_old).transpose();
        }
        (nearest_rotation_with(&cov, fast), c_old, c_new)
    }

    /// The coarse phase's ring fits again for the vertices whose coarse ring at `level` holds
    /// a landmark, with the landmarks' pairs ([`LandmarkTargets::weighted_fit`]); `rings`,
    /// `ring_old` and `ring_new` are the ones the phase fitted (the whole rings, or a sample's).
    #[allow(clippy::too_many_arguments)] // the phase's rings and motion, and the buffers
    pub(super) fn coarse(
        &self,
        level: usize,
        rings: &Neighborhoods,
        ring_old: &[[f64; 3]],
        ring_new: &[[f64; 3]],
        old: &[[f64; 3]],
        eta: f64,
        fast: bool,
        next: &mut [[f64; 3]],
    ) {
        let moved: Vec<(usize, [f64; 3])> = self.coarse[level]
            .par_iter()
            .map(|(v, held)| {
                let v = *v as usize;
                let (r, c_old, c_new) =
                    self.weighted_fit(rings.of(v), ring_old, ring_new, held, old, eta, fast);
                (
                    v,
                    transform_vertex(&r, &vec3(&old[v]), &c_old, &c_new).into(),
                )
            })
            .collect();
        for (v, p) in moved {
            next[v] = p;
        }
    }

    /// The spring of the FoldMatch (or NRGa) iterations, on the proposal and on the update:
    /// each landmark vertex's `x` becomes `(x + η t) / (1 + η)`.
    pub(super) fn pull(&self, eta: f64, next: &mut [[f64; 3]]) {
        for (&u, t) in self.vertices.iter().zip(&self.targets) {
            let x = vec3(&next[u as usize]);
            next[u as usize] = ((x + eta * t) / (1.0 + eta)).into();
        }
    }
}

/// Per coarse level: every vertex whose coarse ring holds one of `vertices`, with the indices
/// (into `vertices`) of those it holds, in vertex order (the n-rings are symmetric: v's ring
/// holds u exactly when u's ring holds v).
fn holders(vertices: &[u32], coarse_levels: &[Neighborhoods]) -> Vec<Vec<(u32, Vec<u32>)>> {
    coarse_levels
        .iter()
        .map(|rings| {
            let mut held: Vec<(u32, u32)> = vertices
                .iter()
                .enumerate()
                .flat_map(|(i, &u)| rings.of(u as usize).iter().map(move |&v| (v, i as u32)))
                .collect();
            held.sort_unstable();
            let mut out: Vec<(u32, Vec<u32>)> = Vec::new();
            for (v, i) in held {
                match out.last_mut() {
                    Some((w, ids)) if *w == v => ids.push(i),
                    _ => out.push((v, vec![i])),
                }
            }
            out
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::{fit_scan, fit_simple, FitParams, ScanExtras};
    use super::LandmarkTargets;
    use crate::landmarks::Landmarks;
    use crate::math::dist2;
    use crate::synthetic::grid_sheet;

    fn rms(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
        (a.iter().zip(b).map(|(p, q)| dist2(p, q)).sum::<f64>() / a.len() as f64).sqrt()
    }

    fn fit(
        v: &[[f64; 3]],
        f: &[[u32; 3]],
        x: &[[f64; 3]],
        landmarks: &Landmarks,
        params: &FitParams,
    ) -> Vec<[f64; 3]> {
        let mut observer = |_: &_| true;
        let extras = ScanExtras {
            landmarks: Some(landmarks),
            ..ScanExtras::default()
        };
        fit_scan(v, f, x, &extras, params, &mut observer)
            .unwrap()
            .vertices
    }

    /// A square sheet turned by 90° about its normal covers the same points: the scan cannot
    /// tell the turn, and the fit keeps every vertex where it is. Four landmarks at the turned
    /// corners' places settle it (they decide the pre-alignment, and hold it).
    #[test]
    fn landmarks_settle_a_turn_the_scan_cannot_show() {
        let (v, f) = grid_sheet(21, 21, 1.0, 1.0);
        // The turn about the sheet's centre (the origin), (x, y) ↦ (−y, x).
        let truth: Vec<[f64; 3]> = v.iter().map(|p| [-p[1], p[0], p[2]]).collect();
        let scan = truth.clone();
        let params = FitParams {
            iterations: 30,
            ..FitParams::default()
        };
        let plain = fit_simple(&v, &f, &scan, None, &params).unwrap().vertices;
        assert!(
            rms(&plain, &truth) > 0.3,
            "the scan alone leaves the turn: {}",
            rms(&plain, &truth)
        );
        let corners: [i64; 4] = [0, 20, 420, 440];
        let targets: Vec<[f64; 3]> = corners.iter().map(|&c| truth[c as usize]).collect();
        let landmarks = Landmarks::new(&corners, &targets, v.len()).unwrap();
        let guided = fit(&v, &f, &scan, &landmarks, &params);
        assert!(
            rms(&guided, &truth) < 0.01,
            "landmarks settle it: {}",
            rms(&guided, &truth)
        );
    }

    /// Landmark targets moved along the surface, away from where the scan alone puts their
    /// vertices: with the default weight the landmark vertices end near their targets; with
    /// weight 0 (pre-alignment only) they stay where the scan puts them.
    #[test]
    fn landmark_vertices_end_near_their_targets() {
        let (v, f) = grid_sheet(25, 25, 1.0, 1.0);
        let wave = |x: f64| 0.05 * (4.0 * x).sin();
        let scan: Vec<[f64; 3]> = v.iter().map(|p| [p[0], p[1], wave(p[0])]).collect();
        // Six inner vertices, each to land 0.02 further along x than its own place.
        let chosen: [i64; 6] = [156, 162, 168, 306, 312, 468];
        let targets: Vec<[f64; 3]> = chosen
            .iter()
            .map(|&c| {
                let p = v[c as usize];
                [p[0] + 0.02, p[1], wave(p[0] + 0.02)]
            })
            .collect();
        let landmarks = Landmarks::new(&chosen, &targets, v.len()).unwrap();
        let gap = |fitted: &[[f64; 3]]| -> f64 {
            chosen
                .iter()
                .zip(&targets)
                .map(|(&c, t)| dist2(&fitted[c as usize], t).sqrt())
                .fold(0.0, f64::max)
        };
        let params = FitParams {
            iterations: 40,
            ..FitParams::default()
        };
        let pulled = fit(&v, &f, &scan, &landmarks, &params);
        let free = fit(
            &v,
            &f,
            &scan,
            &landmarks,
            &FitParams {
                landmark_weight: 0.0,
                ..params.clone()
            },
        );
        assert!(
            gap(&free) > 0.015,
            "weight 0: the scan's place, {}",
            gap(&free)
        );
        assert!(
            gap(&pulled) < 0.004,
            "default weight: at the targets, {}",
            gap(&pulled)
        );
        // The rest of the sheet still lies on the scanned surface, z = wave(x).
        let off: Vec<f64> = pulled.iter().map(|p| (p[2] - wave(p[0])).abs()).collect();
        let mean = off.iter().sum::<f64>() / off.len() as f64;
        assert!(mean < 0.002, "mean height off the scanned surface {mean}");
    }

    /// The weighted fit with the landmarks' weight 0 is the plain Kabsch fit of the ring, and
    /// with a large weight the landmark pairs decide it.
    #[test]
    fn weighted_fit_spans_scan_to_landmarks() {
        use crate::math::Vec3;
        use crate::normalize::Frame;
        let old: Vec<[f64; 3]> = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.3, 0.2, 1.0],
        ];
        let new: Vec<[f64; 3]> = old.iter().map(|p| [p[0] + 0.5, p[1], p[2]]).collect();
        let targets = [[0.0, 0.0, 2.0], [1.0, 0.0, 2.0], [0.0, 1.0, 2.0]];
        let l = Landmarks::new(&[0, 1, 2], &targets, 4).unwrap();
        let lt = LandmarkTargets::new(&l, &Frame::identity(), &[]);
        let ring = [0u32, 1, 2, 3];
        let (r, c_old, c_new) = lt.weighted_fit(&ring, &old, &new, &[0, 1, 2], &old, 0.0, false);
        assert!((r - crate::math::Mat3::identity()).norm() < 1e-12);
        assert!((c_new - c_old - Vec3::new(0.5, 0.0, 0.0)).norm() < 1e-12);
        let (_, c_old, c_new) = lt.weighted_fit(&ring, &old, &new, &[0, 1, 2], &old, 1e9, false);
        let lifted = c_new - c_old;
        assert!(
            (lifted - Vec3::new(0.0, 0.0, 2.0)).norm() < 1e-6,
            "{lifted:?}"
        );
    }
}
