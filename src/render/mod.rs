//! Headless preview images of a fit (feature `render`, part of `cli` and `python`): the scan,
//! the fitted mesh colored by the accumulated wrinkle-vector field, and the fitted mesh colored
//! by each vertex's distance to the scan, each from two or three views, in one PNG.
//!
//! The picture is a grid: one column per [`View`] and one row per layer —
//!
//! 1. **scan** (when given): its points (or its mesh) in gray, darker when farther;
//! 2. **wrinkle |w|**: the fitted mesh, Lambert-shaded, colored by the magnitude of the
//!    wrinkle-vector field with [`crate::io::wrinkle_colors`] (viridis over the 2nd–98th
//!    percentile range: the same colors as the fitted PLY), or plain gray without a field;
//! 3. **distance to scan** (when a scan is given): the fitted mesh colored by each vertex's
//!    distance to the nearest scan point, yellow (0) to dark red (the 98th percentile).
//!
//! with the color bar of each colored row on the right. Every panel frames the same bounding
//! sphere of the scan and the mesh, seen orthographically with +y up.
//!
//! It is drawn by the small z-buffer rasterizer of [`raster`](self) and written by the `png`
//! crate: measured against `tiny-skia` (a 2D path renderer, so no depth test) and `image`,
//! this adds the fewest crates and the least build time (docs/cli.md, "Preview images").
//!
//! # Examples
//! ```
//! use foldmatch::render::{render, PreviewOptions, Scene};
//! let vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
//! let faces = [[0, 1, 2]];
//! let scene = Scene { field: Some(&[0.0, 0.5, 1.0]), ..Scene::mesh(&vertices, &faces) };
//! let preview = render(&scene, &PreviewOptions::default()).unwrap();
//! assert_eq!((preview.image.width, preview.image.height), (3 * 320 + 96, 320));
//! ```

mod camera;
mod colormap;
mod encode;
mod legend;
mod raster;

pub use camera::View;
pub use encode::{encode_png, write_png};

use crate::error::{FoldMatchError, Result};
use crate::io::wrinkle_colors;
use crate::knn::PointIndex;
use camera::{Bounds, Camera};
use colormap::{distance_range, Scale};
use raster::Canvas;
use rayon::prelude::*;

/// What to draw.
#[derive(Clone, Copy, Debug)]
pub struct Scene<'a> {
    /// The fitted mesh's vertices.
    pub vertices: &'a [[f64; 3]],
    /// Its triangles.
    pub faces: &'a [[u32; 3]],
    /// Per-vertex magnitude of the wrinkle-vector field, `|w|` (the mesh is gray without it).
    pub field: Option<&'a [f64]>,
    /// The scan's points: adds the scan row and the distance row.
    pub scan: Option<&'a [[f64; 3]]>,
    /// The scan's triangles, when it is a mesh (drawn shaded instead of as points).
    pub scan_faces: Option<&'a [[u32; 3]]>,
}

impl<'a> Scene<'a> {
    /// The mesh alone.
    pub fn mesh(vertices: &'a [[f64; 3]], faces: &'a [[u32; 3]]) -> Self {
        Self {
            vertices,
            faces,
            field: None,
            scan: None,
            scan_faces: None,
        }
    }
}

/// How to draw it.
#[derive(Clone, Debug, PartialEq)]
pub struct PreviewOptions {
    /// Edge of one square panel, in pixels (16 ..= 4096).
    pub panel: u32,
    /// The columns of the grid, one per view (1 ..= 4).
    pub views: Vec<View>,
}

impl Default for PreviewOptions {
    /// 320-pixel panels, [`View::DEFAULT`].
    fn default() -> Self {
        Self {
            panel: 320,
            views: View::DEFAULT.to_vec(),
        }
    }
}

/// An 8-bit RGB image, rows top to bottom, `width · height · 3` bytes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `[r, g, b]` per pixel, row-major.
    pub pixels: Vec<u8>,
}

/// A rendered preview and the ranges its color bars show.
#[derive(Clone, Debug, PartialEq)]
pub struct Preview {
    /// The picture.
    pub image: Image,
    /// `(lo, hi)` of the wrinkle-field colors, when a field was drawn.
    pub field_range: Option<(f64, f64)>,
    /// `(0, hi)` of the distance colors, when a scan was given.
    pub distance_range: Option<(f64, f64)>,
}

impl Preview {
    /// `tEXt` entries for the PNG: what each row shows and its color range.
    pub fn png_text(&self) -> Vec<(&'static str, String)> {
        let mut text = vec![(
            "Software",
            format!("foldmatch {}", env!("CARGO_PKG_VERSION")),
        )];
        if let Some((lo, hi)) = self.field_range {
            text.push((
                "foldmatch:wrinkle_range",
                format!("viridis of |w| over [{lo:e}, {hi:e}]"),
            ));
        }
        if let Some((lo, hi)) = self.distance_range {
            text.push((
                "foldmatch:distance_range",
                format!("yellow-red of the distance to the scan over [{lo:e}, {hi:e}]"),
            ));
        }
        text
    }
}

/// Background of the panels.
pub const BACKGROUND: [u8; 3] = [255, 255, 255];
/// Width of the color-bar column, in pixels.
pub const LEGEND_WIDTH: u32 = 96;
/// The mesh's color where no field is given (before shading).
const PLAIN: [u8; 3] = [190, 190, 190];
/// Light direction in the camera frame (from the upper left, toward the scene).
const LIGHT: [f64; 3] = [-0.35, 0.45, 0.82];

/// One layer of the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Row {
    Scan,
    Field,
    Distance,
}

/// Renders `scene` (see the [module docs](self) for the layout). Errors name the input when
/// the mesh or scan is empty or a face points past the vertices, when a per-vertex field has
/// the wrong length, or when an option is out of range.
pub fn render(scene: &Scene<'_>, options: &PreviewOptions) -> Result<Preview> {
    validate(scene, options)?;
    let panel = options.panel as usize;
    let field = scene.field.map(wrinkle_colors);
    let distance = scene.scan.map(|scan| {
        let index = PointIndex::new(scan);
        let d: Vec<f64> = scene
            .vertices
            .par_iter()
            .map(|v| index.nearest_one(v).1.sqrt())
            .collect();
        let range = distance_range(&d);
        (Scale::YellowRed.paint(&d, range.0, range.1), range)
    });
    let mut rows = Vec::new();
    if scene.scan.is_some() {
        rows.push(Row::Scan);
    }
    rows.push(Row::Field);
    if scene.scan.is_some() {
        rows.push(Row::Distance);
    }
    let mut sets = vec![scene.vertices];
    sets.extend(scene.scan);
    let bounds = Bounds::of(&sets);
    let plain = vec![PLAIN; scene.vertices.len()];
    let cells: Vec<(usize, usize)> = (0..rows.len())
        .flat_map(|r| (0..options.views.len()).map(move |c| (r, c)))
        .collect();
    let panels: Vec<Canvas> = cells
        .par_iter()
        .map(|&(r, c)| {
            let view = options.views[c];
            let camera = Camera::new(&bounds, view, options.panel);
            let mut canvas = Canvas::new(panel, panel, BACKGROUND);
            let title = match rows[r] {
                Row::Scan => {
                    draw_scan(&mut canvas, &camera, scene, bounds.radius);
                    "scan"
                }
                Row::Field => {
                    let colors = field.as_ref().map_or(&plain, |f| &f.0);
                    draw_mesh(&mut canvas, &camera, scene.vertices, scene.faces, colors);
                    if field.is_some() {
                        "wrinkle |w|"
                    } else {
                        "fit"
                    }
                }
                Row::Distance => {
                    let colors = &distance.as_ref().map_or(&plain, |d| &d.0);
                    draw_mesh(&mut canvas, &camera, scene.vertices, scene.faces, colors);
                    "distance to scan"
                }
            };
            legend::text(&mut canvas, 6, 6, title, [40, 40, 40]);
            let name = view.name();
            legend::text(
                &mut canvas,
                panel.saturating_sub(6 + name.len() * legend::ADVANCE),
                panel.saturating_sub(6 + legend::LINE),
                name,
                [120, 120, 120],
            );
            canvas
        })
        .collect();
    let columns = options.views.len();
    let width = columns * panel + LEGEND_WIDTH as usize;
    let height = rows.len() * panel;
    let mut sheet = Canvas::new(width, height, BACKGROUND);
    for (&(r, c), canvas) in cells.iter().zip(&panels) {
        for y in 0..panel {
            let from = &canvas.rgb[y * panel..(y + 1) * panel];
            let at = (r * panel + y) * width + c * panel;
            sheet.rgb[at..at + panel].copy_from_slice(from);
        }
    }
    for (r, row) in rows.iter().enumerate() {
        let place = (columns * panel, r * panel, panel);
        match (row, &field, &distance) {
            (Row::Field, Some((_, range)), _) => {
                legend::color_bar(&mut sheet, place, "|w|", Scale::Viridis, *range)
            }
            (Row::Distance, _, Some((_, range))) => {
                legend::color_bar(&mut sheet, place, "dist", Scale::YellowRed, *range)
            }
            _ => {}
        }
    }
    // Thin separators between the panels.
    for r in 1..rows.len() {
        let y = r * panel;
        sheet.rgb[y * width..(y * width + columns * panel)].fill([225, 225, 225]);
    }
    for c in 1..=columns {
        for y in 0..height {
            sheet.rgb[y * width + c * panel - 1] = [225, 225, 225];
        }
    }
    Ok(Preview {
        image: Image {
            width: width as u32,
            height: height as u32,
            pixels: sheet.rgb.into_iter().flatten().collect(),
        },
        field_range: field.map(|f| f.1),
        distance_range: distance.map(|d| d.1),
    })
}

fn validate(scene: &Scene<'_>, options: &PreviewOptions) -> Result<()> {
    if !(16..=4096).contains(&options.panel) {
        return Err(FoldMatchError::parameter(
            "panel",
            options.panel,
            "must be in 16..=4096 pixels",
        ));
    }
    if options.views.is_empty() || options.views.len() > 4 {
        return Err(FoldMatchError::parameter(
            "views",
            options.views.len(),
            "give 1 to 4 views",
        ));
    }
    let m = scene.vertices.len();
    if m == 0 {
        return Err(FoldMatchError::shape("vertices", "no vertices to draw"));
    }
    crate::mesh::validate_faces("faces", scene.faces, m)?;
    if let Some(field) = scene.field {
        if field.len() != m {
            return Err(FoldMatchError::shape(
                "field",
                format!("{} values for {m} vertices", field.len()),
            ));
        }
    }
    if let Some(scan) = scene.scan {
        if scan.is_empty() {
            return Err(FoldMatchError::shape("scan", "no points"));
        }
        if let Some(faces) = scene.scan_faces {
            crate::mesh::validate_faces("scan faces", faces, scan.len())?;
        }
    }
    Ok(())
}

/// Lambert shading of a face seen by `camera`: 0.35 ambient + 0.65 diffuse, two-sided (the
/// normal is flipped toward the viewer).
fn shade(camera: &Camera, a: &[f64; 3], b: &[f64; 3], c: &[f64; 3]) -> f32 {
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let n = camera.turn([
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]);
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if len.is_nan() || len <= 0.0 {
        return 0.35;
    }
    let facing = if n[2] < 0.0 { -1.0 } else { 1.0 };
    let dot = facing * (n[0] * LIGHT[0] + n[1] * LIGHT[1] + n[2] * LIGHT[2]) / len;
    (0.35 + 0.65 * dot.max(0.0)) as f32
}

fn draw_mesh(
    canvas: &mut Canvas,
    camera: &Camera,
    vertices: &[[f64; 3]],
    faces: &[[u32; 3]],
    colors: &[[u8; 3]],
) {
    let projected: Vec<[f32; 3]> = vertices.iter().map(|p| camera.project(p)).collect();
    for f in faces {
        let [a, b, c] = f.map(|i| i as usize);
        let s = shade(camera, &vertices[a], &vertices[b], &vertices[c]);
        let lit = |i: usize| colors[i].map(|x| f32::from(x) * s);
        canvas.triangle(
            [projected[a], projected[b], projected[c]],
            [lit(a), lit(b), lit(c)],
        );
    }
}

fn draw_scan(canvas: &mut Canvas, camera: &Camera, scene: &Scene<'_>, radius: f64) {
    let Some(scan) = scene.scan else { return };
    if let Some(faces) = scene.scan_faces.filter(|f| !f.is_empty()) {
        draw_mesh(canvas, camera, scan, faces, &vec![PLAIN; scan.len()]);
        return;
    }
    // Sparse scans as 3×3 splats, dense ones (more than a twentieth of the pixels) as single
    // pixels; gray from 60 (farthest) to 170 (nearest).
    let pixels = canvas.width * canvas.height;
    let splat = if scan.len() * 20 < pixels { 1 } else { 0 };
    for p in scan {
        let q = camera.project(p);
        let t = (0.5 + 0.5 * f64::from(q[2]) / radius).clamp(0.0, 1.0);
        let gray = (60.0 + 110.0 * t) as u8;
        canvas.point(q, splat, [gray; 3]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sheet(n: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let mut v = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let (x, y) = (
                    i as f64 / (n - 1) as f64 - 0.5,
                    j as f64 / (n - 1) as f64 - 0.5,
                );
                v.push([x, y, 0.1 * (6.0 * x).sin()]);
            }
        }
        let mut f = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let a = (j * n + i) as u32;
                let n = n as u32;
                f.push([a, a + 1, a + n]);
                f.push([a + 1, a + n + 1, a + n]);
            }
        }
        (v, f)
    }

    fn pixel(image: &Image, x: u32, y: u32) -> [u8; 3] {
        let i = 3 * (y * image.width + x) as usize;
        [image.pixels[i], image.pixels[i + 1], image.pixels[i + 2]]
    }

    #[test]
    fn layout_follows_the_layers_and_views() {
        let (v, f) = sheet(10);
        let options = PreviewOptions {
            panel: 64,
            views: vec![View::Front, View::Back],
        };
        let alone = render(&Scene::mesh(&v, &f), &options).unwrap();
        assert_eq!(
            (alone.image.width, alone.image.height),
            (2 * 64 + LEGEND_WIDTH, 64)
        );
        assert_eq!(alone.field_range, None);
        let field: Vec<f64> = v.iter().map(|p| p[0] + 0.5).collect();
        let full = Scene {
            field: Some(&field),
            scan: Some(&v),
            ..Scene::mesh(&v, &f)
        };
        let p = render(&full, &options).unwrap();
        assert_eq!(
            (p.image.width, p.image.height),
            (2 * 64 + LEGEND_WIDTH, 3 * 64)
        );
        assert_eq!(
            p.image.pixels.len(),
            (p.image.width * p.image.height * 3) as usize
        );
        assert_eq!(p.distance_range, Some((0.0, 0.0)));
        let (lo, hi) = p.field_range.unwrap();
        assert!(lo < 0.1 && hi > 0.9);
    }

    #[test]
    fn the_field_row_is_painted_with_the_field() {
        let (v, f) = sheet(20);
        let field: Vec<f64> = v.iter().map(|p| p[0] + 0.5).collect();
        let options = PreviewOptions {
            panel: 96,
            views: vec![View::Front],
        };
        let p = render(
            &Scene {
                field: Some(&field),
                ..Scene::mesh(&v, &f)
            },
            &options,
        )
        .unwrap();
        // Seen from the front +x is right: the left of the sheet is dark purple-blue (low
        // viridis), the right green-yellow (high).
        let (left, right) = (pixel(&p.image, 30, 48), pixel(&p.image, 66, 48));
        assert!(left[2] > left[1], "left {left:?}");
        assert!(right[1] > right[2], "right {right:?}");
        let gray = render(&Scene::mesh(&v, &f), &options).unwrap();
        let g = pixel(&gray.image, 30, 48);
        assert!(g[0] == g[1] && g[1] == g[2], "{g:?}");
        assert_eq!(pixel(&p.image, 2, 94), BACKGROUND);
    }

    #[test]
    fn errors_name_the_input() {
        let (v, f) = sheet(3);
        let bad = [[0u32, 1, 99]];
        let e = render(&Scene::mesh(&v, &bad), &PreviewOptions::default()).unwrap_err();
        assert!(e.to_string().contains("faces"), "{e}");
        let short = [1.0];
        let e = render(
            &Scene {
                field: Some(&short),
                ..Scene::mesh(&v, &f)
            },
            &PreviewOptions::default(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("field"), "{e}");
        let options = PreviewOptions {
            panel: 8,
            ..PreviewOptions::default()
        };
        let e = render(&Scene::mesh(&v, &f), &options).unwrap_err();
        assert!(e.to_string().contains("panel"), "{e}");
    }
}
