//! Order-fixed summary statistics of distance vectors (deterministic for any thread count).

/// `num / den`, with `0/0 = 0` and `x/0 = +∞` for `x > 0` (see the module docs).
pub(super) fn safe_ratio(num: f64, den: f64) -> f64 {
    if den > 0.0 {
        num / den
    } else if num == 0.0 {
        0.0
    } else {
        f64::INFINITY
    }
}

/// Largest value (0 for an empty slice: the directed Hausdorff distance of an empty set).
pub(super) fn max_of(v: &[f64]) -> f64 {
    v.iter().copied().fold(0.0, f64::max)
}

/// The upper median of `v` (its element of rank ⌊n/2⌋, the median for odd n), reordering `v`
/// in place. O(n) by selection; `v` must not be empty.
pub(crate) fn upper_median(v: &mut [f64]) -> f64 {
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Arithmetic mean summed sequentially in index order (deterministic); NaN when empty.
pub(super) fn mean_of(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// The `p`-th percentile (`0 ≤ p ≤ 100`) with linear interpolation between the order
/// statistics at ranks `⌊h⌋` and `⌊h⌋+1`, `h = (n − 1)·p/100` (NumPy's default). NaN when
/// empty. O(n) by selection.
pub(crate) fn percentile_linear(v: &[f64], p: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut w = v.to_vec();
    let h = (w.len() - 1) as f64 * (p / 100.0);
    let lo = (h.floor() as usize).min(w.len() - 1);
    let t = h - lo as f64;
    let (_, &mut a, rest) = w.select_nth_unstable_by(lo, f64::total_cmp);
    if t == 0.0 || rest.is_empty() {
        return a;
    }
    let b = rest.iter().copied().fold(f64::INFINITY, f64::min);
    a + t * (b - a)
}
