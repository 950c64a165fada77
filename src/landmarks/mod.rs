//! Landmarks: template vertices whose positions on the scan are known (a user's clicks, a
//! detector's keypoints, a marker's position), given as `(vertex index, target position)`
//! pairs. They decide the global pre-alignment ([`align::fit_similarity`]: the rigid fit of
//! the landmark vertices onto their targets; one or two choose among the search's placements,
//! [`crate::prealign::align_by_landmarks`]) and act as soft constraints through every phase of
//! the fit (docs/method.md "Landmarks").

pub mod align;

use crate::error::{FoldMatchError, Result};
pub use align::{fit_similarity, fixes_rotation, Similarity};

/// Validated landmarks: distinct template vertex indices, each with a finite target position
/// in the scan's coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct Landmarks {
    /// The constrained template vertices (distinct, each below the template's vertex count).
    pub vertices: Vec<u32>,
    /// Where each of them belongs, in the scan's coordinates.
    pub positions: Vec<[f64; 3]>,
}

impl Landmarks {
    /// Checks the pairs against a template of `template_vertices` vertices: as many indices as
    /// positions, at least one pair, every index in range and used once, every coordinate
    /// finite. The error names the first bad landmark ([`FoldMatchError::Landmark`]).
    pub fn new(vertices: &[i64], positions: &[[f64; 3]], template_vertices: usize) -> Result<Self> {
        if vertices.len() != positions.len() {
            return Err(FoldMatchError::shape(
                "landmarks",
                format!(
                    "{} vertex indices but {} target positions (need one position per index)",
                    vertices.len(),
                    positions.len()
                ),
            ));
        }
        if vertices.is_empty() {
            return Err(FoldMatchError::shape(
                "landmarks",
                "no landmarks (pass none instead of an empty list)",
            ));
        }
        let mut first_use = std::collections::HashMap::with_capacity(vertices.len());
        for (i, (&v, p)) in vertices.iter().zip(positions).enumerate() {
            if v < 0 || v as u64 >= template_vertices as u64 {
                return Err(FoldMatchError::Landmark {
                    index: i,
                    reason: format!(
                        "vertex {v} is out of range: the template has {template_vertices} vertices"
                    ),
                });
            }
            if let Some(bad) = p.iter().find(|x| !x.is_finite()) {
                return Err(FoldMatchError::Landmark {
                    index: i,
                    reason: format!("non-finite target coordinate ({bad}) for vertex {v}"),
                });
            }
            if let Some(j) = first_use.insert(v, i) {
                return Err(FoldMatchError::Landmark {
                    index: i,
                    reason: format!("vertex {v} is already constrained by landmark {j}"),
                });
            }
        }
        Ok(Self {
            vertices: vertices.iter().map(|&v| v as u32).collect(),
            positions: positions.to_vec(),
        })
    }

    /// How many landmarks.
    pub fn len(&self) -> usize {
        self.vertices.len()
    }

    /// Whether there are none (never, for a value built by [`Landmarks::new`]).
    pub fn is_empty(&self) -> bool {
        self.vertices.is_empty()
    }

    /// The motion that the landmarks decide for `template`: the least-squares rigid motion
    /// (with `scale`: similarity) of the landmark vertices onto their targets
    /// ([`fit_similarity`]; with fewer than three landmarks, or three on a line, the
    /// translation of their centroid alone).
    pub fn alignment(&self, template: &[[f64; 3]], scale: bool) -> Similarity {
        fit_similarity(&self.on(template), &self.positions, scale)
    }

    /// The landmark vertices' positions in `template`.
    pub fn on(&self, template: &[[f64; 3]]) -> Vec<[f64; 3]> {
        self.vertices
            .iter()
            .map(|&v| template[v as usize])
            .collect()
    }

    /// Whether the landmarks fix the template's orientation by themselves: three or more, not
    /// on a line ([`fixes_rotation`]). Fewer choose among the pre-alignment's placements
    /// instead ([`crate::prealign::align_by_landmarks`]).
    pub fn fix_orientation(&self, template: &[[f64; 3]]) -> bool {
        fixes_rotation(&self.on(template))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refused(vertices: &[i64], positions: &[[f64; 3]]) -> FoldMatchError {
        Landmarks::new(vertices, positions, 10).unwrap_err()
    }

    #[test]
    fn bad_landmarks_are_refused_naming_the_landmark() {
        let p = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        // (indices, positions, the landmark blamed, the reason given)
        type Bad<'a> = (&'a [i64], [[f64; 3]; 3], usize, &'a str);
        let cases: [Bad<'_>; 4] = [
            (
                &[0, 10, 2],
                p,
                1,
                "vertex 10 is out of range: the template has 10 vertices",
            ),
            (&[0, 1, -1], p, 2, "vertex -1 is out of range"),
            (
                &[0, 1, 2],
                [p[0], p[1], [0.0, f64::NAN, 0.0]],
                2,
                "non-finite target coordinate (NaN)",
            ),
            (
                &[4, 5, 4],
                p,
                2,
                "vertex 4 is already constrained by landmark 0",
            ),
        ];
        for (vertices, positions, index, reason) in cases {
            match refused(vertices, &positions) {
                FoldMatchError::Landmark {
                    index: i,
                    reason: r,
                } => {
                    assert_eq!(i, index, "{r}");
                    assert!(r.contains(reason), "{r}");
                }
                other => panic!("{other:?}"),
            }
        }
        let shape = |e: FoldMatchError| matches!(e, FoldMatchError::Shape { .. });
        assert!(shape(refused(&[0, 1], &p)), "two indices, three positions");
        assert!(shape(refused(&[], &[])), "none at all");
        let ok = Landmarks::new(&[9, 0, 3], &p, 10).unwrap();
        assert_eq!(ok.vertices, vec![9, 0, 3]);
        assert_eq!(ok.positions, p.to_vec());
    }

    #[test]
    fn the_alignment_moves_the_landmark_vertices_onto_their_targets() {
        let template = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 2.0, 0.0],
            [0.0, 0.0, 3.0],
        ];
        // Turned by 90° about z, (x, y, z) ↦ (−y, x, z), and moved by (5, 0, 1).
        let moved = |p: &[f64; 3]| [5.0 - p[1], p[0], p[2] + 1.0];
        let targets: Vec<[f64; 3]> = [1, 2, 3].iter().map(|&v| moved(&template[v])).collect();
        let l = Landmarks::new(&[1, 2, 3], &targets, 4).unwrap();
        let aligned = l.alignment(&template, false).apply_all(&template);
        for (a, p) in aligned.iter().zip(&template) {
            let want = moved(p);
            assert!(
                (0..3).all(|i| (a[i] - want[i]).abs() < 1e-12),
                "{a:?} vs {want:?}"
            );
        }
    }
}
