//! Coherent Point Drift, non-rigid (Myronenko & Song 2010, "Point Set Registration: Coherent
//! Point Drift", IEEE TPAMI 32(12)): the template's points are the centroids of a Gaussian
//! mixture, moved by the smooth displacement field `v = G W` (`G` the Gaussian kernel of width
//! β over the template's points as given), and fitted to the scan by EM. It is the coherent
//! candidate of the default fit (docs/method.md "Coherent candidate"): a global, smooth motion that
//! does not lock onto the nearest surface, from which the FoldMatch fit starts a second time.
//!
//! Memory is O((M + N) r), with no M × N matrix:
//! * the E-step streams every (template point, scan point) pair once per iteration over a fixed
//!   number of scan chunks, each summing its own `P1` and `PX`; the chunks are added in a fixed
//!   order, so the result does not depend on the thread count;
//! * the M-step's kernel is the Nyström approximation `G ≈ F Fᵀ` of rank ≤ r on r
//!   farthest-point landmarks, and `(d(P1) G + λσ² I) W = PX − d(P1) Y` is solved by the
//!   Woodbury identity in O(M r²);
//! * templates and scans larger than [`CpdParams::max_points`] are subsampled (every k-th
//!   point) for the EM, and the field is evaluated at every template point at the end (the
//!   Nyström extension of the same kernel).
//!
//! Everything runs in the scan's normalized frame (centroid at the origin, bounding-box
//! diagonal 1), where the parameters are given. The EM stops when σ² changes by less than
//! [`CpdParams::tolerance`], as probreg's `registration_cpd` does.

use crate::normalize::Frame;
use nalgebra::{DMatrix, SymmetricEigen};
use rayon::prelude::*;

/// The settings of [`coherent_point_drift`], in the scan's normalized frame (diagonal 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CpdParams {
    /// λ, the weight of the field's smoothness (larger: a stiffer motion).
    pub smoothness: f64,
    /// β, the width of the Gaussian kernel `exp(−‖a − b‖² / (2β²))`, in scan diagonals
    /// (probreg's `beta` is β²).
    pub kernel_width: f64,
    /// w, the weight of the uniform outlier component, in [0, 1).
    pub outlier_weight: f64,
    /// The most EM iterations.
    pub max_iterations: usize,
    /// Stop when σ² (normalized units) changes by less than this.
    pub tolerance: f64,
    /// The Nyström rank: how many landmark points span the kernel.
    pub rank: usize,
    /// The most template points and the most scan points the EM runs on (every k-th beyond).
    pub max_points: usize,
}

impl Default for CpdParams {
    /// The settings of the harness's CPD peer (bench/peers.py, chosen by a sweep there): λ 512,
    /// β² 0.1, w 0.05, 150 iterations, tolerance 10⁻⁶; rank 64 (the harness's simulated cases
    /// end alike at rank 50 and 300 of the exact eigen-decomposition), 2,048 points.
    fn default() -> Self {
        Self {
            smoothness: 512.0,
            kernel_width: 0.1_f64.sqrt(),
            outlier_weight: 0.05,
            max_iterations: 150,
            tolerance: 1e-6,
            rank: 64,
            max_points: 2048,
        }
    }
}

/// What [`coherent_point_drift`] returns.
#[derive(Clone, Debug)]
pub struct CpdResult {
    /// The moved template points (M rows, the scan's frame).
    pub points: Vec<[f64; 3]>,
    /// The EM iterations run.
    pub iterations: usize,
    /// The final σ² (normalized units).
    pub sigma2: f64,
}

/// The scan chunks the E-step sums over (fixed, so that sums do not depend on the threads).
const CHUNKS: usize = 32;
/// Kernel terms below `exp(−CUTOFF)` are not evaluated (their share of any denominator is
/// below 10⁻¹⁶ of the nearest term's).
const CUTOFF: f64 = 40.0;

/// Non-rigid CPD of `template` onto `scan` (module docs). Both must be non-empty and finite
/// (the caller's checks); the result has the template's length.
pub fn coherent_point_drift(
    template: &[[f64; 3]],
    scan: &[[f64; 3]],
    params: &CpdParams,
) -> CpdResult {
    let frame = Frame::of_target(scan);
    let all_y = frame.forward(template);
    let y: Vec<[f64; 3]> = every_kth(&all_y, params.max_points);
    let x = frame.forward(&every_kth(scan, params.max_points));
    let beta2 = params.kernel_width * params.kernel_width;
    let landmarks = farthest_points(&y, params.rank.max(1));
    let basis = NystromBasis::new(&y, &landmarks, beta2);
    let f = basis.features(&y);
    let mut em = Em::new(&y, &x, f, params.outlier_weight);
    let mut sigma2 = initial_sigma2(&y, &x);
    let mut q = 1.0 + x.len() as f64 * 1.5 * sigma2.ln();
    let mut iterations = 0;
    for _ in 0..params.max_iterations {
        iterations += 1;
        em.expectation(sigma2);
        sigma2 = em.maximization(params.smoothness * sigma2);
        if (sigma2 - q).abs() < params.tolerance {
            break;
        }
        q = sigma2;
    }
    // The field at every template point: v(z) = Σ_m G(z, y_m) w_m ≈ F(z) Fᵀ W.
    let mut points: Vec<[f64; 3]> = if y.len() == all_y.len() {
        std::mem::take(&mut em.moved)
    } else {
        let f_all = basis.features(&all_y);
        let v = &f_all * &em.a;
        (0..all_y.len())
            .map(|m| std::array::from_fn(|c| all_y[m][c] + v[(m, c)]))
            .collect()
    };
    frame.inverse_in_place(&mut points);
    CpdResult {
        points,
        iterations,
        sigma2,
    }
}

/// Every k-th point, k the least that leaves at most `max` (all of them when they fit).
fn every_kth(points: &[[f64; 3]], max: usize) -> Vec<[f64; 3]> {
    let k = points.len().div_ceil(max.max(1)).max(1);
    points.iter().step_by(k).copied().collect()
}

/// σ² of the first E-step: the mean squared distance over every pair, per coordinate.
fn initial_sigma2(y: &[[f64; 3]], x: &[[f64; 3]]) -> f64 {
    let sums = |p: &[[f64; 3]]| {
        let s: [f64; 3] = std::array::from_fn(|a| p.iter().map(|q| q[a]).sum());
        let sq: f64 = p.iter().map(|q| q.iter().map(|c| c * c).sum::<f64>()).sum();
        (s, sq)
    };
    let ((sy, qy), (sx, qx)) = (sums(y), sums(x));
    let (m, n) = (y.len() as f64, x.len() as f64);
    let cross: f64 = (0..3).map(|a| sy[a] * sx[a]).sum();
    ((n * qy + m * qx - 2.0 * cross) / (3.0 * m * n)).max(f64::MIN_POSITIVE)
}

/// `count` farthest-point samples of `points` (from the first), as indices.
fn farthest_points(points: &[[f64; 3]], count: usize) -> Vec<usize> {
    let count = count.min(points.len());
    let mut chosen = Vec::with_capacity(count);
    let mut nearest = vec![f64::INFINITY; points.len()];
    let mut next = 0;
    while chosen.len() < count {
        chosen.push(next);
        let c = points[next];
        let mut far = (0, -1.0);
        for (i, p) in points.iter().enumerate() {
            let d = crate::math::dist2(p, &c);
            if d < nearest[i] {
                nearest[i] = d;
            }
            if nearest[i] > far.1 {
                far = (i, nearest[i]);
            }
        }
        if far.1 <= 0.0 {
            break; // every point is a landmark's duplicate
        }
        next = far.0;
    }
    chosen
}

/// The Nyström approximation of the Gaussian kernel on landmarks `L`:
/// `G(a, b) ≈ k(a)ᵀ K_LL⁻¹ k(b)`, `k(a)` the kernel between `a` and the landmarks, factored as
/// `F(a) F(b)ᵀ` with `F(a) = k(a)ᵀ U S^{-1/2}` (`K_LL = U S Uᵀ`, its eigenvalues below 10⁻¹⁰
/// of the largest dropped).
struct NystromBasis {
    landmarks: Vec<[f64; 3]>,
    /// `U S^{-1/2}` (landmarks × rank).
    whitening: DMatrix<f64>,
    beta2: f64,
}

impl NystromBasis {
    fn new(points: &[[f64; 3]], landmarks: &[usize], beta2: f64) -> Self {
        let l: Vec<[f64; 3]> = landmarks.iter().map(|&i| points[i]).collect();
        let r = l.len();
        let k = DMatrix::from_fn(r, r, |i, j| gaussian(&l[i], &l[j], beta2));
        let eig = SymmetricEigen::new(k);
        let top = eig.eigenvalues.iter().cloned().fold(0.0_f64, f64::max);
        let keep: Vec<usize> = (0..r)
            .filter(|&i| eig.eigenvalues[i] > 1e-10 * top)
            .collect();
        let whitening = DMatrix::from_fn(r, keep.len(), |i, j| {
            eig.eigenvectors[(i, keep[j])] / eig.eigenvalues[keep[j]].sqrt()
        });
        Self {
            landmarks: l,
            whitening,
            beta2,
        }
    }

    /// `F` of every point (points × rank).
    fn features(&self, points: &[[f64; 3]]) -> DMatrix<f64> {
        let k = DMatrix::from_fn(points.len(), self.landmarks.len(), |m, j| {
            gaussian(&points[m], &self.landmarks[j], self.beta2)
        });
        k * &self.whitening
    }
}

#[inline]
fn gaussian(a: &[f64; 3], b: &[f64; 3], beta2: f64) -> f64 {
    (-crate::math::dist2(a, b) / (2.0 * beta2)).exp()
}

/// One E-step chunk's sums over its scan points.
struct ChunkSums {
    /// Σ_n P(m|n) per template point.
    p1: Vec<f64>,
    /// Σ_n P(m|n) x_n per template point.
    px: Vec<[f64; 3]>,
    /// Σ_n Σ_m P(m|n), the chunk's share of N_P.
    np: f64,
    /// Σ_n (Σ_m P(m|n)) ‖x_n‖².
    xpx: f64,
    /// The kernel terms of the scan point at hand (scratch).
    kernel: Vec<f64>,
}

/// The EM's state and every buffer it uses, allocated once.
struct Em<'a> {
    y: &'a [[f64; 3]],
    x: &'a [[f64; 3]],
    f: DMatrix<f64>,
    w: f64,
    /// The moved template points `y + F a`.
    moved: Vec<[f64; 3]>,
    chunks: Vec<ChunkSums>,
    p1: Vec<f64>,
    px: Vec<[f64; 3]>,
    np: f64,
    xpx: f64,
    /// `PX − d(P1) Y` (M × 3), then `W`.
    b: DMatrix<f64>,
    /// `d(P1) F` (M × r).
    df: DMatrix<f64>,
    /// `Fᵀ B`, then the Woodbury solve's `Z` (r × 3).
    ftb: DMatrix<f64>,
    /// `λσ² I + Fᵀ d(P1) F` (r × r), then its Cholesky factor.
    k: DMatrix<f64>,
    /// `F Z`, then `F a` (M × 3).
    fz: DMatrix<f64>,
    /// `a = Fᵀ W` (r × 3): the field is `F a`.
    a: DMatrix<f64>,
}

impl<'a> Em<'a> {
    fn new(y: &'a [[f64; 3]], x: &'a [[f64; 3]], f: DMatrix<f64>, w: f64) -> Self {
        let (m, r) = (y.len(), f.ncols());
        let chunks = (0..CHUNKS.min(x.len()).max(1))
            .map(|_| ChunkSums {
                p1: vec![0.0; m],
                px: vec![[0.0; 3]; m],
                np: 0.0,
                xpx: 0.0,
                kernel: vec![0.0; m],
            })
            .collect();
        Self {
            y,
            x,
            f,
            w,
            moved: y.to_vec(),
            chunks,
            p1: vec![0.0; m],
            px: vec![[0.0; 3]; m],
            np: 0.0,
            xpx: 0.0,
            b: DMatrix::zeros(m, 3),
            df: DMatrix::zeros(m, r),
            ftb: DMatrix::zeros(r, 3),
            k: DMatrix::zeros(r, r),
            fz: DMatrix::zeros(m, 3),
            a: DMatrix::zeros(r, 3),
        }
    }

    /// The posterior sums `P1`, `PX`, `N_P` and `Σ Pᵀ1 ‖x‖²` at `sigma2`.
    fn expectation(&mut self, sigma2: f64) {
        let (m, n) = (self.y.len() as f64, self.x.len() as f64);
        let c = (2.0 * std::f64::consts::PI * sigma2).powf(1.5) * self.w / (1.0 - self.w) * m / n;
        let per_chunk = self.x.len().div_ceil(self.chunks.len());
        let (x, moved) = (self.x, &self.moved);
        let inv = 1.0 / (2.0 * sigma2);
        self.chunks.par_iter_mut().enumerate().for_each(|(i, s)| {
            s.p1.fill(0.0);
            s.px.fill([0.0; 3]);
            s.np = 0.0;
            s.xpx = 0.0;
            let end = ((i + 1) * per_chunk).min(x.len());
            for xn in &x[(i * per_chunk).min(end)..end] {
                let mut den = 0.0;
                for (k, t) in s.kernel.iter_mut().zip(moved) {
                    let e = crate::math::dist2(t, xn) * inv;
                    *k = if e < CUTOFF { (-e).exp() } else { 0.0 };
                    den += *k;
                }
                // probreg's floor for a point no component reaches (w = 0).
                let den = if den == 0.0 { f32::EPSILON as f64 } else { den };
                let scale = 1.0 / (den + c);
                for ((k, p1), px) in s.kernel.iter().zip(&mut s.p1).zip(&mut s.px) {
                    if *k > 0.0 {
                        let p = k * scale;
                        *p1 += p;
                        for a in 0..3 {
                            px[a] += p * xn[a];
                        }
                    }
                }
                let pt1 = den * scale;
                s.np += pt1;
                s.xpx += pt1 * (xn[0] * xn[0] + xn[1] * xn[1] + xn[2] * xn[2]);
            }
        });
        let chunks = &self.chunks;
        self.p1
            .par_iter_mut()
            .zip(self.px.par_iter_mut())
            .enumerate()
            .for_each(|(j, (p1, px))| {
                *p1 = chunks.iter().map(|s| s.p1[j]).sum();
                *px = std::array::from_fn(|a| chunks.iter().map(|s| s.px[j][a]).sum());
            });
        self.np = chunks.iter().map(|s| s.np).sum();
        self.xpx = chunks.iter().map(|s| s.xpx).sum();
    }

    /// The field's update for `lambda_sigma2 = λσ²` (σ² of the E-step), the points moved by
    /// it, and the new σ².
    fn maximization(&mut self, lambda_sigma2: f64) -> f64 {
        let (mm, r) = (self.y.len(), self.f.ncols());
        for j in 0..mm {
            for a in 0..3 {
                self.b[(j, a)] = self.px[j][a] - self.p1[j] * self.y[j][a];
            }
            for i in 0..r {
                self.df[(j, i)] = self.p1[j] * self.f[(j, i)];
            }
        }
        // W = (1/s) (B − d(P1) F (s I + Fᵀ d(P1) F)⁻¹ Fᵀ B), s = λσ² (Woodbury).
        self.f.tr_mul_to(&self.df, &mut self.k);
        for i in 0..r {
            self.k[(i, i)] += lambda_sigma2;
        }
        self.f.tr_mul_to(&self.b, &mut self.ftb);
        cholesky_solve_in_place(&mut self.k, &mut self.ftb);
        self.f.mul_to(&self.ftb, &mut self.fz);
        for j in 0..mm {
            for a in 0..3 {
                self.b[(j, a)] = (self.b[(j, a)] - self.p1[j] * self.fz[(j, a)]) / lambda_sigma2;
            }
        }
        // The field at the template points, G W ≈ F (Fᵀ W).
        self.f.tr_mul_to(&self.b, &mut self.a);
        self.f.mul_to(&self.a, &mut self.fz);
        let mut cross = 0.0;
        let mut norm = 0.0;
        for j in 0..mm {
            let t: [f64; 3] = std::array::from_fn(|a| self.y[j][a] + self.fz[(j, a)]);
            self.moved[j] = t;
            cross += (0..3).map(|a| self.px[j][a] * t[a]).sum::<f64>();
            norm += self.p1[j] * (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
        }
        let sigma2 = (self.xpx - 2.0 * cross + norm) / (3.0 * self.np.max(f64::MIN_POSITIVE));
        sigma2.max(1e-12)
    }
}

/// Solves `K Z = B` in place for a symmetric positive definite `K` (overwritten by its
/// Cholesky factor) and `B` (overwritten by `Z`).
fn cholesky_solve_in_place(k: &mut DMatrix<f64>, b: &mut DMatrix<f64>) {
    let r = k.nrows();
    for j in 0..r {
        let mut d = k[(j, j)];
        for p in 0..j {
            d -= k[(j, p)] * k[(j, p)];
        }
        let d = d.max(f64::MIN_POSITIVE).sqrt();
        k[(j, j)] = d;
        for i in j + 1..r {
            let mut s = k[(i, j)];
            for p in 0..j {
                s -= k[(i, p)] * k[(j, p)];
            }
            k[(i, j)] = s / d;
        }
    }
    for c in 0..b.ncols() {
        for i in 0..r {
            let mut s = b[(i, c)];
            for p in 0..i {
                s -= k[(i, p)] * b[(p, c)];
            }
            b[(i, c)] = s / k[(i, i)];
        }
        for i in (0..r).rev() {
            let mut s = b[(i, c)];
            for p in i + 1..r {
                s -= k[(p, i)] * b[(p, c)];
            }
            b[(i, c)] = s / k[(i, i)];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sheet(n: usize) -> Vec<[f64; 3]> {
        (0..n * n)
            .map(|i| {
                [
                    (i % n) as f64 / (n - 1) as f64,
                    (i / n) as f64 / (n - 1) as f64,
                    0.0,
                ]
            })
            .collect()
    }

    fn rms(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
        (a.iter()
            .zip(b)
            .map(|(p, q)| crate::math::dist2(p, q))
            .sum::<f64>()
            / a.len() as f64)
            .sqrt()
    }

    /// A sheet bent smoothly and shifted is recovered point for point: the drift is coherent
    /// (correspondences follow the motion, not the nearest points).
    #[test]
    fn a_smooth_bend_is_recovered() {
        let y = sheet(20);
        let bent: Vec<[f64; 3]> = y
            .iter()
            .map(|p| {
                [
                    p[0] + 0.05,
                    p[1] - 0.03,
                    0.25 * (std::f64::consts::PI * p[0]).sin(),
                ]
            })
            .collect();
        let r = coherent_point_drift(&y, &bent, &CpdParams::default());
        assert!(r.iterations > 1);
        let before = rms(&y, &bent);
        let after = rms(&r.points, &bent);
        assert!(
            after < 0.05 * before,
            "{after} against {before} at the start"
        );
    }

    /// Subsampled EM and the Nyström extension to every point end where the full EM does.
    #[test]
    fn subsampling_ends_near_the_full_em() {
        let y = sheet(30);
        let bent: Vec<[f64; 3]> = y
            .iter()
            .map(|p| [p[0], p[1], 0.2 * (std::f64::consts::PI * p[1]).sin()])
            .collect();
        let full = coherent_point_drift(&y, &bent, &CpdParams::default());
        let sub = coherent_point_drift(
            &y,
            &bent,
            &CpdParams {
                max_points: 300,
                ..CpdParams::default()
            },
        );
        assert_eq!(sub.points.len(), y.len());
        let gap = rms(&full.points, &sub.points);
        assert!(gap < 0.1 * rms(&y, &bent), "gap {gap}");
    }

    #[test]
    fn cholesky_solves() {
        let k0 = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0]);
        let b0 = DMatrix::from_row_slice(3, 1, &[1.0, 2.0, 3.0]);
        let (mut k, mut b) = (k0.clone(), b0.clone());
        cholesky_solve_in_place(&mut k, &mut b);
        assert!((&k0 * &b - b0).norm() < 1e-12);
    }
}
