//! The fitted mesh as every writer lays it out: the CLI's outputs and Python's
//! `FitResult.save` write it through [`fitted_mesh`], and `FitResult.to_trimesh` takes its
//! colors from the same [`wrinkle_colors`].

use super::{wrinkle_colors, MeshData, VertexProperty};

/// The fitted mesh with its wrinkle-vector field `field` (one vector per vertex): the fitted
/// vertices and the template's faces, the magnitude `|w|` as vertex colors
/// ([`wrinkle_colors`]: viridis over its 2nd–98th percentiles), and the vertex properties
/// `wvf_x`, `wvf_y`, `wvf_z`, `wvf_magnitude` in that order (PLY writes them as `double`
/// after `red green blue`; OBJ keeps only the colors).
///
/// # Examples
/// ```
/// use foldmatch::io::fitted_mesh;
/// let (mesh, extra) = fitted_mesh(&[[0.0; 3], [1.0, 0.0, 0.0]], &[], &[[3.0, 4.0, 0.0], [0.0; 3]]);
/// assert_eq!(extra[3].name, "wvf_magnitude");
/// assert_eq!(extra[3].values, vec![5.0, 0.0]);
/// assert_eq!(mesh.colors.unwrap()[0], [253, 231, 37]);
/// ```
pub fn fitted_mesh(
    fitted: &[[f64; 3]],
    faces: &[[u32; 3]],
    field: &[[f64; 3]],
) -> (MeshData, Vec<VertexProperty>) {
    let magnitude = crate::fit::magnitudes(field);
    let mut mesh = MeshData::new(fitted.to_vec(), faces.to_vec());
    mesh.colors = Some(wrinkle_colors(&magnitude).0);
    let column = |i: usize| field.iter().map(|v| v[i]).collect();
    let extra = vec![
        VertexProperty::new("wvf_x", column(0)),
        VertexProperty::new("wvf_y", column(1)),
        VertexProperty::new("wvf_z", column(2)),
        VertexProperty::new("wvf_magnitude", magnitude),
    ];
    (mesh, extra)
}
