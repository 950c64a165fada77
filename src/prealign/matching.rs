//! The robust two-sided distance between a transformed template and the scan, and the point
//! pairs it is made of: the nearest scan point of every template sample and the nearest
//! template vertex of every scan sample, each direction trimmed to its closest
//! [`KEPT_FRACTION`] (trimmed ICP, Chetverikov et al. 2002), so that scan points the garment
//! does not explain (a hole, another garment, a side the camera did not see) and template
//! parts with no scan support do not decide the placement.

use super::transform::Similarity;
use crate::knn::PointIndex;

/// The share of each direction's matches that counts (the closest ones).
pub const KEPT_FRACTION: f64 = 0.75;

/// At most this many points of each side are matched per evaluation.
pub const SAMPLE_SIZE: usize = 768;

/// At most this many points of each side in the coarse refinement of every candidate
/// ([`Level::Coarse`]; docs/method.md "Global pre-alignment").
pub const COARSE_SAMPLE_SIZE: usize = 128;

/// At most this many points of each side are indexed for the coarse evaluations (their
/// nearest points come from these).
pub const COARSE_CLOUD_SIZE: usize = 2048;

/// Which samples an evaluation matches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    /// [`COARSE_SAMPLE_SIZE`] points of each side: every candidate's first refinement.
    Coarse,
    /// [`SAMPLE_SIZE`] points of each side: the score that decides.
    Full,
}

/// The template and the scan, indexed for nearest-point queries, with the samples whose
/// matches are scored.
pub struct Clouds {
    /// Per [`Level`] (coarse, full): the template's and the scan's points indexed, every point
    /// or (coarse) [`COARSE_CLOUD_SIZE`] of each.
    indices: [(PointIndex, PointIndex); 2],
    /// Per [`Level`] (coarse, full): the template's and the scan's samples.
    samples: [Samples; 2],
}

/// The template's and the scan's points that one [`Level`] matches.
type Samples = (Vec<[f64; 3]>, Vec<[f64; 3]>);

/// A template point matched with a scan point, and their distance in the scan's units.
pub type Match = ([f64; 3], [f64; 3], f64);

/// At most `count` points of `points`, spread over the whole array: one from each of `count`
/// equal runs, its position in the run from a fixed hash (so that a regular grid order does not
/// alias into rows). Deterministic.
pub fn spread_sample(points: &[[f64; 3]], count: usize) -> Vec<[f64; 3]> {
    let n = points.len();
    if n <= count {
        return points.to_vec();
    }
    (0..count)
        .map(|i| {
            let (lo, hi) = (i * n / count, (i + 1) * n / count);
            let h = (i as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 33;
            points[lo + (h as usize) % (hi - lo)]
        })
        .collect()
}

impl Clouds {
    /// Indexes both point sets (each non-empty) and draws the samples: the template's in its
    /// vertex order, the scan's in Morton order (so the scan's order does not choose them; the
    /// fit's result depends on it only by round-off).
    pub fn new(template: &[[f64; 3]], scan: &[[f64; 3]]) -> Self {
        let ordered: Vec<[f64; 3]> = crate::knn::morton_order(scan)
            .into_iter()
            .map(|j| scan[j as usize])
            .collect();
        let scan = &ordered[..];
        let ((t, s), coarse) = rayon::join(
            || rayon::join(|| PointIndex::new(template), || PointIndex::new(scan)),
            || {
                (
                    PointIndex::new(&spread_sample(template, COARSE_CLOUD_SIZE)),
                    PointIndex::new(&spread_sample(scan, COARSE_CLOUD_SIZE)),
                )
            },
        );
        let draw = |count| (spread_sample(template, count), spread_sample(scan, count));
        Self {
            indices: [coarse, (t, s)],
            samples: [draw(COARSE_SAMPLE_SIZE), draw(SAMPLE_SIZE)],
        }
    }

    /// The template's points, every one, indexed.
    pub fn template_index(&self) -> &PointIndex {
        &self.indices[Level::Full as usize].0
    }

    /// The matches under `t` (template coordinates → scan coordinates) of the samples of
    /// `level`, each direction sorted by distance and trimmed to its closest
    /// [`KEPT_FRACTION`]: (template → scan, scan → template), every pair as (template point,
    /// scan point, distance in scan units). Serial: the candidates run in parallel.
    pub fn matches(&self, t: &Similarity, level: Level) -> (Vec<Match>, Vec<Match>) {
        let inverse = t.inverse();
        let (template_sample, scan_sample) = &self.samples[level as usize];
        let (template, scan) = &self.indices[level as usize];
        let mut forward: Vec<Match> = template_sample
            .iter()
            .map(|y| {
                let (j, d2) = scan.nearest_one(&t.apply(y));
                (*y, *scan.point(j), d2.sqrt())
            })
            .collect();
        let mut backward: Vec<Match> = scan_sample
            .iter()
            .map(|x| {
                let (j, d2) = template.nearest_one(&inverse.apply(x));
                (*template.point(j), *x, t.scale * d2.sqrt())
            })
            .collect();
        for side in [&mut forward, &mut backward] {
            side.sort_by(|a, b| a.2.total_cmp(&b.2));
            side.truncate(kept(side.len()));
        }
        (forward, backward)
    }

    /// The two-sided trimmed distance under `t` on the full samples (the mean of the two
    /// directions' trimmed mean distances), and the template → scan direction's alone, in scan
    /// units.
    pub fn scores(&self, t: &Similarity) -> (f64, f64) {
        let (forward, backward) = self.matches(t, Level::Full);
        (score_of(&forward, &backward), mean_distance(&forward))
    }
}

/// The mean of the two directions' mean distances.
pub fn score_of(forward: &[Match], backward: &[Match]) -> f64 {
    0.5 * (mean_distance(forward) + mean_distance(backward))
}

/// The mean distance of the matches `m` (0 when empty).
fn mean_distance(m: &[Match]) -> f64 {
    m.iter().map(|p| p.2).sum::<f64>() / m.len().max(1) as f64
}

fn kept(n: usize) -> usize {
    ((n as f64 * KEPT_FRACTION).ceil() as usize).clamp(n.min(1), n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_sample_takes_one_point_per_run_and_everything_when_small() {
        let points: Vec<[f64; 3]> = (0..1000).map(|i| [i as f64, 0.0, 0.0]).collect();
        let s = spread_sample(&points, 100);
        assert_eq!(s.len(), 100);
        for (i, p) in s.iter().enumerate() {
            assert!((i * 10..(i + 1) * 10).contains(&(p[0] as usize)));
        }
        // Not the same offset in every run (a grid's rows would alias).
        assert!(s
            .iter()
            .any(|p| p[0] as usize % 10 != s[0][0] as usize % 10));
        assert_eq!(spread_sample(&points[..50], 100).len(), 50);
    }

    #[test]
    fn the_score_is_zero_on_a_match_and_the_offset_under_a_translation() {
        let points: Vec<[f64; 3]> = (0..900)
            .map(|i| [(i % 30) as f64 * 0.1, (i / 30) as f64 * 0.1, 0.0])
            .collect();
        let clouds = Clouds::new(&points, &points);
        assert_eq!(clouds.scores(&Similarity::identity()).0, 0.0);
        // Lifted off the plane by 0.5: every match is 0.5 away in both directions.
        let lifted = Similarity {
            translation: crate::math::Vec3::new(0.0, 0.0, 0.5),
            ..Similarity::identity()
        };
        approx::assert_relative_eq!(clouds.scores(&lifted).0, 0.5, epsilon = 1e-12);
        let (f, b) = clouds.matches(&lifted, Level::Full);
        assert_eq!(f.len(), kept(SAMPLE_SIZE));
        assert_eq!(b.len(), kept(SAMPLE_SIZE));
    }
}
