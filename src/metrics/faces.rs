//! Per-face and per-edge measures of a fit against its template: the face classification
//! behind `f_S`, `f_E`, `f_F` and the spread of edge-length ratios.

use rayon::prelude::*;

use super::distance::{bbox_diagonal, dot, norm};
use super::{MetricsParams, MIN_PAR_LEN};

/// The spread of the mesh's edge lengths against the template's: the population standard
/// deviation of `ln(‖ŷᵢ − ŷⱼ‖ / ‖yᵢ − yⱼ‖)` over the unique edges `{i, j}` of `faces` (each
/// edge once, however many faces share it) whose template length is positive.
///
/// 0 for any similarity of the template (a rigid motion with a uniform scale), so it measures
/// how far the fit is from an isometry up to scale, whatever the units; schedule selection
/// breaks near-ties in scan distance with it (cloth barely stretches; docs/method.md, schedule
/// selection). A fitted edge collapsed to zero length counts as the ratio `1e-12`. No edge: 0.
/// For several fits of one template, build [`EdgeLengths`] once.
pub fn edge_length_spread(template: &[[f64; 3]], fitted: &[[f64; 3]], faces: &[[u32; 3]]) -> f64 {
    EdgeLengths::new(template, faces).spread(fitted)
}

/// A template's unique edges of positive length and their lengths: the rest state that
/// [`edge_length_spread`] compares fits with, built once for all the fits of one template.
pub struct EdgeLengths {
    edges: Vec<(u32, u32)>,
    rest: Vec<f64>,
}

impl EdgeLengths {
    /// The unique edges of `faces` (each once, however many faces share it) whose length on
    /// `template` is positive.
    pub fn new(template: &[[f64; 3]], faces: &[[u32; 3]]) -> Self {
        let mut edges: Vec<(u32, u32)> = faces
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .map(|(a, b)| (a.min(b), a.max(b)))
            .collect();
        edges.par_sort_unstable();
        edges.dedup();
        let rest: Vec<f64> = edges.iter().map(|&e| edge_length(template, e)).collect();
        let (edges, rest) = edges
            .into_iter()
            .zip(rest)
            .filter(|&(_, r)| r > 0.0)
            .unzip();
        Self { edges, rest }
    }

    /// The unique edges `(i, j)`, `i < j`, each once.
    pub fn edges(&self) -> &[(u32, u32)] {
        &self.edges
    }

    /// The mean template length of the edges (0 without edges).
    pub fn mean_length(&self) -> f64 {
        self.rest.iter().sum::<f64>() / self.rest.len().max(1) as f64
    }

    /// Every edge's length on `fitted` over its template length, in [`EdgeLengths::edges`]
    /// order (0 for an edge collapsed to a point).
    pub fn ratios(&self, fitted: &[[f64; 3]]) -> Vec<f64> {
        self.edges
            .iter()
            .zip(&self.rest)
            .map(|(&e, &rest)| edge_length(fitted, e) / rest)
            .collect()
    }

    /// [`edge_length_spread`] of `fitted` (the template's vertices, moved).
    pub fn spread(&self, fitted: &[[f64; 3]]) -> f64 {
        if self.edges.is_empty() {
            return 0.0;
        }
        let logs: Vec<f64> = self
            .edges
            .iter()
            .zip(&self.rest)
            .map(|(&e, &rest)| (edge_length(fitted, e) / rest).max(1e-12).ln())
            .collect();
        population_std(&logs)
    }

    /// The spread of the fit's stretch *field*: each vertex's mean `ln(ℓ / ℓ⁰)` over its
    /// edges, averaged `rounds` times with its neighbours' values (each round: the mean over
    /// the vertex and its neighbours), and the population standard deviation of those values
    /// over the vertices with an edge. Unlike [`EdgeLengths::spread`], the edge-scale noise of
    /// a fit on a noisy scan averages out, and what remains is stretch over regions — a sleeve
    /// longer than the template's, a garment that is not the template's isometry (docs/method.md
    /// "Isometric refinement", unstretched garments). 0 for a similarity of the template.
    pub fn stretch_field_spread(&self, fitted: &[[f64; 3]], rounds: usize) -> f64 {
        let m = fitted.len();
        let (mut sum, mut count) = (vec![0.0f64; m], vec![0usize; m]);
        for (&(a, b), &rest) in self.edges.iter().zip(&self.rest) {
            let log = (edge_length(fitted, (a, b)) / rest).max(1e-12).ln();
            for v in [a as usize, b as usize] {
                sum[v] += log;
                count[v] += 1;
            }
        }
        let mut field: Vec<f64> = sum
            .iter()
            .zip(&count)
            .map(|(&s, &c)| if c > 0 { s / c as f64 } else { 0.0 })
            .collect();
        let mut next = vec![0.0f64; m];
        for _ in 0..rounds {
            for (v, (n, &c)) in next.iter_mut().zip(&count).enumerate() {
                *n = field[v] / (c + 1) as f64;
            }
            for &(a, b) in &self.edges {
                let (a, b) = (a as usize, b as usize);
                next[a] += field[b] / (count[a] + 1) as f64;
                next[b] += field[a] / (count[b] + 1) as f64;
            }
            std::mem::swap(&mut field, &mut next);
        }
        let values: Vec<f64> = (0..m).filter(|&v| count[v] > 0).map(|v| field[v]).collect();
        population_std(&values)
    }
}

/// The population standard deviation of `values` (0 when empty).
fn population_std(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    (values.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt()
}

/// The length of the edge `(a, b)` on the points `p`.
fn edge_length(p: &[[f64; 3]], (a, b): (u32, u32)) -> f64 {
    let (a, b) = (&p[a as usize], &p[b as usize]);
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Face classification counts (integers, so the parallel reduction is exact).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub(super) struct FaceCounts {
    pub(super) degenerate: usize,
    pub(super) evaluated: usize,
    pub(super) collapsed: usize,
    pub(super) expanded: usize,
    pub(super) flipped: usize,
}

impl std::ops::Add for FaceCounts {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self {
            degenerate: self.degenerate + o.degenerate,
            evaluated: self.evaluated + o.evaluated,
            collapsed: self.collapsed + o.collapsed,
            expanded: self.expanded + o.expanded,
            flipped: self.flipped + o.flipped,
        }
    }
}

/// Classifies every face (degenerate / collapsed / expanded / flipped).
pub(super) fn face_counts(
    y: &[[f64; 3]],
    y_hat: &[[f64; 3]],
    faces: &[[u32; 3]],
    params: &MetricsParams,
) -> FaceCounts {
    let diag = bbox_diagonal(y);
    let min_area = params.degenerate_area_rel * diag * diag;
    faces
        .par_iter()
        .with_min_len(MIN_PAR_LEN)
        .map(|f| {
            let n = cross_of(y, f);
            let area = 0.5 * norm(n);
            if area <= min_area {
                return FaceCounts {
                    degenerate: 1,
                    ..FaceCounts::default()
                };
            }
            let n_hat = cross_of(y_hat, f);
            let ratio = 0.5 * norm(n_hat) / area;
            FaceCounts {
                degenerate: 0,
                evaluated: 1,
                collapsed: usize::from(ratio < params.tau_s),
                expanded: usize::from(ratio > params.tau_e),
                flipped: usize::from(dot(n, n_hat) < 0.0),
            }
        })
        .reduce(FaceCounts::default, |a, b| a + b)
}

/// `(b − a) × (c − a)` of face `f` over `p`: the normal scaled by twice the area.
#[inline]
pub(crate) fn cross_of(p: &[[f64; 3]], f: &[u32; 3]) -> [f64; 3] {
    let [a, b, c] = f.map(|i| p[i as usize]);
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]
}
