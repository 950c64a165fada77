//! Template mesh checks and per-vertex geometry.
//!
//! Input arrays are validated once at the start of a fit ([`validate_points`],
//! [`validate_faces`]); [`clean_faces`] reports and removes degenerate (a repeated vertex
//! index) and duplicate faces so that the fit still runs; [`vertex_normals`] computes the
//! area-weighted normals used to complete the deformation gradient (Eq. 4).

use crate::error::{FoldMatchError, Result};
use crate::math::{vec3, Vec3};
use rayon::prelude::*;

/// Checks that `points` is non-empty and every coordinate is finite.
pub fn validate_points(name: &str, points: &[[f64; 3]]) -> Result<()> {
    if points.is_empty() {
        return Err(FoldMatchError::shape(
            name,
            "expected at least one point, got 0 rows",
        ));
    }
    for (row, p) in points.iter().enumerate() {
        for &value in p {
            if !value.is_finite() {
                return Err(FoldMatchError::NonFinite {
                    name: name.into(),
                    row,
                    value,
                });
            }
        }
    }
    Ok(())
}

/// Checks that every face index is below `n_vertices`.
pub fn validate_faces(name: &str, faces: &[[u32; 3]], n_vertices: usize) -> Result<()> {
    for (face, f) in faces.iter().enumerate() {
        for &v in f {
            if v as usize >= n_vertices {
                return Err(FoldMatchError::FaceIndex {
                    name: name.into(),
                    face,
                    vertex: v as i64,
                    count: n_vertices,
                });
            }
        }
    }
    Ok(())
}

/// Faces after removing degenerate and duplicate ones, with what was removed.
#[derive(Clone, Debug, Default)]
pub struct CleanFaces {
    /// The faces kept, in input order.
    pub faces: Vec<[u32; 3]>,
    /// Indices (into the input) of faces with a repeated vertex index.
    pub degenerate: Vec<usize>,
    /// Indices (into the input) of faces that repeat an earlier face (same vertex set).
    pub duplicate: Vec<usize>,
}

/// Removes faces with a repeated vertex index and faces that repeat an earlier one (same three
/// vertices in any order). Zero-area faces with three distinct vertices are kept: they carry
/// connectivity and contribute nothing to normals.
pub fn clean_faces(faces: &[[u32; 3]]) -> CleanFaces {
    let mut out = CleanFaces::default();
    let mut seen = std::collections::HashSet::with_capacity(faces.len());
    for (i, f) in faces.iter().enumerate() {
        if f[0] == f[1] || f[1] == f[2] || f[0] == f[2] {
            out.degenerate.push(i);
            continue;
        }
        let mut key = *f;
        key.sort_unstable();
        if !seen.insert(key) {
            out.duplicate.push(i);
            continue;
        }
        out.faces.push(*f);
    }
    out
}

/// The mesh's boundary edges: those only one face uses, each as (lower, higher) vertex index,
/// in increasing order.
pub fn boundary_edges(faces: &[[u32; 3]]) -> Vec<(u32, u32)> {
    let mut edges: Vec<(u32, u32)> = faces
        .iter()
        .flat_map(|f| [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])])
        .filter(|(a, b)| a != b)
        .map(|(a, b)| (a.min(b), a.max(b)))
        .collect();
    edges.sort_unstable();
    let mut once = Vec::new();
    let mut i = 0;
    while i < edges.len() {
        let mut j = i + 1;
        while j < edges.len() && edges[j] == edges[i] {
            j += 1;
        }
        if j - i == 1 {
            once.push(edges[i]);
        }
        i = j;
    }
    once
}

/// The vertices on the mesh's boundary: those of an edge that only one face uses
/// ([`boundary_edges`]), in increasing order.
pub fn boundary_vertices(faces: &[[u32; 3]], n_vertices: usize) -> Vec<u32> {
    let mut on = vec![false; n_vertices];
    for (a, b) in boundary_edges(faces) {
        on[a as usize] = true;
        on[b as usize] = true;
    }
    (0..n_vertices as u32).filter(|&v| on[v as usize]).collect()
}

/// The connected components of the mesh (vertices joined by the faces' edges): each vertex's
/// component label, `0..count`, numbered in the order of each component's lowest vertex. A vertex
/// no face uses is a component of its own.
pub fn connected_components(faces: &[[u32; 3]], n_vertices: usize) -> (Vec<u32>, usize) {
    fn root(parent: &mut [u32], mut v: u32) -> u32 {
        while parent[v as usize] != v {
            let up = parent[parent[v as usize] as usize];
            parent[v as usize] = up;
            v = up;
        }
        v
    }
    let mut parent: Vec<u32> = (0..n_vertices as u32).collect();
    for f in faces {
        for (a, b) in [(f[0], f[1]), (f[1], f[2])] {
            let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
            if ra != rb {
                parent[ra.max(rb) as usize] = ra.min(rb);
            }
        }
    }
    let mut label = vec![u32::MAX; n_vertices];
    let mut count = 0;
    for v in 0..n_vertices as u32 {
        let r = root(&mut parent, v) as usize;
        if label[r] == u32::MAX {
            label[r] = count;
            count += 1;
        }
        label[v as usize] = label[r];
    }
    (label, count as usize)
}

/// Face normal scaled by twice the face area: `(b − a) × (c − a)`.
#[inline]
pub fn face_area_normal(p: &[[f64; 3]], f: &[u32; 3]) -> Vec3 {
    let a = vec3(&p[f[0] as usize]);
    let b = vec3(&p[f[1] as usize]);
    let c = vec3(&p[f[2] as usize]);
    (b - a).cross(&(c - a))
}

/// Vertex → incident faces, in CSR form (computed once per fit).
#[derive(Clone, Debug, Default)]
pub struct VertexFaces {
    /// `offsets[k]..offsets[k+1]` indexes `faces` for vertex k.
    pub offsets: Vec<usize>,
    /// Face indices.
    pub faces: Vec<u32>,
}

impl VertexFaces {
    /// The faces of vertex `v`.
    #[inline]
    pub fn of(&self, v: usize) -> &[u32] {
        &self.faces[self.offsets[v]..self.offsets[v + 1]]
    }

    /// Builds the incidence lists of `n_vertices` vertices.
    pub fn new(faces: &[[u32; 3]], n_vertices: usize) -> Self {
        let mut counts = vec![0usize; n_vertices + 1];
        for f in faces {
            for &v in f {
                counts[v as usize + 1] += 1;
            }
        }
        for i in 0..n_vertices {
            counts[i + 1] += counts[i];
        }
        let mut fill = counts.clone();
        let mut out = vec![0u32; counts[n_vertices]];
        for (fi, f) in faces.iter().enumerate() {
            for &v in f {
                out[fill[v as usize]] = fi as u32;
                fill[v as usize] += 1;
            }
        }
        Self {
            offsets: counts,
            faces: out,
        }
    }
}

/// Area-weighted unit vertex normals written into `out` (zero for a vertex with no face of
/// non-zero area). Vertex-parallel, so the result does not depend on the thread count.
pub fn vertex_normals(
    positions: &[[f64; 3]],
    faces: &[[u32; 3]],
    incidence: &VertexFaces,
    out: &mut [[f64; 3]],
) {
    out.par_iter_mut()
        .enumerate()
        .for_each(|(k, n)| *n = vertex_normal(positions, faces, incidence, k));
}

/// The area-weighted unit normal of vertex `k` (zero when its faces have no area).
pub fn vertex_normal(
    positions: &[[f64; 3]],
    faces: &[[u32; 3]],
    incidence: &VertexFaces,
    k: usize,
) -> [f64; 3] {
    let mut acc = Vec3::zeros();
    for &fi in &incidence.faces[incidence.offsets[k]..incidence.offsets[k + 1]] {
        acc += face_area_normal(positions, &faces[fi as usize]);
    }
    let len = acc.norm();
    if len > 0.0 {
        (acc / len).into()
    } else {
        [0.0; 3]
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn connected_components_label_each_piece_and_isolated_vertex() {
        // Two triangles sharing an edge (0–3), a separate triangle (4, 6, 7), vertex 5 unused.
        let faces = [[0, 1, 2], [2, 1, 3], [7, 4, 6]];
        let (label, count) = super::connected_components(&faces, 8);
        assert_eq!(count, 3);
        assert_eq!(label, vec![0, 0, 0, 0, 1, 2, 1, 1]);
        // Joining the pieces by one face leaves one component besides the unused vertex.
        let joined = [[0, 1, 2], [2, 1, 3], [7, 4, 6], [3, 4, 0]];
        let (label, count) = super::connected_components(&joined, 8);
        assert_eq!(count, 2);
        assert!(label
            .iter()
            .enumerate()
            .all(|(v, &l)| l == u32::from(v == 5)));
    }

    use super::*;

    #[test]
    fn rejects_empty_nan_and_bad_index() {
        assert!(matches!(
            validate_points("x", &[]),
            Err(FoldMatchError::Shape { .. })
        ));
        let e = validate_points("x", &[[0.0; 3], [0.0, f64::NAN, 0.0]]).unwrap_err();
        assert!(matches!(e, FoldMatchError::NonFinite { row: 1, .. }), "{e}");
        let e = validate_faces("f", &[[0, 1, 2], [0, 1, 5]], 3).unwrap_err();
        assert!(
            matches!(
                e,
                FoldMatchError::FaceIndex {
                    face: 1,
                    vertex: 5,
                    ..
                }
            ),
            "{e}"
        );
    }

    #[test]
    fn cleans_degenerate_and_duplicate_faces() {
        let c = clean_faces(&[[0, 1, 2], [0, 0, 1], [2, 0, 1], [1, 2, 3]]);
        assert_eq!(c.faces, vec![[0, 1, 2], [1, 2, 3]]);
        assert_eq!(c.degenerate, vec![1]);
        assert_eq!(c.duplicate, vec![2]);
    }

    #[test]
    fn normals_of_a_flat_square_point_up() {
        let p = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [5.0; 3],
        ];
        let f = [[0, 1, 2], [0, 2, 3]];
        let inc = VertexFaces::new(&f, 5);
        let mut n = vec![[0.0; 3]; 5];
        vertex_normals(&p, &f, &inc, &mut n);
        for normal in &n[..4] {
            assert_eq!(*normal, [0.0, 0.0, 1.0]);
        }
        assert_eq!(n[4], [0.0; 3], "isolated vertex has no normal");
    }
}
