//! The normalized frame (docs/method.md "Frame"): the paper's constants (G, ε, Δt, ρ) only make
//! sense at a fixed scale, so a fit works on coordinates centered on the target's centroid and
//! scaled so that the target's bounding-box diagonal is 1, and reports in the user's frame.

use crate::math::Real;
use serde::{Deserialize, Serialize};

/// A similarity `p ↦ (p − center) / scale` and its inverse.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Frame {
    /// Subtracted before scaling (the target centroid).
    pub center: [Real; 3],
    /// Divides after centering (the target's bounding-box diagonal).
    pub scale: Real,
}

impl Frame {
    /// The identity frame (used when normalization is switched off).
    pub fn identity() -> Self {
        Self {
            center: [0.0; 3],
            scale: 1.0,
        }
    }

    /// The frame that maps `target` to zero centroid and unit bounding-box diagonal. A target
    /// whose points all coincide gets scale 1.
    pub fn of_target(target: &[[Real; 3]]) -> Self {
        let n = target.len().max(1) as Real;
        let mut c = [0.0; 3];
        let mut lo = [Real::INFINITY; 3];
        let mut hi = [Real::NEG_INFINITY; 3];
        for p in target {
            for i in 0..3 {
                c[i] += p[i];
                lo[i] = lo[i].min(p[i]);
                hi[i] = hi[i].max(p[i]);
            }
        }
        let diag = (0..3).map(|i| (hi[i] - lo[i]).powi(2)).sum::<Real>().sqrt();
        let scale = if diag > 0.0 && diag.is_finite() {
            diag
        } else {
            1.0
        };
        Self {
            center: c.map(|x| x / n),
            scale,
        }
    }

    /// Maps user coordinates into the frame.
    pub fn forward(&self, points: &[[Real; 3]]) -> Vec<[Real; 3]> {
        points
            .iter()
            .map(|p| std::array::from_fn(|i| (p[i] - self.center[i]) / self.scale))
            .collect()
    }

    /// Maps frame coordinates back to user coordinates, in place.
    pub fn inverse_in_place(&self, points: &mut [[Real; 3]]) {
        for p in points {
            for (x, c) in p.iter_mut().zip(self.center) {
                *x = *x * self.scale + c;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_diagonal_and_round_trip() {
        let t = [
            [0.0, 0.0, 0.0],
            [3.0, 4.0, 0.0],
            [3.0, 0.0, 0.0],
            [0.0, 4.0, 0.0],
        ];
        let f = Frame::of_target(&t);
        assert_eq!(f.scale, 5.0);
        assert_eq!(f.center, [1.5, 2.0, 0.0]);
        let mut y = f.forward(&t);
        assert_eq!(y[1], [0.3, 0.4, 0.0]);
        f.inverse_in_place(&mut y);
        for (a, b) in y.iter().zip(&t) {
            for i in 0..3 {
                assert!((a[i] - b[i]).abs() < 1e-12);
            }
        }
        assert_eq!(Frame::of_target(&[[1.0; 3], [1.0; 3]]).scale, 1.0);
    }
}
