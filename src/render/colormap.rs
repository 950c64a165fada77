//! The color scales of the preview. The wrinkle-vector field is painted with the one scale
//! used everywhere it is painted ([`crate::io::wrinkle_colors`]: viridis over the 2nd–98th
//! percentile range of `|w|`); the distance to the scan with a yellow–orange–red ramp over
//! `[0, 98th percentile]`, so that the two panels cannot be mistaken for each other.

use crate::io::{colormap_viridis, robust_range};

/// ColorBrewer's YlOrRd anchors (Harrower & Brewer, 2003): light yellow, orange, dark red.
const YL_OR_RD: [[f64; 3]; 3] = [
    [255.0, 255.0, 204.0],
    [253.0, 141.0, 60.0],
    [189.0, 0.0, 38.0],
];

/// The color of a NaN value in every scale.
const NAN_COLOR: [u8; 3] = [128, 128, 128];

/// Which scale a panel's values are painted with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Scale {
    /// Viridis (the wrinkle-vector field).
    Viridis,
    /// Yellow–orange–red, linear between the three anchors (the distance to the scan).
    YellowRed,
}

impl Scale {
    /// The colors of `values` over `[lo, hi]` (clamped outside; NaN gray).
    pub fn paint(self, values: &[f64], lo: f64, hi: f64) -> Vec<[u8; 3]> {
        match self {
            Scale::Viridis => colormap_viridis(values, lo, hi),
            Scale::YellowRed => values.iter().map(|&v| yellow_red(v, lo, hi)).collect(),
        }
    }

    /// The color at `t ∈ [0, 1]` along the scale.
    pub fn at(self, t: f64) -> [u8; 3] {
        self.paint(&[t], 0.0, 1.0)[0]
    }
}

fn yellow_red(v: f64, lo: f64, hi: f64) -> [u8; 3] {
    if v.is_nan() {
        return NAN_COLOR;
    }
    let t = if hi > lo && lo.is_finite() && hi.is_finite() {
        ((v - lo) / (hi - lo)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (a, b, s) = if t < 0.5 {
        (YL_OR_RD[0], YL_OR_RD[1], 2.0 * t)
    } else {
        (YL_OR_RD[1], YL_OR_RD[2], 2.0 * t - 1.0)
    };
    [0, 1, 2].map(|k| (a[k] + s * (b[k] - a[k])).round() as u8)
}

/// The distance scale's range: from 0 to the 98th percentile of the finite distances.
pub(crate) fn distance_range(distance: &[f64]) -> (f64, f64) {
    (0.0, robust_range(distance).1.max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yellow_red_runs_through_its_anchors_and_clamps() {
        let c = Scale::YellowRed.paint(&[-1.0, 0.0, 0.5, 1.0, 2.0, f64::NAN], 0.0, 1.0);
        assert_eq!(c[0], [255, 255, 204]);
        assert_eq!(c[1], [255, 255, 204]);
        assert_eq!(c[2], [253, 141, 60]);
        assert_eq!(c[3], [189, 0, 38]);
        assert_eq!(c[4], [189, 0, 38]);
        assert_eq!(c[5], NAN_COLOR);
        assert_eq!(Scale::Viridis.at(1.0), [253, 231, 37]);
        assert_eq!(distance_range(&[0.5, 1.0, 2.0]), (0.0, 2.0));
    }
}
