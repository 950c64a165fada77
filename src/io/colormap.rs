//! The viridis colormap, for painting scalar per-vertex fields (the wrinkle-vector magnitude).
//!
//! Viridis (van der Walt & Smith, 2015; matplotlib's default) is perceptually uniform and
//! readable in grayscale and by color-blind viewers. The table is matplotlib's 256-entry
//! `_viridis_data` (released under CC0 by its authors), rounded to 8-bit RGB.

/// Maps each value to a viridis color: `lo` → dark purple, `hi` → yellow, linear in between,
/// clamped outside `[lo, hi]`.
///
/// Values are quantized to the 256 table entries (`round(255·t)`). NaN values map to mid
/// gray `[128, 128, 128]`. When the range is empty or invalid (`hi <= lo`, or either bound
/// not finite), every finite value maps to the lowest color.
///
/// # Examples
/// ```
/// use foldmatch::io::colormap_viridis;
/// let c = colormap_viridis(&[0.0, 0.5, 1.0, f64::NAN], 0.0, 1.0);
/// assert_eq!(c, vec![[68, 1, 84], [33, 145, 140], [253, 231, 37], [128, 128, 128]]);
/// ```
pub fn colormap_viridis(values: &[f64], lo: f64, hi: f64) -> Vec<[u8; 3]> {
    let valid = lo.is_finite() && hi.is_finite() && hi > lo;
    let scale = if valid { 255.0 / (hi - lo) } else { 0.0 };
    values
        .iter()
        .map(|&v| {
            if v.is_nan() {
                return NAN_COLOR;
            }
            let t = if valid {
                ((v - lo) * scale).clamp(0.0, 255.0)
            } else {
                0.0
            };
            VIRIDIS[t.round() as usize]
        })
        .collect()
}

/// The color scale of the wrinkle-vector field everywhere it is painted (the fitted PLY's
/// vertex colors written by the CLI and by Python's `FitResult.to_trimesh()`, and the
/// preview images of `foldmatch::render`): viridis of the magnitude `|w|` over
/// [`robust_range`] of the magnitudes. Returns the colors and the range `(lo, hi)` used.
///
/// # Examples
/// ```
/// use foldmatch::io::wrinkle_colors;
/// let (colors, (lo, hi)) = wrinkle_colors(&[0.0, 1.0, 2.0]);
/// assert_eq!((lo, hi), (0.0, 2.0));
/// assert_eq!(colors[0], [68, 1, 84]);
/// assert_eq!(colors[2], [253, 231, 37]);
/// ```
pub fn wrinkle_colors(magnitude: &[f64]) -> (Vec<[u8; 3]>, (f64, f64)) {
    let (lo, hi) = robust_range(magnitude);
    (colormap_viridis(magnitude, lo, hi), (lo, hi))
}

/// The 2nd and 98th percentiles of the finite values (the nearest-rank value at
/// `round((n − 1)·q)` of the sorted values): robust to a few extreme vertices. `(0, 1)` when
/// no value is finite.
pub fn robust_range(values: &[f64]) -> (f64, f64) {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return (0.0, 1.0);
    }
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    (at(0.02), at(0.98))
}

/// The color given to NaN values.
const NAN_COLOR: [u8; 3] = [128, 128, 128];

/// matplotlib's viridis, 256 entries, 8-bit RGB.
#[rustfmt::skip]
const VIRIDIS: [[u8; 3]; 256] = [
    [68, 1, 84], [68, 2, 86], [69, 4, 87], [69, 5, 89], [70, 7, 90], [70, 8, 92],
    [70, 10, 93], [70, 11, 94], [71, 13, 96], [71, 14, 97], [71, 16, 99], [71, 17, 100],
    [71, 19, 101], [72, 20, 103], [72, 22, 104], [72, 23, 105], [72, 24, 106], [72, 26, 108],
    [72, 27, 109], [72, 28, 110], [72, 29, 111], [72, 31, 112], [72, 32, 113], [72, 33, 115],
    [72, 35, 116], [72, 36, 117], [72, 37, 118], [72, 38, 119], [72, 40, 120], [72, 41, 121],
    [71, 42, 122], [71, 44, 122], [71, 45, 123], [71, 46, 124], [71, 47, 125], [70, 48, 126],
    [70, 50, 126], [70, 51, 127], [70, 52, 128], [69, 53, 129], [69, 55, 129], [69, 56, 130],
    [68, 57, 131], [68, 58, 131], [68, 59, 132], [67, 61, 132], [67, 62, 133], [66, 63, 133],
    [66, 64, 134], [66, 65, 134], [65, 66, 135], [65, 68, 135], [64, 69, 136], [64, 70, 136],
    [63, 71, 136], [63, 72, 137], [62, 73, 137], [62, 74, 137], [62, 76, 138], [61, 77, 138],
    [61, 78, 138], [60, 79, 138], [60, 80, 139], [59, 81, 139], [59, 82, 139], [58, 83, 139],
    [58, 84, 140], [57, 85, 140], [57, 86, 140], [56, 88, 140], [56, 89, 140], [55, 90, 140],
    [55, 91, 141], [54, 92, 141], [54, 93, 141], [53, 94, 141], [53, 95, 141], [52, 96, 141],
    [52, 97, 141], [51, 98, 141], [51, 99, 141], [50, 100, 142], [50, 101, 142], [49, 102, 142],
    [49, 103, 142], [49, 104, 142], [48, 105, 142], [48, 106, 142], [47, 107, 142], [47, 108, 142],
    [46, 109, 142], [46, 110, 142], [46, 111, 142], [45, 112, 142], [45, 113, 142], [44, 113, 142],
    [44, 114, 142], [44, 115, 142], [43, 116, 142], [43, 117, 142], [42, 118, 142], [42, 119, 142],
    [42, 120, 142], [41, 121, 142], [41, 122, 142], [41, 123, 142], [40, 124, 142], [40, 125, 142],
    [39, 126, 142], [39, 127, 142], [39, 128, 142], [38, 129, 142], [38, 130, 142], [38, 130, 142],
    [37, 131, 142], [37, 132, 142], [37, 133, 142], [36, 134, 142], [36, 135, 142], [35, 136, 142],
    [35, 137, 142], [35, 138, 141], [34, 139, 141], [34, 140, 141], [34, 141, 141], [33, 142, 141],
    [33, 143, 141], [33, 144, 141], [33, 145, 140], [32, 146, 140], [32, 146, 140], [32, 147, 140],
    [31, 148, 140], [31, 149, 139], [31, 150, 139], [31, 151, 139], [31, 152, 139], [31, 153, 138],
    [31, 154, 138], [30, 155, 138], [30, 156, 137], [30, 157, 137], [31, 158, 137], [31, 159, 136],
    [31, 160, 136], [31, 161, 136], [31, 161, 135], [31, 162, 135], [32, 163, 134], [32, 164, 134],
    [33, 165, 133], [33, 166, 133], [34, 167, 133], [34, 168, 132], [35, 169, 131], [36, 170, 131],
    [37, 171, 130], [37, 172, 130], [38, 173, 129], [39, 173, 129], [40, 174, 128], [41, 175, 127],
    [42, 176, 127], [44, 177, 126], [45, 178, 125], [46, 179, 124], [47, 180, 124], [49, 181, 123],
    [50, 182, 122], [52, 182, 121], [53, 183, 121], [55, 184, 120], [56, 185, 119], [58, 186, 118],
    [59, 187, 117], [61, 188, 116], [63, 188, 115], [64, 189, 114], [66, 190, 113], [68, 191, 112],
    [70, 192, 111], [72, 193, 110], [74, 193, 109], [76, 194, 108], [78, 195, 107], [80, 196, 106],
    [82, 197, 105], [84, 197, 104], [86, 198, 103], [88, 199, 101], [90, 200, 100], [92, 200, 99],
    [94, 201, 98], [96, 202, 96], [99, 203, 95], [101, 203, 94], [103, 204, 92], [105, 205, 91],
    [108, 205, 90], [110, 206, 88], [112, 207, 87], [115, 208, 86], [117, 208, 84], [119, 209, 83],
    [122, 209, 81], [124, 210, 80], [127, 211, 78], [129, 211, 77], [132, 212, 75], [134, 213, 73],
    [137, 213, 72], [139, 214, 70], [142, 214, 69], [144, 215, 67], [147, 215, 65], [149, 216, 64],
    [152, 216, 62], [155, 217, 60], [157, 217, 59], [160, 218, 57], [162, 218, 55], [165, 219, 54],
    [168, 219, 52], [170, 220, 50], [173, 220, 48], [176, 221, 47], [178, 221, 45], [181, 222, 43],
    [184, 222, 41], [186, 222, 40], [189, 223, 38], [192, 223, 37], [194, 223, 35], [197, 224, 33],
    [200, 224, 32], [202, 225, 31], [205, 225, 29], [208, 225, 28], [210, 226, 27], [213, 226, 26],
    [216, 226, 25], [218, 227, 25], [221, 227, 24], [223, 227, 24], [226, 228, 24], [229, 228, 25],
    [231, 228, 25], [234, 229, 26], [236, 229, 27], [239, 229, 28], [241, 229, 29], [244, 230, 30],
    [246, 230, 32], [248, 230, 33], [251, 231, 35], [253, 231, 37],
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn endpoints_midpoint_and_clamping() {
        let c = colormap_viridis(
            &[-1.0, 0.0, 5.0, 10.0, 11.0, f64::INFINITY, f64::NEG_INFINITY],
            0.0,
            10.0,
        );
        assert_eq!(c[0], [68, 1, 84]);
        assert_eq!(c[1], [68, 1, 84]);
        assert_eq!(c[2], [33, 145, 140]); // #21918c, matplotlib's viridis(0.5)
        assert_eq!(c[3], [253, 231, 37]); // #fde725
        assert_eq!(c[4], [253, 231, 37]);
        assert_eq!(c[5], [253, 231, 37]);
        assert_eq!(c[6], [68, 1, 84]);
        assert_eq!(colormap_viridis(&[0.25], 0.0, 1.0)[0], [59, 82, 139]); // #3b528b
    }

    #[test]
    fn robust_range_ignores_outliers_and_non_finite() {
        let mut v: Vec<f64> = (0..=100).map(f64::from).collect();
        v.push(f64::NAN);
        v.push(f64::INFINITY);
        assert_eq!(robust_range(&v), (2.0, 98.0));
        assert_eq!(robust_range(&[f64::NAN]), (0.0, 1.0));
        let (colors, range) = wrinkle_colors(&v[..101]);
        assert_eq!(range, (2.0, 98.0));
        assert_eq!(colors[0], VIRIDIS[0]);
        assert_eq!(colors[100], VIRIDIS[255]);
    }

    #[test]
    fn degenerate_ranges_and_nan() {
        assert_eq!(
            colormap_viridis(&[1.0, 2.0], 1.0, 1.0),
            vec![[68, 1, 84]; 2]
        );
        assert_eq!(colormap_viridis(&[1.0], 2.0, 1.0), vec![[68, 1, 84]]);
        assert_eq!(colormap_viridis(&[1.0], f64::NAN, 1.0), vec![[68, 1, 84]]);
        assert_eq!(colormap_viridis(&[f64::NAN], 0.0, 1.0), vec![NAN_COLOR]);
        assert!(colormap_viridis(&[], 0.0, 1.0).is_empty());
    }

    #[test]
    fn table_is_smooth_and_brightens() {
        // Perceived lightness grows monotonically along viridis; a typo in the table would
        // show up as a jump.
        let luma = |c: [u8; 3]| {
            0.2126 * f64::from(c[0]) + 0.7152 * f64::from(c[1]) + 0.0722 * f64::from(c[2])
        };
        for w in VIRIDIS.windows(2) {
            assert!(luma(w[1]) >= luma(w[0]) - 0.5, "{:?} -> {:?}", w[0], w[1]);
            for k in 0..3 {
                assert!(
                    (i32::from(w[1][k]) - i32::from(w[0][k])).abs() <= 3,
                    "{:?} -> {:?}",
                    w[0],
                    w[1]
                );
            }
        }
    }
}
